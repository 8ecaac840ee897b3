//! The facets drawn at a vertex from a glitter map's tilt distribution
//! (figure 4.6 ④), each the full layered BRDF in its own frame: what a
//! vertex whose footprint holds many facets averages
//! (`render::glitter_facets`) and what the facets' table is built from
//! (`render::glitter_aggregate`).

use glam::{DQuat, DVec3};

use crate::brdf::{BrdfAt, LayeredBrdf, Rgb};
use crate::sampling::Rng;
use crate::texture::pattern::FacetBumpMap;

/// Facets drawn per vertex where a footprint holds many.
pub(crate) const FACETS_PER_VERTEX: usize = 8;

/// [`FACETS_PER_VERTEX`] normals (world space) of `facets` for a vertex
/// seen from `wo` on a stone turned by `rotation` whose normal there is
/// `object_normal` (object space) and `normal` (world), each facing
/// `wo` and `normal` or replaced by `normal` (as the facet under a
/// point is): stratified in the tilt's first number, the rest from
/// `rng`.
#[inline(never)]
pub(crate) fn draw_facet_normals(
    facets: &FacetBumpMap,
    (object_normal, normal, rotation): (DVec3, DVec3, DQuat),
    wo: DVec3,
    rng: &mut Rng,
) -> [DVec3; FACETS_PER_VERTEX] {
    std::array::from_fn(|k| {
        let u_tilt = (k as f64 + rng.next_f64()) / FACETS_PER_VERTEX as f64;
        let u_azimuth = rng.next_f64();
        let facet = facets.normal_from(u_tilt, || rng.next_f64(), u_azimuth);
        let n = (rotation * facet.world(object_normal)).normalize();
        if n.dot(wo) > 0.0 && n.dot(normal) > 0.0 {
            n
        } else {
            normal
        }
    })
}

/// One facet at a vertex: its frame and its material seen from ωo.
#[derive(Clone, Copy)]
pub(crate) struct Facet<'a> {
    tangent: DVec3,
    bitangent: DVec3,
    normal: DVec3,
    brdf_at: BrdfAt<'a>,
}

impl<'a> Facet<'a> {
    /// `brdf` in the frame of the unit `normal` (world, facing `wo`), seen
    /// from the unit `wo` (world).
    pub(crate) fn new(brdf: &'a LayeredBrdf, normal: DVec3, wo: DVec3) -> Self {
        let (tangent, bitangent) = normal.any_orthonormal_pair();
        let local_wo = DVec3::new(wo.dot(tangent), wo.dot(bitangent), wo.dot(normal));
        Facet {
            tangent,
            bitangent,
            normal,
            brdf_at: brdf.at(local_wo),
        }
    }

    /// `v` (world) in the facet's frame.
    fn local(&self, v: DVec3) -> DVec3 {
        DVec3::new(
            v.dot(self.tangent),
            v.dot(self.bitangent),
            v.dot(self.normal),
        )
    }

    /// The facet's f·cosθi (its own cosine) towards the unit `wi` (world)
    /// and its BRDF's density for it.
    pub(crate) fn eval_cos_and_pdf(&self, wi: DVec3) -> (Rgb, f64) {
        let local = self.local(wi);
        if local.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let (f, pdf) = self.brdf_at.eval_and_pdf(local);
        (f * local.z, pdf)
    }

    /// A direction (world) drawn by the facet's BRDF from three uniform
    /// numbers, and its weight f·cosθi over the density.
    pub(crate) fn sample(&self, u: [f64; 3]) -> Option<(DVec3, Rgb)> {
        let sample = self.brdf_at.sample(u)?;
        let wi = sample.wi;
        Some((
            self.tangent * wi.x + self.bitangent * wi.y + self.normal * wi.z,
            sample.weight(),
        ))
    }

    /// [`Self::sample`]'s direction alone.
    pub(crate) fn sample_direction(&self, u: [f64; 3]) -> Option<DVec3> {
        self.sample(u).map(|(wi, _)| wi)
    }
}
