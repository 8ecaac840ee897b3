//! The layered model of [`crate::brdf::stack`] in closed form for its
//! commonest stack: one dielectric interface over a Lambertian base (a
//! clear coat over a colour, the peer stone of `bench/compare`, the
//! coated grounds and stones of the library).
//!
//! The physics is `stack`'s, term for term (f = f₁ + T₁₂ · a · t · ρ/π / η²,
//! the density of its two-lobe mixture, the compensation lobe); what
//! changes is the arithmetic, which the general recursion cannot share:
//!
//! * **One Snell for both refractions through h.** For the half vector
//!   h = (ωᵢ + ωₒ)/|ωᵢ + ωₒ| the two cosines are equal, ωᵢ·h = ωₒ·h = c,
//!   so the pair refracted through h (appendix `refract(Ln, -H, 1/eta)`,
//!   Snell eq. 3.2) is ω′ = ω/η − (c/η − cosθₜ)·h with one cosθₜ, and
//!   ω′·h = cosθₜ exactly. Only the z components of ω′ are needed (the
//!   V-cavity or Smith shadowing inside, Beer's path lengths), so the
//!   refracted vectors are never built or normalised.
//! * **The layer branch needs no refraction**: the base is sampled by a
//!   cosine above the interface (`stack::diffuse_base_sample`, density
//!   cosθᵢ/π where ωᵢ enters).
//! * **Per-vertex constants**: 1/η, 1/η², the density factor and the
//!   compensation lobe's outgoing factors are computed once per path
//!   vertex ([`CoatAt::new`]), so an evaluation has three divisions
//!   (the half vector, Fresnel's quotient at ωᵢ·h when the lobe is lit,
//!   the shadowing) instead of about thirty.
//!
//! The results equal `stack`'s general evaluation up to rounding (tested
//! to 10⁻¹² relative for every such library material and for Blinn,
//! Beckmann and GGX lobes, with and without absorption and compensation).

use crate::brdf::compensation_lobe::{Compensation, CompensationAt};
use crate::brdf::fresnel;
use crate::brdf::layer::Interface;
use crate::brdf::microfacet::MicrofacetModel;
use crate::brdf::sample::{accept, diffuse_base_sample, mixture_pdf, BrdfSample};
use crate::brdf::Rgb;
use crate::sampling::cosine_hemisphere;
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

/// How many directions [`CoatAt::eval_and_pdf_lanes`] evaluates at once.
pub(crate) const LANES: usize = 4;

/// One interface over a Lambert base, prepared for one outgoing direction
/// ωₒ (ωₒ.z > 0): everything that depends on ωₒ and the material alone.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CoatAt<'a> {
    interface: &'a Interface,
    /// The compensation table and its outgoing factors, if the material has one.
    compensation: Option<(&'a Compensation, CompensationAt)>,
    wo: DVec3,
    /// The base's ρ/π.
    base_value: Rgb,
    inv_eta: f64,
    inv_eta_squared: f64,
    /// F(cosθₒ) at the macro-normal: the exit factor of the appendix `tir`.
    fresnel_out: f64,
    /// Mixture probabilities (the interface's lobe, the layer below).
    weights: (f64, f64),
    /// p_below/π when the layer below is sampled and ωₒ leaves it (no
    /// total internal reflection), else 0: the stack's density of the
    /// layer branch at an entering ωᵢ is this times cosθᵢ.
    layer_density_per_cosine: f64,
    /// Probability of sampling the compensation lobe.
    p_comp: f64,
}

impl<'a> CoatAt<'a> {
    /// Prepare `interface` over a Lambert base of albedo `colour` for the
    /// outgoing direction `wo` (wo.z > 0); `weights_from_fresnel` gives the
    /// stack's mixture probabilities for F(cosθₒ) (`LayeredBrdf`'s
    /// albedo guesses).
    #[inline]
    pub(crate) fn new(
        interface: &'a Interface,
        colour: Rgb,
        compensation: Option<&'a Compensation>,
        wo: DVec3,
        weights_from_fresnel: impl FnOnce(f64) -> (f64, f64),
    ) -> Self {
        let eta = interface.eta;
        let (p_comp, compensation) = match compensation {
            Some(table) => {
                let d_o = table.albedo(wo.z);
                (
                    Compensation::sampling_probability(d_o),
                    Some((table, table.at_outgoing(d_o))),
                )
            }
            None => (0.0, None),
        };
        let snell_o = fresnel::Snell::at(wo.z, eta);
        let fresnel_out = fresnel::dielectric_from_snell(wo.z, snell_o, eta);
        let weights = weights_from_fresnel(fresnel_out);
        let inv_eta = 1.0 / eta;
        let inv_eta_squared = inv_eta * inv_eta;
        let layer_density_per_cosine = if weights.1 > 0.0 && snell_o.cos_t.is_some() {
            weights.1 * FRAC_1_PI
        } else {
            0.0
        };
        CoatAt {
            interface,
            compensation,
            wo,
            base_value: colour * FRAC_1_PI,
            inv_eta,
            inv_eta_squared,
            fresnel_out,
            weights,
            layer_density_per_cosine,
            p_comp,
        }
    }

    /// f(ωᵢ, ωₒ) and the sampling density at ωᵢ (wi.z > 0).
    #[inline(never)]
    pub(crate) fn eval_and_pdf(&self, wi: DVec3) -> (Rgb, f64) {
        self.eval_and_pdf_inline(wi)
    }

    /// The body of [`CoatAt::eval_and_pdf`].
    #[inline(always)]
    fn eval_and_pdf_inline(&self, wi: DVec3) -> (Rgb, f64) {
        let itf = self.interface;
        let (lobe_value, lobe_pdf, h, cos_h) = self.interface_lobe(wi);
        // f₁, the interface's Torrance-Sparrow lobe with its Fresnel factor
        // (skipped where the lobe is 0: everywhere off a smooth coat's peak).
        let f_top = if lobe_value == 0.0 {
            0.0
        } else {
            lobe_value * fresnel::dielectric(cos_h, itf.eta)
        };
        // Snell at the macro-normal for ωᵢ: T₁₂ and whether ωᵢ enters.
        let snell_i = fresnel::Snell::at(wi.z, itf.eta);
        let single = Rgb::splat(f_top) + self.through_layer(wi, h, cos_h, snell_i);
        let value = match &self.compensation {
            Some((table, lobe)) => (single + lobe.eval(table.albedo(wi.z))).max(Rgb::ZERO),
            None => single,
        };

        let (p_top, _) = self.weights;
        let mut stack_pdf = 0.0;
        if p_top > 0.0 {
            stack_pdf += p_top * lobe_pdf;
        }
        if snell_i.cos_t.is_some() {
            stack_pdf += self.layer_density_per_cosine * wi.z;
        }
        (value, mixture_pdf(self.p_comp, stack_pdf, wi))
    }

    /// [`CoatAt::eval_and_pdf`] at the first `count` of [`LANES`]
    /// directions at once (each wi.z > 0), lane by lane the same bits (the
    /// other lanes' values are not meaningful). What every direction needs
    /// (the half vector, Snell and Fresnel at ωᵢ, the pair refracted
    /// through h) runs as loops over the lanes, which compile to vector
    /// instructions; what only some lanes need (the interface's lobe where
    /// its D is not 0, Beer's absorption, the compensation table) runs lane
    /// by lane through the scalar code. Inlined, so that the renderer's
    /// x86-64-v3 copy of its pixel loop runs four lanes an instruction.
    #[inline(always)]
    pub(crate) fn eval_and_pdf_lanes(
        &self,
        wi: &[DVec3; LANES],
        count: usize,
    ) -> [(Rgb, f64); LANES] {
        let itf = self.interface;
        let (eta, wo, inv_eta) = (itf.eta, self.wo, self.inv_eta);
        let (x, y, z) = (wi.map(|w| w.x), wi.map(|w| w.y), wi.map(|w| w.z));
        // `interface_lobe`'s half vector, c = |ωᵢ + ωₒ|/2 and whether a
        // Blinn lobe's D is exactly 0 there.
        let (mut hx, mut hy, mut hz) = ([0.0; LANES], [0.0; LANES], [0.0; LANES]);
        let mut c = [0.0; LANES];
        let mut dark = [false; LANES];
        let blinn = itf.lobe.model == MicrofacetModel::Blinn;
        for l in 0..LANES {
            let (sx, sy, sz) = (x[l] + wo.x, y[l] + wo.y, z[l] + wo.z);
            let length = (sx * sx + sy * sy + sz * sz).sqrt();
            let recip = 1.0 / length;
            (hx[l], hy[l], hz[l]) = (sx * recip, sy * recip, sz * recip);
            c[l] = 0.5 * length;
            dark[l] = blinn & (itf.lobe.blinn_exponent * (hz[l] - 1.0) < -800.0);
        }
        // f₁ and the lobe's density where D is not 0.
        let (mut f_top, mut lobe_pdf) = ([0.0; LANES], [0.0; LANES]);
        for l in 0..count {
            if !dark[l] {
                let (value, pdf, h) = itf.lobe.reflection_value_and_pdf(wi[l], wo);
                (hx[l], hy[l], hz[l]) = (h.x, h.y, h.z);
                c[l] = wi[l].dot(h);
                lobe_pdf[l] = pdf;
                if value != 0.0 {
                    f_top[l] = value * fresnel::dielectric(c[l], eta);
                }
            }
        }
        // `through_layer`'s arithmetic and Snell and Fresnel at ωᵢ; a lane
        // whose pair does not cross the layer is masked.
        let (mut cos_i_in, mut cos_o_in) = ([0.0; LANES], [0.0; LANES]);
        let (mut crosses, mut enters) = ([false; LANES], [false; LANES]);
        let (mut transmission_in, mut scale) = ([0.0; LANES], [0.0; LANES]);
        for l in 0..LANES {
            let sin2_t = (1.0 - c[l] * c[l]).max(0.0) * self.inv_eta_squared;
            let cos_t = (1.0 - sin2_t).sqrt();
            let k = (c[l] * inv_eta - cos_t) * hz[l];
            (cos_i_in[l], cos_o_in[l]) = (z[l] * inv_eta - k, wo.z * inv_eta - k);
            // (sin²θₜ is never NaN: the max takes 0 for a NaN.)
            let blocked = cos_i_in[l] <= 0.0 || cos_o_in[l] <= 0.0;
            crosses[l] = (sin2_t < 1.0) & !blocked;
            let g_inside = (2.0 * hz[l] * cos_i_in[l].min(cos_o_in[l]) / cos_t).min(1.0);
            // `fresnel::dielectric_from_snell` at ωᵢ.
            let cos_i = z[l].abs().min(1.0);
            let sin2_i = (1.0 - cos_i * cos_i) / (eta * eta);
            enters[l] = sin2_i < 1.0;
            let cos_t_i = (1.0 - sin2_i).sqrt();
            let r_parallel = (eta * cos_i - cos_t_i) / (eta * cos_i + cos_t_i);
            let r_perpendicular = (cos_i - eta * cos_t_i) / (cos_i + eta * cos_t_i);
            let fresnel_in = if enters[l] {
                0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)
            } else {
                1.0
            };
            transmission_in[l] = 1.0 - fresnel_in;
            let tir = (1.0 - g_inside) + (1.0 - self.fresnel_out) * g_inside;
            scale[l] = transmission_in[l] * tir * self.inv_eta_squared;
        }
        let (p_top, _) = self.weights;
        let mut out = [(Rgb::ZERO, 0.0); LANES];
        for l in 0..count {
            if !blinn && crosses[l] {
                // Smith's shadowing inside instead of the V-cavity's.
                let (i, o) = (cos_i_in[l], cos_o_in[l]);
                let g_inside = itf.lobe.smith_g1_of_cosine(i) * itf.lobe.smith_g1_of_cosine(o);
                let tir = (1.0 - g_inside) + (1.0 - self.fresnel_out) * g_inside;
                scale[l] = transmission_in[l] * tir * self.inv_eta_squared;
            }
            let through = if crosses[l] {
                let absorption = itf.round_trip_transmittance_of_cosines(cos_i_in[l], cos_o_in[l]);
                absorption * self.base_value * scale[l]
            } else {
                Rgb::ZERO
            };
            let single = Rgb::splat(f_top[l]) + through;
            let value = match &self.compensation {
                Some((table, lobe)) => (single + lobe.eval(table.albedo(z[l]))).max(Rgb::ZERO),
                None => single,
            };
            let mut stack_pdf = 0.0;
            if p_top > 0.0 {
                stack_pdf += p_top * lobe_pdf[l];
            }
            if enters[l] {
                stack_pdf += self.layer_density_per_cosine * z[l];
            }
            out[l] = (value, mixture_pdf(self.p_comp, stack_pdf, wi[l]));
        }
        out
    }

    /// The interface's lobe D·G/(4 cosθᵢ cosθₒ) at ωᵢ, its sampling density,
    /// the half vector h and c = ωᵢ·h = ωₒ·h. A Blinn lobe whose D is
    /// exactly 0 at h (β(cosθh − 1) < −800, see `Microfacet::d`: almost
    /// every light sample off a smooth coat's peak) answers from h alone,
    /// with c = |ωᵢ + ωₒ|/2 (the cosine of half the angle between them).
    #[inline(always)]
    fn interface_lobe(&self, wi: DVec3) -> (f64, f64, DVec3, f64) {
        let lobe = &self.interface.lobe;
        if lobe.model == MicrofacetModel::Blinn {
            let sum = wi + self.wo;
            let length = sum.length();
            let h = sum * (1.0 / length);
            if lobe.blinn_exponent * (h.z - 1.0) < -800.0 {
                return (0.0, 0.0, h, 0.5 * length);
            }
        }
        let (value, pdf, h) = lobe.reflection_value_and_pdf(wi, self.wo);
        (value, pdf, h, wi.dot(h))
    }

    /// T₁₂ · a · t · ρ/π / η²: the light that crosses into the layer, is
    /// scattered by the base and crosses out (`stack`'s `eval_level` below
    /// its f₁), with the pair refracted through `h` (c = ωᵢ·h) in closed form.
    #[inline(always)]
    fn through_layer(&self, wi: DVec3, h: DVec3, c: f64, snell_i: fresnel::Snell) -> Rgb {
        let (itf, wo, inv_eta) = (self.interface, self.wo, self.inv_eta);
        // Snell through h, shared by both directions (module notes).
        let sin2_t = (1.0 - c * c).max(0.0) * self.inv_eta_squared;
        if sin2_t >= 1.0 {
            return Rgb::ZERO;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        // z of ω′ = ω/η − (c/η − cosθₜ)·h, pointing up inside the layer.
        let k = (c * inv_eta - cos_t) * h.z;
        let (cos_i_in, cos_o_in) = (wi.z * inv_eta - k, wo.z * inv_eta - k);
        if cos_i_in <= 0.0 || cos_o_in <= 0.0 {
            return Rgb::ZERO;
        }
        // Appendix `geom` of the refracted pair, whose cosines to h are both
        // cosθₜ: min(1, 2(n·h)(n·ω′)/(ω′·h)) over the two directions.
        let g_inside = match itf.lobe.model {
            MicrofacetModel::Blinn => (2.0 * h.z * cos_i_in.min(cos_o_in) / cos_t).min(1.0),
            _ => itf.lobe.smith_g1_of_cosine(cos_i_in) * itf.lobe.smith_g1_of_cosine(cos_o_in),
        };
        // T₁₂ at the macro-normal and the appendix `tir` exit term (see
        // `stack::LayeredBrdf::eval_level` for both deviations).
        let transmission_in = 1.0 - fresnel::dielectric_from_snell(wi.z, snell_i, itf.eta);
        let tir = (1.0 - g_inside) + (1.0 - self.fresnel_out) * g_inside;
        let absorption = itf.round_trip_transmittance_of_cosines(cos_i_in, cos_o_in); // eq. 3.4
        absorption * self.base_value * (transmission_in * tir * self.inv_eta_squared)
    }

    /// Importance-sample ωᵢ from three uniform numbers, as `stack`'s
    /// sampler: the compensation lobe's cosine, else the interface's
    /// lobe or the base's cosine above the interface, by the
    /// mixture weights. None when the sample carries no energy.
    #[inline(never)]
    pub(crate) fn sample(&self, u: [f64; 3]) -> Option<BrdfSample> {
        self.sample_inline(u)
    }

    /// The body of [`CoatAt::sample`] (with the evaluation inlined).
    #[inline(always)]
    fn sample_inline(&self, u: [f64; 3]) -> Option<BrdfSample> {
        let wi = self.sample_direction(u)?;
        let (value, pdf) = self.eval_and_pdf_inline(wi);
        accept(wi, value, pdf)
    }

    /// The direction [`CoatAt::sample`] draws from `u` and then evaluates
    /// (wi.z > 0), None where it returns None before evaluating.
    #[inline(always)]
    pub(crate) fn sample_direction(&self, u: [f64; 3]) -> Option<DVec3> {
        let p_comp = self.p_comp;
        let wi = if u[0] < p_comp {
            cosine_hemisphere(u[1], u[2])
        } else {
            let u0 = ((u[0] - p_comp) / (1.0 - p_comp)).min(1.0 - f64::EPSILON);
            let (p_top, _) = self.weights;
            if u0 < p_top {
                self.interface.lobe.sample_reflection(self.wo, u[1], u[2])?
            } else if self.layer_density_per_cosine > 0.0 {
                // (p_below > 0 and ωₒ leaves the layer, see the field.)
                diffuse_base_sample(u[1], u[2], &[], self.interface.eta)?
            } else {
                return None;
            }
        };
        (wi.z > 0.0).then_some(wi)
    }
}

#[cfg(test)]
mod tests {
    use super::LANES;
    use crate::brdf::stack::MIN_TOP_LOBE_WEIGHT;
    use crate::brdf::{Base, Interface, LayeredBrdf, Microfacet, MicrofacetModel, Rgb};
    use crate::sampling::Rng;
    use glam::DVec3;

    /// One interface of relative index `eta` over a Lambert base, without
    /// a compensation lobe (the library's coats cover that, see `stack`).
    fn coat(model: MicrofacetModel, roughness_deg: f64, eta: f64, absorbing: bool) -> LayeredBrdf {
        let interface = Interface {
            ior_below: eta,
            eta,
            lobe: Microfacet::new(model, roughness_deg),
            own_lobe: Microfacet::new(model, roughness_deg),
            thickness: if absorbing { 0.4 } else { 0.0 },
            absorption_rgb: Rgb::new(0.9, 0.3, 0.0),
        };
        let base = Base::Diffuse {
            colour: Rgb::new(0.1, 0.5, 0.2),
            oren_nayar_sigma_rad: 0.0,
        };
        LayeredBrdf::new("coat", model, vec![interface], base)
    }

    fn coats() -> Vec<LayeredBrdf> {
        let mut all = Vec::new();
        for model in [
            MicrofacetModel::Blinn,
            MicrofacetModel::Beckmann,
            MicrofacetModel::Ggx,
        ] {
            for roughness_deg in [0.01, 4.0, 30.0] {
                // η < 1: a layer rarer than the medium above (total internal
                // reflection on the way in).
                for eta in [1.5, 2.4, 0.8] {
                    for absorbing in [false, true] {
                        all.push(coat(model, roughness_deg, eta, absorbing));
                    }
                }
            }
        }
        all
    }

    fn close(a: f64, b: f64, relative: f64) -> bool {
        (a - b).abs() <= relative * a.abs().max(b.abs()) + 1e-300
    }

    fn direction(rng: &mut Rng) -> DVec3 {
        let [a, b, c] = rng.next_3();
        DVec3::new(a - 0.5, b - 0.5, c + 0.02).normalize()
    }

    #[test]
    fn closed_form_equals_the_general_recursion() {
        // f and the density against `LayeredBrdf::eval` and `pdf` (the
        // recursion over refracted vectors), at random pairs and at mirror
        // pairs where a smooth lobe's D is at its peak.
        let mut rng = Rng::new(21, 22);
        let mut lit = 0;
        for brdf in coats() {
            // Beer's exp(−αd(1/cosθ′ᵢ + 1/cosθ′ₒ)) multiplies the rounding of
            // the cosines by the optical depth (up to ~10³ at grazing).
            let tolerance = if brdf.interfaces[0].thickness > 0.0 {
                1e-10
            } else {
                1e-12
            };
            for k in 0..4000 {
                let wo = direction(&mut rng);
                let wi = if k % 4 == 0 {
                    DVec3::new(-wo.x, -wo.y, wo.z)
                } else {
                    direction(&mut rng)
                };
                let (value, pdf) = brdf
                    .coat_at(wo, MIN_TOP_LOBE_WEIGHT)
                    .unwrap()
                    .eval_and_pdf(wi);
                let (value_ref, pdf_ref) = (brdf.eval(wi, wo), brdf.pdf(wi, wo));
                for (a, b) in value.to_array().into_iter().zip(value_ref.to_array()) {
                    assert!(
                        close(a, b, tolerance),
                        "{brdf:?}\n{value} {value_ref} at {wi} {wo}"
                    );
                }
                assert!(
                    close(pdf, pdf_ref, 1e-12),
                    "{brdf:?}\n{pdf} {pdf_ref} at {wi} {wo}"
                );
                lit += (value.max_element() > 0.0) as usize;
            }
        }
        assert!(lit > 100_000, "only {lit} lit pairs");
    }

    #[test]
    fn lanes_give_the_scalar_bits() {
        // Every coat of the tests and of the library, with and without its
        // compensation lobe, at random pairs and at mirror pairs (a live
        // smooth peak), four at a time against one at a time.
        let mut brdfs = coats();
        for name in crate::recipe::library::builtin_material_names() {
            let brdf = crate::recipe::load_material(name).unwrap();
            if brdf.coat_at(DVec3::Z, MIN_TOP_LOBE_WEIGHT).is_some() {
                brdfs.push(brdf);
            }
        }
        assert!(brdfs.len() > coats().len(), "no library coat");
        let mut rng = Rng::new(25, 26);
        for brdf in brdfs {
            for k in 0..500 {
                let wo = direction(&mut rng);
                let Some(at) = brdf.coat_at(wo, MIN_TOP_LOBE_WEIGHT) else {
                    continue;
                };
                let mirror = DVec3::new(-wo.x, -wo.y, wo.z);
                let wi = [0, 1, 2, 3].map(|l| {
                    if (k + l) % 3 == 0 {
                        mirror
                    } else {
                        direction(&mut rng)
                    }
                });
                let lanes = at.eval_and_pdf_lanes(&wi, LANES);
                for (w, (value, pdf)) in wi.into_iter().zip(lanes) {
                    let (value_scalar, pdf_scalar) = at.eval_and_pdf(w);
                    assert_eq!(
                        (value.to_array().map(f64::to_bits), pdf.to_bits()),
                        (
                            value_scalar.to_array().map(f64::to_bits),
                            pdf_scalar.to_bits()
                        ),
                        "{brdf:?} at {w} {wo}: {value} {pdf} against {value_scalar} {pdf_scalar}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_base_is_sampled_where_light_leaves_the_layer() {
        // Under a denser coat (η > 1) every direction above enters the
        // layer, so no sample of the base's branch is lost (a cosine drawn
        // inside and refracted out lost 1 − 1/η² of them: 31 %, 56 %, 83 %
        // here). Under a rarer one (η < 1) a direction enters only inside
        // the critical cone, sin²θᵢ < η²: a share η² of the cosine's samples.
        let mut rng = Rng::new(31, 32);
        for (eta, kept) in [(1.2, 1.0), (1.5, 1.0), (2.4, 1.0), (0.8, 0.64)] {
            let brdf = coat(MicrofacetModel::Blinn, 0.01, eta, false);
            let at = brdf
                .coat_at(DVec3::new(0.1, 0.0, 1.0).normalize(), MIN_TOP_LOBE_WEIGHT)
                .unwrap();
            let p_top = at.weights.0;
            let n = 20_000;
            let accepted = (0..n)
                .filter(|_| {
                    let [u0, u1, u2] = rng.next_3();
                    // u₀ past the lobe's share: the base's branch.
                    let u = [p_top + (1.0 - p_top) * u0 * 0.999, u1, u2];
                    at.sample(u).is_some()
                })
                .count();
            let share = accepted as f64 / n as f64;
            assert!(
                (share - kept).abs() < 0.015,
                "η {eta}: {share} of the base's samples kept, expected {kept}"
            );
        }
    }

    #[test]
    fn closed_form_sampling_equals_the_general_sampler() {
        // Without a compensation lobe the coat's sampler draws what
        // `LayeredBrdf`'s recursive sampler draws from the same numbers
        // (the lobe, or the base's cosine above the interface), with
        // the same weight f·cosθᵢ/p.
        let mut rng = Rng::new(23, 24);
        let mut accepted = 0;
        for brdf in coats() {
            for _ in 0..2000 {
                let wo = direction(&mut rng);
                let u = rng.next_3();
                let fast = brdf.coat_at(wo, MIN_TOP_LOBE_WEIGHT).unwrap().sample(u);
                let reference = brdf.sample_single_crossing(wo, u);
                match (fast, reference) {
                    (None, None) => {}
                    (Some(s), Some((wi, weight))) => {
                        assert!(
                            (s.wi - wi).abs().max_element() < 1e-12,
                            "{brdf:?}\n{} {wi}",
                            s.wi
                        );
                        for (a, b) in s.weight().to_array().into_iter().zip(weight.to_array()) {
                            assert!(close(a, b, 1e-10), "{brdf:?}\n{} {weight}", s.weight());
                        }
                        accepted += 1;
                    }
                    (fast, reference) => panic!("{brdf:?}\n{fast:?} against {reference:?}"),
                }
            }
        }
        assert!(accepted > 50_000, "only {accepted} samples");
    }
}
