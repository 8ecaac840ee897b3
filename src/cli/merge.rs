//! `lapidary merge`: tiles of a render (`render --tile I/N`) back into its
//! image, the same bytes as a single render, or a refusal naming the tile.

use std::path::PathBuf;

use lapidary::farm::merge::{merge, read_tile, Merged};
use lapidary::output::exr::write_exr_owned;

use super::{whole, MAX_THREADS};

/// Arguments of `lapidary merge`.
#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// The tile EXRs, every tile of one render once, in any order.
    #[arg(required = true, value_name = "TILE.exr")]
    tiles: Vec<PathBuf>,
    /// The image to write: .png (tone-mapped as the render would) or .exr.
    #[arg(short = 'o', long = "output", value_name = "OUT.png|OUT.exr")]
    output: PathBuf,
    /// Worker threads for the encoding (default: all cores).
    #[arg(long, value_name = "N", allow_negative_numbers = true,
        value_parser = whole::<usize, 1, MAX_THREADS>)]
    threads: Option<usize>,
    /// No summary.
    #[arg(long, short = 'q')]
    quiet: bool,
}

/// Run `lapidary merge`.
pub fn run(args: MergeArgs) -> Result<(), String> {
    lapidary::output::check_writable(&args.output).map_err(|e| e.to_string())?;
    let png = super::render::is_png_output(&args.output)?;
    super::check_threads(args.threads)?;
    // The output must not be one of the tiles (it would replace it).
    if let Some(tile) = args
        .tiles
        .iter()
        .find(|t| super::same_file(t, &args.output))
    {
        return Err(format!(
            "{}: the output is one of the tiles ({}); allowed: a file that is not a tile",
            args.output.display(),
            tile.display()
        ));
    }
    let tiles = args
        .tiles
        .iter()
        .map(|path| read_tile(path))
        .collect::<Result<Vec<_>, _>>()?;
    let count = tiles.len();
    let merged = merge(tiles)?;
    let pool = super::worker_pool(args.threads)?;
    pool.install(|| write_merged(&args.output, merged, png))?;
    if !args.quiet {
        eprintln!(
            "merged {count} tile{} into {}",
            if count == 1 { "" } else { "s" },
            args.output.display()
        );
    }
    Ok(())
}

/// Write a merged image to `output` as PNG (when `png`) or EXR, with the
/// warning a single render would print about left-out samples.
pub(super) fn write_merged(
    output: &std::path::Path,
    merged: Merged,
    png: bool,
) -> Result<Option<image::RgbImage>, String> {
    if merged.bad_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN, infinite or negative and were left out",
            merged.bad_samples
        );
    }
    if png {
        let image = merged.png_image();
        lapidary::output::write_png(output, &image).map_err(|e| e.to_string())?;
        Ok(Some(image))
    } else {
        write_exr_owned(output, merged.width, merged.height, merged.channels)
            .map_err(|e| e.to_string())?;
        Ok(None)
    }
}
