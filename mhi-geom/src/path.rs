//! Camera paths around a reference camera, for videos of novel views.
//!
//! Every path is laid out in the reference camera's frame (x right, y down, z forward) and in
//! the scene's own scale, then carried into the world by the reference's pose; every camera
//! keeps the reference's intrinsics and image size. The paths:
//! - [`orbit`]: a circle in the image plane, each camera turned toward a point on the axis;
//! - [`circle`]: the paper's circular light field, cameras on a circle through the reference
//!   whose centre lies on its optical axis, each looking at that centre, stepping a fixed angle
//!   forward, back past the reference and forward again (interpolating and extrapolating);
//! - [`spiral`]: LLFF's forward-facing spiral, looking at a focus depth;
//! - [`dolly`]: in and out along the optical axis, without turning.
//!
//! [`PathRange`] says how far a path turns and travels. Whether it crosses a plane of an MHI
//! is the renderer's question (`mhi_render::plan::check_path`).

use glam::{DMat3, DVec3};

use crate::error::{Error, Result};
use crate::{Camera, RigidTransform};

/// The largest angle any path may turn a camera from the reference, in degrees: beyond it the
/// view looks past the side of everything the reference photo saw.
pub const MAX_TURN_DEG: f64 = 60.0;

fn invalid(reason: String) -> Error {
    Error::InvalidPath { reason }
}

fn check_frames(frames: usize) -> Result<()> {
    if frames == 0 {
        return Err(invalid(
            "zero frames: a path needs at least one camera".into(),
        ));
    }
    Ok(())
}

fn check_length(what: &str, v: f64) -> Result<()> {
    if !(v.is_finite() && v > 0.0) {
        return Err(invalid(format!(
            "{what} {v} must be a finite length above zero (in the scene's units)"
        )));
    }
    Ok(())
}

/// The rotation (camera from reference) of a camera at `center` looking at `target`, both in
/// the reference frame, with no roll about its axis (its x axis stays horizontal: ⟂ to y).
fn look_at(center: DVec3, target: DVec3) -> Result<DMat3> {
    let fwd = (target - center).try_normalize().ok_or(Error::ZeroVector {
        what: "the view direction (the camera sits on the point it looks at)",
    })?;
    let right = DVec3::Y
        .cross(fwd)
        .try_normalize()
        .ok_or(Error::ZeroVector {
            what: "the camera's x axis (it looks straight up or down)",
        })?;
    let down = fwd.cross(right);
    Ok(DMat3::from_cols(right, down, fwd).transpose())
}

/// A camera at `center` (reference frame) with rotation `cam_from_ref`, carried into the world.
fn place(reference: &Camera, center: DVec3, cam_from_ref: DMat3) -> Result<Camera> {
    let world_from_ref = reference.cam_from_world.inverse();
    let center_w = world_from_ref.transform_point(center);
    let r = cam_from_ref * reference.cam_from_world.rotation();
    let pose = RigidTransform::new(r, -(r * center_w))?;
    Camera::new(
        reference.intrinsics,
        pose,
        reference.width,
        reference.height,
    )
}

/// Cameras on a circle of `radius` around the reference camera's centre, in its image plane
/// (starting right of it, then down), each turned to look at the point `look_at` units along
/// the reference's optical axis (as a hand-held orbit does; `None` keeps the reference's
/// orientation, a pure translation).
pub fn orbit(
    reference: &Camera,
    radius: f64,
    frames: usize,
    look_at_depth: Option<f64>,
) -> Result<Vec<Camera>> {
    check_frames(frames)?;
    check_length("the orbit's radius", radius)?;
    if let Some(z) = look_at_depth {
        check_length("the orbit's look-at depth", z)?;
    }
    (0..frames)
        .map(|k| {
            let th = std::f64::consts::TAU * k as f64 / frames as f64;
            let c = DVec3::new(radius * th.cos(), radius * th.sin(), 0.0);
            let turn = match look_at_depth {
                Some(z) => look_at(c, DVec3::new(0.0, 0.0, z))?,
                None => DMat3::IDENTITY,
            };
            place(reference, c, turn)
        })
        .collect()
}

/// The largest angle the circular path reaches with `frames` steps of `step_deg`.
pub fn circle_max_deg(step_deg: f64, frames: usize) -> f64 {
    step_deg * frames as f64 / 4.0
}

/// The paper's circular light field: cameras on a circle of `radius` through the reference
/// camera, centred `radius` ahead of it on its optical axis, each looking at the centre, turned
/// about the reference's vertical axis. The angle moves `step_deg` a frame, from 0 out to
/// `+max`, back through 0 to `−max` and home again, so the video loops and covers both turning
/// directions; `max` is `step_deg · frames / 4` ([`circle_max_deg`]).
pub fn circle(
    reference: &Camera,
    radius: f64,
    step_deg: f64,
    frames: usize,
) -> Result<Vec<Camera>> {
    check_frames(frames)?;
    check_length("the circle's radius", radius)?;
    if !(step_deg.is_finite() && step_deg > 0.0) {
        return Err(invalid(format!(
            "the circle's step {step_deg}° must be a finite angle above zero"
        )));
    }
    let max = circle_max_deg(step_deg, frames);
    if max > MAX_TURN_DEG {
        return Err(invalid(format!(
            "{frames} steps of {step_deg}° turn the camera up to {max:.1}°; at most {MAX_TURN_DEG}° (fewer frames or a smaller step)"
        )));
    }
    let centre = DVec3::new(0.0, 0.0, radius);
    (0..frames)
        .map(|k| {
            // A triangle wave of period `frames` through 0, +max, 0, −max.
            let p = k as f64 / frames as f64;
            let tri = if p < 0.25 {
                4.0 * p
            } else if p < 0.75 {
                2.0 - 4.0 * p
            } else {
                4.0 * p - 4.0
            };
            let th = (tri * max).to_radians();
            let c = DVec3::new(radius * th.sin(), 0.0, radius * (1.0 - th.cos()));
            place(reference, c, look_at(c, centre)?)
        })
        .collect()
}

/// LLFF's forward-facing spiral ("render_path_spiral"): `rotations` turns of a circle of
/// `radius` in the image plane while the camera moves `radius / 2` in and out along the axis at
/// half the rate, every camera looking at the point `focus` units along the reference's axis.
pub fn spiral(
    reference: &Camera,
    radius: f64,
    frames: usize,
    focus: f64,
    rotations: f64,
) -> Result<Vec<Camera>> {
    check_frames(frames)?;
    check_length("the spiral's radius", radius)?;
    check_length("the spiral's focus depth", focus)?;
    if !(rotations.is_finite() && rotations > 0.0) {
        return Err(invalid(format!(
            "the spiral's {rotations} rotations must be a finite count above zero"
        )));
    }
    let target = DVec3::new(0.0, 0.0, focus);
    (0..frames)
        .map(|k| {
            let th = std::f64::consts::TAU * rotations * k as f64 / frames as f64;
            let c = DVec3::new(
                radius * th.cos(),
                radius * th.sin(),
                0.5 * radius * (0.5 * th).sin(),
            );
            place(reference, c, look_at(c, target)?)
        })
        .collect()
}

/// LLFF's focus depth for a scene between `near` and `far`: its disparity is a quarter of
/// 0.9 · near's plus three quarters of 5 · far's.
pub fn llff_focus(near: f64, far: f64) -> Result<f64> {
    check_length("the near depth", near)?;
    check_length("the far depth", far)?;
    Ok(1.0 / (0.25 / (0.9 * near) + 0.75 / (5.0 * far)))
}

/// In and out along the reference's optical axis by up to `distance`, without turning: one
/// period of a sine, starting at the reference and moving forward first.
pub fn dolly(reference: &Camera, distance: f64, frames: usize) -> Result<Vec<Camera>> {
    check_frames(frames)?;
    check_length("the dolly's distance", distance)?;
    (0..frames)
        .map(|k| {
            let th = std::f64::consts::TAU * k as f64 / frames as f64;
            place(
                reference,
                DVec3::new(0.0, 0.0, distance * th.sin()),
                DMat3::IDENTITY,
            )
        })
        .collect()
}

/// How far a path turns and travels from its reference camera.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PathRange {
    /// Cameras on the path.
    pub frames: usize,
    /// The largest rotation from the reference, in degrees.
    pub max_rotation_deg: f64,
    /// The smallest and largest camera centre per axis, in the reference frame (x right, y
    /// down, z forward), in the scene's units.
    pub min_center: [f64; 3],
    /// See [`PathRange::min_center`].
    pub max_center: [f64; 3],
    /// The largest distance of a camera centre from the reference's.
    pub max_distance: f64,
}

impl PathRange {
    /// Measure `path` against `reference`.
    pub fn of(reference: &Camera, path: &[Camera]) -> Self {
        let mut r = Self {
            frames: path.len(),
            max_rotation_deg: 0.0,
            min_center: [f64::INFINITY; 3],
            max_center: [f64::NEG_INFINITY; 3],
            max_distance: 0.0,
        };
        for cam in path {
            let rel = RigidTransform::relative(&reference.cam_from_world, &cam.cam_from_world);
            r.max_rotation_deg = r.max_rotation_deg.max(rel.rotation_angle_deg());
            let c = reference
                .cam_from_world
                .transform_point(cam.center_in_world());
            for (i, v) in c.to_array().into_iter().enumerate() {
                r.min_center[i] = r.min_center[i].min(v);
                r.max_center[i] = r.max_center[i].max(v);
            }
            r.max_distance = r.max_distance.max(c.length());
        }
        r
    }
}

impl std::fmt::Display for PathRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (lo, hi) = (self.min_center, self.max_center);
        write!(
            f,
            "{} cameras, rotation up to {:.1}°, centres x {:+.3}..{:+.3}, y {:+.3}..{:+.3}, z {:+.3}..{:+.3} (up to {:.3} from the reference)",
            self.frames,
            self.max_rotation_deg,
            lo[0],
            hi[0],
            lo[1],
            hi[1],
            lo[2],
            hi[2],
            self.max_distance
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Intrinsics;
    use crate::test_support::assert_close;

    fn reference() -> Camera {
        let k = Intrinsics::new(100.0, 100.0, 64.0, 48.0).unwrap();
        let pose = RigidTransform::new(
            DMat3::from_rotation_y(0.3) * DMat3::from_rotation_x(-0.1),
            DVec3::new(0.5, -0.2, 1.0),
        )
        .unwrap();
        Camera::new(k, pose, 128, 96).unwrap()
    }

    /// A point's coordinates in the reference frame.
    fn in_ref(r: &Camera, cam: &Camera) -> DVec3 {
        r.cam_from_world.transform_point(cam.center_in_world())
    }

    #[test]
    fn the_circle_steps_its_angle_and_looks_at_its_centre() {
        let r = reference();
        let path = circle(&r, 2.0, 2.0, 20).unwrap();
        let range = PathRange::of(&r, &path);
        assert_close(range.max_rotation_deg, 10.0, 1e-9);
        // The first camera is the reference; consecutive cameras turn by the step.
        assert_close(in_ref(&r, &path[0]).length(), 0.0, 1e-12);
        for w in path.windows(2) {
            let rel = RigidTransform::relative(&w[0].cam_from_world, &w[1].cam_from_world);
            assert_close(rel.rotation_angle_deg(), 2.0, 1e-9);
        }
        let centre_w = r
            .cam_from_world
            .inverse()
            .transform_point(DVec3::new(0.0, 0.0, 2.0));
        for cam in &path {
            // Every camera lies on the circle and sees its centre on its optical axis.
            assert_close(
                (in_ref(&r, cam) - DVec3::new(0.0, 0.0, 2.0)).length(),
                2.0,
                1e-12,
            );
            let p = cam.cam_from_world.transform_point(centre_w);
            assert_close(p.x, 0.0, 1e-12);
            assert_close(p.y, 0.0, 1e-12);
            assert!(p.z > 0.0);
            // It turns only about the vertical axis: the centre's y stays 0 (checked), and so
            // does every camera's.
            assert_close(in_ref(&r, cam).y, 0.0, 1e-12);
        }
        // Both directions: cameras right and left of the reference.
        assert!(range.min_center[0] < -0.3 && range.max_center[0] > 0.3);
    }

    #[test]
    fn the_dolly_moves_along_the_axis_without_turning() {
        let r = reference();
        let path = dolly(&r, 0.4, 16).unwrap();
        let range = PathRange::of(&r, &path);
        assert_close(range.max_rotation_deg, 0.0, 1e-9);
        assert_close(range.max_center[2], 0.4, 1e-12);
        assert_close(range.min_center[2], -0.4, 1e-12);
        assert_close(range.max_center[0] - range.min_center[0], 0.0, 1e-12);
    }

    #[test]
    fn the_spiral_and_orbit_look_at_their_focus() {
        let r = reference();
        let focus_w = r
            .cam_from_world
            .inverse()
            .transform_point(DVec3::new(0.0, 0.0, 3.0));
        for path in [
            spiral(&r, 0.2, 30, 3.0, 2.0).unwrap(),
            orbit(&r, 0.2, 30, Some(3.0)).unwrap(),
        ] {
            for cam in &path {
                let p = cam.cam_from_world.transform_point(focus_w);
                assert_close(p.x, 0.0, 1e-12);
                assert_close(p.y, 0.0, 1e-12);
            }
            let range = PathRange::of(&r, &path);
            assert_close(range.max_center[0], 0.2, 1e-3);
        }
        assert_close(
            llff_focus(1.0, 100.0).unwrap(),
            1.0 / (0.25 / 0.9 + 0.75 / 500.0),
            1e-12,
        );
    }

    #[test]
    fn impossible_parameters_are_refused() {
        let r = reference();
        for e in [
            circle(&r, 0.0, 2.0, 10),
            circle(&r, f64::NAN, 2.0, 10),
            circle(&r, 1.0, 2.0, 0),
            circle(&r, 1.0, -1.0, 10),
            circle(&r, 1.0, 10.0, 40),
            dolly(&r, f64::INFINITY, 10),
            dolly(&r, 0.1, 0),
            spiral(&r, 0.1, 10, 0.0, 2.0),
            spiral(&r, 0.1, 10, 1.0, f64::NAN),
            orbit(&r, -1.0, 10, None),
            orbit(&r, 1.0, 10, Some(f64::NAN)),
        ] {
            assert!(matches!(e, Err(Error::InvalidPath { .. })), "{e:?}");
        }
    }
}
