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
//!    code (`dither_offset_lsb`), which turns the banding of smooth
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

use crate::render::film::Film;
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
        let table = srgb_code_table();
        let row_bytes = width as usize * 3;
        let mut bytes = vec![0u8; row_bytes * height as usize];
        bytes
            .par_chunks_mut(row_bytes.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                for (x, out) in row.chunks_exact_mut(3).enumerate() {
                    let index = y * width as usize + x;
                    let rgb = linear.get(index).copied().unwrap_or([0.0; 3]);
                    let codes = self.encode_pixel_with(table, scale, rgb, x as u32, y as u32);
                    out.copy_from_slice(&codes);
                }
            });
        image::RgbImage::from_raw(width, height, bytes)
            .expect("the buffer holds width × height RGB pixels")
    }

    /// [`DisplayTransform::encode`] of a whole film's radiance, at its size.
    pub fn encode_film(&self, film: &Film) -> image::RgbImage {
        self.encode(&film.rgb, film.width, film.height)
    }

    /// The 8-bit sRGB code of one linear pixel at film position (x, y),
    /// given `scale` = 2^exposure_ev (computed once per image): the
    /// definition, through [`srgb_encode`] and [`dither_offset_lsb`].
    #[cfg(test)]
    fn encode_pixel(&self, scale: f64, rgb: [f32; 3], x: u32, y: u32) -> [u8; 3] {
        let mut codes = [0u8; 3];
        for (channel, (&value, code)) in rgb.iter().zip(codes.iter_mut()).enumerate() {
            let display = self.display_value(scale, value);
            let offset = dither_offset_lsb(x, y, channel as u32, self.dither_seed);
            *code = quantize_u8(srgb_encode(display), offset);
        }
        codes
    }

    /// [`Self::encode_pixel`] as the encoder runs it: the pixel's dither
    /// hash once for its three channels and the sRGB code from `table`
    /// (same bytes, see the tests).
    fn encode_pixel_with(
        &self,
        table: &SrgbCodeTable,
        scale: f64,
        rgb: [f32; 3],
        x: u32,
        y: u32,
    ) -> [u8; 3] {
        let offsets = dither_offsets_lsb(x, y, self.dither_seed);
        std::array::from_fn(|channel| {
            table.code(self.display_value(scale, rgb[channel]), offsets[channel])
        })
    }

    /// Exposure and tone curve: the display-linear value in [0, 1] of one
    /// scene-linear channel `value`, given `scale` = 2^exposure_ev.
    fn display_value(&self, scale: f64, value: f32) -> f64 {
        let exposed = sanitize(value as f64) * scale;
        match self.curve {
            ToneCurve::Filmic => filmic(sanitize(exposed)),
            ToneCurve::Linear => sanitize(exposed).min(1.0),
        }
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
#[cfg(test)]
pub(crate) fn dither_offset_lsb(x: u32, y: u32, channel: u32, seed: u64) -> f64 {
    channel_dither_offset_lsb(dither_pixel_hash(x, y, seed), channel)
}

/// [`dither_offset_lsb`] of the three channels of pixel (x, y), sharing
/// the pixel's hash (the same three numbers).
fn dither_offsets_lsb(x: u32, y: u32, seed: u64) -> [f64; 3] {
    let pixel_hash = dither_pixel_hash(x, y, seed);
    [0, 1, 2].map(|channel| channel_dither_offset_lsb(pixel_hash, channel))
}

/// The seed and the packed pixel position folded through [`mix64`].
fn dither_pixel_hash(x: u32, y: u32, seed: u64) -> u64 {
    let pixel = u64::from(y) << 32 | u64::from(x);
    mix64(mix64(seed ^ 0x6a09_e667_f3bc_c908) ^ pixel)
}

/// The offset of `channel` from its pixel's hash.
fn channel_dither_offset_lsb(pixel_hash: u64, channel: u32) -> f64 {
    let bits = mix64(pixel_hash ^ u64::from(channel).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    // 53 bits, centred in their cell: (k + ½)/2^53 ∈ (0, 1), never 0 or 1.
    let unit = ((bits >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64);
    unit - 0.5
}

/// Intervals of [`SrgbCodeTable`] over display-linear [0, 1].
const SRGB_TABLE_INTERVALS: usize = 4096;

/// Margin, in codes, by which [`SrgbCodeTable::code`] widens its bracket:
/// far above every rounding in it (the values are below 258, where an f64
/// ulp is 6·10⁻¹⁴; `powf` is within an ulp of the true power), far below
/// the width of an interval (≥ 0.01 codes), so it rarely costs a fallback.
const SRGB_TABLE_MARGIN: f64 = 1e-9;

/// 255·[`srgb_encode`] + 1.5 at display values i/4096, i = 0…4096: the
/// quantisation sum `255·encoded + 0.5 + offset` of `quantize_u8` at the
/// interval ends, plus 1 so that every bracket is positive (see
/// [`SrgbCodeTable::code`]).
pub(crate) struct SrgbCodeTable {
    shifted_codes: Vec<f64>,
}

/// The table, built once per process (4097 `powf`).
pub(crate) fn srgb_code_table() -> &'static SrgbCodeTable {
    static TABLE: std::sync::OnceLock<SrgbCodeTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| SrgbCodeTable {
        shifted_codes: (0..=SRGB_TABLE_INTERVALS)
            .map(|i| {
                let display = i as f64 / SRGB_TABLE_INTERVALS as f64;
                srgb_encode(display).clamp(0.0, 1.0) * 255.0 + 1.5
            })
            .collect(),
    })
}

impl SrgbCodeTable {
    /// `quantize_u8(srgb_encode(display), offset_lsb)`, the same byte,
    /// mostly without the `powf`.
    ///
    /// srgb_encode increases on each branch, and its one step down, at the
    /// branch point 0.0031308, is 3·10⁻⁸, far less than it rises across
    /// the interval holding it; so on an interval [xᵢ, xᵢ₊₁] of the table
    /// the sum s = 255·encoded + 0.5 + offset lies between its values at
    /// the ends (to within rounding: the margin). When both ends floor to
    /// the same code, so does s: that code is the answer. Otherwise (an
    /// interval that straddles a code boundary for this offset, about one
    /// in ten) the exact formula decides. The +1 of the table keeps the
    /// bracket positive, so truncation is floor.
    #[inline]
    pub fn code(&self, display: f64, offset_lsb: f64) -> u8 {
        if !(0.0..=1.0).contains(&display) {
            return exact_code(display, offset_lsb);
        }
        let position = display * SRGB_TABLE_INTERVALS as f64;
        // i32 casts: one instruction each (values are in [0, 4096] and
        // (0, 258)), where usize and u32 casts take a dozen without SSE4.
        let i = (position as i32).min(SRGB_TABLE_INTERVALS as i32 - 1) as usize;
        let low = self.shifted_codes[i] + offset_lsb - SRGB_TABLE_MARGIN;
        let high = self.shifted_codes[i + 1] + offset_lsb + SRGB_TABLE_MARGIN;
        let (low_code, high_code) = (low as i32, high as i32);
        if low_code == high_code {
            (low_code.clamp(1, 256) - 1) as u8
        } else {
            exact_code(display, offset_lsb)
        }
    }
}

/// `quantize_u8(srgb_encode(display), offset_lsb)`, the definition: out of
/// line, so that the table's common path stays small where it is inlined.
#[cold]
#[inline(never)]
fn exact_code(display: f64, offset_lsb: f64) -> u8 {
    quantize_u8(srgb_encode(display), offset_lsb)
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

    /// The table's code against the exact formula at `display` with a
    /// spread of dither offsets, the extremes included.
    fn assert_table_matches_exact(table: &SrgbCodeTable, display: f64, salt: u64) {
        let hashed = channel_dither_offset_lsb(mix64(display.to_bits() ^ salt), 0);
        for offset in [hashed, -0.499_999_999_999, 0.0, 0.499_999_999_999, -0.25] {
            assert_eq!(
                table.code(display, offset),
                quantize_u8(srgb_encode(display), offset),
                "display {display:e} ({:#x}), offset {offset}",
                display.to_bits()
            );
        }
    }

    #[test]
    fn srgb_table_gives_the_exact_code_over_a_dense_sweep_of_f32_values() {
        let table = srgb_code_table();
        // Every 37th f32 in [0, 1] (28 million values, every exponent),
        // and 1.0 itself; then inputs outside [0, 1] and NaN.
        let one = 1.0f32.to_bits();
        for bits in (0..one).step_by(37).chain([one]) {
            assert_table_matches_exact(table, f32::from_bits(bits) as f64, 1);
        }
        for display in [
            -0.0,
            -1e-300,
            1.0 + f64::EPSILON,
            2.0,
            f64::INFINITY,
            f64::NAN,
        ] {
            assert_table_matches_exact(table, display, 2);
        }
    }

    #[test]
    fn srgb_table_gives_the_exact_code_at_code_boundaries_and_interval_ends() {
        let table = srgb_code_table();
        let near = |display: f64, salt: u64| {
            for step in -300i64..=300 {
                let bits = (display.to_bits() as i64 + step).max(0) as u64;
                let d = f64::from_bits(bits);
                if d <= 1.0 {
                    assert_table_matches_exact(table, d, salt);
                }
            }
        };
        // Every interval end (and the sRGB branch point) and its neighbours.
        for i in 0..=SRGB_TABLE_INTERVALS {
            near(i as f64 / SRGB_TABLE_INTERVALS as f64, 3);
        }
        near(0.003_130_8, 4);
        // Where the exact code steps from k − 1 to k, found by bisection on
        // the bits of the display value, for offsets across (−½, ½).
        let offsets = (0..40).map(|j| channel_dither_offset_lsb(mix64(j), 1));
        for offset in offsets.chain([-0.499_999_999, 0.0, 0.499_999_999]) {
            let code = |d: f64| quantize_u8(srgb_encode(d), offset);
            for k in 1..=255u8 {
                let (mut below, mut above) = (0u64, 1.0f64.to_bits());
                if code(f64::from_bits(above)) < k {
                    continue;
                }
                while above - below > 1 {
                    let middle = below + (above - below) / 2;
                    if code(f64::from_bits(middle)) >= k {
                        above = middle;
                    } else {
                        below = middle;
                    }
                }
                for step in -200i64..=200 {
                    let d = f64::from_bits((above as i64 + step).max(0) as u64);
                    if d <= 1.0 {
                        assert_eq!(
                            table.code(d, offset),
                            code(d),
                            "k {k}, d {d:e}, offset {offset}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_three_channel_offsets_are_those_of_each_channel() {
        for i in 0..5000u32 {
            let (x, y, seed) = (i % 71, i / 71, u64::from(i % 5) * 0x1234_5678);
            let three = dither_offsets_lsb(x, y, seed);
            for channel in 0..3 {
                assert_eq!(
                    three[channel as usize].to_bits(),
                    dither_offset_lsb(x, y, channel, seed).to_bits()
                );
            }
        }
    }

    #[test]
    fn dither_offset_stays_in_open_half_interval() {
        for i in 0..10_000u32 {
            let d = dither_offset_lsb(i % 97, i / 97, i % 3, 7);
            assert!(d > -0.5 && d < 0.5, "offset {d}");
        }
    }
}
