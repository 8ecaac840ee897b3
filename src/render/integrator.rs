//! The path tracer: at every hit the gem's pattern picks a layered BRDF,
//! light arrives by next-event estimation (every light, and the environment
//! by its luminance distribution, a sun in it apart) and by BRDF sampling,
//! and the two strategies are combined with the power heuristic (Veach
//! 1997, §9.2).
//!
//! An opaque stone is a surface (the layered BRDF models what happens
//! under the varnish); a translucent one refracts the path into its body,
//! where it is absorbed, scatters and meets flakes (`flake_medium`,
//! `inclusions`), and lights reach it through the smooth surface
//! (`refracted_light`). A path bounces until it escapes to the
//! environment, meets a light, or reaches `max_bounces`.

use glam::DVec3;

use crate::brdf::sample::accept;
use crate::brdf::{BrdfAt, BrdfSample, LayeredBrdf, Rgb, LANES};
use crate::recipe::gem::{Body, Medium};
use crate::render::dielectric::{cross_smooth_interface, split_smooth_interface, RoughInterface};
use crate::render::environment::{Environment, EnvironmentMap, EnvironmentSample, Texel};
use crate::render::flake_lobe::FlakeLobe;
use crate::render::flake_medium::{FlakeView, OwnCell};
use crate::render::footprint::{aggregate_probability, RayCone};
use crate::render::glitter_aggregate::TableAt;
use crate::render::glitter_facets::{FacetMix, GlitterFacets};
use crate::render::lights::{Light, LightSample};
use crate::render::manifold::MAX_REFLECTIONS;
use crate::render::medium::{
    beer_lambert, henyey_greenstein, sample_free_flight, sample_henyey_greenstein, SpectralPath,
};
use crate::render::refracted_light::ConnectedVertex;
use crate::render::render_scene::{
    power_heuristic, shadow_reach, RenderScene, MATERIAL_ID_GROUND, MAX_LIGHT_SAMPLES,
    TEXTURE_UNITS_PER_SCENE_UNIT,
};
use crate::render::sampler::SampleStream;
use crate::render::world::{Surface, SurfaceHit, RAY_OFFSET};
use crate::sampling::{cosine_hemisphere, Rng};

/// Stream of the generator that draws a vertex's glitter facets (seeded by
/// a number of the path's sample stream).
const FACET_DRAW_STREAM: u64 = 0xface7;
/// Salt of the side generator that draws the sky part's light sample
/// where a map's parts are sampled apart.
const SKY_PART_STREAM: u64 = 0x5c7;

/// The numbers of the sky part's light sample at a vertex that samples a
/// map's parts apart, once `stream` is `pairs_ahead` pairs on: from a side
/// generator, so that the BRDF sample and the later vertices keep the
/// Sobol pairs they have when the map is one part (an extra pair in the
/// main stream moved them and made the stones' bodies 1.24× noisier).
#[inline(always)]
fn sky_part_numbers(stream: &SampleStream, pairs_ahead: u32) -> [f64; 2] {
    let mut side = stream.side_stream_ahead(pairs_ahead, SKY_PART_STREAM);
    [side.next_f64(), side.next_f64()]
}

// A vertex's light samples and its BRDF sample fill one call of the
// BRDF's lanes (see `RenderScene::evaluate_vertex`).
const _: () = assert!(MAX_LIGHT_SAMPLES < LANES);

/// A light sample's f, the BRDF's density and cosθᵢ at its direction.
type Evaluated = (Rgb, f64, f64);

/// A vertex's light samples (at most [`MAX_LIGHT_SAMPLES`], the
/// environment's two parts counted apart, see
/// [`RenderScene::environment_parts_apart`]), gathered before the BRDF is
/// evaluated at them (see [`RenderScene::evaluate_vertex`]).
#[derive(Default)]
struct VertexLightSamples {
    samples: [Option<(LightSample, Option<usize>)>; MAX_LIGHT_SAMPLES],
    count: usize,
}

impl VertexLightSamples {
    /// Add a sample of emitter `emitter` (None: the environment).
    #[inline(always)]
    fn push(&mut self, sample: LightSample, emitter: Option<usize>) {
        self.samples[self.count] = Some((sample, emitter));
        self.count += 1;
    }

    /// The samples in the order they were added.
    #[inline(always)]
    fn iter(&self) -> impl Iterator<Item = (&LightSample, Option<usize>)> {
        self.samples[..self.count]
            .iter()
            .flatten()
            .map(|(sample, emitter)| (sample, *emitter))
    }
}

/// The share of a choice among more emitters than a vertex samples that is
/// spread evenly over them; the rest follows their estimated irradiance at
/// the vertex ([`RenderScene::emitter_choice`]).
const UNIFORM_CHOICE: f64 = 0.25;

/// How many emitters' estimates a vertex keeps on its stack while it
/// chooses among them (those of further emitters are computed again).
const KEPT_ESTIMATES: usize = 16;

/// The probability of choosing an emitter of `estimate` among `emitters`
/// whose estimates sum to `total`: [`UNIFORM_CHOICE`] spread evenly, the
/// rest in proportion to the estimates (evenly when `total` is 0 or not
/// finite). One formula for the choice and for its density in MIS, so that
/// the two agree to the bit.
#[inline(always)]
fn choice_of_estimate(estimate: impl FnOnce() -> f64, total: f64, emitters: usize) -> f64 {
    let uniform = 1.0 / emitters as f64;
    if total > 0.0 && total < f64::INFINITY {
        UNIFORM_CHOICE * uniform + (1.0 - UNIFORM_CHOICE) * estimate() / total
    } else {
        uniform
    }
}

/// Scattering events and flakes a path may meet inside translucent bodies
/// (which are not bounces): a stone whose light scatters further is dark
/// anyway.
const MAX_SCATTERINGS: u32 = 1024;
/// Scattering events before Russian roulette (survival = the largest
/// channel of the throughput, at most 0.95) may end a path.
const SCATTERINGS_BEFORE_ROULETTE: u32 = 4;

/// Russian roulette after a path's `scatterings`-th event inside a body
/// (a scattering or a flake): past [`SCATTERINGS_BEFORE_ROULETTE`] the
/// path survives with probability = the largest channel of its
/// throughput (at most 0.95), which is then divided by it, so the
/// expectation is kept. Whether the path goes on.
fn survives_scattering(
    throughput: &mut Rgb,
    scatterings: u32,
    uniform: impl FnOnce() -> f64,
) -> bool {
    if scatterings <= SCATTERINGS_BEFORE_ROULETTE {
        return true;
    }
    let survival = throughput.max_element().min(0.95);
    if uniform() >= survival {
        return false;
    }
    *throughput /= survival;
    true
}

/// What the camera ray met first (the AOVs of one sample).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstHit {
    /// Distance from the camera.
    pub depth: f64,
    /// World-space shading normal.
    pub normal: DVec3,
    /// One-sample estimate of the directional albedo towards the camera,
    /// f·cosθ/pdf of the first BRDF sample (its mean is the albedo).
    pub albedo: Rgb,
    /// Low 32 bits of the surface-map cell id (0 off the stones).
    pub surface_cell: u32,
    /// True when a glitter flake was hit.
    pub glitter: bool,
    /// See `MATERIAL_ID_GROUND`.
    pub material_id: u32,
    /// 1 if the ambient-occlusion ray escaped, 0 if it was blocked (its
    /// mean is the unoccluded, cosine-weighted fraction of the hemisphere);
    /// 1 when ambient occlusion is off or nothing was hit.
    pub unoccluded: f64,
}

/// A pixel's sums of its samples' [`FirstHit`]s, which
/// [`RenderScene::radiance`] adds to where the first hit is known: a
/// returned `FirstHit` went through an 80-byte stack copy at the end of
/// every path and back.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FirstHitSums {
    /// Σ depth over the samples that hit something.
    pub depth: f64,
    /// Samples that hit something (`material_id` ≠ 0).
    pub hits: u32,
    /// Samples whose first hit was a glitter flake.
    pub glints: u32,
    /// Samples whose camera ray refracted into a translucent stone and met
    /// a flake before anything else inside (scattering, the surface): the
    /// `inclusion` AOV. Not in [`FirstHit`]: the first hit is the stone's
    /// surface, known before the flake is.
    pub inclusions: u32,
    /// Σ finite albedo estimates over the samples that hit something.
    pub albedo: Rgb,
    /// Σ shading normal over the samples that hit something.
    pub normal: DVec3,
    /// Σ `unoccluded` over all samples.
    pub unoccluded: f64,
    /// The surface cell of the pixel's first sample.
    pub surface_cell: u32,
    /// The material id of the pixel's first sample.
    pub material_id: u32,
}

impl FirstHitSums {
    /// Adds one sample's first hit; `first_sample` (the pixel's sample 0)
    /// also sets the cell and material ids.
    #[inline(always)]
    pub fn add(&mut self, hit: &FirstHit, first_sample: bool) {
        self.unoccluded += hit.unoccluded;
        if first_sample {
            self.surface_cell = hit.surface_cell;
            self.material_id = hit.material_id;
        }
        if hit.material_id != 0 {
            self.hits += 1;
            self.depth += hit.depth;
            if hit.albedo.is_finite() {
                self.albedo += hit.albedo;
            }
            self.normal += hit.normal;
            self.glints += u32::from(hit.glitter);
        }
    }
}

/// Ray counts of one path, for the rays/s report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera and BRDF-sampled rays.
    pub traced: u64,
    /// Shadow rays.
    pub shadow: u64,
}

/// An orthonormal frame whose z axis is a surface normal.
#[derive(Clone, Copy, Debug)]
struct Frame {
    t: DVec3,
    b: DVec3,
    n: DVec3,
    /// True for [`Frame::UP`], whose transforms are the identity: the
    /// ground's vertices (most of a typical frame) skip three dot products
    /// per direction.
    is_up: bool,
}

impl Frame {
    /// The frame around +z, the ground's normal: exactly what
    /// `Frame::new(DVec3::Z)` builds (Duff et al.'s basis gives x, y for
    /// z), without computing it at every ground hit.
    const UP: Frame = Frame {
        t: DVec3::X,
        b: DVec3::Y,
        n: DVec3::Z,
        is_up: true,
    };

    fn new(n: DVec3) -> Self {
        let (t, b) = n.any_orthonormal_pair();
        Self {
            t,
            b,
            n,
            is_up: false,
        }
    }
    /// World to frame coordinates. In [`Frame::UP`] each dot product with
    /// an axis is the component itself (v.x·1 + v.y·0 + v.z·0 = v.x for
    /// finite v, up to the sign of a zero).
    #[inline(always)]
    fn to_local(self, v: DVec3) -> DVec3 {
        if self.is_up {
            v
        } else {
            DVec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
        }
    }
    /// Frame to world coordinates (the identity in [`Frame::UP`], as
    /// [`Frame::to_local`]).
    #[inline(always)]
    fn to_world(self, v: DVec3) -> DVec3 {
        if self.is_up {
            v
        } else {
            self.t * v.x + self.b * v.y + self.n * v.z
        }
    }
}

/// The BRDF and frame at a hit, and which material the pattern picked.
struct Shading<'a> {
    brdf: &'a LayeredBrdf,
    frame: Frame,
    pick: MaterialPick,
    /// Where the footprint holds many glitter facets: their mean shades
    /// the vertex, with the facet under the point blended in where they
    /// are too few for the mean alone. The frame is then the stone's, or
    /// the blended facet's own.
    facets: Option<FacetsAt<'a>>,
}

/// [`FacetsAt::tabulated`] where no table shades the facets.
const NOT_TABULATED: u32 = u32::MAX;

/// The glitter facets a vertex's footprint holds. (Its fields are kept
/// small: a wider shading record cost every vertex of every scene
/// instructions.)
#[derive(Clone, Copy)]
struct FacetsAt<'a> {
    /// The gem's facets, to draw for the vertex from a generator of
    /// `seed`.
    facets: &'a GlitterFacets,
    seed: u64,
    /// Where the footprint is still a pixel's (no glossy or diffuse event
    /// before), the material whose tabulated mean reflection shades the
    /// facets when the map has one; else [`NOT_TABULATED`].
    tabulated: u32,
    /// The share of the facet under the point in the blend
    /// (`render::footprint`): 0 where the mean shades alone.
    own_share: f32,
}

/// The pattern's choice at a hit, as the first-hit AOVs report it.
#[derive(Clone, Copy)]
struct MaterialPick {
    material_id: u32,
    surface_cell: u32,
    glitter: bool,
}

impl RenderScene {
    /// Picks the material at a hit seen from direction `wo` (world, unit,
    /// pointing away from the surface) by a footprint `footprint_width_mm`
    /// wide: at a point of a glitter facet where the footprint holds many
    /// facets, it draws facets for the vertex (`render::glitter_facets`;
    /// a blend from `stream`, as a flake's). Inlined like
    /// [`RenderScene::radiance`]: out of line it cost a call, six saved
    /// registers and the `Option<Shading>` through memory at every vertex
    /// (keeping only the stone branch out of line saved less).
    #[inline(always)]
    fn shade(
        &self,
        hit: &SurfaceHit,
        wo: DVec3,
        footprint_width_mm: f64,
        stream: &mut SampleStream,
    ) -> Option<Shading<'_>> {
        match hit.surface {
            Surface::Ground => Some(Shading {
                brdf: self.ground_brdf.as_ref()?,
                frame: if hit.normal == DVec3::Z {
                    Frame::UP
                } else {
                    Frame::new(hit.normal)
                },
                pick: MaterialPick {
                    material_id: MATERIAL_ID_GROUND,
                    surface_cell: 0,
                    glitter: false,
                },
                facets: None,
            }),
            Surface::Stone {
                index,
                object_point,
                object_normal,
            } => {
                let stone = &self.world.stones()[index];
                let gem = &self.gems[stone.gem];
                let resolved = gem
                    .pattern
                    .resolve(object_point * TEXTURE_UNITS_PER_SCENE_UNIT);
                // The facets a footprint holds: its area on the surface
                // (the cone's width widened by the view's slant) over a
                // facet's.
                let facets = resolved
                    .flake_normal
                    .and_then(|_| self.flake_lobes.facets(stone.gem))
                    .and_then(|facets| {
                        let slant = wo.dot(hit.normal).max(1e-3).sqrt();
                        let mean_share = aggregate_probability(
                            footprint_width_mm * TEXTURE_UNITS_PER_SCENE_UNIT / slant,
                            facets.facet_area_texture_units2,
                        );
                        (mean_share > 0.0).then(|| FacetsAt {
                            facets,
                            seed: stream.next_1d().to_bits(),
                            tabulated: if footprint_width_mm.is_finite() {
                                resolved.material
                            } else {
                                NOT_TABULATED
                            },
                            own_share: (1.0 - mean_share) as f32,
                        })
                    });
                // A flake tilts the shading normal (figure 4.6 ③); if the
                // viewer is behind the tilted facet, fall back to the
                // stone's normal rather than shade a back face. Where the
                // facets' mean shades alone, the stone's normal.
                let normal = resolved
                    .flake_normal
                    .filter(|_| facets.is_none_or(|at| at.own_share > 0.0))
                    .map(|f| (stone.rotation * f.world(object_normal)).normalize())
                    .filter(|n| n.dot(wo) > 0.0 && n.dot(hit.normal) > 0.0)
                    .unwrap_or(hit.normal);
                Some(Shading {
                    brdf: &gem.brdfs[resolved.material as usize],
                    frame: Frame::new(normal),
                    pick: MaterialPick {
                        surface_cell: resolved.surface_cell as u32,
                        glitter: resolved.glitter_cell.is_some(),
                        material_id: self.material_id_bases[stone.gem] + resolved.material,
                    },
                    facets,
                })
            }
        }
    }

    /// Radiance arriving at the camera along one ray (origin, unit
    /// direction, and the angle its pixel spans, radians, the spread of its
    /// footprint); what the ray hit first is added to `first_hits`
    /// (`first_sample`: see
    /// [`FirstHitSums::add`]). Consumes numbers from `stream` in a fixed
    /// order.
    ///
    /// Inlined into the film's per-sample loop (its only caller): as a call
    /// it saved six registers, re-read a dozen scene fields into stack slots
    /// and returned the 80-byte `FirstHit` through memory on every sample,
    /// work that the loop now hoists or keeps in registers.
    #[inline(always)]
    pub fn radiance(
        &self,
        (origin, direction, pixel_angle_rad): (DVec3, DVec3, f64),
        stream: &mut SampleStream,
        counts: &mut RayCounts,
        first_hits: &mut FirstHitSums,
        first_sample: bool,
    ) -> Rgb {
        self.trace::<false>(
            (
                origin,
                direction,
                0,
                None,
                RayCone::from_camera(pixel_angle_rad),
            ),
            stream,
            counts,
            first_hits,
            first_sample,
        )
    }

    /// The radiance along the mirror reflection of a camera ray off a
    /// smooth translucent stone `stone`, the path going on from `bounce`:
    /// the branch the camera ray splits into where it meets its first
    /// smooth stone (see [`RenderScene::trace`]).
    #[inline(never)]
    fn reflected_branch(
        &self,
        (origin, direction, bounce, stone, cone): (DVec3, DVec3, u32, Option<usize>, RayCone),
        stream: &mut SampleStream,
        counts: &mut RayCounts,
    ) -> Rgb {
        let mut unused = FirstHitSums::default();
        self.trace::<true>(
            (origin, direction, bounce, stone, cone),
            stream,
            counts,
            &mut unused,
            false,
        )
    }

    /// The path tracer: radiance along the ray `start` = (origin,
    /// direction, bounces so far, the stone it leaves). A camera ray
    /// (`BRANCH` false) that meets a smooth translucent stone first splits
    /// there: its reflection (weight F, eq. 3.1) is traced as a branch of
    /// its own and the path goes on refracted (weight 1 − F), where a
    /// Fresnel choice would reflect only a few per cent of the samples: the
    /// polish's image of a small light, the brightest thing on a stone,
    /// then has no noise of its own. A branch splits no further; deeper
    /// crossings choose by Fresnel.
    #[inline(always)]
    fn trace<const BRANCH: bool>(
        &self,
        (mut origin, mut direction, start_bounce, start_leaving, start_cone): (
            DVec3,
            DVec3,
            u32,
            Option<usize>,
            RayCone,
        ),
        stream: &mut SampleStream,
        counts: &mut RayCounts,
        first_hits: &mut FirstHitSums,
        first_sample: bool,
    ) -> Rgb {
        let mut radiance = Rgb::ZERO;
        let mut throughput = Rgb::ONE;
        // Whether the first hit went into `first_hits` (else: nothing hit).
        let mut first_recorded = false;
        // Where the previous BRDF sample came from, its pdf, whether its
        // vertex sampled the environment's parts apart and the sum of the
        // emitters' estimates there (`RenderScene::emitter_total_at`); None
        // for the camera ray, whose emitters count in full.
        let mut previous: Option<(DVec3, f64, bool, f64)> = None;
        // The stone the current segment leaves (outwards), which it cannot
        // meet again: every cabochon is convex.
        let mut leaving: Option<usize> = start_leaving;
        // The medium of the translucent body the current segment runs
        // through, if it runs inside one.
        let mut inside: Option<(Medium, usize)> = None;
        // The hero channel and relative densities, from the path's first
        // flight through a scattering medium on.
        let mut spectral: Option<SpectralPath> = None;
        // The vertex inside a smooth body whose lights were connected
        // through its surface (`refracted_light`), while the path's sampled
        // continuation may still meet a light the same way.
        let mut connected: Option<ConnectedVertex> = None;
        let mut bounce = start_bounce;
        // The pixel's footprint along the current segment.
        let mut cone = start_cone;
        // Scattering events and flakes inside bodies so far (they are not
        // bounces).
        let mut scatterings = 0;
        // Whether the path meets flakes with lobes as a medium: from the
        // vertex after the one where the pixel's footprint ended (what
        // lights and shades the flake a pixel shows stays its own
        // neighbours'), and the cell of the flake it leaves, if any.
        let mut flakes_as_medium = false;
        let mut own_cell: Option<OwnCell> = None;
        // The environment texel the last bounce's continuation (this
        // iteration's ray) would escape to, found when it was prefetched.
        let mut escape: Option<Texel> = None;
        // Whether the sharply seen vertices sample the environment's parts
        // apart ([`RenderScene::environment_parts_apart`]).
        let parts_apart_where_sharp = self.environment_parts_apart();
        loop {
            counts.traced += 1;
            let arriving = connected.take();
            let own = own_cell.take();
            let escape_texel = escape.take();
            if inside.is_some() {
                // A vertex inside connects one emitter with the next pair;
                // the walk to it runs while the environment's texel loads.
                self.prefetch_environment_sample(stream, 0);
            }
            // Inside a stone the next surface is its own (stones are convex
            // and hold nothing): where the ray leaves it, as the manifold
            // solver's chains leave it. The world's search would also meet
            // the ground where a flat base rests on it, at the same t,
            // and take the ground.
            let hit = inside
                .and_then(|(_, stone)| self.world.stone_exit(stone, origin, direction))
                .or_else(|| {
                    self.world
                        .intersect_leaving(origin, direction, 0.0, f64::INFINITY, leaving)
                });
            // A ray from the ground that meets a stone from inside started
            // under a stone resting there: it enters through the base.
            let contact = hit
                .filter(|h| {
                    inside.is_none()
                        && leaving.is_none()
                        && bounce > 0
                        && direction.dot(h.normal) > 0.0
                })
                .and_then(|h| self.world.contact_with_base(&h, origin));
            let hit = contact.or(hit);
            let t_hit = hit.map_or(f64::INFINITY, |h| h.t);
            if let (Some((medium, stone)), Some(hit)) = (inside, &hit) {
                // The segment ends at the first flake or at the surface;
                // past the vertex after the footprint's end, flakes with a
                // lobe are met as a medium (`render::flake_medium`).
                let flake = self.meet_flake(
                    stone,
                    origin,
                    direction,
                    hit.t,
                    FlakeView::new(flakes_as_medium, own),
                    || stream.next_1d(),
                );
                let t_end = flake.map_or(hit.t, |f| f.t);
                if medium.scattering_per_mm == Rgb::ZERO {
                    // Beer–Lambert along the segment inside the body (eq. 3.4),
                    // and ratio tracking for what zoning adds to it.
                    throughput *= beer_lambert(medium.absorption_per_mm, t_end)
                        * self.zoned_transmittance(stone, origin, direction, t_end, || {
                            stream.next_1d()
                        });
                } else {
                    let spectral = spectral.get_or_insert_with(|| {
                        SpectralPath::new(((stream.next_1d() * 3.0) as usize).min(2))
                    });
                    let flight =
                        sample_free_flight(&medium, t_end, spectral.hero, stream.next_1d());
                    throughput *= spectral.weigh(&flight);
                    // Zoning's absorption over the distance flown, to the
                    // scattering event or the segment's end.
                    let flown = flight.scatters_at.unwrap_or(t_end);
                    throughput *= self
                        .zoned_transmittance(stone, origin, direction, flown, || stream.next_1d());
                    if let Some(t) = flight.scatters_at {
                        // A scattering vertex: the phase function over its
                        // own density is 1. It is no bounce: light in a
                        // cloudy stone scatters dozens of times, so the
                        // walk ends by Russian roulette instead.
                        if bounce > self.max_bounces || scatterings == MAX_SCATTERINGS {
                            break;
                        }
                        origin += direction * t;
                        let g = medium.anisotropy;
                        // A scattering is no bounce: the continuation
                        // crosses the surface at this bounce.
                        let chains = self.chains_from(stone, bounce);
                        flakes_as_medium = cone.is_unbounded();
                        let view = FlakeView::new(flakes_as_medium, None);
                        let incoming = direction;
                        if let Some(chains_up_to) = chains {
                            radiance += throughput
                                * self.refracted_light(
                                    stone,
                                    origin,
                                    |wi| {
                                        let phase = henyey_greenstein(wi.dot(incoming), g);
                                        (Rgb::splat(phase), phase)
                                    },
                                    view,
                                    chains_up_to,
                                    stream,
                                    &mut counts.shadow,
                                );
                        }
                        direction = sample_henyey_greenstein(direction, g, stream.next_2d());
                        connected = chains.map(|chains_up_to| ConnectedVertex {
                            point: origin,
                            direction,
                            pdf: henyey_greenstein(direction.dot(incoming), g),
                            stone,
                            chains_up_to,
                            reflections: 0,
                            exited: false,
                        });
                        scatterings += 1;
                        cone = RayCone::UNBOUNDED;
                        if !survives_scattering(&mut throughput, scatterings, || stream.next_1d()) {
                            break;
                        }
                        leaving = None;
                        previous = None;
                        continue;
                    }
                }
                if let Some(flake) = flake {
                    // Only a camera ray refracted in runs inside at bounce
                    // 1, and it did not scatter: its first event inside.
                    first_hits.inclusions += u32::from(!BRANCH && bounce == 1 && scatterings == 0);
                    // A flake is a scattering event, not a bounce: light
                    // passed between a body's flakes takes as many events
                    // as its reflectance allows (copper's red dozens), so
                    // the walk ends by Russian roulette as a cloudy
                    // stone's does, whatever `max_bounces` is.
                    if bounce > self.max_bounces || scatterings == MAX_SCATTERINGS {
                        break;
                    }
                    let chains = self.chains_from(stone, bounce);
                    // A flake of the medium is the lobe's; one met by the
                    // walk, by the flakes its footprint holds.
                    let population_lobe = self.flake_lobe(stone, flake.population);
                    let lobe = population_lobe.filter(|lobe| {
                        let p =
                            aggregate_probability(cone.width_at(flake.t), lobe.projected_area_mm2);
                        flake.normal.is_none() || p >= 1.0 || (p > 0.0 && stream.next_1d() < p)
                    });
                    // Where its population is met as a medium from here on,
                    // the flake's own cell holds no other of them.
                    flakes_as_medium = cone.is_unbounded();
                    let own = population_lobe
                        .filter(|_| flakes_as_medium)
                        .map(|_| OwnCell::new(flake.population, stream.next_3d()));
                    let view = FlakeView::new(flakes_as_medium, own);
                    cone = RayCone::UNBOUNDED;
                    let on_flake_plane = lobe.is_some();
                    let (sampled_direction, weight, pdf) = if let Some(lobe) = lobe {
                        // The footprint holds many flakes: the population's
                        // lobe shades this one, at its point on the flake,
                        // whose own plane then stops no ray from it.
                        let rotation = self.world.stones()[stone].rotation;
                        let to_object = rotation.inverse();
                        let lobe_at = lobe.at(to_object * -direction);
                        origin += direction * flake.t;
                        if let Some(chains_up_to) = chains {
                            radiance += throughput
                                * self.refracted_light(
                                    stone,
                                    origin,
                                    |wi| lobe_at.eval(to_object * wi),
                                    view,
                                    chains_up_to,
                                    stream,
                                    &mut counts.shadow,
                                );
                        }
                        let Some((wi, weight, pdf)) = lobe_at.sample(stream.next_3d()) else {
                            break;
                        };
                        (rotation * wi, weight, pdf)
                    } else {
                        // A flake reflects by its material's BRDF, from either
                        // side; only its BRDF is sampled (no light reaches a
                        // shadow ray through the smooth boundary).
                        let Some(flake_normal) = flake.normal else {
                            break;
                        };
                        let normal = if flake_normal.dot(direction) < 0.0 {
                            flake_normal
                        } else {
                            -flake_normal
                        };
                        let frame = Frame::new(normal);
                        let wo = frame.to_local(-direction);
                        let brdf_at = flake.brdf.at(wo);
                        origin += direction * flake.t + normal * RAY_OFFSET;
                        if let Some(chains_up_to) = chains {
                            radiance += throughput
                                * self.refracted_light(
                                    stone,
                                    origin,
                                    |wi| {
                                        let local = frame.to_local(wi);
                                        if local.z <= 0.0 {
                                            return (Rgb::ZERO, 0.0);
                                        }
                                        let (f, pdf) = brdf_at.eval_and_pdf(local);
                                        (f * local.z, pdf)
                                    },
                                    view,
                                    chains_up_to,
                                    stream,
                                    &mut counts.shadow,
                                );
                        }
                        let Some(sample) = brdf_at.sample(stream.next_3d()) else {
                            break;
                        };
                        (frame.to_world(sample.wi), sample.weight(), sample.pdf)
                    };
                    throughput *= weight;
                    direction = sampled_direction;
                    connected = chains.map(|chains_up_to| ConnectedVertex {
                        point: origin,
                        direction,
                        pdf,
                        stone,
                        chains_up_to,
                        reflections: 0,
                        exited: false,
                    });
                    if on_flake_plane {
                        // Off the flake's plane along the new direction: the
                        // lobe's point on it must not meet it again.
                        origin += direction * RAY_OFFSET;
                    }
                    own_cell = own;
                    leaving = None;
                    previous = None;
                    scatterings += 1;
                    if !survives_scattering(&mut throughput, scatterings, || stream.next_1d()) {
                        break;
                    }
                    continue;
                }
            }
            // An emitter in front of the surface (or of the sky).
            if let Some((index, light, t, emitted)) = self.nearest_light(origin, direction, t_hit) {
                let weight = match (previous, arriving.filter(|vertex| vertex.exited)) {
                    (_, Some(vertex)) => {
                        self.sampled_chain_weight(&vertex, light, origin, direction, t)
                    }
                    (Some((p, brdf_pdf, _, total)), None) => {
                        let light_pdf = light.pdf(p, direction, t)
                            * self.light_samples_per_emitter(index, p, total);
                        power_heuristic(brdf_pdf, light_pdf)
                    }
                    (None, None) => 1.0,
                };
                radiance += throughput * emitted * weight;
                if t.is_finite() {
                    break;
                }
            }
            let Some(hit) = hit else {
                let exited_from = arriving.filter(|vertex| vertex.exited);
                let (sky, weight) = match (previous, exited_from) {
                    (_, Some(vertex)) if self.samples_environment() => (
                        self.environment.radiance_in(direction, escape_texel),
                        self.environment_sampled_chain_weight(&vertex, direction),
                    ),
                    (Some((p, brdf_pdf, parts_apart, total)), _) if self.samples_environment() => {
                        let (sky, whole_pdf, part_pdf) = self
                            .environment
                            .radiance_and_pdfs_in(direction, escape_texel);
                        let light_pdf = if parts_apart {
                            part_pdf
                        } else {
                            whole_pdf * self.light_samples_per_emitter(self.lights.len(), p, total)
                        };
                        (sky, power_heuristic(brdf_pdf, light_pdf))
                    }
                    _ => (self.environment.radiance_in(direction, escape_texel), 1.0),
                };
                radiance += throughput * sky * weight;
                break;
            };
            if bounce > self.max_bounces {
                // This last segment only collected MIS-weighted emission
                // for the previous vertex's BRDF strategy.
                break;
            }
            if let Some((ior, medium, rough)) = self.translucent_body(&hit) {
                // A smooth dielectric interface: a delta lobe, so no light
                // sampling here; the next segment's emitters count in full.
                // A rough one is sampled like an opaque vertex (below).
                if bounce == 0 {
                    let first = FirstHit {
                        depth: hit.t,
                        normal: hit.normal,
                        albedo: Rgb::ONE,
                        unoccluded: 1.0,
                        surface_cell: 0,
                        glitter: false,
                        material_id: self.stone_material_id_base(&hit),
                    };
                    first_hits.add(&first, first_sample);
                    first_recorded = true;
                }
                let stone = hit.stone_index();
                if let Some(interface) = rough {
                    let frame = Frame::new(hit.normal);
                    let wo = frame.to_local(-direction);
                    let outwards = hit.point + hit.normal * RAY_OFFSET;
                    // Under a base on the ground no light arrives from
                    // outside (its outside is the ground).
                    let parts_apart = parts_apart_where_sharp && !cone.is_unbounded();
                    if contact.is_none() {
                        let sky = parts_apart.then(|| self.sky_part_numbers(stream));
                        radiance += throughput
                            * self.direct_at_interface(
                                interface,
                                frame,
                                wo,
                                (outwards, sky),
                                stone,
                                stream,
                                counts,
                            );
                    }
                    let Some(sample) = interface.sample(wo, stream.next_3d()) else {
                        break;
                    };
                    throughput *= sample.weight;
                    // Into the body: reflected from inside or refracted
                    // from outside (the sample's side is wi's sign of z).
                    let now_inside = sample.wi.z < 0.0;
                    let side = if now_inside { -1.0 } else { 1.0 };
                    inside = stone.filter(|_| now_inside).map(|index| (medium, index));
                    leaving = if now_inside { None } else { stone };
                    origin = hit.point + hit.normal * (side * RAY_OFFSET);
                    direction = frame.to_world(sample.wi);
                    flakes_as_medium = cone.is_unbounded();
                    cone = RayCone::UNBOUNDED;
                    // Light was sampled only outwards: an emitter met
                    // there is weighed against it; none shines inside.
                    // (`origin` is `outwards` then, where the light was sampled.)
                    previous = (!now_inside).then(|| {
                        (
                            origin,
                            sample.pdf,
                            parts_apart,
                            self.emitter_total_at(origin),
                        )
                    });
                    bounce += 1;
                    continue;
                }
                let crossing = if !BRANCH && bounce == 0 && -direction.dot(hit.normal) > 0.0 {
                    // The camera ray's first stone: split (see above).
                    let (reflection, refraction) =
                        split_smooth_interface(direction, hit.normal, ior);
                    let outwards = hit.point + hit.normal * RAY_OFFSET;
                    radiance += throughput
                        * reflection.weight
                        * self.reflected_branch(
                            (
                                outwards,
                                reflection.crossing.direction,
                                bounce + 1,
                                stone,
                                cone.continued(hit.t, 1.0),
                            ),
                            stream,
                            counts,
                        );
                    throughput *= refraction.weight;
                    refraction.crossing
                } else {
                    cross_smooth_interface(direction, hit.normal, ior, stream.next_1d())
                };
                // Refracting in from outside, or reflecting from inside,
                // the new segment runs inside; it starts on that side. A
                // refraction scales the cone's spread by η₁/η₂.
                let now_inside = crossing.refracted == crossing.from_outside;
                let spread_factor = match (crossing.refracted, crossing.from_outside) {
                    (false, _) => 1.0,
                    (true, true) => 1.0 / ior,
                    (true, false) => ior,
                };
                cone = cone.continued(hit.t, spread_factor);
                let side = if now_inside { -1.0 } else { 1.0 };
                inside = stone.filter(|_| now_inside).map(|index| (medium, index));
                leaving = if now_inside { None } else { stone };
                // Leaving from a connected vertex, straight or after
                // internal reflections that a connection's chain also
                // takes: what the next segment meets outside may be a
                // connection's path.
                connected = arriving.and_then(|vertex| vertex.crossed(crossing.refracted));
                origin = hit.point + hit.normal * (side * RAY_OFFSET);
                direction = crossing.direction;
                previous = None;
                bounce += 1;
                continue;
            }
            let wo_world = -direction;
            let parts_apart = parts_apart_where_sharp && !cone.is_unbounded();
            // The sky part's numbers, once: its texel loads while the
            // vertex is shaded (the sun's few are in the caches).
            let sky = parts_apart.then(|| self.sky_part_numbers_prefetched(stream));
            if !parts_apart && self.sampled_emitters() <= MAX_LIGHT_SAMPLES {
                self.prefetch_environment_sample(stream, self.lights.len());
            }
            let Some(shading) = self.shade(&hit, wo_world, cone.width_at(hit.t), stream) else {
                break;
            };
            let wo = shading.frame.to_local(wo_world);
            if wo.z <= 0.0 {
                break; // seen from behind (a ray leaving from inside a surface)
            }
            let point = hit.point + hit.normal * RAY_OFFSET;
            // What depends on wo alone, computed once for the light samples
            // and the BRDF sample of this vertex. Past a glossy or diffuse
            // event (an unbounded footprint) a coat's own lobe is sampled
            // more: what it shows there is a caustic on that earlier vertex.
            let brdf_at = if cone.is_unbounded() {
                shading.brdf.at_after_bounce(wo)
            } else {
                shading.brdf.at(wo)
            };
            let mut mix = shading.facets.and_then(|at| match hit.surface {
                Surface::Stone { .. }
                    if let Some(table) = (at.tabulated != NOT_TABULATED)
                        .then(|| at.facets.aggregate(at.tabulated, shading.brdf))
                        .flatten() =>
                {
                    Some(FacetMix::tabulated(TableAt::new(
                        table, hit.normal, wo_world,
                    )))
                }
                Surface::Stone {
                    index,
                    object_normal,
                    ..
                } => Some(FacetMix::new(
                    shading.brdf,
                    &at.facets.draw(
                        (
                            object_normal,
                            hit.normal,
                            self.world.stones()[index].rotation,
                        ),
                        wo_world,
                        &mut Rng::new(at.seed, FACET_DRAW_STREAM),
                    ),
                    wo_world,
                )),
                Surface::Ground => None,
            });
            // The facet under the point, blended in by its share, is the
            // shading frame's. (In place and out of line: built into the
            // closure above, this cost every vertex of every scene 1–2 %
            // more instructions.)
            if let (Some(mix), Some(at)) = (&mut mix, shading.facets) {
                mix.blend_own_facet(shading.brdf, shading.frame.n, wo_world, at.own_share);
            }

            // Next-event estimation (the lights and the environment), then
            // the path continued by sampling the BRDF: (ωi in world space,
            // f·cosθi/pdf, pdf). Where the BRDF evaluates in vector lanes
            // (a coat) and the vertex has two light samples or more, they
            // are gathered first, so that the BRDF is evaluated at all
            // their directions and at its own sample's in one call; else
            // (lanes idle, or none) each sample is shaded as it is drawn.
            // The numbers are drawn in the same order either way, and the
            // bits are equal.
            let gather = mix.is_none()
                && brdf_at.has_lanes()
                && (self.sampled_emitters() >= 2 || sky.is_some());
            let (emitter_total, sample) = if gather {
                let mut light_samples = VertexLightSamples::default();
                let emitter_total =
                    self.for_each_light_sample(point, sky, stream, |sample, emitter| {
                        light_samples.push(sample, emitter)
                    });
                let (lights, sampled) = self.evaluate_vertex(
                    &shading.frame,
                    &brdf_at,
                    &hit,
                    &light_samples,
                    stream.next_3d(),
                );
                for ((sample, emitter), evaluated) in light_samples.iter().zip(lights) {
                    if let Some(evaluated) = evaluated {
                        let contribution = self.direct_evaluated(
                            evaluated,
                            &hit,
                            point,
                            (sample, emitter),
                            counts,
                        );
                        radiance += throughput * contribution;
                    }
                }
                let sample = sampled.map(|s| (shading.frame.to_world(s.wi), s.weight(), s.pdf));
                (emitter_total, sample)
            } else {
                let emitter_total =
                    self.for_each_light_sample(point, sky, stream, |sample, emitter| {
                        let contribution = self.direct(
                            &shading,
                            (&brdf_at, mix.as_ref()),
                            &hit,
                            point,
                            (&sample, emitter),
                            counts,
                        );
                        radiance += throughput * contribution;
                    });
                let u = stream.next_3d();
                let sample = match &mix {
                    Some(mix) => mix.sample(u),
                    None => brdf_at
                        .sample(u)
                        .map(|s| (shading.frame.to_world(s.wi), s.weight(), s.pdf)),
                };
                (emitter_total, sample)
            };
            if bounce == 0 {
                let first = FirstHit {
                    depth: hit.t,
                    normal: shading.frame.n,
                    albedo: sample.map_or(Rgb::ZERO, |s| s.1),
                    unoccluded: match self.ambient_occlusion {
                        Some(distance) => self.unoccluded(&hit, point, distance, stream, counts),
                        None => 1.0,
                    },
                    surface_cell: shading.pick.surface_cell,
                    glitter: shading.pick.glitter,
                    material_id: shading.pick.material_id,
                };
                first_hits.add(&first, first_sample);
                first_recorded = true;
            }
            let Some((wi_world, weight, pdf)) = sample else {
                break;
            };
            if wi_world.dot(hit.normal) <= 0.0 {
                break; // below the geometric surface: blocked by the stone itself
            }
            throughput *= weight;
            if throughput.max_element() <= 0.0 {
                break;
            }
            previous = Some((point, pdf, parts_apart, emitter_total));
            leaving = hit.stone_index();
            origin = point;
            direction = wi_world;
            flakes_as_medium = cone.is_unbounded();
            cone = RayCone::UNBOUNDED;
            bounce += 1;
            // Should the ray escape, its texel loads while it is traced (a
            // ray bound for the ground never escapes: nothing to find).
            escape = (self.samples_environment() && !self.world.cannot_escape(origin, direction))
                .then(|| self.environment.prefetch_direction(direction))
                .flatten();
        }
        if !BRANCH && !first_recorded {
            let nothing = FirstHit {
                unoccluded: 1.0,
                ..FirstHit::default()
            };
            first_hits.add(&nothing, first_sample);
        }
        radiance
    }

    /// The IOR and medium of the stone hit, when its gem has a translucent
    /// body, and its surface's micro-facets when it is rough (None: a
    /// smooth interface; also at IOR 1, where there is no interface to be
    /// rough).
    #[inline(always)]
    fn translucent_body(&self, hit: &SurfaceHit) -> Option<(f64, Medium, Option<&RoughInterface>)> {
        let index = hit.stone_index()?;
        match &self.gems[self.world.stones()[index].gem].body {
            Body::Translucent {
                ior,
                medium,
                rough_surface,
                ..
            } => Some((*ior, *medium, rough_surface.as_ref())),
            Body::Opaque => None,
        }
    }

    /// Starts loading the environment texel that a light sample drawn
    /// after `pairs_before` more pairs of `stream` will read, so that the
    /// work before it (tracing, shading, the lights' samples) runs while
    /// it loads. The single numbers drawn in between come from another
    /// generator than the first [`SOBOL_PAIRS`] pairs, so the guess is
    /// exact there; beyond, a wrong guess only loads a line for nothing.
    /// Inlined down to the test for a map (a constant sky pays nothing
    /// more); the look-ahead itself is out of line.
    #[inline(always)]
    fn prefetch_environment_sample(&self, stream: &SampleStream, pairs_before: usize) {
        #[inline(never)]
        fn look_ahead(map: &EnvironmentMap, stream: &SampleStream, pairs_before: usize) {
            let mut ahead = stream.clone();
            for _ in 0..pairs_before {
                ahead.skip_2d();
            }
            map.prefetch_sample(ahead.next_2d());
        }
        if let Environment::Map(map) = &self.environment {
            look_ahead(map, stream, pairs_before);
        }
    }

    /// The numbers of the sky part's light sample of a vertex that samples
    /// a map's parts apart, drawn after the lights' and the sun's pairs
    /// ([`sky_part_numbers`]), for [`RenderScene::for_each_light_sample`]:
    /// a pure function of the stream's next pair, which the vertex's
    /// shading (single numbers only) does not move.
    fn sky_part_numbers(&self, stream: &SampleStream) -> [f64; 2] {
        sky_part_numbers(stream, self.lights.len() as u32 + 1)
    }

    /// [`RenderScene::sky_part_numbers`], and the texel they draw first
    /// starts loading ([`RenderScene::prefetch_environment_sample`] for
    /// the sky part). Out of line: only maps with a sun need it.
    #[inline(never)]
    fn sky_part_numbers_prefetched(&self, stream: &SampleStream) -> [f64; 2] {
        let numbers = self.sky_part_numbers(stream);
        if let Environment::Map(map) = &self.environment {
            map.prefetch_sample(numbers);
        }
        numbers
    }

    /// Whether a vertex inside stone `stone` connects lights through the
    /// surface, and the most internal reflections of its chains: its body
    /// is smooth, connections are on, and a sampled continuation could
    /// still reflect that often and leave and meet a light. Each crossing
    /// of the surface is a bounce, and `crossing_bounce` is the bounce of
    /// the continuation's first one: the vertex's own (a flake or a
    /// scattering is no bounce); a crossing at bounce b is taken while
    /// b ≤ `max_bounces`.
    fn chains_from(&self, stone: usize, crossing_bounce: u32) -> Option<usize> {
        (self.connect_through_surfaces
            && crossing_bounce <= self.max_bounces
            && self.smooth_body_ior(stone).is_some())
        .then(|| ((self.max_bounces - crossing_bounce) as usize).min(MAX_REFLECTIONS))
    }

    /// Next-event estimation at a rough interface vertex: one sample of
    /// every light, then of the environment (or of each of its parts, when
    /// `sky` holds the sky part's numbers), as at an opaque vertex ([`RenderScene::direct_evaluated`]'s
    /// power heuristic), for the directions
    /// outwards (`frame.n` is the outward normal): reflection when the
    /// path arrived from outside, transmission out when from inside (no
    /// light shines inside a body). `point` is offset outwards; shadow rays
    /// leave the stone `stone` and treat every other stone as opaque.
    #[allow(clippy::too_many_arguments)]
    fn direct_at_interface(
        &self,
        interface: &RoughInterface,
        frame: Frame,
        wo: DVec3,
        (point, sky): (DVec3, Option<[f64; 2]>),
        stone: Option<usize>,
        stream: &mut SampleStream,
        counts: &mut RayCounts,
    ) -> Rgb {
        let mut sum = Rgb::ZERO;
        let mut one = |sample: LightSample, emitter: Option<usize>| {
            let (direction, incoming, pdf) = (sample.direction, sample.radiance, sample.pdf);
            let wi = frame.to_local(direction);
            if pdf <= 0.0 || wi.z <= 0.0 || incoming.max_element() <= 0.0 {
                return;
            }
            let (f, bsdf_pdf) = interface.eval_and_pdf(wo, wi);
            if f <= 0.0 {
                return;
            }
            counts.shadow += 1;
            let reach = shadow_reach(sample.distance);
            if self.world.occluded_leaving(point, direction, reach, stone)
                || self.another_light_blocks(point, direction, reach, emitter)
            {
                return;
            }
            sum += incoming * (f * light_sample_scale(wi.z, pdf, bsdf_pdf, sample.is_delta));
        };
        self.for_each_light_sample(point, sky, stream, &mut one);
        sum
    }

    /// The aggregate lobe of flake population `population` of stone
    /// `stone`'s body, when it has one.
    fn flake_lobe(&self, stone: usize, population: usize) -> Option<&FlakeLobe> {
        self.flake_lobes
            .get(self.world.stones()[stone].gem, population)
    }

    /// The `material_id` AOV value of the gem of the stone hit (0 off the
    /// stones).
    fn stone_material_id_base(&self, hit: &SurfaceHit) -> u32 {
        hit.stone_index().map_or(0, |index| {
            self.material_id_bases[self.world.stones()[index].gem]
        })
    }

    /// How many samples of emitter `emitter` (as
    /// [`RenderScene::sampled_emitters`] counts them: the lights, then the
    /// environment) next-event estimation draws on average at `point`
    /// ([`RenderScene::for_each_light_sample`]), `total` being
    /// [`RenderScene::emitter_total_at`] there: 1 while there are at most
    /// [`MAX_LIGHT_SAMPLES`] emitters, else [`MAX_LIGHT_SAMPLES`] times its
    /// choice probability. An emitter's light-sampling density in the
    /// power heuristic is its own density times this.
    #[inline(always)]
    fn light_samples_per_emitter(&self, emitter: usize, point: DVec3, total: f64) -> f64 {
        if self.sampled_emitters() <= MAX_LIGHT_SAMPLES {
            return 1.0;
        }
        MAX_LIGHT_SAMPLES as f64 * self.emitter_choice(emitter, point, total)
    }

    /// A rough luminance of the irradiance emitter `emitter` gives a
    /// surface at `point` (see [`Light::irradiance_estimate`]).
    #[inline(always)]
    fn emitter_estimate(&self, emitter: usize, point: DVec3) -> f64 {
        let estimate = match self.lights.get(emitter) {
            Some(light) => light.irradiance_estimate(point),
            None => self.environment.irradiance_estimate(),
        };
        if estimate.is_finite() {
            estimate
        } else {
            0.0
        }
    }

    /// The sum of [`RenderScene::emitter_estimate`] over the emitters at
    /// `point` when a vertex chooses among them (more than
    /// [`MAX_LIGHT_SAMPLES`]), else 0 (not needed): computed once a vertex,
    /// for its light samples and for the BRDF sample's MIS weight.
    #[inline(always)]
    fn emitter_total_at(&self, point: DVec3) -> f64 {
        let emitters = self.sampled_emitters();
        if emitters <= MAX_LIGHT_SAMPLES {
            return 0.0;
        }
        (0..emitters).map(|e| self.emitter_estimate(e, point)).sum()
    }

    /// The probability that a light sample at `point` goes to emitter
    /// `emitter`, `total` being [`RenderScene::emitter_total_at`]:
    /// a share [`UNIFORM_CHOICE`] spread evenly (so that an emitter the
    /// estimate undervalues, or a soft box seen edge-on, keeps samples),
    /// the rest in proportion to the estimates.
    #[inline(always)]
    fn emitter_choice(&self, emitter: usize, point: DVec3, total: f64) -> f64 {
        choice_of_estimate(
            || self.emitter_estimate(emitter, point),
            total,
            self.sampled_emitters(),
        )
    }

    /// Next-event estimation's light samples at `point`, each passed to
    /// `take` with its density already multiplied by
    /// [`RenderScene::light_samples_per_emitter`]: one sample of every
    /// light, then of the environment (of each of its parts when `sky`
    /// holds the sky part's numbers, see
    /// [`RenderScene::environment_parts_apart`]), while there are at most
    /// [`MAX_LIGHT_SAMPLES`] emitters; else [`MAX_LIGHT_SAMPLES`] samples,
    /// each of an emitter chosen in its stratum of the emitters' cumulative
    /// choice probabilities ([`RenderScene::emitter_choice`], by their
    /// estimated irradiance at `point`, whose sum is `emitter_total`; one
    /// number shared by the strata), so that a vertex's work stays bounded
    /// however many lights a scene has. Each of a vertex's samples then
    /// counts 1 / (its emitter's density × the expected samples of that
    /// emitter): unbiased, and the weights with BRDF sampling still sum to 1.
    #[inline(always)]
    fn for_each_light_sample(
        &self,
        point: DVec3,
        sky: Option<[f64; 2]>,
        stream: &mut SampleStream,
        mut take: impl FnMut(LightSample, Option<usize>),
    ) -> f64 {
        let light_sample = |s: EnvironmentSample, share: f64| LightSample {
            direction: s.direction,
            distance: f64::INFINITY,
            radiance: s.radiance,
            pdf: s.pdf * share,
            is_delta: false,
        };
        let environment_sample =
            |u: [f64; 2], share: f64| self.environment.sample(u).map(|s| light_sample(s, share));
        let emitters = self.sampled_emitters();
        if emitters <= MAX_LIGHT_SAMPLES {
            for (index, light) in self.lights.iter().enumerate() {
                let u = stream.next_2d();
                if let Some(sample) = light.sample(point, u) {
                    take(sample, Some(index));
                }
            }
            if let Some(sky) = sky {
                // The sun where the whole map's sample would be (it drew
                // the sun 98 % of the time in the suite's map), the sky
                // from a side generator: the BRDF sample and the later
                // vertices keep the Sobol pairs they had.
                let sun = self.environment.sample_part(1, stream.next_2d());
                let sky = self.environment.sample_part(0, sky);
                for s in [sun, sky].into_iter().flatten() {
                    take(light_sample(s, 1.0), None);
                }
            } else if let Some(sample) = self
                .samples_environment()
                .then(|| environment_sample(stream.next_2d(), 1.0))
                .flatten()
            {
                take(sample, None);
            }
            return 0.0;
        }
        // The first emitters' estimates kept (the rest, rare, computed
        // again in the walk); then, as the strata's positions in [0, 1)
        // rise, one walk along the emitters' cumulative choice finds all
        // three.
        let mut kept = [0.0; KEPT_ESTIMATES];
        let mut total = 0.0;
        for emitter in 0..emitters {
            let estimate = self.emitter_estimate(emitter, point);
            if let Some(slot) = kept.get_mut(emitter) {
                *slot = estimate;
            }
            total += estimate;
        }
        let choice_of = |emitter: usize| {
            let estimate = || {
                kept.get(emitter)
                    .copied()
                    .unwrap_or_else(|| self.emitter_estimate(emitter, point))
            };
            choice_of_estimate(estimate, total, emitters)
        };
        let offset = stream.next_1d();
        let (mut chosen, mut below, mut choice) = (0, 0.0, choice_of(0));
        for stratum in 0..MAX_LIGHT_SAMPLES {
            let position = (stratum as f64 + offset) / MAX_LIGHT_SAMPLES as f64;
            while position >= below + choice && chosen + 1 < emitters {
                below += choice;
                chosen += 1;
                choice = choice_of(chosen);
            }
            let share = MAX_LIGHT_SAMPLES as f64 * choice;
            let u = stream.next_2d();
            let sample = match self.lights.get(chosen) {
                Some(light) => light.sample(point, u).map(|s| LightSample {
                    pdf: s.pdf * share,
                    ..s
                }),
                None => environment_sample(u, share),
            };
            if let Some(sample) = sample {
                take(sample, self.light_of_emitter(chosen));
            }
        }
        total
    }

    /// One ambient-occlusion ray of length `distance` around the geometric
    /// normal (1 escaped, 0 blocked), from a side stream so the beauty
    /// image does not depend on the option. Out of line, and called only
    /// when the option is on: inlined, the compiler hoisted the side
    /// stream's hashing above the option's test, so that every sample of
    /// every render paid for it.
    #[inline(never)]
    fn unoccluded(
        &self,
        hit: &SurfaceHit,
        point: DVec3,
        distance: f64,
        stream: &SampleStream,
        counts: &mut RayCounts,
    ) -> f64 {
        let mut rng = stream.side_stream(0xa0);
        let local = cosine_hemisphere(rng.next_f64(), rng.next_f64());
        let direction = Frame::new(hit.normal).to_world(local);
        counts.shadow += 1;
        if self
            .world
            .occluded_leaving(point, direction, distance, hit.stone_index())
        {
            0.0
        } else {
            1.0
        }
    }

    /// The nearest light surface along the ray before `t_max` (the sun only
    /// when `t_max` is infinite). Always inlined, as [`RenderScene::direct_evaluated`].
    #[inline(always)]
    fn nearest_light(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
    ) -> Option<(usize, &Light, f64, Rgb)> {
        let mut best: Option<(usize, &Light, f64, Rgb)> = None;
        for (index, light) in self.lights.iter().enumerate() {
            // `hit` only reports a crossing nearer than the limit.
            let limit = best.map_or(t_max, |b| b.2);
            if let Some((t, emitted)) = light.hit(origin, direction, limit) {
                best = Some((index, light, t, emitted));
            }
        }
        best
    }

    /// One light sample's MIS-weighted contribution f·L·cosθ/pdf at a
    /// vertex that shades its light samples one by one (see
    /// [`RenderScene::evaluate_vertex`] for the others).
    #[inline(always)]
    fn direct(
        &self,
        shading: &Shading<'_>,
        (brdf_at, mix): (&BrdfAt<'_>, Option<&FacetMix<'_>>),
        hit: &SurfaceHit,
        point: DVec3,
        (sample, emitter): (&LightSample, Option<usize>),
        counts: &mut RayCounts,
    ) -> Rgb {
        let direction = sample.direction;
        let cos_stone = direction.dot(hit.normal);
        if sample.pdf <= 0.0 || cos_stone <= 0.0 {
            return Rgb::ZERO;
        }
        let evaluated = match mix {
            Some(mix) => {
                // The facets' f·cosθi, each by its own normal, as an f
                // against the stone's cos θi (the shading frame is a
                // blended facet's own).
                let (value, pdf) = mix.eval_cos_and_pdf(direction);
                (value / cos_stone, pdf, cos_stone)
            }
            None => {
                let wi = shading.frame.to_local(direction);
                if wi.z <= 0.0 {
                    return Rgb::ZERO;
                }
                let (f, pdf) = brdf_at.eval_and_pdf(wi);
                (f, pdf, wi.z)
            }
        };
        self.direct_evaluated(evaluated, hit, point, (sample, emitter), counts)
    }

    /// The BRDF at a vertex's light samples and at its own sample from
    /// `u`, in one [`BrdfAt::eval_and_pdf_lanes`] call: per light sample
    /// (f, the BRDF's density, cosθᵢ), None where the sample adds nothing
    /// (below the stone's or the shading frame's horizon, or of density 0),
    /// and what [`BrdfAt::sample`]`(u)` returns.
    #[inline(always)]
    fn evaluate_vertex(
        &self,
        frame: &Frame,
        brdf_at: &BrdfAt<'_>,
        hit: &SurfaceHit,
        light_samples: &VertexLightSamples,
        u: [f64; 3],
    ) -> ([Option<Evaluated>; MAX_LIGHT_SAMPLES], Option<BrdfSample>) {
        // The directions to evaluate (wi.z > 0), the BRDF sample's last.
        let mut directions = [DVec3::Z; LANES];
        let mut count = 0;
        let mut lanes = [None; MAX_LIGHT_SAMPLES];
        for (lane, (sample, _)) in lanes.iter_mut().zip(light_samples.iter()) {
            if sample.pdf <= 0.0 || sample.direction.dot(hit.normal) <= 0.0 {
                continue;
            }
            let wi = frame.to_local(sample.direction);
            if wi.z > 0.0 {
                directions[count] = wi;
                *lane = Some(count);
                count += 1;
            }
        }
        let sampled_wi = brdf_at.sample_direction(u);
        if let Some(wi) = sampled_wi {
            directions[count] = wi;
        }
        let used = count + usize::from(sampled_wi.is_some());
        let values = brdf_at.eval_and_pdf_lanes(&directions, used);
        let lights = lanes.map(|lane| lane.map(|k| (values[k].0, values[k].1, directions[k].z)));
        let sampled = sampled_wi.and_then(|wi| accept(wi, values[count].0, values[count].1));
        (lights, sampled)
    }

    /// One light sample's MIS-weighted contribution f·L·cosθ/pdf, given f,
    /// the BRDF's density and cosθᵢ at the sample's direction: its shadow
    /// ray and the power heuristic.
    ///
    /// Always inlined into [`RenderScene::radiance`] (as the compiler chose
    /// by itself until the film's loop grew): out of line, this and
    /// [`RenderScene::nearest_light`] cost calls and arguments passed
    /// through memory on every vertex.
    #[inline(always)]
    fn direct_evaluated(
        &self,
        (f, brdf_pdf, cos_i): Evaluated,
        hit: &SurfaceHit,
        point: DVec3,
        (sample, emitter): (&LightSample, Option<usize>),
        counts: &mut RayCounts,
    ) -> Rgb {
        let LightSample {
            direction,
            distance,
            radiance: incoming,
            pdf,
            is_delta,
        } = *sample;
        if f.max_element() <= 0.0 || incoming.max_element() <= 0.0 {
            return Rgb::ZERO;
        }
        counts.shadow += 1;
        let reach = shadow_reach(distance);
        if self
            .world
            .occluded_leaving(point, direction, reach, hit.stone_index())
            || self.another_light_blocks(point, direction, reach, emitter)
        {
            return Rgb::ZERO;
        }
        f * incoming * light_sample_scale(cos_i, pdf, brdf_pdf, is_delta)
    }
}

/// A light sample's cosθ·w/pdf at a vertex whose BSDF would pick the
/// direction with density `bsdf_pdf`: the power heuristic
/// w = pdf²/(pdf² + pdf_bsdf²) (eq. 9.13) folds into cosθ·pdf/(pdf² +
/// pdf_bsdf²), one division on the path's critical chain instead of two
/// (pdf > 0); a delta light takes cosθ/pdf.
#[inline(always)]
fn light_sample_scale(cos_theta: f64, pdf: f64, bsdf_pdf: f64, is_delta: bool) -> f64 {
    if is_delta {
        cos_theta / pdf
    } else {
        cos_theta * pdf / (pdf * pdf + bsdf_pdf * bsdf_pdf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::render_scene::MATERIAL_ID_FIRST_STONE;

    #[test]
    fn first_hit_sums_count_hits_only_and_keep_the_first_samples_ids() {
        let miss = FirstHit {
            unoccluded: 1.0,
            ..FirstHit::default()
        };
        let flake = FirstHit {
            depth: 2.0,
            normal: DVec3::Z,
            albedo: Rgb::new(0.5, 0.25, 0.125),
            surface_cell: 7,
            glitter: true,
            material_id: MATERIAL_ID_FIRST_STONE,
            unoccluded: 0.0,
        };
        let unlit_ground = FirstHit {
            depth: 4.0,
            normal: DVec3::Y,
            albedo: Rgb::splat(f64::NAN), // a sample that carried nothing
            material_id: MATERIAL_ID_GROUND,
            unoccluded: 1.0,
            ..FirstHit::default()
        };
        let mut sums = FirstHitSums::default();
        sums.add(&miss, true);
        sums.add(&flake, false);
        sums.add(&unlit_ground, false);
        // The misses count towards ambient occlusion only; the ids are the
        // first sample's (a miss: 0) even though later samples hit.
        assert_eq!(sums.unoccluded, 2.0);
        assert_eq!((sums.surface_cell, sums.material_id), (0, 0));
        assert_eq!((sums.hits, sums.glints), (2, 1));
        assert_eq!(sums.depth, 6.0);
        assert_eq!(sums.normal, DVec3::new(0.0, 1.0, 1.0));
        // The non-finite albedo estimate is left out, not propagated.
        assert_eq!(sums.albedo, flake.albedo);

        let mut first_is_flake = FirstHitSums::default();
        first_is_flake.add(&flake, true);
        first_is_flake.add(&miss, false);
        assert_eq!(
            (first_is_flake.surface_cell, first_is_flake.material_id),
            (7, 2)
        );
    }

    #[test]
    fn the_ground_frame_is_the_frame_built_around_plus_z() {
        // `shade` uses the constant for the ground's +z normal in place of
        // `Frame::new`: the same axes, bit for bit, and transforms equal to
        // the general ones (as numbers: a zero may differ in sign).
        let (up, built) = (Frame::UP, Frame::new(DVec3::Z));
        assert_eq!((up.t, up.b, up.n), (built.t, built.b, built.n));
        assert!(up.is_up && !built.is_up);
        let mut rng = crate::sampling::Rng::new(11, 0);
        let mut v = DVec3::new(0.3, -0.5, 0.8);
        for _ in 0..1000 {
            assert_eq!(up.to_local(v), built.to_local(v), "{v}");
            assert_eq!(up.to_world(v), built.to_world(v), "{v}");
            v = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0;
        }
    }
}
