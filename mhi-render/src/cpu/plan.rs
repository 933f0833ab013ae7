//! The render plan: within one error budget per pixel, the normals dropped, the layers each
//! tile skips and where each pixel stops (see the parent module's "How a render runs"), and the
//! least share any plan within the budget must composite.

use glam::DMat3;
use mhi_geom::{Camera, plane_homography};
use rayon::prelude::*;

use super::options::*;
use super::sample::*;
use super::weights::*;
use crate::error::Result;
use crate::mhi::Mhi;

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
        // Each normal's largest weight once (the sort compared them over the whole image at
        // every comparison: 0.2–0.3 ms of a 448 × 256 view).
        let max_of: Vec<f32> = (0..n)
            .map(|i| {
                weights[i * px..(i + 1) * px]
                    .iter()
                    .fold(0.0_f32, |m, v| m.max(*v))
            })
            .collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|a, b| max_of[*a].total_cmp(&max_of[*b]));
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

/// Target columns of a render tile: the unit within which layers are skipped where faint.
pub const TILE_W: usize = 32;
/// Target rows of a render tile.
pub const TILE_H: usize = 8;

/// What one render tile composites.
pub(super) struct TilePlan {
    /// Per normal, the layers to composite, near to far (empty for a dropped normal).
    pub(super) layers: Vec<Vec<usize>>,
    /// An upper bound of the change to any of its pixels from the layers left out here: the
    /// largest summed alpha any kept normal leaves out or, in a blend whose multi-normal images
    /// are not kept, that of every kept normal weighted by its largest blend weight here.
    pub(super) mass: f32,
    /// Visible layers of the kept normals (what an exact render composites here).
    pub(super) visible: usize,
}

/// Bounds `(lo, hi)` of the alpha layer `(i, j)` shows in the target rectangle `x0..x1` ×
/// `y0..y1` through the target→reference homography `h`: the block ranges over the bounding box
/// of the rectangle's image (its corners' images, a bilinear tap and a pixel of rounding around
/// them). The homography's `w` is affine in the pixel, so when it is positive at the four corners
/// the image is the convex hull of theirs, and when it is at or below [`W_EPS`] at all four no
/// sample of the rectangle is valid (they read zero). `lo` is lowered by the weight samples near
/// the border put on taps outside the image (zero padding reads zero); anything unclear falls
/// back to `(0, the layer's maximum)`.
pub(super) fn footprint_range(
    mhi: &Mhi,
    (i, j): (usize, usize),
    h: &[f32; 9],
    (x0, x1): (usize, usize),
    (y0, y1): (usize, usize),
) -> (f32, f32) {
    let h = h.map(f64::from);
    let (rw, rh) = (
        f64::from(mhi.reference().width),
        f64::from(mhi.reference().height),
    );
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut valid = 0;
    for (x, y) in [(x0, y0), (x1 - 1, y0), (x0, y1 - 1), (x1 - 1, y1 - 1)] {
        let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
        let w = h[6] * u + h[7] * v + h[8];
        if w > f64::from(W_EPS) {
            valid += 1;
            let s = [
                (h[0] * u + h[1] * v + h[2]) / w - 0.5,
                (h[3] * u + h[4] * v + h[5]) / w - 0.5,
            ];
            for k in 0..2 {
                lo[k] = lo[k].min(s[k]);
                hi[k] = hi[k].max(s[k]);
            }
        }
    }
    if valid == 0 {
        return (0.0, 0.0);
    }
    if valid < 4 || lo.iter().chain(&hi).any(|v| !v.is_finite()) {
        return (0.0, mhi.layer_max_alpha(i, j));
    }
    // Taps at ⌊s⌋ and ⌊s⌋ + 1, one more pixel either side for rounding.
    let (xa, xb) = (lo[0].floor() - 1.0, hi[0].floor() + 2.0);
    let (ya, yb) = (lo[1].floor() - 1.0, hi[1].floor() + 2.0);
    if xb < 0.0 || yb < 0.0 || xa > rw - 1.0 || ya > rh - 1.0 {
        return (0.0, 0.0);
    }
    let clamp = |v: f64, m: f64| v.clamp(0.0, m) as usize;
    let (a_lo, a_hi) = mhi.alpha_range_in(
        i,
        j,
        (clamp(xa, rw - 1.0), clamp(ya, rh - 1.0)),
        (clamp(xb, rw - 1.0), clamp(yb, rh - 1.0)),
    );
    // A sample at s < 0 puts weight −s on a tap outside the image (zero padding), one at
    // s > size − 1 weight s − (size − 1): the inside taps keep at least (1 − that) per axis, so
    // the sample's alpha is at least `a_lo` times their product (with room for rounding).
    let delta = 1e-3 + 1e-6 * lo.iter().chain(&hi).fold(0.0_f64, |m, v| m.max(v.abs()));
    let outside = |lo: f64, hi: f64, size: f64| {
        ((delta - lo).max(0.0) + (hi + delta - (size - 1.0)).max(0.0)).min(1.0)
    };
    let keep = (1.0 - outside(lo[0], hi[0], rw)) * (1.0 - outside(lo[1], hi[1], rh));
    (a_lo * keep as f32, a_hi)
}

/// Per tile of the target (row-major tiles), the layers each kept normal composites.
///
/// Near to far, a tile keeps an upper bound `T` of the transmittance its pixels can have in
/// front of each layer in the pruned render (the product of `1 − lo` over the kept layers in
/// front; skipped layers do not attenuate). Leaving out layer `k` of alpha `a_k` changes a
/// pixel by at most `a_k · T_k`, where `T_k` is its transmittance in the pruned render, so the
/// tile skips a layer while the summed `hi · T` stays within `share`: layers skipped everywhere
/// (`global_skip`) always, the others when they fit. Faint layers in front and hidden layers
/// behind an opaque surface both go. The far layer is always kept; with `share = 0` nothing is
/// skipped. With `tile_weights` (each normal's largest blend weight per tile, for a render that
/// bounds the blend alone) a normal that weighs little in a tile may leave out more there.
pub(super) fn tile_plans(
    mhi: &Mhi,
    hs: &[Option<[f32; 9]>],
    active: &[bool],
    global_skip: &[Vec<bool>],
    share: f32,
    tile_weights: Option<&[f32]>,
    (tw, th): (usize, usize),
) -> Vec<TilePlan> {
    let (n, d) = (mhi.n(), mhi.d());
    let (tiles_x, tiles_y) = (tw.div_ceil(TILE_W), th.div_ceil(TILE_H));
    let tile_rect = |k: usize| {
        let (x0, y0) = ((k % tiles_x) * TILE_W, (k / tiles_x) * TILE_H);
        ((x0, (x0 + TILE_W).min(tw)), (y0, (y0 + TILE_H).min(th)))
    };
    // The alpha bounds of every layer a plan may leave out, over every tile: layer by layer, so
    // that one layer's block ranges stay in the cache while every tile reads them (tile by
    // tile, each tile's 80-odd reads went to as many tables).
    let ranges: Vec<Vec<(f32, f32)>> = (0..n * d)
        .into_par_iter()
        .map(|l| {
            let (i, j) = (l / d, l % d);
            match hs[l].as_ref() {
                Some(h) if share > 0.0 && j > 0 && active[i] => (0..tiles_x * tiles_y)
                    .map(|k| {
                        let (xs, ys) = tile_rect(k);
                        footprint_range(mhi, (i, j), h, xs, ys)
                    })
                    .collect(),
                _ => Vec::new(),
            }
        })
        .collect();
    (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|k| {
            let mut plan = TilePlan {
                layers: vec![Vec::new(); n],
                mass: 0.0,
                visible: 0,
            };
            // The layers skipped everywhere count first, at their largest alpha here.
            let global: Vec<f32> = (0..n)
                .map(|i| {
                    (1..d)
                        .filter(|j| active[i] && global_skip[i][*j])
                        .filter_map(|j| ranges[i * d + j].get(k).map(|r| r.1))
                        .sum()
                })
                .collect();
            // Each normal's own budget for the layers it leaves out here. Blended (the
            // multi-normal images not kept), a pixel changes by Σ_i w_i · mass_i ≤ Σ_i W_i ·
            // mass_i, W_i the normal's largest weight in the tile: what the global skips leave
            // of the share goes to the kept normals in equal parts, each `rest / (kept · W_i)`
            // in its own colour units (a light normal leaves out more). Otherwise, or when the
            // global skips leave nothing, every normal gets the whole share (Σ_i w_i · mass_i ≤
            // max_i mass_i).
            let kept_normals = active.iter().filter(|a| **a).count();
            let w_of = |i: usize| tile_weights.map(|tw| tw[k * n + i]);
            let rest = share
                - (0..n)
                    .filter(|i| active[*i])
                    .map(|i| w_of(i).unwrap_or(0.0) * global[i])
                    .sum::<f32>();
            let weighted = tile_weights.is_some() && rest > 0.0;
            let budget_of = |i: usize| match w_of(i) {
                Some(w) if weighted => global[i] + share_of(rest, kept_normals, w),
                _ => share,
            };
            let mut weighted_mass = 0.0_f32;
            for i in (0..n).filter(|i| active[*i]) {
                let budget = budget_of(i);
                let mut mass = global[i];
                let mut t_up = 1.0_f32;
                let mut kept = Vec::with_capacity(d);
                for j in (0..d).rev() {
                    if hs[i * d + j].is_none() {
                        continue;
                    }
                    plan.visible += 1;
                    if j == 0 || share <= 0.0 {
                        kept.push(j);
                        continue;
                    }
                    if global_skip[i][j] {
                        continue;
                    }
                    let (lo, hi) = ranges[i * d + j][k];
                    let cost = hi * t_up;
                    if mass + cost <= budget {
                        mass += cost;
                    } else {
                        kept.push(j);
                        t_up *= 1.0 - lo;
                    }
                }
                plan.mass = plan.mass.max(mass);
                weighted_mass += w_of(i).unwrap_or(0.0) * mass;
                plan.layers[i] = kept;
            }
            if weighted {
                // Within the share by construction (`share_of` leaves a hair for rounding).
                plan.mass = weighted_mass.min(share);
            }
            plan
        })
        .collect()
}

/// Per tile of the target (row-major tiles), each normal's largest blend weight (`N` a tile).
pub(super) fn tile_max_weights(weights: &[f32], n: usize, (tw, th): (usize, usize)) -> Vec<f32> {
    let (tiles_x, tiles_y) = (tw.div_ceil(TILE_W), th.div_ceil(TILE_H));
    let px = tw * th;
    (0..tiles_x * tiles_y)
        .into_par_iter()
        .flat_map_iter(|k| {
            let (x0, y0) = ((k % tiles_x) * TILE_W, (k / tiles_x) * TILE_H);
            let (x1, y1) = ((x0 + TILE_W).min(tw), (y0 + TILE_H).min(th));
            (0..n).map(move |i| {
                (y0..y1)
                    .flat_map(|y| &weights[i * px + y * tw + x0..i * px + y * tw + x1])
                    .fold(0.0_f32, |m, v| m.max(*v))
            })
        })
        .collect()
}

/// A kept normal's equal part of `share`, in its own colour units, where its blend weight is at
/// most `weight`: `share / (kept · weight)`, a hair under for the rounding of the weights' sum
/// (infinite at weight zero: nothing of the normal shows).
pub(super) fn share_of(share: f32, kept: usize, weight: f32) -> f32 {
    if weight > 0.0 {
        share * (1.0 - 1e-4) / (kept as f32 * weight)
    } else {
        f32::INFINITY
    }
}

/// The span `(a, b)` without the pixels at either end whose transmittance `t` is at or below
/// their stop `thr` (those inside stay; pass 2 passes over them).
#[inline]
pub(super) fn open_span((mut a, mut b): (usize, usize), t: &[f32], thr: &[f32]) -> (usize, usize) {
    while a < b && t[a] <= thr[a] {
        a += 1;
    }
    while b > a && t[b - 1] <= thr[b - 1] {
        b -= 1;
    }
    (a, b)
}

/// The span `a..b` without the samples at either end whose bilinear taps all lie outside the
/// `rw × rh` image (they read zero: the test of [`sample_zero_padded`]). Along a target row the
/// samples lie on a line, so the ones that touch the image are one stretch of it (a few pixels
/// there may still fall outside by rounding; they are composited and read zero).
#[inline(always)]
pub(super) fn inside_span(
    sxs: &[f32],
    sys: &[f32],
    (mut a, mut b): (usize, usize),
    (rw, rh): (usize, usize),
) -> (usize, usize) {
    let outside = |x: usize| !touches_image(sxs[x], sys[x], rw, rh);
    while a < b && outside(a) {
        a += 1;
    }
    while b > a && outside(b - 1) {
        b -= 1;
    }
    (a, b)
}

/// Where a run's samples read (`idx` from pass 1): `seen`, the texels the layer's runs read so
/// far (lowest, one past the highest), widened to hold them; the next layer is prefetched there.
#[inline(always)]
pub(super) fn widen_reads(seen: &mut (usize, usize), idx: &[u32]) {
    let (lo, hi) = idx.iter().fold((u32::MAX, 0), |(lo, hi), &i| {
        (lo.min(i), hi.max(i.wrapping_add(1)))
    });
    if lo < hi {
        *seen = (seen.0.min(lo as usize), seen.1.max(hi as usize));
    }
}

/// How many pixels of `span` are still open (transmittance above their stop; all of them
/// without a stop).
#[inline(always)]
pub(super) fn open_count(
    t: &[f32],
    thr: &[f32],
    stop: bool,
    span: std::ops::Range<usize>,
) -> usize {
    if stop {
        t[span.clone()]
            .iter()
            .zip(&thr[span])
            .filter(|(t, th)| **t > **th)
            .count()
    } else {
        span.len()
    }
}

/// Which compilation of the row loop a render runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Rows {
    /// The widest the CPU has: an exact render's compositing sixteen pixels at a time with
    /// AVX-512F, else AVX2 and FMA, else the baseline.
    Fastest,
    /// AVX2 and FMA where the CPU has them, else the baseline (tests compare it with the
    /// AVX-512 compositing).
    #[cfg_attr(not(test), allow(dead_code))]
    Avx2,
    /// The baseline x86-64 code (what a CPU without AVX2 runs; tests compare the two).
    #[cfg_attr(not(test), allow(dead_code))]
    Baseline,
}

/// What a render composites: the blend weights (renormalised over the kept normals), the
/// normals kept, each layer's homography and each tile's layers, the budget's shares, and the
/// statistics known before any sample.
pub(super) struct RenderPlan {
    pub(super) weights: Vec<f32>,
    pub(super) active: Vec<bool>,
    pub(super) hs: Vec<Option<[f32; 9]>>,
    pub(super) tiles: Vec<TilePlan>,
    pub(super) share: f32,
    pub(super) eps: f32,
    pub(super) stats: RenderStats,
}

pub(super) fn render_plan(
    mhi: &Mhi,
    target: &Camera,
    opts: &RenderOptions<'_>,
) -> Result<RenderPlan> {
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
    let (active, dropped_max) = normals_to_drop(&weights, n, px, opts.prune.normal_share());
    let (share, eps) = opts.prune.shares_after(dropped_max);
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
    // Layers skipped everywhere: faintest first, while their summed largest alpha fits the
    // share (what the scene plan stores sparsely); the far layer is always kept.
    let mut global_skip = Vec::with_capacity(n);
    for i in 0..n {
        let (skip, _) = layers_to_skip(mhi, i, |j| hs[i * d + j].is_some(), share);
        stats.layers_pruned += skip.iter().filter(|s| **s).count();
        global_skip.push(skip);
    }
    let kept = active.iter().filter(|a| **a).count();
    let tile_weights = (eps > 0.0 && share > 0.0 && !opts.keep_multi_normal && kept > 1)
        .then(|| tile_max_weights(&weights, n, (tw, th)));
    let tiles = tile_plans(
        mhi,
        &hs,
        &active,
        &global_skip,
        share,
        tile_weights.as_deref(),
        (tw, th),
    );
    let (mut pairs, mut composited) = (0_usize, 0_usize);
    for t in &tiles {
        pairs += t.visible;
        composited += t.layers.iter().map(Vec::len).sum::<usize>();
    }
    stats.composited = if pairs > 0 {
        composited as f32 / pairs as f32
    } else {
        1.0
    };
    stats.bound = dropped_max
        + tiles
            .iter()
            .map(|t| t.mass + stop_at(t, eps, share))
            .fold(0.0_f32, f32::max);
    Ok(RenderPlan {
        weights,
        active,
        hs,
        tiles,
        share,
        eps,
        stats,
    })
}

/// A tile that leaves out less layer mass than its share passes the rest on to its
/// transmittance stop: its pixels stop at `eps + share − mass`, so every pixel's bound is still
/// dropped weight + layer mass + stop ≤ the budget (0: no stop).
pub(super) fn stop_at(tile: &TilePlan, eps: f32, share: f32) -> f32 {
    if eps > 0.0 {
        eps + (share - tile.mass).max(0.0)
    } else {
        0.0
    }
}

/// The least share of the (target pixel, visible layer) samples any render within `budget` must
/// composite, under the accounting of [`Prune`]: an ideal plan that knew every pixel's exact
/// contributions — blend weight × transmittance × alpha of each sample, `weights` being the
/// normalised blend weights (`N × H × W`) — and left out, per pixel, the faintest samples while
/// their summed contributions stay within the budget. A render that charges each sample it
/// leaves out at least that much (as [`render`](crate::render) does: colours differ by at most 1, its
/// transmittance is never below the exact one) composites at least this share, so `1 / share`
/// is the most leaving out can speed a view up, whatever the plan.
///
/// This is the floor of a render that bounds the blended image only. One that keeps the
/// multi-normal images bounds each of them on its own (their blend by any weights then stays
/// within the budget): its floor is [`needed_share_per_normal`], higher.
///
/// # Errors
/// For blend weights of the wrong size.
pub fn needed_share(mhi: &Mhi, target: &Camera, weights: &[f32], budget: f32) -> Result<f32> {
    let px = target.width as usize * target.height as usize;
    let weights = normalised_weights(weights, mhi.n(), px)?;
    Ok(least_share(mhi, target, Some(&weights), budget))
}

/// [`needed_share`] for a render that keeps the multi-normal images (what the learned blend
/// reads): every normal's image within `budget` on its own, so each pixel of each normal leaves
/// out its faintest samples (transmittance × alpha) while their sum stays within the budget.
pub fn needed_share_per_normal(mhi: &Mhi, target: &Camera, budget: f32) -> f32 {
    least_share(mhi, target, None, budget)
}

/// The floor of [`needed_share`] (blend `weights`) or, without them, of
/// [`needed_share_per_normal`].
pub(super) fn least_share(mhi: &Mhi, target: &Camera, weights: Option<&[f32]>, budget: f32) -> f32 {
    let (n, d) = (mhi.n(), mhi.d());
    let (tw, th) = (target.width as usize, target.height as usize);
    let hs = layer_homographies(mhi, target);
    let (rw, rh) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    let (total, needed) = (0..th)
        .into_par_iter()
        .map(|y| {
            let (mut total, mut needed) = (0_usize, 0_usize);
            let mut items = Vec::with_capacity(n * d);
            let v = y as f32 + 0.5;
            // Leave out the faintest of `items` within the budget; count what stays.
            let mut settle = |items: &mut Vec<f32>| {
                items.sort_by(f32::total_cmp);
                let mut spent = 0.0_f32;
                let left_out = items
                    .iter()
                    .take_while(|c| {
                        spent += **c;
                        spent <= budget
                    })
                    .count();
                total += items.len();
                needed += items.len() - left_out;
                items.clear();
            };
            for x in 0..tw {
                let u = x as f32 + 0.5;
                for i in 0..n {
                    let w = weights.map_or(1.0, |ws| ws[i * tw * th + y * tw + x]);
                    let mut t = 1.0_f32;
                    for j in (0..d).rev() {
                        let Some(h) = hs[i * d + j].as_ref() else {
                            continue;
                        };
                        let hw = h[6] * u + h[7] * v + h[8];
                        let a = if j == 0 {
                            1.0
                        } else if hw > W_EPS {
                            let sx = (h[0] * u + h[1] * v + h[2]) / hw - 0.5;
                            let sy = (h[3] * u + h[4] * v + h[5]) / hw - 0.5;
                            let alpha = mhi.alpha_layer(i, j);
                            sample_zero_padded::<false, 1>(|k| [alpha[k]], rw, rh, sx, sy)[0]
                        } else {
                            0.0
                        };
                        items.push(w * t * a);
                        t *= 1.0 - a;
                    }
                    if weights.is_none() {
                        settle(&mut items);
                    }
                }
                settle(&mut items);
            }
            (total, needed)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if total > 0 {
        needed as f32 / total as f32
    } else {
        1.0
    }
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
