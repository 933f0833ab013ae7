//! The learned model on the sweep prior starts as the sweep: untrained, its alphas are the
//! sweep's, its blend weights Soft's and its render the sweep's Soft render (to 1e-5); training
//! moves it away from there.

mod common;

use burn::tensor::Device;
use common::{synthetic, tiny_prior_config, trainer};
use mhi_geom::BlendHeuristic;
use mhi_net::{Model, Prior, TrainConfig};
use mhi_render::{Blend, Prune, RenderOptions, SweepConfig, heuristic_weights, render, sweep_mhi};

fn config() -> TrainConfig {
    tiny_prior_config()
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
    let d = synthetic(2, 6, (48, 48), 3);
    let cfg = config();
    assert_eq!(cfg.prior, Prior::Sweep);
    let mut trainer = trainer(&cfg, d.path());
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
        let learned = model.blend_weights(&mni.multi_normal, &soft, None).unwrap();
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

/// Stage 1's input averaged over pixel blocks on the CPU (what training and inference feed a
/// U-Net run on blocks) gives what the network gives when it averages the full-resolution
/// volume itself: same pooled volume, same alphas.
#[test]
fn the_block_averaged_volume_matches_stage_1s_own_pooling() {
    let d = synthetic(1, 3, (48, 32), 5);
    let mut cfg = config();
    cfg.width = 48;
    cfg.height = 32;
    let trainer = trainer(&cfg, d.path());
    let s = trainer.sample(0).unwrap();
    let device = Device::flex();
    let prior = cfg.prior_sweep(48, 32);
    let input = |block| {
        mhi_net::stage1_input(
            &mhi_geom::NormalSet::paper_subset(3).unwrap(),
            &mhi_geom::depths_linear_in_disparity(1.0, 100.0, 6).unwrap(),
            &s.reference,
            &s.source,
            prior.as_ref().map(|c| (c, cfg.prior_eps())),
            block,
            &device,
        )
        .unwrap()
    };
    let (full, pooled) = (input(1), input(4));
    assert_eq!(pooled.volume.dims(), [3, 7, 6, 8, 12]);
    assert_eq!(pooled.size, (32, 48));
    // Stage 1 with scale 4 on the full volume (it pools) and on the CPU-pooled one.
    // (An alpha head: a zero-initialised residual head would compare zeros.)
    let mut sc = cfg.stage1.clone();
    sc.scale = 4;
    sc.unet.residual = false;
    let stage1 = sc.init(&device);
    let a: Vec<f32> = stage1
        .forward(full.volume)
        .into_data()
        .try_to_vec()
        .unwrap();
    let b: Vec<f32> = stage1
        .forward_blocks(pooled.volume, pooled.size)
        .into_data()
        .try_to_vec()
        .unwrap();
    assert_eq!(a.len(), 3 * 6 * 32 * 48);
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0_f32, f32::max);
    assert!(worst <= 1e-5, "alphas differ by {worst}");
    // A side the block does not divide is an error, not a cropped volume.
    let err = mhi_net::stage1_input(
        &mhi_geom::NormalSet::paper_subset(3).unwrap(),
        &mhi_geom::depths_linear_in_disparity(1.0, 100.0, 6).unwrap(),
        &s.reference,
        &s.source,
        None,
        5,
        &device,
    )
    .unwrap_err();
    assert!(err.to_string().contains("divisible by 5"), "{err}");
}

/// `fit` decides how a training frame meets the run's size: stretched (the aspect of the
/// pixels changes, fx / fy with it) or its centred region of the run's aspect cropped (square
/// pixels stay square); both at the run's size, the camera following.
#[test]
fn training_frames_are_stretched_or_cropped_as_the_config_says() {
    let mut cfg = config();
    cfg.width = 48;
    cfg.height = 24;
    let ratio = |fit: mhi_data::Fit| {
        // A set of its own per fit: a run directory holds one run.
        let d = synthetic(1, 4, (48, 48), 5);
        let mut c = cfg.clone();
        c.fit = fit;
        let s = trainer(&c, d.path()).sample(0).unwrap();
        let cam = &s.reference.camera;
        assert_eq!((cam.width, cam.height), (48, 24));
        assert_eq!(s.reference.image.dimensions(), (48, 24));
        cam.intrinsics.fx / cam.intrinsics.fy
    };
    assert!((ratio(mhi_data::Fit::CenterCrop) - 1.0).abs() < 1e-9);
    assert!((ratio(mhi_data::Fit::Stretch) - 2.0).abs() < 1e-9);
}

/// `prior_clamp` moves where the sweep's alphas are clamped before their logit: an untrained
/// model still renders the sweep's alphas (the remainder is added back), but a residual of 1 on
/// a logit the sweep is sure of (alpha 0 or 1) moves that alpha by about `c (1 − c)` instead of
/// `1e-3`: what lets training change the alphas the sweep is sure of.
#[test]
fn the_prior_clamp_keeps_the_sweep_and_sets_how_far_a_residual_moves_sure_alphas() {
    let d = synthetic(1, 6, (48, 48), 3);
    let s = trainer(&config(), d.path()).sample(0).unwrap();
    let alphas_with = |clamp: Option<f32>| {
        let model = Model::untrained(config().with_prior_clamp(clamp), Device::flex()).unwrap();
        let input = model.stage1_input(&s.reference, &s.source).unwrap();
        let prior = input.prior.clone().expect("a model on the sweep prior");
        let (planes, h, w) = prior.shape;
        let one = burn::tensor::Tensor::<4>::ones([planes, 1, h, w], &Device::flex());
        let moved: Vec<f32> = prior.apply(one).into_data().try_to_vec().unwrap();
        (model.alphas(input).unwrap(), moved)
    };
    let (base, moved_base) = alphas_with(None);
    let (wide, moved_wide) = alphas_with(Some(0.05));
    let same = base
        .iter()
        .zip(&wide)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0_f32, f32::max);
    assert!(
        same <= 1e-5,
        "the untrained alphas moved with the clamp by {same}"
    );
    // The alphas the sweep put at (nearly) 0 (most of them: its softmax is peaked), raised by a
    // residual of 1.
    let rise = |moved: &[f32]| {
        let (mut sum, mut count) = (0.0_f64, 0_usize);
        for (a, m) in base.iter().zip(moved) {
            if *a <= 1e-4 {
                sum += f64::from(*m);
                count += 1;
            }
        }
        assert!(count > 100, "only {count} alphas near 0");
        sum / count as f64
    };
    let (r_base, r_wide) = (rise(&moved_base), rise(&moved_wide));
    assert!(
        r_base < 0.003,
        "clamp 1e-3: a residual of 1 raised a zero alpha by {r_base}"
    );
    assert!(
        (0.05..0.15).contains(&r_wide),
        "clamp 0.05: a residual of 1 raised a zero alpha by {r_wide}"
    );
}
