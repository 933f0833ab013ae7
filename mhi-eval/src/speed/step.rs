//! `cargo xtask bench --train-step`: where a training step of the default model spends its time,
//! each part timed forward only and forward + backward (median of several runs), on a real
//! synthetic sample.

use std::path::Path;
use std::time::Instant;

use super::median_ms;

use burn::tensor::{Device, Distribution, Tensor};
use mhi_data::{Dataset, Fit, LoadedFrame, load_frame};
use mhi_geom::BlendHeuristic;
use mhi_net::loss::TrainLoss;
use mhi_net::{TrainConfig, cost_volume, init_models};
use mhi_render::diff::{WarpGeometry, heuristic_weights_tensor, image_to_tensor, render_shared};

/// The default model's configuration and a fixed sample (frames 0, 3, 6 of the first training
/// sequence) at its training size.
fn default_sample(data: &Path) -> anyhow::Result<(TrainConfig, [LoadedFrame; 3])> {
    crate::support::ensure_synthetic(data)?;
    let ds = Dataset::open(data, "train", 3)?;
    let seq = ds
        .sequences
        .first()
        .ok_or_else(|| anyhow::anyhow!("{}: no training sequence", ds.dir.display()))?;
    let config = TrainConfig::for_normals(5);
    let size = Some((config.width, config.height));
    let load = |i: usize| load_frame(&seq.frames[i], size, Fit::Stretch);
    let frames = [load(0)?, load(3)?, load(6)?];
    Ok((config, frames))
}

/// Time the parts of one phase-1 step of the default model (N = 5, D = 8, 64×64).
pub fn train_step(data: &Path, weights: &Path, runs: usize) -> anyhow::Result<serde_json::Value> {
    let (config, [rf, sf, tf]) = default_sample(data)?;
    let device = Device::flex().autodiff();
    let (stage1, _) = init_models(&config, &device);
    let normals = config.normal_set()?;
    let depths = mhi_geom::depths_linear_in_disparity(config.near, config.far, config.planes)?;
    let (n, d) = (normals.len(), depths.len());
    let (w, h) = (config.width as usize, config.height as usize);
    let (loss, why) = TrainLoss::from_weights(
        Some(weights),
        mhi_net::loss::DEFAULT_PERCEPTUAL_WEIGHT,
        &device,
    );
    if let Some(why) = why {
        eprintln!("note: VGG16 weights unavailable ({why}); timing the L1 + SSIM loss");
    }
    let geom = WarpGeometry::new(&normals, &depths, &rf.camera, &tf.camera, &device)?;
    let color = image_to_tensor(&rf.image, &device);
    let soft = heuristic_weights_tensor(
        &normals,
        &rf.camera,
        &tf.camera,
        BlendHeuristic::Soft,
        &device,
    );
    let target = image_to_tensor(&tf.image, &device);

    let volume_ms = median_ms(runs, || {
        let _ = cost_volume(&normals, &depths, &rf, &sf, &device).map(|v| v.into_data());
    });
    let volume = cost_volume(&normals, &depths, &rf, &sf, &device)?;
    let sync = |t: Tensor<1>| {
        let _ = t.into_data();
    };
    let stage1_fwd = median_forward_ms(runs, || Some(stage1.forward(volume.clone()).mean()));
    let stage1_both = median_ms(runs, || {
        let _ = stage1.forward(volume.clone()).mean().backward();
    });
    // Inference: the same network on the plain device, no graph (PyTorch's twin: its frozen
    // stage 1 under `no_grad` in the phase-2 step).
    let plain = Device::flex();
    let (stage1_plain, _) = init_models(&config, &plain);
    let volume_plain = cost_volume(&normals, &depths, &rf, &sf, &plain)?;
    let stage1_infer = median_ms(runs, || {
        sync(stage1_plain.forward(volume_plain.clone()).mean())
    });
    let alpha: Tensor<4> =
        Tensor::random([n * d, 1, h, w], Distribution::Uniform(0.0, 1.0), &device).require_grad();
    let warp_fwd = median_forward_ms(runs, || {
        let (_, mni) = render_shared(alpha.clone(), color.clone(), &geom, soft.clone());
        Some(mni.mean())
    });
    let warp_both = median_ms(runs, || {
        let (_, mni) = render_shared(alpha.clone(), color.clone(), &geom, soft.clone());
        let _ = mni.mean().backward();
    });
    let mni: Tensor<4> =
        Tensor::random([n, 3, h, w], Distribution::Uniform(0.0, 1.0), &device).require_grad();
    let loss_fwd = median_forward_ms(runs, || loss.compute(mni.clone(), target.clone()).ok());
    let loss_both = median_ms(runs, || {
        if let Ok(l) = loss.compute(mni.clone(), target.clone()) {
            let _ = l.backward();
        }
    });
    let rows = [
        ("cost volume (CPU plane sweep)", volume_ms, volume_ms),
        ("stage 1 (3D U-Net, conv3d)", stage1_fwd, stage1_both),
        ("warp + composite", warp_fwd, warp_both),
        ("loss", loss_fwd, loss_both),
    ];
    let total: f64 = rows.iter().map(|r| r.2).sum();
    println!(
        "one phase-1 step, N={n} D={d} {w}x{h}, loss {}, median of {runs} (flex backend, {} threads)",
        loss.name(),
        rayon::current_num_threads()
    );
    println!(
        "{:<34} {:>10} {:>12} {:>10} {:>7}",
        "part", "forward", "fwd+bwd", "backward", "share"
    );
    for (name, f, b) in rows {
        println!(
            "{name:<34} {f:>8.1}ms {b:>10.1}ms {:>8.1}ms {:>6.1}%",
            b - f,
            100.0 * b / total
        );
    }
    println!("{:<34} {:>8} {total:>10.1}ms", "sum", "");
    println!(
        "{:<34} {stage1_infer:>8.1}ms",
        "stage 1 inference (no graph)"
    );
    Ok(serde_json::json!({
        "normals": n, "planes": d, "size": [w, h], "loss": loss.name(), "runs": runs,
        "volume_ms": volume_ms,
        "stage1_forward_ms": stage1_fwd, "stage1_forward_backward_ms": stage1_both,
        "stage1_inference_ms": stage1_infer,
        "warp_forward_ms": warp_fwd, "warp_forward_backward_ms": warp_both,
        "loss_forward_ms": loss_fwd, "loss_forward_backward_ms": loss_both,
    }))
}

/// The parts [`run_step`] reports (its JSON keys, also the twin's) and their labels, in the
/// order of [`mhi_net::StepTimes`]; the last is the step without its cost volume.
pub const RUN_STEP_PARTS: [(&str, &str); 6] = [
    ("volume_ms", "cost volume and its loading (CPU)"),
    ("stage1_ms", "stage 1 forward (and prior, colour)"),
    ("render_ms", "warp + composite"),
    ("loss_ms", "loss forward"),
    ("backward_ms", "backward + clip + Adam"),
    ("step_ms", "step without the cost volume"),
];

/// Whole phase-1 training steps of a run's configuration (its `config.json`: stage 1, planes,
/// size, prior, colour head, loss), as `train` takes them: a fresh trainer with random weights on
/// the synthetic data `data`, two warm-up steps, then `runs` steps; the median of each part of
/// [`mhi_net::StepTimes`] and of the step without its cost volume (the part the PyTorch twin,
/// `xtask/scripts/train_step_torch.py`, does the same work for).
///
/// # Errors
/// An unreadable run, a perceptual run without the VGG16 weights in `weights`, or a failed step.
pub fn run_step(
    run: &Path,
    data: &Path,
    weights: &Path,
    runs: usize,
) -> anyhow::Result<serde_json::Value> {
    use anyhow::Context as _;
    use burn::module::Module as _;
    crate::support::ensure_synthetic(data)?;
    let mut config = mhi_net::RunDir::new(run)
        .config()
        .with_context(|| format!("--run {}", run.display()))?;
    // The run's recipe on this machine's synthetic data, with as little validation as allowed.
    config.data.clear();
    config.val_samples = 1;
    let device = Device::flex().autodiff();
    let loss = match config.loss_kind {
        mhi_net::loss::LossKind::Photometric => TrainLoss::Photometric,
        mhi_net::loss::LossKind::L1 => TrainLoss::L1,
        mhi_net::loss::LossKind::Perceptual => {
            match TrainLoss::from_weights(Some(weights), config.perceptual_weight, &device) {
                (l, None) => l,
                (_, Some(why)) => {
                    anyhow::bail!("{}: the perceptual loss needs VGG16 ({why})", run.display())
                }
            }
        }
    };
    let tmp = tempfile::tempdir()?;
    let mut trainer = mhi_net::Trainer::new(config, &tmp.path().join("run"), data, loss, device)?;
    let params = trainer.stage1().num_params();
    let mut rows = Vec::with_capacity(runs);
    for i in 0..runs.max(1) + 2 {
        let r = trainer.step()?;
        if i >= 2 {
            rows.push(r.times);
        }
    }
    let med = |f: fn(&mhi_net::StepTimes) -> f64| super::median(rows.iter().map(f).collect());
    let values = [
        med(|t| t.volume_ms),
        med(|t| t.stage1_ms),
        med(|t| t.render_ms),
        med(|t| t.loss_ms),
        med(|t| t.backward_ms),
        med(|t| t.stage1_ms + t.render_ms + t.loss_ms + t.backward_ms),
    ];
    let c = trainer.config();
    println!(
        "whole phase-1 steps of {}: N={} D={} {}x{}, stage 1 at 1/{} with {} parameters, loss {}, median of {runs} after 2 warm-up steps (flex backend, {} threads)",
        run.display(),
        c.stage1.normals,
        c.planes,
        c.width,
        c.height,
        c.stage1.scale.max(1),
        params,
        c.loss,
        rayon::current_num_threads()
    );
    let mut v = serde_json::json!({ "run": run, "runs": runs, "params": params });
    for ((key, label), ms) in RUN_STEP_PARTS.into_iter().zip(values) {
        println!("  {label:<40} {ms:>8.1} ms");
        v[key] = serde_json::json!(ms);
    }
    Ok(v)
}

/// The run-configuration twin (`xtask/scripts/train_step_torch.py --config RUN/config.json`) on
/// the same threads and runs: its JSON, with the ratios burn / PyTorch per part added and
/// printed.
pub fn peer_run_step(
    python: &str,
    peer: &Path,
    run: &Path,
    threads: usize,
    runs: usize,
    ours: &serde_json::Value,
) -> anyhow::Result<serde_json::Value> {
    println!("running the PyTorch twin {} ...", peer.display());
    let mut cmd = std::process::Command::new(python);
    cmd.arg(peer)
        .arg("--config")
        .arg(mhi_net::RunDir::new(run).config_path())
        .args([
            "--threads",
            &threads.to_string(),
            "--runs",
            &runs.to_string(),
        ]);
    let mut torch = super::run_peer_json(&mut cmd, peer)?;
    println!(
        "\n{:<28} {:>10} {:>10} {:>8}",
        "part", "burn ms", "torch ms", "ratio"
    );
    let mut ratios = serde_json::Map::new();
    for (key, _) in RUN_STEP_PARTS {
        let (b, t) = (
            ours[key].as_f64().unwrap_or(f64::NAN),
            torch[key].as_f64().unwrap_or(f64::NAN),
        );
        println!(
            "{:<28} {b:>10.1} {t:>10.1} {:>7.2}x",
            key.trim_end_matches("_ms"),
            b / t
        );
        ratios.insert(key.into(), serde_json::json!(b / t));
    }
    torch["ratio_burn_over_torch"] = serde_json::Value::Object(ratios);
    Ok(torch)
}

/// The median time (ms) of a forward pass on the autodiff device, after one warm-up: `f` runs
/// the forward and returns its scalar output, timed until the output's value is read; a backward
/// pass from that output then releases the graph, outside the timed region.
///
/// burn's autodiff keeps the graph of an output that never goes through `backward` (with every
/// activation it saved) until a later backward sweeps it, so forward passes timed one after
/// another without one keep ~80 MB each of stage 1's activations alive and write every new
/// one into fresh pages: the first version of this bench timed stage 1's forward at 138 ms
/// against 62 ms with the graph released (2026-12-03, docs/SPEED.md). A training step always
/// runs its backward, so it never pays that.
fn median_forward_ms(runs: usize, mut f: impl FnMut() -> Option<Tensor<1>>) -> f64 {
    let mut once = || {
        let t0 = Instant::now();
        let out = f();
        if let Some(out) = &out {
            let _ = out.clone().into_data();
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        if let Some(out) = out {
            let _ = out.backward();
        }
        ms
    };
    once(); // warm-up
    super::median((0..runs.max(1)).map(|_| once()).collect())
}

/// Run the PyTorch twin of the training step (`../shared/peer/torch_train_step.py`) with the
/// same shapes, loss, threads and runs, and print the ratio burn / PyTorch per part and for the
/// split's sum. `ours` is [`train_step`]'s JSON. Returns the peer's JSON with the ratios added.
pub fn peer_train_step(
    python: &str,
    peer: &Path,
    threads: usize,
    runs: usize,
    ours: &serde_json::Value,
) -> anyhow::Result<serde_json::Value> {
    use anyhow::Context as _;
    let loss = if ours["loss"].as_str().is_some_and(|l| l.contains("VGG")) {
        "perceptual"
    } else {
        "photometric"
    };
    let tmp = tempfile::tempdir()?;
    let out_json = tmp.path().join("peer.json");
    println!(
        "running the PyTorch peer {} ({loss} loss) ...",
        peer.display()
    );
    let status = std::process::Command::new(python)
        .arg(peer)
        .args([
            "--threads",
            &threads.to_string(),
            "--runs",
            &runs.to_string(),
        ])
        .args(["--loss", loss, "--json"])
        .arg(&out_json)
        .status()
        .with_context(|| format!("cannot start {python} {}", peer.display()))?;
    if !status.success() {
        anyhow::bail!(
            "the peer {} failed ({status}); it needs `pip install torch torchvision`",
            peer.display()
        );
    }
    let text = std::fs::read_to_string(&out_json)
        .with_context(|| format!("the peer wrote no {}", out_json.display()))?;
    let mut torch: serde_json::Value = serde_json::from_str(text.trim())
        .with_context(|| format!("the peer's JSON in {}", out_json.display()))?;
    let parts = [
        ("stage 1 forward", "stage1_forward_ms"),
        ("stage 1 fwd+bwd", "stage1_forward_backward_ms"),
        ("warp forward", "warp_forward_ms"),
        ("warp fwd+bwd", "warp_forward_backward_ms"),
        ("loss forward", "loss_forward_ms"),
        ("loss fwd+bwd", "loss_forward_backward_ms"),
    ];
    println!(
        "\n{:<20} {:>10} {:>10} {:>8}",
        "part (same shapes)", "burn ms", "torch ms", "ratio"
    );
    let mut ratios = serde_json::Map::new();
    let (mut sum_b, mut sum_t) = (0.0, 0.0);
    for (name, key) in parts {
        let (b, t) = (
            ours[key].as_f64().unwrap_or(f64::NAN),
            torch[key].as_f64().unwrap_or(f64::NAN),
        );
        if key.ends_with("backward_ms") {
            sum_b += b;
            sum_t += t;
        }
        println!("{name:<20} {b:>10.1} {t:>10.1} {:>7.2}x", b / t);
        ratios.insert(key.into(), serde_json::json!(b / t));
    }
    println!(
        "{:<20} {sum_b:>10.1} {sum_t:>10.1} {:>7.2}x  (stage 1 + warp + loss, forward and backward)",
        "step",
        sum_b / sum_t
    );
    ratios.insert("step".into(), serde_json::json!(sum_b / sum_t));
    let (b, t) = (
        ours["stage1_inference_ms"].as_f64().unwrap_or(f64::NAN),
        torch["phase2_step_ms"]["stage1_frozen_fwd"]
            .as_f64()
            .unwrap_or(f64::NAN),
    );
    println!(
        "{:<20} {b:>10.1} {t:>10.1} {:>7.2}x  (no graph; PyTorch: its frozen stage 1 under no_grad)",
        "stage 1 inference",
        b / t
    );
    ratios.insert("stage1_inference".into(), serde_json::json!(b / t));
    torch["ratio_burn_over_torch"] = serde_json::Value::Object(ratios);
    Ok(torch)
}

/// Run one forward pass of the default model (cost volume → stage 1 → warp and composite → the
/// blending network) on the flex backend and on `other`, with the same weights (saved from flex,
/// loaded on the other device) and the same sample; report the largest differences and times.
pub fn backend_agreement(
    data: &Path,
    other: crate::run::options::Backend,
) -> anyhow::Result<serde_json::Value> {
    use burn::module::Module as _;
    let (config, [rf, sf, tf]) = default_sample(data)?;
    let flex = Device::flex();
    let gpu = crate::run::options::device(other)?;
    let (stage1, blend) = init_models(&config, &flex);
    let tmp = tempfile::tempdir()?;
    stage1
        .clone()
        .save_file(tmp.path().join("s1.bpk"))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    blend
        .clone()
        .save_file(tmp.path().join("b.bpk"))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let normals = config.normal_set()?;
    let depths = mhi_geom::depths_linear_in_disparity(config.near, config.far, config.planes)?;
    let (n, d) = (normals.len(), depths.len());
    let (w, h) = (config.width as usize, config.height as usize);
    let forward = |device: &Device,
                   s1: &mhi_net::Stage1,
                   bl: &mhi_net::BlendNet|
     -> anyhow::Result<(Vec<f32>, Vec<f32>, f64)> {
        let t0 = Instant::now();
        let volume = cost_volume(&normals, &depths, &rf, &sf, device)?;
        let alpha = s1.forward(volume).reshape([n * d, 1, h, w]);
        let geom = WarpGeometry::new(&normals, &depths, &rf.camera, &tf.camera, device)?;
        let soft = heuristic_weights_tensor(
            &normals,
            &rf.camera,
            &tf.camera,
            BlendHeuristic::Soft,
            device,
        );
        let (_, mni) = render_shared(
            alpha.clone(),
            image_to_tensor(&rf.image, device),
            &geom,
            soft.clone(),
        );
        let input = Tensor::cat(
            vec![
                mni.clone().reshape([1, 3 * n, h, w]),
                soft.reshape([1, n, h, w]),
            ],
            1,
        );
        let weights = bl.forward(input).reshape([n, 1, h, w]);
        let image = mhi_render::diff::blend(mni, weights);
        let a: Vec<f32> = alpha
            .into_data()
            .try_to_vec()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let i: Vec<f32> = image
            .into_data()
            .try_to_vec()
            .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        Ok((a, i, t0.elapsed().as_secs_f64() * 1e3))
    };
    let (a0, i0, t_flex) = forward(&flex, &stage1, &blend)?;
    let s1g = config
        .stage1
        .init(&gpu)
        .try_load_file(tmp.path().join("s1.bpk"))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let blg = config
        .blend
        .init(&gpu)
        .try_load_file(tmp.path().join("b.bpk"))
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let _ = forward(&gpu, &s1g, &blg)?; // warm-up: shader compilation
    let (a1, i1, t_gpu) = forward(&gpu, &s1g, &blg)?;
    let max_diff = |x: &[f32], y: &[f32]| {
        x.iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0_f32, f32::max)
    };
    let nonfinite = a1.iter().chain(&i1).filter(|v| !v.is_finite()).count();
    let (da, di) = (max_diff(&a0, &a1), max_diff(&i0, &i1));
    println!(
        "forward of the default model (N={n} D={d} {w}x{h}): flex {t_flex:.0} ms, {other} {t_gpu:.0} ms (after a warm-up)"
    );
    println!("max |alpha_flex - alpha_{other}| = {da:.2e}");
    println!("max |image_flex - image_{other}| = {di:.2e}");
    println!("non-finite values on {other}: {nonfinite}");
    let ok = da < 1e-3 && di < 1e-3 && nonfinite == 0;
    println!(
        "{}",
        if ok {
            "agree (bound 1e-3)"
        } else {
            "DISAGREE (bound 1e-3)"
        }
    );
    if !ok {
        anyhow::bail!("{other} disagrees with flex beyond 1e-3");
    }
    Ok(serde_json::json!({
        "backend": other.to_string(), "flex_ms": t_flex, "other_ms": t_gpu,
        "max_alpha_diff": da, "max_image_diff": di, "nonfinite": nonfinite,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `run_step` times a run's own configuration (a tiny one here: sweep prior, colour head,
    /// stage 1 on 2 × 2 blocks) and only reads the run.
    #[test]
    fn run_step_times_a_runs_configuration_and_leaves_the_run_alone() {
        let synth = tempfile::tempdir().unwrap();
        mhi_data::generate(
            &mhi_data::SynthConfig {
                scenes: 2,
                frames: 7,
                width: 32,
                height: 32,
                test_fraction: 0.5,
                ..mhi_data::SynthConfig::default()
            },
            synth.path(),
            &|| {},
        )
        .unwrap();
        let mut c = TrainConfig::for_normals(3);
        (c.width, c.height, c.planes) = (32, 32, 4);
        c.stage1.unet.width = 4;
        c.stage1.unet.levels = 1;
        c.stage1.unet.dilations = vec![2];
        c.stage1.unet.colour_head = true;
        c.stage1.scale = 2;
        c.blend.width = 4;
        c.blend.levels = 1;
        c.val_samples = 1;
        let c = c.with_sweep_prior();
        let runs = tempfile::tempdir().unwrap();
        let run = runs.path().join("run");
        let params = {
            use burn::module::Module as _;
            let t = mhi_net::Trainer::new(
                c,
                &run,
                synth.path(),
                TrainLoss::Photometric,
                Device::flex().autodiff(),
            )
            .unwrap();
            t.stage1().num_params()
        };
        let before = files_under(&run);
        let v = run_step(&run, synth.path(), Path::new("/nonexistent"), 1).unwrap();
        assert_eq!(v["params"].as_u64(), Some(params as u64));
        for (key, _) in RUN_STEP_PARTS {
            let ms = v[key].as_f64().unwrap();
            assert!(ms.is_finite() && ms > 0.0, "{key}: {ms}");
        }
        assert_eq!(files_under(&run), before, "the run was written to");
    }

    /// Every file under `dir` with its size and modification time, sorted.
    fn files_under(dir: &Path) -> Vec<(std::path::PathBuf, u64, std::time::SystemTime)> {
        let mut out = Vec::new();
        for e in std::fs::read_dir(dir).unwrap() {
            let e = e.unwrap();
            let m = e.metadata().unwrap();
            if m.is_dir() {
                out.extend(files_under(&e.path()));
            } else {
                out.push((e.path(), m.len(), m.modified().unwrap()));
            }
        }
        out.sort();
        out
    }
}
