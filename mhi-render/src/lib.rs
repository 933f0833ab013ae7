//! Rendering of Multiple Homography Images (MHI).
//!
//! An [`Mhi`] holds N × D alpha layers on the reference grid (planes of N normals at D depths)
//! and their colour — by default the reference image itself, shared by every layer. [`render`]
//! warps every layer into a target camera by its plane-induced homography, composites each
//! normal's layers into a multi-normal image and blends those per pixel ([`Blend`]).
//!
//! Degenerate geometry is masked, never clamped: a plane the target camera sits on or behind
//! contributes nothing, as does a sample with homogeneous `w ≤ 1e-6` or outside the reference
//! image.
//!
//! # Example
//!
//! ```
//! use glam::{DMat3, DVec3};
//! use image::Rgb32FImage;
//! use mhi_geom::{BlendHeuristic, Camera, Intrinsics, NormalSet, RigidTransform, depths_linear_in_disparity};
//! use mhi_render::{Blend, LayerColor, Mhi, RenderOptions, render};
//!
//! let k = Intrinsics::new(32.0, 32.0, 32.0, 24.0).unwrap();
//! let reference = Camera::new(k, RigidTransform::IDENTITY, 64, 48).unwrap();
//! let normals = NormalSet::paper();
//! let depths = depths_linear_in_disparity(1.0, 100.0, 8).unwrap();
//! let image = Rgb32FImage::from_fn(64, 48, |x, y| image::Rgb([x as f32 / 64.0, y as f32 / 48.0, 0.5]));
//! let alpha = vec![0.3_f32; normals.len() * depths.len() * 64 * 48];
//! let mhi = Mhi::new(normals, depths, reference, LayerColor::Shared(image), alpha).unwrap();
//!
//! let pose = RigidTransform::new(DMat3::from_rotation_y(0.05), DVec3::new(0.05, 0.0, 0.0)).unwrap();
//! let target = Camera::new(k, pose, 64, 48).unwrap();
//! let opts = RenderOptions { blend: Blend::Heuristic(BlendHeuristic::Soft), ..Default::default() };
//! let view = render(&mhi, &target, &opts).unwrap();
//! assert!(view.image.as_raw().iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
//! ```

mod bilinear;
mod consistency;
pub mod coverage;
mod cpu;
#[cfg(feature = "diff")]
pub mod diff;
mod error;
mod mhi;
mod oracle;
pub mod plan;
pub mod reference;
pub mod stability;
mod sweep;

pub use consistency::{check_beta, consistent_weights, inconsistency_means, inconsistency_mhi};
pub use cpu::{
    Blend, Prune, RenderOptions, RenderStats, Rendered, TILE_H, TILE_W, W_EPS, combine,
    heuristic_weights, heuristic_weights_for, needed_share, needed_share_per_normal, render,
};
pub use error::{Error, Result};
pub use mhi::{ALPHA_BLOCK, LayerColor, Mhi, first_failing};
pub use oracle::{PixelTruth, oracle_alpha, oracle_weights};
pub use sweep::{
    PlaneSweepVolume, SweepConfig, alphas_from_probabilities, check_parallax, plane_sweep_volume,
    sweep_alphas, sweep_mhi,
};
