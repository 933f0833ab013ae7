//! The backbone loader and LPIPS on weights of the real shapes with random values (the real
//! weights need the network; `.ci/run` checks them against the official LPIPS values).

use std::collections::HashMap;

use burn::tensor::{Device, Tensor};
use mhi_net::backbone::{Backbone, Net};
use safetensors::tensor::{Dtype, TensorView};

fn alexnet_shapes() -> Vec<(String, Vec<usize>)> {
    let convs = [
        (11, 3, 64),
        (5, 64, 192),
        (3, 192, 384),
        (3, 384, 256),
        (3, 256, 256),
    ];
    let mut v = Vec::new();
    for (i, (k, ci, co)) in convs.iter().enumerate() {
        v.push((format!("AlexNet_0/Conv_{i}/kernel"), vec![*k, *k, *ci, *co]));
        v.push((format!("AlexNet_0/Conv_{i}/bias"), vec![*co]));
        v.push((format!("NetLinLayer_{i}/Conv_0/kernel"), vec![1, 1, *co, 1]));
    }
    v
}

fn vgg16_shapes() -> Vec<(String, Vec<usize>)> {
    let cfg = [
        (3, 64),
        (64, 64),
        (64, 128),
        (128, 128),
        (128, 256),
        (256, 256),
        (256, 256),
        (256, 512),
        (512, 512),
        (512, 512),
        (512, 512),
        (512, 512),
        (512, 512),
    ];
    let mut v = Vec::new();
    for (i, (ci, co)) in cfg.iter().enumerate() {
        v.push((format!("VGG16_0/Conv_{i}/kernel"), vec![3, 3, *ci, *co]));
        v.push((format!("VGG16_0/Conv_{i}/bias"), vec![*co]));
    }
    for (i, c) in [64, 128, 256, 512, 512].iter().enumerate() {
        v.push((format!("NetLinLayer_{i}/Conv_0/kernel"), vec![1, 1, *c, 1]));
    }
    v
}

fn write_random_alexnet(dir: &std::path::Path) {
    write_random(dir, alexnet_shapes(), "alexnet.safetensors");
}

fn write_random(dir: &std::path::Path, shapes: Vec<(String, Vec<usize>)>, file: &str) {
    let mut state = 7u64;
    let buffers: Vec<(String, Vec<usize>, Vec<u8>)> = shapes
        .into_iter()
        .map(|(name, shape)| {
            let n: usize = shape.iter().product();
            let lin = name.starts_with("NetLin");
            let bytes = (0..n)
                .flat_map(|_| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let u = (state >> 40) as f32 / (1u64 << 24) as f32;
                    let v = if lin { u * 0.1 } else { (u - 0.5) * 0.05 };
                    v.to_le_bytes()
                })
                .collect();
            (name, shape, bytes)
        })
        .collect();
    let views: Vec<(String, TensorView<'_>)> = buffers
        .iter()
        .map(|(n, s, b)| {
            (
                n.clone(),
                TensorView::new(Dtype::F32, s.clone(), b).unwrap(),
            )
        })
        .collect();
    let bytes = safetensors::tensor::serialize(views, None::<HashMap<String, String>>).unwrap();
    std::fs::write(dir.join(file), bytes).unwrap();
}

#[test]
fn lpips_is_zero_on_equal_images_positive_otherwise() {
    let d = tempfile::tempdir().unwrap();
    write_random_alexnet(d.path());
    let device = Device::flex();
    let net = Backbone::load(d.path(), Net::Alex, &device).unwrap();
    let a: Tensor<4> = Tensor::ones([1, 3, 64, 64], &device) * 0.3;
    let b: Tensor<4> = Tensor::random(
        [1, 3, 64, 64],
        burn::tensor::Distribution::Uniform(0.0, 1.0),
        &device,
    );
    let same: Vec<f32> = net
        .lpips(b.clone(), b.clone())
        .into_data()
        .try_to_vec()
        .unwrap();
    let diff: Vec<f32> = net
        .lpips(a.clone(), b.clone())
        .into_data()
        .try_to_vec()
        .unwrap();
    let rev: Vec<f32> = net.lpips(b, a).into_data().try_to_vec().unwrap();
    assert!(same[0].abs() < 1e-6, "{}", same[0]);
    assert!(diff[0] > 0.0 && diff[0].is_finite(), "{}", diff[0]);
    assert!(
        (diff[0] - rev[0]).abs() < 1e-5,
        "not symmetric: {} vs {}",
        diff[0],
        rev[0]
    );
    let feats = net.features(Tensor::zeros([1, 3, 64, 64], &device));
    let dims: Vec<[usize; 4]> = feats.iter().map(|f| f.dims()).collect();
    assert_eq!(
        dims,
        vec![
            [1, 64, 15, 15],
            [1, 192, 7, 7],
            [1, 384, 3, 3],
            [1, 256, 3, 3],
            [1, 256, 3, 3]
        ]
    );
}

/// Missing weights: the error names the file and says what is missing, and no command line
/// (the CLI adds how to fetch them: `metrics_without_weights_say_how_to_get_them` in xtask).
#[test]
fn missing_weights_name_the_file() {
    let d = tempfile::tempdir().unwrap();
    let err = Backbone::load(d.path(), Net::Vgg16, &Device::flex())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("vgg16.safetensors") && err.contains("pretrained weights"),
        "{err}"
    );
    assert!(!err.contains("cargo xtask"), "{err}");
}

/// The perceptual loss on VGG16 weights of the real shapes (random values): the five taps have
/// the documented shapes, the loss is zero on equal images and positive otherwise, one target is
/// compared with every output of a batch, the gradient is finite, and `TrainLoss` picks the
/// perceptual loss when the file is there and says why not when it is not.
#[test]
fn perceptual_loss_on_vgg16_taps() {
    use mhi_net::loss::{PERCEPTUAL_SUFFIX, TrainLoss, perceptual};
    let d = tempfile::tempdir().unwrap();
    write_random(d.path(), vgg16_shapes(), "vgg16.safetensors");
    let device = Device::flex().autodiff();
    let net = Backbone::load(d.path(), Net::Vgg16, &device).unwrap();
    let feats = net
        .perceptual_features(Tensor::zeros([1, 3, 32, 32], &device))
        .unwrap();
    let dims: Vec<[usize; 4]> = feats.iter().map(|f| f.dims()).collect();
    assert_eq!(
        dims,
        vec![
            [1, 64, 32, 32],
            [1, 128, 16, 16],
            [1, 256, 8, 8],
            [1, 512, 4, 4],
            [1, 512, 2, 2]
        ]
    );
    let target: Tensor<4> = Tensor::random(
        [1, 3, 32, 32],
        burn::tensor::Distribution::Uniform(0.0, 1.0),
        &device,
    );
    let value = |t: Tensor<1>| t.into_data().try_to_vec::<f32>().unwrap()[0];
    let same = value(
        perceptual(
            &net,
            target.clone().expand([3, 3, 32, 32]),
            target.clone(),
            0.226,
        )
        .unwrap(),
    );
    assert!(same.abs() < 1e-6, "{same}");
    let out: Tensor<4> = (Tensor::ones([3, 3, 32, 32], &device) * 0.5).require_grad();
    let loss = perceptual(&net, out.clone(), target.clone(), 0.226).unwrap();
    let l = value(loss.clone());
    assert!(l > 0.0 && l.is_finite(), "{l}");
    let g: Vec<f32> = out
        .grad(&loss.backward())
        .unwrap()
        .into_data()
        .try_to_vec()
        .unwrap();
    assert!(g.iter().all(|x| x.is_finite()) && g.iter().any(|x| *x != 0.0));
    let (chosen, why) = TrainLoss::from_weights(Some(d.path()), 0.226, &device);
    assert!(chosen.name().ends_with(PERCEPTUAL_SUFFIX));
    assert!(why.is_none());
    let empty = tempfile::tempdir().unwrap();
    let (chosen, why) = TrainLoss::from_weights(Some(empty.path()), 0.226, &device);
    assert!(matches!(chosen, TrainLoss::Photometric));
    assert!(why.unwrap().contains("vgg16.safetensors"));
    // AlexNet has no perceptual taps: a clear error, not a panic.
    write_random_alexnet(d.path());
    let alex = Backbone::load(d.path(), Net::Alex, &device).unwrap();
    assert!(perceptual(&alex, target.clone(), target, 0.226).is_err());
}
