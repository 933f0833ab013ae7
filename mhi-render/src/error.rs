//! The error type of the renderer.

/// Why an MHI could not be built or rendered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// Inputs whose sizes or values do not form a valid MHI.
    #[error("invalid MHI: {0}")]
    InvalidMhi(String),
    /// Blending weights that are not usable.
    #[error("invalid blending weights: {0}")]
    InvalidWeights(String),
    /// An input image or camera that does not fit the operation.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// Geometry refused by `mhi-geom`.
    #[error("{context}")]
    Geometry {
        /// What was being built.
        context: String,
        /// The geometric error.
        source: mhi_geom::Error,
    },
}

/// Result of a rendering operation.
pub type Result<T> = std::result::Result<T, Error>;
