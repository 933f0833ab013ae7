//! Helpers shared by several commands: option parsers and checks, the synthetic set on demand,
//! the evaluation size, the weights cache, the tensor backend, scene ground truth and image
//! files. No command module imports another; what two commands share lives here.

use std::path::{Path, PathBuf};

use anyhow::Context;
use burn::tensor::Device;
use image::Rgb32FImage;
use mhi_data::SynthConfig;
use mhi_geom::Camera;
use mhi_render::PixelTruth;

/// Parse a normal count: the paper's sets have N = 1 (the MPI), 2, 3 or 5 normals.
pub fn parse_normals(s: &str) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n @ (1 | 2 | 3 | 5)) => Ok(n),
        _ => Err(format!(
            "{s:?}: choose 1 (an MPI), 2, 3 or 5 normals, the paper's normal sets"
        )),
    }
}

/// Refuse work whose layers would not fit in memory, before allocating them: an N × D MHI at
/// `width × height` with its plane-sweep volume takes about 24 bytes per layer pixel (alpha,
/// warped colour and validity in f32, plus the costs). The limit is the memory available now
/// (`MemAvailable` of /proc/meminfo; 16 GiB where that cannot be read).
pub fn check_memory(what: &str, width: u32, height: u32, layers: usize) -> anyhow::Result<()> {
    let need = 24.0 * f64::from(width) * f64::from(height) * layers as f64;
    let avail = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(16.0 * 1024.0 * 1024.0 * 1024.0, |kib| kib * 1024.0);
    if need > 0.8 * avail {
        anyhow::bail!(
            "{what}: {layers} layers of {width}x{height} need about {:.1} GB, but {:.1} GB of memory is available; choose a smaller size or fewer planes",
            need / 1e9,
            avail / 1e9
        );
    }
    Ok(())
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

/// Make sure a synthetic dataset exists at `root` (generating the default one if not).
pub fn ensure_synthetic(root: &Path) -> anyhow::Result<()> {
    let interrupted = root.join(mhi_data::INCOMPLETE_MARKER).exists();
    if root.join("test").is_dir() && !interrupted {
        return Ok(());
    }
    if interrupted {
        eprintln!(
            "{} holds an interrupted synthetic set: generating it again",
            root.display()
        );
    }
    eprintln!(
        "no synthetic data at {}: generating the default set (100 scenes, 256x256)",
        root.display()
    );
    let config = SynthConfig::default();
    let staged = mhi_data::output::StagedDir::begin(root, mhi_data::SYNTH_KIND, interrupted)?;
    let pb = crate::progress::bar((config.scenes * config.frames) as u64, "synth");
    mhi_data::generate(&config, staged.path(), &|| pb.inc(1))?;
    pb.finish_and_clear();
    staged.commit()?;
    Ok(())
}

/// Per reference pixel, the true surface normal and depth of a synthetic scene.
pub fn truth_of(scene: &mhi_data::Scene, cam: &Camera) -> Vec<Option<PixelTruth>> {
    scene
        .ground_truth(cam)
        .into_iter()
        .map(|t| t.map(|(normal, depth)| PixelTruth { normal, depth }))
        .collect()
}

pub fn save_png(path: &Path, img: &Rgb32FImage) -> anyhow::Result<()> {
    mhi_data::write_png(path, &mhi_data::to_u8(img))?;
    Ok(())
}

/// |a − b| averaged over channels, scaled ×4 and shown in grey (so a 0.25 error is white).
pub fn error_map(a: &Rgb32FImage, b: &Rgb32FImage) -> Rgb32FImage {
    Rgb32FImage::from_fn(a.width(), a.height(), |x, y| {
        let (p, q) = (a.get_pixel(x, y).0, b.get_pixel(x, y).0);
        let e = ((p[0] - q[0]).abs() + (p[1] - q[1]).abs() + (p[2] - q[2]).abs()) / 3.0 * 4.0;
        image::Rgb([e, e, e])
    })
}

/// The evaluation size of frames of `dims`: `short` pixels on the short side, the long side in
/// proportion rounded to a multiple of 16 (at least 16).
pub fn size_for(dims: (u32, u32), short: u32) -> (u32, u32) {
    let (w, h) = (f64::from(dims.0), f64::from(dims.1));
    let long = |l: f64, s: f64| ((l / s * f64::from(short) / 16.0).round() as u32).max(1) * 16;
    if dims.0 >= dims.1 {
        (long(w, h), short)
    } else {
        (short, long(h, w))
    }
}

/// The cache directory for weights.
pub fn cache_dir(explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    if let Some(p) = std::env::var_os("MHI_CACHE") {
        return PathBuf::from(p);
    }
    let home = std::env::var_os("HOME").map_or_else(|| PathBuf::from("."), PathBuf::from);
    home.join(".cache").join("mhi")
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

pub fn device(backend: Backend) -> anyhow::Result<Device> {
    match backend {
        Backend::Flex => Ok(Device::flex()),
        #[cfg(feature = "wgpu")]
        Backend::Wgpu => Ok(Device::wgpu(burn::tensor::DeviceKind::DefaultDevice)),
        #[cfg(not(feature = "wgpu"))]
        Backend::Wgpu => anyhow::bail!(
            "this build has no wgpu backend; build it with `cargo run -p xtask --features wgpu -- ...` (about 14 minutes from clean)"
        ),
    }
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

/// The most orbit frames a GIF takes: a minute at the orbit's 60 ms a frame.
pub const MAX_ORBIT_FRAMES: usize = 1000;

/// Refuse a GIF whose frames (`flag`) would not fit, with what it would cost: every frame is
/// kept (enlarged to at least 256 px wide) until the GIF is encoded.
pub fn check_gif_frames(flag: &str, frames: usize) -> anyhow::Result<()> {
    if frames > MAX_ORBIT_FRAMES {
        anyhow::bail!(
            "{flag} {frames}: the GIF keeps every frame in memory (about {:.1} GB for {frames} frames at 256 px wide) and plays for {:.0} s; at most {MAX_ORBIT_FRAMES} frames ({:.0} s)",
            frames as f64 * 256.0 * 256.0 * 4.0 * 2.0 / 1e9,
            frames as f64 * 0.06,
            MAX_ORBIT_FRAMES as f64 * 0.06
        );
    }
    Ok(())
}

/// The most triplets drawn from one sequence: far more than any sequence supplies distinct ones.
pub const MAX_PER_SEQUENCE: usize = 10_000;

/// Draw the evaluation triplets (see [`mhi_data::TripletIndex::sample`]), refusing absurd counts
/// and warning for every sequence that could not supply distinct triplets enough.
pub fn sample_index(
    ds: &mhi_data::Dataset,
    per_sequence: usize,
    seed: u64,
) -> anyhow::Result<mhi_data::TripletIndex> {
    if per_sequence > MAX_PER_SEQUENCE {
        anyhow::bail!(
            "--per-sequence {per_sequence}: at most {MAX_PER_SEQUENCE} triplets a sequence (a sequence of n frames supplies far fewer distinct ones, and each costs a render of every method)"
        );
    }
    let index = mhi_data::TripletIndex::sample(ds, per_sequence, seed);
    for (name, got) in &index.shortfalls {
        eprintln!(
            "warning: sequence {} supplies only {got} distinct triplets, not the {per_sequence} asked; using {got} (repeats would make the intervals too narrow)",
            mhi_data::sanitize::for_terminal(name)
        );
    }
    Ok(index)
}

/// The most synthetic frames one `synth` makes (a million: about 50 GB of PNGs at 256 × 256).
pub const MAX_SYNTH_FRAMES: usize = 1_000_000;

/// Refuse a synthetic set too large to make, with what it would cost.
pub fn check_synth_count(scenes: usize, frames: usize) -> anyhow::Result<()> {
    let total = scenes.saturating_mul(frames);
    if total > MAX_SYNTH_FRAMES {
        anyhow::bail!(
            "--scenes {scenes} x --frames {frames} = {total} frames: at most {MAX_SYNTH_FRAMES} (about {:.0} hours on 2 cores at 25 frames/s and {:.0} GB of PNGs at 256 x 256)",
            total as f64 / 25.0 / 3600.0,
            total as f64 * 60e3 / 1e9
        );
    }
    Ok(())
}

/// The CPU's model name (`/proc/cpuinfo`), or the architecture where there is none.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

/// The paths the project's own kernels take on this CPU (each is chosen at run time by the
/// CPU's features, capped by `MHI_SIMD`; docs/SPEED.md lists them).
pub fn kernel_paths() -> String {
    use mhi_geom::simd::{Level, detected, level};
    let l = level();
    format!(
        "SIMD level {} (CPU: {}; MHI_SIMD caps it): renderer band loop {}, convolution tiles {}",
        l.name(),
        detected().name(),
        if l >= Level::Avx2 {
            "AVX2 + FMA"
        } else {
            "baseline"
        },
        match l {
            Level::Avx512 => "AVX-512F (16 channels), AVX2 + FMA (8)",
            Level::Avx2 => "AVX2 + FMA (8 channels)",
            Level::Baseline => "gemm only",
        }
    )
}
