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

/// Whether kernels that gather (load sixteen scattered floats with one AVX-512 instruction)
/// should: the level is AVX-512 and either `MHI_SIMD=avx512` asks for it outright, or the CPU
/// is an Intel one whose gathers run at full speed. Measured on an Intel Xeon (Emerald
/// Rapids), the renderer's gathering loop took 0.6 of the AVX2 loop's time; AMD's gathers have
/// not been measured here, and on Intel CPUs that mitigate Gather Data Sampling ("Downfall")
/// in microcode, gathers take several times longer, so both keep the AVX2 loop unless asked.
pub fn fast_gathers() -> bool {
    static FAST: OnceLock<bool> = OnceLock::new();
    *FAST.get_or_init(|| {
        if level() < Level::Avx512 {
            return false;
        }
        let asked = std::env::var("MHI_SIMD").as_deref() == Ok("avx512");
        let gds =
            std::fs::read_to_string("/sys/devices/system/cpu/vulnerabilities/gather_data_sampling")
                .ok();
        asked || gathers_pay(intel(), gds.as_deref())
    })
}

/// Whether an AVX-512 CPU's gathers pay: an Intel CPU (`intel`) whose Gather Data Sampling
/// status (the kernel's `vulnerabilities/gather_data_sampling`, when it reports one) is not a
/// mitigation.
fn gathers_pay(intel: bool, gds_status: Option<&str>) -> bool {
    intel && !gds_status.is_some_and(|s| s.trim_start().starts_with("Mitigation"))
}

/// Whether the CPU says it is an Intel one (`cpuid` leaf 0: "GenuineIntel").
fn intel() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let r = std::arch::x86_64::__cpuid(0);
        let name: Vec<u8> = [r.ebx, r.edx, r.ecx]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        name == b"GenuineIntel"
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// The instructions a build may assume beyond x86-64's own, each with whether this build does
/// (its target features, e.g. AVX2 and FMA from the workspace's `.cargo/config.toml`).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const ASSUMABLE: [(&str, bool); 4] = [
    ("avx", cfg!(target_feature = "avx")),
    ("fma", cfg!(target_feature = "fma")),
    ("avx2", cfg!(target_feature = "avx2")),
    ("avx512f", cfg!(target_feature = "avx512f")),
];

/// Of `assumed` (names from [`ASSUMABLE`]), those a CPU lacks, from its `cpuid` leaf 1 ECX and
/// leaf 7 (sub-leaf 0) EBX. AVX and all that builds on it also need the OS to save the wide
/// registers (OSXSAVE).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn lacking<'a>(assumed: &[&'a str], leaf1_ecx: u32, leaf7_ebx: u32) -> Vec<&'a str> {
    let avx = leaf1_ecx & (1 << 27) != 0 && leaf1_ecx & (1 << 28) != 0;
    let has = |name: &str| match name {
        "avx" => avx,
        "fma" => avx && leaf1_ecx & (1 << 12) != 0,
        "avx2" => avx && leaf7_ebx & (1 << 5) != 0,
        "avx512f" => avx && leaf7_ebx & (1 << 16) != 0,
        _ => false,
    };
    assumed.iter().copied().filter(|n| !has(n)).collect()
}

/// Whether the CPU has the instructions this build was compiled to assume everywhere:
/// `Err` names the missing ones and how to build without them.
///
/// [`detected`] cannot tell: `is_x86_feature_detected!` answers `true` at compile time for a
/// feature the build assumes, so this asks the CPU itself (`cpuid`). A program built this way
/// should call it first, before code that may use those instructions runs.
pub fn check_build_baseline() -> Result<(), String> {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__cpuid, __cpuid_count};
        // `cpuid` exists on every x86-64 CPU; leaf 7 is read only when leaf 0 lists it.
        let leaf7 = if __cpuid(0).eax >= 7 {
            __cpuid_count(7, 0).ebx
        } else {
            0
        };
        let assumed: Vec<&str> = ASSUMABLE
            .iter()
            .filter(|(_, built)| *built)
            .map(|(name, _)| *name)
            .collect();
        let missing = lacking(&assumed, __cpuid(1).ecx, leaf7);
        if !missing.is_empty() {
            return Err(format!(
                "this build assumes CPU instructions this CPU lacks ({}); rebuild for any x86-64 \
                 CPU with RUSTFLAGS=\"\" (the workspace's .cargo/config.toml adds AVX2 and FMA)",
                missing.join(", ")
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_cpu_runs_this_build() {
        // The tests run on this CPU, so it has what the build assumes.
        assert_eq!(check_build_baseline(), Ok(()));
    }

    #[test]
    fn gathers_pay_on_intel_without_a_gather_mitigation() {
        assert!(gathers_pay(true, None));
        assert!(gathers_pay(true, Some("Not affected\n")));
        assert!(gathers_pay(true, Some("Vulnerable")));
        assert!(!gathers_pay(true, Some("Mitigation: Microcode\n")));
        assert!(!gathers_pay(false, None));
        assert!(!gathers_pay(false, Some("Not affected")));
    }

    #[test]
    fn a_cpu_without_avx2_or_fma_is_named() {
        let all = ["avx", "fma", "avx2", "avx512f"];
        let osxsave_avx = (1 << 27) | (1 << 28);
        // A Sandy Bridge: AVX, no FMA, no AVX2.
        assert_eq!(lacking(&all, osxsave_avx, 0), ["fma", "avx2", "avx512f"]);
        // A Haswell: AVX, FMA and AVX2, no AVX-512.
        assert_eq!(lacking(&all, osxsave_avx | (1 << 12), 1 << 5), ["avx512f"]);
        // AVX bits without the OS saving the registers count as nothing.
        assert_eq!(lacking(&all[..3], 1 << 28 | 1 << 12, 1 << 5), all[..3]);
        // A build that assumes nothing runs anywhere.
        assert!(lacking(&[], 0, 0).is_empty());
    }
}
