//! Per-pixel sample streams: Owen-scrambled Sobol points for the first
//! dimensions, hashed random numbers after them.
//!
//! The first `SOBOL_PAIRS` pairs of dimensions of a pixel's samples (the
//! pixel footprint, the first light and BRDF choices) are the 2-D Sobol
//! (0,2)-sequence, nested-uniform scrambled and with its index shuffled per
//! pixel and per pair, after Burley, "Practical Hash-based Owen Scrambling"
//! (JCGT 2020): each pair is a stratified point set on its own, and pairs
//! are decorrelated from each other by the shuffle ("padding"). Deeper
//! dimensions, where stratification buys little, come from a SplitMix64
//! stream. Every number is a pure function of (seed, pixel, sample index,
//! dimension): which thread renders the pixel does not matter.
//!
//! The Sobol points are made `SAMPLE_BATCH` samples at a time, every pair
//! at once (`batch`): integer arithmetic on sixteen lanes
//! that the compiler turns into vector instructions (AVX2, chosen at run
//! time on x86-64), the same bits as one point at a time.

use crate::sampling::{mix64, Rng};

/// How many 2-D dimension pairs come from the scrambled Sobol sequence.
pub(crate) const SOBOL_PAIRS: u32 = 6;

/// The part of every sample stream of one pixel that does not depend on the
/// sample index: the pixel's seed and the scrambling seeds of its Sobol
/// pairs. Made once per pixel, so that the two hashes per pair are not
/// redone for each of the pixel's samples.
#[derive(Clone, Debug)]
pub(crate) struct PixelSampler {
    pixel_seed: u64,
    /// (index shuffle, x, y) scrambling seeds of each Sobol pair.
    pair_seeds: [[u32; 3]; SOBOL_PAIRS as usize],
}

impl PixelSampler {
    /// The sampler of the pixel with flat index `pixel_index`, for the
    /// render seed `seed`.
    pub fn new(seed: u64, pixel_index: u64) -> Self {
        let pixel_seed = mix64(seed ^ mix64(pixel_index.wrapping_add(0x5851_f42d_4c95_7f2d)));
        let mut pair_seeds = [[0; 3]; SOBOL_PAIRS as usize];
        for (pair, seeds) in (0u64..).zip(pair_seeds.iter_mut()) {
            *seeds = scramble_seeds(pixel_seed ^ pair.wrapping_mul(0x9e37_79b9));
        }
        Self {
            pixel_seed,
            pair_seeds,
        }
    }

    /// The Sobol points of the pixel's samples `first_sample` to
    /// `first_sample + SAMPLE_BATCH − 1` (wrapping), every pair of each:
    /// one vectorised pass instead of one scalar pass per point drawn.
    #[cfg(test)]
    pub fn batch(&self, first_sample: u32) -> SampleBatch {
        let mut batch = SampleBatch::default();
        self.refill(&mut batch, first_sample, SAMPLE_BATCH, SOBOL_PAIRS);
        batch
    }

    /// Makes `batch` the batch of the pixel's samples `first_sample` to
    /// `first_sample + lanes − 1`, in place (a batch is 1.5 KB: the render
    /// loop reuses one rather than copy a new one in), with the first
    /// `eager_pairs` Sobol pairs of every lane made now and the others
    /// left to [`SampleStream::next_2d`], which makes a later pair when a
    /// path draws it: most paths end before they need them. A full batch is
    /// made in vector code; fewer lanes (a pixel's last samples, or a
    /// preview's one sample) one point at a time, so that 1 spp does not
    /// pay for 16 samples' points. Either way every number drawn is the
    /// same.
    #[inline(always)]
    pub(crate) fn refill(
        &self,
        batch: &mut SampleBatch,
        first_sample: u32,
        lanes: u32,
        eager_pairs: u32,
    ) {
        let eager_pairs = eager_pairs.min(SOBOL_PAIRS);
        batch.pixel_seed = self.pixel_seed;
        batch.first_sample = first_sample;
        batch.pair_seeds = self.pair_seeds;
        batch.eager_pairs = eager_pairs;
        let seeds = &self.pair_seeds[..eager_pairs as usize];
        if lanes >= SAMPLE_BATCH {
            fill_batch(seeds, first_sample, &mut batch.points);
        } else {
            fill_lanes_one_by_one(seeds, first_sample, lanes, &mut batch.points);
        }
    }
}

/// How many consecutive samples of a pixel [`PixelSampler::batch`] makes
/// points for: sixteen 32-bit lanes, two AVX2 registers (rather than eight
/// in one register, so that the fixed steps of a batch are shared by more
/// samples).
pub(crate) const SAMPLE_BATCH: u32 = 16;

/// Every Sobol pair of [`SAMPLE_BATCH`] consecutive samples of one pixel
/// (the default is all zeros, to be filled by [`PixelSampler::refill`]).
#[derive(Clone, Debug, Default)]
pub(crate) struct SampleBatch {
    pixel_seed: u64,
    first_sample: u32,
    /// The pixel's scrambling seeds of each pair (for the pairs made when
    /// drawn).
    pair_seeds: [[u32; 3]; SOBOL_PAIRS as usize],
    /// How many pairs `points` holds for every lane.
    eager_pairs: u32,
    /// `points[lane][pair]`: pair `pair` (< `eager_pairs`) of sample
    /// `first_sample + lane`.
    points: [[[f64; 2]; SOBOL_PAIRS as usize]; SAMPLE_BATCH as usize],
}

impl SampleBatch {
    /// Pair 0 (the pixel footprint) of every lane's sample.
    pub(crate) fn footprints(&self) -> [[f64; 2]; SAMPLE_BATCH as usize] {
        self.points.map(|pairs| pairs[0])
    }

    /// The stream of sample `first_sample + lane` (lane < [`SAMPLE_BATCH`]).
    #[inline(always)]
    pub fn stream(&self, lane: u32) -> SampleStream<'_> {
        let sample_index = self.first_sample.wrapping_add(lane);
        SampleStream {
            pixel_seed: self.pixel_seed,
            sample_index,
            points: &self.points[lane as usize],
            eager_pairs: self.eager_pairs,
            pair_seeds: &self.pair_seeds,
            next_pair: 0,
            tail: Rng::new(self.pixel_seed, u64::from(sample_index)),
        }
    }
}

/// The random numbers of one sample of one pixel, drawn in a fixed order.
#[derive(Clone, Debug)]
pub struct SampleStream<'a> {
    pixel_seed: u64,
    sample_index: u32,
    /// This sample's Sobol pairs, from its [`SampleBatch`] (the first
    /// `eager_pairs` of them).
    points: &'a [[f64; 2]; SOBOL_PAIRS as usize],
    eager_pairs: u32,
    /// The pixel's scrambling seeds, for the pairs made when drawn.
    pair_seeds: &'a [[u32; 3]; SOBOL_PAIRS as usize],
    next_pair: u32,
    tail: Rng,
}

impl SampleStream<'_> {
    /// The next two numbers in [0, 1). Inlined: a call's set-up (the
    /// result through memory, saved registers) is a tenth of its cost.
    #[inline(always)]
    pub(crate) fn next_2d(&mut self) -> [f64; 2] {
        let pair = self.next_pair;
        self.next_pair += 1;
        if pair < self.eager_pairs {
            self.points[pair as usize]
        } else if pair < SOBOL_PAIRS {
            self.later_pair(pair)
        } else {
            [self.tail.next_f64(), self.tail.next_f64()]
        }
    }

    /// Sobol pair `pair` of this sample made now, one point of the batch's
    /// fill (the same bits): out of line, as few paths get this deep.
    #[inline(never)]
    fn later_pair(&self, pair: u32) -> [f64; 2] {
        let (x, y) = owen_sobol_point(
            self.sample_index.reverse_bits(),
            self.pair_seeds[pair as usize],
        );
        [to_unit(x), to_unit(y)]
    }

    /// Passes over the next two numbers (those the caller already took
    /// from the batch, as the film does with the footprints).
    #[inline(always)]
    pub(crate) fn skip_2d(&mut self) {
        self.next_2d();
    }

    /// The next single number in [0, 1) (from the hashed tail, so a lone
    /// dimension never breaks the pairing of the Sobol dimensions).
    pub(crate) fn next_1d(&mut self) -> f64 {
        self.tail.next_f64()
    }

    /// An independent generator for optional work (ambient occlusion) whose
    /// numbers must not shift the main stream: turning the option on leaves
    /// the beauty image unchanged.
    pub(crate) fn side_stream(&self, salt: u64) -> Rng {
        Rng::new(mix64(self.pixel_seed ^ salt), u64::from(self.sample_index))
    }

    /// [`SampleStream::side_stream`] of the point of the path `pairs_ahead`
    /// pairs on: another generator at each vertex (the main stream's
    /// position is mixed in), for an extra sample that must not shift the
    /// main stream's pairs, whose numbers a caller may also know ahead.
    pub(crate) fn side_stream_ahead(&self, pairs_ahead: u32, salt: u64) -> Rng {
        self.side_stream(salt ^ mix64(u64::from(self.next_pair + pairs_ahead)))
    }

    /// Three numbers for a BRDF sample: a Sobol pair and one more.
    /// Inlined like [`SampleStream::next_2d`].
    #[inline(always)]
    pub(crate) fn next_3d(&mut self) -> [f64; 3] {
        let [a, b] = self.next_2d();
        [a, b, self.next_1d()]
    }
}

/// Point `index` of the shuffled, scrambled 2-D Sobol sequence for `seed`.
#[cfg(test)]
pub(crate) fn owen_sobol_2d(index: u32, seed: u64) -> [f64; 2] {
    let (x, y) = owen_sobol_point(index.reverse_bits(), scramble_seeds(seed));
    [to_unit(x), to_unit(y)]
}

/// Three independent 32-bit scrambling seeds (index shuffle, x, y) from one
/// 64-bit seed, with two hashes.
fn scramble_seeds(seed: u64) -> [u32; 3] {
    let h = mix64(seed);
    [h as u32, (h >> 32) as u32, mix64(h) as u32]
}

/// `points[lane][pair]` of one [`SampleBatch`].
type BatchPoints = [[[f64; 2]; SOBOL_PAIRS as usize]; SAMPLE_BATCH as usize];

/// Fills `points[lane][pair]` with pair `pair` (< `pair_seeds.len()`) of
/// sample `first_sample + lane` of the pixel whose pairs are scrambled by
/// `pair_seeds`, as loops over fixed-size lane arrays, which the compiler
/// vectorises: every step of [`owen_sobol_point`] is one operation on all
/// lanes (`reverse_bits` becomes byte shuffles). Inlined into the pixel loop,
/// so its x86-64-v3 copy (`crate::render::cpu`) runs eight lanes per
/// instruction; integer arithmetic, so every copy gives the same bits.
#[inline(always)]
fn fill_batch(pair_seeds: &[[u32; 3]], first_sample: u32, points: &mut BatchPoints) {
    const LANES: usize = SAMPLE_BATCH as usize;
    let mut reversed_index = [0u32; LANES];
    for (lane, r) in (0u32..).zip(reversed_index.iter_mut()) {
        *r = first_sample.wrapping_add(lane).reverse_bits();
    }
    for (pair, seeds) in pair_seeds.iter().enumerate() {
        let (mut xs, mut ys) = ([0u32; LANES], [0u32; LANES]);
        for lane in 0..LANES {
            (xs[lane], ys[lane]) = owen_sobol_point(reversed_index[lane], *seeds);
        }
        for lane in 0..LANES {
            points[lane][pair] = [to_unit(xs[lane]), to_unit(ys[lane])];
        }
    }
}

/// The first `lanes` lanes of [`fill_batch`], in a loop the compiler
/// does not unroll into vectors (kept out of line: a pixel's last batch
/// only).
#[inline(never)]
fn fill_lanes_one_by_one(
    pair_seeds: &[[u32; 3]],
    first_sample: u32,
    lanes: u32,
    points: &mut BatchPoints,
) {
    for (lane, lane_points) in (0..lanes).zip(points.iter_mut()) {
        let reversed_index = first_sample.wrapping_add(lane).reverse_bits();
        for (seeds, point) in pair_seeds.iter().zip(lane_points.iter_mut()) {
            let (x, y) = owen_sobol_point(reversed_index, *seeds);
            *point = [to_unit(x), to_unit(y)];
        }
    }
}

/// The two 32-bit coordinates of one point of [`owen_sobol_2d`], from the
/// bit-reversed index. Written out, x = nus(sobol₀(shuffled)) and
/// y = nus(sobol₁(shuffled)) with shuffled = nus(index) and
/// nus(v) = rev(LK(rev(v))); since sobol₀ = rev the reversals cancel down
/// to three per point: with q = rev(LK(rev(index))), x = rev(LK(q)) and
/// y = rev(LK(pascal(q))), as rev ∘ sobol₁ = pascal (see
/// [`sobol_dimension_1`]).
#[inline(always)]
fn owen_sobol_point(reversed_index: u32, seeds: [u32; 3]) -> (u32, u32) {
    let q = laine_karras_permutation(reversed_index, seeds[0]).reverse_bits();
    let x = laine_karras_permutation(q, seeds[1]);
    let y = laine_karras_permutation(pascal(q), seeds[2]);
    (x.reverse_bits(), y.reverse_bits())
}

/// The first Sobol dimension: the base-2 radical inverse (van der Corput).
#[cfg(test)]
pub(crate) fn sobol_dimension_0(index: u32) -> u32 {
    index.reverse_bits()
}

/// The second Sobol dimension: direction numbers `v₀ = 2³¹`,
/// `vᵢ = vᵢ₋₁ ⊕ (vᵢ₋₁ >> 1)` (the primitive polynomial x + 1), i.e.
/// rev(vᵢ) = (1 + x)ⁱ over GF(2) with bit k the coefficient of xᵏ. So
/// rev(sobol₁(i)) = Σ iₖ (1 + x)ᵏ = `pascal(i)`: the binary Pascal
/// matrix, five shift-and-XOR steps instead of a loop over 32 bits.
#[cfg(test)]
pub(crate) fn sobol_dimension_1(index: u32) -> u32 {
    pascal(index).reverse_bits()
}

/// p(y) ↦ p(1 + x) for the polynomial p over GF(2) whose coefficient of yᵏ
/// is bit k of `v`. Split p into halves of s = 16, 8, … 1 coefficients,
/// p = p_hi·yˢ + p_lo: then p(1 + x) = p_hi(1 + x)·(1 + xˢ) + p_lo(1 + x),
/// since (1 + x)ˢ = 1 + xˢ over GF(2) for s a power of two, so each level
/// XORs the upper half of every 2s-bit block into its lower half.
#[inline(always)]
fn pascal(mut v: u32) -> u32 {
    v ^= (v & 0xaaaa_aaaa) >> 1;
    v ^= (v & 0xcccc_cccc) >> 2;
    v ^= (v & 0xf0f0_f0f0) >> 4;
    v ^= (v & 0xff00_ff00) >> 8;
    v ^= (v & 0xffff_0000) >> 16;
    v
}

/// The second Sobol dimension bit by bit: the definition [`pascal`] is
/// checked against.
#[cfg(test)]
fn sobol_dimension_1_by_bits(mut index: u32) -> u32 {
    let mut v = 1u32 << 31;
    let mut result = 0;
    while index != 0 {
        if index & 1 != 0 {
            result ^= v;
        }
        index >>= 1;
        v ^= v >> 1;
    }
    result
}

/// Nested uniform (Owen) scrambling of a 32-bit fixed-point number: a hash
/// that only mixes bits downward, applied to the reversed bits (Burley 2020).
#[cfg(test)]
pub(crate) fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras_permutation(x.reverse_bits(), seed).reverse_bits()
}

fn laine_karras_permutation(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

fn to_unit(x: u32) -> f64 {
    // 32 bits of precision, strictly below 1.
    f64::from(x) * (1.0 / 4_294_967_296.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_power_of_two_prefix_is_stratified_in_both_dimensions() {
        // The (0,2)-sequence property: the first 2^m points put exactly one
        // point in every elementary interval of area 2^-m, and scrambling
        // preserves that.
        for m in 0..=8u32 {
            let n = 1u32 << m;
            for split in 0..=m {
                let (cols, rows) = (1u32 << split, 1u32 << (m - split));
                let mut seen = vec![false; (cols * rows) as usize];
                for i in 0..n {
                    let [x, y] = owen_sobol_2d(i, 12345);
                    let cell = ((y * f64::from(rows)) as u32) * cols + (x * f64::from(cols)) as u32;
                    assert!(
                        !seen[cell as usize],
                        "m={m} split={split}: two points in cell {cell}"
                    );
                    seen[cell as usize] = true;
                }
            }
        }
    }

    #[test]
    fn the_pascal_transform_equals_the_bit_by_bit_generator_matrix() {
        let mut rng = crate::sampling::Rng::new(3, 4);
        for i in (0..4096u32).chain((0..4096).map(|_| (rng.next_u64() >> 32) as u32)) {
            assert_eq!(
                sobol_dimension_1(i),
                sobol_dimension_1_by_bits(i),
                "index {i}"
            );
        }
        // Joe & Kuo's second dimension has m = 1, 3, 5, 15: direction
        // numbers 1/2, 3/4, 5/8, 15/16, so indices 1, 2, 3, 4, 8 give
        // 1/2, 3/4, 1/2 ⊕ 3/4 = 1/4, 5/8, 15/16.
        let first: Vec<f64> = [1, 2, 3, 4, 8]
            .map(|i| to_unit(sobol_dimension_1(i)))
            .to_vec();
        assert_eq!(first, vec![0.5, 0.75, 0.25, 0.625, 0.9375]);
    }

    #[test]
    fn the_cancelled_reversals_equal_the_written_out_definition() {
        // x = nus(sobol₀(nus(i, s₀)), s₁), y = nus(sobol₁(nus(i, s₀)), s₂),
        // computed the long way with the bit-by-bit generator.
        for seed in [0u64, 7, 0xdead_beef] {
            let [s0, s1, s2] = scramble_seeds(seed);
            for i in 0..1024u32 {
                let shuffled = nested_uniform_scramble(i, s0);
                let x = nested_uniform_scramble(sobol_dimension_0(shuffled), s1);
                let y = nested_uniform_scramble(sobol_dimension_1_by_bits(shuffled), s2);
                assert_eq!(
                    owen_sobol_2d(i, seed),
                    [to_unit(x), to_unit(y)],
                    "index {i}"
                );
            }
        }
    }

    #[test]
    fn different_pixels_get_different_points() {
        let a = PixelSampler::new(1, 10).batch(0).stream(0).next_2d();
        let b = PixelSampler::new(1, 11).batch(0).stream(0).next_2d();
        assert_ne!(a, b);
    }

    #[test]
    fn a_stream_is_a_pure_function_of_its_coordinates() {
        let draw = || {
            let pixel = PixelSampler::new(9, 77);
            let batch = pixel.batch(5);
            let mut s = batch.stream(0);
            (0..10).map(|_| s.next_2d()).collect::<Vec<_>>()
        };
        assert_eq!(draw(), draw());
    }

    #[test]
    fn per_pixel_seeds_give_the_per_sample_definition() {
        // Each stream must be what it was when every call hashed its pair's
        // seeds itself: pair p of sample i is point i of the sequence with
        // seed pixel_seed ⊕ p·0x9e3779b9, and the tail is SplitMix64 stream
        // i of pixel_seed.
        for (seed, pixel_index) in [(0u64, 0u64), (1, 10), (0xfeed, 123_456), (u64::MAX, 7)] {
            let pixel = PixelSampler::new(seed, pixel_index);
            let pixel_seed = mix64(seed ^ mix64(pixel_index.wrapping_add(0x5851_f42d_4c95_7f2d)));
            for i in [0u32, 1, 2, 3, 15, 16, 63, 1000, u32::MAX] {
                // Sample i from batches starting at i and at i − 3 (lane 3).
                let (batch, shifted) = (pixel.batch(i), pixel.batch(i.wrapping_sub(3)));
                let mut stream = batch.stream(0);
                let mut from_lane_3 = shifted.stream(3);
                let mut tail = Rng::new(pixel_seed, u64::from(i));
                for pair in 0..SOBOL_PAIRS {
                    let expected = owen_sobol_2d(i, pixel_seed ^ (u64::from(pair) * 0x9e37_79b9));
                    assert_eq!(
                        stream.next_2d(),
                        expected,
                        "pixel {pixel_index} sample {i} pair {pair}"
                    );
                    assert_eq!(from_lane_3.next_2d(), expected, "lane 3, sample {i}");
                }
                assert_eq!(stream.next_2d(), [tail.next_f64(), tail.next_f64()]);
                assert_eq!(stream.next_1d(), tail.next_f64());
            }
        }
    }

    #[test]
    fn pairs_made_when_drawn_equal_those_made_with_the_batch() {
        // A batch that makes only its first pairs ahead draws, in every
        // lane, the numbers of the batch that made them all: the later
        // pairs made on demand, then the same tail. Full and partial
        // batches, every eager count.
        for (seed, pixel_index, first) in [(0u64, 0u64, 0u32), (5, 99, 64), (7, 3, u32::MAX - 2)] {
            let pixel = PixelSampler::new(seed, pixel_index);
            let complete = pixel.batch(first);
            for lanes in [SAMPLE_BATCH, 5] {
                for eager_pairs in 0..=SOBOL_PAIRS + 1 {
                    let mut lazy = SampleBatch::default();
                    pixel.refill(&mut lazy, first, lanes, eager_pairs);
                    for lane in 0..lanes {
                        let (mut expected, mut drawn) = (complete.stream(lane), lazy.stream(lane));
                        for draw in 0..SOBOL_PAIRS + 2 {
                            assert_eq!(
                                drawn.next_2d(),
                                expected.next_2d(),
                                "eager {eager_pairs}, lane {lane}, draw {draw}"
                            );
                        }
                        assert_eq!(drawn.next_1d(), expected.next_1d());
                    }
                }
            }
        }
    }

    #[test]
    fn the_vectorised_batch_equals_one_lane_at_a_time() {
        // `fill_batch`'s lane loops against the scalar loop of a partial
        // batch, for every lane. Integer arithmetic: same bits.
        for (seed, pixel_index, first) in [(0u64, 0u64, 0u32), (5, 99, 64), (7, 3, u32::MAX - 2)] {
            let pixel = PixelSampler::new(seed, pixel_index);
            let mut portable = [[[0.0; 2]; SOBOL_PAIRS as usize]; SAMPLE_BATCH as usize];
            fill_lanes_one_by_one(&pixel.pair_seeds, first, SAMPLE_BATCH, &mut portable);
            assert_eq!(pixel.batch(first).points, portable, "first sample {first}");
            // A partial batch (a pixel's last samples) one lane at a time.
            for lanes in [1, 3, SAMPLE_BATCH - 1] {
                let mut partial = SampleBatch::default();
                pixel.refill(&mut partial, first, lanes, SOBOL_PAIRS);
                let n = lanes as usize;
                assert_eq!(partial.points[..n], portable[..n], "{lanes} lanes");
            }
        }
    }
}
