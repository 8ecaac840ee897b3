//! Which compiled copy of the hot loops runs: the portable x86-64 (or
//! other target) code, a copy of the same source compiled for the
//! x86-64-v3 features (AVX2, FMA, BMI1/2, LZCNT: Haswell, every Zen and
//! later), or, on CPUs with AVX-512 as well (x86-64-v4: Skylake-SP, Ice
//! Lake, Zen 4 and later), the v3 copies with the ground path kernel
//! compiled for v4; chosen once per process from the CPU.
//!
//! The copies are the row loop (with the ground path kernel, the Sobol
//! and camera lanes) and, through `code_path_copies!`, the layered BRDF's
//! out-of-line evaluation and sampling that the loop calls. Only the
//! kernel has a v4 copy: its sixteen lanes fit two AVX-512 registers per
//! quantity instead of four AVX2 ones, with 32 vector registers and mask
//! registers for its selects (peer render −10 % of the time on a Zen 4
//! host, alternately); the row loop's scalar stone path and the sampler
//! compiled for v4 were no faster there (issue 6, round 13).
//!
//! The copies do the same IEEE operations in the same order (Rust never
//! fuses a multiply and an add unless asked), so they write the same bytes;
//! `LAPIDARY_SIMD=off` selects the portable code and `LAPIDARY_SIMD=v3` at
//! most the v3 copies, to check exactly that or to rule the vector code out
//! when chasing a problem.

use std::sync::OnceLock;

/// The compiled copy of the hot loops in use, in increasing order of the
/// CPU features it needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum CodePath {
    /// The baseline target's instructions (SSE2 on x86-64).
    Portable,
    /// x86-64-v3: three-operand VEX instructions for the path tracer's
    /// loop and AVX2 lanes for the per-batch sample and camera work.
    X86_64V3,
    /// x86-64-v4: the v3 copies, with the ground path kernel's lanes in
    /// AVX-512 registers.
    X86_64V4,
}

impl CodePath {
    /// How `lapidary render` names it in its summary line.
    pub fn name(self) -> &'static str {
        match self {
            CodePath::Portable => "portable",
            CodePath::X86_64V3 => "x86-64-v3",
            CodePath::X86_64V4 => "x86-64-v4",
        }
    }

    /// Whether the x86-64-v3 copies run (a v4 CPU has every v3 feature).
    #[inline(always)]
    pub fn has_v3(self) -> bool {
        self >= CodePath::X86_64V3
    }
}

/// The copy this process runs (decided at the first call): the best the
/// CPU allows, capped by `LAPIDARY_SIMD` (`off`: portable, `v3`: at most
/// x86-64-v3; any other value caps nothing).
pub fn code_path() -> CodePath {
    static CHOSEN: OnceLock<CodePath> = OnceLock::new();
    *CHOSEN.get_or_init(|| {
        let cap = match std::env::var("LAPIDARY_SIMD").as_deref() {
            Ok("off") => CodePath::Portable,
            Ok("v3") => CodePath::X86_64V3,
            _ => CodePath::X86_64V4,
        };
        cpu_code_path().min(cap)
    })
}

/// The best copy this CPU has every feature of.
fn cpu_code_path() -> CodePath {
    if !cpu_has_x86_64_v3() {
        CodePath::Portable
    } else if cpu_has_x86_64_v4() {
        CodePath::X86_64V4
    } else {
        CodePath::X86_64V3
    }
}

/// Whether the CPU has the AVX-512 features of x86-64-v4 that the kernel's
/// copy is compiled for (on top of v3's).
fn cpu_has_x86_64_v4() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        has!("avx512f")
            && has!("avx512dq")
            && has!("avx512vl")
            && has!("avx512bw")
            && has!("avx512cd")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
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
/// [`code_path`]; also in the v4 path). For functions that stay out of line (too large to
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
            if $crate::render::code_path::code_path().has_v3() {
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
