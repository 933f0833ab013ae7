//! The f32 kernels of [`super`]: a 3D convolution over NCDHW slices as tiles of im2col columns
//! multiplied by the weights with `gemm`, and its two gradients.
//!
//! Layouts are burn's: input `[batch, cin, D, H, W]`, weight `[cout, cin, kd, kh, kw]`, output
//! `[batch, cout, D', H', W']`, all contiguous. A tile is a run of consecutive output positions of
//! one batch item; its columns (`cin · kd · kh · kw` rows × tile positions) stay in the core's
//! cache while `gemm` multiplies them, and the result goes straight into the output's rows (no
//! channels-last copy of the input, no transpose of the result). Tiles run in parallel with rayon.

// The gemm crate's API is raw pointers, and tiles write disjoint parts of one output in
// parallel: the workspace's only unsafe code, kept to this file.
#![allow(unsafe_code)]

use rayon::prelude::*;

/// The geometry of one 3D convolution (groups = 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConvShape {
    /// Batch size.
    pub batch: usize,
    /// Input channels.
    pub cin: usize,
    /// Output channels.
    pub cout: usize,
    /// Input extent (D, H, W).
    pub input: [usize; 3],
    /// Kernel extent.
    pub kernel: [usize; 3],
    /// Stride per axis (≥ 1).
    pub stride: [usize; 3],
    /// Dilation per axis (≥ 1).
    pub dilation: [usize; 3],
    /// Zero padding on both sides, per axis.
    pub padding: [usize; 3],
}

impl ConvShape {
    /// Output extent; an axis whose padded input is shorter than the dilated kernel has 0.
    pub fn output(&self) -> [usize; 3] {
        std::array::from_fn(|a| {
            let span = self.dilation[a] * (self.kernel[a] - 1) + 1;
            let padded = self.input[a] + 2 * self.padding[a];
            if padded < span {
                0
            } else {
                (padded - span) / self.stride[a] + 1
            }
        })
    }

    /// Rows of a column tile: one per (input channel, kernel offset).
    pub fn cols(&self) -> usize {
        self.cin * self.kernel.iter().product::<usize>()
    }

    fn in_len(&self) -> usize {
        self.input.iter().product()
    }

    fn out_len(&self) -> usize {
        self.output().iter().product()
    }

    /// Output positions per tile: the tile's columns fit in about 256 KiB.
    fn tile(&self) -> usize {
        let t = (64 * 1024 / self.cols().max(1)).clamp(64, 2048);
        t.min(self.out_len().max(1))
    }

    /// The tiles `(batch item, first position, end)` of the output.
    fn tiles(&self) -> Vec<(usize, usize, usize)> {
        let (n, t) = (self.out_len(), self.tile());
        (0..self.batch)
            .flat_map(|b| (0..n.div_ceil(t)).map(move |i| (b, i * t, ((i + 1) * t).min(n))))
            .collect()
    }
}

/// A raw pointer the tiles share; each tile writes a disjoint set of elements.
#[derive(Clone, Copy)]
struct SharedMut(*mut f32);
// SAFETY: every use writes only the elements of its own tile (disjoint per tile).
unsafe impl Send for SharedMut {}
unsafe impl Sync for SharedMut {}

/// The runs of a tile along output rows: `(offset in the tile, d, h, first w, length)`.
fn runs(out: [usize; 3], p0: usize, p1: usize) -> impl Iterator<Item = [usize; 5]> {
    let plane = out[1] * out[2];
    let mut p = p0;
    std::iter::from_fn(move || {
        if p >= p1 {
            return None;
        }
        let (d, rem) = (p / plane, p % plane);
        let (h, w0) = (rem / out[2], rem % out[2]);
        let n = (out[2] - w0).min(p1 - p);
        let run = [p - p0, d, h, w0, n];
        p += n;
        Some(run)
    })
}

/// The input index of output coordinate `o` at kernel offset `k` along an axis, or `None` in the
/// padding.
#[inline]
fn source(
    o: usize,
    k: usize,
    stride: usize,
    dilation: usize,
    pad: usize,
    len: usize,
) -> Option<usize> {
    (o * stride + k * dilation)
        .checked_sub(pad)
        .filter(|&i| i < len)
}

/// The range of output w in `[w0, w0 + n)` whose source `w · stride + off` lies in `[0, len)`,
/// where `off = k · dilation − pad` may be negative.
#[inline]
fn valid_w(w0: usize, n: usize, stride: usize, off: isize, len: usize) -> (usize, usize) {
    // w · s + off ≥ 0  ⇔  w ≥ ceil(−off / s);  w · s + off < len  ⇔  w < ceil((len − off) / s).
    let ceil_div = |a: isize, s: isize| {
        if a <= 0 {
            0
        } else {
            ((a + s - 1) / s) as usize
        }
    };
    let (s, len) = (stride as isize, len as isize);
    let lo = ceil_div(-off, s).clamp(w0, w0 + n);
    let hi = ceil_div(len - off, s).clamp(lo, w0 + n);
    (lo, hi)
}

/// Where the kernel offset `(a, b, c)` reads for the output run `(d, h, w0..w0 + n)`: the input
/// row (`z · H + y`), the run's part `[lo, hi)` that lies inside the input and its first input
/// column; `None` when the whole run reads padding.
#[inline]
fn tap(
    s: &ConvShape,
    [d, h, w0, n]: [usize; 4],
    [a, b, c]: [usize; 3],
) -> Option<(usize, usize, usize, usize)> {
    let z = source(d, a, s.stride[0], s.dilation[0], s.padding[0], s.input[0])?;
    let y = source(h, b, s.stride[1], s.dilation[1], s.padding[1], s.input[1])?;
    let off = (c * s.dilation[2]) as isize - s.padding[2] as isize;
    let (lo, hi) = valid_w(w0, n, s.stride[2], off, s.input[2]);
    let first = if lo == hi {
        0
    } else {
        (lo as isize * s.stride[2] as isize + off) as usize
    };
    Some((z * s.input[1] + y, lo, hi, first))
}

/// Calls `f(row of the column tile, offset in the tile, w0, n, tap)` for every kernel offset,
/// input channel and run of the tile `[p0, p1)`; the tap is computed once per offset and run and
/// shared by the input channels.
fn for_each_tap(
    s: &ConvShape,
    p0: usize,
    p1: usize,
    mut f: impl FnMut(usize, usize, usize, usize, usize, Option<(usize, usize, usize, usize)>),
) {
    let [kd, kh, kw] = s.kernel;
    let kk = kd * kh * kw;
    for [o, d, h, w0, n] in runs(s.output(), p0, p1) {
        for a in 0..kd {
            for b in 0..kh {
                for c in 0..kw {
                    let tap = tap(s, [d, h, w0, n], [a, b, c]);
                    let k = (a * kh + b) * kw + c;
                    for ci in 0..s.cin {
                        f(ci * kk + k, ci, o, w0, n, tap);
                    }
                }
            }
        }
    }
}

/// Fills `col` (`cols × t`, row-major) with the patches of output positions `[p0, p1)` of the
/// batch item `x` (`cin × D × H × W`).
fn im2col(s: &ConvShape, x: &[f32], p0: usize, p1: usize, col: &mut [f32]) {
    let t = p1 - p0;
    let (in_len, iw, sw) = (s.in_len(), s.input[2], s.stride[2]);
    for_each_tap(s, p0, p1, |r, ci, o, w0, n, tap| {
        let dst = &mut col[r * t + o..r * t + o + n];
        let Some((row, lo, hi, first)) = tap else {
            dst.fill(0.0);
            return;
        };
        dst[..lo - w0].fill(0.0);
        dst[hi - w0..].fill(0.0);
        let src = &x[ci * in_len + row * iw..ci * in_len + (row + 1) * iw];
        let dst = &mut dst[lo - w0..hi - w0];
        if sw == 1 {
            dst.copy_from_slice(&src[first..first + dst.len()]);
        } else {
            for (i, v) in dst.iter_mut().enumerate() {
                *v = src[first + i * sw];
            }
        }
    });
}

/// Adds `col` (`cols × t`) back onto the batch item `gx` (`cin × D × H × W`): the adjoint of
/// [`im2col`].
fn col2im(s: &ConvShape, col: &[f32], p0: usize, p1: usize, gx: &mut [f32]) {
    let t = p1 - p0;
    let (in_len, iw, sw) = (s.in_len(), s.input[2], s.stride[2]);
    for_each_tap(s, p0, p1, |r, ci, o, w0, _, tap| {
        let Some((row, lo, hi, first)) = tap else {
            return;
        };
        let dst = &mut gx[ci * in_len + row * iw..ci * in_len + (row + 1) * iw];
        for (i, v) in col[r * t + o + lo - w0..r * t + o + hi - w0]
            .iter()
            .enumerate()
        {
            dst[first + i * sw] += v;
        }
    });
}

/// `dst (m × n) = [dst +] lhs (m × k) · rhs (k × n)`, each given by its row and column strides.
///
/// # Safety
/// Every pointer must cover its matrix at the given strides; `dst` must not alias the others.
#[allow(clippy::too_many_arguments)]
unsafe fn gemm(
    [m, n, k]: [usize; 3],
    dst: *mut f32,
    [dst_rs, dst_cs]: [isize; 2],
    accumulate: bool,
    lhs: *const f32,
    [lhs_rs, lhs_cs]: [isize; 2],
    rhs: *const f32,
    [rhs_rs, rhs_cs]: [isize; 2],
) {
    // SAFETY: forwarded from the caller.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            dst,
            dst_cs,
            dst_rs,
            accumulate,
            lhs,
            lhs_cs,
            lhs_rs,
            rhs,
            rhs_cs,
            rhs_rs,
            1.0f32,
            1.0f32,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
}

/// The convolution `x ⋆ w (+ bias)`: `x` is `batch × cin × D × H × W`, `w` is `cout × cols`.
pub fn forward(s: &ConvShape, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let (sp, k) = (s.out_len(), s.cols());
    let mut out = vec![0.0f32; s.batch * s.cout * sp];
    if sp == 0 || s.batch == 0 || s.cout == 0 {
        return out;
    }
    if let Some(bias) = bias {
        for row in out.chunks_exact_mut(sp).enumerate() {
            row.1.fill(bias[row.0 % s.cout]);
        }
    }
    let dst = SharedMut(out.as_mut_ptr());
    let in_len = s.cin * s.in_len();
    s.tiles()
        .into_par_iter()
        .for_each_init(Vec::new, |col, (b, p0, p1)| {
            let t = p1 - p0;
            col.resize(k * t, 0.0);
            im2col(s, &x[b * in_len..(b + 1) * in_len], p0, p1, col);
            let d = dst;
            // SAFETY: the tile writes rows `cout` × positions `[p0, p1)` of batch item `b` only;
            // `col` and `w` cover `k × t` and `cout × k`.
            unsafe {
                gemm(
                    [s.cout, t, k],
                    d.0.add(b * s.cout * sp + p0),
                    [sp as isize, 1],
                    true,
                    w.as_ptr(),
                    [k as isize, 1],
                    col.as_ptr(),
                    [t as isize, 1],
                )
            }
        });
    out
}

/// The gradient of the convolution with respect to its weight (`cout × cols`), from its input
/// `x` and the gradient of its output `gy`.
pub fn grad_weight(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
    let (sp, k) = (s.out_len(), s.cols());
    let in_len = s.cin * s.in_len();
    let zero = || (vec![0.0f32; s.cout * k], Vec::new());
    s.tiles()
        .into_par_iter()
        .fold(zero, |(mut gw, mut col), (b, p0, p1)| {
            let t = p1 - p0;
            col.resize(k * t, 0.0);
            im2col(s, &x[b * in_len..(b + 1) * in_len], p0, p1, &mut col);
            // SAFETY: gw is cout × k; gy's tile is cout rows of t at stride sp; col is k × t,
            // read transposed.
            unsafe {
                gemm(
                    [s.cout, k, t],
                    gw.as_mut_ptr(),
                    [k as isize, 1],
                    true,
                    gy.as_ptr().add(b * s.cout * sp + p0),
                    [sp as isize, 1],
                    col.as_ptr(),
                    [1, t as isize],
                )
            }
            (gw, col)
        })
        .map(|(gw, _)| gw)
        .reduce(
            || vec![0.0f32; s.cout * k],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
                a
            },
        )
}

/// The gradient of the convolution with respect to its input (`batch × cin × D × H × W`), from
/// its weight `w` and the gradient of its output `gy`.
pub fn grad_input(s: &ConvShape, w: &[f32], gy: &[f32]) -> Vec<f32> {
    if let Some((t, wt)) = transposed_as_conv(s, w) {
        return forward(&t, gy, &wt, None);
    }
    let (sp, k) = (s.out_len(), s.cols());
    let in_len = s.cin * s.in_len();
    let mut gx = vec![0.0f32; s.batch * in_len];
    let t = s.tile();
    gx.par_chunks_exact_mut(in_len.max(1))
        .enumerate()
        .for_each(|(b, gxb)| {
            let mut col = vec![0.0f32; k * t];
            for p0 in (0..sp).step_by(t) {
                let p1 = (p0 + t).min(sp);
                let n = p1 - p0;
                // SAFETY: col is k × n; w (cout × k) read transposed; gy's tile cout × n at stride sp.
                unsafe {
                    gemm(
                        [k, n, s.cout],
                        col.as_mut_ptr(),
                        [n as isize, 1],
                        false,
                        w.as_ptr(),
                        [1, k as isize],
                        gy.as_ptr().add(b * s.cout * sp + p0),
                        [sp as isize, 1],
                    )
                }
                col2im(s, &col[..k * n], p0, p1, gxb);
            }
        });
    gx
}

/// A stride-1 convolution's input gradient is itself a convolution of the output gradient, with
/// the kernel flipped and its channels swapped: returns that convolution's shape and weight, or
/// `None` where it does not apply (a stride above 1, or padding wider than the dilated kernel).
fn transposed_as_conv(s: &ConvShape, w: &[f32]) -> Option<(ConvShape, Vec<f32>)> {
    if s.stride != [1, 1, 1] {
        return None;
    }
    let mut padding = [0; 3];
    for (a, p) in padding.iter_mut().enumerate() {
        *p = (s.dilation[a] * (s.kernel[a] - 1)).checked_sub(s.padding[a])?;
    }
    let t = ConvShape {
        batch: s.batch,
        cin: s.cout,
        cout: s.cin,
        input: s.output(),
        kernel: s.kernel,
        stride: [1, 1, 1],
        dilation: s.dilation,
        padding,
    };
    if t.output() != s.input {
        return None;
    }
    let kk: usize = s.kernel.iter().product();
    let mut wt = vec![0.0f32; s.cin * s.cout * kk];
    for co in 0..s.cout {
        for ci in 0..s.cin {
            for o in 0..kk {
                wt[(ci * s.cout + co) * kk + (kk - 1 - o)] = w[(co * s.cin + ci) * kk + o];
            }
        }
    }
    Some((t, wt))
}

/// The gradient of the bias: the output gradient summed over batch and positions.
pub fn grad_bias(s: &ConvShape, gy: &[f32]) -> Vec<f32> {
    let sp = s.out_len();
    let mut gb = vec![0.0f32; s.cout];
    if sp == 0 {
        return gb;
    }
    for (i, row) in gy.chunks_exact(sp).enumerate() {
        gb[i % s.cout] += row.iter().map(|&v| f64::from(v)).sum::<f64>() as f32;
    }
    gb
}
