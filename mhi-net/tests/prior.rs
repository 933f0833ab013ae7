//! The learned model on the sweep prior starts as the sweep: untrained, its alphas are the
//! sweep's, its blend weights Soft's and its render the sweep's Soft render (to 1e-5); training
//! moves it away from there.

use burn::tensor::Device;
use mhi_data::{SynthConfig, generate};
use mhi_geom::BlendHeuristic;
use mhi_net::loss::TrainLoss;
use mhi_net::{Model, Prior, TrainConfig, Trainer};
use mhi_render::{Blend, Prune, RenderOptions, SweepConfig, heuristic_weights, render, sweep_mhi};

fn config() -> TrainConfig {
    let mut c = TrainConfig::for_normals(3);
    c.stage1.unet.width = 4;
    c.stage1.unet.levels = 1;
    c.stage1.unet.dilations = vec![2];
    c.blend.width = 4;
    c.blend.levels = 1;
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

fn options(blend: Blend<'_>) -> RenderOptions<'_> {
    RenderOptions {
        blend,
        prune: Prune::NONE,
        keep_multi_normal: true,
    }
}

#[test]
fn an_untrained_model_on_the_sweep_prior_renders_the_sweep_with_soft() {
    let d = tempfile::tempdir().unwrap();
    generate(
        &SynthConfig {
            scenes: 2,
            frames: 6,
            width: 48,
            height: 48,
            seed: 3,
            test_fraction: 0.0,
            ..SynthConfig::default()
        },
        d.path(),
        &|| {},
    )
    .unwrap();
    let cfg = config();
    assert_eq!(cfg.prior, Prior::Sweep);
    let mut trainer = Trainer::new(
        cfg.clone(),
        &d.path().join("run"),
        d.path(),
        TrainLoss::Photometric,
        Device::flex().autodiff(),
    )
    .unwrap();
    let model = Model::untrained(cfg.clone(), Device::flex()).unwrap();
    let mut worst = 0.0_f32;
    for step in 0..3 {
        let s = trainer.sample(step).unwrap();
        let (rf, sf, tf) = (&s.reference, &s.source, &s.target);
        let sweep = sweep_mhi(
            model.normals(),
            model.depths(),
            &rf.camera,
            &rf.image,
            &sf.camera,
            &sf.image,
            &SweepConfig::for_short_side(32),
        )
        .unwrap();
        let alphas = model.alphas(model.stage1_input(rf, sf).unwrap()).unwrap();
        let da = alphas
            .iter()
            .zip(sweep.alpha())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            da <= 1e-5,
            "sample {step}: alphas differ from the sweep's by {da}"
        );
        let mhi = model.mhi(rf, alphas).unwrap();
        let soft = heuristic_weights(&mhi, &tf.camera, BlendHeuristic::Soft);
        let exact = render(
            &sweep,
            &tf.camera,
            &options(Blend::Heuristic(BlendHeuristic::Soft)),
        )
        .unwrap();
        let mni = render(&mhi, &tf.camera, &options(Blend::Weights(&soft))).unwrap();
        let learned = model.blend_weights(&mni.multi_normal, &soft).unwrap();
        let dw = learned
            .iter()
            .zip(&soft)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        assert!(
            dw <= 1e-5,
            "sample {step}: blend weights differ from Soft by {dw}"
        );
        let ours = render(&mhi, &tf.camera, &options(Blend::Weights(&learned))).unwrap();
        let di = ours
            .image
            .as_raw()
            .iter()
            .zip(exact.image.as_raw())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        worst = worst.max(di);
        assert!(
            di <= 1e-5,
            "sample {step}: render differs from the sweep's by {di}"
        );
    }
    eprintln!("largest difference from the sweep's Soft render: {worst:e}");
    // Training changes the model (the residual heads leave zero), and stays finite.
    while !trainer.finished() {
        let r = trainer.step().unwrap();
        assert!(r.loss.is_finite(), "{r:?}");
    }
    let trained = Model::load(&d.path().join("run"), Device::flex()).unwrap();
    let s = trainer.sample(0).unwrap();
    let a0 = model
        .alphas(model.stage1_input(&s.reference, &s.source).unwrap())
        .unwrap();
    let a1 = trained
        .alphas(trained.stage1_input(&s.reference, &s.source).unwrap())
        .unwrap();
    let moved = a0
        .iter()
        .zip(&a1)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(
        moved > 1e-3,
        "training left the alphas where the sweep put them ({moved})"
    );
}
