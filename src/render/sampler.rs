//! Per-pixel sample streams: Owen-scrambled Sobol points for the first
//! dimensions, hashed random numbers after them.
//!
//! The first [`SOBOL_PAIRS`] pairs of dimensions of a pixel's samples (the
//! pixel footprint, the first light and BRDF choices) are the 2-D Sobol
//! (0,2)-sequence, nested-uniform scrambled and with its index shuffled per
//! pixel and per pair, after Burley, "Practical Hash-based Owen Scrambling"
//! (JCGT 2020): each pair is a stratified point set on its own, and pairs
//! are decorrelated from each other by the shuffle ("padding"). Deeper
//! dimensions, where stratification buys little, come from a SplitMix64
//! stream. Every number is a pure function of (seed, pixel, sample index,
//! dimension): which thread renders the pixel does not matter.

use crate::sampling::{mix64, Rng};

/// How many 2-D dimension pairs come from the scrambled Sobol sequence.
pub const SOBOL_PAIRS: u32 = 6;

/// The part of every sample stream of one pixel that does not depend on the
/// sample index: the pixel's seed and the scrambling seeds of its Sobol
/// pairs. Made once per pixel, so that the two hashes per pair are not
/// redone for each of the pixel's samples.
#[derive(Clone, Debug)]
pub struct PixelSampler {
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

    /// The stream of the pixel's sample `sample_index`.
    pub fn stream(&self, sample_index: u32) -> SampleStream<'_> {
        SampleStream {
            pixel: self,
            sample_index,
            // rev by the low halves of the tables: four loads instead of a
            // byte swap and three mask-and-shift steps.
            reversed_index: rev_and_reversed_sobol_1(sample_index) as u32,
            next_pair: 0,
            tail: Rng::new(self.pixel_seed, u64::from(sample_index)),
        }
    }
}

/// The random numbers of one sample of one pixel, drawn in a fixed order.
#[derive(Clone, Debug)]
pub struct SampleStream<'a> {
    pixel: &'a PixelSampler,
    sample_index: u32,
    /// `sample_index` with its bits reversed, computed once per sample.
    reversed_index: u32,
    next_pair: u32,
    tail: Rng,
}

impl SampleStream<'_> {
    /// The next two numbers in [0, 1). Inlined: a call's set-up (the
    /// result through memory, saved registers) is a tenth of its cost.
    #[inline(always)]
    pub fn next_2d(&mut self) -> [f64; 2] {
        let pair = self.next_pair;
        self.next_pair += 1;
        if pair < SOBOL_PAIRS {
            owen_sobol_2d_reversed(self.reversed_index, self.pixel.pair_seeds[pair as usize])
        } else {
            [self.tail.next_f64(), self.tail.next_f64()]
        }
    }

    /// The next single number in [0, 1) (from the hashed tail, so a lone
    /// dimension never breaks the pairing of the Sobol dimensions).
    pub fn next_1d(&mut self) -> f64 {
        self.tail.next_f64()
    }

    /// An independent generator for optional work (ambient occlusion) whose
    /// numbers must not shift the main stream: turning the option on leaves
    /// the beauty image unchanged.
    pub fn side_stream(&self, salt: u64) -> Rng {
        Rng::new(
            mix64(self.pixel.pixel_seed ^ salt),
            u64::from(self.sample_index),
        )
    }

    /// Three numbers for a BRDF sample: a Sobol pair and one more.
    /// Inlined like [`SampleStream::next_2d`].
    #[inline(always)]
    pub fn next_3d(&mut self) -> [f64; 3] {
        let [a, b] = self.next_2d();
        [a, b, self.next_1d()]
    }
}

/// Point `index` of the shuffled, scrambled 2-D Sobol sequence for `seed`.
pub fn owen_sobol_2d(index: u32, seed: u64) -> [f64; 2] {
    owen_sobol_2d_reversed(index.reverse_bits(), scramble_seeds(seed))
}

/// Three independent 32-bit scrambling seeds (index shuffle, x, y) from one
/// 64-bit seed, with two hashes.
fn scramble_seeds(seed: u64) -> [u32; 3] {
    let h = mix64(seed);
    [h as u32, (h >> 32) as u32, mix64(h) as u32]
}

/// [`owen_sobol_2d`] from the bit-reversed index. Written out,
/// x = nus(sobol₀(shuffled)) and y = nus(sobol₁(shuffled)) with
/// shuffled = nus(index) and nus(v) = rev(LK(rev(v))); since sobol₀ = rev,
/// the reversals cancel down to three per point: with r = LK(rev(index)),
/// x = rev(LK(rev(r))) and y = rev(LK(rev ∘ sobol₁ ∘ rev(r))). Both maps
/// of r are linear over GF(2) and share one set of byte tables
/// ([`REV_AND_REVERSED_SOBOL_1_TABLES`]); the last two reversals are done
/// together on one 64-bit word (x86-64 has no bit-reverse instruction, so
/// each reversal is a byte swap and three mask-and-shift steps).
fn owen_sobol_2d_reversed(reversed_index: u32, seeds: [u32; 3]) -> [f64; 2] {
    let r = laine_karras_permutation(reversed_index, seeds[0]);
    let both = rev_and_reversed_sobol_1(r);
    let x = laine_karras_permutation(both as u32, seeds[1]);
    let y = laine_karras_permutation((both >> 32) as u32, seeds[2]);
    // rev(y ‖ x) = rev(x) ‖ rev(y).
    let reversed = ((u64::from(y) << 32) | u64::from(x)).reverse_bits();
    [to_unit((reversed >> 32) as u32), to_unit(reversed as u32)]
}

/// rev(r) in the low and rev(sobol₁(rev(r))) in the high 32 bits.
fn rev_and_reversed_sobol_1(r: u32) -> u64 {
    let [b0, b1, b2, b3] = r.to_le_bytes();
    let t = &REV_AND_REVERSED_SOBOL_1_TABLES;
    t[0][b0 as usize] ^ t[1][b1 as usize] ^ t[2][b2 as usize] ^ t[3][b3 as usize]
}

/// `REV_AND_REVERSED_SOBOL_1_TABLES[k][b]` holds, for v = b << 8k, rev(v)
/// in the low and rev(sobol₁(rev(v))) in the high 32 bits: two GF(2)-linear
/// maps looked up at once.
static REV_AND_REVERSED_SOBOL_1_TABLES: [[u64; 256]; 4] = rev_and_reversed_sobol_1_tables();

const fn rev_and_reversed_sobol_1_tables() -> [[u64; 256]; 4] {
    let reversed_sobol = sobol_1_tables(true);
    let mut tables = [[0u64; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut byte = 0;
        while byte < 256 {
            let v = (byte as u32) << (8 * k);
            tables[k][byte] = (v.reverse_bits() as u64) | ((reversed_sobol[k][byte] as u64) << 32);
            byte += 1;
        }
        k += 1;
    }
    tables
}

/// The first Sobol dimension: the base-2 radical inverse (van der Corput).
pub fn sobol_dimension_0(index: u32) -> u32 {
    index.reverse_bits()
}

/// The second Sobol dimension: direction numbers `v₀ = 2³¹`,
/// `vᵢ = vᵢ₋₁ ⊕ (vᵢ₋₁ >> 1)` (the primitive polynomial x + 1). The product
/// of the generator matrix with the index is linear over GF(2), so it is the
/// XOR of four byte-wise partial products looked up in tables built at
/// compile time (a scrambled index has all 32 bits set at random, so a
/// bit-by-bit loop would run 32 times per point).
pub fn sobol_dimension_1(index: u32) -> u32 {
    by_byte_tables(&SOBOL_1_TABLES, index)
}

/// A GF(2)-linear map of 32-bit words given by its value on every byte.
type ByteTables = [[u32; 256]; 4];

fn by_byte_tables(tables: &ByteTables, v: u32) -> u32 {
    let [b0, b1, b2, b3] = v.to_le_bytes();
    tables[0][b0 as usize]
        ^ tables[1][b1 as usize]
        ^ tables[2][b2 as usize]
        ^ tables[3][b3 as usize]
}

/// `SOBOL_1_TABLES[k][b]` is the second Sobol dimension of `b << 8k`.
static SOBOL_1_TABLES: ByteTables = sobol_1_tables(false);

/// The tables of sobol₁, or with `reversed` of the same map conjugated by
/// bit reversal: v ↦ rev(sobol₁(rev(v))).
const fn sobol_1_tables(reversed: bool) -> ByteTables {
    // The image of every single index bit.
    let mut image = [0u32; 32];
    let mut v = 1u32 << 31;
    let mut bit = 0;
    while bit < 32 {
        if reversed {
            image[31 - bit] = v.reverse_bits();
        } else {
            image[bit] = v;
        }
        v ^= v >> 1;
        bit += 1;
    }
    let mut tables = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut byte = 0;
        while byte < 256 {
            let mut result = 0;
            let mut b = 0;
            while b < 8 {
                if byte & (1 << b) != 0 {
                    result ^= image[8 * k + b];
                }
                b += 1;
            }
            tables[k][byte] = result;
            byte += 1;
        }
        k += 1;
    }
    tables
}

/// The second Sobol dimension bit by bit: the definition the tables are
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
pub fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
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
    fn byte_tables_equal_the_bit_by_bit_generator_matrix() {
        let mut rng = crate::sampling::Rng::new(3, 4);
        for i in (0..4096u32).chain((0..4096).map(|_| (rng.next_u64() >> 32) as u32)) {
            assert_eq!(
                sobol_dimension_1(i),
                sobol_dimension_1_by_bits(i),
                "index {i}"
            );
            let both = rev_and_reversed_sobol_1(i);
            let direct = sobol_dimension_1_by_bits(i.reverse_bits()).reverse_bits();
            assert_eq!((both >> 32) as u32, direct, "reversed, index {i}");
            assert_eq!(both as u32, i.reverse_bits(), "reversal, index {i}");
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
        let a = PixelSampler::new(1, 10).stream(0).next_2d();
        let b = PixelSampler::new(1, 11).stream(0).next_2d();
        assert_ne!(a, b);
    }

    #[test]
    fn a_stream_is_a_pure_function_of_its_coordinates() {
        let draw = || {
            let pixel = PixelSampler::new(9, 77);
            let mut s = pixel.stream(5);
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
                let mut stream = pixel.stream(i);
                let mut tail = Rng::new(pixel_seed, u64::from(i));
                for pair in 0..SOBOL_PAIRS {
                    let expected = owen_sobol_2d(i, pixel_seed ^ (u64::from(pair) * 0x9e37_79b9));
                    assert_eq!(
                        stream.next_2d(),
                        expected,
                        "pixel {pixel_index} sample {i} pair {pair}"
                    );
                }
                assert_eq!(stream.next_2d(), [tail.next_f64(), tail.next_f64()]);
                assert_eq!(stream.next_1d(), tail.next_f64());
            }
        }
    }
}
