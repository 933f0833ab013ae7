//! Shared helpers for the `*_u8` warp kernels.
//!
//! Both `warp_affine_u8` and `warp_perspective_u8` sample the same way once a
//! source coordinate has been produced — only how that coordinate is generated
//! differs (linear vs rational). This module extracts the common per-pixel
//! bilinear sample.

/// Whether `src` is a packed `src_h x src_w x C` u8 buffer — the layout
/// [`bilinear_sample_u8_valid_unchecked`] and the C=3 SIMD samplers require.
/// Always true for an `Image` slice; callers check it once per call / span so
/// the per-pixel paths can rely on it.
#[inline(always)]
pub(crate) fn is_packed<const C: usize>(
    src: &[u8],
    src_w: i32,
    src_h: i32,
    src_stride: usize,
) -> bool {
    src_w > 0
        && src_h > 0
        && src_stride == src_w as usize * C
        && src.len() >= src_h as usize * src_stride
}

/// Bilinear sample of a u8 source image at `(xf, yf)` into `dst_pixel`, using
/// Q10 fixed-point weights. Writes zeros on out-of-bounds. Kept tiny and
/// `#[inline(always)]` so the hot warp loops get the same codegen as before.
///
/// `src_stride` is `src_cols * C` (row stride in bytes for u8).
#[inline(always)]
pub(crate) fn bilinear_sample_u8<const C: usize>(
    src: &[u8],
    src_w: i32,
    src_h: i32,
    src_stride: usize,
    xf: f32,
    yf: f32,
    dst_pixel: &mut [u8],
) {
    if !xf.is_finite() || !yf.is_finite() {
        for p in dst_pixel.iter_mut().take(C) {
            *p = 0;
        }
        return;
    }
    let xi = xf.floor() as i32;
    let yi = yf.floor() as i32;

    if xi < 0 || xi >= src_w || yi < 0 || yi >= src_h {
        for p in dst_pixel.iter_mut().take(C) {
            *p = 0;
        }
        return;
    }

    let xi1 = if xi + 1 < src_w { xi + 1 } else { xi };
    let yi1 = if yi + 1 < src_h { yi + 1 } else { yi };

    let fx = ((xf - xi as f32) * 1024.0) as u32;
    let fy = ((yf - yi as f32) * 1024.0) as u32;
    let fx1 = 1024 - fx;
    let fy1 = 1024 - fy;

    let row0 = (yi as usize) * src_stride;
    let row1 = (yi1 as usize) * src_stride;
    let xoff0 = (xi as usize) * C;
    let xoff1 = (xi1 as usize) * C;
    let off00 = row0 + xoff0;
    let off01 = row0 + xoff1;
    let off10 = row1 + xoff0;
    let off11 = row1 + xoff1;

    for ch in 0..C {
        let p00 = src[off00 + ch] as u32;
        let p01 = src[off01 + ch] as u32;
        let p10 = src[off10 + ch] as u32;
        let p11 = src[off11 + ch] as u32;
        let top = p00 * fx1 + p01 * fx;
        let bot = p10 * fx1 + p11 * fx;
        let v = (top * fy1 + bot * fy + (1 << 19)) >> 20;
        dst_pixel[ch] = v as u8;
    }
}

/// Q10 bilinear sample at integer tap `(xi, yi)` with fractional weights
/// `fx_q10`/`fy_q10` — safe for any inputs.
///
/// Callers are expected to pass `xi ∈ [0, src_w - 1]`, `yi ∈ [0, src_h - 1]`
/// and fractions in `[0, 1024]`, but nothing here trusts it: callers derive
/// taps from a float span analysis that can disagree with their fixed-point
/// sampling arithmetic by a pixel, so the taps are clamped into the image
/// (a negative tap also drops its fractional weight, so the output is exactly
/// the edge pixel) and the farthest byte read is checked against `src.len()`.
/// For in-range inputs the clamps are no-ops and the bytes are identical to
/// [`bilinear_sample_u8_valid_unchecked`].
///
/// When `xi` (or `yi`) is at the extreme edge, the neighbor index is clamped
/// to the same pixel — equivalent to `BORDER_REPLICATE` for the interior of a
/// single-pixel border. At an exact-integer source coord on the edge
/// (fx_q10=0 or fy_q10=0) the clamped neighbor is weighted to zero, so the
/// output is exactly `src[yi, xi]` — matching the f32 reference kernel's
/// identity-preservation.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn bilinear_sample_u8_valid<const C: usize>(
    src: &[u8],
    src_w: i32,
    src_h: i32,
    src_stride: usize,
    xi: i32,
    yi: i32,
    fx_q10: u32,
    fy_q10: u32,
    dst_pixel: &mut [u8],
) {
    if src_w <= 0 || src_h <= 0 || dst_pixel.len() < C {
        for p in dst_pixel.iter_mut().take(C) {
            *p = 0;
        }
        return;
    }
    let (xi, fx_q10) = if xi < 0 {
        (0, 0)
    } else {
        (xi.min(src_w - 1), fx_q10.min(1024))
    };
    let (yi, fy_q10) = if yi < 0 {
        (0, 0)
    } else {
        (yi.min(src_h - 1), fy_q10.min(1024))
    };
    // The (xi1, yi1) corner holds the farthest byte any path reads.
    let xi1 = if xi + 1 < src_w { xi + 1 } else { xi } as usize;
    let yi1 = if yi + 1 < src_h { yi + 1 } else { yi } as usize;
    let far = yi1 * src_stride + xi1 * C;
    if far + C > src.len() {
        // Only reachable with a `src` shorter than `src_h * src_stride`.
        for p in dst_pixel.iter_mut().take(C) {
            *p = 0;
        }
        return;
    }
    // C=3 SIMD samplers load a 4-byte word per corner.
    let word_ok = far + 4 <= src.len();
    // SAFETY: `0 <= xi <= xi1 < src_w`, `0 <= yi <= yi1 < src_h`, the
    // farthest corner's `C` bytes (and 4 bytes when `word_ok`) lie inside
    // `src` as checked above, all other corners are at lower offsets, and
    // `dst_pixel.len() >= C`.
    unsafe {
        sample_q10_impl::<C>(
            src, src_w, src_h, src_stride, xi, yi, fx_q10, fy_q10, dst_pixel, word_ok,
        );
    }
}

/// Unchecked Q10 bilinear sample — the hot-loop form of
/// [`bilinear_sample_u8_valid`] for callers that have proven the tap range for
/// a whole span up front (see `process_affine_span`).
///
/// `fx_q10`/`fy_q10` should be `<= 1024` for a meaningful result (larger
/// values only corrupt the arithmetic, never memory access).
///
/// # Safety
///
/// - `0 <= xi < src_w` and `0 <= yi < src_h`;
/// - `src.len() >= src_h * src_stride` and `src_stride == src_w * C`;
/// - `dst_pixel.len() >= C`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn bilinear_sample_u8_valid_unchecked<const C: usize>(
    src: &[u8],
    src_w: i32,
    src_h: i32,
    src_stride: usize,
    xi: i32,
    yi: i32,
    fx_q10: u32,
    fy_q10: u32,
    dst_pixel: &mut [u8],
) {
    // The 4-byte corner word at (xi+1, yi+1) is in-bounds unless the tap is
    // in the last two columns of the last two rows: with a packed stride the
    // word then spills one byte past the buffer.
    let word_ok = xi < src_w - 2 || yi < src_h - 2;
    // SAFETY: forwarded from this function's contract; `word_ok` as argued
    // above given `src.len() >= src_h * src_stride` and a packed stride.
    unsafe {
        sample_q10_impl::<C>(
            src, src_w, src_h, src_stride, xi, yi, fx_q10, fy_q10, dst_pixel, word_ok,
        );
    }
}

/// Shared body of the two samplers above.
///
/// # Safety
///
/// - `0 <= xi < src_w`, `0 <= yi < src_h`;
/// - the `C` bytes at `yi1 * src_stride + xi1 * C` are inside `src`, where
///   `xi1`/`yi1` are the edge-clamped `xi + 1`/`yi + 1` (all other corners
///   are at lower offsets);
/// - `word_ok` implies the 4 bytes at that offset are inside `src`;
/// - `dst_pixel.len() >= C`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn sample_q10_impl<const C: usize>(
    src: &[u8],
    src_w: i32,
    src_h: i32,
    src_stride: usize,
    xi: i32,
    yi: i32,
    fx_q10: u32,
    fy_q10: u32,
    dst_pixel: &mut [u8],
    word_ok: bool,
) {
    // NEON fast path for C=3: holds RGB in lanes 0-2 of u32x4, does
    // Q10 bilinear math in SIMD. Needs the 4-byte word reads (`word_ok`).
    #[cfg(target_arch = "aarch64")]
    {
        if C == 3 && word_ok {
            // SAFETY: taps in range and 4-byte corner reads in-bounds
            // (`word_ok`), per this function's contract.
            unsafe {
                bilinear_sample_u8_valid_c3_neon(
                    src.as_ptr(),
                    src_w,
                    src_h,
                    src_stride,
                    xi,
                    yi,
                    fx_q10,
                    fy_q10,
                    dst_pixel.as_mut_ptr(),
                );
            }
            return;
        }
    }
    #[cfg(target_arch = "x86_64")]
    {
        if C == 3 && word_ok && crate::simd::cpu_features().has_avx2 {
            // SAFETY: AVX2 checked at runtime; taps in range and 4-byte
            // corner reads in-bounds (`word_ok`), per this function's contract.
            unsafe {
                bilinear_sample_u8_valid_c3_avx2(
                    src.as_ptr(),
                    src_w,
                    src_h,
                    src_stride,
                    xi,
                    yi,
                    fx_q10,
                    fy_q10,
                    dst_pixel.as_mut_ptr(),
                );
            }
            return;
        }
    }
    #[cfg(not(any(target_arch = "aarch64", target_arch = "x86_64")))]
    let _ = word_ok;

    let fx1 = 1024 - fx_q10;
    let fy1 = 1024 - fy_q10;

    let xi1 = if xi + 1 < src_w { xi + 1 } else { xi };
    let yi1 = if yi + 1 < src_h { yi + 1 } else { yi };

    let row0 = (yi as usize) * src_stride;
    let row1 = (yi1 as usize) * src_stride;
    let xoff0 = (xi as usize) * C;
    let xoff1 = (xi1 as usize) * C;
    let off00 = row0 + xoff0;
    let off01 = row0 + xoff1;
    let off10 = row1 + xoff0;
    let off11 = row1 + xoff1;

    // SAFETY: `off11 + C <= src.len()` per the contract and every other
    // offset is `<=` it; `dst_pixel.len() >= C`.
    unsafe {
        let p = src.as_ptr();
        for ch in 0..C {
            let p00 = *p.add(off00 + ch) as u32;
            let p01 = *p.add(off01 + ch) as u32;
            let p10 = *p.add(off10 + ch) as u32;
            let p11 = *p.add(off11 + ch) as u32;
            let top = p00 * fx1 + p01 * fx_q10;
            let bot = p10 * fx1 + p11 * fx_q10;
            let v = (top * fy1 + bot * fy_q10 + (1 << 19)) >> 20;
            *dst_pixel.as_mut_ptr().add(ch) = v as u8;
        }
    }
}

/// NEON u8 bilinear sampler, C=3 specialization.
///
/// Holds RGB in lanes 0-2 of a u32x4 vector (lane 3 dead), does Q10
/// fixed-point bilinear math in SIMD. Each corner is loaded via one
/// unaligned u32 read (3 bytes RGB + 1 byte slack), then widened
/// u8→u16→u32.
///
/// # Safety
/// - `xi ∈ [0, src_w-1]`, `yi ∈ [0, src_h-1]`.
/// - The 4 bytes at `yi1 * src_stride + xi1 * 3` (the edge-clamped
///   `(xi+1, yi+1)` corner, the farthest one) must be readable from `src`.
///   With a packed buffer of `src_h * src_stride` bytes this holds whenever
///   `xi < src_w-2 OR yi < src_h-2`; at the last pixel the unaligned read
///   would otherwise spill 1 byte past the buffer.
/// - `dst_pixel` must point to 3 writable bytes.
#[cfg(target_arch = "aarch64")]
#[target_feature(enable = "neon")]
#[inline]
#[allow(clippy::too_many_arguments)]
unsafe fn bilinear_sample_u8_valid_c3_neon(
    src: *const u8,
    src_w: i32,
    src_h: i32,
    src_stride: usize,
    xi: i32,
    yi: i32,
    fx_q10: u32,
    fy_q10: u32,
    dst_pixel: *mut u8,
) {
    unsafe {
        use std::arch::aarch64::*;

        let xi1 = if xi + 1 < src_w {
            (xi + 1) as usize
        } else {
            xi as usize
        };
        let yi1 = if yi + 1 < src_h {
            (yi + 1) as usize
        } else {
            yi as usize
        };

        let row0 = (yi as usize) * src_stride;
        let row1 = yi1 * src_stride;
        let xoff0 = (xi as usize) * 3;
        let xoff1 = xi1 * 3;

        // Load 4 bytes per corner via unaligned u32 read, widen u8x4 → u32x4.
        // Lane 3 is garbage (next pixel's R or padding) — ignored by the
        // narrow at the end since we only store 3 bytes.
        let load = |off: usize| -> uint32x4_t {
            let raw = core::ptr::read_unaligned(src.add(off) as *const u32);
            let u8_vec = vreinterpret_u8_u32(vcreate_u32(raw as u64));
            let u16_vec = vmovl_u8(u8_vec);
            vmovl_u16(vget_low_u16(u16_vec))
        };

        let p00 = load(row0 + xoff0);
        let p01 = load(row0 + xoff1);
        let p10 = load(row1 + xoff0);
        let p11 = load(row1 + xoff1);

        let fx_v = vdupq_n_u32(fx_q10);
        let fx1_v = vdupq_n_u32(1024 - fx_q10);
        let fy_v = vdupq_n_u32(fy_q10);
        let fy1_v = vdupq_n_u32(1024 - fy_q10);

        // top = p00 * fx1 + p01 * fx   (values ≤ 255 * 1024 * 2 = 522k, fits u32)
        // bot = p10 * fx1 + p11 * fx
        let top = vmlaq_u32(vmulq_u32(p00, fx1_v), p01, fx_v);
        let bot = vmlaq_u32(vmulq_u32(p10, fx1_v), p11, fx_v);
        // sum = top * fy1 + bot * fy + (1<<19)  (≤ 522k * 1024 + 522k * 1024 = 1.07e9, fits u32)
        let sum = vmlaq_u32(vmulq_u32(top, fy1_v), bot, fy_v);
        let sum = vaddq_u32(sum, vdupq_n_u32(1 << 19));
        let res = vshrq_n_u32::<20>(sum);

        // Narrow u32x4 → u8 (first 3 bytes are R, G, B).
        let u16x4 = vmovn_u32(res);
        let u8x8 = vmovn_u16(vcombine_u16(u16x4, u16x4));
        *dst_pixel.add(0) = vget_lane_u8::<0>(u8x8);
        *dst_pixel.add(1) = vget_lane_u8::<1>(u8x8);
        *dst_pixel.add(2) = vget_lane_u8::<2>(u8x8);
    }
}

/// AVX2 u8 bilinear sampler, C=3 specialization.
///
/// Mirrors the NEON kernel above: 4 corners loaded as u32x4 (`__m128i` with
/// 4 i32 lanes via `_mm_cvtepu8_epi32`), Q10 bilinear math via
/// `_mm_mullo_epi32` + `_mm_add_epi32`, final right-shift by 20 and lane-wise
/// byte stores. SSE4.1 ops are valid inside an AVX2-target_feature function.
///
/// # Safety
/// Same preconditions as `bilinear_sample_u8_valid_c3_neon`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn bilinear_sample_u8_valid_c3_avx2(
    src: *const u8,
    src_w: i32,
    src_h: i32,
    src_stride: usize,
    xi: i32,
    yi: i32,
    fx_q10: u32,
    fy_q10: u32,
    dst_pixel: *mut u8,
) {
    use std::arch::x86_64::*;

    let xi1 = if xi + 1 < src_w {
        (xi + 1) as usize
    } else {
        xi as usize
    };
    let yi1 = if yi + 1 < src_h {
        (yi + 1) as usize
    } else {
        yi as usize
    };

    let row0 = (yi as usize) * src_stride;
    let row1 = yi1 * src_stride;
    let xoff0 = (xi as usize) * 3;
    let xoff1 = xi1 * 3;

    // Load 4 bytes per corner; widen u8→u32 (lane 3 garbage, ignored at end).
    let load = |off: usize| -> __m128i {
        let raw = core::ptr::read_unaligned(src.add(off) as *const i32);
        _mm_cvtepu8_epi32(_mm_cvtsi32_si128(raw))
    };

    let p00 = load(row0 + xoff0);
    let p01 = load(row0 + xoff1);
    let p10 = load(row1 + xoff0);
    let p11 = load(row1 + xoff1);

    let fx_v = _mm_set1_epi32(fx_q10 as i32);
    let fx1_v = _mm_set1_epi32((1024 - fx_q10) as i32);
    let fy_v = _mm_set1_epi32(fy_q10 as i32);
    let fy1_v = _mm_set1_epi32((1024 - fy_q10) as i32);

    // Q10 bilinear: top = p00*(1024-fx) + p01*fx
    //               bot = p10*(1024-fx) + p11*fx
    //               sum = top*(1024-fy) + bot*fy + (1<<19)
    //               out = sum >> 20
    let top = _mm_add_epi32(_mm_mullo_epi32(p00, fx1_v), _mm_mullo_epi32(p01, fx_v));
    let bot = _mm_add_epi32(_mm_mullo_epi32(p10, fx1_v), _mm_mullo_epi32(p11, fx_v));
    let sum = _mm_add_epi32(_mm_mullo_epi32(top, fy1_v), _mm_mullo_epi32(bot, fy_v));
    let sum = _mm_add_epi32(sum, _mm_set1_epi32(1 << 19));
    let res = _mm_srli_epi32::<20>(sum);

    // Extract bottom byte of each of the first 3 i32 lanes.
    *dst_pixel.add(0) = _mm_extract_epi32::<0>(res) as u8;
    *dst_pixel.add(1) = _mm_extract_epi32::<1>(res) as u8;
    *dst_pixel.add(2) = _mm_extract_epi32::<2>(res) as u8;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Regression: `bilinear_sample_u8_valid` used to trust `xi`/`yi` (and the
    /// Q10 fractions) and read through raw pointers, so a caller whose span
    /// analysis disagreed with its sampling arithmetic read out of bounds.
    /// Taps must now be clamped into the image.
    #[test]
    fn valid_sampler_clamps_out_of_range_taps() {
        // 3x2 RGB, buffer exactly `h * stride` bytes.
        let src: Vec<u8> = (0..18u8).map(|v| v * 10).collect();
        let (w, h, stride) = (3, 2, 9);
        let mut out = [0u8; 3];

        // Past the right/bottom edge -> last pixel (2, 1).
        bilinear_sample_u8_valid::<3>(&src, w, h, stride, 3, 1, 512, 0, &mut out);
        assert_eq!(out, [150, 160, 170]);
        bilinear_sample_u8_valid::<3>(&src, w, h, stride, i32::MAX, i32::MAX, 1023, 1023, &mut out);
        assert_eq!(out, [150, 160, 170]);

        // Negative taps -> (0, 0) with the fractional weight dropped.
        bilinear_sample_u8_valid::<3>(&src, w, h, stride, -1, -5, 1023, 1023, &mut out);
        assert_eq!(out, [0, 10, 20]);
        bilinear_sample_u8_valid::<3>(&src, w, h, stride, i32::MIN, i32::MIN, 1023, 1023, &mut out);
        assert_eq!(out, [0, 10, 20]);

        // Out-of-range fraction is clamped to a full-weight neighbour.
        bilinear_sample_u8_valid::<3>(&src, w, h, stride, 0, 0, u32::MAX, 0, &mut out);
        assert_eq!(out, [30, 40, 50]);

        // Single channel, same rules.
        let src1: Vec<u8> = vec![1, 2, 3, 4];
        let mut o1 = [0u8; 1];
        bilinear_sample_u8_valid::<1>(&src1, 2, 2, 2, 7, 7, 100, 100, &mut o1);
        assert_eq!(o1, [4]);

        // Empty source: zeros, no read.
        let mut o = [9u8; 3];
        bilinear_sample_u8_valid::<3>(&[], 0, 0, 0, 0, 0, 0, 0, &mut o);
        assert_eq!(o, [0, 0, 0]);
    }
}
