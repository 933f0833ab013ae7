mod affine;
mod common;
#[cfg(feature = "cuda")]
mod cuda;
mod kernels;
mod perspective;
mod span;

pub use affine::{get_rotation_matrix2d, invert_affine_transform, warp_affine, warp_affine_u8};
#[cfg(target_arch = "x86_64")]
pub(crate) use common::bilinear_sample_u8_valid_c3_avx2;
pub(crate) use common::{bilinear_sample_u8_valid, bilinear_sample_u8_valid_unchecked, is_packed};
#[cfg(feature = "cuda")]
pub(crate) use perspective::invert_homography;
pub use perspective::{warp_perspective, warp_perspective_u8};
