//! One-sample Kolmogorov–Smirnov test.
//!
//! Where the χ² test of [`super::chi2`] bins directions, scalar quantities
//! with a known continuous distribution (a sampled `cosθ`, a Fresnel-weighted
//! lobe choice, a free-flight distance) are better tested without binning:
//! the KS statistic is the largest distance between the empirical CDF of the
//! samples and the claimed CDF, and its distribution under the null
//! hypothesis does not depend on that CDF.

/// The result of a Kolmogorov–Smirnov test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KsOutcome {
    /// `D_n = sup_x |F_n(x) − F(x)|`, the largest gap between the empirical
    /// and the claimed CDF (in `[0, 1]`).
    pub statistic: f64,
    /// Asymptotic probability of a gap at least as large under the
    /// hypothesis that the samples are drawn from `F` (see [`ks_test`]).
    pub p_value: f64,
    /// Number of samples.
    pub n: usize,
}

impl KsOutcome {
    /// `true` when the test does not reject the hypothesis at level
    /// `significance`, i.e. `p_value >= significance`.
    pub fn passes(&self, significance: f64) -> bool {
        self.p_value >= significance
    }
}

/// One-sample Kolmogorov–Smirnov test of `samples` against the continuous
/// CDF `cdf`.
///
/// The samples are sorted in place. With `x_(1) ≤ … ≤ x_(n)` the statistic is
/// `D_n = max_i max(i/n − F(x_(i)), F(x_(i)) − (i−1)/n)`.
///
/// The p-value is the asymptotic Kolmogorov distribution
/// `Q_KS(λ) = 2 Σ_{k≥1} (−1)^{k−1} exp(−2k²λ²)` evaluated at
/// `λ = (√n + 0.12 + 0.11/√n)·D_n`, Stephens' (1970) finite-`n` correction as
/// used by Numerical Recipes, which makes it accurate to a few per cent
/// already for `n ≳ 5`. For `λ < 1.18` the alternating series converges
/// slowly, so its Jacobi-theta dual
/// `1 − Q_KS(λ) = (√(2π)/λ) Σ_{k≥1} exp(−(2k−1)²π²/(8λ²))` is summed instead.
///
/// A NaN sample (or a CDF returning NaN) yields `statistic = 1`,
/// `p_value = 0`: a sampler producing NaN is broken whatever its distribution.
///
/// # Panics
/// If `samples` is empty.
pub fn ks_test(samples: &mut [f64], cdf: impl Fn(f64) -> f64) -> KsOutcome {
    let n = samples.len();
    assert!(n > 0, "ks_test: no samples");
    samples.sort_by(f64::total_cmp);
    let nf = n as f64;
    let mut d: f64 = 0.0;
    for (i, &x) in samples.iter().enumerate() {
        let f = cdf(x);
        if f.is_nan() || x.is_nan() {
            return KsOutcome {
                statistic: 1.0,
                p_value: 0.0,
                n,
            };
        }
        let f = f.clamp(0.0, 1.0);
        d = d.max((i + 1) as f64 / nf - f).max(f - i as f64 / nf);
    }
    let sqrt_n = nf.sqrt();
    let lambda = (sqrt_n + 0.12 + 0.11 / sqrt_n) * d;
    KsOutcome {
        statistic: d,
        p_value: kolmogorov_sf(lambda),
        n,
    }
}

/// Survival function `Q_KS(λ) = P(K > λ)` of the Kolmogorov distribution
/// (the limit law of `√n·D_n`).
pub fn kolmogorov_sf(lambda: f64) -> f64 {
    use std::f64::consts::PI;
    if lambda <= 0.0 {
        return 1.0;
    }
    if lambda < 1.18 {
        // 1 − Q = √(2π)/λ Σ exp(−(2k−1)² π² / (8λ²)).
        let a = -PI * PI / (8.0 * lambda * lambda);
        let mut cdf = 0.0;
        for k in 1..=50 {
            let j = (2 * k - 1) as f64;
            let term = (a * j * j).exp();
            cdf += term;
            if term < 1e-17 * cdf {
                break;
            }
        }
        (1.0 - (2.0 * PI).sqrt() / lambda * cdf).clamp(0.0, 1.0)
    } else {
        // Q = 2 Σ (−1)^(k−1) exp(−2k²λ²); terms decay faster than e^(−2.7 k²).
        let mut q = 0.0;
        let mut sign = 1.0;
        for k in 1..=50 {
            let kf = k as f64;
            let term = (-2.0 * kf * kf * lambda * lambda).exp();
            q += sign * term;
            sign = -sign;
            if term < 1e-17 * q.abs() || term == 0.0 {
                break;
            }
        }
        (2.0 * q).clamp(0.0, 1.0)
    }
}
