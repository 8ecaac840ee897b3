//! The boundary of a translucent body: a dielectric interface between air
//! and the stone (eqs. 3.1–3.2).

use glam::DVec3;

use crate::brdf::fresnel;

/// Where a ray goes at a smooth dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Crossing {
    /// The new unit direction.
    pub(crate) direction: DVec3,
    /// True when it refracted through the interface, false when it
    /// reflected (by the Fresnel draw, or by total internal reflection).
    pub(crate) refracted: bool,
    /// True when the ray arrived from the outside (against the normal).
    pub(crate) from_outside: bool,
}

/// The ray `direction` (unit) meeting a smooth interface of outward unit
/// `normal` between air (outside) and a body of index `ior`: reflected with
/// the Fresnel reflectance F (eq. 3.1), which is 1 under total internal
/// reflection, else refracted by Snell's law (eq. 3.2), chosen by `u` in
/// [0, 1). Each choice is taken with its own probability, so the weight is
/// 1 either way; the radiance scale (η²) of refraction cancels between the
/// way in and the way out of the body.
pub(crate) fn cross_smooth_interface(
    direction: DVec3,
    normal: DVec3,
    ior: f64,
    u: f64,
) -> Crossing {
    let cos_outside = -direction.dot(normal);
    let from_outside = cos_outside > 0.0;
    // The normal on the side the ray comes from, the cosine to it and
    // η = n_transmitted / n_incident.
    let (facing, cos_i, eta) = if from_outside {
        (normal, cos_outside, ior)
    } else {
        (-normal, -cos_outside, 1.0 / ior)
    };
    let reflected = || Crossing {
        direction: (direction + 2.0 * cos_i * facing).normalize(),
        refracted: false,
        from_outside,
    };
    if u < fresnel::dielectric(cos_i, eta) {
        return reflected();
    }
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return reflected(); // total internal reflection
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Crossing {
        direction: (direction / eta + (cos_i / eta - cos_t) * facing).normalize(),
        refracted: true,
        from_outside,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_smooth_interface_refracts_by_snell_and_reflects_by_fresnel() {
        let ior = 1.54;
        let normal = DVec3::new(0.2, -0.1, 1.0).normalize();
        for theta_deg in [0.0f64, 20.0, 45.0, 70.0, 85.0] {
            let (sin, cos) = theta_deg.to_radians().sin_cos();
            let (t, _) = normal.any_orthonormal_pair();
            let towards = -(normal * cos + t * sin); // arriving from outside
                                                     // u = 1 − ε always refracts (F < 1 from outside): Snell's law,
                                                     // n₁ sinθ₁ = n₂ sinθ₂, in the plane of incidence.
            let inward = cross_smooth_interface(towards, normal, ior, 1.0 - 1e-12);
            assert!(inward.refracted && inward.from_outside);
            let sin_t = inward.direction.cross(-normal).length();
            assert!(
                (sin - ior * sin_t).abs() < 1e-12,
                "θ {theta_deg}: {sin} vs {}",
                ior * sin_t
            );
            assert!(inward.direction.dot(normal) < 0.0, "goes in");
            // Reflection frequency over u ∈ [0, 1) is F(θ) (eq. 3.1).
            let n = 10_000;
            let reflected = (0..n)
                .filter(|i| {
                    let u = (f64::from(*i) + 0.5) / f64::from(n);
                    !cross_smooth_interface(towards, normal, ior, u).refracted
                })
                .count();
            let f = fresnel::dielectric(cos, ior);
            assert!(
                (reflected as f64 / f64::from(n) - f).abs() < 2e-4,
                "θ {theta_deg}"
            );
            // Back out along the reversed refracted ray: the same angle.
            let out = cross_smooth_interface(-inward.direction, normal, ior, 1.0 - 1e-12);
            assert!(out.refracted && !out.from_outside);
            assert!((out.direction + towards).length() < 1e-12, "reversible");
        }
        // Beyond the critical angle, inside: always reflected, mirror-like.
        let (t, _) = normal.any_orthonormal_pair();
        let grazing = (t * 0.8 + normal * 0.6).normalize(); // 53° from the normal
        let inside = cross_smooth_interface(grazing, normal, ior, 0.999);
        assert!(!inside.refracted && !inside.from_outside);
        let mirrored = grazing - 2.0 * grazing.dot(normal) * normal;
        assert!((inside.direction - mirrored).length() < 1e-12);
    }
}
