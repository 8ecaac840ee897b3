//! Piecewise-constant 1-D and 2-D distributions for importance sampling
//! (pbrt-v4, section A.5 "Sampling 1D functions" and "Piecewise-constant 2D
//! distributions"; the environment light samples its texels with them).
//!
//! A [`Distribution1D`] over `n` equal bins of `[0, 1)` has density
//! `p(x) = f[i] / I` in bin `i = ⌊x n⌋`, with `I = Σ f / n` the integral of
//! the step function, and is sampled by inverting its CDF. A
//! [`Distribution2D`] over a `width × height` grid factors the joint density
//! into a marginal over rows and a conditional over the columns of each row,
//! `p(u, v) = p(v) p(u | v) = f[row][col] / I`, so that sampling costs two
//! binary searches (pbrt-v4 eq. A.12–A.13 / `PiecewiseConstant2D`).
//!
//! Everything is in `f64`, including the CDFs, so that a 1024 × 512
//! environment map with a dynamic range of 10⁵ keeps its dim texels
//! reachable. Bins of weight zero are never sampled and have pdf zero.

/// Why a grid of weights cannot become a distribution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DistributionError {
    /// A grid with no cells, or a weight slice whose length does not match
    /// the stated size.
    #[error(
        "distribution grid is {width}×{height} with {len} weights; it needs width ≥ 1, \
         height ≥ 1 and exactly width × height weights"
    )]
    BadShape {
        /// Columns requested.
        width: usize,
        /// Rows requested.
        height: usize,
        /// Weights given.
        len: usize,
    },
    /// A NaN, infinite or negative weight.
    #[error(
        "distribution weight at column {x}, row {y} is {value}; weights must be finite and ≥ 0"
    )]
    BadWeight {
        /// Column of the first bad weight.
        x: usize,
        /// Row of the first bad weight.
        y: usize,
        /// The refused value.
        value: f64,
    },
    /// Every weight is zero, so there is nothing to sample.
    #[error("distribution weights are all zero; at least one must be > 0")]
    AllZero,
}

/// A piecewise-constant density over `n` equal bins of `[0, 1)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution1D {
    /// Non-negative bin weights `f[i]`.
    func: Vec<f64>,
    /// `cdf[i] = Σ_{j<i} f[j] / Σ f`, with `cdf[0] = 0` and `cdf[n] = 1`.
    cdf: Vec<f64>,
    /// `∫₀¹ f = Σ f / n` (zero only for the all-zero rows that
    /// [`Distribution2D`] keeps and never samples).
    integral: f64,
    /// Guide table (Chen & Asau's cutpoints): `guide[k]` is the largest `i`
    /// with `cdf[i] ≤ k / n`, for `k = 0…n`. A sample `u` in `[k/n,
    /// (k+1)/n)` inverts the CDF within `guide[k−1]…guide[k+2]`: a search
    /// over a few entries instead of a binary search over all `n + 1`, with
    /// exactly the same result (the environment map's 513- and 1025-entry
    /// CDFs cost a fifth of a studio render with the full search).
    guide: Vec<u32>,
}

impl Distribution1D {
    /// A distribution proportional to `weights` (bin `i` covers
    /// `[i/n, (i+1)/n)`). Refuses an empty slice, a NaN, infinite or
    /// negative weight, and all-zero weights.
    pub fn new(weights: &[f64]) -> Result<Self, DistributionError> {
        check_weights(weights, weights.len(), 1)?;
        let d = Self::build(weights);
        if d.integral > 0.0 {
            Ok(d)
        } else {
            Err(DistributionError::AllZero)
        }
    }

    /// Builds from already-checked weights; an all-zero row gets a uniform
    /// CDF (it is never sampled, as its marginal weight is zero).
    fn build(weights: &[f64]) -> Self {
        let n = weights.len();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut running = 0.0;
        for &w in weights {
            running += w;
            cdf.push(running);
        }
        let total = running;
        if total > 0.0 {
            for c in &mut cdf[1..] {
                *c /= total;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f64 / n as f64;
            }
        }
        // Exactly 1 at the end, whatever the rounding of the running sum.
        cdf[n] = 1.0;
        let mut guide = Vec::with_capacity(n + 1);
        let mut i = 0;
        for k in 0..=n {
            let cut = k as f64 / n as f64;
            while i < n && cdf[i + 1] <= cut {
                i += 1;
            }
            guide.push(i as u32);
        }
        Self {
            func: weights.to_vec(),
            cdf,
            integral: total / n as f64,
            guide,
        }
    }

    /// The largest `i` with `cdf[i] ≤ u`, for `u` in `[0, 1)`, found
    /// between the guide table's cutpoints around `u` (one cutpoint of slack
    /// on each side absorbs the rounding of `u·n`).
    fn invert_cdf(&self, u: f64) -> usize {
        let n = self.func.len();
        let k = bin_of_scaled(u * n as f64, n);
        let lo = self.guide[k.saturating_sub(1)] as usize;
        let hi = self.guide[(k + 2).min(n)] as usize;
        // cdf[lo] ≤ u, and every i with cdf[i] ≤ u is ≤ hi.
        lo + self.cdf[lo..=hi].partition_point(|&c| c <= u).max(1) - 1
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// Always `false`: a distribution has at least one bin (kept for the
    /// `len`/`is_empty` convention).
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// `∫₀¹ f(x) dx = Σ f / n`, the normalisation constant of the density.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// The bin holding `x` (`⌊x n⌋`, clamped into `0..n`); the one rule that
    /// both [`Self::sample`] and [`Self::pdf`] use, so they agree.
    pub fn bin(&self, x: f64) -> usize {
        let n = self.func.len();
        bin_of_scaled(x * n as f64, n)
    }

    /// Inverts the CDF at `u ∈ [0, 1)`: returns the continuous point
    /// `x ∈ [0, 1)`, its density `f[i] / I` and its bin `i`. Bins of zero
    /// weight are never returned, and `self.bin(x) == i` always holds.
    pub fn sample(&self, u: f64) -> (f64, f64, usize) {
        let (x, i) = self.sample_point(u);
        let pdf = if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            0.0
        };
        (x, pdf, i)
    }

    /// [`Self::sample`] without the density: the point `x` and its bin `i`
    /// (what [`Distribution2D::sample`] needs, a division fewer).
    fn sample_point(&self, u: f64) -> (f64, usize) {
        let n = self.func.len();
        // Clamp into [0, 1): the last bin of positive weight ends at a CDF of
        // exactly 1, so any u < 1 lands in a bin of positive weight.
        let u = if u.is_finite() {
            u.clamp(0.0, 1.0_f64.next_down())
        } else {
            0.0
        };
        // Largest i with cdf[i] ≤ u; then cdf[i + 1] > u, so f[i] > 0.
        let i = self.invert_cdf(u).min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        (self.snap_into_bin((i as f64 + du) / n as f64, i), i)
    }

    /// Nudges `x` into `[0, 1)` and then by ulps until [`Self::bin`] maps it
    /// to bin `i` (rounding at `(i + 1)/n` could otherwise report the
    /// neighbouring bin).
    fn snap_into_bin(&self, x: f64, i: usize) -> f64 {
        // The last bin is closed by clamping in `bin`; keep x inside [0, 1).
        let mut x = x.clamp(0.0, 1.0_f64.next_down());
        if self.is_in_bin(x, i) {
            return x;
        }
        for _ in 0..8 {
            match self.bin(x).cmp(&i) {
                std::cmp::Ordering::Equal => return x,
                std::cmp::Ordering::Greater => x = x.next_down(),
                std::cmp::Ordering::Less => x = x.next_up(),
            }
        }
        // Unreachable for n < 2⁵²; the bin centre is always safe.
        (i as f64 + 0.5) / self.func.len() as f64
    }

    /// Whether [`Self::bin`] maps `x ∈ [0, 1)` to bin `i < n`, by two
    /// comparisons instead of a float-to-integer conversion: ⌊x n⌋ = i ⇔
    /// i ≤ x n < i + 1, exact as long as i + 1 ≤ 2⁵³ (no distribution that
    /// fits in memory has more bins); the last bin also takes x n = n.
    fn is_in_bin(&self, x: f64, i: usize) -> bool {
        let n = self.func.len();
        let scaled = x * n as f64;
        scaled >= i as f64 && (scaled < (i + 1) as f64 || i + 1 == n)
    }

    /// Density at `x` with respect to length on `[0, 1)`; zero outside it.
    pub fn pdf(&self, x: f64) -> f64 {
        if !(0.0..1.0).contains(&x) || self.integral <= 0.0 {
            return 0.0;
        }
        self.func[self.bin(x)] / self.integral
    }
}

/// A piecewise-constant density over `[0, 1)²` from a `width × height` grid
/// of weights: column `⌊u·width⌋`, row `⌊v·height⌋`, row-major storage.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution2D {
    /// One distribution over the columns of each row, `p(u | v)`.
    conditional: Vec<Distribution1D>,
    /// The distribution of rows, weighted by each row's integral, `p(v)`.
    marginal: Distribution1D,
}

impl Distribution2D {
    /// A distribution proportional to `weights[row * width + col]`. Refuses
    /// an empty grid, a length other than `width × height`, any NaN,
    /// infinite or negative weight (naming its column and row) and an
    /// all-zero grid.
    pub fn new(weights: &[f64], width: usize, height: usize) -> Result<Self, DistributionError> {
        check_weights(weights, width, height)?;
        let conditional: Vec<Distribution1D> = weights
            .chunks_exact(width)
            .map(Distribution1D::build)
            .collect();
        let row_integrals: Vec<f64> = conditional.iter().map(|c| c.integral).collect();
        let marginal = Distribution1D::build(&row_integrals);
        if marginal.integral > 0.0 {
            Ok(Self {
                conditional,
                marginal,
            })
        } else {
            Err(DistributionError::AllZero)
        }
    }

    /// Number of columns (bins along `u`).
    pub fn width(&self) -> usize {
        self.conditional[0].len()
    }

    /// Number of rows (bins along `v`).
    pub fn height(&self) -> usize {
        self.marginal.len()
    }

    /// Draws a point `(u, v) ∈ [0, 1)²` from two uniform numbers (`u[1]`
    /// picks the row from the marginal, `u[0]` the column from that row's
    /// conditional) and returns it with its density with respect to
    /// `du dv`, which equals [`Self::pdf`] at the returned point.
    pub fn sample(&self, u: [f64; 2]) -> (glam::DVec2, f64) {
        let (v, row) = self.marginal.sample_point(u[1]);
        let (x, col) = self.conditional[row].sample_point(u[0]);
        // f / I directly, as in `pdf`: the product p(v) p(u|v) is the same
        // number mathematically but not always to the last bit.
        let pdf = self.conditional[row].func[col] / self.marginal.integral;
        (glam::DVec2::new(x, v), pdf)
    }

    /// Density at `uv` with respect to `du dv`: `f[row][col] / I` with `I`
    /// the mean weight; zero outside `[0, 1)²` and for non-finite input.
    pub fn pdf(&self, uv: glam::DVec2) -> f64 {
        if !(0.0..1.0).contains(&uv.x) || !(0.0..1.0).contains(&uv.y) {
            return 0.0;
        }
        let row = &self.conditional[self.marginal.bin(uv.y)];
        // p(v) p(u|v) = (I_row / I) (f / I_row) = f / I.
        row.func[row.bin(uv.x)] / self.marginal.integral
    }
}

/// The bin `⌊scaled⌋` of `scaled = x n`, clamped into `0..n` (NaN and
/// negatives to bin 0, beyond `n` to bin `n − 1`). Through `i64`, whose
/// saturating conversion is a few instructions cheaper than `usize`'s and
/// gives the same bin for every input: `n ≤ isize::MAX < 2⁶³` for any slice
/// length, so the `i64::MAX` a huge value saturates to still clamps to
/// `n − 1`, and NaN converts to 0 like the negative values.
pub(crate) fn bin_of_scaled(scaled: f64, n: usize) -> usize {
    ((scaled as i64).max(0) as usize).min(n - 1)
}

/// Checks shape and values: `width × height` finite, non-negative weights.
fn check_weights(weights: &[f64], width: usize, height: usize) -> Result<(), DistributionError> {
    if width == 0 || height == 0 || width.checked_mul(height) != Some(weights.len()) {
        return Err(DistributionError::BadShape {
            width,
            height,
            len: weights.len(),
        });
    }
    if let Some(i) = weights.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
        return Err(DistributionError::BadWeight {
            x: i % width,
            y: i / width,
            value: weights[i],
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The plain binary search the guide table replaces.
    fn invert_by_full_search(d: &Distribution1D, u: f64) -> usize {
        d.cdf.partition_point(|&c| c <= u).max(1) - 1
    }

    /// The bin rule before [`bin_of_scaled`]: `Distribution1D::bin`'s
    /// (clamped at 0 first) and the texel lookup's (without the clamp).
    fn bin_through_usize(scaled: f64, n: usize, clamp_at_zero: bool) -> usize {
        let scaled = if clamp_at_zero {
            scaled.max(0.0)
        } else {
            scaled
        };
        (scaled as usize).min(n - 1)
    }

    #[test]
    fn bins_through_i64_equal_bins_through_usize_for_every_kind_of_input() {
        let mut rng = Rng::new(21, 22);
        let mut scaled = vec![
            f64::NAN,
            -f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            2f64.powi(31),
            2f64.powi(32),
            2f64.powi(63),
            2f64.powi(63).next_down(),
            2f64.powi(64),
            1e30,
            -1e30,
        ];
        for k in -3..1100 {
            let k = k as f64;
            scaled.extend([k, k.next_up(), k.next_down()]);
        }
        scaled.extend((0..20_000).map(|_| (rng.next_f64() - 0.25) * 2000.0));
        for n in [1, 2, 3, 256, 1024, 16384, usize::MAX >> 1] {
            for &t in &scaled {
                for clamp in [true, false] {
                    assert_eq!(
                        bin_of_scaled(t, n),
                        bin_through_usize(t, n, clamp),
                        "n = {n}, scaled = {t}"
                    );
                }
            }
        }
    }

    /// [`Distribution1D::sample`] before the snap's fast path: the ulp
    /// loop run from the start, through the `usize` bin rule.
    fn sample_by_snap_loop(d: &Distribution1D, u: f64) -> (f64, f64, usize) {
        let n = d.func.len();
        let u = if u.is_finite() {
            u.clamp(0.0, 1.0_f64.next_down())
        } else {
            0.0
        };
        let i = invert_by_full_search(d, u).min(n - 1);
        let width = d.cdf[i + 1] - d.cdf[i];
        let du = if width > 0.0 {
            ((u - d.cdf[i]) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let old_bin = |x: f64| bin_through_usize(x * n as f64, n, true);
        let mut x = ((i as f64 + du) / n as f64).clamp(0.0, 1.0_f64.next_down());
        let mut snapped = None;
        for _ in 0..8 {
            match old_bin(x).cmp(&i) {
                std::cmp::Ordering::Equal => {
                    snapped = Some(x);
                    break;
                }
                std::cmp::Ordering::Greater => x = x.next_down(),
                std::cmp::Ordering::Less => x = x.next_up(),
            }
        }
        let x = snapped.unwrap_or((i as f64 + 0.5) / n as f64);
        let pdf = if d.integral > 0.0 {
            d.func[i] / d.integral
        } else {
            0.0
        };
        (x, pdf, i)
    }

    #[test]
    fn sampling_with_the_snap_fast_path_equals_the_ulp_loop_bit_for_bit() {
        let mut rng = Rng::new(31, 32);
        let cases: Vec<Vec<f64>> = vec![
            vec![1.0],
            vec![0.0, 0.0, 3.0, 0.0],
            vec![1.0; 3],
            vec![1.0; 49],
            (0..256).map(|i| 1.0 + (i as f64 * 0.3).sin()).collect(),
            (0..1024)
                .map(|i| if i % 97 == 5 { 1e12 } else { 1.0 })
                .collect(),
            (0..777).map(|_| rng.next_f64().powi(8)).collect(),
        ];
        for weights in &cases {
            let d = Distribution1D::new(weights).unwrap();
            let n = weights.len();
            let mut us: Vec<f64> = (0..20_000).map(|_| rng.next_f64()).collect();
            us.extend([
                0.0,
                -0.0,
                1.0,
                1.0_f64.next_down(),
                1.0_f64.next_down().next_down(),
                -1.0,
                2.0,
                f64::NAN,
                f64::INFINITY,
            ]);
            // Every bin edge in u (CDF values) and in x (k / n), with their
            // neighbouring floats.
            for k in 0..=n {
                for c in [d.cdf[k], k as f64 / n as f64] {
                    us.extend([c, c.next_up(), c.next_down()]);
                }
            }
            for u in us {
                let (x, pdf, i) = d.sample(u);
                let (x_ref, pdf_ref, i_ref) = sample_by_snap_loop(&d, u);
                assert_eq!(
                    (x.to_bits(), pdf.to_bits(), i),
                    (x_ref.to_bits(), pdf_ref.to_bits(), i_ref),
                    "n = {n}, u = {u}"
                );
                assert_eq!(d.bin(x), i, "n = {n}, u = {u}");
            }
        }
    }

    #[test]
    fn guided_inversion_equals_the_full_binary_search() {
        let mut rng = Rng::new(8, 9);
        // Smooth, spiky (dynamic range 10¹²), runs of zero bins, one bin,
        // and sizes that are not powers of two.
        let mut cases: Vec<Vec<f64>> = vec![
            vec![1.0],
            vec![0.0, 0.0, 3.0, 0.0],
            (0..1025).map(|i| 1.0 + (i as f64 * 0.1).sin()).collect(),
            (0..513)
                .map(|i| if i % 97 == 5 { 1e12 } else { 1.0 })
                .collect(),
            (0..300)
                .map(|i| if (40..260).contains(&i) { 0.0 } else { 2.0 })
                .collect(),
        ];
        cases.push((0..777).map(|_| rng.next_f64().powi(8)).collect());
        for weights in &cases {
            let d = Distribution1D::new(weights).unwrap();
            let n = weights.len();
            // Random u, every cutpoint k/n and its neighbouring floats, and
            // every CDF value and its neighbours.
            let mut us: Vec<f64> = (0..20_000).map(|_| rng.next_f64()).collect();
            for k in 0..n {
                let cut = k as f64 / n as f64;
                us.extend([cut, cut.next_up(), cut.next_down().max(0.0)]);
            }
            for &c in &d.cdf[..n] {
                us.extend([c, c.next_up(), c.next_down().max(0.0)]);
            }
            for u in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                assert_eq!(
                    d.invert_cdf(u),
                    invert_by_full_search(&d, u),
                    "n = {n}, u = {u}"
                );
            }
        }
    }
}
