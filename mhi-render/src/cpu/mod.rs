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
//! picked at run time (and where gathers are fast, `mhi_geom::simd::fast_gathers`, a third
//! time with pass 2 sixteen pixels at a time: `wide.rs`, AVX-512 gathers of tap pairs, the same
//! bits), and each specialised on `STOP` (whether the render leaves anything out: the
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

mod kernel;
mod options;
mod plan;
mod sample;
#[cfg(test)]
mod tests;
mod weights;
#[cfg(target_arch = "x86_64")]
mod wide;

pub use kernel::render;
pub use options::{Blend, Prune, RenderOptions, RenderStats, Rendered, W_EPS};
#[cfg(feature = "diff")]
pub(crate) use plan::row_major_f32;
pub use plan::{TILE_H, TILE_W, needed_share, needed_share_per_normal};
pub(crate) use plan::{layers_to_skip, normals_to_drop};
pub use weights::{combine, heuristic_weights, heuristic_weights_for};
