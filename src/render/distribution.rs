//! Alias tables: sampling a piecewise-constant density over `n` equal bins
//! of `[0, 1)` in constant time (Walker's alias method, built by Vose's
//! algorithm; pbrt-v4 section A.1.4 `AliasTable`). The environment light
//! samples its rows with an [`AliasTable`] and the texels of a row with the
//! same construction packed beside its texels (`environment.rs`).
//!
//! # Exact integer weights
//!
//! Every table here is built from **integer** weights whose sum is exactly
//! `n × capacity`, so Vose's construction runs in integers: each bin `j`
//! keeps `threshold[j]` units of its own and lends `capacity − threshold[j]`
//! to `alias[j]`, and the probability that a uniform `u` picks bin `i` is
//! exactly `weight[i] / (n × capacity)`. A density reported from the
//! integer weight is then the density sampled, with no floating-point
//! rounding between them (a table built in floating point, like pbrt's,
//! samples each bin with a probability off by rounding from the one it
//! reports). Real weights become integers by the largest-remainder rule;
//! a bin whose share is below one unit gets weight 0, is never sampled and
//! has density 0 (a multiple-importance-sampled estimator stays unbiased:
//! the other strategy covers it with weight 1).
//!
//! # Continuous samples, and what the alias method gives up
//!
//! One uniform `u` does both jobs: `⌊u n⌋` picks bin `j`, and the rest of
//! `u` (times the capacity) is compared with `threshold[j]` and then
//! *remapped* to a uniform position inside the bin chosen (the part below
//! the threshold for bin `j`, the part above it for its alias). So a
//! sample is a continuous point, uniform within its bin, and no second
//! random number is spent. The trade-off against inverting a CDF: that
//! warp is monotone, so stratified or low-discrepancy `u` stay stratified
//! over the bins, while the alias warp is monotone only on each of its
//! (at most `2n`) pieces; a bin heavier than one bucket gathers pieces
//! from many buckets, whose samples are stratified piece by piece. In
//! exchange a sample costs one multiplication, one comparison and at most
//! two reads, whatever `n` and whatever the weights.

/// Units each bucket of an [`AliasTable`] holds: 2⁴⁰, so that the `n ×
/// capacity` total of a table of up to 2²³ bins fits in a `u64` and every
/// threshold is an `f64` exactly.
const TABLE_CAPACITY: u64 = 1 << 40;

/// Most bins an [`AliasTable`] takes (its total must fit in a `u64`).
pub const MAX_BINS: usize = 1 << 23;

/// Why a list of weights cannot become a distribution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DistributionError {
    /// No weights, or more than [`MAX_BINS`].
    #[error("distribution has {len} weights; it needs between 1 and {MAX_BINS}")]
    BadLength {
        /// Weights given.
        len: usize,
    },
    /// A NaN, infinite or negative weight.
    #[error("distribution weight {index} is {value}; weights must be finite and ≥ 0")]
    BadWeight {
        /// Position of the first bad weight.
        index: usize,
        /// The refused value.
        value: f64,
    },
    /// Every weight is zero (or the weights sum to infinity), so there is
    /// nothing to sample.
    #[error(
        "distribution weights are all zero or sum to infinity; their sum must be finite and > 0"
    )]
    AllZero,
}

/// One bucket of an [`AliasTable`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct AliasBin {
    /// Units of the bucket that stay with this bin, in `0..=TABLE_CAPACITY`.
    threshold: u64,
    /// The bin the rest of the bucket goes to.
    alias: u32,
    /// This bin's integer weight; the weights sum to `n × TABLE_CAPACITY`.
    weight: u64,
}

/// A piecewise-constant density over `n` equal bins of `[0, 1)`, sampled in
/// constant time by the alias method (see the module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct AliasTable {
    bins: Vec<AliasBin>,
}

impl AliasTable {
    /// A distribution proportional to `weights` (bin `i` covers `[i/n,
    /// (i+1)/n)`), rounded to integer weights out of `n × 2⁴⁰`. Refuses an
    /// empty or over-long slice, a NaN, infinite or negative weight, and
    /// weights that are all zero or sum to infinity.
    pub fn new(weights: &[f64]) -> Result<Self, DistributionError> {
        let n = weights.len();
        if n == 0 || n > MAX_BINS {
            return Err(DistributionError::BadLength { len: n });
        }
        if let Some(index) = weights.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(DistributionError::BadWeight {
                index,
                value: weights[index],
            });
        }
        let total = n as u64 * TABLE_CAPACITY;
        let integer = round_to_total(weights, total).ok_or(DistributionError::AllZero)?;
        let table = alias_table(&integer, TABLE_CAPACITY);
        let bins = table
            .into_iter()
            .zip(integer)
            .map(|((threshold, alias), weight)| AliasBin {
                threshold,
                alias,
                weight,
            })
            .collect();
        Ok(Self { bins })
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// Always `false`: a table has at least one bin (kept for the
    /// `len`/`is_empty` convention).
    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    /// The probability of bin `i` (its integer weight over the total,
    /// rounded once); 0 outside the table.
    pub fn probability(&self, i: usize) -> f64 {
        match self.bins.get(i) {
            Some(bin) => bin.weight as f64 / (self.bins.len() as u64 * TABLE_CAPACITY) as f64,
            None => 0.0,
        }
    }

    /// The bin holding `x` (`⌊x n⌋`, clamped into `0..n`); the rule that
    /// both [`Self::sample`] and [`Self::pdf`] use, so they agree.
    pub fn bin(&self, x: f64) -> usize {
        let n = self.bins.len();
        bin_of_scaled(x * n as f64, n)
    }

    /// Density at `x` with respect to length on `[0, 1)`: the probability
    /// of its bin times `n`; zero outside `[0, 1)`.
    pub fn pdf(&self, x: f64) -> f64 {
        if !(0.0..1.0).contains(&x) {
            return 0.0;
        }
        self.probability(self.bin(x)) * self.bins.len() as f64
    }

    /// Draws from `u ∈ [0, 1)` (clamped into it; NaN counts as 0): the
    /// continuous point `x ∈ [0, 1)`, its density ([`Self::pdf`] at `x`)
    /// and its bin `i`, with `self.bin(x) == i`. Bins of weight zero are
    /// never returned.
    pub fn sample(&self, u: f64) -> (f64, f64, usize) {
        let (i, within) = self.sample_bin(u);
        let n = self.bins.len();
        let x = snap_into_bin((i as f64 + within) / n as f64, i, n);
        (x, self.probability(i) * n as f64, i)
    }

    /// The bin drawn from `u` and the sample's position inside it, in
    /// `[0, 1)`: what a caller that maps bins to something else needs.
    pub fn sample_bin(&self, u: f64) -> (usize, f64) {
        draw(u, self.bins.len(), TABLE_CAPACITY, |j| {
            let bin = &self.bins[j];
            (bin.threshold, bin.alias as usize)
        })
    }
}

/// The draw of an alias table with `n` buckets of `capacity` units, whose
/// bucket `j` is `entry(j) = (threshold, alias)`: the bin `⌊u n⌋` when the
/// rest of `u`, scaled to the capacity, falls below its threshold, its
/// alias otherwise, each with the rest of `u` remapped to a uniform
/// position in `[0, 1)` inside the bin drawn. `u` is clamped into `[0, 1)`
/// (NaN counts as 0). `capacity` is a power of two at most 2⁵², so
/// thresholds and the scaled rest compare exactly as `f64`.
#[inline]
pub(crate) fn draw(
    u: f64,
    n: usize,
    capacity: u64,
    entry: impl Fn(usize) -> (u64, usize),
) -> (usize, f64) {
    let scaled = scaled_draw(u, n);
    let j = bin_of_scaled(scaled, n);
    let capacity = capacity as f64;
    // The fraction of the bucket, in units; exact up to the rounding of
    // u·n, and below the capacity.
    let rest = ((scaled - j as f64) * capacity).clamp(0.0, capacity.next_down());
    let (threshold, alias) = entry(j);
    let threshold = threshold as f64;
    let (bin, within) = if rest < threshold {
        (j, rest / threshold)
    } else {
        (alias, (rest - threshold) / (capacity - threshold))
    };
    (bin, within.min(1.0_f64.next_down()))
}

/// `u` clamped into `[0, 1)` (NaN counts as 0) and scaled to `n` buckets:
/// [`draw`]'s bucket is [`bin_of_scaled`] of it.
#[inline]
fn scaled_draw(u: f64, n: usize) -> f64 {
    let u = if u > 0.0 {
        u.min(1.0_f64.next_down())
    } else {
        0.0
    };
    u * n as f64
}

/// The bucket [`draw`] reads for `u` among `n` (the bin it returns is this
/// one or its alias).
#[inline]
pub(crate) fn bucket_of_draw(u: f64, n: usize) -> usize {
    bin_of_scaled(scaled_draw(u, n), n)
}

/// Vose's construction over integer `weights` that sum to exactly
/// `weights.len() × capacity`: per bucket `j`, the units kept by bin `j`
/// (`0..=capacity`) and the bin the rest goes to. In integers, so that the
/// probability of bin `i`, Σ of its own and its lent units over the total,
/// is exactly `weights[i] / total`; bins of weight 0 keep nothing. A
/// bucket that lends nothing is its own alias. Deterministic (index
/// order, two stacks).
pub(crate) fn alias_table(weights: &[u64], capacity: u64) -> Vec<(u64, u32)> {
    let n = weights.len();
    let mut table: Vec<(u64, u32)> = (0..n as u32).map(|i| (capacity, i)).collect();
    let mut left = weights.to_vec();
    let (mut small, mut large): (Vec<u32>, Vec<u32>) =
        (0..n as u32).partition(|&i| left[i as usize] < capacity);
    // Each step fills a small bin's bucket from a large bin; with an exact
    // total the last ones standing hold exactly `capacity` each.
    while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
        small.pop();
        let lent = capacity - left[s as usize];
        table[s as usize] = (left[s as usize], l);
        let rest = &mut left[l as usize];
        *rest = rest.saturating_sub(lent);
        if *rest < capacity {
            large.pop();
            small.push(l);
        }
    }
    table
}

/// Integer weights proportional to `weights` that sum to exactly `total`:
/// each `⌊w total / Σw⌋`, and the units left over to the bins with the
/// largest remainders (the largest-remainder rule), never to a bin of
/// weight 0. `None` when the weights are all zero or sum to infinity.
/// The weights must be finite and ≥ 0.
pub(crate) fn round_to_total(weights: &[f64], total: u64) -> Option<Vec<u64>> {
    let sum: f64 = weights.iter().sum();
    if !(sum > 0.0 && sum.is_finite()) {
        return None;
    }
    let scale = total as f64 / sum;
    let mut integer: Vec<u64> = weights.iter().map(|&w| (w * scale) as u64).collect();
    let assigned: u64 = integer.iter().sum();
    if assigned > total {
        // Rounding of `scale` can overshoot by a few units in 2⁶⁴: take
        // them from the largest weight.
        let largest = (0..integer.len()).max_by_key(|&i| integer[i])?;
        integer[largest] -= (assigned - total).min(integer[largest]);
        return Some(integer);
    }
    let missing = total - assigned;
    let mut lit: Vec<usize> = (0..weights.len()).filter(|&i| weights[i] > 0.0).collect();
    let remainder = |i: usize| weights[i] * scale - integer[i] as f64;
    // Largest remainders first, ties by index (a total order, so the
    // result does not depend on the sort). Rounding can leave more units
    // missing than there are bins: every bin then gets the same share.
    lit.sort_by(|&a, &b| remainder(b).total_cmp(&remainder(a)).then(a.cmp(&b)));
    let (each, extra) = (missing / lit.len() as u64, missing % lit.len() as u64);
    for (k, &i) in lit.iter().enumerate() {
        integer[i] += each + u64::from((k as u64) < extra);
    }
    Some(integer)
}

/// Nudges `x` into `[0, 1)` and then by ulps until `⌊x n⌋ = i` (rounding
/// at `(i + 1)/n` could otherwise report the neighbouring bin).
fn snap_into_bin(x: f64, i: usize, n: usize) -> f64 {
    let mut x = x.clamp(0.0, 1.0_f64.next_down());
    for _ in 0..8 {
        match bin_of_scaled(x * n as f64, n).cmp(&i) {
            std::cmp::Ordering::Equal => return x,
            std::cmp::Ordering::Greater => x = x.next_down(),
            std::cmp::Ordering::Less => x = x.next_up(),
        }
    }
    // Unreachable for n < 2⁵²; the bin centre is always safe.
    (i as f64 + 0.5) / n as f64
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// Each bin's probability from the table itself: its own units plus
    /// the units every bucket lends it, over the total.
    fn probabilities_from_table(table: &[(u64, u32)], capacity: u64) -> Vec<u64> {
        let mut units = vec![0u64; table.len()];
        for (j, &(threshold, alias)) in table.iter().enumerate() {
            units[j] += threshold;
            units[alias as usize] += capacity - threshold;
        }
        units
    }

    #[test]
    fn integer_tables_give_every_bin_exactly_its_weight() {
        let mut rng = Rng::new(4, 5);
        let capacity = 1 << 15;
        let mut cases: Vec<Vec<f64>> = vec![
            vec![1.0],
            vec![0.0, 0.0, 3.0, 0.0],
            vec![1.0; 1000],
            (0..4096)
                .map(|i| if i == 77 { 1e9 } else { 1e-3 })
                .collect(),
            (0..513)
                .map(|i| if i % 97 == 5 { 1e12 } else { 1.0 })
                .collect(),
        ];
        cases.push((0..777).map(|_| rng.next_f64().powi(8)).collect());
        for weights in &cases {
            let n = weights.len() as u64;
            let integer = round_to_total(weights, n * capacity).unwrap();
            assert_eq!(integer.iter().sum::<u64>(), n * capacity);
            for (w, i) in weights.iter().zip(&integer) {
                if *w == 0.0 {
                    assert_eq!(*i, 0, "a bin of weight 0 gets no units");
                }
            }
            let table = alias_table(&integer, capacity);
            assert!(table.iter().all(|&(t, a)| t <= capacity && (a as u64) < n));
            assert_eq!(probabilities_from_table(&table, capacity), integer);
        }
    }

    #[test]
    fn the_bucket_a_prefetch_names_is_the_one_the_draw_reads() {
        use std::cell::Cell;
        let n = 7;
        let specials = [
            0.0,
            -0.0,
            1.0,
            1.0_f64.next_down(),
            -3.0,
            2.0,
            f64::NAN,
            0.5,
        ];
        let grid = (0..1000).map(|k| k as f64 / 999.0);
        for u in specials.into_iter().chain(grid) {
            let read = Cell::new(usize::MAX);
            draw(u, n, 16, |j| {
                read.set(j);
                (8, (j + 1) % n)
            });
            assert_eq!(bucket_of_draw(u, n), read.get(), "u = {u}");
        }
    }

    #[test]
    fn draws_land_in_each_bin_in_proportion_to_its_weight() {
        // A fine grid of u covers each bucket evenly: bin i must receive
        // weight[i] / total of it, up to one grid step per piece.
        let weights = [1.0, 3.0, 0.0, 12.0, 0.5];
        let table = AliasTable::new(&weights).unwrap();
        let steps = 1 << 20;
        let mut hits = [0u64; 5];
        for k in 0..steps {
            let (x, pdf, i) = table.sample((k as f64 + 0.5) / steps as f64);
            assert_eq!(table.bin(x), i);
            assert_eq!(pdf, table.pdf(x));
            hits[i] += 1;
        }
        let sum: f64 = weights.iter().sum();
        for i in 0..5 {
            let share = hits[i] as f64 / steps as f64;
            assert!((share - weights[i] / sum).abs() < 1e-5, "bin {i}: {share}");
            assert!((table.probability(i) - weights[i] / sum).abs() < 1e-12);
        }
        assert_eq!(hits[2], 0);
    }
}
