//! `cargo xtask pose`: two plain photos in, a RealEstate10K camera file out (row 1 the first
//! photo at the identity, row 2 the second), with what was found printed. Also the poses
//! `render` and `export` estimate when no camera file is given.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use mhi_data::{CameraFile, CameraRow};
use mhi_geom::RigidTransform;
use mhi_pose::accuracy::{Outcome, both_solved_row, table_row};
use mhi_pose::{Options, Photo, PosedPair};

/// Intrinsics options, shared by `pose`, `render` and `export`.
#[derive(Args, Debug, Clone, Default)]
pub struct IntrinsicsArgs {
    /// Known intrinsics of both photos, normalised as in a camera file: `fx,fy,cx,cy` (fx, cx
    /// divided by the width; fy, cy by the height). Default: each photo's EXIF focal length,
    /// else a stated 45° field of view.
    #[arg(long, value_parser = parse_intrinsics)]
    pub intrinsics: Option<[f64; 4]>,
    /// The second photo's intrinsics when they differ from --intrinsics.
    #[arg(long, value_parser = parse_intrinsics)]
    pub src_intrinsics: Option<[f64; 4]>,
}

fn parse_intrinsics(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: expected four numbers fx,fy,cx,cy"))?;
    match v.as_slice() {
        [fx, fy, cx, cy] if v.iter().all(|x| x.is_finite()) && *fx > 0.0 && *fy > 0.0 => {
            Ok([*fx, *fy, *cx, *cy])
        }
        _ => Err(format!(
            "{s:?}: expected four finite numbers fx,fy,cx,cy, the focal lengths positive (normalised: fx = focal in pixels / width)"
        )),
    }
}

/// Options of `cargo xtask pose`.
#[derive(Args, Debug)]
pub struct PoseArgs {
    /// The first photo (the reference: row 1, at the identity).
    #[arg(required_unless_present = "data")]
    pub a: Option<PathBuf>,
    /// The second photo (row 2).
    #[arg(required_unless_present = "data")]
    pub b: Option<PathBuf>,
    /// Instead of two photos: measure the accuracy on posed datasets (RealEstate10K layout,
    /// repeatable) against their cameras, with their known intrinsics — pairs --gap frames
    /// apart — and against the OpenCV peer (--peer) on the same pairs.
    #[arg(long, conflicts_with_all = ["a", "b"])]
    pub data: Vec<PathBuf>,
    /// The datasets' split.
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Frames between the two photos of a pair (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "5,10")]
    pub gap: Vec<usize>,
    /// Pairs per sequence and gap, spread evenly along the sequence.
    #[arg(long, default_value_t = 8)]
    pub pairs: usize,
    /// The OpenCV peer (`xtask/scripts/pose_opencv.py`; needs `pip install opencv-python-headless`).
    #[arg(long)]
    pub peer: Option<PathBuf>,
    /// The Python that runs the peer.
    #[arg(long, default_value = "python3")]
    pub python: String,
    #[command(flatten)]
    pub intrinsics: IntrinsicsArgs,
    /// The camera file to write.
    #[arg(long, default_value = "out/cams.txt")]
    pub out: PathBuf,
    /// Replace --out if it exists.
    #[arg(long)]
    pub overwrite: bool,
}

/// Estimate the two photos' cameras and print what was found.
pub fn estimate(a: &Path, b: &Path, k: &IntrinsicsArgs) -> anyhow::Result<(PosedPair, CameraFile)> {
    if a == b {
        bail!(
            "the two photos are the same file ({}): the scene needs two photos taken from different places",
            a.display()
        );
    }
    let t0 = std::time::Instant::now();
    let (pa, pb) = (Photo::open(a)?, Photo::open(b)?);
    let options = Options {
        ref_intrinsics: k.intrinsics,
        src_intrinsics: k.src_intrinsics,
        ..Options::default()
    };
    let pair = mhi_pose::estimate(&pa, &pb, &options).with_context(|| {
        format!(
            "estimating the poses of {} and {}",
            a.display(),
            b.display()
        )
    })?;
    println!(
        "poses of {} and {} in {:.1} s:\n{}",
        a.display(),
        b.display(),
        t0.elapsed().as_secs_f64(),
        pair.summary()
    );
    let row = |timestamp, k: &mhi_pose::Intrinsics, pose| CameraRow {
        timestamp,
        intrinsics: k.normalised,
        distortion: [0.0; 2],
        cam_from_world: pose,
    };
    let src = RigidTransform::new(pair.rotation(), pair.translation())
        .context("the estimated rotation")?;
    let file = CameraFile {
        url: format!(
            "mhi-pose://{}+{}",
            a.file_name().unwrap_or_default().to_string_lossy(),
            b.file_name().unwrap_or_default().to_string_lossy()
        ),
        rows: vec![
            row(0, &pair.ref_intrinsics, RigidTransform::IDENTITY),
            row(1, &pair.src_intrinsics, src),
        ],
        rotation_warning: None,
    };
    Ok((pair, file))
}

/// `cargo xtask pose`.
pub fn pose(a: &PoseArgs) -> anyhow::Result<()> {
    if !a.data.is_empty() {
        return accuracy(a);
    }
    let (Some(pa), Some(pb)) = (&a.a, &a.b) else {
        bail!("give two photos, or --data for the accuracy table");
    };
    if std::fs::symlink_metadata(&a.out).is_ok() && !a.overwrite {
        bail!(
            "{} exists; pass --overwrite to replace it, or choose another --out",
            a.out.display()
        );
    }
    let (_, file) = estimate(pa, pb, &a.intrinsics)?;
    if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    file.write(&a.out)?;
    println!(
        "cameras: {} (row 1 {}, row 2 {}; render with `cargo xtask render --ref {} --src {} --cameras {}`)",
        a.out.display(),
        pa.display(),
        pb.display(),
        pa.display(),
        pb.display(),
        a.out.display()
    );
    Ok(())
}

/// `cargo xtask pose --data …`: ours against the cameras and the OpenCV peer, per set.
fn accuracy(a: &PoseArgs) -> anyhow::Result<()> {
    println!(
        "| set (gap) | pairs | median rotation error | median direction error | AUC 5° / 10° / 20° | failures | time per pair |\n|---|---:|---:|---:|---|---:|---:|"
    );
    let mut both = Vec::new();
    for root in &a.data {
        let ds = mhi_data::Dataset::open(root, &a.split, 3)?;
        for &gap in &a.gap {
            let mut pairs = Vec::new();
            for seq in &ds.sequences {
                let n = seq.frames.len();
                if n <= gap {
                    continue;
                }
                let count = a.pairs.min(n - gap);
                for k in 0..count {
                    let i = k * (n - gap) / count;
                    pairs.push((&seq.frames[i], &seq.frames[i + gap]));
                }
            }
            if pairs.is_empty() {
                eprintln!(
                    "note: {}: no pair {gap} frames apart (every sequence has at most {gap} frames); no row",
                    root.display()
                );
                continue;
            }
            let mut ours = Vec::new();
            let mut jobs = Vec::new();
            for (fa, fb) in &pairs {
                let truth = fb
                    .row
                    .cam_from_world
                    .compose(&fa.row.cam_from_world.inverse());
                let t0 = std::time::Instant::now();
                let (pa, pb) = (Photo::open(&fa.path)?, Photo::open(&fb.path)?);
                let options = Options {
                    ref_intrinsics: Some(fa.row.intrinsics),
                    src_intrinsics: Some(fb.row.intrinsics),
                    ..Options::default()
                };
                ours.push(match mhi_pose::estimate(&pa, &pb, &options) {
                    Ok(p) => Outcome::of(
                        p.rotation(),
                        p.translation(),
                        &truth,
                        t0.elapsed().as_secs_f64(),
                    ),
                    Err(e) => {
                        eprintln!(
                            "  {} / {}: {e}",
                            fa.path.file_name().unwrap_or_default().to_string_lossy(),
                            fb.path.file_name().unwrap_or_default().to_string_lossy()
                        );
                        Outcome::failure(t0.elapsed().as_secs_f64())
                    }
                });
                // OpenCV's pixel centres are at integers: cx, cy half a pixel less.
                let k = |row: &CameraRow, img: &Photo| {
                    let (w, h) = img.image.dimensions();
                    let [fx, fy, cx, cy] = row.intrinsics;
                    let (w, h) = (f64::from(w), f64::from(h));
                    [
                        fx * w,
                        0.0,
                        cx * w - 0.5,
                        0.0,
                        fy * h,
                        cy * h - 0.5,
                        0.0,
                        0.0,
                        1.0,
                    ]
                };
                jobs.push(serde_json::json!({
                    "a": fa.path, "b": fb.path, "k1": k(&fa.row, &pa), "k2": k(&fb.row, &pb),
                    "truth": truth,
                }));
            }
            let name = format!("{} ({gap})", mhi_data::root_name(root));
            println!("{}", table_row(&format!("{name}, ours"), &ours));
            if let Some(peer) = &a.peer {
                let theirs = run_peer(a, peer, &jobs)?;
                let outcomes: Vec<Outcome> = theirs
                    .iter()
                    .zip(&pairs)
                    .map(|(r, (fa, fb))| {
                        let truth = fb
                            .row
                            .cam_from_world
                            .compose(&fa.row.cam_from_world.inverse());
                        let secs = r["seconds"].as_f64().unwrap_or(f64::NAN);
                        match (r["r"].as_array(), r["t"].as_array()) {
                            (Some(rr), Some(tt)) if rr.len() == 9 && tt.len() == 3 => {
                                let v: Vec<f64> = rr.iter().filter_map(|x| x.as_f64()).collect();
                                let t: Vec<f64> = tt.iter().filter_map(|x| x.as_f64()).collect();
                                let r = glam::DMat3::from_cols_slice(&v).transpose();
                                Outcome::of(r, glam::DVec3::new(t[0], t[1], t[2]), &truth, secs)
                            }
                            _ => Outcome::failure(secs),
                        }
                    })
                    .collect();
                println!("{}", table_row(&format!("{name}, OpenCV"), &outcomes));
                both.push(both_solved_row(&name, &ours, &outcomes));
            }
        }
    }
    if !both.is_empty() {
        println!(
            "\nOn the pairs both solved (each median above is over its own successes):\n\n| set (gap) | pairs | median rotation error, ours / OpenCV | median direction error, ours / OpenCV |\n|---|---:|---:|---:|"
        );
        for row in both {
            println!("{row}");
        }
    }
    Ok(())
}

fn run_peer(
    a: &PoseArgs,
    peer: &Path,
    jobs: &[serde_json::Value],
) -> anyhow::Result<Vec<serde_json::Value>> {
    let dir = tempfile::tempdir()?;
    let (input, output) = (dir.path().join("pairs.json"), dir.path().join("out.json"));
    std::fs::write(&input, serde_json::to_vec(jobs)?)?;
    let o = std::process::Command::new(&a.python)
        .arg(peer)
        .arg(&input)
        .arg(&output)
        .output()
        .with_context(|| format!("cannot run {} {}", a.python, peer.display()))?;
    if !o.status.success() {
        bail!(
            "the peer {} failed (pip install opencv-python-headless?): {}",
            peer.display(),
            String::from_utf8_lossy(&o.stderr).trim()
        );
    }
    Ok(serde_json::from_slice(&std::fs::read(&output)?)?)
}
