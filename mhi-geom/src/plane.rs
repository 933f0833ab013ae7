//! Planes `{X : n·X = d}` in the reference camera frame, the paper's normal sets, and plane
//! depths spaced linearly in disparity.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result, ensure_finite};

/// Tolerance on `|‖n‖ − 1|` for a normal to count as unit length.
pub const UNIT_TOLERANCE: f64 = 1e-9;

/// A plane `{X : n·X = d}` in the reference camera frame with `n` a unit normal, `n_z > 0` and
/// `d > 0` (it lies in front of the reference camera and faces it).
///
/// The paper writes `nᵀX + d = 0`; its `d` is our `−d`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    normal: DVec3,
    d: f64,
}

impl Plane {
    /// A validated plane.
    pub fn new(normal: DVec3, d: f64) -> Result<Self> {
        let normal = validate_normal(normal)?;
        ensure_finite("plane offset", &[d])?;
        if d <= 0.0 {
            return Err(Error::InvalidPlaneOffset { d });
        }
        Ok(Self { normal, d })
    }

    /// The plane of `normal` crossing the optical axis at depth `z`: `d = z · n_z`.
    pub fn at_depth(normal: DVec3, z: f64) -> Result<Self> {
        let normal = validate_normal(normal)?;
        ensure_finite("plane depth", &[z])?;
        Self::new(normal, z * normal.z)
    }

    /// The unit normal `n`.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The offset `d` (distance from the reference camera centre to the plane).
    pub fn d(&self) -> f64 {
        self.d
    }

    /// Depth at which the plane crosses the reference optical axis: `d / n_z`.
    pub fn axis_depth(&self) -> f64 {
        self.d / self.normal.z
    }

    /// Signed distance of a point to the plane, `d − n·x`: positive on the reference camera's
    /// side.
    pub fn signed_distance(&self, x: DVec3) -> f64 {
        self.d - self.normal.dot(x)
    }

    /// Where the ray `origin + s · dir` (`s > 0`) meets the plane, as the ray parameter `s`.
    /// `None` when the ray is parallel to the plane (`|n·dir| ≤ 1e-12 ‖dir‖`) or meets it behind
    /// the origin.
    pub fn intersect_ray(&self, origin: DVec3, dir: DVec3) -> Option<f64> {
        let denom = self.normal.dot(dir);
        if !(denom.abs() > 1e-12 * dir.length()) {
            return None;
        }
        let s = self.signed_distance(origin) / denom;
        (s > 0.0 && s.is_finite()).then_some(s)
    }
}

/// Check that `n` is a finite unit vector with `n_z > 0`.
pub fn validate_normal(n: DVec3) -> Result<DVec3> {
    let arr = n.to_array();
    ensure_finite("plane normal", &arr)?;
    if (n.length() - 1.0).abs() > UNIT_TOLERANCE {
        return Err(Error::InvalidNormal {
            normal: arr,
            reason: "not unit length",
        });
    }
    if n.z <= 0.0 {
        return Err(Error::InvalidNormal {
            normal: arr,
            reason: "n_z must be > 0 so the plane faces the reference camera",
        });
    }
    Ok(n)
}

/// An ordered set of plane normals, each a unit vector with `n_z > 0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NormalSet {
    normals: Vec<DVec3>,
}

impl NormalSet {
    /// The paper's five normals n1 … n5 (docs/METHOD.md).
    pub fn paper() -> Self {
        let h2 = std::f64::consts::FRAC_1_SQRT_2;
        let h3 = 3.0_f64.sqrt() / 2.0;
        Self {
            normals: vec![
                DVec3::new(h2, 0.0, h2),
                DVec3::new(0.0, -h3, 0.5),
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(0.0, h3, 0.5),
                DVec3::new(-h2, 0.0, h2),
            ],
        }
    }

    /// The paper's subsets: N = 1 is {n3} (an MPI), N = 2 {n1, n5}, N = 3 {n1, n3, n5}, N = 5
    /// all five.
    pub fn paper_subset(n: usize) -> Result<Self> {
        let all = Self::paper().normals;
        let pick: &[usize] = match n {
            1 => &[2],
            2 => &[0, 4],
            3 => &[0, 2, 4],
            5 => &[0, 1, 2, 3, 4],
            _ => {
                return Err(Error::InvalidNormalSet {
                    reason: format!(
                        "the paper defines sets of N = 1, 2, 3 or 5 normals, not {n} (other sets are built with NormalSet::custom)"
                    ),
                });
            }
        };
        Ok(Self {
            normals: pick.iter().map(|&i| all[i]).collect(),
        })
    }

    /// A custom set; every normal must be unit length with `n_z > 0`.
    pub fn custom(normals: Vec<DVec3>) -> Result<Self> {
        if normals.is_empty() {
            return Err(Error::InvalidNormalSet {
                reason: "a normal set needs at least one normal".into(),
            });
        }
        for n in &normals {
            validate_normal(*n)?;
        }
        Ok(Self { normals })
    }

    /// The normals, in order.
    pub fn normals(&self) -> &[DVec3] {
        &self.normals
    }

    /// Number of normals N.
    pub fn len(&self) -> usize {
        self.normals.len()
    }

    /// Always false: a set holds at least one normal.
    pub fn is_empty(&self) -> bool {
        self.normals.is_empty()
    }

    /// The N × D planes: for each normal (outer) and each depth (inner), the plane crossing the
    /// optical axis at that depth.
    pub fn planes(&self, depths: &[f64]) -> Result<Vec<Plane>> {
        let mut out = Vec::with_capacity(self.len() * depths.len());
        for n in &self.normals {
            for z in depths {
                out.push(Plane::at_depth(*n, *z)?);
            }
        }
        Ok(out)
    }
}

/// `count` depths from `far` down to `near`, spaced linearly in disparity `1/z`, far first
/// (the back-to-front order of compositing). With `count = 1` the single depth is `far`.
///
/// Requires `0 < near < far`, both finite.
pub fn depths_linear_in_disparity(near: f64, far: f64, count: usize) -> Result<Vec<f64>> {
    let err = |reason| Error::InvalidDepthRange {
        near,
        far,
        count,
        reason,
    };
    if !near.is_finite() || !far.is_finite() {
        return Err(err("near and far must be finite"));
    }
    if !(near > 0.0) {
        return Err(err("near must be > 0"));
    }
    if !(far > near) {
        return Err(err("far must be > near"));
    }
    if count == 0 {
        return Err(err("at least one plane is needed"));
    }
    if count == 1 {
        return Ok(vec![far]);
    }
    let (d_far, d_near) = (1.0 / far, 1.0 / near);
    let last = (count - 1) as f64;
    Ok((0..count)
        .map(|i| {
            if i == 0 {
                far
            } else if i == count - 1 {
                near
            } else {
                let t = i as f64 / last;
                1.0 / (d_far + t * (d_near - d_far))
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::assert_close;

    #[test]
    fn paper_normals_are_unit_and_face_the_camera() {
        let set = NormalSet::paper();
        assert_eq!(set.len(), 5);
        for n in set.normals() {
            assert!(validate_normal(*n).is_ok(), "{n}");
        }
        assert_eq!(NormalSet::paper_subset(1).unwrap().normals(), &[DVec3::Z]);
        assert_eq!(NormalSet::paper_subset(3).unwrap().normals()[1], DVec3::Z);
        assert_eq!(NormalSet::paper_subset(2).unwrap().len(), 2);
        assert!(NormalSet::paper_subset(4).is_err());
    }

    #[test]
    fn custom_sets_are_validated() {
        assert!(NormalSet::custom(vec![]).is_err());
        let err = NormalSet::custom(vec![DVec3::new(0.0, 0.0, 2.0)]).unwrap_err();
        assert!(err.to_string().contains("not unit length"), "{err}");
        assert!(NormalSet::custom(vec![-DVec3::Z]).is_err());
        assert!(NormalSet::custom(vec![DVec3::new(0.0, f64::NAN, 1.0)]).is_err());
        let nine: Vec<DVec3> = (0..9)
            .map(|i| {
                let a = i as f64 * 0.1;
                DVec3::new(a.sin() * 0.5, a.cos() * 0.3, 1.0).normalize()
            })
            .collect();
        assert_eq!(NormalSet::custom(nine).unwrap().len(), 9);
    }

    #[test]
    fn plane_at_depth_crosses_the_axis_there() {
        let n = NormalSet::paper().normals()[1];
        let p = Plane::at_depth(n, 4.0).unwrap();
        assert_close(p.d(), 4.0 * n.z, 1e-15);
        assert_close(p.axis_depth(), 4.0, 1e-15);
        assert_close(p.signed_distance(DVec3::new(0.0, 0.0, 4.0)), 0.0, 1e-15);
        assert!(Plane::new(DVec3::Z, 0.0).is_err());
        assert!(Plane::new(DVec3::Z, -1.0).is_err());
        let s = p.intersect_ray(DVec3::ZERO, DVec3::Z).unwrap();
        assert_close(s, 4.0, 1e-15);
        assert!(
            Plane::new(DVec3::Z, 1.0)
                .unwrap()
                .intersect_ray(DVec3::ZERO, DVec3::X)
                .is_none()
        );
    }

    #[test]
    fn depths_are_linear_in_disparity_far_first() {
        let z = depths_linear_in_disparity(1.0, 100.0, 32).unwrap();
        assert_eq!(z.len(), 32);
        assert_eq!(z[0], 100.0);
        assert_eq!(z[31], 1.0);
        let step = 1.0 / z[1] - 1.0 / z[0];
        for w in z.windows(2) {
            assert!(w[1] < w[0]);
            assert_close(1.0 / w[1] - 1.0 / w[0], step, 1e-12);
        }
        assert_eq!(
            depths_linear_in_disparity(1.0, 100.0, 1).unwrap(),
            vec![100.0]
        );
    }

    #[test]
    fn extreme_depth_ranges() {
        let z = depths_linear_in_disparity(1e-3, 1e6, 256).unwrap();
        assert_eq!((z[0], z[255]), (1e6, 1e-3));
        assert!(z.iter().all(|v| v.is_finite() && *v > 0.0));
        assert!(z.windows(2).all(|w| w[1] < w[0]));
        for bad in [
            (0.0, 1.0, 4),
            (2.0, 1.0, 4),
            (1.0, 1.0, 4),
            (1.0, f64::INFINITY, 4),
            (1.0, 2.0, 0),
            (f64::NAN, 2.0, 3),
        ] {
            assert!(
                matches!(
                    depths_linear_in_disparity(bad.0, bad.1, bad.2),
                    Err(Error::InvalidDepthRange { .. })
                ),
                "{bad:?}"
            );
        }
    }
}
