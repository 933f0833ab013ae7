//! The exported viewer against the CPU renderer, in a real browser: a synthetic scene's sweep MHI
//! is exported (with the default budget, layers left out) and rendered exactly by `render`; for
//! each listed camera headless Chromium takes a screenshot of index.html#view=k, and the two
//! images must agree to 35 dB covered PSNR.
//!
//! Skipped with a printed reason where no Chromium is installed, unless MHI_REQUIRE_BROWSER=1
//! (as `.ci/run` sets after installing Debian's `chromium`), which turns a missing browser
//! into a failure.

use std::process::Command;

use mhi_viewer::browser::{chromium_or_skip, dump_dom, screenshot};

use mhi_data::{SynthConfig, generate};

fn xtask(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .output()
        .expect("run xtask");
    assert!(
        out.status.success(),
        "xtask {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The options of `render`/`export` that name the scene's photos and cameras and the sweep.
fn scene_args<'a>(rf: &'a str, sf: &'a str, cams: &'a std::path::Path) -> Vec<&'a str> {
    vec![
        "--ref",
        rf,
        "--src",
        sf,
        "--src-row",
        "4",
        "--cameras",
        cams.to_str().unwrap(),
        "--sweep",
        "--planes",
        "12",
        "--size",
        "128x96",
    ]
}

/// A synthetic sequence in `dir` and a camera file of six of its rows: reference (frame 0),
/// targets (frames 1, 2, 4), source (frame 3). Returns the two photos and the file.
fn scene(dir: &std::path::Path) -> (String, String, std::path::PathBuf) {
    let data = dir.join("data");
    generate(
        &SynthConfig {
            scenes: 1,
            frames: 6,
            width: 128,
            height: 96,
            seed: 5,
            test_fraction: 0.0,
            ..SynthConfig::default()
        },
        &data,
        &|| {},
    )
    .unwrap();
    let seq = ["train", "val", "test"]
        .iter()
        .filter_map(|split| std::fs::read_dir(data.join(split)).ok())
        .flat_map(|rd| rd.flatten().map(|e| e.path()))
        .find(|p| p.is_dir())
        .expect("a generated sequence");
    let file = seq.with_extension("txt");
    let text = std::fs::read_to_string(&file).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // Rows: reference (frame 0), targets (frames 1, 2, 4), source (frame 3).
    let cams = dir.join("cams.txt");
    std::fs::write(
        &cams,
        [lines[0], lines[1], lines[2], lines[3], lines[4], lines[5]].join("\n"),
    )
    .unwrap();
    let frame = |row: usize| {
        let ts = lines[row].split_whitespace().next().unwrap();
        seq.join(format!("{ts}.png")).display().to_string()
    };
    (frame(1), frame(4), cams)
}

#[test]
fn the_browser_viewer_agrees_with_the_cpu_renderer() {
    let Some(browser) = chromium_or_skip() else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let (rf, sf, cams) = scene(d.path());
    let common = scene_args(&rf, &sf, &cams);
    let viewer = d.path().join("viewer");
    let cpu = d.path().join("cpu");
    let mut args = vec!["export"];
    args.extend(common.iter().copied());
    args.extend(["--out", viewer.to_str().unwrap()]);
    xtask(&args);
    let mut args = vec!["render"];
    args.extend(common.iter().copied());
    // The viewer blends with Soft; `render` would blend consistently by default.
    args.extend([
        "--exact",
        "--blend",
        "soft",
        "--frames",
        "0",
        "--out",
        cpu.to_str().unwrap(),
    ]);
    xtask(&args);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(viewer.join("manifest.json")).unwrap())
            .unwrap();
    let reference = mhi_data::CameraFile::read(&cams).unwrap().rows[0]
        .camera(128, 96)
        .unwrap();
    let file_rows = mhi_data::CameraFile::read(&cams).unwrap().rows;
    let to_f = |img: &image::RgbImage| {
        image::Rgb32FImage::from_fn(128, 96, |x, y| {
            image::Rgb(img.get_pixel(x, y).0.map(|v| f32::from(v) / 255.0))
        })
    };
    for (k, row) in [2usize, 3, 5].iter().enumerate() {
        let shot = screenshot(
            &browser,
            &viewer.join("index.html"),
            &format!("view={k}"),
            128,
            96,
            d.path(),
        );
        let truth = image::open(cpu.join(format!("view_row{row:03}.png")))
            .unwrap()
            .to_rgb8();
        let target = file_rows[row - 1].camera(128, 96).unwrap();
        let covered = mhi_eval::covered_mask(&reference, &target, 100.0);
        let psnr = mhi_eval::psnr_masked(&to_f(&shot), &to_f(&truth), &covered)
            .unwrap()
            .expect("covered pixels");
        eprintln!(
            "camera row {row} ({}): browser vs CPU covered PSNR {psnr:.2} dB",
            manifest["views"][k]["name"]
        );
        assert!(psnr >= 35.0, "camera row {row}: {psnr:.2} dB < 35 dB");
    }
    // A black page (no WebGL, a shader that failed) scores far below the threshold.
    let truth = image::open(cpu.join("view_row002.png")).unwrap().to_rgb8();
    let target = file_rows[1].camera(128, 96).unwrap();
    let covered = mhi_eval::covered_mask(&reference, &target, 100.0);
    let black = mhi_eval::psnr_masked(&image::Rgb32FImage::new(128, 96), &to_f(&truth), &covered)
        .unwrap()
        .unwrap();
    assert!(black < 35.0, "a black frame scores {black:.2} dB");
    // A hostile link (the hash reaches the page's error message) must show text, not run it;
    // the page's own script must still run under its Content-Security-Policy.
    let hostile = "view=%3Cimg%20src%3Dx%20onerror%3D%22document.title%3D%27pwned%27%22%3E";
    let dom = dump_dom(&browser, &viewer.join("index.html"), hostile, d.path());
    assert!(
        dom.contains("error: no view"),
        "the viewer's script did not run:\n{dom}"
    );
    assert!(
        !dom.contains("pwned</title>"),
        "script from the URL ran:\n{dom}"
    );
    assert!(
        !dom.contains("<img"),
        "markup from the URL reached the page:\n{dom}"
    );
    assert!(
        dom.contains("&lt;img src=x"),
        "the URL is shown as text:\n{dom}"
    );
}

/// PSNR of two 8-bit images, through `mhi_eval::psnr`.
fn psnr(a: &image::RgbImage, b: &image::RgbImage) -> f64 {
    let f = |img: &image::RgbImage| image::DynamicImage::ImageRgb8(img.clone()).into_rgb32f();
    mhi_eval::psnr(&f(a), &f(b)).unwrap()
}

/// The path's video holds the views the PNGs hold (camera rows 2 and 3 as the path), frame for
/// frame, and plays in the browser beside the viewer.
#[test]
fn the_video_decodes_to_the_rendered_views_and_plays_in_the_browser() {
    let d = tempfile::tempdir().unwrap();
    let (rf, sf, cams) = scene(d.path());
    let (out, viewer) = (d.path().join("views"), d.path().join("viewer"));
    // Row 5 passes behind a tilted plane near the sweep's front: not on the path.
    let text = std::fs::read_to_string(&cams).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let path_file = d.path().join("path.txt");
    std::fs::write(&path_file, [lines[0], lines[2], lines[3]].join("\n")).unwrap();
    let mut args = vec!["render"];
    args.extend(scene_args(&rf, &sf, &cams));
    args.extend([
        "--exact",
        "--path",
        "file",
        "--path-file",
        path_file.to_str().unwrap(),
        "--fps",
        "10",
        "--out",
        out.to_str().unwrap(),
        "--export",
        viewer.to_str().unwrap(),
    ]);
    xtask(&args);
    let bytes = std::fs::read(out.join("video.mp4")).unwrap();
    let video = mhi_video::decode_mp4(&bytes).unwrap();
    assert_eq!(
        (video.frames.len(), video.width, video.height),
        (2, 128, 96),
        "the path is the path file's two rows"
    );
    assert!((video.fps - 10.0).abs() < 0.01, "{}", video.fps);
    for (frame, row) in video.frames.iter().zip([2, 3]) {
        let png = image::open(out.join(format!("view_row{row:03}.png")))
            .unwrap()
            .to_rgb8();
        let db = psnr(frame, &png);
        eprintln!("camera row {row}: video frame vs PNG {db:.2} dB");
        assert!(db >= 35.0, "camera row {row}: {db:.2} dB < 35 dB");
    }
    // The frames differ: the path moves.
    assert!(psnr(&video.frames[0], &video.frames[1]) < 30.0);
    assert_eq!(std::fs::read(viewer.join("video.mp4")).unwrap(), bytes);
    let Some(browser) = chromium_or_skip() else {
        return;
    };
    let dom = dump_dom(&browser, &viewer.join("index.html"), "", d.path());
    assert!(
        dom.contains("data-loaded=\"128x96\""),
        "the browser did not play the video:\n{}",
        &dom[..dom.len().min(2000)]
    );
}
