//! `cargo xtask export` (and `render --export`): an MHI as a self-contained folder that a
//! browser opens without a build step or network — the reference colour once (reference.png),
//! each normal's kept alpha layers tiled in one PNG atlas (`alpha_normal_<i>.png`), a manifest
//! (manifest.json: normals, depths, kept layers and their tiles, cameras, blend, plan), the same
//! data in data.js for the page, and index.html: a WebGL2 viewer that composites each normal's
//! planes back to front and blends the multi-normal images with the Soft weights, as the CPU
//! renderer does.

use std::path::Path;

use anyhow::{Context, bail};
use base64::Engine as _;
use mhi_geom::Camera;
use mhi_render::plan::ScenePlan;
use mhi_render::{LayerColor, Mhi};
use serde::Serialize;

/// The viewer page (no external scripts; it reads data.js beside it).
pub const VIEWER_HTML: &str = include_str!("../assets/viewer.html");

/// A camera as the viewer reads it: intrinsics in pixels of the exported size and the
/// world-to-camera pose, rotation row-major then translation.
#[derive(Debug, Clone, Serialize)]
pub struct ViewerCamera {
    /// What it is (an input photo or a listed view).
    pub name: String,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// `[R (row-major, 9), t (3)]`, `X_cam = R X_world + t`.
    pub cam_from_world: [f64; 12],
}

impl ViewerCamera {
    /// The camera `cam` under `name`.
    pub fn new(name: &str, cam: &Camera) -> Self {
        let r = cam.cam_from_world.rotation();
        let t = cam.cam_from_world.translation();
        let mut m = [0.0; 12];
        for i in 0..3 {
            let row = r.row(i);
            m[3 * i] = row.x;
            m[3 * i + 1] = row.y;
            m[3 * i + 2] = row.z;
        }
        m[9] = t.x;
        m[10] = t.y;
        m[11] = t.z;
        Self {
            name: name.into(),
            fx: cam.intrinsics.fx,
            fy: cam.intrinsics.fy,
            cx: cam.intrinsics.cx,
            cy: cam.intrinsics.cy,
            cam_from_world: m,
        }
    }
}

#[derive(Serialize)]
struct Layer {
    normal: usize,
    depth_index: usize,
    depth: f64,
    tile_x: usize,
    tile_y: usize,
}

#[derive(Serialize)]
struct Atlas {
    file: String,
    cols: usize,
    rows: usize,
}

#[derive(Serialize)]
struct Manifest<'a> {
    format: &'static str,
    source: &'a str,
    width: u32,
    height: u32,
    blend: &'static str,
    reference: ViewerCamera,
    normals: Vec<[f64; 3]>,
    depths: &'a [f64],
    layers: Vec<Layer>,
    atlases: Vec<Atlas>,
    colour: &'static str,
    baseline: f64,
    inputs: &'a [ViewerCamera],
    views: &'a [ViewerCamera],
    path: Vec<&'a ViewerCamera>,
    plan: &'a ScenePlan,
}

/// Write the viewer folder for `mhi` into `dir` (created if needed; files written atomically).
/// Layers the plan leaves out are not written; a normal the plan drops keeps its farthest layer
/// only (its blend weight is within the budget everywhere). `inputs` are the photos' cameras,
/// `views` the listed target cameras (`#view=k` in the page's address shows the k-th), each
/// with its name.
pub fn write_viewer(
    dir: &Path,
    mhi: &Mhi,
    plan: &ScenePlan,
    source: &str,
    inputs: &[(&str, &Camera)],
    views: &[(String, &Camera)],
) -> anyhow::Result<()> {
    let LayerColor::Shared(colour) = mhi.color() else {
        bail!("only MHIs whose layers share the reference colour can be exported");
    };
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let (w, h) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    let rgb = mhi_data::to_u8(colour);
    let mut layers = Vec::new();
    let mut atlases = Vec::new();
    let mut atlas_bytes = Vec::new();
    for i in 0..mhi.n() {
        let kept: Vec<usize> = match plan.per_normal.get(i) {
            Some(u) if !u.dropped && !u.kept_depths.is_empty() => u.kept_depths.clone(),
            _ => vec![0],
        };
        let cols = (kept.len() as f64).sqrt().ceil().max(1.0) as usize;
        let rows = kept.len().div_ceil(cols);
        let aw = cols * w;
        let mut a = vec![0_u8; aw * rows * h];
        for (m, &j) in kept.iter().enumerate() {
            let (tx, ty) = (m % cols, m / cols);
            let src = mhi.alpha_layer(i, j);
            for y in 0..h {
                let row = &mut a[(ty * h + y) * aw + tx * w..][..w];
                for (o, v) in row.iter_mut().zip(&src[y * w..(y + 1) * w]) {
                    *o = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
                }
            }
            layers.push(Layer {
                normal: i,
                depth_index: j,
                depth: mhi.depths()[j],
                tile_x: tx,
                tile_y: ty,
            });
        }
        let file = format!("alpha_normal_{i}.png");
        let img =
            image::GrayImage::from_raw(aw as u32, (rows * h) as u32, a).context("atlas size")?;
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)?;
        mhi_data::write_atomic(&dir.join(&file), &png)?;
        atlas_bytes.push(img.into_raw());
        atlases.push(Atlas { file, cols, rows });
    }
    mhi_data::write_png(&dir.join("reference.png"), &rgb)?;
    let baseline = match inputs {
        [(_, a), (_, b), ..] => (a.center_in_world() - b.center_in_world()).length(),
        _ => 1.0,
    };
    let inputs: Vec<ViewerCamera> = inputs
        .iter()
        .map(|(n, c)| ViewerCamera::new(n, c))
        .collect();
    let views: Vec<ViewerCamera> = views.iter().map(|(n, c)| ViewerCamera::new(n, c)).collect();
    let manifest = Manifest {
        format: "mhi-viewer-1",
        source,
        width: w as u32,
        height: h as u32,
        blend: "soft",
        reference: ViewerCamera::new("reference", mhi.reference()),
        normals: mhi
            .normals()
            .normals()
            .iter()
            .map(|n| [n.x, n.y, n.z])
            .collect(),
        depths: mhi.depths(),
        layers,
        atlases,
        colour: "reference.png",
        baseline,
        inputs: &inputs,
        views: &views,
        path: inputs.iter().chain(&views).collect(),
        plan,
    };
    let manifest_json = serde_json::to_string_pretty(&manifest)?;
    mhi_data::write_atomic(&dir.join("manifest.json"), manifest_json.as_bytes())?;
    let b64 = |v: &[u8]| base64::engine::general_purpose::STANDARD.encode(v);
    let alphas: Vec<String> = atlas_bytes.iter().map(|a| b64(a)).collect();
    let data = format!(
        "// Written by `cargo xtask export`: the manifest and the layers as raw bytes for index.html.\nwindow.MHI_DATA = {};\n",
        serde_json::json!({ "manifest": manifest, "colour": b64(rgb.as_raw()), "alphas": alphas })
    );
    mhi_data::write_atomic(&dir.join("data.js"), data.as_bytes())?;
    mhi_data::write_atomic(&dir.join("index.html"), VIEWER_HTML.as_bytes())?;
    Ok(())
}
