//! Layer normalisation over the channel axis of an NCDHW (or any `[B, C, …]`) tensor, in place
//! of burn's layer norm on the last axis behind two permutes (each a full copy, and their
//! backward two more): the statistics of each position are gathered across the channel rows in
//! chunks of positions, then every channel row is normalised on its own. f32 values, f64 sums
//! where a whole row is summed.

use rayon::prelude::*;

/// Positions per chunk when gathering statistics across channels.
const CHUNK: usize = 1024;

/// The shape `[batch, channels, positions]` of a normalisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NormShape {
    /// Batch size.
    pub batch: usize,
    /// Channels (the normalised axis).
    pub channels: usize,
    /// Positions per channel row (the product of the remaining axes).
    pub positions: usize,
}

/// Per position `(mean, 1 / sqrt(var + eps))` over the channels, `batch × positions` each.
fn stats(s: &NormShape, x: &[f32], eps: f64) -> (Vec<f32>, Vec<f32>) {
    let (c, n) = (s.channels, s.positions);
    let mut mean = vec![0.0f32; s.batch * n];
    let mut rstd = vec![0.0f32; s.batch * n];
    let inv = 1.0 / c as f32;
    let items = mean
        .par_chunks_mut(n.max(1))
        .zip(rstd.par_chunks_mut(n.max(1)));
    items.enumerate().for_each(|(b, (mean, rstd))| {
        let chunks = mean.par_chunks_mut(CHUNK).zip(rstd.par_chunks_mut(CHUNK));
        chunks.enumerate().for_each(|(j, (m, r))| {
            let p0 = j * CHUNK;
            let len = m.len();
            let row = |ch: usize| &x[(b * c + ch) * n + p0..][..len];
            for ch in 0..c {
                m.iter_mut().zip(row(ch)).for_each(|(m, v)| *m += v);
            }
            m.iter_mut().for_each(|m| *m *= inv);
            for ch in 0..c {
                let sq = r.iter_mut().zip(row(ch)).zip(m.iter());
                sq.for_each(|((r, v), m)| *r += (v - m) * (v - m));
            }
            r.iter_mut()
                .for_each(|r| *r = 1.0 / (*r * inv + eps as f32).sqrt());
        });
    });
    (mean, rstd)
}

/// ReLU as burn's: `v` where `v > 0`, else 0 (NaN stays NaN).
#[inline(always)]
fn relu(v: f32) -> f32 {
    if v <= 0.0 { 0.0 } else { v }
}

/// `y = (x − mean) / sqrt(var + eps) · gamma + beta`, statistics over the channels; with
/// `relu`, `max(y, 0)` in the same pass (the values of the two ops one after the other).
pub fn forward(
    s: &NormShape,
    x: &[f32],
    gamma: &[f32],
    beta: &[f32],
    eps: f64,
    relu: bool,
) -> Vec<f32> {
    assert_eq!(x.len(), s.batch * s.channels * s.positions);
    let (c, n) = (s.channels, s.positions);
    let (mean, rstd) = stats(s, x, eps);
    let mut y = vec![0.0f32; x.len()];
    y.par_chunks_mut(n.max(1))
        .enumerate()
        .for_each(|(row, out)| {
            let (b, ch) = (row / c, row % c);
            let (g, bt) = (gamma[ch], beta[ch]);
            let xs = &x[row * n..(row + 1) * n];
            let (m, r) = (&mean[b * n..(b + 1) * n], &rstd[b * n..(b + 1) * n]);
            for i in 0..n {
                out[i] = (xs[i] - m[i]) * r[i] * g + bt;
            }
            if relu {
                out.iter_mut().for_each(|v| *v = self::relu(*v));
            }
        });
    y
}

/// The gradients `(x, gamma, beta)` of [`forward`] given the output gradient `gy`; with
/// `relu: Some(beta)`, of the normalisation followed by ReLU (`gy` kept where the forward's
/// output, recomputed from `x`, `gamma` and `beta` in the same operations, is not at or below
/// zero, as burn's `relu_backward`).
pub fn backward(
    s: &NormShape,
    x: &[f32],
    gamma: &[f32],
    gy: &[f32],
    eps: f64,
    relu: Option<&[f32]>,
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    assert_eq!(x.len(), s.batch * s.channels * s.positions);
    let (c, n) = (s.channels, s.positions);
    let (mean, rstd) = stats(s, x, eps);
    // Behind a ReLU: the output gradient zeroed where the normalised value was not above zero.
    let masked: Vec<f32>;
    let gy = match relu {
        None => gy,
        Some(beta) => {
            let mut m = vec![0.0f32; gy.len()];
            m.par_chunks_mut(n.max(1))
                .enumerate()
                .for_each(|(row, out)| {
                    let (b, ch) = (row / c, row % c);
                    let (g, bt) = (gamma[ch], beta[ch]);
                    let (xs, gs) = (&x[row * n..(row + 1) * n], &gy[row * n..(row + 1) * n]);
                    let (mm, r) = (&mean[b * n..(b + 1) * n], &rstd[b * n..(b + 1) * n]);
                    for i in 0..n {
                        let y = (xs[i] - mm[i]) * r[i] * g + bt;
                        out[i] = if y <= 0.0 { 0.0 } else { gs[i] };
                    }
                });
            masked = m;
            &masked
        }
    };
    // Per position: a = mean_c(gy · gamma), b = mean_c(gy · gamma · x̂).
    let mut a = vec![0.0f32; s.batch * n];
    let mut bb = vec![0.0f32; s.batch * n];
    let inv = 1.0 / c as f32;
    a.par_chunks_mut(n.max(1))
        .zip(bb.par_chunks_mut(n.max(1)))
        .enumerate()
        .for_each(|(b, (a, bb))| {
            let (m, r) = (&mean[b * n..(b + 1) * n], &rstd[b * n..(b + 1) * n]);
            for ch in 0..c {
                let (xs, gs) = (&x[(b * c + ch) * n..][..n], &gy[(b * c + ch) * n..][..n]);
                let g = gamma[ch];
                for i in 0..n {
                    let d = gs[i] * g;
                    a[i] += d;
                    bb[i] += d * (xs[i] - m[i]) * r[i];
                }
            }
            a.iter_mut().for_each(|v| *v *= inv);
            bb.iter_mut().for_each(|v| *v *= inv);
        });
    let mut gx = vec![0.0f32; x.len()];
    // Per channel row: the input gradient, and the row's sums for gamma and beta.
    let sums: Vec<(f64, f64)> = gx
        .par_chunks_mut(n.max(1))
        .enumerate()
        .map(|(row, out)| {
            let (b, ch) = (row / c, row % c);
            let g = gamma[ch];
            let (xs, gs) = (&x[row * n..(row + 1) * n], &gy[row * n..(row + 1) * n]);
            let (m, r) = (&mean[b * n..(b + 1) * n], &rstd[b * n..(b + 1) * n]);
            let (pa, pb) = (&a[b * n..(b + 1) * n], &bb[b * n..(b + 1) * n]);
            let (mut sg, mut sb) = (0.0f64, 0.0f64);
            for i in 0..n {
                let xh = (xs[i] - m[i]) * r[i];
                out[i] = r[i] * (gs[i] * g - pa[i] - xh * pb[i]);
                sg += f64::from(gs[i] * xh);
                sb += f64::from(gs[i]);
            }
            (sg, sb)
        })
        .collect();
    let mut gg = vec![0.0f64; c];
    let mut gb = vec![0.0f64; c];
    for (row, (sg, sb)) in sums.into_iter().enumerate() {
        gg[row % c] += sg;
        gb[row % c] += sb;
    }
    let f = |v: Vec<f64>| v.into_iter().map(|v| v as f32).collect();
    (gx, f(gg), f(gb))
}
