//! Camera poses from two plain photos: everything an MHI needs that a camera file would give.
//!
//! 1. **Intrinsics**: given, or from EXIF (the 35 mm-equivalent focal length, else the focal
//!    length with the focal-plane resolution), else a stated default field of view.
//! 2. **Features and matches**: SIFT (kornia-rs's, bit-exact against OpenCV's) on the photos
//!    brought to a working long side, Lowe's ratio test at 0.8.
//! 3. **Relative pose**: a 5-point essential matrix in RANSAC, raced against a homography (a
//!    scene that one plane explains is refused), a cheirality vote over the four
//!    decompositions, Levenberg–Marquardt refinement, triangulated inliers (kornia-3d).
//! 4. **Scale**: two views fix the translation's direction only. The reconstruction is scaled
//!    so that the 5th-percentile depth of the triangulated points is [`NEAR_DEPTH`], just
//!    beyond an MHI's default near plane (depth 1), so its planes cover the scene.
//!
//! Frames follow the project's conventions (`docs/METHOD.md`): OpenCV axes, pixel centres at
//! `i + 0.5`, the reference camera at the world origin, `src_from_ref` mapping reference-frame
//! points into the source camera.
//!
//! ```no_run
//! let a = mhi_pose::Photo::open("A.jpg".as_ref())?;
//! let b = mhi_pose::Photo::open("B.jpg".as_ref())?;
//! let pair = mhi_pose::estimate(&a, &b, &mhi_pose::Options::default())?;
//! println!("{}", pair.summary());
//! # Ok::<(), mhi_pose::Error>(())
//! ```

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};
use image::RgbImage;
use serde::{Deserialize, Serialize};

pub mod accuracy;
mod exif_focal;

pub use exif_focal::{ExifFocal, exif_focal};

/// The 5th-percentile depth the reconstruction is scaled to (an MHI's near plane is at 1).
pub const NEAR_DEPTH: f64 = 1.25;
/// The focal length assumed without EXIF or given intrinsics: 1.2 × the longer side in pixels
/// (a horizontal field of view of 45° on a landscape photo, COLMAP's default).
pub const DEFAULT_FOCAL_FACTOR: f64 = 1.2;
/// Below this many matches at the working resolution, SIFT runs again from twice it.
pub const ENOUGH_MATCHES: usize = 200;
/// The fewest matches a pose is estimated from.
pub const MIN_MATCHES: usize = 30;
/// The least median parallax (rotation removed) that counts as two viewpoints, in degrees.
pub const MIN_PARALLAX_DEG: f64 = 0.25;
/// Fields of view outside this range (degrees, across the longer side) are not a camera.
pub const FOV_RANGE_DEG: std::ops::RangeInclusive<f64> = 3.0..=150.0;

/// What went wrong, in terms a photographer can act on.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A photo that could not be read.
    #[error("{path}: {fault}", path = path.display())]
    Photo {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        fault: String,
    },
    /// Intrinsics that cannot be a camera's.
    #[error("{0}")]
    Intrinsics(String),
    /// The two photos are one photo.
    #[error(
        "the two photos are the same image: the scene needs two photos taken from different places"
    )]
    SamePhoto,
    /// Too few matches between the photos.
    #[error(
        "only {matches} matches between the photos (at least {MIN_MATCHES} are needed): do they show the same scene, with enough overlap and texture?"
    )]
    TooFewMatches {
        /// Matches that passed the ratio test.
        matches: usize,
    },
    /// Both photos taken from one spot (or a rotation only).
    #[error(
        "no parallax: the median parallax is {median_deg:.2}° once the rotation is removed (at least {MIN_PARALLAX_DEG}° is needed); the photos were taken from one spot — move sideways between the photos"
    )]
    NoParallax {
        /// The median parallax in degrees.
        median_deg: f64,
    },
    /// One plane explains the matches: the pose is ambiguous (`epipolar` is 0 when the
    /// homography was found before any essential matrix).
    #[error(
        "a single plane explains the matches ({homography} of them fit one homography): a flat wall or a photo of a photo gives no reliable pose; photograph a scene with depth"
    )]
    Planar {
        /// Homography inliers.
        homography: usize,
        /// Essential-matrix inliers.
        epipolar: usize,
    },
    /// No consistent pose.
    #[error("no consistent relative pose among {matches} matches ({why})")]
    NoPose {
        /// The matches tried.
        matches: usize,
        /// The estimator's reason.
        why: String,
    },
}

/// Result of pose estimation.
pub type Result<T> = std::result::Result<T, Error>;

/// Intrinsics normalised as in a RealEstate10K camera file (fx, cx by the width; fy, cy by the
/// height), with where they came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// `[fx, fy, cx, cy]`, normalised.
    pub normalised: [f64; 4],
    /// Where they came from (`"given"`, `"EXIF 35 mm-equivalent 26 mm"`, `"assumed …"`).
    pub source: String,
}

impl Intrinsics {
    /// `K` in pixels for an image of `width × height`.
    pub fn k(&self, width: u32, height: u32) -> DMat3 {
        let [fx, fy, cx, cy] = self.normalised;
        let (w, h) = (f64::from(width), f64::from(height));
        DMat3::from_cols(
            DVec3::new(fx * w, 0.0, 0.0),
            DVec3::new(0.0, fy * h, 0.0),
            DVec3::new(cx * w, cy * h, 1.0),
        )
    }

    /// The horizontal field of view in degrees for an image of `width` pixels.
    pub fn hfov_deg(&self) -> f64 {
        2.0 * (0.5 / self.normalised[0]).atan().to_degrees()
    }
}

/// A photo, upright (EXIF orientation applied), with its EXIF focal length if it has one.
#[derive(Debug, Clone)]
pub struct Photo {
    /// The file it came from.
    pub path: PathBuf,
    /// Its pixels.
    pub image: RgbImage,
    /// The EXIF focal length, if the file records one.
    pub exif: Option<ExifFocal>,
}

impl Photo {
    /// Read a photo: its pixels turned upright and its EXIF focal length.
    ///
    /// # Errors
    /// A file that is not a readable image.
    pub fn open(path: &Path) -> Result<Self> {
        let image = mhi_data::read_rgb(path).map_err(|e| Error::Photo {
            path: path.to_path_buf(),
            fault: format!("{e}"),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            exif: exif_focal(path),
            image,
        })
    }

    /// Intrinsics: `given` if some, else from EXIF, else the stated default.
    ///
    /// # Errors
    /// Given or EXIF intrinsics whose field of view is outside [`FOV_RANGE_DEG`].
    pub fn intrinsics(&self, given: Option<[f64; 4]>) -> Result<Intrinsics> {
        let (w, h) = self.image.dimensions();
        let long = f64::from(w.max(h));
        let i = match (given, &self.exif) {
            (Some(n), _) => Intrinsics {
                normalised: n,
                source: "given".into(),
            },
            (None, Some(e)) => {
                let f = e.focal_px(w, h);
                Intrinsics {
                    normalised: [f / f64::from(w), f / f64::from(h), 0.5, 0.5],
                    source: format!("EXIF: {}", e.describe()),
                }
            }
            (None, None) => {
                let f = DEFAULT_FOCAL_FACTOR * long;
                let fov = 2.0 * (0.5 * long / f).atan().to_degrees();
                Intrinsics {
                    normalised: [f / f64::from(w), f / f64::from(h), 0.5, 0.5],
                    source: format!(
                        "assumed: no EXIF focal length, a {fov:.0}° field of view across the longer side (focal {DEFAULT_FOCAL_FACTOR} × {long:.0} px); pass the intrinsics if you know them"
                    ),
                }
            }
        };
        let [fx, fy, cx, cy] = i.normalised;
        let fov = |f: f64, side: f64| 2.0 * (0.5 * side / f).atan().to_degrees();
        let fov_long = if w >= h {
            fov(fx * f64::from(w), f64::from(w))
        } else {
            fov(fy * f64::from(h), f64::from(h))
        };
        let finite = [fx, fy, cx, cy].iter().all(|v| v.is_finite());
        if !finite || fx <= 0.0 || fy <= 0.0 || !FOV_RANGE_DEG.contains(&fov_long) {
            return Err(Error::Intrinsics(format!(
                "{}: intrinsics {} give a field of view of {fov_long:.1}° across the longer side, outside [{}, {}]°: not a camera's (a unit mix-up?)",
                self.path.display(),
                i.source,
                FOV_RANGE_DEG.start(),
                FOV_RANGE_DEG.end()
            )));
        }
        Ok(i)
    }
}

/// Options of [`estimate`].
#[derive(Debug, Clone)]
pub struct Options {
    /// Intrinsics of the reference photo (normalised); `None`: EXIF or the default.
    pub ref_intrinsics: Option<[f64; 4]>,
    /// Intrinsics of the source photo; `None`: the reference's given ones, else its own EXIF.
    pub src_intrinsics: Option<[f64; 4]>,
    /// The photos' longer side while features are found (matches are mapped back).
    pub working_side: u32,
    /// Lowe's ratio.
    pub ratio: f32,
    /// SIFT's first octave at twice the resolution (OpenCV's default: about twice the
    /// keypoints for 3.6 times the time); `false` starts at the working resolution and doubles
    /// only when that gives fewer than [`ENOUGH_MATCHES`] matches.
    pub double_first_octave: bool,
    /// RANSAC's inlier threshold, in working-size pixels.
    pub threshold_px: f64,
    /// RANSAC's seed.
    pub seed: u64,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            ref_intrinsics: None,
            src_intrinsics: None,
            working_side: 1024,
            ratio: 0.8,
            double_first_octave: false,
            threshold_px: 1.0,
            seed: 0,
        }
    }
}

/// Two photos' cameras and what was found on the way.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PosedPair {
    /// The reference photo's intrinsics.
    pub ref_intrinsics: Intrinsics,
    /// The source photo's intrinsics.
    pub src_intrinsics: Intrinsics,
    /// The reference photo's size in pixels.
    pub ref_size: (u32, u32),
    /// The source photo's size in pixels.
    pub src_size: (u32, u32),
    /// `src_from_ref`'s rotation (row-major 3 × 3).
    pub rotation: [f64; 9],
    /// `src_from_ref`'s translation, scaled.
    pub translation: [f64; 3],
    /// The scale applied to the unit translation (5th-percentile depth = [`NEAR_DEPTH`]).
    pub scale: f64,
    /// Features found in each photo.
    pub features: (usize, usize),
    /// Matches that passed the ratio test.
    pub matches: usize,
    /// Matches consistent with the pose.
    pub inliers: usize,
    /// Median parallax of the inliers, rotation removed, in degrees.
    pub median_parallax_deg: f64,
    /// The relative rotation's angle, in degrees.
    pub rotation_deg: f64,
    /// The direction from the reference camera to the source camera, in the reference frame.
    pub baseline_direction: [f64; 3],
    /// 5th and 95th percentile depths of the triangulated points, scaled.
    pub depth_range: (f64, f64),
    /// Triangulated points in the reference frame, scaled.
    pub points: Vec<[f64; 3]>,
}

impl PosedPair {
    /// `src_from_ref` rotation.
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_cols_array(&self.rotation).transpose()
    }

    /// `src_from_ref` translation.
    pub fn translation(&self) -> DVec3 {
        DVec3::from_array(self.translation)
    }

    /// What was found, for a person: focal lengths and where they came from, the match and
    /// inlier counts, the parallax, the rotation, the baseline direction and the depth range.
    pub fn summary(&self) -> String {
        let d = self.baseline_direction;
        let side = |x: f64, pos: &str, neg: &str| {
            if x >= 0.0 {
                pos.to_string()
            } else {
                neg.to_string()
            }
        };
        format!(
            "reference focal fx = {:.4} (normalised; {:.1}° across the width) from {}\n\
             source focal fx = {:.4} from {}\n\
             features {} / {}, matches {}, inliers {} ({:.0} %)\n\
             median parallax {:.2}°, rotation {:.2}°\n\
             baseline direction ({:+.3}, {:+.3}, {:+.3}) in the reference camera (mostly {})\n\
             depths (5th to 95th percentile) {:.2} to {:.2}, with the near plane at 1 (scale {:.4})",
            self.ref_intrinsics.normalised[0],
            self.ref_intrinsics.hfov_deg(),
            self.ref_intrinsics.source,
            self.src_intrinsics.normalised[0],
            self.src_intrinsics.source,
            self.features.0,
            self.features.1,
            self.matches,
            self.inliers,
            100.0 * self.inliers as f64 / self.matches.max(1) as f64,
            self.median_parallax_deg,
            self.rotation_deg,
            d[0],
            d[1],
            d[2],
            {
                let a = d.map(f64::abs);
                if a[0] >= a[1] && a[0] >= a[2] {
                    side(d[0], "to the right", "to the left")
                } else if a[1] >= a[2] {
                    side(d[1], "down", "up")
                } else {
                    side(d[2], "forward", "backward")
                }
            },
            self.depth_range.0,
            self.depth_range.1,
            self.scale
        )
    }
}

/// SIFT keypoints (pixel centres at `i + 0.5`, in the photo's own pixels) and descriptors.
struct Features {
    points: Vec<[f64; 2]>,
    descriptors: Vec<f32>,
}

fn sift(image: &RgbImage, working_side: u32, double: bool) -> Result<Features> {
    let (w, h) = image.dimensions();
    let s = (f64::from(working_side) / f64::from(w.max(h))).min(1.0);
    let (ww, wh) = (
        ((f64::from(w) * s).round() as u32).max(1),
        ((f64::from(h) * s).round() as u32).max(1),
    );
    let small = if s < 1.0 {
        image::imageops::resize(image, ww, wh, image::imageops::FilterType::Triangle)
    } else {
        image.clone()
    };
    // OpenCV's grey, 0..255, as its SIFT takes it.
    let grey: Vec<f32> = small
        .pixels()
        .map(|p| 0.299 * f32::from(p[0]) + 0.587 * f32::from(p[1]) + 0.114 * f32::from(p[2]))
        .collect();
    use kornia_imgproc::features::{
        FirstOctave, SiftConfig, SiftWorkspace, sift_detect_and_compute,
    };
    let mut ws = SiftWorkspace::new();
    let f = sift_detect_and_compute(
        &mut ws,
        &grey,
        ww as usize,
        wh as usize,
        &SiftConfig::default(),
        if double {
            FirstOctave::Double
        } else {
            FirstOctave::Native
        },
        usize::MAX,
        false,
    )
    .map_err(|e| Error::NoPose {
        matches: 0,
        why: format!("feature detection failed: {e}"),
    })?;
    // Back to the photo's pixels: OpenCV's centre is at the integer, ours at i + 0.5.
    let (sx, sy) = (f64::from(w) / f64::from(ww), f64::from(h) / f64::from(wh));
    let points = f
        .keypoints
        .iter()
        .map(|k| [(f64::from(k.x) + 0.5) * sx, (f64::from(k.y) + 0.5) * sy])
        .collect();
    Ok(Features {
        points,
        descriptors: f.descriptors,
    })
}

/// Lowe's ratio test on SIFT descriptors (rows of 128): each descriptor of `a` with its nearest
/// of `b` when that is nearer than `ratio` times the second nearest. The squared distances
/// come from one matrix product (`|x|² + |y|² − 2 x·y`, faer), which is what makes matching
/// thousands of features against thousands take milliseconds.
pub fn ratio_matches(a: &[f32], b: &[f32], ratio: f32) -> Vec<[u32; 2]> {
    const D: usize = kornia_imgproc::features::DESCR_LEN;
    let (na, nb) = (a.len() / D, b.len() / D);
    if na == 0 || nb < 2 {
        return Vec::new();
    }
    let am = faer::MatRef::from_row_major_slice(&a[..na * D], na, D);
    let bm = faer::MatRef::from_row_major_slice(&b[..nb * D], nb, D);
    let mut dots = faer::Mat::<f32>::zeros(na, nb);
    faer::linalg::matmul::matmul(
        dots.as_mut(),
        faer::Accum::Replace,
        am,
        bm.transpose(),
        1.0,
        faer::Par::rayon(0),
    );
    let norm =
        |m: faer::MatRef<'_, f32>, i: usize| (0..D).map(|k| m[(i, k)] * m[(i, k)]).sum::<f32>();
    let nb2: Vec<f32> = (0..nb).map(|j| norm(bm, j)).collect();
    (0..na)
        .filter_map(|i| {
            let na2 = norm(am, i);
            let (mut best, mut second, mut at) = (f32::INFINITY, f32::INFINITY, 0);
            for (j, n) in nb2.iter().enumerate() {
                let d = (na2 + n - 2.0 * dots[(i, j)]).max(0.0);
                if d < best {
                    (second, best, at) = (best, d, j);
                } else if d < second {
                    second = d;
                }
            }
            (best.sqrt() < ratio * second.sqrt()).then_some([i as u32, at as u32])
        })
        .collect()
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

/// The two photos' relative pose, scaled so that the scene's 5th-percentile depth is
/// [`NEAR_DEPTH`]; `reference` is at the world origin.
///
/// # Errors
/// The same photo twice, too few matches, no parallax, a scene one plane explains, no
/// consistent pose, or intrinsics that are not a camera's — each with what to do about it.
pub fn estimate(reference: &Photo, source: &Photo, options: &Options) -> Result<PosedPair> {
    if reference.image.dimensions() == source.image.dimensions()
        && reference.image.as_raw() == source.image.as_raw()
    {
        return Err(Error::SamePhoto);
    }
    let ref_k = reference.intrinsics(options.ref_intrinsics)?;
    let src_given = options.src_intrinsics.or(options.ref_intrinsics);
    let src_k = source.intrinsics(src_given)?;
    let features = |double| {
        let (fa, fb) = rayon::join(
            || sift(&reference.image, options.working_side, double),
            || sift(&source.image, options.working_side, double),
        );
        let (fa, fb) = (fa?, fb?);
        let pairs = ratio_matches(&fa.descriptors, &fb.descriptors, options.ratio);
        Ok::<_, Error>((fa, fb, pairs))
    };
    // Photos smaller than the working side rarely give matches enough at their own
    // resolution: they start from twice it, as OpenCV does, rather than paying for both.
    let small = reference.image.width().max(reference.image.height()) < options.working_side
        && source.image.width().max(source.image.height()) < options.working_side;
    let (mut fa, mut fb, mut pairs) = features(options.double_first_octave || small)?;
    // Few matches at the working resolution: SIFT again from twice the resolution (OpenCV's
    // default), about twice the keypoints for 3.6 times the time.
    if pairs.len() < ENOUGH_MATCHES && !options.double_first_octave && !small {
        (fa, fb, pairs) = features(true)?;
    }
    let matches = pairs.len();
    if matches < MIN_MATCHES {
        return Err(Error::TooFewMatches { matches });
    }
    let x1: Vec<[f64; 2]> = pairs.iter().map(|m| fa.points[m[0] as usize]).collect();
    let x2: Vec<[f64; 2]> = pairs.iter().map(|m| fb.points[m[1] as usize]).collect();
    let (rw, rh) = reference.image.dimensions();
    let (sw, sh) = source.image.dimensions();
    // Thresholds are in the photos' pixels: the working size's, scaled up.
    let scale_px =
        f64::from(rw.max(rh)) / f64::from(options.working_side).min(f64::from(rw.max(rh)));
    let m = pose_from_matches(
        &x1,
        &x2,
        ref_k.k(rw, rh),
        src_k.k(sw, sh),
        options.threshold_px * scale_px,
        options.seed,
    )?;
    let (r, t) = (m.rotation, m.translation);
    let scale = m.scale;
    let centre = -(r.transpose() * t);
    Ok(PosedPair {
        ref_size: (rw, rh),
        src_size: (sw, sh),
        ref_intrinsics: ref_k,
        src_intrinsics: src_k,
        rotation: r.transpose().to_cols_array(),
        translation: t.to_array(),
        scale,
        features: (fa.points.len(), fb.points.len()),
        matches,
        inliers: m.inliers,
        median_parallax_deg: m.median_parallax_deg,
        rotation_deg: mhi_geom::rotation_angle_deg(&r),
        baseline_direction: centre.normalize().to_array(),
        depth_range: m.depth_range,
        points: m.points,
    })
}

/// The geometric core of [`estimate`], on matched pixel positions (centres at `i + 0.5`).
#[derive(Debug, Clone)]
pub struct MatchPose {
    /// `src_from_ref` rotation.
    pub rotation: DMat3,
    /// `src_from_ref` translation, scaled so that the 5th-percentile depth is [`NEAR_DEPTH`].
    pub translation: DVec3,
    /// The scale applied to the unit translation.
    pub scale: f64,
    /// Matches consistent with the pose.
    pub inliers: usize,
    /// Median parallax of the inliers, rotation removed, in degrees.
    pub median_parallax_deg: f64,
    /// 5th and 95th percentile depths, scaled.
    pub depth_range: (f64, f64),
    /// Triangulated inliers in the reference frame, scaled.
    pub points: Vec<[f64; 3]>,
}

/// Whether a homography explains nearly every match (90 %): either a rotation about the camera
/// centre or a distant scene (the homography is then nearly K₂ R K₁⁻¹, `Ok(true)`; whether the
/// small parallax left suffices is decided later) or one plane seen in perspective
/// ([`Error::Planar`]). `Ok(false)` when no homography explains that many.
fn homography_precheck(
    v1: &[kornia_algebra::Vec2F64],
    v2: &[kornia_algebra::Vec2F64],
    (k1, k2): (DMat3, DMat3),
    ransac: kornia_3d::pose::RansacParams,
    matches: usize,
) -> Result<bool> {
    let Ok(h) = kornia_3d::pose::ransac_homography(
        v1,
        v2,
        &kornia_3d::pose::RansacParams {
            min_inliers: 4,
            ..ransac
        },
    ) else {
        return Ok(false);
    };
    if (h.inlier_count as f64) < 0.9 * matches as f64 {
        return Ok(false);
    }
    let m = k2.inverse() * DMat3::from_cols_array(&h.model.to_cols_array()) * k1;
    let det = m.determinant();
    let mostly_rotation = det.abs() > 1e-12 && {
        let n = m * (1.0 / det.cbrt());
        mhi_geom::rotation_error(&n) < 0.02
    };
    if !mostly_rotation {
        return Err(Error::Planar {
            homography: h.inlier_count,
            epipolar: 0,
        });
    }
    Ok(true)
}

/// The median parallax of the inliers with the rotation removed: the angle between R·ray₁ and
/// ray₂, in degrees (0 without inliers).
fn median_parallax_deg(
    x1: &[[f64; 2]],
    x2: &[[f64; 2]],
    inliers: &[bool],
    r: DMat3,
    (k1, k2): (DMat3, DMat3),
) -> f64 {
    let (k1i, k2i) = (k1.inverse(), k2.inverse());
    let mut parallax: Vec<f64> = (0..inliers.len().min(x1.len()).min(x2.len()))
        .filter(|&i| inliers[i])
        .map(|i| {
            let b1 = (r * (k1i * DVec3::new(x1[i][0], x1[i][1], 1.0))).normalize();
            let b2 = (k2i * DVec3::new(x2[i][0], x2[i][1], 1.0)).normalize();
            b1.dot(b2).clamp(-1.0, 1.0).acos().to_degrees()
        })
        .collect();
    parallax.sort_by(f64::total_cmp);
    if parallax.is_empty() {
        0.0
    } else {
        percentile(&parallax, 0.5)
    }
}

/// The relative pose of two cameras (`k1`, `k2` in pixels) from matched positions `x1[i] ↔
/// x2[i]`: a 5-point essential matrix in RANSAC (inlier threshold `threshold_px`, seeded) raced
/// against a homography, the cheirality vote, LM refinement and triangulation; scaled as in
/// [`estimate`].
///
/// # Errors
/// Too few matches, no parallax, a scene one plane explains, or no consistent pose.
pub fn pose_from_matches(
    x1: &[[f64; 2]],
    x2: &[[f64; 2]],
    k1: DMat3,
    k2: DMat3,
    threshold_px: f64,
    seed: u64,
) -> Result<MatchPose> {
    use kornia_3d::pose::{
        EssentialNister5ptSolver, RansacParams, TriangulationConfig, TwoViewError,
        TwoViewEstimator, TwoViewModel,
    };
    use kornia_algebra::{Mat3F64, Vec2F64};
    let matches = x1.len().min(x2.len());
    if matches < MIN_MATCHES {
        return Err(Error::TooFewMatches { matches });
    }
    let v =
        |x: &[[f64; 2]]| -> Vec<Vec2F64> { x.iter().map(|p| Vec2F64::new(p[0], p[1])).collect() };
    let (v1, v2) = (v(&x1[..matches]), v(&x2[..matches]));
    let to_k = |m: DMat3| Mat3F64::from_cols_array(&m.to_cols_array());
    let ransac = RansacParams {
        threshold: threshold_px,
        random_seed: Some(seed),
        ..RansacParams::default()
    };
    let mostly_rotation = homography_precheck(&v1, &v2, (k1, k2), ransac, matches)?;
    let estimator = TwoViewEstimator::builder()
        .epipolar_solver(EssentialNister5ptSolver { ransac })
        // The homography only competes: kornia gives up on the whole pair when it finds fewer
        // inliers than its minimum, which a scene with depth can do; four always suffice.
        .homography_ransac(RansacParams {
            min_inliers: 4,
            ..ransac
        })
        .triangulation(TriangulationConfig {
            min_parallax_deg: 0.05,
            // Small baselines (video frames a fifth of a second apart) leave the runner-up
            // decomposition close; the parallax check below refuses the truly ambiguous.
            cheirality_ambiguity_max: 0.95,
            ..TriangulationConfig::default()
        })
        .build();
    let result = estimator
        .estimate(&v1, &v2, &to_k(k1), &to_k(k2))
        .map_err(|e| match e {
            TwoViewError::AmbiguousCheirality { .. } => Error::NoParallax { median_deg: 0.0 },
            _ if mostly_rotation => Error::NoParallax { median_deg: 0.0 },
            other => Error::NoPose {
                matches,
                why: other.to_string(),
            },
        })?;
    let inliers = result.inliers.iter().filter(|b| **b).count();
    let r = DMat3::from_cols_array(&result.rotation.to_cols_array());
    let t = DVec3::from_array(result.translation.to_array());
    let median_parallax = median_parallax_deg(x1, x2, &result.inliers, r, (k1, k2));
    if median_parallax < MIN_PARALLAX_DEG {
        return Err(Error::NoParallax {
            median_deg: median_parallax,
        });
    }
    // A homography chosen over the essential matrix is kept only for a scene the pre-check
    // found to be a near-rotation with parallax enough (a distant scene); a plane was refused.
    if matches!(result.model, TwoViewModel::Homography(_)) && !mostly_rotation {
        return Err(Error::Planar {
            homography: inliers,
            epipolar: 0,
        });
    }
    let mut depths: Vec<f64> = result
        .points3d
        .iter()
        .map(|p| p.z)
        .filter(|z| z.is_finite() && *z > 0.0)
        .collect();
    if depths.len() < MIN_MATCHES / 2 {
        return Err(Error::NoPose {
            matches,
            why: format!(
                "only {} points triangulate in front of both cameras",
                depths.len()
            ),
        });
    }
    depths.sort_by(f64::total_cmp);
    let scale = NEAR_DEPTH / percentile(&depths, 0.05);
    Ok(MatchPose {
        rotation: r,
        translation: t * scale,
        scale,
        inliers,
        median_parallax_deg: median_parallax,
        depth_range: (
            percentile(&depths, 0.05) * scale,
            percentile(&depths, 0.95) * scale,
        ),
        points: result
            .points3d
            .iter()
            .map(|p| [p.x * scale, p.y * scale, p.z * scale])
            .collect(),
    })
}
