//! The pretrained model shipped in the repository (`models/`), used by `render` and `eval` when
//! no `--run` is given.

use std::path::PathBuf;

/// Folder name of the pretrained model under `models/`.
pub const PRETRAINED_NAME: &str = "mhi-n5d16-colour";

/// The pretrained model's directory (`models/mhi-n5d16-colour` at the repository root), whether or not
/// it exists.
pub fn pretrained_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("models")
        .join(PRETRAINED_NAME)
}

/// The pretrained model's directory if it holds a model (`config.json` and `latest.json`).
pub fn pretrained() -> Option<PathBuf> {
    let d = pretrained_dir();
    let run = mhi_net::RunDir::new(&d);
    (run.started() && run.has_checkpoint()).then_some(d)
}
