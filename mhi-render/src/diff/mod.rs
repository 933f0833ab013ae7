//! The differentiable render path on burn tensors: the same warp, composite and blend as the CPU
//! renderer, for training. Geometry (homographies, validity, heuristic weights) is computed in
//! f64 on the CPU and enters as constants; gradients flow to the alphas, the colours and the
//! blend weights.

use burn::tensor::ops::GridSampleOptions;
use burn::tensor::{Device, Tensor, TensorData};
use mhi_geom::{BlendHeuristic, Camera, NormalSet};
use rayon::prelude::*;

use crate::cpu::{W_EPS, row_major_f32};
use crate::error::{Error, Result};

pub mod gather;
pub mod over;

pub use gather::Taps;

/// Sampling grids of every layer for one (reference, target) pair, as constant tensors.
#[derive(Debug, Clone)]
pub struct WarpGeometry {
    /// Number of normals.
    pub n: usize,
    /// Number of depths.
    pub d: usize,
    /// Target height.
    pub height: usize,
    /// Target width.
    pub width: usize,
    /// Normalised sampling positions in `[-2, 2]`, `[N·D, H, W, 2]` (grid_sample convention,
    /// `align_corners = false`); invalid samples sit at −2, outside the image.
    pub grid: Tensor<4>,
    /// 1 where the sample is valid (plane visible, `w > ε`), `[N·D, 1, H, W]`.
    pub valid: Tensor<4>,
    /// 1 on the farthest layer of each normal (forced opaque), `[N·D, 1, 1, 1]`.
    pub far: Tensor<4>,
    /// The same warp as bilinear taps (built on the CPU backend, where [`warp`] gathers through
    /// them instead of calling `grid_sample`).
    pub taps: Option<std::sync::Arc<Taps>>,
}

impl WarpGeometry {
    /// Build the grids of the N × D planes of `normals` at `depths` (far first) in `reference`,
    /// seen from `target`.
    pub fn new(
        normals: &NormalSet,
        depths: &[f64],
        reference: &Camera,
        target: &Camera,
        device: &Device,
    ) -> Result<Self> {
        let (n, d) = (normals.len(), depths.len());
        let planes = normals.planes(depths).map_err(|source| Error::Geometry {
            context: "render planes".into(),
            source,
        })?;
        let ref_from_tgt = reference.from_other(target);
        let (w, h) = (target.width as usize, target.height as usize);
        let (rw, rh) = (f64::from(reference.width), f64::from(reference.height));
        let mut grid = vec![-2.0_f32; n * d * h * w * 2];
        let mut valid = vec![0.0_f32; n * d * h * w];
        // One layer per task (each writes only its own grid and mask).
        grid.par_chunks_mut((2 * h * w).max(1))
            .zip(valid.par_chunks_mut((h * w).max(1)))
            .zip(planes.par_iter())
            .for_each(|((grid, valid), plane)| {
                let Ok(hm) = mhi_geom::plane_homography(
                    &reference.intrinsics,
                    &target.intrinsics,
                    &ref_from_tgt,
                    plane,
                ) else {
                    return;
                };
                // Same f32 arithmetic as the CPU renderer, so both sample the same positions.
                let hf = row_major_f32(&hm);
                for y in 0..h {
                    let v = y as f32 + 0.5;
                    for x in 0..w {
                        let u = x as f32 + 0.5;
                        let wh = hf[6] * u + hf[7] * v + hf[8];
                        if !(wh > W_EPS) {
                            continue;
                        }
                        let sx = (hf[0] * u + hf[1] * v + hf[2]) / wh;
                        let sy = (hf[3] * u + hf[4] * v + hf[5]) / wh;
                        let k = y * w + x;
                        // Continuous pixel position → [-1, 1]; anything beyond ±2 is fully
                        // outside the image, so clamping there changes no sample.
                        grid[2 * k] = ((f64::from(sx) / rw * 2.0 - 1.0).clamp(-2.0, 2.0)) as f32;
                        grid[2 * k + 1] =
                            ((f64::from(sy) / rh * 2.0 - 1.0).clamp(-2.0, 2.0)) as f32;
                        valid[k] = 1.0;
                    }
                }
            });
        let far: Vec<f32> = (0..n * d)
            .map(|l| if l % d == 0 { 1.0 } else { 0.0 })
            .collect();
        let taps = gather::on_cpu_backend(device).then(|| {
            let source = (reference.width as usize, reference.height as usize);
            std::sync::Arc::new(Taps::new(&grid, &valid, n * d, source, (w, h)))
        });
        Ok(Self {
            n,
            d,
            height: h,
            width: w,
            taps,
            grid: Tensor::from_data(TensorData::new(grid, [n * d, h, w, 2]), device),
            valid: Tensor::from_data(TensorData::new(valid, [n * d, 1, h, w]), device),
            far: Tensor::from_data(TensorData::new(far, [n * d, 1, 1, 1]), device),
        })
    }
}

/// Heuristic blend weights on the target grid as a constant tensor `[N, 1, H, W]`.
pub fn heuristic_weights_tensor(
    mhi_normals: &NormalSet,
    reference: &Camera,
    target: &Camera,
    heuristic: BlendHeuristic,
    device: &Device,
) -> Tensor<4> {
    let w = crate::cpu::heuristic_weights_for(mhi_normals, reference, target, heuristic);
    Tensor::from_data(
        TensorData::new(
            w,
            [
                mhi_normals.len(),
                1,
                target.height as usize,
                target.width as usize,
            ],
        ),
        device,
    )
}

/// Warp every layer into the target.
///
/// # Shapes
/// - `layers`: `[N·D, C, Hr, Wr]` (alpha and/or colour on the reference grid)
/// - returns `[N·D, C, H, W]`, zero where the sample is invalid or outside the reference image.
pub fn warp(layers: Tensor<4>, geom: &WarpGeometry) -> Tensor<4> {
    if let Some(taps) = geom
        .taps
        .as_ref()
        .filter(|_| gather::on_cpu_backend(&layers.device()))
    {
        return gather::warp(layers, taps);
    }
    let warped = layers.grid_sample_2d(geom.grid.clone(), GridSampleOptions::default());
    warped * geom.valid.clone()
}

/// Over-composite each normal's warped layers (paper Eq. 2), the farthest layer opaque.
///
/// # Shapes
/// - `rgb`: `[N·D, 3, H, W]`, `alpha`: `[N·D, 1, H, W]` (warped, far first within each normal)
/// - returns the multi-normal images `[N, 3, H, W]`
pub fn composite(rgb: Tensor<4>, alpha: Tensor<4>, geom: &WarpGeometry) -> Tensor<4> {
    if gather::on_cpu_backend(&rgb.device()) {
        return over::over(rgb, alpha, geom.n);
    }
    composite_ops(rgb, alpha, geom)
}

/// [`composite`] as burn's tensor operations, a loop over the layers (on any device; on the CPU
/// backend [`composite`] runs one fused kernel, [`over`]).
///
/// # Shapes
/// As [`composite`].
pub fn composite_ops(rgb: Tensor<4>, alpha: Tensor<4>, geom: &WarpGeometry) -> Tensor<4> {
    let (n, d, h, w) = (geom.n, geom.d, geom.height, geom.width);
    let far = geom.far.clone();
    let alpha = alpha * (far.ones_like() - far.clone()) + far;
    let rgb: Tensor<5> = rgb.reshape([n, d, 3, h, w]);
    let alpha: Tensor<5> = alpha.reshape([n, d, 1, h, w]);
    let mut t: Tensor<4> = Tensor::ones([n, 1, h, w], &alpha.device());
    let mut out: Tensor<4> = Tensor::zeros([n, 3, h, w], &alpha.device());
    for j in (0..d).rev() {
        let a: Tensor<4> = alpha.clone().narrow(1, j, 1).reshape([n, 1, h, w]);
        let c: Tensor<4> = rgb.clone().narrow(1, j, 1).reshape([n, 3, h, w]);
        let ta = t.clone() * a;
        out = out + c * ta.clone();
        t = t - ta;
    }
    out
}

/// Blend multi-normal images with normalised weights (paper Eq. 4).
///
/// # Shapes
/// - `multi_normal`: `[N, 3, H, W]`, `weights`: `[N, 1, H, W]` summing to 1 over N
/// - returns `[1, 3, H, W]`
pub fn blend(multi_normal: Tensor<4>, weights: Tensor<4>) -> Tensor<4> {
    (multi_normal * weights).sum_dim(0)
}

/// Render an MHI whose colour is shared (the reference image) from the target of `geom`.
///
/// # Shapes
/// - `alpha`: `[N·D, 1, Hr, Wr]` in `[0, 1]`; `color`: `[1, 3, Hr, Wr]`;
///   `weights`: `[N, 1, H, W]` normalised
/// - returns `(image [1, 3, H, W], multi_normal [N, 3, H, W])`
pub fn render_shared(
    alpha: Tensor<4>,
    color: Tensor<4>,
    geom: &WarpGeometry,
    weights: Tensor<4>,
) -> (Tensor<4>, Tensor<4>) {
    let l = geom.n * geom.d;
    let [_, _, rh, rw] = color.dims();
    let color = color.expand([l, 3, rh, rw]);
    let (rgb, a) = if geom.taps.is_some() && gather::on_cpu_backend(&alpha.device()) {
        // The gather warps each channel row on its own: colour and alpha apart give the same
        // values without the concatenation, its slices and their copies (forward and back).
        (warp(color, geom), warp(alpha, geom))
    } else {
        let warped = warp(Tensor::cat(vec![color, alpha], 1), geom);
        (warped.clone().narrow(1, 0, 3), warped.narrow(1, 3, 1))
    };
    let mni = composite(rgb, a, geom);
    (blend(mni.clone(), weights), mni)
}

/// An `image` RGB picture as a `[1, 3, H, W]` tensor.
pub fn image_to_tensor(img: &image::Rgb32FImage, device: &Device) -> Tensor<4> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let raw = img.as_raw();
    let mut planar = vec![0.0_f32; 3 * w * h];
    for p in 0..w * h {
        for k in 0..3 {
            planar[k * w * h + p] = raw[3 * p + k];
        }
    }
    Tensor::from_data(TensorData::new(planar, [1, 3, h, w]), device)
}

/// A `[1, 3, H, W]` tensor as an `image` RGB picture.
///
/// # Errors
/// When the tensor has another shape or cannot be read back as f32.
pub fn tensor_to_image(t: Tensor<4>) -> Result<image::Rgb32FImage> {
    let [b, c, h, w] = t.dims();
    if b != 1 || c != 3 {
        return Err(Error::InvalidInput(format!(
            "expected a [1, 3, H, W] tensor, got {:?}",
            t.dims()
        )));
    }
    let v: Vec<f32> = t
        .into_data()
        .try_into_vec()
        .map_err(|e| Error::InvalidInput(format!("cannot read tensor: {e:?}")))?;
    Ok(image::Rgb32FImage::from_fn(w as u32, h as u32, |x, y| {
        let p = y as usize * w + x as usize;
        image::Rgb([v[p], v[w * h + p], v[2 * w * h + p]])
    }))
}
