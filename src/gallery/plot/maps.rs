//! The figure 4.6 sheet of a gem: ① surface map, ② glitter map, ④ facet
//! normals and ⑤ their combination, side by side over a planar slice
//! z = 0 through the stone's object space.

use crate::brdf::Rgb;
use crate::gallery::plot::text::{draw_text, text_width};
use crate::texture::pattern::Pattern;
use glam::DVec3;
use image::{Rgb as Pixel, RgbImage};
use rayon::prelude::*;

/// Layout of a maps sheet.
#[derive(Clone, Debug)]
pub struct MapsSheetStyle {
    /// Side of each square panel in pixels.
    pub panel_px: u32,
    /// The slice covers x, y ∈ [−extent, extent] texture units.
    pub extent: f64,
    /// Title printed above the panels.
    pub title: String,
}

const MARGIN: u32 = 12;
const LABEL_SCALE: u32 = 2;
const BACKGROUND: Pixel<u8> = Pixel([18, 20, 26]);
const INK: Pixel<u8> = Pixel([230, 230, 230]);
/// Light direction used to shade the facets of panel ⑤ (from the upper left).
const SHADING_LIGHT: DVec3 = DVec3::new(-0.45, 0.35, 0.82);

/// One pixel's colours in the four panels.
fn panel_colours(pattern: &Pattern, material_colours: &[Rgb], p: DVec3) -> [Rgb; 4] {
    let r = pattern.resolve(p);
    let (surface_material, _, _) = pattern.resolve_surface(p);
    let colour_of = |m: u32| {
        material_colours
            .get(m as usize)
            .copied()
            .unwrap_or(Rgb::ONE)
    };
    let surface = colour_of(surface_material);
    match (r.glitter_cell, r.flake_normal) {
        (Some(_), Some(normal)) => {
            let n = normal.local();
            let glitter = colour_of(r.material);
            // ⑤: the flake's colour lit by a fixed light through its tilted
            // normal: tilted facets are darker or brighter than flat ones.
            let shade = n.dot(SHADING_LIGHT.normalize()).max(0.0) * 1.25;
            [
                surface,
                Rgb::splat(0.35) + glitter * 0.65,
                (n + Rgb::ONE) * 0.5,
                (glitter * shade).min(Rgb::ONE),
            ]
        }
        _ => [surface, Rgb::splat(0.005), Rgb::splat(0.03), surface],
    }
}

/// sRGB encoding of a linear value in [0, 1].
fn srgb8(v: f64) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Draw the four-panel sheet. `material_colours` holds one linear RGB per
/// material index (e.g. the material's normal-incidence albedo).
pub fn maps_sheet(pattern: &Pattern, material_colours: &[Rgb], style: &MapsSheetStyle) -> RgbImage {
    let n = style.panel_px.clamp(16, 4096);
    let label_h = 8 * LABEL_SCALE + 8;
    let title_h = 8 * LABEL_SCALE + 12;
    let width = MARGIN + 4 * (n + MARGIN);
    let height = title_h + label_h + n + MARGIN;
    let mut img = RgbImage::from_pixel(width, height, BACKGROUND);
    // The title and labels as long as they fit: a narrow sheet gets the
    // title's first part (up to its colon) and the labels' first words.
    let fits = |text: &str, room: u32| text_width(text, LABEL_SCALE) <= room;
    let title = match style.title.split_once(':') {
        Some((short, _)) if !fits(&style.title, width - MARGIN) => short,
        _ => style.title.as_str(),
    };
    draw_text(&mut img, MARGIN as i64, 6, title, LABEL_SCALE, INK);
    let labels = [
        ["1 surface map", "1 surface", "1"],
        ["2 glitter map", "2 glitter", "2"],
        ["4 facet normals", "4 facets", "4"],
        ["5 combined", "5 both", "5"],
    ];
    // One form for all four: the longest in which every label fits.
    let form = (0..2)
        .find(|&f| labels.iter().all(|forms| fits(forms[f], n)))
        .unwrap_or(2);
    for (k, forms) in labels.iter().enumerate() {
        let label = forms[form];
        let x0 = MARGIN + k as u32 * (n + MARGIN);
        let w = text_width(label, LABEL_SCALE).min(n);
        draw_text(
            &mut img,
            (x0 + (n - w) / 2) as i64,
            title_h as i64,
            label,
            LABEL_SCALE,
            INK,
        );
    }
    let extent = style.extent;
    // Each pixel's four panels as sRGB bytes straight away (12 bytes, not
    // the 96 of four colours in f64: a 4096-pixel sheet took 1.8 GB).
    let rows: Vec<Vec<[[u8; 3]; 4]>> = (0..n)
        .into_par_iter()
        .map(|row| {
            (0..n)
                .map(|col| {
                    let x = ((col as f64 + 0.5) / n as f64 * 2.0 - 1.0) * extent;
                    let y = (1.0 - (row as f64 + 0.5) / n as f64 * 2.0) * extent;
                    panel_colours(pattern, material_colours, DVec3::new(x, y, 0.0))
                        .map(|c| [srgb8(c.x), srgb8(c.y), srgb8(c.z)])
                })
                .collect()
        })
        .collect();
    let top = title_h + label_h;
    for (row, values) in rows.iter().enumerate() {
        for (col, panels) in values.iter().enumerate() {
            for (k, bytes) in panels.iter().enumerate() {
                let x = MARGIN + k as u32 * (n + MARGIN) + col as u32;
                img.put_pixel(x, top + row as u32, Pixel(*bytes));
            }
        }
    }
    img
}
