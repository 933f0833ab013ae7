//! The learned half of MHI view synthesis on burn: the stage-1 3D U-Nets over the oriented cost
//! volume (by default correcting the training-free sweep), the stage-2 blending U-Net, the
//! training loss and the two-phase training loop, and [`ViewSynthesis`]: novel views from a
//! posed pair with a trained model or the sweep.
//!
//! # Example: a novel view from two photos and a camera file
//!
//! ```no_run
//! use burn::tensor::Device;
//! use mhi_data::{CameraFile, Fit, Frame, load_frame};
//! use mhi_net::{BlendChoice, MhiSource, Model, ViewSynthesis};
//! use mhi_render::Prune;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let cams = CameraFile::read("cams.txt".as_ref())?; // rows: reference, source, target
//! let frame = |row: usize, path: &str| Frame { row: cams.rows[row], path: path.into() };
//! let rf = load_frame(&frame(0, "a.png"), Some((448, 256)), Fit::Stretch)?;
//! let sf = load_frame(&frame(1, "b.png"), Some((448, 256)), Fit::Stretch)?;
//! let model = Model::load("models/mhi-n5d16-colour-w16".as_ref(), Device::flex())?;
//! let synth = ViewSynthesis::new(MhiSource::Learned(&model));
//! let (mhi, _times) = synth.mhi(&rf, &sf)?;
//! let target = cams.rows[2].camera(448, 256)?;
//! let view = synth.render(&mhi, &target, BlendChoice::Learned, Prune::DEFAULT)?;
//! mhi_data::write_png("view.png".as_ref(), &mhi_data::to_u8(&view.image))?;
//! # Ok(())
//! # }
//! ```
//!
//! # Example: the networks alone
//!
//! ```
//! use burn::tensor::{Device, Tensor};
//! use mhi_net::{BlendNetConfig, Stage1Config, UNet3dConfig};
//!
//! let device = Device::flex();
//! let stage1 = Stage1Config::new(UNet3dConfig::new().with_width(4), 2).init(&device);
//! // Two normals, 6 channels, 3 planes, 8 × 8 pixels.
//! let alphas = stage1.forward(Tensor::zeros([2, 6, 3, 8, 8], &device));
//! assert_eq!(alphas.dims(), [2, 1, 3, 8, 8]);
//! let blend = BlendNetConfig::new(2).with_width(4).init(&device);
//! let weights = blend.forward(Tensor::zeros([1, 8, 8, 8], &device));
//! assert_eq!(weights.dims(), [1, 2, 8, 8]);
//! ```

pub mod backbone;
mod config;
mod heads;
pub use mhi_kernels as fastconv;
pub mod loss;
mod model;
mod nets;
pub mod pickle;
pub mod pretrained;
mod run;
mod train;
mod view;
mod volume;
pub mod weights;

pub use config::{GRAD_CLIP_NORM, TrainConfig};
pub use model::Model;
pub use nets::{
    BlendNet, BlendNetConfig, SOFT_FLOOR, Stage1, Stage1Config, UNet3d, UNet3dConfig,
    conv3d_planes_as_2d,
};
pub use run::{Latest, RunDir, ValRow};
pub use train::{
    CSV_HEADER, EvalScores, Sample, StepReport, StepTimes, Trainer, VAL_CSV_HEADER, init_models,
};
pub use view::{
    BlendChoice, Blended, CONSISTENCY_BETA, Consistency, MhiSource, MhiTimes, MultiNormal, View,
    ViewSynthesis, inconsistency, multi_normal, render_image, render_view,
};
pub use volume::{
    LOGIT_INPUT_SCALE, PRIOR_EPS, Prior, SourceColour, Stage1Input, SweepPrior, cost_volume,
    stage1_input, stage1_input_with,
};

/// Why building, training or resuming a model failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A configuration that cannot be trained, or a run directory in the wrong state.
    #[error("{0}")]
    Config(String),
    /// A checkpoint that cannot be read or does not match the run's configuration.
    #[error("checkpoint: {0}")]
    Checkpoint(String),
    /// A loss or output that became NaN or infinite.
    #[error("non-finite value: {0}")]
    NonFinite(String),
    /// A file that could not be read or written.
    #[error("{path}", path = path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// Data that could not be loaded.
    #[error(transparent)]
    Data(Box<mhi_data::Error>),
    /// Rendering inputs refused.
    #[error(transparent)]
    Render(#[from] mhi_render::Error),
    /// Geometry refused.
    #[error(transparent)]
    Geometry(#[from] mhi_geom::Error),
}

/// Result of a network operation.
pub type Result<T> = std::result::Result<T, Error>;
