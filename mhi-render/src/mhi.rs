//! The Multiple Homography Image: N normals × D distances of RGBA layers on the reference grid.

use image::Rgb32FImage;
use mhi_geom::{Camera, NormalSet, Plane};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// The colour of the layers.
#[derive(Debug, Clone, PartialEq)]
pub enum LayerColor {
    /// The reference image is the colour of every layer (the paper's choice): a layer costs one
    /// alpha map.
    Shared(Rgb32FImage),
    /// One colour image per layer, normal-major (`index = normal · D + depth`).
    PerLayer(Vec<Rgb32FImage>),
}

/// An MHI: for each normal `i` and each depth `j` (far first), an alpha map on the reference
/// image grid, plus the layers' colour.
///
/// The farthest layer of each normal is treated as opaque when compositing (docs/METHOD.md), so its
/// stored alpha is ignored.
#[derive(Debug, Clone, PartialEq)]
pub struct Mhi {
    normals: NormalSet,
    depths: Vec<f64>,
    planes: Vec<Plane>,
    reference: Camera,
    color: LayerColor,
    alpha: Vec<f32>,
    layer_max: Vec<f32>,
    /// Smallest and largest alpha of each [`ALPHA_BLOCK`]² block of each layer
    /// (`N·D × ⌈H/B⌉ × ⌈W/B⌉`).
    block_range: Vec<(f32, f32)>,
}

/// Side, in reference pixels, of the square blocks whose smallest and largest alpha an [`Mhi`]
/// keeps per layer ([`Mhi::alpha_range_in`]): what lets a render skip a layer where it is faint
/// or hidden.
pub const ALPHA_BLOCK: usize = 8;

impl Mhi {
    /// Build and validate an MHI.
    ///
    /// `depths` are the depths where each normal's planes cross the reference optical axis,
    /// strictly decreasing (far first). `alpha` holds `N · D · H · W` values in `[0, 1]`,
    /// normal-major then depth then row-major pixels, with `H × W` the reference camera's size.
    pub fn new(
        normals: NormalSet,
        depths: Vec<f64>,
        reference: Camera,
        color: LayerColor,
        alpha: Vec<f32>,
    ) -> Result<Self> {
        let (w, h) = (reference.width, reference.height);
        let (n, d) = (normals.len(), depths.len());
        if d == 0 {
            return Err(Error::InvalidMhi("at least one depth is needed".into()));
        }
        if depths.iter().any(|z| !z.is_finite() || *z <= 0.0) {
            return Err(Error::InvalidMhi(format!(
                "depths must be finite and positive: {depths:?}"
            )));
        }
        if depths.windows(2).any(|p| p[1] >= p[0]) {
            return Err(Error::InvalidMhi(
                "depths must decrease strictly (far first)".into(),
            ));
        }
        let px = w as usize * h as usize;
        if alpha.len() != n * d * px {
            return Err(Error::InvalidMhi(format!(
                "expected {n}×{d}×{h}×{w} = {} alpha values, got {}",
                n * d * px,
                alpha.len()
            )));
        }
        if let Some(k) = first_failing(&alpha, |a| (0.0..=1.0).contains(&a)) {
            return Err(Error::InvalidMhi(format!(
                "alpha must lie in [0, 1]; value {} at layer {}, pixel {}",
                alpha[k],
                k / px,
                k % px
            )));
        }
        match &color {
            LayerColor::Shared(img) => check_size(img, w, h, "reference colour")?,
            LayerColor::PerLayer(v) => {
                if v.len() != n * d {
                    return Err(Error::InvalidMhi(format!(
                        "expected {} per-layer colour images, got {}",
                        n * d,
                        v.len()
                    )));
                }
                for img in v {
                    check_size(img, w, h, "layer colour")?;
                }
            }
        }
        let planes = normals.planes(&depths).map_err(|source| Error::Geometry {
            context: "MHI planes".into(),
            source,
        })?;
        let block_range = block_ranges(&alpha, w as usize, h as usize);
        let per_layer = block_range.len() / (n * d).max(1);
        let layer_max = block_range
            .chunks(per_layer.max(1))
            .map(|l| l.iter().fold(0.0_f32, |m, a| m.max(a.1)))
            .collect();
        Ok(Self {
            normals,
            depths,
            planes,
            reference,
            color,
            alpha,
            layer_max,
            block_range,
        })
    }

    /// The normals.
    pub fn normals(&self) -> &NormalSet {
        &self.normals
    }
    /// The depths, far first.
    pub fn depths(&self) -> &[f64] {
        &self.depths
    }
    /// Number of normals N.
    pub fn n(&self) -> usize {
        self.normals.len()
    }
    /// Number of depths D.
    pub fn d(&self) -> usize {
        self.depths.len()
    }
    /// The reference camera (the layers' grid).
    pub fn reference(&self) -> &Camera {
        &self.reference
    }
    /// The layers' colour.
    pub fn color(&self) -> &LayerColor {
        &self.color
    }
    /// All alpha values (normal-major, then depth, then row-major pixels).
    pub fn alpha(&self) -> &[f32] {
        &self.alpha
    }
    /// The plane of layer `(normal, depth)`.
    pub fn plane(&self, normal: usize, depth: usize) -> &Plane {
        &self.planes[normal * self.d() + depth]
    }
    /// The alpha map of layer `(normal, depth)`, row-major.
    pub fn alpha_layer(&self, normal: usize, depth: usize) -> &[f32] {
        let px = self.reference.width as usize * self.reference.height as usize;
        let k = normal * self.d() + depth;
        &self.alpha[k * px..(k + 1) * px]
    }
    /// The largest alpha of layer `(normal, depth)`.
    pub fn layer_max_alpha(&self, normal: usize, depth: usize) -> f32 {
        self.layer_max[normal * self.d() + depth]
    }

    /// Bounds `(lo, hi)` of the alpha of layer `(normal, depth)` over the reference pixels
    /// `x0..=x1` × `y0..=y1` (clamped to the image): the smallest and largest alpha of the
    /// [`ALPHA_BLOCK`]² blocks the rectangle touches. `(1, 0)` for an empty rectangle.
    pub fn alpha_range_in(
        &self,
        normal: usize,
        depth: usize,
        (x0, y0): (usize, usize),
        (x1, y1): (usize, usize),
    ) -> (f32, f32) {
        let (w, h) = (
            self.reference.width as usize,
            self.reference.height as usize,
        );
        let (x1, y1) = (x1.min(w.saturating_sub(1)), y1.min(h.saturating_sub(1)));
        if w == 0 || h == 0 || x0 > x1 || y0 > y1 {
            return (1.0, 0.0);
        }
        let (bw, bh) = (w.div_ceil(ALPHA_BLOCK), h.div_ceil(ALPHA_BLOCK));
        let layer = &self.block_range[(normal * self.d() + depth) * bw * bh..][..bw * bh];
        let (mut lo, mut hi) = (1.0_f32, 0.0_f32);
        for by in y0 / ALPHA_BLOCK..=y1 / ALPHA_BLOCK {
            for v in &layer[by * bw + x0 / ALPHA_BLOCK..=by * bw + x1 / ALPHA_BLOCK] {
                lo = lo.min(v.0);
                hi = hi.max(v.1);
            }
        }
        (lo, hi)
    }
}

impl Mhi {
    /// The expected disparity (1 / depth) seen from the reference camera through normal `i`'s
    /// layers: each layer's visible weight `α_j Π_{nearer} (1 − α)` times the disparity where its
    /// plane meets the pixel's ray. Rays that miss a plane in front count it at disparity 0.
    pub fn expected_disparity(&self, normal: usize) -> Vec<f32> {
        let (w, h) = (self.reference.width, self.reference.height);
        let n = self.normals.normals()[normal];
        let d = self.d();
        let mut out = vec![0.0_f32; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let p = (y * w + x) as usize;
                let ray = self.reference.intrinsics.ray(mhi_geom::pixel_center(x, y));
                let cos = n.dot(ray).max(0.0);
                let mut t = 1.0_f64;
                let mut acc = 0.0_f64;
                for j in (0..d).rev() {
                    let a = if j == 0 {
                        1.0
                    } else {
                        f64::from(self.alpha_layer(normal, j)[p])
                    };
                    acc += t * a * cos / self.plane(normal, j).d();
                    t *= 1.0 - a;
                }
                out[p] = acc as f32;
            }
        }
        out
    }
}

/// The smallest and largest alpha of every [`ALPHA_BLOCK`]² block of every layer of `alpha`
/// (layers of `w × h`), layer-major then block rows.
fn block_ranges(alpha: &[f32], w: usize, h: usize) -> Vec<(f32, f32)> {
    let (bw, bh) = (w.div_ceil(ALPHA_BLOCK), h.div_ceil(ALPHA_BLOCK));
    let px = w * h;
    if px == 0 {
        return Vec::new();
    }
    let mut out = vec![(1.0_f32, 0.0_f32); alpha.len() / px * bw * bh];
    out.par_chunks_mut(bw * bh)
        .zip(alpha.par_chunks(px))
        .for_each(|(blocks, layer)| {
            for (y, row) in layer.chunks(w).enumerate() {
                let brow = &mut blocks[(y / ALPHA_BLOCK) * bw..][..bw];
                for (b, chunk) in brow.iter_mut().zip(row.chunks(ALPHA_BLOCK)) {
                    *b = chunk
                        .iter()
                        .fold(*b, |(lo, hi), a| (lo.min(*a), hi.max(*a)));
                }
            }
        });
    out
}

/// Index of the first value of `values` for which `ok` is false, if any.
///
/// Scans chunks of 64 Ki values in parallel and each chunk in one branch-free pass; only the
/// chunk that fails is searched value by value. (Rayon's `position_first` value by value took
/// about 80 ms on the 9 M alphas of an N = 5, D = 16 MHI at 448 × 256, a quarter of a sweep
/// view; this takes a few.)
pub fn first_failing(values: &[f32], ok: impl Fn(f32) -> bool + Sync) -> Option<usize> {
    const CHUNK: usize = 1 << 16;
    let chunk = values
        .par_chunks(CHUNK)
        .position_first(|c| !c.iter().fold(true, |all, &v| all & ok(v)))?;
    let start = chunk * CHUNK;
    values[start..]
        .iter()
        .position(|&v| !ok(v))
        .map(|k| start + k)
}

fn check_size(img: &Rgb32FImage, w: u32, h: u32, what: &str) -> Result<()> {
    if img.dimensions() != (w, h) {
        return Err(Error::InvalidMhi(format!(
            "{what} is {}×{}, the reference camera is {w}×{h}",
            img.width(),
            img.height()
        )));
    }
    if img.as_raw().iter().any(|v| !v.is_finite()) {
        return Err(Error::InvalidMhi(format!(
            "{what} holds NaN or infinite values"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::first_failing;

    #[test]
    fn first_failing_finds_the_first_bad_value_across_chunks() {
        let chunk = 1 << 16;
        let ok = |v: f32| (0.0..=1.0).contains(&v);
        let mut v = vec![0.5_f32; 5 * chunk + 123];
        assert_eq!(first_failing(&v, ok), None);
        assert_eq!(first_failing(&[], ok), None);
        // Bad values in several chunks: the first one is found, whichever chunk finishes first.
        for &(k, bad) in &[
            (5 * chunk + 122, 1.5),
            (3 * chunk + 7, f32::NAN),
            (chunk, -0.0001),
            (chunk - 1, f32::INFINITY),
        ] {
            v[k] = bad;
            assert_eq!(first_failing(&v, ok), Some(k), "bad value at {k}");
        }
        v[0] = -1.0;
        assert_eq!(first_failing(&v, ok), Some(0));
    }
}
