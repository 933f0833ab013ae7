//! The fast CPU renderer: per target row, every layer is warped, sampled and composited front to
//! back in one pass (no warped image is materialised), rows in parallel with rayon.
//!
//! # How a render runs
//!
//! the fast renderer: per band of 8 target rows (a tile row), per normal, per layer front to back,
//! per row of the band, per run of adjacent tiles of 32 × 8 pixels that keep the layer; while a
//! layer is composited the texels of the next are prefetched (the band reads only a few short rows
//! of each of the N · D layers, too short for the hardware prefetcher); pass 1 computes the tile
//! row's sample positions branch-free and vectorised (the floor and texel index through the
//! float's bits, `floor_small`), pass 2 fetches bilinearly (colour straight from the images' RGB
//! rows, four floats a tap into an RGBx row so the mix runs four wide; one alpha and one colour
//! window a sample, zipped slices, so two bounds checks a sample) and composites; rayon over
//! bands; the band loop (`RowContext`) is compiled twice, baseline and AVX2 + FMA, the latter
//! picked at run time, and each specialised on `STOP` (whether the render leaves anything out: the
//! exact loop has no stop tests, the pruned loop no pairs of layers, and an edit to one does not
//! move the other's code; the next layer's prefetch is a macro because, as a closure, whether it
//! was inlined changed with unrelated edits and out of line it cost the exact render 11 %); a run
//! leaves out, at its ends, the samples whose four taps all fall outside the reference image (in
//! front of the far plane they read zero and change nothing: the same bits); an exact render takes
//! two layers at a time through a row (each pixel's colour and transmittance read and written once
//! for both, same order, same bits; both paths write pass 1, the fetch and the compositing step
//! with the same macros: moved into functions, that code made the loop 40 % slower); `Prune` is
//! the render plan: one error budget per pixel, spent on dropped normals (at most a third), then
//! half of the rest each on skipped layers and early-stopped pixels. Layers are skipped per tile:
//! each tile bounds the alpha a layer can show it (the block minima and maxima `Mhi` keeps per 8 ×
//! 8 reference block, over the bounding box of the tile's footprint) and, near to far, the
//! transmittance in front of it, and skips layers while the summed `alpha · transmittance` fits
//! the layer share — faint layers in front and layers hidden behind an opaque surface (without the
//! multi-normal images only the blend is bounded, so each kept normal gets an equal part of the
//! share divided by its largest weight in the tile: a light normal leaves out more); a tile's
//! unspent layer share goes to its pixels' transmittance stop (without the multi-normal images the
//! stop bounds the blend, Σ_i w_i · T_i, and each kept normal spends an equal part: normal i stops
//! at `share / (K · w_i)` per pixel; with them each image is bounded alone), and a pixel that
//! stops takes the mean colour of the layers it composited for what it leaves out (within T of the
//! exact pixel, unbiased where dropping it darkened); a row composites layer by layer, near to
//! far, and adjacent tiles that keep a layer form one run (an exact render's runs are whole rows:
//! a per-tile loop overhead cost the exact render ~15 %), over the span of its tiles' pixels still
//! open; the render reports the bound it guarantees in `RenderStats::bound`, the share of tile-
//! layer pairs and of pixel-layer samples it composited; `needed_share` is the least share of
//! samples any render within the budget must composite — an ideal per-pixel plan that knows every
//! exact contribution — so its inverse bounds what leaving out can gain on a view;
//! `needed_share_per_normal` is the same floor for a render that keeps the multi-normal images,
//! each bounded on its own, higher

use glam::{DMat3, DVec3};
use image::Rgb32FImage;
use mhi_geom::{BlendHeuristic, Camera, plane_homography};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bilinear;
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
/// The budget is spent in three parts, each a bound that holds whatever the content:
/// - **normals** — normals are dropped (lightest first) while, at every target pixel, the sum of
///   their blend weights stays within a third of the budget; renormalising the rest changes the
///   blend by at most that sum. What the normals do not use passes on: the rest of the budget
///   is split in half between the two other parts ([`Prune::shares_after`]);
/// - **layers** — per render tile of [`TILE_W`] × [`TILE_H`] target pixels and per normal,
///   layers are skipped (faintest there first) while the sum of their largest alphas over the
///   part of the reference image the tile sees stays within the layer share. Removing layers of
///   alphas a_j from an over-composite changes it by at most Σ a_j (each removal changes it by
///   a_j times a colour difference of at most 1), so the skipped mass is accumulated, not
///   bounded per layer. When only the blended view is asked for (not the multi-normal images),
///   a pixel changes by Σ_i w_i · mass_i, so each kept normal gets an equal part of the share
///   divided by its largest blend weight in the tile: a light normal leaves out more;
/// - **transmittance** — a pixel stops compositing once its remaining transmittance is within
///   its share, plus whatever layer share its tile did not spend: what lies behind adds at most
///   that much, and the pixel takes the mean colour of the layers it composited for it (its
///   colour divided by 1 − T: still within T of the exact pixel, but not always darker).
///   When only the blended view is asked for (not the multi-normal images), the
///   share bounds the blend, Σ_i w_i · T_i, and each of the `K` kept normals spends an equal
///   part of it: normal i stops at `T ≤ share / (K · w_i)` at that pixel, so a light normal stops
///   after a layer or two and a heavy one a little later than alone. With the multi-normal images
///   every image is bounded on its own (each normal stops at the share). A row composites layer
///   by layer, near to far; adjacent tiles that keep the layer form one run (an exact render's
///   runs are whole rows) over the span from its first tile's first open pixel to its last
///   tile's last, each pixel tested against its own stop.
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

    /// The share of the budget the blend weights of dropped normals may use: a third.
    pub fn normal_share(&self) -> f32 {
        self.budget / 3.0
    }

    /// The layer share and the transmittance share once normals whose summed weight is at most
    /// `dropped` (≤ [`Self::normal_share`]) are left out: half of the rest each, so the three
    /// parts add up to the budget.
    pub fn shares_after(&self, dropped: f32) -> (f32, f32) {
        let rest = (self.budget - dropped.clamp(0.0, self.normal_share())).max(0.0) / 2.0;
        (rest, rest)
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
    /// Share of the (tile, visible layer) pairs of the kept normals that were composited: the
    /// render plans per tile of [`TILE_W`] × [`TILE_H`] target pixels and skips, in each tile,
    /// the layers that are faint over the part of them the tile sees (1 when nothing is left
    /// out).
    pub composited: f32,
    /// Share of the (target pixel, visible layer) samples of all normals that were composited
    /// (1 when nothing is left out): what the tiles skip, what the transmittance stop skips and
    /// the dropped normals together.
    #[serde(default)]
    pub samples: f32,
    /// The bound the render guarantees: the largest change any pixel can see from what was
    /// left out (skipped alpha mass of the worst normal, or, bounding the blend alone, of every
    /// normal weighted by its blend weight + dropped blend weight of the worst pixel + the
    /// transmittance at which compositing stops), at most the budget.
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
fn soft_row(nt: &[DVec3], k: &mhi_geom::Intrinsics, y: usize, w: usize, row: &mut [f32]) {
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
fn soft_row_generic(nt: &[DVec3], k: &mhi_geom::Intrinsics, y: usize, w: usize, row: &mut [f32]) {
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
struct TilePlan {
    /// Per normal, the layers to composite, near to far (empty for a dropped normal).
    layers: Vec<Vec<usize>>,
    /// An upper bound of the change to any of its pixels from the layers left out here: the
    /// largest summed alpha any kept normal leaves out or, in a blend whose multi-normal images
    /// are not kept, that of every kept normal weighted by its largest blend weight here.
    mass: f32,
    /// Visible layers of the kept normals (what an exact render composites here).
    visible: usize,
}

/// Bounds `(lo, hi)` of the alpha layer `(i, j)` shows in the target rectangle `x0..x1` ×
/// `y0..y1` through the target→reference homography `h`: the block ranges over the bounding box
/// of the rectangle's image (its corners' images, a bilinear tap and a pixel of rounding around
/// them). The homography's `w` is affine in the pixel, so when it is positive at the four corners
/// the image is the convex hull of theirs, and when it is at or below [`W_EPS`] at all four no
/// sample of the rectangle is valid (they read zero). `lo` is lowered by the weight samples near
/// the border put on taps outside the image (zero padding reads zero); anything unclear falls
/// back to `(0, the layer's maximum)`.
fn footprint_range(
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
fn tile_plans(
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
fn tile_max_weights(weights: &[f32], n: usize, (tw, th): (usize, usize)) -> Vec<f32> {
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
fn share_of(share: f32, kept: usize, weight: f32) -> f32 {
    if weight > 0.0 {
        share * (1.0 - 1e-4) / (kept as f32 * weight)
    } else {
        f32::INFINITY
    }
}

/// The span `(a, b)` without the pixels at either end whose transmittance `t` is at or below
/// their stop `thr` (those inside stay; pass 2 passes over them).
#[inline]
fn open_span((mut a, mut b): (usize, usize), t: &[f32], thr: &[f32]) -> (usize, usize) {
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
fn inside_span(
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

/// Whether a bilinear sample at `(sx, sy)` has a tap inside the `w × h` image (otherwise it
/// reads zero under zero padding). NaN positions touch nothing.
#[inline(always)]
fn touches_image(sx: f32, sy: f32, w: usize, h: usize) -> bool {
    sx > -1.0 && sy > -1.0 && sx < w as f32 && sy < h as f32
}

/// Where a run's samples read (`idx` from pass 1): `seen`, the texels the layer's runs read so
/// far (lowest, one past the highest), widened to hold them; the next layer is prefetched there.
#[inline(always)]
fn widen_reads(seen: &mut (usize, usize), idx: &[u32]) {
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
fn open_count(t: &[f32], thr: &[f32], stop: bool, span: std::ops::Range<usize>) -> usize {
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

/// Render the MHI from `target` (the fast path).
///
/// # Errors
/// Only for invalid blend weights; degenerate geometry is masked (see [`RenderStats`]).
pub fn render(mhi: &Mhi, target: &Camera, opts: &RenderOptions<'_>) -> Result<Rendered> {
    render_rows_with(mhi, target, opts, Rows::Fastest)
}

/// Which compilation of the row loop a render runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Rows {
    /// AVX2 and FMA where the CPU has them, else the baseline.
    Fastest,
    /// The baseline x86-64 code (what a CPU without AVX2 runs; tests compare the two).
    #[cfg_attr(not(test), allow(dead_code))]
    Baseline,
}

/// What a render composites: the blend weights (renormalised over the kept normals), the
/// normals kept, each layer's homography and each tile's layers, the budget's shares, and the
/// statistics known before any sample.
struct RenderPlan {
    weights: Vec<f32>,
    active: Vec<bool>,
    hs: Vec<Option<[f32; 9]>>,
    tiles: Vec<TilePlan>,
    share: f32,
    eps: f32,
    stats: RenderStats,
}

fn render_plan(mhi: &Mhi, target: &Camera, opts: &RenderOptions<'_>) -> Result<RenderPlan> {
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

fn render_rows_with(
    mhi: &Mhi,
    target: &Camera,
    opts: &RenderOptions<'_>,
    rows_kind: Rows,
) -> Result<Rendered> {
    let (n, d) = (mhi.n(), mhi.d());
    let (tw, th) = (target.width as usize, target.height as usize);
    let px = tw * th;
    let RenderPlan {
        weights,
        active,
        hs,
        tiles,
        share,
        eps,
        mut stats,
    } = render_plan(mhi, target, opts)?;
    let keep = opts.keep_multi_normal;
    // Each row: blended RGB (W·3) and, if kept, the N multi-normal rows (N·W·3).
    let ctx = RowContext {
        mhi,
        hs: &hs,
        active: &active,
        tiles: &tiles,
        weights: &weights,
        width: tw,
        pixels: px,
        rows: rows_kind,
        eps,
        share,
        keep,
    };
    // Bands of rows (a tile's height) are written in place: the blended image's and, when
    // kept, each multi-normal image's rows.
    let mut image = Rgb32FImage::new(target.width, target.height);
    let mut multi_normal = if keep {
        vec![Rgb32FImage::new(target.width, target.height); n]
    } else {
        Vec::new()
    };
    let band_len = (tw * 3 * TILE_H).max(1);
    let bands = th.div_ceil(TILE_H);
    let mut mni_bands: Vec<Vec<&mut [f32]>> = (0..bands).map(|_| Vec::with_capacity(n)).collect();
    for m in &mut multi_normal {
        for (b, r) in m.as_mut().chunks_mut(band_len).enumerate() {
            mni_bands[b].push(r);
        }
    }
    let done: usize = image
        .as_mut()
        .par_chunks_mut(band_len)
        .zip(mni_bands.par_iter_mut())
        .enumerate()
        .map(|(b, (rows, mni))| ctx.band(b * TILE_H, rows, mni))
        .sum();
    let visible_samples = px * (0..n * d).filter(|k| hs[*k].is_some()).count();
    stats.samples = if visible_samples > 0 {
        done as f32 / visible_samples as f32
    } else {
        1.0
    };
    Ok(Rendered {
        image,
        multi_normal,
        weights,
        stats,
    })
}

/// A tile that leaves out less layer mass than its share passes the rest on to its
/// transmittance stop: its pixels stop at `eps + share − mass`, so every pixel's bound is still
/// dropped weight + layer mass + stop ≤ the budget (0: no stop).
fn stop_at(tile: &TilePlan, eps: f32, share: f32) -> f32 {
    if eps > 0.0 {
        eps + (share - tile.mass).max(0.0)
    } else {
        0.0
    }
}

/// Ask the CPU to fetch `data[from..to]` into its caches: a hint, which changes no result.
///
/// An exact render of N · D layers reads, per band of rows, a few short rows of every layer
/// (N = 5, D = 32 at 256 × 256: 40 MB of alpha a view, 1 kB a row): too short for the
/// hardware prefetcher to see a stream, so each began with waits on memory. With every layer
/// read from one array that stays in the cache, the same render took a third less time;
/// prefetching the next layer's texels while one is composited got about 10 % of it back
/// (`docs/SPEED.md`).
#[inline(always)]
fn prefetch(data: &[f32], from: usize, to: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let to = to.min(data.len());
        let mut k = from.min(to);
        while k < to {
            // SAFETY: a prefetch never faults and changes no memory; the address is inside
            // `data`.
            #[allow(unsafe_code)]
            unsafe {
                use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
                _mm_prefetch::<_MM_HINT_T0>(data.as_ptr().add(k).cast());
            }
            k += 16;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (data, from, to);
}

/// One row of a band as it is composited, normal by normal.
struct BandRow {
    /// The row's `y + ½`.
    v: f32,
    /// Colour so far, four floats a pixel (RGB and an unused one).
    c: Vec<f32>,
    /// Transmittance so far.
    t: Vec<f32>,
    /// The transmittance at which each pixel stops.
    thr: Vec<f32>,
    /// Per tile: the span of its pixels still open.
    open: Vec<(usize, usize)>,
    /// Per tile: how far its layer list (near to far) has been walked.
    next: Vec<usize>,
}

/// What every row of a render reads.
struct RowContext<'a> {
    mhi: &'a Mhi,
    /// Target→reference homographies per layer (`None`: invisible).
    hs: &'a [Option<[f32; 9]>],
    /// Normals kept.
    active: &'a [bool],
    /// Tile plans, row-major.
    tiles: &'a [TilePlan],
    /// Normalised blend weights `N × H × W`.
    weights: &'a [f32],
    /// Target width and pixels.
    width: usize,
    pixels: usize,
    /// Which compilation of the row loop to run.
    rows: Rows,
    /// Transmittance stop and layer share of the budget.
    eps: f32,
    share: f32,
    /// Also return the multi-normal rows.
    keep: bool,
}

impl RowContext<'_> {
    /// The band of target rows from `y0` (a multiple of [`TILE_H`], at most that many rows):
    /// the blended RGB rows (W·3 each, zero on entry) into `out`, each kept multi-normal
    /// image's rows into `mni` (one slice a normal, or none); returns the samples composited.
    /// The rows of a band go through each layer one after the other, and while one layer is
    /// composited the texels of the next are prefetched (see [`prefetch`]). Compiled twice:
    /// for the baseline x86-64 and, picked at run time where the CPU has them, with AVX2 and
    /// FMA, where the bilinear mixes and the compositing fuse each multiply-add (`FUSED`: one
    /// rounding instead of two, a few units in the last place apart from the baseline's; the
    /// renders of the bench's scenes 6–9 % faster). Rust never fuses on its own, so each
    /// compilation is the composite of every sample in its own rounding, to the bit (tested).
    /// Each is also specialised on whether the render leaves anything out (`STOP`): an exact
    /// render's loop then has no stop tests, a pruned render's no pairs of layers, and neither
    /// shares its registers with the other's code.
    fn band(&self, y0: usize, out: &mut [f32], mni: &mut [&mut [f32]]) -> usize {
        #[cfg(target_arch = "x86_64")]
        if self.rows == Rows::Fastest && mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2 {
            // SAFETY: `band_avx2` only needs AVX2 and FMA, which the CPU was found to have.
            #[allow(unsafe_code)]
            return unsafe {
                if self.eps > 0.0 {
                    self.band_avx2::<true>(y0, out, mni)
                } else {
                    self.band_avx2::<false>(y0, out, mni)
                }
            };
        }
        if self.eps > 0.0 {
            self.band_generic::<false, true>(y0, out, mni)
        } else {
            self.band_generic::<false, false>(y0, out, mni)
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn band_avx2<const STOP: bool>(
        &self,
        y0: usize,
        out: &mut [f32],
        mni: &mut [&mut [f32]],
    ) -> usize {
        self.band_generic::<true, STOP>(y0, out, mni)
    }

    /// Colour of layer `k`, read straight from the images' RGB rows (three floats per texel):
    /// copying 160 per-layer images into padded texels cost more than the unaligned reads.
    #[inline(always)]
    fn color_of(&self, k: usize) -> &[f32] {
        match self.mhi.color() {
            LayerColor::Shared(img) => img.as_raw(),
            LayerColor::PerLayer(v) => v[k].as_raw(),
        }
    }

    #[inline(always)]
    fn band_generic<const FUSED: bool, const STOP: bool>(
        &self,
        y0: usize,
        out: &mut [f32],
        mni: &mut [&mut [f32]],
    ) -> usize {
        let (mhi, hs, active, tiles, weights) =
            (self.mhi, self.hs, self.active, self.tiles, self.weights);
        let (n, d, tw) = (mhi.n(), mhi.d(), self.width);
        let px = self.pixels;
        let (rw, rh) = (
            mhi.reference().width as usize,
            mhi.reference().height as usize,
        );
        let (eps, share, keep) = (self.eps, self.share, self.keep);
        let tiles_x = tw.div_ceil(TILE_W);
        let color_of = |k: usize| self.color_of(k);
        let stop_of = |tile: &TilePlan| stop_at(tile, eps, share);
        // Per row of the band, the normal's row so far: colour (RGB and an unused fourth
        // float a pixel), transmittance, the transmittance at which each pixel stops, and per
        // tile the span of its pixels still open and how far its layer list (near to far)
        // has been walked.
        let rows = out.len() / (3 * tw).max(1);
        let mut band_rows: Vec<BandRow> = (0..rows)
            .map(|r| BandRow {
                v: (y0 + r) as f32 + 0.5,
                c: vec![0.0_f32; tw * 4],
                t: vec![1.0_f32; tw],
                thr: vec![0.0_f32; tw],
                open: vec![(0_usize, 0_usize); tiles_x],
                next: vec![0_usize; tiles_x],
            })
            .collect();
        // Sample positions of the current run (pass 1), read by pass 2 right after.
        let (mut sxs, mut sys) = (vec![0.0_f32; tw], vec![0.0_f32; tw]);
        let (mut fxs, mut fys) = (vec![0.0_f32; tw], vec![0.0_f32; tw]);
        let mut idx = vec![0_u32; tw];
        // And of the second layer of a pair (exact renders).
        let (mut sxs2, mut sys2) = (vec![0.0_f32; tw], vec![0.0_f32; tw]);
        let (mut fxs2, mut fys2) = (vec![0.0_f32; tw], vec![0.0_f32; tw]);
        let mut idx2 = vec![0_u32; tw];
        let stop = STOP;
        debug_assert_eq!(STOP, eps > 0.0);
        // Without the multi-normal images only the blend is bounded: Σ_i w_i · stop_i within
        // the tile's stop share. Each kept normal spends an equal part of it, so a pixel's
        // normal stops at `share / (kept · w_i)` (a light normal stops early, a heavy one
        // late); with them, each normal's image is bounded on its own.
        let kept = active.iter().filter(|a| **a).count();
        let weighted = stop && !keep && kept > 1;

        // Pass 1 (vectorisable: sample positions of a row's pixels `p0..p1`, split into the
        // top-left texel index and the bilinear fractions; invalid samples, w ≤ ε, are sent
        // outside the image, where they read zero), pass 2's bilinear fetch (one window of
        // alpha and of colour per sample, so two bounds checks a sample; colour four floats a
        // tap, so that the mix and the compositing run four wide: a texel's RGB and one float
        // more, read inside the two texels, the right tap rotated from the float before it, the
        // fourth lane never read; the general zero-padded sampler for samples not wholly
        // inside) and one front-to-back compositing step. Macros, not functions: moved into
        // functions, the same code made the loop about 40 % slower.
        macro_rules! positions {
            ($h:ident, $v:expr, ($p0:expr, $p1:expr), $sxs:ident, $sys:ident, $fxs:ident, $fys:ident, $idx:ident) => {{
                let (h, v, p0, p1) = ($h, $v, $p0, $p1);
                let (bx, by, bw) = (h[1] * v + h[2], h[4] * v + h[5], h[7] * v + h[8]);
                let (wmax, hmax) = ((rw - 1) as f32, (rh - 1) as f32);
                let pass1 = $sxs[p0..p1]
                    .iter_mut()
                    .zip(&mut $sys[p0..p1])
                    .zip(&mut $fxs[p0..p1])
                    .zip(&mut $fys[p0..p1])
                    .zip(&mut $idx[p0..p1]);
                for (k, ((((sx_out, sy_out), fx), fy), ix)) in pass1.enumerate() {
                    let u = (p0 + k) as i32 as f32 + 0.5;
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
                    *sx_out = sx;
                    *sy_out = sy;
                    let inside = sx >= 0.0 && sy >= 0.0 && sx < wmax && sy < hmax;
                    let (xf, yf) = (floor_small(sx, inside), floor_small(sy, inside));
                    *fx = sx - xf;
                    *fy = sy - yf;
                    *ix = if inside {
                        small_to_u32(yf) * rw as u32 + small_to_u32(xf)
                    } else {
                        u32::MAX
                    };
                }
            }};
        }
        macro_rules! fetch {
            ($alpha:ident, $color:ident, $ix:expr, $fx:expr, $fy:expr, $sx:expr, $sy:expr) => {{
                let (ix, fx, fy, sx, sy) = ($ix, $fx, $fy, $sx, $sy);
                if ix != u32::MAX {
                    let i = ix as usize;
                    let w = bilinear::weights(fx, fy);
                    let wa = &$alpha[i..i + rw + 2];
                    let wc = &$color[3 * i..3 * (i + rw) + 6];
                    let [a] = bilinear::mix_as::<FUSED, 1>(
                        &w,
                        [[wa[0]], [wa[1]], [wa[rw]], [wa[rw + 1]]],
                    );
                    let (top, bot) = (&wc[..6], &wc[3 * rw..3 * rw + 6]);
                    let left = |t: &[f32]| [t[0], t[1], t[2], t[3]];
                    let right = |t: &[f32]| [t[3], t[4], t[5], t[2]];
                    let c = bilinear::mix_as::<FUSED, 4>(
                        &w,
                        [left(top), right(top), left(bot), right(bot)],
                    );
                    (a, c)
                } else {
                    let (a, [r, g, b]) = sample::<FUSED>($alpha, $color, rw, rh, sx, sy);
                    (a, [r, g, b, 0.0])
                }
            }};
        }
        macro_rules! composite {
            ($tx:ident, $cx:ident, $a:expr, $col:expr) => {{
                let ta = *$tx * $a;
                for (c, v) in $cx.iter_mut().zip($col) {
                    *c = if FUSED {
                        ta.mul_add(v, *c)
                    } else {
                        *c + ta * v
                    };
                }
                *$tx -= ta;
            }};
        }
        // Fetch layer `(i, j)`'s texels (and its colour, per layer) where the last layer's runs
        // read, `seen` widened by a row: a band reads a few short rows of each of N · D layers,
        // too short for the hardware to see a stream in. A macro, not a closure: whether LLVM
        // inlined the closure changed with edits elsewhere in the crate, and out of line it
        // made exact renders about 11 % slower (measured when it was introduced; see `docs/EXPERIMENTS.md`).
        macro_rules! prefetch_layer {
            ($i:expr, $j:expr, $seen:expr) => {{
                let (i, j, seen): (usize, usize, (usize, usize)) = ($i, $j, $seen);
                if seen.0 < seen.1 {
                    let (from, to) = (seen.0, seen.1 + rw + 2);
                    prefetch(mhi.alpha_layer(i, j), from, to);
                    if let LayerColor::PerLayer(_) = mhi.color() {
                        prefetch(color_of(i * d + j), 3 * from, 3 * to);
                    }
                }
            }};
        }
        let mut samples = 0_usize;
        let band = &tiles[(y0 / TILE_H) * tiles_x..][..tiles_x];
        let tile_stop: Vec<f32> = band.iter().map(stop_of).collect();
        // The texels (lowest, one past the highest) the last layer's runs read.
        let mut seen = (usize::MAX, 0_usize);
        for i in 0..n {
            if !active[i] {
                continue;
            }
            for (r, row) in band_rows.iter_mut().enumerate() {
                let y = y0 + r;
                row.c.fill(0.0);
                row.t.fill(1.0);
                let wrow = &weights[i * px + y * tw..i * px + (y + 1) * tw];
                if stop {
                    for (x, (th, w)) in row.thr.iter_mut().zip(wrow).enumerate() {
                        let s = tile_stop[x / TILE_W];
                        *th = if weighted { share_of(s, kept, *w) } else { s };
                    }
                }
                // A tile's span starts without the pixels that need nothing of this normal
                // (blended, a weight within the stop share).
                for (o, x_start) in row.open.iter_mut().zip((0..tw).step_by(TILE_W)) {
                    let span = (x_start, (x_start + TILE_W).min(tw));
                    *o = if stop {
                        open_span(span, &row.t, &row.thr)
                    } else {
                        span
                    };
                }
                row.next.fill(0);
            }
            // Layers near to far (each pixel still sees its layers in front-to-back order),
            // each across every row of the band; in a row, adjacent tiles that composite
            // layer j form one run. An exact render's runs are whole rows.
            let mut next_j = d;
            while next_j > 0 {
                next_j -= 1;
                let j = next_j;
                // An exact render composites every visible layer over whole rows: two layers
                // go through a row together, so that each pixel's colour and transmittance
                // are read and written once for both (in the same order: the same bits), and
                // the two layers after them are prefetched meanwhile. Pruned renders (runs,
                // stops) and a layer whose neighbour is not visible take the path after it.
                if let (false, true, Some(h1), Some(h2)) =
                    (stop, j > 0, hs[i * d + j], hs[i * d + j.saturating_sub(1)])
                {
                    let j2 = j - 1;
                    next_j = j2;
                    let far2 = j2 == 0;
                    let (alpha1, alpha2) = (mhi.alpha_layer(i, j), mhi.alpha_layer(i, j2));
                    let (color1, color2) = (color_of(i * d + j), color_of(i * d + j2));
                    for jn in j2.saturating_sub(2)..j2 {
                        prefetch_layer!(i, jn, seen);
                    }
                    seen = (usize::MAX, 0);
                    for row in &mut band_rows {
                        positions!(h1, row.v, (0, tw), sxs, sys, fxs, fys, idx);
                        positions!(h2, row.v, (0, tw), sxs2, sys2, fxs2, fys2, idx2);
                        let (x0, x1) = if far2 {
                            (0, tw)
                        } else {
                            let (a1, b1) = inside_span(&sxs, &sys, (0, tw), (rw, rh));
                            let (a2, b2) = inside_span(&sxs2, &sys2, (0, tw), (rw, rh));
                            (a1.min(a2), b1.max(b2))
                        };
                        samples += 2 * tw;
                        widen_reads(&mut seen, &idx[x0..x1]);
                        widen_reads(&mut seen, &idx2[x0..x1]);
                        let run = x0..x1;
                        let first = idx[run.clone()]
                            .iter()
                            .zip(fxs[run.clone()].iter().zip(&fys[run.clone()]))
                            .zip(sxs[run.clone()].iter().zip(&sys[run.clone()]));
                        let second = idx2[run.clone()]
                            .iter()
                            .zip(fxs2[run.clone()].iter().zip(&fys2[run.clone()]))
                            .zip(sxs2[run.clone()].iter().zip(&sys2[run.clone()]));
                        let pixels = row.t[run.clone()]
                            .iter_mut()
                            .zip(row.c[4 * x0..4 * x1].as_chunks_mut::<4>().0)
                            .zip(first.zip(second));
                        for (
                            (tx, cx),
                            (
                                ((&ix1, (&fx1, &fy1)), (&sx1, &sy1)),
                                ((&ix2, (&fx2, &fy2)), (&sx2, &sy2)),
                            ),
                        ) in pixels
                        {
                            let (a, col) = fetch!(alpha1, color1, ix1, fx1, fy1, sx1, sy1);
                            composite!(tx, cx, a, col);
                            let (a, col) = fetch!(alpha2, color2, ix2, fx2, fy2, sx2, sy2);
                            composite!(tx, cx, if far2 { 1.0 } else { a }, col);
                        }
                        for n in &mut row.next {
                            *n += 2;
                        }
                    }
                    continue;
                }
                let (h, far) = (hs[i * d + j].unwrap_or([0.0; 9]), j == 0);
                let alpha = mhi.alpha_layer(i, j);
                let color = color_of(i * d + j);
                // While this layer is composited, the next one's texels are fetched.
                if j > 0 {
                    prefetch_layer!(i, j - 1, seen);
                }
                seen = (usize::MAX, 0);
                for row in &mut band_rows {
                    let keeps = |k: usize, next: &[usize], open: &[(usize, usize)]| {
                        open[k].0 < open[k].1 && band[k].layers[i].get(next[k]) == Some(&j)
                    };
                    let mut k = 0;
                    while k < tiles_x {
                        if !keeps(k, &row.next, &row.open) {
                            k += 1;
                            continue;
                        }
                        let mut k_end = k + 1;
                        while k_end < tiles_x && keeps(k_end, &row.next, &row.open) {
                            k_end += 1;
                        }
                        // From the first open pixel of the run's first tile to the last of
                        // its last: pixels in between that stopped are passed over in pass 2.
                        let (x0, x1) = (row.open[k].0, row.open[k_end - 1].1);
                        // Pass 1 over whole groups of eight pixels (the AVX2 width; the extra
                        // positions are never read): a run of a pruned render starts and ends
                        // anywhere, and the scalar head and tail cost more than the lanes.
                        let (p0, p1) = (x0 & !7, ((x1 + 7) & !7).min(tw));
                        positions!(h, row.v, (p0, p1), sxs, sys, fxs, fys, idx);
                        // A sample whose four taps all lie outside the image reads zero
                        // alpha and colour: in front of the far layer it changes nothing (its
                        // `T · 0` adds no colour and takes no transmittance), so the run drops
                        // those at its ends and counts them as composited: the same bits, and
                        // an exact render's samples stay 100 %. (The far layer composites them:
                        // alpha 1, colour zero.)
                        let (x0, x1) = if far {
                            (x0, x1)
                        } else {
                            let (a, b) = inside_span(&sxs, &sys, (x0, x1), (rw, rh));
                            samples += open_count(&row.t, &row.thr, stop, x0..a)
                                + open_count(&row.t, &row.thr, stop, b..x1);
                            (a, b)
                        };
                        // The texels the run reads: where to prefetch the next layer.
                        widen_reads(&mut seen, &idx[x0..x1]);
                        // Pass 2: bilinear fetches and front-to-back compositing. Zipped slices
                        // and one window of alpha and of colour per sample, so that the loop
                        // checks two bounds a sample instead of a dozen.
                        let run = x0..x1;
                        let pixels = row.t[run.clone()]
                            .iter_mut()
                            .zip(&row.thr[run.clone()])
                            .zip(row.c[4 * x0..4 * x1].as_chunks_mut::<4>().0)
                            .zip(&idx[run.clone()])
                            .zip(fxs[run.clone()].iter().zip(&fys[run.clone()]))
                            .zip(sxs[run.clone()].iter().zip(&sys[run]));
                        for (((((tx, &th), cx), &ix), (&fx, &fy)), (&sx, &sy)) in pixels {
                            if stop && *tx <= th {
                                continue;
                            }
                            samples += 1;
                            let (a, col) = fetch!(alpha, color, ix, fx, fy, sx, sy);
                            composite!(tx, cx, if far { 1.0 } else { a }, col);
                        }
                        for kk in k..k_end {
                            row.next[kk] += 1;
                            if stop {
                                // The span of the tile's row still open (transmittance above
                                // its stop): pixels that stopped stay stopped, so it only
                                // shrinks; empty, farther layers cannot show there.
                                row.open[kk] = open_span(row.open[kk], &row.t, &row.thr);
                            }
                        }
                        k = k_end;
                    }
                }
            }
            for (r, row) in band_rows.iter_mut().enumerate() {
                // A pixel that stopped leaves out what lies behind, `t` times a colour in
                // [0, 1]; dropping it darkened every such pixel by up to its stop. It gets the
                // mean colour of the layers it composited instead (`c / (1 − t)`, their
                // weights summing to 1 − t): still within `t` of the exact pixel, but no longer
                // biased (on `re10k-3`, ΔPSNR at 8 levels −0.016 dB instead of −0.159).
                if stop {
                    for ((cx, &t), &th) in row.c.chunks_exact_mut(4).zip(&row.t).zip(&row.thr) {
                        if t > 0.0 && t <= th && t < 1.0 {
                            let s = 1.0 / (1.0 - t);
                            for v in &mut cx[..3] {
                                *v *= s;
                            }
                        }
                    }
                }
                let y = y0 + r;
                let wrow = &weights[i * px + y * tw..i * px + (y + 1) * tw];
                let o_row = &mut out[r * 3 * tw..(r + 1) * 3 * tw];
                for ((o, cx), w) in o_row
                    .chunks_exact_mut(3)
                    .zip(row.c.chunks_exact(4))
                    .zip(wrow)
                {
                    for k in 0..3 {
                        o[k] += w * cx[k];
                    }
                }
                if keep {
                    let m_row = &mut mni[i][r * 3 * tw..(r + 1) * 3 * tw];
                    for (m, cx) in m_row.chunks_exact_mut(3).zip(row.c.chunks_exact(4)) {
                        m.copy_from_slice(&cx[..3]);
                    }
                }
            }
        }
        samples
    }
}

/// The least share of the (target pixel, visible layer) samples any render within `budget` must
/// composite, under the accounting of [`Prune`]: an ideal plan that knew every pixel's exact
/// contributions — blend weight × transmittance × alpha of each sample, `weights` being the
/// normalised blend weights (`N × H × W`) — and left out, per pixel, the faintest samples while
/// their summed contributions stay within the budget. A render that charges each sample it
/// leaves out at least that much (as [`render`] does: colours differ by at most 1, its
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
fn least_share(mhi: &Mhi, target: &Camera, weights: Option<&[f32]>, budget: f32) -> f32 {
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

/// Bilinear sample of alpha and colour at pixel-index position `(sx, sy)` (pixel centres at
/// integers), zero outside the image (PyTorch's `grid_sample`, `align_corners=False`,
/// `padding_mode="zeros"`).
#[inline(always)]
fn sample<const FUSED: bool>(
    alpha: &[f32],
    color: &[f32],
    wd: usize,
    h: usize,
    sx: f32,
    sy: f32,
) -> (f32, [f32; 3]) {
    let [a, r, g, b] = sample_zero_padded::<FUSED, 4>(
        |i| [alpha[i], color[3 * i], color[3 * i + 1], color[3 * i + 2]],
        wd,
        h,
        sx,
        sy,
    );
    (a, [r, g, b])
}

/// 2²³: adding it to a float in [0, 2²³) rounds it to an integer (the spacing of floats there
/// is 1), and the integer is then the low bits of the sum.
const ROUNDER: f32 = 8_388_608.0;

/// `⌊s⌋` for `s` in `[0, 2²²)` when `ok` (0 otherwise), without a conversion to an integer: the
/// saturating `as` casts of Rust have no four-wide form on the baseline x86-64 target, and kept
/// the renderer's position pass from being vectorised.
#[inline(always)]
fn floor_small(s: f32, ok: bool) -> f32 {
    let s = if ok { s } else { 0.0 };
    let r = (s + ROUNDER) - ROUNDER; // s rounded to the nearest integer
    if r > s { r - 1.0 } else { r }
}

/// The integer `f` (a whole float in `[0, 2²³)`) as `u32`, by its bits.
#[inline(always)]
fn small_to_u32(f: f32) -> u32 {
    (f + ROUNDER).to_bits() - ROUNDER.to_bits()
}

/// Bilinear sample at `(sx, sy)` of the `wd × h` image whose texel `i` (row-major) is
/// `value(i)`, zero outside it (zero padding).
#[inline(always)]
fn sample_zero_padded<const FUSED: bool, const C: usize>(
    value: impl Fn(usize) -> [f32; C],
    wd: usize,
    h: usize,
    sx: f32,
    sy: f32,
) -> [f32; C] {
    if !touches_image(sx, sy, wd, h) {
        return [0.0; C];
    }
    // floor() without a libm call (the baseline x86-64 target has no SSE4.1 rounding): the
    // shifted value is positive, so truncation is the floor.
    let x0 = (sx + 1.0) as isize - 1;
    let y0 = (sy + 1.0) as isize - 1;
    let w = bilinear::weights(sx - x0 as f32, sy - y0 as f32);
    // Taps outside the image read zero (zero padding).
    let tap = |xx: isize, yy: isize| {
        if xx >= 0 && yy >= 0 && (xx as usize) < wd && (yy as usize) < h {
            value(yy as usize * wd + xx as usize)
        } else {
            [0.0; C]
        }
    };
    bilinear::mix_as::<FUSED, C>(
        &w,
        [
            tap(x0, y0),
            tap(x0 + 1, y0),
            tap(x0, y0 + 1),
            tap(x0 + 1, y0 + 1),
        ],
    )
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use mhi_geom::{Intrinsics, RigidTransform, depths_linear_in_disparity};

    #[test]
    fn soft_weights_row_by_row_are_the_per_pixel_weights() {
        // Off-centre principal point, non-square pixels, a turned target: every pixel's
        // weights against δ from `angle_cost_in_target` and `BlendHeuristic::weights`.
        let k = Intrinsics::new(23.0, 31.0, 14.0, 7.5).unwrap();
        let reference = Camera::new(k, RigidTransform::IDENTITY, 37, 23).unwrap();
        let rel = RigidTransform::new(
            DMat3::from_axis_angle(DVec3::new(0.3, 1.0, -0.4).normalize(), 0.6),
            DVec3::new(0.2, -0.05, 0.1),
        )
        .unwrap();
        let target = Camera::new(k, rel.inverse(), 29, 17).unwrap();
        let normals = mhi_geom::NormalSet::paper();
        let ours = heuristic_weights_for(&normals, &reference, &target, BlendHeuristic::Soft);
        let r = reference.from_other(&target).rotation();
        let (w, h, n) = (29, 17, normals.len());
        let mut worst = 0.0_f64;
        for y in 0..h {
            for x in 0..w {
                let ray = k.ray(mhi_geom::pixel_center(x, y));
                let deltas: Vec<f64> = normals
                    .normals()
                    .iter()
                    .map(|v| mhi_geom::angle_cost_in_target(*v, &r, ray).unwrap())
                    .collect();
                let want = BlendHeuristic::Soft.weights(&deltas);
                for (i, want) in want.iter().enumerate() {
                    let got = ours[i * (w * h) as usize + (y * w + x) as usize];
                    worst = worst.max((f64::from(got) - want).abs());
                }
            }
        }
        assert!(worst < 1e-7, "largest difference {worst:e}");
        // The AVX2 compilation gives the baseline's bits.
        let nt: Vec<DVec3> = normals
            .normals()
            .iter()
            .map(|v| (r.transpose() * *v).normalize())
            .collect();
        for y in 0..17 {
            let (mut a, mut b) = (vec![0.0_f32; n * 29], vec![0.0_f32; n * 29]);
            soft_row(&nt, &k, y, 29, &mut a);
            soft_row_generic(&nt, &k, y, 29, &mut b);
            assert!(a.iter().zip(&b).all(|(a, b)| a.to_bits() == b.to_bits()));
        }
    }

    #[test]
    fn the_avx2_rows_agree_with_the_baseline_rows() {
        // A small MHI with both colour layouts, seen turned and moved, exactly and pruned.
        let k = Intrinsics::new(20.0, 20.0, 18.0, 12.0).unwrap();
        let reference = Camera::new(k, RigidTransform::IDENTITY, 37, 23).unwrap();
        let rel = RigidTransform::new(
            DMat3::from_axis_angle(DVec3::new(0.3, 1.0, 0.1).normalize(), 0.2),
            DVec3::new(0.2, -0.05, 0.1),
        )
        .unwrap();
        let target = Camera::new(k, rel.inverse(), 41, 19).unwrap();
        let (n, d, px) = (3, 6, 37 * 23);
        let value = |i: usize| ((i * 7919) % 1000) as f32 / 999.0;
        let image = |seed: usize| {
            Rgb32FImage::from_fn(37, 23, |x, y| {
                let i = seed + (y * 37 + x) as usize * 3;
                image::Rgb([value(i), value(i + 1), value(i + 2)])
            })
        };
        for per_layer in [false, true] {
            let color = if per_layer {
                LayerColor::PerLayer((0..n * d).map(|l| image(l * 5000)).collect())
            } else {
                LayerColor::Shared(image(0))
            };
            let alpha = (0..n * d * px).map(|i| value(i * 3 + 1).powi(3)).collect();
            let mhi = Mhi::new(
                mhi_geom::NormalSet::paper_subset(n).unwrap(),
                depths_linear_in_disparity(1.0, 50.0, d).unwrap(),
                reference,
                color,
                alpha,
            )
            .unwrap();
            for prune in [Prune::NONE, Prune::DEFAULT] {
                let opts = RenderOptions {
                    prune,
                    keep_multi_normal: true,
                    ..Default::default()
                };
                let fast = render_rows_with(&mhi, &target, &opts, Rows::Fastest).unwrap();
                let base = render_rows_with(&mhi, &target, &opts, Rows::Baseline).unwrap();
                // The AVX2 rows fuse the mix's and the compositing's multiply-adds (one
                // rounding each), the baseline rounds twice: the last bits differ, a few
                // units in the last place of colours in [0, 1]. A pruned pixel whose
                // transmittance lands on its stop differently may composite one sample more
                // or less, which the budget bounds.
                let tol = if prune == Prune::NONE {
                    2e-6
                } else {
                    prune.budget
                };
                let worst = std::iter::once((&fast.image, &base.image))
                    .chain(fast.multi_normal.iter().zip(&base.multi_normal))
                    .flat_map(|(a, b)| a.as_raw().iter().zip(b.as_raw()))
                    .fold(0.0_f32, |m, (a, b)| m.max((a - b).abs()));
                assert!(worst <= tol, "{prune:?}: max |avx2 - baseline| = {worst:e}");
                assert_eq!(fast.stats.composited, base.stats.composited);
                assert!((fast.stats.samples - base.stats.samples).abs() < 0.01);
                if prune == Prune::NONE {
                    assert_eq!(fast.stats, base.stats);
                }
            }
        }
    }

    #[test]
    fn an_exact_render_is_every_sample_composited_to_the_bit() {
        // A target moved and turned far enough that most layers' samples fall outside the
        // reference image on one side (the run trims those) and inside on the other: every
        // multi-normal image must be, bit for bit, the front-to-back composite of every sample
        // through the general zero-padded sampler, and every sample must count.
        let k = Intrinsics::new(20.0, 20.0, 18.0, 12.0).unwrap();
        let reference = Camera::new(k, RigidTransform::IDENTITY, 37, 23).unwrap();
        // Seven layers: three pairs, then the far layer alone.
        let (n, d, px) = (3, 7, 37 * 23);
        let value = |i: usize| ((i * 7919) % 1000) as f32 / 999.0;
        let color = LayerColor::Shared(Rgb32FImage::from_fn(37, 23, |x, y| {
            let i = (y * 37 + x) as usize * 3;
            image::Rgb([value(i), value(i + 1), value(i + 2)])
        }));
        let alpha = (0..n * d * px).map(|i| value(i * 3 + 1)).collect();
        let mhi = Mhi::new(
            mhi_geom::NormalSet::paper_subset(n).unwrap(),
            depths_linear_in_disparity(1.0, 50.0, d).unwrap(),
            reference,
            color,
            alpha,
        )
        .unwrap();
        for (angle, t) in [
            (0.35, DVec3::new(0.6, -0.2, 0.1)),
            (-0.5, DVec3::new(-0.4, 0.3, -0.2)),
        ] {
            let rel = RigidTransform::new(
                DMat3::from_axis_angle(DVec3::new(0.2, 1.0, 0.1).normalize(), angle),
                t,
            )
            .unwrap();
            let target = Camera::new(k, rel.inverse(), 41, 19).unwrap();
            let opts = RenderOptions {
                keep_multi_normal: true,
                ..Default::default()
            };
            // The baseline rows round every product; the AVX2 rows (where the CPU has them)
            // fuse each multiply-add, and so does the composite they are held to here.
            #[cfg(target_arch = "x86_64")]
            let fused = mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2;
            #[cfg(not(target_arch = "x86_64"))]
            let fused = false;
            for (rows, fused) in [(Rows::Baseline, false), (Rows::Fastest, fused)] {
                let got = render_rows_with(&mhi, &target, &opts, rows).unwrap();
                assert_eq!(got.stats.samples, 1.0);
                let hs = layer_homographies(&mhi, &target);
                let mut outside = 0;
                for i in 0..n {
                    for y in 0..19 {
                        for x in 0..41 {
                            let visible = (0..d).rev().filter(|j| hs[i * d + j].is_some());
                            let (c, _, off) =
                                composite_of(&mhi, &hs, (i, x, y), visible, 0.0, fused);
                            outside += off;
                            let p = got.multi_normal[i].get_pixel(x, y).0;
                            assert_eq!(
                                p.map(f32::to_bits),
                                c.map(f32::to_bits),
                                "{rows:?} normal {i} pixel ({x}, {y})"
                            );
                        }
                    }
                }
                // The poses do send many samples off the image.
                assert!(outside > n * d * 41 * 19 / 10, "{outside} samples outside");
            }
        }
    }

    /// Pixel `(x, y)` of normal `i`'s image composited front to back over `layers` (near to
    /// far) the slow way: pass 1's arithmetic for the position, the general zero-padded
    /// sampler, the far layer opaque, no sample once the transmittance is at or below `stop`
    /// (0: never). Returns the colour, the samples composited and those wholly off the image.
    fn composite_of(
        mhi: &Mhi,
        hs: &[Option<[f32; 9]>],
        (i, x, y): (usize, u32, u32),
        layers: impl Iterator<Item = usize>,
        stop: f32,
        fused: bool,
    ) -> ([f32; 3], usize, usize) {
        let (rw, rh) = (
            mhi.reference().width as usize,
            mhi.reference().height as usize,
        );
        let color = match mhi.color() {
            LayerColor::Shared(img) => img.as_raw(),
            LayerColor::PerLayer(_) => unreachable!(),
        };
        let (mut t, mut c, mut composited, mut outside) = (1.0_f32, [0.0_f32; 3], 0, 0);
        for j in layers {
            if stop > 0.0 && t <= stop {
                continue;
            }
            let h = hs[i * mhi.d() + j].unwrap_or([0.0; 9]);
            let (u, v) = (x as i32 as f32 + 0.5, y as f32 + 0.5);
            let (bx, by, bw) = (h[1] * v + h[2], h[4] * v + h[5], h[7] * v + h[8]);
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
            let alpha = mhi.alpha_layer(i, j);
            let (a, col) = if fused {
                sample::<true>(alpha, color, rw, rh, sx, sy)
            } else {
                sample::<false>(alpha, color, rw, rh, sx, sy)
            };
            composited += 1;
            if !touches_image(sx, sy, rw, rh) {
                outside += 1;
            }
            let a = if j == 0 { 1.0 } else { a };
            let ta = t * a;
            for (c, v) in c.iter_mut().zip(col) {
                *c = if fused {
                    ta.mul_add(v, *c)
                } else {
                    *c + ta * v
                };
            }
            t -= ta;
        }
        // A pixel that stopped takes the mean colour of what it composited for what it left
        // out behind.
        if stop > 0.0 && t > 0.0 && t <= stop && t < 1.0 {
            let s = 1.0 / (1.0 - t);
            for v in &mut c {
                *v *= s;
            }
        }
        (c, composited, outside)
    }

    #[test]
    fn a_pruned_render_is_its_plans_samples_composited_to_the_bit() {
        // Layers faint in the reference's left half (the plan leaves them out of the tiles
        // that see only that half, so those tiles keep every other layer) and alphas that
        // stop most pixels before the far layer: every multi-normal image must be, bit for
        // bit, each pixel's tile's layers composited through the general sampler up to its
        // stop, whether the render takes them one or two at a time; every sample must count.
        let k = Intrinsics::new(30.0, 30.0, 30.0, 12.0).unwrap();
        let (rw, rh) = (61_u32, 23_u32);
        let reference = Camera::new(k, RigidTransform::IDENTITY, rw, rh).unwrap();
        let (n, d, px) = (2, 9, (rw * rh) as usize);
        let value = |i: usize| ((i * 7919) % 1000) as f32 / 999.0;
        let color = LayerColor::Shared(Rgb32FImage::from_fn(rw, rh, |x, y| {
            let i = (y * rw + x) as usize * 3;
            image::Rgb([value(i), value(i + 1), value(i + 2)])
        }));
        let alpha = (0..n * d * px)
            .map(|l| {
                let (j, x) = ((l / px) % d, (l % px) % rw as usize);
                if j % 2 == 1 && x < 40 {
                    0.0
                } else {
                    0.6 + 0.35 * value(l * 3 + 1)
                }
            })
            .collect();
        let mhi = Mhi::new(
            mhi_geom::NormalSet::paper_subset(n).unwrap(),
            depths_linear_in_disparity(1.0, 50.0, d).unwrap(),
            reference,
            color,
            alpha,
        )
        .unwrap();
        let rel = RigidTransform::new(
            DMat3::from_axis_angle(DVec3::new(0.1, 1.0, 0.0).normalize(), 0.05),
            DVec3::new(0.05, 0.02, 0.0),
        )
        .unwrap();
        let target = Camera::new(k, rel.inverse(), 64, 19).unwrap();
        let opts = RenderOptions {
            keep_multi_normal: true,
            prune: Prune::DEFAULT,
            ..Default::default()
        };
        let plan = render_plan(&mhi, &target, &opts).unwrap();
        let tiles_x = 64_usize.div_ceil(TILE_W);
        // The plan has tiles that keep two neighbouring layers and tiles that skip some.
        let lists = || plan.tiles.iter().flat_map(|t| &t.layers);
        assert!(lists().any(|l| l.windows(2).any(|w| w[0] == w[1] + 1)));
        assert!(lists().any(|l| l.len() < d));
        #[cfg(target_arch = "x86_64")]
        let fused = mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2;
        #[cfg(not(target_arch = "x86_64"))]
        let fused = false;
        for (rows, fused) in [(Rows::Baseline, false), (Rows::Fastest, fused)] {
            let got = render_rows_with(&mhi, &target, &opts, rows).unwrap();
            let (mut composited, mut stopped) = (0, 0);
            for i in 0..n {
                for y in 0..19 {
                    for x in 0..64 {
                        let tile =
                            &plan.tiles[(y as usize / TILE_H) * tiles_x + x as usize / TILE_W];
                        let stop = stop_at(tile, plan.eps, plan.share);
                        let layers = tile.layers[i].iter().copied();
                        let (c, m, _) =
                            composite_of(&mhi, &plan.hs, (i, x, y), layers, stop, fused);
                        composited += m;
                        stopped += usize::from(m < tile.layers[i].len());
                        let p = got.multi_normal[i].get_pixel(x, y).0;
                        assert_eq!(
                            p.map(f32::to_bits),
                            c.map(f32::to_bits),
                            "{rows:?} normal {i} pixel ({x}, {y})"
                        );
                    }
                }
            }
            let visible = 64 * 19 * plan.hs.iter().filter(|h| h.is_some()).count();
            assert_eq!(got.stats.samples, composited as f32 / visible as f32);
            // Most pixels stop before their tile's last layer.
            assert!(stopped > n * 64 * 19 / 2, "{stopped} pixels stopped");
        }
    }

    #[test]
    fn prefetch_takes_any_range_and_changes_nothing() {
        // Empty, reversed, past the end and whole ranges: a hint never reads outside the
        // slice (the addresses are clamped into it) and never writes.
        let data: Vec<f32> = (0..1000).map(|i| i as f32).collect();
        for (from, to) in [
            (0, 0),
            (10, 5),
            (990, 5000),
            (5000, 6000),
            (0, 1000),
            (3, 17),
        ] {
            prefetch(&data, from, to);
            prefetch(&[], from, to);
        }
        assert!(data.iter().enumerate().all(|(i, v)| *v == i as f32));
    }

    #[test]
    fn floor_small_is_the_floor_of_every_position_a_render_samples() {
        // Whole numbers, the floats just below and above them, halves (where rounding to the
        // nearest ties), and a sweep of the range of positions inside a large image.
        let mut values = vec![0.0_f32, 0.5, 1.5, 2.5, 4095.5, 4_194_303.0];
        for k in 0..5000_u32 {
            let f = k as f32;
            values.extend([f, f + 0.5, f.next_up(), (f + 1.0).next_down()]);
        }
        values.extend((0..100_000).map(|k| k as f32 * 0.0417));
        for s in values {
            let f = floor_small(s, true);
            assert_eq!(f, s.floor(), "floor of {s}");
            assert_eq!(small_to_u32(f), s.floor() as u32, "index of {s}");
        }
        assert_eq!(floor_small(123.4, false), 0.0);
    }
}
