//! Radiance in 33 bits: three 9-bit mantissas sharing one 6-bit exponent
//! (the idea of OpenGL's `RGB9_E5`, `EXT_texture_shared_exponent`, with a
//! wider exponent), the texel format of environment maps.
//!
//! A texel is `(m_r, m_g, m_b) × 2^(e − 40)` with `m` in `0..512` and `e`
//! in `0..64`: the brightest channel keeps 9 significant bits and the
//! others are rounded to the same step. Encoding rounds to nearest, so
//!
//! * every channel is within **2⁻⁹ × max(r, g, b)** of its source (the
//!   brightest one within 2⁻⁹ of itself; a channel 100× dimmer than the
//!   brightest keeps about 2 significant bits, which matters little next
//!   to the brightest of the same texel), for `max(r, g, b) ≥ 2⁻³²`;
//! * below 2⁻³² the step stays 2⁻⁴⁰ (absolute error ≤ 2⁻⁴¹);
//! * the brightest encodable channel is `511 × 2²³` ≈ 4.29 × 10⁹
//!   ([`MAX_RADIANCE`]); brighter texels are refused, not clipped.
//!
//! Radiance HDR files (8-bit mantissas, shared exponent) are represented
//! exactly within that range; half-float OpenEXR loses two bits of its 11
//! in the brightest channel. Values that are powers of two times a 9-bit
//! integer relative to the brightest channel (the tests' maps) are exact.

use crate::brdf::Rgb;

/// Bits of one mantissa.
const MANTISSA_BITS: u32 = 9;
/// The exponent's offset: a texel is `m × 2^(e − EXPONENT_OFFSET)`.
const EXPONENT_OFFSET: i32 = 40;
/// Bits of the shared exponent.
const EXPONENT_BITS: u32 = 6;
/// Bits one texel takes; the rest of a `u64` is free for its owner.
pub(crate) const TEXEL_BITS: u32 = 3 * MANTISSA_BITS + EXPONENT_BITS;
/// The mask of a texel's bits in a `u64`.
pub(crate) const TEXEL_MASK: u64 = (1 << TEXEL_BITS) - 1;
const MANTISSA_MASK: u64 = (1 << MANTISSA_BITS) - 1;
const EXPONENT_MASK: u64 = (1 << EXPONENT_BITS) - 1;

/// The brightest channel value a texel holds, 511 × 2²³.
pub const MAX_RADIANCE: f64 = 511.0 * (1u64 << 23) as f64;

/// The factor each exponent stands for, times a scale (an environment's
/// `intensity`, applied when decoding so the stored texels are the file's):
/// `scale × 2^(e − 40)` for `e` in `0..64`.
pub(crate) fn exponent_scales(scale: f64) -> [f64; 64] {
    std::array::from_fn(|e| scale * 2f64.powi(e as i32 - EXPONENT_OFFSET))
}

/// The texel of `rgb`, rounded to nearest; `None` for a NaN, infinite or
/// negative channel or one above [`MAX_RADIANCE`].
#[inline]
pub(crate) fn encode(rgb: [f64; 3]) -> Option<u64> {
    // + 0 turns −0 into +0; then, for non-negative finite values, the
    // order of the bit patterns is the order of the values, and a negative
    // (sign bit set), infinite or NaN channel has a pattern above every
    // allowed one: one comparison refuses them all and finds the brightest.
    let [r, g, b] = rgb.map(|c| c + 0.0);
    let max_bits = r.to_bits().max(g.to_bits()).max(b.to_bits());
    if max_bits > MAX_RADIANCE.to_bits() {
        return None;
    }
    // e = ⌊log2 max⌋ + 32 puts max in [256, 512) steps of 2^(e − 40);
    // at least 0 (below 2⁻³² the step stays 2⁻⁴⁰). ⌊log2⌋ from the
    // exponent bits (zero and subnormals read −1023 and get e = 0).
    let floor_log2 = (max_bits >> 52) as i32 - 1023;
    let mut e = (floor_log2 + EXPONENT_OFFSET - MANTISSA_BITS as i32 + 1).max(0);
    let mut inverse = inverse_step(e);
    // x / step is x × (1 / step) exactly (a power of two); adding 2⁵²
    // rounds a value below 2¹⁰ to the nearest integer (ties to even) and
    // leaves it in the low bits of the pattern.
    let nearest = |x: f64| (x + 2f64.powi(52)).to_bits() & 0x3ff;
    // Rounding max up to 512 steps needs the next exponent (then 256).
    if nearest(f64::from_bits(max_bits) * inverse) >= 1 << MANTISSA_BITS {
        e += 1;
        inverse *= 0.5;
    }
    // Unreachable below MAX_RADIANCE (e ≤ 63 there), kept as the format's
    // bound.
    if e > EXPONENT_MASK as i32 {
        return None;
    }
    // Every channel is ≤ max, so its mantissa is at most max's (≤ 511).
    let m = |c: f64| nearest(c * inverse);
    Some(m(r) | m(g) << MANTISSA_BITS | m(b) << (2 * MANTISSA_BITS) | (e as u64) << 27)
}

/// `2^(40 − e)`, one over the step of exponent `e` (`0 ≤ e ≤ 64`), built
/// from its bits.
#[inline]
fn inverse_step(e: i32) -> f64 {
    f64::from_bits(((EXPONENT_OFFSET - e + 1023) as u64) << 52)
}

/// The radiance of the texel in the low [`TEXEL_BITS`] of `bits` (higher
/// bits are ignored), with `scales` from [`exponent_scales`].
#[inline]
pub(crate) fn decode(bits: u64, scales: &[f64; 64]) -> Rgb {
    let scale = scales[((bits >> 27) & EXPONENT_MASK) as usize];
    let m = |shift: u32| ((bits >> shift) & MANTISSA_MASK) as f64;
    Rgb::new(
        m(0) * scale,
        m(MANTISSA_BITS) * scale,
        m(2 * MANTISSA_BITS) * scale,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn every_channel_is_within_its_bound_of_the_source() {
        let scales = exponent_scales(1.0);
        let mut rng = Rng::new(91, 92);
        let mut worst: f64 = 0.0;
        for _ in 0..200_000 {
            // Magnitudes over the whole range, channels up to 10⁶ apart.
            let max = 2f64.powf(rng.next_f64() * 63.0 - 31.5);
            let rgb = [0; 3].map(|_| 1e-6f64.powf(rng.next_f64()));
            let brightest = rgb[0].max(rgb[1]).max(rgb[2]);
            let rgb = rgb.map(|c| max * c / brightest);
            let bits = encode(rgb).unwrap();
            assert_eq!(bits & !TEXEL_MASK, 0);
            let back = decode(bits, &scales).to_array();
            let brightest = rgb[0].max(rgb[1]).max(rgb[2]);
            for (b, c) in back.iter().zip(rgb) {
                let error = (b - c).abs() / brightest;
                assert!(error <= 2f64.powi(-9), "{rgb:?} → {back:?}");
                worst = worst.max(error);
            }
        }
        // The bound is tight: rounding reaches nearly half a step of 2⁻⁸.
        assert!(worst > 0.99 * 2f64.powi(-9), "worst {worst}");
    }

    #[test]
    fn exact_values_range_ends_and_refusals() {
        let scales = exponent_scales(1.0);
        for rgb in [
            [0.0, 0.0, 0.0],
            [1.0, 0.5, 0.25],
            [8.0, 4.0, 2.0],
            [24.0, 12.0, 6.0],
            [1.5, 0.75, 0.375],
            [MAX_RADIANCE, 0.0, 8388608.0],
            [2f64.powi(-40), 0.0, 0.0],
            [511.0 * 2f64.powi(-40), 0.0, 0.0],
        ] {
            assert_eq!(decode(encode(rgb).unwrap(), &scales).to_array(), rgb);
        }
        // Below 2⁻³² the step stays 2⁻⁴⁰, and a tenth of it rounds to black.
        let tiny = 1e-11;
        let back = decode(encode([tiny, 0.0, 0.0]).unwrap(), &scales).x;
        assert!((back - tiny).abs() <= 2f64.powi(-41), "{back}");
        assert_eq!(encode([1e-13, 0.0, 0.0]), Some(0));
        // A value that rounds up to 512 steps moves to the next exponent.
        let just_below_two = 2.0 - 2f64.powi(-12);
        assert_eq!(
            decode(encode([just_below_two, 0.0, 0.0]).unwrap(), &scales).x,
            2.0
        );
        for bad in [f64::NAN, -1.0, f64::INFINITY, MAX_RADIANCE * 1.001] {
            assert_eq!(encode([1.0, bad, 1.0]), None, "{bad}");
        }
        // The scale multiplies every channel.
        let bits = encode([1.0, 0.5, 0.25]).unwrap();
        assert_eq!(
            decode(bits, &exponent_scales(3.0)).to_array(),
            [3.0, 1.5, 0.75]
        );
    }
}
