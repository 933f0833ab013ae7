mod bicubic;
mod bilinear;
pub(crate) mod lanczos;

/// Utility functions to generate meshgrid and remap images
pub mod grid;

pub(crate) mod interpolate;
mod nearest;
mod remap;

pub use interpolate::validate_interpolation;
pub use interpolate::InterpolationMode;
pub use remap::{remap, remap_u8};

pub(crate) use bicubic::bicubic_sample;
pub(crate) use bilinear::bilinear_interpolation;
pub use interpolate::interpolate_pixel;
pub(crate) use interpolate::interpolate_pixel_fast;
pub(crate) use lanczos::lanczos_sample;
pub(crate) use nearest::nearest_neighbor_interpolation;
