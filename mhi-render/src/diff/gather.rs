//! The warp as a gather with precomputed bilinear taps and a hand-written backward, for the CPU
//! backend.
//!
//! burn's `grid_sample` recomputes the bilinear positions and weights from the grid on every call
//! and goes through its generic backward, on these shapes 6–20× PyTorch's (docs/SPEED.md). The
//! grid of a training sample is a constant, so [`Taps`] computes once, per target pixel of every
//! layer, the four source pixels and their weights (zero outside the reference image or where the
//! plane is not visible); the warp is then `out[p] = Σ w · in[idx]` per channel row and its
//! gradient the matching scatter-add, each row on its own core. Same values as `grid_sample`
//! (bilinear, zero padding, `align_corners = false`) times the validity mask, to float rounding
//! (`tests/diff.rs`).

use std::sync::Arc;

use burn::backend::autodiff::Autodiff;
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::tensor::FloatTensor;
use burn::backend::{Backend, TensorMetadata, backend_extension};
use burn::tensor::{Tensor, TensorData};
use burn_flex::{Flex, FlexTensor};
use rayon::prelude::*;

/// The four bilinear source pixels and weights of every target pixel of every layer.
#[derive(Debug)]
pub struct Taps {
    /// Layers (N · D).
    pub layers: usize,
    /// Source image (reference) width and height.
    pub source_size: (usize, usize),
    /// Target image width and height.
    pub target_size: (usize, usize),
    source: usize,
    target: usize,
    idx: Vec<[u32; 4]>,
    weight: Vec<[f32; 4]>,
}

impl Taps {
    /// The taps of a `grid_sample` grid (`[layers, H, W, 2]`, normalised, `align_corners =
    /// false`) over a `source_w × source_h` image, times `valid` (`[layers, H, W]`, 0 or 1), for
    /// a `target_size` (W, H) target.
    pub fn new(
        grid: &[f32],
        valid: &[f32],
        layers: usize,
        (source_w, source_h): (usize, usize),
        target_size: (usize, usize),
    ) -> Self {
        let target = target_size.0 * target_size.1;
        assert_eq!(
            valid.len(),
            layers * target,
            "valid covers every target pixel of every layer"
        );
        assert_eq!(
            grid.len(),
            2 * layers * target,
            "grid covers every target pixel of every layer"
        );
        let (sw, sh) = (source_w as f32, source_h as f32);
        let mut idx = vec![[0u32; 4]; layers * target];
        let mut weight = vec![[0.0f32; 4]; layers * target];
        idx.par_iter_mut()
            .zip(weight.par_iter_mut())
            .enumerate()
            .for_each(|(k, (ix, wt))| {
                if valid[k] == 0.0 {
                    return;
                }
                // grid_sample's unnormalisation (align_corners = false).
                let x = ((grid[2 * k] + 1.0) * sw - 1.0) / 2.0;
                let y = ((grid[2 * k + 1] + 1.0) * sh - 1.0) / 2.0;
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let corners = [
                    (x0, y0, (1.0 - fx) * (1.0 - fy)),
                    (x0 + 1.0, y0, fx * (1.0 - fy)),
                    (x0, y0 + 1.0, (1.0 - fx) * fy),
                    (x0 + 1.0, y0 + 1.0, fx * fy),
                ];
                for (t, (cx, cy, w)) in corners.into_iter().enumerate() {
                    if cx >= 0.0 && cy >= 0.0 && cx < sw && cy < sh {
                        ix[t] = (cy as usize * source_w + cx as usize) as u32;
                        wt[t] = w;
                    }
                }
            });
        Self {
            layers,
            source_size: (source_w, source_h),
            target_size,
            source: source_w * source_h,
            target,
            idx,
            weight,
        }
    }

    /// `out` (one target row) from `src` (one source row of layer `l`).
    fn gather(&self, l: usize, src: &[f32], out: &mut [f32]) {
        let (ix, wt) = (
            &self.idx[l * self.target..],
            &self.weight[l * self.target..],
        );
        for (p, o) in out.iter_mut().enumerate() {
            let (i, w) = (ix[p], wt[p]);
            *o = w[0] * src[i[0] as usize]
                + w[1] * src[i[1] as usize]
                + w[2] * src[i[2] as usize]
                + w[3] * src[i[3] as usize];
        }
    }

    /// Adds the adjoint of [`Taps::gather`] of `grad` (one target row) onto `src_grad`.
    fn scatter(&self, l: usize, grad: &[f32], src_grad: &mut [f32]) {
        let (ix, wt) = (
            &self.idx[l * self.target..],
            &self.weight[l * self.target..],
        );
        for (p, g) in grad.iter().enumerate() {
            let (i, w) = (ix[p], wt[p]);
            for t in 0..4 {
                src_grad[i[t] as usize] += w[t] * g;
            }
        }
    }
}

/// The warp as backend operations.
#[backend_extension(Flex, Autodiff)]
pub trait WarpOps: Backend {
    /// `[L, C, Hr, Wr]` → `[L, C, H, W]` through `taps`.
    fn gather_warp(layers: FloatTensor<Self>, taps: Arc<Taps>) -> FloatTensor<Self>;
    /// The gradient of [`WarpOps::gather_warp`] with respect to its layers.
    fn gather_warp_backward(grad: FloatTensor<Self>, taps: Arc<Taps>) -> FloatTensor<Self>;
}

pub use mhi_kernels::on_cpu_backend;

/// Warp `layers` (`[L, C, Hr, Wr]`) through `taps`: `[L, C, H, W]`.
pub fn warp(layers: Tensor<4>, taps: &Arc<Taps>) -> Tensor<4> {
    let out =
        <burn::backend::Dispatch as WarpOps>::gather_warp(layers.into_dispatch(), taps.clone());
    Tensor::<4>::from_dispatch(out)
}

pub use mhi_kernels::f32_contiguous;

impl WarpOps for Flex {
    fn gather_warp(layers: FlexTensor, taps: Arc<Taps>) -> FlexTensor {
        let shape = layers.shape().to_vec();
        let (l, c) = (shape[0], shape[1]);
        let layers = f32_contiguous(layers);
        let src = layers.storage::<f32>();
        let mut out = vec![0.0f32; l * c * taps.target];
        out.par_chunks_mut(taps.target.max(1))
            .enumerate()
            .for_each(|(row, o)| {
                taps.gather(row / c, &src[row * taps.source..(row + 1) * taps.source], o);
            });
        let (w, h) = taps.target_size;
        FlexTensor::from_data(TensorData::new(out, [l, c, h, w]))
    }

    fn gather_warp_backward(grad: FlexTensor, taps: Arc<Taps>) -> FlexTensor {
        let shape = grad.shape().to_vec();
        let (l, c) = (shape[0], shape[1]);
        let grad = f32_contiguous(grad);
        let g = grad.storage::<f32>();
        let mut out = vec![0.0f32; l * c * taps.source];
        out.par_chunks_mut(taps.source.max(1))
            .enumerate()
            .for_each(|(row, o)| {
                taps.scatter(row / c, &g[row * taps.target..(row + 1) * taps.target], o);
            });
        let (w, h) = taps.source_size;
        FlexTensor::from_data(TensorData::new(out, [l, c, h, w]))
    }
}

/// The autodiff node of the warp: its state is the taps.
#[derive(Debug)]
struct GatherWarp;

impl<B: Backend + WarpOps> Backward<B, 1> for GatherWarp {
    type State = Arc<Taps>;

    fn backward(self, ops: Ops<Self::State, 1>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [node] = ops.parents;
        let grad = grads.consume::<B>(&ops.node);
        if let Some(node) = node {
            grads.register::<B>(node.id, B::gather_warp_backward(grad, ops.state));
        }
    }
}

impl<B: Backend + WarpOps, C: CheckpointStrategy> WarpOps for Autodiff<B, C> {
    fn gather_warp(layers: FloatTensor<Self>, taps: Arc<Taps>) -> FloatTensor<Self> {
        match GatherWarp
            .prepare::<C>([layers.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let out = B::gather_warp(layers.into_primitive(), taps.clone());
                prep.finish(taps, out)
            }
            OpsKind::UnTracked(prep) => prep.finish(B::gather_warp(layers.into_primitive(), taps)),
        }
    }

    fn gather_warp_backward(grad: FloatTensor<Self>, taps: Arc<Taps>) -> FloatTensor<Self> {
        // The gradient itself, by the inner backend and not tracked (nothing here
        // differentiates a gradient).
        <FloatTensor<Self>>::new(B::gather_warp_backward(grad.into_primitive(), taps))
    }
}
