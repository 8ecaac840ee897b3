//! The geometry the rays meet: stones (analytic cabochons, placed by a
//! rotation and a translation, found through a grid when they lie side by
//! side on a tray, else through one obvhs BVH) and an optional ground plane.

use glam::{DMat3, DQuat, DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::{Boundable, BvhBuildParams};

use crate::geometry::{Cabochon, Hit};
use crate::render::stone_grid::StoneGrid;

/// One stone in the scene: a cabochon in its object space, placed in the
/// world by `rotation` then `position`, shaded by gem number `gem`.
#[derive(Clone, Debug)]
pub struct StoneInstance {
    /// The stone's shape in object space (z up, girdle plane at z = 0).
    pub cabochon: Cabochon,
    /// Object-to-world rotation.
    pub rotation: DQuat,
    /// Where the object-space origin goes.
    pub position: DVec3,
    /// Index of the gem (pattern + materials) that shades this stone.
    pub gem: usize,
}

impl StoneInstance {
    /// World-space axis-aligned box around the stone.
    pub(crate) fn world_bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.cabochon.bounds();
        let mut min = DVec3::splat(f64::INFINITY);
        let mut max = DVec3::splat(f64::NEG_INFINITY);
        for corner in 0..8 {
            let c = DVec3::new(
                if corner & 1 == 0 { lo.x } else { hi.x },
                if corner & 2 == 0 { lo.y } else { hi.y },
                if corner & 4 == 0 { lo.z } else { hi.z },
            );
            let w = self.position + self.rotation * c;
            min = min.min(w);
            max = max.max(w);
        }
        (min, max)
    }

    /// The first crossing of the world ray with this stone's surface in
    /// (t_min, t_max), from outside or inside, in the stone's object space
    /// (`frame` precomputed by [`World::new`]). A rotation keeps lengths, so
    /// t is the same in both spaces. Inlined into the world's loops so that
    /// the hit stays in registers.
    #[inline(always)]
    fn intersect(
        &self,
        frame: &Placement,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        let (o, d) = frame.object_ray(self.position, origin, direction);
        self.cabochon.intersect(o, d, t_min, t_max)
    }

    /// Whether the world ray crosses this stone's surface in (t_min, t_max).
    #[inline(always)]
    fn crosses(
        &self,
        frame: &Placement,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> bool {
        let (o, d) = frame.object_ray(self.position, origin, direction);
        self.cabochon.crosses(o, d, t_min, t_max)
    }
}

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// Stone number `index`, at a point of its object space.
    Stone {
        /// Index into [`World::stones`].
        index: usize,
        /// The hit point in the stone's object space (for the pattern).
        object_point: glam::DVec3,
        /// The outward unit normal in object space.
        object_normal: glam::DVec3,
    },
    /// The ground plane.
    Ground,
}

/// A ray's nearest intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Distance along the (unit) ray direction.
    pub t: f64,
    /// World-space point.
    pub point: DVec3,
    /// World-space outward unit geometric normal.
    pub normal: DVec3,
    /// Which surface.
    pub surface: Surface,
}

impl SurfaceHit {
    /// The index of the stone hit, `None` for the ground.
    pub(crate) fn stone_index(&self) -> Option<usize> {
        match self.surface {
            Surface::Stone { index, .. } => Some(index),
            Surface::Ground => None,
        }
    }
}

/// A stone's rotation as matrices and its world box in f64, precomputed
/// once: a matrix-vector product is half the work of rotating by a
/// quaternion, and every ray does two.
#[derive(Clone, Copy, Debug)]
struct Placement {
    world_to_object: DMat3,
    object_to_world: DMat3,
    /// The rotation is the identity: object and world differ by the
    /// translation only, and both matrix products are skipped.
    unrotated: bool,
    /// Padded world-space bounds (min, max).
    bounds: (DVec3, DVec3),
}

impl Placement {
    /// A world ray in the object space of the stone at `position`.
    #[inline]
    fn object_ray(&self, position: DVec3, origin: DVec3, direction: DVec3) -> (DVec3, DVec3) {
        if self.unrotated {
            (origin - position, direction)
        } else {
            (
                self.world_to_object * (origin - position),
                self.world_to_object * direction,
            )
        }
    }

    /// The world-space hit of stone number `index` for an object-space `hit`
    /// of the world ray.
    #[inline]
    fn surface_hit(&self, index: usize, origin: DVec3, direction: DVec3, hit: Hit) -> SurfaceHit {
        SurfaceHit {
            t: hit.t,
            point: origin + direction * hit.t,
            // The object normal is unit; a rotation keeps it so up to
            // rounding, which `normalize` removes.
            normal: if self.unrotated {
                hit.normal
            } else {
                (self.object_to_world * hit.normal).normalize()
            },
            surface: Surface::Stone {
                index,
                object_point: hit.point,
                object_normal: hit.normal,
            },
        }
    }
}

/// Scenes with at most this many stones test each stone's box directly:
/// a slab test is cheaper than descending a BVH of a handful of boxes.
const MAX_STONES_WITHOUT_BVH: usize = 4;

/// Stones in a BVH plus the ground.
pub struct World {
    stones: Vec<StoneInstance>,
    placements: Vec<Placement>,
    /// The padded box around all stones (rays that miss it skip the BVH).
    stones_bounds: (DVec3, DVec3),
    /// How the stones are found.
    search: StoneSearch,
    ground_height: Option<f64>,
}

/// How a world with more than one stone finds the stones a ray may meet.
enum StoneSearch {
    /// Each stone's box in turn (at most [`MAX_STONES_WITHOUT_BVH`]).
    Boxes,
    /// The cells of a grid over a tray (stones side by side in a thin slab).
    Grid(StoneGrid),
    /// A BVH over the stones' boxes: any other layout.
    Bvh(CwBvh),
}

/// Whether the ray `origin + t·direction` (with `inverse_direction` its
/// reciprocal) crosses the box for some t in [0, t_max] (Kay & Kajiya
/// slabs; IEEE infinities handle axis-parallel rays).
fn ray_hits_box(
    origin: DVec3,
    inverse_direction: DVec3,
    t_max: f64,
    bounds: (DVec3, DVec3),
) -> bool {
    ray_box_span(origin, inverse_direction, t_max, bounds).is_some()
}

/// The range [near, far] of t in [0, t_max] where the ray is inside the
/// box, if any (see [`ray_hits_box`]).
#[inline(always)]
fn ray_box_span(
    origin: DVec3,
    inverse_direction: DVec3,
    t_max: f64,
    (min, max): (DVec3, DVec3),
) -> Option<(f64, f64)> {
    let t0 = (min - origin) * inverse_direction;
    let t1 = (max - origin) * inverse_direction;
    let near = t0.min(t1).max_element().max(0.0);
    let far = t0.max(t1).min_element().min(t_max);
    (near <= far).then_some((near, far))
}

struct StoneBox(Aabb);

impl Boundable for StoneBox {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// How far a new ray starts from the surface it leaves, in scene units
/// (mm): far above the intersectors' 1e-9 × size accuracy, far below any
/// visible detail.
pub(crate) const RAY_OFFSET: f64 = 1e-5;

/// How far below the ground a ray may start and still meet it: a ray
/// leaving a stone's flat base that rests on the ground starts
/// [`RAY_OFFSET`] below the base, so below the ground, and meets the
/// ground at once (there is no gap between them to pass through).
const GROUND_CONTACT: f64 = 2.0 * RAY_OFFSET;

impl World {
    /// Indexes the stones (one box each): a grid over a tray of stones,
    /// else a BVH, or nothing for a handful of stones.
    pub fn new(stones: Vec<StoneInstance>, ground_height: Option<f64>) -> Self {
        Self::build(stones, ground_height, true)
    }

    /// [`World::new`]; without `allow_grid` a tray gets a BVH too (for
    /// tests comparing the two).
    fn build(stones: Vec<StoneInstance>, ground_height: Option<f64>, allow_grid: bool) -> Self {
        let placements: Vec<Placement> = stones
            .iter()
            .map(|s| {
                let (lo, hi) = s.world_bounds();
                // Pad by an f32 ulp-scale margin so the f32 box test
                // never clips the f64 surface.
                let pad = 1e-4 * (hi - lo).max_element().max(1.0);
                let object_to_world = DMat3::from_quat(s.rotation);
                Placement {
                    world_to_object: DMat3::from_quat(s.rotation.inverse()),
                    object_to_world,
                    unrotated: object_to_world == DMat3::IDENTITY,
                    bounds: (lo - DVec3::splat(pad), hi + DVec3::splat(pad)),
                }
            })
            .collect();
        let stones_bounds = placements.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p.bounds.0), hi.max(p.bounds.1)),
        );
        let bounds: Vec<(DVec3, DVec3)> = placements.iter().map(|p| p.bounds).collect();
        let grid = (allow_grid && stones.len() > MAX_STONES_WITHOUT_BVH)
            .then(|| StoneGrid::for_tray(&bounds, stones_bounds))
            .flatten();
        let search = if stones.len() <= MAX_STONES_WITHOUT_BVH {
            StoneSearch::Boxes
        } else if let Some(grid) = grid {
            StoneSearch::Grid(grid)
        } else {
            let boxes: Vec<StoneBox> = placements
                .iter()
                .map(|p| {
                    StoneBox(Aabb {
                        min: to_f32(p.bounds.0),
                        max: to_f32(p.bounds.1),
                    })
                })
                .collect();
            // At most 1024 boxes, so obvhs' slow, high-quality build costs
            // nothing next to a render, and its tighter tree means fewer
            // boxes visited per ray on a tray of many stones.
            StoneSearch::Bvh(build_cwbvh(
                &boxes,
                BvhBuildParams::slow_build(),
                &mut Default::default(),
            ))
        };
        Self {
            stones,
            placements,
            stones_bounds,
            search,
            ground_height,
        }
    }

    /// The stones, in scene order.
    pub fn stones(&self) -> &[StoneInstance] {
        &self.stones
    }

    /// The height of the ground plane, if there is one.
    pub fn ground_height(&self) -> Option<f64> {
        self.ground_height
    }

    /// Whether a ray from `origin` along `direction` must end on the ground
    /// or a stone, never escaping: [`World::ground_ahead`], by which
    /// [`World::intersect_leaving`] then always finds the ground.
    #[inline(always)]
    pub(crate) fn cannot_escape(&self, origin: DVec3, direction: DVec3) -> bool {
        self.ground_ahead(origin, direction).is_some()
    }

    /// The ground's height when a ray from `origin` along `direction`
    /// meets it: it points down from above the ground (or from within
    /// [`GROUND_CONTACT`] below it).
    #[inline(always)]
    fn ground_ahead(&self, origin: DVec3, direction: DVec3) -> Option<f64> {
        self.ground_height
            .filter(|&h| direction.z < 0.0 && origin.z > h - GROUND_CONTACT)
    }

    /// The world ray in stone `index`'s object space, by its precomputed
    /// placement (a rotation keeps lengths: t is the same in both spaces).
    pub(crate) fn object_ray(
        &self,
        index: usize,
        origin: DVec3,
        direction: DVec3,
    ) -> (DVec3, DVec3) {
        self.placements[index].object_ray(self.stones[index].position, origin, direction)
    }

    /// How the unit outward normal of stone number `index` at the world
    /// surface point `point` turns along each of two world displacements
    /// `dp` in its tangent plane ([`Cabochon::normal_change`]).
    pub(crate) fn stone_normal_change(
        &self,
        index: usize,
        point: DVec3,
        dp: [DVec3; 2],
    ) -> [DVec3; 2] {
        let placement = &self.placements[index];
        let cabochon = &self.stones[index].cabochon;
        let position = self.stones[index].position;
        if placement.unrotated {
            return cabochon.normal_change(point - position, dp);
        }
        let to_object = placement.world_to_object;
        let turns =
            cabochon.normal_change(to_object * (point - position), dp.map(|d| to_object * d));
        turns.map(|t| placement.object_to_world * t)
    }

    /// Where the world ray from a point inside stone number `index` leaves
    /// it ([`Cabochon::exit`]): the surface hit, `None` when the ray meets
    /// no surface ahead or first enters.
    pub(crate) fn stone_exit(
        &self,
        index: usize,
        origin: DVec3,
        direction: DVec3,
    ) -> Option<SurfaceHit> {
        let placement = &self.placements[index];
        let (o, d) = placement.object_ray(self.stones[index].position, origin, direction);
        let hit = self.stones[index].cabochon.exit(o, d)?;
        Some(placement.surface_hit(index, origin, direction, hit))
    }

    /// For a ray outside every stone that met stone `hit` from inside
    /// (`hit.normal · direction > 0`): its origin is inside that stone,
    /// which happens where a path leaves the ground under a stone whose
    /// base rests on it. The ray meets the base at once, from outside
    /// (the two touch: there is no gap to pass through first), so this is
    /// the base where the origin stands on it, straight down within
    /// [`GROUND_CONTACT`], at t = 0; `None` elsewhere (the hit stands).
    pub(crate) fn contact_with_base(&self, hit: &SurfaceHit, origin: DVec3) -> Option<SurfaceHit> {
        let base = self.stone_exit(hit.stone_index()?, origin, DVec3::NEG_Z)?;
        (base.t <= GROUND_CONTACT).then_some(SurfaceHit { t: 0.0, ..base })
    }

    /// The nearest surface along a unit-direction ray in (`t_min`, `t_max`).
    pub fn intersect(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<SurfaceHit> {
        self.intersect_leaving(origin, direction, t_min, t_max, None)
    }

    /// [`World::intersect`] for a ray that leaves the outside of stone
    /// number `leaving` (`None` for a camera ray or one leaving the ground),
    /// pointing away from its geometric normal at the start (direction · n >
    /// 0, which the integrator checks). Every cabochon is convex (see
    /// `outline`): the plane tangent at the start point
    /// has the whole stone behind it, so such a ray cannot meet that stone
    /// again and it is not tested. A stone vertex's shadow ray and its next
    /// path segment each skip one stone intersection.
    ///
    /// Inlined into the integrator: the call passed both vectors and the
    /// optional hit through memory. `occluded_leaving` stays out of line:
    /// inlined as well, it made the render loop costlier.
    #[inline(always)]
    pub fn intersect_leaving(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        leaving: Option<usize>,
    ) -> Option<SurfaceHit> {
        // The ground first: it bounds the search among the stones. Its
        // SurfaceHit is only built if no stone is nearer.
        let mut limit = t_max;
        let mut ground = None;
        if let Some(h) = self.ground_ahead(origin, direction) {
            // h − origin.z < 0 (exactly, for distinct numbers) over
            // direction.z < 0: t > 0, so `t > t_min` holds for every
            // t_min ≤ 0 and is tested only above 0 (a ray from just
            // below the ground meets it at t = 0). Written as
            // `t > t_min && t < limit`, with the camera ray's (0, ∞)
            // LLVM fused the two into a 13-instruction test of t's
            // bits.
            let t = ((h - origin.z) / direction.z).max(0.0);
            if t < limit && (t_min <= 0.0 || t > t_min) {
                limit = t;
                ground = Some(h);
            }
        }
        let stone = if self.nothing_else_to_test(leaving) {
            None
        } else {
            self.nearest_stone(origin, direction, t_min, limit, leaving)
                .map(|(index, hit)| (index, &self.placements[index], hit))
        };
        match stone {
            Some((index, placement, hit)) => {
                Some(placement.surface_hit(index, origin, direction, hit))
            }
            None => ground.map(|h| SurfaceHit {
                t: limit,
                point: DVec3::new(
                    origin.x + direction.x * limit,
                    origin.y + direction.y * limit,
                    h,
                ),
                normal: DVec3::Z,
                surface: Surface::Ground,
            }),
        }
    }

    /// True if anything blocks the segment from `origin` along `direction`
    /// up to `distance` (a shadow ray).
    pub fn occluded(&self, origin: DVec3, direction: DVec3, distance: f64) -> bool {
        self.occluded_leaving(origin, direction, distance, None)
    }

    /// [`World::occluded`] for a shadow ray leaving the outside of stone
    /// number `leaving`, which cannot block it (see
    /// [`World::intersect_leaving`]).
    pub(crate) fn occluded_leaving(
        &self,
        origin: DVec3,
        direction: DVec3,
        distance: f64,
        leaving: Option<usize>,
    ) -> bool {
        if self.ground_blocks(origin, direction, distance) {
            return true;
        }
        if self.nothing_else_to_test(leaving) {
            return false;
        }
        self.any_stone_blocks(origin, direction, distance, leaving)
    }

    /// Whether the ground plane crosses the ray in (0, `distance`): the
    /// first test of [`World::occluded_leaving`].
    #[inline(always)]
    fn ground_blocks(&self, origin: DVec3, direction: DVec3, distance: f64) -> bool {
        self.ground_ahead(origin, direction)
            .is_some_and(|h| (h - origin.z) / direction.z < distance)
    }

    /// Whether stone number `index`, unless it is the one the ray leaves,
    /// crosses the ray in (0, `distance`). Always inlined: as the closure
    /// of [`World::any_stone_blocks`] that its three searches share it was
    /// compiled as a function of its own, and a 1000-stone tray's shadow
    /// rays called it once per stone box they meet.
    #[inline(always)]
    fn one_stone_blocks(
        &self,
        index: usize,
        origin: DVec3,
        direction: DVec3,
        distance: f64,
        leaving: Option<usize>,
    ) -> bool {
        Some(index) != leaving
            && self.stones[index].crosses(&self.placements[index], origin, direction, 0.0, distance)
    }

    /// The stone part of [`World::occluded_leaving`] through the boxes (and
    /// the BVH): apart, so that the one-stone path stays small.
    #[inline(never)]
    fn any_stone_blocks(
        &self,
        origin: DVec3,
        direction: DVec3,
        distance: f64,
        leaving: Option<usize>,
    ) -> bool {
        let inverse_direction = direction.recip();
        let Some((near, far)) =
            ray_box_span(origin, inverse_direction, distance, self.stones_bounds)
        else {
            return false;
        };
        // Any crossing before `distance` blocks.
        let blocks =
            |index: usize| self.one_stone_blocks(index, origin, direction, distance, leaving);
        match &self.search {
            StoneSearch::Boxes => {
                let single = self.placements.len() == 1;
                self.placements
                    .iter()
                    .enumerate()
                    .any(|(index, placement)| {
                        (single
                            || ray_hits_box(origin, inverse_direction, distance, placement.bounds))
                            && blocks(index)
                    })
            }
            StoneSearch::Grid(grid) => {
                let mut blocked = false;
                grid.walk(
                    origin,
                    direction,
                    inverse_direction,
                    near,
                    far,
                    |stones, _| {
                        blocked = stones.iter().any(|&index| {
                            let index = index as usize;
                            ray_hits_box(
                                origin,
                                inverse_direction,
                                distance,
                                self.placements[index].bounds,
                            ) && blocks(index)
                        });
                        blocked
                    },
                );
                blocked
            }
            StoneSearch::Bvh(bvh) => {
                let ray = Ray::new(to_f32(origin), to_f32(direction), 0.0, f32_up(distance));
                // A blocker is reported inside the ray's range so the
                // traversal stops at once.
                !bvh.ray_traverse_miss(ray, |_, id| {
                    if blocks(bvh.primitive_indices[id] as usize) {
                        0.0
                    } else {
                        f32::INFINITY
                    }
                })
            }
        }
    }
}

impl World {
    /// The nearest stone crossing in (t_min, limit) through the boxes (and
    /// the BVH), skipping stone number `leaving`: apart from
    /// [`World::intersect_leaving`], so that the one-stone path stays small.
    #[inline(never)]
    fn nearest_stone(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        mut limit: f64,
        leaving: Option<usize>,
    ) -> Option<(usize, Hit)> {
        let inverse_direction = direction.recip();
        let (near, far) = ray_box_span(origin, inverse_direction, limit, self.stones_bounds)?;
        let mut best = None;
        match &self.search {
            StoneSearch::Boxes => {
                // With one stone its box is the one just tested.
                let single = self.placements.len() == 1;
                for (index, placement) in self.placements.iter().enumerate() {
                    if single || ray_hits_box(origin, inverse_direction, limit, placement.bounds) {
                        if let Some(hit) =
                            self.one_stone_hit(index, origin, direction, t_min, limit, leaving)
                        {
                            limit = hit.t;
                            best = Some((index, hit));
                        }
                    }
                }
            }
            StoneSearch::Grid(grid) => {
                // A hit before the ray leaves the cell is nearer than any
                // stone of a later cell can be.
                grid.walk(
                    origin,
                    direction,
                    inverse_direction,
                    near,
                    far,
                    |stones, t_exit| {
                        for &index in stones {
                            let index = index as usize;
                            if ray_hits_box(
                                origin,
                                inverse_direction,
                                limit,
                                self.placements[index].bounds,
                            ) {
                                if let Some(hit) = self
                                    .one_stone_hit(index, origin, direction, t_min, limit, leaving)
                                {
                                    limit = hit.t;
                                    best = Some((index, hit));
                                }
                            }
                        }
                        limit <= t_exit
                    },
                );
            }
            StoneSearch::Bvh(bvh) => {
                let ray = Ray::new(to_f32(origin), to_f32(direction), 0.0, f32_up(limit));
                let mut ray_hit = RayHit::none();
                bvh.ray_traverse(ray, &mut ray_hit, |_, id| {
                    let index = bvh.primitive_indices[id] as usize;
                    match self.one_stone_hit(index, origin, direction, t_min, limit, leaving) {
                        Some(hit) => {
                            limit = hit.t;
                            best = Some((index, hit));
                            f32_up(limit)
                        }
                        None => f32::INFINITY,
                    }
                });
            }
        }
        best
    }

    /// Stone number `index`'s nearest crossing in (`t_min`, `limit`),
    /// unless it is the one the ray leaves. Always inlined, as
    /// [`World::one_stone_blocks`]: as a closure that
    /// [`World::nearest_stone`]'s three searches shared it was compiled as
    /// a function of its own, called once per stone box a ray meets.
    #[inline(always)]
    fn one_stone_hit(
        &self,
        index: usize,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        limit: f64,
        leaving: Option<usize>,
    ) -> Option<Hit> {
        if Some(index) == leaving {
            return None;
        }
        self.stones[index].intersect(&self.placements[index], origin, direction, t_min, limit)
    }

    /// True when no stone can be met: there are none, or the only one is
    /// the stone the ray leaves.
    fn nothing_else_to_test(&self, leaving: Option<usize>) -> bool {
        match self.stones.len() {
            0 => true,
            1 => leaving == Some(0),
            _ => false,
        }
    }
}

fn to_f32(v: DVec3) -> Vec3A {
    Vec3A::new(v.x as f32, v.y as f32, v.z as f32)
}

/// An f32 not below `x` (so the BVH never culls a box the f64 ray reaches).
fn f32_up(x: f64) -> f32 {
    if x.is_infinite() || x > f64::from(f32::MAX) {
        return f32::INFINITY;
    }
    let y = x as f32;
    if f64::from(y) < x {
        f32::from_bits(y.to_bits() + 1)
    } else {
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{CabochonParams, Outline};
    use crate::sampling::Rng;

    /// `count` oval stones in a row along x, each turned differently, so
    /// that rays leaving one can meet its neighbours.
    fn row_of_stones(count: usize) -> World {
        let stones = (0..count)
            .map(|i| StoneInstance {
                cabochon: Cabochon::new(CabochonParams {
                    outline: Outline::Oval,
                    length: 2.0,
                    width: 1.4,
                    ..CabochonParams::default()
                })
                .unwrap(),
                rotation: DQuat::from_rotation_z(0.7 * i as f64),
                position: DVec3::new(2.2 * i as f64, 0.0, 0.0),
                gem: 0,
            })
            .collect();
        World::new(stones, Some(0.0))
    }

    #[test]
    fn skipping_the_stone_a_ray_leaves_changes_no_answer() {
        // The skip is only sound because a ray leaving a convex stone
        // outwards cannot meet it again: every answer with the skip must
        // equal the full search, with the direct box tests (3 stones) and
        // with the BVH (7 stones), and many rays must meet a neighbour.
        for count in [1, 3, 7] {
            let world = row_of_stones(count);
            let mut rng = Rng::new(4, count as u64);
            let (mut tested, mut met_other, mut blocked) = (0, 0, 0);
            for _ in 0..3000 {
                let [a, b, c] = rng.next_3();
                let target = DVec3::new(2.2 * (count - 1) as f64 * a, 1.4 * (b - 0.5), 0.5 * c);
                let origin = target + DVec3::new(0.0, -6.0, 4.0);
                let Some(hit) =
                    world.intersect(origin, (target - origin).normalize(), 0.0, f64::INFINITY)
                else {
                    continue;
                };
                let Some(index) = hit.stone_index() else {
                    continue;
                };
                let [u, v, w] = rng.next_3();
                let mut d = DVec3::new(u - 0.5, v - 0.5, w - 0.5).normalize();
                if d.dot(hit.normal) <= 0.0 {
                    d -= 2.0 * d.dot(hit.normal) * hit.normal;
                }
                let start = hit.point + hit.normal * RAY_OFFSET;
                let full = world.intersect(start, d, 0.0, f64::INFINITY);
                let skipping = world.intersect_leaving(start, d, 0.0, f64::INFINITY, Some(index));
                assert_eq!(
                    full, skipping,
                    "{count} stones, leaving stone {index} along {d}"
                );
                if full.is_some_and(|h| h.stone_index().is_some()) {
                    met_other += 1;
                }
                for distance in [0.5, 3.0, f64::INFINITY] {
                    let occluded = world.occluded(start, d, distance);
                    assert_eq!(
                        occluded,
                        world.occluded_leaving(start, d, distance, Some(index))
                    );
                    blocked += usize::from(occluded);
                }
                tested += 1;
            }
            assert!(tested > 1000, "{count} stones: {tested} rays");
            if count > 1 {
                assert!(
                    met_other > 20 && blocked > 20,
                    "{count}: {met_other} {blocked}"
                );
            }
        }
    }

    #[test]
    fn a_tray_searched_through_its_grid_answers_as_through_a_bvh() {
        // bench/scaling's tray: peer stones scaled down side by side, each
        // turned about z, plus a few tilted ones. The grid is only another
        // way to find candidates, so every hit, skip and shadow must equal
        // the BVH's, for camera-like rays from above, rays leaving a stone
        // in any direction (grazing ones walk many cells) and shadow rays.
        let mut rng = Rng::new(21, 0);
        let stones = tray_of_stones(12, &mut rng);
        let grid = World::new(stones.clone(), Some(0.0));
        let bvh = World::build(stones, Some(0.0), false);
        assert!(matches!(grid.search, StoneSearch::Grid(_)));
        assert!(matches!(bvh.search, StoneSearch::Bvh(_)));
        let (mut stone_hits, mut met_other, mut blocked) = (0, 0, 0);
        for _ in 0..20_000 {
            let [a, b, c] = rng.next_3();
            let target = DVec3::new(2.6 * a - 1.3, 2.6 * b - 1.3, 0.05 * c);
            let [u, v, w] = rng.next_3();
            let origin = target + 5.0 * DVec3::new(u - 0.5, v - 0.5, 0.2 + w).normalize();
            let d = (target - origin).normalize();
            let hit = grid.intersect(origin, d, 0.0, f64::INFINITY);
            assert_eq!(hit, bvh.intersect(origin, d, 0.0, f64::INFINITY));
            let Some(hit) = hit else { continue };
            let Some(index) = hit.stone_index() else {
                continue;
            };
            stone_hits += 1;
            let [u, v, w] = rng.next_3();
            let mut out = DVec3::new(u - 0.5, v - 0.5, 0.3 * (w - 0.5)).normalize();
            if out.dot(hit.normal) <= 0.0 {
                out -= 2.0 * out.dot(hit.normal) * hit.normal;
            }
            let start = hit.point + hit.normal * RAY_OFFSET;
            let next = grid.intersect_leaving(start, out, 0.0, f64::INFINITY, Some(index));
            assert_eq!(
                next,
                bvh.intersect_leaving(start, out, 0.0, f64::INFINITY, Some(index))
            );
            met_other += usize::from(next.is_some_and(|h| h.stone_index().is_some()));
            for distance in [0.05, 0.5, f64::INFINITY] {
                let occluded = grid.occluded_leaving(start, out, distance, Some(index));
                assert_eq!(
                    occluded,
                    bvh.occluded_leaving(start, out, distance, Some(index))
                );
                blocked += usize::from(occluded);
            }
        }
        assert!(
            stone_hits > 5000 && met_other > 500 && blocked > 1000,
            "{stone_hits} {met_other} {blocked}"
        );
    }

    /// bench/scaling's tray of `side` × `side` peer stones scaled down side
    /// by side on a 2.4-unit square, each turned about z, every 17th tilted
    /// and some raised a little.
    fn tray_of_stones(side: usize, rng: &mut Rng) -> Vec<StoneInstance> {
        let pitch = 2.4 / side as f64;
        (0..side * side)
            .map(|i| {
                let [a, b, _] = rng.next_3();
                let tilt = if i % 17 == 0 { 0.4 } else { 0.0 };
                stone_of(
                    CabochonParams {
                        length: 2.0 / side as f64,
                        width: 1.4 / side as f64,
                        dome_height: 0.45 / side as f64,
                        ..peer_params()
                    },
                    DQuat::from_rotation_z(0.4 * (a - 0.5)) * DQuat::from_rotation_x(tilt),
                    DVec3::new(
                        -1.2 + (i % side) as f64 * pitch + 0.5 * pitch,
                        -1.2 + (i / side) as f64 * pitch + 0.5 * pitch,
                        0.002 * b,
                    ),
                )
            })
            .collect()
    }

    /// The peer scene's stone's cabochon (bench/peer-scene.ron): an
    /// ellipsoid cap of semi-axes 1 × 0.7 × 0.45 on a flat base.
    fn peer_params() -> CabochonParams {
        CabochonParams {
            outline: Outline::Oval,
            length: 2.0,
            width: 1.4,
            dome_height: 0.45,
            girdle_height: 0.0,
            ..CabochonParams::default()
        }
    }

    /// A stone of cabochon `params`, turned by `rotation`, at `position`.
    fn stone_of(params: CabochonParams, rotation: DQuat, position: DVec3) -> StoneInstance {
        StoneInstance {
            cabochon: Cabochon::new(params).unwrap(),
            rotation,
            position,
            gem: 0,
        }
    }

    #[test]
    fn a_lone_stone_answers_as_with_a_second_stone_far_away() {
        // A lone stone skips its box test; a world with a second stone far
        // away tests both boxes, and must give the same hits, skips and
        // shadows, for an unrotated and a rotated stone, a half ellipsoid
        // and one with a girdle band.
        let rotations = [
            DQuat::IDENTITY,
            DQuat::from_rotation_z(0.7) * DQuat::from_rotation_x(0.3),
        ];
        for (rotation, girdle_height) in [
            (rotations[0], 0.0),
            (rotations[1], 0.0),
            (rotations[0], 0.3),
            (rotations[1], 0.3),
        ] {
            let position = DVec3::new(0.3, -0.2, 0.5);
            let params = CabochonParams {
                girdle_height,
                ..peer_params()
            };
            let stone = stone_of(params, rotation, position);
            let far = StoneInstance {
                position: DVec3::new(1e3, 0.0, 0.5),
                ..stone.clone()
            };
            let lone = World::new(vec![stone.clone()], Some(0.0));
            let pair = World::new(vec![stone, far], Some(0.0));
            let mut rng = Rng::new(9, 1);
            let (mut stone_hits, mut ground_hits, mut blocked) = (0, 0, 0);
            for _ in 0..5000 {
                let [a, b, c] = rng.next_3();
                let target = position + DVec3::new(2.4 * a - 1.2, 1.8 * b - 0.9, 0.6 * c - 0.3);
                let [u, v, w] = rng.next_3();
                let origin = target + 4.0 * DVec3::new(u - 0.5, v - 0.5, w).normalize();
                let d = (target - origin).normalize();
                let hit = lone.intersect(origin, d, 0.0, f64::INFINITY);
                assert_eq!(hit, pair.intersect(origin, d, 0.0, f64::INFINITY));
                for distance in [0.5, 3.0, f64::INFINITY] {
                    let occluded = lone.occluded(origin, d, distance);
                    assert_eq!(occluded, pair.occluded(origin, d, distance));
                    blocked += usize::from(occluded);
                }
                let Some(hit) = hit else { continue };
                if hit.stone_index().is_none() {
                    ground_hits += 1;
                    continue;
                }
                stone_hits += 1;
                if rotation == DQuat::IDENTITY {
                    // Unrotated: no matrices, the object normal is the world
                    // normal, the object point the world point less the
                    // position (to rounding).
                    let Surface::Stone {
                        object_point,
                        object_normal,
                        ..
                    } = hit.surface
                    else {
                        unreachable!()
                    };
                    assert_eq!(hit.normal, object_normal);
                    assert!((object_point + position - hit.point).length() < 1e-12);
                }
                // A path leaving the stone skips it in both worlds alike.
                let [u, v, w] = rng.next_3();
                let mut out = DVec3::new(u - 0.5, v - 0.5, w - 0.5).normalize();
                if out.dot(hit.normal) <= 0.0 {
                    out -= 2.0 * out.dot(hit.normal) * hit.normal;
                }
                let start = hit.point + hit.normal * RAY_OFFSET;
                assert_eq!(
                    lone.intersect_leaving(start, out, 0.0, f64::INFINITY, Some(0)),
                    pair.intersect_leaving(start, out, 0.0, f64::INFINITY, Some(0))
                );
                assert_eq!(
                    lone.occluded_leaving(start, out, 2.0, Some(0)),
                    pair.occluded_leaving(start, out, 2.0, Some(0))
                );
            }
            assert!(
                stone_hits > 1000 && ground_hits > 500 && blocked > 1000,
                "{stone_hits} {ground_hits} {blocked}"
            );
        }
    }

    #[test]
    fn a_turned_stone_s_normal_changes_are_its_exit_normals_turning() {
        // `stone_normal_change` (the manifold solver's curvature) in world
        // space for a turned stone: against the normals of two exits from
        // one inner point aimed 10⁻⁵ apart along each tangent (a turned
        // stone whose world normals did not turn by its rotation would
        // fail), for a half ellipsoid and one with a girdle band.
        let rotation = DQuat::from_rotation_z(0.7) * DQuat::from_rotation_x(0.3);
        let position = DVec3::new(0.3, -0.2, 0.5);
        for girdle_height in [0.0, 0.3] {
            let params = CabochonParams {
                girdle_height,
                ..peer_params()
            };
            let world = World::new(vec![stone_of(params, rotation, position)], None);
            let mut rng = Rng::new(4, 2);
            let (mut checked, mut disagree) = (0, 0);
            for _ in 0..2000 {
                let [a, b, c] = rng.next_3();
                let inner = DVec3::new(1.6 * a - 0.8, 1.1 * b - 0.55, 0.3 * c);
                let origin = position + rotation * inner;
                let [u, v, w] = rng.next_3();
                let direction = (DVec3::new(u, v, w) - 0.5).normalize();
                let Some(hit) = world.stone_exit(0, origin, direction) else {
                    continue;
                };
                let (e1, e2) = hit.normal.any_orthonormal_pair();
                for tangent in [e1, e2] {
                    let aim = (hit.point + tangent * 1e-5 - origin).normalize();
                    let Some(next) = world.stone_exit(0, origin, aim) else {
                        continue;
                    };
                    let dp = next.point - hit.point;
                    let [predicted, _] = world.stone_normal_change(0, hit.point, [dp, DVec3::ZERO]);
                    let turned = next.normal - hit.normal;
                    checked += 1;
                    if (predicted - turned).length() > 1e-3 * (turned.length() + dp.length()) {
                        disagree += 1;
                    }
                }
            }
            assert!(checked > 1000, "{checked} pairs");
            assert!(
                disagree * 100 <= checked,
                "{disagree} of {checked} disagree"
            );
        }
    }
}
