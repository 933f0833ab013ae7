//! What stage 1 sees: the oriented cost volume of a posed pair (the reference image and the
//! source warped onto every plane of every normal) and, for a model with the sweep prior, the
//! training-free sweep's alpha logits it corrects (docs/METHOD.md, "The learned model on the
//! sweep prior").

use burn::tensor::activation::sigmoid;
use burn::tensor::{Device, Tensor, TensorData};
use mhi_data::LoadedFrame;
use mhi_geom::NormalSet;
use mhi_render::{PlaneSweepVolume, SweepConfig, check_parallax, plane_sweep_volume, sweep_alphas};
use serde::{Deserialize, Serialize};

/// What stage 1 starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Prior {
    /// Nothing: stage 1 predicts alphas from the cost volume alone (the paper's network).
    #[default]
    None,
    /// The training-free sweep: stage 1 sees its alpha logits as a seventh input channel and
    /// predicts a residual added to them; an untrained model renders the sweep.
    Sweep,
}

impl Prior {
    /// Input channels per plane of stage 1 with this prior.
    pub fn channels(self) -> usize {
        match self {
            Self::None => 6,
            Self::Sweep => 7,
        }
    }
}

/// The sweep's alphas are clamped to `[PRIOR_EPS, 1 − PRIOR_EPS]` before their logit is taken
/// (logits within ±6.9, where the sigmoid still has a gradient); the clamped-off remainder is
/// added back as a constant, so a zero residual gives the sweep's alphas exactly. The default
/// of [`crate::TrainConfig::prior_clamp`], which a run may set otherwise.
pub const PRIOR_EPS: f32 = 1e-3;

/// The logit channel enters the network divided by this (the logits span ±6.9, the colours
/// `[0, 1]`).
pub const LOGIT_INPUT_SCALE: f32 = 5.0;

/// The sweep prior of a pair on the full stage-1 grid (`N·D` planes of `H × W`, normal-major,
/// far first), kept on the CPU: training makes tensors of it, inference applies it in one pass
/// ([`Self::apply_upsampled`]).
#[derive(Debug, Clone)]
pub struct SweepPrior {
    /// `logit(clamp(α_sweep))`.
    pub logit: Vec<f32>,
    /// `α_sweep − clamp(α_sweep)` (a constant).
    pub correction: Vec<f32>,
    /// `(N·D, H, W)`.
    pub shape: (usize, usize, usize),
}

impl SweepPrior {
    /// Alphas `σ(logit + residual) + correction`, clamped to `[0, 1]` (differentiable in the
    /// residual).
    ///
    /// # Shapes
    /// `residual [N·D, 1, H, W]` → `[N·D, 1, H, W]`
    pub fn apply(&self, residual: Tensor<4>) -> Tensor<4> {
        let (planes, h, w) = self.shape;
        let device = residual.device();
        let t = |v: &[f32]| {
            Tensor::<4>::from_data(TensorData::new(v.to_vec(), [planes, 1, h, w]), &device)
        };
        (sigmoid(t(&self.logit) + residual) + t(&self.correction)).clamp(0.0, 1.0)
    }

    /// The prior as the training path's fused upsample-and-apply takes it
    /// ([`crate::heads::upsampled`]).
    pub(crate) fn head(&self) -> crate::heads::Head {
        crate::heads::Head::prior(self.logit.clone(), self.correction.clone(), self.shape)
    }

    /// What [`Self::apply`] gives for the residual `small` (`N·D` planes of `hs × ws`) brought
    /// to the full grid by burn's bilinear `interpolate` (corners aligned, as
    /// [`crate::Stage1::forward_blocks`] does), in one pass over the alphas instead of five
    /// full-size tensor operations: the interpolation is the same sums in the same order; the
    /// sigmoid is `1 / (1 + e^−z)` with `exp_approx` (within 2 · 10⁻⁷ of `e^x`, relatively),
    /// which vectorises where the library's `exp` is a call per value.
    ///
    /// # Panics
    /// If `small` does not hold `N·D · hs · ws` values or a side is zero.
    pub fn apply_upsampled(&self, small: &[f32], (hs, ws): (usize, usize)) -> Vec<f32> {
        let (planes, h, w) = self.shape;
        assert!(hs > 0 && ws > 0 && small.len() == planes * hs * ws);
        // The residual of each row (its taps looked up per column), then the sigmoid pass,
        // which has no lookups and vectorises.
        upsample_rows(small, planes, (hs, ws), (h, w), |k, dst| {
            let at = k * w;
            let (logit, correction) = (&self.logit[at..at + w], &self.correction[at..at + w]);
            for ((o, l), c) in dst.iter_mut().zip(logit).zip(correction) {
                let a = 1.0 / (1.0 + exp_approx(-(l + *o)));
                *o = (a + c).clamp(0.0, 1.0);
            }
        })
    }
}

/// `e^x` in f32 without a library call, so that loops over it vectorise: `x = n · ln 2 + r`
/// with `|r| ≤ ln 2 / 2`, `e^r` by Cephes' `expf` polynomial, `2^n` put in the exponent bits.
/// Relative error within 2 · 10⁻⁷ of `e^x` over `[−87.3, 88]` (tested against f64); below that
/// range it gives `e^−87.3` (about 1.2 · 10⁻³⁸, where `e^x` turns subnormal), above it `e^88`
/// (about 1.7 · 10³⁸); NaN stays NaN.
#[inline(always)]
pub(crate) fn exp_approx(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // ln 2 split in two so that n · LN2_HI is exact.
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // Adding and subtracting 1.5 · 2²³ rounds to the nearest integer (|v| < 2²²).
    const ROUND: f32 = 12_582_912.0;
    // f32::clamp keeps NaN (a min/max pair would turn it into a bound).
    let x = x.clamp(-87.3, 88.0);
    let n = (x * LOG2E + ROUND) - ROUND;
    let r = x - n * LN2_HI - n * LN2_LO;
    let p = ((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r
        + 1.666_666_5e-1)
        * r
        + 0.5;
    let e_r = p * r * r + r + 1.0;
    // 2^n for n in [−126, 127]; NaN casts to 0 and leaves e_r NaN.
    let scale = f32::from_bits(((n as i32 + 127) as u32) << 23);
    e_r * scale
}

/// Everything stage 1 takes for one pair.
#[derive(Debug, Clone)]
pub struct Stage1Input {
    /// `[N, C, D, H / block, W / block]`: reference RGB, warped source RGB and (with the prior)
    /// the logit channel divided by [`LOGIT_INPUT_SCALE`], each averaged over `block × block`
    /// pixel blocks (the input of a U-Net run on blocks, [`crate::Stage1Config::scale`]; the
    /// average is taken here, on the CPU, so the full-resolution volume is never built).
    pub volume: Tensor<5>,
    /// The sweep prior, when the model has one, at full resolution.
    pub prior: Option<SweepPrior>,
    /// What a colour head mixes each plane's colour from, when the model has one.
    pub colour: Option<SourceColour>,
    /// Side of the pixel blocks the volume is averaged over (1: full resolution).
    pub block: usize,
    /// The full-resolution `(height, width)` stage 1's output is brought back to.
    pub size: (usize, usize),
}

/// The oriented cost volume `[N, 6, D, H, W]`: per normal and plane, the reference image and the
/// source image warped onto that plane (zero where the plane is not visible from the source).
pub fn cost_volume(
    normals: &NormalSet,
    depths: &[f64],
    reference: &LoadedFrame,
    source: &LoadedFrame,
    device: &Device,
) -> crate::Result<Tensor<5>> {
    Ok(stage1_input(normals, depths, reference, source, None, 1, device)?.volume)
}

/// Stage 1's input for a pair: the cost volume averaged over `block × block` pixel blocks, and
/// with `prior` (the sweep's constants on this image size, and where its alphas are clamped
/// before their logit is taken: [`PRIOR_EPS`] unless a run says otherwise) the sweep's logits
/// as a seventh channel and, at full resolution, as the base of the residual.
///
/// # Errors
/// Geometry the sweep cannot use, or an image side not divisible by `block`.
pub fn stage1_input(
    normals: &NormalSet,
    depths: &[f64],
    reference: &LoadedFrame,
    source: &LoadedFrame,
    prior: Option<(&SweepConfig, f32)>,
    block: usize,
    device: &Device,
) -> crate::Result<Stage1Input> {
    stage1_input_with(
        normals, depths, reference, source, prior, block, false, device,
    )
}

/// [`stage1_input`], and with `colour` what a colour head mixes each plane's colour from
/// ([`Stage1Input::colour`]).
///
/// # Errors
/// As [`stage1_input`].
#[allow(clippy::too_many_arguments)]
pub fn stage1_input_with(
    normals: &NormalSet,
    depths: &[f64],
    reference: &LoadedFrame,
    source: &LoadedFrame,
    prior: Option<(&SweepConfig, f32)>,
    block: usize,
    colour: bool,
    device: &Device,
) -> crate::Result<Stage1Input> {
    let block = block.max(1);
    let (iw, ih) = (reference.image.width(), reference.image.height());
    if !(iw as usize).is_multiple_of(block) || !(ih as usize).is_multiple_of(block) {
        return Err(crate::Error::Config(format!(
            "image size {iw}x{ih}: stage 1 on {block} x {block} pixel blocks needs both sides divisible by {block}"
        )));
    }
    let psv = plane_sweep_volume(
        normals,
        depths,
        &reference.camera,
        &source.image,
        &source.camera,
    )?;
    let (n, d) = (normals.len(), depths.len());
    let (w, h) = (
        reference.image.width() as usize,
        reference.image.height() as usize,
    );
    let eps = prior.map_or(PRIOR_EPS, |(_, e)| e);
    check_prior_clamp(eps)?;
    let sweep = match prior.map(|(c, _)| c) {
        Some(cfg) => {
            check_parallax(&reference.camera, &source.camera, depths)?;
            Some(sweep_alphas(&psv, &reference.image, cfg)?)
        }
        None => None,
    };
    use rayon::prelude::*;
    // Most of the sweep's alphas are clamped (its softmax is peaked): their logits are two
    // constants, taken once instead of a logarithm each.
    let (lo, hi) = (logit(0.0, eps), logit(1.0, eps));
    let logits: Option<Vec<f32>> = sweep.as_ref().map(|a| {
        a.par_iter()
            .map(|&v| {
                if v <= eps {
                    lo
                } else if v >= 1.0 - eps {
                    hi
                } else {
                    logit(v, eps)
                }
            })
            .collect()
    });
    let channels = if sweep.is_some() { 7 } else { 6 };
    let volume = fill_volume(&psv, &reference.image, logits.as_deref(), block);
    let (hb, wb) = (h / block, w / block);
    let volume = Tensor::from_data(TensorData::new(volume, [n, channels, d, hb, wb]), device);
    let prior = sweep.zip(logits).map(|(alpha, logit)| {
        let correction: Vec<f32> = alpha
            .par_iter()
            .map(|&a| a - a.clamp(eps, 1.0 - eps))
            .collect();
        SweepPrior {
            logit,
            correction,
            shape: (n * d, h, w),
        }
    });
    let colour = colour.then(|| SourceColour::new(psv, &reference.image));
    Ok(Stage1Input {
        volume,
        prior,
        colour,
        block,
        size: (h, w),
    })
}

/// What a colour head mixes each plane's colour from: the reference image and, per plane, the
/// source warped onto it where the source sees the plane. Plane `l`'s colour is
/// `clamp(ref + tanh(m_l) · (src_l − ref)·valid_l, 0, 1)` for the head's logit `m_l`: the
/// reference's at `m = 0` (an untrained head changes nothing), the source's as `m → ∞` where the
/// source sees the plane, the reference's always where it does not. Kept on the CPU at full
/// resolution, in the plane-sweep volume's own buffers (moved, not copied).
#[derive(Debug, Clone)]
pub struct SourceColour {
    /// The reference, interleaved `[H, W, 3]`.
    reference: Vec<f32>,
    /// The source warped onto each plane, interleaved `[N·D, H, W, 3]` (the plane-sweep
    /// volume's RGB).
    source: Vec<f32>,
    /// Where the source sees each plane (> 0), `[N·D, H, W]` (the plane-sweep volume's mask).
    valid: Vec<f32>,
    /// `(N·D, H, W)`.
    shape: (usize, usize, usize),
}

impl SourceColour {
    /// From a plane-sweep volume of the source (kept) and the reference image on the same
    /// grid.
    ///
    /// # Panics
    /// If the image is not the volume's size.
    pub fn new(psv: PlaneSweepVolume, reference: &image::Rgb32FImage) -> Self {
        let (w, h) = (psv.width as usize, psv.height as usize);
        assert_eq!(
            (reference.width() as usize, reference.height() as usize),
            (w, h)
        );
        let planes = psv.n * psv.d;
        assert_eq!(psv.rgb.len(), planes * 3 * w * h);
        assert_eq!(psv.valid.len(), planes * w * h);
        Self {
            reference: reference.as_raw().clone(),
            source: psv.rgb,
            valid: psv.valid,
            shape: (planes, h, w),
        }
    }

    /// The reference planar, `[3, H, W]`, and `(src_l − ref) · valid_l` planar,
    /// `[N·D, 3, H, W]`: what [`Self::apply`] mixes, laid out as tensors take them.
    fn planar(&self) -> (Vec<f32>, Vec<f32>) {
        use rayon::prelude::*;
        let (planes, h, w) = self.shape;
        let px = h * w;
        let mut reference = vec![0.0_f32; 3 * px];
        for p in 0..px {
            for c in 0..3 {
                reference[c * px + p] = self.reference[3 * p + c];
            }
        }
        let mut delta = vec![0.0_f32; planes * 3 * px];
        delta
            .par_chunks_mut(px.max(1))
            .enumerate()
            .for_each(|(k, dst)| {
                let (l, c) = (k / 3, k % 3);
                let rgb = &self.source[l * 3 * px..][..3 * px];
                let valid = &self.valid[l * px..][..px];
                for (p, o) in dst.iter_mut().enumerate() {
                    *o = if valid[p] > 0.0 {
                        rgb[3 * p + c] - self.reference[3 * p + c]
                    } else {
                        0.0
                    };
                }
            });
        (reference, delta)
    }

    /// Every plane's photo-inconsistency, `|src_l − ref|` where the source sees plane `l` and 0
    /// elsewhere (the layer colours of `mhi_render::inconsistency_mhi`), as a tensor.
    ///
    /// # Shapes
    /// `[N·D, 3, H, W]`
    pub fn inconsistency(&self, device: &Device) -> Tensor<4> {
        let (planes, h, w) = self.shape;
        let (_, delta) = self.planar();
        let abs: Vec<f32> = delta.into_iter().map(f32::abs).collect();
        Tensor::from_data(TensorData::new(abs, [planes, 3, h, w]), device)
    }

    /// The colours as the training path's fused upsample-and-apply takes them
    /// ([`crate::heads::upsampled`]).
    pub(crate) fn head(&self) -> crate::heads::Head {
        let (reference, delta) = self.planar();
        crate::heads::Head::colour(reference, delta, self.shape)
    }

    /// Every plane's colour for the head's logits `m` (differentiable in `m`).
    ///
    /// # Shapes
    /// `m [N·D, 1, H, W]` → `[N·D, 3, H, W]`
    pub fn apply(&self, m: Tensor<4>) -> Tensor<4> {
        let (planes, h, w) = self.shape;
        let device = m.device();
        let (reference, delta) = self.planar();
        let reference = Tensor::<4>::from_data(TensorData::new(reference, [1, 3, h, w]), &device)
            .expand([planes, 3, h, w]);
        let delta = Tensor::<4>::from_data(TensorData::new(delta, [planes, 3, h, w]), &device);
        (reference + burn::tensor::activation::tanh(m).expand([planes, 3, h, w]) * delta)
            .clamp(0.0, 1.0)
    }

    /// What [`Self::apply`] gives for the logits `small` (`N·D` planes of `hs × ws`) brought
    /// to the full grid bilinearly as [`crate::Stage1::forward_blocks`] does (corners
    /// aligned), as one picture per plane, on the CPU in one pass per plane (its tanh as
    /// `1 − 2 / (1 + e^2x)` with `exp_approx`, within 10⁻⁶ of the library's).
    ///
    /// # Panics
    /// If `small` does not hold `N·D · hs · ws` values or a side is zero.
    pub fn apply_upsampled(
        &self,
        small: &[f32],
        (hs, ws): (usize, usize),
    ) -> Vec<image::Rgb32FImage> {
        use rayon::prelude::*;
        let (planes, h, w) = self.shape;
        assert!(hs > 0 && ws > 0 && small.len() == planes * hs * ws);
        let (rows, cols) = (bilinear_axis(hs, h), bilinear_axis(ws, w));
        let px = h * w;
        (0..planes)
            .into_par_iter()
            .map(|l| {
                let src = &small[l * hs * ws..][..hs * ws];
                let rgb = &self.source[l * 3 * px..][..3 * px];
                let valid = &self.valid[l * px..][..px];
                let mut raw = vec![0.0_f32; 3 * px];
                let mut t = vec![0.0_f32; w];
                for (y, out) in raw.chunks_exact_mut(3 * w).enumerate() {
                    upsample_row(src, ws, rows[y], &cols, &mut t);
                    // tanh(x) = 1 − 2 / (1 + e^2x) through `exp_approx`, which vectorises (the
                    // library's tanh is a call per value).
                    for v in t.iter_mut() {
                        *v = 1.0 - 2.0 / (1.0 + exp_approx(2.0 * *v));
                    }
                    let at = y * w;
                    let (r, s) = (&self.reference[3 * at..][..3 * w], &rgb[3 * at..][..3 * w]);
                    for (x, &tx) in t.iter().enumerate() {
                        let seen = valid[at + x] > 0.0;
                        for c in 0..3 {
                            let k = 3 * x + c;
                            let delta = if seen { s[k] - r[k] } else { 0.0 };
                            out[k] = (r[k] + tx * delta).clamp(0.0, 1.0);
                        }
                    }
                }
                image::Rgb32FImage::from_raw(w as u32, h as u32, raw)
                    .expect("a buffer of 3 · w · h values")
            })
            .collect()
    }
}

/// Per output coordinate, the two taps and the weight of the second, as burn's
/// `interpolate_bilinear_impl` computes them (corners aligned; in f64, the weight then in f32).
pub(crate) fn bilinear_axis(n_in: usize, n_out: usize) -> Vec<(usize, usize, f32)> {
    let ratio = (n_in as f64 - 1.0) / (n_out.max(1) - 1).max(1) as f64;
    (0..n_out)
        .map(|o| {
            let c = o as f64 * ratio;
            let lo = c.floor().max(0.0) as usize;
            (lo, (lo + 1).min(n_in - 1), (c - lo as f64).max(0.0) as f32)
        })
        .collect()
}

/// `planes` planes of `hs × ws` brought to `h × w` bilinearly, corners aligned (burn's
/// `interpolate` in bilinear mode, the same sums in the same order), each output row `k`
/// (plane `k / h`, row `k % h`) then passed to `then` in place, in parallel.
fn upsample_rows(
    small: &[f32],
    planes: usize,
    (hs, ws): (usize, usize),
    (h, w): (usize, usize),
    then: impl Fn(usize, &mut [f32]) + Sync,
) -> Vec<f32> {
    use rayon::prelude::*;
    let (rows, cols) = (bilinear_axis(hs, h), bilinear_axis(ws, w));
    let mut out = vec![0.0_f32; planes * h * w];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(k, dst)| {
            let (plane, y) = (k / h, k % h);
            upsample_row(
                &small[plane * hs * ws..][..hs * ws],
                ws,
                rows[y],
                &cols,
                dst,
            );
            then(k, dst);
        });
    out
}

/// One output row of a bilinear upsampling of the plane `src` (rows of `ws` values): the taps
/// and weight of the row `(y0, y1, wy)` and of every column, as [`bilinear_axis`] gives them.
#[inline]
pub(crate) fn upsample_row(
    src: &[f32],
    ws: usize,
    (y0, y1, wy): (usize, usize, f32),
    cols: &[(usize, usize, f32)],
    dst: &mut [f32],
) {
    let (top, bottom) = (&src[y0 * ws..(y0 + 1) * ws], &src[y1 * ws..(y1 + 1) * ws]);
    for (o, &(x0, x1, wx)) in dst.iter_mut().zip(cols) {
        *o = top[x0] * (1.0 - wx) * (1.0 - wy)
            + top[x1] * wx * (1.0 - wy)
            + bottom[x0] * (1.0 - wx) * wy
            + bottom[x1] * wx * wy;
    }
}

/// `[N, C, D, (H / block)·(W / block)]` as a flat vector: reference RGB, warped RGB, then
/// (C = 7, with the sweep's `logits`) the logits over [`LOGIT_INPUT_SCALE`], each averaged over
/// `block × block` pixel blocks (the sides divide by `block`).
fn fill_volume(
    psv: &PlaneSweepVolume,
    reference: &image::Rgb32FImage,
    logits: Option<&[f32]>,
    block: usize,
) -> Vec<f32> {
    use rayon::prelude::*;
    let (n, d) = (psv.n, psv.d);
    let (w, h) = (psv.width as usize, psv.height as usize);
    let px = w * h;
    let (wb, hb) = (w / block, h / block);
    let pxb = wb * hb;
    let channels = if logits.is_some() { 7 } else { 6 };
    let refp = reference.as_raw();
    // The reference's channels are the same on every plane: pooled once.
    let mut reference_pooled = vec![0.0_f32; 3 * pxb];
    for (c, dst) in reference_pooled.chunks_exact_mut(pxb.max(1)).enumerate() {
        pool(dst, (w, h), block, |p| refp[3 * p + c]);
    }
    let mut data = vec![0.0_f32; n * channels * d * pxb];
    // One chunk per (normal, channel): `d` planes of `pxb` values.
    data.par_chunks_mut(d * pxb)
        .enumerate()
        .for_each(|(k, chunk)| {
            let (i, c) = (k / channels, k % channels);
            for (j, dst) in chunk.chunks_exact_mut(pxb).enumerate() {
                match c {
                    0..3 => dst.copy_from_slice(&reference_pooled[c * pxb..(c + 1) * pxb]),
                    3..6 => {
                        let src = psv.plane_rgb(i, j);
                        pool(dst, (w, h), block, |p| src[3 * p + c - 3]);
                    }
                    _ => {
                        if let Some(l) = logits {
                            let l = &l[(i * d + j) * px..][..px];
                            pool(dst, (w, h), block, |p| l[p] / LOGIT_INPUT_SCALE);
                        }
                    }
                }
            }
        });
    data
}

/// The average over `block × block` pixel blocks of `value(p)`, `p` the pixel index on the full
/// `w × h` grid, into `dst` (`(w / block) · (h / block)` values; the sides divide by `block`).
fn pool(dst: &mut [f32], (w, h): (usize, usize), block: usize, value: impl Fn(usize) -> f32) {
    if block == 1 {
        for (p, v) in dst.iter_mut().enumerate() {
            *v = value(p);
        }
        return;
    }
    let wb = w / block;
    dst.fill(0.0);
    for y in 0..h {
        let row = &mut dst[(y / block) * wb..][..wb];
        for (xb, v) in row.iter_mut().enumerate() {
            let p = y * w + xb * block;
            // Summed left to right as before, without a division per pixel.
            for x in 0..block {
                *v += value(p + x);
            }
        }
    }
    let norm = 1.0 / (block * block) as f32;
    for v in dst.iter_mut() {
        *v *= norm;
    }
}

/// A clamp `[eps, 1 − eps]` of the prior's alphas is one only for `0 < eps < 0.5` (what
/// [`crate::TrainConfig`] checks of `prior_clamp`, and [`stage1_input`] of what it is given).
pub(crate) fn check_prior_clamp(eps: f32) -> crate::Result<()> {
    if eps > 0.0 && eps < 0.5 {
        Ok(())
    } else {
        Err(crate::Error::Config(format!(
            "prior_clamp {eps}: must lie strictly between 0 and 0.5"
        )))
    }
}

/// `log(c / (1 − c))` of the alpha clamped to `[eps, 1 − eps]`.
fn logit(a: f32, eps: f32) -> f32 {
    let c = a.clamp(eps, 1.0 - eps);
    (c / (1.0 - c)).ln()
}

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::module::interpolate;
    use burn::tensor::ops::{InterpolateMode, InterpolateOptions};

    #[test]
    fn exp_approx_is_within_two_parts_in_ten_million() {
        let mut worst = 0.0_f64;
        for k in 0..=1_753_000 {
            let x = -87.3_f32 + k as f32 * 1e-4;
            let want = f64::from(x).exp();
            let got = f64::from(super::exp_approx(x));
            worst = worst.max((got - want).abs() / want);
        }
        assert!(worst <= 2e-7, "largest relative error {worst:e}");
        assert!(super::exp_approx(f32::NAN).is_nan());
        assert!(super::exp_approx(f32::NEG_INFINITY) > 0.0);
        assert!(super::exp_approx(f32::INFINITY).is_finite());
        assert_eq!(super::exp_approx(0.0), 1.0);
    }

    #[test]
    fn the_fused_prior_gives_the_alphas_of_the_tensor_path() {
        let device = Device::flex();
        // Blocks of 4 (the pretrained model at 448 × 256), of 2, odd sizes, and none.
        for (planes, (hs, ws), (h, w)) in [
            (6, (4, 7), (16, 28)),
            (3, (5, 3), (10, 6)),
            (2, (3, 5), (7, 11)),
            (4, (6, 5), (6, 5)),
        ] {
            let n = planes * h * w;
            let alpha: Vec<f32> = (0..n)
                .map(|k| match k % 7 {
                    0 => 0.0,
                    1 => 1.0,
                    _ => ((k * 7919) % 1000) as f32 / 999.0,
                })
                .collect();
            let prior = SweepPrior {
                logit: alpha.iter().map(|&a| logit(a, PRIOR_EPS)).collect(),
                correction: alpha
                    .iter()
                    .map(|&a| a - a.clamp(PRIOR_EPS, 1.0 - PRIOR_EPS))
                    .collect(),
                shape: (planes, h, w),
            };
            let small: Vec<f32> = (0..planes * hs * ws)
                .map(|k| ((k * 104_729) % 201) as f32 / 20.0 - 5.0)
                .collect();
            let residual = Tensor::<4>::from_data(
                TensorData::new(small.clone(), [1, planes, hs, ws]),
                &device,
            );
            let mut opts = InterpolateOptions::new(InterpolateMode::Bilinear);
            opts.output_size = Some([h, w]);
            let up = if (hs, ws) == (h, w) {
                residual
            } else {
                interpolate(residual, opts)
            };
            let want: Vec<f32> = prior
                .apply(up.reshape([planes, 1, h, w]))
                .into_data()
                .try_to_vec::<f32>()
                .unwrap();
            let got = prior.apply_upsampled(&small, (hs, ws));
            let worst = want
                .iter()
                .zip(&got)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0_f32, f32::max);
            assert!(
                worst <= 1e-6,
                "{hs}x{ws} -> {h}x{w}: max |fused - tensors| = {worst}"
            );
            assert!(got.iter().all(|a| (0.0..=1.0).contains(a)));
        }
    }
}
