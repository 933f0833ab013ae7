//! The one f32 bilinear kernel of the CPU paths: the renderer's warp and the sweep's plane-sweep
//! volume both sample through it (the f64 reference renderer keeps its own, on purpose: it is
//! what this one is tested against).

/// Weights of the taps `(x0, y0)`, `(x0 + 1, y0)`, `(x0, y0 + 1)`, `(x0 + 1, y0 + 1)` for a
/// sample at `(x0 + ax, y0 + ay)`, `ax, ay ∈ [0, 1)`.
#[inline(always)]
pub(crate) fn weights(ax: f32, ay: f32) -> [f32; 4] {
    [
        (1.0 - ax) * (1.0 - ay),
        ax * (1.0 - ay),
        (1.0 - ax) * ay,
        ax * ay,
    ]
}

/// `Σ_k w_k · taps_k` per channel, the taps in the order of [`weights`] (a tap outside the image
/// is passed as zeros: zero padding).
#[inline(always)]
pub(crate) fn mix<const C: usize>(w: &[f32; 4], taps: [[f32; C]; 4]) -> [f32; C] {
    let mut out = [0.0_f32; C];
    for (c, o) in out.iter_mut().enumerate() {
        *o = w[0] * taps[0][c] + w[1] * taps[1][c] + w[2] * taps[2][c] + w[3] * taps[3][c];
    }
    out
}

/// [`mix`], or with each further product added by a fused multiply-add (`FUSED`: one rounding
/// instead of two, so the last bits differ from [`mix`]'s). Only code compiled for FMA should
/// ask for the fused form: without the instruction `mul_add` is a library call.
#[inline(always)]
pub(crate) fn mix_as<const FUSED: bool, const C: usize>(
    w: &[f32; 4],
    taps: [[f32; C]; 4],
) -> [f32; C] {
    if !FUSED {
        return mix(w, taps);
    }
    let mut out = [0.0_f32; C];
    for (c, o) in out.iter_mut().enumerate() {
        let s = w[1].mul_add(taps[1][c], w[0] * taps[0][c]);
        *o = w[3].mul_add(taps[3][c], w[2].mul_add(taps[2][c], s));
    }
    out
}
