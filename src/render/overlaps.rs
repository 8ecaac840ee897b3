//! Where a scene's stones break what the integrator assumes of them:
//! every stone convex and closed, holding nothing but its own body, and at
//! most resting on the ground. A stone sunk into the ground, or two stones
//! that cross, still render, but a path inside a translucent body then
//! meets surfaces it does not expect (another stone, or the ground, inside
//! it). A camera or a light inside a stone sees or lights nothing else,
//! nor does one inside a sphere light or below the ground. `lapidary
//! render` and `validate` warn of each.

use std::fmt;

use glam::DVec3;

use crate::render::world::World;
use crate::scene::{LightSpec, Scene};

/// Directions from a stone's axis to its surface at which it is probed
/// (a Fibonacci sphere): each crossing deeper than [`DEPTH_TOLERANCE_MM`]
/// shows on a few of them at least.
const PROBES: usize = 512;

/// Crossings shallower than this (mm) are touching stones (a tray packed
/// edge to edge) or rounding, and are not reported.
const DEPTH_TOLERANCE_MM: f64 = 1e-3;

/// A placement that the renderer does not model exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlacementProblem {
    /// Stone number `stone` (from 0, in scene order) reaches `depth_mm`
    /// below the ground's plane.
    Sinks {
        /// The stone, from 0.
        stone: usize,
        /// How far below the ground its lowest probed point lies, mm.
        depth_mm: f64,
    },
    /// Stones `first` < `second` (from 0) cross: `point` (world, mm) on
    /// one's surface lies inside the other.
    Overlap {
        /// The first stone, from 0.
        first: usize,
        /// The second stone, from 0.
        second: usize,
        /// A point of the one inside the other, mm.
        point: DVec3,
    },
    /// The camera lies inside stone `stone` (from 0): the picture is
    /// that stone's inside.
    CameraInside {
        /// The stone, from 0.
        stone: usize,
    },
    /// Light `light` (from 0, in scene order) lies inside stone `stone`.
    LightInside {
        /// The light, from 0.
        light: usize,
        /// The stone, from 0.
        stone: usize,
    },
    /// The camera lies inside sphere light `light` (from 0), which emits
    /// outwards only: the picture is black.
    CameraInsideLight {
        /// The light, from 0.
        light: usize,
    },
    /// Stone `stone` lies inside sphere light `light` (from 0): the light
    /// hides it and nothing lights it.
    StoneInsideLight {
        /// The stone, from 0.
        stone: usize,
        /// The light, from 0.
        light: usize,
    },
    /// Light `inner` lies wholly inside sphere light `outer` (both from
    /// 0), which emits outwards only: the sphere hides it from everything
    /// outside the sphere.
    LightInsideLight {
        /// The hidden light, from 0.
        inner: usize,
        /// The sphere light around it, from 0.
        outer: usize,
    },
    /// The camera lies below the ground's plane, at height `z_mm` (the
    /// ground at `ground_mm`).
    CameraBelowGround {
        /// The camera's height, mm.
        z_mm: f64,
        /// The ground's height, mm.
        ground_mm: f64,
    },
    /// Light `light` (from 0) lies wholly below the ground's plane (a sun:
    /// below the horizon): it lights nothing above the ground.
    LightBelowGround {
        /// The light, from 0.
        light: usize,
        /// Whether the light is a sun (its direction at or below the
        /// horizon).
        sun: bool,
    },
}

impl fmt::Display for PlacementProblem {
    /// Stones are numbered from 1, as a user counts them in the scene file.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Sinks { stone, depth_mm } => write!(
                f,
                "stone {} sinks {depth_mm:.3} mm into the ground (raise it by that much to \
                 rest it there); a translucent stone renders as if the ground were not inside it",
                stone + 1
            ),
            Self::Overlap {
                first,
                second,
                point,
            } => write!(
                f,
                "stones {} and {} overlap (near ({:.3}, {:.3}, {:.3}) mm); translucent bodies \
                 render wrongly where they cross (move them apart)",
                first + 1,
                second + 1,
                point.x,
                point.y,
                point.z
            ),
            Self::CameraInside { stone } => write!(
                f,
                "the camera is inside stone {}: the picture shows nothing else (move it out)",
                stone + 1
            ),
            Self::LightInside { light, stone } => write!(
                f,
                "light {} is inside stone {}: it lights nothing (move it out)",
                light + 1,
                stone + 1
            ),
            Self::CameraInsideLight { light } => write!(
                f,
                "the camera is inside light {}, a sphere that emits outwards only: the picture \
                 is black (make the sphere smaller than its distance to the camera)",
                light + 1
            ),
            Self::StoneInsideLight { stone, light } => write!(
                f,
                "stone {} is inside light {}, a sphere that emits outwards only: the light \
                 hides it and nothing lights it (make the sphere smaller or move it)",
                stone + 1,
                light + 1
            ),
            Self::LightInsideLight { inner, outer } => write!(
                f,
                "light {} is inside light {}, a sphere that emits outwards only: the sphere \
                 hides it from everything outside it (make the sphere smaller or move the light \
                 out)",
                inner + 1,
                outer + 1
            ),
            Self::CameraBelowGround { z_mm, ground_mm } => write!(
                f,
                "the camera is below the ground (z = {z_mm:.3} mm, the ground at {ground_mm:.3} \
                 mm): the ground is not seen from below (raise the camera)"
            ),
            Self::LightBelowGround { light, sun: false } => write!(
                f,
                "light {} is below the ground: the ground hides it from everything above \
                 (raise it)",
                light + 1
            ),
            Self::LightBelowGround { light, sun: true } => write!(
                f,
                "light {}, a sun, is at or below the horizon: the ground hides it from \
                 everything above (give its direction a positive z)",
                light + 1
            ),
        }
    }
}

/// What keeps the camera or the lights of `scene` from the stones of
/// `world` (the scene's stones, placed): the camera inside a stone, inside
/// a sphere light or below the ground; a light (all but a sun) that fits
/// inside a stone or wholly inside a sphere light; a stone inside a sphere
/// light; a light wholly below the ground (a sun below the horizon).
pub fn viewpoint_problems(world: &World, scene: &Scene) -> Vec<PlacementProblem> {
    // The stone `point` lies at least `reach` deep inside, if any.
    let inside = |point: DVec3, reach: f64| {
        (0..world.stones().len()).find(|&stone| depth_inside(world, stone, point) > reach)
    };
    let camera = scene.camera.position;
    let ground = world.ground_height();
    let mut problems: Vec<PlacementProblem> = inside(camera, 0.0)
        .map(|stone| PlacementProblem::CameraInside { stone })
        .into_iter()
        .collect();
    if let Some(ground_mm) = ground.filter(|&ground| camera.z < ground) {
        problems.push(PlacementProblem::CameraBelowGround {
            z_mm: camera.z,
            ground_mm,
        });
    }
    for (light, spec) in scene.lights.iter().enumerate() {
        // The light's middle and how far it reaches from it.
        let (place, reach) = match *spec {
            LightSpec::Point { position, .. } => (position, 0.0),
            LightSpec::Sphere { centre, radius, .. } => (centre, radius),
            LightSpec::Rect {
                centre,
                width,
                height,
                ..
            } => (centre, 0.5 * width.hypot(height)),
            LightSpec::Sun { direction, .. } => {
                if ground.is_some() && direction.z <= 0.0 {
                    problems.push(PlacementProblem::LightBelowGround { light, sun: true });
                }
                continue;
            }
        };
        if let Some(stone) = inside(place, reach) {
            problems.push(PlacementProblem::LightInside { light, stone });
        }
        if let LightSpec::Sphere { centre, radius, .. } = *spec {
            if camera.distance(centre) < radius {
                problems.push(PlacementProblem::CameraInsideLight { light });
            }
            for (stone, instance) in world.stones().iter().enumerate() {
                let (lo, hi) = instance.world_bounds();
                if (0.5 * (lo + hi) - centre).length() < radius {
                    problems.push(PlacementProblem::StoneInsideLight { stone, light });
                }
            }
        }
        let around = scene.lights.iter().enumerate().find(|&(outer, other)| {
            matches!(*other, LightSpec::Sphere { centre, radius, .. }
                if outer != light && place.distance(centre) + reach < radius)
        });
        if let Some((outer, _)) = around {
            problems.push(PlacementProblem::LightInsideLight {
                inner: light,
                outer,
            });
        }
        if ground.is_some_and(|ground| place.z + reach < ground) {
            problems.push(PlacementProblem::LightBelowGround { light, sun: false });
        }
    }
    problems
}

/// Every stone of `world` that sinks into its ground, then every pair of
/// stones that overlap, each pair once.
pub fn placement_problems(world: &World) -> Vec<PlacementProblem> {
    let surfaces: Vec<Vec<DVec3>> = (0..world.stones().len())
        .map(|stone| surface_points(world, stone))
        .collect();
    let mut problems = Vec::new();
    if let Some(ground) = world.ground_height() {
        for (stone, points) in surfaces.iter().enumerate() {
            let lowest = points.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
            if lowest < ground - DEPTH_TOLERANCE_MM {
                problems.push(PlacementProblem::Sinks {
                    stone,
                    depth_mm: ground - lowest,
                });
            }
        }
    }
    let boxes: Vec<(DVec3, DVec3)> = world.stones().iter().map(|s| s.world_bounds()).collect();
    for first in 0..boxes.len() {
        for second in first + 1..boxes.len() {
            let (a, b) = (boxes[first], boxes[second]);
            if a.0.cmpgt(b.1).any() || b.0.cmpgt(a.1).any() {
                continue;
            }
            let inside = |points: &[DVec3], other: usize| {
                points
                    .iter()
                    .copied()
                    .find(|&p| depth_inside(world, other, p) > DEPTH_TOLERANCE_MM)
            };
            if let Some(point) =
                inside(&surfaces[first], second).or_else(|| inside(&surfaces[second], first))
            {
                problems.push(PlacementProblem::Overlap {
                    first,
                    second,
                    point,
                });
            }
        }
    }
    problems
}

/// Points of stone `stone`'s surface, world space: where rays from the
/// middle of its axis (inside every cabochon: base to top) leave it; then
/// that middle itself, which lies inside another stone in the same place
/// (whose surface points lie on its surface, at no depth).
fn surface_points(world: &World, stone: usize) -> Vec<DVec3> {
    let instance = &world.stones()[stone];
    let (lo, hi) = instance.cabochon.bounds();
    let middle = DVec3::new(0.0, 0.0, 0.5 * (lo.z + hi.z));
    let middle = instance.position + instance.rotation * middle;
    (0..PROBES)
        .filter_map(|k| {
            let direction = fibonacci_direction(k, PROBES);
            world
                .stone_exit(stone, middle, direction)
                .map(|hit| hit.point)
        })
        .chain([middle])
        .collect()
}

/// How deep `point` (world) lies inside stone `stone`: minus the stone's
/// signed distance estimate ([`crate::geometry::Cabochon::implicit`]),
/// negative outside.
fn depth_inside(world: &World, stone: usize, point: DVec3) -> f64 {
    let instance = &world.stones()[stone];
    let object_point = instance.rotation.inverse() * (point - instance.position);
    -instance.cabochon.implicit(object_point)
}

/// Direction `k` of `n` spread evenly over the sphere (a Fibonacci lattice).
fn fibonacci_direction(k: usize, n: usize) -> DVec3 {
    let golden_turn = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let z = 1.0 - (2.0 * k as f64 + 1.0) / n as f64;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = golden_turn * k as f64;
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Cabochon, CabochonParams};
    use crate::render::world::StoneInstance;
    use glam::DQuat;

    fn stone_at(position: DVec3) -> StoneInstance {
        StoneInstance {
            cabochon: Cabochon::new(CabochonParams::default()).unwrap(),
            rotation: DQuat::IDENTITY,
            position,
            gem: 0,
        }
    }

    #[test]
    fn stones_resting_apart_or_touching_are_fine_and_sunk_or_crossing_ones_are_named() {
        let stone = stone_at(DVec3::ZERO);
        let (lo, hi) = stone.cabochon.bounds();
        let width = hi.x - lo.x;
        // Resting on the ground, and a second one just touching it.
        let resting = World::new(
            vec![stone.clone(), stone_at(DVec3::new(width, 0.0, 0.0))],
            Some(lo.z),
        );
        assert_eq!(placement_problems(&resting), vec![]);
        // Sunk by 0.5 mm, and a third stone crossing the first by a
        // quarter of its width.
        let placed = World::new(
            vec![
                stone.clone(),
                stone_at(DVec3::new(width, 0.0, 0.0)),
                stone_at(DVec3::new(-0.75 * width, 0.0, 0.0)),
            ],
            Some(lo.z + 0.5),
        );
        let problems = placement_problems(&placed);
        assert_eq!(problems.len(), 4, "{problems:?}");
        for (k, problem) in problems[..3].iter().enumerate() {
            match *problem {
                PlacementProblem::Sinks { stone, depth_mm } => {
                    assert_eq!(stone, k);
                    assert!((depth_mm - 0.5).abs() < 1e-6, "{depth_mm}");
                }
                other => panic!("{other:?}"),
            }
        }
        match problems[3] {
            PlacementProblem::Overlap {
                first: 0,
                second: 2,
                point,
            } => assert!(
                point.x < -0.25 * width && point.x > -0.5 * width - 1e-9,
                "{point}"
            ),
            other => panic!("{other:?}"),
        }
        assert_eq!(
            problems[3]
                .to_string()
                .split(';')
                .next()
                .unwrap()
                .split(" (")
                .next(),
            Some("stones 1 and 3 overlap")
        );
        // Two stones in one place, and one turned about its axis in the
        // other's place: every surface point of either lies on the other.
        let turned_in_place = StoneInstance {
            rotation: DQuat::from_rotation_z(0.5),
            ..stone.clone()
        };
        for twin in [stone.clone(), turned_in_place] {
            let twins = World::new(vec![stone.clone(), twin], None);
            assert!(matches!(
                placement_problems(&twins)[..],
                [PlacementProblem::Overlap {
                    first: 0,
                    second: 1,
                    ..
                }]
            ));
        }
        // A turned stone whose lowest corner dips below the ground.
        let turned = StoneInstance {
            rotation: DQuat::from_rotation_x(0.3),
            ..stone
        };
        let tilted = World::new(vec![turned], Some(lo.z));
        assert!(matches!(
            placement_problems(&tilted)[..],
            [PlacementProblem::Sinks { stone: 0, depth_mm }] if depth_mm > 0.1
        ));
    }
}
