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

fn write_random_alexnet(dir: &std::path::Path) {
    let mut state = 7u64;
    let buffers: Vec<(String, Vec<usize>, Vec<u8>)> = alexnet_shapes()
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
    std::fs::write(dir.join("alexnet.safetensors"), bytes).unwrap();
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

#[test]
fn missing_weights_say_how_to_get_them() {
    let d = tempfile::tempdir().unwrap();
    let err = Backbone::load(d.path(), Net::Vgg16, &Device::flex())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("vgg16.safetensors") && err.contains("cargo xtask weights"),
        "{err}"
    );
}
