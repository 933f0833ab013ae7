//! `render_image` against `render_view`: the blended image alone, within the same bound.

use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity};
use mhi_net::{BlendChoice, render_image, render_view};
use mhi_render::{LayerColor, Mhi, Prune};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Without a model (a sweep's MHI) `render_image` keeps no multi-normal images, composites
/// fewer samples than `render_view` within the same budget, and no pixel of it moves from the
/// exact render by more than its bound. Fails for a black image (the exact render is not).
#[test]
fn the_image_alone_stays_within_the_bound_with_fewer_samples() {
    let (w, h, d) = (48_u32, 32_u32, 12);
    let k = Intrinsics::new(30.0, 30.0, 24.0, 16.0).unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, w, h).unwrap();
    let normals = NormalSet::paper_subset(5).unwrap();
    let depths = depths_linear_in_disparity(1.0, 100.0, d).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let color = LayerColor::Shared(Rgb32FImage::from_fn(w, h, |_, _| {
        image::Rgb([rng.random(), rng.random(), rng.random()])
    }));
    let px = (w * h) as usize;
    let alpha = (0..5 * d * px)
        .map(|_| 0.1 + 0.3 * rng.random::<f32>())
        .collect();
    let mhi = Mhi::new(normals, depths, reference, color, alpha).unwrap();
    let pose = RigidTransform::new(
        DMat3::from_rotation_y(6_f64.to_radians()),
        DVec3::new(0.05, 0.0, 0.02),
    )
    .unwrap();
    let target = Camera::new(k, pose, w, h).unwrap();
    let blend = BlendChoice::Learned; // Soft, as there is no model
    let exact = render_view(&mhi, None, &target, blend, Prune::NONE).unwrap();
    let views = render_view(&mhi, None, &target, blend, Prune::DEFAULT).unwrap();
    let image = render_image(&mhi, None, &target, blend, Prune::DEFAULT).unwrap();
    assert_eq!(views.multi_normal.len(), 5);
    assert!(image.multi_normal.is_empty());
    assert!(
        image.stats.samples < views.stats.samples,
        "{:?} / {:?}",
        image.stats,
        views.stats
    );
    let worst = image
        .image
        .as_raw()
        .iter()
        .zip(exact.image.as_raw())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0_f32, f32::max);
    assert!(image.stats.bound > 0.0 && image.stats.bound <= Prune::DEFAULT.budget + 1e-7);
    assert!(
        worst <= image.stats.bound + 1e-6,
        "{worst} > {}",
        image.stats.bound
    );
    assert!(exact.image.as_raw().iter().any(|v| *v > 0.1));
}
