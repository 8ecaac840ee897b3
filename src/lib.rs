//! lapidary: procedural gemstones rendered with layered micro-facet BRDFs.
//!
//! Data flows one way (see `../shared/design.md`): RON recipes are parsed and
//! validated in [`recipe`], compiled into plain data ([`brdf::LayeredBrdf`]),
//! and evaluated in the local shading frame (z is the surface normal).
//!
//! ```
//! use lapidary::sampling::direction_from_degrees;
//! // A library material by name, compiled with its compensation tables.
//! let gold = lapidary::recipe::load_material("gold").unwrap();
//! // f(ωᵢ, ωₒ) at the mirror configuration, 30° from the normal.
//! let f = gold.eval(direction_from_degrees(30.0, 180.0), direction_from_degrees(30.0, 0.0));
//! assert!(f.x > f.z, "gold reflects more red than blue");
//! ```

pub mod brdf;
pub mod gallery;
pub mod geometry;
pub mod output;
pub mod recipe;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod texture;
