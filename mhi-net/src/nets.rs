//! The two networks: a 3D U-Net per normal over the oriented cost volume (stage 1) and a 2D
//! U-Net that predicts per-pixel blending weights of the multi-normal images (stage 2).

use burn::config::Config;
use burn::module::Module;
use burn::nn::conv::{
    Conv2d, Conv2dConfig, Conv3d, Conv3dConfig, ConvTranspose2d, ConvTranspose2dConfig,
    ConvTranspose3d, ConvTranspose3dConfig,
};
use burn::nn::{LayerNorm, LayerNormConfig, PaddingConfig2d, PaddingConfig3d};
use burn::tensor::activation::{relu, sigmoid, softmax};
use burn::tensor::{Device, Tensor};

/// Size of a 3D U-Net.
#[derive(Config, Debug)]
pub struct UNet3dConfig {
    /// Input channels per plane (reference RGB and warped source RGB).
    #[config(default = 6)]
    pub in_channels: usize,
    /// Channels of the first level; each level doubles them.
    #[config(default = 8)]
    pub width: usize,
    /// Number of times the image is halved (the plane axis keeps its size). Images must be
    /// divisible by `2^levels`.
    #[config(default = 2)]
    pub levels: usize,
    /// Dilations of the residual convolutions at the bottom (in the image axes).
    #[config(default = "vec![1, 2, 4]")]
    pub dilations: Vec<usize>,
    /// Residual head: the last convolution starts at zero and its output is returned as is (a
    /// correction of a prior's alpha logits) instead of through a sigmoid.
    #[config(default = false)]
    pub residual: bool,
    /// The encoder halves the plane axis too (stride 2 in depth, as the PyTorch prototype's
    /// U-Net does), so the bottom level sees `2^levels` planes per voxel and the network
    /// compares planes far apart; the plane count must then be divisible by `2^levels`.
    /// Off: only the image axes are halved (the plane axis keeps its size).
    #[config(default = false)]
    pub halve_planes: bool,
    /// How each convolution's output is normalised: 0, over its channels at every voxel (a
    /// layer norm); G > 0, as a group norm over groups of channels, each over the whole volume
    /// (the PyTorch prototype's `GroupNorm(min(4, C), C)`), which keeps how strong a voxel's
    /// response is against the rest of the volume. A convolution with C channels uses the
    /// largest divisor of C up to G groups (`min(G, C)` for the widths 8, 16, 32). Same
    /// parameters either way.
    #[config(default = 0)]
    pub norm_groups: usize,
    /// The PyTorch prototype's layout: two convolutions per level (the stem and every
    /// downsampling convolution are followed by a second one), no residual bottom beyond
    /// `dilations` (set them empty for the prototype's), each decoder level upsampling by
    /// linear interpolation (trilinear with `halve_planes`, half-pixel centres, edges
    /// repeated, as PyTorch's `interpolate(align_corners=False)`) before its convolution
    /// instead of through a transposed convolution, and a 3 × 3 × 3 head instead of 1 × 1 × 1.
    /// Off: one convolution per level, transposed-convolution upsampling, 1 × 1 × 1 head.
    #[config(default = false)]
    pub prototype_layout: bool,
    /// A second output channel per plane (residual heads only, zero-initialised like the
    /// first): the logit of how far each plane's colour moves from the reference's towards
    /// the source's warped onto that plane (see [`crate::SourceColour`]). Off: every plane
    /// takes the reference's colour.
    #[config(default = false)]
    pub colour_head: bool,
}

/// A 3 × k × k convolution of `[B, C, D, H, W]` with zero padding 1 on the plane axis, and
/// stride, dilation and padding only in the image axes, computed as one 2D convolution over the
/// `B·D` planes whose input stacks each plane with its two neighbours (`3C` channels). The
/// same sums as `conv3d`, through burn's 2D kernel.
///
/// # Shapes
/// `x [B, C, D, H, W]`, `weight [Cout, C, 3, k, k]`, `bias [Cout]` →
/// `[B, Cout, D, H', W']`
pub fn conv3d_planes_as_2d(
    x: Tensor<5>,
    weight: Tensor<5>,
    bias: Option<Tensor<1>>,
    stride: usize,
    dilation: usize,
    padding: usize,
) -> Tensor<5> {
    use burn::tensor::module::conv2d;
    use burn::tensor::ops::ConvOptions;
    let [b, c, d, h, w] = x.dims();
    let [cout, _, kd, kh, kw] = weight.dims();
    debug_assert_eq!(kd, 3, "three planes per kernel");
    let zeros = Tensor::zeros([b, c, 1, h, w], &x.device());
    let padded = Tensor::cat(vec![zeros.clone(), x, zeros], 2);
    // Channel k·C + c of plane z is channel c of plane z + k − 1.
    let stacked = Tensor::cat((0..3).map(|k| padded.clone().narrow(2, k, d)).collect(), 1);
    let planes = stacked
        .permute([0, 2, 1, 3, 4])
        .reshape([b * d, 3 * c, h, w]);
    let w2 = weight
        .permute([0, 2, 1, 3, 4])
        .reshape([cout, 3 * c, kh, kw]);
    let y = conv2d(
        planes,
        w2,
        bias,
        ConvOptions::new(
            [stride, stride],
            [padding, padding],
            [dilation, dilation],
            1,
        ),
    );
    let [_, _, ho, wo] = y.dims();
    y.reshape([b, d, cout, ho, wo]).permute([0, 2, 1, 3, 4])
}

/// The layer norms' epsilon (burn's default, named: the module keeps its own private).
const NORM_EPSILON: f64 = 1e-5;

/// Convolution, normalisation (over channels, or in groups over the volume), ReLU.
#[derive(Module, Debug)]
pub struct Block3d {
    conv: Conv3d,
    norm: LayerNorm,
    /// 0: layer norm over channels; else the number of channel groups of a group norm.
    groups: usize,
}

/// Group normalisation of `x` (`[B, C, D, H, W]`) over `groups` groups of channels, each over
/// the whole volume (biased variance, as PyTorch's `GroupNorm`), then `norm`'s per-channel
/// scale and shift. `C` must be divisible by `groups`.
fn group_norm(norm: &LayerNorm, groups: usize, x: Tensor<5>) -> Tensor<5> {
    let [b, c, d, h, w] = x.dims();
    let g = x.reshape([b, groups, (c / groups) * d * h * w]);
    let centred = g.clone() - g.mean_dim(2);
    let var = centred.clone().square().mean_dim(2);
    let y = (centred / (var + NORM_EPSILON).sqrt()).reshape([b, c, d, h, w]);
    let y = y * norm.gamma.val().reshape([1, c, 1, 1, 1]);
    match &norm.beta {
        Some(beta) => y + beta.val().reshape([1, c, 1, 1, 1]),
        None => y,
    }
}

impl Block3d {
    fn new(
        cin: usize,
        cout: usize,
        stride: [usize; 3],
        dilation: usize,
        groups: usize,
        device: &Device,
    ) -> Self {
        let groups = match groups {
            0 => 0,
            g => (1..=g.min(cout))
                .rev()
                .find(|k| cout.is_multiple_of(*k))
                .unwrap_or(1),
        };
        Self {
            groups,
            conv: Conv3dConfig::new([cin, cout], [3, 3, 3])
                .with_stride(stride)
                .with_dilation([1, dilation, dilation])
                .with_padding(PaddingConfig3d::Explicit(1, dilation, dilation))
                .init(device),
            norm: LayerNormConfig::new(cout)
                .with_epsilon(NORM_EPSILON)
                .init(device),
        }
    }

    /// # Shapes
    /// `[B, Cin, D, H, W]` → `[B, Cout, D, H/stride, W/stride]`
    fn forward(&self, x: Tensor<5>) -> Tensor<5> {
        let x = crate::fastconv::forward(&self.conv, x);
        if self.groups > 0 {
            return relu(group_norm(&self.norm, self.groups, x));
        }
        // Layer norm over channels: channels last, normalise, back.
        crate::fastconv::channel_norm_relu(&self.norm, NORM_EPSILON, x)
    }
}

/// The stage-1 network of one normal: encoder, dilated residual bottom, decoder with skip
/// connections, and a sigmoid head giving one alpha per plane and pixel.
#[derive(Module, Debug)]
pub struct UNet3d {
    stem: Block3d,
    down: Vec<Block3d>,
    /// The prototype layout's second convolution of every level (after the stem, then after
    /// each downsampling convolution); empty otherwise.
    again: Vec<Block3d>,
    mid: Vec<Block3d>,
    /// Transposed convolutions of the decoder; empty in the prototype layout, which
    /// interpolates instead.
    up: Vec<ConvTranspose3d>,
    dec: Vec<Block3d>,
    head: Conv3d,
    residual: bool,
    /// The plane axis is halved by the encoder (and interpolated back by the prototype
    /// layout's decoder).
    halve_planes: bool,
}

/// Doubles the size of axis `axis` (2, 3 or 4) of `[B, C, D, H, W]` by linear interpolation
/// with half-pixel centres and the edges repeated (PyTorch's `interpolate(scale_factor=2,
/// align_corners=False)` along that axis): output `2i` is `¾ x[i] + ¼ x[i − 1]`, output
/// `2i + 1` is `¾ x[i] + ¼ x[i + 1]`, with `x[−1] = x[0]` and `x[n] = x[n − 1]`. Plain tensor
/// operations, so autodiff differentiates it.
pub fn upsample2_linear(x: Tensor<5>, axis: usize) -> Tensor<5> {
    let dims = x.dims();
    let n = dims[axis];
    let (prev, next) = if n == 1 {
        (x.clone(), x.clone())
    } else {
        (
            Tensor::cat(
                vec![
                    x.clone().narrow(axis, 0, 1),
                    x.clone().narrow(axis, 0, n - 1),
                ],
                axis,
            ),
            Tensor::cat(
                vec![
                    x.clone().narrow(axis, 1, n - 1),
                    x.clone().narrow(axis, n - 1, 1),
                ],
                axis,
            ),
        )
    };
    let x = x * 0.75;
    let even: Tensor<6> = (x.clone() + prev * 0.25).unsqueeze_dim(axis + 1);
    let odd: Tensor<6> = (x + next * 0.25).unsqueeze_dim(axis + 1);
    let mut out = dims;
    out[axis] *= 2;
    Tensor::cat(vec![even, odd], axis + 1).reshape(out)
}

impl UNet3dConfig {
    /// Output channels per plane: the alpha (or its logit's residual), and with
    /// [`Self::colour_head`] the colour mix's logit.
    pub fn out_channels(&self) -> usize {
        1 + usize::from(self.colour_head)
    }

    /// Build the network.
    pub fn init(&self, device: &Device) -> UNet3d {
        let w = self.width;
        let ch = |l: usize| w << l;
        let bottom = ch(self.levels);
        let sd = if self.halve_planes { 2 } else { 1 };
        let ng = self.norm_groups;
        let proto = self.prototype_layout;
        UNet3d {
            stem: Block3d::new(self.in_channels, w, [1, 1, 1], 1, ng, device),
            down: (0..self.levels)
                .map(|l| Block3d::new(ch(l), ch(l + 1), [sd, 2, 2], 1, ng, device))
                .collect(),
            again: (0..=self.levels)
                .filter(|_| proto)
                .map(|l| Block3d::new(ch(l), ch(l), [1, 1, 1], 1, ng, device))
                .collect(),
            mid: self
                .dilations
                .iter()
                .map(|&d| Block3d::new(bottom, bottom, [1, 1, 1], d, ng, device))
                .collect(),
            up: (0..self.levels)
                .filter(|_| !proto)
                .map(|l| {
                    ConvTranspose3dConfig::new([ch(l + 1), ch(l)], [sd, 2, 2])
                        .with_stride([sd, 2, 2])
                        .init(device)
                })
                .collect(),
            // Upsampled by interpolation the coarser level keeps its channels; through a
            // transposed convolution it arrives with this level's.
            dec: (0..self.levels)
                .map(|l| {
                    let cin = if proto { ch(l + 1) + ch(l) } else { 2 * ch(l) };
                    Block3d::new(cin, ch(l), [1, 1, 1], 1, ng, device)
                })
                .collect(),
            head: zeroed_if(
                self.residual,
                if proto {
                    Conv3dConfig::new([w, self.out_channels()], [3, 3, 3])
                        .with_padding(PaddingConfig3d::Explicit(1, 1, 1))
                        .init(device)
                } else {
                    Conv3dConfig::new([w, self.out_channels()], [1, 1, 1]).init(device)
                },
            ),
            residual: self.residual,
            halve_planes: self.halve_planes,
        }
    }
}

/// A convolution with zero weights and bias when `zero` (a residual head: the untrained network
/// changes nothing).
fn zeroed_if<M: Module>(zero: bool, m: M) -> M {
    if !zero {
        return m;
    }
    struct Zero;
    impl burn::module::ModuleMapper for Zero {
        fn map_float<const D: usize>(
            &mut self,
            param: burn::module::Param<Tensor<D>>,
        ) -> burn::module::Param<Tensor<D>> {
            let (id, t, mapper) = param.consume();
            burn::module::Param::from_mapped_value(id, t.zeros_like(), mapper)
        }
    }
    m.map(&mut Zero)
}

impl UNet3d {
    /// Alphas of every plane, or with a residual head the raw correction of their logits
    /// (and, with a colour head, each plane's colour-mix logit as a second channel).
    ///
    /// # Shapes
    /// `[B, C, D, H, W]` → `[B, 1 or 2, D, H, W]`, in `[0, 1]` unless residual (H and W
    /// divisible by `2^levels`, and D too with `halve_planes`)
    pub fn forward(&self, x: Tensor<5>) -> Tensor<5> {
        let mut again = self.again.iter();
        let mut twice = |x: Tensor<5>| match again.next() {
            Some(block) => block.forward(x),
            None => x,
        };
        let mut x = twice(self.stem.forward(x));
        let mut skips = Vec::with_capacity(self.down.len());
        for down in &self.down {
            skips.push(x.clone());
            x = twice(down.forward(x));
        }
        for mid in &self.mid {
            x = x.clone() + mid.forward(x);
        }
        for (l, dec) in self.dec.iter().enumerate().rev() {
            let skip = skips.pop().expect("one skip per level");
            let up = match self.up.get(l) {
                Some(up) => crate::fastconv::forward_transposed(up, x),
                None => {
                    let x = upsample2_linear(upsample2_linear(x, 3), 4);
                    if self.halve_planes {
                        upsample2_linear(x, 2)
                    } else {
                        x
                    }
                }
            };
            x = dec.forward(Tensor::cat(vec![up, skip], 1));
        }
        let y = crate::fastconv::forward(&self.head, x);
        if self.residual { y } else { sigmoid(y) }
    }
}

/// Stage 1: one 3D U-Net per normal, or one shared by all normals.
#[derive(Config, Debug)]
pub struct Stage1Config {
    /// The per-normal network.
    pub unet: UNet3dConfig,
    /// Number of normals N.
    pub normals: usize,
    /// One network for every normal (the normal's volume differs, the weights do not).
    #[config(default = true)]
    pub share_weights: bool,
    /// The U-Net runs on the cost volume averaged over `scale × scale` pixel blocks and its
    /// output is upsampled bilinearly to the full grid (1: full resolution). With the sweep
    /// prior the residual is upsampled and added to the full-resolution logits, so the prior
    /// keeps its detail. Images must be divisible by `scale · 2^levels`.
    #[config(default = 1)]
    pub scale: usize,
}

/// Stage 1 of the model.
#[derive(Module, Debug)]
pub struct Stage1 {
    nets: Vec<UNet3d>,
    scale: usize,
}

impl Stage1Config {
    /// Build stage 1.
    pub fn init(&self, device: &Device) -> Stage1 {
        let count = if self.share_weights { 1 } else { self.normals };
        Stage1 {
            nets: (0..count).map(|_| self.unet.init(device)).collect(),
            scale: self.scale.max(1),
        }
    }
}

impl Stage1 {
    /// Set the bias of every alpha head to `bias`: a large bias starts every alpha saturated
    /// near 1 (a stress test of training; the sigmoid's gradient is then tiny but finite).
    pub fn with_head_bias(mut self, bias: f32) -> Self {
        for net in &mut self.nets {
            if let Some(b) = net.head.bias.take() {
                let t = b.val();
                let c = t.dims()[0];
                // The alpha channel only; a colour head's second channel keeps its bias.
                let mut parts = vec![t.clone().narrow(0, 0, 1).ones_like() * bias];
                if c > 1 {
                    parts.push(t.narrow(0, 1, c - 1));
                }
                net.head.bias = Some(burn::module::Param::from_tensor(Tensor::cat(parts, 0)));
            }
        }
        self
    }

    /// Alphas (or residuals, and colour-mix logits with a colour head) of all normals, at the
    /// volume's resolution.
    ///
    /// # Shapes
    /// `[N, C, D, H, W]` (one oriented cost volume per normal) → `[N, 1 or 2, D, H, W]`
    pub fn forward(&self, volume: Tensor<5>) -> Tensor<5> {
        if self.scale <= 1 {
            return self.forward_full(volume);
        }
        use burn::tensor::module::avg_pool2d;
        use burn::tensor::ops::AvgPoolOptions;
        let [n, c, d, h, w] = volume.dims();
        let s = self.scale;
        let small = avg_pool2d(
            volume.reshape([n, c * d, h, w]),
            AvgPoolOptions {
                kernel_size: [s, s],
                stride: [s, s],
                padding: [(0, 0), (0, 0)],
                count_include_pad: true,
                ceil_mode: false,
            },
        );
        let [_, _, hs, ws] = small.dims();
        self.forward_blocks(small.reshape([n, c, d, hs, ws]), (h, w))
    }

    /// Alphas (or residuals) of all normals from a volume already averaged over pixel blocks
    /// (e.g. [`crate::Stage1Input`]), brought back to `(height, width)` bilinearly.
    ///
    /// # Shapes
    /// `[N, C, D, h, w]` → `[N, 1 or 2, D, height, width]`
    pub fn forward_blocks(&self, small: Tensor<5>, (h, w): (usize, usize)) -> Tensor<5> {
        use burn::tensor::module::interpolate;
        use burn::tensor::ops::{InterpolateMode, InterpolateOptions};
        let [n, _, d, hs, ws] = small.dims();
        let out = self.forward_full(small);
        if (hs, ws) == (h, w) {
            return out;
        }
        let c = out.dims()[1];
        let mut opts = InterpolateOptions::new(InterpolateMode::Bilinear);
        opts.output_size = Some([h, w]);
        interpolate(out.reshape([n, c * d, hs, ws]), opts).reshape([n, c, d, h, w])
    }

    /// Whether the networks have a colour head (two output channels per plane).
    pub fn colour_head(&self) -> bool {
        self.nets
            .first()
            .is_some_and(|net| net.head.weight.dims()[0] == 2)
    }

    /// Set the bias of the colour head (a test hook: a large bias moves every plane's colour
    /// to the source's where the source sees it). No effect without a colour head.
    pub fn with_colour_bias(mut self, bias: f32) -> Self {
        for net in &mut self.nets {
            if net.head.weight.dims()[0] != 2 {
                continue;
            }
            if let Some(b) = net.head.bias.take() {
                let t = b.val();
                let v = Tensor::cat(
                    vec![
                        t.clone().narrow(0, 0, 1),
                        t.narrow(0, 1, 1).ones_like() * bias,
                    ],
                    0,
                );
                net.head.bias = Some(burn::module::Param::from_tensor(v));
            }
        }
        self
    }

    /// The networks on the volume as it is (no interpolation): `[N, C, D, h, w]` →
    /// `[N, 1 or 2, D, h, w]`.
    pub(crate) fn forward_full(&self, volume: Tensor<5>) -> Tensor<5> {
        if self.nets.len() == 1 {
            return self.nets[0].forward(volume);
        }
        let parts = self
            .nets
            .iter()
            .enumerate()
            .map(|(i, net)| net.forward(volume.clone().narrow(0, i, 1)))
            .collect();
        Tensor::cat(parts, 0)
    }
}

/// Smallest heuristic weight whose logarithm a residual blending network corrects (weights
/// below it count as this; a normalised weight that small contributes less than 1e-30 of a
/// pixel).
pub const SOFT_FLOOR: f32 = 1e-30;

/// Size of the 2D blending U-Net.
#[derive(Config, Debug)]
pub struct BlendNetConfig {
    /// Number of normals N (input 4N channels, output N weights).
    pub normals: usize,
    /// Channels of the first level; each level doubles them.
    #[config(default = 16)]
    pub width: usize,
    /// Number of times the image is halved.
    #[config(default = 2)]
    pub levels: usize,
    /// Residual head: the last convolution starts at zero and corrects the logarithm of the
    /// heuristic weights (the input's last N channels), so the untrained network blends exactly
    /// as the heuristic does.
    #[config(default = false)]
    pub residual: bool,
    /// Also show the network where the normals disagree: per normal, how far its multi-normal
    /// image is from their mean at each pixel (summed over RGB), N more input channels. The
    /// paper's network sees only the images and their weights; the best normal per pixel is
    /// worth far more than Soft on unseen clips (#60), and which one is best shows where they
    /// differ.
    #[config(default = false)]
    pub disagreement: bool,
    /// Also show the network each normal's photo-inconsistency (`mhi_render::inconsistency_mhi`:
    /// N more input channels, after the heuristic weights) and, with a residual head, correct
    /// the consistent blend's log weights, `log w_Soft − β · c`, instead of Soft's: the untrained
    /// network blends as `mhi_render::consistent_weights` does with this β.
    #[config(default = "None")]
    pub consistency: Option<f32>,
}

/// Convolution, layer normalisation over channels, ReLU (2D).
#[derive(Module, Debug)]
pub struct Block2d {
    conv: Conv2d,
    norm: LayerNorm,
}

impl Block2d {
    fn new(cin: usize, cout: usize, stride: usize, device: &Device) -> Self {
        Self {
            conv: Conv2dConfig::new([cin, cout], [3, 3])
                .with_stride([stride, stride])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(device),
            norm: LayerNormConfig::new(cout)
                .with_epsilon(NORM_EPSILON)
                .init(device),
        }
    }

    fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = crate::fastconv::forward2d(&self.conv, x);
        crate::fastconv::channel_norm_relu(&self.norm, NORM_EPSILON, x)
    }
}

/// The stage-2 network: per-pixel softmax weights over the normals.
#[derive(Module, Debug)]
pub struct BlendNet {
    stem: Block2d,
    down: Vec<Block2d>,
    up: Vec<ConvTranspose2d>,
    dec: Vec<Block2d>,
    head: Conv2d,
    residual: bool,
    disagreement: bool,
    consistency: Option<f32>,
}

impl BlendNetConfig {
    /// Build the network.
    pub fn init(&self, device: &Device) -> BlendNet {
        let w = self.width;
        let ch = |l: usize| w << l;
        BlendNet {
            stem: Block2d::new(
                (4 + usize::from(self.disagreement) + usize::from(self.consistency.is_some()))
                    * self.normals,
                w,
                1,
                device,
            ),
            down: (0..self.levels)
                .map(|l| Block2d::new(ch(l), ch(l + 1), 2, device))
                .collect(),
            up: (0..self.levels)
                .map(|l| {
                    ConvTranspose2dConfig::new([ch(l + 1), ch(l)], [2, 2])
                        .with_stride([2, 2])
                        .init(device)
                })
                .collect(),
            dec: (0..self.levels)
                .map(|l| Block2d::new(2 * ch(l), ch(l), 1, device))
                .collect(),
            head: zeroed_if(
                self.residual,
                Conv2dConfig::new([w, self.normals], [1, 1]).init(device),
            ),
            residual: self.residual,
            disagreement: self.disagreement,
            consistency: self.consistency,
        }
    }
}

impl BlendNet {
    /// Blending weights.
    ///
    /// # Shapes
    /// `[1, 4N, H, W]` (the N multi-normal images and their heuristic weight; with
    /// [`BlendNetConfig::consistency`] `[1, 5N, H, W]`, their inconsistency after) →
    /// `[1, N, H, W]`, a softmax over N at every pixel
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let [_, c, _, _] = x.dims();
        let n = c / if self.consistency.is_some() { 5 } else { 4 };
        let prior = self.residual.then(|| {
            let log_soft = x.clone().narrow(1, 3 * n, n).clamp_min(SOFT_FLOOR).log();
            match self.consistency {
                Some(beta) => log_soft - x.clone().narrow(1, 4 * n, n) * beta,
                None => log_soft,
            }
        });
        let x = if self.disagreement {
            let [b, _, h, w] = x.dims();
            let images = x.clone().narrow(1, 0, 3 * n).reshape([b, n, 3, h, w]);
            let mean = images.clone().mean_dim(1);
            let apart = (images - mean).abs().sum_dim(2).reshape([b, n, h, w]);
            Tensor::cat(vec![x, apart], 1)
        } else {
            x
        };
        let mut x = self.stem.forward(x);
        let mut skips = Vec::with_capacity(self.down.len());
        for down in &self.down {
            skips.push(x.clone());
            x = down.forward(x);
        }
        for (up, dec) in self.up.iter().zip(&self.dec).rev() {
            let skip = skips.pop().expect("one skip per level");
            x = dec.forward(Tensor::cat(
                vec![crate::fastconv::forward_transposed2d(up, x), skip],
                1,
            ));
        }
        let logits = crate::fastconv::forward2d(&self.head, x);
        softmax(
            match prior {
                Some(p) => p + logits,
                None => logits,
            },
            1,
        )
    }
}

#[cfg(test)]
mod plane_conv_tests {
    use super::*;
    use burn::tensor::Distribution;
    use burn::tensor::module::conv3d;
    use burn::tensor::ops::ConvOptions;

    #[test]
    fn planes_as_2d_equals_conv3d() {
        let device = Device::flex();
        for (stride, dilation) in [(1, 1), (2, 1), (1, 2), (1, 4)] {
            let x: Tensor<5> =
                Tensor::random([2, 3, 4, 8, 8], Distribution::Normal(0.0, 1.0), &device);
            let w: Tensor<5> =
                Tensor::random([5, 3, 3, 3, 3], Distribution::Normal(0.0, 1.0), &device);
            let b: Tensor<1> = Tensor::random([5], Distribution::Normal(0.0, 1.0), &device);
            let reference = conv3d(
                x.clone(),
                w.clone(),
                Some(b.clone()),
                ConvOptions::new(
                    [1, stride, stride],
                    [1, dilation, dilation],
                    [1, dilation, dilation],
                    1,
                ),
            );
            let ours = conv3d_planes_as_2d(x, w, Some(b), stride, dilation, dilation);
            assert_eq!(ours.dims(), reference.dims());
            let diff: f32 = (ours - reference).abs().max().into_scalar();
            assert!(diff < 1e-4, "stride {stride} dilation {dilation}: {diff}");
        }
    }
}

#[cfg(test)]
mod unet_tests {
    use super::*;
    use burn::tensor::Distribution;

    /// With `halve_planes` the U-Net keeps its output shape, and a change on the first plane
    /// reaches the last of 16, which the plane-keeping network (±8 planes of reach) cannot.
    #[test]
    fn halving_the_planes_widens_the_reach_along_the_planes() {
        let device = Device::flex();
        let x: Tensor<5> =
            Tensor::random([1, 6, 16, 8, 8], Distribution::Normal(0.0, 1.0), &device);
        let mut poked = x.clone().into_data().try_to_vec::<f32>().unwrap();
        for v in poked.iter_mut().step_by(16 * 64).take(6) {
            *v += 5.0; // plane 0, pixel (0, 0) of every channel
        }
        let poked = Tensor::<5>::from_data(
            burn::tensor::TensorData::new(poked, [1, 6, 16, 8, 8]),
            &device,
        );
        for (halve, reaches) in [(false, false), (true, true)] {
            let net = UNet3dConfig::new().with_halve_planes(halve).init(&device);
            let (a, b) = (net.forward(x.clone()), net.forward(poked.clone()));
            assert_eq!(a.dims(), [1, 1, 16, 8, 8]);
            let last = |t: Tensor<5>| t.slice([0..1, 0..1, 15..16, 0..8, 0..8]);
            let change: f32 = (last(a) - last(b)).abs().max().into_scalar();
            assert_eq!(
                change > 0.0,
                reaches,
                "halve_planes {halve}: change {change}"
            );
        }
        // The residual head starts at zero with the halving too.
        let net = UNet3dConfig::new()
            .with_halve_planes(true)
            .with_residual(true)
            .init(&device);
        let y: f32 = net.forward(x).abs().max().into_scalar();
        assert_eq!(y, 0.0);
    }

    /// With the prototype's layout, plane halving, four groups and the sweep prior's seven
    /// channels the U-Net has exactly the PyTorch prototype's 81,625 parameters, keeps the
    /// volume's shape, and its residual head starts at zero.
    #[test]
    fn the_prototype_layout_is_the_prototypes_network() {
        let device = Device::flex();
        let config = UNet3dConfig::new()
            .with_in_channels(7)
            .with_dilations(vec![])
            .with_halve_planes(true)
            .with_norm_groups(4)
            .with_prototype_layout(true)
            .with_residual(true);
        let net = config.init(&device);
        assert_eq!(net.num_params(), 81_625);
        let ours = config.clone().with_prototype_layout(false).init(&device);
        assert_ne!(ours.num_params(), 81_625);
        let x: Tensor<5> =
            Tensor::random([1, 7, 16, 8, 12], Distribution::Normal(0.0, 1.0), &device);
        let y = net.forward(x.clone());
        assert_eq!(y.dims(), [1, 1, 16, 8, 12]);
        let y: f32 = y.abs().max().into_scalar();
        assert_eq!(y, 0.0);
        // Without the residual head every output is a finite alpha.
        let plain = config.with_residual(false).init(&device);
        let a = plain.forward(x).into_data().try_to_vec::<f32>().unwrap();
        assert!(a.iter().all(|v| (0.0..=1.0).contains(v)));
    }

    /// Doubling an axis equals half-pixel linear interpolation computed in f64 from its
    /// definition (output `j` samples the input at `(j + ½) / 2 − ½`, clamped to the axis),
    /// on every axis and on an axis of one.
    #[test]
    fn doubling_an_axis_is_half_pixel_linear_interpolation() {
        let device = Device::flex();
        for (axis, dims) in [
            (2, [2, 3, 5, 2, 3]),
            (3, [1, 2, 2, 4, 3]),
            (4, [1, 1, 3, 2, 1]),
        ] {
            let x: Tensor<5> = Tensor::random(dims, Distribution::Normal(0.0, 1.0), &device);
            let xs = x.clone().into_data().try_to_vec::<f32>().unwrap();
            let y = upsample2_linear(x, axis);
            let mut out = dims;
            out[axis] *= 2;
            assert_eq!(y.dims(), out);
            let ys = y.into_data().try_to_vec::<f32>().unwrap();
            let strides = |d: [usize; 5]| {
                let mut s = [1; 5];
                for i in (0..4).rev() {
                    s[i] = s[i + 1] * d[i + 1];
                }
                s
            };
            let (si, so) = (strides(dims), strides(out));
            let n = dims[axis];
            for (o, &got) in ys.iter().enumerate() {
                let idx: Vec<usize> = (0..5).map(|k| o / so[k] % out[k]).collect();
                let src = ((idx[axis] as f64 + 0.5) / 2.0 - 0.5).clamp(0.0, (n - 1) as f64);
                let (lo, t) = (src.floor() as usize, src.fract());
                let hi = (lo + 1).min(n - 1);
                let at = |i: usize| {
                    let flat: usize = (0..5)
                        .map(|k| if k == axis { i } else { idx[k] } * si[k])
                        .sum();
                    xs[flat] as f64
                };
                let want = at(lo) * (1.0 - t) + at(hi) * t;
                assert!(
                    (got as f64 - want).abs() < 1e-6,
                    "axis {axis}, output {idx:?}: {got} vs {want}"
                );
            }
        }
    }

    /// With `disagreement`, the blending network reads N more channels (each normal's distance
    /// from the mean image) and, untrained with its residual head, still blends exactly as the
    /// heuristic weights it is given; the new channels are zero only where the images agree.
    #[test]
    fn the_disagreement_inputs_start_at_the_heuristic_and_show_where_normals_differ() {
        use burn::tensor::Device as D;
        let device = D::flex();
        let n = 3;
        let net = BlendNetConfig::new(n)
            .with_width(4)
            .with_levels(1)
            .with_residual(true)
            .with_disagreement(true)
            .init(&device);
        let images: Tensor<4> =
            Tensor::random([1, 3 * n, 8, 8], Distribution::Uniform(0.0, 1.0), &device);
        let w: Tensor<4> = Tensor::random([1, n, 8, 8], Distribution::Uniform(0.1, 1.0), &device);
        let w = w.clone() / w.sum_dim(1);
        let out = net.forward(Tensor::cat(vec![images.clone(), w.clone()], 1));
        assert_eq!(out.dims(), [1, n, 8, 8]);
        let diff: f32 = (out - w.clone()).abs().max().into_scalar();
        assert!(
            diff < 1e-5,
            "untrained residual blend moved the weights by {diff}"
        );
        // Where all normals show the same image, the extra channels are zero; where one differs,
        // its channel is not: the network sees the difference.
        let [b, _, h, wd] = images.dims();
        let same = images.clone().narrow(1, 0, 3).repeat_dim(1, n);
        let apart = |x: Tensor<4>| {
            let imgs = x.reshape([b, n, 3, h, wd]);
            let mean = imgs.clone().mean_dim(1);
            (imgs - mean).abs().sum_dim(2).reshape([b, n, h, wd])
        };
        let zero: f32 = apart(same).abs().max().into_scalar();
        let some: f32 = apart(images).abs().max().into_scalar();
        assert!(zero < 1e-6 && some > 0.1, "{zero} {some}");
        // A config.json written before the option reads with it off, and keeps its fingerprint.
        let mut v = serde_json::to_value(crate::TrainConfig::for_normals(5)).unwrap();
        let before = crate::TrainConfig::for_normals(5).fingerprint();
        v["blend"].as_object_mut().unwrap().remove("disagreement");
        let old =
            crate::TrainConfig::from_json(&v.to_string(), std::path::Path::new("config.json"))
                .unwrap();
        assert!(!old.blend.disagreement);
        assert_eq!(old.fingerprint(), before);
        let mut on = crate::TrainConfig::for_normals(5);
        on.blend.disagreement = true;
        assert_ne!(on.fingerprint(), before);
    }

    /// The group norm equals PyTorch's `GroupNorm` formula computed in f64 (biased variance
    /// over each group's channels and voxels), with the per-channel scale and shift; a layer
    /// norm over channels would differ.
    #[test]
    fn group_norm_matches_an_f64_reference() {
        let device = Device::flex();
        let (b, c, d, h, w, g) = (2, 8, 3, 4, 5, 4);
        let x: Tensor<5> = Tensor::random([b, c, d, h, w], Distribution::Normal(1.0, 2.0), &device);
        let mut norm = LayerNormConfig::new(c).init(&device);
        let gamma: Vec<f32> = (0..c).map(|i| 0.5 + i as f32 * 0.25).collect();
        let beta: Vec<f32> = (0..c).map(|i| i as f32 * 0.1 - 0.3).collect();
        norm.gamma =
            burn::module::Param::from_tensor(Tensor::from_floats(gamma.as_slice(), &device));
        norm.beta = Some(burn::module::Param::from_tensor(Tensor::from_floats(
            beta.as_slice(),
            &device,
        )));
        let xs = x.clone().into_data().try_to_vec::<f32>().unwrap();
        let ours = group_norm(&norm, g, x)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let vox = d * h * w;
        let per_group = (c / g) * vox;
        let mut worst = 0.0_f64;
        for bi in 0..b {
            for gi in 0..g {
                let at = bi * c * vox + gi * per_group;
                let vals: Vec<f64> = xs[at..at + per_group].iter().map(|&v| v as f64).collect();
                let mean = vals.iter().sum::<f64>() / per_group as f64;
                let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / per_group as f64;
                for (k, v) in vals.iter().enumerate() {
                    let ch = gi * (c / g) + k / vox;
                    let want = (v - mean) / (var + NORM_EPSILON).sqrt() * gamma[ch] as f64
                        + beta[ch] as f64;
                    worst = worst.max((ours[at + k] as f64 - want).abs());
                }
            }
        }
        assert!(worst < 1e-4, "largest difference {worst}");
    }
}
