//! The options of an evaluation (`cargo xtask eval`'s, as a typed value a library user fills
//! in or parses with clap), and the parsers of the values they take.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use mhi_render::SweepConfig;

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
    /// The same stage 1, Soft weights leaning towards the normals whose geometry both photos
    /// agree with (`--consistency-beta`; needs no training).
    Consistent,
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
        default_value = "learned,soft,hard,avg,consistent,mpi,sweep,oracle,nearest"
    )]
    pub methods: Vec<Method>,
    /// Strength β of the `consistent` blend: each normal's Soft weight is scaled by
    /// `exp(−β · c)`, with `c` the mean colour difference (0 to 1) between the source photo
    /// warped by that normal's layers and the reference photo, along the pixel's ray. 0 is
    /// Soft.
    #[arg(long, default_value_t = mhi_net::CONSISTENCY_BETA, allow_hyphen_values = true)]
    pub consistency_beta: f32,
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
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Short side of the evaluation size when no --size is given; the long side keeps the
    /// frames' aspect ratio, rounded to a multiple of 16 (the networks' stride).
    #[arg(long, default_value_t = 256)]
    pub short_side: u32,
    /// The depth range of the sweep's and the oracle's planes.
    #[command(flatten)]
    pub range: DepthRange,
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

/// The depth range of an MHI's planes (`--near`, `--far`), shared by the commands that build
/// MHIs without a trained model (a trained run keeps its own).
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct DepthRange {
    /// Nearest plane depth, in the cameras' units.
    #[arg(long, default_value_t = 1.0)]
    pub near: f64,
    /// Farthest plane depth (the planes are linear in disparity between the two; `eval`
    /// scores the covered region: what the reference view sees on the fronto-parallel plane at
    /// this depth).
    #[arg(long, default_value_t = 100.0)]
    pub far: f64,
}

impl DepthRange {
    /// `planes` depths linear in disparity, far first.
    pub fn depths(&self, planes: usize) -> anyhow::Result<Vec<f64>> {
        mhi_geom::depths_linear_in_disparity(self.near, self.far, planes)
            .with_context(|| format!("--near {} --far {} --planes {planes}", self.near, self.far))
    }
}

/// Parse a normal count: the paper's sets have N = 1 (the MPI), 2, 3 or 5 normals.
pub fn parse_normals(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n @ (1 | 2 | 3 | 5)) => Ok(n),
        _ => Err(format!(
            "{s:?}: choose 1 (an MPI), 2, 3 or 5 normals, the paper's normal sets"
        )),
    }
}

/// Parse `WIDTHxHEIGHT`.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size {s:?} must look like 256x256"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("width {w:?} is not a positive integer"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("height {h:?} is not a positive integer"))?;
    if w == 0 || h == 0 {
        return Err(format!("size {s:?} has no pixels"));
    }
    Ok((w, h))
}

/// The tensor backend (`--backend`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// burn's CPU backend.
    Flex,
    /// burn's wgpu backend (a build with `--features wgpu`).
    Wgpu,
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Flex => "flex",
            Self::Wgpu => "wgpu",
        })
    }
}

/// An MHI's grid (`--normals`, `--planes`, `--near`, `--far`), shared by `render`, `sweep` and
/// `bench`.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct PlaneArgs {
    /// Number of normals: the paper's subsets, 1 (an MPI), 2, 3 or 5.
    #[arg(long, default_value_t = 5, value_parser = parse_normals)]
    pub normals: usize,
    /// Planes per normal.
    #[arg(long, default_value_t = 32)]
    pub planes: usize,
    #[command(flatten)]
    /// Depths of the nearest and farthest planes.
    pub range: DepthRange,
}

impl PlaneArgs {
    /// The normals (the paper's subset of this size).
    pub fn normal_set(&self) -> anyhow::Result<mhi_geom::NormalSet> {
        mhi_geom::NormalSet::paper_subset(self.normals)
            .with_context(|| format!("--normals {}", self.normals))
    }

    /// The plane depths, far first.
    pub fn depths(&self) -> anyhow::Result<Vec<f64>> {
        self.range.depths(self.planes)
    }

    /// Whether any of the four differs from its default (so that a command where they do not
    /// apply can say so rather than ignore them).
    pub fn given(&self) -> bool {
        self.normals != 5 || self.planes != 32 || self.range.near != 1.0 || self.range.far != 100.0
    }
}

/// The device of the tensor backend `backend`.
pub fn device(backend: Backend) -> anyhow::Result<burn::tensor::Device> {
    match backend {
        Backend::Flex => Ok(burn::tensor::Device::flex()),
        #[cfg(feature = "wgpu")]
        Backend::Wgpu => Ok(burn::tensor::Device::wgpu(
            burn::tensor::DeviceKind::DefaultDevice,
        )),
        #[cfg(not(feature = "wgpu"))]
        Backend::Wgpu => anyhow::bail!(
            "this build has no wgpu backend; build it with `cargo run -p xtask --features wgpu -- ...` (about 14 minutes from clean)"
        ),
    }
}
