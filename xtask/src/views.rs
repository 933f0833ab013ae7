//! Helpers shared by `eval`, `render` and `demo`: combining multi-normal images, a circular
//! orbit of cameras, image sheets and animated GIFs.

use std::path::Path;

use anyhow::Context;
use glam::{DMat3, DVec3};
use image::{Rgb32FImage, RgbImage, RgbaImage};
use mhi_geom::{Camera, RigidTransform};
use mhi_net::Model;
use mhi_render::{Mhi, Prune, RenderStats};

/// One novel view of an MHI within `prune`'s budget: blended by a trained model's network
/// (N > 1), or by Soft, where normals the view does not need are also left out and each
/// pixel's light normals stop early (only the blend is bounded; no multi-normal images).
pub fn view(
    mhi: &Mhi,
    model: Option<&Model>,
    cam: &Camera,
    prune: Prune,
) -> anyhow::Result<(Rgb32FImage, RenderStats)> {
    let v = mhi_net::render_image(mhi, model, cam, mhi_net::BlendChoice::Learned, prune)?;
    Ok((v.image, v.stats))
}

/// Clamp every channel to [0, 1] (what is shown and scored).
pub fn clipped(img: &Rgb32FImage) -> Rgb32FImage {
    let mut o = img.clone();
    for p in o.pixels_mut() {
        for c in &mut p.0 {
            *c = if c.is_finite() {
                c.clamp(0.0, 1.0)
            } else {
                0.0
            };
        }
    }
    o
}

/// Cameras on a circle of `radius` around the reference camera's centre, in its image plane
/// (x right, y down), each turned to look at the point `look_at` units along the reference's
/// optical axis (as a hand-held orbit does; `None` keeps the reference's orientation, a pure
/// translation). Returns the cameras and the largest rotation from the reference, in degrees.
pub fn orbit(
    reference: &Camera,
    radius: f64,
    frames: usize,
    look_at: Option<f64>,
) -> anyhow::Result<(Vec<Camera>, f64)> {
    let world_from_ref = reference.cam_from_world.inverse();
    let r_ref: DMat3 = reference.cam_from_world.rotation();
    let mut max_deg = 0.0_f64;
    let cams = (0..frames)
        .map(|k| {
            let th = std::f64::consts::TAU * k as f64 / frames as f64;
            let offset_cam = DVec3::new(radius * th.cos(), radius * th.sin(), 0.0);
            // cam_from_ref rotation: rows are the new camera's axes in the reference frame.
            let turn = match look_at {
                Some(z) if z.is_finite() && z > 0.0 => {
                    let fwd = (DVec3::new(0.0, 0.0, z) - offset_cam).normalize();
                    let right = DVec3::Y.cross(fwd).normalize();
                    let down = fwd.cross(right);
                    DMat3::from_cols(right, down, fwd).transpose()
                }
                _ => DMat3::IDENTITY,
            };
            max_deg = max_deg.max(mhi_geom::rotation_angle_deg(&turn));
            let center = world_from_ref.transform_point(offset_cam);
            let r = turn * r_ref;
            let pose = RigidTransform::new(r, -(r * center))?;
            Ok(Camera::new(
                reference.intrinsics,
                pose,
                reference.width,
                reference.height,
            )?)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok((cams, max_deg))
}

/// The median depth the MHI sees from its reference camera: the median over pixels of the
/// expected disparity through the normal closest to the optical axis, inverted. `None` when
/// nothing is in front (every disparity zero).
pub fn median_depth(mhi: &Mhi) -> Option<f64> {
    let normals = mhi.normals().normals();
    let i = (0..normals.len()).max_by(|a, b| normals[*a].z.total_cmp(&normals[*b].z))?;
    let mut disp: Vec<f32> = mhi
        .expected_disparity(i)
        .into_iter()
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if disp.is_empty() {
        return None;
    }
    let mid = disp.len() / 2;
    let (_, m, _) = disp.select_nth_unstable_by(mid, f32::total_cmp);
    Some(1.0 / f64::from(*m))
}

/// Nearest-neighbour enlargement by an integer factor (small renders stay readable).
pub fn enlarge(img: &RgbImage, factor: u32) -> RgbImage {
    let f = factor.max(1);
    RgbImage::from_fn(img.width() * f, img.height() * f, |x, y| {
        *img.get_pixel(x / f, y / f)
    })
}

/// The integer factor that brings the width to at least `target` pixels.
pub fn factor_for(width: u32, target: u32) -> u32 {
    target.div_ceil(width.max(1)).max(1)
}

/// Write an animated GIF (looping, `delay_ms` per frame), atomically.
pub fn write_gif(path: &Path, frames: &[RgbImage], delay_ms: u32) -> anyhow::Result<()> {
    use image::codecs::gif::{GifEncoder, Repeat};
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 10);
        enc.set_repeat(Repeat::Infinite)?;
        for f in frames {
            let rgba = RgbaImage::from_fn(f.width(), f.height(), |x, y| {
                let p = f.get_pixel(x, y).0;
                image::Rgba([p[0], p[1], p[2], 255])
            });
            enc.encode_frame(image::Frame::from_parts(
                rgba,
                0,
                0,
                image::Delay::from_numer_denom_ms(delay_ms, 1),
            ))
            .with_context(|| format!("encoding {}", path.display()))?;
        }
    }
    mhi_data::write_atomic(path, &bytes)?;
    Ok(())
}

/// An MHI layer as a picture: its colour weighted by alpha over a grey checkerboard.
pub fn layer_picture(color: &Rgb32FImage, alpha: &[f32]) -> RgbImage {
    RgbImage::from_fn(color.width(), color.height(), |x, y| {
        let a = alpha[(y * color.width() + x) as usize].clamp(0.0, 1.0);
        let bg = if (x / 4 + y / 4) % 2 == 0 { 0.8 } else { 0.6 };
        let p = color.get_pixel(x, y).0;
        image::Rgb(p.map(|c| ((a * c + (1.0 - a) * bg).clamp(0.0, 1.0) * 255.0).round() as u8))
    })
}

/// Tile images left to right with a 2-pixel white gap.
pub fn strip(images: &[RgbImage]) -> RgbImage {
    let h = images.iter().map(|i| i.height()).max().unwrap_or(1);
    let w: u32 = images.iter().map(|i| i.width() + 2).sum::<u32>().max(1);
    let mut out = RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    let mut x0 = 0;
    for im in images {
        image::imageops::replace(&mut out, im, i64::from(x0), 0);
        x0 += im.width() + 2;
    }
    out
}

/// A weight map (values in [0, 1]) as a grey image.
pub fn grey(values: &[f32], width: u32, height: u32) -> RgbImage {
    RgbImage::from_fn(width, height, |x, y| {
        let v = values[(y * width + x) as usize];
        let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        image::Rgb([g, g, g])
    })
}
