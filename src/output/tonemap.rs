//! Display transform: scene-linear film → 8-bit sRGB.
//!
//! The renderer's film holds scene-referred linear RGB (radiance, any value
//! ≥ 0). A PNG holds display-referred, sRGB-encoded bytes. Between them, per
//! pixel and per channel:
//!
//! 1. exposure: multiply by `2^exposure_ev` (one EV is one photographic stop);
//! 2. tone curve: [`filmic`] (scene-linear → display-linear in `[0, 1)`) or a
//!    plain clamp to `[0, 1]` ([`ToneCurve::Linear`]);
//! 3. sRGB encoding: [`srgb_encode`], the IEC 61966-2-1 OETF;
//! 4. quantisation to 8 bits with a deterministic dither of less than half a
//!    code ([`dither_offset_lsb`]), which turns the banding of smooth
//!    gradients into unbiased, invisible noise.
//!
//! The curve is applied per channel, not on luminance. Per channel, a very
//! bright saturated colour (a red specular highlight of a ruby) moves towards
//! white as its channels reach the shoulder one after another, as it does on
//! film and as the eye expects of a highlight; every output channel stays in
//! `[0, 1)` by construction. Scaling RGB by `filmic(Y)/Y` instead keeps the
//! hue but pushes the largest channel of a saturated colour above 1, which
//! then needs a gamut-mapping step of its own.

use rayon::prelude::*;

use crate::sampling::mix64;

/// Which tone curve maps exposed scene-linear values to display-linear ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ToneCurve {
    /// [`filmic`]: gentle toe, long shoulder, never clips (the default for
    /// beauty renders, whose highlights are many times brighter than white).
    Filmic,
    /// Clamp to `[0, 1]`: exact for values already in range (tests, albedo
    /// and other AOVs that are meant to be read as data).
    Linear,
}

/// How a linear film becomes display bytes: exposure, tone curve and dither.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayTransform {
    /// Exposure in photographic stops: the film is multiplied by
    /// `2^exposure_ev` before the curve (+1 doubles, −1 halves).
    pub exposure_ev: f64,
    /// The tone curve applied per channel after exposure.
    pub curve: ToneCurve,
    /// Seed of the quantisation dither: the same seed gives the same bytes,
    /// another seed a different (equally unbiased) noise pattern.
    pub dither_seed: u64,
}

impl Default for DisplayTransform {
    /// Exposure 0 EV, [`ToneCurve::Filmic`], dither seed 0.
    fn default() -> Self {
        DisplayTransform {
            exposure_ev: 0.0,
            curve: ToneCurve::Filmic,
            dither_seed: 0,
        }
    }
}

impl DisplayTransform {
    /// Encode linear RGB (scene-referred, row-major, `width * height` pixels)
    /// as an 8-bit sRGB image.
    ///
    /// NaN, infinite and negative channel values are treated as 0, so a
    /// stray bad sample shows as a black dot instead of aborting the write.
    /// A non-finite `exposure_ev` likewise gives black. If `linear` holds
    /// fewer than `width * height` pixels the missing ones are black; extra
    /// pixels are ignored (the caller's film is meant to match exactly).
    ///
    /// Rows are encoded in parallel on the current rayon pool (every pixel
    /// is a pure function of its value and position, so the bytes do not
    /// depend on the thread count): the encoding runs after the render and
    /// would otherwise be serial time in every `render -o x.png`.
    pub fn encode(&self, linear: &[[f32; 3]], width: u32, height: u32) -> image::RgbImage {
        let scale = self.exposure_ev.exp2();
        let row_bytes = width as usize * 3;
        let mut bytes = vec![0u8; row_bytes * height as usize];
        bytes
            .par_chunks_mut(row_bytes.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                for (x, out) in row.chunks_exact_mut(3).enumerate() {
                    let index = y * width as usize + x;
                    let rgb = linear.get(index).copied().unwrap_or([0.0; 3]);
                    out.copy_from_slice(&self.encode_pixel(scale, rgb, x as u32, y as u32));
                }
            });
        image::RgbImage::from_raw(width, height, bytes)
            .expect("the buffer holds width × height RGB pixels")
    }

    /// The 8-bit sRGB code of one linear pixel at film position (x, y),
    /// given `scale` = 2^exposure_ev (computed once per image).
    fn encode_pixel(&self, scale: f64, rgb: [f32; 3], x: u32, y: u32) -> [u8; 3] {
        let mut codes = [0u8; 3];
        for (channel, (&value, code)) in rgb.iter().zip(codes.iter_mut()).enumerate() {
            let exposed = sanitize(value as f64) * scale;
            let display = match self.curve {
                ToneCurve::Filmic => filmic(sanitize(exposed)),
                ToneCurve::Linear => sanitize(exposed).min(1.0),
            };
            let offset = dither_offset_lsb(x, y, channel as u32, self.dither_seed);
            *code = quantize_u8(srgb_encode(display), offset);
        }
        codes
    }
}

/// NaN, ±∞ and negative values become 0; finite non-negative values pass.
fn sanitize(value: f64) -> f64 {
    if value.is_finite() && value > 0.0 {
        value
    } else {
        0.0
    }
}

/// An sRGB-encoded value in `[0, 1]` plus a dither offset in `(−0.5, 0.5)`
/// codes, rounded to the nearest code. With the offset uniform, the
/// expected code is exactly `255·encoded` (rounding `v + u`, `u ~ U(−½, ½)`,
/// gives `⌊v⌋ + 1` with probability `frac(v)`), so dither adds no bias.
/// 0 stays 0 and 1 stays 255 for every offset.
fn quantize_u8(encoded: f64, offset_lsb: f64) -> u8 {
    let code = (encoded.clamp(0.0, 1.0) * 255.0 + 0.5 + offset_lsb).floor();
    code.clamp(0.0, 255.0) as u8
}

/// The dither offset, in units of one 8-bit code (LSB), for pixel `(x, y)`,
/// `channel` (0 = R, 1 = G, 2 = B) and `seed`: uniform in the open interval
/// `(−0.5, 0.5)` and a pure function of its arguments.
///
/// The seed, the packed pixel position and the channel are folded in one
/// after another, each through the SplitMix64 mixer ([`mix64`], a bijection
/// with full avalanche), so neighbouring pixels and channels get
/// independent offsets (white noise, no visible pattern) and the result does
/// not depend on thread count or tile order.
pub fn dither_offset_lsb(x: u32, y: u32, channel: u32, seed: u64) -> f64 {
    let pixel = u64::from(y) << 32 | u64::from(x);
    let pixel_hash = mix64(mix64(seed ^ 0x6a09_e667_f3bc_c908) ^ pixel);
    let bits = mix64(pixel_hash ^ u64::from(channel).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    // 53 bits, centred in their cell: (k + ½)/2^53 ∈ (0, 1), never 0 or 1.
    let unit = ((bits >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64);
    unit - 0.5
}

// Hable's "Uncharted 2" filmic curve constants (J. Hable, "Filmic Tonemapping
// Operators", 2010; GDC 2010 "Uncharted 2: HDR Lighting"): shoulder strength,
// linear strength, linear angle, toe strength, toe numerator, toe denominator.
const HABLE_A: f64 = 0.15;
const HABLE_B: f64 = 0.50;
const HABLE_C: f64 = 0.10;
const HABLE_D: f64 = 0.20;
const HABLE_E: f64 = 0.02;
const HABLE_F: f64 = 0.30;
/// Scene-linear input scale applied before Hable's curve, chosen so that
/// scene mid-grey 0.18 lands on display-linear 0.182 (mid-grey passes
/// through, and exposure 0 EV means "as lit").
const FILMIC_INPUT_SCALE: f64 = 4.0;

/// Hable's rational curve `h(x) = (x(Ax + CB) + DE) / (x(Ax + B) + DF) − E/F`.
/// Above 1 numerator and denominator are divided by `x²`, so huge inputs
/// (up to `f64::MAX`) do not overflow to `∞/∞`.
fn hable(x: f64) -> f64 {
    let ratio = if x <= 1.0 {
        (x * (HABLE_A * x + HABLE_C * HABLE_B) + HABLE_D * HABLE_E)
            / (x * (HABLE_A * x + HABLE_B) + HABLE_D * HABLE_F)
    } else {
        let r = 1.0 / x;
        (HABLE_A + r * (HABLE_C * HABLE_B + r * HABLE_D * HABLE_E))
            / (HABLE_A + r * (HABLE_B + r * HABLE_D * HABLE_F))
    };
    ratio - HABLE_E / HABLE_F
}

/// The filmic tone curve: scene-linear `x ≥ 0` → display-linear `[0, 1)`.
///
/// Hable's Uncharted 2 curve `h` with its published constants
/// (A, B, C, D, E, F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30), evaluated at
/// `4x` and divided by its asymptote `h(∞) = 1 − E/F = 14/15`:
/// `filmic(x) = h(4x) / (1 − E/F)`.
///
/// Why this curve: it is a published, widely used filmic shape with a toe
/// and a shoulder, it is a ratio of quadratics (cheap, smooth, exact at 0),
/// and its properties can be proved rather than hoped for:
/// * `h(0) = DE/DF − E/F = 0`, so black stays black;
/// * `h'(x)` has the sign of `AB(1 − C)x² + 2AD(F − E)x + BD(CF − E)`, whose
///   coefficients are all positive for these constants (`C < 1`, `F > E`,
///   `CF = 0.03 > E`), so the curve is strictly increasing on `x ≥ 0`;
/// * it tends to `1 − E/F` from below, so after the division every finite
///   input maps strictly below 1 — the shoulder is infinitely long and never
///   clips, unlike Hable's original normalisation by `h(W)` at a white point
///   `W = 11.2`, which exceeds 1 above `W`; highlights of 10× white reach
///   0.93, of 100× white 0.992 (sRGB code 254);
/// * the toe is gentle: the slope at black is 1.19 falling to 0.83 at
///   mid-grey, a slight contrast boost in the shadows without crushing them;
/// * the input scale 4 puts mid-grey 0.18 at 0.182 (Hable's own "exposure
///   bias" 2 with `W = 11.2` gives 0.128, noticeably darker).
///
/// NaN and negative inputs give 0; `+∞` gives the limit value 1.
pub fn filmic(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    if x.is_infinite() {
        return 1.0;
    }
    hable(FILMIC_INPUT_SCALE * x) / (1.0 - HABLE_E / HABLE_F)
}

/// The sRGB opto-electronic transfer function of IEC 61966-2-1:
/// `12.92·L` for `L ≤ 0.0031308`, else `1.055·L^(1/2.4) − 0.055`.
///
/// Input is display-linear in `[0, 1]` and is clamped to it (NaN gives 0);
/// the output is the encoded value in `[0, 1]`, 1 at `L = 1`.
pub fn srgb_encode(linear: f64) -> f64 {
    if linear.is_nan() || linear <= 0.0 {
        return 0.0;
    }
    let l = linear.min(1.0);
    if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantize_maps_ends_exactly_for_extreme_offsets() {
        // floor(0.5 + d) = 0 and floor(255.5 + d) = 255 for all |d| < 0.5.
        for offset in [-0.499_999, 0.0, 0.499_999] {
            assert_eq!(quantize_u8(0.0, offset), 0);
            assert_eq!(quantize_u8(1.0, offset), 255);
        }
    }

    #[test]
    fn parallel_rows_give_the_row_major_pixels_whatever_the_thread_count() {
        // A 7 × 5 film given 30 pixels (the last 5 must come out black),
        // with values across the curve, NaN and negatives included.
        let (width, height) = (7u32, 5u32);
        let linear: Vec<[f32; 3]> = (0..30)
            .map(|i| {
                let v = i as f32 * 0.11 - 0.3;
                [v, v * 2.0, if i == 4 { f32::NAN } else { v * 0.5 }]
            })
            .collect();
        let transform = DisplayTransform {
            exposure_ev: 0.5,
            dither_seed: 11,
            ..DisplayTransform::default()
        };
        let mut expected = Vec::new();
        for y in 0..height {
            for x in 0..width {
                let index = (y * width + x) as usize;
                let rgb = linear.get(index).copied().unwrap_or([0.0; 3]);
                expected.extend_from_slice(&transform.encode_pixel(
                    transform.exposure_ev.exp2(),
                    rgb,
                    x,
                    y,
                ));
            }
        }
        assert_eq!(&expected[30 * 3..], &[0u8; 15][..]);
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            let image = pool.install(|| transform.encode(&linear, width, height));
            assert_eq!((image.width(), image.height()), (width, height));
            assert_eq!(image.into_raw(), expected, "{threads} threads");
        }
        // An empty film is an empty image, not a panic.
        assert_eq!(transform.encode(&[], 0, 3).into_raw(), Vec::<u8>::new());
    }

    #[test]
    fn dither_offset_stays_in_open_half_interval() {
        for i in 0..10_000u32 {
            let d = dither_offset_lsb(i % 97, i / 97, i % 3, 7);
            assert!(d > -0.5 && d < 0.5, "offset {d}");
        }
    }
}
