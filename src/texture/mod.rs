//! Solid procedural textures (section 4.3.1 of the course notes, figures 4.6
//! and 4.7): the deterministic primitives the pattern tree is built from.
//!
//! Every function here is pure in `(seed, object-space point)`: no global RNG,
//! no interior state, every type `Send + Sync`, so a stone looks cut from a
//! block and renders identically on any number of rayon threads. The one
//! memory, [`pattern::Pattern::resolve`]'s per-thread cache, only saves work:
//! what it returns is exactly [`pattern::Pattern::resolve_uncached`]'s.
//!
//! * [`hash`]: integer hashing of lattice cells (SplitMix64), the source of all
//!   per-cell randomness.
//! * [`voronoi`]: jittered 3-D Voronoi cells (F1, F2, cell id, true edge
//!   distance) for the surface, glitter and crystal-facet maps.
//! * [`noise_fns`]: Perlin, fBm, turbulence and marble, the switches between maps.

pub mod hash;
pub mod noise_fns;
pub mod pattern;
pub mod voronoi;
