//! The f32 kernels of [`super`]: a 3D convolution over NCDHW slices as tiles of im2col columns
//! multiplied by the weights with `gemm`, and its two gradients.
//!
//! Layouts are burn's: input `[batch, cin, D, H, W]`, weight `[cout, cin, kd, kh, kw]`, output
//! `[batch, cout, D', H', W']`, all contiguous. A tile is a run of consecutive output positions of
//! one batch item; its columns (`cin · kd · kh · kw` rows × tile positions) stay in the core's
//! cache while `gemm` multiplies them, and the result goes straight into the output's rows (no
//! channels-last copy of the input, no transpose of the result). Tiles run in parallel with rayon.
//!
//! Stride-1 convolutions with few output channels (every stride-1 convolution of stage 1 and the
//! blending network, VGG16's 64-channel layers) skip im2col ([`forward_direct`],
//! [`grad_weight_direct`]): the input is padded once and each kernel offset is one product read
//! at a shifted origin of it, in place.

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
    if direct_applies(s) {
        return forward_direct(s, x, w, bias);
    }
    im2col_forward(s, x, w, bias)
}

/// [`forward`] through im2col tiles.
pub fn im2col_forward(s: &ConvShape, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
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

/// The padded input of a stride-1 convolution for the direct kernels, and their work plan.
///
/// Each channel's depth slices are padded to `hp × wp` and stored `slice` apart (`hp · wp`
/// rounded up to whole SIMD blocks, so that every product reads the input in place); zeros
/// follow so that the reads of the dropped positions stay inside. An output position `(z, h, w)`
/// is "wide" index `z · slice + h · wp + w` (the indices past the output's rows and columns are
/// computed and dropped); for the kernel offset `(a, b, c)` it reads the padded input at that
/// index plus `(a · dd − pd) · slice + b · dh · wp + c · dw`. A job is a block of consecutive
/// wide indices of one batch item, small enough that its `cout` output rows stay in the core's
/// cache while every kernel offset adds to them.
struct Padded {
    data: Vec<f32>,
    /// Padded row length.
    wp: usize,
    /// Stride between depth slices, channels and batch items.
    slice: usize,
    chan: usize,
    item: usize,
    /// Wide indices per job (a multiple of 8).
    block: usize,
}

impl Padded {
    fn new(s: &ConvShape, x: &[f32]) -> Self {
        let [d, h, w] = s.input;
        let (hp, wp) = (h + 2 * s.padding[1], w + 2 * s.padding[2]);
        let slice = (hp * wp).div_ceil(8) * 8;
        let chan = d * slice;
        let item = s.cin * chan;
        let mut data = vec![0.0f32; s.batch * item + slice + 8];
        data[..s.batch * item]
            .par_chunks_exact_mut(slice)
            .zip(x.par_chunks_exact(h * w))
            .for_each(|(dst, src)| {
                for (y, row) in src.chunks_exact(w).enumerate() {
                    let at = (y + s.padding[1]) * wp + s.padding[2];
                    dst[at..at + w].copy_from_slice(row);
                }
            });
        // The job's output rows in about 256 KiB; at least two jobs per thread where the
        // output allows, its indices shared evenly.
        let total = s.output()[0] * slice;
        let mut jobs = total.div_ceil((65536 / s.cout.max(1)).clamp(512, 8192));
        let threads = rayon::current_num_threads().max(1);
        if s.batch * jobs < 2 * threads {
            jobs = (2 * threads).div_ceil(s.batch.max(1));
        }
        let block = total.div_ceil(jobs.max(1)).div_ceil(8) * 8;
        Padded {
            data,
            wp,
            slice,
            chan,
            item,
            block: block.max(8),
        }
    }

    /// The jobs `(batch item, first wide index, end)`.
    fn jobs(&self, s: &ConvShape) -> Vec<(usize, usize, usize)> {
        let total = s.output()[0] * self.slice;
        (0..s.batch)
            .flat_map(|b| {
                (0..total)
                    .step_by(self.block)
                    .map(move |g0| (b, g0, (g0 + self.block).min(total)))
            })
            .collect()
    }

    /// Calls `f(kernel index, first wide index, end, input origin)` for each kernel offset with
    /// the part of the job `[g0, g1)` whose input depth slice is inside; the origin is the padded
    /// input's index read for the part's first wide index.
    fn for_each_tap(
        &self,
        s: &ConvShape,
        (b, g0, g1): (usize, usize, usize),
        mut f: impl FnMut(usize, usize, usize, usize),
    ) {
        let [kd, kh, kw] = s.kernel;
        let od = s.output()[0] as isize;
        for a in 0..kd {
            // The input slice z = zo + a · dd − pd must lie in [0, D).
            let shift = (a * s.dilation[0]) as isize - s.padding[0] as isize;
            let zlo = (-shift).clamp(0, od) as usize;
            let zhi = (s.input[0] as isize - shift).clamp(0, od) as usize;
            let lo = (zlo * self.slice).max(g0);
            let hi = (zhi * self.slice).min(g1);
            if lo >= hi {
                continue;
            }
            let at = (b * self.item + lo) as isize + shift * self.slice as isize;
            for bb in 0..kh {
                for c in 0..kw {
                    let k = (a * kh + bb) * kw + c;
                    let origin = at as usize + bb * s.dilation[1] * self.wp + c * s.dilation[2];
                    f(k, lo, hi, origin);
                }
            }
        }
    }

    /// Calls `f(output index, wide index, length)` for each part of an output row that lies in
    /// the wide indices `[g0, g1)`, output indices within the batch item's channel.
    fn for_each_row(
        &self,
        s: &ConvShape,
        g0: usize,
        g1: usize,
        mut f: impl FnMut(usize, usize, usize),
    ) {
        let o = s.output();
        for zo in g0 / self.slice..g1.div_ceil(self.slice).min(o[0]) {
            for h in 0..o[1] {
                let start = zo * self.slice + h * self.wp;
                let (lo, hi) = (start.max(g0), (start + o[2]).min(g1));
                if lo < hi {
                    f((zo * o[1] + h) * o[2] + (lo - start), lo, hi - lo);
                }
            }
        }
    }
}

/// Whether [`forward`] goes through [`forward_direct`]: stride 1, enough input channels that a
/// product per kernel offset keeps `gemm` busy, few enough output channels that gemm reads the
/// input in place, and padding narrow enough that the dropped wide positions cost little.
/// Measured by `direct_against_im2col_timing` (docs/SPEED.md): 1.4–2× faster on stage 1's
/// undilated shapes (8–32 channels), slower on VGG16's 128- and 512-channel layers, on 3-channel
/// inputs and on the dilation-4 convolutions at 16 × 16 (2.25 wide positions per output).
pub fn direct_applies(s: &ConvShape) -> bool {
    s.cin >= 8 && s.cout <= 64 && direct_shape(s)
}

/// Whether [`grad_weight`] goes through [`grad_weight_direct`]: as [`direct_applies`] but with
/// any number of input channels and at most 32 output channels (1.2–2.4× faster on stage 1's
/// undilated shapes, even with 6 input channels; no gain from 64 output channels on).
pub fn direct_grad_weight_applies(s: &ConvShape) -> bool {
    s.cout <= 32 && direct_shape(s)
}

/// Stride 1, a non-empty output and at most 1.5 wide positions per output position.
fn direct_shape(s: &ConvShape) -> bool {
    let o = s.output();
    let wide = (s.input[1] + 2 * s.padding[1]) * (s.input[2] + 2 * s.padding[2]);
    s.stride == [1, 1, 1] && o.iter().all(|&o| o > 0) && 2 * wide <= 3 * o[1] * o[2]
}

/// A stride-1 convolution without im2col: for each job (a block of wide indices of one batch
/// item), one product per kernel offset of the weights' `cout × cin` slice with the padded
/// input read at a shifted origin, accumulated in the job's output rows. The input is copied
/// once, padded, instead of once per kernel offset.
pub fn forward_direct(s: &ConvShape, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let sp: usize = s.output().iter().product();
    let mut out = vec![0.0f32; s.batch * s.cout * sp];
    if sp == 0 || s.batch == 0 || s.cout == 0 {
        return out;
    }
    let kk: usize = s.kernel.iter().product();
    let p = Padded::new(s, x);
    let q = p.block;
    let dst = SharedMut(out.as_mut_ptr());
    p.jobs(s)
        .into_par_iter()
        .for_each_init(Vec::new, |wide: &mut Vec<f32>, job| {
            let (b, g0, g1) = job;
            wide.clear();
            wide.resize(s.cout * q, 0.0);
            p.for_each_tap(s, job, |k, lo, hi, origin| {
                // SAFETY: `wide` is cout × q, written from column lo − g0 for hi − lo ≤ q
                // positions; the input view is that many positions × cin from `origin` at
                // channel stride `chan`, inside `data` (its zeros past the end cover the dropped
                // positions' reads); the weights cin × cout at strides (kk, cin · kk).
                unsafe {
                    gemm(
                        [hi - lo, s.cout, s.cin],
                        wide.as_mut_ptr().add(lo - g0),
                        [1, q as isize],
                        true,
                        p.data.as_ptr().add(origin),
                        [1, p.chan as isize],
                        w.as_ptr().add(k),
                        [kk as isize, (s.cin * kk) as isize],
                    )
                }
            });
            let d = dst;
            p.for_each_row(s, g0, g1, |at, g, n| {
                for co in 0..s.cout {
                    let add = bias.map_or(0.0, |bias| bias[co]);
                    let src = &wide[co * q + g - g0..co * q + g - g0 + n];
                    // SAFETY: the job writes only the output positions of its own wide
                    // indices, of batch item b.
                    let row = unsafe {
                        std::slice::from_raw_parts_mut(d.0.add((b * s.cout + co) * sp + at), n)
                    };
                    row.iter_mut().zip(src).for_each(|(r, v)| *r = v + add);
                }
            });
        });
    out
}

/// The gradient of the convolution with respect to its weight (`cout × cols`), from its input
/// `x` and the gradient of its output `gy`.
pub fn grad_weight(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
    if direct_grad_weight_applies(s) {
        return grad_weight_direct(s, x, gy);
    }
    im2col_grad_weight(s, x, gy)
}

/// [`grad_weight`] through im2col tiles.
pub fn im2col_grad_weight(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
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

/// [`grad_weight`] without im2col, for stride-1 convolutions: per job, the output gradient laid
/// out at the job's wide indices (zeros at the dropped ones) times the padded input read at
/// each kernel offset's shifted origin.
pub fn grad_weight_direct(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
    let sp: usize = s.output().iter().product();
    let kk: usize = s.kernel.iter().product();
    let k = s.cols();
    if sp == 0 || s.batch == 0 || s.cout == 0 {
        return vec![0.0f32; s.cout * k];
    }
    let p = Padded::new(s, x);
    let q = p.block;
    let zero = || (vec![0.0f32; s.cout * k], Vec::new());
    p.jobs(s)
        .into_par_iter()
        .fold(zero, |(mut gw, mut wide), job| {
            let (b, g0, g1) = job;
            wide.clear();
            wide.resize(s.cout * q, 0.0);
            p.for_each_row(s, g0, g1, |at, g, n| {
                for co in 0..s.cout {
                    let from = (b * s.cout + co) * sp + at;
                    wide[co * q + g - g0..co * q + g - g0 + n].copy_from_slice(&gy[from..from + n]);
                }
            });
            p.for_each_tap(s, job, |kidx, lo, hi, origin| {
                // SAFETY: gw is cout × (cin · kk), written at column stride kk from `kidx`;
                // `wide` is cout × q, read from column lo − g0 for hi − lo positions (zeros at
                // the dropped ones); the input view is those positions × cin from `origin` at
                // channel stride `chan`, inside `data`.
                unsafe {
                    gemm(
                        [s.cout, s.cin, hi - lo],
                        gw.as_mut_ptr().add(kidx),
                        [k as isize, kk as isize],
                        true,
                        wide.as_ptr().add(lo - g0),
                        [q as isize, 1],
                        p.data.as_ptr().add(origin),
                        [1, p.chan as isize],
                    )
                }
            });
            (gw, wide)
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
