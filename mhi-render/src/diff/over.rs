//! Over-compositing of each normal's warped layers (paper Eq. 2) and its gradients as one kernel
//! for the CPU backend.
//!
//! burn's version is a loop over the D layers of five or six tensor operations each (a slice, a
//! product, a sum, a difference), every one a pass over `N × H × W` values with its own autodiff
//! node; here one pass over the layers per block of pixels keeps the transmittance in the
//! core's cache. Layer `j` of a normal (far first; the farthest forced opaque) takes the weight
//! `w(j) = a(j) t(j)`, `t(j)` the product of `1 − a(k)` over the layers `k > j` in front of it,
//! and `out = Σ c(j) w(j)`. With `g(j) = ⟨dL/dout, c(j)⟩` and `R(j)` what the layers behind `j`
//! show (`R(0) = 0`, `R(j + 1) = g(j) a(j) + (1 − a(j)) R(j)`): `dL/dc(j) = dL/dout · w(j)` and
//! `dL/da(j) = t(j) (g(j) − R(j))` (0 for the farthest, opaque whatever its alpha), with no
//! division by `1 − a(j)`.

use burn::backend::autodiff::Autodiff;
use burn::backend::autodiff::NodeId;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::tensor::FloatTensor;
use burn::backend::{Backend, TensorMetadata, backend_extension};
use burn::tensor::{Tensor, TensorData};
use burn_flex::{Flex, FlexTensor};
use mhi_kernels::f32_contiguous;
use rayon::prelude::*;

/// Pixels a task composites at once (its transmittances and sums stay in the core's cache).
const BLOCK: usize = 1024;

/// `[N·D, C, H, W]` layers as normals, depths and pixels a plane.
#[derive(Debug, Clone, Copy)]
struct Shape {
    n: usize,
    d: usize,
    pixels: usize,
}

/// The multi-normal images `[N, 3, H, W]` of `rgb` (`[N·D, 3, H·W]`) and `alpha` (`[N·D, 1,
/// H·W]`), far first within each normal, the farthest opaque.
fn forward(s: Shape, rgb: &[f32], alpha: &[f32]) -> Vec<f32> {
    let (d, px) = (s.d, s.pixels);
    let mut out = vec![0.0f32; s.n * 3 * px];
    if px == 0 {
        return out;
    }
    out.par_chunks_mut(3 * px).enumerate().for_each(|(i, out)| {
        let (o_r, rest) = out.split_at_mut(px);
        let (o_g, o_b) = rest.split_at_mut(px);
        o_r.par_chunks_mut(BLOCK)
            .zip(o_g.par_chunks_mut(BLOCK))
            .zip(o_b.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(blk, ((o_r, o_g), o_b))| {
                let p0 = blk * BLOCK;
                let m = o_r.len();
                let mut t = [1.0f32; BLOCK];
                for j in (0..d).rev() {
                    let l = i * d + j;
                    let a = &alpha[l * px + p0..][..m];
                    let c = &rgb[l * 3 * px..];
                    let (cr, cg, cb) = (&c[p0..][..m], &c[px + p0..][..m], &c[2 * px + p0..][..m]);
                    for p in 0..m {
                        let ta = if j == 0 { t[p] } else { t[p] * a[p] };
                        o_r[p] += cr[p] * ta;
                        o_g[p] += cg[p] * ta;
                        o_b[p] += cb[p] * ta;
                        t[p] -= ta;
                    }
                }
            });
    });
    out
}

/// The gradients `(rgb, alpha)` of [`forward`] from the gradient `g` of its output.
fn backward(s: Shape, rgb: &[f32], alpha: &[f32], g: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let (d, px) = (s.d, s.pixels);
    let mut g_rgb = vec![0.0f32; s.n * d * 3 * px];
    let mut g_alpha = vec![0.0f32; s.n * d * px];
    if px == 0 || d == 0 {
        return (g_rgb, g_alpha);
    }
    let blocks = px.div_ceil(BLOCK);
    // One task per normal and block of pixels, each handed the block's part of every row it
    // writes: its layers' three colour rows (3 j + c) and alpha rows (3 d + j).
    let mut tasks: Vec<Vec<&mut [f32]>> = (0..s.n * blocks)
        .map(|_| Vec::with_capacity(4 * d))
        .collect();
    for (r, row) in g_rgb.chunks_mut(px).enumerate() {
        let i = r / (3 * d);
        for (b, part) in row.chunks_mut(BLOCK).enumerate() {
            tasks[i * blocks + b].push(part);
        }
    }
    for (r, row) in g_alpha.chunks_mut(px).enumerate() {
        let i = r / d;
        for (b, part) in row.chunks_mut(BLOCK).enumerate() {
            tasks[i * blocks + b].push(part);
        }
    }
    tasks
        .into_par_iter()
        .enumerate()
        .for_each(|(task, mut rows)| {
            let (i, blk) = (task / blocks, task % blocks);
            let p0 = blk * BLOCK;
            let m = BLOCK.min(px - p0);
            let g = &g[i * 3 * px..][..3 * px];
            let (gr, gg, gb) = (&g[p0..][..m], &g[px + p0..][..m], &g[2 * px + p0..][..m]);
            // Transmittance in front of each layer.
            let mut t = vec![0.0f32; d * m];
            let mut run = [1.0f32; BLOCK];
            for j in (0..d).rev() {
                let a = &alpha[(i * d + j) * px + p0..][..m];
                t[j * m..(j + 1) * m].copy_from_slice(&run[..m]);
                for p in 0..m {
                    run[p] -= if j == 0 { run[p] } else { run[p] * a[p] };
                }
            }
            let mut behind = [0.0f32; BLOCK];
            for j in 0..d {
                let l = i * d + j;
                let a = &alpha[l * px + p0..][..m];
                let c = &rgb[l * 3 * px..];
                let (cr, cg, cb) = (&c[p0..][..m], &c[px + p0..][..m], &c[2 * px + p0..][..m]);
                let tj = &t[j * m..(j + 1) * m];
                let Ok([dr, dg, db, da]) =
                    rows.get_disjoint_mut([3 * j, 3 * j + 1, 3 * j + 2, 3 * d + j])
                else {
                    unreachable!("4 d distinct rows a task");
                };
                for p in 0..m {
                    let aj = if j == 0 { 1.0 } else { a[p] };
                    let w = tj[p] * aj;
                    dr[p] = gr[p] * w;
                    dg[p] = gg[p] * w;
                    db[p] = gb[p] * w;
                    let gj = gr[p] * cr[p] + gg[p] * cg[p] + gb[p] * cb[p];
                    da[p] = if j == 0 {
                        0.0
                    } else {
                        tj[p] * (gj - behind[p])
                    };
                    behind[p] = gj * aj + (1.0 - aj) * behind[p];
                }
            }
        });
    (g_rgb, g_alpha)
}

/// Over-compositing as backend operations.
#[backend_extension(Flex, Autodiff)]
pub trait OverOps: Backend {
    /// [`over`]'s forward: `rgb` `[N·D, 3, H, W]`, `alpha` `[N·D, 1, H, W]` → `[N, 3, H, W]`.
    fn over_composite(
        rgb: FloatTensor<Self>,
        alpha: FloatTensor<Self>,
        n: usize,
    ) -> FloatTensor<Self>;
    /// Its gradients `(rgb, alpha)` from the output's gradient.
    fn over_composite_backward(
        rgb: FloatTensor<Self>,
        alpha: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        n: usize,
    ) -> (FloatTensor<Self>, FloatTensor<Self>);
}

/// Over-composite `n` normals' layers: `rgb` `[N·D, 3, H, W]` and `alpha` `[N·D, 1, H, W]`, far
/// first within each normal, the farthest forced opaque; returns `[N, 3, H, W]`. For the CPU
/// backend ([`super::composite`] calls it there).
pub fn over(rgb: Tensor<4>, alpha: Tensor<4>, n: usize) -> Tensor<4> {
    let out = <burn::backend::Dispatch as OverOps>::over_composite(
        rgb.into_dispatch(),
        alpha.into_dispatch(),
        n,
    );
    Tensor::<4>::from_dispatch(out)
}

fn shape_of(rgb: &FlexTensor, n: usize) -> (Shape, [usize; 2]) {
    let dims = rgb.shape().to_vec();
    let (layers, h, w) = (dims[0], dims[2], dims[3]);
    (
        Shape {
            n,
            d: layers / n.max(1),
            pixels: h * w,
        },
        [h, w],
    )
}

impl OverOps for Flex {
    fn over_composite(rgb: FlexTensor, alpha: FlexTensor, n: usize) -> FlexTensor {
        let (s, [h, w]) = shape_of(&rgb, n);
        let (rgb, alpha) = (f32_contiguous(rgb), f32_contiguous(alpha));
        let out = forward(s, rgb.storage(), alpha.storage());
        FlexTensor::from_data(TensorData::new(out, [n, 3, h, w]))
    }

    fn over_composite_backward(
        rgb: FlexTensor,
        alpha: FlexTensor,
        grad: FlexTensor,
        n: usize,
    ) -> (FlexTensor, FlexTensor) {
        let (s, [h, w]) = shape_of(&rgb, n);
        let (rgb, alpha, grad) = (
            f32_contiguous(rgb),
            f32_contiguous(alpha),
            f32_contiguous(grad),
        );
        let (gr, ga) = backward(s, rgb.storage(), alpha.storage(), grad.storage());
        let l = s.n * s.d;
        (
            FlexTensor::from_data(TensorData::new(gr, [l, 3, h, w])),
            FlexTensor::from_data(TensorData::new(ga, [l, 1, h, w])),
        )
    }
}

/// The autodiff node of [`over`].
#[derive(Debug)]
struct Over;

impl<B: Backend + OverOps> Backward<B, 2> for Over {
    type State = (NodeId, NodeId, usize);

    fn backward(
        self,
        ops: Ops<Self::State, 2>,
        grads: &mut Gradients,
        checkpointer: &mut Checkpointer,
    ) {
        let [node_rgb, node_alpha] = ops.parents;
        let grad = grads.consume::<B>(&ops.node);
        let (rgb_state, alpha_state, n) = ops.state;
        let rgb = checkpointer.retrieve_node_output::<B::FloatTensorPrimitive>(rgb_state);
        let alpha = checkpointer.retrieve_node_output::<B::FloatTensorPrimitive>(alpha_state);
        let (g_rgb, g_alpha) = B::over_composite_backward(rgb, alpha, grad, n);
        for (node, g) in [(node_rgb, g_rgb), (node_alpha, g_alpha)] {
            if let Some(node) = node {
                grads.register::<B>(node.id, g);
            }
        }
    }
}

impl<B: Backend + OverOps, C: CheckpointStrategy> OverOps for Autodiff<B, C> {
    fn over_composite(
        rgb: FloatTensor<Self>,
        alpha: FloatTensor<Self>,
        n: usize,
    ) -> FloatTensor<Self> {
        match Over
            .prepare::<C>([rgb.node(), alpha.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(mut prep) => {
                let rgb_state = prep.checkpoint(&rgb);
                let alpha_state = prep.checkpoint(&alpha);
                let out = B::over_composite(rgb.into_primitive(), alpha.into_primitive(), n);
                prep.finish((rgb_state, alpha_state, n), out)
            }
            OpsKind::UnTracked(prep) => prep.finish(B::over_composite(
                rgb.into_primitive(),
                alpha.into_primitive(),
                n,
            )),
        }
    }

    fn over_composite_backward(
        rgb: FloatTensor<Self>,
        alpha: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        n: usize,
    ) -> (FloatTensor<Self>, FloatTensor<Self>) {
        // The gradients themselves, by the inner backend and not tracked (nothing here
        // differentiates a gradient).
        let (g_rgb, g_alpha) = B::over_composite_backward(
            rgb.into_primitive(),
            alpha.into_primitive(),
            grad.into_primitive(),
            n,
        );
        let lift = <FloatTensor<Self>>::new;
        (lift(g_rgb), lift(g_alpha))
    }
}
