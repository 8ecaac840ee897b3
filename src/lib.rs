//! lapidary: procedural gemstones rendered with layered micro-facet BRDFs
//! (Weidlich & Wilkie, "Thinking in Layers", SIGGRAPH Asia 2011 course
//! notes: sections 3.4, 4.1–4.3 and the appendix).
//!
//! Data flows one way (the repository's `ARCHITECTURE.md`): a RON gem
//! recipe is parsed, validated and compiled into a [`Gem`] (its pattern
//! tree and one layered BRDF per material); a scene file becomes a
//! [`scene::Scene`]; the renderer traces the gems in the scene into a
//! [`render::film::Film`] of linear radiance and AOVs; [`output`] writes it
//! as PNG or EXR. A render is a pure function of (recipes, scene, seed,
//! settings): the same bytes for any thread count.
//!
//! The default feature `cli` builds the `lapidary` command (and its
//! argument parser, progress bar and Ctrl-C handler); a program that uses
//! the library alone leaves it out with `default-features = false`.
//!
//! A render in one call, [`render::still::render_still`] (the same bytes
//! as `lapidary render goldstone --size 32 --spp 4`); the recipe language
//! is the repository's `docs/recipes.md`, the command's built-in default
//! gem [`recipe::library::DEFAULT_GEM`]:
//!
//! ```
//! use lapidary::render::still::{render_still, StillSettings};
//! use lapidary::{output, scene, GemSource};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let gem = GemSource::load("goldstone")?; // a built-in name or a .ron path
//! let scene = scene::default_scene(); // or scene::load_scene(path)?
//! let settings = StillSettings { width_px: 32, height_px: 32, samples_per_pixel: 4, ..Default::default() };
//! let film = render_still(&scene, &gem, &settings)?; // linear radiance and AOVs
//! let png = output::tonemap::DisplayTransform::default().encode_film(&film);
//! output::write_png(&std::env::temp_dir().join("goldstone.png"), &png)?;
//! # Ok(()) }
//! ```
//!
//! The steps it takes, for a program that changes one of them (its own
//! camera, a compiled gem's fields, another table cache):
//!
//! ```
//! use std::sync::Arc;
//! use lapidary::render::{film, prepare, still};
//! use lapidary::{output, scene, GemSource, TableCache, Tables};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let gem = GemSource::load("goldstone")?; // a built-in name or a .ron path
//! let scene = scene::default_scene(); // or scene::load_scene(path)?
//! let cache = Arc::new(TableCache::in_memory()); // or TableCache::with_folder(dir)
//! let tables = Tables::Computed(&cache);
//! let bounces = still::DEFAULT_BOUNCES; // after the first hit (the command's default)
//! let mut traced = prepare::prepare_scene(&scene, &gem, None, bounces, tables, &|_| {})?;
//! // Flakes and glitter shaded by each pixel's footprint, as the command
//! // does unless `--exact-flakes` (leave it out for that).
//! traced.shade_flakes_by_footprint(Some(Arc::clone(&cache)));
//! let camera = prepare::camera_for(&scene, 32, 32);
//! let settings = film::FilmSettings::new(32, 32, 4, 0); // size, spp, seed (`--seed`)
//! let film = film::render(&traced, &camera, &settings, &|_| {});
//! let png = output::tonemap::DisplayTransform::default().encode(&film.rgb, 32, 32);
//! output::write_png(&std::env::temp_dir().join("goldstone.png"), &png)?;
//! let layers = output::exr::film_channels(film, false); // RGBA + AOVs
//! output::exr::write_exr_owned(&std::env::temp_dir().join("goldstone.exr"), 32, 32, layers)?;
//! # Ok(()) }
//! ```

pub mod brdf;
pub mod farm;
mod file_kind;
pub mod gallery;
pub mod geometry;
mod message;
pub mod output;
pub mod recipe;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod texture;

/// The vector maths of the public API (`DVec3`, `DQuat`), at the version
/// lapidary is built with.
pub use glam;
/// The image type PNG output takes and gives (`RgbImage`).
pub use image;
pub use recipe::gem::{compile_gem, compile_gems, Gem, GemSource};
pub use recipe::{TableCache, Tables};
