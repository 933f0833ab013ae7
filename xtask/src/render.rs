//! `cargo xtask render`: novel views of a user's own two photos. The camera file (RealEstate10K
//! format) holds the reference photo's camera on its first row, the source photo's on its second,
//! and the cameras of the views to render on any further rows; an orbit GIF around the reference
//! view is written too. The MHI comes from a trained run (`--run`) or the training-free sweep.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use burn::tensor::Device;
use clap::Args;
use mhi_data::{CameraFile, Fit, Frame, load_frame};
use mhi_geom::{BlendHeuristic, Camera};
use mhi_net::{MhiSource, Model, ViewSynthesis};
use mhi_render::{Prune, SweepConfig, heuristic_weights_for};

use crate::views::{clipped, enlarge, factor_for, orbit, view, write_gif};

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
    /// A trained run (its latest checkpoint): stage 1 and the learned blend. Default: the
    /// pretrained model in `models/` (see its MODEL.md), or the sweep when there is none.
    #[arg(long, conflicts_with = "sweep")]
    pub run: Option<PathBuf>,
    /// Use the training-free plane-sweep MHI with Soft blending (--normals, --planes, --near,
    /// --far) instead of a trained model.
    #[arg(long)]
    pub sweep: bool,
    /// Working size WIDTHxHEIGHT (photos are resized, intrinsics follow; multiples of 4 for a
    /// run). Default: the reference photo's aspect with its longer side 256 (multiples of 4).
    #[arg(long, value_parser = crate::common::parse_size)]
    pub size: Option<(u32, u32)>,
    /// The sweep MHI's grid (with --sweep or without a model; a trained model keeps its own).
    #[command(flatten)]
    pub grid: crate::common::PlaneArgs,
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

/// `cargo xtask render`.
pub fn render(a: &RenderArgs) -> anyhow::Result<()> {
    run(a, a.export.as_deref(), true)
}

/// `cargo xtask export`: the viewer folder in --out (or --export), no rendered views.
pub fn export(a: &RenderArgs) -> anyhow::Result<()> {
    run(a, Some(a.export.as_deref().unwrap_or(&a.out)), false)
}

fn run(a: &RenderArgs, export: Option<&std::path::Path>, views_too: bool) -> anyhow::Result<()> {
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
    let taken = views_too
        && std::fs::read_dir(&a.out).is_ok_and(|d| {
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
    if let Some(dir) = export
        && dir.join("index.html").exists()
        && !a.overwrite
    {
        bail!(
            "{} already holds an exported viewer; pass --overwrite to replace it or choose another folder",
            dir.display()
        );
    }
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
    let learned: Option<Model> = match &run {
        Some(run) => Some(
            Model::load(run, Device::flex())
                .with_context(|| format!("loading the trained run {}", run.display()))?,
        ),
        None => None,
    };
    let ref_rgb = mhi_data::read_rgb(&a.reference)?;
    // A model's U-Nets need sides divisible by its multiple; the sweep by nothing (4 kept).
    let multiple = learned
        .as_ref()
        .map_or(4, |m| m.config().size_multiple().max(4) as u32);
    let size = a.size.unwrap_or_else(|| {
        let (w, h) = ref_rgb.dimensions();
        let s = 256.0 / f64::from(w.max(h));
        let r =
            |x: u32| ((f64::from(x) * s / f64::from(multiple)).round() as u32).max(1) * multiple;
        (r(w), r(h))
    });
    if let Some(m) = &learned {
        m.check_size(size.0, size.1)?;
    }
    let layers = match &learned {
        Some(m) => m.normals().len() * m.depths().len() * 8,
        None => a.grid.normals * a.grid.planes,
    };
    crate::common::check_memory("--size", size.0, size.1, layers)?;
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
    let synth = ViewSynthesis::new(match &learned {
        Some(m) => MhiSource::Learned(m),
        None => MhiSource::Sweep {
            normals: a.grid.normal_set()?,
            depths: a.grid.depths()?,
            config: SweepConfig::for_short_side(size.0.min(size.1)),
        },
    });
    let (mhi, _) = synth.mhi(&rf, &sf)?;
    let model = synth.model();
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
    let out = if views_too {
        a.out.clone()
    } else {
        export.unwrap_or(&a.out).to_path_buf()
    };
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
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
    let baseline = (rf.camera.center_in_world() - sf.camera.center_in_world()).length();
    let orbit_cams = if a.orbit_frames > 0 && views_too {
        let look_at = crate::views::median_depth(&mhi);
        let (cams, deg) = orbit(
            &rf.camera,
            a.orbit_radius * baseline,
            a.orbit_frames,
            look_at,
        )?;
        match look_at {
            Some(z) => println!(
                "orbit: {} cameras on a circle of radius {:.3}, turned toward the median depth {z:.3} (rotation up to {deg:.1} deg)",
                cams.len(),
                a.orbit_radius * baseline
            ),
            None => println!(
                "orbit: nothing in front of the far plane; the cameras translate without turning"
            ),
        }
        cams
    } else {
        Vec::new()
    };
    if !(a.budget.is_finite() && a.budget >= 0.0 && a.budget <= 255.0) {
        bail!(
            "--budget {} must be a number of 8-bit levels in [0, 255] (1 by default)",
            a.budget
        );
    }
    let prune = if a.exact {
        Prune::NONE
    } else {
        Prune::with_budget(a.budget / 255.0)
    };
    // What the views need: Soft weights for the sweep; a learned blend comes after the
    // multi-normal images, so no normal is left out for it (Avg weights say so).
    let heuristic = match model {
        Some(_) if mhi.n() > 1 => BlendHeuristic::Avg,
        _ => BlendHeuristic::Soft,
    };
    let all_cams: Vec<&Camera> = targets.iter().map(|(_, c)| c).chain(&orbit_cams).collect();
    let weights: Vec<Vec<f32>> = all_cams
        .iter()
        .map(|c| heuristic_weights_for(mhi.normals(), &rf.camera, c, heuristic))
        .collect();
    let views: Vec<(&Camera, &[f32])> = all_cams
        .iter()
        .zip(&weights)
        .map(|(c, w)| (*c, w.as_slice()))
        .collect();
    let plan = mhi_render::plan::analyse(&mhi, &views, prune)?;
    mhi_data::write_atomic(
        &out.join("plan.json"),
        &serde_json::to_vec_pretty(&serde_json::json!({
            "exact": a.exact,
            "blend": if heuristic == BlendHeuristic::Avg { "learned (no normal left out: its weights come after the multi-normal images)" } else { "Soft" },
            "plan": plan,
        }))?,
    )?;
    if a.explain {
        println!("{}", plan.explain());
    }
    if let Some(dir) = export {
        let inputs = [
            ("reference photo", &rf.camera),
            ("source photo", &sf.camera),
        ];
        let listed: Vec<_> = targets
            .iter()
            .map(|(row, c)| (format!("camera row {row}"), c))
            .collect();
        let source = if model.is_some() {
            "trained stage 1 (the viewer blends with Soft: the blending network does not run in the browser)"
        } else {
            "training-free plane sweep"
        };
        crate::export::write_viewer(dir, &mhi, &plan, source, &inputs, &listed)?;
        println!(
            "viewer: {} (open it in a browser; {} of {} layers kept)",
            dir.join("index.html").display(),
            plan.layers_kept,
            mhi.n() * mhi.d()
        );
    }
    if !views_too {
        return Ok(());
    }
    let pb = crate::progress::bar((targets.len() + a.orbit_frames) as u64, "render");
    let mut worst_bound = 0.0_f32;
    for (row, cam) in &targets {
        let (img, stats) = view(&mhi, model, cam, prune)?;
        worst_bound = worst_bound.max(stats.bound);
        let path = a.out.join(format!("view_row{row:03}.png"));
        mhi_data::write_png(&path, &mhi_data::to_u8(&clipped(&img)))?;
        pb.inc(1);
    }
    if a.orbit_frames > 0 {
        let mut frames = Vec::new();
        for cam in &orbit_cams {
            let (img, stats) = view(&mhi, model, cam, prune)?;
            worst_bound = worst_bound.max(stats.bound);
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
        "{} view(s){} in {}; {}",
        targets.len(),
        if a.orbit_frames > 0 {
            " and orbit.gif"
        } else {
            ""
        },
        a.out.display(),
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
