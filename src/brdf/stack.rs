//! The layered BRDF of Weidlich & Wilkie (2007), section 2.3 and the
//! appendix shader, generalised to any number of layers:
//!
//! f = f₁ + T₁₂ · a · t · f₂(ω′ᵢ, ω′ₒ) / η²
//!
//! where f₁ is the interface's Torrance-Sparrow lobe, T₁₂ = 1 − F(ωᵢ·h) the
//! transmission into the layer, a the Beer absorption along the refracted
//! directions (eq. 3.4, appendix `absorption`), t = (1 − G) + (1 − F)·G the
//! exit term of the appendix `tir`, and f₂ the rest of the stack evaluated
//! with the directions refracted through the micro-facet normal h.
//!
//! Deviations from the seed, each marked in the code:
//! * the 1/η² radiance compression of crossing into and out of a denser
//!   medium (étendue: n² cosθ dω is invariant) is included;
//! * the seed's exit transmission is the `tir` term t, whose (1 − F) *is*
//!   T₂₁ with micro-facet shadowing; we do not multiply by T₂₁ a second time;
//! * the transmission Fresnel factors are taken at the macro-normal instead of
//!   the half vector h (at h the seed's albedo exceeds 1 at grazing angles);
//! * the seed evaluates two layers; we recurse through any number;
//! * an energy-compensation lobe (see [`crate::brdf::compensation`]) restores
//!   the light that the single crossing of the model loses.

use crate::brdf::coat::{CoatAt, LANES};
use crate::brdf::compensation_lobe::{Compensation, CompensationAt};
use crate::brdf::diffuse::lambert;
use crate::brdf::fresnel;
use crate::brdf::layer::{Base, Interface};
use crate::brdf::microfacet::{refract, v_cavity_g, MicrofacetModel};
use crate::brdf::sample::{accept, all_finite, diffuse_base_sample, mixture_pdf, BrdfSample};
use crate::brdf::Rgb;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use glam::DVec3;

/// The fewest directions worth [`CoatAt::eval_and_pdf_lanes`] (one is
/// evaluated alone).
const MIN_LANES_USED: usize = 2;

/// The least weight of an interface's own lobe when a BRDF sample picks
/// it or the layers below, against their (1 − F)·albedo guess: as if the
/// interface reflected at least this much instead of its Fresnel F
/// (0.04 head-on for IOR 1.5). A smooth coat's mirror image of a small
/// light is found by BRDF samples alone (a light sample almost never
/// falls in its lobe), so picking it by F gave its highlights, and the
/// scene it reflects, most of a coated stone's noise; the layers below
/// are lit by light samples as well. At 0.25 (about half the samples on
/// the coat of a mid-grey base), 16 spp: a coated stone's RMSE 1.8–2.5×
/// lower under a sphere light, a soft box or the studio, a coated metal
/// 1.3×, and 1.2× higher in a uniform sky with no light (the worst case:
/// there the base's diffuse light needs the samples).
pub(crate) const MIN_TOP_LOBE_WEIGHT: f64 = 0.25;

/// [`MIN_TOP_LOBE_WEIGHT`] for a vertex that a path reaches after a glossy
/// or diffuse bounce (see [`LayeredBrdf::at_after_bounce`]). There the
/// coat's mirror image of a small light is a caustic on the earlier vertex
/// (a smooth stone casting a light's image on the ground), found by BRDF
/// samples alone, a few large samples in an image; the layers below add
/// diffuse light, which any sample finds. At 0.75, 16 spp: the grounds of
/// the peer scene, lavender lepidolite and the studio 0.87–0.90× the RMSE,
/// a soft box under a sky 0.99×, a uniform sky with no light 1.02×.
const MIN_TOP_LOBE_WEIGHT_AFTER_BOUNCE: f64 = 0.75;

/// A compiled layered material: interfaces from top to bottom over a base.
#[derive(Clone, Debug)]
pub struct LayeredBrdf {
    /// Library or file name, for messages and plots.
    pub name: String,
    /// The distribution family shared by every lobe of the material.
    pub model: MicrofacetModel,
    /// Dielectric interfaces, top first.
    pub interfaces: Vec<Interface>,
    /// What lies below the last layer.
    pub base: Base,
    /// Multiple-scattering compensation, if the material enables it.
    pub compensation: Option<Compensation>,
    /// Per interface: a guess of the albedo of everything below it, seen
    /// from inside (for the sampling mixture weights only).
    below_albedo_guess: Vec<f64>,
}

impl LayeredBrdf {
    /// Assemble a material from its parts; computes sampling weights but
    /// no compensation (see [`LayeredBrdf::with_compensation`]).
    pub fn new(name: &str, model: MicrofacetModel, interfaces: Vec<Interface>, base: Base) -> Self {
        let mut below = vec![0.0; interfaces.len()];
        let mut albedo = base.albedo_guess();
        for (j, itf) in interfaces.iter().enumerate().rev() {
            let transmittance = {
                let t = itf.crossing_transmittance(1.0);
                (t * t).element_sum()
            } / 3.0;
            below[j] = albedo * transmittance;
            let f0 = fresnel::dielectric(1.0, itf.eta);
            albedo = f0 + (1.0 - f0) * below[j];
        }
        LayeredBrdf {
            name: name.to_string(),
            model,
            interfaces,
            base,
            compensation: None,
            below_albedo_guess: below,
        }
    }

    /// The full BRDF f(wi, wo) (no cosine): the single-crossing model plus
    /// the compensation lobe when enabled. wi: towards the light; wo: towards
    /// the viewer; both unit vectors (other lengths give wrong values), in
    /// the local frame with z the normal
    /// ([`crate::sampling::direction_from_degrees`] makes one from θ, φ).
    ///
    /// A smooth layer's lobe is nearly a mirror (the notes' 0.01° gives a
    /// Blinn exponent of about 4.6 · 10⁷), so at the exact mirror direction
    /// its value is very large (tens of thousands per steradian) and a
    /// degree away it is 0: integrate it with [`LayeredBrdf::sample`],
    /// not by evaluating on a grid of directions.
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::ZERO;
        }
        let single = self.eval_single_crossing(wi, wo);
        match &self.compensation {
            Some(c) => plus_compensation_lobe(single, c.eval(wi, wo)),
            None => single,
        }
    }

    /// The seed-faithful model: light crosses each layer once.
    pub fn eval_single_crossing(&self, wi: DVec3, wo: DVec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.eval_from(0, wi, wo)
    }

    /// f of the sub-stack starting at interface `level`, directions in the
    /// medium above that interface.
    fn eval_from(&self, level: usize, wi: DVec3, wo: DVec3) -> Rgb {
        let Some(itf) = self.interfaces.get(level) else {
            return self.base.eval(wi, wo);
        };
        let (lobe_value, h) = itf.lobe.reflection_without_fresnel(wi, wo);
        self.eval_level(level, wi, wo, lobe_value, h, || {
            fresnel::dielectric(wo.z, itf.eta)
        })
    }

    /// [`LayeredBrdf::eval_from`] at an interface whose micro-facet lobe
    /// D·G/(4 cosθᵢ cosθₒ) at the half vector `h` is already known;
    /// `fresnel_out` gives F(cosθₒ) at the macro-normal (called only when
    /// the layers below contribute, so that a per-vertex caller can pass a
    /// value it already has and the recursion computes it only when needed).
    fn eval_level(
        &self,
        level: usize,
        wi: DVec3,
        wo: DVec3,
        lobe_value: f64,
        h: DVec3,
        fresnel_out: impl FnOnce() -> f64,
    ) -> Rgb {
        let itf = &self.interfaces[level];
        // f₁: Torrance-Sparrow reflection at the interface (appendix
        // torranceSparrowReflector), with the dielectric Fresnel factor.
        // (A lobe value of 0, everywhere off the peak of a smooth coat,
        // gives 0 for any F in [0, 1]: skip the Fresnel factor.)
        let f_top = if lobe_value == 0.0 {
            Rgb::ZERO
        } else {
            Rgb::splat(lobe_value * fresnel::dielectric(wi.dot(h), itf.eta))
        };

        // Refract both directions through the micro-facet normal h (appendix:
        // refract(Ln, -H, 1/eta)), or the macro-normal over a glossy base
        // (`refraction_normal`); expressed pointing up inside the layer.
        let through = self.refraction_normal(level, h);
        let (Some(ti), Some(to)) = (refract(wi, through, itf.eta), refract(wo, through, itf.eta))
        else {
            return f_top;
        };
        let (wi_in, wo_in) = (-ti, -to);
        if wi_in.z <= 0.0 || wo_in.z <= 0.0 {
            return f_top;
        }
        let below = self.eval_from(level + 1, wi_in, wo_in);
        if below == Rgb::ZERO {
            return f_top;
        }
        // T₁₂ and the exit Fresnel factor are taken at the macro-normal, not
        // at h as in the appendix (deviation): with h the half vector of
        // the external pair, the seed lets light that the interface reflects
        // at grazing incidence still reach the layers below, and blue acrylic
        // reflected 1.10 of the light at 87°. At the macro-normal the factors
        // are exact for smooth coats and fall to 0 at grazing as they must.
        let transmission_in = 1.0 - fresnel::dielectric(wi.z, itf.eta); // T₁₂
                                                                        // Appendix `tir`: t = (1 − G) + (1 − F)·G with G of the refracted pair.
                                                                        // Its (1 − F) is T₂₁ (by the Stokes relations F(ω′ₒ, 1/η) = F(ωₒ, η)),
                                                                        // so T₂₁ is not multiplied again (it would be counted twice).
        let g_inside = itf.lobe.g(wi_in, wo_in, through);
        let f_out = fresnel_out();
        let tir = (1.0 - g_inside) + (1.0 - f_out) * g_inside;
        let absorption = itf.round_trip_transmittance(wi_in, wo_in); // a, eq. 3.4
                                                                     // 1/η²: radiance compression (missing in the seed).
        let scale = transmission_in * tir / (itf.eta * itf.eta);
        f_top + absorption * below * scale
    }

    /// The normal through which the interface at `level` refracts the pair
    /// (ωᵢ, ωₒ) into its layer, for the pair's micro-facet normal `h` at
    /// that interface: `h`, as the appendix does (`refract(Ln, -H,
    /// 1/eta)`), except right over a conductor base, where it is the
    /// macro-normal. Through `h` the refracted pair keeps `h` as its own
    /// half vector, so a glossy base's lobe would leave the layer as narrow
    /// as it is inside, and with the radiance factor 1/η² it would keep
    /// 1/η² of its energy (0.41 of a random walk's at η = 1.58). Through
    /// the macro-normal the lobe widens as refraction widens it (Snell's
    /// Jacobian returns the η²) and agrees with the walk; it is also the
    /// normal through which the stack samples that base. A diffuse base
    /// looks the same either way.
    #[inline]
    fn refraction_normal(&self, level: usize, h: DVec3) -> DVec3 {
        if level + 1 == self.interfaces.len() && matches!(self.base, Base::Conductor { .. }) {
            DVec3::Z
        } else {
            h
        }
    }

    /// Mixture probabilities (top lobe, rest of the stack) at `level` for
    /// outgoing `wo`, proportional to rough albedo guesses, the top lobe's
    /// at least [`MIN_TOP_LOBE_WEIGHT`].
    fn level_weights(&self, level: usize, wo: DVec3) -> (f64, f64) {
        let f = fresnel::dielectric(wo.z, self.interfaces[level].eta);
        self.level_weights_from_fresnel(level, f, MIN_TOP_LOBE_WEIGHT)
    }

    /// [`LayeredBrdf::level_weights`] given the interface's Fresnel
    /// reflectance `f` = F(cosθₒ) at the macro-normal, the top lobe's
    /// weight at least `min_top`.
    fn level_weights_from_fresnel(&self, level: usize, f: f64, min_top: f64) -> (f64, f64) {
        let itf = &self.interfaces[level];
        let top = if itf.eta == 1.0 { 0.0 } else { f.max(min_top) };
        let below = (1.0 - f) * self.below_albedo_guess[level];
        let total = top + below;
        if total <= 0.0 {
            (0.0, 0.0)
        } else {
            (top / total, below / total)
        }
    }

    /// Whether the interface at `level` is the last one, over a diffuse
    /// base: its layer branch is then sampled by a cosine above the whole
    /// stack ([`diffuse_base_sample`] under a single interface).
    fn diffuse_right_below(&self, level: usize) -> bool {
        level + 1 == self.interfaces.len() && matches!(self.base, Base::Diffuse { .. })
    }

    /// Sample wi for the sub-stack at `level`.
    fn sample_from(&self, level: usize, wo: DVec3, u: [f64; 3]) -> Option<DVec3> {
        let Some(itf) = self.interfaces.get(level) else {
            return self.base.sample(wo, u[1], u[2]);
        };
        let weights = self.level_weights(level, wo);
        self.sample_level(level, wo, u, weights, || refract(wo, DVec3::Z, itf.eta))
    }

    /// [`LayeredBrdf::sample_from`] at an interface whose mixture weights
    /// are known; `wo_refracted` gives refract(wo, z, η) (called only when
    /// the sample goes below).
    fn sample_level(
        &self,
        level: usize,
        wo: DVec3,
        u: [f64; 3],
        (p_top, p_below): (f64, f64),
        wo_refracted: impl FnOnce() -> Option<DVec3>,
    ) -> Option<DVec3> {
        let itf = &self.interfaces[level];
        if u[0] < p_top {
            itf.lobe.sample_reflection(wo, u[1], u[2])
        } else if p_below > 0.0 && self.diffuse_right_below(level) {
            // No light leaves along wo from below under total internal
            // reflection; else the base's sample above the whole stack,
            // carried down to this interface (the levels above carry it
            // back out).
            wo_refracted()?;
            diffuse_base_sample(u[1], u[2], &self.interfaces[..level], itf.eta)
        } else if p_below > 0.0 {
            // Refract wo through the macro normal, sample below, refract out.
            let u0 = ((u[0] - p_top) / p_below).min(1.0 - f64::EPSILON);
            let wo_in = -wo_refracted()?;
            let wi_in = self.sample_from(level + 1, wo_in, [u0, u[1], u[2]])?;
            refract(-wi_in, -DVec3::Z, 1.0 / itf.eta)
        } else {
            None
        }
    }

    /// Density of [`LayeredBrdf::sample_from`].
    fn pdf_from(&self, level: usize, wi: DVec3, wo: DVec3) -> f64 {
        let Some(itf) = self.interfaces.get(level) else {
            return self.base.pdf(wi, wo);
        };
        let (p_top, p_below) = self.level_weights(level, wo);
        let top_pdf = if p_top > 0.0 {
            itf.lobe.reflection_pdf(wi, wo)
        } else {
            0.0
        };
        self.pdf_level(level, wi, (p_top, p_below), top_pdf, || {
            refract(wo, DVec3::Z, itf.eta)
        })
    }

    /// [`LayeredBrdf::pdf_from`] at an interface whose mixture weights and
    /// reflection-lobe density are already known; `wo_refracted` gives
    /// refract(wo, z, η) (called only when the layers below are sampled).
    fn pdf_level(
        &self,
        level: usize,
        wi: DVec3,
        (p_top, p_below): (f64, f64),
        top_pdf: f64,
        wo_refracted: impl FnOnce() -> Option<DVec3>,
    ) -> f64 {
        let itf = &self.interfaces[level];
        let mut pdf = 0.0;
        if p_top > 0.0 {
            pdf += p_top * top_pdf;
        }
        if p_below > 0.0 && self.diffuse_right_below(level) {
            // The base's cosine above the whole stack, where wi enters and
            // wo leaves: seen here, below the interfaces above, it is
            // (Π η)²·cosθ/π (the Jacobians of Snell, cosθ/(η² cosθ′), that
            // the levels above multiply in telescope to the cosine above).
            if refract(wi, DVec3::Z, itf.eta).is_some() && wo_refracted().is_some() {
                let above: f64 = self.interfaces[..level]
                    .iter()
                    .map(|upper| upper.eta)
                    .product();
                pdf += p_below * (above * above) * cosine_hemisphere_pdf(wi);
            }
        } else if p_below > 0.0 {
            if let (Some(ti), Some(to)) = (refract(wi, DVec3::Z, itf.eta), wo_refracted()) {
                let (wi_in, wo_in) = (-ti, -to);
                // Change of variables through Snell: dω′ = cosθ dω / (η² cosθ′).
                let jacobian = wi.z / (itf.eta * itf.eta * wi_in.z);
                pdf += p_below * self.pdf_from(level + 1, wi_in, wo_in) * jacobian;
            }
        }
        pdf
    }

    /// Probability of sampling the compensation lobe for outgoing `wo`.
    fn compensation_weight(&self, wo: DVec3) -> f64 {
        match &self.compensation {
            Some(c) => Compensation::sampling_probability(c.albedo(wo.z)),
            None => 0.0,
        }
    }

    /// Importance-sample the incident direction for outgoing `wo` from three
    /// uniform numbers. Returns None when the sample carries no energy.
    /// Same as `self.at(wo).sample(u)`.
    #[inline]
    pub fn sample(&self, wo: DVec3, u: [f64; 3]) -> Option<BrdfSample> {
        self.at(wo).sample(u)
    }

    /// [`LayeredBrdf::eval`] and [`LayeredBrdf::pdf`] together, sharing the
    /// top interface's micro-facet distribution D(h) (one `exp` and one
    /// `ln_1p` per call for the seed's Blinn lobes), its mixture weights and
    /// the compensation lookups: what the renderer needs at every light
    /// sample and every BRDF sample. Equal to the two separate calls (up to
    /// rounding for one interface over a Lambert base, see [`LayeredBrdf::at`]).
    /// Same as `self.at(wo).eval_and_pdf(wi)`.
    #[cfg(test)]
    #[inline]
    pub(crate) fn eval_and_pdf(&self, wi: DVec3, wo: DVec3) -> (Rgb, f64) {
        self.at(wo).eval_and_pdf(wi)
    }

    /// The material prepared for one outgoing direction `wo`: everything
    /// that depends on wo alone (the compensation lookup D(μₒ) and the lobe
    /// probability, the top interface's F(cosθₒ), mixture weights and
    /// refracted wo) is computed here once, and shared by the
    /// `eval_and_pdf` and [`BrdfAt::sample`] calls made at that
    /// vertex. A bare Lambert material (no layers, σ = 0, no compensation)
    /// takes a shortcut: f = colour/π with cosine-weighted sampling; one
    /// interface over a Lambert base takes the closed form of the `coat`
    /// module (equal up to rounding).
    ///
    /// The shortcuts are recognised here, from the public fields, rather
    /// than cached in [`LayeredBrdf::new`], so that they can never go stale.
    #[inline]
    pub fn at(&self, wo: DVec3) -> BrdfAt<'_> {
        self.at_with_min_top(wo, MIN_TOP_LOBE_WEIGHT)
    }

    /// [`LayeredBrdf::at`] for a vertex that a path reaches after a glossy
    /// or diffuse bounce: the same BRDF, its samples taking the top
    /// interface's own lobe at least 75 % of the time instead of 25 %
    /// (there the coat's image of a small light is a caustic on the earlier
    /// vertex, which only BRDF samples find).
    #[inline]
    pub fn at_after_bounce(&self, wo: DVec3) -> BrdfAt<'_> {
        self.at_with_min_top(wo, MIN_TOP_LOBE_WEIGHT_AFTER_BOUNCE)
    }

    /// [`LayeredBrdf::at`] with the top interface's lobe picked by samples
    /// at least `min_top` of the time (the layers deeper down keep
    /// [`MIN_TOP_LOBE_WEIGHT`]).
    #[inline]
    fn at_with_min_top(&self, wo: DVec3, min_top: f64) -> BrdfAt<'_> {
        let form = if wo.z <= 0.0 {
            Form::Below
        } else if let Some(value) = self.bare_lambert() {
            Form::Lambert { value }
        } else {
            return self.layered_at(wo, min_top);
        };
        BrdfAt {
            brdf: self,
            wo,
            form,
        }
    }

    /// The layered forms of [`LayeredBrdf::at`] (wo.z > 0), out of line so
    /// that the bare Lambert path stays small enough to inline into the
    /// renderer. It returns the whole [`BrdfAt`], so that the prepared
    /// quantities are written once, into the caller's value: prepared in a
    /// callee and wrapped by the caller, they were copied twice, and the
    /// copies' wide loads stalled on the callee's narrow stores.
    #[inline(never)]
    fn layered_at(&self, wo: DVec3, min_top: f64) -> BrdfAt<'_> {
        let form = match self.coat_at(wo, min_top) {
            Some(coat) => Form::Coat(coat),
            None => Form::General(self.prepare(wo, min_top)),
        };
        BrdfAt {
            brdf: self,
            wo,
            form,
        }
    }

    /// colour/π when the material is a bare Lambert surface: no layers, a
    /// diffuse base with σ ≤ 0 (where `oren_nayar` is exactly
    /// `lambert(colour)`) and no compensation lobe.
    #[inline]
    pub(crate) fn bare_lambert(&self) -> Option<Rgb> {
        match (&self.compensation, self.interfaces.is_empty(), &self.base) {
            (
                None,
                true,
                Base::Diffuse {
                    colour,
                    oren_nayar_sigma_rad,
                },
            ) if *oren_nayar_sigma_rad <= 0.0 => Some(lambert(*colour)),
            _ => None,
        }
    }

    /// The closed form of one interface over a Lambert base (σ ≤ 0),
    /// prepared for `wo` (wo.z > 0), its own lobe sampled at least
    /// `min_top` of the time; None for every other stack.
    #[inline]
    pub(crate) fn coat_at(&self, wo: DVec3, min_top: f64) -> Option<CoatAt<'_>> {
        match (self.interfaces.as_slice(), &self.base) {
            (
                [interface],
                Base::Diffuse {
                    colour,
                    oren_nayar_sigma_rad,
                },
            ) if *oren_nayar_sigma_rad <= 0.0 => Some(CoatAt::new(
                interface,
                *colour,
                self.compensation.as_ref(),
                wo,
                |fresnel_out| self.level_weights_from_fresnel(0, fresnel_out, min_top),
            )),
            _ => None,
        }
    }

    /// The wo-dependent quantities of the general form (wo.z > 0), the top
    /// lobe sampled at least `min_top` of the time.
    #[inline]
    fn prepare(&self, wo: DVec3, min_top: f64) -> Prepared {
        let (p_comp, compensation_o) = match &self.compensation {
            Some(c) => {
                let albedo_o = c.albedo(wo.z);
                (
                    Compensation::sampling_probability(albedo_o),
                    Some(c.at_outgoing(albedo_o)),
                )
            }
            None => (0.0, None),
        };
        let top = self.interfaces.first().map(|itf| {
            // Snell once for F(cosθₒ) and the refracted wo.
            let snell_o = fresnel::Snell::at(wo.z, itf.eta);
            let fresnel_out = fresnel::dielectric_from_snell(wo.z, snell_o, itf.eta);
            let weights = self.level_weights_from_fresnel(0, fresnel_out, min_top);
            // Used only where the layers below are sampled (p_below > 0).
            let wo_refracted = if weights.1 > 0.0 {
                refract_through_normal(wo, snell_o, itf.eta)
            } else {
                None
            };
            TopAt {
                fresnel_out,
                weights,
                wo_refracted,
            }
        });
        Prepared {
            p_comp,
            compensation_o,
            top,
        }
    }

    /// Density of [`LayeredBrdf::sample`] with respect to solid angle.
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        mixture_pdf(self.compensation_weight(wo), self.pdf_from(0, wi, wo), wi)
    }

    /// Sample of the single-crossing model alone through the general
    /// recursion: the reference the tabulated albedo's sampler (and the
    /// closed form of a coat) is tested against.
    #[cfg(test)]
    pub(crate) fn sample_single_crossing(&self, wo: DVec3, u: [f64; 3]) -> Option<(DVec3, Rgb)> {
        let wi = self.sample_from(0, wo, u)?;
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf_from(0, wi, wo);
        let value = self.eval_single_crossing(wi, wo);
        if pdf.is_nan() || pdf <= 0.0 || !value.is_finite() {
            return None;
        }
        Some((wi, value * (wi.z / pdf)))
    }
}

/// A [`LayeredBrdf`] prepared for one outgoing direction (see
/// [`LayeredBrdf::at`]): evaluate and sample at one path vertex without
/// recomputing what depends on wo alone. Results are bit-identical to the
/// general [`LayeredBrdf::eval`], [`LayeredBrdf::pdf`] (same operations in
/// the same order), except for one interface over a Lambert base, whose
/// closed form (the `coat` module) equals them up to rounding.
#[derive(Clone, Copy, Debug)]
pub struct BrdfAt<'a> {
    brdf: &'a LayeredBrdf,
    wo: DVec3,
    form: Form<'a>,
}

/// Which evaluation a [`BrdfAt`] uses.
#[derive(Clone, Copy, Debug)]
enum Form<'a> {
    /// wo at or below the horizon: nothing is reflected.
    Below,
    /// No layers, Lambert base, no compensation: f = `value` = colour/π.
    Lambert { value: Rgb },
    /// One interface over a Lambert base, in closed form.
    Coat(CoatAt<'a>),
    /// Everything else: the layered model with its wo-dependent parts.
    General(Prepared),
}

/// The wo-dependent quantities of the general form.
#[derive(Clone, Copy, Debug)]
struct Prepared {
    /// Probability of sampling the compensation lobe (0 without one).
    p_comp: f64,
    /// The compensation lobe prepared for wo (None without one).
    compensation_o: Option<CompensationAt>,
    /// The top interface's quantities; None for a bare base.
    top: Option<TopAt>,
}

/// wo-dependent quantities of the top interface.
#[derive(Clone, Copy, Debug)]
struct TopAt {
    /// F(cosθₒ) at the macro-normal (exit factor and mixture weights).
    fresnel_out: f64,
    /// Mixture probabilities (top lobe, layers below).
    weights: (f64, f64),
    /// refract(wo, z, η) when the layers below are sampled, else None.
    wo_refracted: Option<DVec3>,
}

impl BrdfAt<'_> {
    /// f(wi, wo) and the density of [`BrdfAt::sample`] at `wi`; equal to
    /// [`LayeredBrdf::eval`] and, from [`LayeredBrdf::at`],
    /// [`LayeredBrdf::pdf`] (up to rounding for the closed form of a coat);
    /// from [`LayeredBrdf::at_after_bounce`] the density of its own mixture.
    #[inline]
    pub fn eval_and_pdf(&self, wi: DVec3) -> (Rgb, f64) {
        if wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        match &self.form {
            Form::Below => (Rgb::ZERO, 0.0),
            // The mixture with no compensation lobe is (1 − 0)·pdf = pdf.
            Form::Lambert { value } => (*value, cosine_hemisphere_pdf(wi)),
            Form::Coat(coat) => coat.eval_and_pdf(wi),
            Form::General(prepared) => self.eval_and_pdf_general(prepared, wi),
        }
    }

    /// The general form of [`BrdfAt::eval_and_pdf`] (wi.z > 0).
    #[inline(never)]
    fn eval_and_pdf_general(&self, prepared: &Prepared, wi: DVec3) -> (Rgb, f64) {
        self.eval_and_pdf_general_inline(prepared, wi)
    }

    /// The body of [`BrdfAt::eval_and_pdf_general`].
    #[inline(always)]
    fn eval_and_pdf_general_inline(&self, prepared: &Prepared, wi: DVec3) -> (Rgb, f64) {
        let (brdf, wo) = (self.brdf, self.wo);
        let (single, stack_pdf) = match (brdf.interfaces.first(), &prepared.top) {
            (Some(itf), Some(top)) => self.top_eval_and_pdf(itf, top, wi),
            _ => (brdf.base.eval(wi, wo), brdf.base.pdf(wi, wo)),
        };
        // As `LayeredBrdf::eval` and `pdf`, with the lobe prepared for wo
        // and its probability from `prepare`.
        let value = match (&brdf.compensation, &prepared.compensation_o) {
            (Some(c), Some(lobe)) => plus_compensation_lobe(single, lobe.eval(c.albedo(wi.z))),
            _ => single,
        };
        (value, mixture_pdf(prepared.p_comp, stack_pdf, wi))
    }

    /// The single-crossing f and the stack's density at `wi` (wi.z > 0)
    /// for a stack with at least one interface: `eval_level(0, …)` and
    /// `pdf_level(0, …)` of [`LayeredBrdf`] written out in one straight
    /// line, the same operations in the same order (so the same bits), with
    /// the top interface's lobe D(h) computed once for both, and the layers
    /// below it entered through [`LayeredBrdf::eval_from`] and
    /// [`LayeredBrdf::pdf_from`] only for deeper stacks: under one interface
    /// the base is evaluated here directly.
    #[inline(always)]
    fn top_eval_and_pdf(&self, itf: &Interface, top: &TopAt, wi: DVec3) -> (Rgb, f64) {
        let (brdf, wo, eta) = (self.brdf, self.wo, itf.eta);
        let single_interface = brdf.interfaces.len() == 1;
        let (lobe_value, top_pdf, h) = itf.lobe.reflection_value_and_pdf(wi, wo);
        // Snell at the macro-normal for wi, shared by T₁₂ and the density.
        let snell_i = fresnel::Snell::at(wi.z, eta);

        // f: as `eval_level`.
        // f₁, skipping the Fresnel factor where the lobe is 0 (see there).
        let f_top = if lobe_value == 0.0 {
            Rgb::ZERO
        } else {
            Rgb::splat(lobe_value * fresnel::dielectric(wi.dot(h), eta))
        };
        let single = 'single: {
            // Nothing comes back from a black base right below (a bare
            // varnish, a stone's polished surface): no refraction to do.
            if single_interface && matches!(brdf.base, Base::Black) {
                break 'single f_top;
            }
            // The pair refracted through h (or the macro-normal over a
            // glossy base), pointing up inside the layer.
            let through = brdf.refraction_normal(0, h);
            let (Some(ti), Some(to)) = (refract(wi, through, eta), refract(wo, through, eta))
            else {
                break 'single f_top;
            };
            let (wi_in, wo_in) = (-ti, -to);
            if wi_in.z <= 0.0 || wo_in.z <= 0.0 {
                break 'single f_top;
            }
            let below = if single_interface {
                brdf.base.eval(wi_in, wo_in)
            } else {
                brdf.eval_from(1, wi_in, wo_in)
            };
            if below == Rgb::ZERO {
                break 'single f_top;
            }
            // T₁₂ at the macro-normal, the appendix `tir` term, Beer
            // absorption (eq. 3.4) and 1/η²: see `eval_level`.
            let transmission_in = 1.0 - fresnel::dielectric_from_snell(wi.z, snell_i, eta);
            let g_inside = match itf.lobe.model {
                MicrofacetModel::Blinn => v_cavity_g(wi_in, wo_in, through),
                _ => itf.lobe.g(wi_in, wo_in, through),
            };
            let tir = (1.0 - g_inside) + (1.0 - top.fresnel_out) * g_inside;
            let absorption = itf.round_trip_transmittance(wi_in, wo_in);
            let scale = transmission_in * tir / (eta * eta);
            f_top + absorption * below * scale
        };

        // The density: as `pdf_level` with the lobe's density from above.
        let (p_top, p_below) = top.weights;
        let mut pdf = 0.0;
        if p_top > 0.0 {
            pdf += p_top * top_pdf;
        }
        if p_below > 0.0 {
            if let Some(to) = top.wo_refracted {
                match (&brdf.base, single_interface) {
                    // A diffuse base is sampled by its cosine above the
                    // interface where wi enters ([`diffuse_base_sample`]).
                    (Base::Diffuse { .. }, true) => {
                        if snell_i.cos_t.is_some() {
                            pdf += p_below * cosine_hemisphere_pdf(wi);
                        }
                    }
                    _ => {
                        if let Some(ti) = refract_through_normal(wi, snell_i, eta) {
                            let (wi_in, wo_in) = (-ti, -to);
                            // Change of variables through Snell (`pdf_level`).
                            let jacobian = wi.z / (eta * eta * wi_in.z);
                            pdf += p_below * brdf.pdf_from(1, wi_in, wo_in) * jacobian;
                        }
                    }
                }
            }
        }
        (single, pdf)
    }

    /// Importance-sample the incident direction from three uniform
    /// numbers; equal to [`LayeredBrdf::sample`]. None when the sample
    /// carries no energy.
    #[inline]
    pub fn sample(&self, u: [f64; 3]) -> Option<BrdfSample> {
        match &self.form {
            Form::Below => None,
            Form::Lambert { value } => lambert_sample(*value, u),
            Form::Coat(coat) => coat.sample(u),
            Form::General(prepared) => self.sample_general(prepared, u),
        }
    }

    /// The direction [`BrdfAt::sample`] draws from `u` (wi.z > 0) and then
    /// evaluates; None where it returns None before evaluating. So
    /// `sample(u)` is this direction's [`BrdfAt::eval_and_pdf`] passed to
    /// [`accept`], for a caller that evaluates it with other directions
    /// ([`BrdfAt::eval_and_pdf_lanes`]).
    #[inline]
    pub(crate) fn sample_direction(&self, u: [f64; 3]) -> Option<DVec3> {
        match &self.form {
            Form::Below => None,
            Form::Lambert { .. } => {
                let wi = cosine_hemisphere(u[1], u[2]);
                (wi.z > 0.0).then_some(wi)
            }
            Form::Coat(coat) => coat.sample_direction(u),
            Form::General(prepared) => self.general_sample_direction(prepared, u),
        }
    }

    /// Whether [`BrdfAt::eval_and_pdf_lanes`] evaluates in vector lanes
    /// (the closed form of a coat; other forms one direction at a time).
    #[inline(always)]
    pub(crate) fn has_lanes(&self) -> bool {
        matches!(self.form, Form::Coat(_))
    }

    /// [`BrdfAt::eval_and_pdf`] at the first `count` of [`LANES`]
    /// directions at once, the same bits: in vector lanes for the closed
    /// form of a coat when there are at least [`MIN_LANES_USED`], one
    /// after another otherwise.
    #[inline(always)]
    pub(crate) fn eval_and_pdf_lanes(
        &self,
        wi: &[DVec3; LANES],
        count: usize,
    ) -> [(Rgb, f64); LANES] {
        match &self.form {
            Form::Coat(coat) if count >= MIN_LANES_USED && wi.iter().all(|w| w.z > 0.0) => {
                coat.eval_and_pdf_lanes(wi, count)
            }
            _ => {
                let mut out = [(Rgb::ZERO, 0.0); LANES];
                for (value, w) in out.iter_mut().zip(wi).take(count) {
                    *value = self.eval_and_pdf(*w);
                }
                out
            }
        }
    }

    /// The general form of [`BrdfAt::sample`]: the compensation lobe's
    /// cosine sampling or the stack's, then f and the mixture density.
    #[inline(never)]
    fn sample_general(&self, prepared: &Prepared, u: [f64; 3]) -> Option<BrdfSample> {
        self.sample_general_inline(prepared, u)
    }

    /// The body of [`BrdfAt::sample_general`] (with the evaluation inlined).
    #[inline(always)]
    fn sample_general_inline(&self, prepared: &Prepared, u: [f64; 3]) -> Option<BrdfSample> {
        let wi = self.general_sample_direction(prepared, u)?;
        let (value, pdf) = self.eval_and_pdf_general_inline(prepared, wi);
        accept(wi, value, pdf)
    }

    /// The direction [`BrdfAt::sample_general`] draws (wi.z > 0).
    #[inline(always)]
    fn general_sample_direction(&self, prepared: &Prepared, u: [f64; 3]) -> Option<DVec3> {
        let p_comp = prepared.p_comp;
        let wi = if u[0] < p_comp {
            cosine_hemisphere(u[1], u[2])
        } else {
            let u0 = ((u[0] - p_comp) / (1.0 - p_comp)).min(1.0 - f64::EPSILON);
            self.sample_stack(prepared, [u0, u[1], u[2]])?
        };
        (wi.z > 0.0).then_some(wi)
    }

    /// `LayeredBrdf::sample_from(0, wo, u)` with the top interface's
    /// weights and refracted wo from `prepare`.
    fn sample_stack(&self, prepared: &Prepared, u: [f64; 3]) -> Option<DVec3> {
        let brdf = self.brdf;
        match (&prepared.top, brdf.interfaces.as_slice(), &brdf.base) {
            // One interface over a diffuse base: `sample_level` written
            // out, the base's cosine sampling inline (it uses u₁, u₂ only,
            // so the rescaled u₀ is not needed).
            (Some(top), [itf], Base::Diffuse { .. }) => {
                let (p_top, p_below) = top.weights;
                if u[0] < p_top {
                    itf.lobe.sample_reflection(self.wo, u[1], u[2])
                } else if p_below > 0.0 {
                    // No light leaves along wo from below under total
                    // internal reflection (None).
                    top.wo_refracted?;
                    diffuse_base_sample(u[1], u[2], &[], itf.eta)
                } else {
                    None
                }
            }
            (Some(top), _, _) => brdf.sample_level(0, self.wo, u, top.weights, || top.wo_refracted),
            (None, _, _) => brdf.base.sample(self.wo, u[1], u[2]),
        }
    }
}

/// The single-crossing value `single` plus the compensation lobe's value
/// `lobe`. The negative part of the lobe can undershoot where the single
/// crossing is small: a BRDF is never negative.
#[inline(always)]
fn plus_compensation_lobe(single: Rgb, lobe: Rgb) -> Rgb {
    (single + lobe).max(Rgb::ZERO)
}

/// `refract(w, z, eta)` for w.z > 0 given `snell` = [`fresnel::Snell::at`]`(w.z, eta)`:
/// the same bits (w·z is w.z exactly there, and Snell's sin²θₜ and cosθₜ
/// are `refract`'s, see [`fresnel::Snell::at`]); the vector arithmetic is
/// `refract`'s, ±0 terms included.
#[inline(always)]
fn refract_through_normal(w: DVec3, snell: fresnel::Snell, eta: f64) -> Option<DVec3> {
    let cos_t = snell.cos_t?;
    Some((-w / eta + (w.z / eta - cos_t) * DVec3::Z).normalize())
}

/// [`BrdfAt::sample`] of a bare Lambert material with f = `value`: the
/// base's cosine sampling (with p_comp = 0 both branches of the general
/// form draw this same direction from u₁, u₂) and its density cosθᵢ/π.
#[inline]
fn lambert_sample(value: Rgb, u: [f64; 3]) -> Option<BrdfSample> {
    let wi = cosine_hemisphere(u[1], u[2]);
    if wi.z <= 0.0 {
        return None;
    }
    // [`accept`] without its density test: for wi.z > 0 the density cosθᵢ/π
    // is positive and finite (wi.z = √(1 − u₁) ≥ 2⁻²⁷ for u₁ < 1), and
    // tested as `0 < pdf < ∞` it compiled to ten integer instructions on
    // the density's bits, on every bounce off a Lambert surface.
    all_finite(value).then_some(BrdfSample {
        wi,
        value,
        pdf: cosine_hemisphere_pdf(wi),
    })
}

#[cfg(test)]
mod tests {
    use super::{BrdfSample, Form, LayeredBrdf};
    use crate::brdf::{Base, MicrofacetModel, Rgb};
    use crate::recipe::library::builtin_material_names;
    use crate::recipe::load_material;
    use crate::sampling::{cosine_hemisphere, Rng};
    use glam::DVec3;
    use std::f64::consts::PI;

    #[test]
    fn a_sample_is_its_direction_evaluated() {
        // `sample` against `sample_direction`, `eval_and_pdf_lanes` (at one
        // to four directions, the sampled one last) and `accept`, bit for
        // bit, for every form: a lone direction takes the scalar path, two
        // or more a coat's lanes.
        let mut rng = Rng::new(41, 42);
        let mut sampled = 0;
        for brdf in materials() {
            for k in 0..400 {
                let [a, b, c] = rng.next_3();
                let wo = DVec3::new(a - 0.5, b - 0.5, c + 0.02).normalize();
                let at = brdf.at(wo);
                let u = rng.next_3();
                let expected = at.sample(u);
                let Some(wi) = at.sample_direction(u) else {
                    assert!(expected.is_none(), "{}: {expected:?}", brdf.name);
                    continue;
                };
                let count = 1 + k % super::LANES;
                let mut directions = [DVec3::Z; super::LANES];
                for other in directions.iter_mut().take(count - 1) {
                    let [x, y, z] = rng.next_3();
                    *other = DVec3::new(x - 0.5, y - 0.5, z + 0.02).normalize();
                }
                directions[count - 1] = wi;
                let values = at.eval_and_pdf_lanes(&directions, count);
                for (w, (value, pdf)) in directions.iter().zip(values).take(count) {
                    let (value_alone, pdf_alone) = at.eval_and_pdf(*w);
                    assert_eq!(
                        (value.to_array().map(f64::to_bits), pdf.to_bits()),
                        (
                            value_alone.to_array().map(f64::to_bits),
                            pdf_alone.to_bits()
                        ),
                        "{} at {w} {wo}",
                        brdf.name
                    );
                }
                let (value, pdf) = values[count - 1];
                let found = super::accept(wi, value, pdf);
                assert_eq!(
                    format!("{found:?}"),
                    format!("{expected:?}"),
                    "{}",
                    brdf.name
                );
                sampled += found.is_some() as usize;
            }
        }
        assert!(sampled > 1000, "only {sampled} samples");
    }

    /// Every library material, plus a bare Lambert and a bare Oren-Nayar
    /// ground (no layers, no compensation) like the renderer's grounds.
    fn materials() -> Vec<LayeredBrdf> {
        let mut all: Vec<LayeredBrdf> = builtin_material_names()
            .map(|name| load_material(name).unwrap())
            .collect();
        for sigma in [0.0, 0.3] {
            all.push(LayeredBrdf::new(
                "ground",
                MicrofacetModel::Blinn,
                vec![],
                Base::Diffuse {
                    colour: Rgb::new(0.5, 0.4, 0.3),
                    oren_nayar_sigma_rad: sigma,
                },
            ));
        }
        all
    }

    /// The sampling procedure written out on the general, per-call path
    /// (the code before `LayeredBrdf::at`): mixture with the compensation
    /// lobe, the recursive stack sampler, then the separate `eval` and `pdf`.
    fn reference_sample(brdf: &LayeredBrdf, wo: DVec3, u: [f64; 3]) -> Option<BrdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let p_comp = brdf.compensation_weight(wo);
        let wi = if u[0] < p_comp {
            cosine_hemisphere(u[1], u[2])
        } else {
            let u0 = ((u[0] - p_comp) / (1.0 - p_comp)).min(1.0 - f64::EPSILON);
            brdf.sample_from(0, wo, [u0, u[1], u[2]])?
        };
        if wi.z <= 0.0 {
            return None;
        }
        let (value, pdf) = (brdf.eval(wi, wo), brdf.pdf(wi, wo));
        if pdf.is_nan() || pdf <= 0.0 || !pdf.is_finite() || !value.is_finite() {
            return None;
        }
        Some(BrdfSample { wi, value, pdf })
    }

    fn parts(s: Option<BrdfSample>) -> Option<(DVec3, Rgb, f64)> {
        s.map(|s| (s.wi, s.value, s.pdf))
    }

    /// Whether `brdf` takes the closed form of `coat` (equal to the general
    /// path up to rounding, not bit for bit).
    fn is_coat(brdf: &LayeredBrdf) -> bool {
        matches!(brdf.at(DVec3::Z).form, Form::Coat(_))
    }

    /// `a` and `b` equal to `relative` of their size (or 10⁻³⁰⁰ absolute).
    fn close(a: f64, b: f64, relative: f64) -> bool {
        (a - b).abs() <= relative * a.abs().max(b.abs()) + 1e-300
    }

    /// Two samples equal (bit for bit when `exact`), else equal to
    /// rounding: the same outcome, wi to 10⁻¹², f and pdf to 10⁻¹⁰.
    fn assert_same_sample(
        fast: Option<(DVec3, Rgb, f64)>,
        reference: Option<(DVec3, Rgb, f64)>,
        exact: bool,
        name: &str,
    ) {
        if exact {
            assert_eq!(fast, reference, "{name}");
            return;
        }
        match (fast, reference) {
            (None, None) => {}
            (Some((wi, f, pdf)), Some((wi_ref, f_ref, pdf_ref))) => {
                assert!(
                    (wi - wi_ref).abs().max_element() < 1e-12,
                    "{name}: {wi} {wi_ref}"
                );
                for (a, b) in f.to_array().into_iter().zip(f_ref.to_array()) {
                    assert!(close(a, b, 1e-10), "{name}: f {f} {f_ref}");
                }
                assert!(close(pdf, pdf_ref, 1e-10), "{name}: pdf {pdf} {pdf_ref}");
            }
            _ => panic!("{name}: {fast:?} against {reference:?}"),
        }
    }

    #[test]
    fn prepared_sampling_equals_the_general_path() {
        // Bit for bit for every form but the coat's closed form, which
        // equals it to rounding.
        let mut rng = Rng::new(7, 8);
        let mut coats = 0;
        for brdf in materials() {
            let exact = !is_coat(&brdf);
            coats += !exact as usize;
            let mut accepted = 0;
            for _ in 0..200 {
                let [a, b, c] = rng.next_3();
                // Some wo below the horizon, which must give None.
                let wo = DVec3::new(a - 0.5, b - 0.5, c - 0.1).normalize();
                let at = brdf.at(wo);
                for _ in 0..5 {
                    let u = rng.next_3();
                    let fast = parts(at.sample(u));
                    let reference = parts(reference_sample(&brdf, wo, u));
                    assert_same_sample(fast, reference, exact, &brdf.name);
                    assert_eq!(fast, parts(brdf.sample(wo, u)), "{}", brdf.name);
                    accepted += fast.is_some() as usize;
                }
            }
            assert!(accepted > 100, "{}: only {accepted} samples", brdf.name);
        }
        assert!(
            coats >= 3,
            "only {coats} library coats exercise the closed form"
        );
    }

    #[test]
    fn snell_shortcuts_through_the_normal_equal_refract_bit_for_bit() {
        // `refract_through_normal` against the general `refract(w, z, η)`
        // (whose dot product with z and Snell's law it replaces), for
        // denser and rarer media (η < 1: total internal reflection), at
        // random and at exactly normal incidence.
        use super::{fresnel, refract, refract_through_normal};
        let mut rng = Rng::new(11, 12);
        let mut tir = 0;
        for eta in [1.0, 1.31, 1.5, 1.56, 2.0, 1.0 / 1.5, 0.9] {
            for k in 0..20_000 {
                let [a, b, c] = rng.next_3();
                let w = if k == 0 {
                    DVec3::Z
                } else {
                    DVec3::new(a - 0.5, b - 0.5, c + 1e-9).normalize()
                };
                let snell = fresnel::Snell::at(w.z, eta);
                let expected = refract(w, DVec3::Z, eta);
                let fast = refract_through_normal(w, snell, eta);
                assert_eq!(
                    fast.map(|v| v.to_array().map(f64::to_bits)),
                    expected.map(|v| v.to_array().map(f64::to_bits)),
                    "η {eta} w {w}"
                );
                tir += expected.is_none() as usize;
            }
        }
        assert!(tir > 1000, "total internal reflection not exercised");
    }

    #[test]
    fn a_diffuse_base_under_two_coats_is_sampled_where_light_gets_out() {
        // Two coats of index 1.3 over an Oren-Nayar base: a cosine drawn
        // above the lower coat and refracted out through the upper one
        // would meet total internal reflection for 1 − 1/1.3² = 41 % of
        // its samples; drawn above the whole stack, none is lost (the few
        // samples that fail, 2.1 %, are the rough coats' own lobes', below
        // the horizon).
        let brdf = load_material("light-blue-house-paint").unwrap();
        assert_eq!(brdf.interfaces.len(), 2);
        let wo = DVec3::new(0.17, 0.0, 0.98).normalize();
        let mut rng = Rng::new(41, 42);
        let n = 20_000;
        let lost = (0..n)
            .filter(|_| brdf.sample(wo, rng.next_3()).is_none())
            .count();
        assert!(lost < n / 20, "{lost} of {n} samples lost");
    }

    #[test]
    fn a_bare_lambert_ground_is_colour_over_pi_with_cosine_density() {
        let colour = Rgb::new(0.5, 0.4, 0.3);
        let brdfs = materials();
        let ground = brdfs.iter().rev().nth(1).unwrap(); // σ = 0
        let wo = DVec3::new(0.3, -0.4, 0.5).normalize();
        assert!(matches!(ground.at(wo).form, Form::Lambert { .. }));
        let oren_nayar = brdfs.last().unwrap(); // σ = 0.3: not a shortcut
        assert!(matches!(oren_nayar.at(wo).form, Form::General(_)));
        let mut rng = Rng::new(9, 10);
        for _ in 0..1000 {
            let [a, b, c] = rng.next_3();
            let wi = DVec3::new(a - 0.5, b - 0.5, c - 0.2).normalize();
            let (value, pdf) = ground.at(wo).eval_and_pdf(wi);
            // Lambert: f = ρ/π; cosine sampling: p = cosθᵢ/π, both 0 below.
            let expected = if wi.z > 0.0 {
                (colour / PI, wi.z / PI)
            } else {
                (Rgb::ZERO, 0.0)
            };
            assert!((value - expected.0).abs().max_element() < 1e-16);
            assert!((pdf - expected.1).abs() < 1e-16);
            assert_eq!((value, pdf), (ground.eval(wi, wo), ground.pdf(wi, wo)));
        }
    }

    #[test]
    fn a_glossy_base_under_a_coat_leaves_as_bright_and_wide_as_a_random_walk_finds() {
        // A smooth clear coat (IOR 1.58) over 4° silver: the default gem's
        // flakes without their tint. Without the compensation lobe, light at
        // the normal: the single-crossing albedo and the in-plane f·cosθₒ
        // of the glossy lobe against the random walk of the same stack.
        // Refracted through the half vector as the appendix does, the lobe
        // kept 0.41 of the walk's albedo (1/η²) and its inside width (at
        // 14° 0.27 of the walk's value).
        use crate::brdf::albedo::directional_albedo;
        use crate::brdf::reference::{reference_albedo, reference_slice};
        use crate::recipe::compile::{compile_material_without_table, MaterialSource};
        let text = r#"Material(layers: [Layer(ior: 1.58)],
                                base: Conductor(metal: "silver", roughness_deg: 4.0))"#;
        let source = MaterialSource {
            path: "coated-silver.ron".into(),
            name: "coated-silver".into(),
            text: text.into(),
        };
        let material = crate::recipe::parse_material(&source.path, text).unwrap();
        let brdf = compile_material_without_table(&source, &material).unwrap();
        let model = directional_albedo(&brdf, 0.0, 1e-3, 1 << 20, 5).mean.y;
        let (walk, _) = reference_albedo(&brdf, DVec3::Z, 200_000, 5);
        assert!((model / walk.y - 1.0).abs() < 0.06, "{model} vs {}", walk.y);
        let angles = [2.0, 10.0, 14.0];
        let slice = reference_slice(&brdf, 0.0, &angles, 2_000_000, 0.02, 5);
        let wi = crate::sampling::direction_from_degrees(0.0, 180.0);
        for (theta, walk) in angles.iter().zip(slice) {
            let wo = crate::sampling::direction_from_degrees(*theta, 0.0);
            let f_cos = brdf.eval_single_crossing(wi, wo).y * wo.z;
            assert!(
                (f_cos / walk.y - 1.0).abs() < 0.12,
                "{theta}°: {f_cos} vs {}",
                walk.y
            );
        }
    }

    #[test]
    fn fused_eval_and_pdf_equal_the_separate_calls_for_every_library_material() {
        // Bit for bit (signed zeros and NaN payloads included), except the
        // coat's closed form: equal to 10⁻¹² of the value.
        let mut rng = Rng::new(5, 6);
        for name in builtin_material_names() {
            let brdf = load_material(name).unwrap();
            let exact = !is_coat(&brdf);
            let bits = |v: Rgb| v.to_array().map(f64::to_bits);
            let check = |wi: DVec3, wo: DVec3| {
                let (value, pdf) = brdf.eval_and_pdf(wi, wo);
                let (value_ref, pdf_ref) = (brdf.eval(wi, wo), brdf.pdf(wi, wo));
                if exact {
                    assert_eq!(bits(value), bits(value_ref), "{name}: value at {wi} {wo}");
                    assert_eq!(pdf.to_bits(), pdf_ref.to_bits(), "{name}: pdf at {wi} {wo}");
                } else {
                    for (a, b) in value.to_array().into_iter().zip(value_ref.to_array()) {
                        assert!(
                            close(a, b, 1e-12),
                            "{name}: {value} {value_ref} at {wi} {wo}"
                        );
                    }
                    assert!(
                        close(pdf, pdf_ref, 1e-12),
                        "{name}: {pdf} {pdf_ref} at {wi} {wo}"
                    );
                }
            };
            for _ in 0..3000 {
                let mut direction = || {
                    let [a, b, c] = rng.next_3();
                    DVec3::new(a - 0.5, b - 0.5, c - 0.2).normalize()
                };
                let (wi, wo) = (direction(), direction());
                check(wi, wo);
            }
            // …and at the lobe's peak, where D dominates (a mirror pair).
            let wo = DVec3::new(0.3, -0.2, 0.9).normalize();
            check(DVec3::new(-wo.x, -wo.y, wo.z), wo);
        }
    }
}
