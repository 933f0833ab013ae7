//! `cargo xtask train`: the two-phase training of an MHI model (or, with `--normals 1`, of the
//! MPI baseline by the same code).

use anyhow::{Context, bail};
use mhi_data::DataSource;
use mhi_net::loss::TrainLoss;
use mhi_net::{TrainConfig, Trainer};

use crate::common::device;
use crate::options::{FitArg, LossArg, PriorArg, TrainArgs, TripletsArg};

/// The data sources of `--data`, `--data-weight` and `--holdout`.
pub fn sources(a: &TrainArgs) -> anyhow::Result<Vec<DataSource>> {
    if !a.data_weights.is_empty() && a.data_weights.len() != a.data.len() {
        bail!(
            "--data-weight gives {} weights for {} --data roots; give one per root, in order",
            a.data_weights.len(),
            a.data.len()
        );
    }
    let mut out: Vec<DataSource> = a
        .data
        .iter()
        .enumerate()
        .map(|(i, root)| DataSource {
            weight: a.data_weights.get(i).copied().unwrap_or(1.0),
            ..DataSource::train(root.clone())
        })
        .collect();
    for h in &a.holdout {
        let (root, seq) = h.split_once('/').with_context(|| {
            format!("--holdout {h:?} must look like ROOT/SEQUENCE (e.g. llff-6/room)")
        })?;
        let Some(src) = out.iter_mut().find(|s| s.name() == root) else {
            let names: Vec<String> = out.iter().map(DataSource::name).collect();
            bail!(
                "--holdout {h:?}: no --data root is named {root:?} (the roots are: {})",
                names.join(", ")
            );
        };
        src.holdout.push(seq.to_string());
    }
    for s in &out {
        if !(s.weight.is_finite() && s.weight > 0.0) {
            bail!(
                "--data-weight {} for {} must be a positive number",
                s.weight,
                s.root.display()
            );
        }
    }
    Ok(out)
}

/// The configuration of a new run from the options (each refused combination named).
fn new_config(a: &TrainArgs, sources: Vec<DataSource>) -> anyhow::Result<TrainConfig> {
    if let Some(at) = a.lr_drop_at
        && at >= a.phase1_steps
    {
        bail!(
            "--lr-drop-at {at} must be below --phase1-steps {}: the learning rate would never drop",
            a.phase1_steps
        );
    }
    let mut c = TrainConfig::for_normals(a.normals);
    c.stage1.unet.width = a.width;
    c.stage1.share_weights = !a.separate_weights;
    c.stage1.unet.halve_planes = a.stage1_halve_planes;
    c.stage1.unet.norm_groups = a.stage1_norm_groups;
    c.stage1.unet.colour_head = a.stage1_colour;
    if a.stage1_prototype_layout {
        c.stage1.unet.prototype_layout = true;
        c.stage1.unet.dilations.clear();
    }
    c.stage1.scale = a.stage1_scale as usize;
    c.blend.width = a.blend_width;
    c.blend.disagreement = a.blend_disagreement;
    if a.blend_consistency {
        if a.normals < 2 {
            bail!(
                "--blend-consistency weighs normals against each other: it needs --normals 2 or more"
            );
        }
        c.blend.consistency = Some(mhi_net::CONSISTENCY_BETA);
    }
    if a.stage1_consistent_loss {
        if a.normals < 2 {
            bail!(
                "--stage1-consistent-loss blends normals against each other: it needs --normals 2 or more"
            );
        }
        c.stage1_consistent_loss = Some(mhi_net::CONSISTENCY_BETA);
    }
    c.width = a.size.0;
    c.height = a.size.1;
    c.planes = a.planes;
    c.phase1_steps = a.phase1_steps;
    c.phase2_steps = a.phase2_steps;
    c.lr = a.lr;
    c.lr_drop_at = a.lr_drop_at;
    c.lr_drop_factor = a.lr_drop_factor;
    if a.prior != PriorArg::Sweep
        && (a.prior_window_radius.is_some()
            || a.prior_temperature.is_some()
            || a.prior_invalid_cost.is_some()
            || a.prior_clamp.is_some())
    {
        bail!(
            "--prior-window-radius, --prior-temperature, --prior-invalid-cost and --prior-clamp shape the sweep prior: they need --prior sweep"
        );
    }
    if a.stage1_colour && a.prior != PriorArg::Sweep {
        bail!(
            "--stage1-colour mixes each plane's colour by a residual head on the sweep prior: it needs --prior sweep"
        );
    }
    c.prior_clamp = a.prior_clamp;
    c.prior_window_radius = a.prior_window_radius;
    c.prior_temperature = a.prior_temperature;
    c.prior_invalid_cost = a.prior_invalid_cost;
    c.optimizer = c.optimizer.clone().with_epsilon(a.adam_epsilon);
    if a.no_grad_clip {
        c.optimizer = c.optimizer.clone().with_grad_clipping(None);
    }
    c.seed = a.seed;
    c.checkpoint_every = a.checkpoint_every;
    c.val_samples = a.val_samples;
    c.data = sources;
    c.extrapolation_share = a.extrapolation_share;
    c.triplet_sampling = match a.triplets {
        TripletsArg::Clips => mhi_data::TripletSampling::Clips,
        TripletsArg::Neighbours => {
            if a.extrapolation_share != mhi_data::PAPER_EXTRAPOLATION_SHARE {
                bail!(
                    "--extrapolation-share {} has no effect with --triplets neighbours: a neighbour triplet's kind follows from where its views lie",
                    a.extrapolation_share
                );
            }
            mhi_data::TripletSampling::Neighbours
        }
        TripletsArg::ByCapture => mhi_data::TripletSampling::ByCapture,
    };
    c.fit = match a.fit {
        FitArg::Stretch => mhi_data::Fit::Stretch,
        FitArg::Crop => mhi_data::Fit::CenterCrop,
    };
    if a.prior == PriorArg::Sweep {
        c = c.with_sweep_prior();
    }
    Ok(c)
}

/// The loss of a new run: --loss, with L1 + SSIM when the VGG16 weights are missing (said).
fn train_loss(
    a: &TrainArgs,
    weights: &std::path::Path,
    device: &burn::tensor::Device,
) -> anyhow::Result<TrainLoss> {
    Ok(match a.loss {
        LossArg::Photometric => TrainLoss::Photometric,
        LossArg::L1 => TrainLoss::L1,
        want => match TrainLoss::from_weights(Some(weights), a.perceptual_weight, device) {
            (l @ TrainLoss::Perceptual { .. }, _) => l,
            (l, why) => {
                let why = why.unwrap_or_default();
                if want == LossArg::Perceptual {
                    bail!("--loss perceptual: {why}");
                }
                eprintln!(
                    "note: VGG16 weights unavailable ({why}); training with L1 + SSIM instead (recorded in config.json). `cargo xtask weights` fetches them."
                );
                l
            }
        },
    })
}

/// Print what the run reached (and where it started) and write its summary.json.
fn report_run(
    a: &TrainArgs,
    trainer: &Trainer,
    scores: Option<&mhi_net::EvalScores>,
    untrained: Option<&mhi_net::EvalScores>,
) -> anyhow::Result<()> {
    let cfg = trainer.config();
    println!(
        "trained {} steps in {:.0} s ({} normals, {} planes, {}x{}, loss: {})",
        cfg.total_steps(),
        trainer.elapsed_s(),
        cfg.stage1.normals,
        cfg.planes,
        cfg.width,
        cfg.height,
        cfg.loss
    );
    let row = |label: &str, psnr: f64, lpips: Option<f64>| {
        let lpips = lpips.map_or("-".to_string(), |x| format!("{x:.4}"));
        println!("  {label:<30} {psnr:>8.2} {lpips:>8}");
    };
    if let Some(scores) = scores {
        println!(
            "validation scores over {} samples of {} (PSNR dB higher is better, LPIPS-alex lower is better):",
            a.eval_samples,
            trainer.validation_source()
        );
        println!("  {:<30} {:>8} {:>8}", "", "PSNR", "LPIPS");
        row("learned blend", scores.psnr_learned, scores.lpips_learned);
        row(
            "Soft heuristic, same stage 1",
            scores.psnr_soft,
            scores.lpips_soft,
        );
        if let Some(u) = untrained {
            row("untrained model (learned)", u.psnr_learned, u.lpips_learned);
            row("untrained model (Soft)", u.psnr_soft, u.lpips_soft);
        }
    } else {
        println!(
            "no closing evaluation (--eval-samples 0); the validation curve is in {}",
            mhi_net::RunDir::new(&a.run).val_path().display()
        );
    }
    let summary = serde_json::json!({
        "steps": cfg.total_steps(), "elapsed_s": trainer.elapsed_s(), "normals": cfg.stage1.normals, "planes": cfg.planes,
        "eval_samples": a.eval_samples, "trained": scores, "untrained": untrained, "loss": cfg.loss,
        "validation": trainer.validation_source(), "data": cfg.data,
    });
    mhi_data::write_atomic(
        &mhi_net::RunDir::new(&a.run).summary_path(),
        &serde_json::to_vec_pretty(&summary)?,
    )?;
    Ok(())
}

/// The options `--resume` takes besides the run itself; every other one sets the run's
/// configuration, which a resumed run keeps as its config.json says.
const RESUME_OPTIONS: [&str; 7] = [
    "run",
    "resume",
    "data",
    "time_budget",
    "backend",
    "cache",
    "eval_samples",
];

/// With `--resume`: refuse options that would change the run's configuration (they were
/// ignored in silence), and `--data` roots other than the run's own.
fn check_resume_options(a: &TrainArgs) -> anyhow::Result<()> {
    let dir = mhi_net::RunDir::new(&a.run);
    let config = dir.config_path();
    let fixed: Vec<String> = a
        .given
        .iter()
        .filter(|id| !RESUME_OPTIONS.contains(&id.as_str()))
        .map(|id| format!("--{}", id.replace('_', "-")))
        .collect();
    if !fixed.is_empty() {
        let (verb, them) = if fixed.len() == 1 {
            ("sets", "it")
        } else {
            ("set", "them")
        };
        bail!(
            "{} {verb} the run's configuration, which --resume keeps as {} says: drop {them} to continue the run (edit config.json to change a resumed run), or train with {them} in a new --run",
            fixed.join(", "),
            config.display(),
        );
    }
    if a.given.iter().any(|id| id == "data")
        && let Ok(c) = dir.config()
        && !c.data.is_empty()
    {
        let same = |p: &std::path::Path, q: &std::path::Path| {
            p == q || matches!((p.canonicalize(), q.canonicalize()), (Ok(x), Ok(y)) if x == y)
        };
        let recorded: Vec<&std::path::Path> = c.data.iter().map(|d| d.root.as_path()).collect();
        let matching =
            recorded.len() == a.data.len() && recorded.iter().zip(&a.data).all(|(r, d)| same(r, d));
        if !matching {
            bail!(
                "--data {}: the run trains on {} ({}); --resume keeps them: pass the same roots, or none",
                a.data
                    .iter()
                    .map(|d| d.display().to_string())
                    .collect::<Vec<_>>()
                    .join(" --data "),
                recorded
                    .iter()
                    .map(|d| d.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                config.display()
            );
        }
    }
    Ok(())
}

/// `cargo xtask train`.
pub fn train(a: &TrainArgs) -> anyhow::Result<()> {
    if a.data.len() == 1 && a.data[0] == std::path::Path::new("data/synth") {
        crate::common::ensure_synthetic(&a.data[0])?;
    }
    let sources = sources(a)?;
    let device = device(a.backend)?.autodiff();
    let weights = crate::common::cache_dir(a.cache.as_deref()).join("weights");
    let mut trainer = if a.resume {
        check_resume_options(a)?;
        Trainer::resume(&a.run, &a.data[0], Some(&weights), device)
            .with_context(|| {
                format!(
                    "--resume --run {} (a run without a checkpoint starts without --resume; `cargo xtask weights` fetches the VGG16 weights)",
                    a.run.display()
                )
            })?
    } else {
        // Only an existing run is answered with "--resume"; any other refusal (a size the
        // U-Nets cannot halve, a bad data source) names the run it was starting. Checked first, before the
        // VGG16 weights are loaded for the loss.
        if mhi_net::RunDir::new(&a.run).config_path().exists() {
            bail!(
                "--run {} already holds a training run: pass --resume to continue it, or choose another --run",
                a.run.display()
            );
        }
        let c = new_config(a, sources)?;
        let loss = train_loss(a, &weights, &device)?;
        match &a.stage1_from {
            Some(from) => Trainer::new_on_stage1(c, &a.run, &a.data[0], loss, device, from),
            None => Trainer::new(c, &a.run, &a.data[0], loss, device),
        }
        .with_context(|| format!("starting a training run in --run {}", a.run.display()))?
    };
    let cfg = trainer.config().clone();
    let lpips = mhi_net::backbone::Backbone::load(
        &weights,
        mhi_net::backbone::Net::Alex,
        &self::device(a.backend)?,
    )
    .ok();
    let untrained = if trainer.step_index() == 0 && a.eval_samples > 0 {
        Some(trainer.evaluate_scores(a.eval_samples, lpips.as_ref())?)
    } else {
        None
    };
    let pb = crate::progress::bar(cfg.total_steps() as u64, "training");
    pb.set_position(trainer.step_index() as u64);
    let mut psnr_avg = None::<f32>;
    let t0 = std::time::Instant::now();
    while !trainer.finished() {
        let r = trainer.step()?;
        psnr_avg = Some(psnr_avg.map_or(r.psnr, |p| 0.9 * p + 0.1 * r.psnr));
        pb.set_message(format!(
            "phase {} loss {:.4} PSNR {:.2}",
            r.phase,
            r.loss,
            psnr_avg.unwrap_or(0.0)
        ));
        pb.inc(1);
        if a.time_budget
            .is_some_and(|b| t0.elapsed().as_secs_f64() > b)
            && !trainer.finished()
        {
            trainer.checkpoint()?;
            pb.finish_and_clear();
            println!(
                "time budget reached at step {}; continue with --resume",
                trainer.step_index()
            );
            return Ok(());
        }
    }
    pb.finish_and_clear();
    // No closing evaluation with --eval-samples 0: a table of zeros would read as scores.
    let scores = if a.eval_samples > 0 {
        Some(trainer.evaluate_scores(a.eval_samples, lpips.as_ref())?)
    } else {
        None
    };
    report_run(a, &trainer, scores.as_ref(), untrained.as_ref())?;
    println!("run: {}", a.run.display());
    Ok(())
}
