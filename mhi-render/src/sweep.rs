//! The plane-sweep volume (the source image seen on every plane from the reference view) and the
//! training-free "sweep" MHI built from its photo-consistency.

use image::Rgb32FImage;
use mhi_geom::{
    Camera, NormalSet, apply_homography, pixel_center, plane_homography_from_reference,
};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bilinear;
use crate::cpu::W_EPS;
use crate::error::{Error, Result};
use crate::mhi::{LayerColor, Mhi};

/// The source image warped onto each (normal, depth) plane into the reference view.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneSweepVolume {
    /// Number of normals.
    pub n: usize,
    /// Number of depths.
    pub d: usize,
    /// Reference width.
    pub width: u32,
    /// Reference height.
    pub height: u32,
    /// RGB, `[n][d][y][x][3]`; zero where invalid.
    pub rgb: Vec<f32>,
    /// 1 where the sample lies inside the source image and in front of the source camera.
    pub valid: Vec<f32>,
}

impl PlaneSweepVolume {
    /// The RGB slice of plane `(i, j)`.
    pub fn plane_rgb(&self, i: usize, j: usize) -> &[f32] {
        let px = self.width as usize * self.height as usize;
        let k = i * self.d + j;
        &self.rgb[k * px * 3..(k + 1) * px * 3]
    }
    /// The validity mask of plane `(i, j)`.
    pub fn plane_valid(&self, i: usize, j: usize) -> &[f32] {
        let px = self.width as usize * self.height as usize;
        let k = i * self.d + j;
        &self.valid[k * px..(k + 1) * px]
    }
}

/// Build the plane-sweep volume of `source` on the planes of `normals × depths` (far first) in
/// the frame of `reference`.
pub fn plane_sweep_volume(
    normals: &NormalSet,
    depths: &[f64],
    reference: &Camera,
    source_image: &Rgb32FImage,
    source: &Camera,
) -> Result<PlaneSweepVolume> {
    if source_image.dimensions() != (source.width, source.height) {
        return Err(Error::InvalidInput(format!(
            "source image is {}×{}, its camera {}×{}",
            source_image.width(),
            source_image.height(),
            source.width,
            source.height
        )));
    }
    let planes = normals.planes(depths).map_err(|source| Error::Geometry {
        context: "sweep planes".into(),
        source,
    })?;
    let src_from_ref = source.from_other(reference);
    let (w, h) = (reference.width as usize, reference.height as usize);
    let (sw, sh) = (source.width as usize, source.height as usize);
    let px = w * h;
    let src = source_image.as_raw();
    let per_plane: Vec<(Vec<f32>, Vec<f32>)> = planes
        .par_iter()
        .map(|plane| {
            let mut rgb = vec![0.0_f32; px * 3];
            let mut valid = vec![0.0_f32; px];
            let Ok(hm) = plane_homography_from_reference(
                &reference.intrinsics,
                &source.intrinsics,
                &src_from_ref,
                plane,
            ) else {
                return (rgb, valid);
            };
            for y in 0..h {
                for x in 0..w {
                    let Some(p) =
                        apply_homography(&hm, pixel_center(x as u32, y as u32), f64::from(W_EPS))
                    else {
                        continue;
                    };
                    let (sx, sy) = (p.x - 0.5, p.y - 0.5);
                    if !(sx >= 0.0 && sy >= 0.0 && sx <= (sw - 1) as f64 && sy <= (sh - 1) as f64) {
                        continue;
                    }
                    let (x0, y0) = (
                        (sx.floor() as usize).min(sw.saturating_sub(2)),
                        (sy.floor() as usize).min(sh.saturating_sub(2)),
                    );
                    let wts = bilinear::weights((sx - x0 as f64) as f32, (sy - y0 as f64) as f32);
                    let x1 = (x0 + 1).min(sw - 1);
                    let y1 = (y0 + 1).min(sh - 1);
                    let at = |xx: usize, yy: usize| -> [f32; 3] {
                        let i = (yy * sw + xx) * 3;
                        [src[i], src[i + 1], src[i + 2]]
                    };
                    let c = bilinear::mix(&wts, [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)]);
                    rgb[(y * w + x) * 3..][..3].copy_from_slice(&c);
                    valid[y * w + x] = 1.0;
                }
            }
            (rgb, valid)
        })
        .collect();
    let mut rgb = Vec::with_capacity(planes.len() * px * 3);
    let mut valid = Vec::with_capacity(planes.len() * px);
    for (r, v) in per_plane {
        rgb.extend(r);
        valid.extend(v);
    }
    Ok(PlaneSweepVolume {
        n: normals.len(),
        d: depths.len(),
        width: reference.width,
        height: reference.height,
        rgb,
        valid,
    })
}

/// Parameters of the training-free sweep MHI.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SweepConfig {
    /// Radius of the box window the photo-consistency cost is averaged over (4 → 9 × 9).
    pub window_radius: u32,
    /// Softmax temperature of the winner-take-all over depths, in units of mean absolute colour
    /// difference.
    pub temperature: f32,
    /// Cost of a plane where the source does not see the pixel.
    pub invalid_cost: f32,
}

/// The defaults were chosen on validation sequences only (`llff-6/room` and
/// `strecha-2/entry-p10`, held out of training; 16 triplets at a short side of 256 px, N = 5,
/// D = 32, by covered PSNR): a grid of window radius {2, 4, 6, 8, 10, 12, 16, 24, 32} ×
/// temperature {0.00125 … 0.04} (`xtask/scripts/tune_sweep.sh`, results in
/// `xtask/scripts/tune_sweep.csv`). Radius 16 with temperature 0.005 scored 20.38 dB [18.97,
/// 21.72]; the former 4 / 0.01 scored 19.56 dB, a paired gain of +0.82 dB [+0.50, +1.21].
/// Lower temperatures and wider windows help up to radius 16; 24 and 32 fall back (20.33,
/// 20.21 dB). The radius is in pixels: at other image sizes scale it with the short side.
impl SweepConfig {
    /// Short side (pixels) at which the default window radius was chosen.
    pub const TUNED_SHORT_SIDE: u32 = 256;

    /// The defaults with the window radius scaled from [`Self::TUNED_SHORT_SIDE`] to images
    /// whose short side is `short_side` pixels (at least 1): the same window in scene terms.
    pub fn for_short_side(short_side: u32) -> Self {
        let d = Self::default();
        let r = (f64::from(d.window_radius) * f64::from(short_side)
            / f64::from(Self::TUNED_SHORT_SIDE))
        .round()
        .max(1.0) as u32;
        Self {
            window_radius: r,
            ..d
        }
    }
}

impl Default for SweepConfig {
    fn default() -> Self {
        Self {
            window_radius: 16,
            temperature: 0.005,
            invalid_cost: 0.25,
        }
    }
}

/// Mean absolute difference box-filtered with radius `r` (integral image, clamped borders).
fn box_filter(cost: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut integral = vec![0.0_f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += f64::from(cost[y * w + x]);
            integral[(y + 1) * (w + 1) + x + 1] = integral[y * (w + 1) + x + 1] + row;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let s = integral[y1 * (w + 1) + x1]
                - integral[y0 * (w + 1) + x1]
                - integral[y1 * (w + 1) + x0]
                + integral[y0 * (w + 1) + x0];
            out[y * w + x] = (s / ((y1 - y0) * (x1 - x0)) as f64) as f32;
        }
    }
    out
}

/// Each channel of an interleaved RGB image minus its box-filtered local mean.
fn zero_mean(rgb: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut out = vec![0.0_f32; rgb.len()];
    for k in 0..3 {
        let ch: Vec<f32> = rgb.iter().skip(k).step_by(3).copied().collect();
        let mean = box_filter(&ch, w, h, r);
        for p in 0..w * h {
            out[3 * p + k] = ch[p] - mean[p];
        }
    }
    out
}

/// Turn per-depth probabilities (far first, summing to 1 at each pixel) into front-to-back
/// alphas: the nearest layer takes its probability, each farther layer the share of what is
/// left, the farthest everything that remains. Compositing these alphas gives back the
/// probabilities as the layers' visible weights.
pub fn alphas_from_probabilities(prob: &[f32], d: usize, px: usize, alpha: &mut [f32]) {
    for p in 0..px {
        let mut remaining = 1.0_f32;
        for j in (0..d).rev() {
            let pj = prob[j * px + p];
            let a = if j == 0 || remaining <= 1e-6 {
                1.0
            } else {
                (pj / remaining).clamp(0.0, 1.0)
            };
            alpha[j * px + p] = a;
            remaining = (remaining - pj).max(0.0);
        }
    }
}

/// Refuse a pair the sweep cannot measure depth from: no baseline, or a far plane so distant
/// against the baseline that the planes cannot be told apart.
pub fn check_parallax(reference: &Camera, source: &Camera, depths: &[f64]) -> Result<()> {
    // With no baseline every plane warps the source identically: the sweep has no parallax to
    // measure and would return an arbitrary depth.
    let baseline = (reference.center_in_world() - source.center_in_world()).length();
    let farthest = depths.iter().cloned().fold(1.0, f64::max);
    if !(baseline > 1e-9 * farthest) {
        return Err(Error::InvalidInput(if baseline > 0.0 && farthest > 1e6 {
            format!(
                "the farthest plane depth {farthest:e} is more than 1e9 times the baseline between the reference and source cameras ({baseline:e}); the planes cannot be told apart at that range: choose a far depth in the scene's units"
            )
        } else {
            format!(
                "zero baseline: the reference and source cameras are {baseline:e} apart, so the plane sweep has no parallax; choose views taken from different places"
            )
        }));
    }
    Ok(())
}

/// The training-free MHI: for each normal, photo-consistency of the plane-sweep volume against
/// the reference image, a soft winner-take-all over depths, turned into front-to-back alphas.
/// The reference image is the layers' colour.
pub fn sweep_mhi(
    normals: &NormalSet,
    depths: &[f64],
    reference: &Camera,
    reference_image: &Rgb32FImage,
    source: &Camera,
    source_image: &Rgb32FImage,
    cfg: &SweepConfig,
) -> Result<Mhi> {
    if reference_image.dimensions() != (reference.width, reference.height) {
        return Err(Error::InvalidInput(
            "reference image and camera sizes differ".into(),
        ));
    }
    check_parallax(reference, source, depths)?;
    let psv = plane_sweep_volume(normals, depths, reference, source_image, source)?;
    let alpha = sweep_alphas(&psv, reference_image, cfg)?;
    Mhi::new(
        normals.clone(),
        depths.to_vec(),
        *reference,
        LayerColor::Shared(reference_image.clone()),
        alpha,
    )
}

/// The sweep's alphas (`N · D · H · W`, normal-major, far first) from a plane-sweep volume on
/// the grid of `reference_image`: what [`sweep_mhi`] puts in its MHI.
pub fn sweep_alphas(
    psv: &PlaneSweepVolume,
    reference_image: &Rgb32FImage,
    cfg: &SweepConfig,
) -> Result<Vec<f32>> {
    if reference_image.dimensions() != (psv.width, psv.height) {
        return Err(Error::InvalidInput(format!(
            "reference image is {}×{}, the plane-sweep volume {}×{}",
            reference_image.width(),
            reference_image.height(),
            psv.width,
            psv.height
        )));
    }
    if !(cfg.temperature > 0.0) {
        return Err(Error::InvalidInput(format!(
            "sweep temperature must be > 0, got {}",
            cfg.temperature
        )));
    }
    let (w, h) = (psv.width as usize, psv.height as usize);
    let px = w * h;
    let (n, d) = (psv.n, psv.d);
    let refp = reference_image.as_raw();
    let mut alpha = vec![0.0_f32; n * d * px];
    alpha
        .par_chunks_mut(d * px)
        .enumerate()
        .for_each(|(i, out)| {
            let r = cfg.window_radius as usize;
            // Reference luminance-free colour with its local mean removed (zero-mean SAD): robust to
            // the exposure and white-balance changes between real photos.
            let ref_zm = zero_mean(refp, w, h, r);
            let costs: Vec<Vec<f32>> = (0..d)
                .map(|j| {
                    let rgb = psv.plane_rgb(i, j);
                    let valid = psv.plane_valid(i, j);
                    let src_zm = zero_mean(rgb, w, h, r);
                    let raw: Vec<f32> = (0..px)
                        .map(|p| {
                            if valid[p] > 0.0 {
                                (0..3)
                                    .map(|k| (src_zm[3 * p + k] - ref_zm[3 * p + k]).abs())
                                    .sum::<f32>()
                                    / 3.0
                            } else {
                                cfg.invalid_cost
                            }
                        })
                        .collect();
                    box_filter(&raw, w, h, r)
                })
                .collect();
            // Softmax over depths of −cost / τ (max subtracted).
            let mut prob = vec![0.0_f32; d * px];
            for p in 0..px {
                let m = (0..d)
                    .map(|j| -costs[j][p] / cfg.temperature)
                    .fold(f32::NEG_INFINITY, f32::max);
                let mut s = 0.0;
                for j in 0..d {
                    let e = (-costs[j][p] / cfg.temperature - m).exp();
                    prob[j * px + p] = e;
                    s += e;
                }
                for j in 0..d {
                    prob[j * px + p] /= s;
                }
            }
            alphas_from_probabilities(&prob, d, px, out);
        });
    Ok(alpha)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alphas_reproduce_the_probabilities_when_composited() {
        let (d, px) = (5, 1);
        let prob = [0.1_f32, 0.05, 0.5, 0.15, 0.2]; // far first
        let mut alpha = [0.0_f32; 5];
        alphas_from_probabilities(&prob, d, px, &mut alpha);
        // Front to back: visible weight of j = α_j Π_{nearer} (1 − α).
        let mut t = 1.0;
        for j in (0..d).rev() {
            let vis = alpha[j] * t;
            assert!(
                (vis - prob[j]).abs() < 1e-6,
                "layer {j}: {vis} vs {}",
                prob[j]
            );
            t *= 1.0 - alpha[j];
        }
        assert!(alpha.iter().all(|a| (0.0..=1.0).contains(a)));
    }

    #[test]
    fn a_pair_without_parallax_is_refused_naming_why() {
        use mhi_geom::{Intrinsics, RigidTransform};
        let k = Intrinsics::new(8.0, 8.0, 4.0, 4.0).unwrap();
        let at = |x: f64| {
            Camera::new(
                k,
                RigidTransform::new(glam::DMat3::IDENTITY, glam::DVec3::new(x, 0.0, 0.0)).unwrap(),
                8,
                8,
            )
            .unwrap()
        };
        let img = Rgb32FImage::new(8, 8);
        let normals = NormalSet::paper_subset(1).unwrap();
        let sweep = |src: &Camera, far: f64| {
            sweep_mhi(
                &normals,
                &mhi_geom::depths_linear_in_disparity(1.0, far, 4).unwrap(),
                &at(0.0),
                &img,
                src,
                &img,
                &SweepConfig::default(),
            )
            .unwrap_err()
            .to_string()
        };
        assert!(sweep(&at(0.0), 100.0).contains("zero baseline"));
        let e = sweep(&at(0.1), 1e30);
        assert!(
            e.contains("farthest plane depth") && !e.contains("zero baseline"),
            "{e}"
        );
    }

    #[test]
    fn box_filter_averages() {
        let c: Vec<f32> = (0..12).map(|v| v as f32).collect();
        let f = box_filter(&c, 4, 3, 1);
        assert!((f[5] - (0.0 + 1.0 + 2.0 + 4.0 + 5.0 + 6.0 + 8.0 + 9.0 + 10.0) / 9.0).abs() < 1e-6);
        assert!((f[0] - (0.0 + 1.0 + 4.0 + 5.0) / 4.0).abs() < 1e-6);
    }
}
