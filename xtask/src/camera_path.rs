//! The camera path of `render`'s video (`--path`): cameras around the reference photo laid out
//! by `mhi_geom::path`, sized from the scene (the baseline between the photos, the MHI's depths),
//! checked against the MHI's planes by `mhi_render::plan::check_path`.

use std::path::PathBuf;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use mhi_data::CameraFile;
use mhi_geom::Camera;
use mhi_geom::path::{self, PathRange};
use mhi_render::Mhi;

/// The most frames a path may have: 5.5 minutes at 30 frames per second.
pub const MAX_PATH_FRAMES: usize = 10_000;

/// The path's shape.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathKind {
    /// A circle around the reference camera in its image plane, every camera turned toward the
    /// MHI's median depth (radius: --radius, default --orbit-radius times the baseline).
    Orbit,
    /// The paper's circular light field: cameras on a circle through the reference, centred
    /// --radius ahead of it (default the MHI's median depth), each looking at the centre,
    /// stepping --step degrees a frame out to one side, back past the reference to the other,
    /// and home.
    Circle,
    /// LLFF's forward-facing spiral: two turns of radius --radius (default --orbit-radius times
    /// the baseline), moving in and out by half of it, looking at LLFF's focus depth.
    Spiral,
    /// In and out along the reference's optical axis by --radius (default --orbit-radius times
    /// the baseline, at most 40 % of the way to the nearest content), without turning.
    Dolly,
    /// The rows of a camera file (--path-file, or the listed rows of --cameras), in the frame of
    /// the photos' cameras.
    File,
}

/// Options of the camera path.
#[derive(Args, Debug, Clone)]
pub struct PathArgs {
    /// The camera path of the video: orbit (the default), circle, spiral, dolly or file (see
    /// --help).
    #[arg(long, value_enum)]
    pub path: Option<PathKind>,
    /// Frames on the path (0 without --path: no video; --path file takes every row of its file).
    #[arg(long, alias = "orbit-frames", default_value_t = 60)]
    pub frames: usize,
    /// The path's size in the scene's units (those of the camera file; with estimated poses the
    /// nearest content sits at depth 1.25): the radius of the orbit, spiral or circle, the
    /// dolly's travel. Default: see each path.
    #[arg(long, allow_hyphen_values = true)]
    pub radius: Option<f64>,
    /// The default radius of the orbit, spiral and dolly, as a fraction of the distance between
    /// the two photos' cameras.
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    pub orbit_radius: f64,
    /// The circle's step, in degrees a frame (the paper's circular light field steps 2°).
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub step: f64,
    /// Camera file (RealEstate10K format) whose rows are the path, for --path file.
    #[arg(long)]
    pub path_file: Option<PathBuf>,
}

impl PathArgs {
    /// The path asked for (the orbit by default).
    pub fn kind(&self) -> PathKind {
        self.path.unwrap_or(PathKind::Orbit)
    }

    /// Check what can be checked before anything is loaded.
    pub fn check(&self) -> anyhow::Result<()> {
        if self.frames > MAX_PATH_FRAMES {
            bail!(
                "--frames {}: at most {MAX_PATH_FRAMES} ({:.1} minutes at 30 frames a second); every frame is a render",
                self.frames,
                MAX_PATH_FRAMES as f64 / 30.0 / 60.0
            );
        }
        if !(self.orbit_radius.is_finite() && self.orbit_radius > 0.0 && self.orbit_radius <= 10.0)
        {
            bail!(
                "--orbit-radius {} must be a number in (0, 10]: it is a fraction of the distance between the two photos' cameras (0.5 by default); farther, the path leaves what the photos saw",
                self.orbit_radius
            );
        }
        if let Some(r) = self.radius
            && !(r.is_finite() && r > 0.0)
        {
            bail!("--radius {r} must be a finite length above zero, in the scene's units");
        }
        if let Some(p) = self.path
            && self.frames == 0
            && p != PathKind::File
        {
            bail!(
                "--path {} with --frames 0: zero frames make no path (leave --path out for no video)",
                format!("{p:?}").to_lowercase()
            );
        }
        if self.path_file.is_some() && self.kind() != PathKind::File {
            bail!("--path-file gives the cameras of --path file: add --path file");
        }
        Ok(())
    }
}

/// A path's cameras and a line saying what they are.
pub struct Planned {
    /// The cameras, in order.
    pub cameras: Vec<Camera>,
    /// What the path is, its size and reach, for the terminal.
    pub summary: String,
}

/// Lay out the path around `reference` (the MHI's), sized from the baseline between the photos
/// and the MHI's depths, and check it against the MHI's planes. `listed` are the rows of the
/// camera file besides the photos' (for `--path file` without `--path-file`).
pub fn plan(
    a: &PathArgs,
    mhi: &Mhi,
    baseline: f64,
    listed: &[Camera],
) -> anyhow::Result<Option<Planned>> {
    if a.frames == 0 && a.kind() != PathKind::File {
        return Ok(None);
    }
    let reference = mhi.reference();
    let from_baseline = a.orbit_radius * baseline;
    let median = crate::views::median_depth(mhi);
    let near = mhi.depths().iter().copied().fold(f64::INFINITY, f64::min);
    let far = mhi.depths().iter().copied().fold(0.0, f64::max);
    let radius = |default: f64| a.radius.unwrap_or(default);
    let (cameras, what) = match a.kind() {
        PathKind::Orbit => {
            let r = radius(from_baseline);
            let cams = path::orbit(reference, r, a.frames, median)?;
            (
                cams,
                match median {
                    Some(z) => {
                        format!("orbit of radius {r:.3}, turned toward the median depth {z:.3}")
                    }
                    None => format!(
                        "orbit of radius {r:.3} (nothing in front of the far plane: the cameras translate without turning)"
                    ),
                },
            )
        }
        PathKind::Circle => {
            let r = radius(median.unwrap_or(near));
            let cams = path::circle(reference, r, a.step, a.frames)?;
            (
                cams,
                format!(
                    "circle of radius {r:.3} centred {r:.3} ahead, {}° a frame out to ±{:.1}°",
                    a.step,
                    path::circle_max_deg(a.step, a.frames)
                ),
            )
        }
        PathKind::Spiral => {
            let r = radius(from_baseline);
            let focus = path::llff_focus(near, far)?;
            let cams = path::spiral(reference, r, a.frames, focus, 2.0)?;
            (
                cams,
                format!("spiral of radius {r:.3}, two turns, looking at depth {focus:.3}"),
            )
        }
        PathKind::Dolly => {
            let nearest = nearest_content(mhi).unwrap_or(near);
            let r = radius(from_baseline.min(0.4 * nearest));
            (
                path::dolly(reference, r, a.frames)?,
                format!(
                    "dolly in and out by {r:.3} (the nearest content is at depth {nearest:.3})"
                ),
            )
        }
        PathKind::File => match &a.path_file {
            Some(f) => {
                let file = CameraFile::read(f)?;
                let (w, h) = (reference.width, reference.height);
                let cams = file
                    .rows
                    .iter()
                    .enumerate()
                    .map(|(k, r)| {
                        r.camera(w, h)
                            .with_context(|| format!("{} row {}", f.display(), k + 1))
                    })
                    .collect::<anyhow::Result<Vec<_>>>()?;
                (
                    cams,
                    format!("the {} rows of {}", file.rows.len(), f.display()),
                )
            }
            None if listed.is_empty() => bail!(
                "--path file needs cameras: give --path-file, or a --cameras file with rows besides the two photos'"
            ),
            None => (
                listed.to_vec(),
                format!("the {} listed rows of the camera file", listed.len()),
            ),
        },
    };
    if cameras.len() > MAX_PATH_FRAMES {
        bail!(
            "the path has {} cameras: at most {MAX_PATH_FRAMES}",
            cameras.len()
        );
    }
    let clearance = mhi_render::plan::check_path(mhi, &cameras)
        .with_context(|| format!("the {:?} path", a.kind()).to_lowercase())?;
    let range = PathRange::of(reference, &cameras);
    let mut summary = format!("path: {what}; {range}");
    if let Some(c) = clearance {
        summary += &format!(
            "; every camera keeps at least {:.0} % of the way to each plane that holds something",
            100.0 * c.min_relative
        );
    }
    Ok(Some(Planned { cameras, summary }))
}

/// The depth, along the reference's optical axis, of the nearest fronto-parallel-most layer that
/// holds something (largest alpha above 1/255).
fn nearest_content(mhi: &Mhi) -> Option<f64> {
    let i = crate::views::fronto_normal(mhi)?;
    (0..mhi.d())
        .filter(|&j| mhi.layer_max_alpha(i, j) > 1.0 / 255.0)
        .map(|j| mhi.depths()[j])
        .min_by(f64::total_cmp)
}
