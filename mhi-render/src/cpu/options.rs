//! What a render is asked for and what it answers: the blend, the render plan's budget, the
//! options, the statistics and the rendered view.

use image::Rgb32FImage;
use mhi_geom::BlendHeuristic;
use serde::{Deserialize, Serialize};

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
/// - **layers** — per render tile of [`TILE_W`](crate::TILE_W) × [`TILE_H`](crate::TILE_H) target pixels and per normal,
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
    /// render plans per tile of [`TILE_W`](crate::TILE_W) × [`TILE_H`](crate::TILE_H) target pixels and skips, in each tile,
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
