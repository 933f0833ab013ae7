//! Geometry of Multiple Homography Image (MHI) view synthesis, in f64 on plain glam types.
//!
//! Conventions (binding across the workspace; see `docs/METHOD.md` in the repository):
//! - cameras are OpenCV-style (x right, y down, z forward) and poses are world-to-camera
//!   [`RigidTransform`]s named by target and source (`cam_from_world`, `ref_from_tgt`);
//! - a [`Plane`] is `{X : n·X = d}` in the reference camera frame, `n` unit with `n_z > 0`, `d > 0`;
//! - pixel `(i, j)` covers `[i, i+1) × [j, j+1)`, its centre is `(i + 0.5, j + 0.5)`.
//!
//! Every fallible construction returns [`Result`]: a plane seen from behind, a matrix that is not
//! a rotation, or NaN input is an [`Error`], never a NaN or a huge matrix.
//!
//! # Example
//!
//! Map a target pixel to the reference image through each of the paper's five normals:
//!
//! ```
//! use glam::{DMat3, DVec2, DVec3};
//! use mhi_geom::{
//!     apply_homography, depths_linear_in_disparity, plane_homography, Intrinsics, NormalSet,
//!     RigidTransform,
//! };
//!
//! # fn main() -> mhi_geom::Result<()> {
//! let k = Intrinsics::from_normalized(0.5, 0.5, 0.5, 0.5, 256, 256)?;
//! let ref_from_world = RigidTransform::IDENTITY;
//! let tgt_from_world = RigidTransform::new(DMat3::from_rotation_y(0.1), DVec3::new(0.2, 0.0, 0.0))?;
//! let ref_from_tgt = RigidTransform::relative(&ref_from_world, &tgt_from_world);
//! assert!((ref_from_tgt.rotation_angle_deg() - 0.1_f64.to_degrees()).abs() < 1e-9);
//!
//! let depths = depths_linear_in_disparity(1.0, 100.0, 32)?; // far first
//! let normals = NormalSet::paper();
//! for plane in normals.planes(&depths)? {
//!     let h = plane_homography(&k, &k, &ref_from_tgt, &plane)?;
//!     if let Some(u_ref) = apply_homography(&h, DVec2::new(128.5, 128.5), 1e-9) {
//!         assert!(u_ref.is_finite());
//!     }
//! }
//! # Ok(())
//! # }
//! ```

mod angle;
mod camera;
mod error;
mod homography;
mod intrinsics;
pub mod path;
mod plane;
mod pose;
mod rotation;
pub mod simd;

pub use angle::{
    BlendHeuristic, angle_cost, angle_cost_in_target, exp_small, exp_taylor, soft_weight,
    soft_weight_for_f32,
};
pub use camera::Camera;
pub use error::{Error, Result};
pub use homography::{
    MIN_RELATIVE_PLANE_DISTANCE, apply_homography, plane_homography,
    plane_homography_from_reference, plane_homography_metric,
};
pub use intrinsics::{Intrinsics, pixel_center};
pub use plane::{NormalSet, Plane, UNIT_TOLERANCE, depths_linear_in_disparity, validate_normal};
pub use pose::{
    FILE_ROTATION_TOLERANCE, ROTATION_TOLERANCE, RigidTransform, rotation_error, validate_rotation,
};
pub use rotation::{rotation_angle_deg, rotation_angle_rad};

/// Re-export of glam so users need not pin the same version themselves.
pub use glam;

#[cfg(test)]
pub(crate) mod test_support {
    //! The shared approximate-equality helpers and strategies of this crate's tests.
    use crate::RigidTransform;
    use glam::{DMat3, DVec3};
    use proptest::prelude::*;

    /// Assert `|a − b| ≤ tol`, printing both values and the difference.
    #[track_caller]
    pub fn assert_close(a: f64, b: f64, tol: f64) {
        let diff = (a - b).abs();
        assert!(diff <= tol, "{a} vs {b}: |diff| = {diff:e} > {tol:e}");
    }

    /// Assert `|a − b| ≤ rel · |b|`, printing both values and the relative difference.
    #[track_caller]
    pub fn assert_rel(a: f64, b: f64, rel: f64) {
        let diff = (a - b).abs() / b.abs();
        assert!(diff <= rel, "{a} vs {b}: relative diff {diff:e} > {rel:e}");
    }

    /// Random rigid transforms: any rotation axis, angles up to 60°, translations up to 2.
    pub fn arb_transform() -> impl Strategy<Value = RigidTransform> {
        (
            prop::array::uniform3(-1.0f64..1.0),
            0.0f64..60.0,
            prop::array::uniform3(-2.0f64..2.0),
        )
            .prop_filter_map("axis must be non-zero", |(axis, deg, t)| {
                let axis = DVec3::from_array(axis);
                (axis.length() > 1e-3).then(|| {
                    RigidTransform::new(
                        DMat3::from_axis_angle(axis.normalize(), deg.to_radians()),
                        DVec3::from_array(t),
                    )
                    .expect("axis-angle matrices are rotations")
                })
            })
    }
}
