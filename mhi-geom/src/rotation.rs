//! Rotation angles that stay accurate for tiny angles and near 180°.

use glam::{DMat3, DVec3};

/// The rotation angle of `r` in degrees, in `[0, 180]`.
///
/// Uses `θ = atan2(‖vee(R − Rᵀ)‖ / 2, (tr R − 1) / 2)` rather than `arccos((tr R − 1)/2)`, which
/// loses half of its digits near 0° and near 180° (docs/METHOD.md, "Numerical traps"). A matrix
/// with NaN entries yields NaN only if given one; validate poses with
/// [`crate::RigidTransform::new`] first.
pub fn rotation_angle_deg(r: &DMat3) -> f64 {
    rotation_angle_rad(r).to_degrees()
}

/// The rotation angle of `r` in radians, in `[0, π]` (see [`rotation_angle_deg`]).
pub fn rotation_angle_rad(r: &DMat3) -> f64 {
    // Columns: r.x_axis = first column, so R[row][col] = r.col(col)[row].
    let vee = DVec3::new(
        r.y_axis.z - r.z_axis.y, // R32 − R23
        r.z_axis.x - r.x_axis.z, // R13 − R31
        r.x_axis.y - r.y_axis.x, // R21 − R12
    );
    let sin = 0.5 * vee.length();
    let cos = 0.5 * (r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0);
    sin.atan2(cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::assert_rel;

    fn check(deg: f64, axis: DVec3) {
        let r = DMat3::from_axis_angle(axis.normalize(), deg.to_radians());
        assert_rel(rotation_angle_deg(&r), deg, 1e-6);
    }

    #[test]
    fn tiny_angles_are_accurate() {
        for deg in [1e-7, 1e-5, 1e-3] {
            check(deg, DVec3::new(0.3, -0.8, 0.2));
            check(deg, DVec3::Z);
        }
        assert_eq!(rotation_angle_deg(&DMat3::IDENTITY), 0.0);
    }

    #[test]
    fn angles_near_half_turn_are_accurate() {
        for deg in [179.9999, 179.999_999, 180.0 - 1e-3, 90.0, 45.0, 10.0] {
            check(deg, DVec3::new(-0.1, 0.9, 0.4));
        }
        // Exactly 180°: the sine vanishes and the angle is exact.
        let half = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
        assert_eq!(rotation_angle_deg(&half), 180.0);
    }

    #[test]
    fn arccos_would_fail_where_atan2_does_not() {
        // Documented motivation: arccos loses the angle entirely at 1e-7°.
        let r = DMat3::from_axis_angle(DVec3::Y, 1e-7_f64.to_radians());
        let naive = (0.5 * (r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0))
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        assert!((naive - 1e-7).abs() / 1e-7 > 1e-2, "arccos gave {naive}");
        assert_rel(rotation_angle_deg(&r), 1e-7, 1e-6);
    }
}
