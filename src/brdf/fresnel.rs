//! Fresnel reflectance (section 3.1.2): dielectric interfaces with any ratio
//! of indices, seen from either side, and conductors with a complex IOR.

use crate::brdf::Rgb;

/// Unpolarised Fresnel reflectance of a dielectric interface.
///
/// `cos_incident` is the cosine between the incident direction and the
/// (micro-)normal on the incident side (its sign is ignored); `eta` is the
/// ratio n_transmitted / n_incident. Returns 1 under total internal
/// reflection (sin θt > 1, Snell's law eq. 3.2).
#[inline]
pub fn dielectric(cos_incident: f64, eta: f64) -> f64 {
    dielectric_from_snell(cos_incident, Snell::at(cos_incident, eta), eta)
}

/// Snell's law (eq. 3.2) at one incident cosine: the part of
/// [`dielectric`] (and of `microfacet::refract`) that does not depend on
/// the polarisation, computed once where a caller needs both.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Snell {
    /// cosθₜ of the transmitted direction; None under total internal
    /// reflection (sin²θₜ ≥ 1).
    pub cos_t: Option<f64>,
}

impl Snell {
    /// Snell's law for incident cosine `cos_incident` (sign ignored) and
    /// `eta` = n_transmitted / n_incident, with [`dielectric`]'s clamp of
    /// the cosine to 1. For 0 < cos ≤ 1 this is also `refract`'s
    /// sin²θₜ = max(1 − cos², 0)/η², and for cos > 1 both give 0.
    #[inline]
    pub fn at(cos_incident: f64, eta: f64) -> Self {
        let cos_i = cos_incident.abs().min(1.0);
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        Snell {
            cos_t: (sin2_t < 1.0).then(|| (1.0 - sin2_t).sqrt()),
        }
    }
}

/// [`dielectric`] given [`Snell::at`]`(cos_incident, eta)`, for callers
/// that need cosθₜ too: the Fresnel equations for the two polarisations,
/// averaged (1 under total internal reflection).
#[inline]
pub(crate) fn dielectric_from_snell(cos_incident: f64, snell: Snell, eta: f64) -> f64 {
    let Some(cos_t) = snell.cos_t else {
        return 1.0;
    };
    let cos_i = cos_incident.abs().min(1.0);
    let r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)
}

/// Cosine of the critical angle for light inside a medium of relative index
/// `eta` = n_outside / n_inside < 1; 0 when there is no critical angle.
#[cfg(test)]
pub(crate) fn critical_cosine(eta: f64) -> f64 {
    if eta >= 1.0 {
        0.0
    } else {
        (1.0 - eta * eta).sqrt()
    }
}

/// Exact unpolarised Fresnel reflectance of a conductor with relative
/// complex index `n + i k` (eq. 3.3), for one wavelength.
///
/// The appendix's `complexFresnelReflector` is an approximation; we use the
/// exact expression so that normal incidence gives ((n−1)² + k²)/((n+1)² + k²).
/// With k = 0 it equals [`dielectric`] for light entering the denser side.
pub(crate) fn conductor_scalar(cos_incident: f64, n: f64, k: f64) -> f64 {
    // The complex amplitudes' norms in real arithmetic (pbrt's
    // FrConductor): with a² + b² = |η² − sin²θ| and a = Re √(η² − sin²θ)
    // (η = n + ik), R⊥ = (a² + b² − 2a cosθ + cos²θ)/(a² + b² + 2a cosθ +
    // cos²θ) and R∥ = R⊥ (cos²θ (a² + b²) − 2a cosθ sin²θ + sin⁴θ)/(cos²θ
    // (a² + b²) + 2a cosθ sin²θ + sin⁴θ): the complex form to 10⁻¹⁴, in
    // two square roots and two divisions instead of three complex ones.
    let cos_i = cos_incident.abs().min(1.0);
    let cos2 = cos_i * cos_i;
    let sin2 = 1.0 - cos2;
    let (n2, k2) = (n * n, k * k);
    let re = n2 - k2 - sin2;
    let a2_plus_b2 = (re * re + 4.0 * n2 * k2).sqrt();
    let a = (0.5 * (a2_plus_b2 + re)).max(0.0).sqrt();
    let two_a_cos = 2.0 * a * cos_i;
    let perpendicular = (a2_plus_b2 + cos2 - two_a_cos) / (a2_plus_b2 + cos2 + two_a_cos);
    let (t3, t4) = (cos2 * a2_plus_b2 + sin2 * sin2, two_a_cos * sin2);
    let parallel = perpendicular * (t3 - t4) / (t3 + t4);
    (0.5 * (perpendicular + parallel)).clamp(0.0, 1.0)
}

/// `conductor_scalar` per RGB channel (R, G, B at 680, 525, 450 nm, table 4.2).
pub fn conductor(cos_incident: f64, n: Rgb, k: Rgb) -> Rgb {
    Rgb::new(
        conductor_scalar(cos_incident, n.x, k.x),
        conductor_scalar(cos_incident, n.y, k.y),
        conductor_scalar(cos_incident, n.z, k.z),
    )
}

/// Normal-incidence reflectance of a conductor, ((n−1)² + k²)/((n+1)² + k²).
pub(crate) fn conductor_normal_incidence(n: f64, k: f64) -> f64 {
    ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A complex number, just enough arithmetic for the Fresnel amplitudes.
    #[derive(Clone, Copy, Debug)]
    struct Complex {
        re: f64,
        im: f64,
    }

    impl Complex {
        fn new(re: f64, im: f64) -> Self {
            Complex { re, im }
        }
        fn add(self, o: Complex) -> Complex {
            Complex::new(self.re + o.re, self.im + o.im)
        }
        fn sub(self, o: Complex) -> Complex {
            Complex::new(self.re - o.re, self.im - o.im)
        }
        fn mul(self, o: Complex) -> Complex {
            Complex::new(
                self.re * o.re - self.im * o.im,
                self.re * o.im + self.im * o.re,
            )
        }
        fn scale(self, s: f64) -> Complex {
            Complex::new(self.re * s, self.im * s)
        }
        fn norm_sqr(self) -> f64 {
            self.re * self.re + self.im * self.im
        }
        fn div(self, o: Complex) -> Complex {
            let d = o.norm_sqr();
            Complex::new(
                (self.re * o.re + self.im * o.im) / d,
                (self.im * o.re - self.re * o.im) / d,
            )
        }
        /// Principal square root (non-negative real part).
        fn sqrt(self) -> Complex {
            let r = self.norm_sqr().sqrt();
            let re = (0.5 * (r + self.re)).max(0.0).sqrt();
            let im = (0.5 * (r - self.re)).max(0.0).sqrt();
            Complex::new(re, if self.im < 0.0 { -im } else { im })
        }
    }

    #[test]
    fn conductor_reflectance_equals_the_complex_amplitudes() {
        // Eq. 3.3 written with complex amplitudes: cos θt = √(1 − sin²θ/η²)
        // (principal root), r∥ = (η cosθ − cosθt)/(η cosθ + cosθt), r⊥ =
        // (cosθ − η cosθt)/(cosθ + η cosθt), R = (|r∥|² + |r⊥|²)/2: the
        // real-arithmetic form within 10⁻¹³ (relative) at every angle, for
        // the library's metals (table 4.2), dielectrics from both sides
        // (total internal reflection included) and an absorbing glass.
        let amplitudes = |cos_i: f64, n: f64, k: f64| {
            let eta = Complex::new(n, k);
            let sin2_t = Complex::new(1.0 - cos_i * cos_i, 0.0).div(eta.mul(eta));
            let cos_t = Complex::new(1.0, 0.0).sub(sin2_t).sqrt();
            let ci = Complex::new(cos_i, 0.0);
            let r_parallel = eta.scale(cos_i).sub(cos_t).div(eta.scale(cos_i).add(cos_t));
            let r_perpendicular = ci.sub(eta.mul(cos_t)).div(ci.add(eta.mul(cos_t)));
            (0.5 * (r_parallel.norm_sqr() + r_perpendicular.norm_sqr())).clamp(0.0, 1.0)
        };
        let metals = [
            (0.27, 3.4),
            (0.155, 3.6),
            (1.1, 2.6),
            (0.18, 3.0),
            (2.9, 3.1),
            (1.5, 0.0),
            (1.0 / 1.5, 0.0),
            (1.5, 0.01),
        ];
        for (n, k) in metals {
            for i in 0..=2000 {
                let cos_i = f64::from(i) / 2000.0;
                let (real, complex) = (conductor_scalar(cos_i, n, k), amplitudes(cos_i, n, k));
                assert!(
                    (real - complex).abs() <= 1e-13 * complex.max(1e-300),
                    "n {n}, k {k}, cos {cos_i}: {real} against {complex}"
                );
            }
        }
    }

    #[test]
    fn dielectric_normal_incidence_matches_closed_form() {
        for eta in [1.0f64, 1.31, 1.5, 1.7, 2.0, 1.0 / 1.5] {
            let expected = ((eta - 1.0) / (eta + 1.0)).powi(2);
            assert!((dielectric(1.0, eta) - expected).abs() < 1e-12, "eta {eta}");
        }
    }

    #[test]
    fn dielectric_from_snell_equals_dielectric_bit_for_bit() {
        // Against the unpolarised Fresnel equations written out in one
        // piece, including cosines a rounding step above 1 (clamped), 0,
        // negative (sign ignored) and past the critical angle (η < 1: F = 1).
        let dielectric = |cos_incident: f64, eta: f64| {
            let cos_i = cos_incident.abs().min(1.0);
            let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
            if sin2_t >= 1.0 {
                return 1.0;
            }
            let cos_t = (1.0 - sin2_t).sqrt();
            let r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
            let r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
            0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)
        };
        let mut rng = crate::sampling::Rng::new(21, 22);
        for eta in [1.0, 1.31, 1.5, 2.4, 1.0 / 1.5, 0.8] {
            let mut cosines = vec![0.0, 1.0, 1.0 + f64::EPSILON, -0.3];
            cosines.extend((0..20_000).map(|_| rng.next_f64()));
            for cos in cosines {
                let snell = Snell::at(cos, eta);
                assert_eq!(
                    dielectric_from_snell(cos, snell, eta).to_bits(),
                    dielectric(cos, eta).to_bits(),
                    "η {eta} cos {cos}"
                );
                assert_eq!(
                    super::dielectric(cos, eta).to_bits(),
                    dielectric(cos, eta).to_bits(),
                    "η {eta} cos {cos}"
                );
            }
        }
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        // Glass to air: critical angle asin(1/1.5) = 41.81°.
        let eta = 1.0 / 1.5;
        let critical = (1.0f64 / 1.5).asin();
        assert!(dielectric((critical + 1e-3).cos(), eta) == 1.0);
        assert!(dielectric((critical - 1e-2).cos(), eta) < 1.0);
        assert!((critical_cosine(eta) - critical.cos()).abs() < 1e-12);
    }

    #[test]
    fn dielectric_is_the_same_from_both_sides_along_refracted_pairs() {
        // Stokes relations: R(θ1, n1→n2) = R(θ2, n2→n1) for a refracted pair.
        for deg in [0.0f64, 20.0, 40.0, 60.0, 80.0] {
            let ci = deg.to_radians().cos();
            let sin_t = deg.to_radians().sin() / 1.5;
            let ct = (1.0 - sin_t * sin_t).sqrt();
            assert!((dielectric(ci, 1.5) - dielectric(ct, 1.0 / 1.5)).abs() < 1e-12);
        }
    }

    #[test]
    fn conductor_with_zero_k_is_a_dielectric() {
        for deg in [0.0f64, 30.0, 60.0, 89.0] {
            let c = deg.to_radians().cos();
            assert!((conductor_scalar(c, 1.5, 0.0) - dielectric(c, 1.5)).abs() < 1e-12);
        }
    }

    #[test]
    fn conductor_grazing_incidence_reflects_everything() {
        assert!((conductor_scalar(0.0, 0.14, 4.44) - 1.0).abs() < 1e-9);
    }
}
