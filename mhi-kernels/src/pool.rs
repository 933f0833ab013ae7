//! Max pooling over `k × k` windows at stride `s` (no padding, no dilation, output rounded
//! down) and its input gradient, one `H × W` plane per task.
//!
//! burn-flex pools through its 3D pooling with an `i64` index per output and a closure per
//! window; on VGG16's shapes its forward took 8 ms for five 64-channel 64 × 64 maps, 16 % of
//! the perceptual loss's forward (`docs/SPEED.md`). Here a forward that autodiff will need to
//! differentiate also keeps, per output, the position of its maximum in its plane (one float,
//! exact up to 2²⁴ positions), and the backward adds each output's gradient there. The window's maximum is burn's (and
//! PyTorch's): the first largest value in row-major order, a NaN winning over any number (the
//! last NaN in the window), so the gradient goes where burn's goes.

use rayon::prelude::*;

/// `planes` maps of `h × w`, pooled over `k × k` windows at stride `s`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PoolShape {
    /// Batch × channels.
    pub planes: usize,
    /// Input height.
    pub h: usize,
    /// Input width.
    pub w: usize,
    /// Window side.
    pub k: usize,
    /// Stride.
    pub s: usize,
}

impl PoolShape {
    /// The shape, or `None` where a window does not fit the map, `k` or `s` is 0, or a plane
    /// has more than 2²⁴ positions (burn's pooling handles those).
    pub fn new(planes: usize, h: usize, w: usize, k: usize, s: usize) -> Option<Self> {
        (k >= 1 && s >= 1 && h >= k && w >= k && h * w <= 1 << 24).then_some(Self {
            planes,
            h,
            w,
            k,
            s,
        })
    }

    /// Output height and width.
    pub fn output(&self) -> (usize, usize) {
        (
            (self.h - self.k) / self.s + 1,
            (self.w - self.k) / self.s + 1,
        )
    }

    /// The largest value of window `(oy, ox)` of `plane` and its index in the plane.
    #[inline(always)]
    fn window_max(&self, plane: &[f32], oy: usize, ox: usize) -> (f32, usize) {
        let (y0, x0) = (oy * self.s, ox * self.s);
        let mut best = (plane[y0 * self.w + x0], y0 * self.w + x0);
        for y in y0..y0 + self.k {
            for x in x0..x0 + self.k {
                best = pick(best, (plane[y * self.w + x], y * self.w + x));
            }
        }
        best
    }

    /// For each window of output row `oy`, its largest value and that value's index.
    #[inline(always)]
    fn row_max(&self, plane: &[f32], oy: usize, mut each: impl FnMut(usize, (f32, usize))) {
        let ow = self.output().1;
        if self.k == 2 && self.s == 2 {
            // VGG16's windows: two rows, two columns, without the general loop's bounds.
            let i0 = 2 * oy * self.w;
            let (r0, r1) = (
                &plane[i0..i0 + self.w],
                &plane[i0 + self.w..i0 + 2 * self.w],
            );
            for ox in 0..ow {
                let x = 2 * ox;
                let mut best = (r0[x], i0 + x);
                best = pick(best, (r0[x + 1], i0 + x + 1));
                best = pick(best, (r1[x], i0 + self.w + x));
                best = pick(best, (r1[x + 1], i0 + self.w + x + 1));
                each(ox, best);
            }
        } else {
            for ox in 0..ow {
                each(ox, self.window_max(plane, oy, ox));
            }
        }
    }
}

/// burn's rule for the running maximum: a larger value or a NaN takes over.
#[inline(always)]
fn pick(best: (f32, usize), next: (f32, usize)) -> (f32, usize) {
    if next.0 > best.0 || next.0.is_nan() {
        next
    } else {
        best
    }
}

/// The pooled maps, `planes × out_h × out_w`.
pub fn forward(p: &PoolShape, x: &[f32]) -> Vec<f32> {
    let (oh, ow) = p.output();
    let mut out = vec![0.0f32; p.planes * oh * ow];
    out.par_chunks_exact_mut((oh * ow).max(1))
        .zip(x.par_chunks_exact((p.h * p.w).max(1)))
        .for_each(|(o, plane)| {
            for (oy, row) in o.chunks_exact_mut(ow.max(1)).enumerate() {
                p.row_max(plane, oy, |ox, (v, _)| row[ox] = v);
            }
        });
    out
}

/// [`forward`], and per output the index of its maximum in its plane, as a float (exact below
/// 2²⁴ positions a plane).
pub fn forward_argmax(p: &PoolShape, x: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let (oh, ow) = p.output();
    let (mut out, mut arg) = (
        vec![0.0f32; p.planes * oh * ow],
        vec![0.0f32; p.planes * oh * ow],
    );
    out.par_chunks_exact_mut((oh * ow).max(1))
        .zip(arg.par_chunks_exact_mut((oh * ow).max(1)))
        .zip(x.par_chunks_exact((p.h * p.w).max(1)))
        .for_each(|((o, a), plane)| {
            let rows = o.chunks_exact_mut(ow.max(1));
            for (oy, (row, at_row)) in rows.zip(a.chunks_exact_mut(ow.max(1))).enumerate() {
                p.row_max(plane, oy, |ox, (v, at)| {
                    row[ox] = v;
                    at_row[ox] = at as f32;
                });
            }
        });
    (out, arg)
}

/// The gradient with respect to the pooling's input, from the maxima's indices `arg` (of
/// [`forward_argmax`]) and the output's gradient `gy`: each output's gradient goes to its
/// window's maximum (summed where windows overlap, in row-major order of the outputs).
pub fn backward(p: &PoolShape, arg: &[f32], gy: &[f32]) -> Vec<f32> {
    let (oh, ow) = p.output();
    let mut gx = vec![0.0f32; p.planes * p.h * p.w];
    gx.par_chunks_exact_mut((p.h * p.w).max(1))
        .zip(arg.par_chunks_exact((oh * ow).max(1)))
        .zip(gy.par_chunks_exact((oh * ow).max(1)))
        .for_each(|((g, a), gyp)| {
            for (&at, &v) in a.iter().zip(gyp) {
                g[at as usize] += v;
            }
        });
    gx
}
