//! Discovery of RealEstate10K-layout datasets and loading of their frames.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use image::imageops::FilterType;
use image::{ImageReader, Rgb32FImage, RgbImage};
use mhi_geom::Camera;
use serde::{Deserialize, Serialize};
use walkdir::WalkDir;

use crate::error::{Error, Result};
use crate::re10k::{CameraFile, CameraRow};

/// One frame of a sequence: its camera line and the image file that holds it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// The camera line.
    pub row: CameraRow,
    /// The image file.
    pub path: PathBuf,
}

/// A sequence: the frames of one camera file that have an image on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sequence {
    /// The sequence name (camera file stem).
    pub name: String,
    /// The camera file.
    pub camera_file: PathBuf,
    /// Frames with images, in timestamp order.
    pub frames: Vec<Frame>,
}

/// Something the reader passed over, for the user to see.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Warning {
    /// The file or directory concerned.
    pub path: PathBuf,
    /// What was passed over and why.
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

/// A split of a dataset in RealEstate10K layout.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dataset {
    /// `ROOT/<split>`.
    pub dir: PathBuf,
    /// Usable sequences, sorted by name.
    pub sequences: Vec<Sequence>,
    /// Sequences skipped (no frames at all, or too few) and frames missing from kept sequences.
    pub warnings: Vec<Warning>,
    /// Number of sequences skipped entirely.
    pub skipped_sequences: usize,
    /// Number of camera lines without an image in kept sequences.
    pub missing_frames: usize,
}

/// How triplets are drawn from a sequence: its frames are either dense video or a sparse capture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampling {
    /// Consecutive video frames (20–100 frames per second): Stereo Magnification's clips of
    /// [`crate::CLIP_LEN`] frames at a random stride in [`crate::STRIDE_RANGE`].
    Video,
    /// A sparse capture (a few dozen photos): triplets from neighbouring views, clips of at most
    /// [`crate::SPARSE_CLIP_LEN`] consecutive views.
    Sparse,
}

impl Sequence {
    /// The directory that holds the sequence's frames (and, for synthetic scenes, `scene.json`).
    pub fn dir(&self) -> PathBuf {
        self.camera_file.with_extension("")
    }

    /// Video when the median gap between consecutive timestamps lies between 10 and 50 ms
    /// (RealEstate10K clips: 33 or 42 ms), a sparse capture otherwise (the converted LLFF and
    /// Strecha captures number their views 100 ms apart; hand-made files often count 0, 1, 2).
    pub fn sampling(&self) -> Sampling {
        let mut gaps: Vec<u64> = self
            .frames
            .windows(2)
            .map(|w| w[1].row.timestamp.abs_diff(w[0].row.timestamp))
            .collect();
        if gaps.is_empty() {
            return Sampling::Sparse;
        }
        gaps.sort_unstable();
        let median = gaps[gaps.len() / 2];
        if (10_000..=50_000).contains(&median) {
            Sampling::Video
        } else {
            Sampling::Sparse
        }
    }
}

/// Image file extensions accepted for frames.
const EXTENSIONS: [&str; 3] = ["png", "jpg", "jpeg"];

impl Dataset {
    /// Discover `root/split/*.txt` and their frames.
    ///
    /// Frames are `root/split/<seq>/<timestamp>.png|jpg` or `.../<seq>/<seq>_<timestamp>.jpg`.
    /// A sequence with fewer than `min_frames` images is skipped with a warning; camera lines
    /// without an image are dropped with a warning. A camera file that does not parse is an
    /// error (a corrupt dataset should be fixed, not silently shrunk).
    pub fn open(root: &Path, split: &str, min_frames: usize) -> Result<Self> {
        let dir = root.join(split);
        if root.join(crate::INCOMPLETE_MARKER).exists() {
            return Err(Error::Dataset {
                path: root.to_path_buf(),
                fault: format!(
                    "incomplete dataset: its generation was interrupted ({} is still there); generate it again",
                    crate::INCOMPLETE_MARKER
                ),
            });
        }
        if !dir.is_dir() {
            return Err(Error::Dataset {
                path: dir,
                fault: format!(
                    "no such split directory (expected RealEstate10K layout ROOT/{split}/<seq>.txt)"
                ),
            });
        }
        let mut camera_files: Vec<PathBuf> = Vec::new();
        for entry in WalkDir::new(&dir)
            .min_depth(1)
            .max_depth(1)
            .sort_by_file_name()
        {
            let entry = entry.map_err(|e| Error::Dataset {
                path: dir.clone(),
                fault: format!("cannot list directory: {e}"),
            })?;
            let p = entry.path();
            if entry.file_type().is_file() && p.extension().is_some_and(|e| e == "txt") {
                camera_files.push(p.to_path_buf());
            }
        }
        if camera_files.is_empty() {
            return Err(Error::Dataset {
                path: dir,
                fault: "no camera files (*.txt) in this split".into(),
            });
        }
        let mut out = Self {
            dir: dir.clone(),
            sequences: Vec::new(),
            warnings: Vec::new(),
            skipped_sequences: 0,
            missing_frames: 0,
        };
        for cam_path in camera_files {
            let name = cam_path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            if name.is_empty() || name == "." || name == ".." {
                out.warnings.push(Warning {
                    path: cam_path.clone(),
                    message: format!(
                        "skipped: a sequence named {name:?} would read its frames from {} folder",
                        if name == ".." { "the parent" } else { "this" }
                    ),
                });
                out.skipped_sequences += 1;
                continue;
            }
            let file = CameraFile::read(&cam_path)?;
            if let Some(w) = &file.rotation_warning {
                out.warnings.push(Warning {
                    path: cam_path.clone(),
                    message: w
                        .strip_prefix(&format!("{}: ", cam_path.display()))
                        .unwrap_or(w)
                        .to_string(),
                });
            }
            // The frame folder is the camera file's path without `.txt`, taken as the OS gives
            // it (a name that is not UTF-8 still finds its folder).
            let images = list_frames(&cam_path.with_extension(""), &name)?;
            let total = file.rows.len();
            let frames: Vec<Frame> = file
                .rows
                .into_iter()
                .filter_map(|row| {
                    images.get(&row.timestamp).map(|p| Frame {
                        row,
                        path: p.clone(),
                    })
                })
                .collect();
            let missing = total - frames.len();
            if frames.len() < min_frames.max(1) {
                out.skipped_sequences += 1;
                out.warnings.push(Warning {
                    path: cam_path.clone(),
                    message: format!(
                        "sequence skipped: {} of {total} frames have an image in {}/ (need at least {})",
                        frames.len(),
                        name,
                        min_frames.max(1)
                    ),
                });
                continue;
            }
            if missing > 0 {
                out.missing_frames += missing;
                out.warnings.push(Warning {
                    path: cam_path.clone(),
                    message: format!(
                        "{missing} of {total} frames have no image; they are left out"
                    ),
                });
            }
            out.sequences.push(Sequence {
                name,
                camera_file: cam_path,
                frames,
            });
        }
        Ok(out)
    }
}

impl Dataset {
    /// Open the same split of several roots as one dataset. With more than one root, sequence
    /// names are qualified by their root's folder name (`llff-6/room`), so triplet indices stay
    /// unambiguous; with one root this is [`Dataset::open`].
    pub fn open_many(roots: &[PathBuf], split: &str, min_frames: usize) -> Result<Self> {
        let Some(first) = roots.first() else {
            return Err(Error::InvalidArgument("no dataset root given".into()));
        };
        if roots.len() == 1 {
            return Self::open(first, split, min_frames);
        }
        let mut out: Option<Self> = None;
        for root in roots {
            let mut ds = Self::open(root, split, min_frames)?;
            let prefix = root_name(root);
            for s in &mut ds.sequences {
                s.name = format!("{prefix}/{}", s.name);
            }
            match &mut out {
                None => out = Some(ds),
                Some(o) => {
                    o.sequences.append(&mut ds.sequences);
                    o.warnings.append(&mut ds.warnings);
                    o.skipped_sequences += ds.skipped_sequences;
                    o.missing_frames += ds.missing_frames;
                }
            }
        }
        let out = out.expect("at least one root");
        let mut names: Vec<&str> = out.sequences.iter().map(|s| s.name.as_str()).collect();
        names.sort_unstable();
        if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
            return Err(Error::Dataset {
                path: out.dir.clone(),
                fault: format!(
                    "two roots share the folder name of sequence {:?}; give roots distinct names",
                    w[0]
                ),
            });
        }
        Ok(out)
    }

    /// The sequence named `name`, if the dataset has it.
    pub fn sequence(&self, name: &str) -> Option<&Sequence> {
        self.sequences.iter().find(|s| s.name == name)
    }

    /// Keep only the named sequences (`keep = true`) or all but them (`keep = false`). Every
    /// name must be a sequence of the dataset: a typo is an error listing the names there are.
    ///
    /// A name `SEQ@FROM..TO` (or `SEQ@FROM..`, to its end) names a stretch of a sequence instead:
    /// its frames `FROM..TO` in timestamp order, 0-based. Kept, the stretch becomes a sequence of
    /// its own (`SEQ@FROM..TO`); left out, what remains before and after it becomes one or two
    /// (`SEQ@0..FROM`, `SEQ@TO..N`), so no triplet spans the stretch. A long walkthrough can so
    /// give its last part to validation and the rest to training.
    pub fn select(mut self, names: &[String], keep: bool) -> Result<Self> {
        let mut stretches = Vec::new();
        for n in names {
            let (seq, range) = match n.split_once('@') {
                Some((seq, range)) => (seq, Some(range)),
                None => (n.as_str(), None),
            };
            let Some(s) = self.sequences.iter().find(|s| s.name == seq) else {
                let have: Vec<&str> = self.sequences.iter().map(|s| s.name.as_str()).collect();
                return Err(Error::Dataset {
                    path: self.dir.clone(),
                    fault: format!(
                        "no sequence named {seq:?}; the sequences are: {}",
                        have.join(", ")
                    ),
                });
            };
            if let Some(range) = range {
                let (from, to) =
                    parse_stretch(range, s.frames.len()).map_err(|fault| Error::Dataset {
                        path: self.dir.clone(),
                        fault: format!("{n:?}: {fault}"),
                    })?;
                stretches.push((seq.to_string(), from, to));
            }
        }
        let whole = |s: &Sequence| names.iter().any(|n| n == &s.name);
        let mut out = Vec::new();
        for s in std::mem::take(&mut self.sequences) {
            let cut: Vec<(usize, usize)> = stretches
                .iter()
                .filter(|(seq, _, _)| *seq == s.name)
                .map(|&(_, a, b)| (a, b))
                .collect();
            if cut.is_empty() {
                if whole(&s) == keep {
                    out.push(s);
                }
                continue;
            }
            let n = s.frames.len();
            let inside = |k: usize| cut.iter().any(|&(a, b)| (a..b).contains(&k));
            // Maximal runs of frames on the kept side, each a sequence of its own.
            let mut k = 0;
            while k < n {
                if inside(k) != keep {
                    k += 1;
                    continue;
                }
                let start = k;
                while k < n && inside(k) == keep {
                    k += 1;
                }
                out.push(Sequence {
                    name: format!("{}@{start}..{k}", s.name),
                    camera_file: s.camera_file.clone(),
                    frames: s.frames[start..k].to_vec(),
                });
            }
        }
        self.sequences = out;
        Ok(self)
    }
}

/// `FROM..TO` or `FROM..` over `n` frames: a non-empty stretch inside them.
fn parse_stretch(range: &str, n: usize) -> std::result::Result<(usize, usize), String> {
    let bad = || {
        format!(
            "a stretch is FROM..TO or FROM.. (frame indices from 0 in timestamp order; the sequence has {n} frames)"
        )
    };
    let (a, b) = range.split_once("..").ok_or_else(bad)?;
    let from: usize = a.trim().parse().map_err(|_| bad())?;
    let to: usize = if b.trim().is_empty() {
        n
    } else {
        b.trim().parse().map_err(|_| bad())?
    };
    if from >= to || to > n {
        return Err(format!(
            "frames {from}..{to} are not a non-empty stretch of the sequence's {n} frames"
        ));
    }
    Ok((from, to))
}

/// The folder name that stands for a root (its last path component).
pub fn root_name(root: &Path) -> String {
    root.components()
        .next_back()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .filter(|s| !s.is_empty() && s != "." && s != "..")
        .unwrap_or_else(|| root.display().to_string())
}

/// Map timestamp → image path for the frames in `seq_dir` (empty if the directory is missing).
fn list_frames(seq_dir: &Path, seq: &str) -> Result<HashMap<u64, PathBuf>> {
    let mut map = HashMap::new();
    if !seq_dir.is_dir() {
        return Ok(map);
    }
    for entry in WalkDir::new(seq_dir).min_depth(1).max_depth(1) {
        let entry = entry.map_err(|e| Error::Dataset {
            path: seq_dir.to_path_buf(),
            fault: format!("cannot list directory: {e}"),
        })?;
        let p = entry.path();
        // A directory named like a frame (`123.png/`) is not a frame.
        if !entry.file_type().is_file() && !p.is_file() {
            continue;
        }
        let Some(ext) = p
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
        else {
            continue;
        };
        if !EXTENSIONS.contains(&ext.as_str()) {
            continue;
        }
        let stem = p
            .file_stem()
            .map(|s| s.to_string_lossy())
            .unwrap_or_default();
        let ts = stem
            .strip_prefix(seq)
            .and_then(|s| s.strip_prefix('_'))
            .unwrap_or(&stem);
        if let Ok(ts) = ts.parse::<u64>() {
            map.insert(ts, p.to_path_buf());
        }
    }
    Ok(map)
}

/// How a frame is brought to the working resolution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Fit {
    /// Resize to exactly the target size, aspect not kept (Stereo Magnification's choice).
    #[default]
    Stretch,
    /// Crop the largest centred region of the target aspect, then resize.
    CenterCrop,
}

/// A loaded frame: pixels in `[0, 1]` and the camera that follows every resize and crop.
#[derive(Debug, Clone)]
pub struct LoadedFrame {
    /// Linear-in-file RGB values in `[0, 1]`.
    pub image: Rgb32FImage,
    /// The camera of `image`.
    pub camera: Camera,
}

/// Decode an image file. Its content must match its extension: a JPEG named `.png` is refused
/// with an error saying what it really holds (renaming it fixes it), rather than decoded by a
/// guess that would hide a mixed-up dataset.
///
/// The EXIF orientation a photo records is applied, so a portrait photo from a phone is used
/// upright, as every viewer shows it. An empty file, a file over [`MAX_IMAGE_BYTES`] and
/// anything that is not a regular file (a FIFO, `/dev/zero`) are refused before decoding.
pub fn read_rgb(path: &Path) -> Result<RgbImage> {
    use image::ImageDecoder as _;
    let img_err = |source| Error::Image {
        path: path.to_path_buf(),
        source,
    };
    let mut decoder = reader(path)?.into_decoder().map_err(img_err)?;
    let orientation = decoder.orientation().map_err(img_err)?;
    let mut img = image::DynamicImage::from_decoder(decoder).map_err(img_err)?;
    img.apply_orientation(orientation);
    Ok(img.to_rgb8())
}

/// The largest image file read (1 GiB): far above any photo, below what would exhaust memory.
pub const MAX_IMAGE_BYTES: u64 = 1 << 30;

/// Check that `path` is a regular file (a link to one is fine) of at most `max_bytes`, and not
/// empty, before it is read: a FIFO or a device such as `/dev/zero` would be read forever.
/// `what` names the file for the error ("camera file", "image").
pub fn check_regular_file(path: &Path, what: &str, max_bytes: u64) -> Result<u64> {
    let m = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !m.is_file() {
        return Err(Error::Dataset {
            path: path.to_path_buf(),
            fault: format!(
                "is not a regular file (a folder, a pipe or a device); a {what} must be a file"
            ),
        });
    }
    if m.len() == 0 {
        return Err(Error::Dataset {
            path: path.to_path_buf(),
            fault: format!("is empty (0 bytes): not a {what}"),
        });
    }
    if m.len() > max_bytes {
        return Err(Error::Dataset {
            path: path.to_path_buf(),
            fault: format!(
                "is {:.1} MB, more than a {what} can sensibly be (at most {:.0} MB)",
                m.len() as f64 / 1e6,
                max_bytes as f64 / 1e6
            ),
        });
    }
    Ok(m.len())
}

/// An image reader whose format was detected from the content and checked against the name.
fn reader(path: &Path) -> Result<ImageReader<std::io::BufReader<std::fs::File>>> {
    check_regular_file(path, "image", MAX_IMAGE_BYTES)?;
    let reader = ImageReader::open(path)
        .map_err(|e| Error::io(path, e))?
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    let by_name = image::ImageFormat::from_path(path).ok();
    if let (Some(content), Some(name)) = (reader.format(), by_name)
        && content != name
    {
        return Err(Error::Dataset {
            path: path.to_path_buf(),
            fault: format!(
                "the file holds {content:?} data but its name says {name:?}; rename it with the right extension"
            ),
        });
    }
    Ok(reader)
}

/// The size of an image as it is used: from its header, turned by its EXIF orientation.
fn oriented_dimensions(path: &Path) -> Result<(u32, u32)> {
    use image::ImageDecoder as _;
    let img_err = |source| Error::Image {
        path: path.to_path_buf(),
        source,
    };
    let mut decoder = reader(path)?.into_decoder().map_err(img_err)?;
    let (w, h) = decoder.dimensions();
    let turned = matches!(
        decoder.orientation().map_err(img_err)?,
        image::metadata::Orientation::Rotate90
            | image::metadata::Orientation::Rotate270
            | image::metadata::Orientation::Rotate90FlipH
            | image::metadata::Orientation::Rotate270FlipH
    );
    Ok(if turned { (h, w) } else { (w, h) })
}

/// Check that the frames have one size (read from their headers only): a sequence whose frames
/// differ in size is a sign of mixed-up data, and is refused naming two frames that differ.
pub fn check_same_size(frames: &[&Frame]) -> Result<(u32, u32)> {
    let mut first: Option<((u32, u32), &Path)> = None;
    for f in frames {
        let dims = oriented_dimensions(&f.path)?;
        match first {
            None => first = Some((dims, &f.path)),
            Some((d0, p0)) if d0 != dims => {
                return Err(Error::Dataset {
                    path: f.path.clone(),
                    fault: format!(
                        "frames of one sequence differ in size: this one is {}x{}, {} is {}x{}",
                        dims.0,
                        dims.1,
                        p0.display(),
                        d0.0,
                        d0.1
                    ),
                });
            }
            Some(_) => {}
        }
    }
    first
        .map(|(d, _)| d)
        .ok_or_else(|| Error::InvalidArgument("no frame to check".into()))
}

/// Load a frame, optionally bringing it to `size = (width, height)` (Lanczos-3, which also
/// low-passes when shrinking), with the intrinsics following the crop and the resize.
pub fn load_frame(frame: &Frame, size: Option<(u32, u32)>, fit: Fit) -> Result<LoadedFrame> {
    let rgb = read_rgb(&frame.path)?;
    let (w, h) = rgb.dimensions();
    let geom = |e| Error::Geometry {
        context: format!("camera of {}", frame.path.display()),
        source: e,
    };
    let camera = frame.row.camera(w, h).map_err(geom)?;
    let Some((tw, th)) = size else {
        return Ok(LoadedFrame {
            image: to_f32(&rgb),
            camera,
        });
    };
    if tw == 0 || th == 0 {
        return Err(Error::InvalidArgument(format!(
            "target size {tw}×{th} has no pixels"
        )));
    }
    let (rgb, camera) = match fit {
        Fit::Stretch => (rgb, camera),
        Fit::CenterCrop => {
            // Largest centred crop with aspect tw/th.
            let (cw, ch) = if u64::from(w) * u64::from(th) > u64::from(h) * u64::from(tw) {
                (
                    ((u64::from(h) * u64::from(tw)) / u64::from(th)).max(1) as u32,
                    h,
                )
            } else {
                (
                    w,
                    ((u64::from(w) * u64::from(th)) / u64::from(tw)).max(1) as u32,
                )
            };
            let (x0, y0) = ((w - cw) / 2, (h - ch) / 2);
            let k = camera
                .intrinsics
                .cropped((w, h), x0, y0, cw, ch)
                .map_err(geom)?;
            let cropped = image::imageops::crop_imm(&rgb, x0, y0, cw, ch).to_image();
            let cam = Camera::new(k, camera.cam_from_world, cw, ch).map_err(geom)?;
            (cropped, cam)
        }
    };
    let (cw, ch) = rgb.dimensions();
    let resized = if (cw, ch) == (tw, th) {
        rgb
    } else {
        image::imageops::resize(&rgb, tw, th, FilterType::Lanczos3)
    };
    let camera = camera.resized(tw, th).map_err(geom)?;
    Ok(LoadedFrame {
        image: to_f32(&resized),
        camera,
    })
}

/// Convert 8-bit RGB to `[0, 1]` floats.
pub fn to_f32(rgb: &RgbImage) -> Rgb32FImage {
    let (w, h) = rgb.dimensions();
    Rgb32FImage::from_fn(w, h, |x, y| {
        let p = rgb.get_pixel(x, y).0;
        image::Rgb([
            f32::from(p[0]) / 255.0,
            f32::from(p[1]) / 255.0,
            f32::from(p[2]) / 255.0,
        ])
    })
}

/// Convert `[0, 1]` floats to 8-bit RGB (values clamped, NaN to 0).
pub fn to_u8(img: &Rgb32FImage) -> RgbImage {
    let (w, h) = img.dimensions();
    let q = |v: f32| {
        if v.is_nan() {
            0
        } else {
            (v.clamp(0.0, 1.0) * 255.0).round() as u8
        }
    };
    RgbImage::from_fn(w, h, |x, y| {
        let p = img.get_pixel(x, y).0;
        image::Rgb([q(p[0]), q(p[1]), q(p[2])])
    })
}
