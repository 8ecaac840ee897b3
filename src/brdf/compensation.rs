//! Energy between layers: the multiple-scattering compensation lobe.
//!
//! The model of the notes lets light cross each layer once ("light travels
//! only once between layers", table 2.1), so a white Lambert base under a
//! clear IOR 1.5 coat reflects ≈ 0.43 of the light instead of ≈ 1: the
//! light reflected back down by the inside of the coat is lost. For a
//! diffuse base the missing series is ρ/(1 − ρ·F_dr); for rough and metallic
//! stacks it has no closed form.
//!
//! In the manner of Kulla & Conty (2017) we tabulate albedos when the
//! material is compiled: E_single(μ), the directional albedo of the
//! single-crossing model, and E_stack(μ), the albedo of the physical stack
//! from the random walk of [`crate::brdf::reference`] (the way Kulla & Conty's
//! tables are themselves Monte Carlo integrals). The deficit
//! D(μ) = E_stack − E_single is split into its positive part P (energy the
//! single crossing loses) and negative part X (energy it invents, e.g. at
//! grazing angles through rough coats, where the appendix's t term lets
//! shadowed light pass), each returned by a reciprocal lobe
//!
//! f_ms(ωᵢ, ωₒ) = P(μᵢ)·P(μₒ)/(π·P̄) − X(μᵢ)·X(μₒ)/(π·X̄),   P̄ = 2∫P(μ)μ dμ,
//!
//! whose albedo at every angle is exactly P(μ) − X(μ) = D(μ) (Kulla & Conty,
//! eq. 3, with 1 − E replaced by the deficit), per colour channel. The sum
//! with the single-crossing BRDF is clamped at zero by the caller.

use crate::brdf::reference::{reference_albedo_with, WalkTables};
use crate::brdf::stack::LayeredBrdf;
use crate::brdf::Rgb;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::FRAC_1_PI;

/// Number of nodes of the albedo tables, uniform in θ (θ_k = (k + ½)·90°/N)
/// so that the steep grazing end is resolved (3.75° apart).
pub const TABLE_NODES: usize = 24;

/// Cosine of table node `k`.
pub fn node_cosine(k: usize) -> f64 {
    ((k as f64 + 0.5) / TABLE_NODES as f64 * std::f64::consts::FRAC_PI_2).cos()
}
/// Random walks per node for E_stack (standard error ≲ 0.003 for the library).
const WALKS_PER_NODE: usize = 8192;
/// Stratified samples per node for E_single (a 64 × 64 grid).
const SINGLE_SAMPLES_SIDE: usize = 64;

/// The tabulated deficit of a material and its cosine-weighted average.
#[derive(Clone, Debug, PartialEq)]
pub struct Compensation {
    /// D(μ_k) = E_stack − E_single per channel at the nodes of [`node_cosine`] (signed).
    pub deficit: Vec<Rgb>,
    /// P̄ = 2∫P(μ)μ dμ of the interpolated positive part, per channel.
    pub positive_average: Rgb,
    /// X̄ = 2∫X(μ)μ dμ of the interpolated negative part, per channel.
    pub negative_average: Rgb,
    /// E_single(μ_k), kept for diagnostics (`lapidary brdf --albedo`).
    pub single_albedo: Vec<Rgb>,
    /// E_stack(μ_k) from the random walk, kept for diagnostics.
    pub stack_albedo: Vec<Rgb>,
    /// D at s = √(1 − μ) = j/[`COSINE_NODES`], j = 0…N, resampled from the
    /// θ-table so that a lookup is a square root and a lerp instead of an
    /// `acos` (the lobe is looked up several times per BRDF sample in the
    /// renderer). s ≈ θ/√2 near the normal and ≈ 1 − μ/2 at grazing, so the
    /// table is as even in θ as the original.
    deficit_by_cosine: Vec<Rgb>,
}

/// Intervals of the lookup table in s = √(1 − μ) (0.16° to 0.22° apart);
/// its linear interpolation departs from the θ-interpolant only next to the
/// interpolant's kinks (every 3.75°), by ~10⁻³: a third of the tables' own
/// Monte Carlo noise (3·10⁻³, see [`Compensation::compute`]).
const COSINE_NODES: usize = 512;

/// D(μ) interpolated piecewise linearly in θ between the nodes of
/// [`node_cosine`], constant beyond the end nodes.
fn interpolate_in_theta(deficit: &[Rgb], mu: f64) -> Rgb {
    let n = deficit.len();
    let theta = mu.clamp(0.0, 1.0).acos();
    let x = (theta / std::f64::consts::FRAC_PI_2 * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let k = (x.floor() as usize).min(n - 2);
    let t = x - k as f64;
    deficit[k] * (1.0 - t) + deficit[k + 1] * t
}

/// The direction at cosine `mu` in the x–z plane.
fn direction_at_cosine(mu: f64) -> DVec3 {
    DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu)
}

/// Directional albedo ∫ f(ωᵢ, ωₒ) cosθᵢ dωᵢ of the single-crossing model at
/// outgoing cosine `mu`, by stratified importance sampling.
pub fn single_crossing_albedo(brdf: &LayeredBrdf, mu: f64, seed: u64) -> Rgb {
    let wo = direction_at_cosine(mu);
    let mut rng = crate::sampling::Rng::new(seed, mu.to_bits());
    let n = SINGLE_SAMPLES_SIDE;
    let mut sum = Rgb::ZERO;
    for a in 0..n {
        for b in 0..n {
            let u = [
                rng.next_f64(),
                (a as f64 + rng.next_f64()) / n as f64,
                (b as f64 + rng.next_f64()) / n as f64,
            ];
            if let Some((_, weight)) = brdf.sample_single_crossing(wo, u) {
                sum += weight;
            }
        }
    }
    sum / (n * n) as f64
}

impl Compensation {
    /// Tabulate the deficit of `brdf`; None when it is below 3·10⁻³ at every
    /// node (the noise level of the tables).
    pub fn compute(brdf: &LayeredBrdf, seed: u64) -> Option<Self> {
        let tables = WalkTables::new(brdf);
        let rows: Vec<(Rgb, Rgb)> = (0..TABLE_NODES)
            .into_par_iter()
            .map(|k| {
                let mu = node_cosine(k);
                let single = single_crossing_albedo(brdf, mu, seed ^ 0xa1b2);
                let (stack, _) = reference_albedo_with(
                    brdf,
                    &tables,
                    direction_at_cosine(mu),
                    WALKS_PER_NODE,
                    seed ^ k as u64,
                );
                (single, stack.min(Rgb::ONE))
            })
            .collect();
        let single_albedo: Vec<Rgb> = rows.iter().map(|r| r.0).collect();
        let stack_albedo: Vec<Rgb> = rows.iter().map(|r| r.1).collect();
        let deficit: Vec<Rgb> = rows.iter().map(|(s, t)| *t - *s).collect();
        if deficit.iter().all(|d| d.abs().max_element() < 3e-3) {
            return None;
        }
        let deficit_by_cosine = (0..=COSINE_NODES)
            .map(|j| {
                let s = j as f64 / COSINE_NODES as f64;
                interpolate_in_theta(&deficit, 1.0 - s * s)
            })
            .collect();
        let mut table = Compensation {
            deficit,
            deficit_by_cosine,
            positive_average: Rgb::ZERO,
            negative_average: Rgb::ZERO,
            single_albedo,
            stack_albedo,
        };
        // P̄, X̄ = 2∫₀¹ P(μ) μ dμ, 2∫₀¹ X(μ) μ dμ of the interpolant (midpoint rule).
        let steps = 4096;
        for s in 0..steps {
            let mu = (s as f64 + 0.5) / steps as f64;
            let d = table.albedo(mu);
            table.positive_average += d.max(Rgb::ZERO) * (2.0 * mu / steps as f64);
            table.negative_average += (-d).max(Rgb::ZERO) * (2.0 * mu / steps as f64);
        }
        Some(table)
    }

    /// D(μ): the (signed) albedo of the compensation lobe at cosine `mu`
    /// (the θ-table of [`Compensation::deficit`], piecewise linear in θ and
    /// constant beyond the end nodes, resampled finely in μ).
    pub fn albedo(&self, mu: f64) -> Rgb {
        let x = (1.0 - mu.clamp(0.0, 1.0)).sqrt() * COSINE_NODES as f64;
        let j = (x as usize).min(COSINE_NODES - 1);
        let t = x - j as f64;
        self.deficit_by_cosine[j] * (1.0 - t) + self.deficit_by_cosine[j + 1] * t
    }

    /// P(μ), the positive part of the deficit: the albedo the lobe adds.
    pub fn added_albedo(&self, mu: f64) -> Rgb {
        self.albedo(mu).max(Rgb::ZERO)
    }

    /// f_ms(ωᵢ, ωₒ) = P(μᵢ)P(μₒ)/(πP̄) − X(μᵢ)X(μₒ)/(πX̄) per channel (signed).
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> Rgb {
        let (di, d_o) = (self.albedo(wi.z), self.albedo(wo.z));
        let positive = di.max(Rgb::ZERO) * d_o.max(Rgb::ZERO);
        let negative = (-di).max(Rgb::ZERO) * (-d_o).max(Rgb::ZERO);
        (per_channel_div(positive, self.positive_average)
            - per_channel_div(negative, self.negative_average))
            * FRAC_1_PI
    }
}

fn per_channel_div(a: Rgb, b: Rgb) -> Rgb {
    Rgb::new(safe_div(a.x, b.x), safe_div(a.y, b.y), safe_div(a.z, b.z))
}

fn safe_div(a: f64, b: f64) -> f64 {
    if b > 1e-12 {
        a / b
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cosine_table_follows_the_theta_interpolant() {
        let brdf = crate::recipe::load_material("sugar").unwrap();
        let c = brdf.compensation.as_ref().expect("sugar is compensated");
        let range = c
            .deficit
            .iter()
            .fold(0.0f64, |m, d| m.max(d.abs().max_element()));
        assert!(range > 0.1, "a real deficit to compare against");
        // Within half the tables' noise level everywhere, and ten times
        // closer on average.
        let (mut worst, mut sum): (f64, f64) = (0.0, 0.0);
        let samples = 10_000;
        for i in 0..=samples {
            let mu = i as f64 / samples as f64;
            let error = (c.albedo(mu) - interpolate_in_theta(&c.deficit, mu)).abs();
            worst = worst.max(error.max_element());
            sum += error.max_element();
        }
        assert!(worst < 1.5e-3, "worst {worst}");
        assert!(
            sum / (samples as f64) < 1.5e-4,
            "mean {}",
            sum / samples as f64
        );
    }
}
