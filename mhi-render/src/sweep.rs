//! The plane-sweep volume (the source image seen on every plane from the reference view) and the
//! training-free "sweep" MHI built from its photo-consistency.

use image::Rgb32FImage;
use mhi_geom::{Camera, NormalSet, plane_homography_from_reference};
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
    // One allocation filled in place, plane by plane in parallel (allocating each plane and
    // concatenating them cost as much as the sampling).
    let mut rgb = vec![0.0_f32; planes.len() * px * 3];
    let mut valid = vec![0.0_f32; planes.len() * px];
    rgb.par_chunks_mut((px * 3).max(1))
        .zip(valid.par_chunks_mut(px.max(1)))
        .zip(planes.par_iter())
        .for_each(|((rgb, valid), plane)| {
            let Ok(hm) = plane_homography_from_reference(
                &reference.intrinsics,
                &source.intrinsics,
                &src_from_ref,
                plane,
            ) else {
                return;
            };
            // p = H · (u, v, 1) in the order of glam's `DMat3 * DVec3` (x column, then y, then
            // z), with the y and z columns summed once per row: the same f64 values as
            // `apply_homography`, without a call per pixel.
            let (xa, ya, za) = (hm.x_axis, hm.y_axis, hm.z_axis);
            let (xmax, ymax) = (sw.saturating_sub(2), sh.saturating_sub(2));
            let (sx_max, sy_max) = ((sw - 1) as f64, (sh - 1) as f64);
            let (mut sxs, mut sys, mut oks) = (vec![0.0_f64; w], vec![0.0_f64; w], vec![false; w]);
            for y in 0..h {
                let v = y as f64 + 0.5;
                let yv = ya * v;
                // Pass 1 (vectorisable): sample positions of the row and whether all four taps
                // are inside the source (an infinite or NaN position fails the range test).
                for (x, ((sx_out, sy_out), ok_out)) in
                    sxs.iter_mut().zip(&mut sys).zip(&mut oks).enumerate()
                {
                    let u = x as i32 as f64 + 0.5;
                    let p = (xa * u + yv) + za;
                    let (sx, sy) = (p.x / p.z - 0.5, p.y / p.z - 0.5);
                    *ok_out = p.z > f64::from(W_EPS)
                        && sx >= 0.0
                        && sy >= 0.0
                        && sx <= sx_max
                        && sy <= sy_max;
                    (*sx_out, *sy_out) = (sx, sy);
                }
                // Pass 2: bilinear fetches.
                let (rgb_row, valid_row) = (
                    &mut rgb[y * w * 3..(y + 1) * w * 3],
                    &mut valid[y * w..(y + 1) * w],
                );
                for ((((out, ok), &inside), &sx), &sy) in rgb_row
                    .chunks_exact_mut(3)
                    .zip(valid_row.iter_mut())
                    .zip(&oks)
                    .zip(&sxs)
                    .zip(&sys)
                {
                    if !inside {
                        continue;
                    }
                    let (x0, y0) = (floor_index(sx).min(xmax), floor_index(sy).min(ymax));
                    let wts = bilinear::weights((sx - x0 as f64) as f32, (sy - y0 as f64) as f32);
                    let x1 = (x0 + 1).min(sw - 1);
                    let y1 = (y0 + 1).min(sh - 1);
                    let at = |xx: usize, yy: usize| -> [f32; 3] {
                        let i = (yy * sw + xx) * 3;
                        [src[i], src[i + 1], src[i + 2]]
                    };
                    let c = bilinear::mix(&wts, [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)]);
                    out.copy_from_slice(&c);
                    *ok = 1.0;
                }
            }
        });
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
        Self::default().scaled_to_short_side(short_side)
    }

    /// These constants with the window radius, given at a short side of
    /// [`Self::TUNED_SHORT_SIDE`], scaled to images whose short side is `short_side` pixels
    /// (the radius at least 1).
    pub fn scaled_to_short_side(self, short_side: u32) -> Self {
        let r = (f64::from(self.window_radius) * f64::from(short_side)
            / f64::from(Self::TUNED_SHORT_SIDE))
        .round()
        .max(1.0) as u32;
        Self {
            window_radius: r,
            ..self
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

/// `⌊s⌋` of `0 ≤ s < 2⁵¹` as an index, without the libm call `f64::floor` makes on the baseline
/// x86-64 target: adding 2⁵² rounds `s` to an integer (the spacing of doubles there is 1).
#[inline(always)]
fn floor_index(s: f64) -> usize {
    const ROUNDER: f64 = 4_503_599_627_370_496.0; // 2⁵²
    let r = (s + ROUNDER) - ROUNDER;
    let f = if r > s { r - 1.0 } else { r };
    ((f + ROUNDER).to_bits() - ROUNDER.to_bits()) as usize
}

/// The mean of each channel of an interleaved `C`-channel image over the `(2r + 1)²` window
/// around each pixel, clamped at the borders (the window shrinks; it is not padded).
///
/// Separable running sums in f64: a column sum per pixel of the row, moved down a row at a
/// time, then a sum along the row. The inputs are f32, so the sums of a window are exact in f64
/// for colours (and the same as through an integral image) whatever the order.
fn box_mean<const C: usize>(src: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut out = vec![0.0_f32; src.len()];
    if w == 0 || h == 0 {
        return out;
    }
    let row = |y: usize| &src[y * w * C..(y + 1) * w * C];
    let mut col = vec![0.0_f64; w * C];
    for y in 0..(r + 1).min(h) {
        col.iter_mut()
            .zip(row(y))
            .for_each(|(c, v)| *c += f64::from(*v));
    }
    for y in 0..h {
        if y > 0 {
            if y + r < h {
                col.iter_mut()
                    .zip(row(y + r))
                    .for_each(|(c, v)| *c += f64::from(*v));
            }
            if y > r {
                col.iter_mut()
                    .zip(row(y - r - 1))
                    .for_each(|(c, v)| *c -= f64::from(*v));
            }
        }
        let rows = ((y + r + 1).min(h) - y.saturating_sub(r)) as f64;
        let dst = &mut out[y * w * C..(y + 1) * w * C];
        let mut sum = [0.0_f64; C];
        for x in 0..(r + 1).min(w) {
            for k in 0..C {
                sum[k] += col[x * C + k];
            }
        }
        for x in 0..w {
            if x > 0 {
                if x + r < w {
                    for k in 0..C {
                        sum[k] += col[(x + r) * C + k];
                    }
                }
                if x > r {
                    for k in 0..C {
                        sum[k] -= col[(x - r - 1) * C + k];
                    }
                }
            }
            let n = rows * ((x + r + 1).min(w) - x.saturating_sub(r)) as f64;
            for k in 0..C {
                dst[x * C + k] = (sum[k] / n) as f32;
            }
        }
    }
    out
}

/// Mean absolute difference box-filtered with radius `r` (clamped borders).
fn box_filter(cost: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    box_mean::<1>(cost, w, h, r)
}

/// Each channel of an interleaved RGB image minus its box-filtered local mean.
fn zero_mean(rgb: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    let mut out = box_mean::<3>(rgb, w, h, r);
    out.iter_mut().zip(rgb).for_each(|(m, v)| *m = v - *m);
    out
}

/// Turn per-depth probabilities (far first, summing to 1 at each pixel) into front-to-back
/// alphas: the nearest layer takes its probability, each farther layer the share of what is
/// left, the farthest everything that remains. Compositing these alphas gives back the
/// probabilities as the layers' visible weights.
pub fn alphas_from_probabilities(prob: &[f32], d: usize, px: usize, alpha: &mut [f32]) {
    // A plane at a time, near to far, every pixel's remaining share carried along.
    let mut remaining = vec![1.0_f32; px];
    for j in (0..d).rev() {
        let (pj, aj) = (
            &prob[j * px..(j + 1) * px],
            &mut alpha[j * px..(j + 1) * px],
        );
        for ((a, pj), rem) in aj.iter_mut().zip(pj).zip(&mut remaining) {
            *a = if j == 0 || *rem <= 1e-6 {
                1.0
            } else {
                (pj / *rem).clamp(0.0, 1.0)
            };
            *rem = (*rem - pj).max(0.0);
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
    let r = cfg.window_radius as usize;
    // Reference colour with its local mean removed (zero-mean SAD): robust to the exposure and
    // white-balance changes between real photos.
    let ref_zm = zero_mean(refp, w, h, r);
    // The aggregated cost of every plane, planes in parallel.
    let mut costs = vec![0.0_f32; n * d * px];
    costs
        .par_chunks_mut(px.max(1))
        .enumerate()
        .for_each(|(k, out)| {
            let (i, j) = (k / d, k % d);
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
            out.copy_from_slice(&box_filter(&raw, w, h, r));
        });
    let mut alpha = vec![0.0_f32; n * d * px];
    alpha
        .par_chunks_mut((d * px).max(1))
        .zip(costs.par_chunks((d * px).max(1)))
        .for_each(|(out, costs)| {
            // Softmax over depths of −cost / τ (max subtracted), a plane at a time.
            let mut prob: Vec<f32> = costs.iter().map(|c| -c / cfg.temperature).collect();
            let mut m = vec![f32::NEG_INFINITY; px];
            for z in prob.chunks_exact(px.max(1)) {
                m.iter_mut().zip(z).for_each(|(m, z)| *m = m.max(*z));
            }
            let mut sum = vec![0.0_f32; px];
            for z in prob.chunks_exact_mut(px.max(1)) {
                for ((z, m), s) in z.iter_mut().zip(&m).zip(&mut sum) {
                    *z = (*z - m).exp();
                    *s += *z;
                }
            }
            for z in prob.chunks_exact_mut(px.max(1)) {
                z.iter_mut().zip(&sum).for_each(|(z, s)| *z /= s);
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
    fn box_mean_is_the_mean_over_the_clamped_window() {
        // Brute force over every window, for radii below, at and beyond the image's sides.
        for (w, h, r) in [
            (7, 5, 0),
            (7, 5, 1),
            (7, 5, 2),
            (9, 4, 3),
            (3, 8, 5),
            (1, 1, 2),
        ] {
            let img: Vec<f32> = (0..w * h * 3)
                .map(|k| ((k * 7919) % 101) as f32 / 101.0)
                .collect();
            let mean = box_mean::<3>(&img, w, h, r);
            for y in 0..h {
                for x in 0..w {
                    for k in 0..3 {
                        let (mut s, mut n) = (0.0_f64, 0);
                        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                            for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                                s += f64::from(img[(yy * w + xx) * 3 + k]);
                                n += 1;
                            }
                        }
                        let want = (s / f64::from(n)) as f32;
                        let got = mean[(y * w + x) * 3 + k];
                        assert!(
                            (got - want).abs() <= 1e-6,
                            "{w}x{h} r {r} at ({x}, {y}): {got} vs {want}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn floor_index_is_the_floor() {
        for k in 0..20_000_u32 {
            let f = f64::from(k);
            for s in [f, f + 0.25, f + 0.5, f.next_up(), (f + 1.0).next_down()] {
                assert_eq!(floor_index(s), s.floor() as usize, "{s}");
            }
        }
    }

    #[test]
    fn box_filter_averages() {
        let c: Vec<f32> = (0..12).map(|v| v as f32).collect();
        let f = box_filter(&c, 4, 3, 1);
        assert!((f[5] - (0.0 + 1.0 + 2.0 + 4.0 + 5.0 + 6.0 + 8.0 + 9.0 + 10.0) / 9.0).abs() < 1e-6);
        assert!((f[0] - (0.0 + 1.0 + 4.0 + 5.0) / 4.0).abs() < 1e-6);
    }
}
