//! Pinhole intrinsics in pixels, following the continuous pixel frame of docs/METHOD.md.

use glam::{DMat3, DVec2, DVec3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result, ensure_finite};

/// Pinhole intrinsics of an image, in pixels, with zero skew.
///
/// Pixel `(i, j)` covers `[i, i+1) × [j, j+1)`; its centre is `(i + 0.5, j + 0.5)`. A principal
/// point of `(w/2, h/2)` is therefore the exact centre of a `w × h` image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point x, in pixels.
    pub cx: f64,
    /// Principal point y, in pixels.
    pub cy: f64,
}

impl Intrinsics {
    /// Intrinsics from pixel values, validated: finite, focal lengths strictly positive.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64) -> Result<Self> {
        ensure_finite("intrinsics", &[fx, fy, cx, cy])?;
        if fx <= 0.0 || fy <= 0.0 {
            return Err(Error::InvalidIntrinsics {
                reason: format!("focal lengths must be positive, got fx = {fx}, fy = {fy}"),
            });
        }
        Ok(Self { fx, fy, cx, cy })
    }

    /// Intrinsics from RealEstate10K's normalised values for an image of `width × height` pixels:
    /// `fx` and `cx` are multiplied by the width, `fy` and `cy` by the height.
    pub fn from_normalized(
        fx: f64,
        fy: f64,
        cx: f64,
        cy: f64,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        check_size(width, height)?;
        let (w, h) = (f64::from(width), f64::from(height));
        Self::new(fx * w, fy * h, cx * w, cy * h)
    }

    /// The normalised values `(fx, fy, cx, cy)` for an image of `width × height` pixels.
    pub fn to_normalized(&self, width: u32, height: u32) -> Result<[f64; 4]> {
        check_size(width, height)?;
        let (w, h) = (f64::from(width), f64::from(height));
        Ok([self.fx / w, self.fy / h, self.cx / w, self.cy / h])
    }

    /// The 3 × 3 matrix `K`.
    pub fn to_mat3(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx, self.cy, 1.0),
        )
    }

    /// Intrinsics from a 3 × 3 matrix, which must have zero skew and a last row `(0, 0, 1)`
    /// (within `1e-12` relative to the focal length).
    pub fn from_mat3(k: DMat3) -> Result<Self> {
        ensure_finite("intrinsic matrix", &k.to_cols_array())?;
        let scale = k.x_axis.x.abs().max(k.y_axis.y.abs()).max(1.0);
        let off = [k.y_axis.x, k.x_axis.y, k.x_axis.z, k.y_axis.z];
        if off.iter().any(|v| v.abs() > 1e-12 * scale) || (k.z_axis.z - 1.0).abs() > 1e-12 {
            return Err(Error::InvalidIntrinsics {
                reason: format!(
                    "matrix is not [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]: {:?}",
                    k.transpose().to_cols_array_2d()
                ),
            });
        }
        Self::new(k.x_axis.x, k.y_axis.y, k.z_axis.x, k.z_axis.y)
    }

    /// The inverse matrix `K⁻¹`, in closed form (never singular: focal lengths are positive).
    pub fn inverse_mat3(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(1.0 / self.fx, 0.0, 0.0),
            DVec3::new(0.0, 1.0 / self.fy, 0.0),
            DVec3::new(-self.cx / self.fx, -self.cy / self.fy, 1.0),
        )
    }

    /// Intrinsics after resizing the image from `from` to `to` pixels (aspect need not be kept):
    /// the continuous pixel frame scales by `to / from` along each axis.
    pub fn resized(&self, from: (u32, u32), to: (u32, u32)) -> Result<Self> {
        check_size(from.0, from.1)?;
        check_size(to.0, to.1)?;
        let sx = f64::from(to.0) / f64::from(from.0);
        let sy = f64::from(to.1) / f64::from(from.1);
        Self::new(self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy)
    }

    /// Intrinsics of the crop whose top-left pixel is `(x0, y0)`: the principal point shifts.
    /// The crop `x0, y0, width, height` must lie inside an image of `image_size`.
    pub fn cropped(
        &self,
        image_size: (u32, u32),
        x0: u32,
        y0: u32,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        check_size(width, height)?;
        if u64::from(x0) + u64::from(width) > u64::from(image_size.0)
            || u64::from(y0) + u64::from(height) > u64::from(image_size.1)
        {
            return Err(Error::InvalidImageSize {
                reason: format!(
                    "crop {width}×{height} at ({x0}, {y0}) exceeds the {}×{} image",
                    image_size.0, image_size.1
                ),
            });
        }
        Self::new(
            self.fx,
            self.fy,
            self.cx - f64::from(x0),
            self.cy - f64::from(y0),
        )
    }

    /// Project a point in camera coordinates to pixels. `None` when the point is not strictly in
    /// front of the camera (`z ≤ 1e-12`).
    pub fn project(&self, point_in_cam: DVec3) -> Option<DVec2> {
        if !(point_in_cam.z > 1e-12) || !point_in_cam.is_finite() {
            return None;
        }
        Some(DVec2::new(
            self.fx * point_in_cam.x / point_in_cam.z + self.cx,
            self.fy * point_in_cam.y / point_in_cam.z + self.cy,
        ))
    }

    /// The ray through a pixel position (continuous frame), with `z = 1`: `K⁻¹ (u, v, 1)`.
    pub fn ray(&self, pixel: DVec2) -> DVec3 {
        DVec3::new(
            (pixel.x - self.cx) / self.fx,
            (pixel.y - self.cy) / self.fy,
            1.0,
        )
    }
}

/// The centre of pixel `(i, j)` in the continuous pixel frame.
pub fn pixel_center(i: u32, j: u32) -> DVec2 {
    DVec2::new(f64::from(i) + 0.5, f64::from(j) + 0.5)
}

fn check_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::InvalidImageSize {
            reason: format!("image size {width}×{height} has no pixels"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::assert_close;

    #[test]
    fn normalized_round_trip_and_matrix() {
        let k = Intrinsics::from_normalized(0.47, 0.84, 0.5, 0.5, 640, 360).unwrap();
        assert_close(k.fx, 0.47 * 640.0, 1e-12);
        assert_close(k.cy, 180.0, 1e-12);
        let n = k.to_normalized(640, 360).unwrap();
        for (a, b) in n.iter().zip([0.47, 0.84, 0.5, 0.5]) {
            assert_close(*a, b, 1e-12);
        }
        let m = k.to_mat3();
        assert_eq!(Intrinsics::from_mat3(m).unwrap(), k);
        let id = m * k.inverse_mat3();
        assert!(id.abs_diff_eq(DMat3::IDENTITY, 1e-12), "{id:?}");
    }

    #[test]
    fn resize_keeps_the_image_centre_and_scales_projection() {
        let k = Intrinsics::from_normalized(0.6, 0.8, 0.5, 0.5, 768, 512).unwrap();
        let r = k.resized((768, 512), (256, 256)).unwrap();
        assert_close(r.cx, 128.0, 1e-12);
        assert_close(r.cy, 128.0, 1e-12);
        let x = DVec3::new(0.3, -0.2, 2.0);
        let a = k.project(x).unwrap();
        let b = r.project(x).unwrap();
        assert_close(b.x, a.x * 256.0 / 768.0, 1e-9);
        assert_close(b.y, a.y * 256.0 / 512.0, 1e-9);
    }

    #[test]
    fn crop_shifts_the_principal_point() {
        let k = Intrinsics::new(500.0, 500.0, 384.0, 256.0).unwrap();
        let c = k.cropped((768, 512), 128, 0, 512, 512).unwrap();
        assert_close(c.cx, 256.0, 0.0);
        let x = DVec3::new(0.1, 0.2, 3.0);
        assert_close(
            c.project(x).unwrap().x,
            k.project(x).unwrap().x - 128.0,
            1e-9,
        );
        assert!(matches!(
            k.cropped((768, 512), 300, 0, 512, 512),
            Err(Error::InvalidImageSize { .. })
        ));
    }

    #[test]
    fn bad_intrinsics_are_rejected() {
        assert!(matches!(
            Intrinsics::new(f64::NAN, 1.0, 0.0, 0.0),
            Err(Error::NonFinite { .. })
        ));
        assert!(matches!(
            Intrinsics::new(-1.0, 1.0, 0.0, 0.0),
            Err(Error::InvalidIntrinsics { .. })
        ));
        assert!(matches!(
            Intrinsics::from_normalized(0.5, 0.5, 0.5, 0.5, 0, 10),
            Err(Error::InvalidImageSize { .. })
        ));
        let mut m = Intrinsics::new(1.0, 1.0, 0.0, 0.0).unwrap().to_mat3();
        m.y_axis.x = 0.3; // skew
        assert!(matches!(
            Intrinsics::from_mat3(m),
            Err(Error::InvalidIntrinsics { .. })
        ));
    }

    #[test]
    fn points_behind_the_camera_do_not_project() {
        let k = Intrinsics::new(1.0, 1.0, 0.0, 0.0).unwrap();
        assert!(k.project(DVec3::new(0.0, 0.0, -1.0)).is_none());
        assert!(k.project(DVec3::new(1.0, 0.0, 0.0)).is_none());
        assert!(k.project(DVec3::new(f64::NAN, 0.0, 1.0)).is_none());
    }
}
