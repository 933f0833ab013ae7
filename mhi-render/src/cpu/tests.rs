use super::kernel::*;
use super::options::*;
use super::plan::*;
use super::sample::*;
use super::weights::*;
use crate::mhi::{LayerColor, Mhi};
use glam::DMat3;
use glam::DVec3;
use image::Rgb32FImage;
use mhi_geom::{BlendHeuristic, Camera};
use mhi_geom::{Intrinsics, RigidTransform, depths_linear_in_disparity};

#[test]
fn soft_weights_row_by_row_are_the_per_pixel_weights() {
    // Off-centre principal point, non-square pixels, a turned target: every pixel's
    // weights against δ from `angle_cost_in_target` and `BlendHeuristic::weights`.
    let k = Intrinsics::new(23.0, 31.0, 14.0, 7.5).unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, 37, 23).unwrap();
    let rel = RigidTransform::new(
        DMat3::from_axis_angle(DVec3::new(0.3, 1.0, -0.4).normalize(), 0.6),
        DVec3::new(0.2, -0.05, 0.1),
    )
    .unwrap();
    let target = Camera::new(k, rel.inverse(), 29, 17).unwrap();
    let normals = mhi_geom::NormalSet::paper();
    let ours = heuristic_weights_for(&normals, &reference, &target, BlendHeuristic::Soft);
    let r = reference.from_other(&target).rotation();
    let (w, h, n) = (29, 17, normals.len());
    let mut worst = 0.0_f64;
    for y in 0..h {
        for x in 0..w {
            let ray = k.ray(mhi_geom::pixel_center(x, y));
            let deltas: Vec<f64> = normals
                .normals()
                .iter()
                .map(|v| mhi_geom::angle_cost_in_target(*v, &r, ray).unwrap())
                .collect();
            let want = BlendHeuristic::Soft.weights(&deltas);
            for (i, want) in want.iter().enumerate() {
                let got = ours[i * (w * h) as usize + (y * w + x) as usize];
                worst = worst.max((f64::from(got) - want).abs());
            }
        }
    }
    assert!(worst < 1e-7, "largest difference {worst:e}");
    // The AVX2 compilation gives the baseline's bits.
    let nt: Vec<DVec3> = normals
        .normals()
        .iter()
        .map(|v| (r.transpose() * *v).normalize())
        .collect();
    for y in 0..17 {
        let (mut a, mut b) = (vec![0.0_f32; n * 29], vec![0.0_f32; n * 29]);
        soft_row(&nt, &k, y, 29, &mut a);
        soft_row_generic(&nt, &k, y, 29, &mut b);
        assert!(a.iter().zip(&b).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

#[test]
fn the_avx2_rows_agree_with_the_baseline_rows() {
    // A small MHI with both colour layouts, seen turned and moved, exactly and pruned.
    let k = Intrinsics::new(20.0, 20.0, 18.0, 12.0).unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, 37, 23).unwrap();
    let rel = RigidTransform::new(
        DMat3::from_axis_angle(DVec3::new(0.3, 1.0, 0.1).normalize(), 0.2),
        DVec3::new(0.2, -0.05, 0.1),
    )
    .unwrap();
    let target = Camera::new(k, rel.inverse(), 41, 19).unwrap();
    let (n, d, px) = (3, 6, 37 * 23);
    let value = |i: usize| ((i * 7919) % 1000) as f32 / 999.0;
    let image = |seed: usize| {
        Rgb32FImage::from_fn(37, 23, |x, y| {
            let i = seed + (y * 37 + x) as usize * 3;
            image::Rgb([value(i), value(i + 1), value(i + 2)])
        })
    };
    for per_layer in [false, true] {
        let color = if per_layer {
            LayerColor::PerLayer((0..n * d).map(|l| image(l * 5000)).collect())
        } else {
            LayerColor::Shared(image(0))
        };
        let alpha = (0..n * d * px).map(|i| value(i * 3 + 1).powi(3)).collect();
        let mhi = Mhi::new(
            mhi_geom::NormalSet::paper_subset(n).unwrap(),
            depths_linear_in_disparity(1.0, 50.0, d).unwrap(),
            reference,
            color,
            alpha,
        )
        .unwrap();
        for prune in [Prune::NONE, Prune::DEFAULT] {
            let opts = RenderOptions {
                prune,
                keep_multi_normal: true,
                ..Default::default()
            };
            let fast = render_rows_with(&mhi, &target, &opts, Rows::Fastest).unwrap();
            let base = render_rows_with(&mhi, &target, &opts, Rows::Baseline).unwrap();
            // On a CPU with AVX-512F the exact render composites sixteen pixels at a time:
            // the same bits as the AVX2 rows.
            let avx2 = render_rows_with(&mhi, &target, &opts, Rows::Avx2).unwrap();
            let bits = |r: &Rendered| -> Vec<u32> {
                std::iter::once(&r.image)
                    .chain(&r.multi_normal)
                    .flat_map(|m| m.as_raw().iter().map(|v| v.to_bits()))
                    .collect()
            };
            assert!(
                bits(&fast) == bits(&avx2),
                "{prune:?}: widest rows against AVX2 rows"
            );
            assert_eq!(fast.stats, avx2.stats);
            // The AVX2 rows fuse the mix's and the compositing's multiply-adds (one
            // rounding each), the baseline rounds twice: the last bits differ, a few
            // units in the last place of colours in [0, 1]. A pruned pixel whose
            // transmittance lands on its stop differently may composite one sample more
            // or less, which the budget bounds.
            let tol = if prune == Prune::NONE {
                2e-6
            } else {
                prune.budget
            };
            let worst = std::iter::once((&fast.image, &base.image))
                .chain(fast.multi_normal.iter().zip(&base.multi_normal))
                .flat_map(|(a, b)| a.as_raw().iter().zip(b.as_raw()))
                .fold(0.0_f32, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst <= tol, "{prune:?}: max |avx2 - baseline| = {worst:e}");
            assert_eq!(fast.stats.composited, base.stats.composited);
            assert!((fast.stats.samples - base.stats.samples).abs() < 0.01);
            if prune == Prune::NONE {
                assert_eq!(fast.stats, base.stats);
            }
        }
    }
}

#[test]
fn an_exact_render_is_every_sample_composited_to_the_bit() {
    // A target moved and turned far enough that most layers' samples fall outside the
    // reference image on one side (the run trims those) and inside on the other: every
    // multi-normal image must be, bit for bit, the front-to-back composite of every sample
    // through the general zero-padded sampler, and every sample must count.
    let k = Intrinsics::new(20.0, 20.0, 18.0, 12.0).unwrap();
    let reference = Camera::new(k, RigidTransform::IDENTITY, 37, 23).unwrap();
    // Seven layers: three pairs, then the far layer alone.
    let (n, d, px) = (3, 7, 37 * 23);
    let value = |i: usize| ((i * 7919) % 1000) as f32 / 999.0;
    let color = LayerColor::Shared(Rgb32FImage::from_fn(37, 23, |x, y| {
        let i = (y * 37 + x) as usize * 3;
        image::Rgb([value(i), value(i + 1), value(i + 2)])
    }));
    let alpha = (0..n * d * px).map(|i| value(i * 3 + 1)).collect();
    let mhi = Mhi::new(
        mhi_geom::NormalSet::paper_subset(n).unwrap(),
        depths_linear_in_disparity(1.0, 50.0, d).unwrap(),
        reference,
        color,
        alpha,
    )
    .unwrap();
    for (angle, t) in [
        (0.35, DVec3::new(0.6, -0.2, 0.1)),
        (-0.5, DVec3::new(-0.4, 0.3, -0.2)),
    ] {
        let rel = RigidTransform::new(
            DMat3::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), angle),
            t,
        )
        .unwrap();
        let target = Camera::new(k, rel.inverse(), 41, 19).unwrap();
        let opts = RenderOptions {
            keep_multi_normal: true,
            ..Default::default()
        };
        // The baseline rows round every product; the AVX2 rows (where the CPU has them)
        // fuse each multiply-add, and so does the composite they are held to here.
        #[cfg(target_arch = "x86_64")]
        let fused = mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2;
        #[cfg(not(target_arch = "x86_64"))]
        let fused = false;
        let all = [
            (Rows::Baseline, false),
            (Rows::Avx2, fused),
            (Rows::Fastest, fused),
        ];
        for (rows, fused) in all {
            let got = render_rows_with(&mhi, &target, &opts, rows).unwrap();
            assert_eq!(got.stats.samples, 1.0);
            let hs = layer_homographies(&mhi, &target);
            let mut outside = 0;
            for i in 0..n {
                for y in 0..19 {
                    for x in 0..41 {
                        let visible = (0..d).rev().filter(|j| hs[i * d + j].is_some());
                        let (c, _, off) = composite_of(&mhi, &hs, (i, x, y), visible, 0.0, fused);
                        outside += off;
                        let p = got.multi_normal[i].get_pixel(x, y).0;
                        assert_eq!(
                            p.map(f32::to_bits),
                            c.map(f32::to_bits),
                            "{rows:?} normal {i} pixel ({x}, {y})"
                        );
                    }
                }
            }
            // The poses do send many samples off the image.
            assert!(outside > n * d * 41 * 19 / 10, "{outside} samples outside");
        }
    }
}

/// Pixel `(x, y)` of normal `i`'s image composited front to back over `layers` (near to
/// far) the slow way: pass 1's arithmetic for the position, the general zero-padded
/// sampler, the far layer opaque, no sample once the transmittance is at or below `stop`
/// (0: never). Returns the colour, the samples composited and those wholly off the image.
fn composite_of(
    mhi: &Mhi,
    hs: &[Option<[f32; 9]>],
    (i, x, y): (usize, u32, u32),
    layers: impl Iterator<Item = usize>,
    stop: f32,
    fused: bool,
) -> ([f32; 3], usize, usize) {
    let (rw, rh) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    let color = match mhi.color() {
        LayerColor::Shared(img) => img.as_raw(),
        LayerColor::PerLayer(_) => unreachable!(),
    };
    let (mut t, mut c, mut composited, mut outside) = (1.0_f32, [0.0_f32; 3], 0, 0);
    for j in layers {
        if stop > 0.0 && t <= stop {
            continue;
        }
        let h = hs[i * mhi.d() + j].unwrap_or([0.0; 9]);
        let (u, v) = (x as i32 as f32 + 0.5, y as f32 + 0.5);
        let (bx, by, bw) = (h[1] * v + h[2], h[4] * v + h[5], h[7] * v + h[8]);
        let w = h[6] * u + bw;
        let ok = w > W_EPS;
        let inv = 1.0 / if ok { w } else { 1.0 };
        let sx = if ok {
            (h[0] * u + bx) * inv - 0.5
        } else {
            -2.0
        };
        let sy = if ok {
            (h[3] * u + by) * inv - 0.5
        } else {
            -2.0
        };
        let alpha = mhi.alpha_layer(i, j);
        let (a, col) = if fused {
            sample::<true>(alpha, color, rw, rh, sx, sy)
        } else {
            sample::<false>(alpha, color, rw, rh, sx, sy)
        };
        composited += 1;
        if !touches_image(sx, sy, rw, rh) {
            outside += 1;
        }
        let a = if j == 0 { 1.0 } else { a };
        let ta = t * a;
        for (c, v) in c.iter_mut().zip(col) {
            *c = if fused {
                ta.mul_add(v, *c)
            } else {
                *c + ta * v
            };
        }
        t -= ta;
    }
    // A pixel that stopped takes the mean colour of what it composited for what it left
    // out behind.
    if stop > 0.0 && t > 0.0 && t <= stop && t < 1.0 {
        let s = 1.0 / (1.0 - t);
        for v in &mut c {
            *v *= s;
        }
    }
    (c, composited, outside)
}

#[test]
fn a_pruned_render_is_its_plans_samples_composited_to_the_bit() {
    // Layers faint in the reference's left half (the plan leaves them out of the tiles
    // that see only that half, so those tiles keep every other layer) and alphas that
    // stop most pixels before the far layer: every multi-normal image must be, bit for
    // bit, each pixel's tile's layers composited through the general sampler up to its
    // stop, whether the render takes them one or two at a time; every sample must count.
    let k = Intrinsics::new(30.0, 30.0, 30.0, 12.0).unwrap();
    let (rw, rh) = (61_u32, 23_u32);
    let reference = Camera::new(k, RigidTransform::IDENTITY, rw, rh).unwrap();
    let (n, d, px) = (2, 9, (rw * rh) as usize);
    let value = |i: usize| ((i * 7919) % 1000) as f32 / 999.0;
    let color = LayerColor::Shared(Rgb32FImage::from_fn(rw, rh, |x, y| {
        let i = (y * rw + x) as usize * 3;
        image::Rgb([value(i), value(i + 1), value(i + 2)])
    }));
    let alpha = (0..n * d * px)
        .map(|l| {
            let (j, x) = ((l / px) % d, (l % px) % rw as usize);
            if j % 2 == 1 && x < 40 {
                0.0
            } else {
                0.6 + 0.35 * value(l * 3 + 1)
            }
        })
        .collect();
    let mhi = Mhi::new(
        mhi_geom::NormalSet::paper_subset(n).unwrap(),
        depths_linear_in_disparity(1.0, 50.0, d).unwrap(),
        reference,
        color,
        alpha,
    )
    .unwrap();
    let rel = RigidTransform::new(
        DMat3::from_axis_angle(DVec3::new(0.1, 1.0, 0.0).normalize(), 0.05),
        DVec3::new(0.05, 0.02, 0.0),
    )
    .unwrap();
    let target = Camera::new(k, rel.inverse(), 64, 19).unwrap();
    let opts = RenderOptions {
        keep_multi_normal: true,
        prune: Prune::DEFAULT,
        ..Default::default()
    };
    let plan = render_plan(&mhi, &target, &opts).unwrap();
    let tiles_x = 64_usize.div_ceil(TILE_W);
    // The plan has tiles that keep two neighbouring layers and tiles that skip some.
    let lists = || plan.tiles.iter().flat_map(|t| &t.layers);
    assert!(lists().any(|l| l.windows(2).any(|w| w[0] == w[1] + 1)));
    assert!(lists().any(|l| l.len() < d));
    #[cfg(target_arch = "x86_64")]
    let fused = mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2;
    #[cfg(not(target_arch = "x86_64"))]
    let fused = false;
    for (rows, fused) in [(Rows::Baseline, false), (Rows::Fastest, fused)] {
        let got = render_rows_with(&mhi, &target, &opts, rows).unwrap();
        let (mut composited, mut stopped) = (0, 0);
        for i in 0..n {
            for y in 0..19 {
                for x in 0..64 {
                    let tile = &plan.tiles[(y as usize / TILE_H) * tiles_x + x as usize / TILE_W];
                    let stop = stop_at(tile, plan.eps, plan.share);
                    let layers = tile.layers[i].iter().copied();
                    let (c, m, _) = composite_of(&mhi, &plan.hs, (i, x, y), layers, stop, fused);
                    composited += m;
                    stopped += usize::from(m < tile.layers[i].len());
                    let p = got.multi_normal[i].get_pixel(x, y).0;
                    assert_eq!(
                        p.map(f32::to_bits),
                        c.map(f32::to_bits),
                        "{rows:?} normal {i} pixel ({x}, {y})"
                    );
                }
            }
        }
        let visible = 64 * 19 * plan.hs.iter().filter(|h| h.is_some()).count();
        assert_eq!(got.stats.samples, composited as f32 / visible as f32);
        // Most pixels stop before their tile's last layer.
        assert!(stopped > n * 64 * 19 / 2, "{stopped} pixels stopped");
    }
}

#[test]
fn prefetch_takes_any_range_and_changes_nothing() {
    // Empty, reversed, past the end and whole ranges: a hint never reads outside the
    // slice (the addresses are clamped into it) and never writes.
    let data: Vec<f32> = (0..1000).map(|i| i as f32).collect();
    for (from, to) in [
        (0, 0),
        (10, 5),
        (990, 5000),
        (5000, 6000),
        (0, 1000),
        (3, 17),
    ] {
        prefetch(&data, from, to);
        prefetch(&[], from, to);
    }
    assert!(data.iter().enumerate().all(|(i, v)| *v == i as f32));
}

#[test]
fn floor_small_is_the_floor_of_every_position_a_render_samples() {
    // Whole numbers, the floats just below and above them, halves (where rounding to the
    // nearest ties), and a sweep of the range of positions inside a large image.
    let mut values = vec![0.0_f32, 0.5, 1.5, 2.5, 4095.5, 4_194_303.0];
    for k in 0..5000_u32 {
        let f = k as f32;
        values.extend([f, f + 0.5, f.next_up(), (f + 1.0).next_down()]);
    }
    values.extend((0..100_000).map(|k| k as f32 * 0.0417));
    for s in values {
        let f = floor_small(s, true);
        assert_eq!(f, s.floor(), "floor of {s}");
        assert_eq!(small_to_u32(f), s.floor() as u32, "index of {s}");
    }
    assert_eq!(floor_small(123.4, false), 0.0);
}
