//! Helpers shared by the integration tests of training, the sweep prior and the colour head:
//! tiny networks, a tiny model on the sweep prior, a synthetic training set in a temporary
//! folder, a trainer. (Each test binary uses a part of them.)
#![allow(dead_code)]

use burn::tensor::Device;
use mhi_data::{SynthConfig, generate};
use mhi_net::loss::TrainLoss;
use mhi_net::{TrainConfig, Trainer};

/// The default configuration for `normals` normals with networks of width 4 and one level.
pub fn tiny_networks(normals: usize) -> TrainConfig {
    let mut c = TrainConfig::for_normals(normals);
    c.stage1.unet.width = 4;
    c.stage1.unet.levels = 1;
    c.stage1.unet.dilations = vec![2];
    c.blend.width = 4;
    c.blend.levels = 1;
    c
}

/// A tiny N = 3, D = 6 model on the sweep prior at 32 × 32 (6 stage-1 and 4 blending steps).
pub fn tiny_prior_config() -> TrainConfig {
    let mut c = tiny_networks(3);
    c.width = 32;
    c.height = 32;
    c.planes = 6;
    c.lr = 5e-3;
    c.phase1_steps = 6;
    c.phase2_steps = 4;
    c.checkpoint_every = 5;
    c.val_samples = 0;
    c.with_sweep_prior()
}

/// A synthetic training set of `scenes` scenes of `frames` frames in a temporary folder.
pub fn synthetic(
    scenes: usize,
    frames: usize,
    (width, height): (u32, u32),
    seed: u64,
) -> tempfile::TempDir {
    let d = tempfile::tempdir().unwrap();
    generate(
        &SynthConfig {
            scenes,
            frames,
            width,
            height,
            seed,
            test_fraction: 0.0,
            ..SynthConfig::default()
        },
        d.path(),
        &|| {},
    )
    .unwrap();
    d
}

/// A trainer of `cfg` on the synthetic set in `dir` (its run in `dir/run`), with L1 + SSIM.
pub fn trainer(cfg: &TrainConfig, dir: &std::path::Path) -> Trainer {
    Trainer::new(
        cfg.clone(),
        &dir.join("run"),
        dir,
        TrainLoss::Photometric,
        Device::flex().autodiff(),
    )
    .unwrap()
}
