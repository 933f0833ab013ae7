//! The fast CPU renderer: per target row, every layer is warped, sampled and composited front to
//! back in one pass (no warped image is materialised), rows in parallel with rayon.

use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{BlendHeuristic, Camera, plane_homography};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::mhi::{LayerColor, Mhi};

/// Samples whose homogeneous coordinate `w` is not above this are invalid (at or behind the
/// camera): they contribute nothing (the peer renderer uses the same bound).
pub const W_EPS: f32 = 1e-6;

/// How the multi-normal images are combined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Blend<'a> {
    /// A heuristic of the angle between each normal and the target pixel's ray (paper Eq. 4).
    Heuristic(BlendHeuristic),
    /// Per-pixel weights on the target grid, `N × H × W` (normal-major), non-negative with a
    /// positive sum at every pixel (they are normalised here).
    Weights(&'a [f32]),
}

/// What a render may leave out, as one error budget: the largest change, in colour units
/// (colours in [0, 1]), that everything left out may make to any pixel of the blended view.
///
/// The budget is split in three equal shares, each a bound that holds whatever the content:
/// - **layers** — per normal, layers are skipped (faintest first) while the sum of their
///   largest alphas stays within the share. Removing layers of alphas a_j from an
///   over-composite changes it by at most Σ a_j (each removal changes it by a_j times a colour
///   difference of at most 1), so the skipped mass is accumulated, not bounded per layer;
/// - **normals** — normals are dropped (lightest first) while, at every target pixel, the sum of
///   their blend weights stays within the share; renormalising the rest changes the blend by at
///   most that sum;
/// - **transmittance** — a pixel stops compositing once its remaining transmittance is within
///   the share: what lies behind adds at most that much.
///
/// The farthest layer of each normal is never skipped, and at least one normal is kept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Prune {
    /// The budget in colour units per pixel (0 renders exactly).
    pub budget: f32,
}

impl Prune {
    /// Render everything exactly.
    pub const NONE: Self = Self { budget: 0.0 };
    /// The default plan: no pixel changes by more than one 8-bit level (1/255).
    pub const DEFAULT: Self = Self {
        budget: 1.0 / 255.0,
    };

    /// A plan with the given budget (colour units per pixel).
    pub fn with_budget(budget: f32) -> Self {
        Self {
            budget: if budget.is_finite() {
                budget.max(0.0)
            } else {
                0.0
            },
        }
    }

    /// The share of the budget each of the three kinds of leaving out may use.
    pub fn share(&self) -> f32 {
        self.budget / 3.0
    }
}

impl Default for Prune {
    fn default() -> Self {
        Self::NONE
    }
}

/// Options of a render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions<'a> {
    /// How normals are blended.
    pub blend: Blend<'a>,
    /// What may be skipped.
    pub prune: Prune,
    /// Also return the N multi-normal images.
    pub keep_multi_normal: bool,
}

impl Default for RenderOptions<'_> {
    fn default() -> Self {
        Self {
            blend: Blend::Heuristic(BlendHeuristic::Soft),
            prune: Prune::NONE,
            keep_multi_normal: false,
        }
    }
}

/// Counts of what a render did and skipped.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct RenderStats {
    /// N · D.
    pub layers: usize,
    /// Layers whose plane the target camera is on or behind (masked).
    pub layers_invisible: usize,
    /// Layers skipped within the budget's layer share.
    pub layers_pruned: usize,
    /// Normals skipped within the budget's normal share.
    pub normals_pruned: usize,
    /// The bound the render guarantees: the largest change any pixel can see from what was
    /// left out (skipped alpha mass of the worst normal + dropped blend weight of the worst
    /// pixel + the transmittance at which compositing stops), at most the budget.
    pub bound: f32,
}

/// The result of a render.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The blended novel view.
    pub image: Rgb32FImage,
    /// The multi-normal images, when asked for.
    pub multi_normal: Vec<Rgb32FImage>,
    /// The normalised blend weights used, `N × H × W`.
    pub weights: Vec<f32>,
    /// What was done.
    pub stats: RenderStats,
}

/// Per-layer warp: the target→reference homography in f32 (row-major), or `None` when the plane
/// is invisible from the target.
pub(crate) fn layer_homographies(mhi: &Mhi, target: &Camera) -> Vec<Option<[f32; 9]>> {
    let ref_from_tgt = mhi.reference().from_other(target);
    let mut out = Vec::with_capacity(mhi.n() * mhi.d());
    for i in 0..mhi.n() {
        for j in 0..mhi.d() {
            let h = plane_homography(
                &mhi.reference().intrinsics,
                &target.intrinsics,
                &ref_from_tgt,
                mhi.plane(i, j),
            )
            .ok();
            out.push(h.map(|h| row_major_f32(&h)));
        }
    }
    out
}

pub(crate) fn row_major_f32(h: &DMat3) -> [f32; 9] {
    let t = h.transpose().to_cols_array(); // columns of Hᵀ are rows of H
    t.map(|v| v as f32)
}

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
    let r = reference.from_other(target).rotation();
    // Normals in the target frame, normalised once.
    let nt: Vec<DVec3> = normals
        .normals()
        .iter()
        .map(|v| (r.transpose() * *v).normalize())
        .collect();
    let mut out = vec![0.0_f32; n * w * h];
    let px = w * h;
    let rows: Vec<Vec<f32>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut row = vec![0.0_f32; n * w];
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

/// Validate given weights and normalise them per pixel.
fn normalised_weights(given: &[f32], n: usize, px: usize) -> Result<Vec<f32>> {
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

/// Reference colour as RGBA texels (A unused) for aligned bilinear fetches.
fn texels(img: &Rgb32FImage) -> Vec<[f32; 4]> {
    img.pixels()
        .map(|p| [p.0[0], p.0[1], p.0[2], 0.0])
        .collect()
}

/// The normals a render keeps (`true`) and the largest blend weight dropped at any pixel:
/// lightest first (by largest weight), normals are dropped while the summed weight they leave
/// out stays within `share` at every pixel; at least one normal is kept.
pub(crate) fn normals_to_drop(
    weights: &[f32],
    n: usize,
    px: usize,
    share: f32,
) -> (Vec<bool>, f32) {
    let mut active = vec![true; n];
    let mut dropped = vec![0.0_f32; px];
    let mut dropped_max = 0.0_f32;
    if share > 0.0 && n > 1 {
        let max_of = |i: usize| {
            weights[i * px..(i + 1) * px]
                .iter()
                .fold(0.0_f32, |m, v| m.max(*v))
        };
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|a, b| max_of(*a).total_cmp(&max_of(*b)));
        for &i in &order[..n - 1] {
            let w = &weights[i * px..(i + 1) * px];
            let new_max = dropped
                .iter()
                .zip(w)
                .fold(0.0_f32, |m, (d, v)| m.max(d + v));
            if new_max > share {
                break;
            }
            active[i] = false;
            for (d, v) in dropped.iter_mut().zip(w) {
                *d += v;
            }
            dropped_max = new_max;
        }
    }
    (active, dropped_max)
}

/// The layers of normal `i` a render skips and their summed largest alpha: among the layers
/// `visible(j)` except the farthest, faintest first, while the sum stays within `share`.
pub(crate) fn layers_to_skip(
    mhi: &Mhi,
    i: usize,
    visible: impl Fn(usize) -> bool,
    share: f32,
) -> (Vec<bool>, f32) {
    let d = mhi.d();
    let mut skip = vec![false; d];
    let mut mass = 0.0_f32;
    if share > 0.0 {
        let mut order: Vec<usize> = (1..d).filter(|&j| visible(j)).collect();
        order.sort_by(|a, b| {
            mhi.layer_max_alpha(i, *a)
                .total_cmp(&mhi.layer_max_alpha(i, *b))
        });
        for j in order {
            let a = mhi.layer_max_alpha(i, j);
            if mass + a > share {
                break;
            }
            mass += a;
            skip[j] = true;
        }
    }
    (skip, mass)
}

/// Render the MHI from `target` (the fast path).
///
/// # Errors
/// Only for invalid blend weights; degenerate geometry is masked (see [`RenderStats`]).
pub fn render(mhi: &Mhi, target: &Camera, opts: &RenderOptions<'_>) -> Result<Rendered> {
    let (n, d) = (mhi.n(), mhi.d());
    let (tw, th) = (target.width as usize, target.height as usize);
    let px = tw * th;
    let mut weights = match opts.blend {
        Blend::Heuristic(hh) => heuristic_weights(mhi, target, hh),
        Blend::Weights(w) => normalised_weights(w, n, px)?,
    };
    let mut stats = RenderStats {
        layers: n * d,
        ..RenderStats::default()
    };
    let share = opts.prune.share();
    let (active, dropped_max) = normals_to_drop(&weights, n, px, share);
    stats.normals_pruned = active.iter().filter(|a| !**a).count();
    if stats.normals_pruned > 0 {
        for p in 0..px {
            let s: f32 = (0..n)
                .filter(|i| active[*i])
                .map(|i| weights[i * px + p])
                .sum();
            for i in 0..n {
                weights[i * px + p] = if active[i] && s > 0.0 {
                    weights[i * px + p] / s
                } else {
                    0.0
                };
            }
        }
    }
    let hs = layer_homographies(mhi, target);
    stats.layers_invisible = hs.iter().filter(|h| h.is_none()).count();
    // Layers to composite, per normal, front (near) to back; the far layer is always kept.
    // Faintest first, layers are skipped while their summed largest alpha fits the share.
    let mut plan: Vec<Vec<(usize, [f32; 9], bool)>> = Vec::with_capacity(n);
    let mut skipped_mass_max = 0.0_f32;
    for i in 0..n {
        let (skip, mass) = layers_to_skip(mhi, i, |j| hs[i * d + j].is_some(), share);
        if active[i] {
            skipped_mass_max = skipped_mass_max.max(mass);
        }
        let mut layers = Vec::new();
        for j in (0..d).rev() {
            let Some(h) = hs[i * d + j] else { continue };
            if skip[j] {
                stats.layers_pruned += 1;
                continue;
            }
            layers.push((j, h, j == 0));
        }
        plan.push(layers);
    }
    let (rw, rh) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    let shared = match mhi.color() {
        LayerColor::Shared(img) => Some(texels(img)),
        LayerColor::PerLayer(_) => None,
    };
    let per_layer: Vec<Vec<[f32; 4]>> = match mhi.color() {
        LayerColor::Shared(_) => Vec::new(),
        LayerColor::PerLayer(v) => v.iter().map(texels).collect(),
    };
    let eps = share;
    stats.bound = skipped_mass_max + dropped_max + eps;
    let keep = opts.keep_multi_normal;
    // Each row: blended RGB (W·3) and, if kept, the N multi-normal rows (N·W·3).
    let rows: Vec<(Vec<f32>, Vec<f32>)> = (0..th)
        .into_par_iter()
        .map(|y| {
            let mut out = vec![0.0_f32; tw * 3];
            let mut mni = if keep {
                vec![0.0_f32; n * tw * 3]
            } else {
                Vec::new()
            };
            let mut c = vec![0.0_f32; tw * 3];
            let mut t = vec![1.0_f32; tw];
            let (mut sxs, mut sys) = (vec![0.0_f32; tw], vec![0.0_f32; tw]);
            let (mut fxs, mut fys) = (vec![0.0_f32; tw], vec![0.0_f32; tw]);
            let mut idx = vec![0_u32; tw];
            let stop = eps > 0.0;
            let v = y as f32 + 0.5;
            for i in 0..n {
                if !active[i] {
                    continue;
                }
                c.fill(0.0);
                t.fill(1.0);
                for &(j, h, far) in &plan[i] {
                    let alpha = mhi.alpha_layer(i, j);
                    let color: &[[f32; 4]] = match &shared {
                        Some(s) => s,
                        None => &per_layer[i * d + j],
                    };
                    // Pass 1 (vectorisable): sample positions of the whole row, split into the
                    // top-left texel index and the bilinear fractions. Invalid samples (w ≤ ε)
                    // are sent outside the image, where they read zero.
                    let (bx, by, bw) = (h[1] * v + h[2], h[4] * v + h[5], h[7] * v + h[8]);
                    let (wmax, hmax) = ((rw - 1) as f32, (rh - 1) as f32);
                    for x in 0..tw {
                        let u = x as f32 + 0.5;
                        let w = h[6] * u + bw;
                        let ok = w > W_EPS;
                        let inv = 1.0 / if ok { w } else { 1.0 };
                        let sx = if ok {
                            (h[0] * u + bx) * inv - 0.5
                        } else {
                            -2.0
                        };
                        let sy = if ok {
                            (h[3] * u + by) * inv - 0.5
                        } else {
                            -2.0
                        };
                        sxs[x] = sx;
                        sys[x] = sy;
                        // All four taps inside: 0 ≤ sx < w − 1 and 0 ≤ sy < h − 1.
                        let inside = sx >= 0.0 && sy >= 0.0 && sx < wmax && sy < hmax;
                        let xi = if inside { sx as u32 } else { 0 };
                        let yi = if inside { sy as u32 } else { 0 };
                        fxs[x] = sx - xi as f32;
                        fys[x] = sy - yi as f32;
                        idx[x] = if inside {
                            yi * rw as u32 + xi
                        } else {
                            u32::MAX
                        };
                    }
                    // Pass 2: bilinear fetches and front-to-back compositing.
                    for (x, (tx, cx)) in t.iter_mut().zip(c.chunks_exact_mut(3)).enumerate() {
                        if stop && *tx <= eps {
                            continue;
                        }
                        let (a, col) = if idx[x] != u32::MAX {
                            let i = idx[x] as usize;
                            let (ax, ay) = (fxs[x], fys[x]);
                            let (w00, w10, w01, w11) = (
                                (1.0 - ax) * (1.0 - ay),
                                ax * (1.0 - ay),
                                (1.0 - ax) * ay,
                                ax * ay,
                            );
                            let (a_top, a_bot) = (&alpha[i..i + 2], &alpha[i + rw..i + rw + 2]);
                            let (c_top, c_bot) = (&color[i..i + 2], &color[i + rw..i + rw + 2]);
                            let a =
                                w00 * a_top[0] + w10 * a_top[1] + w01 * a_bot[0] + w11 * a_bot[1];
                            let mut col = [0.0_f32; 3];
                            for k in 0..3 {
                                col[k] = w00 * c_top[0][k]
                                    + w10 * c_top[1][k]
                                    + w01 * c_bot[0][k]
                                    + w11 * c_bot[1][k];
                            }
                            (a, col)
                        } else {
                            // Border or outside: the general sampler (zero padding).
                            sample(alpha, color, rw, rh, sxs[x], sys[x])
                        };
                        let a = if far { 1.0 } else { a };
                        let ta = *tx * a;
                        cx[0] += ta * col[0];
                        cx[1] += ta * col[1];
                        cx[2] += ta * col[2];
                        *tx -= ta;
                    }
                    // Every pixel of the row is opaque: the farther layers cannot show.
                    if stop && t.iter().all(|v| *v <= eps) {
                        break;
                    }
                }
                let wrow = &weights[i * px + y * tw..i * px + (y + 1) * tw];
                for x in 0..tw {
                    for k in 0..3 {
                        out[3 * x + k] += wrow[x] * c[3 * x + k];
                    }
                }
                if keep {
                    mni[i * tw * 3..(i + 1) * tw * 3].copy_from_slice(&c);
                }
            }
            (out, mni)
        })
        .collect();
    let mut image = Rgb32FImage::new(target.width, target.height);
    let mut multi_normal = if keep {
        vec![Rgb32FImage::new(target.width, target.height); n]
    } else {
        Vec::new()
    };
    for (y, (row, mni)) in rows.iter().enumerate() {
        let dst = &mut image.as_mut()[y * tw * 3..(y + 1) * tw * 3];
        dst.copy_from_slice(row);
        if keep {
            for (i, m) in multi_normal.iter_mut().enumerate() {
                m.as_mut()[y * tw * 3..(y + 1) * tw * 3]
                    .copy_from_slice(&mni[i * tw * 3..(i + 1) * tw * 3]);
            }
        }
    }
    Ok(Rendered {
        image,
        multi_normal,
        weights,
        stats,
    })
}

/// Bilinear sample of alpha and colour at pixel-index position `(sx, sy)` (pixel centres at
/// integers), zero outside the image (PyTorch's `grid_sample`, `align_corners=False`,
/// `padding_mode="zeros"`).
#[inline(always)]
fn sample(
    alpha: &[f32],
    color: &[[f32; 4]],
    w: usize,
    h: usize,
    sx: f32,
    sy: f32,
) -> (f32, [f32; 3]) {
    if !(sx > -1.0 && sy > -1.0 && sx < w as f32 && sy < h as f32) {
        return (0.0, [0.0; 3]);
    }
    // floor() without a libm call (the baseline x86-64 target has no SSE4.1 rounding): the
    // shifted value is positive, so truncation is the floor.
    let x0 = (sx + 1.0) as isize - 1;
    let y0 = (sy + 1.0) as isize - 1;
    let (ax, ay) = (sx - x0 as f32, sy - y0 as f32);
    let wts = [
        (1.0 - ax) * (1.0 - ay),
        ax * (1.0 - ay),
        (1.0 - ax) * ay,
        ax * ay,
    ];
    let mut a = 0.0;
    let mut c = [0.0_f32; 3];
    if x0 >= 0 && y0 >= 0 && (x0 as usize) + 1 < w && (y0 as usize) + 1 < h {
        let i = y0 as usize * w + x0 as usize;
        let (a_top, a_bot) = (&alpha[i..i + 2], &alpha[i + w..i + w + 2]);
        let (c_top, c_bot) = (&color[i..i + 2], &color[i + w..i + w + 2]);
        a = wts[0] * a_top[0] + wts[1] * a_top[1] + wts[2] * a_bot[0] + wts[3] * a_bot[1];
        for k in 0..3 {
            c[k] = wts[0] * c_top[0][k]
                + wts[1] * c_top[1][k]
                + wts[2] * c_bot[0][k]
                + wts[3] * c_bot[1][k];
        }
    } else {
        let taps = [(x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)];
        for k in 0..4 {
            let (xx, yy) = taps[k];
            if xx >= 0 && yy >= 0 && (xx as usize) < w && (yy as usize) < h {
                let i = yy as usize * w + xx as usize;
                a += wts[k] * alpha[i];
                let t = color[i];
                c[0] += wts[k] * t[0];
                c[1] += wts[k] * t[1];
                c[2] += wts[k] * t[2];
            }
        }
    }
    (a, c)
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
