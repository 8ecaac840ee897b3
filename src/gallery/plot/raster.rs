//! Anti-aliased coverage layers and how they are composited onto an image.
//!
//! Every shape of a plot is first rasterised into a [`Layer`]: one coverage
//! value in [0, 1] per pixel, computed analytically from the distance between
//! the pixel centre and the shape (a cheap form of anti-aliasing). Shapes in
//! one layer combine by `max`, so the joints of a polyline are not painted
//! twice. The layer is then painted onto the image either *over* (opaque
//! ink, for axes and markers) or *added* (light, for the RGB curves, so that
//! overlapping channels mix to yellow, cyan, magenta or white and stay
//! readable).

use image::{Rgb, RgbImage};

/// A point in layer pixel coordinates: x to the right, y downwards, pixel
/// (i, j) covering [i, i+1) × [j, j+1).
pub type Point = (f64, f64);

/// Most dashes one dashed line may have.
const MAX_DASHES: f64 = 10_000.0;

/// A width × height grid of coverage values in [0, 1].
pub struct Layer {
    width: u32,
    height: u32,
    alpha: Vec<f32>,
}

impl Layer {
    /// An empty (fully transparent) layer.
    pub fn new(width: u32, height: u32) -> Self {
        let len = width as usize * height as usize;
        Self {
            width,
            height,
            alpha: vec![0.0; len],
        }
    }

    /// Coverage at pixel (x, y), 0 outside the layer.
    pub(crate) fn coverage(&self, x: u32, y: u32) -> f32 {
        if x >= self.width || y >= self.height {
            return 0.0;
        }
        self.alpha[y as usize * self.width as usize + x as usize]
    }

    /// Resets every pixel to transparent so the buffer can be reused.
    pub fn clear(&mut self) {
        self.alpha.fill(0.0);
    }

    /// Combines coverage `a` into pixel (x, y): by `max` (shapes of one
    /// stroke), or by a clamped sum (a fan of triangles tiling one region,
    /// whose shared edges must not leave seams).
    fn combine(&mut self, x: usize, y: usize, a: f64, sum: bool) {
        let i = y * self.width as usize + x;
        let a = a.clamp(0.0, 1.0) as f32;
        let old = self.alpha[i];
        self.alpha[i] = if sum { (old + a).min(1.0) } else { old.max(a) };
    }

    /// Calls `cover(pixel centre)` for every pixel of the box `lo`–`hi`
    /// (clipped to the layer) and combines the result into the pixel.
    fn cover_box(&mut self, lo: Point, hi: Point, sum: bool, cover: impl Fn(Point) -> f64) {
        let Some((xs, ys)) = self.clip_box(lo, hi) else {
            return;
        };
        for y in ys {
            for x in xs.clone() {
                let a = cover((x as f64 + 0.5, y as f64 + 0.5));
                if a > 0.0 {
                    self.combine(x, y, a, sum);
                }
            }
        }
    }

    /// Pixel index ranges of the box clipped to the layer; `None` if the box
    /// is empty, off the layer or not finite.
    fn clip_box(
        &self,
        lo: Point,
        hi: Point,
    ) -> Option<(std::ops::Range<usize>, std::ops::Range<usize>)> {
        let finite = [lo.0, lo.1, hi.0, hi.1].iter().all(|v| v.is_finite());
        if !finite {
            return None;
        }
        let range = |a: f64, b: f64, n: u32| {
            let start = a.floor().clamp(0.0, f64::from(n)) as usize;
            let end = (b.ceil() + 1.0).clamp(0.0, f64::from(n)) as usize;
            (start < end).then_some(start..end)
        };
        Some((
            range(lo.0, hi.0, self.width)?,
            range(lo.1, hi.1, self.height)?,
        ))
    }

    /// Strokes the segment `a`–`b` with a line `width` pixels wide (round caps).
    pub(crate) fn stroke_segment(&mut self, a: Point, b: Point, width: f64) {
        let half = 0.5 * width;
        let pad = half + 1.0;
        let lo = (a.0.min(b.0) - pad, a.1.min(b.1) - pad);
        let hi = (a.0.max(b.0) + pad, a.1.max(b.1) + pad);
        self.cover_box(lo, hi, false, |p| half + 0.5 - distance_to_segment(p, a, b));
    }

    /// Strokes the open polyline through `points`.
    pub(crate) fn stroke_polyline(&mut self, points: &[Point], width: f64) {
        match points {
            [] => {}
            [p] => self.fill_disc(*p, 0.5 * width),
            _ => {
                for pair in points.windows(2) {
                    self.stroke_segment(pair[0], pair[1], width);
                }
            }
        }
    }

    /// Strokes `a`–`b` as dashes `dash` pixels long separated by `gap` pixels.
    pub(crate) fn stroke_dashed(&mut self, a: Point, b: Point, width: f64, dash: f64, gap: f64) {
        let length = (b.0 - a.0).hypot(b.1 - a.1);
        let period = dash + gap;
        if !length.is_finite() || period <= 0.0 || dash <= 0.0 {
            return;
        }
        let at = |t: f64| lerp_point(a, b, (t / length).min(1.0));
        // Bounded so that an absurdly long line cannot stall the plot.
        let count = (length / period).ceil().min(MAX_DASHES) as usize;
        for i in 0..count {
            let t = i as f64 * period;
            self.stroke_segment(at(t), at(t + dash), width);
        }
    }

    /// Fills the disc of `radius` around `centre`.
    pub(crate) fn fill_disc(&mut self, centre: Point, radius: f64) {
        let pad = radius + 1.0;
        let lo = (centre.0 - pad, centre.1 - pad);
        let hi = (centre.0 + pad, centre.1 + pad);
        self.cover_box(lo, hi, false, |p| radius + 0.5 - distance(p, centre));
    }

    /// Fills the upper half of the disc of `radius` around `centre` (the part
    /// with y < centre.y), i.e. the hemisphere of directions above a surface.
    pub(crate) fn fill_upper_half_disc(&mut self, centre: Point, radius: f64) {
        let lo = (centre.0 - radius - 1.0, centre.1 - radius - 1.0);
        let hi = (centre.0 + radius + 1.0, centre.1);
        self.cover_box(lo, hi, false, |p| {
            let round = (radius + 0.5 - distance(p, centre)).clamp(0.0, 1.0);
            let flat = (centre.1 - p.1 + 0.5).clamp(0.0, 1.0);
            round * flat
        });
    }

    /// Fills the triangle `a`, `b`, `c` with 4×4 supersampling per pixel.
    /// Coverage is *summed* (clamped to 1) so that a fan of triangles sharing
    /// edges fills its region without seams.
    pub(crate) fn fill_triangle(&mut self, a: Point, b: Point, c: Point) {
        let lo = (a.0.min(b.0).min(c.0), a.1.min(b.1).min(c.1));
        let hi = (a.0.max(b.0).max(c.0), a.1.max(b.1).max(c.1));
        self.cover_box(lo, hi, true, |p| {
            let mut hits = 0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let q = (
                        p.0 - 0.375 + 0.25 * sx as f64,
                        p.1 - 0.375 + 0.25 * sy as f64,
                    );
                    hits += usize::from(inside_triangle(q, a, b, c));
                }
            }
            hits as f64 / 16.0
        });
    }
}

/// Linear interpolation between two points.
pub(crate) fn lerp_point(a: Point, b: Point, t: f64) -> Point {
    (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t)
}

fn distance(p: Point, q: Point) -> f64 {
    (p.0 - q.0).hypot(p.1 - q.1)
}

/// Euclidean distance from `p` to the closed segment `a`–`b`.
fn distance_to_segment(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    distance(p, (a.0 + t * dx, a.1 + t * dy))
}

fn inside_triangle(p: Point, a: Point, b: Point, c: Point) -> bool {
    let edge = |u: Point, v: Point| (v.0 - u.0) * (p.1 - u.1) - (v.1 - u.1) * (p.0 - u.0);
    let (e0, e1, e2) = (edge(a, b), edge(b, c), edge(c, a));
    (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0)
}

/// Paints `layer` onto `img` with its top-left corner at `origin`, blending
/// each pixel towards `colour` by its coverage (opaque ink).
pub(crate) fn paint_over(img: &mut RgbImage, origin: (u32, u32), layer: &Layer, colour: Rgb<u8>) {
    paint(img, origin, layer, |dst, a| {
        let mix = |d: u8, c: u8| f32::from(d) + (f32::from(c) - f32::from(d)) * a;
        Rgb(std::array::from_fn(|k| to_u8(mix(dst.0[k], colour.0[k]))))
    });
}

/// Paints `layer` onto `img` at `origin` by adding `colour` × coverage
/// (saturating), like light: red + green reads as yellow, all three as white.
pub(crate) fn paint_add(img: &mut RgbImage, origin: (u32, u32), layer: &Layer, colour: Rgb<u8>) {
    paint(img, origin, layer, |dst, a| {
        Rgb(std::array::from_fn(|k| {
            to_u8(f32::from(dst.0[k]) + f32::from(colour.0[k]) * a)
        }))
    });
}

/// Applies `blend(old pixel, coverage)` to every covered pixel of `layer`
/// that lies inside `img`.
fn paint(
    img: &mut RgbImage,
    origin: (u32, u32),
    layer: &Layer,
    blend: impl Fn(Rgb<u8>, f32) -> Rgb<u8>,
) {
    for y in 0..layer.height {
        for x in 0..layer.width {
            let a = layer.coverage(x, y);
            let (ix, iy) = (origin.0.saturating_add(x), origin.1.saturating_add(y));
            if a <= 0.0 || ix >= img.width() || iy >= img.height() {
                continue;
            }
            let old = *img.get_pixel(ix, iy);
            img.put_pixel(ix, iy, blend(old, a));
        }
    }
}

fn to_u8(v: f32) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segment_coverage_is_full_on_the_line_and_zero_far_away() {
        let mut layer = Layer::new(20, 10);
        layer.stroke_segment((2.0, 5.0), (18.0, 5.0), 2.0);
        assert_eq!(layer.coverage(10, 4), 1.0);
        assert_eq!(layer.coverage(10, 5), 1.0);
        assert_eq!(layer.coverage(10, 8), 0.0);
        assert_eq!(layer.coverage(10, 1), 0.0);
    }

    #[test]
    fn shapes_off_the_layer_or_not_finite_draw_nothing() {
        let mut layer = Layer::new(8, 8);
        layer.stroke_segment((-50.0, -50.0), (-20.0, -40.0), 3.0);
        layer.stroke_segment((f64::NAN, 1.0), (3.0, 3.0), 3.0);
        layer.fill_disc((f64::INFINITY, 2.0), 4.0);
        layer.stroke_dashed((f64::NAN, 0.0), (4.0, 4.0), 1.0, 3.0, 2.0);
        assert!((0..8).all(|y| (0..8).all(|x| layer.coverage(x, y) == 0.0)));
        layer.stroke_dashed((0.0, 0.0), (f64::MAX, 0.0), 2.0, 3.0, 2.0);
        assert_eq!(
            layer.coverage(1, 0),
            1.0,
            "the huge dashed line still starts"
        );
    }

    #[test]
    fn additive_paint_mixes_red_and_green_to_yellow() {
        let mut img = RgbImage::from_pixel(4, 4, Rgb([0, 0, 0]));
        let mut layer = Layer::new(4, 4);
        layer.fill_disc((2.0, 2.0), 3.0);
        paint_add(&mut img, (0, 0), &layer, Rgb([255, 0, 0]));
        paint_add(&mut img, (0, 0), &layer, Rgb([0, 255, 0]));
        assert_eq!(*img.get_pixel(2, 2), Rgb([255, 255, 0]));
    }

    #[test]
    fn a_fan_of_triangles_fills_without_seams() {
        let mut layer = Layer::new(20, 20);
        let c = (10.0, 10.0);
        let rim = [(0.0, 0.0), (7.3, 0.0), (13.1, 0.0), (20.0, 0.0)];
        for pair in rim.windows(2) {
            layer.fill_triangle(c, pair[0], pair[1]);
        }
        for y in 2..8 {
            for x in (y + 1)..(19 - y) {
                assert_eq!(layer.coverage(x, y), 1.0, "seam at ({x}, {y})");
            }
        }
    }
}
