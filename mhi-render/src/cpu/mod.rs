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
mod kernel;
mod plan;
#[cfg(test)]
mod tests;
mod weights;

use kernel::*;
use plan::*;
pub use plan::{TILE_H, TILE_W, needed_share, needed_share_per_normal};
pub(crate) use plan::{layers_to_skip, normals_to_drop};
pub use weights::{heuristic_weights, heuristic_weights_for};

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

/// Render the MHI from `target` (the fast path).
///
/// # Errors
/// Only for invalid blend weights; degenerate geometry is masked (see [`RenderStats`]).
pub fn render(mhi: &Mhi, target: &Camera, opts: &RenderOptions<'_>) -> Result<Rendered> {
    render_rows_with(mhi, target, opts, Rows::Fastest)
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
