//! An MHI as a self-contained folder that a
//! browser opens without a build step or network — the reference colour once (reference.png)
//! when the layers share it, each normal's kept alpha layers tiled in one PNG atlas
//! (`alpha_normal_<i>.png`) and, when every layer has a colour of its own (a model with a
//! colour head), their colours tiled the same way (`colour_normal_<i>.png`), a manifest
//! (manifest.json: normals, depths, kept layers and their tiles, cameras, blend, plan), the same
//! data in data.js for the page, and index.html: a WebGL2 viewer that composites each normal's
//! planes back to front and blends the multi-normal images with the Soft weights, as the CPU
//! renderer does.

use std::path::Path;

use base64::Engine as _;
use mhi_geom::Camera;
use mhi_render::plan::ScenePlan;
use mhi_render::{LayerColor, Mhi};
use serde::Serialize;

/// The viewer page (no external scripts; it reads data.js beside it).
pub const VIEWER_HTML: &str = include_str!("../assets/viewer.html");
/// The viewer's script (a file of its own, so that the page's Content-Security-Policy can
/// forbid inline scripts).
pub const VIEWER_JS: &str = include_str!("../assets/viewer.js");

/// A camera as the viewer reads it: intrinsics in pixels of the exported size and the
/// world-to-camera pose, rotation row-major then translation.
#[derive(Debug, Clone, Serialize)]
pub struct ViewerCamera {
    /// What it is (an input photo or a listed view).
    pub name: String,
    /// Focal length along x, in pixels.
    pub fx: f64,
    /// Focal length along y, in pixels.
    pub fy: f64,
    /// Principal point, x, in pixels.
    pub cx: f64,
    /// Principal point, y, in pixels.
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
    /// The kept layers' own colours, tiled as the alphas (per-layer colour only).
    #[serde(skip_serializing_if = "Option::is_none")]
    colour_file: Option<String>,
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
    /// The video beside the interactive view (`video.mp4`), when one was rendered.
    video: Option<&'static str>,
}

/// One normal's atlas as written: the layers' places, the atlas, its alpha bytes and its colour
/// bytes (per-layer colour only).
type AtlasOut = (Vec<Layer>, Atlas, Vec<u8>, Option<Vec<u8>>);

/// One normal's atlas: its kept layers' alphas tiled into `alpha_normal_I.png` (and, for
/// per-layer colour, `colour_normal_I.png`) in `dir`; returns the layers' places, the atlas, and
/// the raw bytes of both images for data.js.
fn write_atlas(
    dir: &Path,
    mhi: &Mhi,
    plan: &ScenePlan,
    i: usize,
    per_layer: Option<&Vec<image::Rgb32FImage>>,
) -> Result<AtlasOut> {
    let (w, h) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    let mut layers = Vec::new();
    let mut colour_bytes = None;
    let kept: Vec<usize> = match plan.per_normal.get(i) {
        Some(u) if !u.dropped && !u.kept_depths.is_empty() => u.kept_depths.clone(),
        _ => vec![0],
    };
    let cols = (kept.len() as f64).sqrt().ceil().max(1.0) as usize;
    let rows = kept.len().div_ceil(cols);
    let aw = cols * w;
    let mut a = vec![0_u8; aw * rows * h];
    let mut c = vec![
        0_u8;
        if per_layer.is_some() {
            3 * aw * rows * h
        } else {
            0
        }
    ];
    for (m, &j) in kept.iter().enumerate() {
        let (tx, ty) = (m % cols, m / cols);
        let src = mhi.alpha_layer(i, j);
        for y in 0..h {
            let row = &mut a[(ty * h + y) * aw + tx * w..][..w];
            for (o, v) in row.iter_mut().zip(&src[y * w..(y + 1) * w]) {
                *o = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
            }
        }
        if let Some(v) = per_layer {
            let src = mhi_data::to_u8(&v[i * mhi.d() + j]);
            for y in 0..h {
                let at = 3 * ((ty * h + y) * aw + tx * w);
                c[at..at + 3 * w].copy_from_slice(&src.as_raw()[3 * y * w..3 * (y + 1) * w]);
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
    let img = image::GrayImage::from_raw(aw as u32, (rows * h) as u32, a).ok_or(Error::Size)?;
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| Error::Png(e.to_string()))?;
    mhi_data::write_atomic(&dir.join(&file), &png)?;
    let alpha_bytes = img.into_raw();
    let colour_file = if per_layer.is_some() {
        let file = format!("colour_normal_{i}.png");
        let img = image::RgbImage::from_raw(aw as u32, (rows * h) as u32, c).ok_or(Error::Size)?;
        mhi_data::write_png(&dir.join(&file), &img)?;
        colour_bytes = Some(img.into_raw());
        Some(file)
    } else {
        None
    };
    Ok((
        layers,
        Atlas {
            file,
            colour_file,
            cols,
            rows,
        },
        alpha_bytes,
        colour_bytes,
    ))
}

/// Write the viewer folder for `mhi` into `dir` (created if needed; files written atomically).
/// Layers the plan leaves out are not written; a normal the plan drops keeps its farthest layer
/// only (its blend weight is within the budget everywhere). `inputs` are the photos' cameras,
/// `views` the listed target cameras (`#view=k` in the page's address shows the k-th), each
/// with its name. `video` (an MP4's bytes) is shown beside the interactive view.
pub fn write_viewer(
    dir: &Path,
    mhi: &Mhi,
    plan: &ScenePlan,
    source: &str,
    inputs: &[(&str, &Camera)],
    views: &[(String, &Camera)],
    video: Option<&[u8]>,
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|source| Error::Create {
        dir: dir.to_path_buf(),
        source,
    })?;
    let (w, h) = (
        mhi.reference().width as usize,
        mhi.reference().height as usize,
    );
    // `Mhi::new` holds a per-layer MHI to one colour image per layer.
    let (shared, per_layer) = match mhi.color() {
        LayerColor::Shared(colour) => (Some(colour), None),
        LayerColor::PerLayer(v) => (None, Some(v)),
    };
    let mut layers = Vec::new();
    let mut atlases = Vec::new();
    let mut atlas_bytes = Vec::new();
    let mut colour_bytes = Vec::new();
    for i in 0..mhi.n() {
        let (l, atlas, alpha, colour) = write_atlas(dir, mhi, plan, i, per_layer)?;
        layers.extend(l);
        atlases.push(atlas);
        atlas_bytes.push(alpha);
        colour_bytes.extend(colour);
    }
    let reference_rgb = match shared {
        Some(colour) => {
            let rgb = mhi_data::to_u8(colour);
            mhi_data::write_png(&dir.join("reference.png"), &rgb)?;
            Some(rgb)
        }
        None => None,
    };
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
        colour: if per_layer.is_some() {
            "per-layer"
        } else {
            "reference.png"
        },
        baseline,
        inputs: &inputs,
        views: &views,
        path: inputs.iter().chain(&views).collect(),
        plan,
        video: video.map(|_| "video.mp4"),
    };
    if let Some(bytes) = video {
        mhi_data::write_atomic(&dir.join("video.mp4"), bytes)?;
    }
    let manifest_json =
        serde_json::to_string_pretty(&manifest).map_err(|e| Error::Json(e.to_string()))?;
    mhi_data::write_atomic(&dir.join("manifest.json"), manifest_json.as_bytes())?;
    let b64 = |v: &[u8]| base64::engine::general_purpose::STANDARD.encode(v);
    let alphas: Vec<String> = atlas_bytes.iter().map(|a| b64(a)).collect();
    let colours: Vec<String> = colour_bytes.iter().map(|a| b64(a)).collect();
    let data = format!(
        "// Written by `cargo xtask export`: the manifest and the layers as raw bytes for index.html.\nwindow.MHI_DATA = {};\n",
        serde_json::json!({
            "manifest": manifest,
            "colour": reference_rgb.map(|rgb| b64(rgb.as_raw())),
            "alphas": alphas,
            "colours": colours,
        })
    );
    mhi_data::write_atomic(&dir.join("data.js"), data.as_bytes())?;
    mhi_data::write_atomic(&dir.join("viewer.js"), VIEWER_JS.as_bytes())?;
    mhi_data::write_atomic(&dir.join("index.html"), VIEWER_HTML.as_bytes())?;
    Ok(())
}

#[cfg(any(test, feature = "browser"))]
pub mod browser;

/// Why a viewer folder could not be written.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The folder could not be made.
    #[error("cannot create {}: {source}", dir.display())]
    Create {
        /// The folder.
        dir: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file of the folder could not be written.
    #[error(transparent)]
    Write(#[from] mhi_data::Error),
    /// An atlas whose size does not match its pixels (a bug).
    #[error("atlas size")]
    Size,
    /// An atlas that could not be encoded.
    #[error("encoding an atlas: {0}")]
    Png(String),
    /// The manifest could not be written as JSON.
    #[error("the manifest: {0}")]
    Json(String),
}

/// Result of writing a viewer.
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec3};
    use image::{Rgb, Rgb32FImage};
    use mhi_geom::{BlendHeuristic, Intrinsics, NormalSet, RigidTransform};
    use mhi_render::{Prune, RenderOptions};

    /// PSNR of two images of one size (peak 1).
    fn psnr(a: &Rgb32FImage, b: &Rgb32FImage) -> f64 {
        let se: f64 = a
            .as_raw()
            .iter()
            .zip(b.as_raw())
            .map(|(x, y)| f64::from(x - y).powi(2))
            .sum();
        10.0 * (a.as_raw().len() as f64 / se).log10()
    }

    /// An MHI whose every layer has a colour of its own, far from the others' (a hue per layer,
    /// a gradient across the image) and opaque discs at different places per layer.
    fn per_layer_mhi(reference: Camera) -> Mhi {
        let normals = NormalSet::paper_subset(3).unwrap();
        let depths = vec![8.0, 4.0, 2.5, 1.8];
        let (w, h) = (reference.width, reference.height);
        let (n, d) = (normals.len(), depths.len());
        let mut alpha = Vec::new();
        let mut colours = Vec::new();
        for l in 0..n * d {
            let (cx, cy) = (
                (17 + 29 * l) as f32 % w as f32,
                (11 + 23 * l) as f32 % h as f32,
            );
            for y in 0..h {
                for x in 0..w {
                    let r = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
                    alpha.push(if r < 22.0 { 0.8 } else { 0.05 });
                }
            }
            let hue = l as f32 / (n * d) as f32;
            colours.push(Rgb32FImage::from_fn(w, h, |x, y| {
                let g = x as f32 / w as f32;
                Rgb([
                    (hue * 3.0).fract(),
                    (0.3 + 0.7 * g * (1.0 - hue)).min(1.0),
                    (y as f32 / h as f32 + hue).fract(),
                ])
            }));
        }
        Mhi::new(
            normals,
            depths,
            reference,
            LayerColor::PerLayer(colours),
            alpha,
        )
        .unwrap()
    }

    /// A viewer of per-layer colours draws what the CPU renderer draws (Soft blend, exactly),
    /// and the test would see a viewer that used one colour for every layer.
    #[test]
    fn the_viewer_shows_each_layers_own_colour() {
        let Some(chrome) = browser::chromium_or_skip() else {
            return;
        };
        let (w, h) = (128_u32, 96_u32);
        let k = Intrinsics::new(110.0, 110.0, 64.0, 48.0).unwrap();
        let reference = Camera::new(k, RigidTransform::IDENTITY, w, h).unwrap();
        let turn = DMat3::from_rotation_y(0.06);
        let target = Camera::new(
            k,
            RigidTransform::new(turn, DVec3::new(-0.25, 0.05, 0.0)).unwrap(),
            w,
            h,
        )
        .unwrap();
        let mhi = per_layer_mhi(reference);
        let weights = mhi_render::heuristic_weights(&mhi, &target, BlendHeuristic::Soft);
        let plan = mhi_render::plan::analyse(&mhi, &[(&target, &weights)], Prune::NONE).unwrap();
        let d = tempfile::tempdir().unwrap();
        let dir = d.path().join("viewer");
        write_viewer(
            &dir,
            &mhi,
            &plan,
            "test",
            &[("reference", &reference)],
            &[("target".to_string(), &target)],
            None,
        )
        .unwrap();
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap())
                .unwrap();
        assert_eq!(manifest["colour"], "per-layer");
        assert!(dir.join("colour_normal_0.png").is_file());
        assert!(!dir.join("reference.png").exists());

        let cpu = mhi_render::render(&mhi, &target, &RenderOptions::default())
            .unwrap()
            .image;
        let shot = browser::screenshot(&chrome, &dir.join("index.html"), "view=0", w, h, d.path());
        let shot = Rgb32FImage::from_fn(w, h, |x, y| {
            Rgb(shot.get_pixel(x, y).0.map(|v| f32::from(v) / 255.0))
        });
        let cpu8 = Rgb32FImage::from_fn(w, h, |x, y| {
            Rgb(cpu
                .get_pixel(x, y)
                .0
                .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() / 255.0))
        });
        let agree = psnr(&shot, &cpu8);
        eprintln!("per-layer colour: browser vs CPU PSNR {agree:.2} dB");
        assert!(agree >= 35.0, "browser vs CPU: {agree:.2} dB < 35 dB");

        // The same alphas with every layer in the first layer's colour: far from the render
        // above, so a viewer that ignored the layers' own colours would fail.
        let LayerColor::PerLayer(v) = mhi.color() else {
            unreachable!()
        };
        let one = Mhi::new(
            mhi.normals().clone(),
            mhi.depths().to_vec(),
            reference,
            LayerColor::Shared(v[0].clone()),
            mhi.alpha().to_vec(),
        )
        .unwrap();
        let shared = mhi_render::render(&one, &target, &RenderOptions::default())
            .unwrap()
            .image;
        let apart = psnr(&shared, &cpu);
        assert!(
            apart < 25.0,
            "one colour for all layers scores {apart:.2} dB"
        );
    }
}
