//! Deterministic random numbers and hemisphere warps shared by the BRDF
//! estimators and the renderer.
//!
//! Every estimator in lapidary is a pure function of its seed: there is no
//! global RNG. [`Rng`] is SplitMix64 (Steele, Lea & Flood 2014), small,
//! fast, and identical on every platform.

use glam::DVec3;
use std::f64::consts::PI;

/// A SplitMix64 generator: a 64-bit counter passed through a strong mixer.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator for one independent stream, e.g. `Rng::new(seed, angle_index)`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Rng {
            state: seed ^ mix64(stream.wrapping_add(0x632b_e59b_d9b4_e019)),
        };
        rng.next_u64();
        rng
    }

    /// A generator keyed by the bits of `numbers` (salted by `salt`): the
    /// further uniforms a sampler needs past the point it was given (a
    /// rejection's redraws, a choice), so that they are a pure function of
    /// that point and a stratified point stays stratified.
    pub fn keyed_by(salt: u64, numbers: &[f64]) -> Self {
        let key = numbers
            .iter()
            .fold(salt, |hash, x| mix64(hash ^ x.to_bits()));
        Rng::new(key, 0)
    }

    /// The next 64 uniformly distributed bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// A uniform number in [0, 1) with 53 bits of precision.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Three uniform numbers, the argument every `sample` function takes.
    pub fn next_3(&mut self) -> [f64; 3] {
        [self.next_f64(), self.next_f64(), self.next_f64()]
    }
}

/// SplitMix64's output function (Stafford "Mix13"; Steele, Lea & Flood
/// 2014): a cheap bijection on u64 with full avalanche, the building block
/// of every hash and stream here and of the textures' cell hashes.
#[inline(always)]
pub const fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// (sin 2πt, cos 2πt) for an angle of `t` turns, to within 3·10⁻¹⁴: the
/// azimuth of every sampled direction. The angle is reduced to the nearest
/// quarter turn q/4 and a remainder x ∈ [−π/4, π/4], whose sine and cosine
/// are Taylor polynomials to x¹³ and x¹⁴ (the first omitted terms are below
/// (π/4)¹⁵/15! ≈ 2·10⁻¹⁴ and (π/4)¹⁶/16! ≈ 10⁻¹⁵); several times faster
/// than libm's `sin_cos`, which rounds correctly at a cost no sample needs.
pub(crate) fn sin_cos_turns(t: f64) -> (f64, f64) {
    let (quarter, quadrant) = nearest_quarter_turn(t);
    let x = (t - quarter * 0.25) * (2.0 * PI);
    let x2 = x * x;
    // Horner forms of Σ (−1)ᵏ x²ᵏ⁺¹/(2k+1)! and Σ (−1)ᵏ x²ᵏ/(2k)!, started
    // at the highest coefficient (the same sums as folding from 0, where
    // the first step c + x²·0 = c is exact, with two operations fewer).
    let sin_terms = [
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
    ];
    let cos_terms = [
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
        -1.0 / 87_178_291_200.0,
    ];
    let horner = |terms: &[f64]| {
        let (last, rest) = terms.split_last().expect("non-empty");
        rest.iter().rev().fold(*last, |acc, c| c + x2 * acc)
    };
    let sin = x * (1.0 + x2 * horner(&sin_terms));
    let cos = 1.0 + x2 * horner(&cos_terms);
    // sin and cos of q·π/2 + x: (sin, cos), (cos, −sin), (−sin, −cos),
    // (−cos, sin) for q = 0…3. The pair swaps for odd q, the sine is
    // negated for q = 2, 3 (bit 1 of q) and the cosine for q = 1, 2 (bit 1
    // of q + 1): a select and two sign flips rather than a match, which
    // compile to blends with no branch (the same bits: a negation is
    // exact).
    let odd = quadrant & 1 == 1;
    let (sin_abs, cos_abs) = if odd { (cos, sin) } else { (sin, cos) };
    (
        f64::from_bits(sin_abs.to_bits() ^ ((quadrant & 2) << 62)),
        f64::from_bits(cos_abs.to_bits() ^ (((quadrant + 1) & 2) << 62)),
    )
}

/// The nearest quarter turn q to `t` turns, as q and as q mod 4. Rounds by
/// adding and subtracting 1.5·2⁵², which leaves no fraction bits
/// (`f64::round` is a library call on x86-64 without SSE4.1); exact for
/// |4t| < 2⁵¹. The sum 1.5·2⁵² + q has an ulp of 1, so its lowest
/// mantissa bits are those of 2⁵¹ + q: q mod 4, read without a float to
/// integer conversion.
fn nearest_quarter_turn(t: f64) -> (f64, u64) {
    const ROUNDER: f64 = 6_755_399_441_055_744.0;
    let shifted = t * 4.0 + ROUNDER;
    (shifted - ROUNDER, shifted.to_bits() & 3)
}

/// Cosine-weighted direction on the upper hemisphere (z up); pdf = cosθ/π.
pub fn cosine_hemisphere(u1: f64, u2: f64) -> DVec3 {
    let r = u1.sqrt();
    let (sin_phi, cos_phi) = sin_cos_turns(u2);
    DVec3::new(r * cos_phi, r * sin_phi, (1.0 - u1).max(0.0).sqrt())
}

/// Density of [`cosine_hemisphere`] with respect to solid angle.
pub fn cosine_hemisphere_pdf(w: DVec3) -> f64 {
    if w.z > 0.0 {
        w.z / PI
    } else {
        0.0
    }
}

/// Unit direction from spherical angles in degrees (θ from the normal z, φ from x).
pub fn direction_from_degrees(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// The unit vector along `v`, for any finite non-zero `v` (a direction a
/// user wrote): `v.normalize()` where its squared length is a normal
/// number, else `v` scaled by its largest component first, so that
/// (1e-300, 0, 1e-300) and (0.1, −1e300, 1) have their directions too
/// (their squared lengths underflow to 0 or overflow to ∞). None for a
/// zero, infinite or NaN `v`.
pub(crate) fn unit_direction(v: DVec3) -> Option<DVec3> {
    if !v.is_finite() {
        return None;
    }
    let length_squared = v.length_squared();
    if length_squared.is_finite() && length_squared >= f64::MIN_POSITIVE {
        return Some(v.normalize());
    }
    let largest = v.abs().max_element();
    (largest > 0.0).then(|| (v / largest).normalize())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_direction_of_any_finite_size_has_its_unit_vector() {
        let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-15;
        let diagonal = DVec3::new(1.0, 0.0, 1.0) / 2f64.sqrt();
        assert!(close(
            unit_direction(DVec3::new(1e-300, 0.0, 1e-300)).unwrap(),
            diagonal
        ));
        assert!(close(
            unit_direction(DVec3::new(1e300, 0.0, 1e300)).unwrap(),
            diagonal
        ));
        assert!(close(
            unit_direction(DVec3::new(0.1, -1e300, 1.0)).unwrap(),
            DVec3::NEG_Y
        ));
        assert!(close(
            unit_direction(DVec3::new(5e-324, 0.0, 0.0)).unwrap(),
            DVec3::X
        ));
        // An ordinary direction: `normalize`'s own bits.
        let v = DVec3::new(0.1, -0.6, 1.0);
        assert_eq!(unit_direction(v), Some(v.normalize()));
        for bad in [
            DVec3::ZERO,
            DVec3::new(f64::NAN, 0.0, 1.0),
            DVec3::new(f64::INFINITY, 0.0, 0.0),
        ] {
            assert_eq!(unit_direction(bad), None, "{bad}");
        }
    }

    #[test]
    fn turn_sines_match_libm_everywhere_within_3e_14() {
        // Every octant, the reduction's seams at multiples of 1/8 turn, and
        // angles outside one turn.
        let mut worst: f64 = 0.0;
        for i in -4000..=12000 {
            let t = i as f64 / 8000.0 + 1e-9 * (i % 7) as f64;
            let (sin, cos) = sin_cos_turns(t);
            let (sin_ref, cos_ref) = (2.0 * PI * t).sin_cos();
            worst = worst.max((sin - sin_ref).abs()).max((cos - cos_ref).abs());
        }
        assert!(worst < 3e-14, "worst error {worst}");
        // Exact quarter turns give exact axes.
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
    }

    #[test]
    fn the_quadrant_read_from_the_rounder_bits_is_the_quarter_count_mod_4() {
        // Against the integer conversion, for negative and positive angles,
        // on and beside the half-quarter seams where rounding flips.
        let mut rng = Rng::new(5, 6);
        let seams = (-40..=40).flat_map(|k| {
            let seam = (2 * k + 1) as f64 / 8.0;
            [seam, seam - 1e-12, seam + 1e-12, k as f64 / 4.0]
        });
        for t in seams.chain((0..10_000).map(|_| (rng.next_f64() - 0.5) * 1e6)) {
            let (quarter, quadrant) = nearest_quarter_turn(t);
            assert_eq!(quarter, (t * 4.0).round_ties_even(), "t = {t}");
            assert_eq!(quadrant, (quarter as i64 & 3) as u64, "t = {t}");
        }
    }
}
