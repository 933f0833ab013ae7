//! Render benchmarks (divan): one novel view of an N × D MHI at 256 × 256, shared colour, soft
//! blending, full and pruned. `cargo bench -p mhi-render`; the comparison with the PyTorch peer
//! is `cargo xtask bench --peer …`.

use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{
    BlendHeuristic, Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity,
};
use mhi_render::{Blend, LayerColor, Mhi, Prune, RenderOptions, render};
use rand::{Rng, SeedableRng};

fn main() {
    divan::main();
}

fn scene(n: usize, d: usize) -> (Mhi, Camera) {
    let s = 256u32;
    let k = Intrinsics::new(128.0, 128.0, 128.0, 128.0).unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, s, s).unwrap();
    let rel = RigidTransform::new(
        DMat3::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), 4f64.to_radians()),
        DVec3::new(0.08, -0.02, 0.05),
    )
    .unwrap();
    let target = Camera::new(k, rel.inverse(), s, s).unwrap();
    let normals = NormalSet::paper_subset(n).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let img = Rgb32FImage::from_fn(s, s, |_, _| {
        image::Rgb([rng.random(), rng.random(), rng.random()])
    });
    let alpha = (0..n * d * (s * s) as usize)
        .map(|_| rng.random::<f32>())
        .collect();
    let mhi = Mhi::new(
        normals,
        depths_linear_in_disparity(1.0, 100.0, d).unwrap(),
        reference,
        LayerColor::Shared(img),
        alpha,
    )
    .unwrap();
    (mhi, target)
}

#[divan::bench(args = [(1, 32), (5, 32)], sample_count = 10)]
fn full(bencher: divan::Bencher<'_, '_>, (n, d): (usize, usize)) {
    let (mhi, target) = scene(n, d);
    let opts = RenderOptions {
        blend: Blend::Heuristic(BlendHeuristic::Soft),
        ..Default::default()
    };
    bencher.bench_local(|| render(&mhi, &target, &opts).unwrap());
}

#[divan::bench(args = [(5, 32)], sample_count = 10)]
fn pruned(bencher: divan::Bencher<'_, '_>, (n, d): (usize, usize)) {
    let (mhi, target) = scene(n, d);
    let opts = RenderOptions {
        blend: Blend::Heuristic(BlendHeuristic::Soft),
        prune: Prune::DEFAULT,
        ..Default::default()
    };
    bencher.bench_local(|| render(&mhi, &target, &opts).unwrap());
}
