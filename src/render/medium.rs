//! Light inside a translucent body: Beer–Lambert transmittance (eq. 3.4),
//! free flights through a homogeneous, scattering medium with RGB
//! coefficients (spectral MIS over the channels), and the Henyey–Greenstein
//! phase function.

use glam::DVec3;

use crate::brdf::Rgb;
use crate::recipe::gem::Medium;

/// exp(−σa·t) per channel: Beer–Lambert transmittance over a path of
/// length `t` (eq. 3.4).
pub(crate) fn beer_lambert(absorption: Rgb, t: f64) -> Rgb {
    Rgb::new(
        (-absorption.x * t).exp(),
        (-absorption.y * t).exp(),
        (-absorption.z * t).exp(),
    )
}

/// What a free flight through a medium ended in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FreeFlight {
    /// The scattering event's distance along the ray, or None when the
    /// flight reached the segment's end (the surface).
    pub(crate) scatters_at: Option<f64>,
    /// The path's value for the event per channel: σs·Tr(t) for a
    /// scattering event, Tr(t_end) for reaching the surface.
    pub(crate) value: Rgb,
    /// Each channel's density (or probability, for reaching the surface)
    /// of this event had it sampled the distance: σt·Tr(t), or Tr(t_end).
    pub(crate) pdf: Rgb,
}

/// Samples a free-flight distance in a homogeneous medium along a segment
/// of length `t_end` from channel `hero`'s exponential, σt e^(−σt t), by
/// `u`. With RGB coefficients the path keeps every channel's density
/// (`SpectralPath`), and the estimate is weighted by the balance
/// heuristic over the three channels' whole-path densities ("hero
/// wavelength" spectral MIS): unbiased in every channel, with weights
/// bounded by 3 however many times the path scatters.
pub(crate) fn sample_free_flight(medium: &Medium, t_end: f64, hero: usize, u: f64) -> FreeFlight {
    let sigma_t = medium.absorption_per_mm + medium.scattering_per_mm;
    let sigma = sigma_t[hero];
    let t = if sigma > 0.0 {
        -(1.0 - u).ln() / sigma
    } else {
        f64::INFINITY
    };
    if t < t_end {
        let transmittance = beer_lambert(sigma_t, t);
        FreeFlight {
            scatters_at: Some(t),
            value: medium.scattering_per_mm * transmittance,
            pdf: sigma_t * transmittance,
        }
    } else {
        let transmittance = beer_lambert(sigma_t, t_end);
        FreeFlight {
            scatters_at: None,
            value: transmittance,
            pdf: transmittance,
        }
    }
}

/// A path's hero channel and every channel's path density relative to the
/// hero's (pbrt-v4's r_u), for spectral MIS through media.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpectralPath {
    pub(crate) hero: usize,
    pub(crate) relative_pdf: Rgb,
}

impl SpectralPath {
    /// A path whose distances are sampled from channel `hero`.
    pub(crate) fn new(hero: usize) -> Self {
        Self {
            hero,
            relative_pdf: Rgb::ONE,
        }
    }

    /// The factor that turns the throughput before `flight` into the
    /// throughput after it: value / pdf_hero, re-weighted from the balance
    /// heuristic's old denominator (the mean relative density) to its new.
    pub(crate) fn weigh(&mut self, flight: &FreeFlight) -> Rgb {
        let pdf_hero = flight.pdf[self.hero];
        let before = self.relative_pdf.element_sum() / 3.0;
        self.relative_pdf *= flight.pdf / pdf_hero;
        let after = self.relative_pdf.element_sum() / 3.0;
        flight.value * (before / (pdf_hero * after))
    }
}

/// The Henyey–Greenstein phase function of mean cosine `g` at the cosine
/// between the propagation directions before and after scattering:
/// (1 − g²) / (4π (1 + g² − 2g·cosθ)^(3/2)), per steradian.
pub(crate) fn henyey_greenstein(cos_theta: f64, g: f64) -> f64 {
    let denominator = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * denominator * denominator.sqrt())
}

/// A direction scattered from the propagation direction `direction` (unit)
/// by the Henyey–Greenstein phase function of mean cosine `g`, by inverting
/// its CDF in cosθ; the phase function over its own density is 1.
pub(crate) fn sample_henyey_greenstein(direction: DVec3, g: f64, u: [f64; 2]) -> DVec3 {
    let cos_theta = if g.abs() < 1e-3 {
        1.0 - 2.0 * u[0]
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u[0]);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * u[1];
    let (t, b) = direction.any_orthonormal_pair();
    (t * (sin_theta * phi.cos()) + b * (sin_theta * phi.sin()) + direction * cos_theta).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn henyey_greenstein_is_normalised_with_mean_cosine_g() {
        for g in [-0.9, -0.3, 0.0, 0.5, 0.95] {
            // ∫ p dω = 2π ∫ p(μ) dμ over μ ∈ [−1, 1], midpoint rule.
            let n = 200_000;
            let (mut total, mut mean) = (0.0, 0.0);
            for i in 0..n {
                let mu = -1.0 + 2.0 * (f64::from(i) + 0.5) / f64::from(n);
                let p = henyey_greenstein(mu, g) * std::f64::consts::TAU * 2.0 / f64::from(n);
                total += p;
                mean += p * mu;
            }
            assert!((total - 1.0).abs() < 1e-4, "g {g}: ∫p = {total}");
            assert!((mean - g).abs() < 1e-4, "g {g}: ∫p·cos = {mean}");
        }
    }

    #[test]
    fn henyey_greenstein_samples_have_mean_cosine_g() {
        let direction = DVec3::new(0.3, -0.5, 0.8).normalize();
        for g in [-0.9, -0.3, 0.0, 0.5, 0.95] {
            let n = 200;
            let mut sum = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let u = [
                        (f64::from(i) + 0.5) / f64::from(n),
                        (f64::from(j) + 0.5) / f64::from(n),
                    ];
                    let d = sample_henyey_greenstein(direction, g, u);
                    assert!((d.length() - 1.0).abs() < 1e-12);
                    sum += d.dot(direction);
                }
            }
            let mean = sum / f64::from(n * n);
            assert!((mean - g).abs() < 2e-3, "g {g}: mean cosine {mean}");
        }
    }

    #[test]
    fn free_flights_are_unbiased_per_channel() {
        // One flight, its hero channel uniform: E[weight · 1(scatter)] =
        // σs/σt · (1 − e^(−σt L)) and E[weight · 1(reach)] = e^(−σt L),
        // channel by channel, one of them with σt = 0; draws stratified.
        let medium = Medium {
            absorption_per_mm: Rgb::new(0.2, 0.0, 1.5),
            scattering_per_mm: Rgb::new(0.3, 0.0, 0.5),
            anisotropy: 0.0,
        };
        let length = 1.7;
        let n = 600;
        let (mut scattered, mut reached) = (Rgb::ZERO, Rgb::ZERO);
        for hero in 0..3 {
            for i in 0..n {
                let u = (f64::from(i) + 0.5) / f64::from(n);
                let flight = sample_free_flight(&medium, length, hero, u);
                let weight = SpectralPath::new(hero).weigh(&flight) / 3.0;
                match flight.scatters_at {
                    Some(t) => {
                        assert!(t < length);
                        scattered += weight;
                    }
                    None => reached += weight,
                }
            }
        }
        let count = f64::from(n);
        let sigma_t = medium.absorption_per_mm + medium.scattering_per_mm;
        for c in 0..3 {
            let transmittance = (-sigma_t[c] * length).exp();
            let scatter = if sigma_t[c] > 0.0 {
                medium.scattering_per_mm[c] / sigma_t[c] * (1.0 - transmittance)
            } else {
                0.0
            };
            assert!(
                (scattered[c] / count - scatter).abs() < 2e-3,
                "channel {c} scatter"
            );
            assert!(
                (reached[c] / count - transmittance).abs() < 2e-3,
                "channel {c} reach"
            );
        }
    }

    #[test]
    fn spectral_path_weights_stay_bounded_over_many_flights() {
        // The balance heuristic over whole-path densities: with σa = 0 the
        // weight of any path in any channel is at most 3.
        let medium = Medium {
            absorption_per_mm: Rgb::ZERO,
            scattering_per_mm: Rgb::new(0.05, 0.2, 0.6),
            anisotropy: 0.0,
        };
        let mut rng = crate::sampling::Rng::new(4, 2);
        for _ in 0..2000 {
            let mut path = SpectralPath::new(((rng.next_f64() * 3.0) as usize).min(2));
            let mut weight = Rgb::ONE;
            for _ in 0..40 {
                let flight =
                    sample_free_flight(&medium, 1.0 + rng.next_f64(), path.hero, rng.next_f64());
                weight *= path.weigh(&flight);
                assert!(weight.max_element() <= 3.0 + 1e-9, "{weight}");
            }
        }
    }
}
