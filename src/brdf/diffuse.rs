//! Diffuse bases: Lambert and Oren-Nayar (appendix `orenNayarReflector`).

use crate::brdf::Rgb;
use glam::DVec3;
use std::f64::consts::{FRAC_1_PI, PI};

/// Lambert's perfectly diffuse BRDF, colour/π.
pub fn lambert(colour: Rgb) -> Rgb {
    colour * FRAC_1_PI
}

/// Oren-Nayar BRDF (no cosine) with slope deviation σ in radians, the full
/// model of the appendix shader (after Larry Gritz): C1, C2, C3 and the
/// colour² interreflection term L2, divided by π so that σ = 0 is Lambert.
///
/// Negative values (possible for large σ at grazing angles when cos Δφ < 0)
/// are clamped to zero, as are the tangents near 90°.
pub fn oren_nayar(colour: Rgb, sigma_rad: f64, wi: DVec3, wo: DVec3) -> Rgb {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return Rgb::ZERO;
    }
    if sigma_rad <= 0.0 {
        return lambert(colour);
    }
    let sigma2 = sigma_rad * sigma_rad;
    let theta_i = wi.z.min(1.0).acos();
    let theta_o = wo.z.min(1.0).acos();
    let alpha = theta_i.max(theta_o);
    let beta = theta_i.min(theta_o).min(1.5);
    let cos_phi_diff = {
        let (pi, po) = (
            DVec3::new(wi.x, wi.y, 0.0).normalize_or_zero(),
            DVec3::new(wo.x, wo.y, 0.0).normalize_or_zero(),
        );
        pi.dot(po)
    };
    let c1 = 1.0 - 0.5 * sigma2 / (sigma2 + 0.33);
    let mut c2 = 0.45 * sigma2 / (sigma2 + 0.09);
    if cos_phi_diff >= 0.0 {
        c2 *= alpha.sin();
    } else {
        c2 *= alpha.sin() - (2.0 * beta / PI).powi(3);
    }
    let c3 = 0.125 * sigma2 / (sigma2 + 0.09) * (4.0 * alpha * beta / (PI * PI)).powi(2);
    let half_sum_tan = ((alpha + beta) / 2.0).min(1.5).tan();
    let l1 = c1 + cos_phi_diff * c2 * beta.tan() + (1.0 - cos_phi_diff.abs()) * c3 * half_sum_tan;
    let l2_scale =
        0.17 * sigma2 / (sigma2 + 0.13) * (1.0 - cos_phi_diff * (2.0 * beta / PI).powi(2));
    let value = (colour * l1.max(0.0) + colour * colour * l2_scale.max(0.0)) * FRAC_1_PI;
    value.max(Rgb::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oren_nayar_sigma_zero_is_lambert() {
        let colour = Rgb::new(0.9, 0.5, 0.1);
        for k in 0..500 {
            let t = k as f64;
            let wi = crate::sampling::direction_from_degrees((t * 7.3) % 89.9, t * 13.1);
            let wo = crate::sampling::direction_from_degrees((t * 3.7) % 89.9, t * 29.7);
            let on = oren_nayar(colour, 0.0, wi, wo);
            assert!((on - lambert(colour)).abs().max_element() < 1e-15);
        }
    }

    #[test]
    fn oren_nayar_is_brighter_towards_the_light_at_grazing_view() {
        // Back-scattering: with σ > 0, viewing from the light's side at grazing
        // angles is brighter than Lambert (Oren & Nayar 1994, figure 7).
        let wi = crate::sampling::direction_from_degrees(60.0, 0.0);
        let wo = crate::sampling::direction_from_degrees(60.0, 0.0);
        let on = oren_nayar(Rgb::ONE, 0.34, wi, wo);
        assert!(on.x > FRAC_1_PI);
    }
}
