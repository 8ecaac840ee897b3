//! Which compiled copy of the hot loops runs: the portable x86-64 (or
//! other target) code, or a copy of the same source compiled for the
//! x86-64-v3 features (AVX2, FMA, BMI1/2, LZCNT: Haswell, every Zen and
//! later), chosen once per process from the CPU.
//!
//! The copies are the row loop (with the ground path kernel, the Sobol
//! and camera lanes) and, through `code_path_copies!`, the layered BRDF's
//! out-of-line evaluation and sampling that the loop calls.
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

/// Defines a method `$name` that runs one of two out-of-line copies of the
/// `#[inline(always)]` method `$body`: `$portable`, compiled for the
/// baseline target, or `$v3`, compiled for x86-64-v3 (chosen by
/// [`code_path`]). For functions that stay out of line (too large to
/// inline into every caller) but sit in the path tracer's loop, whose own
/// x86-64-v3 copy would otherwise call their baseline code: the VEX
/// encoding drops register copies there too (issue 6, round 12).
macro_rules! code_path_copies {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident(&$this:ident $(, $arg:ident: $arg_ty:ty)*) -> $ret:ty;
        body $body:ident, portable $portable:ident, v3 $v3:ident
    ) => {
        $(#[$meta])*
        #[inline(always)]
        $vis fn $name(&$this $(, $arg: $arg_ty)*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            if $crate::render::code_path::code_path()
                == $crate::render::code_path::CodePath::X86_64V3
            {
                // SAFETY: the copy needs only the features that
                // `code_path` found on this CPU.
                return unsafe { $this.$v3($($arg),*) };
            }
            $this.$portable($($arg),*)
        }

        #[inline(never)]
        fn $portable(&$this $(, $arg: $arg_ty)*) -> $ret {
            $this.$body($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt")]
        #[inline(never)]
        fn $v3(&$this $(, $arg: $arg_ty)*) -> $ret {
            $this.$body($($arg),*)
        }
    };
}
pub(crate) use code_path_copies;
