//! The error type of every fallible geometric operation.

/// Why a geometric construction was refused.
///
/// Geometry never returns NaN or an absurdly large matrix: it returns one of these instead.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// An input held NaN or ±∞.
    #[error("{what} is not finite (contains NaN or infinity)")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// A matrix that should be a rotation is not orthonormal with determinant +1.
    #[error(
        "{what} is not a rotation: max |RᵀR − I| = {orthogonality_error:.3e} (tolerance {tolerance:.1e}), det = {determinant:.6}"
    )]
    NotARotation {
        /// Which input.
        what: &'static str,
        /// Largest entry of `|RᵀR − I|`.
        orthogonality_error: f64,
        /// The determinant (must be close to +1).
        determinant: f64,
        /// The tolerance that was applied.
        tolerance: f64,
    },
    /// A matrix that is orthonormal but has determinant −1: a mirror, not a rotation.
    #[error(
        "{what} is a reflection, not a rotation (det = {determinant:.6}): a left-handed frame or one axis flipped; negate one axis of the pose (both its rotation row and its translation entry) to make it right-handed"
    )]
    Reflection {
        /// Which input.
        what: &'static str,
        /// The determinant (close to −1).
        determinant: f64,
    },
    /// Intrinsics that cannot describe a pinhole camera.
    #[error("invalid intrinsics: {reason}")]
    InvalidIntrinsics {
        /// What is wrong.
        reason: String,
    },
    /// An image size of zero pixels, or a crop outside the image.
    #[error("invalid image size or crop: {reason}")]
    InvalidImageSize {
        /// What is wrong.
        reason: String,
    },
    /// A plane normal that is not unit length or does not face the reference camera.
    #[error("invalid plane normal ({x}, {y}, {z}): {reason}", x = normal[0], y = normal[1], z = normal[2])]
    InvalidNormal {
        /// The offending normal.
        normal: [f64; 3],
        /// What is wrong.
        reason: &'static str,
    },
    /// A plane offset `d` that is not strictly positive.
    #[error(
        "invalid plane offset d = {d}: planes must lie in front of the reference camera (d > 0)"
    )]
    InvalidPlaneOffset {
        /// The offending offset.
        d: f64,
    },
    /// A depth range or plane count that cannot be sampled.
    #[error("invalid depth range near = {near}, far = {far}, count = {count}: {reason}")]
    InvalidDepthRange {
        /// Nearest depth.
        near: f64,
        /// Farthest depth.
        far: f64,
        /// Number of planes asked for.
        count: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A normal set that is empty or a paper subset that does not exist.
    #[error("invalid normal set: {reason}")]
    InvalidNormalSet {
        /// What is wrong.
        reason: String,
    },
    /// The target camera is on or behind the plane, so the plane is invisible from it.
    #[error(
        "plane not visible from the target camera: signed distance d − nᵀt = {signed_distance:.3e} is not clearly positive (needs > {threshold:.3e})"
    )]
    PlaneNotVisible {
        /// `d − nᵀt`, the signed distance from the target camera centre to the plane.
        signed_distance: f64,
        /// The smallest distance accepted for this configuration.
        threshold: f64,
    },
    /// A matrix that had to be inverted is singular.
    #[error("{what} is singular (determinant {determinant:.3e})")]
    Singular {
        /// Which matrix.
        what: &'static str,
        /// Its determinant.
        determinant: f64,
    },
    /// Camera-path parameters that describe no usable path (zero frames, a radius of zero or
    /// NaN, a turn past the side of the scene).
    #[error("invalid camera path: {reason}")]
    InvalidPath {
        /// What is wrong.
        reason: String,
    },
    /// A zero-length vector where a direction was needed.
    #[error("{what} has zero length")]
    ZeroVector {
        /// Which vector.
        what: &'static str,
    },
}

/// Result of a geometric operation.
pub type Result<T> = std::result::Result<T, Error>;

/// Fail with [`Error::NonFinite`] unless every value is finite.
pub(crate) fn ensure_finite(what: &'static str, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite { what })
    }
}
