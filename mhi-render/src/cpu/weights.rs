//! The blend weights: the paper's heuristics (Eqs. 3–4) row by row, given weights checked and
//! normalised, and multi-normal images combined with them.
use glam::DVec3;
use image::Rgb32FImage;
use mhi_geom::{BlendHeuristic, Camera};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::mhi::Mhi;

/// Normalised heuristic weights `N × H × W` on the target grid (f32; δ in f64 per pixel).
pub fn heuristic_weights(mhi: &Mhi, target: &Camera, heuristic: BlendHeuristic) -> Vec<f32> {
    heuristic_weights_for(mhi.normals(), mhi.reference(), target, heuristic)
}

/// As [`heuristic_weights`], from the normals and the reference camera alone.
pub fn heuristic_weights_for(
    normals: &mhi_geom::NormalSet,
    reference: &Camera,
    target: &Camera,
    heuristic: BlendHeuristic,
) -> Vec<f32> {
    let n = normals.len();
    let (w, h) = (target.width as usize, target.height as usize);
    if heuristic == BlendHeuristic::Avg {
        // The same value `weights_into` gives every normal, without a ray per pixel.
        return vec![(1.0 / n.max(1) as f64) as f32; n * w * h];
    }
    let r = reference.from_other(target).rotation();
    // Normals in the target frame, normalised once.
    let nt: Vec<DVec3> = normals
        .normals()
        .iter()
        .map(|v| (r.transpose() * *v).normalize())
        .collect();
    let mut out = vec![0.0_f32; n * w * h];
    let px = w * h;
    let k = &target.intrinsics;
    let rows: Vec<Vec<f32>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut row = vec![0.0_f32; n * w];
            if heuristic == BlendHeuristic::Soft {
                soft_row(&nt, k, y, w, &mut row);
                return row;
            }
            let mut deltas = vec![0.0_f64; n];
            let mut wts = vec![0.0_f64; n];
            for x in 0..w {
                let ray = target
                    .intrinsics
                    .ray(mhi_geom::pixel_center(x as u32, y as u32))
                    .normalize();
                for (k, v) in nt.iter().enumerate() {
                    deltas[k] = v.dot(ray).abs().min(1.0);
                }
                heuristic.weights_into(&deltas, &mut wts);
                for k in 0..n {
                    row[k * w + x] = wts[k] as f32;
                }
            }
            row
        })
        .collect();
    for (y, row) in rows.iter().enumerate() {
        for k in 0..n {
            out[k * px + y * w..k * px + (y + 1) * w].copy_from_slice(&row[k * w..(k + 1) * w]);
        }
    }
    out
}

/// Row `y` of the normalised Soft weights (`N × W`, normal-major) of normals `nt` (unit, in the
/// target frame), normal by normal along the row so that the loops vectorise (a pixel at a
/// time, with libm's exp, took 4.6 ms of a 448 × 256 view): the ray of pixel x is
/// `((x + ½ − cx) / fx, ry, 1)`, `δ = |n · ray| / ‖ray‖`. Compiled for AVX2 too, picked at run
/// time (the same arithmetic: Rust never fuses a multiply and an add on its own).
pub(super) fn soft_row(
    nt: &[DVec3],
    k: &mhi_geom::Intrinsics,
    y: usize,
    w: usize,
    row: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn avx2(nt: &[DVec3], k: &mhi_geom::Intrinsics, y: usize, w: usize, row: &mut [f32]) {
        soft_row_generic(nt, k, y, w, row);
    }
    #[cfg(target_arch = "x86_64")]
    if mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2 {
        // SAFETY: `avx2` only needs AVX2, which the CPU was found to have.
        #[allow(unsafe_code)]
        return unsafe { avx2(nt, k, y, w, row) };
    }
    soft_row_generic(nt, k, y, w, row);
}

#[inline(always)]
pub(super) fn soft_row_generic(
    nt: &[DVec3],
    k: &mhi_geom::Intrinsics,
    y: usize,
    w: usize,
    row: &mut [f32],
) {
    let ry = (y as f64 + 0.5 - k.cy) / k.fy;
    let rx: Vec<f64> = (0..w).map(|x| (x as f64 + 0.5 - k.cx) / k.fx).collect();
    let inv: Vec<f64> = rx
        .iter()
        .map(|rx| 1.0 / (rx * rx + (ry * ry + 1.0)).sqrt())
        .collect();
    let mut wts = vec![0.0_f64; nt.len() * w];
    let mut sum = vec![0.0_f64; w];
    for (v, wk) in nt.iter().zip(wts.chunks_exact_mut(w.max(1))) {
        let base = v.y * ry + v.z;
        for (((o, s), rx), inv) in wk.iter_mut().zip(&mut sum).zip(&rx).zip(&inv) {
            let delta = ((v.x * rx + base) * inv).abs().min(1.0);
            *o = mhi_geom::soft_weight_for_f32(delta);
            *s += *o;
        }
    }
    // One division a pixel, not one a weight.
    for s in &mut sum {
        *s = 1.0 / *s;
    }
    for (r, wk) in row
        .chunks_exact_mut(w.max(1))
        .zip(wts.chunks_exact(w.max(1)))
    {
        for ((o, v), s) in r.iter_mut().zip(wk).zip(&sum) {
            *o = (v * s) as f32;
        }
    }
}

/// Validate given weights and normalise them per pixel.
pub(super) fn normalised_weights(given: &[f32], n: usize, px: usize) -> Result<Vec<f32>> {
    if given.len() != n * px {
        return Err(Error::InvalidWeights(format!(
            "expected {n}×{px} weights, got {}",
            given.len()
        )));
    }
    if let Some(k) = given.iter().position(|v| !v.is_finite() || *v < 0.0) {
        return Err(Error::InvalidWeights(format!(
            "weight {} of normal {} at pixel {} is negative or not finite",
            given[k],
            k / px,
            k % px
        )));
    }
    let mut out = given.to_vec();
    for p in 0..px {
        let s: f32 = (0..n).map(|i| given[i * px + p]).sum();
        if !(s > 0.0) {
            return Err(Error::InvalidWeights(format!(
                "the weights of pixel {p} sum to zero"
            )));
        }
        for i in 0..n {
            out[i * px + p] /= s;
        }
    }
    Ok(out)
}

/// `Σ_i w_i · mni_i` per pixel, with `weights` `N × H × W` (normal-major).
pub fn combine(mni: &[Rgb32FImage], weights: &[f32]) -> Rgb32FImage {
    let (w, h) = mni[0].dimensions();
    let px = (w * h) as usize;
    let mut out = Rgb32FImage::new(w, h);
    for (i, m) in mni.iter().enumerate() {
        let wi = &weights[i * px..(i + 1) * px];
        for ((o, p), &k) in out.pixels_mut().zip(m.pixels()).zip(wi) {
            for c in 0..3 {
                o.0[c] += k * p.0[c];
            }
        }
    }
    out
}
