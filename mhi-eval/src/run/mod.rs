//! The project's evaluation, whole (`cargo xtask eval` is this with its options parsed): every
//! method that applies — the learned MHI and its heuristic blends, the MPI, the training-free
//! sweep, the oracle, the nearest view and renders read from files — scored on the triplets of
//! a dataset through [`crate::protocol`], with the time per novel view split into cost volume,
//! network, render and blend; the report (markdown, JSON, CSV), its figures, sample images, the
//! MHI layers of one scene, an orbit GIF and optionally a browser viewer.
//!
//! ```no_run
//! use clap::Parser as _;
//! # #[derive(clap::Parser)] struct Cli { #[command(flatten)] a: mhi_eval::run::EvalArgs }
//! // The options as `cargo xtask eval` takes them (every field is public, too).
//! let cli = Cli::parse_from(["eval", "--data", "data/synth", "--per-sequence", "1", "--out", "out/eval"]);
//! mhi_eval::run::eval(&cli.a)?; // out/eval/report.md, report.json, figures
//! # Ok::<(), anyhow::Error>(())
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::Bootstrap;
use crate::plot::{Curve, TimePoint};
use crate::protocol::{self, MethodError};
use crate::report::{self, Comparison, Config, Measurement, Row, Times, config_label};
use anyhow::{Context, bail};
use burn::tensor::Device;
use image::Rgb32FImage;
use mhi_data::output::StagedDir;
use mhi_data::sanitize::for_markdown;
use mhi_data::{Dataset, Fit, LoadedFrame, TripletIndex, TripletKind, load_frame, load_scene};
use mhi_geom::{BlendHeuristic, NormalSet};
use mhi_net::backbone::{Backbone, Net};
use mhi_net::{BlendChoice, Blended, MhiSource, Model, ViewSynthesis, multi_normal};
use mhi_render::{Blend, Mhi, Prune, RenderOptions, SweepConfig, heuristic_weights_for, render};
use serde::Serialize;

mod methods;
pub mod options;
mod pictures;
mod pruning;

use crate::images::{clipped, enlarge, factor_for, layer_picture, strip};
use methods::Ctx;
use pictures::{write_layers_and_orbit, write_samples};
use pruning::{PruneMeasure, budget_tradeoff, prune_markdown, prune_rows};

use crate::support::size_for;
pub use options::{DepthRange, EvalArgs, Method, PoseArg};

impl EvalArgs {
    /// The render plan of the scored images.
    pub fn prune(&self) -> Prune {
        if self.exact {
            Prune::NONE
        } else {
            Prune::with_budget(self.budget / 255.0)
        }
    }

    /// The budgets (8-bit levels) measured against exact renders: --budget (unless --exact)
    /// and --also-budgets.
    fn measured_budgets(&self) -> Vec<f32> {
        let main = (!self.exact && self.budget > 0.0).then_some(self.budget);
        main.into_iter()
            .chain(self.also_budgets.iter().copied())
            .collect()
    }
}

/// Parse an `NxD` configuration (normals x planes per normal), e.g. `5x16`.
pub fn parse_nd(s: &str) -> anyhow::Result<(usize, usize)> {
    let (n, d) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("configuration {s:?} must look like 5x8 (normals x planes)"))?;
    let n = options::parse_normals(n)
        .map_err(|e| anyhow::anyhow!("configuration {s:?}: normals {e}"))?;
    let d: usize = d
        .trim()
        .parse()
        .with_context(|| format!("planes in {s:?}"))?;
    if n == 0 || d == 0 {
        bail!("configuration {s:?}: normals and planes must be positive");
    }
    Ok((n, d))
}

struct Loaded {
    run: PathBuf,
    model: Model,
}

/// A rendered method output for one triplet.
struct Output {
    method: String,
    normals: usize,
    planes: usize,
    image: Rgb32FImage,
    times: Times,
    /// The same MHI rendered exactly beside renders of it within a budget: `image` (within
    /// --budget) and any within --also-budgets.
    exact: Vec<ExactCheck>,
}

/// An exact render beside a pruned one of the same MHI and view.
struct ExactCheck {
    /// The budget of the pruned render, in 8-bit levels.
    budget: f32,
    /// The pruned render and its time, when it is not the scored image (a budget of
    /// --also-budgets; the scored one's time is in the output's `times`).
    pruned: Option<(Rgb32FImage, f64)>,
    image: Rgb32FImage,
    /// Time of the exact render.
    render_ms: f64,
    /// What the pruned render left out.
    stats: mhi_render::RenderStats,
    /// The least share of samples any render within the budget composites
    /// ([`mhi_render::needed_share`]).
    needed: f32,
}

#[derive(Serialize)]
struct Meta {
    /// Where the input cameras came from (`given`, or estimated with how many fell back).
    poses: String,
    dataset: String,
    split: String,
    sequences: Vec<String>,
    triplets: usize,
    bin_counts: [usize; 4],
    /// The first sequence's evaluation size (all of them in `sizes`).
    size: (u32, u32),
    sizes: Vec<(u32, u32)>,
    runs: Vec<serde_json::Value>,
    lpips: String,
    covered: String,
    timing: String,
    sweep: SweepConfig,
    bootstrap: Bootstrap,
    machine: String,
    threads: usize,
    date: String,
    /// The largest rotation of the orbit GIF's cameras from the reference, in degrees.
    orbit_rotation_deg: Option<f64>,
    /// Renders scored from files (`--renders NAME=DIR`): name and folder.
    renders: Vec<(String, String)>,
    /// With `--poses estimated`: each triplet's estimated source pose against the true one.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pose_errors: Vec<PoseError>,
}

/// One triplet's estimated relative pose (source from reference) against the dataset's.
#[derive(Serialize)]
struct PoseError {
    triplet: usize,
    sequence: String,
    reference: usize,
    source: usize,
    /// Degrees; `None` when there was no estimate (the true pose was kept).
    rotation_deg: Option<f64>,
    /// The angle between the estimated and the true translation directions, in degrees.
    direction_deg: Option<f64>,
    /// The true baseline, in the dataset's units.
    baseline: f64,
    /// The estimate's median parallax once the rotation is removed, in degrees.
    median_parallax_deg: Option<f64>,
}

#[derive(Serialize)]
struct ReportJson<'a> {
    meta: &'a Meta,
    rows: &'a [Row],
    comparisons: &'a [Comparison],
    measurements: &'a [Measurement],
}

/// `cargo xtask eval`: the report is built beside `--out` and swapped into place whole (see
/// [`mhi_data::output`]), as is the `--export` viewer.
pub fn eval(a: &EvalArgs) -> anyhow::Result<()> {
    if a.data.len() == 1 && a.data[0] == Path::new("data/synth") {
        crate::support::ensure_synthetic(&a.data[0])?;
    }
    if let Some(dir) = &a.export {
        let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        if abs(dir).starts_with(abs(&a.out)) || abs(&a.out).starts_with(abs(dir)) {
            bail!(
                "--out {} and --export {} lie one inside the other: give the viewer a folder of its own",
                a.out.display(),
                dir.display()
            );
        }
    }
    crate::support::check_gif_frames("--orbit-frames", a.orbit_frames)?;
    let report = StagedDir::begin(&a.out, "eval report", a.overwrite)?;
    let viewer = a
        .export
        .as_deref()
        .map(|d| StagedDir::begin(d, "viewer", a.overwrite))
        .transpose()?;
    for n in std::iter::once(&report)
        .chain(&viewer)
        .flat_map(|s| s.notes())
    {
        println!("note: {n}");
    }
    let mut staged = a.clone();
    staged.out = report.path().to_path_buf();
    staged.export = viewer.as_ref().map(|v| v.path().to_path_buf());
    evaluate(&staged)?;
    if let Some(v) = viewer {
        let dir = v.commit()?;
        println!(
            "viewer of the first triplet: {}",
            dir.join("index.html").display()
        );
    }
    let dir = report.commit()?;
    println!("report: {}", dir.join("report.md").display());
    Ok(())
}

fn evaluate(a: &EvalArgs) -> anyhow::Result<()> {
    check_options(a)?;
    let (ds, index) = open_triplets(a)?;
    let cpu = Device::flex();
    let models = load_models(a, &cpu)?;
    let (sweep_grid, oracle_grid, sweep_config, sizes) = plan_grids_and_sizes(a, &ds, &models)?;
    let weights_dir = crate::support::cache_dir(a.cache.as_deref()).join("weights");
    let lpips_net = Backbone::load(&weights_dir, Net::Alex, &cpu)
        .inspect_err(|e| {
            eprintln!("note: LPIPS not computed ({e}; `cargo xtask weights` fetches them)");
        })
        .ok();
    let ctx = Ctx {
        a,
        models: &models,
        sweep_grid: &sweep_grid,
        oracle_grid: &oracle_grid,
        sweep_config,
    };
    let pb = crate::progress::bar(index.triplets.len() as u64 + 1, "eval");
    let mut measurements: Vec<Measurement> = Vec::new();
    let mut pruning: Vec<PruneMeasure> = Vec::new();
    let mut orbit_rotation = None;
    let mut sample_md = String::new();
    let mut sizes_used = Vec::new();
    let mut pose_errors: Vec<PoseError> = Vec::new();
    for (ti, t) in index.triplets.iter().enumerate() {
        let seq = ds
            .sequence(&t.sequence)
            .context("triplet sequence vanished")?;
        let size = sizes[&seq.name];
        if !sizes_used.contains(&size) {
            sizes_used.push(size);
        }
        let (rf, sf, tf) = load_triplet(a, seq, t, size, ti, &mut pose_errors)?;
        if ti == 0 {
            warm_up(&ctx, (&rf, &sf, &tf), seq)?;
            pb.inc(1);
        }
        let outputs = outputs_of(&ctx, (&rf, &sf, &tf), seq, t, size)?;
        let gt = &tf.image;
        let covered = crate::covered_mask(&rf.camera, &tf.camera, a.range.far);
        let lpips = |x: &Rgb32FImage, y: &Rgb32FImage| -> Result<f64, MethodError> {
            let net = lpips_net.as_ref().expect("only called with a network");
            Ok(lpips_of(net, x, y, &cpu)?)
        };
        for o in &outputs {
            let img = clipped(&o.image);
            measurements.push(protocol::score(
                ti,
                t,
                (o.method.clone(), o.normals, o.planes),
                &o.image,
                gt,
                &covered,
                (o.times, !a.renders.iter().any(|(n, _)| *n == o.method)),
                lpips_net.as_ref().map(|_| &lpips as protocol::Scorer<'_>),
            )?);
            for e in &o.exact {
                pruning.push(PruneMeasure::new(o, e, &img, gt, &covered)?);
            }
        }
        if ti < a.samples {
            sample_md.push_str(&write_samples(
                &a.out,
                ti,
                t,
                (&rf, &sf),
                gt,
                &covered,
                &outputs,
            )?);
        }
        if ti == 0 {
            orbit_rotation = write_layers_and_orbit(a, &models, &rf, &sf, &tf)?;
        }
        pb.inc(1);
    }
    pb.finish_and_clear();

    let boot = Bootstrap::default().with_seed(a.bootstrap_seed);
    let rows = report::aggregate(&measurements, &boot);
    let comparisons = comparisons(a, &rows, &measurements, &boot);
    let meta = report_meta(
        a,
        &ds,
        &index,
        &models,
        &sizes_used,
        (lpips_net.is_some(), &weights_dir),
        pose_errors,
        (sweep_config, boot),
        orbit_rotation,
    );
    let prune_rows = write_data_files(
        a,
        &ReportJson {
            meta: &meta,
            rows: &rows,
            comparisons: &comparisons,
            measurements: &measurements,
        },
        &pruning,
        &boot,
    )?;

    write_figures_and_markdown(
        a,
        &meta,
        &rows,
        &comparisons,
        &prune_rows,
        &models,
        &sample_md,
        &sizes_used,
    )?;
    print_summary(&rows, &comparisons);
    Ok(())
}

/// The paired comparisons: the default pairs of the configurations scored, and --compare's.
fn comparisons(
    a: &EvalArgs,
    rows: &[Row],
    measurements: &[Measurement],
    boot: &Bootstrap,
) -> Vec<Comparison> {
    let configs = report::configs(rows);
    let mut pairs = comparison_pairs(&configs);
    for (x, y) in &a.compare {
        for cx in configs.iter().filter(|c| c.0 == *x) {
            for cy in configs.iter().filter(|c| c.0 == *y) {
                if !pairs.contains(&(cx.clone(), cy.clone())) {
                    pairs.push((cx.clone(), cy.clone()));
                }
            }
        }
    }
    for (x, y) in &a.compare {
        for m in [x, y] {
            if !configs.iter().any(|c| c.0 == *m) {
                eprintln!(
                    "warning: --compare {x},{y}: {m} scored no view here (a method that needs a --run, or oracle on real photos?)"
                );
            }
        }
    }
    pairs
        .iter()
        .flat_map(|(x, y)| report::compare(measurements, x, y, boot))
        .collect()
}

/// What the report says about how it was made.
#[allow(clippy::too_many_arguments)]
fn report_meta(
    a: &EvalArgs,
    ds: &Dataset,
    index: &TripletIndex,
    models: &[Loaded],
    sizes_used: &[(u32, u32)],
    (lpips, weights_dir): (bool, &Path),
    pose_errors: Vec<PoseError>,
    (sweep_config, boot): (SweepConfig, Bootstrap),
    orbit_rotation: Option<f64>,
) -> Meta {
    Meta {
        dataset: a
            .data
            .iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        split: a.split.clone(),
        sequences: ds.sequences.iter().map(|s| s.name.clone()).collect(),
        triplets: index.triplets.len(),
        bin_counts: index.bin_counts(),
        size: sizes_used[0],
        sizes: sizes_used.to_vec(),
        runs: models
            .iter()
            .map(|m| {
                let c = m.model.config();
                serde_json::json!({
                    "run": m.run.display().to_string(), "normals": c.stage1.normals,
                    "planes": c.planes, "steps": m.model.step(), "phase1_steps": c.phase1_steps,
                    "phase2_steps": c.phase2_steps, "size": [c.width, c.height], "loss": c.loss,
                    "stage1_width": c.stage1.unet.width, "blend_width": c.blend.width,
                })
            })
            .collect(),
        lpips: if lpips {
            "LPIPS v0.1, AlexNet".into()
        } else {
            format!("not computed: no weights in {}", weights_dir.display())
        },
        covered: format!(
            "target pixels whose ray meets the reference camera's fronto-parallel plane at depth {} inside the reference image; LPIPS covered = LPIPS of the render with uncovered pixels replaced by the ground truth's",
            a.range.far
        ),
        poses: match a.poses {
            options::PoseArg::Given => "given (the dataset's cameras)".into(),
            options::PoseArg::Estimated => format!(
                "estimated from the frames by mhi-pose with the dataset's intrinsics, the translation scaled to the true baseline; {} of {} triplets kept the true pose (no estimate); each triplet's errors in pose_errors",
                pose_errors.iter().filter(|e| e.rotation_deg.is_none()).count(),
                index.triplets.len()
            ),
        },
        timing: "ms per view from the two decoded input images to the final image (cost volume or sweep, networks, building the MHI, render, blend), after one warm-up view; file I/O and metrics excluded".into(),
        sweep: sweep_config,
        bootstrap: boot,
        machine: machine(),
        threads: rayon::current_num_threads(),
        date: crate::support::date(),
        orbit_rotation_deg: orbit_rotation,
        renders: a
            .renders
            .iter()
            .map(|(n, d)| (n.clone(), d.display().to_string()))
            .collect(),
        pose_errors,
    }
}

/// A triplet's three frames at `size`; with --poses estimated, the source's camera estimated
/// from the frames (the true one kept, and said, when that fails), its errors pushed to
/// `pose_errors`.
fn load_triplet(
    a: &EvalArgs,
    seq: &mhi_data::Sequence,
    t: &mhi_data::Triplet,
    size: (u32, u32),
    ti: usize,
    pose_errors: &mut Vec<PoseError>,
) -> anyhow::Result<(LoadedFrame, LoadedFrame, LoadedFrame)> {
    let load = |i: usize| -> anyhow::Result<LoadedFrame> {
        Ok(load_frame(&seq.frames[i], Some(size), Fit::Stretch)?)
    };
    let (rf, mut sf, tf) = (load(t.reference)?, load(t.source)?, load(t.target)?);
    if a.poses == options::PoseArg::Estimated {
        let truth = sf
            .camera
            .cam_from_world
            .compose(&rf.camera.cam_from_world.inverse());
        let mut record = PoseError {
            triplet: ti,
            sequence: seq.name.clone(),
            reference: t.reference,
            source: t.source,
            rotation_deg: None,
            direction_deg: None,
            baseline: truth.translation().length(),
            median_parallax_deg: None,
        };
        match estimated_source(&seq.frames[t.reference], &seq.frames[t.source], &truth) {
            Ok((src_from_ref, parallax)) => {
                let o = mhi_pose::accuracy::Outcome::of(
                    src_from_ref.rotation(),
                    src_from_ref.translation(),
                    &truth,
                    0.0,
                );
                record.rotation_deg = Some(o.rotation_deg);
                record.direction_deg = Some(o.direction_deg);
                record.median_parallax_deg = Some(parallax);
                sf.camera.cam_from_world = src_from_ref.compose(&rf.camera.cam_from_world);
            }
            Err(e) => {
                eprintln!(
                    "warning: triplet {ti}: no estimated pose ({}); it keeps the true one",
                    mhi_data::sanitize::for_terminal(&format!("{e:#}"))
                );
            }
        }
        pose_errors.push(record);
    }
    Ok((rf, sf, tf))
}

/// report.json, pruning.json and report.csv; returns the pruned-against-exact rows.
fn write_data_files(
    a: &EvalArgs,
    doc: &ReportJson<'_>,
    pruning: &[PruneMeasure],
    boot: &Bootstrap,
) -> anyhow::Result<Vec<pruning::PruneRow>> {
    let json = serde_json::to_vec_pretty(doc)?;
    mhi_data::write_atomic(&a.out.join("report.json"), &json)?;
    let prune_rows = prune_rows(pruning, boot);
    mhi_data::write_atomic(
        &a.out.join("pruning.json"),
        &serde_json::to_vec_pretty(&serde_json::json!({
            "budget": a.prune().budget, "budget_levels": a.budget, "rows": prune_rows,
            "measurements": pruning,
        }))?,
    )?;
    mhi_data::write_atomic(&a.out.join("report.csv"), report::csv(doc.rows).as_bytes())?;
    Ok(prune_rows)
}

/// Warm-up: the first view of every method pays for allocations and lazy initialisation that a
/// user rendering many views pays once. Refuses a set of methods of which none applies.
fn warm_up(
    ctx: &Ctx<'_>,
    (rf, sf, tf): (&LoadedFrame, &LoadedFrame, &LoadedFrame),
    seq: &mhi_data::Sequence,
) -> anyhow::Result<()> {
    if ctx.run_methods(rf, sf, tf, seq)?.is_empty() && ctx.a.renders.is_empty() {
        bail!(
            "none of --methods {:?} applies here: learned, soft, hard and avg need a --run with N > 1, mpi a --run with N = 1, oracle synthetic scenes",
            ctx.a.methods
        );
    }
    Ok(())
}

/// Every method's view of a triplet, and the renders --renders scores from files.
fn outputs_of(
    ctx: &Ctx<'_>,
    (rf, sf, tf): (&LoadedFrame, &LoadedFrame, &LoadedFrame),
    seq: &mhi_data::Sequence,
    t: &mhi_data::Triplet,
    size: (u32, u32),
) -> anyhow::Result<Vec<Output>> {
    let mut outputs = ctx.run_methods(rf, sf, tf, seq)?;
    for (name, dir) in &ctx.a.renders {
        outputs.push(Output {
            method: name.clone(),
            normals: 0,
            planes: 0,
            image: load_render(&dir.join(render_file_name(seq, t)), size)?,
            times: Times::default(),
            exact: Vec::new(),
        });
    }
    Ok(outputs)
}

/// Refuse options that cannot be measured honestly, before any work.
fn check_options(a: &EvalArgs) -> anyhow::Result<()> {
    if !(a.budget.is_finite() && (0.0..=255.0).contains(&a.budget)) {
        bail!(
            "--budget {} must be a number of 8-bit levels in [0, 255] (1 by default)",
            a.budget
        );
    }
    for (k, b) in a.also_budgets.iter().enumerate() {
        if !(b.is_finite() && *b > 0.0 && *b <= 255.0) {
            bail!(
                "--also-budgets: {b} must be a number of 8-bit levels in (0, 255] (e.g. --also-budgets 2,4,8)"
            );
        }
        if a.also_budgets[..k].contains(b) || (!a.exact && *b == a.budget) {
            bail!(
                "--also-budgets: {b} is given twice (--budget {} is always measured unless --exact)",
                a.budget
            );
        }
    }
    if a.short_side < 32 {
        bail!(
            "--short-side {} is too small: LPIPS and SSIM need at least 32 pixels a side",
            a.short_side
        );
    }
    if let Some((w, h)) = a.size
        && (w < 32 || h < 32)
    {
        bail!("--size {w}x{h} is too small: LPIPS and SSIM need at least 32 pixels a side");
    }
    mhi_render::check_beta(a.consistency_beta).context("--consistency-beta")?;
    Ok(())
}

/// The dataset (its --sequences) and the triplets to score: --index, else drawn; --renders checked
/// against them.
fn open_triplets(a: &EvalArgs) -> anyhow::Result<(Dataset, TripletIndex)> {
    let ds = Dataset::open_many(&a.data, &a.split, 3)?;
    let ds = if a.sequences.is_empty() {
        ds
    } else {
        ds.select(&a.sequences, true).context("--sequences")?
    };
    for w in &ds.warnings {
        eprintln!(
            "warning: {}",
            mhi_data::sanitize::for_terminal(&w.to_string())
        );
    }
    let index = match &a.index {
        Some(p) => {
            let idx = TripletIndex::load(p)?;
            idx.validate(&ds, p)?;
            idx
        }
        None => crate::support::sample_index(&ds, a.per_sequence, a.seed)?,
    };
    if index.triplets.is_empty() {
        match &a.index {
            Some(p) => bail!("the index {} holds no triplet", p.display()),
            None if a.per_sequence == 0 => {
                bail!("--per-sequence 0 draws no triplet; give at least 1")
            }
            None => bail!(
                "{}: no triplet to evaluate (each sequence needs at least 3 frames)",
                ds.dir.display()
            ),
        }
    }
    check_renders(a, &ds, &index)?;
    Ok((ds, index))
}

/// The trained runs to evaluate: --run, else the pretrained model when a method needs one.
fn load_models(a: &EvalArgs, cpu: &Device) -> anyhow::Result<Vec<Loaded>> {
    let mut models = Vec::new();
    let mut runs = a.runs.clone();
    if runs.is_empty() && !a.no_pretrained {
        let needs_run = [
            Method::Learned,
            Method::Soft,
            Method::Hard,
            Method::Avg,
            Method::Consistent,
        ]
        .iter()
        .any(|m| a.methods.contains(m));
        if let Some(p) = mhi_net::pretrained::pretrained().filter(|_| needs_run) {
            println!(
                "using the pretrained model {} (--run chooses another, --no-pretrained none)",
                p.display()
            );
            runs.push(p);
        }
    }
    for run in &runs {
        let model = Model::load(run, cpu.clone())
            .with_context(|| format!("loading the trained run {}", run.display()))?;
        models.push(Loaded {
            run: run.clone(),
            model,
        });
    }
    Ok(models)
}

/// The sweep's and the oracle's grids, the sweep's settings, and each sequence's evaluation size,
/// checked against every model and the memory before any work.
#[allow(clippy::type_complexity)]
fn plan_grids_and_sizes(
    a: &EvalArgs,
    ds: &Dataset,
    models: &[Loaded],
) -> anyhow::Result<(
    Vec<(usize, usize)>,
    Vec<(usize, usize)>,
    SweepConfig,
    std::collections::BTreeMap<String, (u32, u32)>,
)> {
    let wants = |m: Method| a.methods.contains(&m);
    let sweep_grid: Vec<(usize, usize)> = if wants(Method::Sweep) {
        a.sweep_grid
            .iter()
            .map(|s| parse_nd(s))
            .collect::<anyhow::Result<_>>()?
    } else {
        Vec::new()
    };
    let synthetic = ds
        .sequences
        .iter()
        .all(|s| s.dir().join("scene.json").is_file());
    let oracle_grid: Vec<(usize, usize)> = if wants(Method::Oracle) && synthetic {
        a.oracle_grid
            .iter()
            .map(|s| parse_nd(s))
            .collect::<anyhow::Result<_>>()?
    } else {
        Vec::new()
    };
    let sweep_config = SweepConfig {
        window_radius: a.sweep_window,
        temperature: a.sweep_temperature,
        invalid_cost: a.sweep_invalid_cost,
    };
    // The size of each sequence, checked against every model before any work.
    let size_of = |seq: &mhi_data::Sequence| -> anyhow::Result<(u32, u32)> {
        Ok(match a.size {
            Some(s) => s,
            None => size_for(mhi_data::check_same_size(&[&seq.frames[0]])?, a.short_side),
        })
    };
    let mut sizes = std::collections::BTreeMap::new();
    for seq in &ds.sequences {
        let size = size_of(seq)?;
        for m in models {
            m.model.check_size(size.0, size.1).with_context(|| {
                format!(
                    "evaluation size of sequence {} (--size / --short-side) for the run {}",
                    seq.name,
                    m.run.display()
                )
            })?;
        }
        let layers = sweep_grid
            .iter()
            .chain(&oracle_grid)
            .map(|(n, d)| n * d)
            .chain(
                models
                    .iter()
                    .map(|m| m.model.normals().len() * m.model.depths().len() * 8),
            )
            .max()
            .unwrap_or(1);
        crate::support::check_memory(
            &format!("evaluation size of sequence {}", seq.name),
            size.0,
            size.1,
            layers,
        )?;
        sizes.insert(seq.name.clone(), size);
    }
    Ok((sweep_grid, oracle_grid, sweep_config, sizes))
}

/// The report's figures (error against time, the budget trade-off, training curves) and report.md.
#[allow(clippy::too_many_arguments)]
fn write_figures_and_markdown(
    a: &EvalArgs,
    meta: &Meta,
    rows: &[Row],
    comparisons: &[Comparison],
    prune_rows: &[pruning::PruneRow],
    models: &[Loaded],
    sample_md: &str,
    sizes_used: &[(u32, u32)],
) -> anyhow::Result<()> {
    // Figures, from the rows.
    let mut points = crate::plot::time_points(rows);
    // The same MHIs rendered exactly: a separate series, beside the pruned (scored) renders.
    for p in prune_rows
        .iter()
        .filter(|p| !a.exact && p.budget_levels == a.budget)
    {
        if let Some(r) = rows.iter().find(|r| {
            r.bin == "all"
                && r.kind == "all"
                && (&r.method, r.normals, r.planes) == (&p.method, p.normals, p.planes)
        }) {
            points.push(TimePoint {
                label: format!("{} exact", config_label(&p.method, p.normals, p.planes)),
                ms: r.ms_per_view - p.ms_pruned + p.ms_exact,
                psnr: p.psnr_exact,
                // No interval of its own: the pruned table gives its difference from the pruned
                // renders (ΔPSNR, a few thousandths of a dB) with one.
                psnr_ci: None,
            });
        }
    }
    crate::plot::error_vs_time(
        &a.out.join("error_vs_time"),
        &points,
        &format!(
            "covered PSNR against time per view ({}, {} triplets)",
            size_label(sizes_used),
            meta.triplets
        ),
    )?;
    if !a.also_budgets.is_empty() {
        budget_tradeoff(
            &a.out.join("budget_tradeoff"),
            prune_rows,
            &a.measured_budgets(),
        )?;
    }
    let curves = training_curves(models)?;
    let has_curves = !curves.is_empty();
    if has_curves {
        crate::plot::training_curve(
            &a.out.join("training_curve"),
            &curves,
            "validation PSNR during training",
        )?;
    }
    let md = markdown(meta, rows, comparisons, has_curves, sample_md, a, models);
    let md = md + &prune_markdown(prune_rows, a);
    mhi_data::write_atomic(&a.out.join("report.md"), md.as_bytes())?;
    Ok(())
}

/// The file of a triplet's render in a `--renders` folder: the sequence (a `/` of a qualified
/// name as `-`) and the timestamps of the reference, source and target frames.
pub(crate) fn render_file_name(seq: &mhi_data::Sequence, t: &mhi_data::Triplet) -> String {
    let ts = t
        .timestamps
        .unwrap_or_else(|| [t.reference, t.source, t.target].map(|i| seq.frames[i].row.timestamp));
    format!(
        "{}_{}_{}_{}.png",
        t.sequence.replace('/', "-"),
        ts[0],
        ts[1],
        ts[2]
    )
}

/// Before any work: every `--renders` folder holds a file for every triplet, and every
/// `--compare` name is a method this evaluation scores.
fn check_renders(a: &EvalArgs, ds: &Dataset, index: &TripletIndex) -> anyhow::Result<()> {
    for (k, (name, dir)) in a.renders.iter().enumerate() {
        if a.renders[..k].iter().any(|(n, _)| n == name) {
            bail!("--renders: the name {name:?} is given twice");
        }
        if !dir.is_dir() {
            bail!("--renders {name}={}: no such folder", dir.display());
        }
        let mut missing = Vec::new();
        for t in &index.triplets {
            let seq = ds
                .sequence(&t.sequence)
                .context("triplet sequence vanished")?;
            let f = dir.join(render_file_name(seq, t));
            if !f.is_file() {
                missing.push(f);
            }
        }
        if let Some(first) = missing.first() {
            bail!(
                "--renders {name}={}: {} of {} triplets have no render, e.g. {} (a render is named SEQUENCE_REF_SRC_TGT.png by its frames' timestamps; render the triplets of `cargo xtask triplets --save FILE` and pass FILE as --index)",
                dir.display(),
                missing.len(),
                index.triplets.len(),
                first.display()
            );
        }
    }
    let known = |m: &str| {
        a.renders.iter().any(|(n, _)| n == m)
            || a.methods
                .iter()
                .any(|x| clap::ValueEnum::to_possible_value(x).is_some_and(|v| v.get_name() == m))
    };
    for (x, y) in &a.compare {
        for m in [x, y] {
            if !known(m) {
                bail!("--compare {x},{y}: {m:?} is neither one of --methods nor a --renders name");
            }
        }
    }
    Ok(())
}

/// A render of `--renders`, checked to be at the evaluation size.
fn load_render(path: &Path, size: (u32, u32)) -> anyhow::Result<Rgb32FImage> {
    let img = image::open(path)
        .with_context(|| format!("--renders: cannot read the render {}", path.display()))?
        .to_rgb32f();
    if img.dimensions() != size {
        bail!(
            "--renders: {} is {}x{}, the evaluation size of its sequence is {}x{} (render at that size, or give eval the --size / --short-side the renders were made at)",
            path.display(),
            img.width(),
            img.height(),
            size.0,
            size.1
        );
    }
    if let Some(v) = img.as_raw().iter().find(|v| !v.is_finite()) {
        bail!("--renders: {} holds a non-finite value {v}", path.display());
    }
    Ok(img)
}

fn size_label(sizes: &[(u32, u32)]) -> String {
    sizes
        .iter()
        .map(|(w, h)| format!("{w}x{h}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The comparisons the report draws, among the configurations present: learned and consistent
/// each against Soft on their own stage 1, against the sweep and against the MPI, and learned
/// against consistent; the learned MPI against the sweep;
/// MHI against MPI (N > 1 against N = 1 at the same D) for the sweep and the oracle; the largest
/// sweep against the nearest view. A learned model meets the sweep of its N and D, or else the
/// sweep of its N with the most planes.
fn comparison_pairs(cfgs: &[Config]) -> Vec<(Config, Config)> {
    let has = |c: &Config| cfgs.contains(c);
    let mut out = Vec::new();
    let mut push = |x: Config, y: Config| {
        if has(&x) && has(&y) && !out.contains(&(x.clone(), y.clone())) {
            out.push((x, y));
        }
    };
    let of = |m: &str| -> Vec<Config> { cfgs.iter().filter(|c| c.0 == m).cloned().collect() };
    let sweep_for = |l: &Config| -> Option<Config> {
        let sweeps = of("sweep");
        let same = sweeps.iter().find(|s| s.1 == l.1 && s.2 == l.2);
        let any = sweeps.iter().filter(|s| s.1 == l.1).max_by_key(|s| s.2);
        same.or(any).cloned()
    };
    for l in of("learned").into_iter().chain(of("consistent")) {
        push(l.clone(), ("soft".into(), l.1, l.2));
        if let Some(s) = sweep_for(&l) {
            push(l.clone(), s);
        }
        for m in of("mpi") {
            push(l.clone(), m);
        }
        if l.0 == "learned" {
            push(l.clone(), ("consistent".into(), l.1, l.2));
        }
    }
    for m in of("mpi") {
        if let Some(s) = sweep_for(&m) {
            push(m, s);
        }
    }
    for method in ["sweep", "oracle"] {
        for c in of(method).into_iter().filter(|c| c.1 > 1) {
            push(c.clone(), (method.into(), 1, c.2));
        }
    }
    if let Some(s) = of("sweep").into_iter().max_by_key(|c| (c.1 * c.2, c.1)) {
        push(s, ("nearest".into(), 0, 0));
    }
    out
}

/// `img` with every pixel outside `covered` replaced by `truth`'s: the uncovered region then
/// adds nothing to a whole-image metric such as LPIPS.
fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn lpips_of(
    net: &Backbone,
    a: &Rgb32FImage,
    b: &Rgb32FImage,
    device: &Device,
) -> anyhow::Result<f64> {
    let ta = mhi_render::diff::image_to_tensor(a, device);
    let tb = mhi_render::diff::image_to_tensor(b, device);
    let v: Vec<f32> = net
        .lpips(ta, tb)
        .into_data()
        .try_to_vec()
        .map_err(|e| anyhow::anyhow!("LPIPS output: {e:?}"))?;
    let x = f64::from(v[0]);
    if !x.is_finite() {
        bail!("LPIPS is {x}");
    }
    Ok(x)
}

fn training_curves(models: &[Loaded]) -> anyhow::Result<Vec<Curve>> {
    let mut curves = Vec::new();
    for m in models {
        let rows = mhi_net::RunDir::new(&m.run).val_rows()?;
        if rows.is_empty() {
            continue;
        }
        let n = m.model.normals().len();
        let learned: Vec<(f64, f64)> = rows.iter().map(|r| (r.elapsed_s, r.psnr_learned)).collect();
        let soft: Vec<(f64, f64)> = rows.iter().map(|r| (r.elapsed_s, r.psnr_soft)).collect();
        let name = m
            .run
            .file_name()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        // On the sweep prior the untrained model renders the sweep (tested to 1e-5), so the
        // step-0 row is the sweep's level on the same validation triplets: drawn as a line.
        let sweep_level = (m.model.config().prior == mhi_net::Prior::Sweep)
            .then(|| rows.first().filter(|r| r.step == 0))
            .flatten()
            .map(|r0| Curve {
                label: format!("{name}: the sweep N={n} (its untrained step 0)"),
                points: vec![
                    (0.0, r0.psnr_soft),
                    (rows.last().map_or(0.0, |r| r.elapsed_s), r0.psnr_soft),
                ],
            });
        if n > 1 {
            curves.push(Curve {
                label: format!("{name}: learned blend (N={n})"),
                points: learned,
            });
            curves.push(Curve {
                label: format!("{name}: Soft on its stage 1"),
                points: soft,
            });
        } else {
            curves.push(Curve {
                label: format!("{name}: MPI (N=1)"),
                points: soft,
            });
        }
        curves.extend(sweep_level);
    }
    Ok(curves)
}

fn markdown(
    meta: &Meta,
    rows: &[Row],
    comparisons: &[Comparison],
    has_curves: bool,
    samples: &str,
    a: &EvalArgs,
    models: &[Loaded],
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# MHI evaluation report\n");
    let _ = writeln!(s, "Input cameras: {}.\n", meta.poses);
    let _ = writeln!(
        s,
        "Dataset {} (split {}, {} sequences), {} triplets (rotation bins {}: {} / {} / {} / {}), evaluated at {}. {}. Sweep: window radius {} px at a short side of 256 (scaled with each sequence's short side: {} px at {}), temperature {}, cost of an unseen plane {}. Intervals: 95 % percentile bootstrap over triplets ({} resamples, seed {}). Machine: {}, {} threads, {}.\n",
        for_markdown(&meta.dataset),
        for_markdown(&meta.split),
        meta.sequences.len(),
        meta.triplets,
        mhi_data::RotationBin::ALL.map(|b| b.label()).join(" / "),
        meta.bin_counts[0],
        meta.bin_counts[1],
        meta.bin_counts[2],
        meta.bin_counts[3],
        size_label(&meta.sizes),
        meta.lpips,
        meta.sweep.window_radius,
        meta.sweep
            .scaled_to_short_side(meta.size.0.min(meta.size.1))
            .window_radius,
        meta.size.0.min(meta.size.1),
        meta.sweep.temperature,
        meta.sweep.invalid_cost,
        meta.bootstrap.resamples,
        meta.bootstrap.seed,
        meta.machine,
        meta.threads,
        meta.date
    );
    let _ = writeln!(
        s,
        "Methods: `learned` = stage 1 + learned blending network; `soft`/`hard`/`avg` = the same stage 1 with the paper's heuristic blends; `consistent` = the same stage 1, Soft weights leaning towards the normals both photos agree with (β {}); `mpi` = a run trained with N = 1 (the MPI baseline, same code); `sweep` = training-free plane-sweep MHI (photo-consistency, no network); `oracle` = MHI built from the scene's exact geometry with Soft blending (synthetic only; its time is render + blend only); `nearest` = the input view nearest the target, shown as it is. Scores are computed on images clipped to [0, 1]. Times are wall-clock on this machine, one view at a time, {}.\n",
        a.consistency_beta, meta.timing
    );
    for (m, r) in models.iter().zip(&meta.runs) {
        let c = m.model.config();
        let _ = writeln!(
            s,
            "- run {}: N = {}, D = {}, trained {} of {} steps at {}x{}, loss: {}{}",
            for_markdown(&m.run.display().to_string()),
            c.stage1.normals,
            c.planes,
            m.model.step(),
            c.total_steps(),
            c.width,
            c.height,
            c.loss,
            if m.model.normals().len() > 1 && !m.model.blend_trained() {
                " (**blending network not trained yet: phase 2 never ran**)"
            } else {
                ""
            }
        );
        let _ = writeln!(s, "  (run record: {r})");
    }
    for (name, dir) in &meta.renders {
        let _ = writeln!(
            s,
            "- `{name}`: renders made by another program, read from `{dir}` (one PNG per triplet) and scored here like every method; their time was not measured here"
        );
    }
    s.push('\n');
    s.push_str(&report::markdown_tables(rows, comparisons));
    let _ = writeln!(
        s,
        "## Error against time\n\n![error vs time](error_vs_time.svg)\n\nCovered PSNR of each method and configuration (all triplets) against its time per view, with its 95 % interval as a bar (the spread of each mean over the triplets; the paired comparisons below measure differences between methods much more tightly); the red line is the Pareto front. PNG: [error_vs_time.png](error_vs_time.png).\n"
    );
    if has_curves {
        let _ = writeln!(
            s,
            "## Training\n\n![training curve](training_curve.svg)\n\nValidation PSNR (held-out triplets of the training scenes, logged at every checkpoint) against wall-clock training time; for a model on the sweep prior a flat line marks the sweep's level on the same triplets (its untrained step 0, which renders the sweep).\n"
        );
    }
    let _ = writeln!(
        s,
        "## MHI of the first triplet's reference view\n\nEach normal's layers (far to near), colour × alpha over a checkerboard:\n"
    );
    let n = std::fs::read_dir(a.out.join("layers"))
        .map(|r| {
            r.flatten()
                .filter(|e| e.file_name().to_string_lossy().starts_with("normal_"))
                .count()
        })
        .unwrap_or(0);
    for i in 0..n {
        let _ = writeln!(s, "normal {i}: <img src=\"layers/normal_{i}.png\">\n");
    }
    let _ = writeln!(
        s,
        "Multi-normal images in the target view, and the blend weight of each (white = 1):\n\n<img src=\"layers/multi_normal.png\">\n\n<img src=\"layers/weights.png\">\n"
    );
    if let Some(deg) = meta.orbit_rotation_deg {
        let _ = writeln!(
            s,
            "## Orbit\n\nA circle of cameras around the reference view (radius half the input baseline), each turned toward the median depth of the first triplet's MHI: the rotation reaches {deg:.1}°:\n\n![orbit](orbit.gif)\n"
        );
    }
    let _ = writeln!(s, "## Samples\n\n{samples}");
    s
}

fn print_summary(rows: &[Row], comparisons: &[Comparison]) {
    println!(
        "{:<24} {:>6} {:>22} {:>8} {:>8} {:>8} {:>10}",
        "method", "views", "covered PSNR [95 %]", "cov.SSIM", "cov.LPIPS", "PSNR", "ms/view"
    );
    let opt = |v: Option<f64>, p: usize| v.map_or("-".into(), |x| format!("{x:.p$}"));
    for r in rows.iter().filter(|r| r.bin == "all" && r.kind == "all") {
        let cov = match (r.psnr_covered, r.psnr_covered_ci) {
            (Some(p), Some(c)) => format!("{p:.2} [{:.2}, {:.2}]", c[0], c[1]),
            _ => "-".into(),
        };
        println!(
            "{:<24} {:>6} {:>22} {:>8} {:>8} {:>8.2} {:>10.1}",
            config_label(&r.method, r.normals, r.planes),
            r.count,
            cov,
            opt(r.ssim_covered, 3),
            opt(r.lpips_covered, 3),
            r.psnr,
            r.ms_per_view
        );
    }
    for c in comparisons.iter().filter(|c| {
        c.bin == "all" && c.kind == "all" && c.metric == crate::report::Metric::PsnrCovered
    }) {
        println!(
            "{} − {}: covered PSNR {:+.2} dB [{:+.2}, {:+.2}] ({})",
            c.a,
            c.b,
            c.diff,
            c.ci[0],
            c.ci[1],
            c.verdict()
        );
    }
}

/// The source-from-reference pose `mhi-pose` estimates from the two frames' pixels (their
/// known intrinsics), its translation scaled to the length of `truth`'s, and the estimate's
/// median parallax (degrees). The caller keeps the reference's true pose, so the target's true
/// pose relative to it stands.
fn estimated_source(
    reference: &mhi_data::Frame,
    source: &mhi_data::Frame,
    truth: &mhi_geom::RigidTransform,
) -> anyhow::Result<(mhi_geom::RigidTransform, f64)> {
    let (pa, pb) = (
        mhi_pose::Photo::open(&reference.path)?,
        mhi_pose::Photo::open(&source.path)?,
    );
    let options = mhi_pose::Options {
        ref_intrinsics: Some(reference.row.intrinsics),
        src_intrinsics: Some(source.row.intrinsics),
        ..mhi_pose::Options::default()
    };
    let pair = mhi_pose::estimate(&pa, &pb, &options)?;
    let t = pair.translation().normalize() * truth.translation().length();
    Ok((
        mhi_geom::RigidTransform::new(pair.rotation(), t)?,
        pair.median_parallax_deg,
    ))
}

fn machine() -> String {
    crate::support::cpu_model()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evaluation_size_keeps_the_aspect_ratio_on_a_short_side() {
        assert_eq!(size_for((640, 360), 256), (448, 256));
        assert_eq!(size_for((768, 512), 256), (384, 256));
        assert_eq!(size_for((504, 378), 256), (336, 256));
        assert_eq!(size_for((256, 256), 256), (256, 256));
        assert_eq!(size_for((360, 640), 256), (256, 448));
        assert_eq!(size_for((10_000, 10), 32), (32_000, 32));
    }

    #[test]
    fn comparisons_are_drawn_only_between_configurations_present() {
        let c = |m: &str, n, d| (m.to_string(), n, d);
        let cfgs = vec![
            c("learned", 5, 8),
            c("soft", 5, 8),
            c("mpi", 1, 8),
            c("sweep", 1, 32),
            c("sweep", 5, 32),
            c("nearest", 0, 0),
        ];
        let p = comparison_pairs(&cfgs);
        assert!(p.contains(&(c("learned", 5, 8), c("soft", 5, 8))));
        assert!(p.contains(&(c("learned", 5, 8), c("sweep", 5, 32))));
        assert!(p.contains(&(c("learned", 5, 8), c("mpi", 1, 8))));
        assert!(p.contains(&(c("mpi", 1, 8), c("sweep", 1, 32))));
        assert!(!p.contains(&(c("mpi", 1, 8), c("sweep", 5, 32))));
        assert!(p.contains(&(c("sweep", 5, 32), c("sweep", 1, 32))));
        assert!(p.contains(&(c("sweep", 5, 32), c("nearest", 0, 0))));
        assert!(p.iter().all(|(a, b)| cfgs.contains(a) && cfgs.contains(b)));
        assert!(
            !p.iter()
                .any(|(a, b)| a.0 == "consistent" || b.0 == "consistent")
        );
        let mut with = cfgs.clone();
        with.push(c("consistent", 5, 8));
        let p = comparison_pairs(&with);
        for other in [c("soft", 5, 8), c("sweep", 5, 32), c("mpi", 1, 8)] {
            assert!(p.contains(&(c("consistent", 5, 8), other)));
        }
        assert!(p.contains(&(c("learned", 5, 8), c("consistent", 5, 8))));
    }
}
