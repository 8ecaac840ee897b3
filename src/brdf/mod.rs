//! Layered micro-facet BRDFs (Weidlich & Wilkie; course notes sections 2.3,
//! 3.1, 4.1–4.2 and the appendix shader), in the local shading frame where z
//! is the surface normal and both directions point away from the surface.
//!
//! * [`fresnel`]: dielectric and conductor Fresnel terms;
//! * `microfacet`: Blinn (V-cavity), Beckmann and GGX (Smith) lobes;
//! * `diffuse`: Lambert and Oren-Nayar;
//! * `layer`: compiled interfaces (with Beer absorption) and bases;
//! * `stack`: the layered BRDF with eval, sample and pdf, and its form
//!   prepared for one outgoing direction ([`BrdfAt`], one per path vertex);
//! * `sample`: a BRDF sample, and the sampling parts both forms share;
//! * `coat`: the same model in closed form for one interface over a
//!   Lambert base, the commonest stack (what the renderer evaluates there);
//! * `compensation_lobe`: the multiple-scattering lobe restoring lost
//!   energy, from its table;
//! * [`compensation`]: that table, computed;
//! * [`reference`](mod@reference): the Monte Carlo random walk the model is measured against;
//! * [`smooth_coat`]: the walk's answer under one smooth coat, from a
//!   Markov chain in the cosine instead of random paths;
//! * [`albedo`]: directional albedo estimators.

pub mod albedo;
pub mod classify;
pub(crate) mod coat;
pub mod compensation;
mod compensation_lobe;
pub(crate) mod diffuse;
pub mod fresnel;
pub(crate) mod layer;
pub(crate) mod microfacet;
pub mod reference;
pub(crate) mod sample;
pub mod smooth_coat;
pub(crate) mod stack;

/// Linear RGB, one value per channel (R, G, B at 680, 525, 450 nm for the
/// conductor tables of section 4.2.3).
pub type Rgb = glam::DVec3;

pub(crate) use coat::LANES;
pub use layer::{Base, Interface};
pub use microfacet::{Microfacet, MicrofacetModel};
pub use sample::BrdfSample;
pub use stack::{BrdfAt, LayeredBrdf};
