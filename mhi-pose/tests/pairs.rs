//! Poses recovered from synthetic photos with known cameras (ray-traced textured planes), and
//! every bad pair refused with what to do about it.

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};
use mhi_data::{CameraFile, SynthConfig, generate};
use mhi_pose::{Error, Options, Photo, estimate};

/// A synthetic scene's frames and cameras.
fn scene(dir: &Path, seed: u64) -> (Vec<PathBuf>, CameraFile) {
    let config = SynthConfig {
        scenes: 1,
        frames: 6,
        width: 512,
        height: 384,
        seed,
        test_fraction: 0.0,
        val_fraction: 0.0,
        ..SynthConfig::default()
    };
    generate(&config, dir, &|| {}).unwrap();
    let cams = dir.join("train/scene_00000.txt");
    let file = CameraFile::read(&cams).unwrap();
    let frames = file
        .rows
        .iter()
        .map(|r| dir.join(format!("train/scene_00000/{}.png", r.timestamp)))
        .collect();
    (frames, file)
}

fn truth(file: &CameraFile, a: usize, b: usize) -> (DMat3, DVec3) {
    let ca = file.rows[a].cam_from_world;
    let cb = file.rows[b].cam_from_world;
    let src_from_ref = cb.compose(&ca.inverse());
    (src_from_ref.rotation(), src_from_ref.translation())
}

fn known(file: &CameraFile, k: usize) -> Option<[f64; 4]> {
    Some(file.rows[k].intrinsics)
}

#[test]
fn a_synthetic_pair_is_recovered() {
    let d = tempfile::tempdir().unwrap();
    let (frames, file) = scene(d.path(), 11);
    let (a, b) = (0, 5);
    let options = Options {
        ref_intrinsics: known(&file, a),
        ..Options::default()
    };
    let pair = estimate(
        &Photo::open(&frames[a]).unwrap(),
        &Photo::open(&frames[b]).unwrap(),
        &options,
    )
    .unwrap();
    let (r, t) = truth(&file, a, b);
    let dr = mhi_geom::rotation_angle_deg(&(pair.rotation() * r.transpose()));
    let dt = pair
        .translation()
        .normalize()
        .dot(t.normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    eprintln!(
        "{}\nrotation error {dr:.4}°, direction error {dt:.4}°",
        pair.summary()
    );
    // SIFT on procedural textures: a few tenths of a degree (exact matches: the next test).
    assert!(dr < 2.0, "rotation error {dr}°");
    assert!(dt < 15.0, "translation direction error {dt}°");
    assert!((pair.depth_range.0 - mhi_pose::NEAR_DEPTH).abs() < 1e-9);
    assert!(pair.depth_range.1 > pair.depth_range.0);
}

/// Exact correspondences of random points seen by two cameras with a known pose.
fn projected(
    r: DMat3,
    t: DVec3,
    k: DMat3,
    planar: bool,
    n: usize,
) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
    // A small deterministic generator (no rand dependency in this test).
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut a, mut b) = (Vec::new(), Vec::new());
    while a.len() < n {
        let z = if planar { 4.0 } else { 2.0 + 6.0 * next() };
        let p = DVec3::new((next() - 0.5) * z, (next() - 0.5) * z * 0.75, z);
        let q = r * p + t;
        if q.z <= 0.1 {
            continue;
        }
        let (pa, pb) = (k * (p / p.z), k * (q / q.z));
        if pb.x < 0.0 || pb.x > 640.0 || pb.y < 0.0 || pb.y > 480.0 {
            continue;
        }
        a.push([pa.x, pa.y]);
        b.push([pb.x, pb.y]);
    }
    (a, b)
}

fn k640() -> DMat3 {
    DMat3::from_cols(
        DVec3::new(500.0, 0.0, 0.0),
        DVec3::new(0.0, 500.0, 0.0),
        DVec3::new(320.0, 240.0, 1.0),
    )
}

#[test]
fn exact_matches_give_the_pose_to_a_hundredth_of_a_degree() {
    let r = DMat3::from_rotation_y(0.12) * DMat3::from_rotation_x(-0.05);
    let t = DVec3::new(-0.4, 0.05, 0.1);
    let (a, b) = projected(r, t, k640(), false, 300);
    let m = mhi_pose::pose_from_matches(&a, &b, k640(), k640(), 0.5, 0).unwrap();
    let dr = mhi_geom::rotation_angle_deg(&(m.rotation * r.transpose()));
    let dt = m
        .translation
        .normalize()
        .dot(t.normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    assert!(dr < 0.01, "rotation error {dr}°");
    assert!(dt < 0.01, "direction error {dt}°");
    assert!(
        m.points.iter().all(|p| p[2] > 0.0),
        "a point behind the reference camera"
    );
    // Swapped, the same pair gives the inverse pose: a swap cannot pass for another pose.
    let s = mhi_pose::pose_from_matches(&b, &a, k640(), k640(), 0.5, 0).unwrap();
    let back = mhi_geom::rotation_angle_deg(&(s.rotation * r));
    let tb = s
        .translation
        .normalize()
        .dot((-(r.transpose() * t)).normalize());
    assert!(back < 0.01, "swapped rotation {back}°");
    assert!(tb > 0.9999, "swapped direction cos {tb}");
    // The flipped decomposition (every point behind the cameras) is what the cheirality vote
    // rejects: the recovered translation is not the negated one.
    assert!(m.translation.normalize().dot(-t.normalize()) < 0.0);
}

#[test]
fn degenerate_pairs_are_refused_saying_what_to_do() {
    // One spot: a rotation only.
    let r = DMat3::from_rotation_y(0.1);
    let (a, b) = projected(r, DVec3::ZERO, k640(), false, 300);
    let e = mhi_pose::pose_from_matches(&a, &b, k640(), k640(), 0.5, 0).unwrap_err();
    assert!(matches!(e, Error::NoParallax { .. }), "{e}");
    assert!(e.to_string().contains("move sideways"), "{e}");
    // One flat wall: the homography explains everything.
    let (a, b) = projected(r, DVec3::new(-0.4, 0.0, 0.0), k640(), true, 300);
    let e = mhi_pose::pose_from_matches(&a, &b, k640(), k640(), 0.5, 0).unwrap_err();
    assert!(matches!(e, Error::Planar { .. }), "{e}");
    // Too few matches: the count is given.
    let e = mhi_pose::pose_from_matches(&a[..12], &b[..12], k640(), k640(), 0.5, 0).unwrap_err();
    assert!(e.to_string().contains("only 12 matches"), "{e}");
}

#[test]
fn bad_photos_and_intrinsics_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let (frames, _) = scene(d.path(), 12);
    let a = Photo::open(&frames[0]).unwrap();
    // The same photo twice.
    let e = estimate(&a, &Photo::open(&frames[0]).unwrap(), &Options::default()).unwrap_err();
    assert!(matches!(e, Error::SamePhoto), "{e}");
    // A photo of nothing: no overlap, too few matches.
    let blank = d.path().join("blank.png");
    image::RgbImage::from_pixel(512, 384, image::Rgb([90, 90, 90]))
        .save(&blank)
        .unwrap();
    let e = estimate(&a, &Photo::open(&blank).unwrap(), &Options::default()).unwrap_err();
    assert!(matches!(e, Error::TooFewMatches { .. }), "{e}");
    // No EXIF: a stated assumption, not an error.
    let k = a.intrinsics(None).unwrap();
    assert!(k.source.starts_with("assumed"), "{}", k.source);
    // An implausible focal length (a 0.3° field of view): refused, naming the field of view.
    let e = a.intrinsics(Some([100.0, 133.0, 0.5, 0.5])).unwrap_err();
    assert!(e.to_string().contains("field of view"), "{e}");
    // A file that is not a photo.
    let e = Photo::open(&d.path().join("missing.jpg")).unwrap_err();
    assert!(e.to_string().contains("missing.jpg"), "{e}");
}
