//! The pretrained model shipped in the repository (`models/` at the workspace root), used by
//! `render` and the evaluation when no run is given.

use std::path::{Path, PathBuf};

/// Folder name of the pretrained model under `models/`.
pub const PRETRAINED_NAME: &str = "mhi-n5d16-colour-w16";

/// The pretrained model's directory (`models/mhi-n5d16-colour-w16` at the repository root), whether or not
/// it exists.
pub fn pretrained_dir() -> PathBuf {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    crate_dir
        .parent()
        .unwrap_or(crate_dir)
        .join("models")
        .join(PRETRAINED_NAME)
}

/// The pretrained model's directory if it holds a model (`config.json` and `latest.json`).
pub fn pretrained() -> Option<PathBuf> {
    let d = pretrained_dir();
    let run = crate::RunDir::new(&d);
    (run.started() && run.has_checkpoint()).then_some(d)
}
