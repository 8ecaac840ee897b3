//! Lights placed in the scene: point, sphere, rectangular soft box, sun.
//!
//! Each light can be sampled from a shading point (next-event estimation)
//! and, except the point light, also be found by a BRDF-sampled ray, so the
//! integrator can weight the two strategies by multiple importance sampling.
//! All pdfs are with respect to solid angle at the shading point.

use std::f64::consts::PI;

use glam::DVec3;

use crate::brdf::Rgb;
use crate::render::environment::luminance;
use crate::scene::LightSpec;

/// A light, in world space: the scene's light description, which already
/// holds everything sampling needs (unit normals, frames, the sun's
/// direction). This module gives it its behaviour.
pub type Light = LightSpec;

/// A direction towards a light chosen by [`Light::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub direction: DVec3,
    /// Distance to the sampled point (infinite for the sun).
    pub distance: f64,
    /// Radiance arriving along `direction` (for a point light, the
    /// irradiance-producing intensity / d², with `is_delta`).
    pub radiance: Rgb,
    /// Solid-angle pdf of the direction (1 for a point light).
    pub pdf: f64,
    /// True for a point light, which BRDF sampling can never hit.
    pub is_delta: bool,
}

impl LightSpec {
    /// A rough luminance of the irradiance the light gives a surface at
    /// `point` facing it, unoccluded: I/d² for a point, L·π r²/d² for a
    /// sphere, L·A·cosθ/d² for a soft box (0 behind it), the sun's E. A
    /// vertex weighs emitters by it when it chooses among more than it
    /// samples; distances are kept from falling below the light's own size.
    pub(crate) fn irradiance_estimate(&self, point: DVec3) -> f64 {
        match *self {
            LightSpec::Point {
                position,
                intensity,
            } => luminance(intensity) / position.distance_squared(point).max(1e-6),
            LightSpec::Sphere {
                centre,
                radius,
                radiance,
            } => {
                let r2 = radius * radius;
                luminance(radiance) * PI * r2 / centre.distance_squared(point).max(r2)
            }
            LightSpec::Rect {
                centre,
                normal,
                width,
                height,
                radiance,
                ..
            } => {
                let to_point = point - centre;
                let d2 = to_point.length_squared();
                let area = width * height;
                let cos = (to_point.dot(normal) / d2.sqrt()).max(0.0);
                luminance(radiance) * area * cos / d2.max(area)
            }
            LightSpec::Sun { irradiance, .. } => luminance(irradiance),
        }
    }

    /// A sun of `irradiance` (perpendicular to its direction) and angular
    /// diameter `angular_diameter_deg`, towards `direction`.
    pub fn sun(direction: DVec3, angular_diameter_deg: f64, irradiance: Rgb) -> Self {
        LightSpec::Sun {
            direction: direction.normalize(),
            angular_diameter_deg,
            irradiance,
        }
    }

    /// Choose a direction towards the light seen from `point`.
    ///
    /// Inlined, with the sphere light (the one the benchmark scenes use)
    /// handled here and the other kinds behind a call: a call returned the
    /// sample through memory after a dispatch on the kind, which (with the
    /// same overhead in [`Light::hit`]) was a large part of what the lights
    /// cost.
    #[inline(always)]
    pub fn sample(&self, point: DVec3, u: [f64; 2]) -> Option<LightSample> {
        match *self {
            Light::Sphere {
                centre,
                radius,
                radiance,
            } => sample_sphere(centre, radius, radiance, point, u),
            _ => self.sample_other(point, u),
        }
    }

    /// [`Light::sample`] for every kind but the sphere.
    #[inline(never)]
    fn sample_other(&self, point: DVec3, u: [f64; 2]) -> Option<LightSample> {
        match *self {
            Light::Point {
                position,
                intensity,
            } => {
                let to = position - point;
                let d2 = to.length_squared();
                if d2 <= 0.0 {
                    return None;
                }
                let distance = d2.sqrt();
                Some(LightSample {
                    direction: to / distance,
                    distance,
                    radiance: intensity / d2,
                    pdf: 1.0,
                    is_delta: true,
                })
            }
            Light::Sphere {
                centre,
                radius,
                radiance,
            } => sample_sphere(centre, radius, radiance, point, u),
            Light::Rect {
                centre,
                normal,
                u_axis,
                v_axis,
                width,
                height,
                radiance,
            } => {
                let on_light =
                    centre + u_axis * ((u[0] - 0.5) * width) + v_axis * ((u[1] - 0.5) * height);
                let to = on_light - point;
                let d2 = to.length_squared();
                let distance = d2.sqrt();
                let direction = to / distance;
                let cos_light = -direction.dot(normal);
                if cos_light <= 0.0 || distance <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    direction,
                    distance,
                    radiance,
                    // Area to solid angle: dω = cosθ_light dA / d².
                    pdf: d2 / (cos_light * width * height),
                    is_delta: false,
                })
            }
            Light::Sun {
                direction,
                angular_diameter_deg,
                irradiance,
            } => Some(LightSample {
                direction: sample_cone(direction, sun_cos_radius(angular_diameter_deg), u).0,
                distance: f64::INFINITY,
                radiance: sun_radiance(angular_diameter_deg, irradiance),
                pdf: cone_pdf(sun_cos_radius(angular_diameter_deg)),
                is_delta: false,
            }),
        }
    }

    /// Where a ray from `origin` along unit `direction` first meets the
    /// light's emitting surface, if before `t_max`: (distance, radiance).
    /// The sun is met only by rays that escape (`t_max` infinite).
    ///
    /// Inlined, with the sphere light tested here and the other kinds
    /// behind a call: every traced ray is tested against every light and
    /// almost every test misses at the discriminant, a few instructions
    /// next to those of a call and a dispatch on the kind.
    #[inline(always)]
    pub fn hit(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Option<(f64, Rgb)> {
        match *self {
            Light::Sphere { .. } => self.sphere_hit(origin, direction, t_max),
            _ => self.hit_other(origin, direction, t_max),
        }
    }

    /// [`Light::hit`] of a sphere: its emission where the ray enters it
    /// before `t_max` (None for the other kinds).
    #[inline(always)]
    fn sphere_hit(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Option<(f64, Rgb)> {
        let Light::Sphere {
            centre,
            radius,
            radiance,
        } = *self
        else {
            return None;
        };
        sphere_entry(origin, direction, centre, radius)
            .filter(|t| *t < t_max)
            .map(|t| (t, radiance))
    }

    /// Whether [`Light::hit`] finds the light's surface before `t_max`
    /// (a sphere, or a soft box's front; never a point light or the sun):
    /// the same test, inline and without the emission, for the shadow
    /// rays of other emitters' samples that the light may block.
    #[inline(always)]
    pub(crate) fn blocks(&self, origin: DVec3, direction: DVec3, t_max: f64) -> bool {
        match *self {
            Light::Sphere { .. } => self.sphere_hit(origin, direction, t_max).is_some(),
            Light::Rect { .. } => self.rect_crossing(origin, direction, t_max).is_some(),
            Light::Point { .. } | Light::Sun { .. } => false,
        }
    }

    /// Where the ray from `origin` along unit `direction` crosses a soft
    /// box's front before `t_max` (None for its back, a miss, and every
    /// other kind of light): [`Light::hit`]'s and [`Light::blocks`]' test.
    #[inline(always)]
    fn rect_crossing(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Option<f64> {
        let Light::Rect {
            centre,
            normal,
            u_axis,
            v_axis,
            width,
            height,
            ..
        } = *self
        else {
            return None;
        };
        let denom = direction.dot(normal);
        if denom >= 0.0 {
            return None; // the back of the box, or parallel
        }
        let t = (centre - origin).dot(normal) / denom;
        if t <= 0.0 || t >= t_max {
            return None;
        }
        let local = origin + direction * t - centre;
        let inside =
            local.dot(u_axis).abs() <= 0.5 * width && local.dot(v_axis).abs() <= 0.5 * height;
        inside.then_some(t)
    }

    /// [`Light::hit`] for every kind but the sphere.
    #[inline(never)]
    fn hit_other(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Option<(f64, Rgb)> {
        match *self {
            Light::Point { .. } => None,
            Light::Sphere { .. } => self.sphere_hit(origin, direction, t_max),
            Light::Rect { radiance, .. } => self
                .rect_crossing(origin, direction, t_max)
                .map(|t| (t, radiance)),
            Light::Sun {
                direction: sun,
                angular_diameter_deg,
                irradiance,
            } => (t_max.is_infinite()
                && direction.dot(sun) >= sun_cos_radius(angular_diameter_deg))
            .then(|| {
                (
                    f64::INFINITY,
                    sun_radiance(angular_diameter_deg, irradiance),
                )
            }),
        }
    }

    /// The outward unit normal of the light's emitting surface at `point`
    /// on it: the sphere's radial direction, the soft box's face; None for
    /// a point light and the sun, which have no surface.
    pub(crate) fn surface_normal(&self, point: DVec3) -> Option<DVec3> {
        match *self {
            Light::Sphere { centre, .. } => (point - centre).try_normalize(),
            Light::Rect { normal, .. } => Some(normal),
            Light::Point { .. } | Light::Sun { .. } => None,
        }
    }

    /// Solid-angle pdf with which [`Light::sample`] from `point` would pick
    /// `direction`, given that the direction meets the light at distance `t`.
    pub fn pdf(&self, point: DVec3, direction: DVec3, t: f64) -> f64 {
        match *self {
            Light::Point { .. } => 0.0,
            Light::Sphere { centre, radius, .. } => {
                let d2 = (centre - point).length_squared();
                if d2 <= radius * radius {
                    return 0.0;
                }
                cone_pdf((1.0 - radius * radius / d2).max(0.0).sqrt())
            }
            Light::Rect {
                normal,
                width,
                height,
                ..
            } => {
                let cos_light = -direction.dot(normal);
                if cos_light <= 0.0 {
                    0.0
                } else {
                    t * t / (cos_light * width * height)
                }
            }
            Light::Sun {
                angular_diameter_deg,
                ..
            } => cone_pdf(sun_cos_radius(angular_diameter_deg)),
        }
    }
}

/// [`Light::sample`] for a sphere light of `radius` around `centre`: a
/// direction uniform in the cone the sphere subtends from `point` (Shirley
/// et al. 1996; pbrt-v4 §6.2.4), pdf 1/(2π(1 − cosθ_max)).
#[inline(always)]
fn sample_sphere(
    centre: DVec3,
    radius: f64,
    radiance: Rgb,
    point: DVec3,
    u: [f64; 2],
) -> Option<LightSample> {
    let to = centre - point;
    let d2 = to.length_squared();
    let r2 = radius * radius;
    if d2 <= r2 {
        return None;
    }
    let d = d2.sqrt();
    let axis = to / d;
    let cos_max = (1.0 - r2 / d2).max(0.0).sqrt();
    let (direction, cos_theta) = sample_cone(axis, cos_max, u);
    // The sampled ray meets the sphere at the nearer root of
    // t² − 2t·d·cosθ + d² − r² = 0 (the law of cosines in the
    // triangle point–centre–hit), t = d·cosθ − √(r² − d²·sin²θ):
    // no second ray–sphere test. Inside the cone d·sinθ ≤ r up
    // to rounding, which the clamp absorbs (the tangent point).
    let sin2_theta = 1.0 - cos_theta * cos_theta;
    let distance = d * cos_theta - (r2 - d2 * sin2_theta).max(0.0).sqrt();
    Some(LightSample {
        direction,
        distance,
        radiance,
        pdf: cone_pdf(cos_max),
        is_delta: false,
    })
}

/// cos of the sun disc's angular radius.
fn sun_cos_radius(angular_diameter_deg: f64) -> f64 {
    (angular_diameter_deg * 0.5).to_radians().cos()
}

/// Radiance of a sun disc delivering `irradiance` at normal incidence: a
/// disc of angular radius α and radiance L gives E = L·π·sin²α.
fn sun_radiance(angular_diameter_deg: f64, irradiance: Rgb) -> Rgb {
    let sin_alpha = (angular_diameter_deg * 0.5).to_radians().sin();
    irradiance / (PI * sin_alpha * sin_alpha)
}

/// Uniform density over a cone of directions with cos half-angle `cos_max`.
#[inline(always)]
pub(crate) fn cone_pdf(cos_max: f64) -> f64 {
    1.0 / (2.0 * PI * (1.0 - cos_max).max(1e-300))
}

/// A direction uniformly distributed in the cone around unit `axis`, and
/// the cosine of its angle to the axis. Inlined: passing the sample and
/// the direction through memory is a tenth of its cost.
///
/// The direction is p·t + q·b + c·n for n = `axis`, (p, q, c) = (sinθ cosφ,
/// sinθ sinφ, cosθ) and (t, b) the orthonormal pair of Duff et al.,
/// "Building an Orthonormal Basis, Revisited" (JCGT 2017, listing 3; glam's
/// `any_orthonormal_pair`): with s = sign(n.z), a = −1/(s + n.z),
/// t = (1 + s·x²·a, s·x·y·a, −s·x) and b = (x·y·a, s + y²·a, −y). Collecting
/// the terms in x and y, with w = s·x·p + y·q and m = a·w + c,
///
///   direction = (p + x·m, s·q + y·m, z·c − w),
///
/// the same vector without building t and b: 10 multiplications instead of
/// 20, equal to the sum over the basis to rounding.
/// Unit by construction (sin² + cos² = 1 and an orthonormal basis, to
/// within 10⁻¹³): no normalisation, whose division and square root are a
/// tenth of a light sample's time.
#[inline(always)]
pub(crate) fn sample_cone(axis: DVec3, cos_max: f64, u: [f64; 2]) -> (DVec3, f64) {
    let cos_theta = 1.0 - u[0] * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sin_phi, cos_phi) = crate::sampling::sin_cos_turns(u[1]);
    let (p, q) = (sin_theta * cos_phi, sin_theta * sin_phi);
    // The sign of n.z by `copysign`, which equals `signum` for every number
    // but NaN and skips its NaN test; |s + z| ≥ 1, so a never overflows.
    let s = 1.0f64.copysign(axis.z);
    let a = -1.0 / (s + axis.z);
    let w = s * axis.x * p + axis.y * q;
    let m = a * w + cos_theta;
    let direction = DVec3::new(p + axis.x * m, s * q + axis.y * m, axis.z * cos_theta - w);
    (direction, cos_theta)
}

/// Nearest positive distance at which the ray enters the sphere.
#[inline(always)]
fn sphere_entry(origin: DVec3, direction: DVec3, centre: DVec3, radius: f64) -> Option<f64> {
    let oc = origin - centre;
    let b = oc.dot(direction);
    let c = oc.length_squared() - radius * radius;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let near = -b - root;
    let far = -b + root;
    if near > 0.0 {
        Some(near)
    } else if far > 0.0 && c > 0.0 {
        Some(far)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn cone_samples_are_unit_and_inside_the_cone_without_normalising() {
        let mut rng = Rng::new(2, 3);
        for axis in [DVec3::Z, -DVec3::Z, DVec3::new(0.3, -0.9, 0.1).normalize()] {
            for cos_max in [0.999_999, 0.9, 0.0, -1.0] {
                for _ in 0..2000 {
                    let (d, cos_theta) =
                        sample_cone(axis, cos_max, [rng.next_f64(), rng.next_f64()]);
                    assert!((cos_theta - d.dot(axis)).abs() < 1e-13);
                    assert!((d.length() - 1.0).abs() < 1e-13, "|d| = {}", d.length());
                    assert!(d.dot(axis) >= cos_max - 1e-12);
                }
            }
        }
    }

    #[test]
    fn the_collected_cone_direction_is_the_sample_in_glams_orthonormal_basis() {
        // sample_cone collects the terms of p·t + q·b + c·n; build the same
        // sum from glam's any_orthonormal_pair (Duff et al. 2017) and the
        // spherical coordinates written out with libm's sin and cos.
        let mut rng = Rng::new(4, 4);
        let random = (0..5000).map(|_| {
            let v = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0;
            v.normalize()
        });
        let axes: Vec<DVec3> = [DVec3::Z, -DVec3::Z, DVec3::X, DVec3::new(0.6, 0.8, -0.0)]
            .into_iter()
            .chain(random)
            .collect();
        let mut rng = Rng::new(5, 5);
        for n in axes {
            let (t, b) = n.any_orthonormal_pair();
            for cos_max in [0.999, 0.5, -1.0] {
                let u = [rng.next_f64(), rng.next_f64()];
                let cos_theta = 1.0 - u[0] * (1.0 - cos_max);
                let sin_theta = (1.0 - cos_theta * cos_theta).sqrt();
                let (sin_phi, cos_phi) = (2.0 * PI * u[1]).sin_cos();
                let expected =
                    t * (sin_theta * cos_phi) + b * (sin_theta * sin_phi) + n * cos_theta;
                let (direction, c) = sample_cone(n, cos_max, u);
                assert_eq!(c, cos_theta);
                assert!(
                    (direction - expected).length() < 1e-13,
                    "n = {n}: {direction} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn a_sun_delivers_its_irradiance_to_a_facing_plane() {
        // E = ∫ L cosθ dω over the disc, estimated from the light's own samples.
        let sun = Light::sun(DVec3::Z, 10.0, Rgb::splat(3.0));
        let mut rng = Rng::new(1, 0);
        let n = 20_000;
        let mut e = 0.0;
        for _ in 0..n {
            let s = sun
                .sample(DVec3::ZERO, [rng.next_f64(), rng.next_f64()])
                .unwrap();
            e += s.radiance.x * s.direction.z / s.pdf;
        }
        e /= n as f64;
        // cosθ varies by < 0.4 % over a 10° disc.
        assert!((e - 3.0).abs() < 0.02, "E = {e}");
    }

    #[test]
    fn sampled_directions_hit_the_light_with_the_sampled_pdf() {
        let lights = [
            Light::Sphere {
                centre: DVec3::new(1.0, 2.0, 5.0),
                radius: 1.5,
                radiance: Rgb::ONE,
            },
            Light::Rect {
                centre: DVec3::new(0.0, 0.0, 4.0),
                normal: -DVec3::Z,
                u_axis: DVec3::X,
                v_axis: DVec3::Y,
                width: 3.0,
                height: 2.0,
                radiance: Rgb::ONE,
            },
        ];
        let p = DVec3::new(0.3, -0.2, 0.0);
        let mut rng = Rng::new(2, 0);
        for light in &lights {
            for _ in 0..200 {
                let s = light.sample(p, [rng.next_f64(), rng.next_f64()]).unwrap();
                let (t, _) = light
                    .hit(p, s.direction, f64::INFINITY)
                    .expect("sample misses its light");
                assert!((t - s.distance).abs() < 1e-9 * t.max(1.0));
                let pdf = light.pdf(p, s.direction, t);
                assert!((pdf - s.pdf).abs() < 1e-9 * pdf, "{pdf} vs {}", s.pdf);
            }
        }
    }

    #[test]
    fn the_sphere_sample_distance_is_where_the_ray_enters_the_sphere() {
        // The distance from the cone geometry against a fresh ray–sphere
        // test, from near (d = 1.01 r) to far (d = 10⁴ r) lights.
        let mut rng = Rng::new(8, 1);
        for (radius, distance) in [(1.0, 1.01), (1.0, 1.5), (0.3, 4.0), (0.01, 100.0)] {
            for _ in 0..500 {
                let axis = crate::sampling::cosine_hemisphere(rng.next_f64(), rng.next_f64());
                let point = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
                let centre = point + axis * distance;
                let light = Light::Sphere {
                    centre,
                    radius,
                    radiance: Rgb::ONE,
                };
                let s = light
                    .sample(point, [rng.next_f64(), rng.next_f64()])
                    .unwrap();
                let t = sphere_entry(point, s.direction, centre, radius).unwrap();
                assert!((t - s.distance).abs() < 1e-9 * t, "{t} vs {}", s.distance);
                let on_sphere = (point + s.direction * s.distance - centre).length();
                assert!((on_sphere - radius).abs() < 1e-9 * distance);
            }
        }
    }

    #[test]
    fn the_inlined_sphere_hit_is_the_first_root_of_the_ray_sphere_quadratic() {
        // `hit` tests spheres inline and every other kind behind a call:
        // check the inline test against |o + t·d − c|² = r² solved the
        // textbook way (a = 1, b = 2 oc·d, c = |oc|² − r², t = (−b ∓ √(b² −
        // 4c))/2): a ray from outside meets the light at the smaller root
        // if it is positive; a ray from inside sees the inside of the
        // surface, which emits outwards only (as `sample` gives nothing to
        // a point inside), so never. Rays that miss, graze, start inside,
        // point away and stop short at t_max.
        let centre = DVec3::new(0.5, -1.0, 2.0);
        let radius = 0.75;
        let light = Light::Sphere {
            centre,
            radius,
            radiance: Rgb::new(1.0, 2.0, 3.0),
        };
        let mut rng = Rng::new(11, 2);
        let (mut hits, mut misses) = (0, 0);
        for i in 0..20_000 {
            let origin = centre
                + (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5)
                    * if i % 4 == 0 { 1.0 } else { 6.0 };
            let aim = centre + (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) - 0.5);
            let direction = if i % 3 == 0 {
                (origin - aim).normalize() // mostly away from the sphere
            } else {
                (aim - origin).normalize()
            };
            let t_max = if i % 5 == 0 { 2.0 } else { f64::INFINITY };
            let oc = origin - centre;
            let (b, c) = (
                2.0 * oc.dot(direction),
                oc.length_squared() - radius * radius,
            );
            let disc = b * b - 4.0 * c;
            let expected = (disc >= 0.0)
                .then(|| {
                    let near = (-b - disc.sqrt()) / 2.0;
                    (c > 0.0 && near > 0.0).then_some(near)
                })
                .flatten()
                .filter(|t| *t < t_max);
            match (light.hit(origin, direction, t_max), expected) {
                (Some((t, emitted)), Some(want)) => {
                    hits += 1;
                    assert!((t - want).abs() < 1e-9 * want.max(1.0), "{t} vs {want}");
                    assert_eq!(emitted, Rgb::new(1.0, 2.0, 3.0));
                }
                (None, None) => misses += 1,
                (got, want) => panic!("ray {i}: hit {got:?}, expected {want:?}"),
            }
        }
        assert!(hits > 2000 && misses > 2000, "{hits} hits, {misses} misses");
        // The other kinds go through the out-of-line path.
        let point = Light::Point {
            position: DVec3::ZERO,
            intensity: Rgb::ONE,
        };
        assert_eq!(point.hit(DVec3::Z, -DVec3::Z, f64::INFINITY), None);
        let sun = Light::sun(DVec3::Z, 1.0, Rgb::ONE);
        assert!(sun.hit(DVec3::ZERO, DVec3::Z, f64::INFINITY).is_some());
        assert_eq!(sun.hit(DVec3::ZERO, DVec3::Z, 5.0), None);
    }

    #[test]
    fn a_rect_light_subtends_its_analytic_solid_angle() {
        // Solid angle of a square of side 2 at distance 1 on its axis:
        // Ω = 4·asin(sin a · sin b) with tan a = tan b = 1 → 4·asin(1/2) = 2π/3.
        let rect = Light::Rect {
            centre: DVec3::Z,
            normal: -DVec3::Z,
            u_axis: DVec3::X,
            v_axis: DVec3::Y,
            width: 2.0,
            height: 2.0,
            radiance: Rgb::ONE,
        };
        let mut rng = Rng::new(3, 0);
        let n = 100_000;
        let omega: f64 = (0..n)
            .map(|_| {
                1.0 / rect
                    .sample(DVec3::ZERO, [rng.next_f64(), rng.next_f64()])
                    .unwrap()
                    .pdf
            })
            .sum::<f64>()
            / n as f64;
        assert!((omega - 2.0 * PI / 3.0).abs() < 0.01, "Ω = {omega}");
    }
}
