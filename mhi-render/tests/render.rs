//! The fast f32 renderer against the f64 reference, and the invariants of compositing.

use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{
    BlendHeuristic, Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity,
};
use mhi_render::reference::render_f64;
use mhi_render::{Blend, LayerColor, Mhi, Prune, RenderOptions, render};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_mhi(n: usize, d: usize, w: u32, h: u32, per_layer: bool, seed: u64) -> Mhi {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let k = Intrinsics::new(
        0.6 * f64::from(w),
        0.6 * f64::from(w),
        f64::from(w) / 2.0,
        f64::from(h) / 2.0,
    )
    .unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, w, h).unwrap();
    let normals = NormalSet::paper_subset(n).unwrap();
    let depths = depths_linear_in_disparity(1.0, 100.0, d).unwrap();
    let mut img = || {
        Rgb32FImage::from_fn(w, h, |_, _| {
            image::Rgb([rng.random(), rng.random(), rng.random()])
        })
    };
    let color = if per_layer {
        LayerColor::PerLayer((0..n * d).map(|_| img()).collect())
    } else {
        LayerColor::Shared(img())
    };
    let alpha = (0..n * d * (w * h) as usize)
        .map(|_| rng.random::<f32>())
        .collect();
    Mhi::new(normals, depths, reference, color, alpha).unwrap()
}

/// `base`'s normals, depths and reference camera with other colour and alphas.
fn with_layers(base: &Mhi, color: LayerColor, alpha: Vec<f32>) -> Mhi {
    Mhi::new(
        base.normals().clone(),
        base.depths().to_vec(),
        *base.reference(),
        color,
        alpha,
    )
    .unwrap()
}

/// Alphas of `n` normals × `d` layers × `px` pixels: the far layer of each normal opaque, the
/// others uniform in `lo..lo + span`.
fn alphas_with_opaque_far(
    n: usize,
    d: usize,
    px: usize,
    (lo, span): (f32, f32),
    seed: u64,
) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n * d * px)
        .map(|k| {
            if (k / px).is_multiple_of(d) {
                1.0
            } else {
                lo + span * rng.random::<f32>()
            }
        })
        .collect()
}

/// The largest |a − b| over pixels and channels.
fn largest_change(a: &Rgb32FImage, b: &Rgb32FImage) -> f32 {
    a.as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

fn target(mhi: &Mhi, yaw_deg: f64, pitch_deg: f64, t: DVec3) -> Camera {
    let r = DMat3::from_rotation_y(yaw_deg.to_radians())
        * DMat3::from_rotation_x(pitch_deg.to_radians());
    let pose = RigidTransform::new(r, t).unwrap();
    Camera::new(
        mhi.reference().intrinsics,
        pose,
        mhi.reference().width,
        mhi.reference().height,
    )
    .unwrap()
}

fn max_diff(a: &Rgb32FImage, b: &[[f64; 3]]) -> f64 {
    a.pixels()
        .zip(b)
        .map(|(p, q)| {
            (0..3)
                .map(|k| (f64::from(p.0[k]) - q[k]).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max)
}

#[test]
fn fast_renderer_matches_the_f64_reference() {
    let mut worst = 0.0_f64;
    for (seed, per_layer) in [(1, false), (2, true)] {
        let mhi = random_mhi(5, 8, 40, 32, per_layer, seed);
        for (yaw, pitch, t) in [
            (0.0, 0.0, DVec3::ZERO),
            (4.0, -2.0, DVec3::new(0.08, -0.02, 0.05)),
            (15.0, 5.0, DVec3::new(-0.3, 0.1, 0.2)),
            (-30.0, 10.0, DVec3::new(0.5, 0.0, -0.4)),
        ] {
            let tgt = target(&mhi, yaw, pitch, t);
            let n = mhi.n();
            let given: Vec<f32> = (0..n * 40 * 32)
                .map(|k| ((k * 7919) % 13) as f32 + 0.5)
                .collect();
            for blend in [
                Blend::Heuristic(BlendHeuristic::Soft),
                Blend::Heuristic(BlendHeuristic::Hard),
                Blend::Heuristic(BlendHeuristic::Avg),
                Blend::Weights(&given),
            ] {
                let opts = RenderOptions {
                    blend,
                    keep_multi_normal: true,
                    ..Default::default()
                };
                let fast = render(&mhi, &tgt, &opts).unwrap();
                let (slow, mnis) = render_f64(&mhi, &tgt, blend).unwrap();
                let e = max_diff(&fast.image, &slow);
                for (a, b) in fast.multi_normal.iter().zip(&mnis) {
                    worst = worst.max(max_diff(a, b));
                }
                // Hard blending switches normals where two δ tie; f32 and f64 may pick
                // differently only on an exact tie, which these poses do not produce.
                assert!(
                    e <= 1e-4,
                    "seed {seed} yaw {yaw} {blend:?}: max |f32 − f64| = {e:e}"
                );
                worst = worst.max(e);
            }
        }
    }
    eprintln!("worst max |f32 − f64| over all cases: {worst:e}");
}

#[test]
fn identity_view_of_opaque_front_layer_is_the_reference_image() {
    // Alpha 1 on the nearest layer: from the reference camera every normal shows the image.
    let mut mhi = random_mhi(3, 4, 24, 20, false, 3);
    let px = 24 * 20;
    let mut alpha = mhi.alpha().to_vec();
    for i in 0..3 {
        alpha[(i * 4 + 3) * px..(i * 4 + 4) * px].fill(1.0);
    }
    let LayerColor::Shared(img) = mhi.color().clone() else {
        unreachable!()
    };
    mhi = with_layers(&mhi, LayerColor::Shared(img.clone()), alpha);
    let out = render(&mhi, mhi.reference(), &RenderOptions::default()).unwrap();
    let err = largest_change(&out.image, &img);
    assert!(err < 1e-5, "{err}");
}

#[test]
fn planes_behind_the_target_are_masked_not_nan() {
    // A target far forward (z = 50) is behind the near planes of every normal.
    let mhi = random_mhi(5, 16, 32, 24, false, 4);
    let tgt = target(&mhi, 0.0, 0.0, DVec3::new(0.0, 0.0, -50.0)); // cam_from_world t = −C
    let out = render(&mhi, &tgt, &RenderOptions::default()).unwrap();
    assert!(out.stats.layers_invisible > 0, "{:?}", out.stats);
    assert!(
        out.image
            .as_raw()
            .iter()
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v))
    );
    let (slow, _) = render_f64(&mhi, &tgt, Blend::Heuristic(BlendHeuristic::Soft)).unwrap();
    assert!(max_diff(&out.image, &slow) < 1e-4);
}

#[test]
fn a_path_through_a_plane_that_holds_something_is_refused() {
    use mhi_geom::path::dolly;
    use mhi_render::plan::{MIN_PATH_CLEARANCE, check_path};
    // Near plane at depth 1: a dolly 0.5 forward keeps half its distance, 0.97 keeps 3 %.
    let mut mhi = random_mhi(3, 4, 16, 12, false, 9);
    let r = *mhi.reference();
    let near = check_path(&mhi, &dolly(&r, 0.5, 8).unwrap())
        .unwrap()
        .unwrap();
    assert!((near.min_relative - 0.5).abs() < 1e-9, "{near:?}");
    assert_eq!((near.frame, near.depth), (2, 3)); // a quarter period in, the nearest layer
    // The dolly's frames 2 and 3 (1-based) are sin(45°) and 1 times the distance ahead.
    for (distance, frame, word) in [
        (0.97, 3, "too close to"),
        (1.0, 3, "on"),
        (1.5, 2, "behind"),
    ] {
        let e = check_path(&mhi, &dolly(&r, distance, 8).unwrap()).unwrap_err();
        let want = format!("camera {frame} of 8 of the path is {word} the plane");
        assert!(e.to_string().contains(&want), "{e}");
    }
    // A plane that holds nothing may be crossed: empty the nearest layer (depth 1) of every
    // normal; the next is at 1.49.
    let px = 16 * 12;
    let mut alpha = mhi.alpha().to_vec();
    for n in 0..3 {
        alpha[(n * 4 + 3) * px..(n * 4 + 4) * px].fill(0.0);
    }
    mhi = with_layers(&mhi, mhi.color().clone(), alpha);
    let c = check_path(&mhi, &dolly(&r, 1.3, 8).unwrap())
        .unwrap()
        .unwrap();
    assert!(
        c.min_relative >= MIN_PATH_CLEARANCE && c.depth == 2,
        "{c:?}"
    );
    assert!(check_path(&mhi, &[]).is_err());
}

#[test]
fn pruning_changes_little_and_reports_what_it_skipped() {
    let mut mhi = random_mhi(5, 16, 32, 24, false, 5);
    // Make half of the layers empty so the plan has something to skip.
    let px = 32 * 24;
    let mut alpha = mhi.alpha().to_vec();
    for l in (1..5 * 16).step_by(2) {
        alpha[l * px..(l + 1) * px].fill(0.0);
    }
    let LayerColor::Shared(img) = mhi.color().clone() else {
        unreachable!()
    };
    mhi = with_layers(&mhi, LayerColor::Shared(img), alpha);
    let mut tgt = target(&mhi, 3.0, 1.0, DVec3::new(0.05, 0.0, 0.02));
    // A narrow field of view: the fronto normal wins every pixel under Hard blending, so the
    // four others are negligible and may be skipped.
    tgt.intrinsics = Intrinsics::new(200.0, 200.0, 16.0, 12.0).unwrap();
    let full = render(&mhi, &tgt, &RenderOptions::default()).unwrap();
    let opts = RenderOptions {
        prune: Prune::DEFAULT,
        blend: Blend::Heuristic(BlendHeuristic::Hard),
        ..Default::default()
    };
    let pruned = render(&mhi, &tgt, &opts).unwrap();
    let hard = render(
        &mhi,
        &tgt,
        &RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Hard),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(pruned.stats.layers_pruned, 40);
    assert_eq!(pruned.stats.normals_pruned, 4, "{:?}", pruned.stats);
    let err = largest_change(&pruned.image, &hard.image);
    assert!(
        err <= 1.0 / 255.0 + 1e-6,
        "pruning changed a pixel by {err}"
    );
    assert_eq!(full.stats.layers_pruned, 0);
}

#[test]
fn bad_inputs_are_errors() {
    let mhi = random_mhi(2, 3, 8, 6, false, 6);
    let (n, px) = (2, 48);
    let mut alpha = mhi.alpha().to_vec();
    alpha[5] = f32::NAN;
    let LayerColor::Shared(img) = mhi.color().clone() else {
        unreachable!()
    };
    let err = Mhi::new(
        mhi.normals().clone(),
        mhi.depths().to_vec(),
        *mhi.reference(),
        LayerColor::Shared(img.clone()),
        alpha,
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("alpha must lie in [0, 1]"),
        "{err}"
    );
    let err = Mhi::new(
        mhi.normals().clone(),
        vec![1.0, 2.0, 3.0],
        *mhi.reference(),
        LayerColor::Shared(img.clone()),
        mhi.alpha().to_vec(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("far first"), "{err}");
    let err = Mhi::new(
        mhi.normals().clone(),
        mhi.depths().to_vec(),
        *mhi.reference(),
        LayerColor::Shared(Rgb32FImage::new(3, 3)),
        mhi.alpha().to_vec(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("3×3"), "{err}");
    let zero = vec![0.0_f32; n * px];
    let err = render(
        &mhi,
        mhi.reference(),
        &RenderOptions {
            blend: Blend::Weights(&zero),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(err.to_string().contains("sum to zero"), "{err}");
    let mut neg = vec![1.0_f32; n * px];
    neg[3] = -1.0;
    assert!(
        render(
            &mhi,
            mhi.reference(),
            &RenderOptions {
                blend: Blend::Weights(&neg),
                ..Default::default()
            }
        )
        .is_err()
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Compositing stays in [0, 1] and finite for any alphas in [0, 1], colours in [0, 1] and pose.
    #[test]
    fn compositing_stays_in_unit_range(seed in 0u64..1000, yaw in -60.0f64..60.0, pitch in -30.0f64..30.0, t in prop::array::uniform3(-3.0f64..3.0), h in 0usize..3) {
        let mhi = random_mhi(5, 6, 12, 10, seed % 2 == 0, seed);
        let tgt = target(&mhi, yaw, pitch, DVec3::from_array(t));
        let out = render(&mhi, &tgt, &RenderOptions { blend: Blend::Heuristic(BlendHeuristic::ALL[h]), keep_multi_normal: true, ..Default::default() }).unwrap();
        for img in std::iter::once(&out.image).chain(&out.multi_normal) {
            prop_assert!(img.as_raw().iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= 1.0 + 1e-6));
        }
    }
}

/// One error budget for everything left out: an MHI whose 31 non-far layers are each fainter
/// than the budget's layer share, but far brighter together, with colours that differ as much
/// as they can (black and white), and two normals of negligible blend weight. Pruned against
/// exact, no pixel may move by more than the bound the render reports, and that bound stays
/// within the budget. A plan that bounded each layer on its own would skip all 31 layers and
/// move pixels by about 31 × the share: this test fails for it.
#[test]
fn the_error_budget_bounds_the_total_change_of_every_pixel() {
    let (n, d, w, h) = (5, 32, 24, 20);
    let base = random_mhi(n, d, w, h, true, 9);
    let px = (w * h) as usize;
    let prune = Prune::DEFAULT;
    // A third of the budget: below the layer share whatever the normals leave out.
    let share = prune.normal_share();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut alpha = vec![0.0_f32; n * d * px];
    for i in 0..n {
        for j in 0..d {
            let layer = &mut alpha[(i * d + j) * px..(i * d + j + 1) * px];
            for a in layer.iter_mut() {
                *a = if j == 0 {
                    1.0
                } else {
                    // Just under the share, a little different per layer.
                    share * (0.5 + 0.45 * rng.random::<f32>())
                };
            }
        }
    }
    // Colours alternate black and white from layer to layer: the most a layer can change.
    let colors: Vec<Rgb32FImage> = (0..n * d)
        .map(|k| {
            let v = if k % 2 == 0 { 0.0 } else { 1.0 };
            Rgb32FImage::from_pixel(w, h, image::Rgb([v, v, v]))
        })
        .collect();
    let mhi = with_layers(&base, LayerColor::PerLayer(colors), alpha);
    let tgt = target(&mhi, 2.0, -1.0, DVec3::new(0.03, 0.01, 0.02));
    // Blend weights: normals 3 and 4 negligible (1e-4 each), the others share the rest.
    let mut weights = vec![0.0_f32; n * px];
    for p in 0..px {
        for i in 0..n {
            weights[i * px + p] = if i >= 3 { 1e-4 } else { (1.0 - 2e-4) / 3.0 };
        }
    }
    let exact = render(
        &mhi,
        &tgt,
        &RenderOptions {
            blend: Blend::Weights(&weights),
            ..Default::default()
        },
    )
    .unwrap();
    let pruned = render(
        &mhi,
        &tgt,
        &RenderOptions {
            blend: Blend::Weights(&weights),
            prune,
            ..Default::default()
        },
    )
    .unwrap();
    let s = pruned.stats;
    assert!(s.layers_pruned > 0 && s.normals_pruned == 2, "{s:?}");
    // Not every faint layer may go: together they exceed the share many times over.
    assert!(s.layers_pruned < 3 * (d - 1), "{s:?}");
    assert!(s.bound <= prune.budget + 1e-7, "{s:?}");
    let worst = largest_change(&pruned.image, &exact.image);
    assert!(
        worst <= s.bound + 1e-6,
        "a pixel moved by {worst}, beyond the bound {}",
        s.bound
    );
    // An exact plan leaves nothing out and reports a bound of zero.
    assert_eq!(exact.stats.bound, 0.0);
    assert_eq!(exact.stats.layers_pruned + exact.stats.normals_pruned, 0);

    // The scene analysis of the same view decides the same and keeps the same bound; a second
    // view that needs normal 4 keeps it.
    let plan = mhi_render::plan::analyse(&mhi, &[(&tgt, &weights[..])], prune).unwrap();
    let dropped: Vec<usize> = plan
        .per_normal
        .iter()
        .filter(|u| u.dropped)
        .map(|u| u.index)
        .collect();
    assert_eq!(dropped, vec![3, 4], "{}", plan.explain());
    let skipped: usize = plan.per_normal.iter().map(|u| u.layers_skipped).sum();
    assert_eq!(skipped, s.layers_pruned, "{}", plan.explain());
    let kept: usize = plan
        .per_normal
        .iter()
        .filter(|u| !u.dropped)
        .map(|u| d - u.layers_skipped)
        .sum();
    assert_eq!(plan.layers_kept, kept);
    assert!(plan.bound <= prune.budget + 1e-7 && plan.bytes_kept < plan.bytes_exact);
    assert!(plan.keeps(0, 0) && !plan.keeps(3, 0));
    let mut needs_4 = weights.clone();
    for p in 0..px {
        needs_4[4 * px + p] = 0.5;
        needs_4[p] = (1.0 - 2e-4) / 3.0 - 0.5 + 1e-4;
    }
    let plan2 =
        mhi_render::plan::analyse(&mhi, &[(&tgt, &weights[..]), (&tgt, &needs_4[..])], prune)
            .unwrap();
    assert!(!plan2.per_normal[4].dropped && plan2.per_normal[3].dropped);
    assert!(plan.explain().contains("left out"));
    // An exact budget keeps everything.
    let all = mhi_render::plan::analyse(&mhi, &[(&tgt, &weights[..])], Prune::NONE).unwrap();
    assert_eq!(all.layers_kept, n * d);
    assert_eq!(all.bytes_kept, all.bytes_exact);
}

/// Layers are skipped tile by tile where they are faint or hidden. The middle of the (columns
/// 80 to 175, away from tile edges so that each tile of 32 columns sees one side or both) of the
/// reference: an opaque layer near the front hides everything behind it; elsewhere the even
/// layers have alpha 0.4, the odd ones none and the front one 1e-4. No layer is negligible
/// everywhere, so nothing may be left out of the whole view, but the tiles that see only the
/// middle need the layers down to the opaque one and the far plane (4 of 12), the others the
/// far plane and the even layers (6 of 12), the two tiles that see both at most all 12: at most
/// 56 of 96 tile-layer pairs per tile row (58.3 %; a little more in the top and bottom tile
/// rows, whose samples may put a sliver of weight outside the image, where alphas read zero, so
/// the opaque layer is not quite opaque there; 60 % in all). Pruned against exact, no pixel moves by more than
/// the reported bound; the test fails for a plan that skips nothing per tile and for one that
/// skips a layer that shows.
#[test]
fn layers_are_skipped_per_tile_where_faint_or_hidden() {
    let (n, d, w, h) = (1, 12, 256, 64);
    let base = random_mhi(n, d, w, h, false, 4);
    let px = (w * h) as usize;
    let mut alpha = vec![0.0_f32; n * d * px];
    for j in 0..d {
        for y in 0..h as usize {
            for x in 0..w as usize {
                let middle = (80..176).contains(&x);
                alpha[j * px + y * w as usize + x] = match (j, middle) {
                    (0, _) => 1.0,
                    (9, true) => 1.0,
                    (10 | 11, true) => 0.2,
                    (_, true) => 0.9,
                    (11, false) => 1e-4,
                    (j, false) if j % 2 == 0 => 0.4,
                    (_, false) => 0.0,
                };
            }
        }
    }
    let mhi = with_layers(&base, base.color().clone(), alpha);
    let tgt = target(&mhi, 0.5, 0.0, DVec3::new(0.01, 0.0, 0.0));
    let go = |prune| {
        render(
            &mhi,
            &tgt,
            &RenderOptions {
                prune,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let (exact, pruned) = (go(Prune::NONE), go(Prune::DEFAULT));
    let s = pruned.stats;
    assert_eq!(exact.stats.composited, 1.0, "{:?}", exact.stats);
    assert_eq!(s.layers_pruned, 0, "{s:?}");
    assert!(s.composited <= 0.6, "{s:?}");
    assert!(s.bound <= Prune::DEFAULT.budget + 1e-7, "{s:?}");
    let worst = largest_change(&pruned.image, &exact.image);
    assert!(
        worst <= s.bound + 1e-6,
        "a pixel moved by {worst}, beyond the bound {}",
        s.bound
    );
}

/// The least share of samples a render within the budget must composite: behind an opaque
/// nearest layer nothing contributes, so exactly one layer in D is needed; on a random MHI the
/// pruned render composites no fewer samples than that least share, the exact one all of them.
#[test]
fn the_needed_share_is_a_floor_of_what_a_pruned_render_composites() {
    let (n, d, w, h) = (3, 4, 24, 20);
    let px = (w * h) as usize;
    let mut mhi = random_mhi(n, d, w, h, false, 3);
    let mut alpha = mhi.alpha().to_vec();
    for i in 0..n {
        alpha[(i * d + d - 1) * px..(i * d + d) * px].fill(1.0);
    }
    mhi = Mhi::new(
        mhi.normals().clone(),
        mhi.depths().to_vec(),
        *mhi.reference(),
        mhi.color().clone(),
        alpha,
    )
    .unwrap();
    let soft = mhi_render::heuristic_weights(&mhi, mhi.reference(), BlendHeuristic::Soft);
    let needed = mhi_render::needed_share(&mhi, mhi.reference(), &soft, 0.0).unwrap();
    assert!((needed - 1.0 / d as f32).abs() < 1e-6, "{needed}");
    let per_normal = mhi_render::needed_share_per_normal(&mhi, mhi.reference(), 0.0);
    assert!((per_normal - 1.0 / d as f32).abs() < 1e-6, "{per_normal}");
    // Per normal, each image on its own: two normals of three faint layers (alpha 0.001) in
    // front of an opaque far one, seen from the reference (every sample exact). A budget of
    // 0.0025 leaves out the two faintest samples of each normal's pixel, half of them; shared
    // by the two images it would leave out two of eight.
    let base = random_mhi(2, 4, 12, 10, false, 4);
    let px = 12 * 10;
    let mut alpha = vec![0.001_f32; 2 * 4 * px];
    for i in 0..2 {
        alpha[i * 4 * px..(i * 4 + 1) * px].fill(1.0);
    }
    let faint = with_layers(&base, base.color().clone(), alpha);
    let per_normal = mhi_render::needed_share_per_normal(&faint, faint.reference(), 0.0025);
    assert!((per_normal - 0.5).abs() < 1e-6, "{per_normal}");
    // Weights of the wrong size are an error, not a panic.
    assert!(mhi_render::needed_share(&mhi, mhi.reference(), &soft[1..], 0.0).is_err());

    let mhi = random_mhi(5, 16, 64, 48, false, 11);
    let tgt = target(&mhi, 3.0, -2.0, DVec3::new(0.05, 0.02, 0.03));
    let soft = mhi_render::heuristic_weights(&mhi, &tgt, BlendHeuristic::Soft);
    for budget in [1.0 / 255.0, 8.0 / 255.0] {
        let prune = Prune::with_budget(budget);
        let needed = mhi_render::needed_share(&mhi, &tgt, &soft, budget).unwrap();
        let opts = |prune| RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Soft),
            prune,
            ..Default::default()
        };
        let pruned = render(&mhi, &tgt, &opts(prune)).unwrap();
        let exact = render(&mhi, &tgt, &opts(Prune::NONE)).unwrap();
        assert_eq!(exact.stats.samples, 1.0);
        assert!(needed > 0.0 && needed < 1.0, "{needed}");
        assert!(
            pruned.stats.samples >= needed && pruned.stats.samples < 1.0,
            "composited {} of the samples, the least possible is {needed}",
            pruned.stats.samples
        );
        // Keeping the multi-normal images bounds each on its own: a stricter floor, which the
        // render that keeps them still composites at least.
        let per_normal = mhi_render::needed_share_per_normal(&mhi, &tgt, budget);
        let kept = render(
            &mhi,
            &tgt,
            &RenderOptions {
                keep_multi_normal: true,
                ..opts(prune)
            },
        )
        .unwrap();
        assert!(per_normal > needed, "{per_normal} vs {needed}");
        assert!(
            kept.stats.samples >= per_normal && kept.stats.samples < 1.0,
            "kept the multi-normal images and composited {} of the samples, the least possible is {per_normal}",
            kept.stats.samples
        );
    }
}

/// Without the multi-normal images only the blend is bounded, so each pixel's normals stop by
/// blend weight: a light normal stops early, a heavy one late, Σ_i w_i · stop_i within the stop
/// share. The near layers are white and the far ones black, so a stopped pixel, which takes the
/// white it composited for what lies behind, errs by the transmittance at which each normal
/// stopped: the worst case of the bound. With weights far
/// apart, the blended render composites fewer samples than one that bounds every normal's image
/// on its own, and both stay within their bounds at every pixel. (Fails, by more than twice the
/// budget, if each normal spends the whole stop share at its weight.)
#[test]
fn light_normals_stop_early_and_the_blend_stays_within_the_budget() {
    let (n, d, w, h) = (5, 24, 40, 24);
    let base = random_mhi(n, d, w, h, false, 21);
    let px = (w * h) as usize;
    let alpha = alphas_with_opaque_far(n, d, px, (0.15, 0.2), 5);
    // White near layers in front of black far ones: a pixel that stops among the white ones
    // gives what it left out the white of what it composited, where black was behind, so the
    // change reaches its bound.
    let colors: Vec<Rgb32FImage> = (0..n * d)
        .map(|k| {
            let v = if k % d > d / 3 { 1.0 } else { 0.0 };
            Rgb32FImage::from_pixel(w, h, image::Rgb([v, v, v]))
        })
        .collect();
    let mhi = with_layers(&base, LayerColor::PerLayer(colors), alpha);
    let tgt = target(&mhi, 1.0, 0.5, DVec3::new(0.02, 0.0, 0.01));
    // Normal 0 from 0.9 of the blend at the left edge to 0.2 at the right; the others share
    // the rest as 1 : 2 : 3 : 4.
    let mut weights = vec![0.0_f32; n * px];
    for p in 0..px {
        let heavy = 0.9 - 0.7 * (p % w as usize) as f32 / (w - 1) as f32;
        weights[p] = heavy;
        for i in 1..n {
            weights[i * px + p] = (1.0 - heavy) * i as f32 / 10.0;
        }
    }
    let blend = Blend::Weights(&weights);
    let opts = |prune, keep_multi_normal| RenderOptions {
        blend,
        prune,
        keep_multi_normal,
    };
    let exact = render(&mhi, &tgt, &opts(Prune::NONE, true)).unwrap();
    let blended = render(&mhi, &tgt, &opts(Prune::DEFAULT, false)).unwrap();
    let each = render(&mhi, &tgt, &opts(Prune::DEFAULT, true)).unwrap();
    let budget = Prune::DEFAULT.budget;
    for r in [&blended, &each] {
        assert!(r.stats.bound <= budget + 1e-7, "{:?}", r.stats);
        let worst = largest_change(&r.image, &exact.image);
        assert!(
            worst <= r.stats.bound + 1e-6,
            "a pixel moved by {worst}, beyond the bound {} ({:?})",
            r.stats.bound,
            r.stats
        );
        // The worst case is reached, not merely bounded: a pixel loses close to the bound.
        assert!(worst > 0.5 * r.stats.bound, "{worst} {:?}", r.stats);
    }
    for (m, e) in each.multi_normal.iter().zip(&exact.multi_normal) {
        assert!(largest_change(m, e) <= each.stats.bound + 1e-6);
    }
    assert!(
        blended.stats.samples < 0.95 * each.stats.samples,
        "blended {:?}, each normal bounded {:?}",
        blended.stats,
        each.stats
    );
}

#[test]
fn light_normals_leave_out_more_layers_and_the_blend_stays_within_the_budget() {
    // Faint layers (alpha 0.004–0.006 against a layer share of 0.002): a normal whose own
    // image is bounded keeps them all, but in a blend where it weighs at most 0.02 each of its
    // layers moves a pixel by a hundredth of that, so its tiles skip several.
    let (n, d, w, h) = (5, 12, 64, 32);
    let base = random_mhi(n, d, w, h, true, 33);
    let px = (w * h) as usize;
    let alpha = alphas_with_opaque_far(n, d, px, (0.004, 0.002), 8);
    let mhi = with_layers(&base, base.color().clone(), alpha);
    let tgt = target(&mhi, 1.0, -0.5, DVec3::new(0.01, 0.0, 0.02));
    // Normal 0 carries 0.92 of the blend, the other four 0.02 each.
    let mut weights = vec![0.02_f32; n * px];
    weights[..px].fill(0.92);
    let opts = |prune, keep_multi_normal| RenderOptions {
        blend: Blend::Weights(&weights),
        prune,
        keep_multi_normal,
    };
    let exact = render(&mhi, &tgt, &opts(Prune::NONE, false)).unwrap();
    let blended = render(&mhi, &tgt, &opts(Prune::DEFAULT, false)).unwrap();
    let each = render(&mhi, &tgt, &opts(Prune::DEFAULT, true)).unwrap();
    // Bounded on its own, no normal's tiles skip a layer here; blended, the light ones do.
    assert!(each.stats.composited > 0.999, "{:?}", each.stats);
    assert!(
        blended.stats.composited < 0.85,
        "blended {:?}, each normal bounded {:?}",
        blended.stats,
        each.stats
    );
    for r in [&blended, &each] {
        assert!(
            r.stats.bound <= Prune::DEFAULT.budget + 1e-7,
            "{:?}",
            r.stats
        );
        let worst = largest_change(&r.image, &exact.image);
        assert!(
            worst <= r.stats.bound + 1e-6,
            "a pixel moved by {worst}, beyond the bound {} ({:?})",
            r.stats.bound,
            r.stats
        );
    }
}

#[test]
fn a_stopped_pixel_gives_what_it_leaves_out_the_colour_it_composited() {
    // Every layer the same grey and alphas that stop most pixels well before the far layer:
    // what a stopped pixel leaves out behind it is that grey, and taking the mean colour of
    // what it composited for it changes nothing (dropping it would darken the pixel by up to
    // its stop).
    let (n, d, w, h) = (3, 16, 40, 24);
    let base = random_mhi(n, d, w, h, false, 4);
    let px = (w * h) as usize;
    let alpha = alphas_with_opaque_far(n, d, px, (0.3, 0.2), 6);
    let grey = Rgb32FImage::from_pixel(w, h, image::Rgb([0.5, 0.5, 0.5]));
    let mhi = with_layers(&base, LayerColor::Shared(grey), alpha);
    let tgt = target(&mhi, 0.5, 0.5, DVec3::new(0.01, 0.0, 0.01));
    let opts = |prune| RenderOptions {
        blend: Blend::Heuristic(BlendHeuristic::Avg),
        prune,
        keep_multi_normal: true,
    };
    let exact = render(&mhi, &tgt, &opts(Prune::NONE)).unwrap();
    let pruned = render(&mhi, &tgt, &opts(Prune::with_budget(8.0 / 255.0))).unwrap();
    assert!(pruned.stats.samples < 0.8, "{:?}", pruned.stats);
    // Away from the border (where bilinear taps outside the image read zero colour, so the
    // layers are not all grey there).
    for (p, e) in pruned.multi_normal.iter().zip(&exact.multi_normal) {
        let worst = (4..h - 4)
            .flat_map(|y| (4..w - 4).map(move |x| (x, y)))
            .flat_map(|(x, y)| {
                let (a, b) = (p.get_pixel(x, y).0, e.get_pixel(x, y).0);
                (0..3).map(move |k| (a[k] - b[k]).abs())
            })
            .fold(0.0_f32, f32::max);
        assert!(
            worst < 1e-5,
            "a pixel moved by {worst} (bound {})",
            pruned.stats.bound
        );
    }
}
