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
/// added back as a constant, so a zero residual gives the sweep's alphas exactly.
pub const PRIOR_EPS: f32 = 1e-3;

/// The logit channel enters the network divided by this (the logits span ±6.9, the colours
/// `[0, 1]`).
pub const LOGIT_INPUT_SCALE: f32 = 5.0;

/// The sweep prior of a pair as tensors on the stage-1 grid.
#[derive(Debug, Clone)]
pub struct SweepPrior {
    /// `logit(clamp(α_sweep))`, `[N·D, 1, H, W]`.
    pub logit: Tensor<4>,
    /// `α_sweep − clamp(α_sweep)` (a constant), `[N·D, 1, H, W]`.
    pub correction: Tensor<4>,
}

impl SweepPrior {
    /// Alphas `σ(logit + residual) + correction`, clamped to `[0, 1]`.
    ///
    /// # Shapes
    /// `residual [N·D, 1, H, W]` → `[N·D, 1, H, W]`
    pub fn apply(&self, residual: Tensor<4>) -> Tensor<4> {
        (sigmoid(self.logit.clone() + residual) + self.correction.clone()).clamp(0.0, 1.0)
    }
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
/// with `prior` (the sweep's constants on this image size) the sweep's logits as a seventh
/// channel and, at full resolution, as the base of the residual.
///
/// # Errors
/// Geometry the sweep cannot use, or an image side not divisible by `block`.
pub fn stage1_input(
    normals: &NormalSet,
    depths: &[f64],
    reference: &LoadedFrame,
    source: &LoadedFrame,
    prior: Option<&SweepConfig>,
    block: usize,
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
    let sweep = match prior {
        Some(cfg) => {
            check_parallax(&reference.camera, &source.camera, depths)?;
            Some(sweep_alphas(&psv, &reference.image, cfg)?)
        }
        None => None,
    };
    let logits: Option<Vec<f32>> = sweep
        .as_ref()
        .map(|a| a.iter().map(|&v| logit(v)).collect());
    let channels = if sweep.is_some() { 7 } else { 6 };
    let volume = fill_volume(&psv, &reference.image, logits.as_deref(), block);
    let (hb, wb) = (h / block, w / block);
    let volume = Tensor::from_data(TensorData::new(volume, [n, channels, d, hb, wb]), device);
    let prior = sweep.zip(logits).map(|(alpha, logit)| {
        let correction: Vec<f32> = alpha
            .iter()
            .map(|&a| a - a.clamp(PRIOR_EPS, 1.0 - PRIOR_EPS))
            .collect();
        let t = |v: Vec<f32>| Tensor::from_data(TensorData::new(v, [n * d, 1, h, w]), device);
        SweepPrior {
            logit: t(logit),
            correction: t(correction),
        }
    });
    Ok(Stage1Input {
        volume,
        prior,
        block,
        size: (h, w),
    })
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
    let mut data = vec![0.0_f32; n * channels * d * pxb];
    // One chunk per (normal, channel): `d` planes of `pxb` values.
    data.par_chunks_mut(d * pxb)
        .enumerate()
        .for_each(|(k, chunk)| {
            let (i, c) = (k / channels, k % channels);
            for (j, dst) in chunk.chunks_exact_mut(pxb).enumerate() {
                match c {
                    0..3 => pool(dst, (w, h), block, |p| refp[3 * p + c]),
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
        for x in 0..w {
            row[x / block] += value(y * w + x);
        }
    }
    let norm = 1.0 / (block * block) as f32;
    for v in dst.iter_mut() {
        *v *= norm;
    }
}

/// `log(c / (1 − c))` of the alpha clamped to `[PRIOR_EPS, 1 − PRIOR_EPS]`.
fn logit(a: f32) -> f32 {
    let c = a.clamp(PRIOR_EPS, 1.0 - PRIOR_EPS);
    (c / (1.0 - c)).ln()
}
