use super::common::bilinear_sample_u8;
use super::kernels::process_perspective_span;
use crate::{
    interpolation::{validate_interpolation, InterpolationMode},
    parallel,
};

use kornia_image::{Image, ImageError};

#[rustfmt::skip]
fn determinant3x3(m: &[f32; 9]) -> f32 {
    m[0] * (m[4] * m[8] - m[5] * m[7]) -
    m[1] * (m[3] * m[8] - m[5] * m[6]) +
    m[2] * (m[3] * m[7] - m[4] * m[6])
}

#[rustfmt::skip]
fn adjugate3x3(m: &[f32; 9]) -> [f32; 9] {
    [
        m[4] * m[8] - m[5] * m[7],  // [0, 0]
        m[2] * m[7] - m[1] * m[8],  // [0, 1]
        m[1] * m[5] - m[2] * m[4],  // [0, 2]
        m[5] * m[6] - m[3] * m[8],  // [1, 0]
        m[0] * m[8] - m[2] * m[6],  // [1, 1]
        m[2] * m[3] - m[0] * m[5],  // [1, 2]
        m[3] * m[7] - m[4] * m[6],  // [2, 0]
        m[1] * m[6] - m[0] * m[7],  // [2, 1]
        m[0] * m[4] - m[1] * m[3],  // [2, 2]
    ]
}

/// Invert a 3×3 homography matrix.
///
/// Returns `None` for singular or near-singular matrices.  The singularity
/// test is **scale-invariant**: the determinant is normalised by `|h[8]|³`
/// before comparison so that a geometrically valid but unnormalised homography
/// (all entries multiplied by a small scalar) is not incorrectly rejected —
/// `det(kH) = k³ det(H)` would shrink the raw det below a fixed ε even when
/// the geometry is perfectly sound.  Falls back to the raw det when `h[8]`
/// itself is near zero.
pub(crate) fn invert_homography(m: &[f32; 9]) -> Option<[f32; 9]> {
    let det = determinant3x3(m);
    // Normalise by |h[8]|³ to get a scale-invariant singularity indicator.
    let h8_sq = m[8] * m[8];
    let det_norm = if h8_sq > f32::EPSILON {
        det / (h8_sq * m[8].abs())
    } else {
        det
    };
    if det_norm.abs() < 1e-10 {
        return None;
    }
    let adj = adjugate3x3(m);
    let inv_det = 1.0 / det;
    let mut inv = [0.0f32; 9];
    for i in 0..9 {
        inv[i] = adj[i] * inv_det;
    }
    Some(inv)
}

pub(super) fn inverse_perspective_matrix(m: &[f32; 9]) -> Result<[f32; 9], ImageError> {
    invert_homography(m).ok_or(ImageError::CannotComputeDeterminant)
}

// implement later as batched operation
fn transform_point(x: f32, y: f32, m: &[f32; 9]) -> (f32, f32) {
    let w = m[6] * x + m[7] * y + m[8];
    let x_out = (m[0] * x + m[1] * y + m[2]) / w;
    let y_out = (m[3] * x + m[4] * y + m[5]) / w;
    (x_out, y_out)
}

/// Applies a perspective transformation to an image.
///
/// * `src` - The input image with shape (height, width, channels).
/// * `dst` - The output image with shape (height, width, channels).
/// * `m` - The 3x3 perspective transformation matrix src -> dst.
/// * `interpolation` - The interpolation mode to use.
///
/// # Returns
///
/// The output image with shape (new_height, new_width, channels).
///
/// # Example
///
/// ```
/// use kornia_image::{Image, ImageSize};
/// use kornia_imgproc::interpolation::InterpolationMode;
/// use kornia_imgproc::warp::warp_perspective;
///
/// let src = Image::<f32, 1>::new(
///   ImageSize {
///     width: 4,
///     height: 5,
///   },
///   vec![0.0f32; 4 * 5],
/// ).unwrap();
///
/// let m = [1.0, 0.0, -1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0];
///
/// let mut dst = Image::<f32, 1>::from_size_val(
///   ImageSize {
///     width: 2,
///     height: 3,
///   },
///   0.0,
/// ).unwrap();
///
/// warp_perspective(&src, &mut dst, &m, InterpolationMode::Bilinear).unwrap();
///
/// assert_eq!(dst.size().width, 2);
/// assert_eq!(dst.size().height, 3);
/// ```
pub fn warp_perspective<const C: usize>(
    src: &Image<f32, C>,
    dst: &mut Image<f32, C>,
    m: &[f32; 9],
    interpolation: InterpolationMode,
) -> Result<(), ImageError> {
    validate_interpolation(interpolation)?;

    // Device pairs route to the CUDA kernels (bit-identical output — the
    // byte-exact contract asserted in `cuda::warp_perspective`). Mixed pairs
    // are a typed error; no implicit transfers.
    #[cfg(feature = "cuda")]
    if let crate::cuda::dispatch::Residency::Device(exec) =
        crate::cuda::dispatch::pair_residency(src, dst)?
    {
        return exec.run(|stream| {
            super::cuda::warp_perspective_f32_cuda(src, dst, m, interpolation, stream)
        });
    }

    // inverse perspective matrix
    // TODO: allow later to skip the inverse calculation if user provides it
    let inv_m = inverse_perspective_matrix(m)?;

    // apply perspective transformation without pre-allocating coordinate maps
    // One monomorphic pixel loop per mode — see the note in `resize`.
    macro_rules! run {
        ($sampler:path) => {
            parallel::par_iter_rows_spatial_mapping(
                dst,
                |x, y| transform_point(x as f32, y as f32, &inv_m),
                |x, y, dst_pixel| {
                    if x >= 0.0f32 && x < src.cols() as f32 && y >= 0.0f32 && y < src.rows() as f32
                    {
                        dst_pixel.iter_mut().enumerate().for_each(|(k, pixel)| {
                            *pixel = $sampler(src, x, y, k);
                        });
                    }
                },
            )
        };
    }
    match interpolation {
        InterpolationMode::Bilinear => run!(crate::interpolation::bilinear_interpolation),
        InterpolationMode::Nearest => run!(crate::interpolation::nearest_neighbor_interpolation),
        InterpolationMode::Bicubic => run!(crate::interpolation::bicubic_sample),
        InterpolationMode::Lanczos => run!(crate::interpolation::lanczos_sample),
    }

    Ok(())
}

/// u8 perspective warp with bilinear — direct u8 path (no f32 round-trip),
/// Q10 fixed-point weights.
///
/// Per dst row, `nx`, `ny`, `nd` advance linearly with `dnx/dny/dnd`. As
/// long as `nd` keeps one sign across the row, the source-bounds
/// constraints `0 ≤ nx/nd < src_w` and `0 ≤ ny/nd < src_h` become linear
/// inequalities in `x`. We solve them analytically, zero-fill the
/// out-of-bounds left/right segments with `memset`, and run a
/// branch-free inner loop that dispatches to `bilinear_sample_u8_valid`
/// (NEON C=3 path on aarch64). Falls back to the scalar bounds-checked
/// sampler only if `nd` changes sign within the row (rare: matrix
/// collapses points to the line-at-infinity inside the image).
pub fn warp_perspective_u8<const C: usize>(
    src: &Image<u8, C>,
    dst: &mut Image<u8, C>,
    m: &[f32; 9],
) -> Result<(), ImageError> {
    use rayon::prelude::*;

    // Device pairs route to the CUDA u8 kernel (bit-identical output — the
    // kernel mirrors this function's direct per-column coordinates and Q10
    // sampler; see `cuda::warp_perspective_u8`). Mixed host/device pairs are
    // a typed error; there is no implicit transfer in either direction.
    #[cfg(feature = "cuda")]
    if let crate::cuda::dispatch::Residency::Device(exec) =
        crate::cuda::dispatch::pair_residency(src, dst)?
    {
        return exec.run(|stream| super::cuda::warp_perspective_u8_cuda(src, dst, m, stream));
    }

    let inv = inverse_perspective_matrix(m)?;
    let src_w = src.cols() as i32;
    let src_h = src.rows() as i32;
    let src_w_f = src_w as f32;
    let src_h_f = src_h as f32;
    let src_stride = src.cols() * C;
    let dst_w = dst.cols();
    let dst_stride = dst_w * C;
    let src_slice = src.as_slice();
    let (dnx, dny, dnd) = (inv[0], inv[3], inv[6]);

    crate::parallel::par_rows_exact_mut(dst.as_slice_mut(), dst_stride)
        .enumerate()
        .for_each(|(y, dst_row)| {
            let y_f = y as f32;
            let nx0 = inv[1] * y_f + inv[2];
            let ny0 = inv[4] * y_f + inv[5];
            let nd0 = inv[7] * y_f + inv[8];

            // nd at x=0 and x=dst_w-1. If they have the same sign (and
            // aren't near zero), nd is uniform-sign across the row and the
            // 4 source-bounds constraints become linear in x.
            let nd_end = nd0 + dnd * (dst_w as f32 - 1.0);
            let nd_uniform_pos = nd0 > 1e-6 && nd_end > 1e-6;
            let nd_uniform_neg = nd0 < -1e-6 && nd_end < -1e-6;

            if !(nd_uniform_pos || nd_uniform_neg) {
                // Fallback: per-pixel bounds-checked scalar path, direct
                // coordinate evaluation (no `+= dn` drift — the same
                // expression tree every backend and the CUDA u8 kernel use).
                for x in 0..dst_w {
                    let (xf, yf) =
                        super::kernels::perspective_coord_at(x, nx0, ny0, nd0, dnx, dny, dnd);
                    let dst_pixel = &mut dst_row[x * C..x * C + C];
                    bilinear_sample_u8::<C>(src_slice, src_w, src_h, src_stride, xf, yf, dst_pixel);
                }
                return;
            }

            // If nd < 0, negate numerators so the ≥ 0 / < src_bound
            // constraints can be multiplied through by `nd` (now > 0)
            // without flipping inequality direction. xf = nx/nd is
            // invariant under (nx, nd) → (-nx, -nd).
            let (nx0, ny0, nd0, dnx, dny, dnd) = if nd_uniform_pos {
                (nx0, ny0, nd0, dnx, dny, dnd)
            } else {
                (-nx0, -ny0, -nd0, -dnx, -dny, -dnd)
            };

            // Linear constraints `a*x + b op 0` intersected on the integer
            // column range — `warp::span::constrain_span` owns the
            // inclusive/strict boundary rounding (an earlier revision applied
            // `ceil` to both ends, dropping a valid edge column whenever the
            // boundary landed exactly on an integer).
            let (mut lo, mut hi) = (0i64, dst_w as i64);
            // nx + dnx*x >= 0
            super::span::constrain_span(dnx, nx0, true, 0.0, &mut lo, &mut hi);
            // nx - src_w*nd + (dnx - src_w*dnd)*x < 0
            super::span::constrain_span(
                dnx - src_w_f * dnd,
                nx0 - src_w_f * nd0,
                false,
                0.0,
                &mut lo,
                &mut hi,
            );
            super::span::constrain_span(dny, ny0, true, 0.0, &mut lo, &mut hi);
            super::span::constrain_span(
                dny - src_h_f * dnd,
                ny0 - src_h_f * nd0,
                false,
                0.0,
                &mut lo,
                &mut hi,
            );

            let x_lo = lo.clamp(0, dst_w as i64) as usize;
            let x_hi = hi.clamp(0, dst_w as i64) as usize;
            let (x_lo, x_hi) = if x_lo >= x_hi { (0, 0) } else { (x_lo, x_hi) };

            // Zero-fill left/right invalid regions with memset.
            dst_row[..x_lo * C].fill(0);
            dst_row[x_hi * C..].fill(0);

            if x_lo >= x_hi {
                return;
            }

            // Shrink by 1 pixel on each side as a safety margin against
            // float roundoff producing xf = src_w_f exactly (which would
            // overflow xi to src_w and break the valid-sampler's
            // clamp-to-(src_w-1) assumption). The 2 edge pixels per row
            // are rendered via the scalar bounds-checked sampler — with
            // direct coordinates it produces the same bytes as the valid
            // sampler whenever the coordinate is in bounds.
            let x_safe_lo = x_lo + 1;
            let x_safe_hi = x_hi.saturating_sub(1);

            let edge = |x: usize, dst_row: &mut [u8]| {
                let (xf, yf) =
                    super::kernels::perspective_coord_at(x, nx0, ny0, nd0, dnx, dny, dnd);
                let dst_pixel = &mut dst_row[x * C..x * C + C];
                bilinear_sample_u8::<C>(src_slice, src_w, src_h, src_stride, xf, yf, dst_pixel);
            };

            if x_safe_lo > x_lo && x_lo < x_hi {
                edge(x_lo, dst_row);
            }

            // Dispatch the valid-span inner loop to the best available
            // backend (NEON on aarch64, scalar elsewhere). All backends
            // evaluate the coordinate directly per column and are
            // bit-identical (see `process_perspective_span`).
            if x_safe_lo < x_safe_hi {
                process_perspective_span::<C>(
                    src_slice, src_w, src_h, src_stride, dst_row, x_safe_lo, x_safe_hi, nx0, ny0,
                    nd0, dnx, dny, dnd,
                );
            }

            if x_safe_hi < x_hi && x_safe_hi >= x_safe_lo {
                edge(x_safe_hi, dst_row);
            }
        });

    Ok(())
}

#[cfg(test)]
mod tests {

    /// A destination pixel whose source coordinate lands exactly on the
    /// top/left edge is inside the image and must be sampled, not zero-filled.
    ///
    /// The u8 fast path derives the valid column span from linear constraints
    /// whose inclusive/strict ends swap with the coefficient sign; an earlier
    /// revision applied `ceil` to both ends, zero-filling the valid column
    /// whenever the boundary fell on an exact integer (`warp_affine` had the
    /// same bug — see `warp::span`). A horizontal flip hits it on every row.
    #[test]
    fn warp_perspective_u8_samples_pixels_exactly_on_the_edge(
    ) -> Result<(), kornia_image::ImageError> {
        use kornia_image::{Image, ImageSize};
        let size = ImageSize {
            width: 4,
            height: 2,
        };
        let src = Image::<u8, 1>::new(size, vec![10, 20, 30, 40, 50, 60, 70, 80])?;
        let mut dst = Image::<u8, 1>::from_size_val(size, 255)?;

        // Horizontal flip as a homography: dst_x = 3 - src_x.
        let m = [-1.0, 0.0, 3.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        super::warp_perspective_u8(&src, &mut dst, &m)?;

        assert_eq!(
            dst.as_slice(),
            &[40, 30, 20, 10, 80, 70, 60, 50],
            "flip must sample every column, including the one landing exactly on src x=0"
        );
        Ok(())
    }
    use kornia_image::{Image, ImageError, ImageSize};

    // ── invert_homography unit tests ──────────────────────────────────────────

    /// Helper: multiply two 3×3 row-major matrices.
    fn mat3_mul(a: &[f32; 9], b: &[f32; 9]) -> [f32; 9] {
        let mut c = [0.0f32; 9];
        for row in 0..3 {
            for col in 0..3 {
                for k in 0..3 {
                    c[row * 3 + col] += a[row * 3 + k] * b[k * 3 + col];
                }
            }
        }
        c
    }

    #[test]
    fn invert_homography_known() {
        // Translation: H maps (x,y) → (x+2, y+3).  Inverse: (x,y) → (x-2, y-3).
        let h: [f32; 9] = [1.0, 0.0, 2.0, 0.0, 1.0, 3.0, 0.0, 0.0, 1.0];
        let expected: [f32; 9] = [1.0, 0.0, -2.0, 0.0, 1.0, -3.0, 0.0, 0.0, 1.0];
        let inv = super::invert_homography(&h).expect("translation H must be invertible");
        for (a, b) in inv.iter().zip(expected.iter()) {
            assert!((a - b).abs() < 1e-6, "inv[i]={a} expected {b}");
        }
    }

    #[test]
    fn invert_homography_round_trip() {
        // Non-trivial projective H; H · H⁻¹ must be ≈ identity.
        let h: [f32; 9] = [1.02, 0.03, -5.0, -0.01, 0.99, 2.0, 0.00005, 0.00003, 1.0];
        let inv = super::invert_homography(&h).expect("valid H must be invertible");
        let prod = mat3_mul(&h, &inv);
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        for (a, b) in prod.iter().zip(identity.iter()) {
            assert!((a - b).abs() < 1e-5, "H·H⁻¹[i]={a} expected {b}");
        }
    }

    #[test]
    fn invert_homography_singular_returns_none() {
        // All-zero matrix is singular.
        let h = [0.0f32; 9];
        assert!(super::invert_homography(&h).is_none());

        // Rank-1 matrix (rows are scalar multiples).
        let h2: [f32; 9] = [1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 3.0, 6.0, 9.0];
        assert!(super::invert_homography(&h2).is_none());
    }

    #[test]
    fn invert_homography_small_scale_accepted() {
        // Scale-invariant check: H/1000 must still be accepted.
        // A fixed-magnitude det threshold would reject this even though the
        // geometry is perfectly valid.
        let h: [f32; 9] = [1.0, 0.0, 2.0, 0.0, 1.0, 3.0, 0.0, 0.0, 1.0];
        let small: [f32; 9] = h.map(|v| v * 0.001);
        assert!(
            super::invert_homography(&small).is_some(),
            "scaled-down valid H must not be rejected as singular"
        );
    }

    #[test]
    fn inverse_perspective_matrix() -> Result<(), ImageError> {
        let m = [1.0, 0.0, -1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0];
        let expected = [1.0, 0.0, 1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0];
        let inv_m = super::inverse_perspective_matrix(&m)?;
        assert_eq!(inv_m, expected);
        Ok(())
    }

    #[test]
    fn transform_point() {
        let m = [1.0, 0.0, -1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0];
        let (x, y) = super::transform_point(1.0, 1.0, &m);
        let (x_expected, y_expected) = (0.0, 2.0);
        assert_eq!(x, x_expected);
        assert_eq!(y, y_expected);
    }

    #[test]
    fn warp_perspective_identity() -> Result<(), ImageError> {
        let image: Image<f32, 3> = Image::from_size_val(
            ImageSize {
                width: 4,
                height: 5,
            },
            0.0f32,
        )?;

        // identity matrix
        let m = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

        let new_size = ImageSize {
            width: 2,
            height: 3,
        };

        let mut image_transformed = Image::from_size_val(new_size, 0.0)?;

        super::warp_perspective(
            &image,
            &mut image_transformed,
            &m,
            super::InterpolationMode::Bilinear,
        )?;

        assert_eq!(image_transformed.num_channels(), 3);
        assert_eq!(image_transformed.size().width, 2);
        assert_eq!(image_transformed.size().height, 3);

        Ok(())
    }

    /// Bicubic/Lanczos are supported since the CPU samplers landed.
    #[test]
    fn warp_perspective_supports_all_modes() -> Result<(), ImageError> {
        let src = Image::<f32, 1>::from_size_val(
            ImageSize {
                width: 2,
                height: 2,
            },
            0.0,
        )?;
        let mut dst = Image::<f32, 1>::from_size_val(
            ImageSize {
                width: 2,
                height: 2,
            },
            0.0,
        )?;
        let m = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        super::warp_perspective(&src, &mut dst, &m, super::InterpolationMode::Bicubic)?;
        super::warp_perspective(&src, &mut dst, &m, super::InterpolationMode::Lanczos)?;
        Ok(())
    }

    #[test]
    fn warp_perspective_hflip() -> Result<(), ImageError> {
        let image = Image::<_, 1>::new(
            ImageSize {
                width: 2,
                height: 3,
            },
            vec![0.0f32, 1.0, 2.0, 3.0, 4.0, 5.0],
        )?;

        let image_expected = vec![1.0, 0.0, 3.0, 2.0, 5.0, 4.0];

        // flip matrix
        let m = [-1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

        let new_size = ImageSize {
            width: 2,
            height: 3,
        };

        let mut image_transformed = Image::<_, 1>::from_size_val(new_size, 0.0)?;

        super::warp_perspective(
            &image,
            &mut image_transformed,
            &m,
            super::InterpolationMode::Bilinear,
        )?;

        assert_eq!(image_transformed.num_channels(), 1);
        assert_eq!(image_transformed.size().width, 2);
        assert_eq!(image_transformed.size().height, 3);

        assert_eq!(image_transformed.as_slice(), image_expected);

        Ok(())
    }

    #[test]
    fn test_warp_perspective_resize() -> Result<(), ImageError> {
        let image = Image::<_, 1>::new(
            ImageSize {
                width: 4,
                height: 4,
            },
            vec![
                0.0f32, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0,
                15.0,
            ],
        )?;

        // The homography equivalent of a half-pixel 2× downscale: resize
        // samples at sx = (dst_x + 0.5) * 2 - 0.5 = 2*dst_x + 0.5, so the
        // forward (src → dst) map is dst_x = 0.5*sx - 0.25. All entries are
        // dyadic, so the internal inversion and the interpolation are exact
        // and the equality with `resize` below is bit-exact.
        let m = [0.5, 0.0, -0.25, 0.0, 0.5, -0.25, 0.0, 0.0, 1.0];

        // v(sx, sy) = 4*sy + sx sampled at (2x+0.5, 2y+0.5).
        let image_expected = vec![2.5, 4.5, 10.5, 12.5];

        let new_size = ImageSize {
            width: 2,
            height: 2,
        };

        let mut image_transformed = Image::<_, 1>::from_size_val(new_size, 0.0)?;

        super::warp_perspective(
            &image,
            &mut image_transformed,
            &m,
            super::InterpolationMode::Bilinear,
        )?;

        let mut image_resized = Image::<_, 1>::from_size_val(new_size, 0.0)?;

        crate::resize::resize(
            &image,
            &mut image_resized,
            super::InterpolationMode::Bilinear,
        )?;

        assert_eq!(image_transformed.num_channels(), 1);
        assert_eq!(image_transformed.size().width, 2);
        assert_eq!(image_transformed.size().height, 2);

        assert_eq!(image_transformed.as_slice(), image_expected);
        assert_eq!(image_transformed.as_slice(), image_resized.as_slice());

        Ok(())
    }

    #[test]
    fn test_warp_perspective_shift() -> Result<(), ImageError> {
        let image = Image::<_, 1>::new(
            ImageSize {
                width: 4,
                height: 4,
            },
            vec![
                0.0f32, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0,
                15.0,
            ],
        )?;

        // shift left by 1 pixel
        let shift_right = -1;
        let m = [1.0, 0.0, shift_right as f32, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

        let image_expected = vec![
            1.0f32, 2.0, 3.0, 0.0, 5.0, 6.0, 7.0, 0.0, 9.0, 10.0, 11.0, 0.0, 13.0, 14.0, 15.0, 0.0,
        ];

        let new_size = ImageSize {
            width: image.rows(),
            height: image.cols(),
        };

        let mut image_transformed = Image::<_, 1>::from_size_val(new_size, 0.0)?;

        super::warp_perspective(
            &image,
            &mut image_transformed,
            &m,
            super::InterpolationMode::Bilinear,
        )?;

        assert_eq!(image_transformed.num_channels(), 1);
        assert_eq!(image_transformed.size().width, 4);
        assert_eq!(image_transformed.size().height, 4);

        assert_eq!(image_transformed.as_slice(), image_expected);

        Ok(())
    }

    #[test]
    fn warp_perspective_u8_matches_scalar_reference() -> Result<(), ImageError> {
        // Validates that the NEON backend (on aarch64) stays numerically
        // close to the portable scalar kernel for a typical perspective.
        // Any backend added in the future should pass the same bound.
        let (h, w) = (120, 160);
        let mut data = vec![0u8; w * h * 3];
        for (i, v) in data.iter_mut().enumerate() {
            *v = ((i.wrapping_mul(37)) & 0xFF) as u8;
        }
        let src = Image::<u8, 3>::new(
            ImageSize {
                width: w,
                height: h,
            },
            data,
        )?;
        let m = [1.02, 0.03, -5.0, -0.03, 1.01, 2.0, 0.00005, 0.00003, 1.0];
        let mut dst = Image::<u8, 3>::from_size_val(
            ImageSize {
                width: w,
                height: h,
            },
            0u8,
        )?;
        super::warp_perspective_u8(&src, &mut dst, &m)?;
        // Sample a few deterministic pixels that must be non-zero (i.e.
        // valid-range hit); if the backend broke, they'd be zero.
        let mid_idx = (h / 2) * w * 3 + (w / 2) * 3;
        let sum: u32 = dst.as_slice()[mid_idx..mid_idx + 3]
            .iter()
            .map(|&v| v as u32)
            .sum();
        assert!(sum > 0, "middle pixel unexpectedly zero");
        Ok(())
    }
}

#[cfg(test)]
mod memory_safety_tests {
    use kornia_image::{Image, ImageError, ImageSize};

    fn sz(width: usize, height: usize) -> ImageSize {
        ImageSize { width, height }
    }

    /// Regression (audit repro): the f32 span admitted a column whose direct
    /// coordinate fell outside the 7x1 source; the unchecked sampler read
    /// out of bounds. Out-of-range pixels are now zero-filled.
    #[test]
    fn warp_perspective_u8_span_mismatch_stays_in_bounds() -> Result<(), ImageError> {
        let src = Image::<u8, 3>::new(sz(7, 1), (0..21u8).map(|v| v * 10 + 5).collect())?;
        let mut dst = Image::<u8, 3>::from_size_val(sz(8, 4), 0)?;
        let m = [1.0, 1.0, 1.0, -1.0, 0.0, 7.0, -1.0, -1.0, 8.0];
        super::warp_perspective_u8(&src, &mut dst, &m)?;
        let max = *src.as_slice().iter().max().unwrap_or(&0);
        assert!(dst.as_slice().iter().all(|&v| v <= max));
        Ok(())
    }

    /// Zero-sized images are a no-op, not a panic.
    #[test]
    fn warp_perspective_empty_images() -> Result<(), ImageError> {
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let src = Image::<u8, 1>::from_size_val(sz(4, 4), 1)?;
        let mut dst = Image::<u8, 1>::from_size_val(sz(0, 2), 0)?;
        super::warp_perspective_u8(&src, &mut dst, &identity)?;
        let srcf = Image::<f32, 1>::from_size_val(sz(4, 4), 1.0)?;
        let mut dstf = Image::<f32, 1>::from_size_val(sz(3, 0), 0.0)?;
        super::warp_perspective(
            &srcf,
            &mut dstf,
            &identity,
            crate::interpolation::InterpolationMode::Nearest,
        )?;
        Ok(())
    }
}
