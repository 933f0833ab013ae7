//! `cargo xtask train`: the two-phase training of an MHI model (or, with `--normals 1`, of the
//! MPI baseline by the same code).

use std::path::PathBuf;

use anyhow::{Context, bail};
use burn::tensor::Device;
use clap::Args;
use mhi_net::{TrainConfig, Trainer};

/// Options of `cargo xtask train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Run directory: config.json, log.csv, checkpoints, summary.json.
    #[arg(long, default_value = "out/runs/mhi")]
    pub run: PathBuf,
    /// Dataset root in RealEstate10K layout (its train split is used); the default synthetic set
    /// is generated if missing.
    #[arg(long, default_value = "data/synth")]
    pub data: PathBuf,
    /// Continue the run in --run from its latest checkpoint (other options are read from its
    /// config.json).
    #[arg(long)]
    pub resume: bool,
    /// Number of normals: 1 (the MPI baseline), 2, 3 or 5.
    #[arg(long, default_value_t = 5)]
    pub normals: usize,
    /// Planes per normal.
    #[arg(long, default_value_t = 8)]
    pub planes: usize,
    /// Training resolution WIDTHxHEIGHT (divisible by 4).
    #[arg(long, default_value = "64x64", value_parser = crate::data::parse_size)]
    pub size: (u32, u32),
    /// Channels of the first level of the stage-1 3D U-Net.
    #[arg(long, default_value_t = 8)]
    pub width: usize,
    /// Channels of the first level of the blending U-Net.
    #[arg(long, default_value_t = 16)]
    pub blend_width: usize,
    /// Give every normal its own stage-1 network instead of sharing one.
    #[arg(long)]
    pub separate_weights: bool,
    /// Phase-1 steps (stage 1).
    #[arg(long, default_value_t = 300)]
    pub phase1_steps: usize,
    /// Phase-2 steps (blending network).
    #[arg(long, default_value_t = 150)]
    pub phase2_steps: usize,
    /// Stop (with a checkpoint) after this many seconds, whatever the step count; resume later.
    #[arg(long)]
    pub time_budget: Option<f64>,
    /// Learning rate (Adam).
    #[arg(long, default_value_t = 2e-4)]
    pub lr: f64,
    /// Seed of the weights and of the sampled triplets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Checkpoint every this many steps.
    #[arg(long, default_value_t = 50)]
    pub checkpoint_every: usize,
    /// Backend: flex (CPU, default) or wgpu (needs `--features wgpu`).
    #[arg(long, default_value = "flex")]
    pub backend: String,
    /// Validation samples for the closing comparison (learned vs Soft vs untrained).
    #[arg(long, default_value_t = 12)]
    pub eval_samples: usize,
}

pub fn device(backend: &str) -> anyhow::Result<Device> {
    match backend {
        "flex" => Ok(Device::flex()),
        other => bail!(
            "unknown or unavailable backend {other:?}: this build has flex (the wgpu backend is not wired in yet)"
        ),
    }
}

/// `cargo xtask train`.
pub fn train(a: &TrainArgs) -> anyhow::Result<()> {
    crate::experiments::ensure_synthetic(&a.data)?;
    let device = device(&a.backend)?.autodiff();
    let mut trainer = if a.resume {
        Trainer::resume(&a.run, &a.data, device)
            .with_context(|| format!("resuming {}", a.run.display()))?
    } else {
        let mut c = TrainConfig::for_normals(a.normals);
        c.stage1.unet.width = a.width;
        c.stage1.share_weights = !a.separate_weights;
        c.blend.width = a.blend_width;
        c.width = a.size.0;
        c.height = a.size.1;
        c.planes = a.planes;
        c.phase1_steps = a.phase1_steps;
        c.phase2_steps = a.phase2_steps;
        c.lr = a.lr;
        c.seed = a.seed;
        c.checkpoint_every = a.checkpoint_every;
        Trainer::new(c, &a.run, &a.data, device)
            .with_context(|| format!("starting {}", a.run.display()))?
    };
    let cfg = trainer.config().clone();
    let untrained = if trainer.step_index() == 0 {
        Some(trainer.evaluate(a.eval_samples)?)
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
    let (learned, soft) = trainer.evaluate(a.eval_samples)?;
    println!(
        "trained {} steps in {:.0} s ({} normals, {} planes, {}x{})",
        cfg.total_steps(),
        trainer.elapsed_s(),
        cfg.stage1.normals,
        cfg.planes,
        cfg.width,
        cfg.height
    );
    println!("validation PSNR over {} held-out samples:", a.eval_samples);
    println!("  learned blend:           {learned:.2} dB");
    println!("  Soft heuristic, stage 1: {soft:.2} dB");
    if let Some((u_learned, u_soft)) = untrained {
        println!("  untrained model:         {u_learned:.2} dB (Soft {u_soft:.2} dB)");
    }
    let summary = serde_json::json!({
        "steps": cfg.total_steps(), "elapsed_s": trainer.elapsed_s(), "normals": cfg.stage1.normals, "planes": cfg.planes,
        "eval_samples": a.eval_samples, "psnr_learned": learned, "psnr_soft": soft,
        "psnr_untrained": untrained.map(|u| u.0), "loss": cfg.loss,
    });
    mhi_data::write_atomic(
        &a.run.join("summary.json"),
        &serde_json::to_vec_pretty(&summary)?,
    )?;
    println!("run: {}", a.run.display());
    Ok(())
}
