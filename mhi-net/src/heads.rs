//! Stage 1's outputs brought to the full grid and turned into layers in one pass, with a
//! hand-written backward, for training on the CPU backend.
//!
//! Stage 1 runs on pixel blocks; its alpha residual and colour logit are upsampled bilinearly
//! (corners aligned) to the full grid, where the sweep prior turns the residual into alphas
//! (`clamp(σ(logit + r) + correction, 0, 1)`) and the colour head the logit into colours
//! (`clamp(ref + tanh(m) · (src − ref), 0, 1)`). As tensor operations that is an interpolation
//! and five to seven full-size element-wise passes forward, as many backward, each recorded by
//! autodiff (35–40 ms forward on the shipped model's step). [`upsampled`] does each head in one
//! pass forward and one backward (the gradient with respect to the small grid, through the
//! interpolation's adjoint), with the inference path's arithmetic: `SweepPrior::apply_upsampled`
//! and `SourceColour::apply_upsampled` give the same values.

use std::sync::Arc;

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
use rayon::prelude::*;

use crate::volume::{bilinear_axis, exp_approx, upsample_row};

/// What turns an upsampled plane into a layer, and the grids.
#[derive(Debug)]
pub(crate) struct Head {
    kind: Kind,
    /// `(N·D, H, W)`.
    shape: (usize, usize, usize),
}

#[derive(Debug)]
enum Kind {
    /// The sweep prior: `logit` and `correction`, `[N·D, H, W]`.
    Prior {
        logit: Vec<f32>,
        correction: Vec<f32>,
    },
    /// The colour head: the reference planar `[3, H, W]` and `(src − ref) · valid`,
    /// `[N·D, 3, H, W]`.
    Colour {
        reference: Vec<f32>,
        delta: Vec<f32>,
    },
}

impl Head {
    pub(crate) fn prior(
        logit: Vec<f32>,
        correction: Vec<f32>,
        shape: (usize, usize, usize),
    ) -> Self {
        Self {
            kind: Kind::Prior { logit, correction },
            shape,
        }
    }

    pub(crate) fn colour(
        reference: Vec<f32>,
        delta: Vec<f32>,
        shape: (usize, usize, usize),
    ) -> Self {
        Self {
            kind: Kind::Colour { reference, delta },
            shape,
        }
    }

    /// Output channels per plane.
    fn channels(&self) -> usize {
        match self.kind {
            Kind::Prior { .. } => 1,
            Kind::Colour { .. } => 3,
        }
    }
}

/// `tanh(x)` as the inference path computes it: `1 − 2 / (1 + e^2x)` with `exp_approx`.
#[inline(always)]
fn tanh_approx(x: f32) -> f32 {
    1.0 - 2.0 / (1.0 + exp_approx(2.0 * x))
}

/// Forward: `small` `[N·D, hs, ws]` → `[N·D, C, H, W]`.
fn forward(head: &Head, small: &[f32], (hs, ws): (usize, usize)) -> Vec<f32> {
    let (planes, h, w) = head.shape;
    let (rows, cols) = (bilinear_axis(hs, h), bilinear_axis(ws, w));
    let (c, px) = (head.channels(), h * w);
    let mut out = vec![0.0_f32; planes * c * px];
    out.par_chunks_mut(c * px).enumerate().for_each(|(l, dst)| {
        let src = &small[l * hs * ws..][..hs * ws];
        let mut u = vec![0.0_f32; w];
        for (y, &row) in rows.iter().enumerate() {
            upsample_row(src, ws, row, &cols, &mut u);
            let at = y * w;
            match &head.kind {
                Kind::Prior { logit, correction } => {
                    let (lg, cr) = (&logit[l * px + at..][..w], &correction[l * px + at..][..w]);
                    let o = &mut dst[at..at + w];
                    for x in 0..w {
                        let a = 1.0 / (1.0 + exp_approx(-(lg[x] + u[x])));
                        o[x] = (a + cr[x]).clamp(0.0, 1.0);
                    }
                }
                Kind::Colour { reference, delta } => {
                    for v in u.iter_mut() {
                        *v = tanh_approx(*v);
                    }
                    for ch in 0..3 {
                        let r = &reference[ch * px + at..][..w];
                        let d = &delta[(l * 3 + ch) * px + at..][..w];
                        let o = &mut dst[ch * px + at..][..w];
                        for x in 0..w {
                            o[x] = (r[x] + u[x] * d[x]).clamp(0.0, 1.0);
                        }
                    }
                }
            }
        }
    });
    out
}

/// Backward: the gradient with respect to `small` from the output's `grad`.
fn backward(head: &Head, small: &[f32], (hs, ws): (usize, usize), grad: &[f32]) -> Vec<f32> {
    let (planes, h, w) = head.shape;
    let (rows, cols) = (bilinear_axis(hs, h), bilinear_axis(ws, w));
    let (c, px) = (head.channels(), h * w);
    let mut out = vec![0.0_f32; planes * hs * ws];
    out.par_chunks_mut(hs * ws).enumerate().for_each(|(l, gs)| {
        let src = &small[l * hs * ws..][..hs * ws];
        let g = &grad[l * c * px..][..c * px];
        let (mut u, mut gu) = (vec![0.0_f32; w], vec![0.0_f32; w]);
        for (y, &(y0, y1, wy)) in rows.iter().enumerate() {
            upsample_row(src, ws, (y0, y1, wy), &cols, &mut u);
            let at = y * w;
            // The gradient with respect to the upsampled value; a clamped output passes none.
            match &head.kind {
                Kind::Prior { logit, correction } => {
                    let (lg, cr) = (&logit[l * px + at..][..w], &correction[l * px + at..][..w]);
                    for x in 0..w {
                        let a = 1.0 / (1.0 + exp_approx(-(lg[x] + u[x])));
                        let v = a + cr[x];
                        gu[x] = if (0.0..=1.0).contains(&v) {
                            g[at + x] * a * (1.0 - a)
                        } else {
                            0.0
                        };
                    }
                }
                Kind::Colour { reference, delta } => {
                    for x in 0..w {
                        let t = tanh_approx(u[x]);
                        let mut sum = 0.0_f32;
                        for ch in 0..3 {
                            let (r, d) = (
                                reference[ch * px + at + x],
                                delta[(l * 3 + ch) * px + at + x],
                            );
                            let v = r + t * d;
                            if (0.0..=1.0).contains(&v) {
                                sum += g[ch * px + at + x] * d;
                            }
                        }
                        gu[x] = sum * (1.0 - t * t);
                    }
                }
            }
            // The interpolation's adjoint: each output's gradient back to its four taps.
            for (x, &(x0, x1, wx)) in cols.iter().enumerate() {
                let v = gu[x];
                gs[y0 * ws + x0] += v * (1.0 - wx) * (1.0 - wy);
                gs[y0 * ws + x1] += v * wx * (1.0 - wy);
                gs[y1 * ws + x0] += v * (1.0 - wx) * wy;
                gs[y1 * ws + x1] += v * wx * wy;
            }
        }
    });
    out
}

/// The two heads as backend operations.
#[backend_extension(Flex, Autodiff)]
pub trait HeadOps: Backend {
    /// `small` `[N·D, hs, ws]` → `[N·D, C, H, W]` through `head`.
    fn upsampled_head(small: FloatTensor<Self>, head: Arc<Head>) -> FloatTensor<Self>;
    /// The gradient of [`HeadOps::upsampled_head`] with respect to `small`.
    fn upsampled_head_backward(
        small: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        head: Arc<Head>,
    ) -> FloatTensor<Self>;
}

impl HeadOps for Flex {
    fn upsampled_head(small: FlexTensor, head: Arc<Head>) -> FlexTensor {
        let s = small.shape().to_vec();
        let small = mhi_kernels::f32_contiguous(small);
        let out = forward(&head, small.storage::<f32>(), (s[1], s[2]));
        let (planes, h, w) = head.shape;
        FlexTensor::from_data(TensorData::new(out, [planes, head.channels(), h, w]))
    }

    fn upsampled_head_backward(small: FlexTensor, grad: FlexTensor, head: Arc<Head>) -> FlexTensor {
        let s = small.shape().to_vec();
        let (small, grad) = (
            mhi_kernels::f32_contiguous(small),
            mhi_kernels::f32_contiguous(grad),
        );
        let g = backward(
            &head,
            small.storage::<f32>(),
            (s[1], s[2]),
            grad.storage::<f32>(),
        );
        FlexTensor::from_data(TensorData::new(g, s))
    }
}

/// The autodiff node: its state is the small input (checkpointed) and the head.
#[derive(Debug)]
struct Upsampled;

impl<B: Backend + HeadOps> Backward<B, 1> for Upsampled {
    type State = (NodeId, Arc<Head>);

    fn backward(
        self,
        ops: Ops<Self::State, 1>,
        grads: &mut Gradients,
        checkpointer: &mut Checkpointer,
    ) {
        let [node] = ops.parents;
        let grad = grads.consume::<B>(&ops.node);
        let (small_state, head) = ops.state;
        let small = checkpointer.retrieve_node_output::<B::FloatTensorPrimitive>(small_state);
        if let Some(node) = node {
            grads.register::<B>(node.id, B::upsampled_head_backward(small, grad, head));
        }
    }
}

impl<B: Backend + HeadOps, C: CheckpointStrategy> HeadOps for Autodiff<B, C> {
    fn upsampled_head(small: FloatTensor<Self>, head: Arc<Head>) -> FloatTensor<Self> {
        match Upsampled
            .prepare::<C>([small.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(mut prep) => {
                let state = prep.checkpoint(&small);
                let out = B::upsampled_head(small.into_primitive(), head.clone());
                prep.finish((state, head), out)
            }
            OpsKind::UnTracked(prep) => {
                prep.finish(B::upsampled_head(small.into_primitive(), head))
            }
        }
    }

    fn upsampled_head_backward(
        small: FloatTensor<Self>,
        grad: FloatTensor<Self>,
        head: Arc<Head>,
    ) -> FloatTensor<Self> {
        // The gradient itself, by the inner backend and not tracked.
        <FloatTensor<Self>>::new(B::upsampled_head_backward(
            small.into_primitive(),
            grad.into_primitive(),
            head,
        ))
    }
}

/// `small` (`[N·D, hs, ws]`) upsampled to the head's grid and turned into layers:
/// `[N·D, 1, H, W]` alphas or `[N·D, 3, H, W]` colours.
pub(crate) fn upsampled(small: Tensor<3>, head: Arc<Head>) -> Tensor<4> {
    let out = <burn::backend::Dispatch as HeadOps>::upsampled_head(small.into_dispatch(), head);
    Tensor::<4>::from_dispatch(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{SourceColour, SweepPrior};
    use burn::tensor::module::interpolate;
    use burn::tensor::ops::{InterpolateMode, InterpolateOptions};
    use burn::tensor::{Device, Distribution};

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data()
            .convert::<f32>()
            .try_to_vec::<f32>()
            .expect("f32 values")
    }

    fn max_rel(a: &[f32], b: &[f32]) -> f32 {
        let scale = b.iter().fold(1e-6_f32, |m, v| m.max(v.abs()));
        a.iter()
            .zip(b)
            .fold(0.0_f32, |m, (x, y)| m.max((x - y).abs()))
            / scale
    }

    /// The fused heads against the interpolation and the heads as tensor operations: the same
    /// values and the same gradient with respect to the small grid, with clamped outputs (a
    /// correction pushing alphas past 1, colours past 0 or 1) among them.
    #[test]
    fn fused_heads_match_the_tensor_operations() {
        let dev = Device::flex().autodiff();
        dev.seed(5);
        let (planes, hs, ws, h, w) = (6, 5, 7, 10, 14);
        let px = h * w;
        let rnd = |n: usize, lo: f32, hi: f32, seed: u64| -> Vec<f32> {
            let mut s = seed;
            (0..n)
                .map(|_| {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    lo + (hi - lo) * ((s >> 40) as f32 / (1u64 << 24) as f32)
                })
                .collect()
        };
        let mut correction = vec![0.0_f32; planes * px];
        for (i, c) in correction.iter_mut().enumerate() {
            if i % 7 == 0 {
                *c = 0.6;
            }
        }
        let prior = SweepPrior {
            logit: rnd(planes * px, -6.9, 6.9, 1),
            correction,
            shape: (planes, h, w),
        };
        let psv = mhi_render::PlaneSweepVolume {
            n: 2,
            d: 3,
            width: w as u32,
            height: h as u32,
            rgb: rnd(planes * px * 3, -0.5, 1.5, 2),
            valid: rnd(planes * px, 0.0, 1.0, 3)
                .into_iter()
                .map(|v| if v > 0.2 { 1.0 } else { 0.0 })
                .collect(),
        };
        let reference = image::Rgb32FImage::from_raw(w as u32, h as u32, rnd(3 * px, 0.0, 1.0, 4))
            .expect("an image");
        let colour = SourceColour::new(psv, &reference);
        let mut opts = InterpolateOptions::new(InterpolateMode::Bilinear);
        opts.output_size = Some([h, w]);
        let up = |small: Tensor<3>| {
            interpolate(small.reshape([1, planes, hs, ws]), opts.clone()).reshape([planes, 1, h, w])
        };
        for (name, head, reference_path) in [
            (
                "prior",
                Arc::new(prior.head()),
                Box::new(|s: Tensor<3>| prior.apply(up(s))) as Box<dyn Fn(Tensor<3>) -> Tensor<4>>,
            ),
            (
                "colour",
                Arc::new(colour.head()),
                Box::new(|s: Tensor<3>| colour.apply(up(s))),
            ),
        ] {
            let small =
                Tensor::<3>::random([planes, hs, ws], Distribution::Uniform(-3.0, 3.0), &dev)
                    .require_grad();
            let ours = upsampled(small.clone(), head);
            let theirs = reference_path(small.clone());
            assert_eq!(ours.dims(), theirs.dims(), "{name}");
            let (a, b) = (values(ours.clone()), values(theirs.clone()));
            let clamped = b.iter().filter(|v| **v == 0.0 || **v == 1.0).count();
            assert!(clamped > 0, "{name}: no output was clamped");
            let err = max_rel(&a, &b);
            assert!(err < 2e-6, "{name}: values differ by {err}");
            let weights = Tensor::<4>::random(ours.dims(), Distribution::Uniform(-1.0, 1.0), &dev);
            let ga = small
                .grad(&(ours * weights.clone()).sum().backward())
                .expect("a gradient");
            let gb = small
                .grad(&(theirs * weights).sum().backward())
                .expect("a gradient");
            let err = max_rel(&values(ga), &values(gb));
            assert!(err < 1e-4, "{name}: gradients differ by {err} (relative)");
        }
    }
}
