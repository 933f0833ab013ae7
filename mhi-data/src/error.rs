//! The error type of the data crate: every variant names the file it concerns.

use std::path::PathBuf;

/// What went wrong reading, sampling or writing data.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A camera file that does not follow the RealEstate10K format.
    #[error("{path}:{line}: {fault}", path = path.display())]
    CameraFile {
        /// The camera file.
        path: PathBuf,
        /// 1-based line number (0 when the fault concerns the whole file).
        line: usize,
        /// What is wrong on that line.
        fault: String,
    },
    /// A file or directory that could not be read or written.
    #[error("{path}", path = path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// An image that could not be decoded or encoded.
    #[error("{path}: cannot decode or encode the image", path = path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// The codec's error.
        source: image::ImageError,
    },
    /// A JSON file that could not be read or written.
    #[error("{path}: invalid JSON", path = path.display())]
    Json {
        /// The JSON file.
        path: PathBuf,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// A dataset whose layout or content is not usable.
    #[error("{path}: {fault}", path = path.display())]
    Dataset {
        /// The dataset directory or file concerned.
        path: PathBuf,
        /// What is wrong.
        fault: String,
    },
    /// Geometry refused by `mhi-geom`, with what was being built.
    #[error("{context}")]
    Geometry {
        /// What was being built.
        context: String,
        /// The geometric error.
        source: mhi_geom::Error,
    },
    /// An argument out of its valid range.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

/// Result of a data operation.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}
