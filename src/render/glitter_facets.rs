//! The facets of a glitter map (figure 4.6 ④) where a pixel's footprint
//! holds too many of them to show one by one (`render::footprint`).
//!
//! A point of a filled glitter cell is shaded by its material in the frame
//! of its facet's normal, which the facet cell's hash draws from the map's
//! tilt distribution; where the viewer is behind the facet or the facet
//! faces into the stone, in the stone's own frame (`RenderScene::shade`).
//! A footprint of many facets averages their reflections: the mean of
//! f_n(ωi, ωo)·cosθi over its facets' normals n. Its point's one facet is an
//! estimate of that mean with the variance of a glint, lit or not.
//!
//! Here a vertex where the footprint holds many facets is shaded by
//! [`FACETS_PER_VERTEX`] facets drawn from the tilt distribution (stratified
//! in the tilt), each by the full layered BRDF in its own frame, with the
//! same fall-back: a mixture of equal weights, whose mean over the draws
//! is the footprint's mean reflection exactly. Light samples see all the
//! facets at once; the BRDF sample picks one facet by its first number and
//! is weighted by the whole mixture (its f·cosθi over its density), so
//! multiple importance sampling sees one BSDF. Where the footprint is a
//! pixel's and the facets tilt about the stone's normal, the vertex reads
//! their mean from a table instead (`render::glitter_aggregate`). Where a
//! footprint holds a few hundred facets, too few for their mean alone, the
//! point's own facet is blended in ([`FacetMix::blend_own_facet`]). (A
//! smooth lobe of mirrors
//! of the material's albedo over the widened tilt density, as the flakes
//! at depth have in `render::flake_lobe`, misses where the facets' own
//! lobes meet the horizon: 21 % of the energy for the sunstone's copper
//! platelets seen at 55° with their cleavage axis tilted away.)

use std::sync::{Arc, OnceLock};

use glam::{DQuat, DVec3};

use crate::brdf::{LayeredBrdf, Rgb};
use crate::recipe::gem::{Body, Gem};
use crate::recipe::TableCache;
use crate::render::drawn_facets::{draw_facet_normals, Facet, FACETS_PER_VERTEX};
use crate::render::glitter_aggregate::{AggregateTable, TableAt};
use crate::sampling::Rng;
use crate::texture::pattern::{Around, FacetBumpMap};

/// The mean area a plane cuts from a cell of a Voronoi tessellation with
/// one site per unit cube: one over its cells' mean breadth (1.5 for the
/// unit cube, 1.458 for Poisson sites; a jittered grid lies between).
const SECTION_AREA_PER_CELL_AREA: f64 = 1.0 / 1.48;

/// The facets of a gem's glitter map, to be drawn where a footprint holds
/// many.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct GlitterFacets {
    facets: FacetBumpMap,
    /// Mean area a plane cuts from one facet cell, texture units².
    pub facet_area_texture_units2: f64,
    /// Per material of the gem, its facets' tabulated mean reflection,
    /// built when first needed (`render::glitter_aggregate`); empty when
    /// the facets tilt about a fixed direction, whose mean depends on more
    /// than θo, θi and φi − φo.
    aggregates: Vec<OnceLock<AggregateTable>>,
    /// Where built tables are kept and looked up first, if anywhere.
    store: TableStore,
}

/// A [`TableCache`] for the facets' tables, or none: no part of the
/// facets' identity (a scene prepared with one renders as one without).
#[derive(Clone, Default)]
pub(crate) struct TableStore(pub(crate) Option<Arc<TableCache>>);

impl PartialEq for TableStore {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for TableStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "TableStore(cache)"
        } else {
            "TableStore(none)"
        })
    }
}

impl GlitterFacets {
    /// The facets of `gem`'s glitter map, when it has one on an opaque
    /// body (a translucent body does not show its surface pattern).
    pub(crate) fn of_gem(gem: &Gem, store: &TableStore) -> Option<Self> {
        let glitter = gem.pattern.glitter()?;
        if !matches!(gem.body, Body::Opaque) {
            return None;
        }
        let voronoi = &glitter.facets.voronoi;
        let stretch = voronoi.stretch;
        let tabulated = matches!(glitter.facets.around, Around::SurfaceNormal);
        Some(Self {
            facets: glitter.facets,
            facet_area_texture_units2: SECTION_AREA_PER_CELL_AREA
                * voronoi.cell_size
                * voronoi.cell_size
                * (stretch.x * stretch.y * stretch.z).powf(2.0 / 3.0),
            aggregates: if tabulated {
                gem.brdfs.iter().map(|_| OnceLock::new()).collect()
            } else {
                Vec::new()
            },
            store: store.clone(),
        })
    }

    /// The tabulated mean reflection of these facets in material number
    /// `material` (`brdf`), on the first call read from the store or built
    /// (0.17 s on 2 threads, see [`AggregateTable::build`]) and kept there;
    /// `None` where the facets tilt about a fixed direction.
    pub(crate) fn aggregate(&self, material: u32, brdf: &LayeredBrdf) -> Option<&AggregateTable> {
        let table = self.aggregates.get(material as usize)?;
        Some(table.get_or_init(|| {
            let key = AggregateTable::key(&self.facets, brdf);
            let Some(store) = &self.store.0 else {
                return AggregateTable::build(&self.facets, brdf);
            };
            if let Some(table) = store
                .values(&key)
                .and_then(|n| AggregateTable::from_numbers(&n))
            {
                return table;
            }
            let table = AggregateTable::build(&self.facets, brdf);
            store.store_values(&key, &table.to_numbers());
            table
        }))
    }

    /// [`draw_facet_normals`] of these facets.
    #[inline(always)]
    pub(crate) fn draw(
        &self,
        frame: (DVec3, DVec3, DQuat),
        wo: DVec3,
        rng: &mut Rng,
    ) -> [DVec3; FACETS_PER_VERTEX] {
        draw_facet_normals(&self.facets, frame, wo, rng)
    }
}

/// The facets at one vertex where its footprint holds many: their mean,
/// drawn or tabulated, and where the footprint holds fewer than the mean
/// alone stands for (`render::footprint`), the facet under the vertex's
/// point blended in by its share.
///
/// The blend is a mixture of the two BRDFs, (1 − s)·mean + s·own, sampled
/// as one (multiple importance sampling sees one BSDF): its expected value
/// is that of shading the vertex by the mean with probability 1 − s and by
/// its own facet otherwise, and its variance lower, as the own facet's
/// glint enters every sample scaled by s instead of a share of them
/// unscaled.
#[derive(Clone, Copy)]
pub(crate) struct FacetMix<'a> {
    mean: FacetMean<'a>,
    /// The facet under the point and its share s, in (0, 1).
    own: Option<(Facet<'a>, f64)>,
}

/// The facets' mean at a vertex. It lives on the stack for one vertex, so
/// the drawn variant's size is not boxed away (that would allocate at
/// every such vertex).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
enum FacetMean<'a> {
    /// [`FACETS_PER_VERTEX`] facets drawn for the vertex: a mixture of
    /// their BRDFs with equal weights.
    Drawn([Facet<'a>; FACETS_PER_VERTEX]),
    /// The facets' tabulated mean reflection (`render::glitter_aggregate`).
    Tabulated(TableAt<'a>),
}

impl<'a> FacetMix<'a> {
    /// The mixture of `brdf` in the frames of `normals` (world, each
    /// facing `wo`), seen from the unit `wo` (world).
    #[inline(never)]
    pub(crate) fn new(
        brdf: &'a LayeredBrdf,
        normals: &[DVec3; FACETS_PER_VERTEX],
        wo: DVec3,
    ) -> Self {
        Self {
            mean: FacetMean::Drawn(std::array::from_fn(|k| Facet::new(brdf, normals[k], wo))),
            own: None,
        }
    }

    /// The facets' tabulated mean at a vertex.
    pub(crate) fn tabulated(table: TableAt<'a>) -> Self {
        Self {
            mean: FacetMean::Tabulated(table),
            own: None,
        }
    }

    /// Blends the facet of `brdf` whose unit normal (world, facing `wo`) is
    /// `normal` into this mean by its share `share`, where that is in
    /// (0, 1) (0: the mean alone).
    #[inline(never)]
    pub(crate) fn blend_own_facet(
        &mut self,
        brdf: &'a LayeredBrdf,
        normal: DVec3,
        wo: DVec3,
        share: f32,
    ) {
        if share > 0.0 {
            self.own = Some((Facet::new(brdf, normal, wo), share.into()));
        }
    }

    /// The mixture's f·cosθi (each facet's cosine its own) towards the
    /// unit `wi` (world) and the density with which [`Self::sample`] draws
    /// it. Out of line, as [`Self::new`] and [`Self::sample`]: a vertex
    /// with drawn facets is rare, and the path tracer's loop stays small.
    #[inline(never)]
    pub(crate) fn eval_cos_and_pdf(&self, wi: DVec3) -> (Rgb, f64) {
        let (value, pdf) = match &self.mean {
            FacetMean::Drawn(facets) => {
                let (value, pdf) = facets.iter().fold((Rgb::ZERO, 0.0), |(value, pdf), facet| {
                    let (v, p) = facet.eval_cos_and_pdf(wi);
                    (value + v, pdf + p)
                });
                let share = 1.0 / FACETS_PER_VERTEX as f64;
                (value * share, pdf * share)
            }
            FacetMean::Tabulated(table) => table.eval_cos_and_pdf(wi),
        };
        match &self.own {
            None => (value, pdf),
            Some((facet, share)) => {
                let (own_value, own_pdf) = facet.eval_cos_and_pdf(wi);
                let mean_share = 1.0 - share;
                (
                    value * mean_share + own_value * *share,
                    pdf * mean_share + own_pdf * share,
                )
            }
        }
    }

    /// A direction (world) from three uniform numbers: a part of the blend
    /// by the first (the own facet above 1 − s), then a drawn facet by it,
    /// then that BRDF's sample; (ωi, the mixture's f·cosθi over its
    /// density, that density).
    #[inline(never)]
    pub(crate) fn sample(&self, [u0, u1, u2]: [f64; 3]) -> Option<(DVec3, Rgb, f64)> {
        let mut u0 = u0;
        if let Some((facet, share)) = &self.own {
            let mean_share = 1.0 - share;
            if u0 >= mean_share {
                return self.weighed(facet.sample_direction([
                    (u0 - mean_share) / share,
                    u1,
                    u2,
                ])?);
            }
            u0 /= mean_share;
        }
        let wi = match &self.mean {
            FacetMean::Drawn(facets) => {
                let scaled = u0 * FACETS_PER_VERTEX as f64;
                let k = (scaled as usize).min(FACETS_PER_VERTEX - 1);
                facets[k].sample_direction([scaled - k as f64, u1, u2])?
            }
            FacetMean::Tabulated(table) => table.sample_direction([u0, u1, u2])?,
        };
        self.weighed(wi)
    }

    /// The sampled `wi` with the mixture's f·cosθi over its density, and
    /// that density.
    fn weighed(&self, wi: DVec3) -> Option<(DVec3, Rgb, f64)> {
        let (value, pdf) = self.eval_cos_and_pdf(wi);
        (pdf > 0.0).then(|| (wi, value / pdf, pdf))
    }
}

/// A white Lambert material: the lossless furnace of the facets' tests.
#[cfg(test)]
pub(crate) fn white_lambert() -> LayeredBrdf {
    LayeredBrdf::new(
        "white",
        crate::brdf::MicrofacetModel::Blinn,
        vec![],
        crate::brdf::Base::Diffuse {
            colour: Rgb::ONE,
            oren_nayar_sigma_rad: 0.0,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recipe::compile::load_material_without_table;
    use crate::recipe::gem::parse_gem;
    use crate::recipe::library::builtin_gem_source;
    use crate::render::chi2_cells::{cap_grid, hemisphere_cell, hemisphere_cells, Tally};
    use crate::texture::pattern::Around;

    fn unit(v: DVec3) -> DVec3 {
        v.normalize()
    }

    /// A built-in gem's glitter facets and the material of its glitter
    /// entry `entry`.
    fn glitter_of(name: &str, entry: usize) -> (GlitterFacets, LayeredBrdf) {
        let gem = parse_gem(name, builtin_gem_source(name).unwrap()).unwrap();
        let material = gem.pattern.glitter().unwrap().entries.items()[entry];
        (
            GlitterFacets::of_gem(&gem, &Default::default()).unwrap(),
            gem.brdfs[material as usize].clone(),
        )
    }

    /// The lepidolite's silver facets (a 20° cone about the stone's
    /// normal) and the sunstone's copper platelets (Gaussian 6° about a
    /// fixed cleavage direction).
    fn glitters() -> Vec<(&'static str, GlitterFacets, LayeredBrdf)> {
        [
            ("lepidolite", "lavender-lepidolite", 3),
            ("sunstone", "sunstone", 0),
        ]
        .into_iter()
        .map(|(name, gem, entry)| {
            let (facets, brdf) = glitter_of(gem, entry);
            (name, facets, brdf)
        })
        .collect()
    }

    /// Views (ωo, stone rotation) of a stone whose normal is +z: head on,
    /// oblique, grazing, and the sunstone's cleavage axis turned away.
    fn views() -> Vec<(DVec3, DQuat)> {
        vec![
            (DVec3::Z, DQuat::IDENTITY),
            (unit(DVec3::new(0.8, 0.3, 0.6)), DQuat::from_rotation_x(0.4)),
            (unit(DVec3::new(1.0, 0.0, 0.12)), DQuat::IDENTITY),
            (
                unit(DVec3::new(0.8, 0.3, 0.6)),
                DQuat::from_rotation_y(-1.2),
            ),
        ]
    }

    /// The facets `glitter` draws at a vertex of a stone turned by
    /// `rotation` whose world normal there is +z, seen from `wo`.
    fn draw_at(
        glitter: &GlitterFacets,
        (wo, rotation): (DVec3, DQuat),
        rng: &mut Rng,
    ) -> [DVec3; FACETS_PER_VERTEX] {
        let object_normal = rotation.inverse() * DVec3::Z;
        glitter.draw((object_normal, DVec3::Z, rotation), wo, rng)
    }

    #[test]
    fn facets_drawn_at_a_vertex_follow_the_map_s_tilts() {
        // The tilts of many vertices' facets (the mean of cos θ about the
        // map's axis and of cos² θ) against the facet cells' own, for a
        // stone seen head on (no facet falls back).
        for (name, glitter, _) in glitters() {
            let mut rng = Rng::new(3, 1);
            let n = 20_000;
            let drawn: Vec<f64> = (0..n)
                .flat_map(|_| {
                    glitter.draw((DVec3::Z, DVec3::Z, DQuat::IDENTITY), DVec3::Z, &mut rng)
                })
                .map(|normal| {
                    let axis = match glitter.facets.around {
                        Around::SurfaceNormal => DVec3::Z,
                        Around::Direction(d) => d,
                    };
                    normal.dot(axis)
                })
                .collect();
            let cells: Vec<f64> = (0..drawn.len() as u64)
                .map(|id| {
                    glitter
                        .facets
                        .normal_of_cell(id.wrapping_mul(0x9e37_79b9_7f4a_7c15))
                        .theta
                        .cos()
                })
                .collect();
            let mean =
                |v: &[f64], p: i32| v.iter().map(|c| c.powi(p)).sum::<f64>() / v.len() as f64;
            for p in [1, 2] {
                let (a, b) = (mean(&drawn, p), mean(&cells, p));
                assert!(
                    (a - b).abs() < 2e-4 + 1e-3 * (1.0 - b),
                    "{name}, cos^{p}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn sampling_matches_the_pdf_and_the_weight_is_the_mixture_s() {
        // χ² of 5·10⁵ samples of one vertex's mixture against its pdf,
        // integrated over 24 × 48 cells of equal solid angle about the
        // stone's normal (each cell from 12 × 12 sub-cells); at every
        // sample eval's pdf is the sample's, and its f·cosθi over the pdf
        // the weight. The facets' normals are the glitter maps'; their
        // material a rough paint (the mixture's sums and choice are what
        // is tested: the glitter metals' 1–4° lobes are too sharp for the
        // grid, and every material's own sampling has its χ² in
        // `tests/brdf_sampling.rs`). Cells over which the pdf varies more
        // than fourfold are compared in total only (within 3 % and 4σ).
        const N_COS: usize = 24;
        const N_PHI: usize = 48;
        const FINE: usize = 12;
        let (brdf, _) = load_material_without_table("green-latex").unwrap();
        for (name, glitter, _) in glitters() {
            for (view, (wo, rotation)) in views().into_iter().enumerate() {
                let mut rng = Rng::new(view as u64, 9);
                let normals = draw_at(&glitter, (wo, rotation), &mut rng);
                let drawn = FacetMix::new(&brdf, &normals, wo);
                // Blended with a facet of its own by 0.4, as where a
                // footprint holds a few hundred facets.
                let mut blended = drawn;
                blended.blend_own_facet(&brdf, normals[3], wo, 0.4);
                for (mix, part) in [(drawn, "drawn"), (blended, "blended")] {
                    let (expected, range) =
                        hemisphere_cells(|w| mix.eval_cos_and_pdf(w).1, N_COS, N_PHI, FINE);
                    let samples = 500_000;
                    let mut observed = vec![0u32; N_COS * N_PHI];
                    let mut sampler = Rng::new(4, 2);
                    for _ in 0..samples {
                        let Some((wi, weight, pdf)) = mix.sample(sampler.next_3()) else {
                            continue;
                        };
                        let (value, eval_pdf) = mix.eval_cos_and_pdf(wi);
                        assert!(
                            (eval_pdf - pdf).abs() <= 1e-9 * pdf,
                            "{name}: {eval_pdf} vs {pdf}"
                        );
                        let relative = (value / pdf - weight).abs() / weight.max(Rgb::splat(1e-9));
                        assert!(
                            relative.max_element() <= 1e-9,
                            "{name}: {value} vs {weight}"
                        );
                        if wi.z > 0.0 {
                            observed[hemisphere_cell(wi, N_COS, N_PHI)] += 1;
                        }
                    }
                    let expected: Vec<f64> = expected.iter().map(|e| e * samples as f64).collect();
                    let tally = Tally::new(&expected, &observed, &range);
                    tally.assert_agrees(100, &format!("{name}, view {view}, {part}"));
                }
            }
        }
    }

    #[test]
    fn white_lambert_facets_reflect_everything_that_arrives() {
        // A lossless furnace for the mixture: facets of a white Lambert
        // base each reflect all light over their own hemisphere, so the
        // mixture's f·cosθi integrates to 1 over the sphere (a fine grid
        // of eval) and, f·cosθi being the density itself, every sample's
        // weight is 1.
        let white = white_lambert();
        for (name, glitter, _) in glitters() {
            for (view, (wo, rotation)) in views().into_iter().enumerate() {
                let mut rng = Rng::new(view as u64, 5);
                let normals = draw_at(&glitter, (wo, rotation), &mut rng);
                let drawn = FacetMix::new(&white, &normals, wo);
                let mut blended = drawn;
                blended.blend_own_facet(&white, normals[5], wo, 0.6);
                for mix in [drawn, blended] {
                    let integral = cap_grid(-1.0, 400, 800).fold(Rgb::ZERO, |sum, (wi, cell)| {
                        sum + mix.eval_cos_and_pdf(wi).0 * cell
                    });
                    assert!(
                        (integral - Rgb::ONE).abs().max_element() < 2e-3,
                        "{name}, view {view}: {integral}"
                    );
                    for _ in 0..10_000 {
                        if let Some((_, weight, _)) = mix.sample(rng.next_3()) {
                            assert!(
                                (weight - Rgb::ONE).abs().max_element() < 1e-9,
                                "{name}, view {view}: {weight}"
                            );
                        }
                    }
                }
            }
        }
    }
}
