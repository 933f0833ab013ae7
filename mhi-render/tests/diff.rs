//! The differentiable burn path agrees with the CPU renderer and keeps gradients finite on the
//! extreme cases of docs/METHOD.md ("Numerical traps").

use burn::tensor::{Device, Tensor, TensorData};
use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{
    BlendHeuristic, Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity,
};
use mhi_render::diff::{
    WarpGeometry, heuristic_weights_tensor, image_to_tensor, render_shared, tensor_to_image,
};
use mhi_render::{Blend, LayerColor, Mhi, RenderOptions, render};
use rand::{Rng, SeedableRng};

struct Case {
    mhi: Mhi,
    image: Rgb32FImage,
    alpha: Vec<f32>,
}

fn case(n: usize, d: usize, w: u32, h: u32, seed: u64, alpha_value: Option<f32>) -> Case {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let k = Intrinsics::new(
        0.7 * f64::from(w),
        0.7 * f64::from(w),
        f64::from(w) / 2.0,
        f64::from(h) / 2.0,
    )
    .unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, w, h).unwrap();
    let normals = NormalSet::paper_subset(n).unwrap();
    let depths = depths_linear_in_disparity(1.0, 100.0, d).unwrap();
    let image = Rgb32FImage::from_fn(w, h, |_, _| {
        image::Rgb([rng.random(), rng.random(), rng.random()])
    });
    let alpha: Vec<f32> = (0..n * d * (w * h) as usize)
        .map(|_| alpha_value.unwrap_or_else(|| rng.random()))
        .collect();
    let mhi = Mhi::new(
        normals,
        depths,
        reference,
        LayerColor::Shared(image.clone()),
        alpha.clone(),
    )
    .unwrap();
    Case { mhi, image, alpha }
}

fn target(c: &Case, r: DMat3, t: DVec3) -> Camera {
    let reference = c.mhi.reference();
    Camera::new(
        reference.intrinsics,
        RigidTransform::new(r, t).unwrap(),
        reference.width,
        reference.height,
    )
    .unwrap()
}

fn alpha_tensor(c: &Case, device: &Device) -> Tensor<4> {
    let r = c.mhi.reference();
    Tensor::from_data(
        TensorData::new(
            c.alpha.clone(),
            [
                c.mhi.n() * c.mhi.d(),
                1,
                r.height as usize,
                r.width as usize,
            ],
        ),
        device,
    )
}

#[test]
fn burn_path_matches_the_cpu_renderer() {
    let device = Device::flex();
    let mut worst = 0.0_f32;
    for seed in 0..3u64 {
        let c = case(5, 8, 36, 28, seed, None);
        for (r, t) in [
            (DMat3::IDENTITY, DVec3::ZERO),
            (
                DMat3::from_rotation_y(0.07) * DMat3::from_rotation_x(-0.03),
                DVec3::new(0.08, -0.02, 0.05),
            ),
            (DMat3::from_rotation_y(-0.4), DVec3::new(-0.4, 0.1, 0.3)),
        ] {
            let tgt = target(&c, r, t);
            for heuristic in BlendHeuristic::ALL {
                let cpu = render(
                    &c.mhi,
                    &tgt,
                    &RenderOptions {
                        blend: Blend::Heuristic(heuristic),
                        ..Default::default()
                    },
                )
                .unwrap();
                let geom = WarpGeometry::new(
                    c.mhi.normals(),
                    c.mhi.depths(),
                    c.mhi.reference(),
                    &tgt,
                    &device,
                )
                .unwrap();
                let w = heuristic_weights_tensor(
                    c.mhi.normals(),
                    c.mhi.reference(),
                    &tgt,
                    heuristic,
                    &device,
                );
                let (img, _) = render_shared(
                    alpha_tensor(&c, &device),
                    image_to_tensor(&c.image, &device),
                    &geom,
                    w,
                );
                let img = tensor_to_image(img).unwrap();
                let e = img
                    .as_raw()
                    .iter()
                    .zip(cpu.image.as_raw())
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f32::max);
                assert!(
                    e <= 1e-4,
                    "seed {seed} {heuristic:?}: max |burn − cpu| = {e:e}"
                );
                worst = worst.max(e);
            }
        }
    }
    eprintln!("worst max |burn − cpu| = {worst:e}");
}

fn grads_finite(c: &Case, tgt: &Camera) -> (bool, f32) {
    let device = Device::flex().autodiff();
    let geom = WarpGeometry::new(
        c.mhi.normals(),
        c.mhi.depths(),
        c.mhi.reference(),
        tgt,
        &device,
    )
    .unwrap();
    let alpha = alpha_tensor(c, &device).require_grad();
    let color = image_to_tensor(&c.image, &device).require_grad();
    let w = heuristic_weights_tensor(
        c.mhi.normals(),
        c.mhi.reference(),
        tgt,
        BlendHeuristic::Soft,
        &device,
    )
    .require_grad();
    let (img, _) = render_shared(alpha.clone(), color.clone(), &geom, w.clone());
    let loss = (img.clone() - img.clone().ones_like() * 0.5).abs().sum();
    let grads = loss.backward();
    let mut all = true;
    let mut max = 0.0_f32;
    for g in [alpha.grad(&grads), color.grad(&grads), w.grad(&grads)] {
        let g = g.expect("gradient present");
        let v: Vec<f32> = g.into_data().try_to_vec().unwrap();
        all &= v.iter().all(|x| x.is_finite());
        max = max.max(v.iter().fold(0.0, |m, x| m.max(x.abs())));
    }
    let out: Vec<f32> = img.into_data().try_to_vec().unwrap();
    all &= out.iter().all(|x| x.is_finite());
    (all, max)
}

#[test]
fn gradients_are_finite_on_extreme_cases() {
    let base = case(5, 6, 12, 10, 7, None);
    let zero = case(5, 6, 12, 10, 8, Some(0.0));
    let one = case(5, 6, 12, 10, 9, Some(1.0));
    // Target cameras: identity; sitting exactly on the nearest fronto plane (d − nᵀt = 0); far
    // behind the near planes; rotated 90° and 179° (samples with w ≤ ε); a 1e-9 baseline.
    let near = base.mhi.depths()[base.mhi.d() - 1];
    let cases = [
        ("identity", DMat3::IDENTITY, DVec3::ZERO),
        ("on the plane", DMat3::IDENTITY, DVec3::new(0.0, 0.0, -near)),
        (
            "behind the planes",
            DMat3::IDENTITY,
            DVec3::new(0.0, 0.0, -50.0),
        ),
        (
            "90°",
            DMat3::from_rotation_y(std::f64::consts::FRAC_PI_2),
            DVec3::new(0.1, 0.0, 0.0),
        ),
        (
            "179°",
            DMat3::from_rotation_y(179f64.to_radians()),
            DVec3::new(0.0, 0.0, 0.1),
        ),
        ("1e-9 baseline", DMat3::IDENTITY, DVec3::new(1e-9, 0.0, 0.0)),
    ];
    for c in [&base, &zero, &one] {
        for (name, r, t) in &cases {
            let tgt = target(c, *r, *t);
            let (ok, max) = grads_finite(c, &tgt);
            assert!(ok, "{name}: a gradient or output is not finite");
            assert!(max < 1e6, "{name}: gradient magnitude {max}");
        }
    }
}

/// A tensor's values.
fn values(t: &Tensor<4>) -> Vec<f32> {
    t.to_data().convert::<f32>().try_into_vec::<f32>().unwrap()
}

/// The largest absolute difference of two equally long value lists.
fn max_diff(a: Vec<f32>, b: Vec<f32>) -> f32 {
    a.iter()
        .zip(&b)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max)
}

/// The warp geometry of case `c` seen from `tgt`, on the autodiff CPU device.
fn geometry(c: &Case, tgt: &Camera, device: &Device) -> WarpGeometry {
    WarpGeometry::new(
        c.mhi.normals(),
        c.mhi.depths(),
        c.mhi.reference(),
        tgt,
        device,
    )
    .unwrap()
}

/// The gradients of one random weighting of two outputs, each through its own graph.
fn backward_both(
    ours: Tensor<4>,
    theirs: Tensor<4>,
    device: &Device,
) -> (burn::tensor::Gradients, burn::tensor::Gradients) {
    let weights = Tensor::<4>::random(
        ours.dims(),
        burn::tensor::Distribution::Uniform(-1.0, 1.0),
        device,
    );
    (
        (ours * weights.clone()).sum().backward(),
        (theirs * weights).sum().backward(),
    )
}

/// The gather warp (precomputed taps, hand-written backward) gives `grid_sample` × validity and
/// its gradient, on a view that leaves part of every layer outside the reference image.
#[test]
fn the_gather_warp_matches_grid_sample_and_its_gradient() {
    use burn::tensor::ops::GridSampleOptions;
    let c = case(3, 5, 23, 17, 7, None);
    let tgt = target(
        &c,
        DMat3::from_rotation_y(0.2) * DMat3::from_rotation_x(-0.1),
        DVec3::new(0.3, -0.1, 0.2),
    );
    let device = Device::flex().autodiff();
    let geom = geometry(&c, &tgt, &device);
    assert!(geom.taps.is_some(), "the CPU backend builds taps");
    let layers = Tensor::cat(vec![alpha_tensor(&c, &device); 2], 1).require_grad();
    let ours = mhi_render::diff::warp(layers.clone(), &geom);
    let theirs = layers
        .clone()
        .grid_sample_2d(geom.grid.clone(), GridSampleOptions::default())
        * geom.valid.clone();
    assert_eq!(ours.dims(), theirs.dims());
    let (o, t) = (values(&ours), values(&theirs));
    assert!(
        t.contains(&0.0) && t.iter().any(|&v| v > 0.0),
        "a partial view"
    );
    let err = max_diff(o, t);
    assert!(err < 1e-5, "forward differs by {err}");
    let (g1, g2) = backward_both(ours, theirs, &device);
    let (a, b) = (layers.grad(&g1).unwrap(), layers.grad(&g2).unwrap());
    let err = max_diff(values(&a), values(&b));
    assert!(err < 1e-4, "gradient differs by {err}");
}

/// The fused over-compositing of the CPU backend gives burn's loop of tensor operations and its
/// gradients with respect to the colours and the alphas, with alphas of exactly 0 and 1 among
/// them (the farthest layer opaque whatever its alpha).
#[test]
fn the_fused_composite_matches_burns_loop_and_its_gradients() {
    let c = case(3, 5, 23, 17, 7, None);
    let tgt = target(&c, DMat3::from_rotation_y(0.1), DVec3::new(0.2, 0.0, 0.1));
    let device = Device::flex().autodiff();
    let geom = geometry(&c, &tgt, &device);
    let (l, h, w) = (3 * 5, geom.height, geom.width);
    let rgb = Tensor::<4>::random(
        [l, 3, h, w],
        burn::tensor::Distribution::Uniform(0.0, 1.0),
        &device,
    )
    .require_grad();
    // Alphas in [-0.2, 1.2] clamped: a share of exact zeros and ones.
    let alpha = Tensor::<4>::random(
        [l, 1, h, w],
        burn::tensor::Distribution::Uniform(-0.2, 1.2),
        &device,
    )
    .clamp(0.0, 1.0)
    .detach()
    .require_grad();
    let ours = mhi_render::diff::composite(rgb.clone(), alpha.clone(), &geom);
    let theirs = mhi_render::diff::composite_ops(rgb.clone(), alpha.clone(), &geom);
    assert_eq!(ours.dims(), [3, 3, h, w]);
    let err = max_diff(values(&ours), values(&theirs));
    assert!(err < 1e-5, "forward differs by {err}");
    let (g1, g2) = backward_both(ours, theirs, &device);
    for (name, x) in [("colour", &rgb), ("alpha", &alpha)] {
        let (a, b) = (x.grad(&g1).unwrap(), x.grad(&g2).unwrap());
        let (a, b) = (values(&a), values(&b));
        assert!(
            b.iter().any(|v| v.abs() > 1e-3),
            "{name}: a gradient to compare"
        );
        let err = max_diff(a, b);
        assert!(err < 1e-5, "{name} gradient differs by {err}");
    }
}
