//! Cabochon outlines and analytic ray intersection: shapes match their
//! defining equations, hits lie on the surface with outward unit normals,
//! the solid is closed, the ellipsoid agrees with the closed form.

use glam::DVec3;
use lapidary::geometry::{Base, Cabochon, CabochonParams, Footprint, Outline};
use std::f64::consts::TAU;

/// splitmix64: a tiny deterministic generator, so tests need no new crates.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    fn in_box(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }
    fn direction(&mut self) -> DVec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, TAU);
        let r = (1.0 - z * z).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

fn stone(outline: Outline, length: f64, width: f64) -> CabochonParams {
    CabochonParams {
        outline,
        length,
        width,
        ..CabochonParams::default()
    }
}

/// A spread of stones: every outline, low and high domes, girdles, bases and
/// buff tops.
fn stones() -> Vec<(&'static str, Cabochon)> {
    let mk = |p: CabochonParams| Cabochon::new(p).unwrap();
    vec![
        ("round ellipsoid", mk(stone(Outline::Round, 8.0, 8.0))),
        ("oval", mk(stone(Outline::Oval, 12.0, 7.0))),
        (
            "oval low dome, double",
            mk(CabochonParams {
                profile_exponent: 1.4,
                base: Base::Domed { height: 1.5 },
                ..stone(Outline::Oval, 12.0, 9.0)
            }),
        ),
        (
            "cushion",
            mk(CabochonParams {
                profile_exponent: 3.0,
                ..stone(Outline::Cushion { exponent: 4.0 }, 10.0, 9.0)
            }),
        ),
        (
            "cushion squarish buff top",
            mk(CabochonParams {
                buff_top: Some(0.5),
                girdle_height: 0.0,
                ..stone(Outline::Cushion { exponent: 10.0 }, 10.0, 10.0)
            }),
        ),
        (
            "pear",
            mk(CabochonParams {
                dome_height: 3.0,
                ..stone(Outline::Pear, 14.0, 9.0)
            }),
        ),
        (
            "marquise double high",
            mk(CabochonParams {
                profile_exponent: 6.0,
                base: Base::Domed { height: 2.0 },
                ..stone(Outline::Marquise, 16.0, 7.0)
            }),
        ),
        (
            "oval half ellipsoid",
            mk(CabochonParams {
                girdle_height: 0.0,
                dome_height: 2.5,
                ..stone(Outline::Oval, 10.0, 7.0)
            }),
        ),
        (
            "round half ellipsoid buff top",
            mk(CabochonParams {
                girdle_height: 0.0,
                buff_top: Some(0.4),
                ..stone(Outline::Round, 6.0, 6.0)
            }),
        ),
        (
            "round double ellipsoid",
            mk(CabochonParams {
                base: Base::Domed { height: 2.5 },
                buff_top: Some(0.3),
                ..stone(Outline::Round, 6.0, 6.0)
            }),
        ),
    ]
}

#[test]
fn outlines_match_their_defining_equations() {
    let (l, w) = (14.0, 9.0);
    let (a, b) = (l / 2.0, w / 2.0);
    let tol = 0.005 * l;
    // Each: the outline, and the distance-like error of a point against the
    // defining equation typed here (not taken from the library).
    type Eq = Box<dyn Fn(f64, f64) -> f64>;
    let lens = |half_len: f64| {
        let c = (half_len * half_len - b * b) / (2.0 * b);
        (c, b + c)
    };
    let (cm, rm) = lens(a);
    let xc = -a + b;
    let (cp, rp) = lens(l - b);
    let cases: Vec<(Outline, f64, Eq)> = vec![
        (
            Outline::Round,
            l,
            Box::new(move |x, y| ((x * x + y * y).sqrt() - a).abs()),
        ),
        (
            Outline::Oval,
            w,
            Box::new(move |x, y| a * (((x / a).powi(2) + (y / b).powi(2)).sqrt() - 1.0).abs()),
        ),
        (
            Outline::Cushion { exponent: 5.0 },
            w,
            Box::new(move |x, y| {
                a * (((x / a).abs().powf(5.0) + (y / b).abs().powf(5.0)).powf(0.2) - 1.0).abs()
            }),
        ),
        (
            Outline::Marquise,
            w,
            // Upper arc centred at (0, −c), lower at (0, +c), radius R.
            Box::new(move |x, y| ((x * x + (y.abs() + cm).powi(2)).sqrt() - rm).abs()),
        ),
        (
            Outline::Pear,
            w,
            Box::new(move |x, y| {
                let xr = x - xc;
                if xr <= 0.0 {
                    ((xr * xr + y * y).sqrt() - b).abs()
                } else {
                    ((xr * xr + (y.abs() + cp).powi(2)).sqrt() - rp).abs()
                }
            }),
        ),
    ];
    let mut rng = Rng(7);
    for (outline, width, eq) in cases {
        let fp = Footprint::new(outline, l, width).unwrap();
        let mut max_x = f64::NEG_INFINITY;
        let mut min_x = f64::INFINITY;
        let mut max_y = f64::NEG_INFINITY;
        for i in 0..720 {
            let t = TAU * i as f64 / 720.0;
            let q = fp.boundary_point(t);
            let err = eq(q.x, q.y);
            assert!(
                err < tol,
                "{outline:?} boundary_point({t}) = {q} off by {err}"
            );
            assert!((fp.outline_function(q.x, q.y)).abs() < 1e-9);
            max_x = max_x.max(q.x);
            min_x = min_x.min(q.x);
            max_y = max_y.max(q.y);
        }
        // The extents are the given length and width, centred on the box.
        assert!(
            (max_x - l / 2.0).abs() < tol && (min_x + l / 2.0).abs() < tol,
            "{outline:?} x extent"
        );
        assert!(
            (max_y - width / 2.0).abs() < tol,
            "{outline:?} y extent {max_y}"
        );
        // contains() agrees with the equation away from the boundary: a point
        // is inside iff it is nearer the centre than the boundary point in
        // its direction.
        for _ in 0..2000 {
            let x = rng.range(-a * 1.1, a * 1.1);
            let y = rng.range(-b * 1.1, b * 1.1);
            if eq(x, y) < tol {
                continue;
            }
            let c = fp.centre();
            let angle = (y - c.y).atan2(x - c.x);
            let inside = (x - c.x).hypot(y - c.y) < (fp.boundary_point(angle) - c).length();
            assert_eq!(fp.contains(x, y), inside, "{outline:?} contains({x}, {y})");
        }
        // radius_fraction is the boundary's distance over the half length.
        let r = fp.radius_fraction(0.0);
        assert!((r * a - (fp.boundary_point(0.0) - fp.centre()).length()).abs() < 1e-12);
    }
}

#[test]
fn hits_lie_on_the_surface_with_outward_unit_normals() {
    let mut rng = Rng(11);
    for (name, stone) in stones() {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        let mut hits = 0;
        for _ in 0..2000 {
            let origin = centre + 3.0 * size * rng.direction();
            let dir = rng.in_box(lo, hi) - origin;
            let Some(hit) = stone.intersect(origin, dir, 0.0, f64::INFINITY) else {
                continue;
            };
            hits += 1;
            let d = stone.implicit(hit.point);
            assert!(
                d.abs() < 1e-7 * size,
                "{name}: hit {} off the surface by {d}",
                hit.point
            );
            assert!(hit.entering, "{name}: a ray from outside must enter first");
            assert!(
                (hit.normal.length() - 1.0).abs() < 1e-12,
                "{name}: normal not unit"
            );
            assert!(
                hit.normal.dot(dir) < 0.0,
                "{name}: entering normal faces away"
            );
            assert!((hit.point - (origin + hit.t * dir)).length() < 1e-9 * size);
            let pad = DVec3::splat(1e-7 * size);
            assert!(hit.point.cmpge(lo - pad).all() && hit.point.cmple(hi + pad).all());
        }
        assert!(
            hits > 500,
            "{name}: only {hits} of 2000 rays into the box hit"
        );
    }
}

#[test]
fn rays_leaving_a_stone_outwards_never_meet_it_again() {
    // Every cabochon is convex (convex outline gauge, profile exponent
    // > 1, planes cutting half-spaces), so the plane tangent at a surface
    // point has the whole stone behind it: a ray starting just outside the
    // surface and pointing to the normal's side cannot come back. The
    // renderer relies on it to skip the stone a shadow ray or a bounce
    // leaves (`World::intersect_leaving`); here it is checked on every
    // shape, including nearly tangent rays, and the same rays pointing
    // inwards (not grazing) must all hit (so the test can fail).
    let mut rng = Rng(23);
    for (name, stone) in stones() {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        let mut leaving = 0;
        for _ in 0..400 {
            let origin = centre + 3.0 * size * rng.direction();
            let Some(hit) =
                stone.intersect(origin, rng.in_box(lo, hi) - origin, 0.0, f64::INFINITY)
            else {
                continue;
            };
            let start = hit.point + hit.normal * (1e-7 * size);
            for k in 0..20 {
                let mut d = rng.direction();
                if d.dot(hit.normal) < 0.0 {
                    d -= 2.0 * d.dot(hit.normal) * hit.normal;
                }
                if k < 5 {
                    // Nearly tangent: cos = 10⁻⁶ … 10⁻².
                    let tangent = (d - d.dot(hit.normal) * hit.normal).normalize();
                    let cos = 10f64.powi(-2 - k);
                    d = tangent * (1.0 - cos * cos).sqrt() + hit.normal * cos;
                }
                leaving += 1;
                assert!(
                    stone.intersect(start, d, 0.0, f64::INFINITY).is_none(),
                    "{name}: a ray leaving {} along {d} (normal {}) met the stone again",
                    hit.point,
                    hit.normal
                );
                // Started just outside, an inward ray must not be too
                // grazing to dip into the stone (the surface curves away).
                if k >= 5 && d.dot(hit.normal) > 0.1 {
                    let inward = -d;
                    assert!(
                        stone.intersect(start, inward, 0.0, f64::INFINITY).is_some(),
                        "{name}: the inward ray from {} along {inward} (normal {}) missed",
                        hit.point,
                        hit.normal
                    );
                }
            }
        }
        assert!(leaving > 2000, "{name}: only {leaving} rays tested");
    }
}

#[test]
fn every_ray_crosses_the_surface_an_even_number_of_times() {
    let mut rng = Rng(23);
    let all = stones();
    let per_stone = 10_000;
    for (name, stone) in &all {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        for i in 0..per_stone {
            let origin = centre + 2.0 * size * rng.direction();
            // Half aimed into the box, half anywhere (mostly misses).
            let dir = if i % 2 == 0 {
                rng.in_box(lo, hi) - origin
            } else {
                rng.direction()
            };
            let step = 1e-9 * size / dir.length();
            let mut t = 0.0;
            let mut crossings = 0;
            while let Some(hit) = stone.intersect(origin, dir, t, f64::INFINITY) {
                assert_eq!(
                    hit.entering,
                    crossings % 2 == 0,
                    "{name}: entries and exits alternate"
                );
                crossings += 1;
                t = hit.t + step;
                assert!(
                    crossings <= 4,
                    "{name}: a convex stone is crossed at most twice"
                );
            }
            assert_eq!(
                crossings % 2,
                0,
                "{name}: ray {origin} {dir} crossed {crossings} times"
            );
        }
        // From inside, every direction leaves the stone.
        let mut inside = 0;
        while inside < 500 {
            let origin = rng.in_box(lo, hi);
            if stone.implicit(origin) > -1e-6 * size {
                continue;
            }
            inside += 1;
            let dir = rng.direction();
            let hit = stone
                .intersect(origin, dir, 0.0, f64::INFINITY)
                .unwrap_or_else(|| panic!("{name}: ray from inside {origin} along {dir} escaped"));
            assert!(
                !hit.entering && hit.normal.dot(dir) > 0.0,
                "{name}: exit normal"
            );
        }
    }
}

/// The ellipsoid cap over a flat base, solved in the test from its equation
/// (x/a)² + (y/b)² + (z/h)² = 1, z ≥ 0, plus the disc z = 0.
fn closed_form_entry(a: f64, b: f64, h: f64, o: DVec3, d: DVec3) -> Option<(f64, DVec3)> {
    let s = DVec3::new(1.0 / a, 1.0 / b, 1.0 / h);
    let (os, ds) = (o * s, d * s);
    let (qa, qb, qc) = (ds.dot(ds), 2.0 * os.dot(ds), os.dot(os) - 1.0);
    let disc = qb * qb - 4.0 * qa * qc;
    let mut best: Option<(f64, DVec3)> = None;
    let mut consider = |t: f64, n: DVec3| {
        if t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, n));
        }
    };
    if disc >= 0.0 {
        for t in [
            (-qb - disc.sqrt()) / (2.0 * qa),
            (-qb + disc.sqrt()) / (2.0 * qa),
        ] {
            let p = o + t * d;
            if p.z >= 0.0 {
                consider(t, (p * s * s).normalize());
            }
        }
    }
    if d.z != 0.0 {
        let t = -o.z / d.z;
        let p = o + t * d;
        if (p.x / a).powi(2) + (p.y / b).powi(2) <= 1.0 {
            consider(t, DVec3::NEG_Z);
        }
    }
    best
}

#[test]
fn ellipsoid_agrees_with_the_closed_form_quadratic() {
    let mut rng = Rng(5);
    for (outline, l, w, h) in [
        (Outline::Round, 8.0, 8.0, 3.0),
        (Outline::Oval, 12.0, 7.0, 5.0),
    ] {
        let stone = Cabochon::new(CabochonParams {
            girdle_height: 0.0,
            dome_height: h,
            ..stone(outline, l, w)
        })
        .unwrap();
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let (mut compared, mut mismatched) = (0, 0);
        for _ in 0..5000 {
            let origin = 0.5 * (lo + hi) + 3.0 * size * rng.direction();
            let dir = rng.in_box(lo, hi) - origin;
            let expect = closed_form_entry(l / 2.0, w / 2.0, h, origin, dir);
            let got = stone.intersect(origin, dir, 0.0, f64::INFINITY);
            let iter = stone.intersect_iterative(origin, dir, 0.0, f64::INFINITY);
            match (expect, got) {
                (Some((t, n)), Some(hit)) => {
                    compared += 1;
                    let dl = dir.length();
                    assert!(
                        (hit.t - t).abs() * dl < 1e-9 * size,
                        "{outline:?}: t {} vs {t}",
                        hit.t
                    );
                    assert!((hit.normal - n).length() < 1e-7, "{outline:?}: normal");
                    let it = iter.expect("the iterative solver misses where the exact one hits");
                    assert!(
                        (it.t - t).abs() * dl < 1e-9 * size,
                        "iterative t {} vs {t}",
                        it.t
                    );
                    assert!((it.normal - n).length() < 1e-6, "iterative normal");
                }
                (None, None) => {}
                // Grazing rays may differ by the minimum chord rule.
                (e, g) => {
                    let graze = e.map_or(g.map_or(0.0, |h| h.t), |(t, _)| t);
                    let p = origin + graze * dir;
                    assert!(
                        stone.implicit(p).abs() < 1e-6 * size,
                        "{outline:?}: {e:?} vs {g:?}"
                    );
                    mismatched += 1;
                }
            }
        }
        assert!(compared > 2000, "only {compared} hits compared");
        assert!(
            mismatched <= 3,
            "{outline:?}: {mismatched} grazing disagreements"
        );
    }
}

#[test]
fn normals_match_finite_differences_of_the_surface() {
    let mut rng = Rng(31);
    for (name, stone) in stones() {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        let pointed = matches!(stone.params().outline, Outline::Pear | Outline::Marquise);
        let fp = *stone.footprint();
        let mut checked = 0;
        for _ in 0..2000 {
            let origin = centre + 3.0 * size * rng.direction();
            let dir = rng.in_box(lo, hi) - origin;
            let Some(hit) = stone.intersect(origin, dir, 0.0, f64::INFINITY) else {
                continue;
            };
            let p = hit.point;
            // Skip the kinks: the points of pear and marquise, and the rims
            // where a buff top or flat base meets the dome.
            if pointed && p.y.abs() < 1e-3 * size && p.x > fp.centre().x {
                continue;
            }
            let h = 1e-6 * size;
            let body = |q: DVec3| stone.body_and_gradient(q).0;
            let is_plane = hit.normal.z.abs() == 1.0 && hit.normal.x == 0.0 && hit.normal.y == 0.0;
            let fd = if is_plane {
                if body(p) > 1.0 - 1e-4 {
                    continue;
                }
                // The plane's own normal: finite differences of z.
                DVec3::Z * hit.normal.z
            } else {
                if (p.z - hi.z).abs() < 1e-4 * size || (p.z - lo.z).abs() < 1e-4 * size {
                    continue;
                }
                let g = DVec3::new(
                    body(p + DVec3::X * h) - body(p - DVec3::X * h),
                    body(p + DVec3::Y * h) - body(p - DVec3::Y * h),
                    body(p + DVec3::Z * h) - body(p - DVec3::Z * h),
                );
                g.normalize()
            };
            checked += 1;
            assert!(
                (stone.normal(p) - hit.normal).length() < 1e-9,
                "{name}: normal()"
            );
            let err = (fd - hit.normal).length();
            assert!(
                err < 1e-4,
                "{name}: normal {} vs finite differences {fd} at {p}",
                hit.normal
            );
        }
        assert!(checked > 300, "{name}: only {checked} normals checked");
    }
}

#[test]
fn bad_parameters_are_refused_with_the_parameter_named() {
    let base = CabochonParams::default();
    let cases: Vec<(CabochonParams, &str)> = vec![
        (
            CabochonParams {
                length: -1.0,
                ..base
            },
            "length",
        ),
        (
            CabochonParams {
                length: 0.0,
                ..base
            },
            "length",
        ),
        (
            CabochonParams {
                width: f64::NAN,
                ..base
            },
            "width",
        ),
        (
            CabochonParams {
                dome_height: 0.0,
                ..base
            },
            "dome_height",
        ),
        (
            CabochonParams {
                dome_height: f64::INFINITY,
                ..base
            },
            "dome_height",
        ),
        (
            CabochonParams {
                profile_exponent: 1.0,
                ..base
            },
            "profile_exponent",
        ),
        (
            CabochonParams {
                profile_exponent: 40.0,
                ..base
            },
            "profile_exponent",
        ),
        (
            CabochonParams {
                profile_exponent: f64::NAN,
                ..base
            },
            "profile_exponent",
        ),
        (
            CabochonParams {
                girdle_height: -0.1,
                ..base
            },
            "girdle_height",
        ),
        (
            CabochonParams {
                base: Base::Domed { height: 0.0 },
                ..base
            },
            "base.height",
        ),
        (
            CabochonParams {
                buff_top: Some(1.0),
                ..base
            },
            "buff_top",
        ),
        (
            CabochonParams {
                buff_top: Some(-0.2),
                ..base
            },
            "buff_top",
        ),
        (
            CabochonParams {
                outline: Outline::Cushion { exponent: 2.0 },
                ..base
            },
            "exponent",
        ),
        (
            CabochonParams {
                outline: Outline::Cushion { exponent: 17.0 },
                ..base
            },
            "exponent",
        ),
        (
            CabochonParams {
                outline: Outline::Round,
                ..base
            },
            "width",
        ),
        (
            CabochonParams {
                outline: Outline::Marquise,
                width: 10.0,
                ..base
            },
            "width",
        ),
        (
            CabochonParams {
                outline: Outline::Pear,
                width: 12.0,
                ..base
            },
            "width",
        ),
    ];
    for (params, name) in cases {
        let err = Cabochon::new(params).expect_err(name);
        assert_eq!(err.name, name, "{params:?}");
        let msg = err.to_string();
        assert!(
            msg.contains(&format!("`{name}`")) && msg.contains("must"),
            "{msg}"
        );
    }
    assert!(Cabochon::new(base).is_ok());
}

/// Timing note, not a benchmark: `cargo test --release --test geometry_shapes
/// -- --ignored --nocapture`.
#[test]
#[ignore]
fn time_a_million_intersections() {
    let cases = [
        ("ellipsoid (round, p = 2)", stone(Outline::Round, 8.0, 8.0)),
        (
            "cushion n = 4, p = 3",
            CabochonParams {
                profile_exponent: 3.0,
                ..stone(Outline::Cushion { exponent: 4.0 }, 10.0, 9.0)
            },
        ),
        ("oval p = 2, Newton", stone(Outline::Oval, 12.0, 7.0)),
    ];
    for (i, (name, params)) in cases.into_iter().enumerate() {
        let stone = Cabochon::new(params).unwrap();
        let (lo, hi) = stone.bounds();
        let mut rng = Rng(99);
        let rays: Vec<(DVec3, DVec3)> = (0..1_000_000)
            .map(|_| {
                let o = 0.5 * (lo + hi) + 2.0 * stone.size() * rng.direction();
                (o, rng.in_box(lo, hi) - o)
            })
            .collect();
        let start = std::time::Instant::now();
        let mut hits = 0usize;
        for &(o, d) in &rays {
            let h = if i == 2 {
                stone.intersect_iterative(o, d, 0.0, f64::INFINITY)
            } else {
                stone.intersect(o, d, 0.0, f64::INFINITY)
            };
            hits += std::hint::black_box(h).is_some() as usize;
        }
        let ns = start.elapsed().as_nanos() as f64 / rays.len() as f64;
        println!("{name}: {ns:.1} ns per intersection ({hits} hits)");
        // Exits from points inside, as the paths and the manifold solver
        // within a translucent stone ask for them (`exit` has no iterative
        // twin: the third case would repeat the first's closed form).
        if i == 2 {
            continue;
        }
        let mut inner: Vec<(DVec3, DVec3)> = Vec::with_capacity(1_000_000);
        while inner.len() < 1_000_000 {
            let o = rng.in_box(lo, hi);
            if stone.contains(o) {
                inner.push((o, rng.direction()));
            }
        }
        let start = std::time::Instant::now();
        let exits: usize = inner
            .iter()
            .map(|&(o, d)| usize::from(std::hint::black_box(stone.exit(o, d)).is_some()))
            .sum();
        let ns = start.elapsed().as_nanos() as f64 / inner.len() as f64;
        println!("{name}: {ns:.1} ns per exit from inside ({exits} exits)");
    }
}

#[test]
fn exact_and_iterative_solvers_agree_with_girdle_domed_base_and_buff_top() {
    let mut rng = Rng(41);
    let params = [
        CabochonParams {
            base: Base::Domed { height: 2.5 },
            buff_top: Some(0.3),
            girdle_height: 0.8,
            ..stone(Outline::Round, 6.0, 6.0)
        },
        CabochonParams {
            base: Base::Domed { height: 1.0 },
            ..stone(Outline::Oval, 9.0, 5.0)
        },
        CabochonParams {
            girdle_height: 1.5,
            ..stone(Outline::Oval, 9.0, 5.0)
        },
    ];
    for params in params {
        let stone = Cabochon::new(params).unwrap();
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let (mut compared, mut mismatched) = (0, 0);
        for _ in 0..3000 {
            let origin = 0.5 * (lo + hi) + 3.0 * size * rng.direction();
            let dir = rng.in_box(lo, hi) - origin;
            let exact = stone.intersect(origin, dir, 0.0, f64::INFINITY);
            let iter = stone.intersect_iterative(origin, dir, 0.0, f64::INFINITY);
            if let (Some(e), Some(i)) = (exact, iter) {
                compared += 1;
                assert!(
                    (e.t - i.t).abs() * dir.length() < 1e-9 * size,
                    "{params:?}: t"
                );
                assert!((e.normal - i.normal).length() < 1e-6, "{params:?}: normal");
            } else if let Some(h) = exact.or(iter) {
                // Only grazing rays may disagree: one solver's hit on a chord
                // near the minimum length.
                let far = stone.intersect_iterative(origin, dir, h.t, f64::INFINITY);
                let chord = far.map_or(0.0, |f| (f.t - h.t) * dir.length());
                assert!(chord < 1e-6 * size, "{params:?}: {exact:?} vs {iter:?}");
                mismatched += 1;
            }
        }
        assert!(compared > 1000);
        assert!(
            mismatched <= 3,
            "{params:?}: {mismatched} rays hit by one solver only"
        );
    }
}

#[test]
fn extreme_stones_and_axis_aligned_rays_stay_watertight() {
    let extremes = [
        CabochonParams {
            profile_exponent: 16.0,
            ..stone(Outline::Cushion { exponent: 16.0 }, 10.0, 10.0)
        },
        CabochonParams {
            profile_exponent: 1.05,
            dome_height: 6.0,
            ..stone(Outline::Marquise, 10.0, 3.0)
        },
        CabochonParams {
            dome_height: 0.05,
            girdle_height: 0.0,
            base: Base::Domed { height: 0.02 },
            ..stone(Outline::Pear, 10.0, 6.0)
        },
        CabochonParams {
            profile_exponent: 2.5,
            buff_top: Some(0.95),
            ..stone(Outline::Cushion { exponent: 2.01 }, 1e-3, 0.9e-3)
        },
    ];
    let mut rng = Rng(77);
    for params in extremes {
        let stone = Cabochon::new(params).unwrap();
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        for i in 0..4000 {
            let target = rng.in_box(lo, hi);
            // Far cameras, axis-aligned rays and rays through the apex.
            let dir = match i % 4 {
                0 => rng.direction(),
                1 => [DVec3::X, DVec3::Y, DVec3::Z, DVec3::NEG_Z][i / 4 % 4],
                2 => DVec3::new(0.0, 0.0, -1.0) + 1e-9 * rng.direction(),
                _ => target - (centre + 1e4 * size * rng.direction()),
            };
            let target = if i % 4 == 2 {
                DVec3::new(stone.footprint().centre().x, 0.0, 0.0)
            } else {
                target
            };
            // Case 3 starts 10⁴ sizes away: dir reaches the target at t = 1.
            let origin = if i % 4 == 3 {
                target - dir
            } else {
                target - 3.0 * size * dir / dir.length()
            };
            let step = 1e-9 * size / dir.length();
            let (mut t, mut crossings) = (0.0, 0);
            while let Some(hit) = stone.intersect(origin, dir, t, f64::INFINITY) {
                assert!(stone.implicit(hit.point).abs() < 1e-7 * size, "{params:?}");
                assert!((hit.normal.length() - 1.0).abs() < 1e-12);
                assert_eq!(hit.entering, hit.normal.dot(dir) < 0.0, "{params:?}");
                crossings += 1;
                t = hit.t + step;
                assert!(crossings <= 2, "{params:?}: {origin} {dir}");
            }
            assert!(
                crossings % 2 == 0,
                "{params:?}: {origin} {dir} crossed {crossings}"
            );
            if i % 4 == 2 {
                assert_eq!(crossings, 2, "{params:?}: a vertical ray through the apex");
            }
        }
    }
}

/// Flat-backed ovals (round/oval, p = 2, flat base) of several proportions:
/// half ellipsoids (no girdle band) and banded ones, with and without a
/// buff top.
/// [`stones`] and [`flat_ovals`] together.
fn every_stone() -> Vec<Cabochon> {
    let mut all: Vec<Cabochon> = stones().into_iter().map(|(_, s)| s).collect();
    all.extend(flat_ovals());
    all
}

fn flat_ovals() -> Vec<Cabochon> {
    let oval = |outline, l, w, h, girdle_height, buff_top| {
        Cabochon::new(CabochonParams {
            girdle_height,
            dome_height: h,
            buff_top,
            ..stone(outline, l, w)
        })
        .unwrap()
    };
    vec![
        // The peer scene's stone (bench/peer-scene.ron).
        oval(Outline::Oval, 2.0, 1.4, 0.45, 0.0, None),
        oval(Outline::Round, 8.0, 8.0, 3.0, 0.0, None),
        oval(Outline::Oval, 12.0, 5.0, 9.0, 0.0, None),
        oval(Outline::Oval, 10.0, 7.0, 4.0, 0.0, Some(0.5)),
        // The studio scene's stone (gem-recipes/scenes/studio.ron).
        oval(Outline::Oval, 10.0, 8.0, 4.0, 0.5, None),
        oval(Outline::Round, 6.0, 6.0, 1.5, 2.0, Some(0.3)),
    ]
}

#[test]
fn flat_oval_fast_path_agrees_with_the_general_path() {
    // The fast path clips the dome's quadratic (and the band cylinder's) by
    // the planes itself; the general path collects the roots of every patch
    // within a z tolerance, then clips, and takes the normal from the body
    // gradient via the outline gauge. Away from the rim they must
    // agree to rounding: the same t (the same quotients), the same side
    // (entering), normals within 1e-12. Rays start outside and inside,
    // aim at the box, the rim and the base plane, and some lie in planes.
    let mut rng = Rng(77);
    for stone in flat_ovals() {
        assert!(stone.is_flat_oval());
        let girdle = stone.params().girdle_height;
        let at_rim = |p: DVec3| {
            p.z.abs() < 1e-9 * stone.size() || (p.z + girdle).abs() < 1e-9 * stone.size()
        };
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        let (mut hits, mut misses, mut rim) = (0, 0, 0);
        for i in 0..20_000 {
            let origin = match i % 4 {
                0 => centre + 3.0 * size * rng.direction(),
                1 => rng.in_box(lo, hi),
                2 => DVec3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), 0.0),
                _ => centre + 0.7 * size * rng.direction(),
            };
            let mut dir = if i % 3 == 0 {
                rng.in_box(lo, hi) - origin
            } else {
                rng.direction() * rng.range(0.1, 10.0)
            };
            if i % 17 == 0 {
                dir.z = 0.0;
            }
            let t_min = if i % 5 == 0 {
                rng.range(-1.0, 1.0)
            } else {
                0.0
            };
            let fast = stone.intersect(origin, dir, t_min, f64::INFINITY);
            let general = stone.intersect_general(origin, dir, t_min, f64::INFINITY);
            assert_eq!(
                fast.is_some(),
                stone.crosses(origin, dir, t_min, f64::INFINITY),
                "crosses disagrees with intersect"
            );
            match (fast, general) {
                (Some(f), Some(g)) if f.t == g.t && f.entering == g.entering => {
                    hits += 1;
                    assert_eq!(f.point, g.point);
                    assert!(
                        (f.normal - g.normal).length() < 1e-12 || at_rim(f.point),
                        "normal {} vs {} at {}",
                        f.normal,
                        g.normal,
                        f.point
                    );
                    assert!((f.normal.length() - 1.0).abs() < 1e-15);
                }
                (None, None) => misses += 1,
                // Only at a rim (z = 0 or −g) may the general path's
                // 1e-12 × size tolerance keep a root of the other patch, or a
                // chord differ in length by rounding.
                (f, g) => {
                    let hit = f.or(g).unwrap();
                    assert!(
                        at_rim(hit.point),
                        "{f:?} vs {g:?} from {origin} along {dir}"
                    );
                    rim += 1;
                }
            }
        }
        assert!(hits > 5000 && misses > 2000, "{hits} hits, {misses} misses");
        assert!(rim <= 5, "{rim} rays disagree at the rim");
    }
}

#[test]
fn exit_from_inside_agrees_with_intersect_on_every_stone() {
    // `exit` (the manifold solver's surface, from inside) finds a flat
    // oval's far end by one quadric instead of the whole chord: from
    // points inside, it must give `intersect`'s exit — the same t and side,
    // to rounding — including rays in the girdle plane, vertical ones and
    // ones that cross from the band into the dome or back.
    let mut rng = Rng(123);
    for stone in every_stone() {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let (mut exits, mut band_to_dome) = (0, 0);
        for i in 0..20_000 {
            let origin = rng.in_box(lo, hi);
            if !stone.contains(origin) {
                continue;
            }
            let mut dir = rng.direction();
            match i % 13 {
                0 => dir.z = 0.0,
                1 => dir = DVec3::new(0.0, 0.0, dir.z.signum()),
                _ => {}
            }
            let expected = stone.intersect(origin, dir, 0.0, f64::INFINITY);
            let exit = stone.exit(origin, dir);
            let (Some(e), Some(x)) = (expected, exit) else {
                panic!("{expected:?} vs {exit:?} from {origin} along {dir}");
            };
            assert!(!e.entering && !x.entering);
            assert!(
                (e.t - x.t).abs() <= 1e-12 * size,
                "t {} vs {} from {origin} along {dir}",
                e.t,
                x.t
            );
            assert!(
                (e.normal - x.normal).length() < 1e-9,
                "normal {} vs {} at {}",
                e.normal,
                x.normal,
                e.point
            );
            exits += 1;
            if origin.z < 0.0 && e.point.z > 0.0 {
                band_to_dome += 1;
            }
        }
        assert!(exits > 2000, "{exits} exits");
        if stone.is_flat_oval() && stone.params().girdle_height > 0.0 {
            assert!(band_to_dome > 20, "{band_to_dome} rays from band to dome");
        }
    }
}

#[test]
fn crosses_agrees_with_intersect_on_every_stone() {
    // `crosses` (shadow rays) must answer exactly whether `intersect` finds
    // a crossing in (t_min, t_max), for every shape, including short
    // segments that end inside the stone.
    let mut rng = Rng(91);
    for stone in every_stone() {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let centre = 0.5 * (lo + hi);
        let (mut yes, mut no) = (0, 0);
        for _ in 0..4000 {
            let origin = centre + 2.0 * size * rng.direction();
            let dir = (rng.in_box(lo, hi) - origin).normalize();
            let t_max = rng.range(0.5, 4.0) * size;
            let crosses = stone.crosses(origin, dir, 0.0, t_max);
            assert_eq!(crosses, stone.intersect(origin, dir, 0.0, t_max).is_some());
            if crosses {
                yes += 1;
            } else {
                no += 1;
            }
        }
        assert!(yes > 500 && no > 200, "{yes} crossings, {no} misses");
    }
}

#[test]
fn flat_oval_refuses_non_finite_and_zero_rays() {
    // Like the general path, which refuses them up front: a NaN or infinite
    // origin or direction, or a zero direction, is a miss, not a NaN hit;
    // with and without a girdle band.
    for stone in [&flat_ovals()[0], &flat_ovals()[4]] {
        let inside = DVec3::new(0.1, 0.1, 0.1);
        for (origin, dir) in [
            (DVec3::new(f64::NAN, 0.0, 1.0), DVec3::NEG_Z),
            (DVec3::new(f64::INFINITY, 0.0, 1.0), DVec3::NEG_Z),
            (inside, DVec3::new(f64::INFINITY, 0.0, 0.0)),
            (inside, DVec3::new(f64::NAN, 0.0, 0.0)),
            (inside, DVec3::new(f64::INFINITY, 1.0, -1.0)),
            (inside, DVec3::ZERO),
        ] {
            assert!(stone.intersect(origin, dir, 0.0, f64::INFINITY).is_none());
            assert!(!stone.crosses(origin, dir, 0.0, f64::INFINITY));
            assert!(stone
                .intersect_general(origin, dir, 0.0, f64::INFINITY)
                .is_none());
        }
        // The same inside point with a finite direction does hit (leaving).
        let hit = stone
            .intersect(inside, DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert!(!hit.entering);
    }
}

#[test]
fn flat_oval_meets_vertical_rays() {
    // A ray straight down through a flat-backed oval enters the dome at
    // z = h·√(1 − (x/a)² − (y/b)²) (or the buff top) and leaves through the
    // base at z = −g (written out from the definition); straight up it
    // enters through the base. Both the fast path (`intersect`) and the
    // general one (`intersect_general`, whose band quadratic has no roots
    // when the direction has no x, y part) must find these.
    for stone in flat_ovals() {
        for (origin, direction) in [
            (DVec3::new(0.3, -0.2, 5.0), DVec3::NEG_Z),
            (DVec3::new(-0.1, 0.25, -5.0), DVec3::Z),
            (DVec3::new(0.0, 0.0, 0.01), DVec3::NEG_Z),
        ] {
            let o =
                origin * DVec3::new(stone.params().length / 2.0, stone.params().width / 2.0, 1.0);
            let fast = stone.intersect(o, direction, 0.0, f64::INFINITY);
            let general = stone.intersect_general(o, direction, 0.0, f64::INFINITY);
            let (fast, general) = (
                fast.expect("fast path hits"),
                general.expect("general path hits"),
            );
            assert_eq!(fast.t, general.t);
            assert_eq!(fast.entering, general.entering);
            assert!(
                (fast.normal - general.normal).length() < 1e-12,
                "{origin} {direction}: {} vs {}",
                fast.normal,
                general.normal
            );
        }
    }
    for stone in flat_ovals() {
        let p = *stone.params();
        let (a, b, h, g) = (
            p.length / 2.0,
            p.width / 2.0,
            p.dome_height,
            p.girdle_height,
        );
        let (x, y) = (0.3 * a, -0.2 * b);
        let dome_z = h * (1.0 - (x / a).powi(2) - (y / b).powi(2)).sqrt();
        let top = dome_z.min(stone.bounds().1.z);
        let down = stone
            .intersect(DVec3::new(x, y, 2.0 * h), DVec3::NEG_Z, 0.0, f64::INFINITY)
            .expect("a vertical ray through the dome");
        assert!((down.point.z - top).abs() < 1e-12 * stone.size());
        assert!(down.entering && down.normal.z > 0.0);
        let out = stone
            .intersect(
                DVec3::new(x, y, 0.5 * top),
                DVec3::NEG_Z,
                0.0,
                f64::INFINITY,
            )
            .expect("from inside out through the base");
        assert!((out.point.z + g).abs() < 1e-12 * stone.size());
        assert!(!out.entering && out.normal == DVec3::NEG_Z);
        let up = stone
            .intersect(DVec3::new(x, y, -g - 1.0), DVec3::Z, 0.0, f64::INFINITY)
            .expect("a vertical ray up through the base");
        assert!(up.entering && (up.point.z + g).abs() < 1e-12 * stone.size());
        assert_eq!(up.normal, DVec3::NEG_Z);
    }
}

#[test]
fn normal_change_is_how_exit_normals_turn_on_every_stone() {
    // `normal_change` (the manifold solver's Jacobian, through the
    // surface's curvature) against the exits of two rays from one inner
    // point, aimed a step of 10⁻⁵ of the stone's size apart along each
    // tangent: the second normal less the first, against the change
    // predicted for the second point less the first. The planes' normals
    // do not turn; a pair that straddles a crease (a plane's rim, the
    // girdle), or lies where a profile exponent below 2 makes the
    // curvature change fast near the girdle (0.6 % of one stone's pairs,
    // off by 0.1–1 %), may disagree, so 1 % are allowed.
    let mut rng = Rng(321);
    for stone in every_stone() {
        let size = stone.size();
        let (lo, hi) = stone.bounds();
        let (mut checked, mut disagree, mut turning) = (0, 0, 0);
        for _ in 0..4000 {
            let origin = rng.in_box(lo, hi);
            if !stone.contains(origin) {
                continue;
            }
            let Some(hit) = stone.exit(origin, rng.direction()) else {
                continue;
            };
            let (u, v) = hit.normal.any_orthonormal_pair();
            for tangent in [u, v] {
                let aim = hit.point + tangent * (1e-5 * size) - origin;
                let Some(next) = stone.exit(origin, aim.normalize()) else {
                    continue;
                };
                let dp = next.point - hit.point;
                let [predicted, _] = stone.normal_change(hit.point, [dp, DVec3::ZERO]);
                let turned = next.normal - hit.normal;
                checked += 1;
                turning += usize::from(turned.length() > 1e-3 * dp.length() / size);
                if (predicted - turned).length() > 1e-3 * (turned.length() + dp.length() / size) {
                    disagree += 1;
                }
            }
        }
        assert!(checked > 1000, "{checked} pairs");
        assert!(turning > checked / 4, "{turning} of {checked} normals turn");
        assert!(
            disagree * 100 <= checked,
            "{disagree} of {checked} pairs disagree on {:?}",
            stone.params()
        );
    }
}
