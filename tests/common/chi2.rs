//! Pearson χ² goodness-of-fit test for direction samplers.
//!
//! This follows the methodology of the χ² sampling tests of pbrt-v4
//! (`Chi2Test` in `src/pbrt/bsdfs_test.cpp`) and Mitsuba 3
//! (`mitsuba.chi2.ChiSquareTest`):
//!
//! 1. Draw many directions from the sampler under test and histogram them over
//!    a grid of cells covering the whole sphere.
//! 2. Integrate the density the sampler *claims* over every cell, accurately,
//!    to get the expected count of each cell.
//! 3. Sort cells by expected count and pool the cells whose expected count is
//!    too small for the χ² approximation (below 5) into one cell.
//! 4. Compare observed against expected with Pearson's statistic and turn it
//!    into a p-value with the χ² distribution with `cells − 1` degrees of
//!    freedom.
//!
//! A sample landing in a cell that the density says is (numerically)
//! impossible is an immediate failure, as in both references: no amount of
//! statistics excuses a sampler that produces directions of zero density.
//! "Numerically impossible" means an expected count below 1e−8·n, limited to
//! the emptiest cells whose expected counts sum to at most 1e−4, so that a
//! correct sampler fails this way with probability at most 1e−4 (see
//! [`Chi2Options`]); pbrt-v4 and Mitsuba 3 use exactly-zero expected counts.
//!
//! The grid is regular in `(cosθ, φ)` with `θ` measured from +z, like
//! Mitsuba's spherical domain (pbrt bins in `θ` instead). Since
//! `dω = dcosθ dφ`, every cell has the same solid angle and the integral of a
//! solid-angle density over a cell is a plain 2-D integral over a rectangle,
//! which [`Quadrature`] evaluates with adaptive tensor-product
//! Gauss–Legendre rules (pbrt-v4 uses nested adaptive Simpson over `(θ, φ)`,
//! Mitsuba 3 a trapezoid rule on a fixed sub-grid of each cell).
//!
//! Randomness comes from a small internal SplitMix64 generator, so a test with
//! a fixed seed is reproducible bit for bit and independent of any `rand`
//! version.

use std::f64::consts::{PI, TAU};
use std::fmt;

use glam::DVec3;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The result of a χ² goodness-of-fit test.
///
/// `p_value` is the probability, under the hypothesis that the sampler draws
/// exactly from the claimed density, of a statistic at least as large as the
/// one observed. A correct sampler gives p-values uniform on `[0, 1]`, so a
/// test *fails* when `p_value` falls below a chosen significance level (see
/// [`Chi2Outcome::passes`] and [`sidak`]).
#[derive(Clone, Debug)]
pub struct Chi2Outcome {
    /// Pearson's statistic `Σ (observed − expected)² / expected` over the
    /// cells left after pooling (0 when the test failed immediately).
    pub statistic: f64,
    /// Degrees of freedom: number of cells after pooling, minus one.
    pub dof: usize,
    /// Upper-tail probability of `statistic` under χ²(`dof`); exactly 0 for an
    /// immediate failure (see [`Chi2Outcome::failure`]), 1 when `dof` is 0.
    pub p_value: f64,
    /// Number of histogram cells (including the "failed sample" cell) that
    /// were merged into the pooled low-expectation cell; cells treated as
    /// impossible (see [`Chi2Options::impossible_budget`]) are not counted.
    pub pooled_cells: usize,
    /// Number of times the sampler was called.
    pub samples_taken: usize,
    /// Number of calls that returned `None` (a failed sample).
    pub samples_failed: usize,
    /// Integral of the claimed density over the whole sphere. It is 1 for a
    /// sampler that never fails; a sampler that fails with probability `q`
    /// must claim a density integrating to `1 − q`, and the failed samples are
    /// tested as one more cell with expected count `n·(1 − pdf_integral)`.
    pub pdf_integral: f64,
    /// The unpooled cell with the largest standardized residual
    /// `|observed − expected| / √expected`, to help locate a bug.
    pub worst_cell: Option<CellResidual>,
    /// Why the test failed without computing a statistic (`p_value == 0`):
    /// a sample in an impossible cell, an invalid direction, or an invalid
    /// density. `None` for an ordinary χ² result.
    pub failure: Option<String>,
}

/// Observed and expected counts of one histogram cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellResidual {
    /// Index of the `cosθ` bin (0 is `cosθ ∈ [−1, −1 + 2/cos_bins)`).
    pub cos_bin: usize,
    /// Index of the `φ` bin (0 is `φ ∈ [0, 2π/phi_bins)`).
    pub phi_bin: usize,
    /// Number of samples that landed in the cell.
    pub observed: f64,
    /// `n_samples × ∫_cell pdf dω`.
    pub expected: f64,
}

impl CellResidual {
    /// Standardized residual `(observed − expected) / √expected`; about
    /// standard normal per cell for a correct sampler.
    pub fn residual(&self) -> f64 {
        (self.observed - self.expected) / self.expected.sqrt()
    }
}

impl Chi2Outcome {
    /// `true` when the test does not reject the sampler at level
    /// `significance`, i.e. `p_value >= significance`.
    ///
    /// For several tests in one suite, pass a per-test level from [`sidak`] so
    /// that the whole suite keeps a bounded false-alarm rate.
    pub fn passes(&self, significance: f64) -> bool {
        self.p_value >= significance
    }
}

impl fmt::Display for Chi2Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "chi2 = {:.4} (dof {}), p = {:.4e}, pooled {} cells, {} samples ({} failed), \
             pdf integral {:.8}",
            self.statistic,
            self.dof,
            self.p_value,
            self.pooled_cells,
            self.samples_taken,
            self.samples_failed,
            self.pdf_integral
        )?;
        if let Some(c) = &self.worst_cell {
            write!(
                f,
                ", worst cell (cos {}, phi {}): observed {} expected {} (residual {:+.2})",
                c.cos_bin,
                c.phi_bin,
                c.observed,
                if c.expected >= 0.01 {
                    format!("{:.2}", c.expected)
                } else {
                    format!("{:.3e}", c.expected)
                },
                c.residual()
            )?;
        }
        if let Some(why) = &self.failure {
            write!(f, ", FAILED: {why}")?;
        }
        Ok(())
    }
}

/// Šidák correction: the per-test significance `1 − (1 − alpha)^(1/n_tests)`
/// such that `n_tests` independent tests, each run at that level, reject a
/// correct sampler with probability `alpha` in total (the family-wise error
/// rate).
///
/// Both pbrt-v4 and Mitsuba 3 run many χ² tests (one per material and
/// incident direction) and apply this correction so that a suite of correct
/// samplers does not fail by chance more often than `alpha`.
///
/// # Panics
/// If `n_tests` is 0 or `alpha` is outside `[0, 1]`.
pub fn sidak(alpha: f64, n_tests: usize) -> f64 {
    assert!(n_tests > 0, "sidak: n_tests must be positive");
    assert!(
        (0.0..=1.0).contains(&alpha),
        "sidak: alpha must be in [0, 1]"
    );
    // -expm1(ln1p(-alpha) / n) == 1 - (1 - alpha)^(1/n), without cancellation.
    -((-alpha).ln_1p() / n_tests as f64).exp_m1()
}

/// Accuracy settings for integrating a density over one histogram cell.
///
/// Each cell is first split into `sub_grid × sub_grid` panels; each panel is
/// integrated with an `order × order` tensor Gauss–Legendre rule and compared
/// with the sum over its four quadrants; panels where the two disagree by more
/// than the tolerance are bisected recursively, up to `max_depth` times. The
/// initial sub-grid guards against lobes narrow enough to slip between the
/// nodes of a single panel (adaptive schemes cannot refine what they never
/// see); the adaptivity then resolves peaks and the discontinuity at the
/// horizon without a uniformly fine grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadrature {
    /// Panels per axis per cell before any adaptive refinement (≥ 1).
    pub sub_grid: usize,
    /// Gauss–Legendre points per axis per panel (≥ 1); exact for
    /// polynomials of degree `2·order − 1` in each variable.
    pub order: usize,
    /// Maximum number of recursive bisections of a panel.
    pub max_depth: u32,
    /// Target absolute error of the integral over one cell, in probability
    /// units (multiply by `n_samples` for the error of an expected count).
    pub abs_tolerance: f64,
}

impl Default for Quadrature {
    /// 3×3 panels of 7×7 Gauss–Legendre points, depth ≤ 8, tolerance 1e-11
    /// per cell: expected counts accurate to ~1e-5 samples at 10⁶ samples
    /// for smooth densities, and Phong-like lobes with exponents in the
    /// thousands on a 10×20 grid integrate to 1 within ~1e-9.
    fn default() -> Self {
        Quadrature {
            sub_grid: 3,
            order: 7,
            max_depth: 8,
            abs_tolerance: 1e-11,
        }
    }
}

/// Settings of [`chi2_directions_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chi2Options {
    /// How the expected count of each cell is integrated.
    pub quadrature: Quadrature,
    /// Cells with a smaller expected count are pooled (the usual rule of
    /// thumb for the validity of the χ² approximation is 5, used by pbrt and
    /// Mitsuba alike).
    pub min_expected: f64,
    /// A cell whose expected count is below `impossible_fraction × n_samples`
    /// may be treated as impossible: a single sample in it fails the test
    /// (subject to `impossible_budget`).
    pub impossible_fraction: f64,
    /// Bound on the chance that a *correct* sampler fails through the
    /// impossible-cell rule. A correct sampler hits a set of cells with
    /// probability at most their total expected count, so only the
    /// lowest-expectation cells whose expected counts add up to at most this
    /// budget are treated as impossible; any other cell below
    /// `impossible_fraction × n_samples` is pooled like any small cell.
    ///
    /// Without the budget, the thin tail of a peaky lobe (rows of cells each
    /// expecting ~10⁻³ samples) would fail a correct sampler several per cent
    /// of the time. Cells of exactly zero density always stay impossible.
    pub impossible_budget: f64,
    /// Largest accepted `| |d| − 1 |` of a sampled direction; anything else
    /// (including non-finite components) fails the test.
    pub unit_tolerance: f64,
}

impl Default for Chi2Options {
    /// Default quadrature, pooling below 5, impossible below 1e-8·n within a
    /// false-alarm budget of 1e-4, unit length within 1e-6.
    fn default() -> Self {
        Chi2Options {
            quadrature: Quadrature::default(),
            min_expected: 5.0,
            impossible_fraction: 1e-8,
            impossible_budget: 1e-4,
            unit_tolerance: 1e-6,
        }
    }
}

/// Goodness of fit of a direction sampler against the density it claims
/// (w.r.t. solid angle) over the whole sphere, with default [`Chi2Options`].
///
/// * `sample` maps three independent uniform numbers in `[0, 1)` to a unit
///   direction, or `None` for a failed sample (counted in `samples_failed`).
/// * `pdf` is the claimed solid-angle density; it must be finite and
///   non-negative everywhere, and zero where the sampler never goes.
/// * The histogram has `cos_bins × phi_bins` cells, regular in
///   `cosθ ∈ [−1, 1]` and `φ ∈ [0, 2π)`. With an even `cos_bins` the
///   horizon (`cosθ = 0`), where BSDF densities are discontinuous, is a cell
///   boundary: the quadrature is then fast and exact, and the rows just
///   below the horizon have zero expected count, so any leak below it fails
///   (even one from rounding, e.g. `z = −1e−17`). Mitsuba defaults to an odd
///   resolution for the opposite reason, tolerance of such rounding; here an
///   odd `cos_bins` also works. (A discontinuity inside a cell costs
///   adaptive refinement along it and bounds the accuracy of the expected
///   counts at roughly 1e−7·n with the default [`Quadrature`]; for
///   odd-by-odd panel grids the horizon is a panel midpoint and stays exact.)
/// * `seed` seeds the internal SplitMix64 generator; the test is
///   deterministic for a given seed.
///
/// See the module documentation for the method and [`Chi2Outcome`] for the
/// result.
pub fn chi2_directions(
    sample: impl FnMut([f64; 3]) -> Option<DVec3>,
    pdf: impl Fn(DVec3) -> f64,
    n_samples: usize,
    cos_bins: usize,
    phi_bins: usize,
    seed: u64,
) -> Chi2Outcome {
    chi2_directions_with(
        sample,
        pdf,
        n_samples,
        cos_bins,
        phi_bins,
        seed,
        &Chi2Options::default(),
    )
}

/// [`chi2_directions`] with explicit settings (quadrature accuracy, pooling
/// threshold, impossibility threshold).
///
/// # Panics
/// If `n_samples`, `cos_bins` or `phi_bins` is 0.
pub fn chi2_directions_with(
    mut sample: impl FnMut([f64; 3]) -> Option<DVec3>,
    pdf: impl Fn(DVec3) -> f64,
    n_samples: usize,
    cos_bins: usize,
    phi_bins: usize,
    seed: u64,
    options: &Chi2Options,
) -> Chi2Outcome {
    assert!(n_samples > 0, "chi2_directions: n_samples must be positive");
    assert!(
        cos_bins > 0 && phi_bins > 0,
        "chi2_directions: the grid must have at least one cell"
    );
    let n = n_samples as f64;

    // Expected cell probabilities (check the density before sampling, so a
    // bad density is reported as such).
    let probabilities = cell_integrals(&pdf, cos_bins, phi_bins, &options.quadrature);
    let pdf_integral: f64 = probabilities.iter().sum();

    let mut outcome = Chi2Outcome {
        statistic: 0.0,
        dof: 0,
        p_value: 0.0,
        pooled_cells: 0,
        samples_taken: 0,
        samples_failed: 0,
        pdf_integral,
        worst_cell: None,
        failure: None,
    };
    if let Some(i) = probabilities
        .iter()
        .position(|p| !p.is_finite() || *p < 0.0)
    {
        outcome.failure = Some(format!(
            "the density integrates to {} over cell (cos {}, phi {}); it must be finite and \
             non-negative",
            probabilities[i],
            i / phi_bins,
            i % phi_bins
        ));
        return outcome;
    }

    // Histogram of the sampled directions.
    let mut rng = SplitMix64::new(seed);
    let mut observed = vec![0u64; cos_bins * phi_bins];
    let mut invalid: Option<DVec3> = None;
    for _ in 0..n_samples {
        let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
        outcome.samples_taken += 1;
        match sample(u) {
            None => outcome.samples_failed += 1,
            Some(d) => {
                if !(d.is_finite() && (d.length() - 1.0).abs() <= options.unit_tolerance) {
                    invalid.get_or_insert(d);
                    continue;
                }
                observed[cell_index(d, cos_bins, phi_bins)] += 1;
            }
        }
    }
    if let Some(d) = invalid {
        outcome.failure = Some(format!(
            "the sampler returned a direction that is not a unit vector, e.g. {d:?}"
        ));
        return outcome;
    }

    // Impossible cells: in order of increasing expectation, those below the
    // threshold while their total expected count stays within the budget.
    let impossible = options.impossible_fraction * n;
    let mut order: Vec<usize> = (0..probabilities.len()).collect();
    order.sort_by(|&a, &b| probabilities[a].total_cmp(&probabilities[b]));
    let mut is_impossible = vec![false; probabilities.len()];
    let mut spent = 0.0;
    for &i in &order {
        let e = probabilities[i] * n;
        if e >= impossible || (e > 0.0 && spent + e > options.impossible_budget) {
            break;
        }
        spent += e;
        is_impossible[i] = true;
    }

    // Samples in cells the density calls impossible: immediate failure.
    let mut bad_hits = 0u64;
    let mut first_bad = None;
    for (i, (&o, &p)) in observed.iter().zip(&probabilities).enumerate() {
        if o > 0 && is_impossible[i] {
            bad_hits += o;
            first_bad.get_or_insert(CellResidual {
                cos_bin: i / phi_bins,
                phi_bin: i % phi_bins,
                observed: o as f64,
                expected: p * n,
            });
        }
    }
    if let Some(c) = first_bad {
        outcome.worst_cell = Some(c);
        outcome.failure = Some(format!(
            "{bad_hits} sample(s) landed in cells of (nearly) zero density, first in \
             (cos {}, phi {}) with expected count {:.3e}",
            c.cos_bin, c.phi_bin, c.expected
        ));
        return outcome;
    }

    // Cells as (observed, expected, where); the failed samples are one more
    // cell whose expected count is the density's missing mass.
    let mut cells: Vec<(f64, f64, Option<usize>)> = observed
        .iter()
        .zip(&probabilities)
        .enumerate()
        .filter(|&(i, _)| !is_impossible[i])
        .map(|(i, (&o, &p))| (o as f64, p * n, Some(i)))
        .collect();
    let expected_failed = (n * (1.0 - pdf_integral)).max(0.0);
    if outcome.samples_failed > 0 || expected_failed >= impossible {
        cells.push((outcome.samples_failed as f64, expected_failed, None));
    }

    // Pool as pbrt does: in order of increasing expectation, cells below the
    // threshold go into the pool, and so do further cells until the pool
    // itself reaches the threshold.
    cells.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
    let mut counted = 0usize;
    let mut statistic = 0.0;
    let mut worst: Option<CellResidual> = None;
    for &(o, e, where_) in &cells {
        if e < options.min_expected
            || (outcome.pooled_cells > 0 && pooled_exp < options.min_expected)
        {
            pooled_obs += o;
            pooled_exp += e;
            outcome.pooled_cells += 1;
        } else {
            statistic += (o - e) * (o - e) / e;
            counted += 1;
            if let Some(i) = where_ {
                let c = CellResidual {
                    cos_bin: i / phi_bins,
                    phi_bin: i % phi_bins,
                    observed: o,
                    expected: e,
                };
                if worst.is_none_or(|w| c.residual().abs() > w.residual().abs()) {
                    worst = Some(c);
                }
            }
        }
    }
    if pooled_exp > 0.0 {
        statistic += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        counted += 1;
    } else if pooled_obs > 0.0 {
        // Samples (failed ones, or any with `impossible_fraction` set to 0)
        // where nothing at all is expected.
        statistic = f64::INFINITY;
        counted += 1;
    }

    outcome.statistic = statistic;
    outcome.worst_cell = worst;
    outcome.dof = counted.saturating_sub(1);
    outcome.p_value = if !statistic.is_finite() {
        0.0
    } else if outcome.dof == 0 {
        1.0
    } else {
        ChiSquared::new(outcome.dof as f64)
            .expect("positive degrees of freedom")
            .sf(statistic)
    };
    outcome
}

/// Integral of a solid-angle density over the whole sphere with the default
/// [`Quadrature`], computed cell by cell on the same `(cosθ, φ)` grid that
/// [`chi2_directions`] uses (so cell boundaries, e.g. the horizon for even
/// `cos_bins`, can be aligned with discontinuities of the density).
///
/// A normalized density gives 1; a sampler that fails with probability `q`
/// should claim a density integrating to `1 − q`.
pub fn integrate_pdf_sphere(pdf: impl Fn(DVec3) -> f64, cos_bins: usize, phi_bins: usize) -> f64 {
    integrate_pdf_sphere_with(pdf, cos_bins, phi_bins, &Quadrature::default())
}

/// [`integrate_pdf_sphere`] with explicit quadrature settings.
pub fn integrate_pdf_sphere_with(
    pdf: impl Fn(DVec3) -> f64,
    cos_bins: usize,
    phi_bins: usize,
    quadrature: &Quadrature,
) -> f64 {
    cell_integrals(&pdf, cos_bins, phi_bins, quadrature)
        .iter()
        .sum()
}

/// Index (row-major, `cos_bin * phi_bins + phi_bin`) of the cell holding the
/// unit direction `d`.
fn cell_index(d: DVec3, cos_bins: usize, phi_bins: usize) -> usize {
    let z = d.z.clamp(-1.0, 1.0);
    let ci = (((z + 1.0) * 0.5 * cos_bins as f64) as usize).min(cos_bins - 1);
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += TAU;
    }
    let pj = ((phi / TAU * phi_bins as f64) as usize).min(phi_bins - 1);
    ci * phi_bins + pj
}

/// Integral of `pdf` over each cell, in the order of [`cell_index`].
fn cell_integrals(
    pdf: &impl Fn(DVec3) -> f64,
    cos_bins: usize,
    phi_bins: usize,
    q: &Quadrature,
) -> Vec<f64> {
    assert!(cos_bins > 0 && phi_bins > 0, "the grid must have cells");
    assert!(q.sub_grid > 0 && q.order > 0, "empty quadrature rule");
    let rule = GaussLegendre::new(q.order);
    let f = |z: f64, phi: f64| {
        let s = (1.0 - z * z).max(0.0).sqrt();
        let (sin_phi, cos_phi) = phi.sin_cos();
        pdf(DVec3::new(s * cos_phi, s * sin_phi, z))
    };
    // Panel edges come from integer indices, so neighbouring panels and
    // cells share their edges exactly.
    let k = q.sub_grid;
    let z_edge = |i: usize| -1.0 + 2.0 * i as f64 / (cos_bins * k) as f64;
    let phi_edge = |j: usize| TAU * j as f64 / (phi_bins * k) as f64;
    let panel_tol = q.abs_tolerance / (k * k) as f64;
    let mut out = Vec::with_capacity(cos_bins * phi_bins);
    for ci in 0..cos_bins {
        for pj in 0..phi_bins {
            let mut sum = 0.0;
            for a in ci * k..(ci + 1) * k {
                for b in pj * k..(pj + 1) * k {
                    let panel = (z_edge(a), z_edge(a + 1), phi_edge(b), phi_edge(b + 1));
                    let whole = rule.panel(&f, panel);
                    sum += adaptive(&f, &rule, panel, whole, panel_tol, q.max_depth);
                }
            }
            out.push(sum);
        }
    }
    out
}

/// A rectangle `[z0, z1] × [φ0, φ1]` as `(z0, z1, φ0, φ1)`.
type Panel = (f64, f64, f64, f64);

/// Adaptive refinement of one panel: compare the panel's estimate with the
/// sum over its quadrants and recurse where they disagree.
fn adaptive(
    f: &impl Fn(f64, f64) -> f64,
    rule: &GaussLegendre,
    (z0, z1, p0, p1): Panel,
    whole: f64,
    tol: f64,
    depth: u32,
) -> f64 {
    let (zm, pm) = (0.5 * (z0 + z1), 0.5 * (p0 + p1));
    let quads = [
        (z0, zm, p0, pm),
        (z0, zm, pm, p1),
        (zm, z1, p0, pm),
        (zm, z1, pm, p1),
    ];
    let parts = quads.map(|panel| rule.panel(f, panel));
    let sum: f64 = parts.iter().sum();
    if depth == 0 || !sum.is_finite() || (sum - whole).abs() <= tol.max(1e-14 * sum.abs()) {
        return sum;
    }
    quads
        .iter()
        .zip(parts)
        .map(|(&panel, part)| adaptive(f, rule, panel, part, 0.25 * tol, depth - 1))
        .sum()
}

/// Gauss–Legendre nodes and weights on `[−1, 1]`.
struct GaussLegendre {
    nodes: Vec<f64>,
    weights: Vec<f64>,
}

impl GaussLegendre {
    /// The `n`-point rule, by Newton iteration on the Legendre polynomial
    /// `P_n` from the usual Chebyshev-like initial guesses.
    fn new(n: usize) -> Self {
        let mut nodes = vec![0.0; n];
        let mut weights = vec![0.0; n];
        let nf = n as f64;
        for i in 0..n.div_ceil(2) {
            let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                // Recurrence for P_n(x) and P_{n-1}(x).
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let kf = k as f64;
                    let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
                    p0 = p1;
                    p1 = p2;
                }
                dp = nf * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            nodes[i] = -x;
            nodes[n - 1 - i] = x;
            weights[i] = w;
            weights[n - 1 - i] = w;
        }
        GaussLegendre { nodes, weights }
    }

    /// Tensor-product rule over the rectangle `[z0, z1] × [p0, p1]`.
    fn panel(&self, f: &impl Fn(f64, f64) -> f64, (z0, z1, p0, p1): Panel) -> f64 {
        let (cz, hz) = (0.5 * (z0 + z1), 0.5 * (z1 - z0));
        let (cp, hp) = (0.5 * (p0 + p1), 0.5 * (p1 - p0));
        let mut sum = 0.0;
        for (xi, wi) in self.nodes.iter().zip(&self.weights) {
            let z = cz + hz * xi;
            let mut row = 0.0;
            for (xj, wj) in self.nodes.iter().zip(&self.weights) {
                row += wj * f(z, cp + hp * xj);
            }
            sum += wi * row;
        }
        sum * hz * hp
    }
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny, fast, well-mixed 64-bit
/// generator, used so that tests are deterministic and self-contained.
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator whose sequence is determined by `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform number in `[0, 1)` with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}
