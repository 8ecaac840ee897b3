//! Which compiled copy of the pixel loop runs: the portable code of the
//! build target, or a copy of the same source compiled for the x86-64-v3
//! features (AVX2, FMA, BMI1/2, LZCNT: Haswell, every Zen and later).
//!
//! The film (`crate::render::film`) picks the copy once, at the entry of
//! each span of a row; nothing below it (integrator, BRDF, textures, geometry) knows
//! about CPU features. The copies do the same IEEE operations in the same
//! order (Rust never fuses a multiply and an add unless asked), so they
//! write the same bytes; [`FilmSettings::code_path`](crate::render::film::FilmSettings)
//! may ask for the portable copy to check exactly that.

use std::sync::OnceLock;

/// A compiled copy of the pixel loop, in increasing order of the CPU
/// features it needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum CodePath {
    /// The baseline target's instructions (SSE2 on x86-64).
    Portable,
    /// x86-64-v3: three-operand VEX instructions and AVX2 lanes.
    X86_64V3,
}

impl CodePath {
    /// The best copy this CPU has every feature of (detected once).
    pub fn best_available() -> CodePath {
        static BEST: OnceLock<CodePath> = OnceLock::new();
        *BEST.get_or_init(|| {
            if cpu_has_x86_64_v3() {
                CodePath::X86_64V3
            } else {
                CodePath::Portable
            }
        })
    }

    /// How `lapidary render` names it in its summary line.
    pub fn name(self) -> &'static str {
        match self {
            CodePath::Portable => "portable",
            CodePath::X86_64V3 => "x86-64-v3",
        }
    }
}

/// Whether the CPU has every x86-64-v3 feature the copy is compiled for.
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

/// Asks the CPU to start loading the cache line of `value` without waiting
/// for it: a hint for a read the caller will make after other work (a
/// texel of a map too large for the caches). Nothing observable changes;
/// on targets without a stable prefetch instruction it does nothing.
#[inline(always)]
pub(crate) fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `_mm_prefetch` is in SSE, part of every x86-64 CPU; a
    // prefetch never faults, and `value` is a valid reference anyway.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((value as *const T).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
