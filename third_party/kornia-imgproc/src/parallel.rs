use rayon::prelude::*;

use kornia_image::Image;

/// Row-group granularity for per-pixel rayon sharding. At 1 row per task,
/// spawn overhead (~2-5 μs on the 8-core Orin pool) rivals per-row work for
/// memory-bound ops like u8→f32 normalize, killing throughput. 16-row chunks
/// put ~68 tasks on an 8-core pool for 1080p (~8 per worker) — enough for
/// work-stealing balance without drowning in task overhead.
const ROWS_PER_TASK: usize = 16;

/// Parallel mutable chunks of `rows_per_task` whole rows of `row_len`
/// elements each.
///
/// For an image buffer (`data.len()` a multiple of `row_len`), an empty
/// image — zero rows or zero-length rows — has an empty `data` and yields no
/// chunks. This is the single place that keeps rayon's `chunk_size != 0`
/// assertion from firing on empty images; callers need no guard of their own
/// for it.
#[inline]
pub(crate) fn par_row_chunks_mut<T: Send>(
    data: &mut [T],
    row_len: usize,
    rows_per_task: usize,
) -> rayon::slice::ChunksMut<'_, T> {
    data.par_chunks_mut(row_len.saturating_mul(rows_per_task).max(1))
}

/// Shared-reference twin of [`par_row_chunks_mut`].
#[inline]
pub(crate) fn par_row_chunks<T: Sync>(
    data: &[T],
    row_len: usize,
    rows_per_task: usize,
) -> rayon::slice::Chunks<'_, T> {
    data.par_chunks(row_len.saturating_mul(rows_per_task).max(1))
}

/// Parallel mutable rows of exactly `row_len` elements; an empty image
/// yields no rows (see [`par_row_chunks_mut`]).
#[inline]
pub(crate) fn par_rows_exact_mut<T: Send>(
    data: &mut [T],
    row_len: usize,
) -> rayon::slice::ChunksExactMut<'_, T> {
    data.par_chunks_exact_mut(row_len.max(1))
}

/// Apply a function to each pixel in the image in parallel.
///
/// # Arguments
///
/// * `src` - The input image.
/// * `dst` - The output image.
/// * `f` - The function to apply to each pixel.
pub fn par_iter_rows<T1, const C1: usize, T2, const C2: usize>(
    src: &Image<T1, C1>,
    dst: &mut Image<T2, C2>,
    f: impl Fn(&[T1], &mut [T2]) + Send + Sync,
) where
    T1: Clone + Send + Sync,
    T2: Clone + Send + Sync,
{
    let src_row_len = C1 * src.cols();
    let dst_row_len = C2 * src.cols();
    par_row_chunks(src.as_slice(), src_row_len, ROWS_PER_TASK)
        .zip(par_row_chunks_mut(
            dst.as_slice_mut(),
            dst_row_len,
            ROWS_PER_TASK,
        ))
        .for_each(|(src_chunk, dst_chunk)| {
            src_chunk
                .chunks_exact(C1)
                .zip(dst_chunk.chunks_exact_mut(C2))
                .for_each(|(src_pixel, dst_pixel)| {
                    f(src_pixel, dst_pixel);
                });
        });
}

/// Apply a function to each pixel in the image in parallel with a value.
pub fn par_iter_rows_val<T1, const C1: usize, T2, const C2: usize>(
    src: &Image<T1, C1>,
    dst: &mut Image<T2, C2>,
    f: impl Fn(&T1, &mut T2) + Send + Sync,
) where
    T1: Clone + Send + Sync,
    T2: Clone + Send + Sync,
{
    let src_row_len = C1 * src.cols();
    let dst_row_len = C2 * src.cols();
    par_row_chunks(src.as_slice(), src_row_len, ROWS_PER_TASK)
        .zip(par_row_chunks_mut(
            dst.as_slice_mut(),
            dst_row_len,
            ROWS_PER_TASK,
        ))
        .for_each(|(src_chunk, dst_chunk)| {
            src_chunk
                .iter()
                .zip(dst_chunk.iter_mut())
                .for_each(|(src_pixel, dst_pixel)| {
                    f(src_pixel, dst_pixel);
                });
        });
}

/// Apply a function to each pixel in the image in parallel with two values.
pub fn par_iter_rows_val_two<T1, const C1: usize, T2, const C2: usize, T3, const C3: usize>(
    src1: &Image<T1, C1>,
    src2: &Image<T2, C2>,
    dst: &mut Image<T3, C3>,
    f: impl Fn(&T1, &T2, &mut T3) + Send + Sync,
) where
    T1: Clone + Send + Sync,
    T2: Clone + Send + Sync,
    T3: Clone + Send + Sync,
{
    let cols = src1.cols();
    let s1_row = C1 * cols;
    let s2_row = C2 * cols;
    let d_row = C3 * cols;
    par_row_chunks(src1.as_slice(), s1_row, ROWS_PER_TASK)
        .zip(par_row_chunks(src2.as_slice(), s2_row, ROWS_PER_TASK))
        .zip(par_row_chunks_mut(dst.as_slice_mut(), d_row, ROWS_PER_TASK))
        .for_each(|((src1_chunk, src2_chunk), dst_chunk)| {
            src1_chunk
                .iter()
                .zip(src2_chunk.iter())
                .zip(dst_chunk.iter_mut())
                .for_each(|((src1_pixel, src2_pixel), dst_pixel)| {
                    f(src1_pixel, src2_pixel, dst_pixel);
                });
        });
}

/// Apply a function to each pixel for grid sampling in parallel.
pub fn par_iter_rows_resample<const C: usize>(
    dst: &mut Image<f32, C>,
    map_x: &[f32],
    map_y: &[f32],
    f: impl Fn(&f32, &f32, &mut [f32]) + Send + Sync,
) {
    let cols = dst.cols();
    par_row_chunks_mut(dst.as_slice_mut(), C * cols, ROWS_PER_TASK)
        .zip(par_row_chunks(map_x, cols, ROWS_PER_TASK))
        .zip(par_row_chunks(map_y, cols, ROWS_PER_TASK))
        .for_each(|((dst_chunk, map_x_chunk), map_y_chunk)| {
            dst_chunk
                .chunks_exact_mut(C)
                .zip(map_x_chunk.iter().zip(map_y_chunk.iter()))
                .for_each(|(dst_pixel, (x, y))| f(x, y, dst_pixel))
        });
}

/// Apply a spatial mapping function to each pixel in parallel without pre-allocating coordinate tensors.
pub fn par_iter_rows_spatial_mapping<const C: usize>(
    dst: &mut Image<f32, C>,
    map_coord: impl Fn(usize, usize) -> (f32, f32) + Send + Sync,
    f: impl Fn(f32, f32, &mut [f32]) + Send + Sync,
) {
    let cols = dst.cols();
    let row_len = C * cols;
    par_row_chunks_mut(dst.as_slice_mut(), row_len, ROWS_PER_TASK)
        .enumerate()
        .for_each(|(chunk_idx, dst_chunk)| {
            let r_base = chunk_idx * ROWS_PER_TASK;
            dst_chunk
                .chunks_exact_mut(row_len)
                .enumerate()
                .for_each(|(dr, row)| {
                    let r = r_base + dr;
                    row.chunks_exact_mut(C)
                        .enumerate()
                        .for_each(|(c, dst_pixel)| {
                            let (x, y) = map_coord(c, r);
                            f(x, y, dst_pixel)
                        });
                });
        });
}
