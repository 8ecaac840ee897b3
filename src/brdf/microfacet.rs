//! Micro-facet distributions and shadowing (section 2.1, appendix `blinnD`,
//! `geom`): the Torrance-Sparrow lobe used for every interface and for
//! conductor bases.
//!
//! Roughness is the artist's `roughness_deg`, the average micro-facet slope
//! m. For the seed's Blinn distribution the exponent is β = −ln 2 / ln cos m
//! (appendix, "Convert degrees"), i.e. D falls to half its peak at θh = m.
//! Beckmann and GGX take α = tan m, the RMS slope, and use Smith shadowing.

use crate::sampling::Rng;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The smallest roughness we evaluate, in degrees: the notes' "0.01° for very
/// smooth, almost perfect surfaces" (section 4.2.1). Zero would be a Dirac lobe.
pub(crate) const MIN_ROUGHNESS_DEG: f64 = 0.01;

/// Which micro-facet normal distribution (and matching shadowing) to use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum MicrofacetModel {
    /// Blinn's cosine power with the V-cavity shadowing of Torrance-Sparrow
    /// (the seed's model, appendix `blinnD` and `geom`).
    #[default]
    Blinn,
    /// Beckmann with Smith shadowing (Walter et al. 2007 rational Λ).
    Beckmann,
    /// GGX / Trowbridge-Reitz with exact Smith shadowing.
    Ggx,
}

/// One micro-facet lobe: a distribution with its roughness precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    /// The distribution family.
    pub model: MicrofacetModel,
    /// Average slope m in degrees, clamped to at least `MIN_ROUGHNESS_DEG`.
    pub roughness_deg: f64,
    /// Blinn exponent β = −ln 2 / ln cos m (only used by `Blinn`).
    pub blinn_exponent: f64,
    /// α = tan m (only used by `Beckmann` and `Ggx`).
    pub alpha: f64,
    /// 1/(β + 2), the power of the Blinn lobe's sampling cosθ = u^(1/(β+2)),
    /// kept so that sampling needs no division.
    blinn_sampling_power: f64,
}

impl Microfacet {
    /// A lobe of the given family with average micro-facet slope `roughness_deg`.
    pub fn new(model: MicrofacetModel, roughness_deg: f64) -> Self {
        let m_deg = roughness_deg.clamp(MIN_ROUGHNESS_DEG, 89.0);
        let m = m_deg.to_radians();
        // ln cos m ≈ −m²/2 for small m; use ln_1p for precision near 0.
        let ln_cos = (-(m.sin().powi(2)) / (1.0 + m.cos())).ln_1p();
        let blinn_exponent = -std::f64::consts::LN_2 / ln_cos;
        Microfacet {
            model,
            roughness_deg: m_deg,
            blinn_exponent,
            alpha: m.tan(),
            blinn_sampling_power: 1.0 / (blinn_exponent + 2.0),
        }
    }

    /// Normal distribution D(h), normalised so that ∫ D(h) cosθh dω = 1.
    #[inline]
    pub fn d(&self, h: DVec3) -> f64 {
        let cos_h = h.z;
        if cos_h <= 0.0 {
            return 0.0;
        }
        match self.model {
            // appendix blinnD: (β + 2)/(2π) · cos^β θh
            MicrofacetModel::Blinn => {
                let beta = self.blinn_exponent;
                // cos^β = exp(β ln cosθh) with ln cosθh ≤ cosθh − 1: below
                // β (cosθh − 1) < −800 the exponent is under −745, where exp
                // is exactly 0 in f64, so skip the ln_1p and exp (most of
                // the hemisphere for a smooth lobe: β ≈ 4.6·10⁷ at 0.01°).
                if beta * (cos_h - 1.0) < -800.0 {
                    return 0.0;
                }
                (beta + 2.0) * (0.5 / PI) * pow_cos(cos_h, beta)
            }
            MicrofacetModel::Beckmann => {
                let c2 = cos_h * cos_h;
                let tan2 = (1.0 - c2).max(0.0) / c2;
                let a2 = self.alpha * self.alpha;
                (-tan2 / a2).exp() / (PI * a2 * c2 * c2)
            }
            MicrofacetModel::Ggx => {
                let c2 = cos_h * cos_h;
                let tan2 = (1.0 - c2).max(0.0) / c2;
                let a2 = self.alpha * self.alpha;
                let denom = a2 + tan2;
                a2 / (PI * c2 * c2 * denom * denom)
            }
        }
    }

    /// Shadowing-masking G(i, o, h) for directions on the same side as h.
    ///
    /// Blinn uses the V-cavity term of the appendix `geom`:
    /// min(1, 2(n·h)(n·o)/(o·h), 2(n·h)(n·i)/(o·h)); the others Smith's
    /// separable G1(i)·G1(o). Absolute cosines let the same code serve
    /// transmission through an interface in the random-walk reference.
    pub fn g(&self, wi: DVec3, wo: DVec3, h: DVec3) -> f64 {
        if self.model == MicrofacetModel::Blinn {
            return v_cavity_g(wi, wo, h);
        }
        let (ih, oh) = (wi.dot(h), wo.dot(h));
        if ih * wi.z <= 0.0 || oh * wo.z <= 0.0 || h.z <= 0.0 {
            return 0.0;
        }
        self.smith_g1(wi) * self.smith_g1(wo)
    }

    /// Smith's monodirectional shadowing 1/(1 + Λ(w)).
    fn smith_g1(&self, w: DVec3) -> f64 {
        self.smith_g1_of_cosine(w.z)
    }

    /// [`Microfacet::smith_g1`] of a direction with cosine `cos_theta` to
    /// the normal (Λ depends on nothing else).
    pub(crate) fn smith_g1_of_cosine(&self, cos_theta: f64) -> f64 {
        let c2 = cos_theta * cos_theta;
        if c2 >= 1.0 {
            return 1.0;
        }
        let tan = ((1.0 - c2) / c2).sqrt();
        let lambda = match self.model {
            MicrofacetModel::Ggx => 0.5 * (-1.0 + (1.0 + (self.alpha * tan).powi(2)).sqrt()),
            _ => {
                // Beckmann Λ, Walter et al. 2007 eq. 27 rational approximation.
                // Its numerator dips below 0 for 1.5497 < a < 1.6 (roots
                // of 1 − 1.259a + 0.396a²), where G1 would exceed 1 by up to
                // 6·10⁻⁵ and a coat's exit term 1 − F·G under total internal
                // reflection turn negative: Λ is a mean slope excess, ≥ 0.
                let a = 1.0 / (self.alpha * tan);
                if a >= 1.6 {
                    0.0
                } else {
                    ((1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a)).max(0.0)
                }
            }
        };
        1.0 / (1.0 + lambda)
    }

    /// Sample a micro-facet normal with density D(h)·cosθh (upper hemisphere).
    pub(crate) fn sample_normal(&self, u1: f64, u2: f64) -> DVec3 {
        let cos_theta = match self.model {
            // ∫ D cos dω for Blinn gives cosθ = u^(1/(β+2)).
            // As exp(ln u/(β+2)): u > 0 here (ln 0 = −∞ gives exp = 0,
            // as 0^p does), and a logarithm and an exponential cost about
            // half of the general `powf` (a sixth of a material's compile).
            MicrofacetModel::Blinn => (u1.ln() * self.blinn_sampling_power).exp(),
            MicrofacetModel::Beckmann => {
                let tan2 = -self.alpha * self.alpha * (1.0 - u1).ln();
                1.0 / (1.0 + tan2).sqrt()
            }
            MicrofacetModel::Ggx => {
                let tan2 = self.alpha * self.alpha * u1 / (1.0 - u1).max(1e-300);
                1.0 / (1.0 + tan2).sqrt()
            }
        };
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let (sin_phi, cos_phi) = crate::sampling::sin_cos_turns(u2);
        DVec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
    }

    /// A micro-facet normal drawn from the distribution of normals visible
    /// from `w` (z > 0), D_w(h) = G1(w, h) max(0, w·h) D(h) / cos θw
    /// (Heitz & d'Eon 2014), from `u` in [0, 1)²: GGX's by Heitz 2018;
    /// Blinn's V-cavities by drawing h from D(h) cos θh and keeping it or
    /// its mirror about the normal in proportion to their projected areas
    /// (Heitz & d'Eon 2014, section 5); Beckmann's by rejection from GGX's
    /// of the same α, whose tails hold it: D_Beckmann / D_GGX =
    /// (1 + x)² e^(−x) ≤ 4/e with x = tan²θh / α² (1.5–2.6 draws on
    /// average). Numbers past `u` (the mirror's choice, a refused draw's
    /// next) come from a generator keyed by `u`, so a stratified `u` stays
    /// stratified. Scattering about the normal then weighs G / G1(w, h)
    /// ([`Microfacet::visible_g1`]), at most 1.
    pub(crate) fn sample_visible_normal(&self, w: DVec3, u: [f64; 2]) -> DVec3 {
        let mut more = || Rng::keyed_by(0x9e37_79b9_7f4a_7c15, &u);
        match self.model {
            MicrofacetModel::Ggx => ggx_visible_normal(self.alpha, w, u),
            MicrofacetModel::Blinn => {
                let h = self.sample_normal(u[0], u[1]);
                let mirror = DVec3::new(-h.x, -h.y, h.z);
                let (seen, mirror_seen) = (w.dot(h).max(0.0), w.dot(mirror).max(0.0));
                if more().next_f64() * (seen + mirror_seen) < mirror_seen {
                    mirror
                } else {
                    h
                }
            }
            MicrofacetModel::Beckmann => {
                let mut numbers = u;
                let mut rng: Option<Rng> = None;
                let mut h = DVec3::Z;
                for _ in 0..MAX_BECKMANN_DRAWS {
                    h = ggx_visible_normal(self.alpha, w, numbers);
                    let generator = rng.get_or_insert_with(&mut more);
                    let c2 = h.z * h.z;
                    let x = (1.0 - c2).max(0.0) / (c2 * self.alpha * self.alpha);
                    // Kept with probability (D_Beckmann / D_GGX) / (4/e).
                    if 4.0 * generator.next_f64() < (1.0 + x) * (1.0 + x) * (1.0 - x).exp() {
                        break;
                    }
                    numbers = [generator.next_f64(), generator.next_f64()];
                }
                h
            }
        }
    }

    /// The masking G1(w, h) of direction `w` (z > 0) over micro-normal
    /// `h` that [`Microfacet::sample_visible_normal`]'s density holds: the
    /// V-cavity's min(1, 2 cosθh cosθw / (w·h)) for Blinn, Smith's
    /// 1/(1 + Λ(w)) for the others; 0 where h faces away from w.
    pub(crate) fn visible_g1(&self, w: DVec3, h: DVec3) -> f64 {
        let wh = w.dot(h);
        if wh <= 0.0 || h.z <= 0.0 {
            return 0.0;
        }
        match self.model {
            MicrofacetModel::Blinn => (2.0 * h.z * w.z / wh).min(1.0),
            _ => self.smith_g1(w),
        }
    }

    /// Density of [`Microfacet::sample_normal`] with respect to solid angle.
    pub(crate) fn normal_pdf(&self, h: DVec3) -> f64 {
        self.d(h) * h.z.max(0.0)
    }

    /// Torrance-Sparrow reflection D·G·F/(4 cosθi cosθo) without F (the
    /// caller multiplies the Fresnel factor of its interface).
    pub(crate) fn reflection_without_fresnel(&self, wi: DVec3, wo: DVec3) -> (f64, DVec3) {
        let h = (wi + wo).normalize_or_zero();
        if h == DVec3::ZERO || wi.z <= 0.0 || wo.z <= 0.0 {
            return (0.0, DVec3::Z);
        }
        let value = value_without_fresnel(self.d(h), || self.g(wi, wo, h), wi, wo);
        (value, h)
    }

    /// [`Microfacet::reflection_without_fresnel`] and
    /// [`Microfacet::reflection_pdf`] at once, D(h) evaluated once:
    /// (value, pdf, h), each equal to the separate call's.
    #[inline]
    pub(crate) fn reflection_value_and_pdf(&self, wi: DVec3, wo: DVec3) -> (f64, f64, DVec3) {
        let h = half_vector(wi, wo);
        if h == DVec3::ZERO || wi.z <= 0.0 || wo.z <= 0.0 {
            return (0.0, 0.0, DVec3::Z);
        }
        let d = self.d(h);
        let value = value_without_fresnel(d, || self.g(wi, wo, h), wi, wo);
        let oh = wo.dot(h);
        // D = 0: the density 0·cosθh/(4 o·h) is +0 (o·h > 0) without the
        // arithmetic.
        let pdf = if oh <= 0.0 || d == 0.0 {
            0.0
        } else {
            d * h.z.max(0.0) / (4.0 * oh)
        };
        (value, pdf, h)
    }

    /// Sample the incident direction of the reflection lobe for outgoing `wo`:
    /// a normal from `sample_normal`, mirrored. None below the horizon.
    pub fn sample_reflection(&self, wo: DVec3, u1: f64, u2: f64) -> Option<DVec3> {
        let h = self.sample_normal(u1, u2);
        let oh = wo.dot(h);
        if oh <= 0.0 {
            return None;
        }
        let wi = reflect(wo, h);
        (wi.z > 0.0).then_some(wi)
    }

    /// Density of [`Microfacet::sample_reflection`]: D cosθh / (4 |o·h|).
    pub fn reflection_pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let h = (wi + wo).normalize_or_zero();
        let oh = wo.dot(h);
        if oh <= 0.0 {
            return 0.0;
        }
        self.normal_pdf(h) / (4.0 * oh)
    }
}

/// D·G/(4 cosθᵢ cosθₒ) given D = `d` and G from `g`. Where D = 0 (off the
/// peak of a smooth lobe) the value is 0·G/(4 cosθᵢ cosθₒ) = 0 for any G in
/// [0, 1], so G is not evaluated; the same bits as the full product as long
/// as the denominator has not underflowed to 0 (then 0/0 is NaN in both).
#[inline]
fn value_without_fresnel(d: f64, g: impl FnOnce() -> f64, wi: DVec3, wo: DVec3) -> f64 {
    let denominator = 4.0 * wi.z * wo.z;
    if d == 0.0 && denominator > 0.0 {
        return 0.0;
    }
    d * g() / denominator
}

/// The V-cavity shadowing-masking of the appendix `geom` (the Blinn arm of
/// [`Microfacet::g`]): min(1, 2(n·h)|n·o|/|o·h|, 2(n·h)|n·i|/|i·h|), 0
/// where i or o is on the other side of h than of the normal. Inlined into
/// the renderer's layered BRDF, where an out-of-line call costs the caller
/// its registers.
#[inline(always)]
pub(crate) fn v_cavity_g(wi: DVec3, wo: DVec3, h: DVec3) -> f64 {
    let (ih, oh) = (wi.dot(h), wo.dot(h));
    if ih * wi.z <= 0.0 || oh * wo.z <= 0.0 || h.z <= 0.0 {
        return 0.0;
    }
    let masking = 2.0 * h.z * wo.z.abs() / oh.abs();
    let shadowing = 2.0 * h.z * wi.z.abs() / ih.abs();
    masking.min(shadowing).min(1.0)
}

/// Draws from a Beckmann lobe's visible normals before the last is kept
/// (a draw is kept with probability at least e/4 · G1_GGX / G1_Beckmann
/// ≥ 0.38: left over once in 10¹³).
const MAX_BECKMANN_DRAWS: usize = 64;

/// A micro-normal (upper hemisphere) among those of a GGX lobe of
/// roughness `alpha` visible from `w` (from either side), drawn from `u`
/// (Heitz 2018, "Sampling the GGX distribution of visible normals"),
/// density D_w(m) = G1(w) |w·m| D(m) / |cos θw|.
pub(crate) fn ggx_visible_normal(alpha: f64, w: DVec3, u: [f64; 2]) -> DVec3 {
    // The view in the upper hemisphere, stretched to unit roughness.
    let v = (w * w.z.signum() * DVec3::new(alpha, alpha, 1.0)).normalize();
    let across = v.x.hypot(v.y);
    let t1 = if across > 0.0 {
        DVec3::new(-v.y, v.x, 0.0) / across
    } else {
        DVec3::X
    };
    let t2 = v.cross(t1);
    let r = u[0].sqrt();
    let (sin_phi, cos_phi) = crate::sampling::sin_cos_turns(u[1]);
    let p1 = r * cos_phi;
    let s = 0.5 * (1.0 + v.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * sin_phi;
    let n = t1 * p1 + t2 * p2 + v * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    DVec3::new(alpha * n.x, alpha * n.y, n.z.max(0.0)).normalize_or_zero()
}

/// (wi + wo).normalize_or_zero(), the same bits: glam tests its
/// reciprocal length with `is_finite() && > 0`, here the equivalent
/// `0 < r < ∞` (false for NaN too) in two comparisons instead of bit tests.
#[inline]
fn half_vector(wi: DVec3, wo: DVec3) -> DVec3 {
    let sum = wi + wo;
    let length_recip = 1.0 / sum.length();
    if length_recip > 0.0 && length_recip < f64::INFINITY {
        sum * length_recip
    } else {
        DVec3::ZERO
    }
}

/// cos^β computed as exp(β ln cos) with ln_1p for cosines near 1, so that the
/// very large exponents of smooth layers (β ≈ 4.6·10⁷ at 0.01°) stay accurate.
fn pow_cos(cos: f64, beta: f64) -> f64 {
    (beta * (cos - 1.0).ln_1p()).exp()
}

/// Mirror `w` about the unit normal `n`.
pub(crate) fn reflect(w: DVec3, n: DVec3) -> DVec3 {
    2.0 * w.dot(n) * n - w
}

/// Refract `w` (pointing away from the surface on the incident side, w·n > 0)
/// through the unit normal `n`; `eta` = n_transmitted / n_incident. Returns
/// the transmitted direction pointing away on the other side, or None under
/// total internal reflection (Snell, eq. 3.2).
#[inline]
pub(crate) fn refract(w: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = w.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-w / eta + (cos_i / eta - cos_t) * n).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smith_shadowing_never_exceeds_one() {
        // G1 = 1/(1 + Λ) ≤ 1 needs Λ ≥ 0. Beckmann's rational Λ dips below
        // 0 for a = 1/(α tanθ) in (1.5497, 1.6); sweep a across it (and
        // every cosine for GGX): before the clamp G1 reached 1.00006 there.
        for model in [MicrofacetModel::Beckmann, MicrofacetModel::Ggx] {
            for roughness_deg in [1.0, 14.4, 40.0] {
                let lobe = Microfacet::new(model, roughness_deg);
                let mut dipped = 0;
                for k in 0..=20_000 {
                    let a = 1.5 + 0.11 * f64::from(k) / 20_000.0;
                    let tan = 1.0 / (a * lobe.alpha);
                    let cos_theta = 1.0 / (1.0 + tan * tan).sqrt();
                    let g1 = lobe.smith_g1_of_cosine(cos_theta);
                    assert!(
                        (0.0..=1.0).contains(&g1),
                        "{model:?} {roughness_deg}° a = {a}: {g1}"
                    );
                    dipped += usize::from(g1 == 1.0 && a < 1.6);
                }
                if model == MicrofacetModel::Beckmann {
                    // Where Λ dipped it is now 0: G1 = 1 exactly.
                    assert!(dipped > 1000, "{dipped}");
                }
            }
        }
    }

    #[test]
    fn blinn_sampling_cosine_is_u_to_the_power_one_over_beta_plus_two() {
        // The inverse CDF of D(h)·cosθh for Blinn (eq. of the sampling
        // routine), written with `powf`: exp/ln must agree to rounding.
        for roughness_deg in [0.01, 0.5, 3.0, 17.0, 60.0] {
            let lobe = Microfacet::new(MicrofacetModel::Blinn, roughness_deg);
            for k in 0..=1000 {
                let u = k as f64 / 1000.0;
                let expected = u.powf(1.0 / (lobe.blinn_exponent + 2.0));
                let got = lobe.sample_normal(u, 0.3).z;
                assert!(
                    (got - expected).abs() <= 1e-13 * expected.max(1e-300),
                    "m = {roughness_deg}°, u = {u}: {got} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn blinn_exponent_halves_the_distribution_at_the_average_slope() {
        for m in [1.0, 10.0, 30.0] {
            let lobe = Microfacet::new(MicrofacetModel::Blinn, m);
            let at_m = DVec3::new(m.to_radians().sin(), 0.0, m.to_radians().cos());
            assert!((lobe.d(at_m) / lobe.d(DVec3::Z) - 0.5).abs() < 1e-9);
        }
    }

    #[test]
    fn blinn_shortcut_to_zero_equals_the_written_out_distribution() {
        // D = (β + 2)/(2π) · exp(β ln_1p(cosθh − 1)) (appendix blinnD), at
        // angles around where exp underflows, for smooth to rough lobes.
        for m in [MIN_ROUGHNESS_DEG, 0.1, 1.0, 10.0, 45.0, 89.0] {
            let lobe = Microfacet::new(MicrofacetModel::Blinn, m);
            let beta = lobe.blinn_exponent;
            let mut zeros = 0;
            for k in 0..20_000 {
                let theta = (k as f64 / 20_000.0).powi(3) * std::f64::consts::FRAC_PI_2;
                let h = DVec3::new(theta.sin(), 0.0, theta.cos());
                let expected = (beta + 2.0) * (0.5 / PI) * ((h.z - 1.0).ln_1p() * beta).exp();
                assert_eq!(lobe.d(h).to_bits(), expected.to_bits(), "m {m} θ {theta}");
                zeros += (expected == 0.0) as usize;
            }
            if m < 1.0 {
                assert!(zeros > 1000, "m {m}: the shortcut is not exercised");
            }
        }
    }

    #[test]
    fn reflection_value_skipping_g_equals_the_full_product() {
        // D·G/(4 cosθi cosθo) written out, for a smooth and a rough lobe
        // of each family, at random pairs (mostly D = 0 for the smooth one).
        let mut rng = crate::sampling::Rng::new(3, 4);
        for model in [
            MicrofacetModel::Blinn,
            MicrofacetModel::Beckmann,
            MicrofacetModel::Ggx,
        ] {
            for m in [MIN_ROUGHNESS_DEG, 0.2, 20.0] {
                let lobe = Microfacet::new(model, m);
                for _ in 0..5000 {
                    let [a, b, c] = rng.next_3();
                    let [x, y, _] = rng.next_3();
                    let wi = DVec3::new(a - 0.5, b - 0.5, c + 0.01).normalize();
                    let wo = DVec3::new(0.5 - a, 0.5 - b + 0.02 * (x - 0.5), c + 0.01 + y * 1e-3);
                    let wo = wo.normalize();
                    let h = (wi + wo).normalize();
                    let expected = lobe.d(h) * lobe.g(wi, wo, h) / (4.0 * wi.z * wo.z);
                    let (value, pdf, _) = lobe.reflection_value_and_pdf(wi, wo);
                    assert_eq!(value.to_bits(), expected.to_bits(), "{model:?} {m}");
                    assert_eq!(lobe.reflection_without_fresnel(wi, wo).0, value);
                    assert_eq!(pdf, lobe.reflection_pdf(wi, wo));
                }
            }
        }
    }

    #[test]
    fn half_vector_equals_normalize_or_zero() {
        // Random pairs, opposite pairs (zero sum), and non-finite input.
        let mut rng = crate::sampling::Rng::new(5, 6);
        let mut pairs = vec![
            (DVec3::Z, -DVec3::Z),
            (DVec3::new(0.6, 0.0, 0.8), DVec3::new(-0.6, 0.0, -0.8)),
            (DVec3::new(f64::NAN, 0.0, 1.0), DVec3::Z),
            (DVec3::new(f64::INFINITY, 0.0, 1.0), DVec3::Z),
            (DVec3::splat(1e-200), DVec3::splat(1e-200)),
        ];
        for _ in 0..10_000 {
            let [a, b, c] = rng.next_3();
            let [x, y, z] = rng.next_3();
            pairs.push((
                DVec3::new(a - 0.5, b - 0.5, c).normalize(),
                DVec3::new(x - 0.5, y - 0.5, z).normalize(),
            ));
        }
        for (wi, wo) in pairs {
            let expected = (wi + wo).normalize_or_zero().to_array().map(f64::to_bits);
            assert_eq!(
                half_vector(wi, wo).to_array().map(f64::to_bits),
                expected,
                "{wi} {wo}"
            );
        }
    }

    #[test]
    fn refract_obeys_snell_and_reverses() {
        let w = DVec3::new(0.6, 0.0, 0.8);
        let t = refract(w, DVec3::Z, 1.5).unwrap();
        assert!((t.x.abs() * 1.5 - 0.6).abs() < 1e-12 && t.z < 0.0);
        // Reverse path: from below, along t reversed, light leaves along w.
        let back = refract(t, -DVec3::Z, 1.0 / 1.5).unwrap();
        assert!((back - w).length() < 1e-12);
    }

    /// Pearson's statistic of `n` normals drawn by `sample_visible_normal`
    /// for view `w`, in cells of 5° in θh (to 90°) by 15° in φ, against
    /// the density G1(w, h) max(0, w·h) D(h) / cosθw integrated over each
    /// cell (midpoint rule, 12 × 12 points); cells expecting under 20 are
    /// pooled into one. Returns the statistic and its degrees of freedom.
    fn visible_normal_chi2(lobe: &Microfacet, w: DVec3, n: usize) -> (f64, usize) {
        let (theta_cells, phi_cells, points) = (18, 24, 12);
        let cell_theta = PI / 2.0 / theta_cells as f64;
        let cell_phi = 2.0 * PI / phi_cells as f64;
        let density = |h: DVec3| lobe.visible_g1(w, h) * w.dot(h).max(0.0) * lobe.d(h) / w.z;
        let mut expected = vec![0.0; theta_cells * phi_cells];
        for (cell, e) in expected.iter_mut().enumerate() {
            let (i, j) = (cell / phi_cells, cell % phi_cells);
            for a in 0..points {
                for b in 0..points {
                    let theta = (i as f64 + (a as f64 + 0.5) / points as f64) * cell_theta;
                    let phi = (j as f64 + (b as f64 + 0.5) / points as f64) * cell_phi;
                    let h = DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    );
                    *e += density(h) * theta.sin();
                }
            }
            *e *= cell_theta * cell_phi / (points * points) as f64 * n as f64;
        }
        let mut observed = vec![0.0; expected.len()];
        let mut rng = Rng::new(7, 0);
        for _ in 0..n {
            let h = lobe.sample_visible_normal(w, [rng.next_f64(), rng.next_f64()]);
            let i = ((h.z.clamp(-1.0, 1.0).acos() / cell_theta) as usize).min(theta_cells - 1);
            let phi = h.y.atan2(h.x).rem_euclid(2.0 * PI);
            let j = ((phi / cell_phi) as usize).min(phi_cells - 1);
            observed[i * phi_cells + j] += 1.0;
        }
        let (mut statistic, mut cells) = (0.0, 0);
        let (mut pooled_observed, mut pooled_expected) = (0.0, 0.0);
        for (o, e) in observed.iter().zip(&expected) {
            if *e < 20.0 {
                pooled_observed += o;
                pooled_expected += e;
            } else {
                statistic += (o - e) * (o - e) / e;
                cells += 1;
            }
        }
        if pooled_expected > 0.0 {
            statistic += (pooled_observed - pooled_expected).powi(2) / pooled_expected;
            cells += 1;
        }
        (statistic, cells - 1)
    }

    #[test]
    fn visible_normals_have_the_density_g1_times_their_projected_area() {
        // Each model's visible normals (GGX's Heitz 2018, Blinn's mirrored
        // V-cavity pairs, Beckmann's by rejection from GGX's) against
        // G1(w, h) max(0, w·h) D(h) / cosθw, face-on, at 45° and at 80°:
        // Pearson's statistic within dof + 6√(2 dof) (a failing sampler,
        // e.g. D(h) cosθh alone, is thousands above).
        for model in [
            MicrofacetModel::Blinn,
            MicrofacetModel::Beckmann,
            MicrofacetModel::Ggx,
        ] {
            for roughness_deg in [15.0, 40.0] {
                let lobe = Microfacet::new(model, roughness_deg);
                for theta_deg in [0.0f64, 45.0, 80.0] {
                    let t = theta_deg.to_radians();
                    let w = DVec3::new(t.sin(), 0.0, t.cos());
                    let (statistic, dof) = visible_normal_chi2(&lobe, w, 200_000);
                    let bound = dof as f64 + 6.0 * (2.0 * dof as f64).sqrt();
                    assert!(
                        statistic < bound,
                        "{model:?} {roughness_deg}° at {theta_deg}°: χ² {statistic:.0} (dof {dof})"
                    );
                }
            }
        }
    }

    #[test]
    fn scattering_about_a_visible_normal_weighs_at_most_one() {
        // G/G1(w, h) ≤ 1 for reflection and for refraction (both sides):
        // the walk keeps a draw with that probability.
        let mut rng = Rng::new(3, 1);
        for model in [
            MicrofacetModel::Blinn,
            MicrofacetModel::Beckmann,
            MicrofacetModel::Ggx,
        ] {
            let lobe = Microfacet::new(model, 30.0);
            for _ in 0..20_000 {
                let z = rng.next_f64().max(1e-3);
                let phi = 2.0 * PI * rng.next_f64();
                let r = (1.0 - z * z).sqrt();
                let w = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                let h = lobe.sample_visible_normal(w, [rng.next_f64(), rng.next_f64()]);
                let visible = lobe.visible_g1(w, h);
                if visible <= 0.0 {
                    continue;
                }
                let outcomes = [
                    Some(reflect(w, h)),
                    refract(w, h, 1.5),
                    refract(w, h, 1.0 / 1.5),
                ];
                for wo in outcomes.into_iter().flatten() {
                    let ratio = lobe.g(w, wo, h) / visible;
                    assert!(
                        ratio <= 1.0 + 1e-12,
                        "{model:?}: G/G1 = {ratio} for {w} {wo}"
                    );
                }
            }
        }
    }

    #[test]
    fn distributions_are_normalised_over_projected_area() {
        // ∫ D(h) cosθh dω = 1, integrated numerically in θ (azimuthally symmetric).
        for model in [
            MicrofacetModel::Blinn,
            MicrofacetModel::Beckmann,
            MicrofacetModel::Ggx,
        ] {
            for m in [5.0, 20.0, 45.0] {
                let lobe = Microfacet::new(model, m);
                let n = 200_000;
                let mut sum = 0.0;
                for k in 0..n {
                    let theta = (k as f64 + 0.5) / n as f64 * PI / 2.0;
                    let h = DVec3::new(theta.sin(), 0.0, theta.cos());
                    sum += lobe.d(h) * theta.cos() * theta.sin() * 2.0 * PI * (PI / 2.0 / n as f64);
                }
                let tol = if model == MicrofacetModel::Ggx && m >= 45.0 {
                    2e-3
                } else {
                    1e-4
                };
                assert!((sum - 1.0).abs() < tol, "{model:?} m={m}: {sum}");
            }
        }
    }
}
