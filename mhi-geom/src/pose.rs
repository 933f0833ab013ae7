//! Rigid transforms between camera and world frames, validated on construction.

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result, ensure_finite};

/// Default tolerance on `max |RᵀR − I|` when validating a rotation read from a file.
///
/// RealEstate10K stores nine decimals, so its rotations are orthonormal to about `1e-8`; `1e-5`
/// accepts any honestly rounded rotation and rejects anything that is not one.
pub const ROTATION_TOLERANCE: f64 = 1e-5;

/// The largest `max |RᵀR − I|` accepted in a rotation read from a file that was printed with
/// few decimals (four decimals give about `1e-4`; 7-Scenes' pose files are like that). Such a
/// rotation is re-orthonormalised, and the reader warns with the error it found
/// ([`rotation_error`]); beyond this tolerance the matrix is not a rotation.
pub const FILE_ROTATION_TOLERANCE: f64 = 2e-3;

/// `max |RᵀR − I|` of `r`: how far it is from orthonormal.
pub fn rotation_error(r: &DMat3) -> f64 {
    (r.transpose() * *r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .fold(0.0_f64, |m, v| m.max(v.abs()))
}

/// A rigid transform `X_b = R · X_a + t` mapping points of frame `a` to frame `b`.
///
/// Name values by target and source: a world-to-camera pose is `cam_from_world`, the relative
/// pose used by the homography is `ref_from_tgt`. Construct with [`RigidTransform::new`], which
/// checks that `R` is a rotation; the fields are private so a value is always valid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RigidTransform {
    rotation: DMat3,
    translation: DVec3,
}

impl RigidTransform {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        rotation: DMat3::IDENTITY,
        translation: DVec3::ZERO,
    };

    /// A transform from a rotation and a translation, validated with [`ROTATION_TOLERANCE`].
    ///
    /// The rotation is re-orthonormalised (polar projection) so that errors of a few `1e-9` in
    /// stored rotations do not accumulate through compositions.
    pub fn new(rotation: DMat3, translation: DVec3) -> Result<Self> {
        Self::with_tolerance(rotation, translation, ROTATION_TOLERANCE)
    }

    /// As [`RigidTransform::new`] with an explicit tolerance on `max |RᵀR − I|`.
    pub fn with_tolerance(rotation: DMat3, translation: DVec3, tolerance: f64) -> Result<Self> {
        ensure_finite("rotation", &rotation.to_cols_array())?;
        ensure_finite("translation", &translation.to_array())?;
        let rotation = validate_rotation("rotation", rotation, tolerance)?;
        Ok(Self {
            rotation,
            translation,
        })
    }

    /// A transform from a row-major 3 × 4 matrix `[R | t]` as stored in RealEstate10K files:
    /// `r11 r12 r13 t1 r21 r22 r23 t2 r31 r32 r33 t3`.
    pub fn from_row_major_3x4(m: &[f64; 12]) -> Result<Self> {
        let rotation = DMat3::from_cols(
            DVec3::new(m[0], m[4], m[8]),
            DVec3::new(m[1], m[5], m[9]),
            DVec3::new(m[2], m[6], m[10]),
        );
        Self::new(rotation, DVec3::new(m[3], m[7], m[11]))
    }

    /// The row-major 3 × 4 matrix `[R | t]`.
    pub fn to_row_major_3x4(&self) -> [f64; 12] {
        let r = self.rotation.transpose(); // columns of Rᵀ are rows of R
        let t = self.translation;
        [
            r.x_axis.x, r.x_axis.y, r.x_axis.z, t.x, //
            r.y_axis.x, r.y_axis.y, r.y_axis.z, t.y, //
            r.z_axis.x, r.z_axis.y, r.z_axis.z, t.z,
        ]
    }

    /// The rotation `R`.
    pub fn rotation(&self) -> DMat3 {
        self.rotation
    }

    /// The translation `t`.
    pub fn translation(&self) -> DVec3 {
        self.translation
    }

    /// Apply to a point: `R · x + t`.
    pub fn transform_point(&self, x: DVec3) -> DVec3 {
        self.rotation * x + self.translation
    }

    /// Apply to a direction: `R · v`.
    pub fn transform_vector(&self, v: DVec3) -> DVec3 {
        self.rotation * v
    }

    /// The inverse transform `(Rᵀ, −Rᵀ t)`: if `self` is `b_from_a`, this is `a_from_b`.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Composition `self ∘ other`: if `self` is `c_from_b` and `other` is `b_from_a`, the result
    /// is `c_from_a`.
    pub fn compose(&self, other: &Self) -> Self {
        Self {
            rotation: orthonormalize(self.rotation * other.rotation),
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The relative pose `ref_from_tgt = ref_from_world ∘ (tgt_from_world)⁻¹` of two
    /// world-to-camera poses, so that `X_ref = R · X_tgt + t` as in the homography of docs/METHOD.md.
    pub fn relative(ref_from_world: &Self, tgt_from_world: &Self) -> Self {
        ref_from_world.compose(&tgt_from_world.inverse())
    }

    /// The camera centre in the source frame, for a `cam_from_world` pose: `−Rᵀ t`.
    pub fn center(&self) -> DVec3 {
        self.inverse().translation
    }

    /// Rotation angle of this transform's rotation, in degrees (see [`crate::rotation_angle_deg`]).
    pub fn rotation_angle_deg(&self) -> f64 {
        crate::rotation::rotation_angle_deg(&self.rotation)
    }
}

/// Check that `r` is a rotation within `tolerance` and return its nearest exact rotation.
pub fn validate_rotation(what: &'static str, r: DMat3, tolerance: f64) -> Result<DMat3> {
    ensure_finite(what, &r.to_cols_array())?;
    let orthogonality_error = rotation_error(&r);
    let determinant = r.determinant();
    if orthogonality_error <= tolerance && (determinant + 1.0).abs() <= 3.0 * tolerance {
        return Err(Error::Reflection { what, determinant });
    }
    if !(orthogonality_error <= tolerance) || !((determinant - 1.0).abs() <= 3.0 * tolerance) {
        return Err(Error::NotARotation {
            what,
            orthogonality_error,
            determinant,
            tolerance,
        });
    }
    Ok(orthonormalize(r))
}

/// Nearest rotation of a nearly orthonormal matrix, by two Newton steps of the polar
/// decomposition `R ← (R + R⁻ᵀ)/2` (quadratic convergence: exact to rounding in three steps
/// from [`FILE_ROTATION_TOLERANCE`]).
fn orthonormalize(mut r: DMat3) -> DMat3 {
    for _ in 0..2 {
        let inv_t = r.inverse().transpose();
        r = (r + inv_t) * 0.5;
    }
    // A rotation printed with few decimals needs a third step; one within 1e-5 does not (and
    // keeps the bits it always had).
    if rotation_error(&r) > 1e-13 {
        let inv_t = r.inverse().transpose();
        r = (r + inv_t) * 0.5;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::{arb_transform, assert_close};
    use proptest::prelude::*;

    #[test]
    fn row_major_round_trip() {
        let r = DMat3::from_rotation_y(0.3) * DMat3::from_rotation_x(-0.2);
        let p = RigidTransform::new(r, DVec3::new(1.0, 2.0, 3.0)).unwrap();
        let q = RigidTransform::from_row_major_3x4(&p.to_row_major_3x4()).unwrap();
        assert!(q.rotation().abs_diff_eq(p.rotation(), 1e-15));
        assert_eq!(q.translation(), p.translation());
        // Row-major means the second number is r12 = R[row 0][col 1].
        let m = p.to_row_major_3x4();
        assert_close(m[1], p.rotation().y_axis.x, 0.0);
    }

    /// A rotation printed with four decimals (as 7-Scenes' pose files are) is accepted with the
    /// file tolerance and comes back exactly orthonormal.
    #[test]
    fn rotations_printed_with_four_decimals_are_reorthonormalised() {
        let r = DMat3::from_rotation_y(0.3) * DMat3::from_rotation_x(-0.2);
        let rounded = DMat3::from_cols_array(&r.to_cols_array().map(|v| (v * 1e4).round() / 1e4));
        assert!(rotation_error(&rounded) > ROTATION_TOLERANCE);
        assert!(RigidTransform::new(rounded, DVec3::ZERO).is_err());
        let p =
            RigidTransform::with_tolerance(rounded, DVec3::ZERO, FILE_ROTATION_TOLERANCE).unwrap();
        assert!(
            rotation_error(&p.rotation()) < 1e-14,
            "{}",
            rotation_error(&p.rotation())
        );
        assert!(p.rotation().abs_diff_eq(r, 2e-4));
    }

    #[test]
    fn non_rotations_and_nan_are_rejected_with_a_clear_error() {
        let scaled = DMat3::IDENTITY * 1.01;
        let err = RigidTransform::new(scaled, DVec3::ZERO).unwrap_err();
        assert!(matches!(err, Error::NotARotation { .. }), "{err}");
        assert!(err.to_string().contains("not a rotation"), "{err}");
        let reflection = DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0));
        let err = RigidTransform::new(reflection, DVec3::ZERO).unwrap_err();
        assert!(matches!(err, Error::Reflection { determinant, .. } if determinant < 0.0));
        assert!(err.to_string().contains("is a reflection"), "{err}");
        let sheared = DMat3::from_cols(DVec3::X, DVec3::new(0.01, 1.0, 0.0), DVec3::Z);
        assert!(RigidTransform::new(sheared, DVec3::ZERO).is_err());
        let err = RigidTransform::new(DMat3::IDENTITY, DVec3::new(0.0, f64::NAN, 0.0)).unwrap_err();
        assert_eq!(
            err,
            Error::NonFinite {
                what: "translation"
            }
        );
        let mut nan_r = DMat3::IDENTITY;
        nan_r.x_axis.y = f64::INFINITY;
        assert!(matches!(
            RigidTransform::new(nan_r, DVec3::ZERO),
            Err(Error::NonFinite { what: "rotation" })
        ));
    }

    #[test]
    fn slightly_rounded_rotations_are_accepted_and_cleaned() {
        let mut r = DMat3::from_rotation_z(0.7);
        r.x_axis.x += 3e-9; // nine-decimal rounding as in RealEstate10K files
        let p = RigidTransform::new(r, DVec3::ZERO).unwrap();
        let e = p.rotation().transpose() * p.rotation() - DMat3::IDENTITY;
        assert!(e.abs_diff_eq(DMat3::ZERO, 1e-15), "{e:?}");
    }

    #[test]
    fn relative_pose_maps_target_points_to_reference_points() {
        let ref_from_world =
            RigidTransform::new(DMat3::from_rotation_y(0.2), DVec3::new(0.1, -0.3, 0.5)).unwrap();
        let tgt_from_world = RigidTransform::new(
            DMat3::from_rotation_x(-0.1) * DMat3::from_rotation_z(0.05),
            DVec3::new(-0.4, 0.2, 0.1),
        )
        .unwrap();
        let ref_from_tgt = RigidTransform::relative(&ref_from_world, &tgt_from_world);
        let x_world = DVec3::new(1.0, 2.0, 5.0);
        let x_tgt = tgt_from_world.transform_point(x_world);
        let x_ref = ref_from_world.transform_point(x_world);
        assert!(
            ref_from_tgt
                .transform_point(x_tgt)
                .abs_diff_eq(x_ref, 1e-12)
        );
        let c = tgt_from_world.center();
        assert!(
            tgt_from_world
                .transform_point(c)
                .abs_diff_eq(DVec3::ZERO, 1e-12)
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        #[test]
        fn inverse_and_composition_round_trip(a in arb_transform(), b in arb_transform(), x in prop::array::uniform3(-100.0f64..100.0)) {
            let x = DVec3::from_array(x);
            let back = a.inverse().transform_point(a.transform_point(x));
            prop_assert!((back - x).length() <= 1e-12 * (1.0 + x.length() + a.translation().length()));
            let ab = a.compose(&b);
            let direct = a.transform_point(b.transform_point(x));
            prop_assert!((ab.transform_point(x) - direct).length() <= 1e-11 * (1.0 + direct.length()));
            let id = ab.compose(&ab.inverse());
            prop_assert!(id.rotation().abs_diff_eq(DMat3::IDENTITY, 1e-12));
            prop_assert!(id.translation().length() <= 1e-11 * (1.0 + ab.translation().length()));
            // The composed rotation stays exactly orthonormal.
            let e = ab.rotation().transpose() * ab.rotation() - DMat3::IDENTITY;
            prop_assert!(e.abs_diff_eq(DMat3::ZERO, 1e-14));
        }
    }
}
