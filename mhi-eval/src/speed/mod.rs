//! Speed measured against a peer in the same run (`cargo xtask bench` is [`bench()`] with its
//! options parsed): one novel view of an N × D MHI against the PyTorch peer renderer with the
//! same thread count, and the memory-bandwidth floor; the pruned render on a real scene; one
//! training step of the default model against its PyTorch twin ([`step`]); every op of it
//! ([`ops`]); how a view's time grows with size, planes, normals and threads ([`scaling`]).

pub mod ops;
pub mod scaling;
pub mod step;

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{
    BlendHeuristic, Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity,
};
use mhi_render::{Blend, LayerColor, Mhi, Prune, RenderOptions, render};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// Options of `cargo xtask bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Path of the PyTorch peer renderer (e.g. ../shared/peer/torch_render.py); without it only
    /// this renderer is timed.
    #[arg(long)]
    pub peer: Option<PathBuf>,
    /// Python interpreter for the peer.
    #[arg(long, default_value = "python3")]
    pub python: String,
    /// Threads for both renderers.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// The MHI's grid.
    #[command(flatten)]
    pub grid: crate::run::options::PlaneArgs,
    /// Image side in pixels (square).
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Timed runs (the median is reported).
    #[arg(long, default_value_t = 10)]
    pub runs: usize,
    /// Instead of the renderer, split one training step of the default model (cost volume,
    /// stage 1, warp, loss; forward and backward each) on a synthetic sample.
    #[arg(long)]
    pub train_step: bool,
    /// Instead of one view, measure how the time of a view grows with image size (64 → 1024),
    /// planes (8 → 128), normals (1 → 9) and threads (1, 2) for the renderer, the sweep and the
    /// learned model's inference; writes scaling.csv and log-log figures into --scaling-out
    /// and prints the fitted exponents.
    #[arg(long)]
    pub scaling: bool,
    /// Output directory of --scaling.
    #[arg(long, default_value = "out/scaling")]
    pub scaling_out: PathBuf,
    /// Instead of the renderer, time every kind of op of the default model's training step on
    /// its real shapes, forward and forward + backward; with --peer-ops, beside PyTorch.
    #[arg(long)]
    pub ops: bool,
    /// The PyTorch twin of --ops (xtask/scripts/ops_torch.py).
    #[arg(long)]
    pub peer_ops: Option<PathBuf>,
    /// Instead of the renderer, run the default model's forward pass on flex and on this
    /// backend (`wgpu`, needs `--features wgpu`) with the same weights and compare.
    #[arg(long, value_enum)]
    pub compare_backend: Option<crate::run::options::Backend>,
    /// Dataset for --train-step and --compare-backend (synthetic; generated if missing), and
    /// the scene of the pruned render's timing: the sweep MHI of its first test triplet (a real
    /// root such as ../shared/data/real/re10k-3 gives a real scene).
    #[arg(long, default_value = "data/synth")]
    pub data: PathBuf,
    /// Also time the pruned render on this trained run's MHI of the same triplet, as `eval` and
    /// `render` render it: the N multi-normal images, each within the budget, before the
    /// blending network (e.g. models/mhi-n5d16). With --train-step: time whole training steps of
    /// this run's configuration (its config.json) instead of the default model's parts, against
    /// the run twin `xtask/scripts/train_step_torch.py` as --peer.
    #[arg(long)]
    pub run: Option<PathBuf>,
    /// Weights cache for --train-step's VGG loss (default: $MHI_CACHE, else ~/.cache/mhi).
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// With --peer: rounds of this renderer (or, with --train-step, this training step) then
    /// the peer, alternating, each the median of --runs. The ratio reported is the median of the
    /// rounds' ratios, with a distribution-free interval of that median from the rounds' order
    /// statistics (5 rounds: their range, which holds the median 94 % of the times; 3 rounds:
    /// 75 %): on a shared machine a swing of speed then falls on both sides of a round instead
    /// of on one.
    #[arg(long, default_value_t = 5)]
    pub rounds: usize,
    /// Also write {"render_ms", "torch_ms", "ratio", ...} to this JSON file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Median wall-clock milliseconds of `runs` calls of `f`, after one warm-up call.
pub fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    f(); // warm-up
    median(
        (0..runs.max(1))
            .map(|_| {
                let t0 = Instant::now();
                f();
                t0.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

pub use crate::support::median;

/// The peer's scene: K = [[W/2, 0, W/2], [0, W/2, H/2]], ref_from_tgt = (rot((0.2, 1, 0.1), 4°),
/// (0.08, −0.02, 0.05)), uniform random alphas and colours.
pub fn scene(n: usize, d: usize, size: u32, per_layer: bool) -> anyhow::Result<(Mhi, Camera)> {
    let s = f64::from(size);
    let k = Intrinsics::new(0.5 * s, 0.5 * s, 0.5 * s, 0.5 * s)?;
    let reference = Camera::new(k, RigidTransform::IDENTITY, size, size)?;
    let ref_from_tgt = RigidTransform::new(
        DMat3::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), 4f64.to_radians()),
        DVec3::new(0.08, -0.02, 0.05),
    )?;
    let target = Camera::new(k, ref_from_tgt.inverse(), size, size)?;
    let normals = NormalSet::paper_subset(n)?;
    let depths = depths_linear_in_disparity(1.0, 100.0, d)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut img = || {
        Rgb32FImage::from_fn(size, size, |_, _| {
            image::Rgb([rng.random(), rng.random(), rng.random()])
        })
    };
    let color = if per_layer {
        LayerColor::PerLayer((0..n * d).map(|_| img()).collect())
    } else {
        LayerColor::Shared(img())
    };
    let alpha = (0..n * d * (size * size) as usize)
        .map(|_| rng.random::<f32>())
        .collect();
    Ok((Mhi::new(normals, depths, reference, color, alpha)?, target))
}

/// Soft blending, exactly and with the default render plan.
fn soft_exact_and_pruned() -> (RenderOptions<'static>, RenderOptions<'static>) {
    let soft = RenderOptions {
        blend: Blend::Heuristic(BlendHeuristic::Soft),
        ..Default::default()
    };
    (
        soft,
        RenderOptions {
            prune: Prune::DEFAULT,
            ..soft
        },
    )
}

/// Exact against pruned render time of a real MHI.
#[derive(serde::Serialize)]
struct RealPruning {
    /// `sweep` or the trained run's path.
    mhi: String,
    scene: String,
    size: (u32, u32),
    exact_ms: f64,
    pruned_ms: f64,
    /// Median of the paired exact / pruned ratios.
    speedup: f64,
    /// Order-statistic interval of that median, and its coverage.
    speedup_interval: [f64; 2],
    speedup_coverage: f64,
    layers_pruned: usize,
    normals_pruned: usize,
    composited: f32,
    samples: f32,
    bound: f32,
}

/// The sweep MHI of the first test triplet of `--data` (and, with `--run`, the trained model's
/// MHI of the same triplet), each rendered exactly and with the default plan.
fn realistic_pruning(a: &BenchArgs, pool: &rayon::ThreadPool) -> anyhow::Result<Vec<RealPruning>> {
    if a.data == std::path::Path::new("data/synth") {
        crate::support::ensure_synthetic(&a.data)?;
    }
    let ds = mhi_data::Dataset::open(&a.data, "test", 3).with_context(|| {
        format!(
            "--data {}: the pruned timing needs its test split",
            a.data.display()
        )
    })?;
    let idx = mhi_data::TripletIndex::sample(&ds, 1, 0);
    let t = idx
        .triplets
        .first()
        .with_context(|| format!("--data {}: no test triplet", a.data.display()))?;
    let seq = ds.sequence(&t.sequence).context("triplet sequence")?;
    let model = match &a.run {
        Some(run) => Some(
            mhi_net::Model::load(run, burn::tensor::Device::flex())
                .with_context(|| format!("--run {}: loading the trained run", run.display()))?,
        ),
        None => None,
    };
    let mut size = crate::support::size_for(mhi_data::check_same_size(&[&seq.frames[0]])?, a.size);
    if let Some(m) = &model {
        // The U-Nets need sides divisible by the model's multiple.
        let k = m.config().size_multiple().max(1) as u32;
        size = (size.0 / k * k, size.1 / k * k);
        m.check_size(size.0, size.1)?;
    }
    let load = |i: usize| mhi_data::load_frame(&seq.frames[i], Some(size), mhi_data::Fit::Stretch);
    let (rf, sf, tf) = (load(t.reference)?, load(t.source)?, load(t.target)?);
    let scene = format!(
        "{}/{} frames {}-{}-{}",
        a.data.display(),
        seq.name,
        t.reference,
        t.source,
        t.target
    );
    let synth = mhi_net::ViewSynthesis::new(mhi_net::MhiSource::Sweep {
        normals: a.grid.normal_set()?,
        depths: a.grid.depths()?,
        config: mhi_render::SweepConfig::for_short_side(size.0.min(size.1)),
    });
    let (mhi, _) = synth.mhi(&rf, &sf)?;
    let (soft, pruned_opts) = soft_exact_and_pruned();
    let time = |what: String, mhi: &Mhi, (exact, pruned)| {
        time_pruning(
            what,
            scene.clone(),
            size,
            a.runs,
            pool,
            mhi,
            &tf.camera,
            (exact, pruned),
        )
    };
    let mut out = vec![time("sweep".into(), &mhi, (&soft, &pruned_opts))?];
    if let (Some(m), Some(run)) = (&model, &a.run) {
        let (mhi, _) = mhi_net::ViewSynthesis::new(mhi_net::MhiSource::Learned(m)).mhi(&rf, &sf)?;
        // As `render` renders a learned MHI (and `eval` its learned blend): every multi-normal
        // image kept.
        let mni = |prune| RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Avg),
            prune,
            keep_multi_normal: true,
        };
        let kept = (mni(Prune::NONE), mni(Prune::DEFAULT));
        out.push(time(run.display().to_string(), &mhi, (&kept.0, &kept.1))?);
        // And as `eval`'s soft row renders it: Soft weights, only the blend bounded.
        out.push(time(
            format!("{} (Soft, as eval's soft row)", run.display()),
            &mhi,
            (&soft, &pruned_opts),
        )?);
    }
    Ok(out)
}

/// Median exact and pruned render times of one MHI and view.
#[allow(clippy::too_many_arguments)]
fn time_pruning(
    what: String,
    scene: String,
    size: (u32, u32),
    runs: usize,
    pool: &rayon::ThreadPool,
    mhi: &Mhi,
    camera: &Camera,
    (exact, pruned): (&RenderOptions<'_>, &RenderOptions<'_>),
) -> anyhow::Result<RealPruning> {
    let stats = render(mhi, camera, pruned)?.stats;
    // Exact and pruned alternate, so that a shared machine's swings hit both alike; the
    // speed-up is the median of the paired ratios.
    let (exact_ms, pruned_ms, speedup, ratios) = pool.install(|| {
        let time = |o: &RenderOptions<'_>| {
            let t0 = Instant::now();
            std::hint::black_box(render(mhi, camera, o).expect("valid scene"));
            t0.elapsed().as_secs_f64() * 1e3
        };
        time(exact);
        time(pruned);
        let (mut e, mut p, mut r) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..runs.max(1) {
            let (te, tp) = (time(exact), time(pruned));
            e.push(te);
            p.push(tp);
            r.push(te / tp);
        }
        (median(e), median(p), median(r.clone()), r)
    });
    let (speedup_interval, speedup_coverage) =
        crate::stats::median_interval(&ratios, 0.95).context("a render time was not finite")?;
    Ok(RealPruning {
        mhi: what,
        scene,
        size,
        exact_ms,
        pruned_ms,
        speedup,
        speedup_interval,
        speedup_coverage,
        layers_pruned: stats.layers_pruned,
        normals_pruned: stats.normals_pruned,
        composited: stats.composited,
        samples: stats.samples,
        bound: stats.bound,
    })
}

/// Run the PyTorch peer renderer on the bench's shapes; its median milliseconds and version.
fn run_peer_render(
    a: &BenchArgs,
    peer: &std::path::Path,
    shared: bool,
) -> anyhow::Result<(f64, String)> {
    let mut cmd = Command::new(&a.python);
    cmd.arg(peer).args([
        "--n",
        &a.grid.normals.to_string(),
        "--d",
        &a.grid.planes.to_string(),
        "--size",
        &a.size.to_string(),
        "--threads",
        &a.threads.to_string(),
        "--runs",
        &a.runs.to_string(),
    ]);
    if shared {
        cmd.arg("--shared-colour");
    }
    let v = run_peer_json(&mut cmd, peer)?;
    let ms = v["median_ms"]
        .as_f64()
        .context("peer JSON lacks median_ms")?;
    Ok((ms, v["torch"].as_str().unwrap_or("?").to_string()))
}

/// The bench scene with any normal set and shared colour.
pub fn scene_with(normals: NormalSet, d: usize, size: u32) -> anyhow::Result<(Mhi, Camera)> {
    let (base, target) = scene(1, 1, size, false)?;
    let n = normals.len();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let alpha = (0..n * d * (size * size) as usize)
        .map(|_| rng.random::<f32>())
        .collect();
    let depths = depths_linear_in_disparity(1.0, 100.0, d)?;
    let color = base.color().clone();
    Ok((
        Mhi::new(normals, depths, *base.reference(), color, alpha)?,
        target,
    ))
}

/// Run a Python peer (`cmd` names the interpreter and `script` with its arguments) and parse
/// the last line of its standard output that is a JSON object.
pub fn run_peer_json(
    cmd: &mut Command,
    script: &std::path::Path,
) -> anyhow::Result<serde_json::Value> {
    let out = cmd
        .output()
        .with_context(|| format!("cannot start the peer {}", script.display()))?;
    if !out.status.success() {
        bail!(
            "the peer {} failed ({}): {} (it needs `pip install torch torchvision`)",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .with_context(|| format!("the peer {} printed no JSON line", script.display()))?;
    serde_json::from_str(line).with_context(|| format!("the peer's JSON {line:?}"))
}

/// Read bandwidth in bytes/s: a parallel sum over 512 MiB, best of three.
fn read_bandwidth() -> f64 {
    let v = vec![1.0_f32; 128 << 20];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t0 = Instant::now();
        let s: f32 = v.par_chunks(1 << 16).map(|c| c.iter().sum::<f32>()).sum();
        std::hint::black_box(s);
        best = best.min(t0.elapsed().as_secs_f64());
    }
    (v.len() * 4) as f64 / best
}

/// `bench --train-step`: the phase-1 step, beside the PyTorch twin in alternating rounds with
/// --peer.
fn train_step_bench(a: &BenchArgs) -> anyhow::Result<()> {
    let weights = crate::support::cache_dir(a.cache.as_deref()).join("weights");
    // With --run, whole steps of that run's configuration against the run twin; else the
    // default model's parts against its twin.
    let ours = || match &a.run {
        Some(run) => step::run_step(run, &a.data, &weights, a.runs),
        None => step::train_step(&a.data, &weights, a.runs),
    };
    let Some(peer) = &a.peer else {
        return write_json(a, &ours()?);
    };
    if a.rounds == 0 {
        bail!("--rounds 0: at least one round of this step and the peer's is needed for a ratio");
    }
    let parts: &[(&str, &str)] = if a.run.is_some() {
        &[
            (
                "step_ms",
                "phase-1 step of the run's configuration (no cost volume)",
            ),
            ("stage1_ms", "stage 1 forward (with prior and colour)"),
            ("backward_ms", "backward + clip + Adam"),
        ]
    } else {
        &[
            ("step", "phase-1 step (stage 1 + warp + loss, fwd+bwd)"),
            ("stage1_inference", "stage 1 inference"),
        ]
    };
    // Rounds of our step then the peer's, alternating (as the render's): a swing of the
    // shared machine's speed falls on both sides of a round.
    let mut rounds: Vec<Vec<f64>> = Vec::with_capacity(a.rounds);
    let mut v = serde_json::Value::Null;
    for r in 0..a.rounds {
        println!("\n== round {}/{} ==", r + 1, a.rounds);
        v = ours()?;
        let torch = match &a.run {
            Some(run) => step::peer_run_step(&a.python, peer, run, a.threads, a.runs, &v)?,
            None => step::peer_train_step(&a.python, peer, a.threads, a.runs, &v)?,
        };
        rounds.push(
            parts
                .iter()
                .map(|(key, _)| {
                    torch["ratio_burn_over_torch"][key]
                        .as_f64()
                        .unwrap_or(f64::NAN)
                })
                .collect(),
        );
        v["peer"] = torch;
    }
    println!(
        "\nburn / PyTorch over {} alternating rounds (median; distribution-free interval of the median):",
        a.rounds
    );
    let mut summary = serde_json::Map::new();
    for (part, (key, label)) in parts.iter().enumerate() {
        let ratios: Vec<f64> = rounds.iter().map(|r| r[part]).collect();
        let (ci, coverage) = crate::stats::median_interval(&ratios, 0.95)
            .context("the peer or this step gave a non-finite time")?;
        let m = median(ratios.clone());
        println!(
            "  {label:<58} {m:.2}x ({:.0} % interval {:.2}–{:.2}x; rounds {})",
            100.0 * coverage,
            ci[0],
            ci[1],
            ratios
                .iter()
                .map(|r| format!("{r:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        summary.insert(
            (*key).into(),
            serde_json::json!({ "median": m, "interval": ci, "coverage": coverage, "rounds": ratios }),
        );
    }
    v["ratio_rounds"] = serde_json::Value::Object(summary);
    write_json(a, &v)
}

/// The peer's median time, the median ratio, the rounds (ours, the peer's) and the ratio's
/// interval.
type PeerRounds = (f64, f64, Vec<(f64, f64)>, serde_json::Value);

/// Alternating rounds of this renderer (`scene`'s MHI, target and options) and the PyTorch peer
/// in one colour layout: the peer's median time, the median ratio, the rounds and the ratio's
/// interval.
fn peer_rounds(
    a: &BenchArgs,
    peer: &std::path::Path,
    pool: &rayon::ThreadPool,
    (m, target, soft): (&mhi_render::Mhi, &mhi_geom::Camera, &RenderOptions<'_>),
    shared: bool,
    label: &str,
) -> anyhow::Result<PeerRounds> {
    let mut rounds = Vec::with_capacity(a.rounds);
    let mut version = String::new();
    for r in 0..a.rounds {
        let ours = pool.install(|| {
            median_ms(a.runs, || {
                std::hint::black_box(render(m, target, soft).expect("valid bench scene"));
            })
        });
        let (torch, v) = run_peer_render(a, peer, shared)?;
        version = v;
        println!(
            "    {} round {}/{}: this renderer {ours:.1} ms, PyTorch {torch:.1} ms → {:.1}x",
            label.trim_end(),
            r + 1,
            a.rounds,
            torch / ours
        );
        rounds.push((ours, torch));
    }
    let ratios: Vec<f64> = rounds.iter().map(|(o, t)| t / o).collect();
    let (ci, coverage) = crate::stats::median_interval(&ratios, 0.95)
        .context("the peer or this renderer gave a non-finite time")?;
    let ratio = median(ratios);
    let torch = median(rounds.iter().map(|(_, t)| *t).collect());
    println!(
        "  PyTorch peer ({version}, {label}): {torch:8.1} ms  → ratio {ratio:.1}x (median of {} rounds; {:.0} % interval of the median {:.1}–{:.1}x)",
        a.rounds,
        100.0 * coverage,
        ci[0],
        ci[1]
    );
    let interval = serde_json::json!({ "interval": ci, "coverage": coverage });
    Ok((torch, ratio, rounds, interval))
}

/// Write `v` to --json when asked.
fn write_json(a: &BenchArgs, v: &serde_json::Value) -> anyhow::Result<()> {
    if let Some(p) = &a.json {
        mhi_data::write_atomic(p, &serde_json::to_vec_pretty(v)?)?;
    }
    Ok(())
}

/// The benches other than the render's (`--compare-backend`, `--scaling`, `--ops`,
/// `--train-step`), when one is asked for: `true` when it ran.
fn other_bench(a: &BenchArgs) -> anyhow::Result<bool> {
    if let Some(other) = &a.compare_backend {
        let v = step::backend_agreement(&a.data, *other)?;
        write_json(a, &v)?;
        return Ok(true);
    }
    if a.scaling {
        let v = scaling::scaling(&a.scaling_out, a.runs)?;
        write_json(a, &v)?;
        return Ok(true);
    }
    if a.ops {
        let v = ops::ops(&a.python, a.peer_ops.as_deref(), a.threads, a.runs)?;
        write_json(a, &v)?;
        return Ok(true);
    }
    if a.train_step {
        train_step_bench(a)?;
        return Ok(true);
    }
    Ok(false)
}

/// One line per real-frame MHI: exact against pruned, and what was left out.
fn print_real_pruning(real: &[RealPruning]) {
    for r in real {
        println!(
            "  {} MHI of {} at {}x{}: exact {:.1} ms, pruned {:.1} ms (paired {:.2}x, {:.0} % interval of the median {:.2}–{:.2}x; {} layers and {} normals left out everywhere, {:.0} % of the tile-layer pairs and {:.0} % of the samples composited, bound {:.5})",
            r.mhi,
            r.scene,
            r.size.0,
            r.size.1,
            r.exact_ms,
            r.pruned_ms,
            r.speedup,
            100.0 * r.speedup_coverage,
            r.speedup_interval[0],
            r.speedup_interval[1],
            r.layers_pruned,
            r.normals_pruned,
            100.0 * r.composited,
            100.0 * r.samples,
            r.bound
        );
    }
}

/// `cargo xtask bench`.
pub fn bench(a: &BenchArgs) -> anyhow::Result<()> {
    if a.runs == 0 {
        bail!("--runs 0: at least one timed run is needed for a median");
    }
    if a.rounds == 0 {
        bail!("--rounds 0: at least one round of this renderer and the peer is needed for a ratio");
    }
    println!(
        "CPU: {} ({} threads); {}",
        crate::support::cpu_model(),
        rayon::current_num_threads(),
        crate::support::kernel_paths()
    );
    if other_bench(a)? {
        return Ok(());
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()?;
    let (n, d, size) = (a.grid.normals, a.grid.planes, a.size);
    let (mhi, target) = scene(n, d, size, false)?;
    let (soft, pruned_opts) = soft_exact_and_pruned();
    let (render_ms, pruned_ms, bw) = pool.install(|| -> anyhow::Result<_> {
        let full = median_ms(a.runs, || {
            std::hint::black_box(render(&mhi, &target, &soft).expect("valid bench scene"));
        });
        let pruned = median_ms(a.runs, || {
            std::hint::black_box(render(&mhi, &target, &pruned_opts).expect("valid bench scene"));
        });
        Ok((full, pruned, read_bandwidth()))
    })?;
    // Pruning pays only on a real MHI (uniform random alphas leave nothing out): the sweep MHI
    // of the first test triplet of --data, exact against pruned, at the bench's N, D and short
    // side.
    let real = realistic_pruning(a, &pool)?;
    // Per-layer colour (the peer's layout): every layer is a full RGBA image.
    let (mhi_pl, _) = scene(n, d, size, true)?;
    let per_layer_ms = pool.install(|| {
        median_ms(a.runs, || {
            std::hint::black_box(render(&mhi_pl, &target, &soft).expect("valid bench scene"));
        })
    });
    let px = f64::from(size) * f64::from(size);
    let bytes = (n * d) as f64 * px * 4.0 + px * 3.0 * 4.0;
    let floor_ms = bytes / bw * 1e3;
    println!(
        "MHI N={n} D={d} at {size}x{size}, {} threads, median of {} runs:",
        a.threads, a.runs
    );
    println!("  this renderer (shared colour, soft blend): {render_ms:8.1} ms");
    println!(
        "  with the default render plan (pruning):    {pruned_ms:8.1} ms (random alphas: only the transmittance stop applies)"
    );
    print_real_pruning(&real);
    println!("  per-layer colour (the peer's layout):      {per_layer_ms:8.1} ms");
    println!(
        "  memory floor: {:.1} MB read once at {:.1} GB/s = {floor_ms:.1} ms ({:.1}x above it)",
        bytes / 1e6,
        bw / 1e9,
        render_ms / floor_ms
    );
    // Like for like: our shared-colour render against the peer's `--shared-colour` layout,
    // our per-layer render against the peer's RGBA-per-layer layout, in alternating rounds.
    let (mut torch_shared, mut torch_per_layer) = (None, None);
    let (mut ratio_shared, mut ratio_per_layer) = (None, None);
    let (mut rounds_shared, mut rounds_per_layer) = (Vec::new(), Vec::new());
    let (mut interval_shared, mut interval_per_layer) =
        (serde_json::Value::Null, serde_json::Value::Null);
    if let Some(peer) = &a.peer {
        if !peer.is_file() {
            bail!("peer renderer {} not found", peer.display());
        }
        for shared in [true, false] {
            let (m, label) = if shared {
                (&mhi, "--shared-colour")
            } else {
                (&mhi_pl, "RGBA per layer ")
            };
            let (torch, ratio, rounds, interval) =
                peer_rounds(a, peer, &pool, (m, &target, &soft), shared, label)?;
            if shared {
                (torch_shared, ratio_shared, rounds_shared, interval_shared) =
                    (Some(torch), Some(ratio), rounds, interval);
            } else {
                (
                    torch_per_layer,
                    ratio_per_layer,
                    rounds_per_layer,
                    interval_per_layer,
                ) = (Some(torch), Some(ratio), rounds, interval);
            }
        }
    }
    if let Some(p) = &a.json {
        let v = serde_json::json!({
            "normals": n, "planes": d, "size": size, "threads": a.threads, "runs": a.runs,
            "render_ms": render_ms, "pruned_ms": pruned_ms, "per_layer_color_ms": per_layer_ms,
            "realistic_pruning": serde_json::to_value(&real)?,
            "torch_shared_ms": torch_shared, "torch_per_layer_ms": torch_per_layer,
            "ratio_shared": ratio_shared, "ratio_per_layer": ratio_per_layer,
            "ratio_interval": { "shared": interval_shared, "per_layer": interval_per_layer },
            "rounds_ms": { "shared": rounds_shared, "per_layer": rounds_per_layer },
            "floor_ratio": render_ms / floor_ms,
            "floor_bytes": bytes, "bandwidth_gbs": bw / 1e9, "floor_ms": floor_ms,
        });
        mhi_data::write_atomic(p, &serde_json::to_vec_pretty(&v)?)?;
        println!("wrote {}", p.display());
    }
    Ok(())
}
