//! `cargo xtask sweep`: the training-free MHI of one triplet of real posed photos, rendered and
//! compared with the photo and the nearest input view.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::Args;
use image::Rgb32FImage;
use mhi_data::{Dataset, Fit, load_frame};
use mhi_geom::{BlendHeuristic, Camera, NormalSet};
use mhi_net::{BlendChoice, MhiSource, ViewSynthesis};
use mhi_render::{Prune, SweepConfig};

use crate::common::{error_map, save_png};

/// Options of `cargo xtask sweep`.
#[derive(Args, Debug, Clone)]
pub struct SweepArgs {
    /// Dataset root in RealEstate10K layout.
    #[arg(long)]
    pub data: PathBuf,
    /// Split.
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Sequence name (default: the first).
    #[arg(long)]
    pub seq: Option<String>,
    /// Frame index of the reference view (the MHI's grid).
    #[arg(long = "ref", default_value_t = 3)]
    pub reference: usize,
    /// Frame index of the source view.
    #[arg(long, default_value_t = 5)]
    pub src: usize,
    /// Frame index of the view to synthesise and compare against.
    #[arg(long, default_value_t = 4)]
    pub target: usize,
    /// Working resolution WIDTHxHEIGHT (frames are resized, intrinsics follow).
    #[arg(long, default_value = "384x256", value_parser = crate::common::parse_size)]
    pub size: (u32, u32),
    #[command(flatten)]
    pub grid: crate::common::PlaneArgs,
    /// Softmax temperature of the winner-take-all over depths (lower is sharper).
    #[arg(long, default_value_t = SweepConfig::default().temperature)]
    pub temperature: f32,
    /// Radius of the box window of the photo-consistency cost, in pixels at a short side of
    /// 256; scaled with the short side of --size (the same window in scene terms).
    #[arg(long, default_value_t = SweepConfig::default().window_radius)]
    pub window: u32,
    /// Output directory for the images and summary.json.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
}

/// `cargo xtask sweep`.
pub fn sweep(a: &SweepArgs) -> anyhow::Result<()> {
    mhi_eval::support::staged(&a.out, "sweep output", |out| {
        let mut a = a.clone();
        a.out = out.to_path_buf();
        sweep_into(&a)
    })?;
    println!("images and summary.json in {}", a.out.display());
    Ok(())
}

/// The sequence `sweep` reads (--seq, else the first) with its three frames checked: in range,
/// distinct, of one size.
fn sweep_sequence<'d>(a: &SweepArgs, ds: &'d Dataset) -> anyhow::Result<&'d mhi_data::Sequence> {
    let seq = match &a.seq {
        Some(name) => ds
            .sequences
            .iter()
            .find(|s| &s.name == name)
            .with_context(|| format!("no sequence {name:?} in {}", ds.dir.display()))?,
        None => ds
            .sequences
            .first()
            .context("dataset has no usable sequence")?,
    };
    let n = seq.frames.len();
    for (what, i) in [
        ("--ref", a.reference),
        ("--src", a.src),
        ("--target", a.target),
    ] {
        if i >= n {
            bail!(
                "{what} {i} is out of range: sequence {} has frames 0..{}",
                seq.name,
                n - 1
            );
        }
    }
    if a.reference == a.src || a.target == a.reference || a.target == a.src {
        bail!(
            "--ref {}, --src {} and --target {} must be three different frames: a view rendered from itself, or an MHI from one photo, says nothing",
            a.reference,
            a.src,
            a.target
        );
    }
    mhi_data::check_same_size(&[
        &seq.frames[a.reference],
        &seq.frames[a.src],
        &seq.frames[a.target],
    ])?;
    Ok(seq)
}

/// `sweep`'s pictures: the photos, the render and the nearest input with their error maps, the
/// reference's disparity (near = white) and the multi-normal images.
fn save_sweep_pictures(
    out_dir: &std::path::Path,
    (rf, sf, tf): (
        &mhi_data::LoadedFrame,
        &mhi_data::LoadedFrame,
        &mhi_data::LoadedFrame,
    ),
    render: &mhi_net::View,
    nearest: &mhi_data::LoadedFrame,
    mhi: &mhi_render::Mhi,
    normals: &NormalSet,
) -> anyhow::Result<()> {
    save_png(&out_dir.join("target_photo.png"), &tf.image)?;
    save_png(&out_dir.join("sweep_render.png"), &render.image)?;
    save_png(&out_dir.join("nearest_input.png"), &nearest.image)?;
    save_png(&out_dir.join("reference.png"), &rf.image)?;
    save_png(&out_dir.join("source.png"), &sf.image)?;
    save_png(
        &out_dir.join("sweep_error.png"),
        &error_map(&render.image, &tf.image),
    )?;
    save_png(
        &out_dir.join("nearest_error.png"),
        &error_map(&nearest.image, &tf.image),
    )?;
    // Disparity of the fronto-parallel (or first) normal as grey, near = white.
    let fronto = normals
        .normals()
        .iter()
        .position(|n| n.z > 0.999)
        .unwrap_or(0);
    let disp = mhi.expected_disparity(fronto);
    let max = disp.iter().cloned().fold(1e-6_f32, f32::max);
    let dimg = Rgb32FImage::from_fn(rf.camera.width, rf.camera.height, |x, y| {
        let v = disp[(y * rf.camera.width + x) as usize] / max;
        image::Rgb([v, v, v])
    });
    save_png(&out_dir.join("reference_disparity.png"), &dimg)?;
    for (i, mni) in render.multi_normal.iter().enumerate() {
        save_png(&out_dir.join(format!("multi_normal_{}.png", i + 1)), mni)?;
    }
    Ok(())
}

fn sweep_into(a: &SweepArgs) -> anyhow::Result<()> {
    let ds = Dataset::open(&a.data, &a.split, 3)?;
    let seq = sweep_sequence(a, &ds)?;
    crate::common::check_memory("--size", a.size.0, a.size.1, a.grid.normals * a.grid.planes)?;
    let load = |i: usize| load_frame(&seq.frames[i], Some(a.size), Fit::Stretch);
    let (rf, sf, tf) = (load(a.reference)?, load(a.src)?, load(a.target)?);
    let normals = a.grid.normal_set()?;
    let depths = a.grid.depths()?;
    let cfg = SweepConfig {
        temperature: a.temperature,
        window_radius: a.window,
        ..SweepConfig::default()
    }
    .scaled_to_short_side(a.size.0.min(a.size.1));
    let synth = ViewSynthesis::new(MhiSource::Sweep {
        normals: normals.clone(),
        depths,
        config: cfg,
    });
    let (mhi, times) = synth.mhi(&rf, &sf)?;
    let build_ms = times.volume_ms;
    let out = synth.render(
        &mhi,
        &tf.camera,
        BlendChoice::Heuristic(BlendHeuristic::Soft),
        Prune::NONE,
    )?;
    let render_ms = out.render_ms;
    // The floor: the input view nearest the target (by camera centre), shown as it is.
    let dist = |c: &Camera| (c.center_in_world() - tf.camera.center_in_world()).length();
    let nearest = if dist(&rf.camera) <= dist(&sf.camera) {
        &rf
    } else {
        &sf
    };
    let nearest_name = if std::ptr::eq(nearest, &rf) {
        "reference"
    } else {
        "source"
    };
    let m = |img: &Rgb32FImage| -> anyhow::Result<(f64, f64)> {
        Ok((
            mhi_eval::psnr(img, &tf.image)?,
            mhi_eval::ssim(img, &tf.image)?,
        ))
    };
    let (sp, ss) = m(&out.image)?;
    let (np, ns) = m(&nearest.image)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    save_sweep_pictures(&a.out, (&rf, &sf, &tf), &out, nearest, &mhi, &normals)?;
    let summary = serde_json::json!({
        "sequence": seq.name, "reference": a.reference, "source": a.src, "target": a.target,
        "size": [a.size.0, a.size.1], "normals": normals.len(), "planes": a.grid.planes,
        "sweep": {"psnr": sp, "ssim": ss, "build_ms": build_ms, "render_ms": render_ms},
        "nearest": {"view": nearest_name, "psnr": np, "ssim": ns},
    });
    mhi_data::write_atomic(
        &a.out.join("summary.json"),
        &serde_json::to_vec_pretty(&summary)?,
    )?;
    println!(
        "{} frames ref {} src {} → target {} at {}x{}, N={} D={}",
        seq.name,
        a.reference,
        a.src,
        a.target,
        a.size.0,
        a.size.1,
        normals.len(),
        a.grid.planes
    );
    println!(
        "  sweep MHI (soft blend): PSNR {sp:.2} dB  SSIM {ss:.4}  (build {build_ms:.0} ms, render {render_ms:.0} ms)"
    );
    println!("  nearest input ({nearest_name}):  PSNR {np:.2} dB  SSIM {ns:.4}");
    Ok(())
}
