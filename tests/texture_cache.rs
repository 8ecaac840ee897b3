//! The per-thread resolve cache must never change an answer: the cached
//! [`Pattern::resolve`] equals [`Pattern::resolve_uncached`] bit for bit on
//! every kind of query sequence (far jumps, tiny steps, steps across cell
//! borders, points within rounding of a border), for every built-in gem,
//! with patterns interleaved and on many threads. Below that, a certified
//! nearest site must be what [`Voronoi::nearest`] returns wherever
//! [`Voronoi::nearest_within`] says the certificate covers.

use glam::DVec3;
use lapidary::recipe::gem::{parse_gem, Gem};
use lapidary::recipe::library::{builtin_gem_names, builtin_gem_source};
use lapidary::texture::pattern::{Pattern, Resolved};
use lapidary::texture::voronoi::{CertifiedNearest, Voronoi};
use rayon::prelude::*;

mod common;
use common::rng::TestRng;

/// A step length log-uniform in `[10^lo, 10^hi]`.
fn step(rng: &mut TestRng, lo: f64, hi: f64) -> f64 {
    10f64.powf(rng.range(lo, hi))
}

fn builtin(name: &str) -> Gem {
    let text = builtin_gem_source(name).unwrap_or_else(|| panic!("no built-in gem {name}"));
    parse_gem(&format!("builtin:{name}"), text).unwrap_or_else(|e| panic!("{e}"))
}

/// Texture-space box a little larger than a studio stone (object
/// millimetres × 0.1), reaching into negative coordinates.
const LO: DVec3 = DVec3::new(-0.6, -0.5, -0.1);
const HI: DVec3 = DVec3::new(0.6, 0.5, 0.5);

/// Every field of a [`Resolved`] as bits, so that "equal" means bit for bit.
fn bits(r: &Resolved) -> (u32, u64, Option<u64>, u32, Option<(u64, u64)>) {
    (
        r.material,
        r.surface_cell,
        r.glitter_cell,
        r.map_index,
        r.flake_normal.map(|f| (f.theta.to_bits(), f.phi.to_bits())),
    )
}

fn assert_cached_equals_uncached(pattern: &Pattern, points: &[DVec3], what: &str) {
    for (i, p) in points.iter().enumerate() {
        let cached = pattern.resolve(*p);
        let reference = pattern.resolve_uncached(*p);
        assert_eq!(
            bits(&cached),
            bits(&reference),
            "{what}: point {i} = {p:?}\ncached = {cached:?}\nuncached = {reference:?}"
        );
    }
}

/// Far jumps: independent uniform points.
fn uniform_points(rng: &mut TestRng, n: usize) -> Vec<DVec3> {
    (0..n).map(|_| rng.point_in(LO, HI)).collect()
}

/// Random walks with steps from 10⁻¹³ to 10⁻¹ texture units (tiny steps
/// inside a cell up to steps across several small cells), restarting now
/// and then far away, and sometimes stepping straight back.
fn walk_points(rng: &mut TestRng, n: usize) -> Vec<DVec3> {
    let mut p = rng.point_in(LO, HI);
    let mut points = Vec::with_capacity(n);
    for _ in 0..n {
        let u = rng.unit();
        p = if u < 0.02 {
            rng.point_in(LO, HI)
        } else if u < 0.1 && !points.is_empty() {
            points[points.len() - 1 - (rng.unit() * points.len().min(8) as f64) as usize]
        } else {
            p + rng.direction() * step(rng, -13.0, -1.0)
        };
        points.push(p);
    }
    points
}

/// Pixel-like clusters: 16 points within a small disc-ish blob, the next
/// blob next to it, as a render's samples of neighbouring pixels.
fn pixel_points(rng: &mut TestRng, n: usize) -> Vec<DVec3> {
    let mut centre = rng.point_in(LO, HI);
    let row = rng.direction();
    let footprint = step(rng, -4.0, -2.0);
    let mut points = Vec::with_capacity(n);
    while points.len() < n {
        for _ in 0..16 {
            points.push(centre + rng.direction() * footprint * rng.unit());
        }
        centre += row * footprint;
    }
    points.truncate(n);
    points
}

/// The point where the nearest site of `v` changes on the segment from
/// `a` to `b` (whose nearest sites differ), located to the last bit.
fn border_between(v: &Voronoi, mut a: DVec3, mut b: DVec3) -> DVec3 {
    let site_a = v.nearest(a).cell_id;
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if m == a || m == b {
            break;
        }
        if v.nearest(m).cell_id == site_a {
            a = m;
        } else {
            b = m;
        }
    }
    a
}

/// Points within a few ulps to 10⁻⁶ of Voronoi borders of `v`, visited in
/// short back-and-forth runs across the border.
fn border_points(rng: &mut TestRng, v: &Voronoi, n: usize) -> Vec<DVec3> {
    let mut points = Vec::with_capacity(n);
    while points.len() < n {
        let a = rng.point_in(LO, HI);
        let b = a + rng.direction() * v.cell_size * 1.5;
        if v.nearest(a).cell_id == v.nearest(b).cell_id {
            continue;
        }
        let border = border_between(v, a, b);
        let across = (b - a).normalize();
        for _ in 0..12 {
            let k = rng.range(-1.0, 1.0);
            let scale = if rng.unit() < 0.5 {
                f64::EPSILON * border.abs().max_element().max(1e-300) * 8.0
            } else {
                step(rng, -15.0, -6.0)
            };
            points.push(border + across * k * scale);
        }
    }
    points.truncate(n);
    points
}

/// Every Voronoi of a pattern (map cells, per-cell switch cells, glitter
/// and facet cells).
fn voronois_of(pattern: &Pattern) -> Vec<Voronoi> {
    use lapidary::texture::pattern::Node;
    let mut all: Vec<Voronoi> = pattern
        .nodes()
        .iter()
        .filter_map(|n| match n {
            Node::Map(m) => Some(m.voronoi),
            Node::Switch(s) => s.per_cell,
        })
        .collect();
    if let Some(g) = pattern.glitter() {
        all.push(g.voronoi);
        all.push(g.facets.voronoi);
    }
    all
}

#[test]
fn cached_resolve_equals_uncached_for_every_builtin_gem() {
    let names: Vec<&str> = builtin_gem_names().collect();
    assert!(names.len() >= 5, "built-in gems: {names:?}");
    for (g, name) in names.iter().enumerate() {
        let gem = builtin(name);
        let mut rng = TestRng(0x9e37_79b9_7f4a_7c15 ^ g as u64);
        let pattern = &gem.pattern;
        assert_cached_equals_uncached(pattern, &uniform_points(&mut rng, 3000), name);
        assert_cached_equals_uncached(pattern, &walk_points(&mut rng, 6000), name);
        assert_cached_equals_uncached(pattern, &pixel_points(&mut rng, 6000), name);
        for v in voronois_of(pattern) {
            assert_cached_equals_uncached(pattern, &border_points(&mut rng, &v, 600), name);
        }
    }
}

#[test]
fn a_plain_stone_answers_inline_as_the_uncached_tree() {
    // One material, no map, no glitter: `resolve` answers without the
    // tree walk; the answer must be the walk's, and name the surface's
    // material.
    let text = r#"Gem(
        name: "plain",
        materials: {
            "a": Material(layers: [], base: Diffuse(colour: (0.5, 0.5, 0.5))),
            "b": Material(layers: [Layer(ior: 1.5, roughness_deg: 0.0)], base: Diffuse(colour: (0.1, 0.5, 0.2))),
        },
        surface: "b",
    )"#;
    let gem = parse_gem("plain.ron", text).unwrap_or_else(|e| panic!("{e}"));
    let mut rng = TestRng(0x9a1e);
    let points = uniform_points(&mut rng, 1000);
    assert_cached_equals_uncached(&gem.pattern, &points, "plain");
    let material = gem.pattern.resolve(points[0]).material;
    assert_eq!(gem.materials[material as usize].0, "b");
}

#[test]
fn cached_resolve_equals_uncached_when_two_patterns_alternate() {
    let a = builtin("lavender-lepidolite");
    let b = builtin("pink-sunstone");
    let mut rng = TestRng(0x0123_4567_89ab_cdef);
    let points = pixel_points(&mut rng, 4000);
    let walk = walk_points(&mut rng, 4000);
    for (i, (p, q)) in points.iter().zip(&walk).enumerate() {
        // Same point to both, then each its own sequence, in runs of 1 to 3.
        for (pattern, x) in [(&a.pattern, p), (&b.pattern, p), (&b.pattern, q)] {
            for _ in 0..=(i % 3) {
                assert_eq!(
                    bits(&pattern.resolve(*x)),
                    bits(&pattern.resolve_uncached(*x)),
                    "step {i}: {x:?}"
                );
            }
        }
    }
}

#[test]
fn cached_resolve_is_independent_of_the_thread_and_its_history() {
    let gem = builtin("lavender-lepidolite");
    let mut rng = TestRng(0x5151_5151);
    let points = pixel_points(&mut rng, 20_000);
    let reference: Vec<_> = points
        .iter()
        .map(|p| bits(&gem.pattern.resolve_uncached(*p)))
        .collect();
    for chunk in [1, 7, 64, 1000] {
        let parallel: Vec<_> = points
            .par_chunks(chunk)
            .flat_map_iter(|c| c.iter().map(|p| bits(&gem.pattern.resolve(*p))))
            .collect();
        assert_eq!(parallel, reference, "chunks of {chunk}");
    }
}

#[test]
fn patterns_compare_by_content_not_by_id() {
    let a = builtin("lavender-lepidolite");
    let b = builtin("lavender-lepidolite");
    assert_ne!(a.pattern.id(), b.pattern.id());
    assert_eq!(a.pattern, b.pattern);
    let copy = a.pattern.clone();
    assert_eq!(copy.id(), a.pattern.id());
    assert_ne!(a.pattern, builtin("goldstone").pattern);
}

/// Voronoi settings that stress the certificate: full and partial jitter,
/// a regular grid (many exact ties), stretch, tiny and large cells.
fn test_voronois() -> Vec<Voronoi> {
    let mut v = vec![
        Voronoi::new(1.0, 1),
        Voronoi::new(0.008, 7),
        Voronoi::new(3.7, 99),
    ];
    v.push(Voronoi {
        jitter: 0.4,
        ..Voronoi::new(0.5, 3)
    });
    v.push(Voronoi {
        jitter: 0.0,
        ..Voronoi::new(1.0, 4)
    });
    v.push(Voronoi {
        stretch: DVec3::new(3.0, 1.0, 0.5),
        ..Voronoi::new(0.2, 5)
    });
    v
}

#[test]
fn a_certificate_covers_only_points_with_the_same_nearest_site() {
    let mut rng = TestRng(0xfeed_beef);
    for v in test_voronois() {
        let scale = v.stretch * v.cell_size;
        let mut covered = 0;
        for round in 0..3000 {
            // Near the origin, and far out (10⁶ cells), negative included.
            let offset = if round % 3 == 2 {
                DVec3::new(1.0e6, -2.5e6, 0.75e6) * scale
            } else {
                DVec3::ZERO
            };
            let p0 = offset + rng.point_in(-8.0 * scale, 8.0 * scale);
            let certified = v.certify_nearest(p0);
            assert_eq!(certified.site, v.nearest(p0).site(), "{v:?} at {p0:?}");
            for _ in 0..20 {
                let length = step(&mut rng, -14.0, 0.3) * v.cell_size;
                let p = p0 + rng.direction() * length * v.stretch;
                if v.nearest_within(&certified, p) {
                    covered += 1;
                    assert_eq!(
                        certified.site,
                        v.nearest(p).site(),
                        "{v:?}: certified at {p0:?}, queried at {p:?}"
                    );
                }
            }
        }
        // Regular grids tie everywhere only on cell faces: most certificates
        // still cover something.
        assert!(covered > 10_000, "{v:?}: only {covered} covered queries");
    }
}

#[test]
fn certificates_near_borders_stay_exact() {
    let mut rng = TestRng(0xb0de_b0de);
    for v in test_voronois() {
        let scale = v.stretch * v.cell_size;
        let mut n = 0;
        while n < 400 {
            let a = rng.point_in(-6.0 * scale, 6.0 * scale);
            let b = a + rng.direction() * 1.5 * scale;
            if v.nearest(a).cell_id == v.nearest(b).cell_id {
                continue;
            }
            n += 1;
            let border = border_between(&v, a, b);
            let across = (b - a).normalize() * scale;
            // Certify on either side at distances from ulps to 10⁻⁵ cells;
            // query on both sides.
            for _ in 0..8 {
                let p0 = border + across * rng.range(-1.0, 1.0) * step(&mut rng, -16.0, -5.0);
                let certified = v.certify_nearest(p0);
                assert_eq!(certified.site, v.nearest(p0).site());
                for _ in 0..8 {
                    let p = border + across * rng.range(-1.0, 1.0) * step(&mut rng, -16.0, -3.0);
                    if v.nearest_within(&certified, p) {
                        assert_eq!(
                            certified.site,
                            v.nearest(p).site(),
                            "{v:?}: {p0:?} -> {p:?}"
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn empty_and_non_finite_certificates_cover_nothing() {
    let v = Voronoi::new(1.0, 2);
    for p in [DVec3::ZERO, DVec3::splat(0.3), DVec3::new(-5.0, 2.0, 1.0)] {
        assert!(!v.nearest_within(&CertifiedNearest::EMPTY, p));
    }
    let nan = DVec3::new(f64::NAN, 0.0, 0.0);
    let certified = v.certify_nearest(nan);
    assert_eq!(certified.site, v.nearest(nan).site());
    assert!(!v.nearest_within(&certified, nan));
    assert!(!v.nearest_within(&certified, DVec3::ZERO));
    let far = DVec3::splat(1.0e12);
    let certified = v.certify_nearest(far);
    assert_eq!(certified.site, v.nearest(far).site());
    assert!(!v.nearest_within(&certified, far));
    // A finite query certifies itself.
    let p = DVec3::new(0.31, -0.72, 4.05);
    assert!(v.nearest_within(&v.certify_nearest(p), p));
}
