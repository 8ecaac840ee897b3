//! Cabochon geometry in object space, intersected analytically.
//!
//! A stone is an [`Outline`] (the girdle seen from above, sized by a
//! [`Footprint`]) swept into a dome, a vertical girdle band and a flat or
//! domed base: a [`Cabochon`]. The solid is convex and closed by
//! construction; rays are intersected without tessellation (a finely
//! tessellated dome traced through a triangle BVH is too slow: its cost
//! grows with the triangle count a smooth silhouette needs), so the BVH
//! only has to hold one box per stone ([`Cabochon::bounds`]).

#![deny(missing_docs)]

pub(crate) mod cabochon;
pub(crate) mod error;
pub(crate) mod outline;

pub use cabochon::{Base, Cabochon, CabochonParams, Hit, PROFILE_EXPONENT_RANGE};
pub use error::GeometryError;
pub use outline::{Footprint, Outline, CUSHION_EXPONENT_RANGE};
