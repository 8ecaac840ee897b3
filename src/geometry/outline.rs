//! Cabochon outlines: the shape of the girdle seen from above.
//!
//! Every outline is described by its *gauge function* `s(x, y)` (the
//! Minkowski functional of the outline about its gauge centre): `s = 0` at the
//! centre, `s = 1` on the outline, `s < 1` inside, and `s(c + λ·v) = λ·s(c + v)`
//! for λ ≥ 0. Because every outline here is convex, `s` is convex, which makes
//! the whole cabochon solid convex (see [`super::cabochon`]) and ray hits easy
//! to bracket. The signed outline function is `g(x, y) = s(x, y) − 1`
//! (`g ≤ 0` inside).
//!
//! Coordinates: x along the length, y along the width, the origin at the
//! centre of the outline's bounding box. `a = length / 2`, `b = width / 2`.
//!
//! | outline | definition |
//! |---|---|
//! | `Round`, `Oval` | ellipse `(x/a)² + (y/b)² = 1` (round: `a = b`) |
//! | `Cushion { n }` | superellipse `|x/a|ⁿ + |y/b|ⁿ = 1`, `2 < n ≤ 16` |
//! | `Marquise` | lens: intersection of the discs `x² + (y ∓ c)² ≤ R²` with `c = (a² − b²) / 2b`, `R = b + c`; points at `(±a, 0)` |
//! | `Pear` | a round end, the half disc `(x − x_c)² + y² ≤ b²` for `x ≤ x_c` with `x_c = −a + b`, joined tangentially at `(x_c, ±b)` to a half marquise of half-length `d = 2a − b` ending in a point at `(a, 0)` |

use glam::DVec2;

use super::error::{check_positive, GeometryError};

/// The family of a cabochon's outline (girdle shape seen from above).
///
/// Plain data; the sizes live in [`Footprint`], which precomputes the
/// constants each shape needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Outline {
    /// A circle; `length` must equal `width`.
    Round,
    /// An ellipse with semi-axes `length / 2` (x) and `width / 2` (y).
    Oval,
    /// A superellipse `|x/a|ⁿ + |y/b|ⁿ = 1`: a rounded rectangle, squarer as
    /// `exponent` (n, in `(2, 16]`) grows.
    Cushion {
        /// The superellipse exponent n, `2 < n ≤ 16`.
        exponent: f64,
    },
    /// A teardrop: a round end at −x blended tangentially into a point at +x
    /// (`length > width`).
    Pear,
    /// A lens (navette): two circular arcs meeting in points at ±x
    /// (`length > width`).
    Marquise,
}

/// Smallest and largest allowed [`Outline::Cushion`] exponent (the lower
/// bound is exclusive: n = 2 is an [`Outline::Oval`]).
pub const CUSHION_EXPONENT_RANGE: (f64, f64) = (2.0, 16.0);

/// An [`Outline`] with its size: the gauge function, its gradient, and
/// boundary points, in coordinates centred on the outline's bounding box.
///
/// Built by [`Footprint::new`], which validates the parameters; fields are
/// private so that the precomputed constants always match the outline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    outline: Outline,
    /// Half length `a` (x) and half width `b` (y).
    half: DVec2,
    /// `1/a`, `1/b`: multiplications instead of divisions in the hot path.
    inv_half: DVec2,
    /// Gauge centre (the dome's apex); the origin except for a pear.
    centre: DVec2,
    /// Lens constants: half-length of the (half) marquise and circle offset c.
    lens_a: f64,
    lens_c: f64,
}

impl Footprint {
    /// Validates `length` (x) and `width` (y) for `outline` and precomputes
    /// the shape constants.
    ///
    /// Refused: non-finite or non-positive sizes; a `Round` whose width
    /// differs from its length (use `Oval`); a `Pear` or `Marquise` that is
    /// not longer than wide (no point would form); a cushion exponent outside
    /// `(2, 16]`.
    pub fn new(outline: Outline, length: f64, width: f64) -> Result<Self, GeometryError> {
        let length = check_positive("length", length)?;
        let width = check_positive("width", width)?;
        let (a, b) = (0.5 * length, 0.5 * width);
        let mut fp = Footprint {
            outline,
            half: DVec2::new(a, b),
            inv_half: DVec2::new(1.0 / a, 1.0 / b),
            centre: DVec2::ZERO,
            lens_a: a,
            lens_c: 0.0,
        };
        match outline {
            Outline::Round => {
                if (length - width).abs() > 1e-12 * length {
                    return Err(GeometryError::new(
                        "width",
                        width,
                        format!("must equal length ({length}) for a Round outline (use Oval)"),
                    ));
                }
            }
            Outline::Oval => {}
            Outline::Cushion { exponent } => {
                let (lo, hi) = CUSHION_EXPONENT_RANGE;
                if !(exponent.is_finite() && exponent > lo && exponent <= hi) {
                    return Err(GeometryError::new(
                        "exponent",
                        exponent,
                        format!("the Cushion exponent must be in ({lo}, {hi}] (2 is an Oval)"),
                    ));
                }
            }
            Outline::Pear | Outline::Marquise => {
                if width >= length {
                    return Err(GeometryError::new(
                        "width",
                        width,
                        format!("must be < length ({length}) for a pointed {outline:?} outline"),
                    ));
                }
                if outline == Outline::Pear {
                    // Round end of radius b centred at x_c; the point at x = a.
                    fp.centre = DVec2::new(-a + b, 0.0);
                    fp.lens_a = length - b;
                }
                // Lens through (±lens_a, 0) and (0, ±b): c = (a² − b²) / 2b.
                fp.lens_c = (fp.lens_a * fp.lens_a - b * b) / (2.0 * b);
            }
        }
        Ok(fp)
    }

    /// The outline family.
    pub fn outline(&self) -> Outline {
        self.outline
    }

    /// Full length (x extent).
    pub fn length(&self) -> f64 {
        2.0 * self.half.x
    }

    /// Full width (y extent).
    pub fn width(&self) -> f64 {
        2.0 * self.half.y
    }

    /// The gauge centre: where `s = 0` and the dome has its apex. The origin
    /// for all outlines except `Pear`, whose apex sits at the round end's
    /// centre `(−a + b, 0)`.
    pub fn centre(&self) -> DVec2 {
        self.centre
    }

    /// The normalised outline radius `s(x, y)` (gauge function): 0 at the
    /// centre, 1 on the outline, homogeneous of degree 1 about the centre.
    pub fn gauge(&self, x: f64, y: f64) -> f64 {
        self.gauge_and_gradient(x, y).0
    }

    /// The signed outline function `g = s − 1`: negative inside, zero on the
    /// outline; smooth except at the points of a pear or marquise.
    pub fn outline_function(&self, x: f64, y: f64) -> f64 {
        self.gauge(x, y) - 1.0
    }

    /// Whether `(x, y)` lies inside or on the outline.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        self.gauge(x, y) <= 1.0
    }

    /// The point of the outline in direction `angle` (radians) seen from the
    /// gauge centre; for plots and tests. `angle` may be any real number.
    pub fn boundary_point(&self, angle: f64) -> DVec2 {
        let u = DVec2::new(angle.cos(), angle.sin());
        // Homogeneity: s(c + u / s(c + u)) = 1.
        self.centre + u / self.gauge(self.centre.x + u.x, self.centre.y + u.y)
    }

    /// The outline radius from the gauge centre in direction `angle`
    /// (radians), as a fraction of the half length `a`.
    pub fn radius_fraction(&self, angle: f64) -> f64 {
        (self.boundary_point(angle) - self.centre).length() / self.half.x
    }

    /// `s(x, y)` and its gradient `(∂s/∂x, ∂s/∂y)`.
    ///
    /// The gradient is the analytic one; at the centre (where `s` has a cone
    /// point) and on the symmetry axis of a point (where `|y|` has a kink) a
    /// one-sided value is returned. Callers multiply it by `p·s^(p−1)`, which
    /// vanishes at the centre.
    pub(crate) fn gauge_and_gradient(&self, x: f64, y: f64) -> (f64, DVec2) {
        let (ia, ib) = (self.inv_half.x, self.inv_half.y);
        match self.outline {
            Outline::Round | Outline::Oval => {
                let (u, v) = (x * ia, y * ib);
                let s = (u * u + v * v).sqrt();
                if s == 0.0 {
                    return (0.0, DVec2::ZERO);
                }
                let inv_s = 1.0 / s;
                (s, DVec2::new(u * ia * inv_s, v * ib * inv_s))
            }
            Outline::Cushion { exponent: n } => {
                let (u, v) = ((x * ia).abs(), (y * ib).abs());
                if u.max(v) == 0.0 {
                    return (0.0, DVec2::ZERO);
                }
                // ∂s/∂u = (u/s)^(n−1), ∂s/∂v = (v/s)^(n−1).
                let (s, k_u, k_v) = p_norm(u, v, n);
                (s, DVec2::new(k_u.copysign(x) * ia, k_v.copysign(y) * ib))
            }
            Outline::Marquise => self.lens_gauge(x, y),
            Outline::Pear => {
                let xr = x - self.centre.x;
                if xr <= 0.0 {
                    let r = (xr * xr + y * y).sqrt();
                    if r == 0.0 {
                        return (0.0, DVec2::ZERO);
                    }
                    (r * ib, DVec2::new(xr, y) * (ib / r))
                } else {
                    self.lens_gauge(xr, y)
                }
            }
        }
    }

    /// Gauge of the lens through `(±lens_a, 0)` and `(0, ±b)`, centred at the
    /// origin: the ray from the centre meets the arc of the disc centred at
    /// `(0, −c)` (for y ≥ 0) at radius `r`, and `s = |p| / r` simplifies to
    /// `s = (c|y| + √(c²y² + A²(x² + y²))) / A²`.
    fn lens_gauge(&self, x: f64, y: f64) -> (f64, DVec2) {
        let (la, c) = (self.lens_a, self.lens_c);
        let la2 = la * la;
        let ay = y.abs();
        let q = (c * c * y * y + la2 * (x * x + y * y)).sqrt();
        if q == 0.0 {
            return (0.0, DVec2::ZERO);
        }
        let s = (c * ay + q) / la2;
        let dx = x / q;
        let dy = (c.copysign(y) + (c * c + la2) * y / q) / la2;
        (s, DVec2::new(dx, dy))
    }
}

/// The p-norm `N = (aᵖ + bᵖ)^(1/p)` of `a, b ≥ 0`, not both 0, and the
/// factors `(a/N)^(p−1)`, `(b/N)^(p−1)` of its gradient. With m the larger
/// of the two and r = smaller/m ≤ 1: N = m·Q, Q = q^(1/p), q = 1 + rᵖ; the
/// larger's factor is Q/q = Q^(1−p), the smaller's r^(p−1)·Q/q = (rᵖ/r)·Q/q.
/// Two powers (where aᵖ⁻¹, bᵖ⁻¹ and Σ^(1/p) took three: they are most of a
/// Newton-intersected stone's time), and rᵖ ≤ 1 never overflows.
#[inline]
pub(crate) fn p_norm(a: f64, b: f64, p: f64) -> (f64, f64, f64) {
    let (m, r) = if a >= b { (a, b / a) } else { (b, a / b) };
    let r_p = pow(r, p);
    let q = 1.0 + r_p;
    let big_q = root(q, p);
    let k_larger = big_q / q;
    // r = 0: the smaller term has no slope (p > 1).
    let k_smaller = if r > 0.0 { r_p / r * k_larger } else { 0.0 };
    if a >= b {
        (m * big_q, k_larger, k_smaller)
    } else {
        (m * big_q, k_smaller, k_larger)
    }
}

/// `x^e` for `x ≥ 0`, by repeated multiplication when `e` is a whole number
/// (the usual cushion and profile exponents), which is several times faster
/// than `powf` in the Newton loop.
#[inline]
pub(crate) fn pow(x: f64, e: f64) -> f64 {
    if e == e.trunc() && e.abs() <= 32.0 {
        x.powi(e as i32)
    } else {
        x.powf(e)
    }
}

/// `x^(1/e)` for `x ≥ 0`, by `sqrt`/`cbrt` for e = 2, 3, 4 (the common
/// exponents), else `powf`.
#[inline]
pub(crate) fn root(x: f64, e: f64) -> f64 {
    if e == 2.0 {
        x.sqrt()
    } else if e == 3.0 {
        x.cbrt()
    } else if e == 4.0 {
        x.sqrt().sqrt()
    } else {
        x.powf(1.0 / e)
    }
}
