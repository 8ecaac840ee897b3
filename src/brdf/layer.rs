//! The compiled pieces of a layer stack: dielectric interfaces with the
//! layer beneath them, and the base (diffuse, conductor, or black).

use crate::brdf::diffuse::{lambert, oren_nayar};
use crate::brdf::fresnel;
use crate::brdf::microfacet::Microfacet;
use crate::brdf::Rgb;
use glam::DVec3;

/// A dielectric interface and the layer of varnish directly below it.
#[derive(Clone, Debug, PartialEq)]
pub struct Interface {
    /// Absolute index of refraction of the varnish below the interface.
    pub ior_below: f64,
    /// Relative index η = n_below / n_above, the ratio every Fresnel and
    /// refraction at this interface uses.
    pub eta: f64,
    /// The lobe of the analytic model: this interface's roughness plus the
    /// roughness of every interface above (section 4.2.3: "the roughness of
    /// the top surface increases the roughness of the next surface").
    pub lobe: Microfacet,
    /// The interface's own roughness, used by the physical random walk,
    /// where the broadening from above happens by refraction itself.
    pub own_lobe: Microfacet,
    /// Thickness d of the layer below (same length unit as 1/absorption).
    pub thickness: f64,
    /// Absorption coefficient α per channel (Beer-Lambert, eq. 3.4).
    pub absorption_rgb: Rgb,
}

impl Interface {
    /// Beer-Lambert transmittance exp(−α d / cosθ) of one straight crossing
    /// of the layer at a direction with cosine `cos_theta` to the normal
    /// (eq. 3.4 with path length l = d / cosθ).
    pub(crate) fn crossing_transmittance(&self, cos_theta: f64) -> Rgb {
        if self.thickness == 0.0 || self.absorption_rgb == Rgb::ZERO {
            return Rgb::ONE;
        }
        // Optical depth α·d first: a channel with α = 0 stays 0 even when
        // d / cosθ overflows to ∞ (0 · ∞ would be NaN).
        let depth = self.absorption_rgb * self.thickness;
        (-depth / cos_theta.abs().max(1e-3)).exp()
    }

    /// Appendix `absorption`: Beer's law along both refracted directions,
    /// exp(−α d (1/cosθ'ᵢ + 1/cosθ'ₒ)), the cosines clamped at 0.001 as there.
    #[inline]
    pub(crate) fn round_trip_transmittance(&self, wi_inside: DVec3, wo_inside: DVec3) -> Rgb {
        self.round_trip_transmittance_of_cosines(wi_inside.z, wo_inside.z)
    }

    /// [`Interface::round_trip_transmittance`] of two directions inside
    /// the layer given by their cosines to the normal.
    #[inline]
    pub(crate) fn round_trip_transmittance_of_cosines(
        &self,
        cos_i_inside: f64,
        cos_o_inside: f64,
    ) -> Rgb {
        if self.thickness == 0.0 || self.absorption_rgb == Rgb::ZERO {
            return Rgb::ONE;
        }
        // α·d first, as in `crossing_transmittance`: no 0 · ∞ for a huge d.
        let depth = self.absorption_rgb * self.thickness;
        let secants = 1.0 / cos_i_inside.clamp(1e-3, 1.0) + 1.0 / cos_o_inside.clamp(1e-3, 1.0);
        (-depth * secants).exp()
    }
}

/// What lies under the last layer.
#[derive(Clone, Debug, PartialEq)]
pub enum Base {
    /// Oren-Nayar (σ in radians; 0 is Lambert) with a diffuse colour.
    Diffuse {
        /// Diffuse reflectance per channel.
        colour: Rgb,
        /// Oren-Nayar slope deviation σ in radians.
        oren_nayar_sigma_rad: f64,
    },
    /// A metal: complex IOR relative to the medium above it, and a lobe.
    Conductor {
        /// n / n_above per channel.
        n_relative: Rgb,
        /// k / n_above per channel.
        k_relative: Rgb,
        /// Lobe of the analytic model (accumulated roughness, section 4.2.3).
        lobe: Microfacet,
        /// The metal's own roughness, for the random walk.
        own_lobe: Microfacet,
    },
    /// Nothing comes back: the bare interface reflection of a varnish.
    Black,
}

impl Base {
    /// The base BRDF f(wi, wo) in the frame of the medium above it.
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> Rgb {
        match self {
            // σ ≤ 0 is Lambert: `oren_nayar`'s own first two cases, here
            // without the call (the base of every coat over Lambert).
            Base::Diffuse {
                colour,
                oren_nayar_sigma_rad,
            } if *oren_nayar_sigma_rad <= 0.0 => {
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    Rgb::ZERO
                } else {
                    lambert(*colour)
                }
            }
            Base::Diffuse {
                colour,
                oren_nayar_sigma_rad,
            } => oren_nayar(*colour, *oren_nayar_sigma_rad, wi, wo),
            Base::Conductor {
                n_relative,
                k_relative,
                lobe,
                ..
            } => {
                let (value, h) = lobe.reflection_without_fresnel(wi, wo);
                if value == 0.0 {
                    return Rgb::ZERO;
                }
                fresnel::conductor(wi.dot(h), *n_relative, *k_relative) * value
            }
            Base::Black => Rgb::ZERO,
        }
    }

    /// Sample the incident direction for outgoing `wo`; None if none.
    pub fn sample(&self, wo: DVec3, u1: f64, u2: f64) -> Option<DVec3> {
        match self {
            Base::Diffuse { .. } => Some(crate::sampling::cosine_hemisphere(u1, u2)),
            Base::Conductor { lobe, .. } => lobe.sample_reflection(wo, u1, u2),
            Base::Black => None,
        }
    }

    /// Density of [`Base::sample`].
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        match self {
            Base::Diffuse { .. } => crate::sampling::cosine_hemisphere_pdf(wi),
            Base::Conductor { lobe, .. } => lobe.reflection_pdf(wi, wo),
            Base::Black => 0.0,
        }
    }

    /// A rough guess of the base's hemispherical albedo (mean over channels),
    /// used only to choose how often to sample it.
    pub(crate) fn albedo_guess(&self) -> f64 {
        match self {
            Base::Diffuse { colour, .. } => colour.element_sum() / 3.0,
            Base::Conductor {
                n_relative,
                k_relative,
                ..
            } => fresnel::conductor(1.0, *n_relative, *k_relative).element_sum() / 3.0,
            Base::Black => 0.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lambert_base_evaluates_like_oren_nayar_with_zero_sigma() {
        // The σ ≤ 0 arm of `Base::eval` against the general `oren_nayar`,
        // including directions below the horizon (0 there).
        let colour = Rgb::new(0.1, 0.5, 0.2);
        for sigma in [0.0, -1.0] {
            let base = Base::Diffuse {
                colour,
                oren_nayar_sigma_rad: sigma,
            };
            let mut rng = crate::sampling::Rng::new(1, 2);
            for _ in 0..2000 {
                let [a, b, c] = rng.next_3();
                let [x, y, z] = rng.next_3();
                let wi = DVec3::new(a - 0.5, b - 0.5, c - 0.3).normalize();
                let wo = DVec3::new(x - 0.5, y - 0.5, z - 0.3).normalize();
                assert_eq!(base.eval(wi, wo), oren_nayar(colour, sigma, wi, wo));
            }
        }
    }
}
