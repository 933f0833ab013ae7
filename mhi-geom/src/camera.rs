//! A posed pinhole camera: intrinsics, world-to-camera pose and image size.

use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::intrinsics::Intrinsics;
use crate::pose::RigidTransform;

/// A pinhole camera with its image size and world-to-camera pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    /// Intrinsics in pixels of a `width × height` image.
    pub intrinsics: Intrinsics,
    /// World-to-camera pose, `X_cam = R · X_world + t`.
    pub cam_from_world: RigidTransform,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera, rejecting an empty image size.
    pub fn new(
        intrinsics: Intrinsics,
        cam_from_world: RigidTransform,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::InvalidImageSize {
                reason: format!("camera image size {width}×{height} has no pixels"),
            });
        }
        Ok(Self {
            intrinsics,
            cam_from_world,
            width,
            height,
        })
    }

    /// The same camera for the image resized to `width × height` (aspect need not be kept).
    pub fn resized(&self, width: u32, height: u32) -> Result<Self> {
        let intrinsics = self
            .intrinsics
            .resized((self.width, self.height), (width, height))?;
        Self::new(intrinsics, self.cam_from_world, width, height)
    }

    /// The relative pose `self_from_other`, mapping points of `other`'s frame into this one.
    pub fn from_other(&self, other: &Camera) -> RigidTransform {
        RigidTransform::relative(&self.cam_from_world, &other.cam_from_world)
    }

    /// Project a world point to pixels; `None` behind the camera.
    pub fn project_world(&self, x_world: DVec3) -> Option<DVec2> {
        self.intrinsics
            .project(self.cam_from_world.transform_point(x_world))
    }

    /// Camera centre in world coordinates.
    pub fn center_in_world(&self) -> DVec3 {
        self.cam_from_world.center()
    }

    /// Whether a pixel position (continuous frame) lies inside the image.
    pub fn contains(&self, pixel: DVec2) -> bool {
        pixel.x >= 0.0
            && pixel.y >= 0.0
            && pixel.x < f64::from(self.width)
            && pixel.y < f64::from(self.height)
    }
}
