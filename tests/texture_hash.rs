//! The cell hash is a contract (module doc of `texture::hash`): these tests
//! re-implement it from its written definition and pin published SplitMix64
//! vectors, then check the statistical properties the textures rely on.

use glam::IVec3;
use lapidary::texture::hash::{
    derive_stream, hash_cell, hash_prefix, mix64, seed_key, unit_f64, unit_triple_21bit,
    GOLDEN_GAMMA,
};

/// SplitMix64's output function, typed in from Steele, Lea & Flood (2014) /
/// Vigna's `splitmix64.c`, independently of the library's code.
fn splitmix64_next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E3779B97F4A7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
    z ^ (z >> 31)
}

/// `hash_cell` as the module documentation defines it, step by step.
fn documented_hash_cell(x: i32, y: i32, z: i32, seed: u64) -> u64 {
    let mix = |v: u64| {
        let mut s = v.wrapping_sub(0x9E3779B97F4A7C15);
        splitmix64_next(&mut s)
    };
    let mut h = mix(seed.wrapping_add(0x9E3779B97F4A7C15));
    for c in [x, y, z] {
        h = mix(h.wrapping_add(c as i64 as u64));
    }
    h
}

#[test]
fn splitmix64_published_vectors_for_seed_zero() {
    // First four outputs of splitmix64.c with state 0 (the values that seed
    // xoshiro in Vigna's reference code).
    let published = [
        0xE220A8397B1DCDAF_u64,
        0x6E789E6AA1B965F4,
        0x06C45D188009454F,
        0xF88BB8A8724C81EC,
    ];
    assert_eq!(seed_key(0), published[0]);
    for (stream, expected) in published.iter().enumerate() {
        assert_eq!(
            derive_stream(0, stream as u64),
            *expected,
            "stream {stream}"
        );
    }
    assert_eq!(mix64(GOLDEN_GAMMA), published[0]);
}

#[test]
fn derive_stream_is_the_splitmix64_sequence_seeded_with_the_hash() {
    for h in [1_u64, 42, 0xDEAD_BEEF_0123_4567, u64::MAX] {
        let mut state = h;
        for stream in 0..5 {
            assert_eq!(derive_stream(h, stream), splitmix64_next(&mut state));
        }
    }
}

#[test]
fn hash_cell_golden_values_follow_the_documented_chain() {
    let cells = [
        (0, 0, 0),
        (1, 0, 0),
        (0, 1, 0),
        (0, 0, 1),
        (1, -2, 3),
        (-1, -1, -1),
        (i32::MIN, i32::MAX, 0),
    ];
    for seed in [0_u64, 42, u64::MAX] {
        for &(x, y, z) in &cells {
            assert_eq!(
                hash_cell(IVec3::new(x, y, z), seed),
                documented_hash_cell(x, y, z, seed),
                "cell ({x}, {y}, {z}) seed {seed}"
            );
        }
    }
    // The chain prefix helper composes to the same value.
    let h = hash_prefix(hash_prefix(hash_prefix(seed_key(7), -3), 4), -5);
    assert_eq!(h, hash_cell(IVec3::new(-3, 4, -5), 7));
}

#[test]
fn unit_values_stay_in_the_half_open_unit_interval() {
    assert_eq!(unit_f64(0), 0.0);
    assert_eq!(unit_f64(u64::MAX), 1.0 - 2f64.powi(-53));
    assert_eq!(unit_f64(1 << 63), 0.5);
    let step = 2f64.powi(-21);
    assert_eq!(unit_triple_21bit(0), [0.0; 3]);
    assert_eq!(unit_triple_21bit(1 << 43), [step, 0.0, 0.0]);
    assert_eq!(unit_triple_21bit(1 << 22), [0.0, step, 0.0]);
    assert_eq!(unit_triple_21bit(1 << 1), [0.0, 0.0, step]);
    assert_eq!(unit_triple_21bit(1), [0.0; 3], "bit 0 is unused");
    assert_eq!(unit_triple_21bit(u64::MAX), [1.0 - step; 3]);
}

/// Chi-square statistic of `values` (in [0,1)) over `bins` equal bins.
fn chi_square(values: &[f64], bins: usize) -> f64 {
    let mut counts = vec![0usize; bins];
    for &v in values {
        counts[(v * bins as f64) as usize] += 1;
    }
    let expected = values.len() as f64 / bins as f64;
    counts
        .iter()
        .map(|&c| (c as f64 - expected).powi(2) / expected)
        .sum()
}

#[test]
fn cell_hashes_are_uniform_distinct_and_uncorrelated() {
    let side = 48;
    let seed = 1234;
    let mut ids = Vec::new();
    let mut components: [Vec<f64>; 3] = Default::default();
    let mut neighbour_products = 0.0;
    for x in -side / 2..side / 2 {
        for y in -side / 2..side / 2 {
            for z in -side / 2..side / 2 {
                let h = hash_cell(IVec3::new(x, y, z), seed);
                ids.push(h);
                for (axis, u) in unit_triple_21bit(h).iter().enumerate() {
                    components[axis].push(*u);
                }
                let next = unit_f64(hash_cell(IVec3::new(x + 1, y, z), seed));
                neighbour_products += (unit_f64(h) - 0.5) * (next - 0.5);
            }
        }
    }
    let n = ids.len() as f64;
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len() as f64, n, "distinct cells must get distinct ids");

    // 32 bins: chi-square with 31 degrees of freedom; 70 is far beyond p = 1e-4.
    for (axis, values) in components.iter().enumerate() {
        let chi2 = chi_square(values, 32);
        assert!(chi2 < 70.0, "axis {axis}: chi2 = {chi2}");
    }
    // Correlation of neighbouring cells: sd of the mean product is 1/(12√n).
    let correlation = neighbour_products / n * 12.0;
    assert!(
        correlation.abs() < 5.0 / n.sqrt(),
        "correlation {correlation}"
    );
    // The three jitter components of one cell are not correlated either.
    let xy: f64 = components[0]
        .iter()
        .zip(&components[1])
        .map(|(a, b)| (a - 0.5) * (b - 0.5))
        .sum::<f64>()
        / n
        * 12.0;
    assert!(xy.abs() < 5.0 / n.sqrt(), "x-y correlation {xy}");
}

#[test]
fn neighbouring_seeds_flip_half_the_bits() {
    let mut flipped = 0u64;
    let trials = 4096u64;
    for i in 0..trials {
        let cell = IVec3::new(
            i as i32 % 16 - 8,
            (i / 16) as i32 % 16 - 8,
            (i / 256) as i32 - 8,
        );
        flipped += (hash_cell(cell, 77) ^ hash_cell(cell, 78)).count_ones() as u64;
    }
    let mean = flipped as f64 / trials as f64;
    // Binomial(64, 1/2): mean 32, sd of the average 4/√4096 = 0.0625.
    assert!((mean - 32.0).abs() < 0.5, "mean flipped bits {mean}");
}
