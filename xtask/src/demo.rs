//! `cargo xtask demo`: the tool's main job on two bundled photos — their poses estimated, the
//! pretrained MHI, views, an orbit and the browser viewer. `--full`: the whole method from a
//! fresh clone — synthetic scenes, the pretrained weights, the default MHI model, the MPI
//! baseline, and the evaluation report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args, Parser};

use crate::options::{EvalArgs, TrainArgs, WeightsArgs};
use crate::render::RenderArgs;

/// The commands the demo runs, handed over by `main.rs` (the demo imports no other command's
/// module).
pub struct Commands<'a> {
    /// `cargo xtask weights`.
    pub weights: &'a dyn Fn(&WeightsArgs) -> anyhow::Result<()>,
    /// `cargo xtask train`.
    pub train: &'a dyn Fn(&TrainArgs) -> anyhow::Result<()>,
    /// `cargo xtask eval`.
    pub eval: &'a dyn Fn(&EvalArgs) -> anyhow::Result<()>,
    /// `cargo xtask render`.
    pub render: &'a dyn Fn(&RenderArgs) -> anyhow::Result<()>,
}

/// Options of `cargo xtask demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output directory: views/ and viewer/ (and with --full runs/mhi, runs/mpi and report/;
    /// finished runs found there are reused and interrupted ones resumed). What the demo wrote
    /// before is replaced.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// The whole method instead: synthesise scenes, train the MHI model and the MPI baseline
    /// for a few minutes each, and evaluate every method (about 12 minutes from a fresh clone).
    #[arg(long)]
    pub full: bool,
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

/// A command's options with every default it declares (what `cargo xtask <command>` with no
/// option gets), for the demo to set fields on: typed, and no default repeated here.
fn defaults<T: Args>() -> T {
    Wrap::<T>::try_parse_from(["xtask"])
        .expect("every option of the commands the demo runs has a default")
        .inner
}

/// Train `run` (`set` adjusts the default options) unless it already finished; resume it if
/// it was interrupted.
fn train(
    cmd: &Commands<'_>,
    run: &Path,
    a: &DemoArgs,
    set: impl FnOnce(&mut TrainArgs),
) -> anyhow::Result<()> {
    let dir = mhi_net::RunDir::new(run);
    if dir.finished() {
        println!("  {} already trained; reusing it", run.display());
        return Ok(());
    }
    let mut t = defaults::<TrainArgs>();
    t.run = run.to_path_buf();
    t.data = vec![a.data.clone()];
    t.cache.clone_from(&a.cache);
    if dir.has_checkpoint() {
        println!("  resuming the interrupted run {}", run.display());
        t.resume = true;
    } else {
        if dir.started() {
            anyhow::bail!(
                "{} holds a run that never reached its first checkpoint; remove it and run the demo again",
                run.display()
            );
        }
        set(&mut t);
    }
    (cmd.train)(&t)
}

/// The two photos bundled with the project (`examples/hololens/`, MIT: see its README).
pub fn example_photos() -> (PathBuf, PathBuf) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/hololens");
    (dir.join("a.jpg"), dir.join("b.jpg"))
}

/// `cargo xtask demo`: two plain photos in, views out.
pub fn demo(a: &DemoArgs, cmd: &Commands<'_>) -> anyhow::Result<()> {
    if a.full {
        return full(a, cmd);
    }
    let t0 = Instant::now();
    let (ra, rb) = example_photos();
    println!(
        "[1/1] two plain photos ({}, {}): their poses, the pretrained MHI, a video along the paper's circular path, the browser viewer",
        ra.display(),
        rb.display(),
    );
    let mut r = Wrap::<RenderArgs>::try_parse_from([
        "xtask".as_ref(),
        "--ref".as_ref(),
        ra.as_os_str(),
        "--src".as_ref(),
        rb.as_os_str(),
        "--path".as_ref(),
        "circle".as_ref(),
        "--gif".as_ref(),
    ])?
    .inner;
    r.out = a.out.join("views");
    r.export = Some(a.out.join("viewer"));
    r.overwrite = true;
    (cmd.render)(&r)?;
    println!(
        "demo finished in {:.1} min: video.mp4 (and path.gif) in {}, viewer {} (open it in a browser: the video plays beside the interactive view). \
         The training and evaluation walk-through: cargo xtask demo --full",
        t0.elapsed().as_secs_f64() / 60.0,
        a.out.join("views").display(),
        a.out.join("viewer").join("index.html").display()
    );
    Ok(())
}

fn full(a: &DemoArgs, cmd: &Commands<'_>) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let stage = |k: usize, what: &str| {
        println!(
            "[{k}/5] {what} ({:.1} min so far)",
            t0.elapsed().as_secs_f64() / 60.0
        );
    };
    stage(1, "synthetic scenes");
    crate::common::ensure_synthetic(&a.data)?;
    stage(
        2,
        "pretrained weights (VGG16 for the perceptual loss, AlexNet for LPIPS)",
    );
    if a.offline {
        println!("  --offline: skipped");
    } else {
        let mut w = defaults::<WeightsArgs>();
        w.cache.clone_from(&a.cache);
        if let Err(e) = (cmd.weights)(&w) {
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
    train(cmd, &runs.join("mhi"), a, |_| {})?;
    stage(
        4,
        "training the MPI baseline (N = 1, same code and budget per step)",
    );
    train(cmd, &runs.join("mpi"), a, |t| {
        t.normals = 1;
        t.phase2_steps = 0;
    })?;
    stage(
        5,
        "evaluating every method (and the pretrained model) on the synthetic test scenes",
    );
    let mut e = defaults::<EvalArgs>();
    e.data = vec![a.data.clone()];
    e.runs = vec![runs.join("mhi"), runs.join("mpi")];
    e.out = a.out.join("report");
    e.overwrite = true;
    e.per_sequence = a.per_sequence;
    // Twice the training size: the CPU-sized models are trained at 64 x 64, the report is read
    // at 128 x 128 (the synthetic frames are 256 x 256; `eval` alone defaults to them).
    e.size = Some((128, 128));
    e.cache.clone_from(&a.cache);
    // The pretrained model beside the short runs (its own N and D; compared with the sweep of
    // the same N and D in the report).
    match crate::models::pretrained() {
        Some(p) => e.runs.push(p),
        None => println!(
            "  no pretrained model at {}; the report shows the short runs only",
            crate::models::pretrained_dir().display()
        ),
    }
    (cmd.eval)(&e)?;
    println!(
        "demo finished in {:.1} min; report: {}",
        t0.elapsed().as_secs_f64() / 60.0,
        a.out.join("report").join("report.md").display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The demo sets fields on each command's defaults: every option of those commands must
    /// keep a default (a required one would stop the demo), and the defaults are the commands'.
    #[test]
    fn the_commands_the_demo_runs_have_defaults_for_every_option() {
        let t = defaults::<TrainArgs>();
        assert_eq!(
            t.phase1_steps,
            mhi_net::TrainConfig::for_normals(5).phase1_steps
        );
        let e = defaults::<EvalArgs>();
        assert_eq!(e.per_sequence, 2);
        assert!(e.runs.is_empty() && !e.overwrite);
        let w = defaults::<WeightsArgs>();
        assert!(w.cache.is_none());
    }
}
