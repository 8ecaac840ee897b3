//! Bitmap text for plots: font8x8 glyphs scaled by an integer factor.
//!
//! The plots need a handful of labels ("θi = 30°", "max 0.52") and nothing
//! more, so text is drawn pixel by pixel from the 8×8 public-domain glyphs of
//! `font8x8` instead of pulling in a font rasteriser. Glyphs are looked up in
//! the Basic Latin, Latin-1 (for `°`, `·`) and Greek (for `θ`) tables; a
//! character missing from all of them is drawn as `?` so that a gap in a label
//! is visible rather than silent.

use font8x8::{UnicodeFonts, BASIC_FONTS, GREEK_FONTS, LATIN_FONTS};
use image::{Rgb, RgbImage};

/// Width and height of one unscaled glyph cell, in pixels.
pub(crate) const GLYPH_SIZE: u32 = 8;

/// θ drawn as a full-height 'O' with a bar. font8x8's θ is x-height and
/// reads as 'e' at plot sizes, and "θi" is the label a reader looks for first.
const THETA: [u8; 8] = [0x1C, 0x36, 0x63, 0x7F, 0x63, 0x36, 0x1C, 0x00];

/// The 8×8 bitmap of `ch` (each byte one row, bit 0 the leftmost pixel), or
/// the bitmap of `?` when no table holds `ch`.
pub(crate) fn glyph(ch: char) -> [u8; 8] {
    if ch == 'θ' {
        return THETA;
    }
    BASIC_FONTS
        .get(ch)
        .or_else(|| LATIN_FONTS.get(ch))
        .or_else(|| GREEK_FONTS.get(ch))
        .or_else(|| BASIC_FONTS.get('?'))
        .unwrap_or([0; 8])
}

/// Width in pixels of `text` drawn at `scale` (every glyph advances by one
/// full cell; the font is monospaced), so callers can centre or right-align.
pub(crate) fn text_width(text: &str, scale: u32) -> u32 {
    let chars = u32::try_from(text.chars().count()).unwrap_or(u32::MAX);
    chars.saturating_mul(GLYPH_SIZE).saturating_mul(scale)
}

/// Height in pixels of one line of text at `scale`.
pub(crate) fn text_height(scale: u32) -> u32 {
    GLYPH_SIZE.saturating_mul(scale)
}

/// A rectangle of the image that drawing may touch; everything outside it is
/// left alone (used to keep a panel's labels inside that panel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ClipRect {
    /// Leftmost column that may be written.
    pub left: u32,
    /// Topmost row that may be written.
    pub top: u32,
    /// Number of writable columns.
    pub width: u32,
    /// Number of writable rows.
    pub height: u32,
}

impl ClipRect {
    /// The whole of `img`.
    pub(crate) fn of_image(img: &RgbImage) -> Self {
        Self {
            left: 0,
            top: 0,
            width: img.width(),
            height: img.height(),
        }
    }

    /// Column and row ranges [start, end) of the rectangle, within `img`.
    fn ranges(&self, img: &RgbImage) -> ((i64, i64), (i64, i64)) {
        let span = |start: u32, len: u32, limit: u32| {
            let end = u64::from(start) + u64::from(len);
            (i64::from(start), end.min(u64::from(limit)) as i64)
        };
        (
            span(self.left, self.width, img.width()),
            span(self.top, self.height, img.height()),
        )
    }
}

/// Draws `text` with its top-left corner at (`x`, `y`), each glyph pixel
/// becoming a `scale`×`scale` block of `colour`.
///
/// Only set glyph pixels are written (the background shows through), and
/// pixels falling outside the image are skipped, so labels near an edge are
/// clipped instead of panicking. Returns the advance width in pixels.
pub(crate) fn draw_text(
    img: &mut RgbImage,
    x: i64,
    y: i64,
    text: &str,
    scale: u32,
    colour: Rgb<u8>,
) -> u32 {
    let clip = ClipRect::of_image(img);
    draw_text_clipped(img, clip, (x, y), text, scale, colour)
}

/// Like [`draw_text`] with the top-left corner at `at`, but writes only
/// pixels inside `clip`.
pub(crate) fn draw_text_clipped(
    img: &mut RgbImage,
    clip: ClipRect,
    at: (i64, i64),
    text: &str,
    scale: u32,
    colour: Rgb<u8>,
) -> u32 {
    let cell = i64::from(GLYPH_SIZE) * i64::from(scale);
    let pen = Pen {
        clip: clip.ranges(img),
        scale: i64::from(scale),
        colour,
    };
    for (i, ch) in text.chars().enumerate() {
        let gx = at.0.saturating_add((i as i64).saturating_mul(cell));
        pen.glyph(img, gx, at.1, glyph(ch));
    }
    text_width(text, scale)
}

/// Draws `text` horizontally centred on `cx` with its top edge at `y`,
/// writing only inside `clip`.
pub(crate) fn draw_text_centred(
    img: &mut RgbImage,
    clip: ClipRect,
    (cx, y): (i64, i64),
    text: &str,
    scale: u32,
    colour: Rgb<u8>,
) {
    let half = i64::from(text_width(text, scale) / 2);
    draw_text_clipped(img, clip, (cx.saturating_sub(half), y), text, scale, colour);
}

/// Everything a glyph needs besides its bitmap and position.
struct Pen {
    /// Writable column and row ranges [start, end).
    clip: ((i64, i64), (i64, i64)),
    scale: i64,
    colour: Rgb<u8>,
}

impl Pen {
    /// Draws one glyph bitmap with its top-left corner at (`x`, `y`).
    fn glyph(&self, img: &mut RgbImage, x: i64, y: i64, rows: [u8; 8]) {
        for (row, bits) in rows.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    let px = x.saturating_add(col * self.scale);
                    let py = y.saturating_add(row as i64 * self.scale);
                    self.block(img, px, py);
                }
            }
        }
    }

    /// Fills the scale×scale square at (`x`, `y`), clipped.
    fn block(&self, img: &mut RgbImage, x: i64, y: i64) {
        let ((cx0, cx1), (cy0, cy1)) = self.clip;
        let (x0, x1) = (x.max(cx0), x.saturating_add(self.scale).min(cx1));
        let (y0, y1) = (y.max(cy0), y.saturating_add(self.scale).min(cy1));
        for py in y0..y1 {
            for px in x0..x1 {
                img.put_pixel(px as u32, py as u32, self.colour);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
    const BLACK: Rgb<u8> = Rgb([0, 0, 0]);

    fn is_dark(p: &Rgb<u8>) -> bool {
        p.0.iter().all(|&c| c < 128)
    }

    #[test]
    fn text_sets_exactly_the_glyph_pixels_inside_its_box() {
        let mut img = RgbImage::from_pixel(60, 40, WHITE);
        let (x0, y0, scale) = (5_u32, 7_u32, 2_u32);
        let advance = draw_text(&mut img, x0.into(), y0.into(), "A7", scale, BLACK);
        assert_eq!(advance, 32);
        let glyphs = [glyph('A'), glyph('7')];
        let mut dark = 0;
        for (x, y, p) in img.enumerate_pixels() {
            let inside = (x0..x0 + 32).contains(&x) && (y0..y0 + 16).contains(&y);
            if !inside {
                assert!(
                    !is_dark(p),
                    "dark pixel outside the glyph box at ({x}, {y})"
                );
                continue;
            }
            let (lx, ly) = ((x - x0) / scale, (y - y0) / scale);
            let rows = glyphs[(lx / 8) as usize];
            let bit = rows[ly as usize] & (1 << (lx % 8)) != 0;
            assert_eq!(is_dark(p), bit, "pixel ({x}, {y}) disagrees with the glyph");
            dark += usize::from(bit);
        }
        assert!(dark > 20, "only {dark} glyph pixels drawn");
    }

    #[test]
    fn theta_and_degree_glyphs_exist() {
        let question = glyph('?');
        for ch in ['θ', '°', '·'] {
            assert_ne!(glyph(ch), question, "{ch} falls back to '?'");
            assert_ne!(glyph(ch), [0; 8]);
        }
    }

    #[test]
    fn clipped_text_stays_inside_its_rectangle() {
        let mut img = RgbImage::from_pixel(40, 20, WHITE);
        let clip = ClipRect {
            left: 4,
            top: 2,
            width: 10,
            height: 6,
        };
        draw_text_clipped(&mut img, clip, (0, 0), "MMMM", 1, BLACK);
        for (x, y, p) in img.enumerate_pixels() {
            let inside = (4..14).contains(&x) && (2..8).contains(&y);
            assert!(
                inside || !is_dark(p),
                "dark pixel outside the clip at ({x}, {y})"
            );
        }
        assert!(img.pixels().any(is_dark));
    }

    #[test]
    fn text_is_clipped_at_the_image_edges() {
        let mut img = RgbImage::from_pixel(10, 10, WHITE);
        draw_text(&mut img, -12, 4, "WWW", 3, BLACK);
        draw_text(&mut img, i64::MAX - 3, i64::MIN, "x", u32::MAX, BLACK);
        assert!(img.pixels().any(is_dark));
    }
}
