//! What the evaluation shares with the project's other commands: limits checked before any
//! work, the synthetic set made on demand, the evaluation size, the weights cache, scene ground
//! truth, medians and the machine a measurement ran on.

use std::path::{Path, PathBuf};

use mhi_data::SynthConfig;
use mhi_geom::Camera;
use mhi_render::PixelTruth;

/// Refuse work whose layers would not fit in memory, before allocating them: an N × D MHI at
/// `width × height` with its plane-sweep volume takes about 24 bytes per layer pixel (alpha,
/// warped colour and validity in f32, plus the costs). The limit is the memory available now
/// (`MemAvailable` of /proc/meminfo; 16 GiB where that cannot be read).
pub fn check_memory(what: &str, width: u32, height: u32, layers: usize) -> anyhow::Result<()> {
    let need = 24.0 * f64::from(width) * f64::from(height) * layers as f64;
    let avail = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse::<f64>().ok())
        })
        .map_or(16.0 * 1024.0 * 1024.0 * 1024.0, |kib| kib * 1024.0);
    if need > 0.8 * avail {
        anyhow::bail!(
            "{what}: {layers} layers of {width}x{height} need about {:.1} GB, but {:.1} GB of memory is available; choose a smaller size or fewer planes",
            need / 1e9,
            avail / 1e9
        );
    }
    Ok(())
}

/// Make sure a synthetic dataset exists at `root` (generating the default one if not).
pub fn ensure_synthetic(root: &Path) -> anyhow::Result<()> {
    let interrupted = root.join(mhi_data::INCOMPLETE_MARKER).exists();
    if root.join("test").is_dir() && !interrupted {
        return Ok(());
    }
    if interrupted {
        eprintln!(
            "{} holds an interrupted synthetic set: generating it again",
            root.display()
        );
    }
    eprintln!(
        "no synthetic data at {}: generating the default set (100 scenes, 256x256)",
        root.display()
    );
    let config = SynthConfig::default();
    let staged = mhi_data::output::StagedDir::begin(root, mhi_data::SYNTH_KIND, interrupted)?;
    let pb = crate::progress::bar((config.scenes * config.frames) as u64, "synth");
    mhi_data::generate(&config, staged.path(), &|| pb.inc(1))?;
    pb.finish_and_clear();
    staged.commit()?;
    Ok(())
}

/// Per reference pixel, the true surface normal and depth of a synthetic scene.
pub fn truth_of(scene: &mhi_data::Scene, cam: &Camera) -> Vec<Option<PixelTruth>> {
    scene
        .ground_truth(cam)
        .into_iter()
        .map(|t| t.map(|(normal, depth)| PixelTruth { normal, depth }))
        .collect()
}

/// The evaluation size of frames of `dims`: `short` pixels on the short side, the long side in
/// proportion rounded to a multiple of 16 (at least 16).
pub fn size_for(dims: (u32, u32), short: u32) -> (u32, u32) {
    let (w, h) = (f64::from(dims.0), f64::from(dims.1));
    let long = |l: f64, s: f64| ((l / s * f64::from(short) / 16.0).round() as u32).max(1) * 16;
    if dims.0 >= dims.1 {
        (long(w, h), short)
    } else {
        (short, long(h, w))
    }
}

/// The cache directory for weights.
pub fn cache_dir(explicit: Option<&Path>) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    if let Some(p) = std::env::var_os("MHI_CACHE") {
        return PathBuf::from(p);
    }
    let home = std::env::var_os("HOME").map_or_else(|| PathBuf::from("."), PathBuf::from);
    home.join(".cache").join("mhi")
}

/// The most orbit frames a GIF takes: a minute at the orbit's 60 ms a frame.
pub const MAX_ORBIT_FRAMES: usize = 1000;

/// Refuse a GIF whose frames (`flag`) would not fit, with what it would cost: every frame is
/// kept (enlarged to at least 256 px wide) until the GIF is encoded.
pub fn check_gif_frames(flag: &str, frames: usize) -> anyhow::Result<()> {
    if frames > MAX_ORBIT_FRAMES {
        anyhow::bail!(
            "{flag} {frames}: the GIF keeps every frame in memory (about {:.1} GB for {frames} frames at 256 px wide) and plays for {:.0} s; at most {MAX_ORBIT_FRAMES} frames ({:.0} s)",
            frames as f64 * 256.0 * 256.0 * 4.0 * 2.0 / 1e9,
            frames as f64 * 0.06,
            MAX_ORBIT_FRAMES as f64 * 0.06
        );
    }
    Ok(())
}

/// The most triplets drawn from one sequence: far more than any sequence supplies distinct ones.
pub const MAX_PER_SEQUENCE: usize = 10_000;

/// Draw the evaluation triplets (see [`mhi_data::TripletIndex::sample`]), refusing absurd counts
/// and warning for every sequence that could not supply distinct triplets enough.
pub fn sample_index(
    ds: &mhi_data::Dataset,
    per_sequence: usize,
    seed: u64,
) -> anyhow::Result<mhi_data::TripletIndex> {
    if per_sequence > MAX_PER_SEQUENCE {
        anyhow::bail!(
            "--per-sequence {per_sequence}: at most {MAX_PER_SEQUENCE} triplets a sequence (a sequence of n frames supplies far fewer distinct ones, and each costs a render of every method)"
        );
    }
    let index = mhi_data::TripletIndex::sample(ds, per_sequence, seed);
    for (name, got) in &index.shortfalls {
        eprintln!(
            "warning: sequence {} supplies only {got} distinct triplets, not the {per_sequence} asked; using {got} (repeats would make the intervals too narrow)",
            mhi_data::sanitize::for_terminal(name)
        );
    }
    Ok(index)
}

/// The CPU's model name (`/proc/cpuinfo`) with its family and model numbers, or the architecture
/// where there is none. The numbers tell CPU generations apart where a virtual machine's name
/// does not (under KVM an Intel Xeon of any generation reads "Intel(R) Xeon(R) Processor").
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| cpu_model_from(&t))
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

/// [`cpu_model`] from the text of `/proc/cpuinfo` (its first processor).
fn cpu_model_from(cpuinfo: &str) -> Option<String> {
    let field = |key: &str| {
        cpuinfo
            .lines()
            .filter_map(|l| l.split_once(':'))
            .find(|(k, _)| k.trim() == key)
            .map(|(_, v)| v.trim().to_string())
    };
    let name = field("model name")?;
    Some(match (field("cpu family"), field("model")) {
        (Some(family), Some(model)) => format!("{name} (family {family}, model {model})"),
        _ => name,
    })
}

/// The current UTC date and time, for reports (from `date`; the epoch seconds if it is missing).
pub fn date() -> String {
    std::process::Command::new("date")
        .args(["-u", "+%Y-%m-%d %H:%M UTC"])
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| {
            let t = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs());
            format!("{t} s since 1970 (UTC)")
        })
}

/// The median of `v` (the upper one of an even count; NaN when empty).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The paths the project's own kernels take on this CPU (each is chosen at run time by the
/// CPU's features, capped by `MHI_SIMD`; docs/SPEED.md lists them).
pub fn kernel_paths() -> String {
    use mhi_geom::simd::{Level, detected, level};
    let l = level();
    format!(
        "SIMD level {} (CPU: {}; MHI_SIMD caps it): renderer band loop {}, convolution tiles {}",
        l.name(),
        detected().name(),
        if mhi_geom::simd::fast_gathers() {
            "AVX2 + FMA, exact renders' compositing AVX-512F gathers (16 pixels)"
        } else if l >= Level::Avx2 {
            "AVX2 + FMA"
        } else {
            "baseline"
        },
        match l {
            Level::Avx512 => "AVX-512F (16 channels, or 16 positions for blocks of 8)",
            Level::Avx2 => "AVX2 + FMA (8 channels)",
            Level::Baseline => "gemm only",
        }
    )
}

/// Run `f` on a folder built beside `out` and swapped into place whole when it succeeds (an
/// earlier output of the same kind is replaced; a folder of the user's is refused).
pub fn staged(
    out: &std::path::Path,
    kind: &str,
    f: impl FnOnce(&std::path::Path) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let s = mhi_data::output::StagedDir::begin(out, kind, true)?;
    f(s.path())?;
    s.commit()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_cpu_model_carries_its_family_and_model_numbers() {
        let kvm = "processor\t: 0\nvendor_id\t: GenuineIntel\ncpu family\t: 6\nmodel\t\t: 207\n\
                   model name\t: Intel(R) Xeon(R) Processor\nstepping\t: 2\n";
        assert_eq!(
            super::cpu_model_from(kvm).as_deref(),
            Some("Intel(R) Xeon(R) Processor (family 6, model 207)")
        );
        // A name without the numbers stays the name; no name is no model.
        assert_eq!(
            super::cpu_model_from("model name\t: Some CPU\n").as_deref(),
            Some("Some CPU")
        );
        assert_eq!(super::cpu_model_from("processor\t: 0\n"), None);
    }
}
