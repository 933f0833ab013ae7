//! Pictures of MHIs and views, shared by the evaluation and the commands: one view of an MHI,
//! layer pictures, image sheets, error maps and animated GIFs.

use std::path::Path;

use anyhow::Context;
use image::{Rgb32FImage, RgbImage, RgbaImage};
use mhi_geom::Camera;
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

pub use crate::protocol::clipped;

/// The index of the MHI's normal closest to the reference's optical axis (largest z).
pub fn fronto_normal(mhi: &Mhi) -> Option<usize> {
    let normals = mhi.normals().normals();
    (0..normals.len()).max_by(|a, b| normals[*a].z.total_cmp(&normals[*b].z))
}

/// The median depth the MHI sees from its reference camera: the median over pixels of the
/// expected disparity through the normal closest to the optical axis, inverted. `None` when
/// nothing is in front (every disparity zero).
pub fn median_depth(mhi: &Mhi) -> Option<f64> {
    let i = fronto_normal(mhi)?;
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

/// Write `img` as an 8-bit PNG, atomically.
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
