//! Which vector instructions the project's own kernels may use: what the CPU has, capped by
//! the `MHI_SIMD` environment variable (`baseline`, `avx2` or `avx512`), read once. The cap
//! lets one machine run every path its CPU has — the tests under each, a benchmark on each —
//! and every kernel that picks a path at run time asks here.

use std::sync::OnceLock;

/// A level of vector instructions, from none to AVX-512.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Portable code only (what the compiler makes of it for the target's baseline).
    Baseline,
    /// AVX2 with FMA.
    Avx2,
    /// AVX-512F (with AVX2 and FMA).
    Avx512,
}

impl Level {
    /// The name `MHI_SIMD` takes.
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }
}

/// What the CPU has.
pub fn detected() -> Level {
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma");
        if avx2 && std::arch::is_x86_feature_detected!("avx512f") {
            return Level::Avx512;
        }
        if avx2 {
            return Level::Avx2;
        }
    }
    Level::Baseline
}

/// The level the kernels use: [`detected`], capped by `MHI_SIMD` when it names a lower one
/// (a higher one than the CPU has is capped to the CPU; an unknown name is ignored with a
/// message on stderr).
pub fn level() -> Level {
    static LEVEL: OnceLock<Level> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        let cpu = detected();
        match std::env::var("MHI_SIMD").as_deref() {
            Err(_) | Ok("") => cpu,
            Ok("baseline") => Level::Baseline,
            Ok("avx2") => cpu.min(Level::Avx2),
            Ok("avx512") => cpu,
            Ok(other) => {
                eprintln!(
                    "note: MHI_SIMD={other:?} is not baseline, avx2 or avx512; using what the CPU has ({})",
                    cpu.name()
                );
                cpu
            }
        }
    })
}
