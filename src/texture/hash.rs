//! Integer hashing of lattice cells: the only source of "randomness" in the
//! solid textures of section 4.3.1.
//!
//! Every random choice a texture makes (where a Voronoi feature point sits,
//! which surface entry a cell picks, whether a glitter cell is filled) is a
//! pure function of `(seed, integer cell coordinates)`, so the same stone looks
//! the same on every run, thread and machine. There is no global or per-thread
//! RNG and nothing to share between rayon workers.
//!
//! # Definition (a contract: tests re-implement it literally)
//!
//! All arithmetic is on `u64` with wrapping addition and multiplication.
//!
//! * [`mix64`] is the SplitMix64 output function (Steele, Lea & Flood 2014,
//!   "Fast splittable pseudorandom number generators", variant "Mix13" of
//!   Stafford's MurmurHash3 finaliser):
//!   `z ^= z >> 30; z *= 0xbf58476d1ce4e5b9; z ^= z >> 27; z *= 0x94d049bb133111eb; z ^= z >> 31`.
//!   It is a bijection on `u64` with full avalanche.
//! * [`seed_key`]`(seed) = mix64(seed + GOLDEN_GAMMA)`: the first output of a
//!   SplitMix64 generator whose state is `seed`.
//! * [`hash_cell`]`(cell, seed)` absorbs the coordinates one at a time, each
//!   sign-extended to 64 bits (`i as i64 as u64`):
//!   `h = seed_key(seed); h = mix64(h + x); h = mix64(h + y); h = mix64(h + z)`.
//!   The chain lets a 3×3×3 neighbourhood search share prefixes
//!   ([`hash_prefix`] for `x`, then `(x, y)`): 1 + 3 + 9 + 27 mixes instead of 27 × 4.
//! * [`derive_stream`]`(h, stream) = mix64(h + (stream + 1) · GOLDEN_GAMMA)`: output
//!   number `stream` of a SplitMix64 generator seeded with `h`, so one cell hash
//!   yields as many independent values as a caller needs.
//!
//! Distinct cells share a hash only by chance (no structured collisions
//! between nearby cells; a 48³ block is tested to be collision-free), so a
//! cell hash is a good label but not a guaranteed-unique key. A different
//! seed starts the chain from an unrelated key, so its pattern is not a
//! shifted or permuted copy of another seed's.

use glam::IVec3;

pub use crate::sampling::mix64;

/// The SplitMix64 increment, ⌊2⁶⁴/φ⌋ (odd): the "golden gamma" of Steele et al. 2014.
pub const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// Turns a user seed into the start of the cell-hash chain: the first output
/// of SplitMix64 with state `seed`. Nearby seeds give unrelated keys.
#[inline(always)]
pub const fn seed_key(seed: u64) -> u64 {
    mix64(seed.wrapping_add(GOLDEN_GAMMA))
}

/// Absorbs one signed lattice coordinate into a running hash:
/// `mix64(h + coordinate)`, the coordinate sign-extended so that negative
/// cells are as good as positive ones.
#[inline(always)]
pub const fn hash_prefix(h: u64, coordinate: i32) -> u64 {
    mix64(h.wrapping_add(coordinate as i64 as u64))
}

/// Hash of the integer lattice cell `cell` under `seed` (see the module
/// documentation for the exact definition). Used as the Voronoi cell id and
/// as the root of every per-cell random choice.
#[inline]
pub const fn hash_cell(cell: IVec3, seed: u64) -> u64 {
    let h = seed_key(seed);
    let h = hash_prefix(h, cell.x);
    let h = hash_prefix(h, cell.y);
    hash_prefix(h, cell.z)
}

/// Value number `stream` derived from a hash: output `stream` of SplitMix64
/// seeded with `h`. Use a different stream per decision (entry choice, fill,
/// facet tilt…) so decisions about one cell are independent.
#[inline(always)]
pub const fn derive_stream(h: u64, stream: u64) -> u64 {
    mix64(h.wrapping_add(stream.wrapping_add(1).wrapping_mul(GOLDEN_GAMMA)))
}

/// Uniform `f64` in `[0, 1)` from the top 53 bits of `h` (every value is a
/// multiple of 2⁻⁵³, so 1.0 is never reached).
#[inline(always)]
pub fn unit_f64(h: u64) -> f64 {
    const INV_2_POW_53: f64 = 1.0 / (1u64 << 53) as f64;
    // < 2⁵³, so the signed conversion is exact (and one instruction on x86-64,
    // unlike u64 → f64).
    ((h >> 11) as i64) as f64 * INV_2_POW_53
}

/// Three 21-bit integers cut from one hash: bits 63..43, 42..22 and 21..1
/// (bit 0 unused). The raw form of [`unit_triple_21bit`], for callers that
/// fold the 2⁻²¹ scale into another factor.
#[inline(always)]
pub const fn triple_21bit(h: u64) -> [u32; 3] {
    const MASK_21: u64 = (1 << 21) - 1;
    [
        (h >> 43) as u32,
        ((h >> 22) & MASK_21) as u32,
        ((h >> 1) & MASK_21) as u32,
    ]
}

/// Three uniform values in `[0, 1)`, multiples of 2⁻²¹, from one hash
/// ([`triple_21bit`] scaled). This is how a Voronoi cell places its feature
/// point with a single hash; a resolution of 2⁻²¹ of a cell is far below
/// anything visible.
#[inline(always)]
pub fn unit_triple_21bit(h: u64) -> [f64; 3] {
    const INV_2_POW_21: f64 = 1.0 / (1u64 << 21) as f64;
    triple_21bit(h).map(|n| n as f64 * INV_2_POW_21)
}
