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
//! method solves it with its exact Jacobian, the ray's differentials
//! carried across each surface crossing (Igehy 1999, "Tracing Ray
//! Differentials"), which also gives the generalised geometry term at the
//! solution. The body's surface can be any closed surface that answers
//! "where does this ray from inside leave, what is the outward normal
//! there, and how does it turn" ([`Boundary`]).

use glam::DVec3;

use crate::brdf::fresnel;

/// Where a ray from inside a body leaves it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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

    /// How the outward normal at `exit` turns along each of two
    /// displacements `dp` of the point in the tangent plane there (the
    /// surface's shape operator applied to them).
    fn normal_change(&self, exit: &Exit, dp: [DVec3; 2]) -> [DVec3; 2];
}

/// What the refracted ray must reach.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Target {
    /// A point outside the body (on an area or point light).
    Point(DVec3),
    /// A unit direction the ray must leave along (a distant light).
    Direction(DVec3),
}

/// Mirror reflections inside the body that a chain may take before it
/// leaves: a chain is `reflections` internal reflections at the surface,
/// 0 ..= this, then one refraction out.
pub(crate) const MAX_REFLECTIONS: usize = 1;

/// A straight piece of a chain inside the body.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Segment {
    /// Where it starts: the inner point, or just inside a reflection.
    pub start: DVec3,
    /// Its unit direction.
    pub direction: DVec3,
    /// Its length, to the surface.
    pub length: f64,
}

/// A path from an inner point through `reflections` internal reflections
/// and one refraction to a target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Connection {
    /// Unit direction at the inner point, towards the first surface point.
    pub inside_direction: DVec3,
    /// The inner segments (the first `reflections + 1`), in order.
    segments: [Segment; MAX_REFLECTIONS + 1],
    /// Internal reflections before the exit.
    pub reflections: usize,
    /// Where the path leaves the body, and the outward normal there.
    pub exit: Exit,
    /// Unit direction of the refracted ray, away from the body.
    pub outside_direction: DVec3,
    /// Distance from the exit to the target point (infinite for a
    /// direction target).
    pub outside_length: f64,
    /// The Fresnel factors of the chain (eq. 3.1): reflectance F at each
    /// internal reflection (1 beyond the critical angle) times the
    /// transmittance 1 − F of the exit. Also the probability with which
    /// Fresnel choices follow the chain from the inner point.
    pub fresnel: f64,
    /// |dω_inside / dA⊥| at the target point (area perpendicular to the
    /// refracted ray), or |dω_inside / dω_outside| for a direction target:
    /// the generalised geometry term that turns the light's measure into
    /// solid angle at the inner point. Without refraction or reflection it
    /// is 1/d² (or 1).
    pub inside_solid_angle_per_target_measure: f64,
}

impl Connection {
    /// The chain's straight pieces inside the body, from the inner point.
    pub(crate) fn inner_segments(&self) -> &[Segment] {
        &self.segments[..=self.reflections]
    }
}

/// Newton steps before a solve gives up.
const MAX_STEPS: usize = 12;
/// Halvings of a Newton step that does not reduce the residual.
const MAX_HALVINGS: usize = 4;
/// Length of the Snell residual (n·ωᵢ − ωₒ) × N at which a solve has
/// converged: about the angle, in radians, by which the refracted ray
/// misses the target.
const TOLERANCE: f64 = 1e-9;
/// Residual length below which the next Newton step is taken without
/// evaluating the residual it reaches: Newton converges quadratically
/// here (r → ≈ 0.1·r² on the built-in gems, up to ≈ 30·r² through a
/// tight ball in the tests), so that step lands at about [`TOLERANCE`] or
/// below (a few 10⁻⁹ rad at worst: nanometres at the light), and the
/// solution's own check (its refracted ray meets the target within
/// [`SAME_DIRECTION`]) rejects a step that does not. Saves the residual's
/// Jacobian (a surface curvature and the chain's differentials) at the
/// solution, which nothing else uses.
const LAST_STEP_BELOW: f64 = 1e-5;
/// Unit directions closer than this agree (a solution's refracted ray and
/// the direction to its target): the check every solution passes, the one
/// reached by a step taken without evaluation ([`LAST_STEP_BELOW`]) too.
const SAME_DIRECTION: f64 = 1e-7;
/// How far inside a reflection point the next inner segment starts, so
/// that it does not meet the surface it leaves (scene units, as the
/// integrator's ray offset).
const REFLECTION_OFFSET: f64 = 1e-5;

/// The inner part of a chain traced from a direction: its segments and
/// where the last one meets the surface.
#[derive(Clone, Copy)]
struct Inner {
    segments: [Segment; MAX_REFLECTIONS + 1],
    reflections: usize,
    exit: Exit,
}

impl Inner {
    /// The direction in which the last segment meets the exit.
    fn last_direction(&self) -> DVec3 {
        self.segments[self.reflections].direction
    }
}

/// The ray from `origin` (inside a body) along unit `direction`, mirrored
/// `reflections` times where it meets the surface: the segments and the
/// point where the last one meets it, or None when a segment leaves no
/// surface behind.
fn trace_inner(
    boundary: &impl Boundary,
    origin: DVec3,
    direction: DVec3,
    reflections: usize,
) -> Option<Inner> {
    debug_assert!(reflections <= MAX_REFLECTIONS);
    let mut segments = [Segment::default(); MAX_REFLECTIONS + 1];
    let (mut start, mut direction) = (origin, direction);
    for (i, segment) in segments.iter_mut().enumerate() {
        let exit = boundary.exit(start, direction)?;
        *segment = Segment {
            start,
            direction,
            length: exit.t,
        };
        if i == reflections {
            return Some(Inner {
                segments,
                reflections,
                exit,
            });
        }
        // Mirror reflection at the surface, from inside.
        let cos = direction.dot(exit.normal);
        if cos <= 0.0 {
            return None;
        }
        direction = (direction - exit.normal * (2.0 * cos)).normalize();
        start = exit.point - exit.normal * REFLECTION_OFFSET;
    }
    None
}

/// The chain of the ray from `origin` (inside a body of index `ior`)
/// along unit `direction`: its inner part and the refracted direction in
/// air, or None when it misses the surface or is totally reflected where
/// it should leave.
fn shoot(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    direction: DVec3,
    reflections: usize,
) -> Option<(Inner, DVec3)> {
    let inner = trace_inner(boundary, origin, direction, reflections)?;
    refract_out(inner, ior)
}

/// The chain `inner` refracted out where its last segment meets the
/// surface: `inner` and the refracted direction in air, or None when it is
/// totally reflected there.
fn refract_out(inner: Inner, ior: f64) -> Option<(Inner, DVec3)> {
    let (exit, direction) = (inner.exit, inner.last_direction());
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
    Some((inner, out))
}

/// Where the chain of the ray from `origin` (inside a body of index `ior`)
/// along unit `direction` through `reflections` internal reflections
/// leaves the body, and its refracted direction: the forward map that
/// [`Start::solve`] solves, so a target met along it is one the solve from
/// `origin` can recover `direction` for. None when the ray misses the
/// surface or is totally reflected where it should leave.
pub(crate) fn trace(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    direction: DVec3,
    reflections: usize,
) -> Option<(Exit, DVec3)> {
    if reflections > MAX_REFLECTIONS {
        return None;
    }
    shoot(boundary, ior, origin, direction, reflections).map(|(inner, out)| (inner.exit, out))
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

    /// [`Self::direction`] at (a, b) and its derivatives along a and b.
    fn direction_and_change(&self, a: f64, b: f64) -> (DVec3, [DVec3; 2]) {
        let v = self.centre + self.t * a + self.s * b;
        let inv_length = v.length_recip();
        let direction = v * inv_length;
        let along = |axis: DVec3| (axis - direction * direction.dot(axis)) * inv_length;
        (direction, [along(self.t), along(self.s)])
    }
}

/// How a traced chain's end moves with its start direction: for each of
/// two changes of the unit start direction, the change of the exit point,
/// of the outward normal there and of the last segment's direction.
#[derive(Clone, Copy)]
struct ChainChange {
    point: [DVec3; 2],
    normal: [DVec3; 2],
    last_direction: [DVec3; 2],
}

/// The change of where a segment along unit `direction` meets the surface
/// at `exit` (at distance `exit.t`), for a start moved by `d_origin` and
/// a direction turned by `d_direction`: the point slides in the tangent
/// plane, dp = m − ω (N·m)/(N·ω) with m = d_origin + t·d_direction, and
/// the normal turns with it. The point's changes, then the normal's.
fn transfer(
    boundary: &impl Boundary,
    exit: &Exit,
    direction: DVec3,
    d_origin: [DVec3; 2],
    d_direction: [DVec3; 2],
) -> ([DVec3; 2], [DVec3; 2]) {
    let cos = exit.normal.dot(direction);
    let dp = std::array::from_fn(|i| {
        let moved = d_origin[i] + d_direction[i] * exit.t;
        moved - direction * (exit.normal.dot(moved) / cos)
    });
    (dp, boundary.normal_change(exit, dp))
}

/// [`ChainChange`] of the chain `inner` for the start direction's changes
/// `d_direction`: carried across each reflection, where the mirrored
/// direction ω − 2(ω·N)N turns with both ω and N.
fn chain_change(boundary: &impl Boundary, inner: &Inner, d_direction: [DVec3; 2]) -> ChainChange {
    let (mut d_origin, mut d_direction) = ([DVec3::ZERO; 2], d_direction);
    for k in 0..inner.reflections {
        let (segment, next) = (inner.segments[k], inner.segments[k + 1]);
        // The reflection's point and normal, as `trace_inner` found them
        // (to rounding): the normal lies along the mirror pair's difference.
        let mirror = Exit {
            t: segment.length,
            point: segment.start + segment.direction * segment.length,
            normal: (segment.direction - next.direction).normalize(),
        };
        let (dp, dn) = transfer(boundary, &mirror, segment.direction, d_origin, d_direction);
        let cos = segment.direction.dot(mirror.normal);
        for i in 0..2 {
            let d_cos = d_direction[i].dot(mirror.normal) + segment.direction.dot(dn[i]);
            d_direction[i] -= (mirror.normal * d_cos + dn[i] * cos) * 2.0;
            d_origin[i] = dp[i] - dn[i] * REFLECTION_OFFSET;
        }
    }
    let last = inner.segments[inner.reflections].direction;
    let (point, normal) = transfer(boundary, &inner.exit, last, d_origin, d_direction);
    ChainChange {
        point,
        normal,
        last_direction: d_direction,
    }
}

/// Snell's residual (n·ωᵢ − ωₒ) × N of a chain whose last segment runs
/// along `last` to `exit` (see [`Start::solve`]), and its changes for the
/// chain's `change`.
fn residual_and_change(
    ior: f64,
    last: DVec3,
    exit: &Exit,
    target: Target,
    change: &ChainChange,
) -> (DVec3, [DVec3; 2]) {
    let out = towards(exit.point, target);
    let half = last * ior - out;
    let inv_distance = match target {
        Target::Point(y) => (y - exit.point).length_recip(),
        Target::Direction(_) => 0.0,
    };
    let d_residual = std::array::from_fn(|i| {
        // ωₒ = (y − p)/|y − p| turns by −(I − ωₒωₒᵀ)dp/|y − p|.
        let dp = change.point[i];
        let d_out = (out * out.dot(dp) - dp) * inv_distance;
        (change.last_direction[i] * ior - d_out).cross(exit.normal) + half.cross(change.normal[i])
    });
    (half.cross(exit.normal), d_residual)
}

/// The unit direction from `from` towards `target`.
fn towards(from: DVec3, target: Target) -> DVec3 {
    match target {
        Target::Point(y) => (y - from).normalize(),
        Target::Direction(d) => d,
    }
}

/// [`Start::new`] and [`Start::solve`] in one call.
#[cfg(test)]
pub(crate) fn connect(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    target: Target,
    reflections: usize,
) -> Option<Connection> {
    let start = Start::new(boundary, ior, origin, target, reflections)?;
    start.solve(boundary, ior)
}

/// Where the solve of a chain starts, before it runs ([`Start::solve`]):
/// the direction at the origin that its start guess takes (a function of
/// the origin, the target and the chain alone), and what the traces of
/// that guess say of the chain ([`Start::preview`]), known before paying
/// for the solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Start {
    origin: DVec3,
    target: Target,
    reflections: usize,
    direction: DVec3,
    preview: Preview,
}

/// What a [`Start`]'s plane construction says of its chain: roughly the
/// solution's chain, where the surface is nearly plane over the distance
/// between the start and the solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Preview {
    /// The total length of the inner segments.
    pub inner_length: f64,
    /// The Fresnel reflectance F of the internal reflections, multiplied
    /// (1 beyond the critical angle; 1 for a chain without reflection).
    pub reflectance: f64,
}

impl Start {
    /// The start of the solve for the chain from `origin` (inside a body
    /// of index `ior`) through `reflections` (0 ..= [`MAX_REFLECTIONS`])
    /// internal reflections and one refraction to `target`: the straight
    /// line refined by [`refraction_towards`] without reflection,
    /// [`Mirror::start`] with one. None when there is none.
    pub(crate) fn new(
        boundary: &impl Boundary,
        ior: f64,
        origin: DVec3,
        target: Target,
        reflections: usize,
    ) -> Option<Self> {
        debug_assert!(reflections <= MAX_REFLECTIONS);
        let (direction, preview) = if reflections == 0 {
            let straight = towards(origin, target);
            if !straight.is_finite() {
                return None;
            }
            let exit = boundary.exit(origin, straight);
            let direction = exit
                .and_then(|exit| refraction_towards(&exit, ior, target))
                .unwrap_or(straight);
            let preview = Preview {
                inner_length: exit.map_or(0.0, |exit| exit.t),
                reflectance: 1.0,
            };
            (direction, preview)
        } else {
            return Some(Mirror::find(boundary, origin, target)?.start(boundary, ior));
        };
        Some(Self {
            origin,
            target,
            reflections,
            direction,
            preview,
        })
    }

    /// The unit direction at the origin the solve starts from: near the
    /// solution's where the surface is nearly plane between their exits.
    pub(crate) fn direction(&self) -> DVec3 {
        self.direction
    }

    /// The chain as the start's construction sees it (its inner length
    /// and its reflections' Fresnel factors), for no further trace.
    pub(crate) fn preview(&self) -> Preview {
        self.preview
    }

    /// The internal reflections of the chain it starts.
    pub(crate) fn reflections(&self) -> usize {
        self.reflections
    }

    /// Finds the chain from the origin (inside a body of index `ior`)
    /// through the start's reflections (0 ..= [`MAX_REFLECTIONS`]) at the
    /// surface and one refraction out to its target, by Newton from the
    /// start (whose construction treats the surface as planes); None when
    /// it does not converge to a physical chain (no solution near the
    /// start, a grazing exit, or a step across a crease of the surface).
    /// The solution is a function of
    /// the origin, the target and the chain alone (one per call, when the
    /// chain has several).
    ///
    /// The unknown is the direction at the origin; the forward map traces it,
    /// mirrors it at each reflection, and the residual is Snell's law at the
    /// exit point the last segment reaches, written as the generalised half
    /// vector n·ωᵢ − ωₒ being parallel to the normal (ωᵢ along the last
    /// segment, ωₒ from the exit towards the target): the cross product
    /// (n·ωᵢ − ωₒ) × N. Unlike the refracted ray's miss distance it is defined
    /// at every exit point, total internal reflection included, so a start
    /// whose line cannot leave the body still converges.
    pub(crate) fn solve(&self, boundary: &impl Boundary, ior: f64) -> Option<Connection> {
        let Self {
            origin,
            target,
            reflections,
            direction: start,
            ..
        } = *self;
        solve(boundary, ior, origin, target, reflections, start)
    }
}

/// The residual of the chain from `origin` through `reflections` to
/// `target` whose start direction is `chart`'s at (a, b), its Jacobian
/// in (a, b), and where the chain leaves (kept for the solution's own
/// refraction when it has no reflection).
fn evaluate(
    boundary: &impl Boundary,
    ior: f64,
    (origin, target, reflections): (DVec3, Target, usize),
    chart: &Chart,
    a: f64,
    b: f64,
) -> Option<(DVec3, [DVec3; 2], Exit)> {
    let (direction, d_direction) = chart.direction_and_change(a, b);
    // Straight out, the one exit is the whole chain: traced without
    // building its segments (the solve's inner loop).
    let (last, exit, change) = if reflections == 0 {
        let exit = boundary.exit(origin, direction)?;
        let (point, normal) = transfer(boundary, &exit, direction, [DVec3::ZERO; 2], d_direction);
        let change = ChainChange {
            point,
            normal,
            last_direction: d_direction,
        };
        (direction, exit, change)
    } else {
        let inner = trace_inner(boundary, origin, direction, reflections)?;
        let change = chain_change(boundary, &inner, d_direction);
        (inner.last_direction(), inner.exit, change)
    };
    let (r, j) = residual_and_change(ior, last, &exit, target, &change);
    Some((r, j, exit))
}

/// Gauss–Newton for the chain of [`Start::solve`] from the direction
/// `start`.
fn solve(
    boundary: &impl Boundary,
    ior: f64,
    origin: DVec3,
    target: Target,
    reflections: usize,
    start: DVec3,
) -> Option<Connection> {
    let chart = Chart::around(start);
    let evaluate =
        |a: f64, b: f64| evaluate(boundary, ior, (origin, target, reflections), &chart, a, b);
    // Newton (Gauss–Newton on the normal equations of the 3 × 2 system
    // J·δ = −r, whose residual has rank 2) with the exact Jacobian.
    let (mut a, mut b) = (0.0, 0.0);
    let (mut r, [mut ja, mut jb], exit) = evaluate(a, b)?;
    // Where the chain at (a, b) leaves, while (a, b) is a point evaluated.
    let mut evaluated_exit = Some(exit);
    let mut steps = 0;
    loop {
        let residual = r.length();
        if residual <= TOLERANCE {
            break;
        }
        let (aa, ab, bb) = (ja.dot(ja), ja.dot(jb), jb.dot(jb));
        let (ra, rb) = (ja.dot(r), jb.dot(r));
        let det = aa * bb - ab * ab;
        if !(det.abs() > f64::MIN_POSITIVE && det.is_finite()) {
            return None;
        }
        let da = -(bb * ra - ab * rb) / det;
        let db = -(aa * rb - ab * ra) / det;
        if residual <= LAST_STEP_BELOW {
            (a, b, evaluated_exit) = (a + da, b + db, None);
            break;
        }
        if steps == MAX_STEPS {
            return None;
        }
        steps += 1;
        // Damped: halve the step until the residual falls.
        let mut step = 1.0;
        let mut next = None;
        for _ in 0..MAX_HALVINGS {
            let (sa, sb) = (step * da, step * db);
            if let Some(found) = evaluate(a + sa, b + sb) {
                if found.0.length() < residual {
                    next = Some((sa, sb, found));
                    break;
                }
            }
            step *= 0.5;
        }
        let (sa, sb, (nr, [na, nb], n_exit)) = next?;
        (a, b, r, ja, jb, evaluated_exit) = (a + sa, b + sb, nr, na, nb, Some(n_exit));
    }
    // A physical refraction: leaving the body, on towards the target (the
    // cross product also vanishes for the half vector's other sign).
    let inside_direction = chart.direction(a, b);
    // Without a reflection the last evaluation's exit is the whole chain.
    let inner = if let (0, Some(exit)) = (reflections, evaluated_exit) {
        let mut segments = [Segment::default(); MAX_REFLECTIONS + 1];
        segments[0] = Segment {
            start: origin,
            direction: inside_direction,
            length: exit.t,
        };
        Inner {
            segments,
            reflections,
            exit,
        }
    } else {
        trace_inner(boundary, origin, inside_direction, reflections)?
    };
    let (inner, out) = refract_out(inner, ior)?;
    let exit = inner.exit;
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
    let inside_solid_angle_per_target_measure =
        1.0 / spread(boundary, ior, &inner, out, outside_length)?;
    // Fresnel (eq. 3.1) from inside, η = 1/ior: F at each reflection, 1 − F
    // at the exit.
    let cos_at = |segment: &Segment, normal: DVec3| segment.direction.dot(normal);
    let reflectance: f64 = (0..reflections)
        .map(|i| {
            let next = &inner.segments[i + 1];
            // The normal at reflection i, from the mirror pair of directions.
            let normal = (inner.segments[i].direction - next.direction).normalize();
            fresnel::dielectric(cos_at(&inner.segments[i], normal), 1.0 / ior)
        })
        .product();
    let exit_transmittance =
        1.0 - fresnel::dielectric(cos_at(&inner.segments[reflections], exit.normal), 1.0 / ior);
    Some(Connection {
        inside_direction,
        segments: inner.segments,
        reflections,
        exit,
        outside_direction: out,
        outside_length,
        fresnel: reflectance * exit_transmittance,
        inside_solid_angle_per_target_measure,
    })
}

/// A better start than the straight line: where the straight line leaves
/// the body (`exit`), the direction inside that the surface there (taken
/// as its tangent plane) refracts towards the target; None when the
/// target lies behind that plane. Exact for a plane and a direction
/// target; otherwise off by the surface's curvature over the distance
/// between this exit and the solution's.
fn refraction_towards(exit: &Exit, ior: f64, target: Target) -> Option<DVec3> {
    let out = towards(exit.point, target);
    let cos_out = out.dot(exit.normal);
    if cos_out.is_nan() || cos_out <= 0.0 {
        return None;
    }
    // Snell (eq. 3.2) read backwards: ωₒ = n·ωᵢ − N·(n·cosθᵢ − cosθₒ).
    let cos_in = (1.0 - (1.0 - cos_out * cos_out) / (ior * ior)).sqrt();
    let inside = ((out + exit.normal * (ior * cos_in - cos_out)) / ior).normalize();
    inside.is_finite().then_some(inside)
}

/// The first trace of the start of a chain with one reflection (see
/// [`Mirror::start`]): the surface behind the origin, seen away from the
/// target, taken as a mirror plane, and the line from the origin's image
/// in it towards the target. Known before the rest of the start is paid
/// for, so that a caller can end the chain early ([`Mirror::depth`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mirror {
    origin: DVec3,
    target: Target,
    /// Where the ray away from the target leaves the body.
    plane: DVec3,
    /// The outward normal there.
    normal: DVec3,
    /// The origin mirrored in the plane.
    image: DVec3,
    /// The unit direction from the image towards the target.
    line: DVec3,
    /// `line · normal` (< 0: the line crosses the plane inwards).
    speed: f64,
}

impl Mirror {
    /// The mirror plane of the chain from `origin` (inside the body) to
    /// `target`; None when the ray away from the target leaves no surface
    /// or the image's line towards the target does not cross the plane
    /// inwards.
    pub(crate) fn find(boundary: &impl Boundary, origin: DVec3, target: Target) -> Option<Self> {
        let away = -towards(origin, target);
        if !away.is_finite() {
            return None;
        }
        let mirror = boundary.exit(origin, away)?;
        let (plane, normal) = (mirror.point, mirror.normal);
        let image = origin - normal * (2.0 * (origin - plane).dot(normal));
        let line = towards(image, target);
        let speed = line.dot(normal);
        if speed.is_nan() || speed >= 0.0 {
            return None;
        }
        Some(Self {
            origin,
            target,
            plane,
            normal,
            image,
            line,
            speed,
        })
    }

    /// The origin's depth under the mirror plane: at most the inner
    /// length of the start's [`Preview`] (its run to the plane is at
    /// least this deep), so that a chain's expected throughput through
    /// the body is at most what this depth alone lets through.
    pub(crate) fn depth(&self) -> f64 {
        (self.plane - self.origin).dot(self.normal).max(0.0)
    }

    /// The start of the chain: where the image's line crosses the plane
    /// the reflected ray runs along it; that line's direction after the
    /// plane, refined by [`refraction_towards`] where it leaves, mirrored
    /// back. Exact for a slab and a direction target.
    ///
    /// Also the chain's preview read off the same traces, the surface taken
    /// as the mirror plane and the tangent plane where the line leaves: the
    /// start's run to the mirror plane plus its mirrored run on to the
    /// exit's plane, and the Fresnel reflectance at the mirror.
    pub(crate) fn start(&self, boundary: &impl Boundary, ior: f64) -> Start {
        let (origin, target, plane, normal) = (self.origin, self.target, self.plane, self.normal);
        let (image, line) = (self.image, self.line);
        let reflect = |v: DVec3| v - normal * (2.0 * v.dot(normal));
        let crossing = image + line * ((plane - image).dot(normal) / self.speed);
        let exit = boundary.exit(crossing - normal * REFLECTION_OFFSET, line);
        let refined = exit
            .and_then(|exit| refraction_towards(&exit, ior, target))
            .filter(|inside| inside.dot(normal) < 0.0)
            .map(reflect);
        let start = refined.unwrap_or_else(|| reflect(line));
        // The preview's chain: the start to the mirror plane, mirrored, on to
        // the tangent plane where the line left.
        let cos_mirror = start.dot(normal);
        let to_mirror = (plane - origin).dot(normal) / cos_mirror;
        let onwards = reflect(start);
        let to_exit = exit.map_or(0.0, |exit| {
            let speed = onwards.dot(exit.normal);
            let from_mirror = origin + start * to_mirror;
            if speed > 0.0 {
                (exit.point - from_mirror).dot(exit.normal) / speed
            } else {
                exit.t
            }
        });
        let preview = Preview {
            // Never below the depth (a start that turns away from the
            // plane would have a negative run to it).
            inner_length: (to_mirror.max(0.0) + to_exit.max(0.0)).max(self.depth()),
            reflectance: fresnel::dielectric(cos_mirror, 1.0 / ior),
        };
        Start {
            origin,
            target,
            reflections: 1,
            direction: start,
            preview,
        }
    }
}

/// |d(target measure) / dω| at the solution `inner` (refracted out along
/// `out`, reaching a target point `outside_length` away, or a direction
/// target when that is infinite): the area swept across the refracted ray
/// at the target point per solid angle at the origin, or the solid angle
/// swept by the refracted direction; from the chain's change along an
/// orthonormal pair across its start direction, and Snell's refraction
/// ωₒ = n·ω − N(n·cosθᵢ − cosθₜ) (eq. 3.2) differentiated.
fn spread(
    boundary: &impl Boundary,
    ior: f64,
    inner: &Inner,
    out: DVec3,
    outside_length: f64,
) -> Option<f64> {
    let (t, s) = inner.segments[0].direction.any_orthonormal_pair();
    let change = chain_change(boundary, inner, [t, s]);
    let (exit, last) = (inner.exit, inner.last_direction());
    let cos_i = last.dot(exit.normal);
    let cos_t = (1.0 - (1.0 - cos_i * cos_i) * ior * ior).sqrt();
    let axes = out.any_orthonormal_pair();
    let across = |i: usize| -> [f64; 2] {
        let d_cos_i = change.last_direction[i].dot(exit.normal) + last.dot(change.normal[i]);
        let d_cos_t = ior * ior * cos_i * d_cos_i / cos_t;
        let d_out = change.last_direction[i] * ior
            - change.normal[i] * (ior * cos_i - cos_t)
            - exit.normal * (ior * d_cos_i - d_cos_t);
        // Across the ray (the part along ωₒ drops out): the direction's
        // turn, or the point's slide plus the turn over the distance.
        let moved = if outside_length.is_finite() {
            change.point[i] + d_out * outside_length
        } else {
            d_out
        };
        [axes.0.dot(moved), axes.1.dot(moved)]
    };
    let (ja, jb) = (across(0), across(1));
    let det = (ja[0] * jb[1] - ja[1] * jb[0]).abs();
    (det > 0.0 && det.is_finite()).then_some(det)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec2;

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

        fn normal_change(&self, _: &Exit, _: [DVec3; 2]) -> [DVec3; 2] {
            [DVec3::ZERO; 2]
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

        fn normal_change(&self, exit: &Exit, dp: [DVec3; 2]) -> [DVec3; 2] {
            dp.map(|d| (d - exit.normal * exit.normal.dot(d)) / self.0)
        }
    }

    #[test]
    fn through_a_plane_the_path_obeys_snell_and_reaches_the_target() {
        let ior = 1.5;
        let origin = DVec3::new(0.0, 0.0, -2.0);
        let y = DVec3::new(7.0, 3.0, 10.0);
        let c = connect(&Slab, ior, origin, Target::Point(y), 0).expect("a solution");
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
        let c = connect(
            &Slab,
            ior,
            origin,
            Target::Point(DVec3::new(0.0, 0.0, h)),
            0,
        )
        .unwrap();
        let expected = 1.0 / ((ior * h + d) * (ior * h + d));
        let measured = c.inside_solid_angle_per_target_measure;
        assert!(
            (measured / expected - 1.0).abs() < 1e-6,
            "{measured} vs {expected}"
        );
        // Fresnel at normal incidence: 1 − ((n − 1)/(n + 1))².
        let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
        assert!((c.fresnel - (1.0 - f0)).abs() < 1e-12);
    }

    #[test]
    fn without_refraction_the_geometry_term_is_the_inverse_square() {
        let origin = DVec3::new(0.2, -0.1, -0.5);
        let y = DVec3::new(3.0, 4.0, 12.0);
        let c = connect(&Ball(1.0), 1.0, origin, Target::Point(y), 0).unwrap();
        let d2 = (y - origin).length_squared();
        assert!((c.inside_solid_angle_per_target_measure * d2 - 1.0).abs() < 1e-6);
        assert!((c.inside_direction - (y - origin).normalize()).length() < 1e-9);
    }

    #[test]
    fn the_geometry_term_integrates_to_the_light_seen_through_a_ball() {
        // Shoot directions around the solution from an inner point, count
        // those whose chains (straight out, or mirrored once inside first)
        // cross a small disc around a target point (a quadrature of ∫ dω
        // over the disc's preimage), and compare with area·(dω/dA⊥): the
        // Jacobian is the density of refracted rays at the target.
        let ior = 1.5;
        let ball = Ball(1.0);
        let origin = DVec3::new(0.3, 0.1, 0.2);
        let y = DVec3::new(1.0, 2.0, 5.0);
        for reflections in 0..=MAX_REFLECTIONS {
            let c = connect(&ball, ior, origin, Target::Point(y), reflections).unwrap();
            assert_eq!(c.inner_segments().len(), reflections + 1);
            let across = c.outside_direction;
            let (u, v) = across.any_orthonormal_pair();
            let radius = 0.05;
            let n = 1000;
            let mut solid_angle = 0.0;
            let mut inside_edge = true;
            // Directions stratified around the solution on a fine chart
            // about twice the preimage's size.
            let chart = Chart::around(c.inside_direction);
            let half = 2.0 * radius * c.inside_solid_angle_per_target_measure.sqrt();
            let cell = (2.0 * half / f64::from(n)).powi(2);
            for i in 0..n {
                for j in 0..n {
                    let a = -half + 2.0 * half * (f64::from(i) + 0.5) / f64::from(n);
                    let b = -half + 2.0 * half * (f64::from(j) + 0.5) / f64::from(n);
                    let direction = chart.direction(a, b);
                    let Some((inner, out)) = shoot(&ball, ior, origin, direction, reflections)
                    else {
                        continue;
                    };
                    let speed = out.dot(across);
                    let exit = inner.exit.point;
                    let q = exit + out * ((y - exit).dot(across) / speed) - y;
                    if q.dot(u).hypot(q.dot(v)) < radius {
                        // dω per da·db in the chart.
                        solid_angle += (1.0 + a * a + b * b).powf(-1.5) * cell;
                        inside_edge &= a.abs().max(b.abs()) < 0.9 * half;
                    }
                }
            }
            assert!(
                inside_edge,
                "{reflections}: the disc's preimage fits in the chart"
            );
            let expected =
                std::f64::consts::PI * radius * radius * c.inside_solid_angle_per_target_measure;
            assert!(
                (solid_angle / expected - 1.0).abs() < 0.01,
                "{reflections}: {solid_angle} vs {expected}"
            );
        }
    }

    #[test]
    fn a_newton_step_taken_unevaluated_still_meets_the_target() {
        // Solutions through a ball from points all over it, straight out
        // and mirrored once, to points and directions: the residual at the
        // returned direction, evaluated afresh, is within a few TOLERANCE
        // even though the solver did not evaluate it (LAST_STEP_BELOW; a
        // threshold of 10⁻⁴ fails here), and the refracted ray reaches a
        // point target.
        let (ior, ball) = (1.5, Ball(1.0));
        let mut solved = [0; MAX_REFLECTIONS + 1];
        for i in 0..200 {
            let k = f64::from(i);
            let origin = DVec3::new(
                0.7 * (k * 0.37).sin(),
                0.7 * (k * 0.71).cos(),
                0.6 * (k * 1.13).sin(),
            );
            let targets = [
                Target::Point(DVec3::new(
                    3.0 * (k * 0.5).cos(),
                    2.0,
                    4.0 + (k * 0.9).sin(),
                )),
                Target::Direction(DVec3::new((k * 0.3).sin(), 0.4, 1.0).normalize()),
            ];
            for target in targets {
                for (reflections, count) in solved.iter_mut().enumerate() {
                    let Some(c) = connect(&ball, ior, origin, target, reflections) else {
                        continue;
                    };
                    *count += 1;
                    let chart = Chart::around(c.inside_direction);
                    let (r, _, _) =
                        evaluate(&ball, ior, (origin, target, reflections), &chart, 0.0, 0.0)
                            .expect("the solution's chain");
                    assert!(r.length() <= 5.0 * TOLERANCE, "{origin} {reflections}: {r}");
                    if let Target::Point(y) = target {
                        let reach = c.exit.point + c.outside_direction * c.outside_length;
                        assert!((reach - y).length() < 1e-7, "{reach} vs {y}");
                    }
                }
            }
        }
        assert!(solved[0] > 200 && solved[1] > 20, "{solved:?}");
    }

    #[test]
    fn the_newton_jacobian_is_the_residual_s_derivative() {
        // The Jacobian from ray differentials (through the surface's
        // curvature and the mirror reflection) against central differences
        // of the residual, from points in a ball, straight out and mirrored
        // once, to a point and to a direction, off the chart's centre.
        let (ior, ball, h) = (1.5, Ball(1.0), 1e-6);
        let origins = [
            DVec3::new(0.3, 0.1, 0.2),
            DVec3::new(-0.5, 0.2, -0.1),
            DVec3::new(0.0, -0.6, 0.4),
        ];
        let targets = [
            Target::Point(DVec3::new(1.0, 2.0, 5.0)),
            Target::Direction(DVec3::new(0.2, -0.3, 1.0).normalize()),
        ];
        let mut checked = 0;
        for (k, origin) in origins.into_iter().enumerate() {
            for target in targets {
                for reflections in 0..=MAX_REFLECTIONS {
                    let towards_target = towards(origin, target);
                    let centre = if reflections == 0 {
                        towards_target
                    } else {
                        -towards_target
                    };
                    let chart = Chart::around(centre);
                    let at = |a: f64, b: f64| {
                        evaluate(&ball, ior, (origin, target, reflections), &chart, a, b).unwrap()
                    };
                    let (a, b) = (0.05 * k as f64, -0.03);
                    let (_, [ja, jb], _) = at(a, b);
                    let da = (at(a + h, b).0 - at(a - h, b).0) / (2.0 * h);
                    let db = (at(a, b + h).0 - at(a, b - h).0) / (2.0 * h);
                    for (exact, differences) in [(ja, da), (jb, db)] {
                        assert!(
                            (exact - differences).length() <= 1e-6 * (1.0 + differences.length()),
                            "{reflections} reflections, {target:?}: {exact} vs {differences}"
                        );
                    }
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 12);
    }

    #[test]
    fn the_geometry_term_is_the_determinant_of_the_traced_chain_s_differences() {
        // |dω_inside / d(target measure)| from ray differentials against
        // central differences of traced chains around the solution: the
        // refracted direction's turn (direction target) or the refracted
        // ray's slide across the target point.
        let (ior, ball, h) = (1.5, Ball(1.0), 1e-6);
        let origin = DVec3::new(0.3, 0.1, 0.2);
        let targets = [
            Target::Point(DVec3::new(1.0, 2.0, 5.0)),
            Target::Direction(DVec3::new(0.2, -0.3, 1.0).normalize()),
        ];
        for target in targets {
            for reflections in 0..=MAX_REFLECTIONS {
                // Solved from the best of a scan of directions (the mirror
                // plane's start is far off in a ball).
                let miss = |direction: DVec3| {
                    shoot(&ball, ior, origin, direction, reflections)
                        .map_or(f64::INFINITY, |(inner, out)| {
                            (out - towards(inner.exit.point, target)).length()
                        })
                };
                let start = (0..200 * 200)
                    .map(|k| {
                        let z = 1.0 - (f64::from(k / 200) + 0.5) / 100.0;
                        let phi = std::f64::consts::TAU * (f64::from(k % 200) + 0.5) / 200.0;
                        let r = (1.0 - z * z).sqrt();
                        DVec3::new(r * phi.cos(), r * phi.sin(), z)
                    })
                    .min_by(|p, q| miss(*p).total_cmp(&miss(*q)))
                    .unwrap();
                let c = solve(&ball, ior, origin, target, reflections, start)
                    .unwrap_or_else(|| panic!("{reflections} reflections, {target:?}: no chain"));
                let chart = Chart::around(c.inside_direction);
                let (u, v) = c.outside_direction.any_orthonormal_pair();
                let across = |a: f64, b: f64| {
                    let (inner, out) =
                        shoot(&ball, ior, origin, chart.direction(a, b), reflections).unwrap();
                    let q = match target {
                        Target::Point(y) => {
                            let exit = inner.exit.point;
                            let speed = out.dot(c.outside_direction);
                            exit + out * ((y - exit).dot(c.outside_direction) / speed) - y
                        }
                        Target::Direction(_) => out,
                    };
                    DVec2::new(q.dot(u), q.dot(v))
                };
                let da = (across(h, 0.0) - across(-h, 0.0)) / (2.0 * h);
                let db = (across(0.0, h) - across(0.0, -h)) / (2.0 * h);
                let differences = da.perp_dot(db).abs();
                let exact = 1.0 / c.inside_solid_angle_per_target_measure;
                assert!(
                    (exact / differences - 1.0).abs() < 1e-6,
                    "{reflections} reflections, {target:?}: {exact} vs {differences}"
                );
            }
        }
    }

    /// The plate −`.0` < z < 0 (top normal +z, bottom −z), as a body.
    struct Plate(f64);

    impl Boundary for Plate {
        fn exit(&self, origin: DVec3, direction: DVec3) -> Option<Exit> {
            let (t, normal) = if direction.z > 0.0 {
                (-origin.z / direction.z, DVec3::Z)
            } else if direction.z < 0.0 {
                ((-self.0 - origin.z) / direction.z, -DVec3::Z)
            } else {
                return None;
            };
            Some(Exit {
                t,
                point: origin + direction * t,
                normal,
            })
        }

        fn normal_change(&self, _: &Exit, _: [DVec3; 2]) -> [DVec3; 2] {
            [DVec3::ZERO; 2]
        }
    }

    #[test]
    fn in_a_plate_the_preview_of_a_reflected_chain_is_its_solution_s() {
        // For a plate and a direction target the mirror-plane start is the
        // solution, so its preview's inner length and reflectance are the
        // solved chain's (up to the reflection's offset off the surface,
        // 10⁻⁵); for a point target they are close (the start is off by the
        // target's parallax over the plate).
        let (ior, h) = (1.54, 3.0);
        let origin = DVec3::new(0.4, -0.2, -1.1);
        for (target, tolerance) in [
            (
                Target::Direction(DVec3::new(0.5, -0.3, 0.8).normalize()),
                1e-5,
            ),
            (Target::Point(DVec3::new(7.0, 3.0, 10.0)), 0.05),
        ] {
            let start = Start::new(&Plate(h), ior, origin, target, 1).unwrap();
            let preview = start.preview();
            let chain = start.solve(&Plate(h), ior).expect("a chain");
            let segments = chain.inner_segments();
            let length = segments[0].length + segments[1].length;
            let reflectance = fresnel::dielectric(segments[0].direction.dot(-DVec3::Z), 1.0 / ior);
            assert!(
                (preview.inner_length / length - 1.0).abs() < tolerance,
                "{target:?}: {} vs {length}",
                preview.inner_length
            );
            assert!(
                (preview.reflectance / reflectance - 1.0).abs() < tolerance,
                "{target:?}: {} vs {reflectance}",
                preview.reflectance
            );
        }
        // Without reflection: the straight line's run to the surface.
        let start = Start::new(
            &Slab,
            ior,
            origin,
            Target::Point(DVec3::new(0.4, -0.2, 9.0)),
            0,
        );
        let preview = start.unwrap().preview();
        assert!((preview.inner_length - 1.1).abs() < 1e-12);
        assert_eq!(preview.reflectance, 1.0);
    }

    #[test]
    fn mirrored_in_a_plate_the_chain_is_the_image_s_refraction() {
        // Down to the plate's bottom, mirrored, up through its top: the
        // chain from depth d in a plate of thickness h is the straight
        // refraction from the origin's mirror image at depth 2h − d, with
        // the first segment mirrored (the method of images).
        let (ior, h) = (1.54, 3.0);
        let origin = DVec3::new(0.4, -0.2, -1.1);
        let image = DVec3::new(origin.x, origin.y, -2.0 * h - origin.z);
        for target in [
            Target::Point(DVec3::new(7.0, 3.0, 10.0)),
            Target::Point(DVec3::new(-2.0, 1.0, 0.5)),
            Target::Direction(DVec3::new(0.5, -0.3, 0.8).normalize()),
        ] {
            let chain = connect(&Plate(h), ior, origin, target, 1).expect("a chain");
            let straight = connect(&Slab, ior, image, target, 0).expect("the image's");
            let unfolded = chain.inside_direction * DVec3::new(1.0, 1.0, -1.0);
            assert!(
                (unfolded - straight.inside_direction).length() < 1e-6,
                "{target:?}: {unfolded} vs {}",
                straight.inside_direction
            );
            // Up to the reflection's offset off the surface, 10⁻⁵.
            assert!((chain.exit.point - straight.exit.point).length() < 1e-4);
            let (j1, j0) = (
                chain.inside_solid_angle_per_target_measure,
                straight.inside_solid_angle_per_target_measure,
            );
            assert!((j1 / j0 - 1.0).abs() < 1e-4, "{target:?}: {j1} vs {j0}");
            // F at the bottom (the same angle as at the top) times 1 − F.
            let segments = chain.inner_segments();
            assert_eq!(segments.len(), 2);
            assert!(segments[0].direction.z < 0.0 && segments[1].direction.z > 0.0);
            let cos = segments[1].direction.z;
            let f = fresnel::dielectric(cos, 1.0 / ior);
            assert!((chain.fresnel - f * (1.0 - f)).abs() < 1e-12);
            let lengths = segments[0].length + segments[1].length;
            let unfolded_length = straight.inner_segments()[0].length;
            assert!(
                (lengths - unfolded_length).abs() < 1e-4,
                "{lengths} vs {unfolded_length}"
            );
        }
        // Straight up from depth d: the closed form of the term through
        // a plane, 1/(D + n·H)², at the unfolded depth D = 2h − d.
        let height = 20.0;
        let up = connect(
            &Plate(h),
            ior,
            origin,
            Target::Point(DVec3::new(0.4, -0.2, height)),
            1,
        )
        .unwrap();
        let depth = 2.0 * h + origin.z;
        let expected = 1.0 / (depth + ior * height).powi(2);
        let measured = up.inside_solid_angle_per_target_measure;
        assert!(
            (measured / expected - 1.0).abs() < 1e-6,
            "{measured} vs {expected}"
        );
        let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
        assert!((up.fresnel - f0 * (1.0 - f0)).abs() < 1e-12);
    }

    #[test]
    fn a_chain_is_the_same_for_the_same_question() {
        // A pure function of origin, target and chain: the integrator's
        // weights ask the solver again for a path it sampled.
        let ball = Ball(1.0);
        let origin = DVec3::new(0.3, 0.1, 0.2);
        let target = Target::Point(DVec3::new(1.0, 2.0, 5.0));
        for reflections in 0..=MAX_REFLECTIONS {
            let a = connect(&ball, 1.5, origin, target, reflections);
            let b = connect(&ball, 1.5, origin, target, reflections);
            assert!(a.is_some());
            assert_eq!(a, b);
        }
    }

    #[test]
    fn a_direction_target_is_met_and_straight_through_costs_nothing() {
        let origin = DVec3::new(0.1, 0.2, -0.3);
        let d = DVec3::new(0.3, -0.2, 0.9).normalize();
        let c = connect(&Ball(1.0), 1.54, origin, Target::Direction(d), 0).unwrap();
        assert!((c.outside_direction - d).length() < 1e-8);
        let plain = connect(&Ball(1.0), 1.0, origin, Target::Direction(d), 0).unwrap();
        assert!((plain.inside_solid_angle_per_target_measure - 1.0).abs() < 1e-6);
    }

    #[test]
    fn an_unreachable_target_has_no_connection() {
        // Every ray refracted up out of a slab leaves upwards.
        let origin = DVec3::new(0.0, 0.0, -0.5);
        let downwards = DVec3::new(1.0, 0.0, -0.1).normalize();
        assert!(connect(&Slab, 1.54, origin, Target::Direction(downwards), 0).is_none());
    }
}
