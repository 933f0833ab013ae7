//! The covered region of a target view: the pixels whose ray, met on the farthest plane, lands
//! inside the reference image. Every method of an MHI composites that plane opaquely, so outside
//! this region a render can only show what is not there (black); scoring those pixels measures
//! the camera path, not the method. One geometric mask per triplet, the same for every method.

use mhi_geom::glam::DVec3;
use mhi_geom::{Camera, Plane, apply_homography, pixel_center, plane_homography};

/// The covered mask of `target` (row-major, one flag per target pixel): `true` where the ray
/// through the pixel centre meets the fronto-parallel plane at depth `far` of the reference
/// camera at a point the reference image holds.
///
/// A target camera on or behind that plane sees none of it: the mask is then all `false`, as is
/// any pixel whose point would lie behind the reference camera. A non-finite or non-positive
/// `far` gives an all-`false` mask too (nothing is known to be covered).
pub fn covered_mask(reference: &Camera, target: &Camera, far: f64) -> Vec<bool> {
    let (w, h) = (target.width, target.height);
    let none = vec![false; (w as usize) * (h as usize)];
    let Ok(plane) = Plane::at_depth(DVec3::Z, far) else {
        return none;
    };
    let ref_from_tgt = reference.from_other(target);
    let Ok(hm) = plane_homography(
        &reference.intrinsics,
        &target.intrinsics,
        &ref_from_tgt,
        &plane,
    ) else {
        return none;
    };
    (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            apply_homography(&hm, pixel_center(x, y), 1e-9).is_some_and(|u| reference.contains(u))
        })
        .collect()
}

/// Fraction of `true` flags (0 for an empty mask).
pub fn fraction(mask: &[bool]) -> f64 {
    if mask.is_empty() {
        0.0
    } else {
        mask.iter().filter(|&&m| m).count() as f64 / mask.len() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mhi_geom::glam::DMat3;
    use mhi_geom::{Intrinsics, RigidTransform};

    fn cam(rot_y_deg: f64, tx: f64) -> Camera {
        let k = Intrinsics::new(32.0, 32.0, 16.0, 12.0).unwrap();
        let pose = RigidTransform::new(
            DMat3::from_rotation_y(rot_y_deg.to_radians()),
            DVec3::new(tx, 0.0, 0.0),
        )
        .unwrap();
        Camera::new(k, pose, 32, 24).unwrap()
    }

    #[test]
    fn same_view_is_covered_and_a_turned_view_is_partly_uncovered() {
        let r = cam(0.0, 0.0);
        assert!(covered_mask(&r, &r, 100.0).iter().all(|&m| m));
        // Turned by 20° about y (horizontal field of view 53°): a band on one side is not seen.
        let t = cam(20.0, 0.0);
        let m = covered_mask(&r, &t, 100.0);
        let f = fraction(&m);
        assert!(f > 0.3 && f < 0.8, "{f}");
        // Turned about y: one side of the target is what the reference never saw, the other
        // side is seen.
        assert_ne!(m[12 * 32], m[12 * 32 + 31]);
        // Looking away entirely: nothing covered.
        assert_eq!(fraction(&covered_mask(&r, &cam(120.0, 0.0), 100.0)), 0.0);
        assert_eq!(fraction(&covered_mask(&r, &t, f64::NAN)), 0.0);
    }
}
