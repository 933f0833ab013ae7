//! Image-quality metrics of view synthesis (PSNR and SSIM on plain `image` types; LPIPS lives
//! with the pretrained backbones in `mhi-net`), the aggregation of per-view scores into report
//! rows and tables ([`report`]), the report's figures ([`plot`]), the evaluation protocol that
//! ties them together, with methods plugged in through a trait ([`protocol`]), and the
//! project's whole evaluation with its own methods ([`run`]; `cargo xtask eval` parses its
//! options and calls it).
//!
//! # Example: two methods on a dataset
//!
//! Triplets of a (here synthetic) dataset, two methods, every view scored on its covered
//! region, rows with bootstrap intervals, a paired comparison, the tables and the error-against-
//! time figure:
//!
//! ```
//! use mhi_data::{Dataset, SynthConfig, TripletIndex, generate};
//! use mhi_eval::methods::{Nearest, Sweep};
//! use mhi_eval::protocol::{Method, evaluate};
//! use mhi_eval::{Bootstrap, plot, report};
//!
//! let dir = tempfile::tempdir()?;
//! let synth = SynthConfig { scenes: 2, frames: 5, width: 64, height: 48, test_fraction: 1.0,
//!                           val_fraction: 0.0, ..SynthConfig::default() };
//! generate(&synth, dir.path(), &|| {})?;
//! let data = Dataset::open(dir.path(), "test", 3)?;
//! let triplets = TripletIndex::sample(&data, 2, 0);
//! let (mut sweep, mut nearest) = (Sweep::new(5, 8, 1.0, 100.0)?, Nearest);
//! let views = evaluate(&data, &triplets, None, 100.0, &mut [&mut sweep, &mut nearest], None)?;
//! let boot = Bootstrap::default();
//! let rows = report::aggregate(&views, &boot);
//! let diff = report::compare(&views, &sweep.config(), &nearest.config(), &boot);
//! println!("{}", report::markdown_tables(&rows, &diff));
//! plot::error_vs_time(&dir.path().join("error_vs_time"), &plot::time_points(&rows), "PSNR")?;
//! assert!(dir.path().join("error_vs_time.svg").is_file() && !diff.is_empty());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! PSNR and SSIM alone:
//!
//! ```
//! use image::Rgb32FImage;
//! let a = Rgb32FImage::from_fn(16, 16, |x, y| image::Rgb([x as f32 / 16.0, y as f32 / 16.0, 0.5]));
//! let mut b = a.clone();
//! b.get_pixel_mut(3, 4).0[0] += 0.1;
//! let psnr = mhi_eval::psnr(&a, &b).unwrap();
//! assert!((psnr - 10.0 * (1.0_f64 / (0.01 / (16.0 * 16.0 * 3.0))).log10()).abs() < 1e-3);
//! assert!(mhi_eval::ssim(&a, &a).unwrap() > 0.999_999);
//! ```

pub use mhi_render::coverage;
pub mod images;
pub mod methods;
mod metrics;
pub mod oracle;
pub mod plot;
pub mod progress;
pub mod protocol;
pub mod report;
pub mod run;
pub mod speed;
pub mod stats;
pub mod support;

pub use coverage::covered_mask;
pub use metrics::{MAX_PSNR, MIN_SSIM_SIDE, psnr, psnr_masked, ssim, ssim_masked};
pub use stats::Bootstrap;

/// Why a metric could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The two images differ in size.
    #[error("images differ in size: {a:?} vs {b:?}")]
    SizeMismatch {
        /// Size of the first image.
        a: (u32, u32),
        /// Size of the second image.
        b: (u32, u32),
    },
    /// An image too small or holding NaN.
    #[error("invalid image: {0}")]
    InvalidImage(String),
}

/// Result of a metric.
pub type Result<T> = std::result::Result<T, Error>;
