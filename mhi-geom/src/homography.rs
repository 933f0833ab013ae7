//! The plane-induced homography mapping target pixels to reference pixels (paper Eq. 1).

use glam::{DMat3, DVec2, DVec3};

use crate::error::{Error, Result, ensure_finite};
use crate::intrinsics::Intrinsics;
use crate::plane::Plane;
use crate::pose::RigidTransform;

/// The smallest accepted ratio `(d − nᵀt) / max(d, ‖t‖)`.
///
/// The homography's plane term is `t nᵀR / (d − nᵀt)`; this bound keeps it below `1e6` times
/// the camera baseline ratio, so a plane passing through (or almost through) the target camera
/// is reported as invisible instead of producing an enormous, meaningless matrix.
pub const MIN_RELATIVE_PLANE_DISTANCE: f64 = 1e-6;

/// `H = K_ref (R + t nᵀR / (d − nᵀt)) K_tgt⁻¹`, mapping homogeneous target pixels to reference
/// pixels for points on `plane` (given in the reference frame), with `ref_from_tgt = (R, t)`,
/// i.e. `X_ref = R · X_tgt + t`.
///
/// # Errors
/// [`Error::PlaneNotVisible`] when the target camera centre is on, behind, or within
/// [`MIN_RELATIVE_PLANE_DISTANCE`] of the plane: the plane is then invisible from the target and
/// must contribute nothing. All inputs are validated types, so they are finite; the result is
/// checked to be finite too.
pub fn plane_homography(
    k_ref: &Intrinsics,
    k_tgt: &Intrinsics,
    ref_from_tgt: &RigidTransform,
    plane: &Plane,
) -> Result<DMat3> {
    let m = plane_homography_metric(ref_from_tgt, plane)?;
    let h = k_ref.to_mat3() * m * k_tgt.inverse_mat3();
    ensure_finite("homography", &h.to_cols_array())?;
    Ok(h)
}

/// The homography between normalised camera coordinates, `R + t nᵀR / (d − nᵀt)`, which maps a
/// target ray `X_tgt` (any scale) to the reference ray of the same point on the plane.
pub fn plane_homography_metric(ref_from_tgt: &RigidTransform, plane: &Plane) -> Result<DMat3> {
    let r = ref_from_tgt.rotation();
    let t = ref_from_tgt.translation();
    let n = plane.normal();
    let signed_distance = plane.signed_distance(t);
    let threshold = MIN_RELATIVE_PLANE_DISTANCE * plane.d().max(t.length());
    if !(signed_distance > threshold) {
        return Err(Error::PlaneNotVisible {
            signed_distance,
            threshold,
        });
    }
    // t nᵀR is the outer product of t with the row vector nᵀR = (Rᵀn)ᵀ.
    let nr = r.transpose() * n;
    let outer = DMat3::from_cols(t * nr.x, t * nr.y, t * nr.z);
    Ok(r + outer * (1.0 / signed_distance))
}

/// `H = K_src (R + t nᵀ / d) K_ref⁻¹`, mapping reference pixels to source pixels for points on
/// `plane` (given in the reference frame), with `src_from_ref = (R, t)`. This is the warp of the
/// plane-sweep volume: the source image seen on a reference-frame plane.
///
/// The plane is always in front of the reference camera (`d > 0`), so the only failure is a
/// non-finite result; points behind the source camera show up as `w ≤ ε` in
/// [`apply_homography`].
pub fn plane_homography_from_reference(
    k_ref: &Intrinsics,
    k_src: &Intrinsics,
    src_from_ref: &RigidTransform,
    plane: &Plane,
) -> Result<DMat3> {
    let t = src_from_ref.translation();
    let n = plane.normal();
    let outer = DMat3::from_cols(t * n.x, t * n.y, t * n.z);
    let m = src_from_ref.rotation() + outer * (1.0 / plane.d());
    let h = k_src.to_mat3() * m * k_ref.inverse_mat3();
    ensure_finite("homography", &h.to_cols_array())?;
    Ok(h)
}

/// Apply a homography to a pixel position: `None` when the homogeneous coordinate `w` is not
/// clearly positive (`w ≤ eps`), i.e. the point lies at or behind the camera; the sample is then
/// invalid, never clamped.
pub fn apply_homography(h: &DMat3, pixel: DVec2, eps: f64) -> Option<DVec2> {
    let p = *h * DVec3::new(pixel.x, pixel.y, 1.0);
    if !(p.z > eps) {
        return None;
    }
    let out = DVec2::new(p.x / p.z, p.y / p.z);
    out.is_finite().then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::arb_transform;
    use proptest::prelude::*;

    fn k() -> Intrinsics {
        Intrinsics::new(300.0, 280.0, 128.0, 120.0).unwrap()
    }

    /// Reference pixel of the point where the target pixel's ray meets the plane, computed by
    /// explicit ray–plane intersection (independent of the closed form).
    fn by_intersection(
        k_ref: &Intrinsics,
        k_tgt: &Intrinsics,
        ref_from_tgt: &RigidTransform,
        plane: &Plane,
        u_tgt: DVec2,
    ) -> Option<DVec2> {
        let origin = ref_from_tgt.translation();
        let dir = ref_from_tgt.transform_vector(k_tgt.ray(u_tgt));
        let s = plane.intersect_ray(origin, dir)?;
        k_ref.project(origin + dir * s)
    }

    #[test]
    fn fronto_parallel_plane_gives_the_mpi_homography() {
        // The MPI (Stereo Magnification) homography of a fronto-parallel plane at depth z in the
        // reference frame, written out for n = (0, 0, 1): H = K_ref (R + t e3ᵀR / (z − t_z)) K⁻¹.
        let rel = RigidTransform::new(
            DMat3::from_rotation_y(0.1) * DMat3::from_rotation_x(0.05),
            DVec3::new(0.2, -0.1, 0.3),
        )
        .unwrap();
        let z = 5.0;
        let plane = Plane::at_depth(DVec3::Z, z).unwrap();
        let h = plane_homography(&k(), &k(), &rel, &plane).unwrap();
        let r = rel.rotation();
        let t = rel.translation();
        let row3 = DVec3::new(r.x_axis.z, r.y_axis.z, r.z_axis.z); // third row of R
        let mpi = k().to_mat3()
            * (r + DMat3::from_cols(t * row3.x, t * row3.y, t * row3.z) * (1.0 / (z - t.z)))
            * k().inverse_mat3();
        assert!(h.abs_diff_eq(
            mpi,
            1e-12 * h.abs().to_cols_array().iter().cloned().fold(0.0, f64::max)
        ));
        for u in [DVec2::new(0.5, 0.5), DVec2::new(200.0, 17.0)] {
            let a = apply_homography(&h, u, 1e-12).unwrap();
            let b = by_intersection(&k(), &k(), &rel, &plane, u).unwrap();
            assert!((a - b).length() < 1e-9, "{a} vs {b}");
        }
    }

    #[test]
    fn identity_pose_gives_identity_homography() {
        let plane = Plane::at_depth(crate::NormalSet::paper().normals()[0], 3.0).unwrap();
        let h = plane_homography(&k(), &k(), &RigidTransform::IDENTITY, &plane).unwrap();
        assert!(h.abs_diff_eq(DMat3::IDENTITY, 1e-12), "{h:?}");
    }

    #[test]
    fn target_on_or_behind_the_plane_is_an_error_not_a_huge_matrix() {
        let plane = Plane::new(DVec3::Z, 1.0).unwrap();
        for gap in [1e-12, 0.0, -1e-12, -0.5, -10.0] {
            let rel =
                RigidTransform::new(DMat3::IDENTITY, DVec3::new(0.1, 0.0, 1.0 - gap)).unwrap();
            let err = plane_homography(&k(), &k(), &rel, &plane).unwrap_err();
            assert!(
                matches!(err, Error::PlaneNotVisible { .. }),
                "gap {gap}: {err}"
            );
        }
        // Just past the threshold the matrix is large but finite and still exact.
        let rel = RigidTransform::new(DMat3::IDENTITY, DVec3::new(0.1, 0.0, 1.0 - 1e-5)).unwrap();
        let h = plane_homography(&k(), &k(), &rel, &plane).unwrap();
        assert!(h.is_finite());
        let u = DVec2::new(128.0, 120.0);
        let a = apply_homography(&h, u, 1e-12).unwrap();
        let b = by_intersection(&k(), &k(), &rel, &plane, u).unwrap();
        assert!((a - b).length() < 1e-6 * b.length(), "{a} vs {b}");
    }

    #[test]
    fn plane_nearly_edge_on_to_the_target_ray() {
        // Target camera beside a steep plane, looking almost along it.
        let n = DVec3::new(0.999_999, 0.0, (1.0 - 0.999_999_f64 * 0.999_999).sqrt());
        let plane = Plane::at_depth(n, 2.0).unwrap();
        let rel =
            RigidTransform::new(DMat3::from_rotation_y(0.3), DVec3::new(-0.5, 0.0, 0.1)).unwrap();
        let h = plane_homography(&k(), &k(), &rel, &plane).unwrap();
        assert!(h.is_finite());
        let mut checked = 0;
        for i in (0..256).step_by(15) {
            for j in (0..240).step_by(15) {
                let u = DVec2::new(i as f64 + 0.5, j as f64 + 0.5);
                let by_h = apply_homography(&h, u, 1e-9);
                let by_ray = by_intersection(&k(), &k(), &rel, &plane, u);
                if let (Some(a), Some(b)) = (by_h, by_ray) {
                    assert!((a - b).length() <= 1e-7 * (1.0 + b.length()), "{a} vs {b}");
                    checked += 1;
                }
                // Every output is finite or masked; never NaN.
                if let Some(a) = by_h {
                    assert!(a.is_finite());
                }
            }
        }
        assert!(checked > 10);
    }

    #[test]
    fn points_behind_the_camera_are_masked() {
        let h = DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::new(0.0, 0.0, -1.0));
        assert!(apply_homography(&h, DVec2::new(3.0, 4.0), 1e-12).is_none());
        let h = DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::new(0.0, 0.0, 0.0));
        assert!(apply_homography(&h, DVec2::new(3.0, 4.0), 1e-12).is_none());
    }

    fn arb_visible_case() -> impl Strategy<Value = (RigidTransform, Plane, DVec2, DVec2)> {
        (
            arb_transform(),
            prop::array::uniform2(-0.8f64..0.8),
            0.5f64..50.0,
            prop::array::uniform2(-0.9f64..0.9),
        )
            .prop_filter_map(
                "point must be visible in both cameras and the plane from the target",
                |(rel, nxy, z, uv)| {
                    // A plane with a random normal through the point at depth z on a random
                    // reference ray; the target camera is rel (X_ref = R X_tgt + t).
                    let n = DVec3::new(nxy[0], nxy[1], 1.0).normalize();
                    let ray_ref = DVec3::new(uv[0], uv[1], 1.0);
                    let x_ref = ray_ref * z;
                    let plane = Plane::new(n, n.dot(x_ref)).ok()?;
                    let x_tgt = rel.inverse().transform_point(x_ref);
                    let u_tgt = k().project(x_tgt)?;
                    let u_ref = k().project(x_ref)?;
                    (x_tgt.z > 0.05 && plane.signed_distance(rel.translation()) > 1e-3)
                        .then_some((rel, plane, u_tgt, u_ref))
                },
            )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]

        #[test]
        fn homography_maps_points_on_the_plane((rel, plane, u_tgt, u_ref) in arb_visible_case()) {
            let h = plane_homography(&k(), &k(), &rel, &plane).unwrap();
            let p = h * DVec3::new(u_tgt.x, u_tgt.y, 1.0);
            let q = DVec3::new(u_ref.x, u_ref.y, 1.0);
            // u_ref ≅ H u_tgt: parallel homogeneous vectors, to ~1e-9 relative.
            let rel_err = p.normalize().cross(q.normalize()).length();
            prop_assert!(rel_err < 1e-9, "relative error {:e}", rel_err);
        }

        #[test]
        fn inverse_homography_round_trips((rel, plane, u_tgt, _u_ref) in arb_visible_case()) {
            let h = plane_homography(&k(), &k(), &rel, &plane).unwrap();
            let inv = h.inverse();
            let back = inv * (h * DVec3::new(u_tgt.x, u_tgt.y, 1.0));
            let back = DVec2::new(back.x / back.z, back.y / back.z);
            prop_assert!((back - u_tgt).length() < 1e-8 * (1.0 + u_tgt.length()));
        }
    }

    #[test]
    fn from_reference_is_the_inverse_direction() {
        // Mapping ref → src with the plane in the ref frame inverts the tgt → ref homography of
        // the same plane when src is the target camera.
        let ref_from_tgt = RigidTransform::new(
            DMat3::from_rotation_x(0.1) * DMat3::from_rotation_y(-0.2),
            DVec3::new(0.3, 0.1, -0.2),
        )
        .unwrap();
        let plane = Plane::at_depth(DVec3::new(0.2, -0.3, 1.0).normalize(), 4.0).unwrap();
        let tgt_to_ref = plane_homography(&k(), &k(), &ref_from_tgt, &plane).unwrap();
        let ref_to_tgt =
            plane_homography_from_reference(&k(), &k(), &ref_from_tgt.inverse(), &plane).unwrap();
        let u = DVec2::new(77.5, 140.5);
        let back = apply_homography(
            &ref_to_tgt,
            apply_homography(&tgt_to_ref, u, 1e-9).unwrap(),
            1e-9,
        )
        .unwrap();
        assert!((back - u).length() < 1e-9, "{back} vs {u}");
    }

    #[test]
    fn huge_and_tiny_baselines() {
        let plane = Plane::at_depth(DVec3::new(0.3, 0.0, 1.0).normalize(), 2.0).unwrap();
        for tx in [1e-9, 1.0, 1e3] {
            // Sideways translation keeps the target off the plane's back side for small tx; for
            // large tx the target may be behind the plane, which must be an error, not NaN.
            let rel = RigidTransform::new(DMat3::IDENTITY, DVec3::new(-tx, 0.0, 0.0)).unwrap();
            match plane_homography(&k(), &k(), &rel, &plane) {
                Ok(h) => {
                    assert!(h.is_finite());
                    let u = DVec2::new(100.5, 90.5);
                    if let (Some(a), Some(b)) = (
                        apply_homography(&h, u, 1e-12),
                        by_intersection(&k(), &k(), &rel, &plane, u),
                    ) {
                        assert!(
                            (a - b).length() < 1e-8 * (1.0 + b.length()),
                            "tx {tx}: {a} vs {b}"
                        );
                    }
                }
                Err(e) => assert!(matches!(e, Error::PlaneNotVisible { .. })),
            }
        }
    }
}
