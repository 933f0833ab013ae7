//! Synthetic ground truth is self-consistent: pixels of one frame, reprojected through the
//! scene's exact planes into another frame, match that frame's pixels.

use glam::{DVec2, DVec3};
use mhi_data::{Dataset, Scene, SynthConfig, generate, load_frame, load_scene, make_scene};

/// Bilinear sample of an f32 RGB image at a continuous-frame position (pixel centres at +0.5).
fn bilinear(img: &image::Rgb32FImage, p: DVec2) -> Option<[f32; 3]> {
    let (x, y) = (p.x - 0.5, p.y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    if x0 < 0.0
        || y0 < 0.0
        || x0 + 1.0 >= f64::from(img.width())
        || y0 + 1.0 >= f64::from(img.height())
    {
        return None;
    }
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let g = |dx: u32, dy: u32| img.get_pixel(x0 as u32 + dx, y0 as u32 + dy).0;
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let top = g(0, 0)[k] * (1.0 - fx) + g(1, 0)[k] * fx;
        let bot = g(0, 1)[k] * (1.0 - fx) + g(1, 1)[k] * fx;
        *o = top * (1.0 - fy) + bot * fy;
    }
    Some(out)
}

/// Mean and median absolute colour difference between frame `a` and frame `b` reprojected into
/// it through the traced surfaces, over pixels visible in both; `flip` corrupts b's pose to prove
/// the check can fail.
fn reprojection_error(
    scene: &Scene,
    a: &image::Rgb32FImage,
    b: &image::Rgb32FImage,
    ia: usize,
    ib: usize,
    corrupt: bool,
) -> (f64, f64, usize) {
    let ca = &scene.cameras[ia];
    let mut cb = scene.cameras[ib];
    if corrupt {
        // Transposed rotation: the classic world-to-camera / camera-to-world mix-up.
        cb.cam_from_world = mhi_geom::RigidTransform::new(
            cb.cam_from_world.rotation().transpose(),
            cb.cam_from_world.translation(),
        )
        .unwrap();
    }
    let wa = ca.cam_from_world.inverse();
    let origin_b = scene.cameras[ib].cam_from_world.center();
    let mut errs = Vec::new();
    for y in 0..ca.height {
        for x in 0..ca.width {
            let dir = wa.transform_vector(ca.intrinsics.ray(mhi_geom::pixel_center(x, y)));
            let hit = scene
                .trace(wa.translation(), dir)
                .expect("scenes are closed");
            let p = wa.translation() + dir * hit.s;
            // Visible from b: the ray from b's centre to p hits p first.
            let to_p = p - origin_b;
            let seen = scene
                .trace(origin_b, to_p)
                .is_some_and(|h| (h.s - 1.0).abs() < 1e-6);
            if !seen {
                continue;
            }
            let Some(ub) = cb.project_world(p) else {
                continue;
            };
            let Some(cb_col) = bilinear(b, ub) else {
                continue;
            };
            let ca_col = a.get_pixel(x, y).0;
            let e = (0..3)
                .map(|k| f64::from((ca_col[k] - cb_col[k]).abs()))
                .sum::<f64>()
                / 3.0;
            errs.push(e);
        }
    }
    errs.sort_by(f64::total_cmp);
    let mean = errs.iter().sum::<f64>() / errs.len().max(1) as f64;
    (
        mean,
        errs.get(errs.len() / 2).copied().unwrap_or(f64::NAN),
        errs.len(),
    )
}

#[test]
fn reprojection_through_the_true_planes_matches() {
    let config = SynthConfig {
        scenes: 4,
        frames: 6,
        width: 96,
        height: 72,
        seed: 11,
        supersample: 3,
        ..SynthConfig::default()
    };
    for i in 0..config.scenes {
        let scene = make_scene(&config, i).unwrap();
        let (a, b) = (
            scene.render(0, config.supersample),
            scene.render(5, config.supersample),
        );
        let (mean, median, n) = reprojection_error(&scene, &a, &b, 0, 5, false);
        eprintln!(
            "scene {i} ({}): {n} pixels, mean |err| {mean:.4}, median {median:.4}",
            scene.kind
        );
        // Interpolation error only: textures have sharp edges, so a few pixels differ a lot, the
        // bulk very little.
        assert!(
            n > 96 * 72 / 3,
            "scene {i}: only {n} pixels visible in both frames"
        );
        assert!(median < 0.02, "scene {i}: median error {median}");
        assert!(mean < 0.06, "scene {i}: mean error {mean}");
        let (bad_mean, _, _) = reprojection_error(&scene, &a, &b, 0, 5, true);
        assert!(
            bad_mean > 2.0 * mean,
            "scene {i}: a corrupted pose went unnoticed ({bad_mean} vs {mean})"
        );
    }
}

#[test]
fn generation_is_deterministic_and_written_in_re10k_layout() {
    let config = SynthConfig {
        scenes: 3,
        frames: 4,
        width: 40,
        height: 30,
        seed: 5,
        ..SynthConfig::default()
    };
    let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let s1 = generate(&config, d1.path(), &|| {}).unwrap();
    let s2 = generate(&config, d2.path(), &|| {}).unwrap();
    assert_eq!(s1, s2);
    // 3 scenes: one each for train, val (validation) and test.
    assert_eq!(
        (s1.train.len(), s1.val.len(), s1.test.len(), s1.frames),
        (1, 1, 1, 12)
    );
    for split in ["train", "val", "test"] {
        let a = Dataset::open(d1.path(), split, 3).unwrap();
        let b = Dataset::open(d2.path(), split, 3).unwrap();
        assert!(a.warnings.is_empty(), "{:?}", a.warnings);
        for (sa, sb) in a.sequences.iter().zip(&b.sequences) {
            for (fa, fb) in sa.frames.iter().zip(&sb.frames) {
                assert_eq!(
                    std::fs::read(&fa.path).unwrap(),
                    std::fs::read(&fb.path).unwrap()
                );
            }
            // The camera file and scene.json agree with the generator.
            let scene =
                load_scene(&d1.path().join(split).join(&sa.name).join("scene.json")).unwrap();
            let loaded = load_frame(&sa.frames[1], None, mhi_data::Fit::Stretch).unwrap();
            let cam = loaded.camera;
            assert_eq!(cam.width, 40);
            let p = DVec3::new(0.3, 0.2, 4.0);
            let (u1, u2) = (cam.project_world(p), scene.cameras[1].project_world(p));
            if let (Some(u1), Some(u2)) = (u1, u2) {
                assert!((u1 - u2).length() < 1e-6, "{u1} vs {u2}");
            }
        }
    }
}

#[test]
fn clips_rotate_enough_and_content_sits_at_re10k_depths() {
    let config = SynthConfig {
        scenes: 20,
        frames: 10,
        width: 64,
        height: 64,
        seed: 3,
        ..SynthConfig::default()
    };
    let mut max_rot = 0.0_f64;
    let mut depths = Vec::new();
    for i in 0..config.scenes {
        let s = make_scene(&config, i).unwrap();
        let first = &s.cameras[0].cam_from_world;
        let last = &s.cameras[9].cam_from_world;
        max_rot = max_rot.max(mhi_geom::RigidTransform::relative(first, last).rotation_angle_deg());
        let w = s.cameras[0].cam_from_world.inverse();
        for y in (0..64).step_by(4) {
            for x in (0..64).step_by(4) {
                let ray = s.cameras[0].intrinsics.ray(mhi_geom::pixel_center(x, y));
                let h = s.trace(w.translation(), w.transform_vector(ray)).unwrap();
                if s.surfaces[h.surface].kind != "sky" {
                    depths.push(h.s); // ray has z = 1 in the camera, so s is the depth
                }
            }
        }
    }
    assert!(
        max_rot >= 10.0,
        "largest rotation across a clip is only {max_rot}°"
    );
    depths.sort_by(f64::total_cmp);
    let pct = |q: f64| depths[((depths.len() - 1) as f64 * q) as usize];
    assert!(
        pct(0.1) > 1.0 && pct(0.9) < 15.0,
        "depth 10–90%: {} – {}",
        pct(0.1),
        pct(0.9)
    );
}
