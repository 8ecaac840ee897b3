//! Tests of the polar plot: layout, geometry of the curves, robustness.

use super::*;

fn panel(incidence_deg: f64, curves: [Vec<(f64, f64)>; 3]) -> PolarPanel {
    PolarPanel {
        incidence_deg,
        curves,
        reference: None,
    }
}

fn empty_panel(incidence_deg: f64) -> PolarPanel {
    panel(incidence_deg, [vec![], vec![], vec![]])
}

fn style(title: &str) -> PolarPlotStyle {
    PolarPlotStyle {
        title: title.to_string(),
        ..PolarPlotStyle::default()
    }
}

/// Strongly red: a red curve stroke, not the faint fill or grey ink.
fn is_strong_red(p: &Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r >= 200 && r - g >= 100 && r - b >= 100
}

/// Any red tint at all, fill included.
fn is_reddish(p: &Rgb<u8>) -> bool {
    let [r, g, b] = p.0.map(i32::from);
    r - g >= 20 && r - b >= 20
}

/// A single lobe, cos²-shaped, centred on θo = +30°, peak 1, zero elsewhere.
fn lobe_at_30() -> Vec<(f64, f64)> {
    (-90..=90)
        .map(|t| {
            let t = f64::from(t);
            let x = (t - 30.0) / 20.0;
            let v = if x.abs() < 1.0 {
                (x * std::f64::consts::FRAC_PI_2).cos().powi(2)
            } else {
                0.0
            };
            (t, v)
        })
        .collect()
}

#[test]
fn image_size_follows_the_number_of_panels() {
    let s = style("size");
    let size = s.panel_size_px;
    let mut heights = Vec::new();
    for n in 1..=4 {
        let panels: Vec<PolarPanel> = (0..n).map(|i| empty_panel(30.0 * i as f64)).collect();
        let img = polar_plot(&panels, &s);
        assert_eq!(img.width(), 2 * PAD + n * size, "{n} panels");
        let layout = Layout::new(n as usize, &s, false);
        assert_eq!(
            img.height(),
            layout.panels_top + layout.metrics.height + PAD / 2
        );
        assert!(layout.metrics.height >= size / 2, "a half-disc fits");
        heights.push(img.height());
    }
    assert!(
        heights.windows(2).all(|h| h[0] >= h[1]),
        "narrower plots wrap the legend: {heights:?}"
    );
    let four = Layout::new(4, &s, true);
    assert!(
        four.legend.iter().all(|item| item.1 == four.legend[0].1),
        "four panels: one legend row"
    );
    assert_eq!(heights[3], four.panels_top + four.metrics.height + PAD / 2);
    assert!(heights[3] < 2 * size, "{heights:?}");
}

#[test]
fn zero_panels_give_a_small_image_with_the_title() {
    let img = polar_plot(&[], &style("Lapis lazuli"));
    assert!(img.width() <= MAX_BLANK_WIDTH && img.height() < 80);
    let text_pixels = img.pixels().filter(|p| **p == palette::TEXT).count();
    assert!(text_pixels > 50, "the title is drawn ({text_pixels} px)");
}

#[test]
fn too_many_panels_wrap_into_rows_and_stay_bounded() {
    let panels: Vec<PolarPanel> = (0..100).map(|_| empty_panel(0.0)).collect();
    let img = polar_plot(&panels, &style("many"));
    let one_row = polar_plot(&panels[..8], &style("many"));
    assert_eq!(img.width(), one_row.width());
    let rows = (MAX_PANELS / MAX_COLUMNS) as u32;
    let layout = Layout::new(8, &style("many"), false);
    assert_eq!(
        img.height(),
        one_row.height() + (rows - 1) * layout.metrics.height
    );
}

#[test]
fn a_lobe_at_plus_30_degrees_is_drawn_up_and_right_at_its_radius() {
    let s = style("lobe");
    let img = polar_plot(&[panel(30.0, [lobe_at_30(), vec![], vec![]])], &s);
    let frame = Layout::new(1, &s, false).frame(0);
    let m = frame.metrics;
    let (cx, cy) = (
        f64::from(frame.left) + m.centre.0,
        f64::from(frame.top) + m.centre.1,
    );
    // Peak 1 → linear scale with outer ring 1 → the peak sits on the rim.
    let (s30, c30) = 30f64.to_radians().sin_cos();
    let along_ray = |d: f64| ((cx + d * s30) as u32, (cy - d * c30) as u32);
    let (px, py) = along_ray(m.radius);
    let near_peak =
        (px - 1..=px + 1).any(|x| (py - 1..=py + 1).any(|y| is_strong_red(img.get_pixel(x, y))));
    assert!(near_peak, "no red stroke at the expected peak ({px}, {py})");
    for step in 12..(2 * m.radius as u32 + 20) {
        let d = f64::from(step) / 2.0;
        let (x, y) = along_ray(d);
        if is_strong_red(img.get_pixel(x, y)) {
            assert!(
                (d - m.radius).abs() <= 2.5,
                "red stroke at distance {d}, not {}",
                m.radius
            );
        }
    }
    let panel_rows = frame.top..(cy - 2.0) as u32;
    let left_cols = frame.left..(cx - 2.0) as u32;
    for y in panel_rows {
        for x in left_cols.clone() {
            assert!(
                !is_reddish(img.get_pixel(x, y)),
                "red in the upper left at ({x}, {y})"
            );
        }
    }
}

#[test]
fn overlapping_channels_add_up_to_white() {
    let lobe = lobe_at_30();
    let img = polar_plot(
        &[panel(30.0, [lobe.clone(), lobe.clone(), lobe])],
        &style("grey"),
    );
    let frame = Layout::new(1, &style("grey"), false).frame(0);
    let m = frame.metrics;
    let (s30, c30) = 30f64.to_radians().sin_cos();
    let x = (f64::from(frame.left) + m.centre.0 + m.radius * s30) as u32;
    let y = (f64::from(frame.top) + m.centre.1 - m.radius * c30) as u32;
    let white = (x - 1..=x + 1)
        .any(|x| (y - 1..=y + 1).any(|y| img.get_pixel(x, y).0.iter().all(|&c| c >= 245)));
    assert!(white, "R+G+B on the same curve should read as white");
}

#[test]
fn garbage_values_are_skipped_and_stay_inside_their_panel() {
    let garbage = vec![
        (f64::NAN, 1.0),
        (30.0, f64::NAN),
        (30.0, f64::INFINITY),
        (45.0, -1.0),
        (0.0, 0.0),
        (120.0, 1.0),
        (-1e9, 1.0),
        (f64::NEG_INFINITY, 1.0),
        (10.0, f64::MAX),
        (20.0, 5e-324),
        (-90.0, 0.0),
        (90.0, 1e-300),
    ];
    let dirty = [
        PolarPanel {
            incidence_deg: f64::NAN,
            curves: [garbage.clone(), vec![], vec![(f64::NAN, f64::NAN)]],
            reference: Some([garbage.clone(), vec![], garbage.clone()]),
        },
        PolarPanel {
            incidence_deg: 1e9,
            curves: [vec![(0.0, 0.0)], garbage.clone(), garbage.clone()],
            reference: Some([vec![], vec![], vec![]]),
        },
    ];
    let clean: Vec<PolarPanel> = dirty
        .iter()
        .map(|p| PolarPanel {
            curves: [vec![], vec![], vec![]],
            reference: Some([vec![], vec![], vec![]]),
            ..p.clone()
        })
        .collect();
    let s = style("garbage");
    let (a, b) = (polar_plot(&dirty, &s), polar_plot(&clean, &s));
    assert_eq!(a.dimensions(), b.dimensions());
    let layout = Layout::new(2, &s, true);
    let mut changed = 0;
    for (x, y, p) in a.enumerate_pixels() {
        if p == b.get_pixel(x, y) {
            continue;
        }
        changed += 1;
        let inside = (0..2).any(|i| {
            let f = layout.frame(i);
            let (lx, ly) = (
                f64::from(x) - f64::from(f.left),
                f64::from(y) - f64::from(f.top),
            );
            let caption = ly >= f64::from(f.metrics.caption_top) - 1.0
                && ly < f64::from(f.metrics.height)
                && lx >= 0.0
                && lx < f64::from(f.metrics.width);
            let (dx, dy) = (lx - f.metrics.centre.0, ly - f.metrics.centre.1);
            let disc = dx.hypot(dy) <= f.metrics.radius + 4.0 && dy <= 4.0;
            let ring_labels = dy > 0.0
                && ly < f64::from(f.metrics.caption_top)
                && dx >= -4.0
                && lx < f64::from(f.metrics.width);
            caption || disc || ring_labels
        });
        assert!(
            inside,
            "pixel ({x}, {y}) changed outside its panel's plot area"
        );
    }
    assert!(changed > 0, "the finite values were drawn");
}

#[test]
fn huge_dynamic_range_is_labelled_log() {
    let mut spike: Vec<(f64, f64)> = (-90..=90).map(|t| (f64::from(t), 0.05)).collect();
    spike[150].1 = 80.0;
    let p = panel(60.0, [spike.clone(), spike.clone(), spike]);
    assert!(fit_scale(&p).caption().contains("log"));
    let img = polar_plot(&[p], &style("spike"));
    assert!(img.pixels().any(|p| p.0.iter().all(|&c| c >= 245)));
}

/// Synthetic material: coloured Lambert base plus a white glossy lobe round
/// the mirror direction, value = f·cosθo.
fn synthetic(theta_i: f64, theta_o: f64, albedo: f64, gloss: (f64, f64)) -> f64 {
    let cos_o = theta_o.to_radians().cos().max(0.0);
    let diffuse = albedo / std::f64::consts::PI;
    let (height, width_deg) = gloss;
    let x = (theta_o - theta_i) / width_deg;
    let glossy = height * (-x * x).exp() / cos_o.max(0.2);
    (diffuse + glossy) * cos_o
}

/// Deterministic noise in [-1, 1) (a tiny LCG, to avoid a dependency).
fn noise(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

fn demo_panels(gloss: (f64, f64), with_reference: bool) -> Vec<PolarPanel> {
    let albedo = [0.85, 0.55, 0.2];
    let mut state = 7;
    [0.0, 30.0, 60.0, 75.0]
        .iter()
        .map(|&ti| {
            let curves = albedo.map(|a| {
                (-90..=90)
                    .map(|t| (f64::from(t), synthetic(ti, f64::from(t), a, gloss)))
                    .collect::<Vec<_>>()
            });
            let reference = with_reference.then(|| {
                albedo.map(|a| {
                    (-88..=88)
                        .step_by(4)
                        .map(|t| {
                            let v = synthetic(ti, f64::from(t), a, gloss);
                            (f64::from(t), v * (1.0 + 0.08 * noise(&mut state)))
                        })
                        .collect::<Vec<_>>()
                })
            });
            PolarPanel {
                incidence_deg: ti,
                curves,
                reference,
            }
        })
        .collect()
}

#[test]
fn demo_png_is_written() {
    let glossy = polar_plot(
        &demo_panels((0.3, 12.0), true),
        &style("Demo: orange Lambert base + white glossy lobe"),
    );
    glossy
        .save("/tmp/polar_demo.png")
        .expect("write /tmp/polar_demo.png");
    let spiky = polar_plot(
        &demo_panels((20.0, 1.5), false),
        &style("Demo: near-mirror spike (log scale)"),
    );
    spiky
        .save("/tmp/polar_demo_log.png")
        .expect("write /tmp/polar_demo_log.png");
    assert!(glossy.width() > 1000);
}
