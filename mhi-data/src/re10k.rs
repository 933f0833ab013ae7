//! Strict reader and writer of RealEstate10K camera files.
//!
//! A camera file `ROOT/<split>/<seq>.txt` holds a URL on its first line, then one line per frame:
//! `timestamp fx fy cx cy k1 k2 r11 r12 r13 t1 r21 r22 r23 t2 r31 r32 r33 t3` (19 numbers: a
//! microsecond timestamp, normalised intrinsics, two zero distortion terms and the
//! world-to-camera matrix row by row).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use mhi_geom::{Camera, Intrinsics, RigidTransform};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Number of whitespace-separated values on a frame line.
pub const COLUMNS: usize = 19;

/// One frame line of a camera file.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraRow {
    /// Timestamp in microseconds; frames are named after it.
    pub timestamp: u64,
    /// Normalised intrinsics `[fx, fy, cx, cy]` (fx, cx by width; fy, cy by height).
    pub intrinsics: [f64; 4],
    /// The two distortion terms (zero in RealEstate10K).
    pub distortion: [f64; 2],
    /// World-to-camera pose.
    pub cam_from_world: RigidTransform,
}

impl CameraRow {
    /// The camera of this row for an image of `width × height` pixels.
    pub fn camera(&self, width: u32, height: u32) -> mhi_geom::Result<Camera> {
        let [fx, fy, cx, cy] = self.intrinsics;
        let k = Intrinsics::from_normalized(fx, fy, cx, cy, width, height)?;
        Camera::new(k, self.cam_from_world, width, height)
    }
}

/// A parsed camera file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraFile {
    /// The source URL on the first line.
    pub url: String,
    /// Frame lines, in strictly increasing timestamp order.
    pub rows: Vec<CameraRow>,
    /// Set when some rotation was orthonormal only to more than
    /// [`mhi_geom::ROTATION_TOLERANCE`] (but within [`mhi_geom::FILE_ROTATION_TOLERANCE`]) and
    /// was re-orthonormalised: the warning to show, with the worst error and its line.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation_warning: Option<String>,
}

/// The largest camera file read (1 GiB, about five million rows): a RealEstate10K file holds
/// hundreds. A FIFO or a device is refused before reading, so nothing is read forever.
pub const MAX_CAMERA_FILE_BYTES: u64 = 1 << 30;

impl CameraFile {
    /// Read and parse a camera file from disk.
    pub fn read(path: &Path) -> Result<Self> {
        crate::check_regular_file(path, "camera file", MAX_CAMERA_FILE_BYTES)?;
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        Self::parse_bytes(&bytes, path)
    }

    /// Parse raw bytes; `path` is only used in error messages.
    pub fn parse_bytes(bytes: &[u8], path: &Path) -> Result<Self> {
        let text = std::str::from_utf8(bytes).map_err(|e| {
            // Report the line of the first invalid byte.
            let line = 1 + bytes[..e.valid_up_to()]
                .iter()
                .filter(|b| **b == b'\n')
                .count();
            fault(path, line, format!("not valid UTF-8 text ({e})"))
        })?;
        Self::parse(text, path)
    }

    /// Parse the text of a camera file; `path` is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let mut lines = text.lines().enumerate();
        let url = loop {
            match lines.next() {
                None => return Err(fault(path, 0, "empty camera file (no URL line, no frames)")),
                Some((_, l)) if l.trim().is_empty() => continue,
                Some((i, l)) => {
                    let l = l.trim();
                    if l.split_whitespace().count() == COLUMNS
                        && l.split_whitespace().all(|t| t.parse::<f64>().is_ok())
                    {
                        return Err(fault(
                            path,
                            i + 1,
                            "the first line must be the video URL, found a frame line",
                        ));
                    }
                    break l.to_owned();
                }
            }
        };
        let mut rows: Vec<CameraRow> = Vec::new();
        let mut worst_rotation = (0.0_f64, 0_usize);
        for (i, line) in lines {
            let n = i + 1;
            if line.trim().is_empty() {
                continue;
            }
            let (row, error) = parse_row(line, path, n)?;
            if error > worst_rotation.0 {
                worst_rotation = (error, n);
            }
            if let Some(prev) = rows.last()
                && row.timestamp <= prev.timestamp
            {
                return Err(fault(
                    path,
                    n,
                    format!(
                        "timestamps must increase strictly: {} follows {}",
                        row.timestamp, prev.timestamp
                    ),
                ));
            }
            rows.push(row);
        }
        if rows.is_empty() {
            return Err(fault(path, 0, "no frame lines after the URL line"));
        }
        let rotation_warning = (worst_rotation.0 > mhi_geom::ROTATION_TOLERANCE).then(|| {
            format!(
                "{}: rotations are orthonormal only to {:.1e} (worst on line {}; files with nine decimals reach 1e-8): accepted up to {:.0e} and re-orthonormalised",
                path.display(),
                worst_rotation.0,
                worst_rotation.1,
                mhi_geom::FILE_ROTATION_TOLERANCE
            )
        });
        Ok(Self {
            url,
            rows,
            rotation_warning,
        })
    }

    /// The file's text, in the same format (nine decimals), so that parsing it gives the rows back
    /// to within 5e-10.
    pub fn to_text(&self) -> String {
        let mut s = String::with_capacity(64 + self.rows.len() * 200);
        s.push_str(&self.url);
        s.push('\n');
        for r in &self.rows {
            let _ = write!(s, "{}", r.timestamp);
            for v in r
                .intrinsics
                .iter()
                .chain(&r.distortion)
                .chain(&r.cam_from_world.to_row_major_3x4())
            {
                let _ = write!(s, " {v:.9}");
            }
            s.push('\n');
        }
        s
    }

    /// Write the file atomically (a temporary file renamed into place).
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::write_atomic(path, self.to_text().as_bytes())
    }
}

fn fault(path: &Path, line: usize, msg: impl Into<String>) -> Error {
    Error::CameraFile {
        path: PathBuf::from(path),
        line,
        fault: msg.into(),
    }
}

/// Normalised focal lengths outside this range are refused: a field of view wider than 170° or
/// narrower than 1.1° is a unit or column mix-up, not a camera.
pub const FOCAL_RANGE: std::ops::RangeInclusive<f64> = 0.02..=50.0;
/// Normalised principal points outside this range (half an image beyond either border) are
/// refused.
pub const PRINCIPAL_POINT_RANGE: std::ops::RangeInclusive<f64> = -0.5..=1.5;
/// Camera positions farther than this from the world origin are refused (RealEstate10K scenes
/// span a few units; 1e6 leaves room for any scale a capture uses while catching overflow).
pub const MAX_TRANSLATION: f64 = 1e6;

/// A number as a person reads it: plain when moderate, in exponent form when huge or tiny.
fn num(x: f64) -> String {
    if x != 0.0 && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Reject cameras that parse but cannot be right, with the column and the reason.
fn check_plausible(v: &[f64; COLUMNS - 1], path: &Path, n: usize) -> Result<()> {
    for (k, name) in [(0, "fx"), (1, "fy")] {
        if !FOCAL_RANGE.contains(&v[k]) {
            return Err(fault(
                path,
                n,
                format!(
                    "column {}: normalised focal length {name} = {} is outside [{}, {}] (a field of view between 1.1° and 170°); intrinsics are divided by the image width (fx, cx) and height (fy, cy)",
                    k + 2,
                    num(v[k]),
                    FOCAL_RANGE.start(),
                    FOCAL_RANGE.end()
                ),
            ));
        }
    }
    for (k, name) in [(2, "cx"), (3, "cy")] {
        if !PRINCIPAL_POINT_RANGE.contains(&v[k]) {
            return Err(fault(
                path,
                n,
                format!(
                    "column {}: normalised principal point {name} = {} lies more than half an image outside the image (expected within [{}, {}], 0.5 is the centre)",
                    k + 2,
                    num(v[k]),
                    PRINCIPAL_POINT_RANGE.start(),
                    PRINCIPAL_POINT_RANGE.end()
                ),
            ));
        }
    }
    for (k, name) in [(4, "k1"), (5, "k2")] {
        if v[k] != 0.0 {
            return Err(fault(
                path,
                n,
                format!(
                    "column {}: distortion {name} = {} is not zero; this project models undistorted pinhole cameras only (RealEstate10K's are), so undistort the frames first",
                    k + 2,
                    num(v[k])
                ),
            ));
        }
    }
    for (k, name) in [(9, "t1"), (13, "t2"), (17, "t3")] {
        if v[k].abs() > MAX_TRANSLATION {
            return Err(fault(
                path,
                n,
                format!(
                    "column {}: translation {name} = {:e} is implausibly large (more than {:e} from the origin)",
                    k + 2,
                    v[k],
                    MAX_TRANSLATION
                ),
            ));
        }
    }
    Ok(())
}

fn parse_row(line: &str, path: &Path, n: usize) -> Result<(CameraRow, f64)> {
    let tokens: Vec<&str> = line.split_whitespace().collect();
    if tokens.len() != COLUMNS {
        return Err(fault(
            path,
            n,
            format!(
                "expected {COLUMNS} values (timestamp fx fy cx cy k1 k2 and a 3×4 pose), found {}",
                tokens.len()
            ),
        ));
    }
    let timestamp: u64 = tokens[0].parse().map_err(|_| {
        fault(
            path,
            n,
            format!(
                "column 1: timestamp {:?} is not a non-negative integer",
                tokens[0]
            ),
        )
    })?;
    let mut v = [0.0_f64; COLUMNS - 1];
    for (k, t) in tokens[1..].iter().enumerate() {
        let x: f64 = t
            .parse()
            .map_err(|_| fault(path, n, format!("column {}: {t:?} is not a number", k + 2)))?;
        if !x.is_finite() {
            return Err(fault(
                path,
                n,
                format!("column {}: {t:?} is not finite", k + 2),
            ));
        }
        v[k] = x;
    }
    let intrinsics = [v[0], v[1], v[2], v[3]];
    if intrinsics[0] <= 0.0 || intrinsics[1] <= 0.0 {
        return Err(fault(
            path,
            n,
            format!(
                "focal lengths must be positive, found fx = {}, fy = {}",
                v[0], v[1]
            ),
        ));
    }
    check_plausible(&v, path, n)?;
    let mut pose = [0.0; 12];
    pose.copy_from_slice(&v[6..18]);
    let rotation = glam::DMat3::from_cols(
        glam::DVec3::new(pose[0], pose[4], pose[8]),
        glam::DVec3::new(pose[1], pose[5], pose[9]),
        glam::DVec3::new(pose[2], pose[6], pose[10]),
    );
    let rotation_error = mhi_geom::rotation_error(&rotation);
    let cam_from_world = RigidTransform::with_tolerance(
        rotation,
        glam::DVec3::new(pose[3], pose[7], pose[11]),
        mhi_geom::FILE_ROTATION_TOLERANCE,
    )
    .map_err(|e| fault(path, n, format!("invalid world-to-camera pose: {e}")))?;
    Ok((
        CameraRow {
            timestamp,
            intrinsics,
            distortion: [v[4], v[5]],
            cam_from_world,
        },
        rotation_error,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const SAMPLE: &str = include_str!("../tests/fixtures/0bf152ef84195293.txt");

    fn p() -> &'static Path {
        Path::new("seq.txt")
    }

    #[test]
    fn genuine_file_parses() {
        let f = CameraFile::parse(SAMPLE, Path::new("0bf152ef84195293.txt")).unwrap();
        assert!(f.url.starts_with("https://"));
        assert_eq!(f.rows.len(), 16);
        assert_eq!(f.rows[0].timestamp, 158692025);
        assert!((f.rows[0].intrinsics[0] - 0.474812461).abs() < 1e-15);
        let cam = f.rows[0].camera(640, 360).unwrap();
        assert!((cam.intrinsics.cx - 320.0).abs() < 1e-12);
        // Round trip through the writer.
        let g = CameraFile::parse(&f.to_text(), p()).unwrap();
        for (a, b) in f.rows.iter().zip(&g.rows) {
            assert_eq!(a.timestamp, b.timestamp);
            let (ma, mb) = (
                a.cam_from_world.to_row_major_3x4(),
                b.cam_from_world.to_row_major_3x4(),
            );
            for (x, y) in ma.iter().zip(&mb) {
                assert!((x - y).abs() < 1e-9);
            }
        }
    }

    fn expect_fault(text: &str, line: usize, needle: &str) {
        match CameraFile::parse(text, p()) {
            Err(Error::CameraFile {
                path,
                line: l,
                fault,
            }) => {
                assert_eq!(path, p());
                assert_eq!(l, line, "{fault}");
                assert!(fault.contains(needle), "{fault:?} lacks {needle:?}");
                let msg = Error::CameraFile {
                    path,
                    line: l,
                    fault,
                }
                .to_string();
                assert!(msg.starts_with(&format!("seq.txt:{line}:")), "{msg}");
            }
            other => panic!("expected a camera-file error, got {other:?}"),
        }
    }

    const ROW: &str = "1000 0.5 0.8 0.5 0.5 0 0 1 0 0 0.1 0 1 0 0.2 0 0 1 0.3";

    #[test]
    fn implausible_cameras_are_refused_naming_the_column() {
        let row = |fx: &str, cx: &str, k1: &str, t1: &str| {
            format!("url\n1000 {fx} 0.8 {cx} 0.5 {k1} 0 1 0 0 {t1} 0 1 0 0 0 0 1 0\n")
        };
        expect_fault(
            &row("1e30", "0.5", "0", "0"),
            2,
            "column 2: normalised focal length fx",
        );
        expect_fault(&row("0.001", "0.5", "0", "0"), 2, "170°");
        expect_fault(
            &row("0.6", "50", "0", "0"),
            2,
            "column 4: normalised principal point cx",
        );
        expect_fault(&row("0.6", "0.5", "0.1", "0"), 2, "column 6: distortion k1");
        expect_fault(
            &row("0.6", "0.5", "0", "1e30"),
            2,
            "column 11: translation t1",
        );
        CameraFile::parse(&row("0.6", "0.5", "0", "3"), p()).unwrap();
    }

    #[test]
    fn malformed_files_name_the_line_and_the_fault() {
        expect_fault("", 0, "empty");
        expect_fault("url\n", 0, "no frame lines");
        expect_fault(&format!("{ROW}\n"), 1, "URL");
        expect_fault(
            &format!("url\n{ROW}\n1001 0.5 0.8\n"),
            3,
            "expected 19 values",
        );
        expect_fault(
            &format!("url\n{}\n", ROW.replace("0.8", "abc")),
            2,
            "column 3: \"abc\" is not a number",
        );
        expect_fault(
            &format!("url\n{}\n", ROW.replace("0.8", "NaN")),
            2,
            "not finite",
        );
        expect_fault(
            &format!("url\n{}\n", ROW.replace("0.8", "inf")),
            2,
            "not finite",
        );
        expect_fault(
            &format!("url\n{}\n", ROW.replace("1000", "-5")),
            2,
            "timestamp",
        );
        expect_fault(
            &format!("url\n{}\n", ROW.replace(" 1 0 0 0.1", " 2 0 0 0.1")),
            2,
            "not a rotation",
        );
        expect_fault(&format!("url\n{ROW}\n{ROW}\n"), 3, "increase strictly");
        expect_fault(
            &format!("url\n{}\n", ROW.replace("0.5 0.8", "-0.5 0.8")),
            2,
            "focal",
        );
        match CameraFile::parse_bytes(b"url\n\xff\xfe", p()) {
            Err(Error::CameraFile { line: 2, fault, .. }) => assert!(fault.contains("UTF-8")),
            other => panic!("{other:?}"),
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 100_000, failure_persistence: None, ..ProptestConfig::default() })]

        /// Arbitrary bytes never panic the parser, and every error names the file.
        #[test]
        fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
            if let Err(e) = CameraFile::parse_bytes(&bytes, p()) {
                prop_assert!(e.to_string().starts_with("seq.txt:"));
            }
        }

        /// Mutations of a valid file (tokens replaced by arbitrary strings) never panic.
        #[test]
        fn mutated_rows_never_panic(idx in 0usize..19, token in "\\PC{0,12}", extra in prop::option::of("[0-9eE.+-]{1,8}")) {
            let mut toks: Vec<String> = ROW.split(' ').map(str::to_owned).collect();
            toks[idx] = token;
            if let Some(x) = extra { toks.push(x); }
            let text = format!("url\n{}\n", toks.join(" "));
            let _ = CameraFile::parse(&text, p());
        }
    }
}
