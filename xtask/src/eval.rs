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
use mhi_eval::plot::{Curve, TimePoint};
use mhi_eval::report::{self, Measurement, Row, Times, config_label};
use mhi_geom::{BlendHeuristic, NormalSet, depths_linear_in_disparity};
use mhi_net::Model;
use mhi_net::backbone::{Backbone, Net};
use mhi_render::heuristic_weights_for;
use mhi_render::{
    Blend, LayerColor, Mhi, Prune, RenderOptions, SweepConfig, oracle_alpha, render, sweep_mhi,
};
use serde::Serialize;

use crate::views::{clipped, combine, enlarge, factor_for, layer_picture, strip};

/// Options of `cargo xtask eval`.
#[derive(Args, Debug, Clone)]
pub struct EvalArgs {
    /// Dataset root in RealEstate10K layout (synthetic scenes are generated there if missing
    /// and the path is the default).
    #[arg(long, default_value = "data/synth")]
    pub data: PathBuf,
    /// Split to evaluate.
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Triplet index (JSON from `cargo xtask triplets --save`); default: sample --per-sequence
    /// triplets per sequence with --seed.
    #[arg(long)]
    pub index: Option<PathBuf>,
    /// Triplets sampled per sequence when no --index is given.
    #[arg(long, default_value_t = 2)]
    pub per_sequence: usize,
    /// Seed of the sampled triplets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// A trained run (repeat for several): N > 1 gives `learned`, `soft`, `hard` and `avg`;
    /// N = 1 gives `mpi`.
    #[arg(long = "run")]
    pub runs: Vec<PathBuf>,
    /// Methods to score (comma-separated); those that do not apply are skipped.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "learned,soft,hard,avg,mpi,sweep,oracle,nearest"
    )]
    pub methods: Vec<String>,
    /// (N, D) configurations of the training-free sweep, as NxD (N in 1, 2, 3, 5).
    #[arg(long, value_delimiter = ',', default_value = "1x8,5x8,1x32,5x32")]
    pub sweep_grid: Vec<String>,
    /// (N, D) configurations of the oracle (synthetic scenes only).
    #[arg(long, value_delimiter = ',', default_value = "1x8,5x8,5x32")]
    pub oracle_grid: Vec<String>,
    /// Evaluation size WIDTHxHEIGHT (default: the first run's training size, else 64x64).
    #[arg(long, value_parser = crate::data::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Nearest plane depth of the sweep and oracle.
    #[arg(long, default_value_t = 1.0)]
    pub near: f64,
    /// Farthest plane depth of the sweep and oracle.
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
}

pub fn parse_nd(s: &str) -> anyhow::Result<(usize, usize)> {
    let (n, d) = s
        .split_once(['x', 'X'])
        .with_context(|| format!("configuration {s:?} must look like 5x8 (normals x planes)"))?;
    let n: usize = n
        .trim()
        .parse()
        .with_context(|| format!("normals in {s:?}"))?;
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
}

#[derive(Serialize)]
struct Meta {
    dataset: String,
    split: String,
    triplets: usize,
    bin_counts: [usize; 4],
    size: (u32, u32),
    runs: Vec<serde_json::Value>,
    lpips: String,
    machine: String,
    threads: usize,
    date: String,
}

#[derive(Serialize)]
struct ReportJson<'a> {
    meta: &'a Meta,
    rows: &'a [Row],
    measurements: &'a [Measurement],
}

/// `cargo xtask eval`.
pub fn eval(a: &EvalArgs) -> anyhow::Result<()> {
    if a.data == Path::new("data/synth") {
        crate::experiments::ensure_synthetic(&a.data)?;
    }
    if a.out.join("report.json").exists() && !a.overwrite {
        bail!(
            "{} already holds a report; pass --overwrite to replace it or choose another --out",
            a.out.display()
        );
    }
    let ds = Dataset::open(&a.data, &a.split, 3)?;
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
        bail!(
            "{}: no triplet to evaluate (each sequence needs at least 3 frames)",
            ds.dir.display()
        );
    }
    let cpu = Device::flex();
    let mut models = Vec::new();
    for run in &a.runs {
        let model = Model::load(run, cpu.clone())
            .with_context(|| format!("loading the trained run {}", run.display()))?;
        models.push(Loaded {
            run: run.clone(),
            model,
        });
    }
    let size = a.size.unwrap_or_else(|| {
        models.first().map_or((64, 64), |m| {
            (m.model.config().width, m.model.config().height)
        })
    });
    for m in &models {
        m.model
            .check_size(size.0, size.1)
            .with_context(|| format!("--size for the run {}", m.run.display()))?;
    }
    let wants = |m: &str| a.methods.iter().any(|x| x == m);
    let sweep_grid: Vec<(usize, usize)> = if wants("sweep") {
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
        .all(|s| ds.dir.join(&s.name).join("scene.json").is_file());
    let oracle_grid: Vec<(usize, usize)> = if wants("oracle") && synthetic {
        a.oracle_grid
            .iter()
            .map(|s| parse_nd(s))
            .collect::<anyhow::Result<_>>()?
    } else {
        Vec::new()
    };
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
    let pb = crate::progress::bar(index.triplets.len() as u64, "eval");
    let mut measurements: Vec<Measurement> = Vec::new();
    let mut sample_md = String::new();
    for (ti, t) in index.triplets.iter().enumerate() {
        let seq = ds
            .sequences
            .iter()
            .find(|s| s.name == t.sequence)
            .context("triplet sequence vanished")?;
        let load = |i: usize| -> anyhow::Result<LoadedFrame> {
            Ok(load_frame(&seq.frames[i], Some(size), Fit::Stretch)?)
        };
        let (rf, sf, tf) = (load(t.reference)?, load(t.source)?, load(t.target)?);
        let outputs = run_methods(
            a,
            &models,
            &rf,
            &sf,
            &tf,
            &sweep_grid,
            &oracle_grid,
            &ds,
            seq,
        )?;
        let gt = &tf.image;
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
            let lpips = match &lpips_net {
                Some(net) => Some(lpips_of(net, &img, gt, &cpu)?),
                None => None,
            };
            measurements.push(Measurement {
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
                times: o.times,
            });
        }
        if ti < a.samples {
            sample_md.push_str(&write_samples(&a.out, ti, t, &rf, &sf, gt, &outputs)?);
        }
        if ti == 0 {
            write_layers_and_orbit(a, &models, &rf, &sf, &tf)?;
        }
        pb.inc(1);
    }
    pb.finish_and_clear();

    let rows = report::aggregate(&measurements);
    let meta = Meta {
        dataset: ds.dir.display().to_string(),
        split: a.split.clone(),
        triplets: index.triplets.len(),
        bin_counts: index.bin_counts(),
        size,
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
        machine: machine(),
        threads: rayon::current_num_threads(),
        date: crate::date(),
    };
    let json = serde_json::to_vec_pretty(&ReportJson {
        meta: &meta,
        rows: &rows,
        measurements: &measurements,
    })?;
    mhi_data::write_atomic(&a.out.join("report.json"), &json)?;
    mhi_data::write_atomic(&a.out.join("report.csv"), report::csv(&rows).as_bytes())?;

    // Figures, from the rows.
    let points: Vec<TimePoint> = rows
        .iter()
        .filter(|r| r.bin == "all" && r.kind == "all")
        .map(|r| TimePoint {
            label: config_label(&r.method, r.normals, r.planes),
            ms: r.ms_per_view,
            psnr: r.psnr,
        })
        .collect();
    mhi_eval::plot::error_vs_time(
        &a.out.join("error_vs_time"),
        &points,
        &format!(
            "PSNR against time per view ({}x{}, {} triplets)",
            size.0, size.1, meta.triplets
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
    let md = markdown(&meta, &rows, has_curves, &sample_md, a, &models);
    mhi_data::write_atomic(&a.out.join("report.md"), md.as_bytes())?;
    print_summary(&rows);
    println!("report: {}", a.out.join("report.md").display());
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn run_methods(
    a: &EvalArgs,
    models: &[Loaded],
    rf: &LoadedFrame,
    sf: &LoadedFrame,
    tf: &LoadedFrame,
    sweep_grid: &[(usize, usize)],
    oracle_grid: &[(usize, usize)],
    ds: &Dataset,
    seq: &mhi_data::Sequence,
) -> anyhow::Result<Vec<Output>> {
    let wants = |m: &str| a.methods.iter().any(|x| x == m);
    let mut out = Vec::new();
    if wants("nearest") {
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
        });
    }
    for m in models {
        let model = &m.model;
        let n = model.normals().len();
        let is_mpi = n == 1;
        if is_mpi && !wants("mpi") {
            continue;
        }
        if !is_mpi && !["learned", "soft", "hard", "avg"].iter().any(|x| wants(x)) {
            continue;
        }
        let d = model.depths().len();
        let t0 = Instant::now();
        let volume = model.cost_volume(rf, sf)?;
        let volume_ms = ms(t0);
        let t1 = Instant::now();
        let alphas = model.alphas(volume)?;
        let network_ms = ms(t1);
        let mhi = model.mhi(rf, alphas)?;
        let t2 = Instant::now();
        let r = render_mni(&mhi, &tf.camera)?;
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
            });
            continue;
        }
        let mni = &r.multi_normal;
        if wants("learned") {
            let t3 = Instant::now();
            let soft = heuristic_weights_for(
                model.normals(),
                &rf.camera,
                &tf.camera,
                BlendHeuristic::Soft,
            );
            let w = model.blend_weights(mni, &soft)?;
            let image = combine(mni, &w);
            out.push(Output {
                method: "learned".into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    blend_ms: ms(t3),
                    ..base
                },
            });
        }
        for (name, h) in [
            ("soft", BlendHeuristic::Soft),
            ("hard", BlendHeuristic::Hard),
            ("avg", BlendHeuristic::Avg),
        ] {
            if !wants(name) {
                continue;
            }
            let t3 = Instant::now();
            let w = heuristic_weights_for(model.normals(), &rf.camera, &tf.camera, h);
            let image = combine(mni, &w);
            out.push(Output {
                method: name.into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    blend_ms: ms(t3),
                    ..base
                },
            });
        }
    }
    for &(n, d) in sweep_grid {
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
            &SweepConfig::default(),
        )?;
        let volume_ms = ms(t0);
        let (image, render_ms, blend_ms) = render_soft(&mhi, tf)?;
        out.push(Output {
            method: "sweep".into(),
            normals: n,
            planes: d,
            image,
            times: Times {
                volume_ms,
                network_ms: 0.0,
                render_ms,
                blend_ms,
            },
        });
    }
    if !oracle_grid.is_empty() {
        let scene = load_scene(&ds.dir.join(&seq.name).join("scene.json"))?;
        let truth = crate::experiments::truth_of(&scene, &rf.camera);
        for &(n, d) in oracle_grid {
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
            let (image, render_ms, blend_ms) = render_soft(&mhi, tf)?;
            out.push(Output {
                method: "oracle".into(),
                normals: n,
                planes: d,
                image,
                times: Times {
                    render_ms,
                    blend_ms,
                    ..Times::default()
                },
            });
        }
    }
    Ok(out)
}

/// The N multi-normal images of a view, exactly (no pruning).
pub fn render_mni(mhi: &Mhi, camera: &mhi_geom::Camera) -> anyhow::Result<mhi_render::Rendered> {
    Ok(render(
        mhi,
        camera,
        &RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Avg),
            prune: Prune::NONE,
            keep_multi_normal: true,
        },
    )?)
}

/// Render the multi-normal images, then blend them with Soft (timed apart).
fn render_soft(mhi: &Mhi, tf: &LoadedFrame) -> anyhow::Result<(Rgb32FImage, f64, f64)> {
    let t0 = Instant::now();
    let r = render_mni(mhi, &tf.camera)?;
    let render_ms = ms(t0);
    let t1 = Instant::now();
    let w = heuristic_weights_for(
        mhi.normals(),
        mhi.reference(),
        &tf.camera,
        BlendHeuristic::Soft,
    );
    let image = combine(&r.multi_normal, &w);
    Ok((image, render_ms, ms(t1)))
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
    rf: &LoadedFrame,
    sf: &LoadedFrame,
    gt: &Rgb32FImage,
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
    let mut err_row = String::from("| | | *error ×4* |");
    for o in outputs {
        let name = file_label(o);
        let img = clipped(&o.image);
        let p = mhi_eval::psnr(&img, gt)?;
        let _ = write!(
            head,
            " {} ({p:.1} dB) |",
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
            let alphas = m.model.alphas(m.model.cost_volume(rf, sf)?)?;
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
    let r = render_mni(&mhi, &tf.camera)?;
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
        let cams = crate::views::orbit(&rf.camera, 0.5 * baseline, a.orbit_frames)?;
        let mut frames = Vec::new();
        for c in &cams {
            let r = render_mni(&mhi, c)?;
            let soft = heuristic_weights_for(mhi.normals(), &rf.camera, c, BlendHeuristic::Soft);
            let wts = match learned {
                Some(m) if mhi.n() > 1 => m.blend_weights(&r.multi_normal, &soft)?,
                _ => soft,
            };
            let img = combine(&r.multi_normal, &wts);
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
    has_curves: bool,
    samples: &str,
    a: &EvalArgs,
    models: &[Loaded],
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# MHI evaluation report\n");
    let _ = writeln!(
        s,
        "Dataset `{}` (split `{}`), {} triplets (rotation bins ≤2° / 2-4° / 4-8° / >8°: {} / {} / {} / {}), evaluated at {}x{}. {}. Machine: {}, {} threads, {}.\n",
        meta.dataset,
        meta.split,
        meta.triplets,
        meta.bin_counts[0],
        meta.bin_counts[1],
        meta.bin_counts[2],
        meta.bin_counts[3],
        meta.size.0,
        meta.size.1,
        meta.lpips,
        meta.machine,
        meta.threads,
        meta.date
    );
    let _ = writeln!(
        s,
        "Methods: `learned` = stage 1 + learned blending network; `soft`/`hard`/`avg` = the same stage 1 with the paper's heuristic blends; `mpi` = a run trained with N = 1 (the MPI baseline, same code); `sweep` = training-free plane-sweep MHI (photo-consistency, no network); `oracle` = MHI built from the scene's exact geometry with Soft blending (synthetic only; its time is render + blend only); `nearest` = the input view nearest the target, shown as it is. Scores are computed on images clipped to [0, 1]; times are wall-clock on this machine, one view at a time (cost volume / network / render of the N multi-normal images / blend).\n"
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
        let _ = r;
    }
    s.push('\n');
    s.push_str(&report::markdown_tables(rows));
    let _ = writeln!(
        s,
        "## Error against time\n\n![error vs time](error_vs_time.svg)\n\nOne point per method and configuration (all triplets); the red line is the Pareto front. PNG: [error_vs_time.png](error_vs_time.png).\n"
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

fn print_summary(rows: &[Row]) {
    println!(
        "{:<24} {:>6} {:>8} {:>7} {:>7} {:>10}",
        "method", "views", "PSNR", "SSIM", "LPIPS", "ms/view"
    );
    for r in rows.iter().filter(|r| r.bin == "all" && r.kind == "all") {
        println!(
            "{:<24} {:>6} {:>8.2} {:>7.3} {:>7} {:>10.1}",
            config_label(&r.method, r.normals, r.planes),
            r.count,
            r.psnr,
            r.ssim,
            r.lpips.map_or("-".into(), |l| format!("{l:.3}")),
            r.ms_per_view
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
