//! What a command may write: only a folder it owns, whole or not at all, one writer at a time,
//! never through a link, with the modes the umask gives; and inputs that would never end (a
//! FIFO, `/dev/zero`, a camera file of a million rows) are refused or streamed.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use mhi_data::{SynthConfig, generate};

fn xtask(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .output()
        .expect("xtask runs")
}

fn ok(args: &[&str]) -> String {
    let o = xtask(args);
    assert!(
        o.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn fails(args: &[&str]) -> String {
    let o = xtask(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert!(err.lines().any(|l| l.starts_with("error: ")), "{err}");
    err
}

/// A tiny synthetic set and a render's arguments on its test scene (the sweep, 32 × 24).
struct Scene {
    _dir: tempfile::TempDir,
    root: PathBuf,
    cams: PathBuf,
    a: String,
    b: String,
}

/// A synthetic set of `scenes` scenes of `frames` frames, `test_fraction` of them in `test`.
fn synth(root: &Path, scenes: usize, frames: usize, size: (u32, u32), seed: u64, test: f64) {
    let config = SynthConfig {
        scenes,
        frames,
        width: size.0,
        height: size.1,
        seed,
        test_fraction: test,
        val_fraction: 0.0,
        ..SynthConfig::default()
    };
    generate(&config, root, &|| {}).unwrap();
}

fn scene() -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("data");
    synth(&root, 2, 4, (32, 24), 3, 0.5);
    let seq = root.join("test/scene_00001");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(&seq)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    frames.sort();
    Scene {
        cams: root.join("test/scene_00001.txt"),
        a: frames[0].display().to_string(),
        b: frames[2].display().to_string(),
        root,
        _dir: dir,
    }
}

impl Scene {
    fn tmp(&self) -> &Path {
        self._dir.path()
    }

    fn render<'a>(&'a self, task: &'a str, out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
        let mut v = vec![
            task,
            "--ref",
            &self.a,
            "--src",
            &self.b,
            "--src-row",
            "3",
            "--cameras",
            self.cams.to_str().unwrap(),
            "--size",
            "32x24",
            "--planes",
            "4",
            "--sweep",
            "--frames",
            "2",
            "--out",
            out,
        ];
        // An option given again replaces the default above.
        let mut i = 0;
        while i < extra.len() {
            let takes_value = extra.get(i + 1).is_some_and(|x| !x.starts_with("--"));
            match v.iter().position(|a| *a == extra[i]) {
                Some(k) if takes_value => v[k + 1] = extra[i + 1],
                Some(_) => {}
                None if takes_value => v.extend([extra[i], extra[i + 1]]),
                None => v.push(extra[i]),
            }
            i += if takes_value { 2 } else { 1 };
        }
        v
    }
}

/// `eval` of the nearest view only, at 32 × 32, one triplet a sequence (`extra`, if not empty,
/// appended).
fn eval_args<'a>(data: &'a str, samples: &'a str, out: &'a str, extra: &'a str) -> Vec<&'a str> {
    let mut v = vec![
        "eval",
        "--data",
        data,
        "--size",
        "32x32",
        "--per-sequence",
        "1",
        "--methods",
        "nearest",
        "--orbit-frames",
        "0",
        "--samples",
        samples,
        "--out",
        out,
    ];
    if !extra.is_empty() {
        v.push(extra);
    }
    v
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_folder_of_the_users_is_never_written_into() {
    let s = scene();
    // A dataset split, a model folder: anything holding files no mhi command made.
    let theirs = s.root.join("test");
    let before = names(&theirs);
    for args in [
        s.render("render", theirs.to_str().unwrap(), &["--overwrite"]),
        s.render("export", theirs.to_str().unwrap(), &["--overwrite"]),
    ] {
        let err = fails(&args);
        assert!(err.contains("holds files no mhi command made"), "{err}");
    }
    let data = s.root.to_str().unwrap();
    let out = theirs.to_str().unwrap();
    let err = fails(&eval_args(data, "0", out, "--overwrite"));
    assert!(err.contains("holds files no mhi command made"), "{err}");
    let err = fails(&[
        "train",
        "--run",
        out,
        "--data",
        data,
        "--size",
        "32x32",
        "--planes",
        "4",
        "--width",
        "2",
        "--blend-width",
        "2",
        "--phase1-steps",
        "1",
        "--phase2-steps",
        "0",
        "--loss",
        "photometric",
    ]);
    assert!(err.contains("holds files no mhi command made"), "{err}");
    let err = fails(&[
        "synth",
        "--out",
        out,
        "--scenes",
        "2",
        "--frames",
        "3",
        "--overwrite",
    ]);
    assert!(err.contains("holds files no mhi command made"), "{err}");
    assert_eq!(
        names(&theirs),
        before,
        "a refused command changed the folder"
    );
    // Nothing was left beside it either (no partial folder, no lock).
    assert_eq!(names(&s.root), [".mhi-output.json", "test", "train"]);
}

#[cfg(unix)]
#[test]
fn links_are_replaced_not_written_through_and_modes_follow_the_umask() {
    use std::os::unix::fs::PermissionsExt as _;
    let s = scene();
    let viewer = s.tmp().join("viewer");
    let v = viewer.to_str().unwrap();
    ok(&s.render("export", v, &[]));
    // Someone plants a link in the viewer folder, to a file elsewhere.
    let elsewhere = s.tmp().join("elsewhere.txt");
    std::fs::write(&elsewhere, "precious").unwrap();
    std::fs::set_permissions(&elsewhere, std::fs::Permissions::from_mode(0o600)).unwrap();
    std::fs::remove_file(viewer.join("manifest.json")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, viewer.join("manifest.json")).unwrap();
    ok(&s.render("export", v, &["--overwrite"]));
    assert_eq!(std::fs::read_to_string(&elsewhere).unwrap(), "precious");
    assert_eq!(
        std::fs::metadata(&elsewhere).unwrap().permissions().mode() & 0o777,
        0o600
    );
    assert!(
        std::fs::symlink_metadata(viewer.join("manifest.json"))
            .unwrap()
            .is_file()
    );
    // Every file and the folder have what the umask gives a plainly created one.
    let plain = s.tmp().join("plain");
    std::fs::write(&plain, "x").unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    for f in ["index.html", "viewer.js", "data.js", "manifest.json"] {
        assert_eq!(mode(&viewer.join(f)), mode(&plain), "{f}");
    }
    std::fs::create_dir(s.tmp().join("plain-dir")).unwrap();
    assert_eq!(mode(&viewer), mode(&s.tmp().join("plain-dir")));
}

#[test]
fn a_second_writer_is_refused_naming_the_first() {
    let s = scene();
    let out = s.tmp().join("views");
    let o = out.to_str().unwrap();
    ok(&s.render("render", o, &[]));
    // This test process holds the folder's lock, as a running render would.
    let lock = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(out.join(mhi_data::output::LOCK_FILE))
        .unwrap();
    lock.try_lock().unwrap();
    std::fs::write(
        out.join(mhi_data::output::LOCK_FILE),
        format!("{}\n", std::process::id()),
    )
    .unwrap();
    let err = fails(&s.render("render", o, &["--overwrite"]));
    assert!(
        err.contains(&format!("process {} is writing", std::process::id())),
        "{err}"
    );
    drop(lock);
    ok(&s.render("render", o, &["--overwrite"]));
}

/// A render killed mid-write (SIGTERM, then SIGKILL on the rerun's predecessor) leaves the
/// previous output whole, and the next run says what it found and removes the partial folder.
/// Not SIGINT: a shell starts background jobs with SIGINT ignored, and a test binary run from
/// one (a CI script started with `&`) passes that on, so the render would finish instead.
#[cfg(unix)]
#[test]
fn an_interrupted_render_leaves_the_old_output_whole() {
    let s = scene();
    let out = s.tmp().join("views");
    let o = out.to_str().unwrap().to_string();
    ok(&s.render("render", &o, &[]));
    let before: Vec<(String, Vec<u8>)> = names(&out)
        .into_iter()
        .filter(|n| !n.starts_with(".mhi-lock"))
        .map(|n| (n.clone(), std::fs::read(out.join(&n)).unwrap()))
        .collect();
    for signal in ["-TERM", "-KILL"] {
        // Many orbit frames at a size well above the scene's keep it busy long enough (seconds)
        // to be interrupted while it writes, even on a loaded machine where this thread may
        // wait a while between polls (CI once saw 900 frames at 64 × 48 finish first).
        let args = s.render(
            "render",
            &o,
            &["--overwrite", "--frames", "900", "--size", "192x144"],
        );
        let mut child = Command::new(env!("CARGO_BIN_EXE_xtask"))
            .args(&args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let partial = s.tmp().join(format!(".views.partial-{}", child.id()));
        let t0 = Instant::now();
        while !partial.join("plan.json").exists() && t0.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert!(partial.exists(), "the render never started writing");
        Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        let status = child.wait().unwrap();
        assert!(!status.success());
        for (n, bytes) in &before {
            assert_eq!(&std::fs::read(out.join(n)).unwrap(), bytes, "{n} changed");
        }
        assert!(
            partial.exists(),
            "a killed render leaves its partial folder, named so"
        );
    }
    let said = ok(&s.render("render", &o, &["--overwrite"]));
    assert!(said.contains("partial"), "{said}");
    let left: Vec<String> = names(s.tmp())
        .into_iter()
        .filter(|n| n.contains("partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[cfg(unix)]
#[test]
fn a_fifo_or_a_device_is_refused_not_read_forever() {
    let s = scene();
    let fifo = s.tmp().join("frame.png");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let out = s.tmp().join("views");
    let o = out.to_str().unwrap();
    for bad in [fifo.to_str().unwrap(), "/dev/zero"] {
        let mut args = s.render("render", o, &[]);
        args[2] = bad;
        let t0 = Instant::now();
        let err = fails(&args);
        assert!(err.contains("not a regular file"), "{err}");
        assert!(t0.elapsed() < Duration::from_secs(60));
        let mut args = s.render("render", o, &[]);
        args[8] = bad;
        let err = fails(&args);
        assert!(err.contains("not a regular file"), "{err}");
    }
    let empty = s.tmp().join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let mut args = s.render("render", o, &[]);
    args[2] = empty.to_str().unwrap();
    let err = fails(&args);
    assert!(err.contains("is empty"), "{err}");
    assert!(!out.exists(), "a refused render leaves no folder");
}

/// A camera file of a million rows renders as a stream: under a 3 GB address-space cap (one
/// view's blend weights held at a time; before, every view's were kept, 15 KB each at 32 × 24,
/// 15 GB for a million) it plans every view and starts writing views.
#[cfg(target_os = "linux")]
#[test]
fn a_million_camera_rows_stream_under_a_memory_cap() {
    let s = scene();
    let text = std::fs::read_to_string(&s.cams).unwrap();
    let mut lines = text.lines();
    let url = lines.next().unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split_whitespace().collect()).collect();
    let big = s.tmp().join("million.txt");
    let mut out = String::with_capacity(200 << 20);
    out.push_str(url);
    out.push('\n');
    // Rows 1 to 3 are the scene's own; then a million copies of its fourth camera.
    for (k, r) in rows.iter().take(3).enumerate() {
        out.push_str(&format!("{} {}\n", k + 1, r[1..].join(" ")));
    }
    let tail = rows[3][1..].join(" ");
    for k in 0..1_000_000 {
        out.push_str(&format!("{} {tail}\n", k + 4));
    }
    std::fs::write(&big, out).unwrap();
    let views = s.tmp().join("views");
    let cams = big.to_str().unwrap().to_string();
    let mut args = s.render(
        "render",
        views.to_str().unwrap(),
        &["--size", "32x24", "--exact", "--frames", "0"],
    );
    args[8] = &cams;
    let line = args
        .iter()
        .map(|a| format!("'{a}'"))
        .collect::<Vec<_>>()
        .join(" ");
    let mut child = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v 3000000; exec '{}' {line}",
            env!("CARGO_BIN_EXE_xtask")
        ))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let partial = s.tmp().join(format!(".views.partial-{}", child.id()));
    let t0 = Instant::now();
    let mut written = false;
    while t0.elapsed() < Duration::from_secs(240) {
        if partial.join("view_row010.png").exists() {
            written = true;
            break;
        }
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
            panic!("the render ended ({status}) before writing views: {err}");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let _ = child.kill();
    let _ = child.wait();
    assert!(written, "no view written within 4 minutes");
}

#[test]
fn absurd_counts_are_refused_with_their_cost() {
    let s = scene();
    let out = s.tmp().join("views");
    let err = fails(&s.render("render", out.to_str().unwrap(), &["--frames", "100000"]));
    assert!(err.contains("--frames 100000: at most 10000"), "{err}");
    let err = fails(&s.render(
        "render",
        out.to_str().unwrap(),
        &["--frames", "5000", "--gif"],
    ));
    assert!(
        err.contains("--frames with --gif 5000") && err.contains("GB"),
        "{err}"
    );
    let data = s.root.to_str().unwrap();
    let report = s.tmp().join("report");
    let err = fails(&[
        "eval",
        "--data",
        data,
        "--orbit-frames",
        "100000",
        "--out",
        report.to_str().unwrap(),
    ]);
    assert!(err.contains("--orbit-frames 100000"), "{err}");
    assert!(!report.exists());
    let err = fails(&["triplets", "--data", data, "--per-sequence", "100000000"]);
    assert!(err.contains("--per-sequence 100000000"), "{err}");
    let synth = s.tmp().join("synth");
    let err = fails(&[
        "synth",
        "--out",
        synth.to_str().unwrap(),
        "--scenes",
        "100000000",
    ]);
    assert!(
        err.contains("--scenes 100000000") && err.contains("GB"),
        "{err}"
    );
    let o = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["triplets", "--data", data])
        .env("RAYON_NUM_THREADS", "100000")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("RAYON_NUM_THREADS"),
        "{err}"
    );
    assert!(!out.exists() && !synth.exists());
    // More triplets than a sequence supplies: a warning and no repeats.
    let o = xtask(&["triplets", "--data", data, "--per-sequence", "500"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("distinct triplets"), "{err}");
}

/// A sequence named `..`, a name with terminal escapes and markup: neither reads outside the
/// dataset nor reaches the terminal or the report raw.
#[test]
fn hostile_sequence_names_are_contained() {
    let s = scene();
    let test = s.root.join("test");
    std::fs::copy(test.join("scene_00001.txt"), test.join("...txt")).unwrap();
    let hostile = "x\u{1b}[31m<img src=q onerror=alert(1)>";
    std::fs::copy(
        test.join("scene_00001.txt"),
        test.join(format!("{hostile}.txt")),
    )
    .unwrap();
    let src = test.join("scene_00001");
    let dst = test.join(hostile);
    std::fs::create_dir(&dst).unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), dst.join(e.file_name())).unwrap();
    }
    let data = s.root.to_str().unwrap();
    let o = xtask(&["triplets", "--data", data, "--per-sequence", "2"]);
    let (out, err) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("would read its frames from the parent folder"),
        "{err}"
    );
    assert!(
        !out.contains('\u{1b}') && !err.contains('\u{1b}'),
        "{out}{err}"
    );
    let report = s.tmp().join("report");
    ok(&eval_args(data, "3", report.to_str().unwrap(), ""));
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(!md.contains("<img src=q") && !md.contains('\u{1b}'), "{md}");
}

/// Rotations printed with four decimals (7-Scenes' pose files) are accepted with a warning
/// that gives the error; a reflection is named as one.
#[test]
fn four_decimal_rotations_warn_and_reflections_are_named() {
    let s = scene();
    let text = std::fs::read_to_string(&s.cams).unwrap();
    let rounded: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                return l.to_string();
            }
            let mut c: Vec<String> = l.split_whitespace().map(String::from).collect();
            for k in [7, 8, 9, 11, 12, 13, 15, 16, 17] {
                c[k] = format!("{:.4}", c[k].parse::<f64>().unwrap());
            }
            c.join(" ")
        })
        .collect();
    std::fs::write(&s.cams, rounded.join("\n")).unwrap();
    let out = s.tmp().join("views");
    let o = xtask(&s.render("render", out.to_str().unwrap(), &[]));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("orthonormal only to") && err.contains("re-orthonormalised"),
        "{err}"
    );
    // Row 2 mirrored: its third rotation row negated.
    let mut lines: Vec<String> = rounded.clone();
    let mut c: Vec<String> = lines[2].split_whitespace().map(String::from).collect();
    for k in [15, 16, 17] {
        let v: f64 = c[k].parse().unwrap();
        c[k] = format!("{}", -v);
    }
    lines[2] = c.join(" ");
    std::fs::write(&s.cams, lines.join("\n")).unwrap();
    let err = fails(&s.render("render", s.tmp().join("v2").to_str().unwrap(), &[]));
    assert!(
        err.contains(":3:") && err.contains("is a reflection"),
        "{err}"
    );
}

/// Two plain photos in, views out: `pose` writes a camera file, `render` without `--cameras`
/// estimates the poses itself; bad pairs are refused with what to do.
#[test]
fn two_plain_photos_give_poses_and_views() {
    let d = tempfile::tempdir().unwrap();
    let root = d.path().join("data");
    synth(&root, 1, 6, (512, 384), 11, 0.0);
    let file = mhi_data::CameraFile::read(&root.join("train/scene_00000.txt")).unwrap();
    let frame = |k: usize| {
        root.join(format!("train/scene_00000/{}.png", file.rows[k].timestamp))
            .display()
            .to_string()
    };
    let (a, b) = (frame(0), frame(3));
    let cams = d.path().join("cams.txt");
    let said = ok(&["pose", &a, &b, "--out", cams.to_str().unwrap()]);
    assert!(
        said.contains("inliers") && said.contains("assumed"),
        "{said}"
    );
    let written = mhi_data::CameraFile::read(&cams).unwrap();
    assert_eq!(written.rows.len(), 2);
    let err = fails(&["pose", &a, &b, "--out", cams.to_str().unwrap()]);
    assert!(err.contains("--overwrite"), "{err}");
    let views = d.path().join("views");
    let said = ok(&[
        "render",
        "--ref",
        &a,
        "--src",
        &b,
        "--sweep",
        "--planes",
        "8",
        "--frames",
        "3",
        "--out",
        views.to_str().unwrap(),
    ]);
    assert!(said.contains("poses of"), "{said}");
    assert!(views.join("video.mp4").is_file() && views.join("plan.json").is_file());
    let err = fails(&[
        "pose",
        &a,
        &a,
        "--out",
        d.path().join("x.txt").to_str().unwrap(),
    ]);
    assert!(err.contains("same file"), "{err}");
    let blank = d.path().join("blank.png");
    image::RgbImage::from_pixel(512, 384, image::Rgb([90, 90, 90]))
        .save(&blank)
        .unwrap();
    let err = fails(&[
        "pose",
        &a,
        blank.to_str().unwrap(),
        "--out",
        d.path().join("y.txt").to_str().unwrap(),
    ]);
    assert!(err.contains("matches"), "{err}");
    let err = fails(&[
        "pose",
        &a,
        &b,
        "--intrinsics",
        "100,133,0.5,0.5",
        "--out",
        d.path().join("z.txt").to_str().unwrap(),
    ]);
    assert!(err.contains("field of view"), "{err}");
    assert!(!d.path().join("x.txt").exists() && !d.path().join("y.txt").exists());
}
