//! The multiple-scattering compensation lobe (Kulla & Conty 2017, eq. 3,
//! with 1 − E replaced by the deficit; see [`crate::brdf::compensation`]
//! for how its table is computed): the table of a material's deficit
//! D(μ) = E_stack − E_single, looked up, and the lobe
//! f_ms(ωᵢ, ωₒ) = P(μᵢ)·P(μₒ)/(π·P̄) − X(μᵢ)·X(μₒ)/(π·X̄) it defines.

use crate::brdf::Rgb;
use glam::DVec3;
use std::f64::consts::FRAC_1_PI;

/// Number of nodes of the albedo tables, uniform in θ (θ_k = (k + ½)·90°/N)
/// so that the steep grazing end is resolved (3.75° apart).
pub const TABLE_NODES: usize = 24;

/// Cosine of table node `k`.
pub fn node_cosine(k: usize) -> f64 {
    ((k as f64 + 0.5) / TABLE_NODES as f64 * std::f64::consts::FRAC_PI_2).cos()
}

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
    /// 1/(πP̄) and 1/(πX̄) per channel (0 where the average is below
    /// 10⁻¹², as `safe_div`): the lobe's normalisations as products, for
    /// [`Compensation::at_outgoing`] at every path vertex.
    inverse_pi_averages: (Rgb, Rgb),
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

impl Compensation {
    /// The tables from E_single and E_stack at the [`TABLE_NODES`] nodes
    /// (everything else follows from them deterministically, so a table
    /// stored as these two columns is rebuilt bit for bit, as
    /// `crate::recipe::TableCache` does from disk). None when the deficit is below 3·10⁻³ at
    /// every node, or when the columns are not [`TABLE_NODES`] long.
    pub fn from_albedos(single_albedo: Vec<Rgb>, stack_albedo: Vec<Rgb>) -> Option<Self> {
        if single_albedo.len() != TABLE_NODES || stack_albedo.len() != TABLE_NODES {
            return None;
        }
        let deficit: Vec<Rgb> = single_albedo
            .iter()
            .zip(&stack_albedo)
            .map(|(s, t)| *t - *s)
            .collect();
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
            inverse_pi_averages: (Rgb::ZERO, Rgb::ZERO),
        };
        // P̄, X̄ = 2∫₀¹ P(μ) μ dμ, 2∫₀¹ X(μ) μ dμ of the interpolant (midpoint rule).
        let steps = 4096;
        for s in 0..steps {
            let mu = (s as f64 + 0.5) / steps as f64;
            let d = table.albedo(mu);
            table.positive_average += d.max(Rgb::ZERO) * (2.0 * mu / steps as f64);
            table.negative_average += (-d).max(Rgb::ZERO) * (2.0 * mu / steps as f64);
        }
        let inverse_pi = |average: Rgb| per_channel_div(Rgb::splat(FRAC_1_PI), average);
        table.inverse_pi_averages = (
            inverse_pi(table.positive_average),
            inverse_pi(table.negative_average),
        );
        Some(table)
    }

    /// D(μ): the (signed) albedo of the compensation lobe at cosine `mu`
    /// (the θ-table of [`Compensation::deficit`], piecewise linear in θ and
    /// constant beyond the end nodes, resampled finely in μ).
    pub fn albedo(&self, mu: f64) -> Rgb {
        let x = (1.0 - mu.clamp(0.0, 1.0)).sqrt() * COSINE_NODES as f64;
        // x ∈ [0, N] (or NaN, which casts to 0 either way): the i32 cast
        // is the same index as a usize cast, in fewer instructions.
        let j = (x as i32).min(COSINE_NODES as i32 - 1);
        let t = x - f64::from(j);
        let j = j as usize;
        self.deficit_by_cosine[j] * (1.0 - t) + self.deficit_by_cosine[j + 1] * t
    }

    /// Probability with which a layered BRDF samples this lobe for an
    /// outgoing direction whose table value is D(μₒ) = `d_o`: the mean added
    /// albedo d mapped to d / (d + 0.5), at most one half.
    pub(crate) fn sampling_probability(d_o: Rgb) -> f64 {
        let d = d_o.max(Rgb::ZERO).element_sum() / 3.0;
        (d / (d + 0.5)).min(0.5)
    }

    /// f_ms(ωᵢ, ωₒ) = P(μᵢ)P(μₒ)/(πP̄) − X(μᵢ)X(μₒ)/(πX̄) per channel (signed).
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> Rgb {
        self.at_outgoing(self.albedo(wo.z)).eval(self.albedo(wi.z))
    }

    /// The lobe for an outgoing direction whose table value is D(μₒ) =
    /// `d_o`, so that a path vertex looks D(μₒ) up and scales it once for
    /// all its evaluations (see `BrdfAt`).
    pub(crate) fn at_outgoing(&self, d_o: Rgb) -> CompensationAt {
        CompensationAt {
            positive_o: d_o.max(Rgb::ZERO),
            negative_o: (-d_o).max(Rgb::ZERO),
            inverse_pi_averages: self.inverse_pi_averages,
        }
    }
}

/// The compensation lobe prepared for one outgoing direction:
/// f_ms(ωᵢ) = (P(μᵢ)P(μₒ))/(πP̄) − (X(μᵢ)X(μₒ))/(πX̄) with P(μₒ), X(μₒ)
/// looked up once per path vertex and the normalisations as products.
/// The two table values are multiplied first, so the lobe stays exactly
/// reciprocal.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CompensationAt {
    /// P(μₒ) per channel.
    positive_o: Rgb,
    /// X(μₒ) per channel.
    negative_o: Rgb,
    /// 1/(πP̄) and 1/(πX̄) of the table.
    inverse_pi_averages: (Rgb, Rgb),
}

impl CompensationAt {
    /// f_ms at an incident direction whose table value is D(μᵢ) = `di` (signed).
    #[inline]
    pub fn eval(&self, di: Rgb) -> Rgb {
        let (positive, negative) = self.inverse_pi_averages;
        (di.max(Rgb::ZERO) * self.positive_o) * positive
            - ((-di).max(Rgb::ZERO) * self.negative_o) * negative
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
    fn the_table_lookup_indexes_as_a_usize_cast_would() {
        // `albedo` written out with the saturating usize cast it replaces,
        // over the whole range, the ends and out-of-range cosines.
        let brdf = crate::recipe::load_material("sugar").unwrap();
        let c = brdf.compensation.as_ref().expect("sugar is compensated");
        let reference = |mu: f64| {
            let x = (1.0 - mu.clamp(0.0, 1.0)).sqrt() * COSINE_NODES as f64;
            let j = (x as usize).min(COSINE_NODES - 1);
            let t = x - j as f64;
            c.deficit_by_cosine[j] * (1.0 - t) + c.deficit_by_cosine[j + 1] * t
        };
        let mut cosines = vec![-0.5, 0.0, 1e-300, 1.0 - f64::EPSILON, 1.0, 1.5];
        cosines.extend((0..=100_000).map(|i| i as f64 / 100_000.0));
        for mu in cosines {
            let bits = |v: Rgb| v.to_array().map(f64::to_bits);
            assert_eq!(bits(c.albedo(mu)), bits(reference(mu)), "μ {mu}");
        }
    }

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
