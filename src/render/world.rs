//! The geometry the rays meet: stones (analytic cabochons, placed by a
//! rotation and a translation, all in one obvhs BVH) and an optional ground
//! plane.

use glam::{DQuat, DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::{Boundable, BvhBuildParams};

use crate::geometry::Cabochon;

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
    pub fn world_bounds(&self) -> (DVec3, DVec3) {
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
    /// (t_min, t_max), from outside or inside.
    fn intersect(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<SurfaceHit> {
        let inverse = self.rotation.inverse();
        let o = inverse * (origin - self.position);
        let d = inverse * direction;
        // A rotation keeps lengths, so t is the same in both spaces.
        let hit = self.cabochon.intersect(o, d, t_min, t_max)?;
        Some(SurfaceHit {
            t: hit.t,
            point: origin + direction * hit.t,
            normal: (self.rotation * hit.normal).normalize(),
            surface: Surface::Stone {
                index: 0,
                object_point: hit.point,
                object_normal: hit.normal,
            },
        })
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

/// Stones in a BVH plus the ground.
pub struct World {
    stones: Vec<StoneInstance>,
    bvh: Option<CwBvh>,
    ground_height: Option<f64>,
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
pub const RAY_OFFSET: f64 = 1e-5;

impl World {
    /// Builds the BVH over the stones (one box each).
    pub fn new(stones: Vec<StoneInstance>, ground_height: Option<f64>) -> Self {
        let bvh = (!stones.is_empty()).then(|| {
            let boxes: Vec<StoneBox> = stones
                .iter()
                .map(|s| {
                    let (lo, hi) = s.world_bounds();
                    // Pad by an f32 ulp-scale margin so the f32 box test
                    // never clips the f64 surface.
                    let pad = 1e-4 * (hi - lo).max_element().max(1.0);
                    StoneBox(Aabb {
                        min: to_f32(lo - DVec3::splat(pad)),
                        max: to_f32(hi + DVec3::splat(pad)),
                    })
                })
                .collect();
            build_cwbvh(
                &boxes,
                BvhBuildParams::fast_build(),
                &mut Default::default(),
            )
        });
        Self {
            stones,
            bvh,
            ground_height,
        }
    }

    /// The stones, in scene order.
    pub fn stones(&self) -> &[StoneInstance] {
        &self.stones
    }

    /// The ground plane's height, if there is one.
    pub fn ground_height(&self) -> Option<f64> {
        self.ground_height
    }

    /// The nearest surface along a unit-direction ray in (`t_min`, `t_max`).
    pub fn intersect(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<SurfaceHit> {
        let mut best: Option<SurfaceHit> = None;
        let mut limit = t_max;
        if let Some(bvh) = &self.bvh {
            let ray = Ray::new(to_f32(origin), to_f32(direction), 0.0, f32_up(t_max));
            let mut ray_hit = RayHit::none();
            bvh.ray_traverse(ray, &mut ray_hit, |_, id| {
                let index = bvh.primitive_indices[id] as usize;
                match self.stones[index].intersect(origin, direction, t_min, limit) {
                    Some(mut hit) => {
                        if let Surface::Stone { index: i, .. } = &mut hit.surface {
                            *i = index;
                        }
                        limit = hit.t;
                        best = Some(hit);
                        f32_up(hit.t)
                    }
                    None => f32::INFINITY,
                }
            });
        }
        if let Some(h) = self.ground_height {
            if direction.z < 0.0 && origin.z > h {
                let t = (h - origin.z) / direction.z;
                if t > t_min && t < limit {
                    best = Some(SurfaceHit {
                        t,
                        point: DVec3::new(
                            origin.x + direction.x * t,
                            origin.y + direction.y * t,
                            h,
                        ),
                        normal: DVec3::Z,
                        surface: Surface::Ground,
                    });
                }
            }
        }
        best
    }

    /// True if anything blocks the segment from `origin` along `direction`
    /// up to `distance` (a shadow ray).
    pub fn occluded(&self, origin: DVec3, direction: DVec3, distance: f64) -> bool {
        if let Some(h) = self.ground_height {
            if direction.z < 0.0 && origin.z > h && (h - origin.z) / direction.z < distance {
                return true;
            }
        }
        let Some(bvh) = &self.bvh else {
            return false;
        };
        let ray = Ray::new(to_f32(origin), to_f32(direction), 0.0, f32_up(distance));
        let missed = bvh.ray_traverse_miss(ray, |_, id| {
            let index = bvh.primitive_indices[id] as usize;
            // Any crossing before `distance` blocks; report it inside the
            // ray's range so the traversal stops at once.
            match self.stones[index].intersect(origin, direction, 0.0, distance) {
                Some(_) => 0.0,
                None => f32::INFINITY,
            }
        });
        !missed
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
