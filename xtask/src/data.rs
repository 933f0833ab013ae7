//! `synth` and `triplets`: making and inspecting datasets.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use mhi_data::output::StagedDir;
use mhi_data::{Dataset, RotationBin, SynthConfig, TripletKind};

use crate::common::parse_size;

/// Options of `cargo xtask synth`.
#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Output directory; `train/` and `test/` splits are written inside it.
    #[arg(long)]
    pub out: PathBuf,
    /// Number of scenes (one sequence each).
    #[arg(long, default_value_t = 100)]
    pub scenes: usize,
    /// Frames per sequence.
    #[arg(long, default_value_t = 10)]
    pub frames: usize,
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, default_value = "256x256", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Seed: the same seed gives the same scenes, bit for bit.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Fraction of scenes written to the test split.
    #[arg(long, default_value_t = 0.2)]
    pub test_fraction: f64,
    /// Fraction of scenes written to the val split (validation: defaults are chosen there,
    /// never on test).
    #[arg(long, default_value_t = 0.1)]
    pub val_fraction: f64,
    /// Samples per pixel along each axis (anti-aliasing).
    #[arg(long, default_value_t = 2)]
    pub supersample: u32,
    /// Replace a synthetic dataset made before in --out (a folder holding anything else is
    /// refused with or without it).
    #[arg(long)]
    pub overwrite: bool,
}

/// `cargo xtask synth`.
pub fn synth(a: &SynthArgs) -> anyhow::Result<()> {
    let config = SynthConfig {
        scenes: a.scenes,
        frames: a.frames,
        width: a.size.0,
        height: a.size.1,
        seed: a.seed,
        test_fraction: a.test_fraction,
        val_fraction: a.val_fraction,
        supersample: a.supersample,
    };
    crate::common::check_synth_count(a.scenes, a.frames)?;
    if a.out.join(mhi_data::INCOMPLETE_MARKER).exists() && !a.overwrite {
        bail!(
            "{} holds an incomplete synthetic set (an earlier synth was interrupted); pass --overwrite to generate it again",
            a.out.display()
        );
    }
    // Built beside --out and swapped into place whole; a folder of the user's is refused.
    let staged = StagedDir::begin(&a.out, mhi_data::SYNTH_KIND, a.overwrite)?;
    for n in staged.notes() {
        println!("note: {n}");
    }
    let pb = crate::progress::bar((config.scenes * config.frames) as u64, "rendering");
    let t0 = Instant::now();
    let summary = mhi_data::generate(&config, staged.path(), &|| pb.inc(1))
        .with_context(|| format!("generating synthetic scenes in {}", a.out.display()))?;
    pb.finish_and_clear();
    staged.commit()?;
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "wrote {} frames of {} scenes ({} train, {} val, {} test) at {}x{} to {} in {:.1} s ({:.1} frames/s)",
        summary.frames,
        config.scenes,
        summary.train.len(),
        summary.val.len(),
        summary.test.len(),
        config.width,
        config.height,
        a.out.display(),
        secs,
        summary.frames as f64 / secs
    );
    Ok(())
}

/// Options of `cargo xtask triplets`.
#[derive(Args, Debug)]
pub struct TripletsArgs {
    /// Dataset root in RealEstate10K layout (`ROOT/<split>/<seq>.txt` and frames); repeat to
    /// open several roots as one (sequence names then qualified as ROOT/SEQUENCE).
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    /// Split to open.
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Triplets drawn per sequence.
    #[arg(long, default_value_t = 10)]
    pub per_sequence: usize,
    /// Seed of the draw.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write the triplets to this JSON index (refuses to replace an existing file).
    #[arg(long)]
    pub save: Option<PathBuf>,
}

/// `cargo xtask triplets`.
pub fn triplets(a: &TripletsArgs) -> anyhow::Result<()> {
    let ds = Dataset::open_many(&a.data, &a.split, 3)?;
    for w in &ds.warnings {
        eprintln!(
            "warning: {}",
            mhi_data::sanitize::for_terminal(&w.to_string())
        );
    }
    let frames: usize = ds.sequences.iter().map(|s| s.frames.len()).sum();
    println!(
        "{}: {} sequences, {} frames; {} sequences skipped, {} frames missing",
        ds.dir.display(),
        ds.sequences.len(),
        frames,
        ds.skipped_sequences,
        ds.missing_frames
    );
    if ds.sequences.is_empty() {
        bail!(
            "{}: no usable sequence: each needs at least 3 frames with images, and {} camera files were skipped (the warnings above say which and why)",
            ds.dir.display(),
            ds.skipped_sequences
        );
    }
    let first = &ds.sequences[0].frames[0];
    let loaded = mhi_data::load_frame(first, None, mhi_data::Fit::Stretch)?;
    let k = loaded.camera.intrinsics;
    println!(
        "first frame {}: {}x{}, fx {:.1} fy {:.1} cx {:.1} cy {:.1}",
        first.path.display(),
        loaded.image.width(),
        loaded.image.height(),
        k.fx,
        k.fy,
        k.cx,
        k.cy
    );
    for s in &ds.sequences {
        println!(
            "  {}: {} frames, sampled as {}",
            mhi_data::sanitize::for_terminal(&s.name),
            s.frames.len(),
            match s.sampling() {
                mhi_data::Sampling::Video => "video (clips of 10 frames, stride 3-10)",
                mhi_data::Sampling::Sparse => "a sparse capture (neighbouring views)",
            }
        );
    }
    let index = crate::common::sample_index(&ds, a.per_sequence, a.seed)?;
    let counts = index.bin_counts();
    let interp = index
        .triplets
        .iter()
        .filter(|t| t.kind == TripletKind::Interpolation)
        .count();
    println!(
        "{} triplets (seed {}): {} interpolation, {} extrapolation",
        index.triplets.len(),
        a.seed,
        interp,
        index.triplets.len() - interp
    );
    for (bin, c) in RotationBin::ALL.iter().zip(counts) {
        println!("  rotation {:>5}: {c}", bin.label());
    }
    if let Some(p) = &a.save {
        if p.exists() {
            bail!("{} exists; remove it or choose another path", p.display());
        }
        index.save(p)?;
        println!("saved {}", p.display());
    }
    Ok(())
}
