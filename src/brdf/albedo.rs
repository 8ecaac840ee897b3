//! Directional albedo: the white-furnace quantity ∫ f(ωᵢ, ωₒ) cosθᵢ dωᵢ.

use crate::brdf::stack::LayeredBrdf;
use crate::brdf::Rgb;
use crate::sampling::Rng;
use glam::DVec3;

/// An albedo estimate with its standard error, per channel.
#[derive(Clone, Copy, Debug)]
pub struct AlbedoEstimate {
    /// Mean of the importance-sampled estimator.
    pub mean: Rgb,
    /// Standard error of the mean.
    pub std_error: Rgb,
    /// Samples used.
    pub samples: usize,
}

/// Directional albedo of the full model at viewing angle `theta_deg`,
/// importance-sampled with a fixed seed, in batches of 4096 (one at
/// least) until the standard error of every channel is below
/// `target_std_error` (or `max_samples` is reached).
///
/// # Panics
///
/// If `theta_deg` is not within [0, 90] degrees (NaN included).
pub fn directional_albedo(
    brdf: &LayeredBrdf,
    theta_deg: f64,
    target_std_error: f64,
    max_samples: usize,
    seed: u64,
) -> AlbedoEstimate {
    assert!(
        (0.0..=90.0).contains(&theta_deg),
        "directional_albedo: theta_deg = {theta_deg}; allowed: 0 to 90 degrees"
    );
    let wo = crate::sampling::direction_from_degrees(theta_deg, 0.0);
    let mut rng = Rng::new(seed, theta_deg.to_bits());
    let (mut sum, mut sum_sq, mut n) = (Rgb::ZERO, Rgb::ZERO, 0usize);
    loop {
        for _ in 0..4096 {
            let w = brdf
                .sample(wo, rng.next_3())
                .map(|s| s.weight())
                .unwrap_or(Rgb::ZERO);
            sum += w;
            sum_sq += w * w;
        }
        n += 4096;
        let mean = sum / n as f64;
        let var = (sum_sq / n as f64 - mean * mean).max(Rgb::ZERO);
        let std_error = (var / n as f64).map(f64::sqrt);
        if std_error.max_element() <= target_std_error || n >= max_samples {
            return AlbedoEstimate {
                mean,
                std_error,
                samples: n,
            };
        }
    }
}

/// The incidence angles of `lapidary brdf --albedo`: 0, 5, … 85 degrees.
pub fn albedo_angles_deg() -> impl Iterator<Item = f64> {
    (0..18).map(|k| k as f64 * 5.0)
}

/// Direction at `theta_deg` from the normal in the x–z plane.
pub fn in_plane(theta_deg: f64) -> DVec3 {
    crate::sampling::direction_from_degrees(theta_deg, 0.0)
}

/// The in-plane slice f(ωᵢ, ωₒ)·cosθₒ for light at `theta_i_deg` on the
/// φ = 180° side, at signed outgoing angles `theta_o_deg` (negative: on the
/// light's side), each the model's value at that one direction (what
/// `lapidary brdf --slice` prints and the polar plots draw).
pub fn in_plane_slice(brdf: &LayeredBrdf, theta_i_deg: f64, theta_o_deg: &[f64]) -> Vec<Rgb> {
    let wi = crate::sampling::direction_from_degrees(theta_i_deg, 180.0);
    theta_o_deg
        .iter()
        .map(|&t| {
            let wo =
                crate::sampling::direction_from_degrees(t.abs(), if t < 0.0 { 180.0 } else { 0.0 });
            brdf.eval(wi, wo) * wo.z
        })
        .collect()
}
