//! Bad input through the command line: every case exits non-zero with a one-paragraph error that
//! names the file and the fault, never panics, and leaves existing outputs intact. Plus a
//! training process killed mid-run and resumed.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use mhi_data::{SynthConfig, generate};

fn xtask(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .output()
        .expect("xtask runs")
}

/// Run, expect failure, and return stderr after checking it is a clean error.
fn fails(args: &[&str]) -> String {
    let out = xtask(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "{args:?} succeeded: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    // Warnings about the data (frames left out, …) may come first; the error is one line that
    // starts with `error: `.
    assert!(
        err.lines().any(|l| l.starts_with("error: ")),
        "{args:?}: {err}"
    );
    err
}

fn dataset(dir: &Path) -> PathBuf {
    let config = SynthConfig {
        scenes: 2,
        frames: 4,
        width: 32,
        height: 24,
        seed: 3,
        test_fraction: 0.5,
        ..SynthConfig::default()
    };
    generate(&config, dir, &|| {}).unwrap();
    dir.to_path_buf()
}

fn first_frame(root: &Path) -> PathBuf {
    let seq = root.join("test/scene_00001");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&seq)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    v.sort();
    v[0].clone()
}

/// `triplets --per-sequence 2 --save DIR/index.json` on `data`; the index's path.
fn save_index(data: &str, dir: &Path) -> PathBuf {
    let index = dir.join("index.json");
    let o = xtask(&[
        "triplets",
        "--data",
        data,
        "--per-sequence",
        "2",
        "--save",
        index.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    index
}

fn sweep_args<'a>(root: &'a str, out: &'a str) -> Vec<&'a str> {
    vec![
        "sweep", "--data", root, "--ref", "0", "--src", "2", "--target", "1", "--size", "32x24",
        "--planes", "4", "--out", out,
    ]
}

#[test]
fn sweep_runs_on_good_data() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let out = d.path().join("out");
    let o = xtask(&sweep_args(root.to_str().unwrap(), out.to_str().unwrap()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("sweep_render.png").is_file());
}

#[test]
fn truncated_png() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let f = first_frame(&root);
    let bytes = std::fs::read(&f).unwrap();
    std::fs::write(&f, &bytes[..bytes.len() / 2]).unwrap();
    let out = d.path().join("out");
    let err = fails(&sweep_args(root.to_str().unwrap(), out.to_str().unwrap()));
    assert!(
        err.contains(&*f.to_string_lossy()) && err.contains("cannot decode"),
        "{err}"
    );
}

#[test]
fn jpeg_with_png_extension() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let f = first_frame(&root);
    let img = image::open(&f).unwrap();
    img.save_with_format(&f, image::ImageFormat::Jpeg).unwrap();
    let err = fails(&sweep_args(
        root.to_str().unwrap(),
        d.path().join("o").to_str().unwrap(),
    ));
    assert!(
        err.contains(&*f.to_string_lossy()) && err.contains("Jpeg") && err.contains("rename"),
        "{err}"
    );
}

/// Rewrite the tokens of line 3 (the second frame) of scene_00001's camera file.
fn corrupt_camera(root: &Path, edit: impl FnOnce(&mut Vec<String>)) {
    let cam = root.join("test/scene_00001.txt");
    let text = std::fs::read_to_string(&cam).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let mut tokens: Vec<String> = lines[2].split(' ').map(str::to_owned).collect();
    edit(&mut tokens);
    lines[2] = tokens.join(" ");
    std::fs::write(&cam, lines.join("\n") + "\n").unwrap();
}

/// Cameras that parse but cannot be right (a principal point 50 images away, a focal length of
/// 1e30, a translation of 1e30, a distortion this project ignores) are refused with the file,
/// line and column, instead of rendering black with exit 0.
#[test]
fn implausible_cameras_name_file_line_and_column() {
    for (col, value, expect) in [
        (3, "50", "column 4: normalised principal point cx = 50"),
        (1, "1e30", "column 2: normalised focal length fx = 1e30"),
        (10, "1e30", "column 11: translation t1"),
        (5, "0.1", "column 6: distortion k1 = 0.1"),
    ] {
        let d = tempfile::tempdir().unwrap();
        let root = dataset(d.path());
        corrupt_camera(&root, |t| t[col] = value.into());
        let err = fails(&sweep_args(
            root.to_str().unwrap(),
            d.path().join("o").to_str().unwrap(),
        ));
        assert!(
            err.contains("scene_00001.txt:3:") && err.contains(expect),
            "{err}"
        );
    }
}

#[test]
fn camera_file_with_nan() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    corrupt_camera(&root, |t| t[5] = "nan".into()); // k1, the first 0.000000000
    let err = fails(&sweep_args(
        root.to_str().unwrap(),
        d.path().join("o").to_str().unwrap(),
    ));
    assert!(
        err.contains("scene_00001.txt:3:") && err.contains("not finite"),
        "{err}"
    );
}

#[test]
fn rotation_that_is_not_a_rotation() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    corrupt_camera(&root, |t| t[7] = "1.5".into()); // r11
    let err = fails(&sweep_args(
        root.to_str().unwrap(),
        d.path().join("o").to_str().unwrap(),
    ));
    assert!(
        err.contains("scene_00001.txt:3:") && err.contains("not a rotation"),
        "{err}"
    );
}

#[test]
fn frames_of_different_sizes() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let f = first_frame(&root);
    image::DynamicImage::ImageRgb8(image::RgbImage::new(16, 12))
        .save(&f)
        .unwrap();
    let err = fails(&sweep_args(
        root.to_str().unwrap(),
        d.path().join("o").to_str().unwrap(),
    ));
    assert!(
        err.contains("differ in size") && err.contains("16x12"),
        "{err}"
    );
}

#[test]
fn zero_baseline_pair() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let r = root.to_str().unwrap();
    let o = d.path().join("o");
    let err = fails(&[
        "sweep",
        "--data",
        r,
        "--ref",
        "1",
        "--src",
        "1",
        "--target",
        "2",
        "--size",
        "32x24",
        "--planes",
        "4",
        "--out",
        o.to_str().unwrap(),
    ]);
    // The same frame twice is caught before the sweep (whose own zero-baseline guard is
    // tested in mhi-render).
    assert!(err.contains("three different frames"), "{err}");
}

#[test]
fn missing_directory() {
    let err = fails(&["sweep", "--data", "/nonexistent/dataset"]);
    assert!(
        err.contains("/nonexistent/dataset/test") && err.contains("no such split directory"),
        "{err}"
    );
    let err = fails(&["triplets", "--data", "/nonexistent/dataset"]);
    assert!(err.contains("no such split directory"), "{err}");
}

#[test]
fn unwritable_output_directory() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let err = fails(&sweep_args(root.to_str().unwrap(), "/proc/mhi-out"));
    assert!(err.contains("/proc/mhi-out"), "{err}");
    let err = fails(&[
        "synth",
        "--out",
        "/proc/mhi-synth",
        "--scenes",
        "1",
        "--frames",
        "3",
        "--size",
        "8x8",
    ]);
    assert!(err.contains("/proc/mhi-synth"), "{err}");
}

#[test]
fn existing_outputs_are_not_overwritten() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let f = first_frame(&root);
    let before = std::fs::read(&f).unwrap();
    let err = fails(&[
        "synth",
        "--out",
        root.to_str().unwrap(),
        "--scenes",
        "1",
        "--frames",
        "3",
        "--size",
        "8x8",
    ]);
    assert!(err.contains("--overwrite"), "{err}");
    assert_eq!(
        std::fs::read(&f).unwrap(),
        before,
        "an existing frame was changed"
    );
}

fn train_args<'a>(run: &'a str, data: &'a str, p1: &'a str) -> Vec<&'a str> {
    vec![
        "train",
        "--run",
        run,
        "--data",
        data,
        "--normals",
        "2",
        "--planes",
        "2",
        "--size",
        "16x16",
        "--width",
        "2",
        "--blend-width",
        "2",
        "--phase1-steps",
        p1,
        "--phase2-steps",
        "2",
        "--checkpoint-every",
        "1",
        "--eval-samples",
        "1",
        "--val-samples",
        "1",
        "--loss",
        "photometric",
    ]
}

/// A training size the U-Nets cannot halve is refused naming the size, not answered with the
/// "--resume" hint meant for a directory that already holds a run; nothing is written.
#[test]
fn a_bad_training_option_is_not_answered_with_resume() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let args: Vec<&str> = train_args(r, data, "2")
        .into_iter()
        .map(|a| if a == "16x16" { "17x17" } else { a })
        .collect();
    let err = fails(&args);
    assert!(err.contains("17x17") && err.contains("divisible"), "{err}");
    assert!(!err.contains("--resume"), "{err}");
    assert!(!run.join("config.json").exists());
}

/// Neighbour triplets take their kind from the views, so a share of extrapolations given with
/// them is refused naming both options; a run records its sampling, and by capture its share.
#[test]
fn an_extrapolation_share_with_neighbour_triplets_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let mut args = train_args(r, data, "2");
    args.extend(["--triplets", "neighbours", "--extrapolation-share", "0.75"]);
    let err = fails(&args);
    assert!(
        err.contains("--extrapolation-share 0.75") && err.contains("--triplets neighbours"),
        "{err}"
    );
    assert!(!run.join("config.json").exists());
    let mut args = train_args(r, data, "2");
    args.extend(["--triplets", "neighbours"]);
    let o = xtask(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cfg = std::fs::read_to_string(run.join("config.json")).unwrap();
    assert!(
        cfg.contains("\"triplet_sampling\": \"Neighbours\""),
        "{cfg}"
    );
    // By capture, the share applies to the clips of video and is kept.
    let run = d.path().join("run-by-capture");
    let mut args = train_args(run.to_str().unwrap(), data, "2");
    args.extend(["--triplets", "by-capture", "--extrapolation-share", "0.75"]);
    let o = xtask(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cfg = std::fs::read_to_string(run.join("config.json")).unwrap();
    assert!(
        cfg.contains("\"triplet_sampling\": \"ByCapture\"")
            && cfg.contains("\"extrapolation_share\": 0.75"),
        "{cfg}"
    );
}

#[test]
fn checkpoint_from_another_configuration_and_existing_run() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let o = xtask(&train_args(r, data, "2"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Starting again in the same directory is refused; the run is untouched.
    let log = std::fs::read(run.join("log.csv")).unwrap();
    let err = fails(&train_args(r, data, "2"));
    assert!(
        err.contains("already holds a training run") && err.contains("--resume"),
        "{err}"
    );
    assert_eq!(std::fs::read(run.join("log.csv")).unwrap(), log);
    // --resume keeps the run's configuration: an option that would change it, or other data
    // roots, is refused naming it (it used to be ignored), and nothing is trained.
    let err = fails(&[
        "train",
        "--run",
        r,
        "--data",
        data,
        "--resume",
        "--lr",
        "0.5",
        "--lr-drop-at",
        "1",
    ]);
    assert!(
        err.contains("--lr, --lr-drop-at set the run's configuration")
            && err.contains("config.json"),
        "{err}"
    );
    let other = d.path().join("other");
    let err = fails(&[
        "train",
        "--run",
        r,
        "--data",
        other.to_str().unwrap(),
        "--resume",
    ]);
    assert!(err.contains("--resume keeps them"), "{err}");
    assert_eq!(std::fs::read(run.join("log.csv")).unwrap(), log);
    // The existing run is named before the loss is set up: a perceptual loss whose VGG16
    // weights are missing is not what the user hears about.
    let empty = d.path().join("empty-cache");
    let mut args: Vec<&str> = train_args(r, data, "2")
        .into_iter()
        .map(|a| if a == "photometric" { "perceptual" } else { a })
        .collect();
    args.extend(["--cache", empty.to_str().unwrap()]);
    let err = fails(&args);
    assert!(
        err.contains("already holds a training run") && err.contains("--resume"),
        "{err}"
    );
    // A config edited to another width no longer matches the checkpoint.
    let cfg = run.join("config.json");
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replacen("\"width\": 2", "\"width\": 4", 1);
    std::fs::write(&cfg, text).unwrap();
    let err = fails(&["train", "--run", r, "--data", data, "--resume"]);
    assert!(
        err.contains("does not match this run's config.json"),
        "{err}"
    );
}

#[test]
fn killed_training_resumes_from_its_last_checkpoint() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let mut child = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(train_args(r, data, "400"))
        .spawn()
        .unwrap();
    // Wait for a few checkpoints, then kill the process outright.
    let latest = run.join("latest.json");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    loop {
        let step = std::fs::read_to_string(&latest)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["step"].as_u64());
        if step.is_some_and(|s| s >= 3) {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "no checkpoint within 120 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let killed_at: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&latest).unwrap()).unwrap();
    let resumed_from = killed_at["step"].as_u64().unwrap();
    assert!(
        resumed_from < 402,
        "the run finished before it could be killed"
    );
    // Resume with a small phase 1 left: edit the step budget so the test stays short.
    let cfg = run.join("config.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cfg).unwrap()).unwrap();
    v["phase1_steps"] = serde_json::json!(resumed_from + 2);
    std::fs::write(&cfg, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let o = xtask(&["train", "--run", r, "--data", data, "--resume"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let log = std::fs::read_to_string(run.join("log.csv")).unwrap();
    let steps: Vec<u64> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    let expected: Vec<u64> = (0..resumed_from + 4).collect();
    assert_eq!(
        steps, expected,
        "log steps are not contiguous after the resume"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["steps"].as_u64(), Some(resumed_from + 4));
}

/// `eval` end to end on a tiny synthetic set with a tiny trained run: every method appears in
/// report.json with the documented fields, the markdown tables and figures are written, and a
/// second run refuses to replace the report without --overwrite.
#[test]
fn eval_writes_a_complete_report_and_keeps_an_existing_one() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let o = xtask(&train_args(r, data, "2"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = d.path().join("report");
    let o_ = out.to_str().unwrap();
    let cache = d.path().join("no-cache");
    let eval = [
        "eval",
        "--data",
        data,
        "--run",
        r,
        "--size",
        "32x32",
        "--sweep-grid",
        "1x2,2x2",
        "--oracle-grid",
        "2x2",
        "--orbit-frames",
        "3",
        "--samples",
        "1",
        "--also-budgets",
        "16,4",
        "--out",
        o_,
        "--cache",
        cache.to_str().unwrap(),
    ];
    let o = xtask(&eval);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    // The pruned-against-exact table: a row per MHI and budget (--budget 1 and --also-budgets,
    // in increasing order), each within its own budget at every pixel.
    let p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("pruning.json")).unwrap()).unwrap();
    let prune_rows = p["rows"].as_array().unwrap();
    for (method, normals) in [("soft", 2), ("sweep", 1), ("sweep", 2), ("oracle", 2)] {
        let budgets: Vec<f64> = prune_rows
            .iter()
            .filter(|r| r["method"] == method && r["normals"] == normals)
            .map(|r| r["budget_levels"].as_f64().unwrap())
            .collect();
        assert_eq!(
            budgets,
            [1.0, 4.0, 16.0],
            "{method} N={normals}: {prune_rows:?}"
        );
    }
    for r in prune_rows {
        let (budget, bound) = (
            r["budget_levels"].as_f64().unwrap(),
            r["bound"].as_f64().unwrap(),
        );
        assert!(bound <= budget / 255.0 + 1e-6, "{r}");
        assert!(r["max_abs"].as_f64().unwrap() <= bound + 1e-5, "{r}");
        assert_eq!(r["over_bound"], 0, "{r}");
    }
    let methods: std::collections::BTreeSet<&str> =
        rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    for m in [
        "learned",
        "soft",
        "hard",
        "avg",
        "consistent",
        "sweep",
        "oracle",
        "nearest",
    ] {
        assert!(methods.contains(m), "{m} missing from {methods:?}");
    }
    for row in rows {
        for k in [
            "method",
            "normals",
            "planes",
            "bin",
            "kind",
            "count",
            "psnr",
            "ssim",
            "lpips",
            "psnr_ci",
            "psnr_covered",
            "psnr_covered_ci",
            "ssim_covered",
            "lpips_covered",
            "covered_fraction",
            "ms_per_view",
        ] {
            assert!(row.get(k).is_some(), "{k} missing in {row}");
        }
        assert!(row["psnr"].as_f64().unwrap().is_finite());
        let ci = row["psnr_ci"].as_array().unwrap();
        let (lo, hi) = (ci[0].as_f64().unwrap(), ci[1].as_f64().unwrap());
        assert!(lo <= row["psnr"].as_f64().unwrap() && row["psnr"].as_f64().unwrap() <= hi);
        // No weights in the cache: LPIPS is absent, not invented.
        assert!(row["lpips"].is_null());
    }
    // Paired comparisons: learned against Soft on its own stage 1, MHI against MPI.
    let comps = v["comparisons"].as_array().unwrap();
    let pairs: std::collections::BTreeSet<(String, String)> = comps
        .iter()
        .map(|c| (c["a"].to_string(), c["b"].to_string()))
        .collect();
    assert!(
        pairs.contains(&("\"learned N=2 D=2\"".into(), "\"soft N=2 D=2\"".into())),
        "{pairs:?}"
    );
    assert!(pairs.contains(&("\"sweep N=2 D=2\"".into(), "\"sweep N=1 D=2\"".into())));
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("#### PSNR")
            && md.contains("#### Covered PSNR")
            && md.contains("Paired comparisons")
            && md.contains("N × D sweep: sweep")
            && md.contains("](budget_tradeoff.svg)"),
        "{md}"
    );
    for f in [
        "report.csv",
        "error_vs_time.svg",
        "error_vs_time.png",
        "budget_tradeoff.png",
        "training_curve.png",
        "orbit.gif",
        "layers/normal_0.png",
        "samples/000/ground_truth.png",
    ] {
        assert!(out.join(f).is_file(), "{f} not written");
    }
    // The run is on the sweep prior: its curve has the sweep's level (step 0) as a line.
    let curve = std::fs::read_to_string(out.join("training_curve.svg")).unwrap();
    assert!(
        curve.contains("the sweep N=2 (its untrained step 0)"),
        "no sweep level in the training curve"
    );
    let before = std::fs::read(out.join("report.json")).unwrap();
    let err = fails(&eval);
    assert!(err.contains("--overwrite"), "{err}");
    assert_eq!(std::fs::read(out.join("report.json")).unwrap(), before);
}

#[test]
fn render_names_the_bad_camera_row_and_refuses_missing_rows() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let seq = root.join("test/scene_00001");
    let cams = root.join("test/scene_00001.txt");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&seq)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    frames.sort();
    let (a, b) = (frames[0].to_str().unwrap(), frames[2].to_str().unwrap());
    let out = d.path().join("views");
    let base = |cams: &str, extra: &[&'static str]| {
        let mut v = vec![
            "render".to_string(),
            "--ref".into(),
            a.into(),
            "--src".into(),
            b.into(),
            "--src-row".into(),
            "3".into(),
            "--cameras".into(),
            cams.into(),
            "--size".into(),
            "32x24".into(),
            "--planes".into(),
            "4".into(),
            "--sweep".into(),
            "--frames".into(),
            "2".into(),
            "--out".into(),
            out.to_str().unwrap().into(),
        ];
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let run = |v: Vec<String>| {
        let refs: Vec<&str> = v.iter().map(String::as_str).collect();
        xtask(&refs)
    };
    // A good file renders rows 2 and 4 and the orbit's video.
    let o = run(base(cams.to_str().unwrap(), &[]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("view_row002.png").is_file() && out.join("video.mp4").is_file());
    // Again without --overwrite: refused.
    let v = base(cams.to_str().unwrap(), &[]);
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("--overwrite"), "{err}");
    // The plan is beside the views; a budget that is not a number of levels is refused.
    assert!(out.join("plan.json").is_file());
    let v = base(cams.to_str().unwrap(), &["--overwrite", "--budget", "-1"]);
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("--budget -1"), "{err}");
    // An exported viewer is not replaced without --overwrite.
    let viewer = d.path().join("viewer");
    let mut v = base(cams.to_str().unwrap(), &["--export"]);
    v.push(viewer.to_str().unwrap().into());
    v[0] = "export".into();
    let o = run(v.clone());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(viewer.join("index.html").is_file() && viewer.join("manifest.json").is_file());
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("already holds a viewer"), "{err}");
    // A row that is not a pose names the file and line.
    let text = std::fs::read_to_string(&cams).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cols: Vec<String> = lines[2].split_whitespace().map(String::from).collect();
    cols[7] = "2.0".into();
    lines[2] = cols.join(" ");
    let bad = d.path().join("bad.txt");
    std::fs::write(&bad, lines.join("\n")).unwrap();
    let v = base(bad.to_str().unwrap(), &["--overwrite"]);
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("bad.txt:3"), "{err}");
    // A photo row beyond the file.
    let mut v = base(cams.to_str().unwrap(), &["--overwrite"]);
    v[6] = "9".into();
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("--src-row 9"), "{err}");
    // An orbit radius that is not a number, or absurdly far: refused before anything renders.
    for r in ["nan", "1e30", "0"] {
        let v = base(
            cams.to_str().unwrap(),
            &["--overwrite", "--orbit-radius", r],
        );
        let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(err.contains("--orbit-radius"), "{r}: {err}");
    }
    // Paths that cannot be: each refused with what is wrong, nothing written.
    // `base` with `flags`, a flag it holds already taking the new value.
    let with = |flags: &[&str]| -> Vec<String> {
        let mut v = base(cams.to_str().unwrap(), &[]);
        let mut k = 0;
        while k < flags.len() {
            let f = flags[k];
            let value = flags.get(k + 1).filter(|x| !x.starts_with("--"));
            match (v.iter().position(|x| x == f), value) {
                (Some(i), Some(x)) => v[i + 1] = x.to_string(),
                (Some(_), None) => {}
                (None, _) => v.extend(std::iter::once(f).chain(value.copied()).map(String::from)),
            }
            k += 1 + usize::from(value.is_some());
        }
        v
    };
    let fails_with = |flags: &[&str]| {
        let v = with(flags);
        fails(&v.iter().map(String::as_str).collect::<Vec<_>>())
    };
    for (extra, says) in [
        (&["--radius", "0"][..], "--radius 0 must be a finite length"),
        (
            &["--radius", "nan"][..],
            "--radius NaN must be a finite length",
        ),
        (&["--path", "circle", "--frames", "0"][..], "zero frames"),
        (
            &["--path", "circle", "--step", "5", "--frames", "60"][..],
            "up to 75.0°",
        ),
        (
            &["--path", "circle", "--step", "-1"][..],
            "finite angle above zero",
        ),
        (
            &["--path", "dolly", "--radius", "200", "--frames", "4"][..],
            "behind the plane",
        ),
        (&["--path", "orbit", "--fps", "0"][..], "--fps 0"),
        (&["--path-file", "x.txt"][..], "add --path file"),
    ] {
        let mut e = vec!["--overwrite"];
        e.extend_from_slice(extra);
        let before = std::fs::read(out.join("video.mp4")).unwrap();
        let err = fails_with(&e);
        assert!(err.contains(says), "{extra:?}: {err}");
        assert_eq!(std::fs::read(out.join("video.mp4")).unwrap(), before);
    }
    // Every path makes a video of its frames (file: the listed rows 2 and 4).
    for (path, frames) in [
        ("orbit", 4),
        ("circle", 4),
        ("spiral", 4),
        ("dolly", 4),
        ("file", 2),
    ] {
        let o = run(with(&[
            "--overwrite",
            "--path",
            path,
            "--frames",
            "4",
            "--gif",
        ]));
        assert!(
            o.status.success(),
            "{path}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let said = String::from_utf8_lossy(&o.stdout);
        assert!(
            said.contains("path: ") && said.contains("rotation up to"),
            "{said}"
        );
        let video = mhi_video::decode_mp4(&std::fs::read(out.join("video.mp4")).unwrap()).unwrap();
        assert_eq!(
            (video.frames.len(), video.width, video.height),
            (frames, 32, 24),
            "{path}"
        );
        assert!(out.join("path.gif").is_file());
    }
    // --video: a file of its own, never one of the user's.
    let mine = d.path().join("mine.mp4");
    std::fs::write(&mine, b"the user's holiday video").unwrap();
    for extra in [
        &["--video", mine.to_str().unwrap()][..],
        &["--overwrite", "--video", mine.to_str().unwrap()][..],
    ] {
        let err = fails_with(extra);
        assert!(err.contains("mine.mp4"), "{err}");
        assert_eq!(std::fs::read(&mine).unwrap(), b"the user's holiday video");
    }
    let ours = d.path().join("ours.mp4");
    for _ in 0..2 {
        let o = run(with(&["--overwrite", "--video", ours.to_str().unwrap()]));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            mhi_video::decode_mp4(&std::fs::read(&ours).unwrap())
                .unwrap()
                .frames
                .len(),
            2
        );
    }
    // The same photo twice.
    let mut v = base(cams.to_str().unwrap(), &["--overwrite"]);
    v[4] = a.into();
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(err.contains("same file"), "{err}");
}

/// `eval` refuses what it cannot score honestly: an unknown method (listing the choices), a
/// size too small for its metrics, an index whose target is its reference, an index reused
/// after frames were deleted; and a directory named like a frame is not taken for one.
#[test]
fn eval_refuses_unknown_methods_tiny_sizes_and_stale_or_degenerate_indices() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let data = root.to_str().unwrap();
    let out = d.path().join("report");
    let o_ = out.to_str().unwrap();
    let base = |extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = [
            "eval",
            "--data",
            data,
            "--methods",
            "sweep,nearest",
            "--sweep-grid",
            "1x2",
            "--size",
            "32x32",
            "--orbit-frames",
            "0",
            "--samples",
            "0",
            "--out",
            o_,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    fn refs(v: &[String]) -> Vec<&str> {
        v.iter().map(String::as_str).collect()
    }
    let mut v = base(&[]);
    v[4] = "sweep,bogus".into();
    let err = fails(&refs(&v));
    assert!(err.contains("bogus") && err.contains("nearest"), "{err}");
    let mut v = base(&[]);
    v[8] = "4x4".into();
    let err = fails(&refs(&v));
    assert!(err.contains("--size 4x4") && err.contains("32"), "{err}");
    for (bad, why) in [
        ("0", "(0, 255]"),
        ("2,x", "x"),
        ("1", "twice"),
        ("4,4", "twice"),
    ] {
        let err = fails(&refs(&base(&["--also-budgets", bad])));
        assert!(
            err.contains("--also-budgets") && err.contains(why),
            "{bad}: {err}"
        );
    }
    for bad in ["-1", "nan", "inf"] {
        let err = fails(&refs(&base(&["--consistency-beta", bad])));
        assert!(err.contains("--consistency-beta"), "{bad}: {err}");
    }
    assert!(!out.exists(), "a refused eval leaves no output folder");
    // An index with a degenerate triplet, then one whose frames changed.
    let index = save_index(data, d.path());
    let good = std::fs::read_to_string(&index).unwrap();
    let mut j: serde_json::Value = serde_json::from_str(&good).unwrap();
    let r = j["triplets"][0]["reference"].clone();
    j["triplets"][0]["target"] = r;
    let bad = d.path().join("bad.json");
    std::fs::write(&bad, j.to_string()).unwrap();
    let err = fails(&refs(&base(&["--index", bad.to_str().unwrap()])));
    assert!(err.contains("uses one frame twice"), "{err}");
    let seq = root.join("test/scene_00001");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&seq)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    frames.sort();
    std::fs::remove_file(&frames[0]).unwrap();
    // A directory named like the deleted frame is not a frame either.
    std::fs::create_dir(&frames[0]).unwrap();
    let err = fails(&refs(&base(&["--index", index.to_str().unwrap()])));
    assert!(
        err.contains("frames were added or deleted") || err.contains("does not have"),
        "{err}"
    );
}

/// Training on a mix of two roots: the weights and the held-out sequence are recorded in
/// config.json, validation draws from the held-out sequence, and a typo in a held-out root or
/// sequence is an error naming what there is (and leaves no run behind).
#[test]
fn training_mixes_roots_with_weights_and_validates_on_held_out_sequences() {
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("alpha"), d.path().join("beta"));
    for (dir, seed) in [(&a, 1), (&b, 2)] {
        std::fs::create_dir_all(dir).unwrap();
        let config = SynthConfig {
            scenes: 3,
            frames: 4,
            width: 32,
            height: 24,
            seed,
            test_fraction: 0.0,
            val_fraction: 0.0,
            ..SynthConfig::default()
        };
        generate(&config, dir, &|| {}).unwrap();
    }
    let run = d.path().join("run");
    let (r, sa, sb) = (
        run.to_str().unwrap(),
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    );
    let mut args = train_args(r, sa, "1");
    args.extend([
        "--data",
        sb,
        "--data-weight",
        "3,1",
        "--holdout",
        "beta/scene_00002",
    ]);
    let o = xtask(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap()).unwrap();
    let data = cfg["data"].as_array().unwrap();
    assert_eq!(data.len(), 2);
    assert_eq!(data[0]["weight"].as_f64(), Some(3.0));
    assert_eq!(data[1]["holdout"][0].as_str(), Some("scene_00002"));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    let val = summary["validation"].as_str().unwrap();
    assert!(
        val.contains("beta: held-out sequences scene_00002"),
        "{val}"
    );

    let bad = d.path().join("bad");
    let b_ = bad.to_str().unwrap();
    let mut args = train_args(b_, sa, "1");
    args.extend(["--holdout", "gamma/scene_00002"]);
    let err = fails(&args);
    assert!(err.contains("gamma") && err.contains("alpha"), "{err}");
    let mut args = train_args(b_, sa, "1");
    args.extend(["--holdout", "alpha/scene_0009"]);
    let err = fails(&args);
    assert!(
        err.contains("scene_0009") && err.contains("scene_00000"),
        "{err}"
    );
    assert!(!bad.join("config.json").exists());
    let mut args = train_args(b_, sa, "1");
    args.extend(["--data-weight", "1,2"]);
    let err = fails(&args);
    assert!(err.contains("--data-weight"), "{err}");
}

/// `metrics` on images too small for SSIM or LPIPS says which metric needs how many pixels,
/// never panics and never prints NaN.
#[test]
fn metrics_on_tiny_images_name_the_minimum_size() {
    let d = tempfile::tempdir().unwrap();
    for side in [1u32, 5, 24] {
        let a = d.path().join(format!("a{side}.png"));
        let b = d.path().join(format!("b{side}.png"));
        image::RgbImage::from_pixel(side, side, image::Rgb([10, 20, 30]))
            .save(&a)
            .unwrap();
        image::RgbImage::from_pixel(side, side, image::Rgb([12, 20, 30]))
            .save(&b)
            .unwrap();
        let o = xtask(&[
            "metrics",
            a.to_str().unwrap(),
            b.to_str().unwrap(),
            "--cache",
            d.path().join("none").to_str().unwrap(),
        ]);
        let (out, err) = (
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr),
        );
        assert!(
            !err.contains("panicked") && !out.contains("NaN"),
            "{out}{err}"
        );
        assert!(out.contains("PSNR"), "{out}");
        if side < 11 {
            assert!(
                out.contains("SSIM       n/a") && out.contains("11×11"),
                "{out}"
            );
        }
        assert!(
            out.contains("LPIPS-alex n/a (needs at least 32x32 pixels"),
            "{side}: {out}{err}"
        );
    }
}

/// `metrics` needing LPIPS with no weights in the cache says how to fetch them (the library's
/// error names the file; the command line adds the command).
#[test]
fn metrics_without_weights_say_how_to_get_them() {
    let d = tempfile::tempdir().unwrap();
    let (a, b) = (d.path().join("a.png"), d.path().join("b.png"));
    for (p, v) in [(&a, 10u8), (&b, 12)] {
        image::RgbImage::from_pixel(40, 40, image::Rgb([v, 20, 30]))
            .save(p)
            .unwrap();
    }
    let err = fails(&[
        "metrics",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--cache",
        d.path().join("none").to_str().unwrap(),
    ]);
    assert!(
        err.contains("alexnet.safetensors") && err.contains("cargo xtask weights"),
        "{err}"
    );
}

/// A start that fails (an unsupported normal count) leaves nothing behind, so the same command
/// with a fixed option starts cleanly; `bench --json` refuses a device and `--runs 0`.
#[test]
fn failed_starts_leave_nothing_and_special_files_are_not_replaced() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let mut args = train_args(r, data, "1");
    let k = args.iter().position(|a| *a == "--normals").unwrap();
    args[k + 1] = "4";
    let err = fails(&args);
    assert!(err.contains("choose 1 (an MPI), 2, 3 or 5"), "{err}");
    assert!(!run.join("config.json").exists() && !run.join("log.csv").exists());
    let o = xtask(&train_args(r, data, "1"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let err = fails(&["bench", "--size", "16", "--planes", "2", "--runs", "0"]);
    assert!(err.contains("--runs 0"), "{err}");
    let err = fails(&["bench", "--size", "16", "--planes", "2", "--rounds", "0"]);
    assert!(err.contains("--rounds 0"), "{err}");
    if std::path::Path::new("/dev/full").exists() {
        let err = fails(&[
            "bench",
            "--size",
            "16",
            "--planes",
            "2",
            "--runs",
            "1",
            "--json",
            "/dev/full",
        ]);
        assert!(err.contains("not a regular file"), "{err}");
        assert!(!std::fs::metadata("/dev/full").unwrap().is_file());
    }
}

/// Sizes that cannot fit in memory are refused with the figure before anything is allocated;
/// a sweep of a frame onto itself is refused.
#[test]
fn absurd_sizes_and_degenerate_frames_are_refused_up_front() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let data = root.to_str().unwrap();
    let out = d.path().join("sweep");
    let o_ = out.to_str().unwrap();
    let mut args = sweep_args(data, o_);
    let k = args.iter().position(|a| *a == "--size").unwrap();
    args[k + 1] = "100000x100000";
    let err = fails(&args);
    assert!(err.contains("GB") && err.contains("--size"), "{err}");
    let mut args = sweep_args(data, o_);
    let k = args.iter().position(|a| *a == "--target").unwrap();
    args[k + 1] = "0";
    let err = fails(&args);
    assert!(err.contains("three different frames"), "{err}");
}

/// An interrupted `synth` is named as such by `synth` and by every reader; a far plane
/// absurdly far for the baseline is named as that, not as a zero baseline; a method list that
/// applies to nothing is refused rather than reported as empty tables.
#[test]
fn interrupted_sets_absurd_far_planes_and_methods_that_apply_to_nothing() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let data = root.to_str().unwrap();
    let out = d.path().join("o");
    let mut args = sweep_args(data, out.to_str().unwrap());
    args.extend(["--far", "1e30"]);
    let err = fails(&args);
    assert!(err.contains("farthest plane depth"), "{err}");
    let err = fails(&[
        "eval",
        "--data",
        data,
        "--methods",
        "learned",
        "--no-pretrained",
        "--size",
        "32x32",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(err.contains("none of --methods"), "{err}");
    std::fs::write(root.join(mhi_data::INCOMPLETE_MARKER), "x").unwrap();
    let err = fails(&["triplets", "--data", data]);
    assert!(err.contains("incomplete dataset"), "{err}");
    let err = fails(&[
        "synth", "--out", data, "--scenes", "2", "--frames", "3", "--size", "16x16",
    ]);
    assert!(
        err.contains("incomplete synthetic set") && err.contains("--overwrite"),
        "{err}"
    );
}

/// With a peer, the render ratio is the median over alternating rounds of ours and the peer's:
/// each round is recorded, and the ratio is the median of the rounds' own ratios (a stand-in
/// peer that reports a fixed time keeps the test off PyTorch).
#[test]
fn the_render_ratio_is_the_median_of_alternating_rounds() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(&d.path().join("data"));
    let peer = d.path().join("peer.py");
    std::fs::write(
        &peer,
        "import json\nprint(json.dumps({\"median_ms\": 1000.0, \"torch\": \"stand-in\"}))\n",
    )
    .unwrap();
    let json = d.path().join("bench.json");
    let o = xtask(&[
        "bench",
        "--size",
        "16",
        "--planes",
        "2",
        "--runs",
        "1",
        "--rounds",
        "3",
        "--data",
        root.to_str().unwrap(),
        "--peer",
        peer.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    for (layout, key) in [("shared", "ratio_shared"), ("per_layer", "ratio_per_layer")] {
        let rounds = v["rounds_ms"][layout].as_array().unwrap();
        assert_eq!(rounds.len(), 3, "{v}");
        let mut ratios: Vec<f64> = rounds
            .iter()
            .map(|r| r[1].as_f64().unwrap() / r[0].as_f64().unwrap())
            .collect();
        assert!(rounds.iter().all(|r| r[1].as_f64() == Some(1000.0)), "{v}");
        ratios.sort_by(f64::total_cmp);
        let ratio = v[key].as_f64().unwrap();
        assert!(
            (ratio - ratios[1]).abs() <= 1e-9 * ratio,
            "{key} {ratio} against {ratios:?}"
        );
    }
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("median of 3 rounds"), "{out}");
}

/// `eval`'s sweep row is what an untrained residual model on the sweep prior renders: both scale
/// the window radius (given at a short side of 256) with the image, so at 32 px they use the
/// same 2-px window. Before they agreed, the sweep row kept 16 px at every size and differed
/// from the untrained model by 0.09 dB on this data.
#[test]
fn the_sweep_row_is_what_an_untrained_residual_model_renders() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    // One step at a negligible learning rate: a checkpoint whose residual heads are still zero.
    let o = xtask(&[
        "train",
        "--run",
        r,
        "--data",
        data,
        "--prior",
        "sweep",
        "--normals",
        "1",
        "--planes",
        "4",
        "--size",
        "32x32",
        "--width",
        "2",
        "--blend-width",
        "2",
        "--phase1-steps",
        "1",
        "--phase2-steps",
        "0",
        "--lr",
        "1e-20",
        "--checkpoint-every",
        "1",
        "--eval-samples",
        "0",
        "--val-samples",
        "1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = d.path().join("report");
    let o = xtask(&[
        "eval",
        "--data",
        data,
        "--run",
        r,
        "--no-pretrained",
        "--methods",
        "mpi,sweep",
        "--sweep-grid",
        "1x4",
        "--size",
        "32x32",
        "--samples",
        "1",
        "--orbit-frames",
        "2",
        "--out",
        out.to_str().unwrap(),
        "--cache",
        d.path().join("no-cache").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let covered = |method: &str| -> f64 {
        v["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["method"] == method && r["bin"] == "all" && r["kind"] == "all")
            .unwrap_or_else(|| panic!("no {method} row in {v}"))["psnr_covered"]
            .as_f64()
            .unwrap()
    };
    let (mpi, sweep) = (covered("mpi"), covered("sweep"));
    assert!(
        (mpi - sweep).abs() < 1e-4,
        "untrained model {mpi} dB, sweep row {sweep} dB"
    );
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("2 px at 32"), "{md}");
}

/// `eval --renders` scores another program's renders under the same protocol: the target frame
/// itself scores as well as PSNR can say, a black picture far worse, and --compare pairs them;
/// a missing render, one of the wrong size, a folder that does not exist, a name eval uses
/// itself and a --compare name that is nowhere are refused before any work, naming what is
/// wrong.
#[test]
fn eval_scores_renders_from_files_and_refuses_incomplete_ones() {
    let d = tempfile::tempdir().unwrap();
    let config = SynthConfig {
        scenes: 2,
        frames: 4,
        width: 32,
        height: 32,
        seed: 5,
        test_fraction: 0.5,
        ..SynthConfig::default()
    };
    generate(&config, d.path(), &|| {}).unwrap();
    let data = d.path().to_str().unwrap();
    let index = save_index(data, d.path());
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&index).unwrap()).unwrap();
    let (truth, black, small) = (
        d.path().join("truth"),
        d.path().join("black"),
        d.path().join("small"),
    );
    for dir in [&truth, &black, &small] {
        std::fs::create_dir(dir).unwrap();
    }
    let trips = j["triplets"].as_array().unwrap();
    assert!(trips.len() >= 2);
    for t in trips {
        let seq = t["sequence"].as_str().unwrap();
        let ts: Vec<u64> = t["timestamps"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        let name = format!("{seq}_{}_{}_{}.png", ts[0], ts[1], ts[2]);
        let target = d
            .path()
            .join("test")
            .join(seq)
            .join(format!("{}.png", ts[2]));
        std::fs::copy(&target, truth.join(&name)).unwrap();
        image::RgbImage::new(32, 32)
            .save(black.join(&name))
            .unwrap();
        image::RgbImage::new(32, 16)
            .save(small.join(&name))
            .unwrap();
    }
    let out = d.path().join("report");
    let args = |extra: &[String]| -> Vec<String> {
        let mut v: Vec<String> = [
            "eval",
            "--data",
            data,
            "--index",
            index.to_str().unwrap(),
            "--methods",
            "nearest",
            "--size",
            "32x32",
            "--orbit-frames",
            "0",
            "--samples",
            "1",
            "--out",
            out.to_str().unwrap(),
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.extend(extra.iter().cloned());
        v
    };
    let arg = |s: &str| s.to_string();
    let renders =
        |name: &str, dir: &Path| vec![arg("--renders"), format!("{name}={}", dir.display())];
    let run = |v: Vec<String>| xtask(&v.iter().map(String::as_str).collect::<Vec<_>>());
    let fail = |v: Vec<String>| fails(&v.iter().map(String::as_str).collect::<Vec<_>>());

    // Refused up front.
    let missing = d.path().join("missing");
    let err = fail(args(&renders("peer", &missing)));
    assert!(
        err.contains("peer") && err.contains("no such folder"),
        "{err}"
    );
    let err = fail(args(&renders("sweep", &truth)));
    assert!(
        err.contains("\"sweep\"") && err.contains("another name"),
        "{err}"
    );
    let err = fail(args(&renders("a b", &truth)));
    assert!(err.contains("letters, digits"), "{err}");
    let one = trips[0]["timestamps"][2].as_u64().unwrap();
    let gone = std::fs::read_dir(&black)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with(&format!("_{one}.png")))
        .unwrap();
    let kept = std::fs::read(&gone).unwrap();
    std::fs::remove_file(&gone).unwrap();
    let err = fail(args(&renders("black", &black)));
    assert!(
        err.contains("1 of") && err.contains(gone.file_name().unwrap().to_str().unwrap()),
        "{err}"
    );
    std::fs::write(&gone, kept).unwrap();
    let mut v = renders("truth", &truth);
    v.extend([arg("--compare"), arg("truth,elsewhere")]);
    let err = fail(args(&v));
    assert!(
        err.contains("\"elsewhere\"") && err.contains("--renders"),
        "{err}"
    );
    assert!(!out.exists(), "a refused eval leaves no output folder");
    let err = fail(args(&renders("small", &small)));
    assert!(err.contains("32x16") && err.contains("32x32"), "{err}");

    // Scored: the truth as well as PSNR can say, black far below, and paired.
    let mut v = renders("truth", &truth);
    v.extend(renders("black", &black));
    v.extend([arg("--compare"), arg("truth,black"), arg("--overwrite")]);
    let o = run(args(&v));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let row = |m: &str| {
        r["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|x| x["method"] == m && x["bin"] == "all" && x["kind"] == "all")
            .unwrap_or_else(|| panic!("no row of {m}"))
            .clone()
    };
    let (t, b) = (row("truth"), row("black"));
    assert!(t["psnr_covered"].as_f64().unwrap() > 60.0, "{t}");
    assert!(b["psnr_covered"].as_f64().unwrap() < 20.0, "{b}");
    assert_eq!(t["timed"], false);
    assert_eq!(row("nearest")["timed"], true);
    let cmp = r["comparisons"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| {
            c["a"] == "truth"
                && c["b"] == "black"
                && c["metric"] == "psnr_covered"
                && c["bin"] == "all"
                && c["kind"] == "all"
        })
        .expect("--compare truth,black is in the report")
        .clone();
    assert!(cmp["diff"].as_f64().unwrap() > 30.0, "{cmp}");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("| truth | not measured here"), "{md}");
}

/// `eval --poses estimated` estimates each triplet's source pose from the frames and records,
/// per triplet, how far it is from the true one; on clean synthetic frames it is close.
#[test]
fn eval_with_estimated_poses_records_each_triplets_pose_error() {
    let d = tempfile::tempdir().unwrap();
    let config = SynthConfig {
        scenes: 1,
        frames: 6,
        width: 512,
        height: 384,
        seed: 11,
        test_fraction: 1.0,
        val_fraction: 0.0,
        ..SynthConfig::default()
    };
    generate(&config, d.path(), &|| {}).unwrap();
    let data = d.path().to_str().unwrap().to_string();
    let cache = d.path().join("no-cache").to_str().unwrap().to_string();
    // An eval of the sweep into `out` (`poses`: extra options); its report.json.
    let eval = |out: &Path, poses: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "eval",
            "--data",
            &data,
            "--methods",
            "sweep",
            "--sweep-grid",
            "1x2",
            "--size",
            "64x48",
            "--samples",
            "0",
            "--orbit-frames",
            "0",
            "--out",
            out.to_str().unwrap(),
            "--cache",
            &cache,
        ];
        args.extend_from_slice(poses);
        let o = xtask(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
    };
    let v = eval(&d.path().join("report"), &["--poses", "estimated"]);
    let meta = &v["meta"];
    let errors = meta["pose_errors"].as_array().unwrap();
    assert_eq!(
        errors.len() as u64,
        meta["triplets"].as_u64().unwrap(),
        "{meta}"
    );
    let solved: Vec<&serde_json::Value> = errors
        .iter()
        .filter(|e| !e["rotation_deg"].is_null())
        .collect();
    assert!(!solved.is_empty(), "{meta}");
    for e in &solved {
        assert!(e["rotation_deg"].as_f64().unwrap() < 2.0, "{e}");
        assert!(e["direction_deg"].as_f64().unwrap() < 15.0, "{e}");
        assert!(e["baseline"].as_f64().unwrap() > 0.0, "{e}");
        assert_ne!(e["reference"], e["source"], "{e}");
    }
    let failed = errors.len() - solved.len();
    assert!(
        meta["poses"].as_str().unwrap().contains(&format!(
            "{failed} of {} triplets kept the true pose",
            errors.len()
        )),
        "{meta}"
    );
    // With the dataset's cameras, no pose errors are recorded.
    let v = eval(&d.path().join("given"), &[]);
    assert!(v["meta"].get("pose_errors").is_none(), "{}", v["meta"]);
}

/// `render --blend`: views are blended consistently by default, a trained run's and the
/// sweep's, with Soft on `--blend soft` and with a run's network on `--blend learned` (plan.json
/// says which); the network cannot be asked of the sweep, and the refusal writes nothing.
#[test]
fn render_blends_consistently_by_default_and_otherwise_on_request() {
    let d = tempfile::tempdir().unwrap();
    let root = dataset(d.path());
    let run = d.path().join("run");
    let (r, data) = (run.to_str().unwrap(), root.to_str().unwrap());
    let o = xtask(&train_args(r, data, "2"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let seq = root.join("test/scene_00001");
    let cams = root.join("test/scene_00001.txt");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&seq)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    frames.sort();
    let (a, b) = (frames[0].to_str().unwrap(), frames[2].to_str().unwrap());
    let render = |out: &Path, extra: &[&str]| {
        let mut v = vec![
            "render",
            "--ref",
            a,
            "--src",
            b,
            "--src-row",
            "3",
            "--cameras",
            cams.to_str().unwrap(),
            "--size",
            "16x16",
            "--frames",
            "2",
            "--out",
            out.to_str().unwrap(),
        ];
        v.extend_from_slice(extra);
        v.iter().map(|s| s.to_string()).collect::<Vec<String>>()
    };
    let blend_of = |out: &Path| -> String {
        let plan: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
        plan["blend"].as_str().unwrap().to_string()
    };
    let default = d.path().join("default");
    let v = render(&default, &["--run", r]);
    let o = xtask(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        blend_of(&default).starts_with("consistent"),
        "{}",
        blend_of(&default)
    );
    let soft = d.path().join("soft");
    let v = render(&soft, &["--run", r, "--blend", "soft"]);
    let o = xtask(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(blend_of(&soft), "Soft");
    // Soft and consistent blends of the same MHI differ, so the default did blend otherwise.
    let png = |dir: &Path| std::fs::read(dir.join("view_row002.png")).unwrap();
    assert_ne!(png(&default), png(&soft));
    let sweep = d.path().join("sweep-default");
    let v = render(&sweep, &["--sweep", "--planes", "4"]);
    let o = xtask(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        blend_of(&sweep).starts_with("consistent"),
        "{}",
        blend_of(&sweep)
    );
    let learned = d.path().join("learned");
    let v = render(&learned, &["--run", r, "--blend", "learned"]);
    let o = xtask(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        blend_of(&learned).starts_with("learned"),
        "{}",
        blend_of(&learned)
    );
    let sweep = d.path().join("sweep");
    let v = render(&sweep, &["--sweep", "--planes", "4", "--blend", "learned"]);
    let err = fails(&v.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        err.contains("--blend learned needs a trained model"),
        "{err}"
    );
    assert!(!sweep.exists());
}
