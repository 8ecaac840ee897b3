//! The ground path kernel: the commonest samples of a product shot, traced
//! sixteen at a time in lane loops.
//!
//! Most of a frame is ground around the stone. A sample whose camera ray
//! meets a bare Lambert ground is a short path: the ground vertex, next-event
//! estimation of each sphere light with a shadow test against the stone, a
//! cosine-sampled bounce that escapes to a constant sky or meets a light.
//! [`RenderScene::radiance`] traces it with the generality every vertex
//! pays for (the material enum, the light and environment kinds, the stone
//! search, the AOVs, its state through memory); here the same arithmetic is
//! written as one straight line per lane over the sixteen samples of a
//! [`SampleBatch`], with every branch a select, which the x86-64-v3 copy of
//! the row loop ([`crate::render::code_path`]) compiles to AVX2 arithmetic
//! on four lanes per instruction.
//!
//! **The same bits.** Every lane does the IEEE operations of
//! [`RenderScene::radiance`] in the same order, draws the same numbers from
//! its [`SampleStream`](crate::render::sampler::SampleStream), and reports
//! the same radiance, first-hit AOVs and ray counts. A lane whose path
//! leaves the kernel's class — its camera ray misses the ground or meets
//! the stone or a light first, its ground point is inside a light, its
//! bounce meets the stone — is marked, and the film traces that sample
//! again from its start with the general loop (its random numbers are a
//! pure function of the sample, so the retrace is the sample). The film
//! sums the lanes in sample order. So an image is the same bytes with the
//! kernel on or off (`LAPIDARY_KERNELS=off`; tested).
//!
//! **The class** ([`GroundPaths::for_scene`]): a ground whose material is a
//! bare Lambert surface, one to [`MAX_LIGHTS`] sphere lights and nothing
//! else, a constant environment, no ambient-occlusion AOV, and any stones.
//! One half-ellipsoid cabochon (any placement) is tested in the lanes;
//! several (a tray) through the world's own search, the general loop's
//! question asked for the sixteen rays at once (`World::occluded_lanes`).
//! Round 12: with the lone stone in the kernel and trays outside it, the
//! 1000-stone tray had reached 2.13 times one stone's time, alternately;
//! 1.79 with trays in it. Everything else renders with the general loop
//! alone.

use std::f64::consts::PI;

use glam::DVec3;

use crate::brdf::Rgb;
#[cfg(target_arch = "x86_64")]
use crate::render::code_path::{code_path, CodePath};
use crate::render::environment::Environment;
use crate::render::integrator::{power_heuristic, FirstHit, RenderScene, MATERIAL_ID_GROUND};
use crate::render::lights::{cone_pdf, sample_cone, sphere_entry_or_infinity, Light};
use crate::render::sampler::{SampleBatch, SAMPLE_BATCH, SOBOL_PAIRS};
use crate::render::world::{LoneStone, World, RAY_OFFSET};
use crate::sampling::cosine_hemisphere;

/// Samples traced together: one [`SampleBatch`].
pub const LANES: usize = SAMPLE_BATCH as usize;

/// The most sphere lights the kernel takes: their samples and the bounce's
/// must all come from the batch's Sobol pairs (footprint, lights, bounce).
pub const MAX_LIGHTS: usize = 4;
const _: () = assert!(1 + MAX_LIGHTS < SOBOL_PAIRS as usize);

/// Whether `LAPIDARY_KERNELS=off` turns the kernel off for this process
/// (to check that it changes no byte, or to rule it out when chasing a
/// problem), read once.
pub fn kernels_enabled() -> bool {
    static ENABLED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ENABLED.get_or_init(|| std::env::var("LAPIDARY_KERNELS").map_or(true, |v| v != "off"))
}

/// A sphere light as the kernel reads it.
#[derive(Clone, Copy, Debug)]
struct SphereLight {
    centre: DVec3,
    radius: f64,
    radiance: Rgb,
    /// `direct`'s test f·L > 0 in some channel, which depends only on the
    /// ground's value and the light here: when false no shadow ray is cast.
    lights_the_ground: bool,
}

/// The scene's constants for the kernel; built by [`GroundPaths::for_scene`]
/// for scenes in its class.
#[derive(Clone, Debug)]
pub struct GroundPaths {
    ground_height: f64,
    /// colour/π of the bare Lambert ground.
    ground_value: Rgb,
    lights: Vec<SphereLight>,
    sky: Rgb,
    stones: StoneTest,
}

/// How the kernel tests its rays against the stones.
#[derive(Clone, Debug)]
enum StoneTest {
    /// The world has no stones.
    None,
    /// One half ellipsoid, tested in the lanes ([`stone_blocks`]).
    Lone(LoneStone),
    /// Any other set of stones (a tray): the lanes ask the world's own
    /// search, [`World::occluded_leaving`], as the general loop does for its
    /// shadow rays; on a tray's grid through [`World::occluded_lanes`],
    /// which gathers the stones near all sixteen rays once (1000-stone tray
    /// −11 % of the time, alternately). For the camera segment and the bounce it answers what
    /// the general loop's [`World::intersect_leaving`] decides: whether a
    /// stone is crossed before the ground point (or at all), which is the
    /// same test of each stone (`Cabochon::crosses` and `intersect` agree
    /// on a crossing in a range) behind the same grid or BVH search. Its
    /// ground test never fires here: the camera segment's range ends at
    /// the ground point itself, and shadow rays and bounces rise.
    World,
}

/// The kernel's answer for the sixteen samples of a batch.
#[derive(Clone, Copy, Debug)]
pub struct GroundLanes {
    /// True where the lane's path stayed in the kernel's class and the
    /// fields below are its results; false where the film must trace the
    /// sample with the general loop.
    pub traced: [bool; LANES],
    /// Radiance along the camera ray.
    pub radiance: [Rgb; LANES],
    /// Distance from the camera to the ground point (the `depth` AOV).
    pub depth: [f64; LANES],
    /// The BRDF sample's weight f·cosθ/pdf (the `albedo` AOV).
    pub albedo: [Rgb; LANES],
    /// Shadow rays cast (lights that passed `direct`'s tests).
    pub shadow_rays: [u32; LANES],
}

/// Camera ray and bounce: the rays of every path the kernel traces.
pub const TRACED_RAYS_PER_PATH: u64 = 2;

impl GroundLanes {
    /// Lane `lane`'s first hit, as [`RenderScene::radiance`] records a
    /// ground hit (no AO ray in the kernel's class).
    #[inline(always)]
    pub fn first_hit(&self, lane: usize) -> FirstHit {
        FirstHit {
            depth: self.depth[lane],
            normal: DVec3::Z,
            albedo: self.albedo[lane],
            unoccluded: 1.0,
            surface_cell: 0,
            glitter: false,
            material_id: MATERIAL_ID_GROUND,
        }
    }
}

/// Per-lane arrays of one quantity.
type Lanes = [f64; LANES];

impl GroundPaths {
    /// The kernel for `scene`, or None when the scene is outside its class
    /// (see the module documentation) or the kernel is turned off.
    pub fn for_scene(scene: &RenderScene) -> Option<Self> {
        if !kernels_enabled() || scene.ambient_occlusion.is_some() {
            return None;
        }
        let ground_height = scene.world.ground_height()?;
        let ground_value = scene.ground_brdf.as_ref()?.bare_lambert()?;
        // `lambert_sample` keeps only finite values; the bounce is traced
        // only where the throughput is positive somewhere.
        if !(ground_value.is_finite() && ground_value.max_element() > 0.0) {
            return None;
        }
        let Environment::Constant(sky) = scene.environment else {
            return None;
        };
        if scene.lights.is_empty() || scene.lights.len() > MAX_LIGHTS {
            return None;
        }
        let lights = scene
            .lights
            .iter()
            .map(|light| match *light {
                Light::Sphere {
                    centre,
                    radius,
                    radiance,
                } => Some(SphereLight {
                    centre,
                    radius,
                    radiance,
                    lights_the_ground: !(ground_value.max_element() <= 0.0
                        || radiance.max_element() <= 0.0),
                }),
                _ => None,
            })
            .collect::<Option<Vec<_>>>()?;
        let stones = match scene.world.lone_stone_for_lanes() {
            Some(None) => StoneTest::None,
            Some(Some(stone)) => StoneTest::Lone(stone),
            None => StoneTest::World,
        };
        // The batch's pairs the kernel reads (footprint, lights, bounce)
        // are among those the film makes for every lane.
        debug_assert!(2 + lights.len() as u32 <= scene.first_vertex_pairs());
        Some(Self {
            ground_height,
            ground_value,
            lights,
            sky,
            stones,
        })
    }

    /// Traces the sixteen samples of `batch` whose camera rays leave
    /// `origin` along `directions`, as [`RenderScene::radiance`] would (see
    /// the module documentation). In the x86-64-v3 code path the lane
    /// loops are compiled with AVX2, in the v4 path with AVX-512; every
    /// copy gives the same bits. Written out, not through
    /// `code_path_copies!`: that macro's always-inlined dispatcher copied
    /// the kernel's 1 kB answer once more on its way to the film (peer
    /// render loop +1.2 % of the instructions).
    pub fn trace(
        &self,
        world: &World,
        origin: DVec3,
        directions: &[DVec3; LANES],
        batch: &SampleBatch,
    ) -> GroundLanes {
        #[cfg(target_arch = "x86_64")]
        match code_path() {
            // SAFETY (both): the copy needs only the features that
            // `code_path` found on this CPU.
            CodePath::X86_64V4 => {
                return unsafe { self.trace_x86_64_v4(world, origin, directions, batch) };
            }
            CodePath::X86_64V3 => {
                return unsafe { self.trace_x86_64_v3(world, origin, directions, batch) };
            }
            CodePath::Portable => {}
        }
        self.trace_lanes(world, origin, directions, batch)
    }

    /// [`GroundPaths::trace_lanes`] compiled for x86-64-v3.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt")]
    #[inline(never)]
    fn trace_x86_64_v3(
        &self,
        world: &World,
        origin: DVec3,
        directions: &[DVec3; LANES],
        batch: &SampleBatch,
    ) -> GroundLanes {
        self.trace_lanes(world, origin, directions, batch)
    }

    /// [`GroundPaths::trace_lanes`] compiled for x86-64-v4: a lane array
    /// of sixteen f64 is two AVX-512 registers (four AVX2 ones), the
    /// selects are mask operations, and 32 vector registers hold more of
    /// the kernel's state (peer render −10 % of the time against the v3
    /// copy, alternately, on a Zen 4 host; see [`crate::render::code_path`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(
        enable = "avx2,fma,bmi1,bmi2,lzcnt,avx512f,avx512dq,avx512vl,avx512bw,avx512cd"
    )]
    #[inline(never)]
    fn trace_x86_64_v4(
        &self,
        world: &World,
        origin: DVec3,
        directions: &[DVec3; LANES],
        batch: &SampleBatch,
    ) -> GroundLanes {
        self.trace_lanes(world, origin, directions, batch)
    }

    /// The kernel itself (see [`GroundPaths::trace`]).
    #[inline(always)]
    fn trace_lanes(
        &self,
        world: &World,
        origin: DVec3,
        directions: &[DVec3; LANES],
        batch: &SampleBatch,
    ) -> GroundLanes {
        let zero: Lanes = [0.0; LANES];
        let lights = self.lights.len();
        // Each step below is a loop over the lanes with a straight-line
        // body (a loop over the lights inside one would keep LLVM from
        // vectorising it), the stone's tests in loops of their own.

        // The camera segment: `World::intersect_leaving` finds the ground
        // (and no stone before it), `nearest_light` no light before it.
        let h = self.ground_height;
        let mut traced = [false; LANES];
        let mut depth = zero;
        let (mut px, mut py) = (zero, zero);
        for lane in 0..LANES {
            let d = directions[lane];
            let t = (h - origin.z) / d.z;
            traced[lane] = (d.z < 0.0) & (origin.z > h) & (t < f64::INFINITY);
            depth[lane] = t;
            // The hit point, then `+ normal · RAY_OFFSET` (normal +z).
            px[lane] = (origin.x + d.x * t) + 0.0 * RAY_OFFSET;
            py[lane] = (origin.y + d.y * t) + 0.0 * RAY_OFFSET;
        }
        let blocked = self.stones_block(world, &[origin; LANES], directions, &depth, &traced);
        for lane in 0..LANES {
            traced[lane] &= !blocked[lane];
        }
        for light in &self.lights {
            for lane in 0..LANES {
                let t_light =
                    sphere_entry_or_infinity(origin, directions[lane], light.centre, light.radius);
                // (`nearest_light` takes a light at t < depth; a NaN
                // here falls back to the general loop.)
                traced[lane] &= t_light >= depth[lane];
            }
        }
        // A batch of a pixel on the stone (or the sky) ends here.
        if !traced.contains(&true) {
            return GroundLanes {
                traced,
                radiance: [Rgb::ZERO; LANES],
                depth,
                albedo: [Rgb::ZERO; LANES],
                shadow_rays: [0; LANES],
            };
        }
        let pz = h + 1.0 * RAY_OFFSET;
        let mut points = [DVec3::ZERO; LANES];
        for lane in 0..LANES {
            points[lane] = DVec3::new(px[lane], py[lane], pz);
        }

        // The random numbers, in each stream's order: Sobol pair 0 is the
        // footprint (already in `directions`), pair 1 + i light i's sample,
        // pair 1 + lights and the tail's first number the bounce's.
        let mut bounce_tail = zero;
        for (lane, tail) in bounce_tail.iter_mut().enumerate() {
            *tail = batch.first_tail_number(lane as u32);
        }

        // Next-event estimation of each light (`Light::sample` of a sphere,
        // then `RenderScene::direct` with the Lambert value and the power
        // heuristic), added to the radiance in light order. The ground's
        // frame is the identity and the throughput is still 1.
        let (mut red, mut green, mut blue) = (zero, zero, zero);
        let mut shadow_rays = [0u32; LANES];
        let mut light_pdf = [zero; MAX_LIGHTS];
        for (index, light) in self.lights.iter().enumerate() {
            let r2 = light.radius * light.radius;
            let mut direction = [DVec3::ZERO; LANES];
            let mut reach = zero;
            let mut cast = [false; LANES];
            for lane in 0..LANES {
                // `sample_sphere`.
                let to = light.centre - points[lane];
                let d2 = to.length_squared();
                // A point inside the light gets no sample (general loop).
                traced[lane] &= d2 > r2;
                let d = d2.sqrt();
                let axis = to / d;
                let cos_max = (1.0 - r2 / d2).max(0.0).sqrt();
                let (sampled, cos_theta) = sample_cone(axis, cos_max, batch.pair(lane, 1 + index));
                let sin2_theta = 1.0 - cos_theta * cos_theta;
                let distance = d * cos_theta - (r2 - d2 * sin2_theta).max(0.0).sqrt();
                light_pdf[index][lane] = cone_pdf(cos_max);
                direction[lane] = sampled;
                // `direct`: the direction above the ground and f·L > 0,
                // then a shadow ray (the ground cannot block a rising ray).
                cast[lane] = (sampled.z > 0.0) & light.lights_the_ground;
                reach[lane] = distance * (1.0 - 1e-7) - RAY_OFFSET;
            }
            let mut lit = cast;
            let mut asked = cast;
            for lane in 0..LANES {
                asked[lane] &= traced[lane];
            }
            let blocked = self.stones_block(world, &points, &direction, &reach, &asked);
            for lane in 0..LANES {
                lit[lane] &= !blocked[lane];
            }
            for lane in 0..LANES {
                let pdf = light_pdf[index][lane];
                let cos_theta = direction[lane].z;
                let brdf_pdf = cos_theta / PI;
                let scale = cos_theta * pdf / (pdf * pdf + brdf_pdf * brdf_pdf);
                let f = self.ground_value;
                let contribution = Rgb::ONE * (f * light.radiance * scale);
                let contribution = if lit[lane] { contribution } else { Rgb::ZERO };
                red[lane] += contribution.x;
                green[lane] += contribution.y;
                blue[lane] += contribution.z;
                shadow_rays[lane] += u32::from(cast[lane]);
            }
        }

        // The bounce: `lambert_sample`, the first-hit albedo, the
        // throughput, then the segment to the sky or a light.
        let mut albedo = [Rgb::ZERO; LANES];
        let mut wi = [DVec3::ZERO; LANES];
        let mut brdf_pdf = zero;
        for lane in 0..LANES {
            // `lambert_sample` reads u₁ and u₂ of (u₀, u₁, u₂).
            let [_, u1] = batch.pair(lane, 1 + lights);
            let sampled = cosine_hemisphere(u1, bounce_tail[lane]);
            let pdf = sampled.z / PI;
            let weight = self.ground_value * (sampled.z / pdf);
            let throughput = Rgb::ONE * weight;
            traced[lane] &= (sampled.z > 0.0) & (throughput.max_element() > 0.0);
            wi[lane] = sampled;
            brdf_pdf[lane] = pdf;
            albedo[lane] = weight;
        }
        let blocked = self.stones_block(world, &points, &wi, &[f64::INFINITY; LANES], &traced);
        for lane in 0..LANES {
            traced[lane] &= !blocked[lane];
        }
        // `nearest_light`, keeping each lane's nearest light's radiance and
        // density (the NEE's: same point, same light).
        let mut nearest = [f64::INFINITY; LANES];
        let mut emitted = [Rgb::ZERO; LANES];
        let mut nearest_pdf = zero;
        for (index, light) in self.lights.iter().enumerate() {
            for lane in 0..LANES {
                let t =
                    sphere_entry_or_infinity(points[lane], wi[lane], light.centre, light.radius);
                let nearer = t < nearest[lane];
                nearest[lane] = if nearer { t } else { nearest[lane] };
                emitted[lane] = if nearer {
                    light.radiance
                } else {
                    emitted[lane]
                };
                nearest_pdf[lane] = if nearer {
                    light_pdf[index][lane]
                } else {
                    nearest_pdf[lane]
                };
            }
        }
        // The light with the power heuristic, else the sky (weight 1).
        for lane in 0..LANES {
            let throughput = Rgb::ONE * albedo[lane];
            let weight = power_heuristic(brdf_pdf[lane], nearest_pdf[lane]);
            let from_light = throughput * emitted[lane] * weight;
            let from_sky = throughput * self.sky * 1.0;
            let brought = if nearest[lane] < f64::INFINITY {
                from_light
            } else {
                from_sky
            };
            red[lane] += brought.x;
            green[lane] += brought.y;
            blue[lane] += brought.z;
        }

        let mut radiance = [Rgb::ZERO; LANES];
        for lane in 0..LANES {
            radiance[lane] = Rgb::new(red[lane], green[lane], blue[lane]);
        }
        GroundLanes {
            traced,
            radiance,
            depth,
            albedo,
            shadow_rays,
        }
    }

    /// Whether a stone blocks each lane's ray from `origins` along
    /// `directions` in (0, `t_max`), for the lanes marked in `asked` (the
    /// others' answers are not used: their paths are retraced, or their
    /// shadow ray is not cast). Only the world's own search looks at
    /// `asked`; the lone stone's lane test answers every lane.
    #[inline(always)]
    fn stones_block(
        &self,
        world: &World,
        origins: &[DVec3; LANES],
        directions: &[DVec3; LANES],
        t_max: &Lanes,
        asked: &[bool; LANES],
    ) -> [bool; LANES] {
        match &self.stones {
            StoneTest::None => [false; LANES],
            StoneTest::Lone(stone) => stone_blocks(stone, origins, directions, t_max),
            StoneTest::World => world.occluded_lanes(origins, directions, t_max, asked),
        }
    }
}

/// Whether the stone blocks each lane's ray from `origins` along
/// `directions` in (0, `t_max`): [`LoneStone::crosses`] of every lane when
/// any lane's ray [`LoneStone::may_cross`], else false for all (the exact
/// answer then: no ray comes near the stone). Most batches of a frame are
/// far from the stone, and their shadow rays and bounces with it.
#[inline(always)]
fn stone_blocks(
    stone: &LoneStone,
    origins: &[DVec3; LANES],
    directions: &[DVec3; LANES],
    t_max: &Lanes,
) -> [bool; LANES] {
    let mut near = [false; LANES];
    for lane in 0..LANES {
        near[lane] = stone.may_cross(origins[lane], directions[lane]);
    }
    let mut blocked = [false; LANES];
    if near.contains(&true) {
        for lane in 0..LANES {
            blocked[lane] = stone.crosses(origins[lane], directions[lane], 0.0, t_max[lane]);
        }
    }
    blocked
}
