//! The scene as the integrator reads it ([`RenderScene`]: stones and
//! ground, their gems, lights, environment and settings), and what the
//! path tracer (`integrator`) and the light connections through a smooth
//! body (`refracted_light`) both ask of it: which emitters next-event
//! estimation samples, whether another light blocks a shadow ray and how
//! far that ray runs, a body's index; with the power heuristic both weigh
//! their strategies by.

use std::sync::Arc;

use glam::DVec3;

use crate::brdf::LayeredBrdf;
use crate::recipe::gem::{Body, Gem};
use crate::recipe::TableCache;
use crate::render::environment::Environment;
use crate::render::flake_lobe::FlakeLobes;
use crate::render::lights::Light;
use crate::render::sampler::SOBOL_PAIRS;
use crate::render::world::{World, RAY_OFFSET};

/// Length in texture space of one scene unit: recipes write cell sizes in
/// centimetres of stone (a 10 mm stone is one texture unit long), scenes
/// write stones in millimetres.
pub(crate) const TEXTURE_UNITS_PER_SCENE_UNIT: f64 = 0.1;

/// `material_id` AOV values: 0 is the background, 1 the ground, stones'
/// materials count from 2.
pub(crate) const MATERIAL_ID_GROUND: u32 = 1;
/// See `MATERIAL_ID_GROUND`.
pub const MATERIAL_ID_FIRST_STONE: u32 = 2;

/// The most light samples a vertex's next-event estimation draws (see
/// [`RenderScene::for_each_light_sample`]): every emitter of a scene with
/// a light and an environment map, as many as that of a scene with more.
pub(crate) const MAX_LIGHT_SAMPLES: usize = 3;

/// Everything the integrator reads.
pub struct RenderScene {
    /// Stones and ground.
    pub world: World,
    /// Gems, indexed by [`crate::render::world::StoneInstance::gem`].
    pub gems: Vec<Gem>,
    /// `material_id` AOV value of each gem's material 0: each gem its own
    /// run after [`MATERIAL_ID_FIRST_STONE`] (see
    /// [`RenderScene::material_id_bases`]).
    pub material_id_bases: Vec<u32>,
    /// The ground's BRDF (used when the world has a ground).
    pub ground_brdf: Option<LayeredBrdf>,
    /// Lights placed in the scene.
    pub lights: Vec<Light>,
    /// Light from infinitely far away.
    pub environment: Environment,
    /// Bounces after the first hit (0: direct light only).
    pub max_bounces: u32,
    /// `Some(distance)`: estimate ambient occlusion at the first hit with one
    /// cosine-distributed ray of that length per sample, as the appendix
    /// shader's `gather` does (written to the `ao` AOV).
    pub ambient_occlusion: Option<f64>,
    /// Light reaches flakes and scattering vertices inside smooth
    /// translucent bodies by manifold next-event estimation through the
    /// surface (see `refracted_light`), as well as by path sampling. True
    /// for every render; false leaves those paths to sampling alone, which
    /// converges far more slowly under small lights (for comparisons).
    pub connect_through_surfaces: bool,
    /// Per gem, per flake population of its translucent body, the lobe that
    /// shades a flake when the pixel's footprint holds many, and the
    /// glitter facets of an opaque one to draw there (see
    /// `render::footprint` and [`RenderScene::shade_flakes_by_footprint`]);
    /// [`FlakeLobes::default`], as prepared: every flake and facet by its
    /// own normal.
    pub flake_lobes: FlakeLobes,
}

impl RenderScene {
    /// The `material_id` AOV value of each gem's material 0: the stones'
    /// materials count from [`MATERIAL_ID_FIRST_STONE`], each gem its own
    /// run of [`Gem::brdfs`]`.len()` values.
    pub fn material_id_bases(gems: &[Gem]) -> Vec<u32> {
        gems.iter()
            .scan(MATERIAL_ID_FIRST_STONE, |next, gem| {
                let base = *next;
                *next += gem.brdfs.len() as u32;
                Some(base)
            })
            .collect()
    }

    /// The IOR of stone `stone`'s translucent body when its surface is
    /// smooth (as [`RenderScene::translucent_body`] decides), where lights
    /// are connected through it; None for an opaque or rough one.
    pub(crate) fn smooth_body_ior(&self, stone: usize) -> Option<f64> {
        match &self.gems[self.world.stones()[stone].gem].body {
            Body::Translucent {
                ior, rough_surface, ..
            } if rough_surface.is_none() => Some(*ior),
            _ => None,
        }
    }

    /// Shades the flakes inside translucent bodies, and the glitter facets
    /// of opaque stones, by their pixel's footprint: a flake met where the
    /// footprint holds many is shaded by its population's aggregate lobe,
    /// a point of a glitter facet by facets drawn from its map's tilts (as
    /// `lapidary render` and `lapidary gallery` do unless `--exact-flakes`);
    /// without it, every flake and facet by its own normal. The glitter
    /// facets' tables (`render::glitter_aggregate`) are looked up in and
    /// kept by `tables` when given (in memory and on disk, as the
    /// compensation tables): the same pictures, without building a table
    /// again in the next render.
    pub fn shade_flakes_by_footprint(&mut self, tables: Option<Arc<TableCache>>) {
        self.flake_lobes = FlakeLobes::of_gems_keeping_tables(&self.gems, tables);
    }

    /// The emitters next-event estimation samples (and a translucent
    /// body's connections choose from): the lights, then the environment
    /// when [`RenderScene::samples_environment`].
    pub(crate) fn sampled_emitters(&self) -> usize {
        self.lights.len() + usize::from(self.samples_environment())
    }

    /// The index in [`RenderScene::lights`] of emitter number `emitter`
    /// (as [`RenderScene::sampled_emitters`] counts them: the lights, then
    /// the environment); None for the environment.
    #[inline(always)]
    pub(crate) fn light_of_emitter(&self, emitter: usize) -> Option<usize> {
        (emitter < self.lights.len()).then_some(emitter)
    }

    /// Whether a light other than the sampled one (`sampled`, an index of
    /// [`RenderScene::lights`]; None for the environment) lies on a shadow
    /// ray within `reach`. A light's surface stops the rays that BRDF
    /// sampling follows ([`RenderScene::nearest_light`]), so it must stop
    /// light samples too: else the light behind it would count by its
    /// samples' MIS weight where BRDF sampling never sees it. The sun,
    /// which BRDF-sampled rays pass on to the sky, blocks nothing, nor
    /// does a point light.
    #[inline(always)]
    pub(crate) fn another_light_blocks(
        &self,
        point: DVec3,
        direction: DVec3,
        reach: f64,
        sampled: Option<usize>,
    ) -> bool {
        self.lights
            .iter()
            .enumerate()
            .any(|(index, light)| Some(index) != sampled && light.blocks(point, direction, reach))
    }

    /// Whether next-event estimation may sample each part of the
    /// environment ([`Environment::parts`]) with a sample of its own
    /// instead of the whole map with one: when the map has two parts and
    /// the scene's lights and both parts are at most [`MAX_LIGHT_SAMPLES`]
    /// emitters. A vertex does so where a pixel sees it sharply (its
    /// footprint is bounded: the camera's vertices, and those past smooth
    /// reflections and refractions). There the skylight that a sun leaves
    /// to BRDF sampling shows as grain; past a glossy or diffuse bounce a
    /// pixel averages it, and one sample of the whole map costs less.
    pub(crate) fn environment_parts_apart(&self) -> bool {
        self.samples_environment()
            && self.environment.parts() == 2
            && self.lights.len() + 2 <= MAX_LIGHT_SAMPLES
    }

    /// Whether next-event estimation samples the environment. A constant
    /// environment is left to BRDF sampling alone: for uniform incident
    /// radiance the BRDF's own importance (cosine-weighted for the diffuse
    /// base, the lobe for the coats) is already the ideal density, while a
    /// light sample would spend a BRDF evaluation and a shadow ray on
    /// directions half of which point below the surface.
    pub(crate) fn samples_environment(&self) -> bool {
        !matches!(self.environment, Environment::Constant(_))
    }

    /// How many 2-D pairs of its stream a path draws at its first vertex
    /// (in [`RenderScene::radiance`]'s order: the footprint, one per light,
    /// the environment's sample if it takes one, the BRDF sample), at most
    /// [`SOBOL_PAIRS`]: the pairs worth making for every sample of a batch
    /// ahead of time (see [`PixelSampler::refill`]).
    ///
    /// [`PixelSampler::refill`]: crate::render::sampler::PixelSampler::refill
    pub(crate) fn first_vertex_pairs(&self) -> u32 {
        let pairs = 2 + self.sampled_emitters().min(MAX_LIGHT_SAMPLES);
        pairs.min(SOBOL_PAIRS as usize) as u32
    }
}

/// The power heuristic with exponent 2 for a strategy of density `pdf_a`
/// against one of density `pdf_b` (Veach 1997, eq. 9.13).
#[inline(always)]
pub(crate) fn power_heuristic(pdf_a: f64, pdf_b: f64) -> f64 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b <= 0.0 {
        0.0
    } else {
        a / (a + b)
    }
}

/// How far a shadow ray towards a light point at `distance` may run before
/// it counts as blocked: short of the light by a relative 10⁻⁷ and the ray
/// offset (everything, for a light at infinity).
#[inline(always)]
pub(crate) fn shadow_reach(distance: f64) -> f64 {
    if distance.is_finite() {
        distance * (1.0 - 1e-7) - RAY_OFFSET
    } else {
        f64::INFINITY
    }
}
