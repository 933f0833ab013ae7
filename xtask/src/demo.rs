//! `cargo xtask demo`: the whole method from a fresh clone — synthetic scenes, the pretrained
//! weights, the default MHI model, the MPI baseline, and the evaluation report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args, Parser};

use crate::eval::EvalArgs;
use crate::train::TrainArgs;
use crate::weights::WeightsArgs;

/// Options of `cargo xtask demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output directory: runs/mhi, runs/mpi and report/. Finished runs found there are reused
    /// and interrupted ones resumed; the report in it is rewritten.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Synthetic dataset (generated if missing).
    #[arg(long, default_value = "data/synth")]
    pub data: PathBuf,
    /// Weights cache (default: $MHI_CACHE, else ~/.cache/mhi).
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Do not try to download the pretrained weights (LPIPS is then skipped and training uses
    /// L1 + SSIM).
    #[arg(long)]
    pub offline: bool,
    /// Test triplets per synthetic test scene.
    #[arg(long, default_value_t = 2)]
    pub per_sequence: usize,
}

#[derive(Parser)]
struct Wrap<T: Args> {
    #[command(flatten)]
    inner: T,
}

fn parse<T: Args>(args: &[String]) -> anyhow::Result<T> {
    let mut v = vec!["xtask".to_string()];
    v.extend(args.iter().cloned());
    Ok(Wrap::<T>::try_parse_from(v)?.inner)
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// Train `run` with `extra` options unless it already finished; resume it if it was interrupted.
fn train(run: &Path, a: &DemoArgs, extra: &[&str]) -> anyhow::Result<()> {
    let dir = mhi_net::RunDir::new(run);
    if dir.finished() {
        println!("  {} already trained; reusing it", run.display());
        return Ok(());
    }
    let mut args = vec!["--run".to_string(), s(run), "--data".into(), s(&a.data)];
    if let Some(c) = &a.cache {
        args.extend(["--cache".into(), s(c)]);
    }
    if dir.has_checkpoint() {
        println!("  resuming the interrupted run {}", run.display());
        args.push("--resume".into());
    } else {
        if dir.started() {
            anyhow::bail!(
                "{} holds a run that never reached its first checkpoint; remove it and run the demo again",
                run.display()
            );
        }
        args.extend(extra.iter().map(|x| x.to_string()));
    }
    crate::train::train(&parse::<TrainArgs>(&args)?)
}

/// `cargo xtask demo`.
pub fn demo(a: &DemoArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let stage = |k: usize, what: &str| {
        println!(
            "[{k}/5] {what} ({:.1} min so far)",
            t0.elapsed().as_secs_f64() / 60.0
        );
    };
    stage(1, "synthetic scenes");
    crate::experiments::ensure_synthetic(&a.data)?;
    stage(
        2,
        "pretrained weights (VGG16 for the perceptual loss, AlexNet for LPIPS)",
    );
    if a.offline {
        println!("  --offline: skipped");
    } else {
        let mut args = Vec::new();
        if let Some(c) = &a.cache {
            args.extend(["--cache".to_string(), s(c)]);
        }
        if let Err(e) = crate::weights::weights(&parse::<WeightsArgs>(&args)?) {
            eprintln!(
                "note: the pretrained weights could not be fetched ({e:#}); the demo goes on without LPIPS and trains with L1 + SSIM"
            );
        }
    }
    let runs = a.out.join("runs");
    stage(
        3,
        "training the MHI model (N = 5 normals, default settings)",
    );
    train(&runs.join("mhi"), a, &[])?;
    stage(
        4,
        "training the MPI baseline (N = 1, same code and budget per step)",
    );
    train(
        &runs.join("mpi"),
        a,
        &["--normals", "1", "--phase2-steps", "0"],
    )?;
    stage(
        5,
        "evaluating every method (and the pretrained model) on the synthetic test scenes",
    );
    let mut args = vec![
        "--data".to_string(),
        s(&a.data),
        "--run".into(),
        s(&runs.join("mhi")),
        "--run".into(),
        s(&runs.join("mpi")),
        "--out".into(),
        s(&a.out.join("report")),
        "--overwrite".into(),
        "--per-sequence".into(),
        a.per_sequence.to_string(),
        // Twice the training size: the CPU-sized models are trained at 64 x 64, the report is
        // read at 128 x 128 (the synthetic frames are 256 x 256; `eval` alone defaults to them).
        "--size".into(),
        "128x128".into(),
    ];
    if let Some(c) = &a.cache {
        args.extend(["--cache".into(), s(c)]);
    }
    // The pretrained model beside the short runs (its own N and D; compared with the sweep of
    // the same N and D in the report).
    match crate::models::pretrained() {
        Some(p) => args.extend(["--run".into(), s(&p)]),
        None => println!(
            "  no pretrained model at {}; the report shows the short runs only",
            crate::models::pretrained_dir().display()
        ),
    }
    crate::eval::eval(&parse::<EvalArgs>(&args)?)?;
    println!(
        "demo finished in {:.1} min; report: {}",
        t0.elapsed().as_secs_f64() / 60.0,
        a.out.join("report").join("report.md").display()
    );
    Ok(())
}
