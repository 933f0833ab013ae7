//! Training on a tiny configuration: the loss decreases, nothing becomes NaN, and a run resumed
//! from a checkpoint ends exactly where an uninterrupted run ends.

mod common;

use burn::tensor::{Device, Tensor};
use mhi_net::loss::TrainLoss;
use mhi_net::{TrainConfig, Trainer};

/// Two synthetic scenes of six 48 × 48 frames in a temporary folder.
fn data() -> tempfile::TempDir {
    common::synthetic(2, 6, (48, 48), 1)
}

fn tiny(steps1: usize, steps2: usize) -> TrainConfig {
    let mut c = common::tiny_networks(2);
    c.width = 16;
    c.height = 16;
    c.planes = 4;
    c.lr = 2e-3;
    c.phase1_steps = steps1;
    c.phase2_steps = steps2;
    c.checkpoint_every = 3;
    c
}

/// The networks' outputs on a fixed input: equal outputs mean equal weights here.
fn outputs(t: &Trainer) -> Vec<f32> {
    let device = Device::flex().autodiff();
    let x: Tensor<5> = Tensor::ones([2, 6, 4, 16, 16], &device) * 0.3;
    let mut v: Vec<f32> = t.stage1().forward(x).into_data().try_to_vec().unwrap();
    let y: Tensor<4> = Tensor::ones([1, 8, 16, 16], &device) * 0.3;
    v.extend(
        t.blend_net()
            .forward(y)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap(),
    );
    v
}

#[test]
fn loss_decreases_and_stays_finite() {
    let d = data();
    let mut config = tiny(30, 10);
    config.lr = 5e-3;
    let mut t = Trainer::new(
        config,
        &d.path().join("run"),
        d.path(),
        TrainLoss::Photometric,
        Device::flex().autodiff(),
    )
    .unwrap();
    // The loss on the first training samples, before and after training on them.
    let probe = |t: &Trainer| (0..6).map(|s| t.phase1_loss(s).unwrap()).sum::<f32>() / 6.0;
    let before = probe(&t);
    while !t.finished() {
        let r = t.step().unwrap();
        assert!(r.loss.is_finite() && r.psnr.is_finite(), "{r:?}");
    }
    let after = probe(&t);
    eprintln!("phase-1 loss on 6 training samples: {before:.4} before, {after:.4} after 30 steps");
    assert!(
        after < 0.95 * before,
        "loss did not decrease: {before} → {after}"
    );
    let log = std::fs::read_to_string(d.path().join("run/log.csv")).unwrap();
    assert_eq!(log.lines().count(), 41);
}

#[test]
fn resume_continues_exactly() {
    let d = data();
    let device = Device::flex().autodiff();
    // Uninterrupted: 6 steps.
    let mut a = Trainer::new(
        tiny(4, 2),
        &d.path().join("a"),
        d.path(),
        TrainLoss::Photometric,
        device.clone(),
    )
    .unwrap();
    while !a.finished() {
        a.step().unwrap();
    }
    // Interrupted after step 4 (checkpoint at 3): the trainer is dropped mid-run.
    let mut b = Trainer::new(
        tiny(4, 2),
        &d.path().join("b"),
        d.path(),
        TrainLoss::Photometric,
        device.clone(),
    )
    .unwrap();
    for _ in 0..4 {
        b.step().unwrap();
    }
    drop(b);
    let mut b = Trainer::resume(&d.path().join("b"), d.path(), None, device.clone()).unwrap();
    assert_eq!(b.step_index(), 3, "resumes from the last checkpoint");
    while !b.finished() {
        b.step().unwrap();
    }
    let (oa, ob) = (outputs(&a), outputs(&b));
    let diff = oa
        .iter()
        .zip(&ob)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert!(
        diff == 0.0,
        "resumed run differs from the uninterrupted one by {diff}"
    );
    let log = std::fs::read_to_string(d.path().join("b/log.csv")).unwrap();
    let steps: Vec<&str> = log
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(steps, ["0", "1", "2", "3", "4", "5"]);
    // A run directory is never silently reused, and a checkpoint of another size is refused.
    assert!(
        Trainer::new(
            tiny(4, 2),
            &d.path().join("a"),
            d.path(),
            TrainLoss::Photometric,
            device.clone()
        )
        .is_err()
    );
    let cfg = d.path().join("b/config.json");
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("\"width\": 4", "\"width\": 8");
    std::fs::write(&cfg, text).unwrap();
    // One trainer per run folder: the resumed one lets go of it first.
    drop(b);
    let err = Trainer::resume(&d.path().join("b"), d.path(), None, device)
        .err()
        .expect("mismatched checkpoint");
    assert!(
        err.to_string()
            .contains("does not match this run's config.json"),
        "{err}"
    );
}

#[test]
fn initial_weights_depend_on_the_seed_alone_and_checkpoints_round_trip() {
    let d = data();
    let device = Device::flex().autodiff();
    let a = Trainer::new(
        tiny(4, 2),
        &d.path().join("a"),
        d.path(),
        TrainLoss::Photometric,
        device.clone(),
    )
    .unwrap();
    let b = Trainer::new(
        tiny(4, 2),
        &d.path().join("b"),
        d.path(),
        TrainLoss::Photometric,
        device.clone(),
    )
    .unwrap();
    let (oa, ob) = (outputs(&a), outputs(&b));
    let diff = oa
        .iter()
        .zip(&ob)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert_eq!(
        diff, 0.0,
        "two runs with one seed start from different weights"
    );
    let mut a = a;
    a.checkpoint().unwrap();
    // A second trainer on a run folder in use is refused, naming the first's process.
    let busy = Trainer::resume(&d.path().join("a"), d.path(), None, device.clone())
        .err()
        .expect("a second writer");
    assert!(
        busy.to_string()
            .contains(&format!("process {} is writing", std::process::id())),
        "{busy}"
    );
    drop(a);
    let c = Trainer::resume(&d.path().join("a"), d.path(), None, device.clone()).unwrap();
    let oc = outputs(&c);
    let diff = oa
        .iter()
        .zip(&oc)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert_eq!(diff, 0.0, "a checkpoint does not restore the weights");
}

/// Stiff settings: 200 steps at lr 1e-2 with every alpha starting saturated (head bias 12, α ≈
/// 0.999994) and every fifth step a target camera sitting exactly on the nearest fronto plane.
/// Guards that keep it finite: gradient clipping to norm 1 (checked below), the SSIM constants
/// C1, C2 > 0, the plane-visibility mask of the warp, and the loss check that refuses to step on a
/// non-finite loss.
#[test]
fn stiff_training_stays_finite() {
    let d = data();
    let mut config = tiny(160, 40);
    config.lr = 1e-2;
    config.checkpoint_every = 1000;
    let device = Device::flex().autodiff();
    assert!(
        format!("{:?}", config.optimizer).contains("Norm(1.0)"),
        "gradient clipping is off: {:?}",
        config.optimizer
    );
    let mut t = Trainer::new(
        config,
        &d.path().join("run"),
        d.path(),
        TrainLoss::Photometric,
        device,
    )
    .unwrap();
    let saturated = t.stage1().clone().with_head_bias(12.0);
    t.set_stage1(saturated);
    let mut losses = Vec::new();
    while !t.finished() {
        let k = t.step_index();
        let start = std::time::Instant::now();
        let r = if k % 5 == 4 {
            let mut s = t.sample(k).unwrap();
            // Target centre on the nearest fronto plane (depth `near` in the reference frame).
            let ref_pose = s.reference.camera.cam_from_world;
            let on_plane = mhi_geom::RigidTransform::new(
                glam::DMat3::IDENTITY,
                glam::DVec3::new(0.0, 0.0, -1.0),
            )
            .unwrap();
            s.target.camera.cam_from_world = on_plane.compose(&ref_pose);
            t.step_with(s, start).unwrap()
        } else {
            t.step().unwrap()
        };
        assert!(r.loss.is_finite() && r.psnr.is_finite(), "step {k}: {r:?}");
        losses.push(r.loss);
    }
    assert_eq!(losses.len(), 200);
    let out = outputs(&t);
    assert!(
        out.iter().all(|v| v.is_finite()),
        "weights became non-finite"
    );
}

/// A run trained with L1 alone records it and resumes with it: the resumed run ends exactly
/// where the uninterrupted L1 run ends (resuming with L1 + SSIM would not).
#[test]
fn an_l1_run_resumes_with_l1() {
    let d = data();
    let device = Device::flex().autodiff();
    let run = |name: &str, steps: Option<usize>| {
        let mut t = Trainer::new(
            tiny(4, 2),
            &d.path().join(name),
            d.path(),
            TrainLoss::L1,
            device.clone(),
        )
        .unwrap();
        for _ in 0..steps.unwrap_or(usize::MAX) {
            if t.finished() {
                break;
            }
            t.step().unwrap();
        }
        t
    };
    let a = run("a", None);
    drop(run("b", Some(4)));
    let config = std::fs::read_to_string(d.path().join("b/config.json")).unwrap();
    assert!(config.contains("\"loss_kind\": \"L1\""), "{config}");
    let mut b = Trainer::resume(&d.path().join("b"), d.path(), None, device.clone()).unwrap();
    assert_eq!(b.step_index(), 3, "resumes from the last checkpoint");
    while !b.finished() {
        b.step().unwrap();
    }
    let diff = outputs(&a)
        .iter()
        .zip(&outputs(&b))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max);
    assert!(
        diff == 0.0,
        "resumed L1 run differs from the uninterrupted one by {diff}"
    );
}

/// Stage 1 trains at the dropped learning rate from `lr_drop_at` on: runs with and without the
/// drop agree up to it and part after it, and a drop by a factor of 1 changes nothing.
#[test]
fn the_learning_rate_drop_changes_the_steps_after_it_only() {
    let d = data();
    let device = Device::flex().autodiff();
    let run = |name: &str, drop: Option<(usize, f64)>, steps: usize| {
        let mut c = tiny(4, 0);
        if let Some((at, factor)) = drop {
            c.lr_drop_at = Some(at);
            c.lr_drop_factor = factor;
        }
        let mut t = Trainer::new(
            c,
            &d.path().join(name),
            d.path(),
            TrainLoss::Photometric,
            device.clone(),
        )
        .unwrap();
        for _ in 0..steps {
            t.step().unwrap();
        }
        outputs(&t)
    };
    let max_diff = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0_f32, f32::max)
    };
    let (plain2, dropped2) = (run("a2", None, 2), run("b2", Some((2, 0.1)), 2));
    assert_eq!(max_diff(&plain2, &dropped2), 0.0, "before the drop");
    let (plain4, dropped4) = (run("a4", None, 4), run("b4", Some((2, 0.1)), 4));
    assert!(
        max_diff(&plain4, &dropped4) > 1e-6,
        "the drop did not change the steps after it"
    );
    assert_eq!(max_diff(&plain4, &run("c4", Some((2, 1.0)), 4)), 0.0);
}

/// A run folder tampered with: a `latest.json` that points outside the run is not followed, and
/// a `config.json` with absurd sizes is refused before anything is allocated.
#[test]
fn tampered_run_files_are_refused() {
    let d = data();
    let device = Device::flex().autodiff();
    let run = d.path().join("run");
    let mut t = Trainer::new(tiny(4, 2), &run, d.path(), TrainLoss::Photometric, device).unwrap();
    t.checkpoint().unwrap();
    drop(t);
    let load = || {
        mhi_net::Model::load(&run, Device::flex())
            .err()
            .expect("a tampered run loads")
            .to_string()
    };
    let latest = run.join("latest.json");
    let good = std::fs::read_to_string(&latest).unwrap();
    std::fs::write(&latest, r#"{"step": 0, "dir": "../elsewhere"}"#).unwrap();
    let err = load();
    assert!(err.contains("refusing to follow"), "{err}");
    std::fs::write(&latest, good).unwrap();
    let cfg = run.join("config.json");
    let text = std::fs::read_to_string(&cfg).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let width = v["stage1"]["unet"]["width"].as_u64().unwrap();
    std::fs::write(
        &cfg,
        text.replacen(
            &format!("\"width\": {width},\n      \"levels\""),
            "\"width\": 100000000,\n      \"levels\"",
            1,
        ),
    )
    .unwrap();
    let err = load();
    assert!(err.contains("stage1.unet.width = 100000000"), "{err}");
}
