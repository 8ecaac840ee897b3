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

/// The random numbers of one sample of one pixel, drawn in a fixed order.
#[derive(Clone, Debug)]
pub struct SampleStream {
    pixel_seed: u64,
    sample_index: u32,
    next_pair: u32,
    tail: Rng,
}

impl SampleStream {
    /// The stream of sample `sample_index` of the pixel with flat index
    /// `pixel_index`, for the render seed `seed`.
    pub fn new(seed: u64, pixel_index: u64, sample_index: u32) -> Self {
        let pixel_seed = mix64(seed ^ mix64(pixel_index.wrapping_add(0x5851_f42d_4c95_7f2d)));
        Self {
            pixel_seed,
            sample_index,
            next_pair: 0,
            tail: Rng::new(pixel_seed, u64::from(sample_index)),
        }
    }

    /// The next two numbers in [0, 1).
    pub fn next_2d(&mut self) -> [f64; 2] {
        let pair = self.next_pair;
        self.next_pair += 1;
        if pair < SOBOL_PAIRS {
            let pair_seed = mix64(self.pixel_seed ^ u64::from(pair).wrapping_mul(0x9e37_79b9));
            owen_sobol_2d(self.sample_index, pair_seed)
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
        Rng::new(mix64(self.pixel_seed ^ salt), u64::from(self.sample_index))
    }

    /// Three numbers for a BRDF sample: a Sobol pair and one more.
    pub fn next_3d(&mut self) -> [f64; 3] {
        let [a, b] = self.next_2d();
        [a, b, self.next_1d()]
    }
}

/// Point `index` of the shuffled, scrambled 2-D Sobol sequence for `seed`.
pub fn owen_sobol_2d(index: u32, seed: u64) -> [f64; 2] {
    let shuffled = nested_uniform_scramble(index, hash32(seed, 0));
    let x = nested_uniform_scramble(sobol_dimension_0(shuffled), hash32(seed, 1));
    let y = nested_uniform_scramble(sobol_dimension_1(shuffled), hash32(seed, 2));
    [to_unit(x), to_unit(y)]
}

/// The first Sobol dimension: the base-2 radical inverse (van der Corput).
pub fn sobol_dimension_0(index: u32) -> u32 {
    index.reverse_bits()
}

/// The second Sobol dimension: direction numbers `v₀ = 2³¹`,
/// `vᵢ = vᵢ₋₁ ⊕ (vᵢ₋₁ >> 1)` (the primitive polynomial x + 1).
pub fn sobol_dimension_1(mut index: u32) -> u32 {
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

fn hash32(seed: u64, salt: u64) -> u32 {
    (mix64(seed ^ salt.wrapping_mul(0xd6e8_feb8_6659_fd93)) >> 32) as u32
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
    fn different_pixels_get_different_points() {
        let a = SampleStream::new(1, 10, 0).next_2d();
        let b = SampleStream::new(1, 11, 0).next_2d();
        assert_ne!(a, b);
    }

    #[test]
    fn a_stream_is_a_pure_function_of_its_coordinates() {
        let draw = || {
            let mut s = SampleStream::new(9, 77, 5);
            (0..10).map(|_| s.next_2d()).collect::<Vec<_>>()
        };
        assert_eq!(draw(), draw());
    }
}
