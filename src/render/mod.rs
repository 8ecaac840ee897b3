//! The CPU ray caster: camera, lights, environment, integrator and film.
//!
//! Data flows one way: a compiled scene and its compiled gems go in,
//! linear radiance per pixel (plus AOVs) comes out.
//! Every pixel is a pure function of (scene, gems, seed, settings), so the
//! image is the same whatever the thread count.

pub mod camera;
#[cfg(test)]
mod chi2_cells;
pub mod cpu;
pub mod dielectric;
pub mod distribution;
pub(crate) mod drawn_facets;
pub mod environment;
pub mod film;
pub mod flake_lobe;
pub(crate) mod flake_medium;
pub(crate) mod footprint;
pub(crate) mod glitter_aggregate;
pub(crate) mod glitter_facets;
pub(crate) mod inclusions;
pub mod integrator;
pub mod lights;
pub(crate) mod manifold;
pub(crate) mod medium;
pub mod overlaps;
pub mod prepare;
pub(crate) mod refracted_light;
pub mod render_scene;
pub(crate) mod sampler;
pub(crate) mod shared_exponent;
pub mod still;
pub(crate) mod stone_grid;
pub mod tiles;
pub mod turntable;
pub mod world;
pub(crate) mod zoning;

#[cfg(test)]
mod snell_tests;
