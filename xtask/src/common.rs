//! Helpers shared by several commands: option parsers and checks, the synthetic set on demand,
//! the evaluation size, the weights cache, the tensor backend, scene ground truth and image
//! files. No command module imports another; what two commands share lives here.

pub use mhi_eval::images::{error_map, save_png};
pub use mhi_eval::run::options::{Backend, PlaneArgs, device, parse_normals, parse_size};
pub use mhi_eval::support::{
    cache_dir, check_gif_frames, check_memory, ensure_synthetic, sample_index,
};

/// The most synthetic frames one `synth` makes (a million: about 50 GB of PNGs at 256 × 256).
pub const MAX_SYNTH_FRAMES: usize = 1_000_000;

/// Refuse a synthetic set too large to make, with what it would cost.
pub fn check_synth_count(scenes: usize, frames: usize) -> anyhow::Result<()> {
    let total = scenes.saturating_mul(frames);
    if total > MAX_SYNTH_FRAMES {
        anyhow::bail!(
            "--scenes {scenes} x --frames {frames} = {total} frames: at most {MAX_SYNTH_FRAMES} (about {:.0} hours on 2 cores at 25 frames/s and {:.0} GB of PNGs at 256 x 256)",
            total as f64 / 25.0 / 3600.0,
            total as f64 * 60e3 / 1e9
        );
    }
    Ok(())
}
