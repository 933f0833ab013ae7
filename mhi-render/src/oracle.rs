//! The oracle MHI of a scene with known geometry: each reference pixel goes to the layer nearest
//! its true surface, so rendering it measures the representation's error alone, with no network.

use glam::DVec3;
use mhi_geom::{Camera, NormalSet, pixel_center};

/// The true surface seen at one pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelTruth {
    /// Unit normal of the surface in the camera frame (either orientation).
    pub normal: DVec3,
    /// Depth (camera z) of the surface point on the pixel's centre ray.
    pub depth: f64,
}

/// Oracle alphas `N × D × H × W` for `reference`: for every normal, each pixel is opaque on the
/// layer of that normal whose plane meets the pixel's ray nearest (in disparity) to the true
/// depth, and transparent on the others. Pixels without truth fall to the farthest layer.
pub fn oracle_alpha(
    normals: &NormalSet,
    depths: &[f64],
    reference: &Camera,
    truth: &[Option<PixelTruth>],
) -> Vec<f32> {
    let (w, h) = (reference.width, reference.height);
    let px = w as usize * h as usize;
    let d = depths.len();
    let mut alpha = vec![0.0_f32; normals.len() * d * px];
    for (i, n) in normals.normals().iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                let p = (y * w + x) as usize;
                let Some(t) = truth.get(p).copied().flatten() else {
                    continue;
                };
                let ray = reference.intrinsics.ray(pixel_center(x, y));
                let cos = n.dot(ray);
                if !(cos > 1e-9) {
                    continue;
                }
                let target = 1.0 / t.depth;
                // Plane j (d_j = z_j n_z) meets the ray (z = 1) at depth d_j / (n·ray).
                let best = (0..d)
                    .min_by(|a, b| {
                        let e = |j: usize| (cos / (depths[j] * n.z) - target).abs();
                        e(*a).total_cmp(&e(*b))
                    })
                    .unwrap_or(0);
                alpha[(i * d + best) * px + p] = 1.0;
            }
        }
    }
    alpha
}

/// Oracle blending weights `N × H × W` on the target grid: one-hot on the normal closest to the
/// true surface normal, given per target pixel in the reference frame. Pixels without truth get
/// equal weights.
pub fn oracle_weights(normals: &NormalSet, true_normals_in_ref: &[Option<DVec3>]) -> Vec<f32> {
    let n = normals.len();
    let px = true_normals_in_ref.len();
    let mut out = vec![0.0_f32; n * px];
    for (p, t) in true_normals_in_ref.iter().enumerate() {
        match t {
            Some(tn) => {
                let best = (0..n)
                    .max_by(|a, b| {
                        normals.normals()[*a]
                            .dot(*tn)
                            .abs()
                            .total_cmp(&normals.normals()[*b].dot(*tn).abs())
                    })
                    .unwrap_or(0);
                out[best * px + p] = 1.0;
            }
            None => (0..n).for_each(|i| out[i * px + p] = 1.0 / n as f32),
        }
    }
    out
}
