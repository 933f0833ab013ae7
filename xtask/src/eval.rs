//! `cargo xtask eval`: every method that applies, scored on the triplets of a dataset, with the
//! time per novel view split into cost volume, network, render and blend; the report (markdown,
//! JSON, CSV), its figures, sample images, the MHI layers of one scene and an orbit GIF.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use burn::tensor::Device;
use clap::Args;
use image::Rgb32FImage;
use mhi_data::{Dataset, Fit, LoadedFrame, TripletIndex, TripletKind, load_frame, load_scene};
use mhi_eval::Bootstrap;
use mhi_eval::plot::{Curve, TimePoint};
use mhi_eval::report::{self, Comparison, Config, Measurement, Row, Times, config_label};
use mhi_geom::{BlendHeuristic, NormalSet, depths_linear_in_disparity};
use mhi_net::Model;
use mhi_net::backbone::{Backbone, Net};
use mhi_render::heuristic_weights_for;
use mhi_render::{
    Blend, LayerColor, Mhi, Prune, RenderOptions, SweepConfig, oracle_alpha, render, sweep_mhi,
};
use serde::Serialize;

use crate::views::{clipped, combine, enlarge, factor_for, layer_picture, render_mni, strip};

/// A method `cargo xtask eval` can score.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Stage 1 of a trained run with N > 1 and its learned blending network.
    Learned,
    /// The same stage 1, blended with the paper's Soft heuristic.
    Soft,
    /// The same stage 1, Hard blending (one normal per pixel).
    Hard,
    /// The same stage 1, Avg blending.
    Avg,
    /// A trained run with N = 1 (the MPI baseline).
    Mpi,
    /// The training-free plane-sweep MHI at each --sweep-grid configuration.
    Sweep,
    /// The MHI of the scene's exact geometry (synthetic scenes only).
    Oracle,
    /// The input view nearest the target, shown as it is.
    Nearest,
}

/// Options of `cargo xtask eval`.
#[derive(Args, Debug, Clone)]
pub struct EvalArgs {
    /// Dataset root in RealEstate10K layout; repeat for several (sequence names are then
    /// qualified by the root's folder name, e.g. `llff-6/room`). Synthetic scenes are generated
    /// at the default path if missing.
    #[arg(long, default_value = "data/synth")]
    pub data: Vec<PathBuf>,
    /// Split to evaluate (real training roots keep whole sequences for validation: evaluate
    /// those with `--split train --sequences NAME`).
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Only these sequences (comma-separated; qualified names with several roots).
    #[arg(long, value_delimiter = ',')]
    pub sequences: Vec<String>,
    /// Triplet index (JSON from `cargo xtask triplets --save`); default: sample --per-sequence
    /// triplets per sequence with --seed (video: Stereo Magnification's clips of 10 frames at a
    /// stride of 3-10; sparse captures: neighbouring views), half interpolation, half
    /// extrapolation.
    #[arg(long)]
    pub index: Option<PathBuf>,
    /// Triplets sampled per sequence when no --index is given.
    #[arg(long, default_value_t = 2)]
    pub per_sequence: usize,
    /// Seed of the sampled triplets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Seed of the bootstrap resampling behind every interval of the report.
    #[arg(long, default_value_t = 0)]
    pub bootstrap_seed: u64,
    /// A trained run (repeat for several): N > 1 gives `learned`, `soft`, `hard` and `avg`;
    /// N = 1 gives `mpi`. Default: the pretrained model in `models/` when there is one.
    #[arg(long = "run")]
    pub runs: Vec<PathBuf>,
    /// Do not fall back to the pretrained model when no --run is given.
    #[arg(long)]
    pub no_pretrained: bool,
    /// Methods to score (comma-separated); `learned`/`soft`/`hard`/`avg`/`mpi` need a --run,
    /// `oracle` synthetic scenes.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "learned,soft,hard,avg,mpi,sweep,oracle,nearest"
    )]
    pub methods: Vec<Method>,
    /// (N, D) configurations of the training-free sweep, as NxD (N in 1, 2, 3, 5).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1x8,5x8,1x16,5x16,1x32,5x32"
    )]
    pub sweep_grid: Vec<String>,
    /// Radius of the sweep's photo-consistency window (chosen on validation sequences; see
    /// README).
    #[arg(long, default_value_t = SweepConfig::default().window_radius)]
    pub sweep_window: u32,
    /// Softmax temperature of the sweep's winner-take-all over depths (chosen on validation
    /// sequences; see README).
    #[arg(long, default_value_t = SweepConfig::default().temperature)]
    pub sweep_temperature: f32,
    /// (N, D) configurations of the oracle (synthetic scenes only).
    #[arg(long, value_delimiter = ',', default_value = "1x8,5x8,5x32")]
    pub oracle_grid: Vec<String>,
    /// Evaluation size WIDTHxHEIGHT for every sequence (default: the short side at
    /// --short-side, the aspect ratio kept).
    #[arg(long, value_parser = crate::data::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Short side of the evaluation size when no --size is given; the long side keeps the
    /// frames' aspect ratio, rounded to a multiple of 16 (the networks' stride).
    #[arg(long, default_value_t = 256)]
    pub short_side: u32,
    /// Nearest plane depth of the sweep and oracle.
    #[arg(long, default_value_t = 1.0)]
    pub near: f64,
    /// Farthest plane depth of the sweep and oracle; the covered region is what the reference
    /// view sees on the fronto-parallel plane at this depth.
    #[arg(long, default_value_t = 100.0)]
    pub far: f64,
    /// Output directory of the report.
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Replace a report already in --out.
    #[arg(long)]
    pub overwrite: bool,
    /// Sample sheets (ground truth, each method, error maps) for this many triplets.
    #[arg(long, default_value_t = 4)]
    pub samples: usize,
    /// Frames of the orbit GIF (0: none).
    #[arg(long, default_value_t = 24)]
    pub orbit_frames: usize,
    /// Weights cache for LPIPS (default: $MHI_CACHE, else ~/.cache/mhi); see `cargo xtask weights`.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Score exact renders. By default every MHI is rendered leaving out what the view does not
    /// need within --budget (the report's pruned-vs-exact table measures what that changes).
    #[arg(long)]
    pub exact: bool,
    /// The error budget of a pruned render, in 8-bit levels per pixel (1 = 1/255).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub budget: f32,
}

impl EvalArgs {
    /// The render plan of the scored images.
    pub fn prune(&self) -> Prune {
        if self.exact {
            Prune::NONE
        } else {
            Prune::with_budget(self.budget / 255.0)
        }
    }
}

/// The evaluation size of frames of `dims`: `short` pixels on the short side, the long side in
/// proportion rounded to a multiple of 16 (at least 16).
pub fn size_for(dims: (u32, u32), short: u32) -> (u32, u32) {
    let (w, h) = (f64::from(dims.0), f64::from(dims.1));
    let long = |l: f64, s: f64| ((l / s * f64::from(short) / 16.0).round() as u32).max(1) * 16;
    if dims.0 >= dims.1 {
        (long(w, h), short)
    } else {
        (short, long(h, w))
    }
}

pub fn parse_nd(s: &str) -> anyhow::Result<(usize, usize)> {
    let (n, d) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("configuration {s:?} must look like 5x8 (normals x planes)"))?;
    let n = crate::data::parse_normals(n)
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
    /// The same MHI rendered exactly, when `image` was rendered pruned.
    exact: Option<ExactCheck>,
}

/// An exact render beside a pruned one of the same MHI and view.
struct ExactCheck {
    image: Rgb32FImage,
    /// Time of the exact render (the pruned one's is in `times`).
    render_ms: f64,
    /// What the pruned render left out.
    stats: mhi_render::RenderStats,
}

#[derive(Serialize)]
struct Meta {
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
}

#[derive(Serialize)]
struct ReportJson<'a> {
    meta: &'a Meta,
    rows: &'a [Row],
    comparisons: &'a [Comparison],
    measurements: &'a [Measurement],
}

/// `cargo xtask eval`.
pub fn eval(a: &EvalArgs) -> anyhow::Result<()> {
    if a.data.len() == 1 && a.data[0] == Path::new("data/synth") {
        crate::experiments::ensure_synthetic(&a.data[0])?;
    }
    if a.out.join("report.json").exists() && !a.overwrite {
        bail!(
            "{} already holds a report; pass --overwrite to replace it or choose another --out",
            a.out.display()
        );
    }
    if !(a.budget.is_finite() && (0.0..=255.0).contains(&a.budget)) {
        bail!(
            "--budget {} must be a number of 8-bit levels in [0, 255] (1 by default)",
            a.budget
        );
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
    let ds = Dataset::open_many(&a.data, &a.split, 3)?;
    let ds = if a.sequences.is_empty() {
        ds
    } else {
        ds.select(&a.sequences, true).context("--sequences")?
    };
    for w in &ds.warnings {
        eprintln!("warning: {}: {}", w.path.display(), w.message);
    }
    let index = match &a.index {
        Some(p) => {
            let idx = TripletIndex::load(p)?;
            idx.validate(&ds, p)?;
            idx
        }
        None => TripletIndex::sample(&ds, a.per_sequence, a.seed),
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
    let cpu = Device::flex();
    let mut models = Vec::new();
    let mut runs = a.runs.clone();
    if runs.is_empty() && !a.no_pretrained {
        let needs_run = [Method::Learned, Method::Soft, Method::Hard, Method::Avg]
            .iter()
            .any(|m| a.methods.contains(m));
        if let Some(p) = crate::models::pretrained().filter(|_| needs_run) {
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
        ..SweepConfig::default()
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
        for m in &models {
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
        crate::data::check_memory(
            &format!("evaluation size of sequence {}", seq.name),
            size.0,
            size.1,
            layers,
        )?;
        sizes.insert(seq.name.clone(), size);
    }
    let weights_dir = crate::weights::cache_dir(a.cache.as_deref()).join("weights");
    let lpips_net = match Backbone::load(&weights_dir, Net::Alex, &cpu) {
        Ok(b) => Some(b),
        Err(e) => {
            eprintln!("note: LPIPS not computed ({e})");
            None
        }
    };
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    // A report replaced with --overwrite must not keep pictures of the one before.
    for stale in ["samples", "layers"] {
        let p = a.out.join(stale);
        if p.is_dir() {
            std::fs::remove_dir_all(&p)
                .with_context(|| format!("cannot remove the old {}", p.display()))?;
        }
    }
    for stale in ["orbit.gif", "training_curve.svg", "training_curve.png"] {
        let p = a.out.join(stale);
        if p.is_file() {
            std::fs::remove_file(&p)
                .with_context(|| format!("cannot remove the old {}", p.display()))?;
        }
    }
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
    let mut sample_md = String::new();
    let mut sizes_used = Vec::new();
    for (ti, t) in index.triplets.iter().enumerate() {
        let seq = ds
            .sequences
            .iter()
            .find(|s| s.name == t.sequence)
            .context("triplet sequence vanished")?;
        let size = sizes[&seq.name];
        if !sizes_used.contains(&size) {
            sizes_used.push(size);
        }
        let load = |i: usize| -> anyhow::Result<LoadedFrame> {
            Ok(load_frame(&seq.frames[i], Some(size), Fit::Stretch)?)
        };
        let (rf, sf, tf) = (load(t.reference)?, load(t.source)?, load(t.target)?);
        if ti == 0 {
            // Warm-up: the first view of every method pays for allocations and lazy
            // initialisation that a user rendering many views pays once.
            if ctx.run_methods(&rf, &sf, &tf, seq)?.is_empty() {
                bail!(
                    "none of --methods {:?} applies here: learned, soft, hard and avg need a --run with N > 1, mpi a --run with N = 1, oracle synthetic scenes",
                    a.methods
                );
            }
            pb.inc(1);
        }
        let outputs = ctx.run_methods(&rf, &sf, &tf, seq)?;
        let gt = &tf.image;
        let covered = mhi_eval::covered_mask(&rf.camera, &tf.camera, a.far);
        let covered_fraction = mhi_eval::coverage::fraction(&covered);
        let kind = match t.kind {
            TripletKind::Interpolation => "interpolation",
            TripletKind::Extrapolation => "extrapolation",
        };
        let bin = serde_json::to_value(t.bin)?
            .as_str()
            .unwrap_or("all")
            .to_string();
        for o in &outputs {
            let img = clipped(&o.image);
            let pasted = with_uncovered_from(&img, gt, &covered);
            let (lpips, lpips_covered) = match &lpips_net {
                Some(net) => (
                    Some(lpips_of(net, &img, gt, &cpu)?),
                    (covered_fraction > 0.0)
                        .then(|| lpips_of(net, &pasted, gt, &cpu))
                        .transpose()?,
                ),
                None => (None, None),
            };
            measurements.push(Measurement {
                triplet: ti,
                method: o.method.clone(),
                normals: o.normals,
                planes: o.planes,
                sequence: t.sequence.clone(),
                target: t.target,
                bin: bin.clone(),
                kind: kind.into(),
                psnr: mhi_eval::psnr(&img, gt)?,
                ssim: mhi_eval::ssim(&img, gt)?,
                lpips,
                psnr_covered: mhi_eval::psnr_masked(&img, gt, &covered)?,
                ssim_covered: mhi_eval::ssim_masked(&img, gt, &covered)?,
                lpips_covered,
                covered_fraction,
                times: o.times,
            });
            if let Some(e) = &o.exact {
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
            write_layers_and_orbit(a, &models, &rf, &sf, &tf)?;
        }
        pb.inc(1);
    }
    pb.finish_and_clear();

    let boot = Bootstrap::default().with_seed(a.bootstrap_seed);
    let rows = report::aggregate(&measurements, &boot);
    let comparisons: Vec<Comparison> = comparison_pairs(&report::configs(&rows))
        .iter()
        .flat_map(|(x, y)| report::compare(&measurements, x, y, &boot))
        .collect();
    let meta = Meta {
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
        sizes: sizes_used.clone(),
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
        lpips: if lpips_net.is_some() {
            "LPIPS v0.1, AlexNet".into()
        } else {
            format!("not computed: no weights in {}", weights_dir.display())
        },
        covered: format!(
            "target pixels whose ray meets the reference camera's fronto-parallel plane at depth {} inside the reference image; LPIPS covered = LPIPS of the render with uncovered pixels replaced by the ground truth's",
            a.far
        ),
        timing: "ms per view from the two decoded input images to the final image (cost volume or sweep, networks, building the MHI, render, blend), after one warm-up view; file I/O and metrics excluded".into(),
        sweep: sweep_config,
        bootstrap: boot,
        machine: machine(),
        threads: rayon::current_num_threads(),
        date: crate::date(),
    };
    let json = serde_json::to_vec_pretty(&ReportJson {
        meta: &meta,
        rows: &rows,
        comparisons: &comparisons,
        measurements: &measurements,
    })?;
    mhi_data::write_atomic(&a.out.join("report.json"), &json)?;
    let prune_rows = prune_rows(&pruning, &boot);
    mhi_data::write_atomic(
        &a.out.join("pruning.json"),
        &serde_json::to_vec_pretty(&serde_json::json!({
            "budget": a.prune().budget, "rows": prune_rows, "measurements": pruning,
        }))?,
    )?;
    mhi_data::write_atomic(&a.out.join("report.csv"), report::csv(&rows).as_bytes())?;

    // Figures, from the rows.
    let mut points: Vec<TimePoint> = rows
        .iter()
        .filter(|r| r.bin == "all" && r.kind == "all")
        .map(|r| TimePoint {
            label: config_label(&r.method, r.normals, r.planes),
            ms: r.ms_per_view,
            psnr: r.psnr_covered.unwrap_or(r.psnr),
        })
        .collect();
    // The same MHIs rendered exactly: a separate series, beside the pruned (default) renders.
    for p in &prune_rows {
        if let Some(r) = rows.iter().find(|r| {
            r.bin == "all"
                && r.kind == "all"
                && (&r.method, r.normals, r.planes) == (&p.method, p.normals, p.planes)
        }) {
            points.push(TimePoint {
                label: format!("{} exact", config_label(&p.method, p.normals, p.planes)),
                ms: r.ms_per_view - p.ms_pruned + p.ms_exact,
                psnr: p.psnr_exact,
            });
        }
    }
    mhi_eval::plot::error_vs_time(
        &a.out.join("error_vs_time"),
        &points,
        &format!(
            "covered PSNR against time per view ({}, {} triplets)",
            size_label(&sizes_used),
            meta.triplets
        ),
    )?;
    let curves = training_curves(&models)?;
    let has_curves = !curves.is_empty();
    if has_curves {
        mhi_eval::plot::training_curve(
            &a.out.join("training_curve"),
            &curves,
            "validation PSNR during training",
        )?;
    }
    let md = markdown(
        &meta,
        &rows,
        &comparisons,
        has_curves,
        &sample_md,
        a,
        &models,
    );
    let md = md + &prune_markdown(&prune_rows, a);
    mhi_data::write_atomic(&a.out.join("report.md"), md.as_bytes())?;
    print_summary(&rows, &comparisons);
    println!("report: {}", a.out.join("report.md").display());
    Ok(())
}

/// One pruned render against the exact render of the same MHI and view.
#[derive(Serialize)]
struct PruneMeasure {
    method: String,
    normals: usize,
    planes: usize,
    /// Largest |pruned − exact| over pixels and channels (colour units).
    max_abs: f32,
    /// Mean |pruned − exact|.
    mean_abs: f64,
    /// Pixels whose change exceeds the bound the render reported (must be 0).
    over_bound: usize,
    /// Covered PSNR against the ground truth, pruned and exact (None without covered pixels).
    psnr_pruned: Option<f64>,
    psnr_exact: Option<f64>,
    ms_pruned: f64,
    ms_exact: f64,
    layers: usize,
    layers_pruned: usize,
    normals_pruned: usize,
    bound: f32,
}

impl PruneMeasure {
    fn new(
        o: &Output,
        e: &ExactCheck,
        pruned: &Rgb32FImage,
        gt: &Rgb32FImage,
        covered: &[bool],
    ) -> anyhow::Result<Self> {
        let exact = clipped(&e.image);
        let (mut max_abs, mut sum, mut over) = (0.0_f32, 0.0_f64, 0usize);
        for (p, q) in pruned.pixels().zip(exact.pixels()) {
            let d = (0..3)
                .map(|c| (p.0[c] - q.0[c]).abs())
                .fold(0.0_f32, f32::max);
            max_abs = max_abs.max(d);
            sum += (0..3)
                .map(|c| f64::from((p.0[c] - q.0[c]).abs()))
                .sum::<f64>();
            if d > e.stats.bound + 1e-5 {
                over += 1;
            }
        }
        Ok(Self {
            method: o.method.clone(),
            normals: o.normals,
            planes: o.planes,
            max_abs,
            mean_abs: sum / (3 * pruned.width() as usize * pruned.height() as usize).max(1) as f64,
            over_bound: over,
            psnr_pruned: mhi_eval::psnr_masked(pruned, gt, covered)?,
            psnr_exact: mhi_eval::psnr_masked(&exact, gt, covered)?,
            ms_pruned: o.times.render_ms + o.times.blend_ms,
            ms_exact: e.render_ms + o.times.blend_ms,
            layers: e.stats.layers,
            layers_pruned: e.stats.layers_pruned,
            normals_pruned: e.stats.normals_pruned,
            bound: e.stats.bound,
        })
    }
}

/// Pruned against exact, per method and configuration over every triplet.
#[derive(Serialize)]
struct PruneRow {
    method: String,
    normals: usize,
    planes: usize,
    views: usize,
    max_abs: f32,
    mean_abs: f64,
    over_bound: usize,
    bound: f32,
    psnr_pruned: f64,
    psnr_exact: f64,
    /// Mean covered-PSNR change (pruned − exact) with its 95 % interval (None when a PSNR is
    /// infinite: identical images).
    delta_psnr: Option<(f64, [f64; 2])>,
    ms_pruned: f64,
    ms_exact: f64,
    /// Total exact render time over total pruned render time.
    speedup: f64,
    layers: usize,
    layers_pruned: f64,
    normals_pruned: f64,
}

fn prune_rows(ms_: &[PruneMeasure], boot: &Bootstrap) -> Vec<PruneRow> {
    let mut keys: Vec<(String, usize, usize)> = Vec::new();
    for m in ms_ {
        let k = (m.method.clone(), m.normals, m.planes);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    keys.into_iter()
        .map(|(method, normals, planes)| {
            let g: Vec<&PruneMeasure> = ms_
                .iter()
                .filter(|m| {
                    (m.method.as_str(), m.normals, m.planes) == (method.as_str(), normals, planes)
                })
                .collect();
            let k = g.len().max(1) as f64;
            let mean = |f: &dyn Fn(&PruneMeasure) -> f64| g.iter().map(|m| f(m)).sum::<f64>() / k;
            let pairs: Vec<(f64, f64)> = g
                .iter()
                .filter_map(|m| Some((m.psnr_pruned?, m.psnr_exact?)))
                .filter(|(p, e)| p.is_finite() && e.is_finite())
                .collect();
            let deltas: Vec<f64> = pairs.iter().map(|(p, e)| p - e).collect();
            let kp = pairs.len().max(1) as f64;
            let (ms_pruned, ms_exact) = (mean(&|m| m.ms_pruned), mean(&|m| m.ms_exact));
            PruneRow {
                views: g.len(),
                max_abs: g.iter().map(|m| m.max_abs).fold(0.0, f32::max),
                mean_abs: mean(&|m| m.mean_abs),
                over_bound: g.iter().map(|m| m.over_bound).sum(),
                bound: g.iter().map(|m| m.bound).fold(0.0, f32::max),
                psnr_pruned: pairs.iter().map(|p| p.0).sum::<f64>() / kp,
                psnr_exact: pairs.iter().map(|p| p.1).sum::<f64>() / kp,
                delta_psnr: boot.mean_ci(&deltas),
                ms_pruned,
                ms_exact,
                speedup: ms_exact / ms_pruned.max(1e-9),
                layers: g.first().map_or(0, |m| m.layers),
                layers_pruned: mean(&|m| m.layers_pruned as f64),
                normals_pruned: mean(&|m| m.normals_pruned as f64),
                method,
                normals,
                planes,
            }
        })
        .collect()
}

fn prune_markdown(rows: &[PruneRow], a: &EvalArgs) -> String {
    let mut s = String::from(
        "## Leaving out what a view does not need: pruned against exact

",
    );
    if a.exact {
        s += "Not measured: this report was made with `--exact` (every render exact).

";
        return s;
    }
    let _ = writeln!(
        s,
        "Every MHI below was rendered twice per view, exactly and within the error budget of {:.2} 8-bit level(s) per pixel (the default; `--exact` turns it off). |Δ| compares the two renders (not the ground truth); ΔPSNR is the change of covered PSNR against the ground truth (mean, 95 % interval); time is the render (and Soft blend) alone; layers and normals are those left out per view. The report's other tables score the pruned renders.\n",
        a.budget
    );
    s += "| method | views | max \\|Δ\\| | mean \\|Δ\\| | bound | pixels over bound | ΔPSNR dB | exact ms | pruned ms | speed-up | layers left out | normals left out |\n|---|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|\n";
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.5} | {:.6} | {:.5} | {} | {} | {:.1} | {:.1} | {:.2}x | {:.1} of {} | {:.2} of {} |",
            config_label(&r.method, r.normals, r.planes),
            r.views,
            r.max_abs,
            r.mean_abs,
            r.bound,
            r.over_bound,
            r.delta_psnr.map_or("-".into(), |(m, [lo, hi])| format!(
                "{m:+.3} [{lo:+.3}, {hi:+.3}]"
            )),
            r.ms_exact,
            r.ms_pruned,
            r.speedup,
            r.layers_pruned,
            r.layers,
            r.normals_pruned,
            r.normals
        );
    }
    s.push('\n');
    s
}

fn size_label(sizes: &[(u32, u32)]) -> String {
    sizes
        .iter()
        .map(|(w, h)| format!("{w}x{h}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The comparisons the report draws, among the configurations present: learned against Soft on
/// its own stage 1, against the sweep and against the MPI; MHI against MPI (N > 1 against N = 1
/// at the same D) for the sweep and the oracle; the largest sweep against the nearest view.
fn comparison_pairs(cfgs: &[Config]) -> Vec<(Config, Config)> {
    let has = |c: &Config| cfgs.contains(c);
    let mut out = Vec::new();
    let mut push = |x: Config, y: Config| {
        if has(&x) && has(&y) && !out.contains(&(x.clone(), y.clone())) {
            out.push((x, y));
        }
    };
    let of = |m: &str| -> Vec<Config> { cfgs.iter().filter(|c| c.0 == m).cloned().collect() };
    for l in of("learned") {
        push(l.clone(), ("soft".into(), l.1, l.2));
        let sweeps = of("sweep");
        let same = sweeps.iter().find(|s| s.1 == l.1 && s.2 == l.2);
        let any = sweeps.iter().filter(|s| s.1 == l.1).max_by_key(|s| s.2);
        if let Some(s) = same.or(any) {
            push(l.clone(), s.clone());
        }
        for m in of("mpi") {
            push(l.clone(), m);
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
fn with_uncovered_from(img: &Rgb32FImage, truth: &Rgb32FImage, covered: &[bool]) -> Rgb32FImage {
    let mut o = img.clone();
    for ((p, t), &c) in o.pixels_mut().zip(truth.pixels()).zip(covered) {
        if !c {
            *p = *t;
        }
    }
    o
}

/// A blended view of a trained run: the shared time split plus this blend's time since `t0`.
fn blended(
    method: &str,
    normals: usize,
    planes: usize,
    image: Rgb32FImage,
    base: Times,
    t0: Instant,
) -> Output {
    Output {
        method: method.into(),
        normals,
        planes,
        image,
        times: Times {
            blend_ms: ms(t0),
            ..base
        },
        exact: None,
    }
}

/// What every method of one evaluation shares.
struct Ctx<'a> {
    a: &'a EvalArgs,
    models: &'a [Loaded],
    sweep_grid: &'a [(usize, usize)],
    oracle_grid: &'a [(usize, usize)],
    sweep_config: SweepConfig,
}

impl Ctx<'_> {
    fn wants(&self, m: Method) -> bool {
        self.a.methods.contains(&m)
    }

    /// Every method's view of `tf` from the pair (`rf`, `sf`), timed from the decoded images.
    fn run_methods(
        &self,
        rf: &LoadedFrame,
        sf: &LoadedFrame,
        tf: &LoadedFrame,
        seq: &mhi_data::Sequence,
    ) -> anyhow::Result<Vec<Output>> {
        let a = self.a;
        let mut out = Vec::new();
        if self.wants(Method::Nearest) {
            let t0 = Instant::now();
            let c = tf.camera.center_in_world();
            let dr = (rf.camera.center_in_world() - c).length();
            let ds_ = (sf.camera.center_in_world() - c).length();
            let image = if dr <= ds_ {
                rf.image.clone()
            } else {
                sf.image.clone()
            };
            out.push(Output {
                method: "nearest".into(),
                normals: 0,
                planes: 0,
                image,
                times: Times {
                    blend_ms: ms(t0),
                    ..Times::default()
                },
                exact: None,
            });
        }
        for m in self.models {
            let model = &m.model;
            let n = model.normals().len();
            let is_mpi = n == 1;
            if is_mpi && !self.wants(Method::Mpi) {
                continue;
            }
            let heuristics = [
                (Method::Soft, "soft", BlendHeuristic::Soft),
                (Method::Hard, "hard", BlendHeuristic::Hard),
                (Method::Avg, "avg", BlendHeuristic::Avg),
            ];
            if !is_mpi
                && !self.wants(Method::Learned)
                && !heuristics.iter().any(|h| self.wants(h.0))
            {
                continue;
            }
            let d = model.depths().len();
            let t0 = Instant::now();
            let volume = model.stage1_input(rf, sf)?;
            let volume_ms = ms(t0);
            let t1 = Instant::now();
            let alphas = model.alphas(volume)?;
            let network_ms = ms(t1);
            let t2 = Instant::now();
            let mhi = model.mhi(rf, alphas)?;
            let r = render_mni(&mhi, &tf.camera, a.prune())?;
            let render_ms = ms(t2);
            let base = Times {
                volume_ms,
                network_ms,
                render_ms,
                blend_ms: 0.0,
            };
            if is_mpi {
                out.push(Output {
                    method: "mpi".into(),
                    normals: 1,
                    planes: d,
                    image: r.multi_normal[0].clone(),
                    times: base,
                    exact: None,
                });
                continue;
            }
            let mni = &r.multi_normal;
            if self.wants(Method::Learned) {
                let t3 = Instant::now();
                let soft = heuristic_weights_for(
                    model.normals(),
                    &rf.camera,
                    &tf.camera,
                    BlendHeuristic::Soft,
                );
                let w = model.blend_weights(mni, &soft)?;
                out.push(blended("learned", n, d, combine(mni, &w), base, t3));
            }
            for (which, name, h) in heuristics {
                if !self.wants(which) {
                    continue;
                }
                let t3 = Instant::now();
                let w = heuristic_weights_for(model.normals(), &rf.camera, &tf.camera, h);
                let mut o = blended(name, n, d, combine(mni, &w), base, t3);
                if which == Method::Soft && a.prune().budget > 0.0 {
                    // The same MHI's multi-normal images rendered exactly, Soft-blended.
                    let t4 = Instant::now();
                    let e = render_mni(&mhi, &tf.camera, Prune::NONE)?;
                    let render_ms = ms(t4);
                    o.exact = Some(ExactCheck {
                        image: combine(&e.multi_normal, &w),
                        render_ms,
                        stats: r.stats,
                    });
                }
                out.push(o);
            }
        }
        for &(n, d) in self.sweep_grid {
            let normals = NormalSet::paper_subset(n)?;
            let depths = depths_linear_in_disparity(a.near, a.far, d)?;
            let t0 = Instant::now();
            let mhi = sweep_mhi(
                &normals,
                &depths,
                &rf.camera,
                &rf.image,
                &sf.camera,
                &sf.image,
                &self.sweep_config,
            )?;
            let volume_ms = ms(t0);
            let (image, render_ms, exact) = render_soft(&mhi, tf, a.prune())?;
            out.push(Output {
                method: "sweep".into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    volume_ms,
                    network_ms: 0.0,
                    render_ms,
                    blend_ms: 0.0,
                },
                exact,
            });
        }
        if !self.oracle_grid.is_empty() {
            let scene = load_scene(&seq.dir().join("scene.json"))?;
            let truth = crate::experiments::truth_of(&scene, &rf.camera);
            for &(n, d) in self.oracle_grid {
                let normals = NormalSet::paper_subset(n)?;
                let depths = depths_linear_in_disparity(a.near, a.far, d)?;
                let alpha = oracle_alpha(&normals, &depths, &rf.camera, &truth);
                let mhi = Mhi::new(
                    normals,
                    depths,
                    rf.camera,
                    LayerColor::Shared(rf.image.clone()),
                    alpha,
                )?;
                let (image, render_ms, exact) = render_soft(&mhi, tf, a.prune())?;
                out.push(Output {
                    method: "oracle".into(),
                    normals: n,
                    planes: d,
                    image,
                    times: Times {
                        render_ms,
                        ..Times::default()
                    },
                    exact,
                });
            }
        }
        Ok(out)
    }
}

/// Render with Soft blending within `prune` (timed) and, when something may be left out, also
/// exactly (timed) for the pruned-vs-exact table. Returns the image to score (the pruned one),
/// its render time and the exact check.
fn render_soft(
    mhi: &Mhi,
    tf: &LoadedFrame,
    prune: Prune,
) -> anyhow::Result<(Rgb32FImage, f64, Option<ExactCheck>)> {
    let go = |p: Prune| -> anyhow::Result<(mhi_render::Rendered, f64)> {
        let t0 = Instant::now();
        let r = render(
            mhi,
            &tf.camera,
            &RenderOptions {
                blend: Blend::Heuristic(BlendHeuristic::Soft),
                prune: p,
                keep_multi_normal: false,
            },
        )?;
        Ok((r, ms(t0)))
    };
    let (exact, exact_ms) = go(Prune::NONE)?;
    if prune.budget <= 0.0 {
        return Ok((exact.image, exact_ms, None));
    }
    let (pruned, pruned_ms) = go(prune)?;
    Ok((
        pruned.image,
        pruned_ms,
        Some(ExactCheck {
            image: exact.image,
            render_ms: exact_ms,
            stats: pruned.stats,
        }),
    ))
}

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

fn file_label(o: &Output) -> String {
    if o.normals == 0 {
        o.method.clone()
    } else {
        format!("{}_n{}_d{}", o.method, o.normals, o.planes)
    }
}

/// One sample: images and error maps in `samples/NNN/`, and the markdown table showing them.
fn write_samples(
    out: &Path,
    k: usize,
    t: &mhi_data::Triplet,
    (rf, sf): (&LoadedFrame, &LoadedFrame),
    gt: &Rgb32FImage,
    covered: &[bool],
    outputs: &[Output],
) -> anyhow::Result<String> {
    let dir = out.join("samples").join(format!("{k:03}"));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let f = factor_for(gt.width(), 192);
    let save = |name: &str, img: &Rgb32FImage| -> anyhow::Result<String> {
        let file = format!("{name}.png");
        mhi_data::write_png(
            &dir.join(&file),
            &enlarge(&mhi_data::to_u8(&clipped(img)), f),
        )?;
        Ok(format!("samples/{k:03}/{file}"))
    };
    let mut md = format!(
        "#### Sample {k}: {} frames {} + {} → {} ({}, {:.1}° max rotation)\n\n",
        t.sequence,
        t.reference,
        t.source,
        t.target,
        match t.kind {
            TripletKind::Interpolation => "interpolation",
            TripletKind::Extrapolation => "extrapolation",
        },
        t.max_rotation_deg
    );
    let mut head = String::from("| reference | source | ground truth |");
    let mut row = format!(
        "| <img src=\"{}\" width=\"160\"> | <img src=\"{}\" width=\"160\"> | <img src=\"{}\" width=\"160\"> |",
        save("reference", &rf.image)?,
        save("source", &sf.image)?,
        save("ground_truth", gt)?
    );
    let mut dimmed = gt.clone();
    for (p, &c) in dimmed.pixels_mut().zip(covered) {
        if !c {
            for v in &mut p.0 {
                *v *= 0.25;
            }
        }
    }
    let mut err_row = format!(
        "| | | <img src=\"{}\" width=\"160\"><br>*covered region (uncovered dimmed); below: error ×4* |",
        save("covered", &dimmed)?
    );
    for o in outputs {
        let name = file_label(o);
        let img = clipped(&o.image);
        let p = mhi_eval::psnr_masked(&img, gt, covered)?
            .map_or("no covered pixel".to_string(), |p| {
                format!("{p:.1} dB covered")
            });
        let _ = write!(
            head,
            " {} ({p}) |",
            config_label(&o.method, o.normals, o.planes)
        );
        let _ = write!(row, " <img src=\"{}\" width=\"160\"> |", save(&name, &img)?);
        let errp = save(
            &format!("{name}_error"),
            &crate::experiments::error_map(&img, gt),
        )?;
        let _ = write!(err_row, " <img src=\"{errp}\" width=\"160\"> |");
    }
    let sep = format!("|{}", "---|".repeat(3 + outputs.len()));
    let _ = writeln!(md, "{head}\n{sep}\n{row}\n{err_row}\n");
    Ok(md)
}

/// The MHI layers of the first triplet's scene (first run with N > 1, else the sweep), the
/// multi-normal images and blend weights in the target, and an orbit GIF.
fn write_layers_and_orbit(
    a: &EvalArgs,
    models: &[Loaded],
    rf: &LoadedFrame,
    sf: &LoadedFrame,
    tf: &LoadedFrame,
) -> anyhow::Result<()> {
    let dir = a.out.join("layers");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let model = models
        .iter()
        .find(|m| m.model.normals().len() > 1)
        .or(models.first());
    let (mhi, learned) = match model {
        Some(m) => {
            let alphas = m.model.alphas(m.model.stage1_input(rf, sf)?)?;
            (m.model.mhi(rf, alphas)?, Some(&m.model))
        }
        None => (
            sweep_mhi(
                &NormalSet::paper(),
                &depths_linear_in_disparity(a.near, a.far, 8)?,
                &rf.camera,
                &rf.image,
                &sf.camera,
                &sf.image,
                &SweepConfig::default(),
            )?,
            None,
        ),
    };
    let (w, h) = (rf.image.width(), rf.image.height());
    let px = (w * h) as usize;
    let f = factor_for(w, 96);
    for i in 0..mhi.n() {
        let tiles: Vec<_> = (0..mhi.d())
            .map(|j| {
                let k = i * mhi.d() + j;
                enlarge(
                    &layer_picture(&rf.image, &mhi.alpha()[k * px..(k + 1) * px]),
                    f,
                )
            })
            .collect();
        mhi_data::write_png(&dir.join(format!("normal_{i}.png")), &strip(&tiles))?;
    }
    let r = render_mni(&mhi, &tf.camera, Prune::NONE)?;
    let soft = heuristic_weights_for(mhi.normals(), &rf.camera, &tf.camera, BlendHeuristic::Soft);
    let weights = match learned {
        Some(m) if mhi.n() > 1 => m.blend_weights(&r.multi_normal, &soft)?,
        _ => soft,
    };
    let (tw, th) = (tf.image.width(), tf.image.height());
    let tpx = (tw * th) as usize;
    let mni: Vec<_> = r
        .multi_normal
        .iter()
        .map(|m| enlarge(&mhi_data::to_u8(&clipped(m)), f))
        .collect();
    let wts: Vec<_> = (0..mhi.n())
        .map(|i| {
            enlarge(
                &crate::views::grey(&weights[i * tpx..(i + 1) * tpx], tw, th),
                f,
            )
        })
        .collect();
    mhi_data::write_png(&dir.join("multi_normal.png"), &strip(&mni))?;
    mhi_data::write_png(&dir.join("weights.png"), &strip(&wts))?;

    if a.orbit_frames > 0 {
        let baseline = (rf.camera.center_in_world() - sf.camera.center_in_world()).length();
        let (cams, _) = crate::views::orbit(
            &rf.camera,
            0.5 * baseline,
            a.orbit_frames,
            crate::views::median_depth(&mhi),
        )?;
        let mut frames = Vec::new();
        for c in &cams {
            let (img, _) = crate::views::view(&mhi, learned, c, a.prune())?;
            frames.push(enlarge(
                &mhi_data::to_u8(&clipped(&img)),
                factor_for(img.width(), 256),
            ));
        }
        crate::views::write_gif(&a.out.join("orbit.gif"), &frames, 80)?;
    }
    Ok(())
}

fn training_curves(models: &[Loaded]) -> anyhow::Result<Vec<Curve>> {
    let mut curves = Vec::new();
    for m in models {
        let path = m.run.join("val.csv");
        let Ok(text) = std::fs::read_to_string(&path) else {
            continue;
        };
        let n = m.model.normals().len();
        let mut learned = Vec::new();
        let mut soft = Vec::new();
        for (i, line) in text.lines().enumerate().skip(1) {
            let f: Vec<&str> = line.split(',').collect();
            let parse = |k: usize| -> anyhow::Result<f64> {
                f.get(k)
                    .and_then(|s| s.parse::<f64>().ok())
                    .filter(|v| v.is_finite())
                    .with_context(|| {
                        format!(
                            "{}:{}: column {} is not a number",
                            path.display(),
                            i + 1,
                            k + 1
                        )
                    })
            };
            let t = parse(1)?;
            learned.push((t, parse(2)?));
            soft.push((t, parse(3)?));
        }
        let name = m
            .run
            .file_name()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
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
    let _ = writeln!(
        s,
        "Dataset `{}` (split `{}`, {} sequences), {} triplets (rotation bins ≤2° / 2-4° / 4-8° / >8°: {} / {} / {} / {}), evaluated at {}. {}. Sweep: window radius {}, temperature {}. Intervals: 95 % percentile bootstrap over triplets ({} resamples, seed {}). Machine: {}, {} threads, {}.\n",
        meta.dataset,
        meta.split,
        meta.sequences.len(),
        meta.triplets,
        meta.bin_counts[0],
        meta.bin_counts[1],
        meta.bin_counts[2],
        meta.bin_counts[3],
        size_label(&meta.sizes),
        meta.lpips,
        meta.sweep.window_radius,
        meta.sweep.temperature,
        meta.bootstrap.resamples,
        meta.bootstrap.seed,
        meta.machine,
        meta.threads,
        meta.date
    );
    let _ = writeln!(
        s,
        "Methods: `learned` = stage 1 + learned blending network; `soft`/`hard`/`avg` = the same stage 1 with the paper's heuristic blends; `mpi` = a run trained with N = 1 (the MPI baseline, same code); `sweep` = training-free plane-sweep MHI (photo-consistency, no network); `oracle` = MHI built from the scene's exact geometry with Soft blending (synthetic only; its time is render + blend only); `nearest` = the input view nearest the target, shown as it is. Scores are computed on images clipped to [0, 1]. Times are wall-clock on this machine, one view at a time, {}.\n",
        meta.timing
    );
    for (m, r) in models.iter().zip(&meta.runs) {
        let c = m.model.config();
        let _ = writeln!(
            s,
            "- run `{}`: N = {}, D = {}, trained {} of {} steps at {}x{}, loss: {}{}",
            m.run.display(),
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
    s.push('\n');
    s.push_str(&report::markdown_tables(rows, comparisons));
    let _ = writeln!(
        s,
        "## Error against time\n\n![error vs time](error_vs_time.svg)\n\nCovered PSNR of each method and configuration (all triplets) against its time per view; the red line is the Pareto front. PNG: [error_vs_time.png](error_vs_time.png).\n"
    );
    if has_curves {
        let _ = writeln!(
            s,
            "## Training\n\n![training curve](training_curve.svg)\n\nValidation PSNR (held-out triplets of the training scenes, logged at every checkpoint) against wall-clock training time.\n"
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
    if a.orbit_frames > 0 {
        let _ = writeln!(
            s,
            "## Orbit\n\nA circle of cameras around the reference view (radius half the input baseline):\n\n![orbit](orbit.gif)\n"
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
        c.bin == "all" && c.kind == "all" && c.metric == mhi_eval::report::Metric::PsnrCovered
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

fn machine() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
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
        assert!(p.contains(&(c("sweep", 5, 32), c("sweep", 1, 32))));
        assert!(p.contains(&(c("sweep", 5, 32), c("nearest", 0, 0))));
        assert!(p.iter().all(|(a, b)| cfgs.contains(a) && cfgs.contains(b)));
    }
}
