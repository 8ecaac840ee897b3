//! The radial scale of one polar panel: value → fraction of the plot radius.
//!
//! Each panel gets its own scale from the peak of its analytic curves,
//! rounded up to a nice number so the rings carry round labels. When the
//! dynamic range is huge (a glossy spike over a faint diffuse base, peak /
//! median > [`LOG_THRESHOLD`]), a linear scale would shrink everything but the
//! spike to a dot, so the panel switches to a logarithmic scale spanning a few
//! decades and says so in its label.

/// Peak / median ratio above which a panel uses a logarithmic radius.
pub(crate) const LOG_THRESHOLD: f64 = 50.0;

/// Fewest and most decades a logarithmic panel spans.
const LOG_DECADES: (f64, f64) = (3.0, 6.0);

/// How values map to radius in one panel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum RadialScale {
    /// radius ∝ value; rings every `step`, the outermost at `step × rings`.
    Linear {
        /// Value between neighbouring rings.
        step: f64,
        /// Number of rings; the outer ring is the plot radius.
        rings: u32,
    },
    /// radius ∝ log10(value / floor), one ring per decade, the outermost at
    /// `top`; values at or below `top / 10^decades` sit at the centre.
    Log {
        /// Value on the outer ring.
        top: f64,
        /// Decades between the centre and the outer ring.
        decades: u32,
    },
}

/// The scale of a panel together with the peak it was built for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PanelScale {
    /// The value → radius mapping.
    pub radial: RadialScale,
    /// Largest value the scale was fitted to (0 when there was no data).
    pub peak: f64,
}

impl PanelScale {
    /// Fits a scale to `values`; non-finite and non-positive values are
    /// ignored, and no usable value gives a unit linear scale.
    pub fn fit(values: impl IntoIterator<Item = f64>) -> Self {
        let mut v: Vec<f64> = values
            .into_iter()
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect();
        if v.is_empty() {
            return Self {
                radial: RadialScale::Linear {
                    step: 0.25,
                    rings: 4,
                },
                peak: 0.0,
            };
        }
        v.sort_by(f64::total_cmp);
        let peak = v[v.len() - 1];
        let median = v[v.len() / 2];
        let radial = if peak / median > LOG_THRESHOLD {
            log_scale(peak, median)
        } else {
            linear_scale(peak)
        };
        Self { radial, peak }
    }

    /// Fraction of the plot radius (in [0, 1]) at which `value` is drawn;
    /// values beyond the outer ring are pinned to it. `None` for values that
    /// cannot be plotted (negative, NaN, infinite).
    pub fn fraction(&self, value: f64) -> Option<f64> {
        if !value.is_finite() || value < 0.0 {
            return None;
        }
        let f = match self.radial {
            RadialScale::Linear { step, rings } => value / (step * f64::from(rings)),
            RadialScale::Log { top, decades } => {
                let d = f64::from(decades);
                1.0 + (value / top).log10() / d
            }
        };
        Some(if f.is_nan() { 0.0 } else { f.clamp(0.0, 1.0) })
    }

    /// The rings to draw: (fraction of the radius, label of its value).
    pub(crate) fn rings(&self) -> Vec<(f64, String)> {
        match self.radial {
            RadialScale::Linear { step, rings } => (1..=rings)
                .map(|k| {
                    let frac = f64::from(k) / f64::from(rings);
                    (frac, format_value(step * f64::from(k), 3))
                })
                .collect(),
            RadialScale::Log { top, decades } => (1..=decades)
                .map(|k| {
                    let frac = f64::from(k) / f64::from(decades);
                    let value = top / 10f64.powi((decades - k) as i32);
                    (frac, format_value(value, 2))
                })
                .collect(),
        }
    }

    /// The caption under the panel, e.g. "max 0.52" or "max 31 (log scale)".
    pub fn caption(&self) -> String {
        if self.peak == 0.0 {
            return "no data".to_string();
        }
        let max = format!("max {}", format_value(self.peak, 2));
        match self.radial {
            RadialScale::Linear { .. } => max,
            RadialScale::Log { .. } => format!("{max} (log scale)"),
        }
    }
}

/// Linear scale with 1–4 rings at a round step and the outer ring ≥ `peak`.
fn linear_scale(peak: f64) -> RadialScale {
    let step = nice_ceil(peak / 4.0, &[1.0, 2.0, 2.5, 5.0, 10.0]);
    let rings = (peak / step * (1.0 - 1e-9)).ceil().clamp(1.0, 4.0) as u32;
    let outer = step * f64::from(rings);
    if step > 0.0 && outer.is_finite() && outer >= peak * (1.0 - 1e-9) {
        RadialScale::Linear { step, rings }
    } else {
        // Peaks near the ends of the f64 range: no rounding, one ring at the peak.
        RadialScale::Linear {
            step: peak,
            rings: 1,
        }
    }
}

/// Log scale whose outer ring is `peak` rounded up to 1, 2 or 5 × 10^k and
/// whose floor lies at least a decade below `median`.
fn log_scale(peak: f64, median: f64) -> RadialScale {
    let mut top = nice_ceil(peak, &[1.0, 2.0, 5.0, 10.0]);
    if !(top.is_finite() && top > 0.0) {
        top = peak;
    }
    let span = (top / median).log10() + 1.0;
    let decades = if span.is_finite() {
        span.ceil().clamp(LOG_DECADES.0, LOG_DECADES.1)
    } else {
        LOG_DECADES.1
    };
    RadialScale::Log {
        top,
        decades: decades as u32,
    }
}

/// Smallest `m × 10^k` ≥ `x` with `m` from `mantissas` (ascending, ending
/// in 10); 0 when `x` is not a positive finite number.
fn nice_ceil(x: f64, mantissas: &[f64]) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return 0.0;
    }
    let base = 10f64.powf(x.log10().floor());
    mantissas
        .iter()
        .map(|m| m * base)
        .find(|s| *s >= x * (1.0 - 1e-12))
        .unwrap_or(10.0 * base)
}

/// Formats `v` with at most `sig` significant digits and no trailing zeros:
/// plain decimals for 0.001 ≤ |v| < 100000, scientific ("1e-5") otherwise.
pub(crate) fn format_value(v: f64, sig: usize) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if a == 0.0 {
        return "0".to_string();
    }
    let sig = sig.max(1);
    if (1e-3..1e5).contains(&a) {
        let magnitude = a.log10().floor() as i64;
        let decimals = (sig as i64 - 1 - magnitude).max(0) as usize;
        trim_zeros(&format!("{v:.decimals$}"))
    } else {
        let s = format!("{v:.prec$e}", prec = sig - 1);
        match s.split_once('e') {
            Some((mantissa, exp)) => format!("{}e{exp}", trim_zeros(mantissa)),
            None => s,
        }
    }
}

/// "0.250" → "0.25", "2.00" → "2", "40" → "40".
fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_scale_rounds_the_peak_up_to_round_rings() {
        let s = PanelScale::fit([0.1, 0.3, 0.52]);
        assert_eq!(
            s.radial,
            RadialScale::Linear {
                step: 0.2,
                rings: 3
            }
        );
        assert_eq!(s.caption(), "max 0.52");
        let labels: Vec<String> = s.rings().into_iter().map(|r| r.1).collect();
        assert_eq!(labels, ["0.2", "0.4", "0.6"]);
        assert!((s.fraction(0.3).unwrap() - 0.5).abs() < 1e-12);
        assert_eq!(
            s.fraction(0.9),
            Some(1.0),
            "beyond the outer ring is pinned"
        );
    }

    #[test]
    fn lambert_peak_gets_four_rings_of_a_tenth() {
        let s = PanelScale::fit([1.0 / std::f64::consts::PI, 0.2]);
        assert_eq!(
            s.radial,
            RadialScale::Linear {
                step: 0.1,
                rings: 4
            }
        );
    }

    #[test]
    fn huge_dynamic_range_switches_to_a_log_scale_and_says_so() {
        let mut values = vec![0.05; 50];
        values.push(30.0);
        let s = PanelScale::fit(values);
        let RadialScale::Log { top, decades } = s.radial else {
            panic!("expected a log scale, got {:?}", s.radial);
        };
        assert_eq!(top, 50.0);
        assert!(
            top / 10f64.powi(decades as i32) <= 0.005,
            "median a decade above floor"
        );
        assert!(s.caption().contains("log"), "{}", s.caption());
        assert_eq!(s.fraction(50.0), Some(1.0));
        assert_eq!(s.fraction(1e-30), Some(0.0));
        let f = s.fraction(5.0).unwrap();
        assert!((f - (1.0 - 1.0 / f64::from(decades))).abs() < 1e-12);
    }

    #[test]
    fn degenerate_values_give_usable_scales() {
        for values in [
            vec![],
            vec![f64::NAN, f64::INFINITY, -1.0, 0.0],
            vec![f64::MAX],
            vec![f64::MIN_POSITIVE, 5e-324],
            vec![f64::MAX, 5e-324],
        ] {
            let s = PanelScale::fit(values.clone());
            for v in [0.0, 1.0, f64::MAX, 5e-324] {
                let f = s.fraction(v).unwrap();
                assert!((0.0..=1.0).contains(&f), "{values:?}: {v} -> {f}");
            }
            assert!(s.fraction(f64::NAN).is_none());
            assert!(!s.rings().is_empty());
        }
    }

    #[test]
    fn values_are_formatted_compactly() {
        assert_eq!(format_value(0.25, 3), "0.25");
        assert_eq!(format_value(2.0, 3), "2");
        assert_eq!(format_value(0.5234, 2), "0.52");
        assert_eq!(format_value(120.4, 2), "120");
        assert_eq!(format_value(1e-4, 2), "1e-4");
        assert_eq!(format_value(1.26e7, 2), "1.3e7");
    }
}
