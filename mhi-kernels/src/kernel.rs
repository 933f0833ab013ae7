//! The f32 kernels of [`super`]: a 3D convolution over NCDHW slices as tiles of im2col columns
//! multiplied by the weights with `gemm`, and its two gradients.
//!
//! Layouts are burn's: input `[batch, cin, D, H, W]`, weight `[cout, cin, kd, kh, kw]`, output
//! `[batch, cout, D', H', W']`, all contiguous. A tile is a run of consecutive output positions of
//! one batch item; its columns (`cin · kd · kh · kw` rows × tile positions) stay in the core's
//! cache while `gemm` multiplies them, and the result goes straight into the output's rows (no
//! channels-last copy of the input, no transpose of the result). Tiles run in parallel with rayon.
//!
//! Convolutions with few output channels and stride 1 in depth (every convolution of stage 1
//! and the blending network, VGG16's 64-channel layers) skip im2col ([`forward_direct`],
//! [`grad_weight_direct`]): the input is padded once and split into its polyphase components
//! (one for stride 1, four for stride 2 in the image axes), so every kernel offset reads one
//! component at a shifted origin, in place. The forward then runs as a register-blocked AVX2 +
//! FMA kernel ([`blocked`]) where the CPU has both and the output channels come in blocks of 8
//! (its tiles AVX-512 wide where the CPU has AVX-512F and the channels come in blocks of 16),
//! else as one `gemm` per kernel offset.

// The gemm crate's API is raw pointers, tiles write disjoint parts of one output in parallel,
// and the blocked kernel's AVX2 intrinsics are `unsafe` calls: the network's only unsafe code,
// kept to this file.
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

/// The padded input of a convolution for the direct kernels, and their work plan.
///
/// The input is padded to `hp × wp` per depth slice and split into its `sy · sx` polyphase
/// components (pixel `(Y, X)` of the padded slice goes to phase `(Y mod sy, X mod sx)` at row
/// `Y / sy`, column `X / sx` of a `hq × wq` phase image), so that a stride-`(1, sy, sx)`
/// convolution reads every kernel offset from one phase at a unit stride; with stride 1 there is
/// one phase, the padded input itself. Each phase image is stored `slice` apart (`hq · wq`
/// rounded up to whole SIMD blocks), a channel's phases `phase` apart, and zeros follow so that
/// the reads of the dropped positions stay inside. An output position `(z, h, w)` is "wide"
/// index `z · slice + h · wq + w` (the columns past the output's row are computed and dropped);
/// for the kernel offset `(a, b, c)` it reads phase `(b · dh mod sy, c · dw mod sx)` at that
/// index plus `(a · dd − pd) · slice + (b · dh / sy) · wq + c · dw / sx`. A job is one batch
/// item's output rows `[h0, h1)` of the depth slices `[z0, z1)`, a segment of wide indices per
/// slice (the padding rows between slices are never computed), small enough that its `cout`
/// output rows stay in the core's cache while every kernel offset adds to them.
struct Padded {
    data: Vec<f32>,
    /// Phase image row length.
    wq: usize,
    /// Phase counts `[sy, sx]`: along the padded columns (rows' phases) and along the rows.
    phases: [usize; 2],
    /// Stride between depth slices of one phase.
    slice: usize,
    /// Stride between the phases of one channel.
    phase: usize,
    /// Stride between channels and between batch items.
    chan: usize,
    item: usize,
    /// Jobs' (batch item, z0, z1, h0, h1).
    jobs: Vec<(usize, usize, usize, usize, usize)>,
    /// The most columns a job's segments take (a multiple of 8).
    q: usize,
}

impl Padded {
    fn new(s: &ConvShape, x: &[f32]) -> Self {
        assert!(
            s.stride[0] == 1,
            "the direct kernels take stride 1 in depth"
        );
        let [d, h, w] = s.input;
        let [sy, sx] = [s.stride[1], s.stride[2]];
        let (hp, wp) = (h + 2 * s.padding[1], w + 2 * s.padding[2]);
        let (hq, wq) = (hp.div_ceil(sy), wp.div_ceil(sx));
        let slice = (hq * wq).div_ceil(8) * 8;
        let phase = d * slice;
        let chan = sy * sx * phase;
        let item = s.cin * chan;
        // The slack after the last slice: a tile reads up to 48 positions past its start.
        let len = s.batch * item + 2 * slice + 64;
        let mut data: Vec<f32> = Vec::with_capacity(len);
        // One channel of one batch item per task: its region zeroed (in the core's cache, in
        // parallel, rather than one serial memset of the whole buffer first), then each padded
        // depth slice's rows scattered to the phases.
        let spare = &mut data.spare_capacity_mut()[..len];
        // Unit tests start from NaN everywhere, so that a position the writes below miss shows.
        #[cfg(test)]
        spare.fill(std::mem::MaybeUninit::new(f32::NAN));
        let (body, slack) = spare.split_at_mut(s.batch * item);
        slack.fill(std::mem::MaybeUninit::new(0.0));
        body.par_chunks_exact_mut(chan)
            .zip(x.par_chunks_exact(d * h * w))
            .for_each(|(dst, src)| {
                let zero = std::mem::MaybeUninit::new(0.0);
                if sy == 1 && sx == 1 {
                    // One phase: only the padding around each slice's rows (and the slice's
                    // rounding) is zeroed; the rows' values are written below.
                    let (ph, pw) = (s.padding[1], s.padding[2]);
                    for z in 0..d {
                        let at = z * slice;
                        dst[at..at + ph * wq].fill(zero);
                        for y in 0..h {
                            let row = at + (ph + y) * wq;
                            dst[row..row + pw].fill(zero);
                            dst[row + pw + w..row + wq].fill(zero);
                        }
                        dst[at + (ph + h) * wq..at + slice].fill(zero);
                    }
                    // (`chan` is `d · slice` here: nothing follows the last slice.)
                } else {
                    dst.fill(zero);
                }
                for (z, plane) in src.chunks_exact(h * w).enumerate() {
                    for (y, row) in plane.chunks_exact(w).enumerate() {
                        let yp = y + s.padding[1];
                        let base = (yp % sy) * sx * phase + z * slice + (yp / sy) * wq;
                        if sx == 1 {
                            let at = base + s.padding[2];
                            for (o, &v) in dst[at..at + w].iter_mut().zip(row) {
                                *o = std::mem::MaybeUninit::new(v);
                            }
                            continue;
                        }
                        // Phase px of this row holds the padded columns px, px + sx, …: the
                        // row's values from index (px − pad) mod sx on, every sx-th.
                        for px in 0..sx {
                            let first = (px + sx - s.padding[2] % sx) % sx;
                            let xp0 = first + s.padding[2];
                            let at = base + px * phase + xp0 / sx;
                            let vals = row.iter().skip(first).step_by(sx);
                            for (o, &v) in dst[at..].iter_mut().zip(vals) {
                                *o = std::mem::MaybeUninit::new(v);
                            }
                        }
                    }
                }
            });
        // SAFETY: every element of `..len` was written above (the body chunk by chunk, which
        // covers `batch · item` exactly as `chan` divides it, and the slack).
        unsafe { data.set_len(len) };
        // Jobs of about 256 KiB of output rows; at least two per thread where the output allows.
        let [od, oh, _] = s.output();
        let target = (65536 / s.cout.max(1)).clamp(512, 8192);
        let threads = rayon::current_num_threads().max(1);
        let per_slice = oh * wq;
        let mut jobs = Vec::new();
        if per_slice >= target || s.batch * od < 2 * threads {
            // Row chunks of one slice each.
            let mut chunks = per_slice.div_ceil(target).max(1);
            if s.batch * od * chunks < 2 * threads {
                chunks = (2 * threads).div_ceil(s.batch * od.max(1));
            }
            let rows = oh.div_ceil(chunks.min(oh).max(1));
            for b in 0..s.batch {
                for z in 0..od {
                    for h0 in (0..oh).step_by(rows.max(1)) {
                        jobs.push((b, z, z + 1, h0, (h0 + rows).min(oh)));
                    }
                }
            }
        } else {
            // Whole slices, several per job.
            let mut group = (target / per_slice.max(1)).clamp(1, od);
            while group > 1 && s.batch * od.div_ceil(group) < 2 * threads {
                group -= 1;
            }
            for b in 0..s.batch {
                for z0 in (0..od).step_by(group) {
                    jobs.push((b, z0, (z0 + group).min(od), 0, oh));
                }
            }
        }
        let q = jobs
            .iter()
            .map(|&(_, z0, z1, h0, h1)| (z1 - z0) * (h1 - h0) * wq)
            .max()
            .unwrap_or(0)
            .div_ceil(8)
            * 8;
        Padded {
            data,
            wq,
            phases: [sy, sx],
            slice,
            phase,
            chan,
            item,
            jobs,
            q: q.max(8),
        }
    }

    /// Calls `f(kernel index, first column of the job's buffer, length, input origin)` for each
    /// kernel offset and each of the job's depth slices whose input slice is inside; the origin
    /// is the padded input's index read for the segment's first wide index.
    fn for_each_tap(
        &self,
        s: &ConvShape,
        (b, z0, z1, h0, h1): (usize, usize, usize, usize, usize),
        mut f: impl FnMut(usize, usize, usize, usize),
    ) {
        let [kd, kh, kw] = s.kernel;
        let [sy, sx] = self.phases;
        let len = (h1 - h0) * self.wq;
        for a in 0..kd {
            // The input slice z = zo + a · dd − pd must lie in [0, D).
            let shift = (a * s.dilation[0]) as isize - s.padding[0] as isize;
            for (i, z) in (z0..z1).enumerate() {
                let zi = z as isize + shift;
                if zi < 0 || zi >= s.input[0] as isize {
                    continue;
                }
                let at = b * self.item + zi as usize * self.slice + h0 * self.wq;
                for bb in 0..kh {
                    let (py, qy) = ((bb * s.dilation[1]) % sy, (bb * s.dilation[1]) / sy);
                    for c in 0..kw {
                        let (px, qx) = ((c * s.dilation[2]) % sx, (c * s.dilation[2]) / sx);
                        let k = (a * kh + bb) * kw + c;
                        let origin = at + (py * sx + px) * self.phase + qy * self.wq + qx;
                        f(k, i * len, len, origin);
                    }
                }
            }
        }
    }

    /// Every tap of each of the job's depth slices at once: `(first column of the job's buffer,
    /// length, [(kernel index, input origin)])`, the taps whose input slice is inside.
    fn segments(
        &self,
        s: &ConvShape,
        (b, z0, z1, h0, h1): (usize, usize, usize, usize, usize),
    ) -> Vec<Segment> {
        let len = (h1 - h0) * self.wq;
        let mut out: Vec<_> = (0..z1 - z0).map(|i| (i * len, len, Vec::new())).collect();
        self.for_each_tap(s, (b, z0, z1, h0, h1), |k, col, _, origin| {
            out[col / len.max(1)].2.push((k, origin));
        });
        out
    }

    /// Writes the job's buffer `wide` (`cout` rows of `q` columns) to its output rows in `out`
    /// (the whole `batch × cout × D' × H' × W'` output), adding the bias; the dropped columns
    /// are left out.
    fn write_rows(
        &self,
        s: &ConvShape,
        job: (usize, usize, usize, usize, usize),
        wide: &[f32],
        q: usize,
        bias: Option<&[f32]>,
        out: SharedMut,
    ) {
        let sp: usize = s.output().iter().product();
        let b = job.0;
        self.for_each_row(s, job, |at, col, n| {
            for co in 0..s.cout {
                let add = bias.map_or(0.0, |bias| bias[co]);
                let src = &wide[co * q + col..co * q + col + n];
                // SAFETY: the job writes only the output positions of its own rows, of batch
                // item b; `out` covers the whole output.
                let row = unsafe {
                    std::slice::from_raw_parts_mut(out.0.add((b * s.cout + co) * sp + at), n)
                };
                row.iter_mut().zip(src).for_each(|(r, v)| *r = v + add);
            }
        });
    }

    /// Calls `f(output index, column of the job's buffer, length)` for each output row of the
    /// job, output indices within the batch item's channel.
    fn for_each_row(
        &self,
        s: &ConvShape,
        (_, z0, z1, h0, h1): (usize, usize, usize, usize, usize),
        mut f: impl FnMut(usize, usize, usize),
    ) {
        let [_, oh, ow] = s.output();
        let len = (h1 - h0) * self.wq;
        for (i, z) in (z0..z1).enumerate() {
            for h in h0..h1 {
                f((z * oh + h) * ow, i * len + (h - h0) * self.wq, ow);
            }
        }
    }
}

/// One depth slice of a job: its first column in the job's buffer, its length, and its taps
/// `(kernel index, input origin)`.
type Segment = (usize, usize, Vec<(usize, usize)>);

/// Whether [`forward`] goes through [`forward_direct`] (measured by
/// `direct_against_im2col_timing`, docs/SPEED.md). With the register-blocked kernel
/// ([`blocked`]: AVX2 and FMA, output channels in blocks of 8): at least 4 input channels, at
/// most 64 output channels and 1.5 wide positions per output — every convolution of stage 1
/// (the stem 1.6×, the strided ones 1.3–1.4×, the dilation-4 ones 1.1× faster than im2col) and
/// VGG16's 64-channel layers; not 3-channel inputs (VGG16's first layer) nor 128 output channels
/// and more, where one im2col product is faster. Without it (one `gemm` per kernel offset): at
/// least 8 input channels and at most 1.25 wide positions per output.
pub fn direct_applies(s: &ConvShape) -> bool {
    if s.cout > 64 {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    if blocked::applies(s) {
        return s.cin >= 4 && direct_shape(s, [3, 2]);
    }
    s.cin >= 8 && direct_shape(s, [5, 4])
}

/// Whether [`grad_weight`] goes through [`grad_weight_direct`]: any number of input channels,
/// at most 32 output channels and 1.25 wide positions per output (1.2–2.4× faster on stage 1's
/// undilated shapes, even with 6 input channels; no gain from 64 output channels on, none on the
/// dilation-4 ones).
pub fn direct_grad_weight_applies(s: &ConvShape) -> bool {
    s.cout <= 32 && direct_shape(s, [5, 4])
}

/// Whether [`grad_weight`] goes through the register-blocked [`blocked::grad_weight`]: the CPU
/// has AVX2 and FMA, 16 to 64 output channels in blocks of 8, at least 4 input channels and the
/// forward's 1.5 wide positions per output. Measured per shape against the gemm kernels
/// (`direct_against_im2col_timing`, run by hand): 1.2–1.7× faster on stage 1's shapes with 16
/// to 64 output channels and on VGG16's 64-channel layers; slower with 8 output channels and
/// with 256 and more.
pub fn blocked_grad_weight_applies(s: &ConvShape) -> bool {
    #[cfg(target_arch = "x86_64")]
    if blocked::applies(s) {
        return (16..=64).contains(&s.cout) && s.cin >= 4 && direct_shape(s, [3, 2]);
    }
    let _ = s;
    false
}

/// Stride 1 in depth, a non-empty output and at most `num / den` wide positions per output
/// position (the phase image's row against the output's: 66 / 64 at 64 × 64, 24 / 16 for the
/// dilation-4 convolutions at 16 × 16).
fn direct_shape(s: &ConvShape, [num, den]: [usize; 2]) -> bool {
    let o = s.output();
    let wq = (s.input[2] + 2 * s.padding[2]).div_ceil(s.stride[2]);
    s.stride[0] == 1 && o.iter().all(|&o| o > 0) && den * wq <= num * o[2]
}

/// A convolution without im2col (stride 1 in depth, any stride in the image axes): for each
/// job (a block of output rows of one batch item), one product per kernel offset of the
/// weights' `cout × cin` slice with the padded input's phase read at a shifted origin,
/// accumulated in the job's output rows. The input is copied once, padded and split into its
/// phases, instead of once per kernel offset.
pub fn forward_direct(s: &ConvShape, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let sp: usize = s.output().iter().product();
    if sp == 0 || s.batch == 0 || s.cout == 0 {
        return vec![0.0f32; s.batch * s.cout * sp];
    }
    #[cfg(target_arch = "x86_64")]
    if blocked::applies(s) {
        return blocked::forward(s, x, w, bias);
    }
    forward_direct_gemm(s, x, w, bias)
}

/// [`forward_direct`] with one `gemm` per kernel offset.
pub fn forward_direct_gemm(s: &ConvShape, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
    let sp: usize = s.output().iter().product();
    let mut out = vec![0.0f32; s.batch * s.cout * sp];
    if sp == 0 || s.batch == 0 || s.cout == 0 {
        return out;
    }
    let kk: usize = s.kernel.iter().product();
    let p = Padded::new(s, x);
    let q = p.q;
    let dst = SharedMut(out.as_mut_ptr());
    p.jobs
        .par_iter()
        .for_each_init(Vec::new, |wide: &mut Vec<f32>, &job| {
            wide.clear();
            wide.resize(s.cout * q, 0.0);
            p.for_each_tap(s, job, |k, col, len, origin| {
                // SAFETY: `wide` is cout × q, written from column `col` for `len` positions
                // (col + len ≤ q); the input view is that many positions × cin from `origin` at
                // channel stride `chan`, inside `data` (its zeros past the end cover the dropped
                // positions' reads); the weights cin × cout at strides (kk, cin · kk).
                unsafe {
                    gemm(
                        [len, s.cout, s.cin],
                        wide.as_mut_ptr().add(col),
                        [1, q as isize],
                        true,
                        p.data.as_ptr().add(origin),
                        [1, p.chan as isize],
                        w.as_ptr().add(k),
                        [kk as isize, (s.cin * kk) as isize],
                    )
                }
            });
            p.write_rows(s, job, wide, q, bias, dst);
        });
    out
}

/// The gradient of the convolution with respect to its weight (`cout × cols`), from its input
/// `x` and the gradient of its output `gy`.
pub fn grad_weight(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
    #[cfg(target_arch = "x86_64")]
    if blocked_grad_weight_applies(s) {
        return blocked::grad_weight(s, x, gy);
    }
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
        .reduce(|| vec![0.0f32; s.cout * k], add_into)
}

/// [`grad_weight`] without im2col (the shapes of [`forward_direct`]): per job, the output
/// gradient laid out at the job's wide indices (zeros at the dropped ones) times the padded
/// input's phase read at each kernel offset's shifted origin.
pub fn grad_weight_direct(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
    let sp: usize = s.output().iter().product();
    let kk: usize = s.kernel.iter().product();
    let k = s.cols();
    if sp == 0 || s.batch == 0 || s.cout == 0 {
        return vec![0.0f32; s.cout * k];
    }
    let p = Padded::new(s, x);
    let q = p.q;
    let zero = || (vec![0.0f32; s.cout * k], Vec::new());
    p.jobs
        .par_iter()
        .fold(zero, |(mut gw, mut wide), &job| {
            wide.clear();
            wide.resize(s.cout * q, 0.0);
            let b = job.0;
            p.for_each_row(s, job, |at, col, n| {
                for co in 0..s.cout {
                    let from = (b * s.cout + co) * sp + at;
                    wide[co * q + col..co * q + col + n].copy_from_slice(&gy[from..from + n]);
                }
            });
            p.for_each_tap(s, job, |kidx, col, len, origin| {
                // SAFETY: gw is cout × (cin · kk), written at column stride kk from `kidx`;
                // `wide` is cout × q, read from column `col` for `len` positions (zeros at the
                // dropped ones); the input view is those positions × cin from `origin` at
                // channel stride `chan`, inside `data`.
                unsafe {
                    gemm(
                        [s.cout, s.cin, len],
                        gw.as_mut_ptr().add(kidx),
                        [k as isize, kk as isize],
                        true,
                        wide.as_ptr().add(col),
                        [q as isize, 1],
                        p.data.as_ptr().add(origin),
                        [1, p.chan as isize],
                    )
                }
            });
            (gw, wide)
        })
        .map(|(gw, _)| gw)
        .reduce(|| vec![0.0f32; s.cout * k], add_into)
}

/// `a += b`, element by element: the sum of two threads' partial weight gradients.
fn add_into(mut a: Vec<f32>, b: Vec<f32>) -> Vec<f32> {
    a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
    a
}

/// The gradient of the convolution with respect to its input (`batch × cin × D × H × W`), from
/// its weight `w` and the gradient of its output `gy`.
pub fn grad_input(s: &ConvShape, w: &[f32], gy: &[f32]) -> Vec<f32> {
    if let Some((t, wt)) = transposed_as_conv(s, w) {
        return forward(&t, gy, &wt, None);
    }
    if let Some(gx) = strided_grad_input(s, w, gy) {
        return gx;
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

/// The input gradient of a 3 × 3 × 3 convolution with stride 2 in the image axes, padding 1 and
/// an input exactly twice its output (stage 1's downsampling layers), as four stride-1
/// convolutions of the output gradient, one per phase of the input (even or odd row and column):
/// each phase only ever meets the kernel rows and columns of its parity (one for even, two for
/// odd), so the four together do the forward's sums, on [`forward`]'s kernels, then interleave.
/// `None` for any other shape. (Through im2col and col2im, parallel over the batch only, it took
/// 2.2× the forward's time.)
fn strided_grad_input(s: &ConvShape, w: &[f32], gy: &[f32]) -> Option<Vec<f32>> {
    let [od, oh, ow] = s.output();
    let fits = s.kernel == [3, 3, 3]
        && s.stride == [1, 2, 2]
        && s.padding == [1, 1, 1]
        && s.dilation == [1, 1, 1]
        && s.input == [od, 2 * oh, 2 * ow]
        && od * oh * ow > 0
        && s.batch > 0;
    if !fits {
        return None;
    }
    // Input row Y = 2m + p meets kernel row b at output row (Y + 1 − b) / 2: for p = 0, b = 1 at
    // m; for p = 1, b = 2 at m and b = 0 at m + 1 (the phase convolution's taps 0 and 1). An odd
    // phase's convolution is padded by one on both sides (the output gradient's row past its
    // end reads as zero), so its output row m + 1 is the phase's row m and row 0 is dropped.
    let taps = |p: usize| if p == 0 { vec![1] } else { vec![2, 0] };
    let mut gx = vec![0.0f32; s.batch * s.cin * s.in_len()];
    let [ih, iw] = [2 * oh, 2 * ow];
    for (py, px) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
        let (tb, tc) = (taps(py), taps(px));
        let (kb, kc) = (tb.len(), tc.len());
        let t = ConvShape {
            batch: s.batch,
            cin: s.cout,
            cout: s.cin,
            input: [od, oh, ow],
            kernel: [3, kb, kc],
            stride: [1, 1, 1],
            dilation: [1, 1, 1],
            padding: [1, py, px],
        };
        let kk = 3 * kb * kc;
        let mut wt = vec![0.0f32; s.cin * s.cout * kk];
        for ci in 0..s.cin {
            for co in 0..s.cout {
                for jd in 0..3 {
                    for (jb, &b) in tb.iter().enumerate() {
                        for (jc, &c) in tc.iter().enumerate() {
                            // Depth is a plain correlation with the kernel flipped.
                            let from = (co * s.cin + ci) * 27 + ((2 - jd) * 3 + b) * 3 + c;
                            wt[(ci * s.cout + co) * kk + (jd * kb + jb) * kc + jc] = w[from];
                        }
                    }
                }
            }
        }
        let y = forward(&t, gy, &wt, None);
        let [_, yh, yw] = t.output();
        // The phase's rows m < oh and columns n < ow (the output's from py, px) go to input
        // rows 2m + py, columns 2n + px.
        gx.par_chunks_exact_mut(od * ih * iw)
            .zip(y.par_chunks_exact(od * yh * yw))
            .for_each(|(dst, src)| {
                for z in 0..od {
                    for m in 0..oh {
                        let srow = &src[(z * yh + m + py) * yw + px..][..ow];
                        let drow = &mut dst[(z * ih + 2 * m + py) * iw..][..iw];
                        for (d, v) in drow[px..].iter_mut().step_by(2).zip(srow) {
                            *d = *v;
                        }
                    }
                }
            });
    }
    Some(gx)
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
    channel_sums(gy, s.batch, s.cout)
}

/// The values of a `[batch, channels, …]` tensor `g` summed per channel (in f64, a channel per
/// task).
pub fn channel_sums(g: &[f32], batch: usize, channels: usize) -> Vec<f32> {
    let rest = g.len() / (batch * channels).max(1);
    (0..channels)
        .into_par_iter()
        .map(|ch| {
            let rows = (0..batch).map(|b| &g[(b * channels + ch) * rest..][..rest]);
            rows.map(|row| row.iter().map(|&v| f64::from(v)).sum::<f64>())
                .sum::<f64>() as f32
        })
        .collect()
}

/// The direct forward as a register-blocked AVX2 + FMA kernel, for output channels in whole
/// blocks of 8: each tile of `P` consecutive wide positions keeps its `P × 8 · NV` outputs in
/// registers while it runs over every kernel offset and input channel (a broadcast input value
/// times `NV` vectors of 8 output channels' weights), so the outputs are written once and the
/// input is read in place, with no packing and no im2col. Picked at run time where the CPU has
/// both features; elsewhere [`forward_direct_gemm`] runs. Where the CPU also has AVX-512F and
/// the output channels come in blocks of 16, the tiles hold vectors of 16 channels (32
/// registers: 24 accumulators); in blocks of 8 only, vectors of 16 positions (8 channels × 2 or
/// 3 vectors); both the same bits as the AVX2 tiles, tested. The same sums as the gemm kernels in
/// another order (tested against the f64 reference and against them).
#[cfg(target_arch = "x86_64")]
pub mod blocked {
    use super::{ConvShape, Padded, SharedMut};
    use rayon::prelude::*;
    use std::arch::x86_64::*;

    /// Whether [`forward`] runs: the CPU has AVX2 and FMA, and the output channels come in
    /// whole blocks of 8.
    pub fn applies(s: &ConvShape) -> bool {
        s.cout.is_multiple_of(8) && mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx2
    }

    /// Which vector width a blocked forward runs at.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Width {
        /// The widest the CPU and the shape allow: AVX-512 where the CPU has AVX-512F and the
        /// output channels come in blocks of 16, else AVX2.
        Widest,
        /// AVX2 and FMA, 8 output channels a vector (tests compare the two).
        Avx2,
    }

    /// Whether the AVX-512 tiles run for `s` ([`Width::Widest`]): the CPU has AVX-512F (and the
    /// output channels come in whole blocks of 8). Blocks of 16 take tiles of 16 channels a
    /// vector; others, 16 positions a vector (`tile512_positions`).
    pub fn avx512_applies(s: &ConvShape) -> bool {
        applies(s) && mhi_geom::simd::level() >= mhi_geom::simd::Level::Avx512
    }

    /// The convolution of the shapes [`super::forward_direct`] takes, `cout` a multiple of 8,
    /// at the widest vectors the CPU has.
    ///
    /// # Panics
    /// If the CPU lacks AVX2 or FMA, or `cout` is not a multiple of 8 ([`applies`]).
    pub fn forward(s: &ConvShape, x: &[f32], w: &[f32], bias: Option<&[f32]>) -> Vec<f32> {
        forward_at(s, x, w, bias, Width::Widest)
    }

    /// [`forward`] at the vector width `width`. Both widths give the same bits: every output
    /// sums the same products in the same order (kernel offset, then input channel), one fused
    /// multiply-add each.
    ///
    /// # Panics
    /// As [`forward`].
    pub fn forward_at(
        s: &ConvShape,
        x: &[f32],
        w: &[f32],
        bias: Option<&[f32]>,
        width: Width,
    ) -> Vec<f32> {
        assert!(
            applies(s),
            "the blocked kernel needs AVX2, FMA and cout % 8 == 0"
        );
        let sp: usize = s.output().iter().product();
        let len = s.batch * s.cout * sp;
        // Not zeroed first: the jobs' rows cover every output element (`Padded::write_rows`),
        // and zeroing it took a sixth of a strided convolution's time.
        let mut out: Vec<f32> = Vec::with_capacity(len);
        let p = Padded::new(s, x);
        let dst = SharedMut(out.as_mut_ptr());
        if width == Width::Widest && avx512_applies(s) && !s.cout.is_multiple_of(16) {
            // Blocks of 8 output channels: a vector of 8 channels would use half of each
            // multiply-add, so the vectors run over 16 positions instead, 8 channels × 2 or 3
            // vectors of accumulators, each weight broadcast from memory to 2 or 3 of them.
            // The AVX2 tiles' weight layout, each 8 channels' weights as plain floats.
            let wf = pack::<[f32; 8], 8>(s, w, 1, |c| c);
            let per_block = wf.len() / (s.cout / 8);
            let tiling = Tiling::choose(s, &p, &[48, 32]);
            run(s, &p, tiling, 8, bias, dst, |wide, at, q, taps, g, ob| {
                let wb = &wf[ob * per_block..(ob + 1) * per_block];
                let out = (wide, at, q);
                // SAFETY: AVX-512F was detected (`avx512_applies`).
                unsafe {
                    if tiling.len == 48 {
                        tile512_positions::<3>(&p, taps, g, s.cin, wb, out);
                    } else {
                        tile512_positions::<2>(&p, taps, g, s.cin, wb, out);
                    }
                }
            });
        } else if width == Width::Widest && avx512_applies(s) {
            // 32 vector registers: 24 accumulators (12 positions × 32 channels, or 24 × 16)
            // and the weights; the broadcast input rides in the multiply-add's memory operand.
            let nv = if s.cout.is_multiple_of(32) { 2 } else { 1 };
            // The tile's length: the full register file's, or two thirds of it where whole
            // rows of the output take fewer positions that way (16 × 16 outputs: 16 positions
            // a row instead of the 18 or 24 of the padded rows).
            let tiling = if nv == 2 {
                Tiling::choose(s, &p, &[12, 8])
            } else {
                Tiling::choose(s, &p, &[24, 16])
            };
            // SAFETY: a plain transmute of 16 floats into a vector (same size, any bits).
            let wv = pack::<__m512, 16>(s, w, nv, |c| unsafe {
                std::mem::transmute::<[f32; 16], __m512>(c)
            });
            let per_block = wv.len() / (s.cout / (16 * nv));
            run(
                s,
                &p,
                tiling,
                16 * nv,
                bias,
                dst,
                |wide, at, q, taps, g, ob| {
                    let wb = &wv[ob * per_block..(ob + 1) * per_block];
                    let out = (wide, at, q);
                    // SAFETY: AVX-512F was detected (`avx512_applies`).
                    unsafe {
                        match (nv, tiling.len) {
                            (2, 12) => tile512::<2, 12>(&p, taps, g, s.cin, wb, out),
                            (2, _) => tile512::<2, 8>(&p, taps, g, s.cin, wb, out),
                            (_, 24) => tile512::<1, 24>(&p, taps, g, s.cin, wb, out),
                            _ => tile512::<1, 16>(&p, taps, g, s.cin, wb, out),
                        }
                    }
                },
            );
        } else {
            let nv = if s.cout.is_multiple_of(16) { 2 } else { 1 };
            let p_len = if nv == 2 { 6 } else { 12 };
            // SAFETY: a plain transmute of 8 floats into a vector (same size, any bits).
            let wv = pack::<__m256, 8>(s, w, nv, |c| unsafe {
                std::mem::transmute::<[f32; 8], __m256>(c)
            });
            let per_block = wv.len() / (s.cout / (8 * nv));
            run(
                s,
                &p,
                Tiling::choose(s, &p, &[p_len]),
                8 * nv,
                bias,
                dst,
                |wide, at, q, taps, g, ob| {
                    let wb = &wv[ob * per_block..(ob + 1) * per_block];
                    // SAFETY: AVX2 and FMA were detected (`applies`).
                    unsafe {
                        if nv == 2 {
                            tile::<2, 6>(&p, taps, g, s.cin, wb, (wide, at, q));
                        } else {
                            tile::<1, 12>(&p, taps, g, s.cin, wb, (wide, at, q));
                        }
                    }
                },
            );
        }
        // SAFETY: `run` wrote every element of `..len` through `dst`: the jobs cover every
        // batch item, output slice and output row, and `write_rows` writes each row's `W'`
        // values for every output channel.
        unsafe { out.set_len(len) };
        out
    }

    /// Weights per block of output channels, as vectors of `L` lanes: `[block][kernel
    /// index][ci][NV]`, the vector of block ob, part v holding output channels
    /// `ob · L · nv + L v … + L`.
    fn pack<V, const L: usize>(
        s: &ConvShape,
        w: &[f32],
        nv: usize,
        vector: impl Fn([f32; L]) -> V,
    ) -> Vec<V> {
        let kk: usize = s.kernel.iter().product();
        let lanes = L * nv;
        let mut wv = Vec::with_capacity(w.len() / L);
        for ob in 0..s.cout / lanes {
            for k in 0..kk {
                for ci in 0..s.cin {
                    for v in 0..nv {
                        let lane = |l: usize| {
                            let co = ob * lanes + L * v + l;
                            w[(co * s.cin + ci) * kk + k]
                        };
                        wv.push(vector(std::array::from_fn(lane)));
                    }
                }
            }
        }
        wv
    }

    /// How a job's wide positions are cut into tiles.
    #[derive(Debug, Clone, Copy)]
    struct Tiling {
        /// Positions a tile.
        len: usize,
        /// Tiles start at every output row (and leave the row's dropped columns out) instead
        /// of running through the segment's wide positions, dropped ones included.
        rows: bool,
    }

    impl Tiling {
        /// Of the tile lengths `lens` (the first preferred on a tie) and the two layouts, the
        /// one that computes the fewest positions a row of the output: `wq` through the padded
        /// row, `⌈W' / len⌉ · len` by rows.
        fn choose(s: &ConvShape, p: &Padded, lens: &[usize]) -> Self {
            let ow = s.output()[2];
            let mut best = (
                p.wq,
                Tiling {
                    len: lens[0],
                    rows: false,
                },
            );
            for &len in lens {
                let cost = ow.div_ceil(len) * len;
                if cost < best.0 {
                    best = (cost, Tiling { len, rows: true });
                }
            }
            best.1
        }
    }

    /// Every job of `p`: its tiles of `tiling.len` wide positions, block of `lanes` output
    /// channels by block (`tile(wide, at, q, taps, g, block)`), into the job's buffer, then the
    /// job's rows into the output with the bias.
    fn run(
        s: &ConvShape,
        p: &Padded,
        tiling: Tiling,
        lanes: usize,
        bias: Option<&[f32]>,
        dst: SharedMut,
        tile: impl Fn(&mut [f32], usize, usize, &[(usize, usize)], usize, usize) + Sync,
    ) {
        let p_len = tiling.len;
        let q = p.q + p_len;
        let (wq, ow) = (p.wq, s.output()[2]);
        p.jobs
            .par_iter()
            .for_each_init(Vec::new, |wide: &mut Vec<f32>, &job| {
                // Not cleared between jobs: every column `write_rows` reads is written by the
                // job's own tiles first (each segment's tiles cover all its columns), so the
                // buffer is zeroed once per rayon split (a few per thread), not once per job.
                if wide.len() != s.cout * q {
                    wide.clear();
                    wide.resize(s.cout * q, 0.0);
                }
                for (col, len, taps) in p.segments(s, job) {
                    for ob in 0..s.cout / lanes {
                        // The tile's outputs go straight into `wide`, channel by channel
                        // (written value by value through a buffer, with a bounds check each,
                        // they took 8 % of stage 1's inference). A tile that runs past its
                        // row or segment spills up to p_len − 1 columns into the next row's or
                        // segment's, which their own tiles overwrite later (and into the
                        // buffer's p_len spare columns after the last segment).
                        let mut each =
                            |g: usize| tile(wide, ob * lanes * q + col + g, q, &taps, g, ob);
                        if tiling.rows {
                            for r in (0..len).step_by(wq) {
                                (0..ow).step_by(p_len).for_each(|c| each(r + c));
                            }
                        } else {
                            (0..len).step_by(p_len).for_each(&mut each);
                        }
                    }
                }
                p.write_rows(s, job, wide, q, bias, dst);
            });
    }

    /// The weight gradient of the shapes [`forward`] takes (`cout` a multiple of 8), at the
    /// widest vectors the CPU has: the forward's register tiles turned around. A tile holds
    /// `P` (kernel offset, input channel) pairs × `L · NV` output channels of the gradient in
    /// registers while it runs over the job's output positions, each adding one broadcast input
    /// value (read in place from the padded input, as the forward reads it) times `NV` vectors of
    /// the output gradient, laid out position by position (channels contiguous) once per job.
    /// Positions a row drops (the padded row's extra columns) are skipped, not multiplied by
    /// zero. Per-thread partial sums are added at the end.
    ///
    /// # Panics
    /// As [`forward`].
    pub fn grad_weight(s: &ConvShape, x: &[f32], gy: &[f32]) -> Vec<f32> {
        grad_weight_at(s, x, gy, Width::Widest)
    }

    /// [`grad_weight`] at the vector width `width` (the sums in the same order at both widths).
    ///
    /// # Panics
    /// As [`forward`].
    pub fn grad_weight_at(s: &ConvShape, x: &[f32], gy: &[f32], width: Width) -> Vec<f32> {
        assert!(
            applies(s),
            "the blocked kernel needs AVX2, FMA and cout % 8 == 0"
        );
        let kk: usize = s.kernel.iter().product();
        let cols = s.cin * kk;
        let sp: usize = s.output().iter().product();
        if sp == 0 || s.batch == 0 {
            return vec![0.0; s.cout * cols];
        }
        let p = Padded::new(s, x);
        let (q, wq, ow) = (p.q, p.wq, s.output()[2]);
        // Vectors of 16 output channels: whole blocks of 16 only.
        let wide512 = width == Width::Widest && avx512_applies(s) && s.cout.is_multiple_of(16);
        let (lanes, pairs_per_tile) = match (
            wide512,
            s.cout.is_multiple_of(32),
            s.cout.is_multiple_of(16),
        ) {
            (true, true, _) => (32, 12),
            (true, false, _) => (16, 24),
            (false, _, true) => (16, 6),
            (false, _, false) => (8, 12),
        };
        let gwt = p
            .jobs
            .par_iter()
            .fold(
                || (vec![0.0f32; cols * s.cout], Vec::new()),
                |(mut gwt, mut gyt): (Vec<f32>, Vec<f32>), &job| {
                    // The job's output gradient position by position, channels contiguous;
                    // the dropped columns are never read.
                    gyt.resize(q * s.cout, 0.0);
                    let b = job.0;
                    p.for_each_row(s, job, |at, col, n| {
                        // Eight channels at a time: eight read streams, runs of eight written
                        // (channel by channel it wrote one float per cache line).
                        for c0 in (0..s.cout).step_by(8) {
                            let rows: [&[f32]; 8] = std::array::from_fn(|c| {
                                let from = (b * s.cout + c0 + c) * sp + at;
                                &gy[from..from + n]
                            });
                            let dst = &mut gyt[col * s.cout..(col + n) * s.cout];
                            for (i, run) in dst.chunks_exact_mut(s.cout).enumerate() {
                                for (c, d) in run[c0..c0 + 8].iter_mut().enumerate() {
                                    *d = rows[c][i];
                                }
                            }
                        }
                    });
                    for (col, len, taps) in p.segments(s, job) {
                        // Every (kernel offset, input channel) pair of the segment, with the
                        // padded input's index of its first position; padded to whole tiles
                        // with copies of the first pair (their sums are dropped).
                        let mut pairs: Vec<(usize, usize)> = taps
                            .iter()
                            .flat_map(|&(k, origin)| {
                                (0..s.cin).map(move |ci| (ci * kk + k, origin + ci * p.chan))
                            })
                            .collect();
                        let real = pairs.len();
                        if real == 0 {
                            continue;
                        }
                        let first = pairs[0];
                        pairs.resize(real.div_ceil(pairs_per_tile) * pairs_per_tile, first);
                        let rows = len / wq;
                        let mut sums = vec![0.0f32; pairs_per_tile * lanes];
                        for (t, tile) in pairs.chunks_exact(pairs_per_tile).enumerate() {
                            let keep = (real - t * pairs_per_tile).min(pairs_per_tile);
                            for ob in 0..s.cout / lanes {
                                let job = GwTile {
                                    data: &p.data,
                                    gyt: &gyt,
                                    cout: s.cout,
                                    co0: ob * lanes,
                                    col,
                                    rows,
                                    wq,
                                    ow,
                                };
                                // Every element of `sums` is overwritten by the tile.
                                // SAFETY: the features were detected (`avx512_applies`,
                                // `applies`).
                                unsafe {
                                    match (wide512, lanes) {
                                        (true, 32) => gw_tile512::<2, 12>(&job, tile, &mut sums),
                                        (true, _) => gw_tile512::<1, 24>(&job, tile, &mut sums),
                                        (false, 16) => gw_tile::<2, 6>(&job, tile, &mut sums),
                                        (false, _) => gw_tile::<1, 12>(&job, tile, &mut sums),
                                    }
                                }
                                for (j, &(r, _)) in tile.iter().take(keep).enumerate() {
                                    let dst = &mut gwt[r * s.cout + ob * lanes..][..lanes];
                                    for (d, v) in dst.iter_mut().zip(&sums[j * lanes..]) {
                                        *d += v;
                                    }
                                }
                            }
                        }
                    }
                    (gwt, gyt)
                },
            )
            .map(|(g, _)| g)
            .reduce(|| vec![0.0f32; cols * s.cout], super::add_into);
        // [cols][cout] → [cout][cols]
        let mut gw = vec![0.0f32; s.cout * cols];
        for (r, row) in gwt.chunks_exact(s.cout).enumerate() {
            for (co, &v) in row.iter().enumerate() {
                gw[co * cols + r] = v;
            }
        }
        gw
    }

    /// What a weight-gradient tile reads: the padded input, the job's output gradient
    /// (position-major), its block of output channels from `co0`, and the segment's output rows
    /// (`rows` of `ow` positions, `wq` apart, from column `col` of the job).
    struct GwTile<'a> {
        data: &'a [f32],
        gyt: &'a [f32],
        cout: usize,
        co0: usize,
        col: usize,
        rows: usize,
        wq: usize,
        ow: usize,
    }

    /// Defines a weight-gradient tile for one vector type (the AVX2 and the AVX-512 tiles are the
    /// same code over their vectors).
    macro_rules! gw_tile {
        ($(#[$doc:meta])* $name:ident, $feature:literal, $v:ty, $l:literal,
         $zero:ident, $load:ident, $set1:ident, $fmadd:ident) => {
            $(#[$doc])*
            #[target_feature(enable = $feature)]
            unsafe fn $name<const NV: usize, const P: usize>(
                t: &GwTile<'_>,
                pairs: &[(usize, usize)],
                sums: &mut [f32],
            ) {
                let mut acc = [[$zero(); NV]; P];
                let origins: [usize; P] = std::array::from_fn(|j| pairs[j].1);
                // Every read below lies inside `data` and `gyt`: checked once per tile here, so
                // that the inner loop runs on raw pointers.
                let last = (t.rows.max(1) - 1) * t.wq + t.ow;
                assert!(origins.iter().all(|&o| o + last <= t.data.len()));
                assert!((t.col + last) * t.cout <= t.gyt.len() && t.co0 + $l * NV <= t.cout);
                for r in 0..t.rows {
                    let g0 = r * t.wq;
                    // SAFETY: within the bounds asserted above.
                    let xs: [*const f32; P] =
                        std::array::from_fn(|j| unsafe { t.data.as_ptr().add(origins[j] + g0) });
                    let gs = unsafe { t.gyt.as_ptr().add((t.col + g0) * t.cout + t.co0) };
                    for i in 0..t.ow {
                        // SAFETY: position i < ow of the row, inside the asserted bounds.
                        unsafe {
                            let gp = gs.add(i * t.cout);
                            let g: [$v; NV] = std::array::from_fn(|v| $load(gp.add($l * v)));
                            for (a, x) in acc.iter_mut().zip(&xs) {
                                let x = $set1(*x.add(i));
                                for (r, gv) in a.iter_mut().zip(&g) {
                                    *r = $fmadd(x, *gv, *r);
                                }
                            }
                        }
                    }
                }
                for (j, a) in acc.iter().enumerate() {
                    for (v, r) in a.iter().enumerate() {
                        // SAFETY: a plain transmute of a vector into its floats.
                        let vals = unsafe { std::mem::transmute::<$v, [f32; $l]>(*r) };
                        sums[j * $l * NV + $l * v..][..$l].copy_from_slice(&vals);
                    }
                }
            }
        };
    }

    gw_tile!(
        /// One weight-gradient tile: `sums[j · 8 · NV + 8 v + l]` = Σ over the segment's kept
        /// positions g of `data[origin_j + g] · gyt[(col + g) · cout + co0 + 8 v + l]`.
        ///
        /// # Safety
        /// The CPU has AVX2 and FMA.
        gw_tile, "avx2,fma", __m256, 8,
        _mm256_setzero_ps, _mm256_loadu_ps, _mm256_set1_ps, _mm256_fmadd_ps
    );

    gw_tile!(
        /// [`gw_tile`] with vectors of 16 output channels.
        ///
        /// # Safety
        /// The CPU has AVX-512F.
        gw_tile512, "avx512f", __m512, 16,
        _mm512_setzero_ps, _mm512_loadu_ps, _mm512_set1_ps, _mm512_fmadd_ps
    );

    /// One tile: `wide[at + (8 v + l) · q + i]` = Σ over taps `(k, origin)` and input channels
    /// of `data[origin + g + i + ci · chan] · w[k][ci][v][l]`, for `i < P`. Safe indexing only
    /// (slices of known length, so the checks leave the inner loop): the accumulators stay in
    /// registers.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA.
    #[target_feature(enable = "avx2,fma")]
    unsafe fn tile<const NV: usize, const P: usize>(
        p: &Padded,
        taps: &[(usize, usize)],
        g: usize,
        cin: usize,
        w: &[__m256],
        (wide, at, q): (&mut [f32], usize, usize),
    ) {
        let mut acc = [[_mm256_setzero_ps(); NV]; P];
        for &(k, origin) in taps {
            let wk = &w[k * cin * NV..(k + 1) * cin * NV];
            let at = origin + g;
            for (ci, wr) in wk.chunks_exact(NV).enumerate() {
                let x0 = at + ci * p.chan;
                let xr: &[f32; P] = p.data[x0..x0 + P].try_into().expect("P values");
                for (a, x) in acc.iter_mut().zip(xr) {
                    let x = _mm256_set1_ps(*x);
                    for (r, wv) in a.iter_mut().zip(wr) {
                        *r = _mm256_fmadd_ps(x, *wv, *r);
                    }
                }
            }
        }
        // SAFETY: a plain transmute of a vector into 8 floats (same size, any bits).
        let vals = acc.map(|a| a.map(|r| unsafe { std::mem::transmute::<__m256, [f32; 8]>(r) }));
        write_tile(&vals, (wide, at, q));
    }

    /// A tile's results, `vals[i][v][l]` for position `i` and channel `L v + l`, into
    /// `wide[at + (L v + l) · q + i]`: one checked run of `P` columns a channel.
    #[inline(always)]
    fn write_tile<const L: usize, const NV: usize, const P: usize>(
        vals: &[[[f32; L]; NV]; P],
        (wide, at, q): (&mut [f32], usize, usize),
    ) {
        for v in 0..NV {
            for lane in 0..L {
                let row = at + (L * v + lane) * q;
                let run: &mut [f32; P] = (&mut wide[row..row + P]).try_into().expect("P values");
                for (o, val) in run.iter_mut().zip(vals) {
                    *o = val[v][lane];
                }
            }
        }
    }

    /// [`tile`] for a block of 8 output channels with vectors over 16 positions:
    /// `wide[at + c · q + i]` for channel `c < 8` and position `i < 16 V`, from the weights
    /// `w[k · cin + ci][c]`. Each output sums the same products in the same order as [`tile`] (kernel
    /// offset, then input channel), one fused multiply-add each: the same bits.
    ///
    /// # Safety
    /// The CPU has AVX-512F.
    #[target_feature(enable = "avx512f")]
    unsafe fn tile512_positions<const V: usize>(
        p: &Padded,
        taps: &[(usize, usize)],
        g: usize,
        cin: usize,
        w: &[[f32; 8]],
        (wide, at, q): (&mut [f32], usize, usize),
    ) {
        let mut acc = [[_mm512_setzero_ps(); V]; 8];
        for &(k, origin) in taps {
            let wk = &w[k * cin..(k + 1) * cin];
            let at = origin + g;
            for (ci, wr) in wk.iter().enumerate() {
                let x0 = at + ci * p.chan;
                let xr = &p.data[x0..x0 + 16 * V];
                let mut xv = [_mm512_setzero_ps(); V];
                for (v, x) in xv.iter_mut().enumerate() {
                    let part: &[f32; 16] = xr[16 * v..16 * v + 16].try_into().expect("16 values");
                    // SAFETY: a plain transmute of 16 floats into a vector.
                    *x = unsafe { std::mem::transmute::<[f32; 16], __m512>(*part) };
                }
                for (a, wv) in acc.iter_mut().zip(wr) {
                    let b = _mm512_set1_ps(*wv);
                    for (r, x) in a.iter_mut().zip(&xv) {
                        *r = _mm512_fmadd_ps(*x, b, *r);
                    }
                }
            }
        }
        for (c, a) in acc.iter().enumerate() {
            let row = at + c * q;
            let out: &mut [f32] = &mut wide[row..row + 16 * V];
            for (v, r) in a.iter().enumerate() {
                // SAFETY: a plain transmute of a vector into 16 floats.
                let vals = unsafe { std::mem::transmute::<__m512, [f32; 16]>(*r) };
                out[16 * v..16 * v + 16].copy_from_slice(&vals);
            }
        }
    }

    /// [`tile`] with vectors of 16 output channels: `wide[at + (16 v + l) · q + i]`, `i < P`.
    ///
    /// # Safety
    /// The CPU has AVX-512F.
    #[target_feature(enable = "avx512f")]
    unsafe fn tile512<const NV: usize, const P: usize>(
        p: &Padded,
        taps: &[(usize, usize)],
        g: usize,
        cin: usize,
        w: &[__m512],
        (wide, at, q): (&mut [f32], usize, usize),
    ) {
        let mut acc = [[_mm512_setzero_ps(); NV]; P];
        for &(k, origin) in taps {
            let wk = &w[k * cin * NV..(k + 1) * cin * NV];
            let at = origin + g;
            for (ci, wr) in wk.chunks_exact(NV).enumerate() {
                let x0 = at + ci * p.chan;
                let xr: &[f32; P] = p.data[x0..x0 + P].try_into().expect("P values");
                for (a, x) in acc.iter_mut().zip(xr) {
                    let x = _mm512_set1_ps(*x);
                    for (r, wv) in a.iter_mut().zip(wr) {
                        *r = _mm512_fmadd_ps(x, *wv, *r);
                    }
                }
            }
        }
        // SAFETY: a plain transmute of a vector into 16 floats (same size, any bits).
        let vals = acc.map(|a| a.map(|r| unsafe { std::mem::transmute::<__m512, [f32; 16]>(r) }));
        write_tile(&vals, (wide, at, q));
    }
}

#[cfg(test)]
mod padded_tests {
    use super::{ConvShape, Padded};

    /// The padded input holds each value at its place and zeros everywhere else (built from a
    /// buffer of NaN under test, so a position left unwritten reads as one).
    #[test]
    fn the_padded_input_is_the_input_among_zeros() {
        for (input, stride, pad) in [([3, 5, 7], 1, 1), ([2, 6, 9], 1, 4), ([2, 8, 6], 2, 1)] {
            let s = ConvShape {
                batch: 2,
                cin: 3,
                cout: 8,
                input,
                kernel: [3, 3, 3],
                stride: [1, stride, stride],
                dilation: [1, pad, pad],
                padding: [1, pad, pad],
            };
            let n = s.batch * s.cin * input.iter().product::<usize>();
            let x: Vec<f32> = (0..n).map(|i| 1.0 + i as f32).collect();
            let p = Padded::new(&s, &x);
            assert!(
                p.data.iter().all(|v| v.is_finite()),
                "{input:?}: an unwritten value"
            );
            let [d, h, w] = input;
            let [sy, sx] = p.phases;
            let mut seen = 0;
            for b in 0..s.batch {
                for c in 0..s.cin {
                    for z in 0..d {
                        for y in 0..h {
                            for xx in 0..w {
                                let (yp, xp) = (y + pad, xx + pad);
                                let at = b * p.item
                                    + c * p.chan
                                    + ((yp % sy) * sx + xp % sx) * p.phase
                                    + z * p.slice
                                    + (yp / sy) * p.wq
                                    + xp / sx;
                                let want = x[(((b * s.cin + c) * d + z) * h + y) * w + xx];
                                assert_eq!(p.data[at], want, "{input:?} {b} {c} {z} {y} {xx}");
                                seen += 1;
                            }
                        }
                    }
                }
            }
            let nonzero = p.data.iter().filter(|v| **v != 0.0).count();
            assert_eq!(nonzero, seen, "{input:?}: a padding value is not zero");
        }
    }
}
