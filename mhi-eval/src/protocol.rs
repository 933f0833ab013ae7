//! The evaluation protocol as a library: triplets of a dataset, methods that render the target
//! view from the two inputs, each view scored (PSNR, SSIM and, given a scorer, LPIPS, over the
//! whole image and over the covered pixels), then [`crate::report`] for rows with bootstrap
//! intervals, paired comparisons and tables. `cargo xtask eval` is this loop with the project's
//! methods (the learned ones live in `mhi-net`, above this crate) plugged in through [`Method`].
//!
//! ```
//! use image::Rgb32FImage;
//! use mhi_data::{Dataset, LoadedFrame, SynthConfig, TripletIndex, generate};
//! use mhi_eval::protocol::{Method, Output, evaluate};
//! use mhi_eval::{Bootstrap, report};
//!
//! /// The simplest method: the reference photo as the target view.
//! struct Nearest;
//! impl Method for Nearest {
//!     fn config(&self) -> (String, usize, usize) { ("nearest".into(), 0, 0) }
//!     fn render(&mut self, reference: &LoadedFrame, _: &LoadedFrame, _: &mhi_geom::Camera)
//!         -> Result<Output, mhi_eval::protocol::MethodError> {
//!         Ok(Output { image: reference.image.clone(), times: Default::default() })
//!     }
//! }
//!
//! let dir = tempfile::tempdir().unwrap();
//! let synth = SynthConfig {
//!     scenes: 2, frames: 5, width: 48, height: 32, test_fraction: 1.0, val_fraction: 0.0,
//!     ..SynthConfig::default()
//! };
//! generate(&synth, dir.path(), &|| {}).unwrap();
//! let data = Dataset::open(dir.path(), "test", 3).unwrap();
//! let index = TripletIndex::sample(&data, 2, 7);
//! let views = evaluate(&data, &index, Some((48, 32)), 100.0, &mut [&mut Nearest], None).unwrap();
//! let rows = report::aggregate(&views, &Bootstrap::default());
//! assert_eq!(views.len(), index.triplets.len());
//! println!("{}", report::markdown_tables(&rows, &[]));
//! ```

use image::Rgb32FImage;
use mhi_data::{Dataset, Fit, LoadedFrame, Triplet, TripletIndex, TripletKind, load_frame};
use mhi_geom::Camera;

use crate::report::{Measurement, Times};

/// A method's error, whatever its type.
pub type MethodError = Box<dyn std::error::Error + Send + Sync>;

/// A scorer of two images of one size (LPIPS, say): lower is closer.
pub type Scorer<'a> = &'a dyn Fn(&Rgb32FImage, &Rgb32FImage) -> Result<f64, MethodError>;

/// A rendered view and what it took.
#[derive(Debug, Clone)]
pub struct Output {
    /// The view (values outside [0, 1] are clipped before scoring).
    pub image: Rgb32FImage,
    /// Time per stage.
    pub times: Times,
}

/// A view-synthesis method under evaluation.
pub trait Method {
    /// Its name and grid: normals N and planes D (0 and 0 for a method without planes).
    fn config(&self) -> (String, usize, usize);
    /// The target camera's view from the reference and source frames (images and cameras).
    ///
    /// # Errors
    /// Whatever keeps the method from rendering this view.
    fn render(
        &mut self,
        reference: &LoadedFrame,
        source: &LoadedFrame,
        target: &Camera,
    ) -> Result<Output, MethodError>;
}

/// Why an evaluation stopped.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A frame could not be loaded, or the index does not fit the dataset.
    #[error(transparent)]
    Data(#[from] mhi_data::Error),
    /// A metric refused its images.
    #[error(transparent)]
    Metric(#[from] crate::Error),
    /// A method failed on a view.
    #[error("{method} on triplet {triplet}: {source}")]
    Method {
        /// The method.
        method: String,
        /// The triplet's index.
        triplet: usize,
        /// What failed.
        source: MethodError,
    },
}

/// Clamp every channel to [0, 1], NaN to 0 (what is shown and scored).
pub fn clipped(img: &Rgb32FImage) -> Rgb32FImage {
    let mut o = img.clone();
    for c in o.iter_mut() {
        *c = if c.is_finite() {
            c.clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    o
}

/// `img` with its uncovered pixels replaced by `truth`'s (they then score no difference).
pub fn with_uncovered_from(
    img: &Rgb32FImage,
    truth: &Rgb32FImage,
    covered: &[bool],
) -> Rgb32FImage {
    let mut o = img.clone();
    for ((p, t), &c) in o.pixels_mut().zip(truth.pixels()).zip(covered) {
        if !c {
            *p = *t;
        }
    }
    o
}

/// What one view of triplet `index` (`t`) scored: `image` (clipped here) against `truth` over
/// the whole image and over `covered` (see [`crate::covered_mask`]); `lpips` also scores the
/// render with its uncovered pixels taken from the truth.
///
/// # Errors
/// When the images differ in size or a scorer fails.
#[allow(clippy::too_many_arguments)]
pub fn score(
    index: usize,
    t: &Triplet,
    (method, normals, planes): (String, usize, usize),
    image: &Rgb32FImage,
    truth: &Rgb32FImage,
    covered: &[bool],
    (times, timed): (Times, bool),
    lpips: Option<Scorer<'_>>,
) -> Result<Measurement, EvalError> {
    let img = clipped(image);
    let covered_fraction = crate::coverage::fraction(covered);
    let scorer = |e: MethodError| EvalError::Method {
        method: format!("LPIPS of {method}"),
        triplet: index,
        source: e,
    };
    let (lpips, lpips_covered) = match lpips {
        Some(f) => (
            Some(f(&img, truth).map_err(scorer)?),
            (covered_fraction > 0.0)
                .then(|| f(&with_uncovered_from(&img, truth, covered), truth))
                .transpose()
                .map_err(scorer)?,
        ),
        None => (None, None),
    };
    Ok(Measurement {
        triplet: index,
        normals,
        planes,
        sequence: t.sequence.clone(),
        target: t.target,
        bin: t.bin.key().to_string(),
        kind: match t.kind {
            TripletKind::Interpolation => "interpolation",
            TripletKind::Extrapolation => "extrapolation",
        }
        .into(),
        psnr: crate::psnr(&img, truth)?,
        ssim: crate::ssim(&img, truth)?,
        lpips,
        psnr_covered: crate::psnr_masked(&img, truth, covered)?,
        ssim_covered: crate::ssim_masked(&img, truth, covered)?,
        lpips_covered,
        covered_fraction,
        times,
        timed,
        method,
    })
}

/// Every method on every triplet of `index` over `data`, frames loaded at `size` (their own
/// size when `None`), covered pixels those whose ray meets the reference's plane at depth `far`
/// inside its image; `lpips` scores too when given. One measurement per method and triplet, in
/// that order; [`crate::report::aggregate`] makes rows of them.
///
/// # Errors
/// A frame that does not load, a triplet whose sequence is not in `data`, a method that fails.
pub fn evaluate(
    data: &Dataset,
    index: &TripletIndex,
    size: Option<(u32, u32)>,
    far: f64,
    methods: &mut [&mut dyn Method],
    lpips: Option<Scorer<'_>>,
) -> Result<Vec<Measurement>, EvalError> {
    let mut out = Vec::new();
    for (ti, t) in index.triplets.iter().enumerate() {
        let seq = data
            .sequence(&t.sequence)
            .ok_or_else(|| mhi_data::Error::Dataset {
                path: data.dir.clone(),
                fault: format!(
                    "the index names sequence {:?}, which is not here",
                    t.sequence
                ),
            })?;
        let load = |i: usize| load_frame(&seq.frames[i], size, Fit::Stretch);
        let (rf, sf, tf) = (load(t.reference)?, load(t.source)?, load(t.target)?);
        let covered = crate::covered_mask(&rf.camera, &tf.camera, far);
        for m in methods.iter_mut() {
            let config = m.config();
            let o = m
                .render(&rf, &sf, &tf.camera)
                .map_err(|source| EvalError::Method {
                    method: config.0.clone(),
                    triplet: ti,
                    source,
                })?;
            out.push(score(
                ti,
                t,
                config,
                &o.image,
                &tf.image,
                &covered,
                (o.times, true),
                lpips,
            )?);
        }
    }
    Ok(out)
}
