//! A colour head (`stage1.unet.colour_head`) gives every plane a colour of its own, mixed from
//! the reference towards the source warped onto that plane. Untrained it changes nothing (the
//! model renders the sweep); saturated, each plane shows the source where the source sees it
//! and the reference elsewhere; the CPU path of inference gives what training's tensors give;
//! training moves the colours; a checkpoint with a colour head does not load into a config
//! without one.

mod common;

use burn::tensor::{Device, Tensor, TensorData};
use common::{synthetic, tiny_prior_config, trainer};
use mhi_geom::{BlendHeuristic, NormalSet, depths_linear_in_disparity};
use mhi_net::loss::TrainLoss;
use mhi_net::{Model, TrainConfig, Trainer, stage1_input_with};
use mhi_render::{
    Blend, LayerColor, Prune, RenderOptions, SweepConfig, plane_sweep_volume, render, sweep_mhi,
};

fn config() -> TrainConfig {
    let mut c = tiny_prior_config();
    c.phase2_steps = 2;
    c.checkpoint_every = 4;
    c.stage1.unet.colour_head = true;
    c
}

/// Two scenes of six 48 × 48 frames.
fn two_scenes(seed: u64) -> tempfile::TempDir {
    synthetic(2, 6, (48, 48), seed)
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

#[test]
fn an_untrained_colour_head_renders_the_sweep() {
    let d = two_scenes(3);
    let cfg = config();
    let trainer = trainer(&cfg, d.path());
    let model = Model::untrained(cfg, Device::flex()).unwrap();
    for step in 0..2 {
        let s = trainer.sample(step).unwrap();
        let (rf, sf, tf) = (&s.reference, &s.source, &s.target);
        let (alphas, colours) = model.layers(model.stage1_input(rf, sf).unwrap()).unwrap();
        let colours = colours.expect("a colour head gives every layer a colour");
        assert_eq!(colours.len(), 3 * 6);
        for c in &colours {
            assert_eq!(
                c.as_raw(),
                rf.image.as_raw(),
                "an untrained layer's colour is not the reference's"
            );
        }
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
        let mhi = model.mhi_with(rf, alphas, Some(colours)).unwrap();
        assert!(matches!(mhi.color(), LayerColor::PerLayer(_)));
        let opts = RenderOptions {
            blend: Blend::Heuristic(BlendHeuristic::Soft),
            prune: Prune::NONE,
            keep_multi_normal: false,
        };
        let ours = render(&mhi, &tf.camera, &opts).unwrap();
        let exact = render(&sweep, &tf.camera, &opts).unwrap();
        let di = max_diff(ours.image.as_raw(), exact.image.as_raw());
        assert!(
            di <= 1e-5,
            "sample {step}: render differs from the sweep's by {di}"
        );
    }
}

/// With the colour logit saturated (bias 20, tanh = 1), every plane takes the source's warped
/// colour where the source sees it and keeps the reference's where it does not; and the CPU
/// path of inference (`apply_upsampled`) gives training's colours for any logits on blocks.
#[test]
fn a_saturated_colour_head_shows_the_source_and_inference_matches_training() {
    let d = two_scenes(5);
    let cfg = config();
    let s = trainer(&cfg, d.path()).sample(0).unwrap();
    let device = Device::flex();
    let (normals, depths) = (
        NormalSet::paper_subset(3).unwrap(),
        depths_linear_in_disparity(1.0, 100.0, 6).unwrap(),
    );
    let prior = cfg.prior_sweep(32, 32);
    let input = |block| {
        stage1_input_with(
            &normals,
            &depths,
            &s.reference,
            &s.source,
            prior.as_ref().map(|c| (c, cfg.prior_eps())),
            block,
            true,
            &device,
        )
        .unwrap()
    };
    let full = input(1);
    let sc = full.colour.clone().expect("asked for the source colour");
    let stage1 = cfg.stage1.init(&device).with_colour_bias(20.0);
    let out = stage1.forward_blocks(full.volume, full.size);
    assert_eq!(out.dims(), [3, 2, 6, 32, 32]);
    let m = out.narrow(1, 1, 1).reshape([18, 1, 32, 32]);
    let colours: Vec<f32> = sc.apply(m).into_data().try_to_vec().unwrap();
    let psv = plane_sweep_volume(
        &normals,
        &depths,
        &s.reference.camera,
        &s.source.image,
        &s.source.camera,
    )
    .unwrap();
    let (px, raw) = (32 * 32, s.reference.image.as_raw());
    let (mut seen, mut unseen) = (0, 0);
    for l in 0..18 {
        let (rgb, valid) = (psv.plane_rgb(l / 6, l % 6), psv.plane_valid(l / 6, l % 6));
        for p in 0..px {
            for c in 0..3 {
                let got = colours[(l * 3 + c) * px + p];
                let want = if valid[p] > 0.0 {
                    rgb[3 * p + c]
                } else {
                    raw[3 * p + c]
                };
                assert!(
                    (got - want).abs() <= 1e-5,
                    "layer {l} pixel {p} channel {c}: {got} against {want} (valid {})",
                    valid[p]
                );
            }
            if valid[p] > 0.0 {
                seen += 1
            } else {
                unseen += 1
            }
        }
    }
    assert!(seen > 1000 && unseen > 100, "seen {seen}, unseen {unseen}");

    // Logits on 4 × 4 blocks, brought to the full grid by training's tensors and by
    // inference's CPU pass.
    let (hs, ws) = (8, 8);
    let small: Vec<f32> = (0..18 * hs * ws)
        .map(|k| ((k * 7919 % 1000) as f32 / 250.0) - 2.0)
        .collect();
    let t = Tensor::<5>::from_data(TensorData::new(small.clone(), [3, 1, 6, hs, ws]), &device);
    use burn::tensor::module::interpolate;
    use burn::tensor::ops::{InterpolateMode, InterpolateOptions};
    let mut opts = InterpolateOptions::new(InterpolateMode::Bilinear);
    opts.output_size = Some([32, 32]);
    let up = interpolate(t.reshape([3, 6, hs, ws]), opts).reshape([18, 1, 32, 32]);
    let by_tensor: Vec<f32> = sc.apply(up).into_data().try_to_vec().unwrap();
    let by_cpu = sc.apply_upsampled(&small, (hs, ws));
    assert_eq!(by_cpu.len(), 18);
    let mut worst = 0.0_f32;
    for (l, img) in by_cpu.iter().enumerate() {
        for p in 0..px {
            for c in 0..3 {
                let a = img.as_raw()[3 * p + c];
                let b = by_tensor[(l * 3 + c) * px + p];
                worst = worst.max((a - b).abs());
            }
        }
    }
    assert!(
        worst <= 1e-5,
        "inference's colours differ from training's by {worst}"
    );
}

#[test]
fn training_moves_the_colours_and_the_checkpoint_needs_its_colour_head() {
    let d = two_scenes(7);
    let cfg = config();
    let mut t = trainer(&cfg, d.path());
    while !t.finished() {
        let r = t.step().unwrap();
        assert!(r.loss.is_finite(), "{r:?}");
    }
    let run = d.path().join("run");
    let trained = Model::load(&run, Device::flex()).unwrap();
    let s = t.sample(0).unwrap();
    let (_, colours) = trained
        .layers(trained.stage1_input(&s.reference, &s.source).unwrap())
        .unwrap();
    let moved = colours
        .unwrap()
        .iter()
        .map(|c| max_diff(c.as_raw(), s.reference.image.as_raw()))
        .fold(0.0, f32::max);
    assert!(
        moved > 1e-3,
        "training left every colour at the reference's ({moved})"
    );

    // The same checkpoint under a config without the colour head: a clear error.
    let path = run.join("config.json");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("\"colour_head\": true"), "{text}");
    std::fs::write(
        &path,
        text.replace("\"colour_head\": true", "\"colour_head\": false"),
    )
    .unwrap();
    let err = Model::load(&run, Device::flex())
        .err()
        .expect("a mismatched checkpoint loads");
    assert!(
        err.to_string()
            .contains("does not match this run's config.json"),
        "{err}"
    );
}

#[test]
fn a_colour_head_needs_the_sweep_prior() {
    let mut c = TrainConfig::for_normals(3);
    c.stage1.unet.colour_head = true;
    let d = two_scenes(9);
    let err = Trainer::new(
        c,
        &d.path().join("run"),
        d.path(),
        TrainLoss::Photometric,
        Device::flex().autodiff(),
    )
    .err()
    .expect("a colour head without the prior is accepted");
    assert!(err.to_string().contains("needs the sweep prior"), "{err}");
}
