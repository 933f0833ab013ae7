//! Bilinear samples with zero padding, the floor and texel index through the float's bits;
//! shared by the band loop and the render plan's bounds.

use crate::bilinear;

/// Bilinear sample of alpha and colour at pixel-index position `(sx, sy)` (pixel centres at
/// integers), zero outside the image (PyTorch's `grid_sample`, `align_corners=False`,
/// `padding_mode="zeros"`).
#[inline(always)]
pub(super) fn sample<const FUSED: bool>(
    alpha: &[f32],
    color: &[f32],
    wd: usize,
    h: usize,
    sx: f32,
    sy: f32,
) -> (f32, [f32; 3]) {
    let [a, r, g, b] = sample_zero_padded::<FUSED, 4>(
        |i| [alpha[i], color[3 * i], color[3 * i + 1], color[3 * i + 2]],
        wd,
        h,
        sx,
        sy,
    );
    (a, [r, g, b])
}

/// 2²³: adding it to a float in [0, 2²³) rounds it to an integer (the spacing of floats there
/// is 1), and the integer is then the low bits of the sum.
pub(super) const ROUNDER: f32 = 8_388_608.0;

/// `⌊s⌋` for `s` in `[0, 2²²)` when `ok` (0 otherwise), without a conversion to an integer: the
/// saturating `as` casts of Rust have no four-wide form on the baseline x86-64 target, and kept
/// the renderer's position pass from being vectorised.
#[inline(always)]
pub(super) fn floor_small(s: f32, ok: bool) -> f32 {
    let s = if ok { s } else { 0.0 };
    let r = (s + ROUNDER) - ROUNDER; // s rounded to the nearest integer
    if r > s { r - 1.0 } else { r }
}

/// The integer `f` (a whole float in `[0, 2²³)`) as `u32`, by its bits.
#[inline(always)]
pub(super) fn small_to_u32(f: f32) -> u32 {
    (f + ROUNDER).to_bits() - ROUNDER.to_bits()
}

/// Bilinear sample at `(sx, sy)` of the `wd × h` image whose texel `i` (row-major) is
/// `value(i)`, zero outside it (zero padding).
#[inline(always)]
pub(super) fn sample_zero_padded<const FUSED: bool, const C: usize>(
    value: impl Fn(usize) -> [f32; C],
    wd: usize,
    h: usize,
    sx: f32,
    sy: f32,
) -> [f32; C] {
    if !touches_image(sx, sy, wd, h) {
        return [0.0; C];
    }
    // floor() without a libm call (the baseline x86-64 target has no SSE4.1 rounding): the
    // shifted value is positive, so truncation is the floor.
    let x0 = (sx + 1.0) as isize - 1;
    let y0 = (sy + 1.0) as isize - 1;
    let w = bilinear::weights(sx - x0 as f32, sy - y0 as f32);
    // Taps outside the image read zero (zero padding).
    let tap = |xx: isize, yy: isize| {
        if xx >= 0 && yy >= 0 && (xx as usize) < wd && (yy as usize) < h {
            value(yy as usize * wd + xx as usize)
        } else {
            [0.0; C]
        }
    };
    bilinear::mix_as::<FUSED, C>(
        &w,
        [
            tap(x0, y0),
            tap(x0 + 1, y0),
            tap(x0, y0 + 1),
            tap(x0 + 1, y0 + 1),
        ],
    )
}

/// Whether a bilinear sample at `(sx, sy)` has a tap inside the `w × h` image (otherwise it
/// reads zero under zero padding). NaN positions touch nothing.
#[inline(always)]
pub(super) fn touches_image(sx: f32, sy: f32, w: usize, h: usize) -> bool {
    sx > -1.0 && sy > -1.0 && sx < w as f32 && sy < h as f32
}
