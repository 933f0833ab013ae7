//! `cargo xtask render`: novel views of a user's own two photos. The camera file (RealEstate10K
//! format) holds the reference photo's camera on its first row, the source photo's on its second,
//! and the cameras of the views to render on any further rows; a video along a camera path around
//! the reference view (`--path`) is written too. The MHI comes from a trained run (`--run`) or the
//! training-free sweep.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use burn::tensor::Device;
use clap::Args;
use mhi_data::output::StagedDir;
use mhi_data::sanitize::for_terminal;
use mhi_data::{CameraFile, Fit, Frame, load_frame};
use mhi_geom::{BlendHeuristic, Camera};
use mhi_net::{MhiSource, Model, ViewSynthesis};
use mhi_render::{Prune, SweepConfig, heuristic_weights_for};

use crate::camera_path::PathKind;
use crate::views::{clipped, enlarge, factor_for, view, write_gif};

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
    /// every other row is a view to render. Without it the two photos' poses are estimated
    /// from the photos themselves (`cargo xtask pose`) and the views follow the orbit.
    #[arg(long)]
    pub cameras: Option<PathBuf>,
    #[command(flatten)]
    pub intrinsics: crate::pose::IntrinsicsArgs,
    /// Camera row (1-based, not counting the URL line) of the reference photo.
    #[arg(long, default_value_t = 1)]
    pub ref_row: usize,
    /// Camera row (1-based) of the source photo.
    #[arg(long, default_value_t = 2)]
    pub src_row: usize,
    /// A trained run (its latest checkpoint): its stage 1 makes the MHI (its blending network
    /// blends only with --blend learned). Default: the
    /// pretrained model in `models/` (see its MODEL.md), or the sweep when there is none.
    #[arg(long, conflicts_with = "sweep")]
    pub run: Option<PathBuf>,
    /// Use the training-free plane-sweep MHI (--normals, --planes, --near, --far) instead of a
    /// trained model.
    #[arg(long)]
    pub sweep: bool,
    /// How the multi-normal images are blended: `consistent` (Soft weights leaning towards the
    /// normals whose geometry both photos agree with; no training), `soft` (the paper's
    /// heuristic of the angle between each normal and the pixel's ray; it also lets the render
    /// leave out normals a view does not need) or `learned` (a trained model's blending
    /// network). Default: `consistent`, which beats Soft and the network on validation data,
    /// for the trained model and the sweep alike (models/mhi-n5d16-colour-w16/MODEL.md,
    /// docs/EXPERIMENTS.md); `soft` for `export` (the viewer blends with Soft).
    #[arg(long, value_enum)]
    pub blend: Option<BlendArg>,
    /// Working size WIDTHxHEIGHT (photos are resized, intrinsics follow). A trained model needs
    /// each side a multiple of its U-Nets' multiple (8 for the pretrained model; the error names
    /// it). Default: the reference photo's aspect with its longer side 256, rounded to that
    /// multiple.
    #[arg(long, value_parser = crate::common::parse_size)]
    pub size: Option<(u32, u32)>,
    /// The sweep MHI's grid (with --sweep or without a model; a trained model keeps its own).
    #[command(flatten)]
    pub grid: crate::common::PlaneArgs,
    /// The video's camera path around the reference view.
    #[command(flatten)]
    pub path: crate::camera_path::PathArgs,
    /// Frames per second of the video.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
    pub fps: f64,
    /// Write the video here instead of video.mp4 in --out (an existing file is replaced only
    /// with --overwrite, and only if this tool wrote it).
    #[arg(long)]
    pub video: Option<PathBuf>,
    /// Also write the path as an animated GIF (path.gif in --out: 256 colours, enlarged to at
    /// least 256 pixels wide; plays where a video cannot, in a README for one).
    #[arg(long)]
    pub gif: bool,
    /// Output directory (view_rowNNN.png per rendered camera row, video.mp4, plan.json).
    #[arg(long, default_value = "out/render")]
    pub out: PathBuf,
    /// Replace a render (or viewer) this command wrote before in --out. A folder holding files
    /// no mhi command made is refused with or without it.
    #[arg(long)]
    pub overwrite: bool,
    /// Render everything: leave nothing out (by default what the views do not need is left out
    /// within --budget; see plan.json).
    #[arg(long)]
    pub exact: bool,
    /// The error budget, in 8-bit levels per pixel: the most that everything left out may
    /// change any pixel (1 = 1/255).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub budget: f32,
    /// Also write the MHI as an interactive viewer folder here (see `cargo xtask export`).
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// Print the scene plan: what the views do not need (normals, layers, depth range), why,
    /// the bound kept, and the MHI's size before and after (it is written to plan.json too).
    #[arg(long)]
    pub explain: bool,
}

/// `render --blend`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BlendArg {
    /// The Soft heuristic.
    Soft,
    /// The trained model's blending network.
    Learned,
    /// Soft weights scaled by each normal's photo-consistency (`mhi_net::Consistency`).
    Consistent,
}

/// How `render` blends each view: by a heuristic or a model's network
/// ([`mhi_eval::images::view`]), or consistently.
#[derive(Clone, Copy)]
enum Blender<'a> {
    Model(Option<&'a Model>),
    /// The consistent blend, or a model's network that reads the same inconsistency images.
    Consistent(&'a mhi_net::Consistency, Option<&'a Model>),
}

impl Blender<'_> {
    /// Whether the blend needs every multi-normal image (so the plan leaves no normal out).
    fn needs_every_normal(&self) -> bool {
        !matches!(self, Blender::Model(None))
    }

    fn view(
        &self,
        mhi: &mhi_render::Mhi,
        cam: &Camera,
        prune: Prune,
    ) -> anyhow::Result<(image::Rgb32FImage, mhi_render::RenderStats)> {
        match self {
            Blender::Model(m) => view(mhi, *m, cam, prune),
            Blender::Consistent(c, m) => {
                let v = c.render_with(mhi, *m, cam, prune)?;
                Ok((v.image, v.stats))
            }
        }
    }
}

/// `cargo xtask render`.
pub fn render(a: &RenderArgs) -> anyhow::Result<()> {
    run(a, a.export.as_deref(), true)
}

/// `cargo xtask export`: the viewer folder in --out (or --export), no rendered views.
pub fn export(a: &RenderArgs) -> anyhow::Result<()> {
    run(a, Some(a.export.as_deref().unwrap_or(&a.out)), false)
}

/// The most camera rows an exported viewer lists (each is a camera in its manifest).
const MAX_VIEWER_VIEWS: usize = 10_000;

/// Check the options against the camera file before anything is loaded or written.
fn check_args(a: &RenderArgs, file: &CameraFile, views_too: bool) -> anyhow::Result<()> {
    let rows = file.rows.len();
    let cameras = a.cameras.as_deref().map_or_else(
        || "the estimated poses".to_string(),
        |p| p.display().to_string(),
    );
    for (what, r) in [("--ref-row", a.ref_row), ("--src-row", a.src_row)] {
        if r == 0 || r > rows {
            bail!("{what} {r}: {cameras} has camera rows 1 to {rows}");
        }
    }
    a.path.check()?;
    if a.sweep && a.blend == Some(BlendArg::Learned) {
        bail!("--blend learned needs a trained model: the sweep (--sweep) has no blending network");
    }
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 240.0) {
        bail!(
            "--fps {} must be a number of frames per second in (0, 240]",
            a.fps
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
    if !(a.budget.is_finite() && a.budget >= 0.0 && a.budget <= 255.0) {
        bail!(
            "--budget {} must be a number of 8-bit levels in [0, 255] (1 by default)",
            a.budget
        );
    }
    if views_too && a.gif {
        crate::common::check_gif_frames("--frames with --gif", a.path.frames)?;
    }
    if let Some(v) = &a.video {
        check_video_file(v, &a.out, a.overwrite)?;
    }
    if a.export.is_some() || !views_too {
        let listed = rows - 2;
        if listed > MAX_VIEWER_VIEWS {
            bail!(
                "{cameras} lists {listed} views: an exported viewer lists at most {MAX_VIEWER_VIEWS} (each is a camera in its manifest); render the views without --export, or export with a shorter camera file"
            );
        }
    }
    if !a.sweep && a.grid.given() && (a.run.is_some() || crate::models::pretrained().is_some()) {
        bail!(
            "--normals, --planes, --near and --far set the training-free sweep's grid; a trained model (--run, or the pretrained one used without it) keeps its own: drop them, or pass --sweep"
        );
    }
    Ok(())
}

/// Refuse an output folder inside the other: each is swapped into place whole, and the outer
/// one's swap would take the inner one with it.
fn check_apart(views: &Path, viewer: &Path) -> anyhow::Result<()> {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (v, w) = (abs(views), abs(viewer));
    if v.starts_with(&w) || w.starts_with(&v) {
        bail!(
            "--out {} and --export {} lie one inside the other: give the viewer a folder of its own",
            views.display(),
            viewer.display()
        );
    }
    Ok(())
}

fn load_model(a: &RenderArgs) -> anyhow::Result<Option<Model>> {
    let run = match (&a.run, a.sweep) {
        (Some(r), _) => Some(r.clone()),
        (None, true) => None,
        (None, false) => {
            let p = crate::models::pretrained();
            match &p {
                Some(d) => println!(
                    "using the pretrained model {} (--run chooses another, --sweep the training-free sweep)",
                    d.display()
                ),
                None => println!(
                    "no pretrained model at {}; using the training-free sweep",
                    crate::models::pretrained_dir().display()
                ),
            }
            p
        }
    };
    run.map(|run| {
        Model::load(&run, Device::flex())
            .with_context(|| format!("loading the trained run {}", run.display()))
    })
    .transpose()
}

/// The working size: `--size`, or the reference photo's aspect with its longer side 256.
fn working_size(a: &RenderArgs, learned: Option<&Model>) -> anyhow::Result<(u32, u32)> {
    let (w, h) = mhi_data::read_rgb(&a.reference)?.dimensions();
    // A model's U-Nets need sides divisible by its multiple; the sweep by nothing (4 kept).
    let multiple = learned.map_or(4, |m| m.config().size_multiple().max(4) as u32);
    let size = a.size.unwrap_or_else(|| {
        let s = 256.0 / f64::from(w.max(h));
        let r =
            |x: u32| ((f64::from(x) * s / f64::from(multiple)).round() as u32).max(1) * multiple;
        (r(w), r(h))
    });
    if let Some(m) = learned {
        m.check_size(size.0, size.1)?;
    }
    let layers = match learned {
        Some(m) => m.normals().len() * m.depths().len() * 8,
        None => a.grid.normals * a.grid.planes,
    };
    crate::common::check_memory("--size", size.0, size.1, layers)?;
    Ok(size)
}

/// The photos' cameras (and any listed views): --cameras, else estimated from the photos.
fn camera_file(a: &RenderArgs) -> anyhow::Result<CameraFile> {
    Ok(match &a.cameras {
        Some(p) => CameraFile::read(p)?,
        None => {
            if (a.ref_row, a.src_row) != (1, 2) {
                bail!(
                    "--ref-row and --src-row name rows of a camera file: give --cameras, or leave them out to estimate the poses"
                );
            }
            crate::pose::estimate(&a.reference, &a.src, &a.intrinsics)?.1
        }
    })
}

/// The camera file's rows other than the photos', one camera at a time: a camera file of any
/// length costs one view.
fn listed_cameras<'a>(
    a: &'a RenderArgs,
    file: &'a CameraFile,
    (w, h): (u32, u32),
) -> impl Iterator<Item = anyhow::Result<(usize, Camera)>> + 'a {
    file.rows
        .iter()
        .enumerate()
        .filter(|(k, _)| *k + 1 != a.ref_row && *k + 1 != a.src_row)
        .map(move |(k, r)| {
            let cam = r
                .camera(w, h)
                .with_context(|| format!("camera row {}", k + 1))?;
            Ok((k + 1, cam))
        })
}

/// The scene plan over every view to render (listed and path cameras), and plan.json's bytes.
fn plan_views(
    a: &RenderArgs,
    mhi: &mhi_render::Mhi,
    blender: Blender<'_>,
    reference: &Camera,
    cams: impl Iterator<Item = anyhow::Result<Camera>>,
    count: usize,
    prune: Prune,
) -> anyhow::Result<(mhi_render::plan::ScenePlan, Vec<u8>)> {
    // What the views need: Soft weights for Soft; a learned or consistent blend comes after the
    // multi-normal images, so no normal is left out for it (Avg weights say so).
    let heuristic = if blender.needs_every_normal() && mhi.n() > 1 {
        BlendHeuristic::Avg
    } else {
        BlendHeuristic::Soft
    };
    let mut seen = mhi_render::plan::ViewsSeen::new(mhi, prune);
    let pb = crate::progress::bar(count as u64, "plan");
    for cam in cams {
        let cam = cam?;
        seen.add(
            &cam,
            &heuristic_weights_for(mhi.normals(), reference, &cam, heuristic),
        )?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    let plan = seen.finish(mhi)?;
    let plan_json = serde_json::to_vec_pretty(&serde_json::json!({
        "exact": a.exact,
        "blend": match (blender, heuristic) {
            (_, BlendHeuristic::Soft) => "Soft",
            (Blender::Consistent(_, None), _) => "consistent (no normal left out: its weights come after the multi-normal images)",
            _ => "learned (no normal left out: its weights come after the multi-normal images)",
        },
        "plan": plan,
    }))?;
    if a.explain {
        println!("{}", plan.explain());
    }
    Ok((plan, plan_json))
}

/// The two photos at the working size with their cameras, and their MHI (the trained model's, or
/// the sweep's), timed.
fn build_mhi(
    a: &RenderArgs,
    file: &CameraFile,
    size: (u32, u32),
    learned: Option<&Model>,
) -> anyhow::Result<(
    mhi_data::LoadedFrame,
    mhi_data::LoadedFrame,
    mhi_render::Mhi,
)> {
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
    let synth = ViewSynthesis::new(match learned {
        Some(m) => MhiSource::Learned(m),
        None => MhiSource::Sweep {
            normals: a.grid.normal_set()?,
            depths: a.grid.depths()?,
            config: SweepConfig::for_short_side(size.0.min(size.1)),
        },
    });
    let (mhi, _) = synth.mhi(&rf, &sf)?;
    println!(
        "MHI: {} normals x {} planes at {}x{} ({}) in {:.0} ms",
        mhi.n(),
        mhi.d(),
        size.0,
        size.1,
        if learned.is_some() {
            "trained stage 1"
        } else {
            "plane sweep"
        },
        t0.elapsed().as_secs_f64() * 1e3
    );
    Ok((rf, sf, mhi))
}

fn run(a: &RenderArgs, export: Option<&Path>, views_too: bool) -> anyhow::Result<()> {
    let file = camera_file(a)?;
    if let Some(w) = &file.rotation_warning {
        eprintln!("warning: {}", for_terminal(w));
    }
    check_args(a, &file, views_too)?;
    if let (true, Some(dir)) = (views_too, export) {
        check_apart(&a.out, dir)?;
    }
    // Claimed before any work: a second writer, or a folder of the user's, stops us here.
    let views_out = views_too
        .then(|| StagedDir::begin(&a.out, "render", a.overwrite))
        .transpose()?;
    let viewer_out = export
        .map(|d| StagedDir::begin(d, "viewer", a.overwrite))
        .transpose()?;
    for n in views_out.iter().chain(&viewer_out).flat_map(|s| s.notes()) {
        println!("note: {n}");
    }
    let learned = load_model(a)?;
    if learned.is_none() && a.blend == Some(BlendArg::Learned) {
        bail!(
            "--blend learned needs a trained model (--run, or the pretrained model in models/); the sweep has no blending network"
        );
    }
    let size = working_size(a, learned.as_ref())?;
    let (rf, sf, mhi) = build_mhi(a, &file, size, learned.as_ref())?;
    let model = learned.as_ref();
    let listed = || listed_cameras(a, &file, size);
    let listed_count = file.rows.len() - 2;
    let baseline = (rf.camera.center_in_world() - sf.camera.center_in_world()).length();
    let path = if views_too {
        // The listed rows as a path are held in memory only when they are asked for.
        let rows_as_path = if a.path.kind() == PathKind::File && a.path.path_file.is_none() {
            listed()
                .map(|r| r.map(|(_, c)| c))
                .collect::<anyhow::Result<Vec<_>>>()?
        } else {
            Vec::new()
        };
        crate::camera_path::plan(&a.path, &mhi, baseline, &rows_as_path)?
    } else {
        None
    };
    if let Some(p) = &path {
        println!("{}", p.summary);
    }
    let path_cams: &[Camera] = path.as_ref().map_or(&[], |p| &p.cameras);
    let prune = if a.exact {
        Prune::NONE
    } else {
        Prune::with_budget(a.budget / 255.0)
    };
    // The model blends only with --blend learned; its stage 1 made the MHI either way.
    // Without views (`export`) the default is the viewer's own blend, Soft: the plan may then
    // leave out the normals its cameras do not need.
    let blend = a.blend.unwrap_or(if views_too {
        BlendArg::Consistent
    } else {
        BlendArg::Soft
    });
    let network = model.filter(|_| blend == BlendArg::Learned);
    // A network that reads each normal's photo-inconsistency needs the same images.
    let reads_inc = network.and_then(Model::blend_consistency);
    let consistency = ((blend == BlendArg::Consistent || reads_inc.is_some()) && mhi.n() > 1)
        .then(|| {
            let beta = reads_inc.unwrap_or(mhi_net::CONSISTENCY_BETA);
            mhi_net::Consistency::new(&mhi, &rf, &sf, beta)
        })
        .transpose()?;
    let blender = match &consistency {
        Some(c) => Blender::Consistent(c, network),
        None => Blender::Model(network),
    };
    let (plan, plan_json) = plan_views(
        a,
        &mhi,
        blender,
        &rf.camera,
        listed()
            .map(|r| r.map(|(_, c)| c))
            .chain(path_cams.iter().cloned().map(Ok)),
        listed_count + path_cams.len(),
        prune,
    )?;
    let mut worst_bound = 0.0_f32;
    let mut video = None;
    if let Some(out) = &views_out {
        mhi_data::write_atomic(&out.path().join("plan.json"), &plan_json)?;
        let pb = crate::progress::bar(listed_count as u64, "views");
        for r in listed() {
            let (row, cam) = r?;
            let (img, stats) = blender.view(&mhi, &cam, prune)?;
            worst_bound = worst_bound.max(stats.bound);
            let path = out.path().join(format!("view_row{row:03}.png"));
            mhi_data::write_png(&path, &mhi_data::to_u8(&clipped(&img)))?;
            pb.inc(1);
        }
        pb.finish_and_clear();
        if !path_cams.is_empty() {
            let (v, bound) = path_video(a, &mhi, blender, path_cams, prune, out.path())?;
            worst_bound = worst_bound.max(bound);
            video = Some(v);
        }
    }
    if let Some(out) = &viewer_out {
        let cams: Vec<(usize, Camera)> = listed().collect::<anyhow::Result<_>>()?;
        let plan_json = (!views_too).then_some(&plan_json[..]);
        write_viewer_out(
            out.path(),
            &mhi,
            &plan,
            model.is_some(),
            (&rf.camera, &sf.camera),
            &cams,
            plan_json,
            video.as_ref(),
        )?;
    }
    if let Some(out) = viewer_out {
        let dir = out.commit()?;
        println!(
            "viewer: {} (open it in a browser; {} of {} layers kept)",
            dir.join("index.html").display(),
            plan.layers_kept,
            mhi.n() * mhi.d()
        );
    }
    if let Some(out) = views_out {
        let dir = out.commit()?;
        report_views(a, &dir, listed_count, video.as_ref(), worst_bound)?;
    }
    Ok(())
}

/// The viewer folder: the MHI's layers, the photos' and listed cameras, the video when there is
/// one, and plan.json when no views folder holds it.
#[allow(clippy::too_many_arguments)]
fn write_viewer_out(
    dir: &Path,
    mhi: &mhi_render::Mhi,
    plan: &mhi_render::plan::ScenePlan,
    learned: bool,
    (reference, source): (&Camera, &Camera),
    cams: &[(usize, Camera)],
    plan_json: Option<&[u8]>,
    video: Option<&mhi_video::Video>,
) -> anyhow::Result<()> {
    let inputs = [("reference photo", reference), ("source photo", source)];
    let names: Vec<_> = cams
        .iter()
        .map(|(row, c)| (format!("camera row {row}"), c))
        .collect();
    let source = if learned {
        "trained stage 1 (the viewer blends with Soft: the blending network does not run in the browser)"
    } else {
        "training-free plane sweep"
    };
    if let Some(bytes) = plan_json {
        mhi_data::write_atomic(&dir.join("plan.json"), bytes)?;
    }
    mhi_viewer::write_viewer(
        dir,
        mhi,
        plan,
        source,
        &inputs,
        &names,
        video.map(|v| &v.bytes[..]),
    )?;
    Ok(())
}

/// Put a --video file in place and say what was written where, with the bound the render kept.
fn report_views(
    a: &RenderArgs,
    dir: &Path,
    listed_count: usize,
    video: Option<&mhi_video::Video>,
    worst_bound: f32,
) -> anyhow::Result<()> {
    let video_at = match (video, &a.video) {
        (None, _) => None,
        (Some(v), Some(file)) => {
            mhi_data::write_atomic(file, &v.bytes)?;
            Some(file.clone())
        }
        (Some(_), None) => Some(dir.join(VIDEO_FILE)),
    };
    println!(
        "{listed_count} view(s){} in {}; {}",
        match &video_at {
            Some(f) => format!(" and the path's video {}", f.display()),
            None => String::new(),
        },
        dir.display(),
        if a.exact {
            "rendered exactly (--exact)".to_string()
        } else {
            format!(
                "no pixel moved by more than {:.2} 8-bit levels from what was left out (budget {}; --exact renders everything, --explain says what was left out)",
                worst_bound * 255.0,
                a.budget
            )
        }
    );
    Ok(())
}

/// The video's file name in --out.
pub const VIDEO_FILE: &str = "video.mp4";

/// Refuse a --video file that is not ours to write: inside --out (swapped away with it), or an
/// existing file without --overwrite, or one this tool did not write.
fn check_video_file(file: &Path, out: &Path, overwrite: bool) -> anyhow::Result<()> {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    if abs(file).starts_with(abs(out)) {
        bail!(
            "--video {} lies inside --out {}: the video is written there as {VIDEO_FILE} without --video",
            file.display(),
            out.display()
        );
    }
    if file.extension().and_then(|e| e.to_str()) != Some("mp4") {
        bail!("--video {}: the file name must end in .mp4", file.display());
    }
    match std::fs::symlink_metadata(file) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("--video {}", file.display())),
        Ok(_) if !overwrite => bail!(
            "--video {} exists: pass --overwrite to replace it (only a video this tool wrote is replaced)",
            file.display()
        ),
        Ok(m) if !m.is_file() => bail!(
            "--video {} is not a regular file; it is left alone",
            file.display()
        ),
        Ok(_) => {
            use std::io::Read;
            let mut head = Vec::new();
            std::fs::File::open(file)
                .and_then(|f| f.take(1 << 20).read_to_end(&mut head))
                .with_context(|| format!("reading --video {}", file.display()))?;
            let ours = head.get(4..8) == Some(b"ftyp")
                && head
                    .windows(mhi_video::TITLE.len())
                    .any(|w| w == mhi_video::TITLE.as_bytes());
            if !ours {
                bail!(
                    "--video {} is not a video this tool wrote; it is left alone even with --overwrite",
                    file.display()
                );
            }
            Ok(())
        }
    }
}

/// Render the path's cameras into an H.264 MP4 (and path.gif with --gif, in `dir`), printing
/// the frame rates of rendering and encoding. Returns the video and the worst pruning bound.
fn path_video(
    a: &RenderArgs,
    mhi: &mhi_render::Mhi,
    blender: Blender<'_>,
    cams: &[Camera],
    prune: Prune,
    dir: &Path,
) -> anyhow::Result<(mhi_video::Video, f32)> {
    let (w, h) = (mhi.reference().width, mhi.reference().height);
    let mut enc = mhi_video::Mp4Encoder::new(w, h, a.fps)?;
    let mut gif = Vec::new();
    let (mut t_render, mut t_encode, mut bound) = (0.0_f64, 0.0_f64, 0.0_f32);
    let pb = crate::progress::bar(cams.len() as u64, "video");
    for cam in cams {
        let t0 = Instant::now();
        let (img, stats) = blender.view(mhi, cam, prune)?;
        let rgb = mhi_data::to_u8(&clipped(&img));
        t_render += t0.elapsed().as_secs_f64();
        bound = bound.max(stats.bound);
        let t1 = Instant::now();
        enc.push(&rgb)?;
        t_encode += t1.elapsed().as_secs_f64();
        if a.gif {
            gif.push(enlarge(&rgb, factor_for(w, 256)));
        }
        pb.inc(1);
    }
    let t1 = Instant::now();
    let video = enc.finish()?;
    t_encode += t1.elapsed().as_secs_f64();
    pb.finish_and_clear();
    if a.video.is_none() {
        mhi_data::write_atomic(&dir.join(VIDEO_FILE), &video.bytes)?;
    }
    if a.gif {
        write_gif(&dir.join("path.gif"), &gif, (1000.0 / a.fps).round() as u32)?;
    }
    let n = cams.len() as f64;
    println!(
        "video: {} frames {w}x{h} at {} fps ({:.1} s, {:.0} kB, {:.0} kB/s); render {:.1} frames/s, encode {:.0} frames/s (render and encode {:.1} frames/s)",
        video.frames,
        a.fps,
        video.seconds(),
        video.bytes.len() as f64 / 1e3,
        video.bytes.len() as f64 / 1e3 / video.seconds(),
        n / t_render.max(1e-9),
        n / t_encode.max(1e-9),
        n / (t_render + t_encode).max(1e-9)
    );
    Ok((video, bound))
}
