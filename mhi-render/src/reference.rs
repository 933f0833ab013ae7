//! The f64 reference renderer: the method's equations written out literally (each layer warped
//! into its own image, Eq. 2 composited back to front, Eq. 4 blended), slow and obvious. The
//! fast renderer is checked against it.

use glam::DVec2;
use mhi_geom::{Camera, angle_cost_in_target, apply_homography, pixel_center, plane_homography};

use crate::cpu::{Blend, W_EPS};
use crate::error::{Error, Result};
use crate::mhi::{LayerColor, Mhi};

/// An f64 RGB image, row-major.
pub type ImageF64 = Vec<[f64; 3]>;

fn bilinear(values: &dyn Fn(usize) -> [f64; 4], w: usize, h: usize, p: DVec2) -> [f64; 4] {
    let (x, y) = (p.x - 0.5, p.y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (ax, ay) = (x - x0, y - y0);
    let mut out = [0.0; 4];
    for (dx, dy, wt) in [
        (0.0, 0.0, (1.0 - ax) * (1.0 - ay)),
        (1.0, 0.0, ax * (1.0 - ay)),
        (0.0, 1.0, (1.0 - ax) * ay),
        (1.0, 1.0, ax * ay),
    ] {
        let (xx, yy) = (x0 + dx, y0 + dy);
        if xx >= 0.0 && yy >= 0.0 && xx < w as f64 && yy < h as f64 {
            let v = values(yy as usize * w + xx as usize);
            for k in 0..4 {
                out[k] += wt * v[k];
            }
        }
    }
    out
}

/// Render in f64: returns the blended image and the N multi-normal images.
pub fn render_f64(
    mhi: &Mhi,
    target: &Camera,
    blend: Blend<'_>,
) -> Result<(ImageF64, Vec<ImageF64>)> {
    let (n, d) = (mhi.n(), mhi.d());
    let (tw, th) = (target.width as usize, target.height as usize);
    let (rw, rh) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    let ref_from_tgt = mhi.reference().from_other(target);
    let mut mnis = Vec::with_capacity(n);
    for i in 0..n {
        // Warp every layer (RGB and alpha) into the target.
        let mut warped: Vec<Vec<[f64; 4]>> = Vec::with_capacity(d);
        for j in 0..d {
            let h = plane_homography(
                &mhi.reference().intrinsics,
                &target.intrinsics,
                &ref_from_tgt,
                mhi.plane(i, j),
            )
            .ok();
            let alpha = mhi.alpha_layer(i, j);
            let color = |k: usize| -> [f64; 3] {
                let p = match mhi.color() {
                    LayerColor::Shared(img) => img.as_raw(),
                    LayerColor::PerLayer(v) => v[i * d + j].as_raw(),
                };
                [
                    f64::from(p[3 * k]),
                    f64::from(p[3 * k + 1]),
                    f64::from(p[3 * k + 2]),
                ]
            };
            let values = |k: usize| {
                let c = color(k);
                [c[0], c[1], c[2], f64::from(alpha[k])]
            };
            let mut layer = vec![[0.0; 4]; tw * th];
            if let Some(h) = h {
                for y in 0..th {
                    for x in 0..tw {
                        if let Some(p) =
                            apply_homography(&h, pixel_center(x as u32, y as u32), f64::from(W_EPS))
                        {
                            layer[y * tw + x] = bilinear(&values, rw, rh, p);
                        }
                    }
                }
            }
            if j == 0 {
                for v in &mut layer {
                    v[3] = 1.0; // the farthest plane is opaque
                }
            }
            warped.push(layer);
        }
        // Eq. 2: Ĉ_i = Σ_j C_ij α_ij Π_{k nearer than j} (1 − α_ik); nearer = larger j.
        let mut mni = vec![[0.0; 3]; tw * th];
        for (p, out) in mni.iter_mut().enumerate() {
            for j in 0..d {
                let mut trans = 1.0;
                for layer in &warped[j + 1..] {
                    trans *= 1.0 - layer[p][3];
                }
                let v = warped[j][p];
                for k in 0..3 {
                    out[k] += v[k] * v[3] * trans;
                }
            }
        }
        mnis.push(mni);
    }
    // Eq. 4.
    let px = tw * th;
    let mut image = vec![[0.0; 3]; px];
    for (p, out) in image.iter_mut().enumerate() {
        let (x, y) = ((p % tw) as u32, (p / tw) as u32);
        let w: Vec<f64> = match blend {
            Blend::Heuristic(hh) => {
                let ray = target.intrinsics.ray(pixel_center(x, y));
                let deltas: Vec<f64> = mhi
                    .normals()
                    .normals()
                    .iter()
                    .map(|nv| angle_cost_in_target(*nv, &ref_from_tgt.rotation(), ray))
                    .collect::<std::result::Result<_, _>>()
                    .map_err(|source| Error::Geometry {
                        context: "angle cost".into(),
                        source,
                    })?;
                hh.weights(&deltas)
            }
            Blend::Weights(wts) => {
                let raw: Vec<f64> = (0..n).map(|i| f64::from(wts[i * px + p])).collect();
                let s: f64 = raw.iter().sum();
                raw.iter().map(|v| v / s).collect()
            }
        };
        for i in 0..n {
            for k in 0..3 {
                out[k] += w[i] * mnis[i][p][k];
            }
        }
    }
    Ok((image, mnis))
}
