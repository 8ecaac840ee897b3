//! Meeting the flakes inside a translucent body: one by one, or as a
//! medium of many.
//!
//! The walk of [`crate::render::inclusions`] finds the very flake a ray
//! crosses. Camera rays and their specular continuations walk (the flakes
//! a pixel shows are the recipe's own), and so does the path leaving the
//! vertex where the pixel's footprint ends (the first glossy, diffuse,
//! flake or scattering event): what lights the flake a pixel shows and
//! which of its neighbours shade it are visible per pixel. Past that,
//! where flakes are shaded by footprint (`render::footprint`), a path has
//! spread over more flakes than any footprint shows one by one and meets
//! the populations that have an aggregate lobe as what they are on
//! average: a medium of flakes (the microflake view, Jakob et al. 2010)
//! whose mean crossings along ω are the number density n times the mean
//! area a flake projects along ω,
//!
//! ```text
//! n · f(x) · A⊥(ω)
//! ```
//!
//! with f(x) ∈ [0, 1] the share of cells a density modulation keeps there
//! (1 without one), its collisions shaded by the population's lobe
//! ([`crate::render::flake_lobe`]). The distance to the next flake is then
//! drawn in constant time, where the walk visits every cell on the way:
//! delta tracking under a density modulation (Woodcock et al. 1965), ratio
//! tracking or exp(−σL) for a connection (Novák, Selle & Jarosz 2014). Two
//! corrections stand for the grid's one flake a cell (see
//! [`extinction_per_mm`] and [`OwnCell`]); the grid's statistics also
//! depend on a path's direction against its axes (a flake kept wholly in
//! its cell leaves lanes along the faces), which the medium averages over.
//! A ray crosses the grid's flakes at exactly the medium's mean rate in
//! every direction (this module's tests).

use glam::DVec3;

use crate::brdf::LayeredBrdf;
use crate::recipe::gem::{Body, Inclusions};
use crate::render::flake_lobe::FlakeLobe;
use crate::render::render_scene::RenderScene;

/// The most tentative collisions one free flight or transmittance draws (a
/// bound on work for absurd inputs; a stone's chord at the densities
/// allowed is far fewer).
const MAX_TENTATIVE_COLLISIONS: u32 = 1 << 16;

/// Where a path leaves a flake whose population is met as a medium: its
/// place in the flake's own cell, which holds no other flake of that
/// population. A jittered grid's path from a flake crosses no flake of
/// the population until it leaves that cell (others reach in only from
/// the neighbours), so it sees fewer of them than from a random point;
/// the medium keeps that stretch clear. The place is drawn uniformly in a
/// cell, as the flake's centre is.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OwnCell {
    /// The population of the flake left.
    pub population: usize,
    /// The place in the cell, in cell sides, each in [0, 1).
    place: DVec3,
}

impl OwnCell {
    /// The own cell of a flake of `population`, its place from `u`.
    pub(crate) fn new(population: usize, u: [f64; 3]) -> Self {
        Self {
            population,
            place: DVec3::from_array(u),
        }
    }

    /// The distance (mm) along the unit object-space `direction` to the
    /// cell's face, for cells of side `cell_mm`.
    fn exit_mm(&self, direction: DVec3, cell_mm: f64) -> f64 {
        let ahead = DVec3::select(
            direction.cmpgt(DVec3::ZERO),
            DVec3::ONE - self.place,
            self.place,
        );
        (ahead / direction.abs()).min_element() * cell_mm
    }

    /// The clear stretch along `direction` for population `population`.
    fn clear_mm(own: Option<Self>, population: usize, direction: DVec3, cell_mm: f64) -> f64 {
        own.filter(|own| own.population == population)
            .map_or(0.0, |own| own.exit_mm(direction, cell_mm))
    }
}

/// How the path from a vertex meets the flakes of its body: one by one
/// where the pixel's footprint ended at that vertex (what lights the flake
/// the pixel shows, and what shades it, are its own neighbours), as a
/// medium past it.
#[derive(Clone, Copy, Debug)]
pub(crate) enum FlakeView {
    /// Every flake by the walk.
    Walked,
    /// Populations with an aggregate lobe as a medium, clear of the flake
    /// left within its own cell, if any.
    Medium(Option<OwnCell>),
}

impl FlakeView {
    /// As a medium (clear of `own` cell) where `as_medium`, else walked.
    pub(crate) fn new(as_medium: bool, own: Option<OwnCell>) -> Self {
        if as_medium {
            Self::Medium(own)
        } else {
            Self::Walked
        }
    }
}

/// A flake a path meets inside a body.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MetFlake<'a> {
    /// Distance along the ray, mm.
    pub t: f64,
    /// The flake's unit normal in world space (either side); None for a
    /// flake of the medium of many, which its population's lobe shades.
    pub normal: Option<DVec3>,
    /// The flake's material.
    pub brdf: &'a LayeredBrdf,
    /// Index of the flake's population in the body's inclusions.
    pub population: usize,
}

/// How much faster than their mean crossings the flakes of a grid stop a
/// path, per flake crossed per cell side (see [`extinction_per_mm`]).
const HARD_CORE: f64 = 1.0 / 3.0;

/// The flakes a path along the unit `direction` crosses per mm on average
/// where the population's density modulation keeps every cell: n A⊥(ω).
fn crossings_per_mm(population: &Inclusions, lobe: &FlakeLobe, direction: DVec3) -> f64 {
    lobe.projected_area_along_mm2(direction) / population.cell_mm.powi(3)
}

/// The rate at which a path meets its first flake, for `crossings` mean
/// crossings per mm where a share `kept` of the cells keeps its flake.
/// Each cell holds one flake, met at most once, so the chance of meeting
/// none over a stretch is Π(1 − pᵢ) over the flakes nearby, below the
/// exp(−Σpᵢ) of independent flakes: −ln(1 − p) ≈ p + p²/2, with p about
/// the crossings over one cell's chord, raises the rate by about
/// [`HARD_CORE`] × crossings × cell side (fitted against a grid whose
/// flakes may reach into the neighbouring cells, where the chance of
/// crossing none is the same in every direction: within 0.004 of the walk
/// there; the built-in grid's average over directions is a little lower
/// still, bench/results/2026-12-03-flakes-as-a-medium.md).
fn extinction_per_mm(crossings: f64, cell_mm: f64, kept: f64) -> f64 {
    let mean = crossings * kept;
    mean * (1.0 + HARD_CORE * mean * cell_mm)
}

/// Delta tracking's distance to the first flake of `population`, as a
/// medium, along `origin + t·direction` for 0 < t < `t_max` (object space,
/// mm, unit direction), with numbers from `next_1d`; None when the path
/// crosses none.
fn free_flight(
    population: &Inclusions,
    lobe: &FlakeLobe,
    origin: DVec3,
    direction: DVec3,
    t_max: f64,
    mut next_1d: impl FnMut() -> f64,
) -> Option<f64> {
    let crossings = crossings_per_mm(population, lobe, direction);
    let rate = extinction_per_mm(crossings, population.cell_mm, 1.0);
    if !(rate > 0.0 && t_max > 0.0) {
        return None;
    }
    let mut t = 0.0;
    for _ in 0..MAX_TENTATIVE_COLLISIONS {
        t -= (1.0 - next_1d()).ln() / rate;
        if t >= t_max {
            return None;
        }
        if population.density_modulation.is_none()
            || next_1d() * rate
                < extinction_per_mm(
                    crossings,
                    population.cell_mm,
                    population.kept_fraction(origin + direction * t),
                )
        {
            return Some(t);
        }
    }
    None
}

/// The chance that a path along `origin + t·direction`, 0 < t < `length`
/// (object space, mm, unit direction), crosses no flake of `population`
/// as a medium: exp(−n A⊥ L), or ratio tracking's estimate of exp(−∫σ dt)
/// from `next_1d` where a density modulation varies σ.
fn transmittance(
    population: &Inclusions,
    lobe: &FlakeLobe,
    origin: DVec3,
    direction: DVec3,
    length: f64,
    mut next_1d: impl FnMut() -> f64,
) -> f64 {
    let crossings = crossings_per_mm(population, lobe, direction);
    let rate = extinction_per_mm(crossings, population.cell_mm, 1.0);
    if !(rate > 0.0 && length > 0.0) {
        return 1.0;
    }
    if population.density_modulation.is_none() {
        return (-rate * length).exp();
    }
    let (mut weight, mut t) = (1.0, 0.0);
    for _ in 0..MAX_TENTATIVE_COLLISIONS {
        t -= (1.0 - next_1d()).ln() / rate;
        if t >= length {
            return weight;
        }
        let kept = population.kept_fraction(origin + direction * t);
        weight *= 1.0 - extinction_per_mm(crossings, population.cell_mm, kept) / rate;
        if weight <= 0.0 {
            return 0.0;
        }
    }
    0.0
}

impl RenderScene {
    /// The first flake inside stone `stone` along the world ray for 0 < t
    /// < `t_max`, as `view` says, with numbers from `next_1d`.
    pub(crate) fn meet_flake(
        &self,
        stone: usize,
        origin: DVec3,
        direction: DVec3,
        t_max: f64,
        view: FlakeView,
        mut next_1d: impl FnMut() -> f64,
    ) -> Option<MetFlake<'_>> {
        let instance = &self.world.stones()[stone];
        let gem = &self.gems[instance.gem];
        let Body::Translucent { inclusions, .. } = &gem.body else {
            return None;
        };
        if inclusions.is_empty() {
            return None;
        }
        let (o, d) = self.world.object_ray(stone, origin, direction);
        let mut nearest: Option<(f64, Option<DVec3>, usize)> = None;
        for (index, population) in inclusions.iter().enumerate() {
            let limit = nearest.map_or(t_max, |(t, _, _)| t);
            let lobe = self.flake_lobes.get(instance.gem, index);
            let met = match (lobe, view) {
                (Some(lobe), FlakeView::Medium(own)) => {
                    let clear = OwnCell::clear_mm(own, index, d, population.cell_mm).min(limit);
                    free_flight(
                        population,
                        lobe,
                        o + d * clear,
                        d,
                        limit - clear,
                        &mut next_1d,
                    )
                    .map(|t| (clear + t, None, index))
                }
                _ => population
                    .nearest(o, d, limit)
                    .map(|hit| (hit.t, Some(instance.rotation * hit.normal), index)),
            };
            nearest = met.or(nearest);
        }
        nearest.map(|(t, normal, population)| MetFlake {
            t,
            normal,
            brdf: &gem.brdfs[inclusions[population].material as usize],
            population,
        })
    }

    /// The chance that a connection's segment from `origin` along the unit
    /// world `direction` for `length` inside stone `stone` crosses no
    /// flake, as `view` says: 0 or 1 by the walk, the medium's
    /// transmittance for a population met as one, with numbers from
    /// `next_1d`.
    pub(crate) fn flake_transmittance(
        &self,
        stone: usize,
        origin: DVec3,
        direction: DVec3,
        length: f64,
        view: FlakeView,
        mut next_1d: impl FnMut() -> f64,
    ) -> f64 {
        let instance = &self.world.stones()[stone];
        let Body::Translucent { inclusions, .. } = &self.gems[instance.gem].body else {
            return 1.0;
        };
        if inclusions.is_empty() {
            return 1.0;
        }
        let (o, d) = self.world.object_ray(stone, origin, direction);
        let mut product = 1.0;
        for (index, population) in inclusions.iter().enumerate() {
            product *= match (self.flake_lobes.get(instance.gem, index), view) {
                (Some(lobe), FlakeView::Medium(own)) => {
                    let clear = OwnCell::clear_mm(own, index, d, population.cell_mm).min(length);
                    transmittance(
                        population,
                        lobe,
                        o + d * clear,
                        d,
                        length - clear,
                        &mut next_1d,
                    )
                }
                _ => f64::from(u8::from(population.nearest(o, d, length).is_none())),
            };
            if product <= 0.0 {
                return 0.0;
            }
        }
        product
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recipe::gem::{parse_gem, FlakeShape};
    use crate::recipe::library::builtin_gem_source;
    use crate::sampling::Rng;
    use crate::texture::noise_fns::{PerlinNoise, PerlinSource};
    use crate::texture::pattern::SwitchFunction;

    /// Goldstone's first population (its copper) with the outline, the
    /// cell and the orientation given, and its lobe.
    fn population(shape: FlakeShape, aligned: Option<(DVec3, f64)>) -> (Inclusions, FlakeLobe) {
        let gem = parse_gem("goldstone", builtin_gem_source("goldstone").unwrap()).unwrap();
        let Body::Translucent { inclusions, .. } = &gem.body else {
            panic!("goldstone is translucent");
        };
        let population = Inclusions {
            shape,
            radius_mm: 0.08,
            size_spread: 0.4,
            cell_mm: 0.25,
            aligned,
            ..inclusions[0].clone()
        };
        let lobe = FlakeLobe::new(&population, &gem.brdfs[population.material as usize]).unwrap();
        (population, lobe)
    }

    /// The unit direction of two uniform numbers, uniform over the sphere.
    fn sphere(u: f64, v: f64) -> DVec3 {
        let z = 1.0 - 2.0 * u;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (sin_phi, cos_phi) = crate::sampling::sin_cos_turns(v);
        DVec3::new(r * cos_phi, r * sin_phi, z)
    }

    /// Crossings of the walk per mm along the unit `direction`, over 20-mm
    /// paths from `rays` random origins (restarting just past each
    /// crossing), and the medium's expected crossings over the same paths
    /// (its majorant times the midpoint rule's ∫f dt).
    fn walked_and_expected(
        population: &Inclusions,
        lobe: &FlakeLobe,
        direction: DVec3,
        rays: u32,
    ) -> (f64, f64) {
        let (length, steps) = (20.0, 400);
        let rate = crossings_per_mm(population, lobe, direction);
        let mut rng = Rng::new(5, 6);
        let (mut crossings, mut expected) = (0u32, 0.0);
        for _ in 0..rays {
            let [a, b, c] = rng.next_3();
            let start = DVec3::new(a, b, c) * 10.0;
            let (mut origin, mut left) = (start, length);
            while let Some(hit) = population.nearest(origin, direction, left) {
                crossings += 1;
                origin += direction * (hit.t + 1e-9);
                left -= hit.t + 1e-9;
            }
            let step = length / f64::from(steps);
            expected += (0..steps)
                .map(|k| {
                    let point = start + direction * (step * (f64::from(k) + 0.5));
                    rate * population.kept_fraction(point) * step
                })
                .sum::<f64>();
        }
        (f64::from(crossings), expected)
    }

    #[test]
    fn from_a_flake_the_medium_stops_a_path_as_often_as_the_walk() {
        // Paths leaving a flake found by the walk, each in a random
        // direction: the chance of crossing no other flake over an optical
        // depth of 0.7 (mean crossings), by the walk against the medium's
        // transmittance clear of the flake's own cell. 40 000 paths: within
        // four binomial standard deviations (0.01), and the medium without
        // the clear stretch off by more than that.
        let axis = DVec3::new(0.3, 0.4, 0.866).normalize();
        let cases = [
            ("isotropic", population(FlakeShape::Disc, None)),
            (
                "5° cone",
                population(FlakeShape::Hexagon, Some((axis, 5f64.to_radians().cos()))),
            ),
        ];
        for (name, (population, lobe)) in cases {
            let mut rng = Rng::new(3, 4);
            let (mut unblocked, mut medium, mut unclear, mut paths) = (0u32, 0.0, 0.0, 0u32);
            while paths < 40_000 {
                let [a, b, c] = rng.next_3();
                let origin = DVec3::new(a, b, c) * 10.0;
                let [u, v, _] = rng.next_3();
                let into = sphere(u, v);
                let Some(hit) = population.nearest(origin, into, 50.0) else {
                    continue;
                };
                let [u, v, _] = rng.next_3();
                let out = sphere(u, v);
                let length = 0.7 / crossings_per_mm(&population, &lobe, out);
                let start = origin + into * hit.t + out * 1e-9;
                unblocked += u32::from(population.nearest(start, out, length).is_none());
                let own = Some(OwnCell::new(0, rng.next_3()));
                let clear = OwnCell::clear_mm(own, 0, out, population.cell_mm).min(length);
                medium += transmittance(&population, &lobe, start, out, length - clear, || 0.5);
                unclear += transmittance(&population, &lobe, start, out, length, || 0.5);
                paths += 1;
            }
            let n = f64::from(paths);
            let (walked, medium, unclear) = (f64::from(unblocked) / n, medium / n, unclear / n);
            assert!(
                (walked - medium).abs() < 0.01 && (walked - unclear).abs() > 0.01,
                "{name}: the walk {walked:.4}, the medium {medium:.4} ({unclear:.4} without its clear stretch)"
            );
        }
    }

    #[test]
    fn the_medium_crosses_as_many_flakes_as_the_walk_in_every_direction() {
        // The walk's crossings of jittered flakes against the medium's mean
        // crossings n·f(x)·A⊥(ω): isotropic hexagons, platelets within 5°
        // and 30° of a tilted axis seen along it, at 45° and edge-on
        // (A⊥ from the cone's own table), and isotropic discs thinned by
        // Perlin patches (f read along the path, the walk's f at each
        // flake's centre). Within four standard deviations of the count,
        // plus 2 % where f's sampling points differ.
        let axis = DVec3::new(0.3, 0.4, 0.866).normalize();
        let (tangent, _) = axis.any_orthonormal_pair();
        let oblique = (axis + tangent).normalize();
        let mut thinned = population(FlakeShape::Disc, None);
        thinned.0.density_modulation = Some(SwitchFunction::Perlin(PerlinNoise {
            source: PerlinSource::new(5),
            frequency: 3.0,
        }));
        let cases = [
            (
                "isotropic",
                population(FlakeShape::Hexagon, None),
                oblique,
                0.0,
            ),
            (
                "5° cone, along",
                population(FlakeShape::Disc, Some((axis, 5f64.to_radians().cos()))),
                axis,
                0.0,
            ),
            (
                "5° cone, 45°",
                population(FlakeShape::Disc, Some((axis, 5f64.to_radians().cos()))),
                oblique,
                0.0,
            ),
            (
                "5° cone, edge-on",
                population(FlakeShape::Disc, Some((axis, 5f64.to_radians().cos()))),
                tangent,
                0.0,
            ),
            (
                "30° cone, edge-on",
                population(FlakeShape::Triangle, Some((axis, 30f64.to_radians().cos()))),
                tangent,
                0.0,
            ),
            ("thinned", thinned, oblique, 0.02),
        ];
        for (name, (population, lobe), direction, slack) in cases {
            let (walked, expected) = walked_and_expected(&population, &lobe, direction, 600);
            let tolerance = 4.0 * expected.sqrt() + slack * expected;
            assert!(
                expected > 400.0 && (walked - expected).abs() < tolerance,
                "{name}: walked {walked}, the medium {expected:.1} ± {tolerance:.1}"
            );
        }
    }

    #[test]
    fn free_flights_and_transmittance_agree_with_the_extinction() {
        // Along one path through Perlin patches: ratio tracking's mean
        // estimate is exp(−∫σ dt) by the midpoint rule (σ the extinction
        // of the kept share of cells there), and delta tracking
        // stops before the end as often as 1 minus that; without patches the
        // transmittance is exp(−σL) exactly and free flights are
        // exponential. Means of 40 000 draws, within four standard errors.
        let (mut thinned, lobe) = population(FlakeShape::Disc, None);
        thinned.density_modulation = Some(SwitchFunction::Perlin(PerlinNoise {
            source: PerlinSource::new(11),
            frequency: 3.0,
        }));
        let (plain, _) = population(FlakeShape::Disc, None);
        let origin = DVec3::new(0.4, -1.0, 2.0);
        let direction = DVec3::new(0.6, 0.0, 0.8);
        let length = 1.5;
        let crossings = crossings_per_mm(&thinned, &lobe, direction);
        let rate = extinction_per_mm(crossings, thinned.cell_mm, 1.0);
        let steps = 10_000;
        let optical: f64 = (0..steps)
            .map(|k| {
                let t = length * (f64::from(k) + 0.5) / f64::from(steps);
                let kept = thinned.kept_fraction(origin + direction * t);
                extinction_per_mm(crossings, thinned.cell_mm, kept) * length / f64::from(steps)
            })
            .sum();
        let mut rng = Rng::new(9, 9);
        let draws = 40_000;
        for (population, exact) in [
            (&thinned, (-optical).exp()),
            (&plain, (-rate * length).exp()),
        ] {
            let mut next = || rng.next_f64();
            let (mut sum, mut stopped) = (0.0, 0u32);
            for _ in 0..draws {
                sum += transmittance(population, &lobe, origin, direction, length, &mut next);
                stopped += u32::from(
                    free_flight(population, &lobe, origin, direction, length, &mut next).is_some(),
                );
            }
            let mean = sum / f64::from(draws);
            let stop_rate = f64::from(stopped) / f64::from(draws);
            let error = 4.0 * (exact * (1.0 - exact) / f64::from(draws)).sqrt();
            assert!(
                (mean - exact).abs() < error,
                "transmittance {mean} against {exact}"
            );
            assert!(
                (1.0 - stop_rate - exact).abs() < error,
                "no stop {stop_rate} against {exact}"
            );
        }
        assert_eq!(
            transmittance(&plain, &lobe, origin, direction, length, || 0.5),
            (-rate * length).exp()
        );
    }
}
