//! Data for MHI view synthesis: RealEstate10K camera files and frames, triplet sampling with
//! rotation bins, and synthetic posed scenes with exact ground truth.
//!
//! Everything here uses plain `image` and `glam` types; there is no tensor code.
//!
//! # Example
//!
//! Generate a tiny synthetic dataset, open it as a RealEstate10K-layout dataset and draw
//! reproducible evaluation triplets:
//!
//! ```
//! use mhi_data::{Dataset, SynthConfig, TripletIndex, generate};
//!
//! # fn main() -> mhi_data::Result<()> {
//! let dir = tempfile::tempdir().unwrap();
//! let config = SynthConfig { scenes: 2, frames: 5, width: 32, height: 24, ..SynthConfig::default() };
//! generate(&config, dir.path(), &|| {})?;
//!
//! let test = Dataset::open(dir.path(), "test", 3)?;
//! assert_eq!(test.sequences.len(), 1);
//! let index = TripletIndex::sample(&test, 4, 7);
//! assert_eq!(index.triplets.len(), 4);
//! let frame = mhi_data::load_frame(&test.sequences[0].frames[0], Some((16, 12)), mhi_data::Fit::Stretch)?;
//! assert_eq!(frame.image.dimensions(), (16, 12));
//! assert_eq!(frame.camera.intrinsics.cx, 8.0);
//! # Ok(())
//! # }
//! ```

mod dataset;
mod error;
mod mix;
pub mod output;
mod re10k;
pub mod sanitize;
mod synth;
mod triplets;

use std::io::Write as _;
use std::path::Path;

pub use dataset::{
    Dataset, Fit, Frame, LoadedFrame, MAX_IMAGE_BYTES, Sampling, Sequence, Warning,
    check_regular_file, check_same_size, load_frame, read_rgb, root_name, to_f32, to_u8,
};
pub use error::{Error, Result};
pub use mix::{DataMix, DataSource};
pub use re10k::{COLUMNS, CameraFile, CameraRow};
pub use synth::{
    Hit, SYNTH_KIND, Scene, Surface, SynthConfig, SynthSummary, Texture, generate, load_scene,
    make_scene,
};
pub use triplets::{
    CLIP_LEN, NEIGHBOUR_SOURCES, NEIGHBOUR_TARGETS, PAPER_EXTRAPOLATION_SHARE, RotationBin,
    SPARSE_CLIP_LEN, STRIDE_RANGE, Triplet, TripletIndex, TripletKind, TripletSampling,
    max_rotation_deg, sample_clip, sample_clip_for, sample_neighbour_triplet,
    sample_training_triplet, sample_triplet,
};

/// File in a dataset root while [`generate`] has not finished writing it (a set `Dataset::open`
/// refuses). Here, at the crate root, so that reading datasets and making them do not import
/// each other.
pub const INCOMPLETE_MARKER: &str = "SYNTH_INCOMPLETE";

/// Write `bytes` to `path` atomically: to a temporary file beside it, then renamed into place,
/// so an interrupted write never leaves a truncated file where a good one was.
///
/// Nothing is ever written through a symbolic link: a link at `path` is replaced by the new
/// file and what it pointed to is left alone. A path that exists and is not a regular file or a
/// link (a directory, a device such as `/dev/full`, a pipe) is refused rather than replaced. A
/// new file's mode follows the process's umask (`0666` masked, as `File::create` gives); a
/// replaced regular file keeps its mode. The data is flushed to disk before the rename, so a
/// full disk is an error, and it names `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    static COUNTER: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let old = std::fs::symlink_metadata(path).ok();
    if let Some(m) = &old
        && !m.is_file()
        && !m.file_type().is_symlink()
    {
        return Err(Error::Dataset {
            path: path.to_path_buf(),
            fault: "exists and is not a regular file (a directory or a device); refusing to replace it: choose a file path".into(),
        });
    }
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let tmp = dir.join(format!(
        ".tmp-{}-{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        name.as_deref().unwrap_or("out")
    ));
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt as _;
        options.mode(0o666);
    }
    let written = (|| -> std::io::Result<()> {
        let mut file = options.open(&tmp)?;
        file.write_all(bytes)?;
        if let Some(m) = &old
            && m.is_file()
        {
            file.set_permissions(m.permissions())?;
        }
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// Encode an 8-bit RGB image as PNG (fast compression) and write it atomically.
pub fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    use image::ImageEncoder as _;
    let mut buf = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut buf,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(
        img.as_raw(),
        img.width(),
        img.height(),
        image::ExtendedColorType::Rgb8,
    )
    .map_err(|source| Error::Image {
        path: path.to_path_buf(),
        source,
    })?;
    write_atomic(path, &buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_writes_replace_links_keep_modes_and_refuse_special_files() {
        let d = tempfile::tempdir().unwrap();
        let target = d.path().join("target.txt");
        std::fs::write(&target, "old").unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let link = d.path().join("link.txt");
            std::os::unix::fs::symlink(&target, &link).unwrap();
            write_atomic(&link, b"new").unwrap();
            // The link is replaced by the file; what it pointed to is untouched.
            assert!(std::fs::symlink_metadata(&link).unwrap().is_file());
            assert_eq!(std::fs::read_to_string(&link).unwrap(), "new");
            assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
            // A new file gets what File::create gives (the umask); a replaced one keeps its mode.
            let plain = d.path().join("plain.txt");
            std::fs::write(&plain, "x").unwrap();
            let fresh = d.path().join("fresh.txt");
            write_atomic(&fresh, b"x").unwrap();
            let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode(&fresh), mode(&plain));
            std::fs::set_permissions(&fresh, std::fs::Permissions::from_mode(0o640)).unwrap();
            write_atomic(&fresh, b"y").unwrap();
            assert_eq!(mode(&fresh), 0o640);
        }
        let e = write_atomic(d.path(), b"x").unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
        if Path::new("/dev/null").exists() {
            let e = write_atomic(Path::new("/dev/null"), b"x")
                .unwrap_err()
                .to_string();
            assert!(e.contains("not a regular file"), "{e}");
            assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
        }
    }
}
