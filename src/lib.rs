//! lapidary: procedural gemstones rendered with layered micro-facet BRDFs.
//!
//! Data flows one way (see `../shared/design.md`): RON recipes are parsed and
//! validated in [`recipe`], compiled into plain data ([`brdf::LayeredBrdf`]),
//! and evaluated in the local shading frame (z is the surface normal).

pub mod brdf;
pub mod output;
pub mod plot;
pub mod recipe;
pub mod sampling;
pub mod texture;
