//! An analytic cabochon: outline × dome profile, a girdle band and a base,
//! intersected by rays without tessellation.
//!
//! # Object space
//!
//! z is up. The plane `z = 0` is where the dome meets the girdle (the
//! stone's widest outline); the dome rises to `z = dome_height`; the
//! vertical girdle band spans `−girdle_height ≤ z ≤ 0`; below it the base is
//! either the plane `z = −girdle_height` (`Base::Flat`) or a second dome
//! reaching `z = −girdle_height − height` (`Base::Domed`, a double
//! cabochon). x runs along the length, y along the width, and the outline's
//! bounding box is centred on the z axis (see [`super::outline`]).
//!
//! # The solid
//!
//! With the outline gauge `s(x, y)` (0 at the apex, 1 on the girdle) and the
//! normalised height
//!
//! ```text
//! ζ(z) = z / h                       for z > 0            (dome)
//!      = 0                           for −g ≤ z ≤ 0       (girdle band)
//!      = (−g − z) / h_b              for z < −g           (domed base; 0 for a flat base)
//! ```
//!
//! the stone is `N(x, y, z) = (sᵖ + ζᵖ)^(1/p) ≤ 1`, intersected with the
//! half-spaces `z ≤ z_top` (buff top) and `z ≥ −g` (flat base). On the dome
//! this is `z = h·(1 − sᵖ)^(1/p)`: p = 2 gives an ellipsoid cap over a round
//! or oval outline, p < 2 a lower, more pointed dome, p > 2 a fuller, flatter
//! topped one. The domed base uses the same profile exponent.
//!
//! Every piece is convex (`s` is a gauge of a convex outline, ζ is convex and
//! non-negative, and the p-norm is monotone), so the solid is convex and a
//! line meets it in one interval: closedness holds by construction, and the
//! entry and exit points can each be found by Newton's method started
//! outside, which on a convex function never overshoots.
//!
//! # Accuracy
//!
//! Round and oval stones with p = 2 are intersected exactly (quadratics for
//! the dome, the band's elliptic cylinder and the base ellipsoid). All other
//! stones use monotone Newton iteration on `N − 1` along the ray, stopped when
//! a step is below `1e-12 × size` (at most `MAX_NEWTON_STEPS`); hit points
//! lie within about `1e-9 × size` of the surface, on its outside. Normals are
//! the normalised analytic gradient of `N`, smooth everywhere except at the
//! points of a pear or marquise and along the rims of a buff top or flat base.

use glam::{DVec2, DVec3};

use super::error::{check_positive, GeometryError};
use super::outline::{p_norm, Footprint, Outline};

/// The base of the stone, below the girdle band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Base {
    /// A flat polished back at `z = −girdle_height` (the usual cabochon).
    Flat,
    /// A second dome below the girdle (a double cabochon), with the dome's
    /// profile exponent.
    Domed {
        /// Depth of the lower dome below the girdle band, > 0.
        height: f64,
    },
}

/// The parameters of a cabochon, as a recipe would write them (lengths in
/// scene units). Validated by [`Cabochon::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CabochonParams {
    /// The girdle's shape seen from above.
    pub outline: Outline,
    /// Extent along x, > 0.
    pub length: f64,
    /// Extent along y, > 0 (equal to `length` for `Round`, smaller for
    /// `Pear` and `Marquise`).
    pub width: f64,
    /// Height of the dome above the girdle plane z = 0, > 0.
    pub dome_height: f64,
    /// Dome profile exponent p in `z = h·(1 − sᵖ)^(1/p)`, in
    /// [`PROFILE_EXPONENT_RANGE`]; 2 is elliptical.
    pub profile_exponent: f64,
    /// Height of the vertical girdle band below z = 0, ≥ 0.
    pub girdle_height: f64,
    /// Flat or domed back.
    pub base: Base,
    /// `Some(f)`: the dome is polished flat where its outline gauge is below
    /// `f` (the table is the outline scaled by f, 0 < f < 1); `None`: a full
    /// dome.
    pub buff_top: Option<f64>,
}

impl Default for CabochonParams {
    /// A 10 × 8 oval with an elliptical 4-high dome, a 0.5 girdle band and a
    /// flat back.
    fn default() -> Self {
        Self {
            outline: Outline::Oval,
            length: 10.0,
            width: 8.0,
            dome_height: 4.0,
            profile_exponent: 2.0,
            girdle_height: 0.5,
            base: Base::Flat,
            buff_top: None,
        }
    }
}

/// Allowed dome profile exponents: above 1 (p = 1 is a cone with no normal
/// at its tip) up to 16 (nearly a flat-topped cylinder).
pub const PROFILE_EXPONENT_RANGE: (f64, f64) = (1.0, 16.0);

/// Upper bound on Newton steps per root; a ray that has not converged by
/// then grazes the stone and is reported as a miss.
pub(crate) const MAX_NEWTON_STEPS: usize = 64;

/// A ray–stone intersection in object space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter: `point = origin + t · dir`.
    pub t: f64,
    /// The hit point, on the surface (within the documented accuracy).
    pub point: DVec3,
    /// Unit outward surface normal (whether the ray enters or leaves).
    pub normal: DVec3,
    /// True when the ray enters the stone here, false when it leaves (its
    /// origin side is inside).
    pub entering: bool,
}

/// Which surface bounds an interval end, for its normal.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Side {
    /// The dome/band/base body `N = 1`.
    Body,
    /// The buff-top plane.
    Top,
    /// The flat base plane.
    Bottom,
}

/// Largest extent of a stone (length, width, or height from base to top), in
/// object units (mm in a scene): the BVH over stones is built in f32, where
/// 1e300 is infinite and the build panics.
pub(crate) const MAX_SIZE: f64 = 1e5;

/// A validated, analytic cabochon solid (see the module docs for the
/// geometry and accuracy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cabochon {
    params: CabochonParams,
    footprint: Footprint,
    p: f64,
    inv_h: f64,
    /// 1 / base height; 0 for a flat base (ζ = 0 below the band).
    inv_hb: f64,
    girdle: f64,
    /// Buff-top plane height, `dome_height` when there is none.
    z_top: f64,
    /// Lowest z of the stone.
    z_bottom: f64,
    flat_base: bool,
    buffed: bool,
    /// Round/oval with p = 2: closed-form quadratics.
    ellipsoidal: bool,
    /// Ellipsoidal with a flat base (any girdle band, optionally buffed):
    /// intersected by [`Self::intersect_flat_oval`].
    flat_oval: bool,
    /// `(1/a, 1/b, 1/h)`: object space to the space where the dome
    /// ellipsoid is the unit sphere.
    inv_axes: DVec3,
    size: f64,
}

impl Cabochon {
    /// Validates the parameters and precomputes the solid.
    ///
    /// Errors name the offending parameter and its allowed range: sizes must
    /// be finite and positive (`girdle_height` may be 0), `profile_exponent`
    /// in `(1, 16]`, `buff_top` in `(0, 1)`, and the outline's own rules of
    /// [`Footprint::new`].
    pub fn new(params: CabochonParams) -> Result<Self, GeometryError> {
        let footprint = Footprint::new(params.outline, params.length, params.width)?;
        let h = check_positive("dome_height", params.dome_height)?;
        let p = params.profile_exponent;
        let (p_lo, p_hi) = PROFILE_EXPONENT_RANGE;
        if !(p.is_finite() && p > p_lo && p <= p_hi) {
            return Err(GeometryError::new(
                "profile_exponent",
                p,
                format!("must be in ({p_lo}, {p_hi}] (2 is elliptical)"),
            ));
        }
        let g = params.girdle_height;
        if !(g.is_finite() && g >= 0.0) {
            return Err(GeometryError::new(
                "girdle_height",
                g,
                "must be finite and ≥ 0",
            ));
        }
        let (inv_hb, base_depth, flat_base) = match params.base {
            Base::Flat => (0.0, 0.0, true),
            Base::Domed { height } => {
                let hb = check_positive("base.height", height)?;
                (1.0 / hb, hb, false)
            }
        };
        let z_top = match params.buff_top {
            None => h,
            Some(f) => {
                if !(f.is_finite() && f > 0.0 && f < 1.0) {
                    return Err(GeometryError::new(
                        "buff_top",
                        f,
                        "the flat top fraction must be in (0, 1)",
                    ));
                }
                // The dome height where the outline gauge equals f.
                h * (1.0 - f.powf(p)).powf(1.0 / p)
            }
        };
        let z_bottom = -g - base_depth;
        let ellipsoidal = matches!(params.outline, Outline::Round | Outline::Oval) && p == 2.0;
        let flat_oval = ellipsoidal && params.base == Base::Flat;
        let size = params.length.max(params.width).max(z_top - z_bottom);
        if size.is_nan() || size > MAX_SIZE {
            // The field that makes it too large: the first above the bound
            // itself (each is finite by now), else the dome, which the girdle
            // and base add to.
            let (name, value) = [
                ("length", params.length),
                ("width", params.width),
                ("girdle_height", g),
                ("base.height", base_depth),
            ]
            .into_iter()
            .find(|(_, value)| *value > MAX_SIZE)
            .unwrap_or(("dome_height", h));
            return Err(GeometryError::new(
                name,
                value,
                format!("the stone's length, width and height (dome, girdle and base together) must each be at most {} mm (the scene's bounding boxes are f32)", crate::message::number(MAX_SIZE)),
            ));
        }
        Ok(Self {
            params,
            footprint,
            p,
            inv_h: 1.0 / h,
            inv_hb,
            girdle: g,
            z_top,
            z_bottom,
            flat_base,
            buffed: params.buff_top.is_some(),
            ellipsoidal,
            flat_oval,
            // The same quotients as `body_chord_exact`'s, so both paths scale
            // a ray identically.
            inv_axes: DVec3::new(2.0 / params.length, 2.0 / params.width, 1.0 / h),
            size,
        })
    }

    /// The validated parameters.
    pub fn params(&self) -> &CabochonParams {
        &self.params
    }

    /// The outline with its size.
    pub fn footprint(&self) -> &Footprint {
        &self.footprint
    }

    /// Whether the stone is a flat-backed oval (round/oval outline, profile
    /// exponent 2, flat base, any girdle band and buff top), intersected by
    /// `intersect_flat_oval`.
    pub fn is_flat_oval(&self) -> bool {
        self.flat_oval
    }

    /// The stone's characteristic size (largest extent), the scale of all
    /// tolerances.
    pub fn size(&self) -> f64 {
        self.size
    }

    /// Axis-aligned bounds `(min, max)` in object space, for the BVH: tight
    /// (the outline's box × the stone's z range).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let (a, b) = (0.5 * self.params.length, 0.5 * self.params.width);
        (
            DVec3::new(-a, -b, self.z_bottom),
            DVec3::new(a, b, self.z_top),
        )
    }

    /// The body function `N(x, y, z) = (sᵖ + ζᵖ)^(1/p)` (1 on the dome,
    /// band and domed base) and its gradient.
    pub fn body_and_gradient(&self, point: DVec3) -> (f64, DVec3) {
        let terms = self.body_terms(point);
        (terms.n, terms.gradient())
    }

    /// The body function's value and the parts of its gradient at `point`
    /// (see [`BodyTerms`]).
    #[inline(always)]
    fn body_terms(&self, point: DVec3) -> BodyTerms {
        let (s, grad_s) = self.footprint.gauge_and_gradient(point.x, point.y);
        let z = point.z;
        let (zeta, dzeta) = if z > 0.0 {
            (z * self.inv_h, self.inv_h)
        } else if z < -self.girdle {
            ((-self.girdle - z) * self.inv_hb, -self.inv_hb)
        } else {
            (0.0, 0.0)
        };
        let terms = |n, k_s, k_zeta| BodyTerms {
            s,
            grad_s,
            zeta,
            dzeta,
            n,
            k_s,
            k_zeta,
        };
        if zeta == 0.0 {
            return terms(s, 1.0, 0.0);
        }
        if s == 0.0 {
            return terms(zeta, 0.0, 1.0);
        }
        let p = self.p;
        if p == 2.0 {
            let n = (s * s + zeta * zeta).sqrt();
            let inv_n = 1.0 / n;
            return terms(n, s * inv_n, zeta * inv_n);
        }
        let (n, k_s, k_zeta) = p_norm(s, zeta, p);
        terms(n, k_s, k_zeta)
    }

    /// A signed distance estimate to the surface (negative inside): the
    /// body's first-order distance `(N − 1)/|∇N|`, combined by `max` with the
    /// buff-top and flat-base planes. Exact on the planes, first-order
    /// accurate near the curved surface; zero on the surface.
    pub fn implicit(&self, point: DVec3) -> f64 {
        let (n, grad) = self.body_and_gradient(point);
        let len = grad.length();
        let mut d = if len > 0.0 {
            (n - 1.0) / len
        } else {
            -self.size
        };
        if self.buffed {
            d = d.max(point.z - self.z_top);
        }
        if self.flat_base {
            d = d.max(-self.girdle - point.z);
        }
        d
    }

    /// Whether the point is inside or on the stone.
    pub fn contains(&self, point: DVec3) -> bool {
        self.implicit(point) <= 0.0
    }

    /// The unit outward normal at a surface point: the normalised gradient
    /// of the body, or ±z on the buff-top and flat-base planes (whichever
    /// surface the point is nearest).
    pub fn normal(&self, point: DVec3) -> DVec3 {
        let (n, grad) = self.body_and_gradient(point);
        self.side_normal(self.nearest_side(point, n, grad), grad)
    }

    /// Which surface a point is nearest, the body's value `n` and gradient
    /// `grad` there given: the one whose signed distance is largest.
    fn nearest_side(&self, point: DVec3, n: f64, grad: DVec3) -> Side {
        let body = (n - 1.0) / grad.length().max(f64::MIN_POSITIVE);
        let mut side = Side::Body;
        let mut best = body;
        if self.buffed && point.z - self.z_top > best {
            best = point.z - self.z_top;
            side = Side::Top;
        }
        if self.flat_base && -self.girdle - point.z > best {
            side = Side::Bottom;
        }
        side
    }

    /// How the unit outward normal at the surface point `point` turns
    /// along each of two displacements `dp` in the tangent plane there
    /// (the shape operator applied to them), for ray differentials and the
    /// manifold solver's Jacobian. The buff-top and base planes do not
    /// turn; a flat oval's dome and band are quadrics, answered in closed
    /// form, N = Hp/|Hp| with dN = (I − NNᵀ)H·dp/|Hp|; every other body by
    /// the same formula with the body function's Hessian (see
    /// `body_hessian_times`), or near its axis and girdle plane by
    /// differences of its gradient's direction over a step of 10⁻⁶ of the
    /// stone's size.
    pub fn normal_change(&self, point: DVec3, dp: [DVec3; 2]) -> [DVec3; 2] {
        if self.flat_oval {
            // The planes, to a rounding of their z (a point on the crease
            // between a plane and the body may take either).
            let tolerance = 1e-9 * self.size;
            if (self.buffed && point.z >= self.z_top - tolerance)
                || point.z <= -self.girdle + tolerance
            {
                return [DVec3::ZERO; 2];
            }
            // H = diag(1/a², 1/b², 1/h²) on the dome; the band's cylinder
            // (z ≤ 0) has no z term.
            let mut hessian = self.inv_axes * self.inv_axes;
            if point.z <= 0.0 {
                hessian.z = 0.0;
            }
            let gradient = point * hessian;
            let inv_length = 1.0 / gradient.length();
            let normal = gradient * inv_length;
            return dp.map(|d| {
                let turn = d * hessian * inv_length;
                turn - normal * normal.dot(turn)
            });
        }
        let terms = self.body_terms(point);
        let grad = terms.gradient();
        if self.nearest_side(point, terms.n, grad) != Side::Body {
            return [DVec3::ZERO; 2];
        }
        let normal = self.side_normal(Side::Body, grad);
        let step = 1e-6 * self.size;
        // Near the axis (s → 0) and the girdle plane (ζ → 0) the terms
        // ∇s/s and ∇ζ/ζ grow without bound while N stays smooth: there
        // the normal's own difference over the step.
        const NEAR_ZERO: f64 = 1e-3;
        if terms.s < NEAR_ZERO || (terms.zeta > 0.0 && terms.zeta < NEAR_ZERO) {
            return dp.map(|d| {
                let length = d.length();
                if !(length > 0.0 && length.is_finite()) {
                    return DVec3::ZERO;
                }
                let moved = self.body_and_gradient(point + d * (step / length)).1;
                (moved.try_normalize().unwrap_or(normal) - normal) * (length / step)
            });
        }
        let inv_length = 1.0 / grad.length();
        dp.map(|d| {
            let turn = self.body_hessian_times(&terms, grad, point, d, step) * inv_length;
            turn - normal * normal.dot(turn)
        })
    }

    /// The body function's Hessian times `d` at `point`, its `terms` and
    /// gradient `grad` there given. With ∇N = a∇s + b∇ζ, a = (s/N)^(p−1), b = (ζ/N)^(p−1) and ζ
    /// linear in z: H·d = a·H_s·d + ∇s (∇a·d) + ∇ζ (∇b·d), where
    /// ∇a = (p − 1)·a·(∇s/s − ∇N/N) and ∇b = (p − 1)·b·(∇ζ/ζ − ∇N/N); the
    /// outline gauge's own H_s·d by a difference of its gradient over
    /// `step` (no power of the profile: those are most of a body
    /// evaluation).
    fn body_hessian_times(
        &self,
        terms: &BodyTerms,
        grad: DVec3,
        point: DVec3,
        d: DVec3,
        step: f64,
    ) -> DVec3 {
        let length = d.length();
        if !(length > 0.0 && length.is_finite()) {
            return DVec3::ZERO;
        }
        let across = d.truncate() * (step / length);
        let moved = self
            .footprint
            .gauge_and_gradient(point.x + across.x, point.y + across.y)
            .1;
        let gauge_turn = ((moved - terms.grad_s) * (length / step)).extend(0.0);
        let grad_s = terms.grad_s.extend(0.0);
        let grad_zeta = DVec3::new(0.0, 0.0, terms.dzeta);
        let grad_n_along = grad.dot(d) / terms.n;
        let p1 = self.p - 1.0;
        let mut turn = gauge_turn * terms.k_s;
        if terms.s > 0.0 && terms.k_s > 0.0 {
            turn += grad_s * (p1 * terms.k_s * (grad_s.dot(d) / terms.s - grad_n_along));
        }
        if terms.zeta > 0.0 && terms.k_zeta > 0.0 {
            turn +=
                grad_zeta * (p1 * terms.k_zeta * (grad_zeta.dot(d) / terms.zeta - grad_n_along));
        }
        turn
    }

    fn side_normal(&self, side: Side, body_grad: DVec3) -> DVec3 {
        match side {
            Side::Body => body_grad.try_normalize().unwrap_or(DVec3::Z),
            Side::Top => DVec3::Z,
            Side::Bottom => DVec3::NEG_Z,
        }
    }

    /// The first intersection of the ray `origin + t·dir` with the stone's
    /// surface for `t_min < t < t_max`, entering or leaving.
    ///
    /// `dir` need not be normalised. Chords shorter than `1e-8 × size`
    /// (grazing rays) count as misses, so hits always come in entry/exit
    /// pairs. A flat-backed oval (round/oval, p = 2, flat base) takes
    /// `intersect_flat_oval`; every other stone
    /// [`Self::intersect_general`].
    #[inline(always)]
    pub fn intersect(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> Option<Hit> {
        if self.flat_oval {
            self.intersect_flat_oval(origin, dir, t_min, t_max)
        } else {
            self.intersect_general(origin, dir, t_min, t_max)
        }
    }

    /// Whether the ray `origin + t·dir` crosses the surface for some
    /// `t_min < t < t_max`: `self.intersect(..).is_some()`, without the hit
    /// point and normal (for shadow rays).
    #[inline(always)]
    pub fn crosses(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> bool {
        if self.flat_oval {
            self.flat_oval_chord(origin, dir)
                .is_some_and(|c| c.span.first_end(t_min, t_max).is_some())
        } else {
            self.intersect_general(origin, dir, t_min, t_max).is_some()
        }
    }

    /// Where the ray `origin + t·dir` from a point inside the stone leaves
    /// it (t > 0): [`Self::intersect`]`(origin, dir, 0, ∞)`, an exit;
    /// `None` when the ray meets no surface ahead. Only the far end of the
    /// chord is sought, so an origin outside is not detected: the answer
    /// is then the far end of the chord ahead, if any.
    ///
    /// A flat-backed oval's far end is the far root of the one quadric the
    /// ray leaves through (the dome above z = 0, the band's cylinder
    /// below), clipped by the plane it may cross first, so one square root
    /// instead of the chord's two; other stones take `exit_general`.
    #[inline]
    pub fn exit(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        if !self.flat_oval {
            return self.exit_general(origin, dir);
        }
        let origin_scaled = origin * self.inv_axes;
        let dir_scaled = dir * self.inv_axes;
        // The far root of |o + t·d|² = 1 (over x, y only for the band's
        // cylinder), by `Chord::between_unit_roots`' formula; None for a
        // line that misses the quadric or a zero, infinite or NaN ray.
        let far_root = |o: DVec3, d: DVec3| -> Option<f64> {
            let (dd, od, c) = (d.dot(d), o.dot(d), o.dot(o) - 1.0);
            let disc = od * od - dd * c;
            if !(disc >= 0.0 && dd > 0.0 && dd < f64::INFINITY) {
                return None;
            }
            let q = -(od + disc.sqrt().copysign(od));
            (q != 0.0).then(|| (q / dd).max(c / q))
        };
        let plane = |z: f64| (z - origin.z) / dir.z;
        // The dome part: its far root, cut by the buff top when rising.
        let leave_dome = || -> Option<(f64, Side)> {
            let t_dome = far_root(origin_scaled, dir_scaled)?;
            if self.buffed && dir.z > 0.0 && plane(self.z_top) < t_dome {
                Some((plane(self.z_top), Side::Top))
            } else {
                Some((t_dome, Side::Body))
            }
        };
        // The band part: its cylinder's far root, cut by the base when
        // falling; a half ellipsoid's band is the base plane z = 0 itself.
        let leave_band = || -> Option<(f64, Side)> {
            if self.girdle == 0.0 {
                return (dir.z < 0.0).then(|| (plane(0.0), Side::Bottom));
            }
            let (o2, d2) = (origin_scaled.truncate(), dir_scaled.truncate());
            let t_band = if d2 == DVec2::ZERO {
                // Vertical: inside the cylinder for every t, or never.
                (o2.length_squared() <= 1.0).then_some(f64::INFINITY)?
            } else {
                far_root(o2.extend(0.0), d2.extend(0.0))?
            };
            if dir.z < 0.0 && plane(-self.girdle) < t_band {
                Some((plane(-self.girdle), Side::Bottom))
            } else {
                Some((t_band, Side::Body))
            }
        };
        // Above z = 0 the stone is the dome below the buff top, below it
        // the band down to the base: a ray leaves through the part it is
        // in when that part's far end comes before the plane z = 0, else
        // through the other part (which then holds the crossing of z = 0).
        let in_dome = origin.z > 0.0 || (origin.z == 0.0 && dir.z >= 0.0);
        let (t, side) = if in_dome {
            let (t, side) = leave_dome()?;
            if dir.z < 0.0 && t > plane(0.0) {
                leave_band()?
            } else {
                (t, side)
            }
        } else {
            let (t, side) = leave_band()?;
            if dir.z > 0.0 && t > plane(0.0) {
                leave_dome()?
            } else {
                (t, side)
            }
        };
        if !(t > 0.0 && t < f64::INFINITY) {
            return None;
        }
        let chord = Chord {
            span: Span {
                t_in: f64::NEG_INFINITY,
                t_out: t,
                side_in: side,
                side_out: side,
            },
            origin_scaled,
            dir_scaled,
        };
        self.flat_oval_hit(chord, origin, dir, 0.0, f64::INFINITY)
    }

    /// [`Self::intersect`] by the general pipeline for every stone: the body
    /// chord (exact quadratics for round/oval p = 2 stones, else Newton),
    /// clipped by the buff-top and flat-base planes, the normal from the
    /// body's gradient. Public so that the fast path can be checked
    /// against it.
    pub fn intersect_general(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        let chord = if self.ellipsoidal {
            self.body_chord_exact(origin, dir).map(ChordEnd::pair)
        } else {
            self.body_chord_newton(origin, dir)
        };
        self.finish(origin, dir, t_min, t_max, chord)
    }

    /// [`Self::exit`] for every stone but a flat oval: the far end of the
    /// body chord alone (a round or oval p = 2 stone's by its quadratics;
    /// any other by the Newton search `body_chord_newton` runs for it, from
    /// the far side of the box back towards the origin: the same iterates,
    /// so the same t), cut by the buff top when rising and the flat base
    /// when falling. Half the Newton work of the whole chord, whose near
    /// end lies behind a ray from inside.
    fn exit_general(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        if !(origin.is_finite() && dir.is_finite()) || dir == DVec3::ZERO {
            return None;
        }
        let body_exit = if self.ellipsoidal {
            ChordEnd::at(self.body_chord_exact(origin, dir)?.1)
        } else {
            let (_, t_far) = self.box_range(origin, dir)?;
            let tol = 1e-12 * self.size / dir.length();
            // A body exit behind the origin (or none) is no exit.
            self.newton_root(origin, dir, t_far, 0.0, tol, -1.0)?
        };
        let mut span = Span::body(f64::NEG_INFINITY, body_exit.t);
        self.clip_by_planes(&mut span, origin, dir);
        let (t, side) = (span.t_out, span.side_out);
        if !(t > 0.0 && t < f64::INFINITY) {
            return None;
        }
        let point = origin + t * dir;
        Some(Hit {
            t,
            point,
            normal: self.end_normal(side, body_exit, point),
            entering: false,
        })
    }

    /// [`Self::intersect`] for a flat-backed oval, in the space where the
    /// dome is the unit sphere, `(x/a, y/b, z/h)`. Without a girdle band
    /// (a half ellipsoid) one quadratic, clipped by the base plane z = 0 and
    /// the buff top; with one, the union of that dome piece above z = 0 and
    /// the band's elliptic-cylinder piece for −g ≤ z ≤ 0. The normal is the
    /// gradient `(x/a², y/b², z/h²)` of `(x/a)² + (y/b)² + (z/h)²` on the
    /// dome, `(x/a², y/b², 0)` on the band, normalised.
    ///
    /// The same roots, clipping (`Span::clip`) and minimum chord as
    /// [`Self::intersect_general`]; it differs only where that path's
    /// `1e-12 × size` tolerance in z lets a root of the other patch stand in
    /// at a rim, and in the last bits of the normal.
    #[inline(always)]
    pub(crate) fn intersect_flat_oval(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        let chord = self.flat_oval_chord(origin, dir)?;
        self.flat_oval_hit(chord, origin, dir, t_min, t_max)
    }

    /// The hit at the first end of a flat oval's chord in (t_min, t_max).
    #[inline(always)]
    fn flat_oval_hit(
        &self,
        chord: Chord,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        let (t, side, entering) = chord.span.first_end(t_min, t_max)?;
        let normal = match side {
            Side::Body => {
                // The unit-sphere point at t, mapped by the inverse axes once
                // more: ∇((x/a)² + (y/b)² + (z/h)²) / 2 on the dome; on the
                // band (z ≤ 0) the cylinder's (x/a², y/b², 0).
                let mut unit_point = chord.origin_scaled + t * chord.dir_scaled;
                unit_point.z = unit_point.z.max(0.0);
                (unit_point * self.inv_axes).normalize()
            }
            Side::Top => DVec3::Z,
            Side::Bottom => DVec3::NEG_Z,
        };
        Some(Hit {
            t,
            point: origin + t * dir,
            normal,
            entering,
        })
    }

    /// The chord of the line through a flat-backed oval (see
    /// [`Self::intersect_flat_oval`]), `None` for a miss or a chord below
    /// the minimum length.
    #[inline(always)]
    fn flat_oval_chord(&self, origin: DVec3, dir: DVec3) -> Option<Chord> {
        if self.girdle > 0.0 {
            self.banded_oval_chord(origin, dir)
        } else {
            self.half_ellipsoid_chord(origin, dir)
        }
    }

    /// [`Self::flat_oval_chord`] without a girdle band: the dome
    /// ellipsoid's chord, clipped by the base z = 0 and the buff top.
    #[inline(always)]
    fn half_ellipsoid_chord(&self, origin: DVec3, dir: DVec3) -> Option<Chord> {
        let origin_scaled = origin * self.inv_axes;
        let dir_scaled = dir * self.inv_axes;
        let dd = dir_scaled.dot(dir_scaled);
        let od = origin_scaled.dot(dir_scaled);
        let c = origin_scaled.dot(origin_scaled) - 1.0;
        let disc = od * od - dd * c;
        // Most misses leave here (also a NaN discriminant, from a NaN or
        // infinite origin or direction).
        if disc < 0.0 || disc.is_nan() {
            return None;
        }
        // Refuses a zero or infinite direction (an infinite origin with a
        // finite direction left a NaN or −∞ discriminant above).
        if !(dd > 0.0 && dd < f64::INFINITY) {
            return None;
        }
        let mut chord = Chord::between_unit_roots(od, dd, c, origin_scaled, dir_scaled)?;
        // As `finish`: the buff top, then the base.
        if self.buffed {
            chord
                .span
                .clip(origin.z, dir.z, self.z_top, true, Side::Top);
        }
        chord
            .span
            .clip(origin.z, dir.z, -self.girdle, false, Side::Bottom);
        self.long_enough(&chord.span, dir).then_some(chord)
    }

    /// [`Self::flat_oval_chord`] with a girdle band: the union of the dome
    /// piece (the ellipsoid's chord for z ≥ 0, below the buff top) and the
    /// band piece (the elliptic cylinder's chord for −g ≤ z ≤ 0). The
    /// cylinder holds the whole stone, so a line that misses it misses.
    /// Never inlined, so that the half ellipsoid's path stays small.
    #[inline(never)]
    fn banded_oval_chord(&self, origin: DVec3, dir: DVec3) -> Option<Chord> {
        let origin_scaled = origin * self.inv_axes;
        let dir_scaled = dir * self.inv_axes;
        let (o2, d2) = (origin_scaled.truncate(), dir_scaled.truncate());
        let (dd2, od2, c2) = (d2.dot(d2), o2.dot(d2), o2.dot(o2) - 1.0);
        let disc2 = od2 * od2 - dd2 * c2;
        if disc2 < 0.0 || disc2.is_nan() {
            return None;
        }
        let dd = dir_scaled.dot(dir_scaled);
        // Refuses a zero, infinite or NaN direction or origin.
        if !(dd > 0.0 && dd < f64::INFINITY && origin_scaled.is_finite()) {
            return None;
        }
        let mut band = if dd2 > 0.0 {
            Chord::between_unit_roots(od2, dd2, c2, origin_scaled, dir_scaled)?
        } else if c2 <= 0.0 {
            // A vertical line inside the cylinder: inside it for every t.
            Chord {
                span: Span::body(f64::NEG_INFINITY, f64::INFINITY),
                origin_scaled,
                dir_scaled,
            }
        } else {
            return None;
        };
        // The z = 0 end of the band piece continues into the dome piece.
        band.span.clip(origin.z, dir.z, 0.0, true, Side::Body);
        band.span
            .clip(origin.z, dir.z, -self.girdle, false, Side::Bottom);
        let od = origin_scaled.dot(dir_scaled);
        let c = origin_scaled.dot(origin_scaled) - 1.0;
        let disc = od * od - dd * c;
        let dome = if disc >= 0.0 {
            Chord::between_unit_roots(od, dd, c, origin_scaled, dir_scaled).map(|mut dome| {
                if self.buffed {
                    dome.span.clip(origin.z, dir.z, self.z_top, true, Side::Top);
                }
                dome.span.clip(origin.z, dir.z, 0.0, false, Side::Body);
                dome
            })
        } else {
            None
        };
        // Also refuses NaN ends.
        let band = (band.span.t_in < band.span.t_out).then_some(band);
        let dome = dome.filter(|d| d.span.t_in < d.span.t_out);
        let chord = match (band, dome) {
            (Some(mut band), Some(dome)) => {
                if dome.span.t_in < band.span.t_in {
                    band.span.t_in = dome.span.t_in;
                    band.span.side_in = dome.span.side_in;
                }
                if dome.span.t_out > band.span.t_out {
                    band.span.t_out = dome.span.t_out;
                    band.span.side_out = dome.span.side_out;
                }
                band
            }
            (Some(piece), None) | (None, Some(piece)) => piece,
            (None, None) => return None,
        };
        self.long_enough(&chord.span, dir).then_some(chord)
    }

    /// Whether the span is at least `1e-8 × size` long: shorter ones
    /// (grazing rays) count as misses, so hits come in entry/exit pairs.
    #[inline(always)]
    fn long_enough(&self, span: &Span, dir: DVec3) -> bool {
        let min_chord = 1e-8 * self.size / dir.length();
        // Also refuses NaN spans.
        span.t_out - span.t_in >= min_chord
    }

    /// Like [`Self::intersect`] but always by Newton iteration, also for
    /// ellipsoidal stones; public so that the exact and iterative solvers can
    /// be checked against each other.
    pub fn intersect_iterative(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
    ) -> Option<Hit> {
        let chord = self.body_chord_newton(origin, dir);
        self.finish(origin, dir, t_min, t_max, chord)
    }

    /// Clips the body chord by the planes and picks the first end in range.
    fn finish(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f64,
        t_max: f64,
        chord: Option<(ChordEnd, ChordEnd)>,
    ) -> Option<Hit> {
        let (body_entry, body_exit) = chord?;
        let mut span = Span::body(body_entry.t, body_exit.t);
        self.clip_by_planes(&mut span, origin, dir);
        if !self.long_enough(&span, dir) {
            return None;
        }
        let (t, side, entering) = span.first_end(t_min, t_max)?;
        let point = origin + t * dir;
        let body_end = if entering { body_entry } else { body_exit };
        Some(Hit {
            t,
            point,
            normal: self.end_normal(side, body_end, point),
            entering,
        })
    }

    /// Cuts a body chord's span by the buff-top plane and the flat base,
    /// where the stone has them.
    fn clip_by_planes(&self, span: &mut Span, origin: DVec3, dir: DVec3) {
        if self.buffed {
            span.clip(origin.z, dir.z, self.z_top, true, Side::Top);
        }
        if self.flat_base {
            span.clip(origin.z, dir.z, -self.girdle, false, Side::Bottom);
        }
    }

    /// The unit outward normal at `point`, an end of a chord on `side`;
    /// on the body from the gradient its root search left in `body_end`,
    /// if any (within the search's tolerance of the point), else from the
    /// gradient there.
    fn end_normal(&self, side: Side, body_end: ChordEnd, point: DVec3) -> DVec3 {
        let grad = match (side, body_end.gradient) {
            (Side::Body, Some(grad)) => grad,
            (Side::Body, None) => self.body_and_gradient(point).1,
            _ => DVec3::ZERO,
        };
        self.side_normal(side, grad)
    }

    /// The line's parameter range inside the bounding box grown by a small
    /// margin (so both ends are strictly outside the body), if any.
    fn box_range(&self, origin: DVec3, dir: DVec3) -> Option<(f64, f64)> {
        let (lo, hi) = self.bounds();
        let pad = DVec3::splat(1e-6 * self.size);
        let (lo, hi) = (lo - pad, hi + pad);
        let mut t0 = f64::NEG_INFINITY;
        let mut t1 = f64::INFINITY;
        for axis in 0..3 {
            let (o, d) = (origin[axis], dir[axis]);
            if d == 0.0 {
                if o < lo[axis] || o > hi[axis] {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo[axis] - o) / d, (hi[axis] - o) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        (t0 < t1 && t0.is_finite() && t1.is_finite()).then_some((t0, t1))
    }

    /// Entry and exit of the line through the body `N ≤ 1` (ignoring the
    /// planes), by Newton's method from each end of the box range. `N − 1`
    /// is convex along the line, so each Newton iterate started outside stays
    /// outside and approaches its root monotonically; a step away from the
    /// body or beyond the range means a miss.
    fn body_chord_newton(&self, origin: DVec3, dir: DVec3) -> Option<(ChordEnd, ChordEnd)> {
        if !(origin.is_finite() && dir.is_finite()) || dir == DVec3::ZERO {
            return None;
        }
        let (t0, t1) = self.box_range(origin, dir)?;
        let tol = 1e-12 * self.size / dir.length();
        let entry = self.newton_root(origin, dir, t0, t1, tol, 1.0)?;
        let exit = self.newton_root(origin, dir, t1, entry.t, tol, -1.0)?;
        Some((entry, exit))
    }

    /// Newton on `f(t) = N(origin + t·dir) − 1` from `start` towards `limit`
    /// (`sense` = +1 forwards, −1 backwards): the root, with the body's
    /// gradient at the last point evaluated (the root itself, or a step of
    /// at most `tol` from it), which serves as the normal there.
    fn newton_root(
        &self,
        origin: DVec3,
        dir: DVec3,
        start: f64,
        limit: f64,
        tol: f64,
        sense: f64,
    ) -> Option<ChordEnd> {
        let mut t = start;
        for _ in 0..MAX_NEWTON_STEPS {
            let (n, grad) = self.body_and_gradient(origin + t * dir);
            let f = n - 1.0;
            if f <= 0.0 {
                return Some(ChordEnd::with_gradient(t, grad));
            }
            // Slope along the search direction; must point into the body.
            let slope = grad.dot(dir) * sense;
            if slope >= 0.0 {
                return None;
            }
            let step = -f / slope;
            t += sense * step;
            if (t - limit) * sense > 0.0 {
                return None;
            }
            if step <= tol {
                return Some(ChordEnd::with_gradient(t, grad));
            }
        }
        None
    }

    /// Exact entry and exit for round/oval stones with p = 2: the dome
    /// ellipsoid (z ≥ 0), the band's elliptic cylinder (−g ≤ z ≤ 0, or all
    /// z ≤ 0 over a flat base) and the base ellipsoid (z ≤ −g). Each root on
    /// its own patch is a boundary point of the convex body, so entry and
    /// exit are the smallest and largest of them.
    fn body_chord_exact(&self, origin: DVec3, dir: DVec3) -> Option<(f64, f64)> {
        if !(origin.is_finite() && dir.is_finite()) || dir == DVec3::ZERO {
            return None;
        }
        let inv_ab = DVec2::new(2.0 / self.params.length, 2.0 / self.params.width);
        let eps = 1e-12 * self.size;
        let g = self.girdle;
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let z_at = |t: f64| origin.z + t * dir.z;
        let mut keep = |t: f64, z_ok: bool| {
            if z_ok {
                lo = lo.min(t);
                hi = hi.max(t);
            }
        };
        let o2 = origin.truncate() * inv_ab;
        let d2 = dir.truncate() * inv_ab;
        // Dome: (x/a)² + (y/b)² + (z/h)² = 1 for z ≥ 0.
        let o3 = o2.extend(origin.z * self.inv_h);
        let d3 = d2.extend(dir.z * self.inv_h);
        for t in quadratic_unit_roots(o3.dot(o3), o3.dot(d3), d3.dot(d3)) {
            keep(t, z_at(t) >= -eps);
        }
        // Band: (x/a)² + (y/b)² = 1.
        if g > 0.0 || self.flat_base {
            let flat = self.flat_base;
            for t in quadratic_unit_roots(o2.dot(o2), o2.dot(d2), d2.dot(d2)) {
                let z = z_at(t);
                keep(t, z <= eps && (flat || z >= -g - eps));
            }
            // A vertical line never crosses the band's wall: inside the
            // outline it runs down the flat-backed band, unbounded below
            // until `finish` clips it at the base plane z = −g; a point one
            // stone size below that plane stands for the band's end (a
            // point on the plane itself would make `finish` keep the band,
            // not the base, as the surface hit).
            if flat && d2 == DVec2::ZERO && o2.dot(o2) <= 1.0 {
                keep((-g - self.size - origin.z) / dir.z, true);
            }
        }
        // Domed base: (x/a)² + (y/b)² + ((z + g)/h_b)² = 1 for z ≤ −g.
        if !self.flat_base {
            let o3 = o2.extend((origin.z + g) * self.inv_hb);
            let d3 = d2.extend(dir.z * self.inv_hb);
            for t in quadratic_unit_roots(o3.dot(o3), o3.dot(d3), d3.dot(d3)) {
                keep(t, z_at(t) <= -g + eps);
            }
        }
        (lo < hi).then_some((lo, hi))
    }
}

/// The parameter range of a line inside a stone, with the surface that
/// bounds each end: the body chord cut by the stone's planes.
#[derive(Debug, Clone, Copy)]
struct Span {
    t_in: f64,
    t_out: f64,
    side_in: Side,
    side_out: Side,
}

impl Span {
    /// The body's chord (t_in, t_out), bounded by the body at both ends.
    #[inline(always)]
    fn body(t_in: f64, t_out: f64) -> Self {
        Self {
            t_in,
            t_out,
            side_in: Side::Body,
            side_out: Side::Body,
        }
    }

    /// Keeps the part of the span with z ≤ `plane_z` (`below`) or
    /// z ≥ `plane_z`; an end the plane cuts off is bounded by `side` now.
    #[inline]
    fn clip(&mut self, origin_z: f64, dir_z: f64, plane_z: f64, below: bool, side: Side) {
        if dir_z == 0.0 {
            let outside = if below {
                origin_z > plane_z
            } else {
                origin_z < plane_z
            };
            if outside {
                self.t_out = f64::NEG_INFINITY;
            }
            return;
        }
        let t = (plane_z - origin_z) / dir_z;
        if (dir_z > 0.0) == below {
            if t < self.t_out {
                self.t_out = t;
                self.side_out = side;
            }
        } else if t > self.t_in {
            self.t_in = t;
            self.side_in = side;
        }
    }

    /// The first end in `(t_min, t_max)`: its t, side and whether the line
    /// enters there.
    #[inline]
    fn first_end(&self, t_min: f64, t_max: f64) -> Option<(f64, Side, bool)> {
        if self.t_in > t_min && self.t_in < t_max {
            Some((self.t_in, self.side_in, true))
        } else if self.t_out > t_min && self.t_out < t_max {
            Some((self.t_out, self.side_out, false))
        } else {
            None
        }
    }
}

/// The body function `N = (sᵖ + ζᵖ)^(1/p)` at a point with its parts:
/// the outline gauge `s` and its gradient, the normalised height `ζ` and
/// its z derivative, and the factors `k_s = (s/N)^(p−1)`,
/// `k_ζ = (ζ/N)^(p−1)` of the gradient `∇N = k_s∇s + k_ζ∇ζ`.
#[derive(Debug, Clone, Copy)]
struct BodyTerms {
    s: f64,
    grad_s: DVec2,
    zeta: f64,
    dzeta: f64,
    n: f64,
    k_s: f64,
    k_zeta: f64,
}

impl BodyTerms {
    /// ∇N.
    #[inline(always)]
    fn gradient(&self) -> DVec3 {
        (self.grad_s * self.k_s).extend(self.dzeta * self.k_zeta)
    }
}

/// One end of a body chord: its t and, where the root search evaluated
/// the body there, its gradient.
#[derive(Debug, Clone, Copy)]
struct ChordEnd {
    t: f64,
    gradient: Option<DVec3>,
}

impl ChordEnd {
    /// An end without a gradient (found in closed form).
    fn at(t: f64) -> Self {
        Self { t, gradient: None }
    }

    /// An end whose search left the body's gradient there.
    fn with_gradient(t: f64, gradient: DVec3) -> Self {
        Self {
            t,
            gradient: Some(gradient),
        }
    }

    /// Both ends of a closed-form chord.
    fn pair((t_in, t_out): (f64, f64)) -> (Self, Self) {
        (Self::at(t_in), Self::at(t_out))
    }
}

/// The span of a line inside a flat-backed oval and the line in
/// unit-sphere space (for the normal).
#[derive(Debug, Clone, Copy)]
struct Chord {
    span: Span,
    origin_scaled: DVec3,
    dir_scaled: DVec3,
}

impl Chord {
    /// The chord between the roots of `|o + t·d|² = 1`, given `o·d`, `d·d`
    /// and `o·o − 1` with a non-negative discriminant, by
    /// `quadratic_unit_roots`' cancellation-free formula; `None` for the
    /// single root at t = 0 (a chord of length 0).
    #[inline(always)]
    fn between_unit_roots(
        od: f64,
        dd: f64,
        c: f64,
        origin_scaled: DVec3,
        dir_scaled: DVec3,
    ) -> Option<Self> {
        let disc = od * od - dd * c;
        let q = -(od + disc.sqrt().copysign(od));
        if q == 0.0 {
            return None;
        }
        let (r0, r1) = (q / dd, c / q);
        Some(Self {
            span: Span::body(r0.min(r1), r0.max(r1)),
            origin_scaled,
            dir_scaled,
        })
    }
}

/// Roots of `|o + t·d|² = 1` given `oo = o·o`, `od = o·d`, `dd = d·d`, by
/// the cancellation-free form of the quadratic formula.
fn quadratic_unit_roots(oo: f64, od: f64, dd: f64) -> impl Iterator<Item = f64> {
    let c = oo - 1.0;
    let disc = od * od - dd * c;
    let roots = if dd > 0.0 && disc >= 0.0 {
        let q = -(od + disc.sqrt().copysign(od));
        if q == 0.0 {
            [Some(0.0), None]
        } else {
            [Some(q / dd), Some(c / q)]
        }
    } else {
        [None, None]
    };
    roots.into_iter().flatten()
}
