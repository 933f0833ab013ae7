//! A blending network that reads each normal's photo-inconsistency starts as the consistent
//! blend, trains on a stage 1 taken from another run, and cannot be run without the
//! inconsistency images.

mod common;

use burn::tensor::Device;
use common::{synthetic, tiny_prior_config, trainer};
use mhi_geom::BlendHeuristic;
use mhi_net::loss::TrainLoss;
use mhi_net::{Consistency, Model, Trainer, inconsistency, multi_normal};
use mhi_render::{Prune, consistent_weights, heuristic_weights};

#[test]
fn an_untrained_consistency_network_blends_as_the_consistent_heuristic() {
    let d = synthetic(2, 6, (48, 48), 5);
    let mut cfg = tiny_prior_config();
    cfg.stage1.unet.colour_head = true;
    cfg.blend.consistency = Some(mhi_net::CONSISTENCY_BETA);
    let t = trainer(&cfg, d.path());
    let model = Model::untrained(cfg.clone(), Device::flex()).unwrap();
    let s = t.sample(0).unwrap();
    let (rf, sf, tf) = (&s.reference, &s.source, &s.target);
    let (alphas, colours) = model.layers(model.stage1_input(rf, sf).unwrap()).unwrap();
    let mhi = model.mhi_with(rf, alphas, colours).unwrap();
    let mn = multi_normal(&mhi, &tf.camera, Prune::NONE).unwrap();
    let inc = inconsistency(&mhi, rf, sf, &tf.camera).unwrap();
    let soft = heuristic_weights(&mhi, &tf.camera, BlendHeuristic::Soft);
    let want = consistent_weights(&soft, &inc, mhi_net::CONSISTENCY_BETA).unwrap();
    let got = model.blend_weights(&mn.images, &soft, Some(&inc)).unwrap();
    let dw = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(
        dw <= 1e-5,
        "weights differ from the consistent blend's by {dw}"
    );
    // The photos disagree somewhere, so the consistent blend is not Soft.
    let from_soft = want
        .iter()
        .zip(&soft)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(from_soft > 1e-3, "{from_soft}");
    // Without the images the network refuses, and `Consistency` renders it whole.
    let err = model.blend_weights(&mn.images, &soft, None).unwrap_err();
    assert!(err.to_string().contains("photo-inconsistency"), "{err}");
    let c = Consistency::new(&mhi, rf, sf, mhi_net::CONSISTENCY_BETA).unwrap();
    let v = c
        .render_with(&mhi, Some(&model), &tf.camera, Prune::NONE)
        .unwrap();
    let dw = v
        .weights
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(dw <= 1e-5, "{dw}");
    assert!(Consistency::new(&mhi, rf, sf, -1.0).is_err());
}

#[test]
fn a_run_can_start_on_another_runs_stage_1_and_train_only_its_blend() {
    let d = synthetic(2, 6, (48, 48), 6);
    let mut cfg = tiny_prior_config();
    cfg.stage1.unet.colour_head = true;
    let mut first = trainer(&cfg, d.path());
    while !first.finished() {
        first.step().unwrap();
    }
    let from = d.path().join("run");
    let trained = Model::load(&from, Device::flex()).unwrap();
    let mut second = cfg.clone();
    second.blend.consistency = Some(mhi_net::CONSISTENCY_BETA);
    second.phase1_steps = 0;
    second.phase2_steps = 3;
    let dir = d.path().join("blend-only");
    let mut t = Trainer::new_on_stage1(
        second.clone(),
        &dir,
        d.path(),
        TrainLoss::Photometric,
        Device::flex().autodiff(),
        &from,
    )
    .unwrap();
    assert!(
        t.config()
            .stage1_from
            .as_deref()
            .unwrap()
            .contains("step 10")
    );
    while !t.finished() {
        let r = t.step().unwrap();
        assert_eq!(r.phase, 2);
        assert!(r.loss.is_finite());
    }
    // Its stage 1 is the first run's, untouched by blend-only training.
    let model = Model::load(&dir, Device::flex()).unwrap();
    let s = t.sample(0).unwrap();
    let a = |m: &Model| {
        m.alphas(m.stage1_input(&s.reference, &s.source).unwrap())
            .unwrap()
    };
    assert_eq!(a(&model), a(&trained));
    // A run whose stage 1 means something else cannot start on it.
    let mut other = second;
    other.planes = 4;
    let err = Trainer::new_on_stage1(
        other,
        &d.path().join("other"),
        d.path(),
        TrainLoss::Photometric,
        Device::flex().autodiff(),
        &from,
    )
    .err()
    .unwrap();
    assert!(err.to_string().contains("differs"), "{err}");
    assert!(!d.path().join("other").join("config.json").exists());
}

#[test]
fn stage_1_can_learn_from_its_consistent_blend() {
    let d = synthetic(2, 6, (48, 48), 7);
    let mut cfg = tiny_prior_config();
    cfg.stage1.unet.colour_head = true;
    cfg.phase1_steps = 2;
    cfg.phase2_steps = 0;
    let plain = cfg.clone();
    cfg.stage1_consistent_loss = Some(mhi_net::CONSISTENCY_BETA);
    let start = |c: &mhi_net::TrainConfig, name: &str| {
        Trainer::new(
            c.clone(),
            &d.path().join(name),
            d.path(),
            TrainLoss::Photometric,
            Device::flex().autodiff(),
        )
        .unwrap()
    };
    let (mut with, mut without) = (start(&cfg, "with"), start(&plain, "without"));
    // Same sample, same untrained weights: the loss differs only by its blended half.
    let (a, b) = (with.step().unwrap(), without.step().unwrap());
    assert!(a.loss.is_finite() && b.loss.is_finite());
    assert!(
        (a.loss - b.loss).abs() > 1e-6,
        "{} against {}",
        a.loss,
        b.loss
    );
    assert_eq!(a.psnr, b.psnr, "the logged PSNR is each normal's image's");
    // Recorded in config.json; bad settings refused before anything is written.
    let run = mhi_net::RunDir::new(d.path().join("with"));
    assert_eq!(
        run.config().unwrap().stage1_consistent_loss,
        Some(mhi_net::CONSISTENCY_BETA)
    );
    for (beta, normals) in [(-1.0, 3), (f32::NAN, 3), (20.0, 1)] {
        let mut bad = tiny_prior_config();
        bad.stage1_consistent_loss = Some(beta);
        if normals == 1 {
            bad = mhi_net::TrainConfig {
                stage1_consistent_loss: Some(beta),
                ..common::tiny_networks(1).with_sweep_prior()
            };
        }
        let dir = d.path().join(format!("bad-{normals}"));
        let err = Trainer::new(
            bad,
            &dir.join("run"),
            d.path(),
            TrainLoss::Photometric,
            Device::flex().autodiff(),
        )
        .err()
        .unwrap();
        assert!(err.to_string().contains("stage1_consistent_loss"), "{err}");
        assert!(!dir.join("run").join("config.json").exists());
    }
}
