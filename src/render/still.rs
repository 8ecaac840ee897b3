//! One call from a scene and a gem to a film, as `lapidary render` makes
//! it: compensation tables computed, flakes and glitter shaded by their
//! footprint, the camera's film and the sampler's of one size. The steps
//! it takes ([`crate::render::prepare::prepare_scene`],
//! [`crate::render::film::render`], …) stay public for a program that
//! changes one of them.

use std::sync::Arc;

use crate::recipe::gem::GemSource;
use crate::recipe::{TableCache, Tables};
use crate::render::film::{self, Film, FilmSettings};
use crate::render::prepare::{camera_for, prepare_scene, RenderError};
use crate::scene::Scene;

/// Largest image side, in pixels (the command's `--width`/`--height`).
pub const MAX_SIDE_PX: u32 = 32_768;
/// Most samples per pixel (the command's `--spp`).
pub const MAX_SPP: u32 = 1 << 20;
/// Most bounces after the first hit (the command's `--bounces`).
pub const MAX_BOUNCES: u32 = 64;
/// Bounces after the first hit when none are asked for (the command's
/// `--bounces`, a job's `bounces`, the gallery's): a flaked translucent
/// stone's light reflected inside its surface is within about 0.3 % of
/// its value at 32 bounces (at 4, up to 4 % below).
pub const DEFAULT_BOUNCES: u32 = 8;

/// What [`render_still`] renders besides the scene and the gem; its
/// [`Default`] is `lapidary render`'s.
#[derive(Clone, Debug)]
pub struct StillSettings {
    /// Image width, 1 to [`MAX_SIDE_PX`] pixels (default 512).
    pub width_px: u32,
    /// Image height, 1 to [`MAX_SIDE_PX`] pixels (default 512).
    pub height_px: u32,
    /// Samples per pixel, 1 to [`MAX_SPP`] (default 64).
    pub samples_per_pixel: u32,
    /// Seed of the sample pattern (default 0); the picture's flakes are
    /// the recipe's, whatever this is.
    pub seed: u64,
    /// Bounces after the first hit, 0 to [`MAX_BOUNCES`] (default
    /// [`DEFAULT_BOUNCES`]; a translucent stone's inside needs at least 2).
    pub bounces: u32,
    /// Flakes and glitter shaded by each pixel's footprint (default on);
    /// off, every flake by its own normal (the command's `--exact-flakes`).
    pub flake_footprints: bool,
    /// Where the materials' compensation tables are kept: `None` computes
    /// them for this render alone (seconds for a rough layered material);
    /// a cache shared between renders computes each once.
    pub tables: Option<Arc<TableCache>>,
}

impl Default for StillSettings {
    fn default() -> Self {
        StillSettings {
            width_px: 512,
            height_px: 512,
            samples_per_pixel: 64,
            seed: 0,
            bounces: DEFAULT_BOUNCES,
            flake_footprints: true,
            tables: None,
        }
    }
}

/// Renders `scene` with `gem` on every stone that names no recipe of its
/// own: the film of `lapidary render` with the same inputs and settings
/// (its PNG is [`crate::output::tonemap::DisplayTransform::encode_film`],
/// the command's with `dither_seed` = `seed`; its EXR
/// [`crate::output::exr::film_channels`]).
///
/// ```
/// use lapidary::render::still::{render_still, StillSettings};
/// use lapidary::{output::tonemap::DisplayTransform, scene, GemSource};
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let gem = GemSource::load("sunstone")?; // a built-in name or a .ron path
/// let settings = StillSettings { width_px: 32, height_px: 24, samples_per_pixel: 4, ..Default::default() };
/// let film = render_still(&scene::default_scene(), &gem, &settings)?;
/// let png = DisplayTransform::default().encode_film(&film);
/// png.save(std::env::temp_dir().join("sunstone.png"))?;
/// # Ok(()) }
/// ```
pub fn render_still(
    scene: &Scene,
    gem: &GemSource,
    settings: &StillSettings,
) -> Result<Film, RenderError> {
    let fail = |message: String| Err(RenderError::from(message));
    for (name, value) in [
        ("width_px", settings.width_px),
        ("height_px", settings.height_px),
    ] {
        if !(1..=MAX_SIDE_PX).contains(&value) {
            return fail(format!("{name} {value}: allowed 1 to {MAX_SIDE_PX} pixels"));
        }
    }
    if !(1..=MAX_SPP).contains(&settings.samples_per_pixel) {
        return fail(format!(
            "samples_per_pixel {}: allowed 1 to {MAX_SPP}",
            settings.samples_per_pixel
        ));
    }
    if settings.bounces > MAX_BOUNCES {
        return fail(format!(
            "bounces {}: allowed 0 to {MAX_BOUNCES}",
            settings.bounces
        ));
    }
    let cache = settings
        .tables
        .clone()
        .unwrap_or_else(|| Arc::new(TableCache::in_memory()));
    let mut traced = prepare_scene(
        scene,
        gem,
        None,
        settings.bounces,
        Tables::Computed(&cache),
        &|_| {},
    )?;
    if settings.flake_footprints {
        traced.shade_flakes_by_footprint(Some(cache));
    }
    let (width, height) = (settings.width_px, settings.height_px);
    let camera = camera_for(scene, width, height);
    let film_settings = FilmSettings::new(width, height, settings.samples_per_pixel, settings.seed);
    Ok(film::render(&traced, &camera, &film_settings, &|_| {}))
}
