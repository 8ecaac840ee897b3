//! Manifold next-event estimation through one smooth refraction (Hanika,
//! Droske, Fascione 2015, "Manifold Next Event Estimation"; Zeltner,
//! Georgiev, Jakob 2020): from a point inside a translucent body, find the
//! direction whose ray leaves the body by refraction (Snell, eq. 3.2) and
//! passes through a given point of a light (or leaves along a given
//! direction, for the sun), and the Jacobian that turns the light's area
//! (or solid angle) into solid angle at the inner point.
//!
//! The unknown is the direction at the inner point, two numbers in a plane
//! tangent to the unit sphere. The forward map (intersect the body from
//! inside, refract, carry on to the target) is traced exactly; Newton's
//! method solves it with its Jacobian by finite differences, which also
//! gives the generalised geometry term at the solution. The body's surface
//! can be any closed surface that answers "where does this ray from inside
//! leave, and what is the outward normal there" ([`Boundary`]).

use glam::DVec3;

use crate::brdf::fresnel;

/// Where a ray from inside a body leaves it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Exit {
    /// Distance along the (unit) ray.
    pub t: f64,
    /// The point on the surface.
    pub point: DVec3,
    /// The outward unit normal there.
    pub normal: DVec3,
}

/// A closed body whose surface rays from inside can be traced to.
pub(crate) trait Boundary {
    /// Where the ray from `origin` (inside) along unit `direction` leaves.
    fn exit(&self, origin: DVec3, direction: DVec3) -> Option<Exit>;
}

/// What the refracted ray must reach.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Target {
    /// A point outside the body (on an area or point light).
    Point(DVec3),
    /// A unit direction the ray must leave along (a distant light).
    Direction(DVec3),
}

/// A path from an inner point through one refraction to a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Connection {
    /// Unit direction at the inner point, towards the exit.
    pub inside_direction: DVec3,
    /// Where the path leaves the body, and the outward normal there.
    pub exit: Exit,
    /// Unit direction of the refracted ray, away from the body.
    pub outside_direction: DVec3,
    /// Distance from the exit to the target point (infinite for a
    /// direction target).
    pub outside_length: f64,
    /// Fresnel transmittance 1 − F of the exit (eq. 3.1).
    pub transmittance: f64,
    /// |dω_inside / dA⊥| at the target point (area perpendicular to the
    /// refracted ray), or |dω_inside / dω_outside| for a direction target:
    /// the generalised geometry term that turns the light's measure into
    /// solid angle at the inner point. Without refraction it is 1/d² (or 1).
    pub inside_solid_angle_per_target_measure: f64,
}

/// Newton steps before a solve gives up.
const MAX_STEPS: usize = 12;
/// Halvings of a Newton step that does not reduce the residual.
const MAX_HALVINGS: usize = 4;
/// Finite-difference step in the direction's tangent coordinates
/// (radians).
const JACOBIAN_STEP: f64 = 1e-6;
/// Length of the Snell residual (n·ωᵢ − ωₒ) × N at which a solve has
/// converged: about the angle, in radians, by which the refracted ray
/// misses the target.
const TOLERANCE: f64 = 1e-9;
/// Unit directions closer than this agree (a solution's refracted ray and
/// the direction to its target).
const SAME_DIRECTION: f64 = 1e-7;

/// The refracted ray of the ray from `origin` (inside a body of index
/// `ior`) along unit `direction`: the exit and the direction in air, or
/// None when the ray misses the surface or is totally reflected.
fn shoot(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    direction: DVec3,
) -> Option<(Exit, DVec3)> {
    let exit = boundary.exit(origin, direction)?;
    let cos_i = direction.dot(exit.normal);
    if cos_i <= 0.0 {
        return None;
    }
    // Snell (eq. 3.2) from index `ior` into air: sinθₜ = ior·sinθᵢ.
    let sin2_t = (1.0 - cos_i * cos_i) * ior * ior;
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let out = (direction * ior - exit.normal * (ior * cos_i - cos_t)).normalize();
    Some((exit, out))
}

/// Tangent coordinates around a unit direction: (a, b) ↦ normalize(ω₀ +
/// a·t + b·s), whose Jacobian at (0, 0) is the identity onto solid angle.
#[derive(Clone, Copy)]
struct Chart {
    centre: DVec3,
    t: DVec3,
    s: DVec3,
}

impl Chart {
    fn around(centre: DVec3) -> Self {
        let (t, s) = centre.any_orthonormal_pair();
        Self { centre, t, s }
    }
    fn direction(&self, a: f64, b: f64) -> DVec3 {
        (self.centre + self.t * a + self.s * b).normalize()
    }
}

/// The 2-D residual of a traced ray against the target, measured in a
/// plane across the target (point) or across the target direction.
#[derive(Clone, Copy)]
struct Residual {
    target: Target,
    /// Normal of the measuring plane (unit).
    across: DVec3,
    /// An orthonormal basis of the measuring plane.
    axes: (DVec3, DVec3),
}

impl Residual {
    fn new(target: Target, across: DVec3) -> Self {
        Self {
            target,
            across,
            axes: across.any_orthonormal_pair(),
        }
    }

    fn of(&self, exit: &Exit, out: DVec3) -> Option<[f64; 2]> {
        let offset = match self.target {
            Target::Point(y) => {
                // Where the refracted ray crosses the plane through y.
                let speed = out.dot(self.across);
                if speed <= 1e-9 {
                    return None;
                }
                exit.point + out * ((y - exit.point).dot(self.across) / speed) - y
            }
            Target::Direction(d) => {
                if out.dot(d) <= 0.0 {
                    return None;
                }
                out - d
            }
        };
        Some([offset.dot(self.axes.0), offset.dot(self.axes.1)])
    }
}

/// Finds the refraction path from `origin` (inside a body of index `ior`)
/// to `target` by Gauss–Newton from the straight line, or None when it
/// does not converge to a physical refraction (no solution near the
/// start, a grazing exit, or a stencil across a crease of the surface).
///
/// The unknown is the direction at the origin; the residual is Snell's
/// law at the exit point that direction reaches, written as the
/// generalised half vector n·ωᵢ − ωₒ being parallel to the normal
/// (ωᵢ along the ray inside, ωₒ from the exit towards the target): the
/// cross product (n·ωᵢ − ωₒ) × N. Unlike the refracted ray's miss
/// distance it is defined at every exit point, total internal reflection
/// included, so a start whose straight line cannot leave the body still
/// converges.
pub(crate) fn connect(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    target: Target,
) -> Option<Connection> {
    let start = match target {
        Target::Point(y) => (y - origin).normalize(),
        Target::Direction(d) => d,
    };
    if !start.is_finite() {
        return None;
    }
    let start = backward_refraction(boundary, ior, origin, start, target).unwrap_or(start);
    let chart = Chart::around(start);
    let evaluate = |a: f64, b: f64| -> Option<DVec3> {
        let direction = chart.direction(a, b);
        let exit = boundary.exit(origin, direction)?;
        let out = match target {
            Target::Point(y) => (y - exit.point).normalize(),
            Target::Direction(d) => d,
        };
        Some((direction * ior - out).cross(exit.normal))
    };
    // Gauss–Newton on the normal equations of the 3 × 2 system J·δ = −r,
    // J by finite differences at the start and then by Broyden's rank-one
    // updates (one trace per step instead of three).
    let (mut a, mut b) = (0.0, 0.0);
    let mut r = evaluate(a, b)?;
    let h = JACOBIAN_STEP;
    let mut ja = (evaluate(h, 0.0)? - r) / h;
    let mut jb = (evaluate(0.0, h)? - r) / h;
    for _ in 0..MAX_STEPS {
        if r.length() <= TOLERANCE {
            break;
        }
        let (aa, ab, bb) = (ja.dot(ja), ja.dot(jb), jb.dot(jb));
        let (ra, rb) = (ja.dot(r), jb.dot(r));
        let det = aa * bb - ab * ab;
        if det.abs() <= f64::MIN_POSITIVE || !det.is_finite() {
            return None;
        }
        let da = -(bb * ra - ab * rb) / det;
        let db = -(aa * rb - ab * ra) / det;
        // Damped: halve the step until the residual falls.
        let mut step = 1.0;
        let mut accepted = None;
        for _ in 0..MAX_HALVINGS {
            let (sa, sb) = (step * da, step * db);
            if let Some(nr) = evaluate(a + sa, b + sb) {
                if nr.length() < r.length() {
                    accepted = Some((sa, sb, nr));
                    break;
                }
            }
            step *= 0.5;
        }
        let (sa, sb, nr) = accepted?;
        // Broyden: J += (Δr − J·Δp)·Δpᵀ / |Δp|².
        let miss = (nr - r - ja * sa - jb * sb) / (sa * sa + sb * sb);
        ja += miss * sa;
        jb += miss * sb;
        (a, b, r) = (a + sa, b + sb, nr);
    }
    if r.length() > TOLERANCE {
        return None;
    }
    // A physical refraction: leaving the body, on towards the target (the
    // cross product also vanishes for the half vector's other sign).
    let inside_direction = chart.direction(a, b);
    let (exit, out) = shoot(boundary, ior, origin, inside_direction)?;
    let outside_length = match target {
        Target::Point(y) => {
            let to = y - exit.point;
            let length = to.length();
            if (to / length - out).length() > SAME_DIRECTION {
                return None;
            }
            length
        }
        Target::Direction(d) => {
            if (d - out).length() > SAME_DIRECTION {
                return None;
            }
            f64::INFINITY
        }
    };
    let inside_solid_angle_per_target_measure = 1.0
        / spread(
            boundary,
            ior,
            origin,
            inside_direction,
            target,
            (&exit, out),
        )?;
    let cos_inside = inside_direction.dot(exit.normal);
    Some(Connection {
        inside_direction,
        exit,
        outside_direction: out,
        outside_length,
        transmittance: 1.0 - fresnel::dielectric(cos_inside, 1.0 / ior),
        inside_solid_angle_per_target_measure,
    })
}

/// A better start than the straight line: where the straight line leaves
/// the body, the direction inside that the surface there (taken as its
/// tangent plane) refracts towards the target. Exact for a plane and a
/// direction target; otherwise off by the surface's curvature over the
/// distance between this exit and the solution's.
fn backward_refraction(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    straight: DVec3,
    target: Target,
) -> Option<DVec3> {
    let exit = boundary.exit(origin, straight)?;
    let out = match target {
        Target::Point(y) => (y - exit.point).normalize(),
        Target::Direction(d) => d,
    };
    let cos_out = out.dot(exit.normal);
    if cos_out.is_nan() || cos_out <= 0.0 {
        return None;
    }
    // Snell (eq. 3.2) read backwards: ωₒ = n·ωᵢ − N·(n·cosθᵢ − cosθₒ).
    let cos_in = (1.0 - (1.0 - cos_out * cos_out) / (ior * ior)).sqrt();
    let inside = ((out + exit.normal * (ior * cos_in - cos_out)) / ior).normalize();
    inside.is_finite().then_some(inside)
}

/// |d(target measure) / dω| at the solution: the area swept across the
/// refracted ray at the target point per solid angle at the origin, or
/// the solid angle swept by the refracted direction, by differences in a
/// chart centred on the solution, measured across the refracted ray.
fn spread(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    direction: DVec3,
    target: Target,
    (exit, out): (&Exit, DVec3),
) -> Option<f64> {
    let chart = Chart::around(direction);
    // Measured against the solution's own ray, so the residual is exactly
    // the position (or direction) across it.
    let residual = Residual::new(
        match target {
            Target::Point(_) => target,
            Target::Direction(_) => Target::Direction(out),
        },
        out,
    );
    let h = JACOBIAN_STEP;
    let at = |a: f64, b: f64| {
        let (exit, out) = shoot(boundary, ior, origin, chart.direction(a, b))?;
        residual.of(&exit, out)
    };
    // Forward differences from the solution, whose residual is 0 in this
    // measure up to the solve's tolerance: O(h) relative error, 10⁻⁶.
    let (centre, pa, pb) = (residual.of(exit, out)?, at(h, 0.0)?, at(0.0, h)?);
    let ja = [(pa[0] - centre[0]) / h, (pa[1] - centre[1]) / h];
    let jb = [(pb[0] - centre[0]) / h, (pb[1] - centre[1]) / h];
    let det = (ja[0] * jb[1] - ja[1] * jb[0]).abs();
    (det > 0.0 && det.is_finite()).then_some(det)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The half-space z < 0, as a body.
    struct Slab;

    impl Boundary for Slab {
        fn exit(&self, origin: DVec3, direction: DVec3) -> Option<Exit> {
            if direction.z <= 0.0 {
                return None;
            }
            let t = -origin.z / direction.z;
            Some(Exit {
                t,
                point: origin + direction * t,
                normal: DVec3::Z,
            })
        }
    }

    /// A ball of radius `r` around the origin.
    struct Ball(f64);

    impl Boundary for Ball {
        fn exit(&self, origin: DVec3, direction: DVec3) -> Option<Exit> {
            let b = origin.dot(direction);
            let c = origin.length_squared() - self.0 * self.0;
            let disc = b * b - c;
            if disc < 0.0 {
                return None;
            }
            let t = -b + disc.sqrt();
            let point = origin + direction * t;
            Some(Exit {
                t,
                point,
                normal: point / self.0,
            })
        }
    }

    #[test]
    fn through_a_plane_the_path_obeys_snell_and_reaches_the_target() {
        let ior = 1.5;
        let origin = DVec3::new(0.0, 0.0, -2.0);
        let y = DVec3::new(7.0, 3.0, 10.0);
        let c = connect(&Slab, ior, origin, Target::Point(y)).expect("a solution");
        // Snell: ior·sinθᵢ = sinθₜ, in the plane of incidence.
        let sin_i = c.inside_direction.cross(DVec3::Z).length();
        let sin_t = c.outside_direction.cross(DVec3::Z).length();
        assert!((ior * sin_i - sin_t).abs() < 1e-9);
        let reach = c.exit.point + c.outside_direction * c.outside_length;
        assert!((reach - y).length() < 1e-7, "{reach} vs {y}");
    }

    #[test]
    fn through_a_plane_the_geometry_term_has_its_closed_form() {
        // Straight up from depth d to a target at height h: a ray at a
        // small angle θᵢ inside leaves at θₜ ≈ n·θᵢ and meets the target's
        // plane at r = d·tanθᵢ + h·tanθₜ ≈ (d + n·h)·θᵢ, so area per solid
        // angle is (d + n·h)², the inverse of the term.
        let ior = 1.54;
        let (d, h) = (1.3, 20.0);
        let origin = DVec3::new(0.0, 0.0, -d);
        let c = connect(&Slab, ior, origin, Target::Point(DVec3::new(0.0, 0.0, h))).unwrap();
        let expected = 1.0 / ((ior * h + d) * (ior * h + d));
        let measured = c.inside_solid_angle_per_target_measure;
        assert!(
            (measured / expected - 1.0).abs() < 1e-6,
            "{measured} vs {expected}"
        );
        // Fresnel at normal incidence: 1 − ((n − 1)/(n + 1))².
        let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
        assert!((c.transmittance - (1.0 - f0)).abs() < 1e-12);
    }

    #[test]
    fn without_refraction_the_geometry_term_is_the_inverse_square() {
        let origin = DVec3::new(0.2, -0.1, -0.5);
        let y = DVec3::new(3.0, 4.0, 12.0);
        let c = connect(&Ball(1.0), 1.0, origin, Target::Point(y)).unwrap();
        let d2 = (y - origin).length_squared();
        assert!((c.inside_solid_angle_per_target_measure * d2 - 1.0).abs() < 1e-6);
        assert!((c.inside_direction - (y - origin).normalize()).length() < 1e-9);
    }

    #[test]
    fn the_geometry_term_integrates_to_the_light_seen_through_a_ball() {
        // Shoot directions uniformly over the sphere from an inner point,
        // count those whose refracted rays cross a small disc around a
        // target point (a Monte Carlo estimate of ∫ dω over the disc's
        // preimage), and compare with area·(dω/dA⊥): the Jacobian is the
        // density of refracted rays at the target.
        let ior = 1.5;
        let ball = Ball(1.0);
        let origin = DVec3::new(0.3, 0.1, 0.2);
        let y = DVec3::new(1.0, 2.0, 5.0);
        let c = connect(&ball, ior, origin, Target::Point(y)).unwrap();
        let across = c.outside_direction;
        let (u, v) = across.any_orthonormal_pair();
        let radius = 0.05;
        let n = 2000;
        let mut solid_angle = 0.0;
        let mut inside_edge = true;
        // Directions stratified around the solution on a fine chart.
        let chart = Chart::around(c.inside_direction);
        let half = 0.05;
        let cell = (2.0 * half / f64::from(n)).powi(2);
        for i in 0..n {
            for j in 0..n {
                let a = -half + 2.0 * half * (f64::from(i) + 0.5) / f64::from(n);
                let b = -half + 2.0 * half * (f64::from(j) + 0.5) / f64::from(n);
                let Some((exit, out)) = shoot(&ball, ior, origin, chart.direction(a, b)) else {
                    continue;
                };
                let speed = out.dot(across);
                let q = exit.point + out * ((y - exit.point).dot(across) / speed) - y;
                if q.dot(u).hypot(q.dot(v)) < radius {
                    // dω per da·db in the chart.
                    solid_angle += (1.0 + a * a + b * b).powf(-1.5) * cell;
                    inside_edge &= a.abs().max(b.abs()) < 0.9 * half;
                }
            }
        }
        assert!(inside_edge, "the disc's preimage fits in the chart");
        let expected =
            std::f64::consts::PI * radius * radius * c.inside_solid_angle_per_target_measure;
        assert!(
            (solid_angle / expected - 1.0).abs() < 0.01,
            "{solid_angle} vs {expected}"
        );
    }

    #[test]
    fn a_direction_target_is_met_and_straight_through_costs_nothing() {
        let origin = DVec3::new(0.1, 0.2, -0.3);
        let d = DVec3::new(0.3, -0.2, 0.9).normalize();
        let c = connect(&Ball(1.0), 1.54, origin, Target::Direction(d)).unwrap();
        assert!((c.outside_direction - d).length() < 1e-8);
        let plain = connect(&Ball(1.0), 1.0, origin, Target::Direction(d)).unwrap();
        assert!((plain.inside_solid_angle_per_target_measure - 1.0).abs() < 1e-6);
    }

    #[test]
    fn an_unreachable_target_has_no_connection() {
        // Every ray refracted up out of a slab leaves upwards.
        let origin = DVec3::new(0.0, 0.0, -0.5);
        let downwards = DVec3::new(1.0, 0.0, -0.1).normalize();
        assert!(connect(&Slab, 1.54, origin, Target::Direction(downwards)).is_none());
    }
}
