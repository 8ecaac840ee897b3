//! `lapidary maps`: the figure 4.6 decomposition of a gem recipe.

use super::MapsArgs;
use lapidary::brdf::compensation::single_crossing_albedo;
use lapidary::brdf::Rgb;
use lapidary::gallery::plot::maps::{maps_sheet, MapsSheetStyle};
use lapidary::recipe::gem::{compile_gem, Body, Gem, GemSource};
use lapidary::recipe::Tables;

/// The widest slice drawn, texture units (10 m of stone): far beyond any
/// stone, and before the patterns' coordinates lose their precision.
const MAX_EXTENT: f64 = 1000.0;

/// Panel sizes beyond this would make a sheet of more than ~200 MB.
pub(super) const MAX_PANEL_PX: u32 = 4096;

/// Each material's normal-incidence albedo (single-crossing model), the
/// colour it gets in the surface and glitter panels.
fn material_colours(gem: &Gem) -> Vec<Rgb> {
    gem.brdfs
        .iter()
        .map(|brdf| single_crossing_albedo(brdf, 1.0, gem.seed))
        .collect()
}

/// Run `lapidary maps`.
pub fn run(args: MapsArgs) -> Result<(), String> {
    super::check_png_output(&args.output)?;
    if args.size == 0 || args.size > MAX_PANEL_PX {
        return Err(format!(
            "--size {}: allowed 1 to {MAX_PANEL_PX} pixels per panel",
            args.size
        ));
    }
    if !(args.extent > 0.0 && args.extent <= MAX_EXTENT) {
        return Err(format!(
            "--extent {}: allowed above 0 up to {MAX_EXTENT} texture units (one is 10 mm of stone)",
            super::typed(args.extent)
        ));
    }
    let source = GemSource::load(&args.recipe).map_err(|e| e.to_string())?;
    let gem = compile_gem(&source, None, Tables::Skipped).map_err(|e| e.to_string())?;
    let colours = material_colours(&gem);
    let style = MapsSheetStyle {
        panel_px: args.size,
        extent: args.extent,
        title: format!("{}: figure 4.6 maps, slice z = 0", gem.name),
    };
    if matches!(gem.body, Body::Translucent { .. }) {
        eprintln!(
            "note: {} is translucent: its look comes from inside the stone, which this sheet of its surface maps does not show",
            gem.name
        );
    }
    let image = maps_sheet(&gem.pattern, &colours, &style);
    lapidary::output::write_png(&args.output, &image).map_err(|e| e.to_string())?;
    eprintln!("wrote {}", args.output.display());
    Ok(())
}
