//! `cargo xtask render`: novel views of a user's own two photos. The camera file (RealEstate10K
//! format) holds the reference photo's camera on its first row, the source photo's on its second,
//! and the cameras of the views to render on any further rows; an orbit GIF around the reference
//! view is written too. The MHI comes from a trained run (`--run`) or the training-free sweep.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use burn::tensor::Device;
use clap::Args;
use image::Rgb32FImage;
use mhi_data::{CameraFile, Fit, Frame, LoadedFrame, load_frame};
use mhi_geom::{BlendHeuristic, Camera, depths_linear_in_disparity};
use mhi_net::Model;
use mhi_render::{Mhi, SweepConfig, heuristic_weights_for, sweep_mhi};

use crate::views::{clipped, combine, enlarge, factor_for, orbit, write_gif};

/// Options of `cargo xtask render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The reference photo (the MHI is built on its pixel grid).
    #[arg(long = "ref")]
    pub reference: PathBuf,
    /// The second photo.
    #[arg(long)]
    pub src: PathBuf,
    /// Camera file, RealEstate10K format: URL line, then one row per camera (timestamp fx fy cx
    /// cy k1 k2 and the 3x4 world-to-camera pose, intrinsics normalised by the image size),
    /// timestamps increasing. The rows named by --ref-row and --src-row are the photos' cameras;
    /// every other row is a view to render.
    #[arg(long)]
    pub cameras: PathBuf,
    /// Camera row (1-based, not counting the URL line) of the reference photo.
    #[arg(long, default_value_t = 1)]
    pub ref_row: usize,
    /// Camera row (1-based) of the source photo.
    #[arg(long, default_value_t = 2)]
    pub src_row: usize,
    /// A trained run (its latest checkpoint): stage 1 and the learned blend. Without it the
    /// training-free plane-sweep MHI with Soft blending is used.
    #[arg(long)]
    pub run: Option<PathBuf>,
    /// Working size WIDTHxHEIGHT (photos are resized, intrinsics follow; multiples of 4 for a
    /// run). Default: the reference photo's aspect with its longer side 256 (multiples of 4).
    #[arg(long, value_parser = crate::data::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Normals of the sweep MHI (1, 2, 3 or 5).
    #[arg(long, default_value_t = 5, value_parser = crate::data::parse_normals)]
    pub normals: usize,
    /// Planes per normal of the sweep MHI.
    #[arg(long, default_value_t = 32)]
    pub planes: usize,
    /// Nearest plane depth of the sweep MHI, in the cameras' units.
    #[arg(long, default_value_t = 1.0)]
    pub near: f64,
    /// Farthest plane depth of the sweep MHI.
    #[arg(long, default_value_t = 100.0)]
    pub far: f64,
    /// Frames of the orbit GIF around the reference view (0: none).
    #[arg(long, default_value_t = 30)]
    pub orbit_frames: usize,
    /// Orbit radius as a fraction of the distance between the two photos' cameras.
    #[arg(long, default_value_t = 0.5)]
    pub orbit_radius: f64,
    /// Output directory (view_rowNNN.png per rendered camera row, orbit.gif).
    #[arg(long, default_value = "out/render")]
    pub out: PathBuf,
    /// Replace images already in --out.
    #[arg(long)]
    pub overwrite: bool,
}

/// `cargo xtask render`.
pub fn render(a: &RenderArgs) -> anyhow::Result<()> {
    let file = CameraFile::read(&a.cameras)?;
    let rows = file.rows.len();
    for (what, r) in [("--ref-row", a.ref_row), ("--src-row", a.src_row)] {
        if r == 0 || r > rows {
            bail!(
                "{what} {r}: {} has camera rows 1 to {rows}",
                a.cameras.display()
            );
        }
    }
    if !(a.orbit_radius.is_finite() && a.orbit_radius > 0.0 && a.orbit_radius <= 10.0) {
        bail!(
            "--orbit-radius {} must be a number in (0, 10]: it is a fraction of the distance between the two photos' cameras (0.5 by default); farther, the orbit leaves what the photos saw",
            a.orbit_radius
        );
    }
    if a.reference == a.src {
        bail!(
            "--ref and --src are the same file ({}): the MHI needs two photos taken from different places",
            a.reference.display()
        );
    }
    if a.ref_row == a.src_row {
        bail!(
            "--ref-row and --src-row are both {}: the two photos need two cameras",
            a.ref_row
        );
    }
    let taken = std::fs::read_dir(&a.out).is_ok_and(|d| {
        d.flatten().any(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.starts_with("view_row") || n == "orbit.gif"
        })
    });
    if taken && !a.overwrite {
        bail!(
            "{} already holds rendered views; pass --overwrite to replace them or choose another --out",
            a.out.display()
        );
    }
    let learned: Option<Model> = match &a.run {
        Some(run) => Some(
            Model::load(run, Device::flex())
                .with_context(|| format!("loading the trained run {}", run.display()))?,
        ),
        None => None,
    };
    let ref_rgb = mhi_data::read_rgb(&a.reference)?;
    let size = a.size.unwrap_or_else(|| {
        let (w, h) = ref_rgb.dimensions();
        let s = 256.0 / f64::from(w.max(h));
        let r4 = |x: u32| ((f64::from(x) * s / 4.0).round() as u32).max(1) * 4;
        (r4(w), r4(h))
    });
    if let Some(m) = &learned {
        m.check_size(size.0, size.1)?;
    }
    let layers = match &learned {
        Some(m) => m.normals().len() * m.depths().len() * 8,
        None => a.normals * a.planes,
    };
    crate::data::check_memory("--size", size.0, size.1, layers)?;
    let frame = |path: &PathBuf, row: usize| Frame {
        row: file.rows[row],
        path: path.clone(),
    };
    let rf = load_frame(
        &frame(&a.reference, a.ref_row - 1),
        Some(size),
        Fit::Stretch,
    )?;
    let sf = load_frame(&frame(&a.src, a.src_row - 1), Some(size), Fit::Stretch)?;
    let t0 = Instant::now();
    let (mhi, model) = match &learned {
        Some(m) => {
            let alphas = m.alphas(m.cost_volume(&rf, &sf)?)?;
            (m.mhi(&rf, alphas)?, Some(m))
        }
        None => (
            sweep_mhi(
                &mhi_geom::NormalSet::paper_subset(a.normals)?,
                &depths_linear_in_disparity(a.near, a.far, a.planes)?,
                &rf.camera,
                &rf.image,
                &sf.camera,
                &sf.image,
                &SweepConfig::default(),
            )?,
            None,
        ),
    };
    println!(
        "MHI: {} normals x {} planes at {}x{} ({}) in {:.0} ms",
        mhi.n(),
        mhi.d(),
        size.0,
        size.1,
        if model.is_some() {
            "trained stage 1"
        } else {
            "plane sweep"
        },
        t0.elapsed().as_secs_f64() * 1e3
    );
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let targets: Vec<(usize, Camera)> = file
        .rows
        .iter()
        .enumerate()
        .filter(|(k, _)| *k + 1 != a.ref_row && *k + 1 != a.src_row)
        .map(|(k, r)| {
            let cam = r
                .camera(size.0, size.1)
                .with_context(|| format!("{}: camera row {}", a.cameras.display(), k + 1))?;
            Ok((k + 1, cam))
        })
        .collect::<anyhow::Result<_>>()?;
    let pb = crate::progress::bar((targets.len() + a.orbit_frames) as u64, "render");
    for (row, cam) in &targets {
        let img = view(&mhi, model, &rf, cam)?;
        let path = a.out.join(format!("view_row{row:03}.png"));
        mhi_data::write_png(&path, &mhi_data::to_u8(&clipped(&img)))?;
        pb.inc(1);
    }
    if a.orbit_frames > 0 {
        let baseline = (rf.camera.center_in_world() - sf.camera.center_in_world()).length();
        let mut frames = Vec::new();
        for cam in orbit(&rf.camera, a.orbit_radius * baseline, a.orbit_frames)? {
            let img = view(&mhi, model, &rf, &cam)?;
            frames.push(enlarge(
                &mhi_data::to_u8(&clipped(&img)),
                factor_for(img.width(), 256),
            ));
            pb.inc(1);
        }
        write_gif(&a.out.join("orbit.gif"), &frames, 60)?;
    }
    pb.finish_and_clear();
    println!(
        "{} view(s){} in {}",
        targets.len(),
        if a.orbit_frames > 0 {
            " and orbit.gif"
        } else {
            ""
        },
        a.out.display()
    );
    Ok(())
}

/// One novel view: the multi-normal images, blended by the learned network or by Soft.
fn view(
    mhi: &Mhi,
    model: Option<&Model>,
    rf: &LoadedFrame,
    cam: &Camera,
) -> anyhow::Result<Rgb32FImage> {
    let r = crate::eval::render_mni(mhi, cam)?;
    let soft = heuristic_weights_for(mhi.normals(), &rf.camera, cam, BlendHeuristic::Soft);
    let w = match model {
        Some(m) if mhi.n() > 1 => m.blend_weights(&r.multi_normal, &soft)?,
        _ => soft,
    };
    Ok(combine(&r.multi_normal, &w))
}
