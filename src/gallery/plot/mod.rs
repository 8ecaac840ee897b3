//! Polar plots of BRDF slices in the plane of incidence, in the manner of
//! the top row of figure 2.1 of the course notes: for a fixed incidence
//! angle, the cosine-weighted BRDF `f·cosθo` is drawn as a radius over the
//! outgoing angle θo, so a reader sees at a glance whether a material
//! reflects diffusely (a round blob), glossily (a lobe around the mirror
//! direction) or towards the light (retro-reflection).
//!
//! The library only draws: [`polar_plot`] returns an [`image::RgbImage`] and
//! never touches files; the command line decides where it goes.
//!
//! Layout of the image: a title row, a legend row, then one panel per
//! incidence angle side by side. Each panel is a dark half-disc (the upper
//! hemisphere) over the surface line, with rays every 30°, rings labelled in
//! BRDF units, the incoming light as a grey arrow from the upper left and the
//! mirror direction dashed. The three colour channels are drawn as red, green
//! and blue light that *adds up*: where channels coincide the curve turns
//! yellow, cyan, magenta or white, so overlaps stay readable and a neutral
//! material simply reads as white.

pub mod maps;
mod raster;
mod scale;
pub mod text;

use image::{Rgb, RgbImage};
use raster::{paint_add, paint_over, Layer, Point};
use scale::PanelScale;
use text::{draw_text_centred, draw_text_clipped, text_height, text_width, ClipRect};

/// One panel: a fixed incidence angle, curves over signed outgoing angle in
/// the incidence plane.
///
/// Angles are in degrees from the surface normal. Positive θo lies on the
/// mirror side (to the right in the plot), negative θo on the side of the
/// light, so a glossy lobe appears near θo = +incidence.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolarPanel {
    /// Incidence angle θi of the light; drawn as a grey arrow arriving from
    /// the upper left at this angle from the normal.
    pub incidence_deg: f64,
    /// Per RGB channel, points `(θo in degrees within [-90, 90], value ≥ 0)`
    /// sorted by θo, where value is the cosine-weighted BRDF `f·cosθo`.
    /// Drawn as polylines in the order given; a point with a NaN, infinite
    /// or negative value, or θo outside [-90, 90], breaks the line. A value
    /// of 0 is a legitimate radius and lies at the centre.
    pub curves: [Vec<(f64, f64)>; 3],
    /// Optional Monte Carlo reference in the same layout, drawn as dots so
    /// that noise does not masquerade as a feature of the curve.
    pub reference: Option<[Vec<(f64, f64)>; 3]>,
}

/// The panel of `brdf`'s in-plane slice `f(ωi, ωo)·cosθo` at incidence
/// `incidence_deg`, light on the φ = 180° side, θo from −90° to 90° in
/// quarter degrees, without a reference.
pub fn in_plane_panel(brdf: &crate::brdf::LayeredBrdf, incidence_deg: f64) -> PolarPanel {
    let angles: Vec<f64> = (0..=720)
        .map(|step| -90.0 + f64::from(step) * 0.25)
        .collect();
    let values = crate::brdf::albedo::in_plane_slice(brdf, incidence_deg, &angles);
    PolarPanel {
        incidence_deg,
        curves: rgb_curves(&angles, &values),
        reference: None,
    }
}

/// Per-channel curves `(θo, value)` in [`PolarPanel`]'s layout, of RGB
/// `values` at the outgoing angles `theta_o_deg`.
pub fn rgb_curves(theta_o_deg: &[f64], values: &[crate::brdf::Rgb]) -> [Vec<(f64, f64)>; 3] {
    std::array::from_fn(|c| {
        theta_o_deg
            .iter()
            .zip(values)
            .map(|(&theta, v)| (theta, v[c]))
            .collect()
    })
}

/// How a polar plot looks.
#[derive(Clone, Debug, PartialEq)]
pub struct PolarPlotStyle {
    /// Width of one panel in pixels (its height follows from it), clamped
    /// between `MIN_PANEL_PX` and [`MAX_PANEL_PX`]. Text is drawn twice as
    /// large from 320 px up, so panels of 400 px read well on a screen.
    pub panel_size_px: u32,
    /// Title drawn above the legend, e.g. the material's name.
    pub title: String,
}

impl Default for PolarPlotStyle {
    /// 400-px panels (1624 px wide for the typical four) and a generic title.
    fn default() -> Self {
        Self {
            panel_size_px: 400,
            title: "BRDF slices in the plane of incidence".to_string(),
        }
    }
}

/// Smallest panel width in pixels; below it the labels would cover the plot.
pub(crate) const MIN_PANEL_PX: u32 = 160;
/// Largest panel width in pixels, bounding the image's memory.
pub const MAX_PANEL_PX: u32 = 2048;
/// Panels per row; more panels wrap onto further rows.
pub(crate) const MAX_COLUMNS: usize = 8;
/// Panels drawn at most; further panels are ignored to bound memory.
pub(crate) const MAX_PANELS: usize = 64;

/// Margin around the whole image, in pixels.
const PAD: u32 = 12;
/// Narrowest image, so that a plot without panels still shows its title.
const MIN_WIDTH: u32 = 240;
/// Widest image without panels (a very long title is clipped, not obeyed).
const MAX_BLANK_WIDTH: u32 = 2048;

/// Colours of the dark theme: the curves are light added onto it.
mod palette {
    use image::Rgb;

    pub const BACKGROUND: Rgb<u8> = Rgb([16, 18, 24]);
    pub(crate) const HEMISPHERE: Rgb<u8> = Rgb([30, 33, 43]);
    pub const GRID: Rgb<u8> = Rgb([66, 71, 88]);
    pub(crate) const NORMAL: Rgb<u8> = Rgb([105, 110, 128]);
    pub(crate) const SURFACE: Rgb<u8> = Rgb([185, 185, 195]);
    pub(crate) const LIGHT: Rgb<u8> = Rgb([180, 180, 180]);
    pub(crate) const MIRROR: Rgb<u8> = Rgb([120, 122, 135]);
    pub(crate) const TEXT: Rgb<u8> = Rgb([230, 230, 235]);
    pub(crate) const DIM_TEXT: Rgb<u8> = Rgb([150, 156, 172]);
    pub(crate) const WHITE: Rgb<u8> = Rgb([255, 255, 255]);
    /// Red, green and blue chosen so that each reads on the dark background
    /// (pure blue is too dark) and all three sum to white.
    pub(crate) const CHANNELS: [Rgb<u8>; 3] =
        [Rgb([255, 60, 60]), Rgb([40, 215, 60]), Rgb([80, 130, 255])];
}

/// Width of the curve strokes in pixels at text scale 1.
const CURVE_WIDTH: f64 = 1.6;
/// Share of a channel's colour tinting the area under its curve.
const FILL_ALPHA: f32 = 0.16;
/// Radius of a reference dot in pixels at text scale 1.
const DOT_RADIUS: f64 = 1.2;

/// Draws `panels` side by side as polar plots under a title and a legend.
///
/// Every panel has its own radial scale (see [`PolarPanel`]); a huge dynamic
/// range (peak / median > 50) switches that panel to a logarithmic radius
/// and its caption says "(log scale)". No input panics: non-finite values
/// are skipped, and zero panels give a small image with just the title.
pub fn polar_plot(panels: &[PolarPanel], style: &PolarPlotStyle) -> RgbImage {
    let panels = &panels[..panels.len().min(MAX_PANELS)];
    let has_reference = panels.iter().any(|p| p.reference.is_some());
    let layout = Layout::new(panels.len(), style, has_reference);
    let mut img = RgbImage::from_pixel(layout.width, layout.height, palette::BACKGROUND);
    draw_title(&mut img, &layout, &style.title);
    draw_legend(&mut img, &layout);
    for (i, panel) in panels.iter().enumerate() {
        draw_panel(&mut img, &layout.frame(i), panel);
    }
    img
}

/// Integer text scales: `big` for title, legend, headers and captions,
/// `small` for the tick labels around the half-disc.
#[derive(Clone, Copy, Debug)]
struct Fonts {
    big: u32,
    small: u32,
}

impl Fonts {
    fn for_panel(size: u32) -> Self {
        Self {
            big: if size >= 320 { 2 } else { 1 },
            small: if size >= 640 { 2 } else { 1 },
        }
    }
}

/// Geometry shared by all panels, in panel-local pixels.
#[derive(Clone, Copy, Debug)]
struct PanelMetrics {
    width: u32,
    height: u32,
    /// Where the normal meets the surface: the pole of the polar plot.
    centre: Point,
    /// Radius of the outer ring.
    radius: f64,
    /// Top of the "θi = …" header.
    header_top: u32,
    /// Top of the caption ("max 0.52") under the ring labels.
    caption_top: u32,
    fonts: Fonts,
}

impl PanelMetrics {
    /// Top to bottom: header, angle labels, half-disc, ring labels, caption.
    fn new(width: u32, fonts: Fonts) -> Self {
        let (big, small) = (text_height(fonts.big), text_height(fonts.small));
        let side = text_width("-90°", fonts.small) + 12;
        let radius = width.saturating_sub(2 * side) / 2;
        let header_top = 8;
        let arc_top = header_top + big + 10 + small + 8;
        let surface_y = arc_top + radius;
        let caption_top = surface_y + 6 + small + 8;
        Self {
            width,
            height: caption_top + big + 10,
            centre: (f64::from(width / 2), f64::from(surface_y)),
            radius: f64::from(radius),
            header_top,
            caption_top,
            fonts,
        }
    }
}

/// Where one panel sits in the image.
#[derive(Clone, Copy, Debug)]
struct PanelFrame {
    left: u32,
    top: u32,
    metrics: PanelMetrics,
}

impl PanelFrame {
    fn clip(&self) -> ClipRect {
        ClipRect {
            left: self.left,
            top: self.top,
            width: self.metrics.width,
            height: self.metrics.height,
        }
    }
}

/// A legend entry: a small picture and what it means.
#[derive(Clone, Copy, Debug)]
enum Swatch {
    /// Text only, no picture.
    None,
    /// A curve stroke in this colour.
    Line(Rgb<u8>),
    /// A reference dot with its halo.
    Dot,
    /// The light arrow.
    Arrow,
    /// The dashed mirror direction.
    Dashed,
}

/// Width of a legend swatch in pixels at text scale 1.
const SWATCH_WIDTH: u32 = 16;

/// The legend entries, the reference dot only when some panel has one.
fn legend_items(has_reference: bool) -> Vec<(Swatch, &'static str)> {
    let [r, g, b] = palette::CHANNELS;
    let mut items = vec![
        (Swatch::Line(r), "R"),
        (Swatch::Line(g), "G"),
        (Swatch::Line(b), "B"),
        (Swatch::Line(palette::WHITE), "analytic f·cosθo"),
        (Swatch::None, "(overlaps add: R+G+B = white)"),
    ];
    if has_reference {
        items.push((Swatch::Dot, "MC reference"));
    }
    items.push((Swatch::Arrow, "light"));
    items.push((Swatch::Dashed, "mirror"));
    items
}

/// A legend entry placed at (x, y), its top-left corner.
type PlacedItem = (u32, u32, Swatch, &'static str);

/// Positions of everything in the image.
#[derive(Debug)]
struct Layout {
    fonts: Fonts,
    metrics: PanelMetrics,
    columns: u32,
    panels_top: u32,
    legend: Vec<PlacedItem>,
    width: u32,
    height: u32,
}

impl Layout {
    fn new(panels: usize, style: &PolarPlotStyle, has_reference: bool) -> Self {
        let size = style.panel_size_px.clamp(MIN_PANEL_PX, MAX_PANEL_PX);
        let fonts = Fonts::for_panel(size);
        let metrics = PanelMetrics::new(size, fonts);
        let columns = panels.min(MAX_COLUMNS) as u32;
        let rows = panels.div_ceil(MAX_COLUMNS) as u32;
        let width = if panels == 0 {
            (2 * PAD)
                .saturating_add(text_width(&style.title, fonts.big))
                .clamp(MIN_WIDTH, MAX_BLANK_WIDTH)
        } else {
            (2 * PAD + columns * size).max(MIN_WIDTH)
        };
        let title_height = PAD + text_height(fonts.big) + 8;
        let legend = if panels == 0 {
            Vec::new()
        } else {
            place_legend(&legend_items(has_reference), width, title_height, fonts)
        };
        let legend_bottom = legend
            .iter()
            .map(|item| item.1 + legend_row_height(fonts))
            .max()
            .unwrap_or(title_height);
        let panels_top = legend_bottom + 4;
        Self {
            fonts,
            metrics,
            columns,
            panels_top,
            legend,
            width,
            height: panels_top + rows * metrics.height + PAD / 2,
        }
    }

    /// The frame of panel `i` (row-major, [`MAX_COLUMNS`] per row).
    fn frame(&self, i: usize) -> PanelFrame {
        let columns = self.columns.max(1) as usize;
        let (row, column) = ((i / columns) as u32, (i % columns) as u32);
        PanelFrame {
            left: PAD + column * self.metrics.width,
            top: self.panels_top + row * self.metrics.height,
            metrics: self.metrics,
        }
    }
}

fn legend_row_height(fonts: Fonts) -> u32 {
    text_height(fonts.big) + 10
}

/// Width of one legend entry: swatch, gap, label.
fn legend_item_width(swatch: Swatch, label: &str, fonts: Fonts) -> u32 {
    swatch_width(swatch, fonts) + text_width(label, fonts.big)
}

/// Width of a legend picture including the gap before its label.
fn swatch_width(swatch: Swatch, fonts: Fonts) -> u32 {
    match swatch {
        Swatch::None => 0,
        _ => SWATCH_WIDTH * fonts.big + 6,
    }
}

/// Flows the legend entries into centred rows no wider than the image.
fn place_legend(
    items: &[(Swatch, &'static str)],
    width: u32,
    top: u32,
    fonts: Fonts,
) -> Vec<PlacedItem> {
    let spacing = 10 * fonts.big;
    let available = width.saturating_sub(2 * PAD);
    let mut rows: Vec<Vec<(Swatch, &'static str)>> = vec![Vec::new()];
    let mut used = 0;
    for &(swatch, label) in items {
        let w = legend_item_width(swatch, label, fonts);
        let row = rows.last_mut().expect("rows start non-empty");
        if !row.is_empty() && used + spacing + w > available {
            rows.push(vec![(swatch, label)]);
            used = w;
        } else {
            used += if row.is_empty() { w } else { spacing + w };
            row.push((swatch, label));
        }
    }
    let mut placed = Vec::new();
    for (r, row) in rows.iter().enumerate() {
        let widths: Vec<u32> = row
            .iter()
            .map(|i| legend_item_width(i.0, i.1, fonts))
            .collect();
        let total = widths.iter().sum::<u32>() + spacing * (row.len() as u32).saturating_sub(1);
        let mut x = PAD + available.saturating_sub(total) / 2;
        let y = top + r as u32 * legend_row_height(fonts);
        for (item, w) in row.iter().zip(widths) {
            placed.push((x, y, item.0, item.1));
            x += w + spacing;
        }
    }
    placed
}

fn draw_title(img: &mut RgbImage, layout: &Layout, title: &str) {
    let clip = ClipRect::of_image(img);
    let cx = i64::from(layout.width / 2);
    let at = (cx, i64::from(PAD));
    draw_text_centred(img, clip, at, title, layout.fonts.big, palette::TEXT);
}

fn draw_legend(img: &mut RgbImage, layout: &Layout) {
    let scale = layout.fonts.big;
    let (w, h) = (SWATCH_WIDTH * scale, text_height(scale));
    for &(x, y, swatch, label) in &layout.legend {
        draw_swatch(img, (x, y), (w, h), swatch, f64::from(scale));
        let clip = ClipRect::of_image(img);
        let at = (
            i64::from(x + swatch_width(swatch, layout.fonts)),
            i64::from(y),
        );
        draw_text_clipped(img, clip, at, label, scale, palette::TEXT);
    }
}

/// Draws a legend swatch of size `w`×`h` with its top-left corner at `at`.
fn draw_swatch(img: &mut RgbImage, at: (u32, u32), (w, h): (u32, u32), swatch: Swatch, k: f64) {
    let mut layer = Layer::new(w, h);
    let (w, mid) = (f64::from(w), f64::from(h) / 2.0);
    match swatch {
        Swatch::None => {}
        Swatch::Line(colour) => {
            layer.stroke_segment((1.0, mid), (w - 1.0, mid), CURVE_WIDTH * k);
            paint_add(img, at, &layer, colour);
        }
        Swatch::Dot => {
            draw_dot_halo(&mut layer, (w / 2.0, mid), k);
            paint_over(img, at, &layer, palette::BACKGROUND);
            layer.clear();
            layer.fill_disc((w / 2.0, mid), DOT_RADIUS * k);
            paint_add(img, at, &layer, palette::WHITE);
        }
        Swatch::Arrow => {
            draw_arrow(&mut layer, (1.0, mid), (w - 1.0, mid), k);
            paint_over(img, at, &layer, palette::LIGHT);
        }
        Swatch::Dashed => {
            layer.stroke_dashed((1.0, mid), (w - 1.0, mid), k, 3.0 * k, 2.5 * k);
            paint_over(img, at, &layer, palette::MIRROR);
        }
    }
}

/// A panel being drawn: the image, where the panel sits, and a scratch
/// coverage layer the size of the panel.
struct Canvas<'a> {
    img: &'a mut RgbImage,
    frame: PanelFrame,
    layer: Layer,
}

impl<'a> Canvas<'a> {
    fn new(img: &'a mut RgbImage, frame: PanelFrame) -> Self {
        let layer = Layer::new(frame.metrics.width, frame.metrics.height);
        Self { img, frame, layer }
    }

    fn m(&self) -> &PanelMetrics {
        &self.frame.metrics
    }

    /// Stroke width scaled with the text so big panels get bolder lines.
    fn px(&self, width: f64) -> f64 {
        width * f64::from(self.m().fonts.big)
    }

    /// Point at outgoing angle `theta_deg` (from the normal, positive to the
    /// right) and `fraction` of the plot radius from the pole.
    fn polar(&self, theta_deg: f64, fraction: f64) -> Point {
        let (s, c) = theta_deg.to_radians().sin_cos();
        let (cx, cy) = self.m().centre;
        let r = fraction * self.m().radius;
        (cx + r * s, cy - r * c)
    }

    /// Rasterises with `draw` and paints the result as opaque `colour`.
    fn ink(&mut self, colour: Rgb<u8>, draw: impl FnOnce(&mut Layer)) {
        self.layer.clear();
        draw(&mut self.layer);
        let origin = (self.frame.left, self.frame.top);
        paint_over(self.img, origin, &self.layer, colour);
    }

    /// Rasterises with `draw` and adds the result as light of `colour`.
    fn light(&mut self, colour: Rgb<u8>, draw: impl FnOnce(&mut Layer)) {
        self.layer.clear();
        draw(&mut self.layer);
        let origin = (self.frame.left, self.frame.top);
        paint_add(self.img, origin, &self.layer, colour);
    }

    /// Draws `text` with its top-left corner at panel-local `at`.
    fn text(&mut self, at: Point, text: &str, scale: u32, colour: Rgb<u8>) {
        let x = i64::from(self.frame.left) + at.0.round() as i64;
        let y = i64::from(self.frame.top) + at.1.round() as i64;
        draw_text_clipped(self.img, self.frame.clip(), (x, y), text, scale, colour);
    }

    /// Draws `text` centred horizontally on panel-local `cx`, top at `y`.
    fn text_centred(&mut self, (cx, y): Point, text: &str, scale: u32, colour: Rgb<u8>) {
        let half = f64::from(text_width(text, scale)) / 2.0;
        self.text((cx - half, y), text, scale, colour);
    }
}

fn draw_panel(img: &mut RgbImage, frame: &PanelFrame, panel: &PolarPanel) {
    let scale = fit_scale(panel);
    let mut canvas = Canvas::new(img, *frame);
    draw_axes(&mut canvas, &scale);
    draw_light(&mut canvas, panel.incidence_deg);
    draw_curves(&mut canvas, &scale, &panel.curves);
    if let Some(reference) = &panel.reference {
        draw_reference(&mut canvas, &scale, reference);
    }
    draw_labels(&mut canvas, &scale, panel.incidence_deg);
}

/// The panel's scale fitted to its analytic curves, or to the reference
/// when there are no analytic values (reference noise must not set the
/// scale; reference points beyond it are pinned to the outer ring).
fn fit_scale(panel: &PolarPanel) -> PanelScale {
    let values = |curves: &[Vec<(f64, f64)>; 3]| -> Vec<f64> {
        curves
            .iter()
            .flatten()
            .filter(|(t, _)| is_plottable_angle(*t))
            .map(|p| p.1)
            .collect()
    };
    let analytic = PanelScale::fit(values(&panel.curves));
    match &panel.reference {
        Some(reference) if analytic.peak == 0.0 => PanelScale::fit(values(reference)),
        _ => analytic,
    }
}

fn is_plottable_angle(theta_deg: f64) -> bool {
    (-90.0..=90.0).contains(&theta_deg)
}

/// The hemisphere, its rings and rays, the normal and the surface line.
fn draw_axes(canvas: &mut Canvas, scale: &PanelScale) {
    let (centre, radius) = (canvas.m().centre, canvas.m().radius);
    canvas.ink(palette::HEMISPHERE, |l| {
        l.fill_upper_half_disc(centre, radius)
    });
    let rings: Vec<Vec<Point>> = scale
        .rings()
        .iter()
        .map(|(frac, _)| arc(canvas, *frac))
        .collect();
    let rays: Vec<(Point, Point)> = [-60.0, -30.0, 30.0, 60.0]
        .iter()
        .map(|&t| (centre, canvas.polar(t, 1.0)))
        .collect();
    canvas.ink(palette::GRID, |l| {
        rings.iter().for_each(|ring| l.stroke_polyline(ring, 1.0));
        rays.iter().for_each(|&(a, b)| l.stroke_segment(a, b, 1.0));
    });
    let top = canvas.polar(0.0, 1.0);
    canvas.ink(palette::NORMAL, |l| l.stroke_segment(centre, top, 1.0));
    let half = radius + 4.0;
    let (left, right) = ((centre.0 - half, centre.1), (centre.0 + half, centre.1));
    let width = canvas.px(1.0);
    canvas.ink(palette::SURFACE, |l| l.stroke_segment(left, right, width));
}

/// Points of the upper half circle at `fraction` of the radius, about 2 px apart.
fn arc(canvas: &Canvas, fraction: f64) -> Vec<Point> {
    let length = std::f64::consts::PI * fraction * canvas.m().radius;
    let n = (length / 2.0).clamp(16.0, 4096.0) as usize;
    (0..=n)
        .map(|i| canvas.polar(-90.0 + 180.0 * i as f64 / n as f64, fraction))
        .collect()
}

/// The incoming light as a grey arrow from the upper left into the pole and
/// the mirror direction as a dashed ray; nothing for light below the horizon.
fn draw_light(canvas: &mut Canvas, incidence_deg: f64) {
    if !is_plottable_angle(incidence_deg) {
        return;
    }
    let centre = canvas.m().centre;
    let mirror = canvas.polar(incidence_deg, 1.0);
    let (w, dash) = (canvas.px(0.75), canvas.px(4.0));
    canvas.ink(palette::MIRROR, |l| {
        l.stroke_dashed(centre, mirror, w, dash, 0.8 * dash);
    });
    let tail = canvas.polar(-incidence_deg, 0.97);
    let k = f64::from(canvas.m().fonts.big);
    canvas.ink(palette::LIGHT, |l| draw_arrow(l, tail, centre, k));
}

/// An arrow from `tail` to `tip` whose head and shaft scale with `k`; the
/// tip stops a few pixels short so it does not hide the pole.
fn draw_arrow(layer: &mut Layer, tail: Point, tip: Point, k: f64) {
    let length = (tip.0 - tail.0).hypot(tip.1 - tail.1);
    if !(length.is_finite() && length > 0.0) {
        return;
    }
    let dir = ((tip.0 - tail.0) / length, (tip.1 - tail.1) / length);
    let normal = (-dir.1, dir.0);
    let at = |back: f64, side: f64| {
        (
            tip.0 - dir.0 * back + normal.0 * side,
            tip.1 - dir.1 * back + normal.1 * side,
        )
    };
    let (gap, head, half) = ((1.5 * k).min(length), 8.0 * k, 4.0 * k);
    layer.stroke_segment(tail, at(gap + head * 0.8, 0.0), 1.25 * k);
    layer.fill_triangle(at(gap, 0.0), at(gap + head, half), at(gap + head, -half));
}

/// Splits a curve into runs of plottable points (panel-local pixels); an
/// unplottable point ends the current run.
fn curve_runs(canvas: &Canvas, scale: &PanelScale, curve: &[(f64, f64)]) -> Vec<Vec<Point>> {
    let mut runs = vec![Vec::new()];
    for &(theta, value) in curve {
        let fraction = scale.fraction(value).filter(|_| is_plottable_angle(theta));
        match fraction {
            Some(f) => runs
                .last_mut()
                .expect("never empty")
                .push(canvas.polar(theta, f)),
            None if runs.last().is_some_and(|r| !r.is_empty()) => runs.push(Vec::new()),
            None => {}
        }
    }
    runs.retain(|r| !r.is_empty());
    runs
}

/// Each channel as a faint filled lobe plus a bright outline, added as light.
fn draw_curves(canvas: &mut Canvas, scale: &PanelScale, curves: &[Vec<(f64, f64)>; 3]) {
    let centre = canvas.m().centre;
    let width = canvas.px(CURVE_WIDTH);
    for (curve, colour) in curves.iter().zip(palette::CHANNELS) {
        let runs = curve_runs(canvas, scale, curve);
        canvas.light(dim(colour, FILL_ALPHA), |l| {
            for pair in runs.iter().flat_map(|run| run.windows(2)) {
                l.fill_triangle(centre, pair[0], pair[1]);
            }
        });
        canvas.light(colour, |l| {
            runs.iter().for_each(|run| l.stroke_polyline(run, width));
        });
    }
}

fn dim(colour: Rgb<u8>, factor: f32) -> Rgb<u8> {
    Rgb(colour.0.map(|c| (f32::from(c) * factor).round() as u8))
}

/// Reference samples as coloured dots with a dark halo, so they stand out
/// even where they sit exactly on the analytic curve of the same colour.
fn draw_reference(canvas: &mut Canvas, scale: &PanelScale, reference: &[Vec<(f64, f64)>; 3]) {
    let dots: Vec<Vec<Point>> = reference
        .iter()
        .map(|curve| curve_runs(canvas, scale, curve).concat())
        .collect();
    let k = f64::from(canvas.m().fonts.big);
    canvas.ink(palette::BACKGROUND, |l| {
        dots.iter().flatten().for_each(|&p| draw_dot_halo(l, p, k));
    });
    for (channel, colour) in dots.iter().zip(palette::CHANNELS) {
        canvas.light(colour, |l| {
            channel.iter().for_each(|&p| l.fill_disc(p, DOT_RADIUS * k));
        });
    }
}

fn draw_dot_halo(layer: &mut Layer, p: Point, k: f64) {
    layer.fill_disc(p, (DOT_RADIUS + 0.8) * k);
}

/// Header, angle labels round the rim, ring values under the surface line
/// (right half) and the scale caption.
fn draw_labels(canvas: &mut Canvas, scale: &PanelScale, incidence_deg: f64) {
    let m = *canvas.m();
    let header = format!("θi = {}", format_degrees(incidence_deg));
    let header_at = (m.centre.0, f64::from(m.header_top));
    canvas.text_centred(header_at, &header, m.fonts.big, palette::TEXT);
    draw_angle_labels(canvas);
    draw_ring_labels(canvas, scale);
    let caption_at = (m.centre.0, f64::from(m.caption_top));
    canvas.text_centred(caption_at, &scale.caption(), m.fonts.big, palette::TEXT);
}

/// "30°", "27.5°", or "?" for an angle that is not a number.
fn format_degrees(deg: f64) -> String {
    if !deg.is_finite() {
        "?".to_string()
    } else if deg.fract() == 0.0 && deg.abs() < 1e6 {
        format!("{deg:.0}°")
    } else {
        format!("{}°", scale::format_value(deg, 3))
    }
}

/// Labels every 30° just outside the outer ring, each placed so that its box
/// lies outside the circle along its ray (±90° above the surface line).
fn draw_angle_labels(canvas: &mut Canvas) {
    let m = *canvas.m();
    let h = f64::from(text_height(m.fonts.small));
    for theta in (-90_i32..=90).step_by(30) {
        let label = format!("{theta}°");
        let w = f64::from(text_width(&label, m.fonts.small));
        let (s, c) = f64::from(theta).to_radians().sin_cos();
        let anchor = canvas.polar(f64::from(theta), 1.0);
        let gap = 6.0;
        let centre = (
            anchor.0 + s * (gap + w / 2.0),
            anchor.1 - c * (gap + h / 2.0),
        );
        // ±90° sit just above the surface line, clear of the ring labels below it.
        let lift = if theta.abs() == 90 {
            h / 2.0 + 3.0
        } else {
            0.0
        };
        let at = (centre.0 - w / 2.0, centre.1 - h / 2.0 - lift);
        canvas.text(at, &label, m.fonts.small, palette::DIM_TEXT);
    }
}

/// Ring values under the surface line on the right, from the outer ring
/// inwards, skipping labels that would collide with the previous one.
fn draw_ring_labels(canvas: &mut Canvas, scale: &PanelScale) {
    let m = *canvas.m();
    let y = m.centre.1 + 6.0;
    let mut left_limit = f64::INFINITY;
    for (frac, label) in scale.rings().iter().rev() {
        let w = f64::from(text_width(label, m.fonts.small));
        let cx = m.centre.0 + frac * m.radius;
        if cx + w / 2.0 + 4.0 > left_limit {
            continue;
        }
        canvas.text_centred((cx, y), label, m.fonts.small, palette::DIM_TEXT);
        left_limit = cx - w / 2.0;
    }
}

#[cfg(test)]
mod tests;
