//! The SSIM loss `mean(clamp(1 − SSIM, 0, 2)) / 2` of two `[B, C, H, W]` images with 3 × 3 box
//! windows over the valid region (C1 = 0.01², C2 = 0.03²), and its gradients, in one pass per
//! plane: burn's version is five average poolings and about twenty element-wise tensors, each
//! a pass over memory of its own, and as many again in its backward.
//!
//! Per window `w`: `μa`, `μb` the means, `Saa`, `Sbb`, `Sab` the means of the products,
//! `σa = Saa − μa²`, `σab = Sab − μa μb`; `SSIM = N / D` with `N = A1 A2`, `A1 = 2 μa μb + C1`,
//! `A2 = 2 σab + C2`, and `D = B1 B2`, `B1 = μa² + μb² + C1`, `B2 = σa + σb + C2`. Its
//! derivatives: `∂N/∂μa = 2 μb (A2 − A1)`, `∂D/∂μa = 2 μa (B2 − B1)`, `∂D/∂Saa = B1`,
//! `∂N/∂Sab = 2 A1`; `a`'s pixel `p` enters each window that holds it through `∂μa/∂a(p) =
//! 1/9`, `∂Saa/∂a(p) = 2 a(p)/9` and `∂Sab/∂a(p) = b(p)/9` (and `b` likewise, the roles
//! swapped).

use rayon::prelude::*;

const C1: f32 = 0.01 * 0.01;
const C2: f32 = 0.03 * 0.03;

/// `[B, C, H, W]` as planes of `h × w`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SsimShape {
    /// `B · C`.
    pub planes: usize,
    /// Rows.
    pub h: usize,
    /// Columns.
    pub w: usize,
}

impl SsimShape {
    /// Windows per plane: `(h − 2) · (w − 2)` (0 below 3 × 3).
    pub fn windows(&self) -> usize {
        self.h.saturating_sub(2) * self.w.saturating_sub(2)
    }
}

/// The five window means of one plane (`(h − 2) × (w − 2)` each): `μa, μb, Saa, Sbb, Sab`.
fn window_means(s: &SsimShape, a: &[f32], b: &[f32]) -> [Vec<f32>; 5] {
    let (h, w) = (s.h, s.w);
    let (oh, ow) = (h - 2, w - 2);
    let f: [fn(f32, f32) -> f32; 5] =
        [|a, _| a, |_, b| b, |a, _| a * a, |_, b| b * b, |a, b| a * b];
    f.map(|f| {
        // Sums of three along each row, then of three rows.
        let mut rows = vec![0.0f32; h * ow];
        for y in 0..h {
            let (ra, rb) = (&a[y * w..(y + 1) * w], &b[y * w..(y + 1) * w]);
            for x in 0..ow {
                rows[y * ow + x] =
                    f(ra[x], rb[x]) + f(ra[x + 1], rb[x + 1]) + f(ra[x + 2], rb[x + 2]);
            }
        }
        let mut out = vec![0.0f32; oh * ow];
        for y in 0..oh {
            for x in 0..ow {
                out[y * ow + x] =
                    (rows[y * ow + x] + rows[(y + 1) * ow + x] + rows[(y + 2) * ow + x]) / 9.0;
            }
        }
        out
    })
}

/// The SSIM of one window from its five means, with `(N, D, A1, A2, B1, B2)`.
#[inline]
fn window(mu_a: f32, mu_b: f32, saa: f32, sbb: f32, sab: f32) -> (f32, [f32; 4]) {
    let (sa, sb, sab) = (saa - mu_a * mu_a, sbb - mu_b * mu_b, sab - mu_a * mu_b);
    let a1 = mu_a * mu_b * 2.0 + C1;
    let a2 = sab * 2.0 + C2;
    let b1 = mu_a * mu_a + mu_b * mu_b + C1;
    let b2 = sa + sb + C2;
    ((a1 * a2) / (b1 * b2), [a1, a2, b1, b2])
}

/// The loss `mean over planes and windows of clamp(1 − SSIM, 0, 2) / 2` (0 without windows).
pub fn forward(s: &SsimShape, a: &[f32], b: &[f32]) -> f32 {
    let n = s.windows();
    if n == 0 || s.planes == 0 {
        return 0.0;
    }
    let plane = s.h * s.w;
    let total: f64 = a
        .par_chunks_exact(plane)
        .zip(b.par_chunks_exact(plane))
        .map(|(a, b)| {
            let [ma, mb, saa, sbb, sab] = window_means(s, a, b);
            (0..n)
                .map(|i| {
                    let (ssim, _) = window(ma[i], mb[i], saa[i], sbb[i], sab[i]);
                    f64::from((1.0 - ssim).clamp(0.0, 2.0))
                })
                .sum::<f64>()
        })
        .sum();
    (total / (n * s.planes) as f64 / 2.0) as f32
}

/// The gradients of [`forward`] with respect to `a` and `b`, times the upstream gradient `g`.
/// A window whose `1 − SSIM` is clamped passes no gradient.
pub fn backward(s: &SsimShape, a: &[f32], b: &[f32], g: f32) -> (Vec<f32>, Vec<f32>) {
    let plane = s.h * s.w;
    let (mut ga, mut gb) = (vec![0.0f32; a.len()], vec![0.0f32; b.len()]);
    let n = s.windows();
    if n == 0 || s.planes == 0 {
        return (ga, gb);
    }
    let (oh, ow) = (s.h - 2, s.w - 2);
    // d loss / d SSIM of every window.
    let dl = -g / (2.0 * (n * s.planes) as f32);
    ga.par_chunks_exact_mut(plane)
        .zip(gb.par_chunks_exact_mut(plane))
        .zip(a.par_chunks_exact(plane).zip(b.par_chunks_exact(plane)))
        .for_each(|((ga, gb), (a, b))| {
            let [ma, mb, saa, sbb, sab] = window_means(s, a, b);
            // Per window, the gradient with respect to its means, over 9: μa, μb, Saa, Sbb, Sab.
            let mut dm = [(); 5].map(|_| vec![0.0f32; oh * ow]);
            for i in 0..n {
                let (mu_a, mu_b) = (ma[i], mb[i]);
                let (ssim, [a1, a2, b1, b2]) = window(mu_a, mu_b, saa[i], sbb[i], sab[i]);
                let loss = 1.0 - ssim;
                if !(0.0..=2.0).contains(&loss) {
                    continue;
                }
                let d = b1 * b2;
                let k = dl / d / 9.0;
                dm[0][i] = k * (2.0 * mu_b * (a2 - a1) - ssim * 2.0 * mu_a * (b2 - b1));
                dm[1][i] = k * (2.0 * mu_a * (a2 - a1) - ssim * 2.0 * mu_b * (b2 - b1));
                dm[2][i] = k * (-ssim * b1);
                dm[3][i] = k * (-ssim * b1);
                dm[4][i] = k * (2.0 * a1);
            }
            // Each pixel gathers the windows that hold it: the adjoint of the box sums.
            let spread = |m: &[f32]| -> Vec<f32> {
                let mut rows = vec![0.0f32; s.h * ow];
                for y in 0..s.h {
                    for x in 0..ow {
                        let lo = y.saturating_sub(2);
                        let hi = y.min(oh - 1);
                        rows[y * ow + x] = (lo..=hi).map(|wy| m[wy * ow + x]).sum();
                    }
                }
                let mut out = vec![0.0f32; plane];
                for y in 0..s.h {
                    for x in 0..s.w {
                        let lo = x.saturating_sub(2);
                        let hi = x.min(ow - 1);
                        out[y * s.w + x] = (lo..=hi).map(|wx| rows[y * ow + wx]).sum();
                    }
                }
                out
            };
            let [d_ma, d_mb, d_saa, d_sbb, d_sab] = dm.map(|m| spread(&m));
            for p in 0..plane {
                ga[p] = d_ma[p] + 2.0 * a[p] * d_saa[p] + b[p] * d_sab[p];
                gb[p] = d_mb[p] + 2.0 * b[p] * d_sbb[p] + a[p] * d_sab[p];
            }
        });
    (ga, gb)
}
