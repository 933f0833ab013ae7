//! Reading RealEstate10K-layout datasets: discovery, missing frames, naming schemes, resizing.

use std::path::Path;

use mhi_data::{CameraFile, Dataset, Error, Fit, SynthConfig, generate, load_frame, write_png};

fn tiny_dataset(dir: &Path) {
    let config = SynthConfig {
        scenes: 3,
        frames: 5,
        width: 48,
        height: 32,
        seed: 2,
        test_fraction: 0.0,
        val_fraction: 0.0,
        ..SynthConfig::default()
    };
    generate(&config, dir, &|| {}).unwrap();
}

#[test]
fn missing_frames_are_dropped_and_empty_sequences_skipped_with_warnings() {
    let d = tempfile::tempdir().unwrap();
    tiny_dataset(d.path());
    let train = d.path().join("train");
    // scene_00000: delete one frame; scene_00001: delete all frames.
    let first = train.join("scene_00000");
    let mut pngs: Vec<_> = std::fs::read_dir(&first)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    pngs.sort();
    std::fs::remove_file(&pngs[2]).unwrap();
    std::fs::remove_dir_all(train.join("scene_00001")).unwrap();
    let ds = Dataset::open(d.path(), "train", 3).unwrap();
    assert_eq!(ds.sequences.len(), 2);
    assert_eq!(ds.skipped_sequences, 1);
    assert_eq!(ds.missing_frames, 1);
    assert_eq!(ds.sequences[0].frames.len(), 4);
    assert_eq!(ds.warnings.len(), 2);
    let text: Vec<String> = ds.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        text.iter()
            .any(|w| w.contains("scene_00001.txt") && w.contains("sequence skipped")),
        "{text:?}"
    );
    assert!(
        text.iter()
            .any(|w| w.contains("scene_00000.txt") && w.contains("1 of 5 frames have no image")),
        "{text:?}"
    );
}

#[test]
fn stereo_magnification_frame_names_are_accepted() {
    let d = tempfile::tempdir().unwrap();
    tiny_dataset(d.path());
    let seq = d.path().join("train/scene_00002");
    for e in std::fs::read_dir(&seq).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|e| e == "png") {
            let img = mhi_data::read_rgb(&p).unwrap();
            let ts = p.file_stem().unwrap().to_string_lossy().into_owned();
            image::DynamicImage::ImageRgb8(img)
                .save(seq.join(format!("scene_00002_{ts}.jpg")))
                .unwrap();
            std::fs::remove_file(&p).unwrap();
        }
    }
    let ds = Dataset::open(d.path(), "train", 3).unwrap();
    let s = ds
        .sequences
        .iter()
        .find(|s| s.name == "scene_00002")
        .unwrap();
    assert_eq!(s.frames.len(), 5);
    assert!(s.frames[0].path.to_string_lossy().ends_with(".jpg"));
}

#[test]
fn resize_and_crop_carry_the_intrinsics() {
    let d = tempfile::tempdir().unwrap();
    tiny_dataset(d.path());
    let ds = Dataset::open(d.path(), "train", 3).unwrap();
    let f = &ds.sequences[0].frames[0];
    let full = load_frame(f, None, Fit::Stretch).unwrap();
    assert_eq!(full.image.dimensions(), (48, 32));
    let small = load_frame(f, Some((24, 24)), Fit::Stretch).unwrap();
    assert_eq!(small.image.dimensions(), (24, 24));
    assert!((small.camera.intrinsics.fx - full.camera.intrinsics.fx * 0.5).abs() < 1e-9);
    assert!((small.camera.intrinsics.fy - full.camera.intrinsics.fy * 0.75).abs() < 1e-9);
    // Centre crop of a 48×32 image to a square: the central 32×32, then resized to 16×16.
    let sq = load_frame(f, Some((16, 16)), Fit::CenterCrop).unwrap();
    assert_eq!(sq.image.dimensions(), (16, 16));
    assert!((sq.camera.intrinsics.fx - full.camera.intrinsics.fx * 0.5).abs() < 1e-9);
    assert!((sq.camera.intrinsics.cx - 8.0).abs() < 1e-9);
    assert!(
        sq.image
            .pixels()
            .all(|p| p.0.iter().all(|v| (0.0..=1.0).contains(v)))
    );
}

#[test]
fn bad_files_give_errors_naming_them() {
    let d = tempfile::tempdir().unwrap();
    tiny_dataset(d.path());
    let train = d.path().join("train");
    // A truncated PNG.
    let ds = Dataset::open(d.path(), "train", 3).unwrap();
    let f = ds.sequences[0].frames[0].clone();
    let bytes = std::fs::read(&f.path).unwrap();
    std::fs::write(&f.path, &bytes[..bytes.len() / 3]).unwrap();
    let err = load_frame(&f, None, Fit::Stretch).unwrap_err();
    assert!(matches!(err, Error::Image { .. }), "{err}");
    assert!(
        err.to_string().contains(&*f.path.to_string_lossy()),
        "{err}"
    );
    // A JPEG under a .png name is refused, saying what it holds.
    let img = image::RgbImage::from_pixel(48, 32, image::Rgb([10, 200, 30]));
    image::DynamicImage::ImageRgb8(img)
        .save_with_format(&f.path, image::ImageFormat::Jpeg)
        .unwrap();
    let err = load_frame(&f, None, Fit::Stretch).unwrap_err().to_string();
    assert!(
        err.contains(&*f.path.to_string_lossy()) && err.contains("Jpeg") && err.contains("rename"),
        "{err}"
    );
    // Frames of different sizes within a sequence are refused, naming both.
    let other = ds.sequences[0].frames[1].clone();
    let small = f.path.with_extension("jpg");
    image::DynamicImage::ImageRgb8(image::RgbImage::new(20, 10))
        .save(&small)
        .unwrap();
    let g = mhi_data::Frame {
        path: small,
        ..f.clone()
    };
    let err = mhi_data::check_same_size(&[&other, &g])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("differ in size") && err.contains("20x10"),
        "{err}"
    );
    assert_eq!(
        mhi_data::check_same_size(&[&other, &other]).unwrap(),
        (48, 32)
    );
    // A camera file with NaN.
    let cam = train.join("scene_00000.txt");
    let mut text = std::fs::read_to_string(&cam).unwrap();
    text = text.replacen(" 0.000000000 0.000000000 ", " nan 0.000000000 ", 1);
    std::fs::write(&cam, text).unwrap();
    let err = Dataset::open(d.path(), "train", 3).unwrap_err().to_string();
    assert!(
        err.contains("scene_00000.txt:2:") && err.contains("not finite"),
        "{err}"
    );
    // A missing split.
    let err = Dataset::open(d.path(), "nope", 3).unwrap_err().to_string();
    assert!(
        err.contains("nope") && err.contains("no such split"),
        "{err}"
    );
    // Writing over a read-only path fails with the path in the message.
    let err = write_png(
        Path::new("/proc/forbidden.png"),
        &image::RgbImage::new(1, 1),
    )
    .unwrap_err();
    assert!(err.to_string().contains("/proc"), "{err}");
}

#[test]
fn the_genuine_camera_file_parses() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/0bf152ef84195293.txt");
    let f = CameraFile::read(&p).unwrap();
    assert_eq!(f.rows.len(), 16);
    for r in &f.rows {
        let t = r.cam_from_world;
        assert!((t.rotation().determinant() - 1.0).abs() < 1e-12);
    }
}

/// A synthetic set whose generation was interrupted (its marker is still there) is refused by
/// name, rather than opened with a fraction of its frames.
#[test]
fn an_interrupted_generation_is_refused() {
    let d = tempfile::tempdir().unwrap();
    tiny_dataset(d.path());
    assert!(!d.path().join(mhi_data::INCOMPLETE_MARKER).exists());
    Dataset::open(d.path(), "train", 3).unwrap();
    std::fs::write(d.path().join(mhi_data::INCOMPLETE_MARKER), "x").unwrap();
    let e = Dataset::open(d.path(), "train", 3).unwrap_err().to_string();
    assert!(
        e.contains("incomplete dataset") && e.contains("interrupted"),
        "{e}"
    );
}

/// A sequence whose name is not UTF-8 still finds its frames (the folder is joined as the OS
/// gives it, not through a lossy string).
#[cfg(unix)]
#[test]
fn a_sequence_name_that_is_not_utf8_finds_its_frames() {
    use std::os::unix::ffi::OsStrExt;
    let d = tempfile::tempdir().unwrap();
    tiny_dataset(d.path());
    let train = d.path().join("train");
    let odd = std::ffi::OsStr::from_bytes(b"scene_\xff");
    std::fs::rename(
        train.join("scene_00000.txt"),
        train.join(odd).with_extension("txt"),
    )
    .unwrap();
    std::fs::rename(train.join("scene_00000"), train.join(odd)).unwrap();
    let ds = Dataset::open(d.path(), "train", 3).unwrap();
    let seq = ds
        .sequences
        .iter()
        .find(|s| {
            s.name.starts_with("scene_") && s.name != "scene_00001" && s.name != "scene_00002"
        })
        .expect("the renamed sequence is kept");
    assert_eq!(seq.frames.len(), 5, "{:?}", ds.warnings);
}

/// A phone's portrait photo is stored landscape with EXIF orientation 6 ("turn 90° clockwise
/// to show"): it is used upright, as every viewer shows it, in its pixels and its size.
#[test]
fn exif_orientation_is_applied() {
    let d = tempfile::tempdir().unwrap();
    // 6 × 4 stored, left half red, right half blue.
    let img = image::RgbImage::from_fn(6, 4, |x, _| {
        if x < 3 {
            image::Rgb([255, 0, 0])
        } else {
            image::Rgb([0, 0, 255])
        }
    });
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode_image(&img)
        .unwrap();
    // An APP1 Exif segment right after SOI: a little-endian TIFF header and one IFD entry,
    // Orientation (0x0112), SHORT, 1 value: 6.
    let mut exif = b"Exif\0\0II*\0\x08\0\0\0\x01\0".to_vec();
    exif.extend([0x12, 0x01, 3, 0, 1, 0, 0, 0, 6, 0, 0, 0, 0, 0, 0, 0]);
    let mut app1 = vec![0xff, 0xe1];
    app1.extend(((exif.len() + 2) as u16).to_be_bytes());
    app1.extend(exif);
    let mut file = jpeg[..2].to_vec();
    file.extend(app1);
    file.extend(&jpeg[2..]);
    let path = d.path().join("portrait.jpg");
    std::fs::write(&path, file).unwrap();
    let rgb = mhi_data::read_rgb(&path).unwrap();
    assert_eq!(rgb.dimensions(), (4, 6), "the photo is turned upright");
    // Turned clockwise, the stored left half (red) is now on top.
    assert!(rgb.get_pixel(2, 0).0[0] > 200 && rgb.get_pixel(2, 5).0[2] > 200);
}
