//! `lapidary brdf`: albedo tables, point evaluations and polar plots.

use super::BrdfArgs;
use lapidary::brdf::albedo::{albedo_angles_deg, directional_albedo, in_plane, in_plane_slice};
use lapidary::brdf::reference::{model_slice, reference_albedo_with, reference_slice, WalkTables};
use lapidary::brdf::LayeredBrdf;
use lapidary::gallery::plot::{in_plane_panel, polar_plot, rgb_curves, PolarPanel, PolarPlotStyle};
use lapidary::recipe::compile::load_material_with;
use lapidary::recipe::Tables;
use lapidary::sampling::direction_from_degrees;

/// Fixed seed of every estimate this command prints: same output each run.
const SEED: u64 = 2011;
/// ±0.005 at two standard errors.
const ALBEDO_STD_ERROR: f64 = 0.0025;
/// Incidence angles of the plots (the top row of figure 2.1).
const PLOT_INCIDENCE_DEG: [f64; 4] = [0.0, 30.0, 60.0, 75.0];

fn load(args: &BrdfArgs) -> Result<LayeredBrdf, String> {
    let cache = super::table_cache_from_env();
    let tables = if args.single_crossing {
        Tables::Skipped
    } else {
        Tables::Computed(&cache)
    };
    load_material_with(&args.material, tables).map_err(|e| e.to_string())
}

/// Run `lapidary brdf`.
pub fn run(args: BrdfArgs) -> Result<(), String> {
    if let Some(path) = &args.output {
        super::check_png_output(path)?;
    }
    let eval_angles = args.eval.map(check_eval_angles).transpose()?;
    if let Some(theta_i) = args.slice {
        if !(0.0..=90.0).contains(&theta_i) {
            return Err(format!("--slice {theta_i}: allowed 0 to 90 degrees"));
        }
    }
    let brdf = load(&args)?;
    if args.albedo {
        print_albedo(&brdf, args.reference);
    } else if let Some(theta_i) = args.slice {
        print_slice(&brdf, theta_i, args.reference);
    } else if let Some([ti, pi, to, po]) = eval_angles {
        let f = brdf.eval(
            direction_from_degrees(ti, pi),
            direction_from_degrees(to, po),
        );
        super::emit(&format!("{:.6},{:.6},{:.6}", f.x, f.y, f.z));
    } else if let Some(path) = &args.output {
        let image = plot(&brdf, args.reference);
        lapidary::output::write_png(path, &image).map_err(|e| e.to_string())?;
        eprintln!("wrote {}", path.display());
    } else {
        unreachable!("clap requires one of --albedo, --slice, --eval or -o");
    }
    Ok(())
}

/// `--eval`'s "θi,φi,θo,φo": four numbers (anything else is a usage
/// error); their ranges are [`check_eval_angles`]'s.
pub(super) fn parse_four_numbers(text: &str) -> Result<[f64; 4], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 4 {
        return Err("expected four angles THETA_I,PHI_I,THETA_O,PHI_O in degrees".into());
    }
    let mut out = [0.0; 4];
    for (k, p) in parts.iter().enumerate() {
        out[k] = p.parse().map_err(|_| format!("`{p}` is not a number"))?;
    }
    Ok(out)
}

/// `--eval`'s angles in degrees, if θ lies in [0, 90] and φ is finite.
fn check_eval_angles(angles: [f64; 4]) -> Result<[f64; 4], String> {
    for (k, v) in angles.iter().enumerate() {
        if !v.is_finite() || ((k == 0 || k == 2) && !(0.0..=90.0).contains(v)) {
            let [ti, pi, to, po] = angles.map(super::typed);
            return Err(format!(
                "--eval {ti},{pi},{to},{po}: `{}` is out of range; θ must be in [0, 90] degrees, φ finite",
                super::typed(*v)
            ));
        }
    }
    Ok(angles)
}

fn print_albedo(brdf: &LayeredBrdf, with_reference: bool) {
    // The walk's micro-facet tables, built once for all 18 angles.
    let tables = with_reference.then(|| WalkTables::new(brdf));
    if with_reference {
        super::emit("theta_deg,r,g,b,reference_r,reference_g,reference_b");
    } else {
        super::emit("theta_deg,r,g,b");
    }
    for theta in albedo_angles_deg() {
        let a = directional_albedo(brdf, theta, ALBEDO_STD_ERROR, 4_000_000, SEED);
        let m = a.mean;
        if let Some(tables) = &tables {
            let (r, _) = reference_albedo_with(brdf, tables, in_plane(theta), 100_000, SEED);
            super::emit(&format!(
                "{theta},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
                m.x, m.y, m.z, r.x, r.y, r.z
            ));
        } else {
            super::emit(&format!("{theta},{:.4},{:.4},{:.4}", m.x, m.y, m.z));
        }
    }
}

/// Side of the walk's bins on the projected unit disc, for `--slice`.
const SLICE_BIN: f64 = 0.02;

/// The in-plane slice f·cosθₒ for light at `theta_i` degrees as CSV, with
/// the random walk's (2 M paths, squares of side 0.02 on the projected
/// disc) beside it when asked. Beside the walk the model is averaged over
/// the same squares ([`model_slice`]), so that a lobe narrower than a
/// square compares like with like; a mirror-like coat (below about 0.1°)
/// is a spike that average does not resolve at its peak.
fn print_slice(brdf: &LayeredBrdf, theta_i: f64, with_reference: bool) {
    let angles = walk_angles_deg();
    let (model, reference) = if with_reference {
        (
            model_slice(brdf, theta_i, &angles, SLICE_BIN),
            Some(reference_slice(
                brdf, theta_i, &angles, 2_000_000, SLICE_BIN, SEED,
            )),
        )
    } else {
        (in_plane_slice(brdf, theta_i, &angles), None)
    };
    if with_reference {
        super::emit("theta_o_deg,r,g,b,reference_r,reference_g,reference_b");
    } else {
        super::emit("theta_o_deg,r,g,b");
    }
    for (k, (&theta_o, v)) in angles.iter().zip(&model).enumerate() {
        let mut line = format!("{theta_o},{:.6},{:.6},{:.6}", v.x, v.y, v.z);
        if let Some(r) = reference.as_ref().map(|r| r[k]) {
            line += &format!(",{:.6},{:.6},{:.6}", r.x, r.y, r.z);
        }
        super::emit(&line);
    }
}

/// The signed outgoing angles at which the random walk's slice is
/// estimated: −87° to 87° in steps of 3.
fn walk_angles_deg() -> Vec<f64> {
    (0..=58).map(|k| -87.0 + f64::from(k) * 3.0).collect()
}

/// In-plane slice f(ωᵢ, ωₒ)·cosθₒ; light on the φ = 180° side.
fn plot(brdf: &LayeredBrdf, with_reference: bool) -> image::RgbImage {
    let panels: Vec<PolarPanel> = PLOT_INCIDENCE_DEG
        .iter()
        .map(|&theta_i| {
            let mut panel = in_plane_panel(brdf, theta_i);
            panel.reference = with_reference.then(|| {
                let angles = walk_angles_deg();
                let values = reference_slice(brdf, theta_i, &angles, 400_000, 0.05, SEED);
                rgb_curves(&angles, &values)
            });
            panel
        })
        .collect();
    let style = PolarPlotStyle {
        title: format!("{}: f·cos θo in the plane of incidence", brdf.name),
        ..PolarPlotStyle::default()
    };
    polar_plot(&panels, &style)
}
