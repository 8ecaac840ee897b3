//! A BRDF's importance sample and the parts every form of the layered
//! BRDF (`stack`'s general recursion, `coat`'s closed form) samples with:
//! the diffuse base's direction, the mixture with the compensation lobe's
//! cosine sampling, and the test that a sample carries usable energy.

use crate::brdf::layer::Interface;
use crate::brdf::microfacet::refract;
use crate::brdf::{fresnel, Rgb};
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::DVec3;

/// One importance sample of the incident direction.
#[derive(Clone, Copy, Debug)]
pub struct BrdfSample {
    /// Sampled incident (light) direction, z > 0.
    pub wi: DVec3,
    /// f(wi, wo).
    pub value: Rgb,
    /// Density of wi with respect to solid angle.
    pub pdf: f64,
}

impl BrdfSample {
    /// The Monte Carlo weight f·cosθᵢ/pdf.
    pub fn weight(&self) -> Rgb {
        self.value * (self.wi.z / self.pdf)
    }
}

/// The layer branch's sample for a diffuse base under the last interface,
/// of relative index `eta`, below the interfaces `above` it: a
/// cosine-distributed direction above the whole stack (density cosθᵢ/π
/// there), refracted down through `above` to just over the last
/// interface; None where it would not get there or not enter (η < 1
/// beyond the critical angle). Under a single interface (`above` empty)
/// it is the cosine itself. The layer's term f·cosθᵢ = T₁₂·a·t·ρ/(πη²)
/// ·cosθᵢ follows this cosine up to the Fresnel and absorption factors.
/// (A cosine drawn inside and refracted out has the same shape above,
/// cosθᵢ/(πη²) by Snell's Jacobian, but only the part inside the critical
/// cone, sinθ′ < 1/η, gets out: 1 − 1/η² of its samples, 56 % at
/// η = 1.5, would be lost to total internal reflection.)
#[inline(always)]
pub(crate) fn diffuse_base_sample(
    u1: f64,
    u2: f64,
    above: &[Interface],
    eta: f64,
) -> Option<DVec3> {
    let mut wi = cosine_hemisphere(u1, u2);
    for upper in above {
        wi = -refract(wi, DVec3::Z, upper.eta)?;
    }
    enters(wi, eta).then_some(wi)
}

/// Whether `w` (w.z > 0) is refracted into a layer of relative index `eta`
/// rather than totally reflected: always for η ≥ 1 (`Snell::at` agrees:
/// sin²θₜ = sin²θᵢ/η² < 1 for cosθᵢ > 0).
#[inline(always)]
fn enters(w: DVec3, eta: f64) -> bool {
    eta >= 1.0 || fresnel::Snell::at(w.z, eta).cos_t.is_some()
}

/// The density of sampling wi given the stack's own density `stack_pdf`:
/// the mixture with the compensation lobe's cosine sampling, chosen with
/// probability `p_comp`.
#[inline(always)]
pub(crate) fn mixture_pdf(p_comp: f64, stack_pdf: f64, wi: DVec3) -> f64 {
    let mut pdf = (1.0 - p_comp) * stack_pdf;
    if p_comp > 0.0 {
        pdf += p_comp * cosine_hemisphere_pdf(wi);
    }
    pdf
}

/// Whether every channel of `value` is finite; `&` rather than `&&`: no
/// branch per channel.
#[inline(always)]
pub(crate) fn all_finite(value: Rgb) -> bool {
    value.x.is_finite() & value.y.is_finite() & value.z.is_finite()
}

/// The sample (wi, f, pdf) unless it carries no usable energy: the density
/// must be positive and finite and the value finite.
#[inline]
pub(crate) fn accept(wi: DVec3, value: Rgb, pdf: f64) -> Option<BrdfSample> {
    if pdf > 0.0 && pdf < f64::INFINITY && all_finite(value) {
        Some(BrdfSample { wi, value, pdf })
    } else {
        None
    }
}
