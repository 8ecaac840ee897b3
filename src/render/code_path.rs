//! Which compiled copy of the hot loops runs: the portable x86-64 (or
//! other target) code, or a copy of the same source compiled for the
//! x86-64-v3 features (AVX2, FMA, BMI1/2, LZCNT: Haswell, every Zen and
//! later), chosen once per process from the CPU.
//!
//! The copies do the same IEEE operations in the same order (Rust never
//! fuses a multiply and an add unless asked), so they write the same bytes;
//! `LAPIDARY_SIMD=off` selects the portable code, to check exactly that or
//! to rule the vector code out when chasing a problem.

use std::sync::OnceLock;

/// The compiled copy of the hot loops in use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CodePath {
    /// The baseline target's instructions (SSE2 on x86-64).
    Portable,
    /// x86-64-v3: three-operand VEX instructions for the path tracer's
    /// loop and AVX2 lanes for the per-batch sample and camera work.
    X86_64V3,
}

impl CodePath {
    /// How `lapidary render` names it in its summary line.
    pub fn name(self) -> &'static str {
        match self {
            CodePath::Portable => "portable",
            CodePath::X86_64V3 => "x86-64-v3",
        }
    }
}

/// The copy this process runs (decided at the first call).
pub fn code_path() -> CodePath {
    static CHOSEN: OnceLock<CodePath> = OnceLock::new();
    *CHOSEN.get_or_init(|| {
        let forced_off = std::env::var("LAPIDARY_SIMD").is_ok_and(|v| v == "off");
        if !forced_off && cpu_has_x86_64_v3() {
            CodePath::X86_64V3
        } else {
            CodePath::Portable
        }
    })
}

/// Whether the CPU has every x86-64-v3 feature the vector copies are
/// compiled for.
fn cpu_has_x86_64_v3() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        has!("avx2") && has!("fma") && has!("bmi1") && has!("bmi2") && has!("lzcnt")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
