//! A render's compositing sixteen pixels at a time with AVX-512F: the bilinear fetch as 64-bit
//! gathers of tap pairs (alpha left and right; a row's six colour floats as three pairs), the mix
//! and the front-to-back step on vectors of sixteen pixels, a pruned render's stops as lane
//! masks. Each lane does what the AVX2 + FMA band loop does for its pixel, in the same order and
//! rounding (weights as plain products, the mix and the colour step as fused multiply-adds): the
//! same bits (tested). Samples whose taps are not all inside the image go through the scalar
//! zero-padded sampler, lane by lane.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use super::sample::sample;

/// One layer's samples along a row (pass 1's output) and its texels.
pub(super) struct LayerRow<'a> {
    pub(super) alpha: &'a [f32],
    pub(super) color: &'a [f32],
    pub(super) idx: &'a [u32],
    pub(super) fx: &'a [f32],
    pub(super) fy: &'a [f32],
    pub(super) sx: &'a [f32],
    pub(super) sy: &'a [f32],
    /// The far layer: composited with alpha 1.
    pub(super) far: bool,
}

/// Pass 1's output for a row: top-left texel index, fractions, positions.
type Pass1<'a> = (&'a [u32], &'a [f32], &'a [f32], &'a [f32], &'a [f32]);

impl<'a> LayerRow<'a> {
    /// A layer's texels `(alpha, color)` and pass 1's `(idx, fx, fy, sx, sy)` for a row.
    pub(super) fn new(
        (alpha, color): (&'a [f32], &'a [f32]),
        (idx, fx, fy, sx, sy): Pass1<'a>,
        far: bool,
    ) -> Self {
        Self {
            alpha,
            color,
            idx,
            fx,
            fy,
            sx,
            sy,
            far,
        }
    }
}

/// Whether the wide path can address a `rw × rh` reference image: every colour tap's index fits
/// a gather's signed 32-bit offsets.
pub(super) fn fits(rw: usize, rh: usize) -> bool {
    rw.checked_mul(rh)
        .and_then(|px| px.checked_mul(3))
        .is_some_and(|n| n < i32::MAX as usize)
}

/// Composite `layers`, one after the other (near to far), into pixels `x0..x1` of a row whose
/// transmittance is `t` (one float a pixel) and colour `c` (four floats a pixel: RGB and one
/// never read). `rw × rh` is the reference image; every layer's `alpha` holds `rw · rh` floats
/// and `color` three times that, and pass 1 wrote `idx` (the top-left tap, `u32::MAX` where not
/// all four taps are inside), the fractions and the positions for every pixel of `x0..x1`.
/// With `stop` (a pruned render; one layer), a pixel whose transmittance is at or below its
/// stop is passed over. Returns the samples composited.
///
/// # Safety
/// The CPU has AVX-512F; [`fits`]`(rw, rh)`.
///
/// # Panics
/// If a slice is shorter than the above, or an index lies outside the image.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn composite_row<const L: usize>(
    layers: &[LayerRow<'_>; L],
    (rw, rh): (usize, usize),
    (x0, x1): (usize, usize),
    t: &mut [f32],
    c: &mut [f32],
    stop: Option<&[f32]>,
) -> usize {
    assert!(x0 <= x1 && x1 <= t.len() && 4 * x1 <= c.len());
    assert!(stop.is_none_or(|s| s.len() >= x1 && L == 1));
    let mut composited = 0;
    for l in layers {
        assert!(l.alpha.len() >= rw * rh && l.color.len() >= 3 * rw * rh);
        let n = [l.idx.len(), l.fx.len(), l.fy.len(), l.sx.len(), l.sy.len()];
        assert!(n.iter().all(|&n| n >= x1));
    }
    // The largest top-left tap whose four taps are inside: (rh − 2) · rw + rw − 2.
    let last = (rh.max(2) - 2) * rw + rw.max(2) - 2;
    let last = _mm512_set1_epi32(last as i32);
    let (one, none) = (_mm512_set1_ps(1.0), _mm512_set1_epi32(-1));
    // The even and the odd floats of two vectors, each as one vector.
    let even = _mm512_set_epi32(30, 28, 26, 24, 22, 20, 18, 16, 14, 12, 10, 8, 6, 4, 2, 0);
    let odd = _mm512_set_epi32(31, 29, 27, 25, 23, 21, 19, 17, 15, 13, 11, 9, 7, 5, 3, 1);
    let mut x = x0;
    // SAFETY: lanes < len read and write inside `..x1` of each slice (asserted above), and a
    // gathered tap lies inside the image (its top-left index at most `last`, checked per chunk);
    // masked-off lanes touch no memory.
    unsafe {
        while x < x1 {
            let len = (x1 - x).min(16);
            let lanes: __mmask16 = if len == 16 { 0xffff } else { (1 << len) - 1 };
            let tp = t.as_mut_ptr().add(x);
            let mut tv = _mm512_maskz_loadu_ps(lanes, tp);
            // The pixels still open: all, or those whose transmittance is above their stop (as
            // the scalar loop's `t <= stop` skips, NaN stays open).
            let open = match stop {
                None => lanes,
                Some(s) => {
                    let th = _mm512_maskz_loadu_ps(lanes, s.as_ptr().add(x));
                    _mm512_mask_cmp_ps_mask::<_CMP_NLE_UQ>(lanes, tv, th)
                }
            };
            if open == 0 {
                x += len;
                continue;
            }
            composited += open.count_ones() as usize * L;
            let [mut r, mut g, mut b] = load_rgb(c.as_ptr().add(4 * x), len);
            for l in layers {
                let iv = _mm512_maskz_loadu_epi32(lanes, l.idx.as_ptr().add(x).cast());
                // Lanes whose taps all lie inside; the others take the scalar sampler.
                let inside = _mm512_mask_cmpneq_epi32_mask(open, iv, none);
                assert!(
                    _mm512_mask_cmpgt_epu32_mask(inside, iv, last) == 0,
                    "a texel index outside the image"
                );
                let ax = _mm512_maskz_loadu_ps(lanes, l.fx.as_ptr().add(x));
                let ay = _mm512_maskz_loadu_ps(lanes, l.fy.as_ptr().add(x));
                let (bx, by) = (_mm512_sub_ps(one, ax), _mm512_sub_ps(one, ay));
                let w = [
                    _mm512_mul_ps(bx, by),
                    _mm512_mul_ps(ax, by),
                    _mm512_mul_ps(bx, ay),
                    _mm512_mul_ps(ax, ay),
                ];
                // Horizontally neighbouring taps are neighbours in memory: each lane of a 64-bit
                // gather brings two floats (alpha: the left and right tap; colour: a pixel's six
                // floats of a row as three pairs), half the loads of gathering every float alone.
                // Eight pixels a gather, then the pairs split into sixteen-pixel vectors.
                let halves = [
                    _mm512_castsi512_si256(iv),
                    _mm512_extracti64x4_epi64::<1>(iv),
                ];
                let masks = [inside as __mmask8, (inside >> 8) as __mmask8];
                macro_rules! pairs {
                    ($data:expr, $at:expr, $add:expr) => {{
                        let (data, at, add): (*const f32, &[__m256i; 2], __m256i) =
                            ($data, $at, $add);
                        let z = _mm512_setzero_pd();
                        let lo = _mm512_castpd_ps(_mm512_mask_i32gather_pd::<4>(
                            z,
                            masks[0],
                            _mm256_add_epi32(at[0], add),
                            data.cast(),
                        ));
                        let hi = _mm512_castpd_ps(_mm512_mask_i32gather_pd::<4>(
                            z,
                            masks[1],
                            _mm256_add_epi32(at[1], add),
                            data.cast(),
                        ));
                        (
                            _mm512_permutex2var_ps(lo, even, hi),
                            _mm512_permutex2var_ps(lo, odd, hi),
                        )
                    }};
                }
                let down = _mm256_set1_epi32(rw as i32);
                let zero = _mm256_setzero_si256();
                let (a0, a1) = pairs!(l.alpha.as_ptr(), &halves, zero);
                let (a2, a3) = pairs!(l.alpha.as_ptr(), &halves, down);
                let mut a = mix(&w, [a0, a1, a2, a3]);
                // Colour: three times the texel index, the row below 3 · rw further.
                let colour = [
                    _mm256_mullo_epi32(halves[0], _mm256_set1_epi32(3)),
                    _mm256_mullo_epi32(halves[1], _mm256_set1_epi32(3)),
                ];
                let p = l.color.as_ptr();
                let down3 = _mm256_set1_epi32(3 * rw as i32);
                let (r0, g0) = pairs!(p, &colour, zero);
                let (b0, r1) = pairs!(p.add(2), &colour, zero);
                let (g1, b1) = pairs!(p.add(4), &colour, zero);
                let (r2, g2) = pairs!(p, &colour, down3);
                let (b2, r3) = pairs!(p.add(2), &colour, down3);
                let (g3, b3) = pairs!(p.add(4), &colour, down3);
                let mut rgb = [
                    mix(&w, [r0, r1, r2, r3]),
                    mix(&w, [g0, g1, g2, g3]),
                    mix(&w, [b0, b1, b2, b3]),
                ];
                let outside = open & !inside;
                if outside != 0 {
                    let (mut av, mut cv) = ([0.0_f32; 16], [[0.0_f32; 16]; 3]);
                    _mm512_storeu_ps(av.as_mut_ptr(), a);
                    for (k, v) in cv.iter_mut().enumerate() {
                        _mm512_storeu_ps(v.as_mut_ptr(), rgb[k]);
                    }
                    for lane in 0..len {
                        if outside & (1 << lane) != 0 {
                            let (s, [cr, cg, cb]) = sample::<true>(
                                l.alpha,
                                l.color,
                                rw,
                                rh,
                                l.sx[x + lane],
                                l.sy[x + lane],
                            );
                            av[lane] = s;
                            (cv[0][lane], cv[1][lane], cv[2][lane]) = (cr, cg, cb);
                        }
                    }
                    a = _mm512_loadu_ps(av.as_ptr());
                    rgb = [
                        _mm512_loadu_ps(cv[0].as_ptr()),
                        _mm512_loadu_ps(cv[1].as_ptr()),
                        _mm512_loadu_ps(cv[2].as_ptr()),
                    ];
                }
                // Pixels not open have alpha 0 here (no tap gathered), so `t · a` below is 0 and
                // they keep their colour and transmittance to the bit.
                if l.far {
                    a = _mm512_mask_mov_ps(a, open, one);
                }
                // t · a, then each channel c + (t · a) · v fused, then t − t · a.
                let ta = _mm512_mul_ps(tv, a);
                r = _mm512_fmadd_ps(ta, rgb[0], r);
                g = _mm512_fmadd_ps(ta, rgb[1], g);
                b = _mm512_fmadd_ps(ta, rgb[2], b);
                tv = _mm512_sub_ps(tv, ta);
            }
            _mm512_mask_storeu_ps(tp, lanes, tv);
            store_rgb(c.as_mut_ptr().add(4 * x), len, [r, g, b]);
            x += len;
        }
    }
    composited
}

/// `Σ_k w_k · taps_k` as the fused scalar mix rounds it: `w1 · t1 + w0 · t0` fused, then `w2`'s
/// and `w3`'s products fused onto it in turn.
#[inline]
#[target_feature(enable = "avx512f")]
fn mix(w: &[__m512; 4], taps: [__m512; 4]) -> __m512 {
    let s = _mm512_fmadd_ps(w[1], taps[1], _mm512_mul_ps(w[0], taps[0]));
    _mm512_fmadd_ps(w[3], taps[3], _mm512_fmadd_ps(w[2], taps[2], s))
}

/// The red, green and blue of `len ≤ 16` pixels stored four floats apart, as three vectors
/// (lanes from `len` on zero).
///
/// # Safety
/// `p` points to `4 · len` readable floats; the CPU has AVX-512F.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn load_rgb(p: *const f32, len: usize) -> [__m512; 3] {
    let part = |k: usize| -> __mmask16 {
        let n = len.saturating_sub(4 * k).min(4) * 4;
        if n == 16 { 0xffff } else { (1 << n) - 1 }
    };
    // SAFETY: lanes below each mask are inside the 4 · len floats (the caller's promise).
    let q = unsafe {
        [
            _mm512_maskz_loadu_ps(part(0), p),
            _mm512_maskz_loadu_ps(part(1), p.add(16)),
            _mm512_maskz_loadu_ps(part(2), p.add(32)),
            _mm512_maskz_loadu_ps(part(3), p.add(48)),
        ]
    };
    // Pixels 0..8 and 8..16 as [R × 8, G × 8] and [B × 8, X × 8], then the halves joined.
    let rg = _mm512_set_epi32(29, 25, 21, 17, 13, 9, 5, 1, 28, 24, 20, 16, 12, 8, 4, 0);
    let bx = _mm512_set_epi32(31, 27, 23, 19, 15, 11, 7, 3, 30, 26, 22, 18, 14, 10, 6, 2);
    let (rg_lo, rg_hi) = (
        _mm512_permutex2var_ps(q[0], rg, q[1]),
        _mm512_permutex2var_ps(q[2], rg, q[3]),
    );
    let (bx_lo, bx_hi) = (
        _mm512_permutex2var_ps(q[0], bx, q[1]),
        _mm512_permutex2var_ps(q[2], bx, q[3]),
    );
    let first = _mm512_set_epi32(23, 22, 21, 20, 19, 18, 17, 16, 7, 6, 5, 4, 3, 2, 1, 0);
    let second = _mm512_set_epi32(31, 30, 29, 28, 27, 26, 25, 24, 15, 14, 13, 12, 11, 10, 9, 8);
    [
        _mm512_permutex2var_ps(rg_lo, first, rg_hi),
        _mm512_permutex2var_ps(rg_lo, second, rg_hi),
        _mm512_permutex2var_ps(bx_lo, first, bx_hi),
    ]
}

/// [`load_rgb`] turned around: `len` pixels' RGB back four floats apart (the fourth float of
/// each written with its blue, never read).
///
/// # Safety
/// `p` points to `4 · len` writable floats; the CPU has AVX-512F.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn store_rgb(p: *mut f32, len: usize, [r, g, b]: [__m512; 3]) {
    // R and G of pixels 0..8 interleaved, and 8..16; B with itself likewise.
    let lo = _mm512_set_epi32(23, 7, 22, 6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1, 16, 0);
    let hi = _mm512_set_epi32(31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8);
    let (rg_lo, rg_hi) = (
        _mm512_permutex2var_ps(r, lo, g),
        _mm512_permutex2var_ps(r, hi, g),
    );
    let (bb_lo, bb_hi) = (
        _mm512_permutex2var_ps(b, lo, b),
        _mm512_permutex2var_ps(b, hi, b),
    );
    // Pixel pairs: [R G] from the first, [B B] from the second, four pixels a vector.
    let px03 = _mm512_set_epi32(23, 22, 7, 6, 21, 20, 5, 4, 19, 18, 3, 2, 17, 16, 1, 0);
    let px47 = _mm512_set_epi32(31, 30, 15, 14, 29, 28, 13, 12, 27, 26, 11, 10, 25, 24, 9, 8);
    let q = [
        _mm512_permutex2var_ps(rg_lo, px03, bb_lo),
        _mm512_permutex2var_ps(rg_lo, px47, bb_lo),
        _mm512_permutex2var_ps(rg_hi, px03, bb_hi),
        _mm512_permutex2var_ps(rg_hi, px47, bb_hi),
    ];
    for (k, v) in q.iter().enumerate() {
        let n = len.saturating_sub(4 * k).min(4) * 4;
        if n > 0 {
            let m: __mmask16 = if n == 16 { 0xffff } else { (1 << n) - 1 };
            // SAFETY: lanes below n are inside the 4 · len floats (the caller's promise).
            unsafe { _mm512_mask_storeu_ps(p.add(16 * k), m, *v) };
        }
    }
}
