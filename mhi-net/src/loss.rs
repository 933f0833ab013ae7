//! Training losses: L1 and a differentiable SSIM term.
//!
//! The paper's loss is L1 plus a VGG-19 perceptual term. The VGG weights come from a registry
//! package that is not wired in yet, so training uses L1 + SSIM (Monodepth's photometric mix);
//! the run's `config.json` records which loss was used.

use burn::tensor::Tensor;
use burn::tensor::module::avg_pool2d;
use burn::tensor::ops::AvgPoolOptions;

/// Mean absolute error.
///
/// # Shapes
/// `[B, C, H, W]`, `[B, C, H, W]` → `[1]`
pub fn l1(a: Tensor<4>, b: Tensor<4>) -> Tensor<1> {
    (a - b).abs().mean()
}

fn pool(x: Tensor<4>) -> Tensor<4> {
    avg_pool2d(
        x,
        AvgPoolOptions {
            kernel_size: [3, 3],
            stride: [1, 1],
            padding: [(0, 0), (0, 0)],
            count_include_pad: false,
            ceil_mode: false,
        },
    )
}

/// `(1 − SSIM) / 2` averaged over pixels, with 3 × 3 box windows (valid region only), C1 =
/// 0.01², C2 = 0.03². In `[0, 1]`; its gradient is finite for constant images (C1, C2 > 0).
///
/// # Shapes
/// `[B, C, H, W]` (H, W ≥ 3) → `[1]`
pub fn ssim_loss(a: Tensor<4>, b: Tensor<4>) -> Tensor<1> {
    let (c1, c2) = (0.01_f32 * 0.01, 0.03_f32 * 0.03);
    let mu_a = pool(a.clone());
    let mu_b = pool(b.clone());
    let sigma_a = pool(a.clone() * a.clone()) - mu_a.clone() * mu_a.clone();
    let sigma_b = pool(b.clone() * b.clone()) - mu_b.clone() * mu_b.clone();
    let sigma_ab = pool(a * b) - mu_a.clone() * mu_b.clone();
    let num = (mu_a.clone() * mu_b.clone() * 2.0 + c1) * (sigma_ab * 2.0 + c2);
    let den = (mu_a.clone() * mu_a + mu_b.clone() * mu_b + c1) * (sigma_a + sigma_b + c2);
    ((num / den).neg() + 1.0).clamp(0.0, 2.0).mean() / 2.0
}

/// The training loss: `0.15 · L1 + 0.85 · (1 − SSIM) / 2`.
///
/// # Shapes
/// `[B, C, H, W]`, `[B, C, H, W]` → `[1]`
pub fn photometric(a: Tensor<4>, b: Tensor<4>) -> Tensor<1> {
    l1(a.clone(), b.clone()) * 0.15 + ssim_loss(a, b) * 0.85
}

/// Name of the loss recorded in a run's config.
pub const LOSS_NAME: &str = "0.15*L1 + 0.85*(1-SSIM)/2 (VGG perceptual weights not available)";

#[cfg(test)]
mod tests {
    use super::*;
    use burn::tensor::Device;

    /// Guard: constant (zero-variance) and saturated images give a finite loss and gradient,
    /// thanks to C1, C2 > 0.
    #[test]
    fn ssim_gradient_is_finite_on_flat_and_saturated_images() {
        let device = Device::flex().autodiff();
        for (va, vb) in [(0.0, 0.0), (1.0, 1.0), (0.0, 1.0), (0.5, 0.5)] {
            let a: Tensor<4> = (Tensor::ones([1, 3, 8, 8], &device) * va).require_grad();
            let b: Tensor<4> = Tensor::ones([1, 3, 8, 8], &device) * vb;
            let loss = photometric(a.clone(), b);
            let grads = loss.backward();
            let g: Vec<f32> = a
                .grad(&grads)
                .expect("gradient")
                .into_data()
                .try_to_vec()
                .unwrap();
            assert!(g.iter().all(|x| x.is_finite()), "{va} vs {vb}");
        }
    }
}
