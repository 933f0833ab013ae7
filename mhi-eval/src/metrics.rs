//! PSNR and SSIM (Wang et al. 2004), matching scikit-image's conventions.

use image::Rgb32FImage;

use crate::{Error, Result};

/// PSNR of identical images: the MSE is floored at `1e-10`, so the value stays finite.
pub const MAX_PSNR: f64 = 100.0;

fn check(a: &Rgb32FImage, b: &Rgb32FImage) -> Result<()> {
    if a.dimensions() != b.dimensions() {
        return Err(Error::SizeMismatch {
            a: a.dimensions(),
            b: b.dimensions(),
        });
    }
    if a.width() == 0 || a.height() == 0 {
        return Err(Error::InvalidImage("empty image".into()));
    }
    if a.as_raw().iter().chain(b.as_raw()).any(|v| v.is_nan()) {
        return Err(Error::InvalidImage("image holds NaN".into()));
    }
    Ok(())
}

fn check_mask(a: &Rgb32FImage, mask: &[bool]) -> Result<()> {
    if mask.len() != (a.width() as usize) * (a.height() as usize) {
        return Err(Error::InvalidImage(format!(
            "mask has {} flags for {} pixels",
            mask.len(),
            a.width() * a.height()
        )));
    }
    Ok(())
}

fn clip(v: f32) -> f64 {
    f64::from(v.clamp(0.0, 1.0))
}

/// Peak signal-to-noise ratio in dB of two RGB images with values clipped to `[0, 1]`
/// (data range 1), over all pixels and channels; at most [`MAX_PSNR`].
pub fn psnr(a: &Rgb32FImage, b: &Rgb32FImage) -> Result<f64> {
    check(a, b)?;
    let n = a.as_raw().len() as f64;
    let mse = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| (clip(*x) - clip(*y)).powi(2))
        .sum::<f64>()
        / n;
    Ok((10.0 * (1.0 / mse.max(1e-10)).log10()).min(MAX_PSNR))
}

/// PSNR over the pixels where `mask` is true (row-major, one flag per pixel); `None` when the
/// mask selects no pixel.
pub fn psnr_masked(a: &Rgb32FImage, b: &Rgb32FImage, mask: &[bool]) -> Result<Option<f64>> {
    check(a, b)?;
    check_mask(a, mask)?;
    let (mut sum, mut n) = (0.0, 0usize);
    for (p, (x, y)) in a.as_raw().chunks(3).zip(b.as_raw().chunks(3)).enumerate() {
        if mask[p] {
            sum += (0..3)
                .map(|k| (clip(x[k]) - clip(y[k])).powi(2))
                .sum::<f64>();
            n += 3;
        }
    }
    Ok((n > 0).then(|| (10.0 * (1.0 / (sum / n as f64).max(1e-10)).log10()).min(MAX_PSNR)))
}

/// Normalised 1-D Gaussian of σ = 1.5 truncated at 3.5σ (radius 5: an 11 × 11 window), as
/// `scipy.ndimage.gaussian_filter` builds it.
fn gaussian_kernel() -> [f64; 11] {
    let mut k = [0.0; 11];
    for (i, v) in k.iter_mut().enumerate() {
        let x = i as f64 - 5.0;
        *v = (-x * x / (2.0 * 1.5 * 1.5)).exp();
    }
    let s: f64 = k.iter().sum();
    k.map(|v| v / s)
}

/// Index with scipy's `reflect` border (`d c b a | a b c d | d c b a`).
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let period = 2 * n;
    let mut m = i.rem_euclid(period);
    if m >= n {
        m = period - 1 - m;
    }
    m as usize
}

/// Separable Gaussian filter of a `w × h` plane.
fn filter(src: &[f64], w: usize, h: usize, k: &[f64; 11]) -> Vec<f64> {
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            tmp[y * w + x] = (0..11)
                .map(|t| k[t] * src[y * w + reflect(x as isize + t as isize - 5, w)])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = (0..11)
                .map(|t| k[t] * tmp[reflect(y as isize + t as isize - 5, h) * w + x])
                .sum();
        }
    }
    out
}

/// Structural similarity of two RGB images with values clipped to `[0, 1]`, as scikit-image's
/// `structural_similarity(a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
/// data_range=1, channel_axis=-1)`: Gaussian 11 × 11 window (σ = 1.5), K1 = 0.01, K2 = 0.03, the
/// SSIM map averaged over the pixels at least 5 from the border, then over channels. Images need
/// at least [`MIN_SSIM_SIDE`] × [`MIN_SSIM_SIDE`] pixels.
pub fn ssim(a: &Rgb32FImage, b: &Rgb32FImage) -> Result<f64> {
    let map = ssim_map(a, b)?;
    let (w, h) = (a.width() as usize, a.height() as usize);
    let (mut sum, mut count) = (0.0, 0usize);
    for py in 5..h - 5 {
        for px in 5..w - 5 {
            sum += map[py * w + px];
            count += 1;
        }
    }
    Ok(sum / count as f64)
}

/// SSIM averaged over the pixels where `mask` is true and that lie at least 5 pixels from the
/// border (the same window and crop as [`ssim`]); `None` when no such pixel is selected.
pub fn ssim_masked(a: &Rgb32FImage, b: &Rgb32FImage, mask: &[bool]) -> Result<Option<f64>> {
    check_mask(a, mask)?;
    let map = ssim_map(a, b)?;
    let (w, h) = (a.width() as usize, a.height() as usize);
    let (mut sum, mut count) = (0.0, 0usize);
    for py in 5..h - 5 {
        for px in 5..w - 5 {
            if mask[py * w + px] {
                sum += map[py * w + px];
                count += 1;
            }
        }
    }
    Ok((count > 0).then(|| sum / count as f64))
}

/// The smallest side SSIM accepts: its Gaussian window is 11 pixels wide.
pub const MIN_SSIM_SIDE: u32 = 11;

/// The per-pixel SSIM map, averaged over the three channels (row-major, one value per pixel).
fn ssim_map(a: &Rgb32FImage, b: &Rgb32FImage) -> Result<Vec<f64>> {
    check(a, b)?;
    let (w, h) = (a.width() as usize, a.height() as usize);
    if a.width() < MIN_SSIM_SIDE || a.height() < MIN_SSIM_SIDE {
        return Err(Error::InvalidImage(format!(
            "SSIM needs at least {MIN_SSIM_SIDE}×{MIN_SSIM_SIDE} pixels, got {w}×{h}"
        )));
    }
    let k = gaussian_kernel();
    let (c1, c2) = ((0.01_f64).powi(2), (0.03_f64).powi(2));
    let mut map = vec![0.0; w * h];
    for ch in 0..3 {
        let x: Vec<f64> = a.pixels().map(|p| clip(p.0[ch])).collect();
        let y: Vec<f64> = b.pixels().map(|p| clip(p.0[ch])).collect();
        let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
        let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
        let xy: Vec<f64> = x.iter().zip(&y).map(|(p, q)| p * q).collect();
        let (ux, uy) = (filter(&x, w, h, &k), filter(&y, w, h, &k));
        let (uxx, uyy, uxy) = (
            filter(&xx, w, h, &k),
            filter(&yy, w, h, &k),
            filter(&xy, w, h, &k),
        );
        for (i, m) in map.iter_mut().enumerate() {
            let (mx, my) = (ux[i], uy[i]);
            let vx = uxx[i] - mx * mx;
            let vy = uyy[i] - my * my;
            let vxy = uxy[i] - mx * my;
            *m += ((2.0 * mx * my + c1) * (2.0 * vxy + c2))
                / ((mx * mx + my * my + c1) * (vx + vy + c2))
                / 3.0;
        }
    }
    Ok(map)
}
