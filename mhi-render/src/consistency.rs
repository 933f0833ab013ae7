//! Photo-consistency of each normal's geometry, a blend cue that needs no training.
//!
//! Each normal's layers say where along a ray the surface lies. Where they are right, the source
//! photo warped onto those layers shows what the reference does; where they are wrong, it shows
//! something else. [`inconsistency_mhi`] gives every layer the colour `|src_l − ref|` (the source
//! warped onto plane `l`, where the source sees it; 0 elsewhere) with the MHI's own alphas:
//! rendered from a target camera, normal `k`'s image is the expected photo-inconsistency of
//! normal `k`'s geometry along each target ray. [`consistent_weights`] then scales the Soft
//! weights by `exp(−β · c_k)`, so that a pixel leans towards the normals whose geometry both photos
//! agree with. A pixel where every normal is equally consistent (or the source sees none of them)
//! keeps its Soft weights.

use image::Rgb32FImage;
use mhi_geom::Camera;
use rayon::prelude::*;

use crate::{Error, LayerColor, Mhi, Result, plane_sweep_volume};

/// The MHI `mhi` with every layer coloured by how far the source photo, warped onto the layer's
/// plane, is from the reference photo there (per channel, `|src − ref|`; 0 where the source does
/// not see the plane). Its multi-normal images from a target camera are per-normal
/// inconsistency maps (see the module documentation).
///
/// # Errors
/// If `reference_image` is not the size of the MHI's reference camera, or `source_image` not the
/// size of `source`.
pub fn inconsistency_mhi(
    mhi: &Mhi,
    reference_image: &Rgb32FImage,
    source_image: &Rgb32FImage,
    source: &Camera,
) -> Result<Mhi> {
    let r = mhi.reference();
    if reference_image.dimensions() != (r.width, r.height) {
        return Err(Error::InvalidInput(format!(
            "reference image is {}×{}, the MHI's reference camera {}×{}",
            reference_image.width(),
            reference_image.height(),
            r.width,
            r.height
        )));
    }
    let psv = plane_sweep_volume(mhi.normals(), mhi.depths(), r, source_image, source)?;
    let (w, h) = (r.width, r.height);
    let px = w as usize * h as usize;
    let reference = reference_image.as_raw();
    let layers: Vec<Rgb32FImage> = psv
        .rgb
        .par_chunks(3 * px)
        .zip(psv.valid.par_chunks(px))
        .map(|(rgb, valid)| {
            let mut raw = vec![0.0_f32; 3 * px];
            for (p, &v) in valid.iter().enumerate() {
                if v > 0.0 {
                    for c in 0..3 {
                        raw[3 * p + c] = (rgb[3 * p + c] - reference[3 * p + c]).abs();
                    }
                }
            }
            Rgb32FImage::from_raw(w, h, raw).expect("a buffer of 3 · w · h values")
        })
        .collect();
    Mhi::new(
        mhi.normals().clone(),
        mhi.depths().to_vec(),
        *r,
        LayerColor::PerLayer(layers),
        mhi.alpha().to_vec(),
    )
}

/// Check the consistent blend's strength β: finite and at least 0 (0 gives Soft back).
///
/// # Errors
/// If it is not.
pub fn check_beta(beta: f32) -> Result<()> {
    if beta.is_finite() && beta >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidInput(format!(
            "the consistent blend's strength β must be a finite number of at least 0 (0 is Soft), got {beta}"
        )))
    }
}

/// Each normal's inconsistency `c_k`, the mean over RGB of its image (`inconsistency`, the
/// multi-normal images of [`inconsistency_mhi`]), `N × H × W` normal-major: what
/// [`consistent_weights`] and a blending network that reads the inconsistency take.
pub fn inconsistency_means(inconsistency: &[Rgb32FImage]) -> Vec<f32> {
    inconsistency
        .iter()
        .flat_map(|m| {
            m.as_raw()
                .chunks_exact(3)
                .map(|p| (p[0] + p[1] + p[2]) / 3.0)
        })
        .collect()
}

/// Blend weights `N × H × W` (normal-major, summing to 1 per pixel): `soft`'s scaled by
/// `exp(−β · c_k)`, with `c_k` the mean over RGB of normal `k`'s inconsistency image
/// (`inconsistency`, one per normal, the multi-normal images of [`inconsistency_mhi`]). β = 0
/// gives `soft` back. The exponent is taken relative to the pixel's most consistent normal, so no
/// weight underflows to an all-zero pixel.
///
/// # Errors
/// If β is negative or not finite, or the shapes disagree.
pub fn consistent_weights(
    soft: &[f32],
    inconsistency: &[Rgb32FImage],
    beta: f32,
) -> Result<Vec<f32>> {
    check_beta(beta)?;
    let n = inconsistency.len();
    let Some(first) = inconsistency.first() else {
        return Err(Error::InvalidInput("no inconsistency image".into()));
    };
    let (w, h) = first.dimensions();
    let px = w as usize * h as usize;
    if soft.len() != n * px || inconsistency.iter().any(|m| m.dimensions() != (w, h)) {
        return Err(Error::InvalidInput(format!(
            "expected {n} inconsistency images of {w}×{h} and {} weights, got {} weights",
            n * px,
            soft.len()
        )));
    }
    let c = inconsistency_means(inconsistency);
    // Per pixel: the most consistent normal's c, then the scaled weights' sum.
    let per_pixel =
        |f: &(dyn Fn(usize, usize) -> f32 + Sync), start: f32, op: fn(f32, f32) -> f32| {
            (0..px)
                .into_par_iter()
                .map(|p| (0..n).fold(start, |acc, k| op(acc, f(k, p))))
                .collect::<Vec<f32>>()
        };
    let lo = per_pixel(&|k, p| c[k * px + p], f32::INFINITY, f32::min);
    let scaled: Vec<f32> = (0..n * px)
        .into_par_iter()
        .map(|i| soft[i] * (-beta * (c[i] - lo[i % px])).exp())
        .collect();
    let sum = per_pixel(&|k, p| scaled[k * px + p], 0.0, |a, b| a + b);
    Ok((0..n * px)
        .into_par_iter()
        .map(|i| {
            let s = sum[i % px];
            if s > 0.0 && s.is_finite() {
                scaled[i] / s
            } else {
                soft[i]
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec3};
    use mhi_geom::{Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity};

    fn flat(w: u32, h: u32, v: [f32; 3]) -> Rgb32FImage {
        Rgb32FImage::from_pixel(w, h, image::Rgb(v))
    }

    #[test]
    fn beta_zero_keeps_soft_and_weights_lean_to_the_consistent_normal() {
        let (w, h) = (4, 3);
        let soft: Vec<f32> = [0.5_f32, 0.3, 0.2]
            .iter()
            .flat_map(|&v| std::iter::repeat_n(v, 12))
            .collect();
        let inc = vec![
            flat(w, h, [0.3, 0.3, 0.3]),
            flat(w, h, [0.0, 0.0, 0.0]),
            flat(w, h, [0.3, 0.3, 0.3]),
        ];
        let same = consistent_weights(&soft, &inc, 0.0).unwrap();
        assert!(same.iter().zip(&soft).all(|(a, b)| (a - b).abs() < 1e-7));
        let lean = consistent_weights(&soft, &inc, 10.0).unwrap();
        for p in 0..12 {
            let s: f32 = (0..3).map(|k| lean[k * 12 + p]).sum();
            assert!((s - 1.0).abs() < 1e-6);
            // Normal 1 was 0.3 of Soft; consistent where the others are 0.3 off, it takes most.
            let e = (-3.0_f32).exp();
            let want = 0.3 / (0.5 * e + 0.3 + 0.2 * e);
            assert!(
                (lean[12 + p] - want).abs() < 1e-6,
                "{} {want}",
                lean[12 + p]
            );
        }
        // A huge β and inconsistency cannot make a pixel all zero.
        let far = vec![
            flat(w, h, [1.0; 3]),
            flat(w, h, [1.0; 3]),
            flat(w, h, [1.0; 3]),
        ];
        let v = consistent_weights(&soft, &far, 1e6).unwrap();
        assert!(v.iter().zip(&soft).all(|(a, b)| (a - b).abs() < 1e-6));
        assert!(consistent_weights(&soft, &inc, -1.0).is_err());
        assert!(consistent_weights(&soft, &inc, f32::NAN).is_err());
        assert!(consistent_weights(&soft[1..], &inc, 1.0).is_err());
    }

    /// Two photos of a slanted plane: the normal that matches its slant is the most consistent.
    #[test]
    fn the_true_normal_is_the_most_consistent() {
        use crate::{Blend, PixelTruth, RenderOptions, oracle_alpha, render};
        let (w, h) = (96_u32, 64_u32);
        let k = Intrinsics::new(80.0, 80.0, 48.0, 32.0).unwrap();
        let reference = Camera::new(k, RigidTransform::IDENTITY, w, h).unwrap();
        let normals = NormalSet::paper_subset(3).unwrap();
        let depths = depths_linear_in_disparity(2.0, 8.0, 25).unwrap();
        // A textured plane (world = reference frame) through depth 4 on the optical axis,
        // slanted like the first normal.
        let nt = normals.normals()[0];
        let c = 4.0 * nt.z;
        let texture = |p: DVec3| -> [f32; 3] {
            let u = (p.x * 7.0).sin() * 0.5 + 0.5;
            let v = (p.y * 5.0 + p.z * 3.0).cos() * 0.5 + 0.5;
            [u as f32, v as f32, (u * v) as f32]
        };
        // Where the ray of pixel (x, y) of `cam` meets the plane, in the world.
        let hit = |cam: &Camera, x: u32, y: u32| -> DVec3 {
            let world_from_cam = cam.cam_from_world.inverse();
            let o = world_from_cam.transform_point(DVec3::ZERO);
            let d = world_from_cam.transform_vector(
                cam.intrinsics
                    .ray(glam::DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5)),
            );
            o + d * ((c - nt.dot(o)) / nt.dot(d))
        };
        let photo =
            |cam: &Camera| Rgb32FImage::from_fn(w, h, |x, y| image::Rgb(texture(hit(cam, x, y))));
        let camera = |angle: f64, t: DVec3| {
            Camera::new(
                k,
                RigidTransform::new(DMat3::from_rotation_y(angle), t).unwrap(),
                w,
                h,
            )
            .unwrap()
        };
        let source = camera(-0.02, DVec3::new(-0.3, 0.0, 0.0));
        let target = camera(0.03, DVec3::new(0.25, 0.05, 0.0));
        let (ref_img, src_img) = (photo(&reference), photo(&source));
        let truth: Vec<Option<PixelTruth>> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                Some(PixelTruth {
                    normal: nt,
                    depth: hit(&reference, x, y).z,
                })
            })
            .collect();
        let alpha = oracle_alpha(&normals, &depths, &reference, &truth);
        let mhi = Mhi::new(
            normals,
            depths,
            reference,
            LayerColor::Shared(ref_img.clone()),
            alpha,
        )
        .unwrap();
        let inc = inconsistency_mhi(&mhi, &ref_img, &src_img, &source).unwrap();
        let r = render(
            &inc,
            &target,
            &RenderOptions {
                blend: Blend::Heuristic(mhi_geom::BlendHeuristic::Avg),
                keep_multi_normal: true,
                ..Default::default()
            },
        )
        .unwrap();
        let mean = |m: &Rgb32FImage| m.as_raw().iter().map(|&v| f64::from(v)).sum::<f64>();
        let c: Vec<f64> = r.multi_normal.iter().map(mean).collect();
        assert!(c[0] < 0.5 * c[1] && c[0] < 0.5 * c[2], "{c:?}");
        assert!(inconsistency_mhi(&mhi, &src_img, &flat(3, 3, [0.0; 3]), &source).is_err());
        assert!(inconsistency_mhi(&mhi, &flat(3, 3, [0.0; 3]), &src_img, &source).is_err());
    }
}
