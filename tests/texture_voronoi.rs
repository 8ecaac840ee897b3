//! Voronoi: the fast query against the brute-force reference, and properties
//! that follow from the definition of a Voronoi diagram independently of
//! either implementation.

use glam::DVec3;
use lapidary::texture::voronoi::{Voronoi, VoronoiSample};
use rayon::prelude::*;

mod common;
use common::rng::TestRng;

/// A point with some coordinates on or within 1e-12 of a lattice plane
/// `k · cell_size · stretch`, including negative k.
fn point_near_planes(rng: &mut TestRng, v: &Voronoi) -> DVec3 {
    let scale = v.stretch * v.cell_size;
    let mut p = rng.cube(12.0);
    for axis in 0..3 {
        if rng.unit() < 0.6 {
            let k = (rng.range(-8.0, 8.0)).round();
            let nudge = [0.0, 1e-12, -1e-12, 1e-15, -1e-15][(rng.unit() * 5.0) as usize];
            p[axis] = (k + nudge) * scale[axis];
        }
    }
    p
}

const TOLERANCE: f64 = 1e-9;

/// Asserts the fast and reference samples agree; an id may differ only at a
/// tie between the two nearest sites (then both edge distances are ~0).
fn assert_agree(v: &Voronoi, p: DVec3, fast: &VoronoiSample, reference: &VoronoiSample) {
    let context =
        || format!("p = {p:?}, voronoi = {v:?}\nfast = {fast:?}\nreference = {reference:?}");
    assert!(
        (fast.f1 - reference.f1).abs() < TOLERANCE,
        "F1: {}",
        context()
    );
    assert!(
        (fast.f2 - reference.f2).abs() < TOLERANCE,
        "F2: {}",
        context()
    );
    assert!(
        (fast.edge_distance - reference.edge_distance).abs() < TOLERANCE,
        "edge: {}",
        context()
    );
    let tie = reference.f2 - reference.f1 < TOLERANCE;
    if !tie {
        assert_eq!(fast.cell_id, reference.cell_id, "id: {}", context());
        assert_eq!(fast.cell, reference.cell, "cell: {}", context());
        assert!(
            fast.feature_point.distance(reference.feature_point) < TOLERANCE,
            "feature point: {}",
            context()
        );
    }
    let nearest = v.nearest(p);
    assert!(
        (nearest.f1 - fast.f1).abs() < TOLERANCE,
        "nearest F1: {}",
        context()
    );
    if !tie {
        assert_eq!(nearest.cell_id, fast.cell_id, "nearest id: {}", context());
        assert_eq!(nearest.cell, fast.cell);
        assert_eq!(nearest.feature_point, fast.feature_point);
    }
}

fn compare_with_brute_force(v: &Voronoi, count: usize, seed: u64, near_planes: bool) {
    let mut rng = TestRng(seed);
    for _ in 0..count {
        let p = if near_planes {
            point_near_planes(&mut rng, v)
        } else {
            rng.cube(15.0)
        };
        assert_agree(v, p, &v.query(p), &v.query_brute_force(p));
    }
}

fn voronoi(jitter: f64, stretch: DVec3, seed: u64) -> Voronoi {
    Voronoi {
        cell_size: 0.7,
        jitter,
        stretch,
        seed,
    }
}

#[test]
fn fast_query_matches_brute_force_full_jitter() {
    // Full jitter is the case where the 3×3×3 block is not always enough.
    compare_with_brute_force(&voronoi(1.0, DVec3::ONE, 11), 50_000, 1, false);
    compare_with_brute_force(&voronoi(1.0, DVec3::ONE, 12), 20_000, 2, true);
}

#[test]
fn fast_query_matches_brute_force_half_jitter() {
    compare_with_brute_force(&voronoi(0.5, DVec3::ONE, 21), 10_000, 3, false);
    compare_with_brute_force(&voronoi(0.5, DVec3::ONE, 22), 5_000, 4, true);
}

#[test]
fn fast_query_matches_brute_force_regular_grid() {
    compare_with_brute_force(&voronoi(0.0, DVec3::ONE, 31), 5_000, 5, false);
    compare_with_brute_force(&voronoi(0.0, DVec3::ONE, 32), 5_000, 6, true);
}

#[test]
fn fast_query_matches_brute_force_stretched() {
    let stretch = DVec3::new(3.0, 1.0, 0.5);
    compare_with_brute_force(&voronoi(1.0, stretch, 41), 10_000, 7, false);
    compare_with_brute_force(&voronoi(0.8, stretch, 42), 5_000, 8, true);
}

/// With jitter 0 every site is its cell centre, so the Voronoi cells are
/// exactly the lattice cells: everything follows from the fraction f of p in
/// its cell (cell size s): F1 = s|f − ½|, edge = s·minᵢ min(fᵢ, 1 − fᵢ), and
/// the second site is the face neighbour across the nearest face:
/// F2² = F1² + s²(1 − 2 maxᵢ |fᵢ − ½|).
#[test]
fn regular_grid_cells_are_the_lattice_cells() {
    let v = voronoi(0.0, DVec3::ONE, 5);
    let s = v.cell_size;
    let mut rng = TestRng(9);
    for _ in 0..20_000 {
        let p = rng.cube(20.0);
        let sample = v.query(p);
        let cell = (p / s).floor();
        let f = p / s - cell;
        assert_eq!(sample.cell, cell.as_ivec3(), "p = {p}");
        assert!(sample.feature_point.distance((cell + 0.5) * s) < 1e-12);
        let e = (f - 0.5).abs();
        let f1 = s * e.length();
        assert!((sample.f1 - f1).abs() < 1e-12);
        let edge = s * f.min(DVec3::ONE - f).min_element();
        assert!((sample.edge_distance - edge).abs() < 1e-12, "p = {p}");
        let f2 = (f1 * f1 + s * s * (1.0 - 2.0 * e.max_element())).sqrt();
        assert!((sample.f2 - f2).abs() < 1e-9, "p = {p}");
    }
}

/// The returned points are consistent with the returned distances, and each
/// feature point sits in its own cell's jitter box: c + ½ ± jitter/2.
#[test]
fn feature_points_are_consistent_with_distances_and_cells() {
    for (jitter, stretch) in [(0.5, DVec3::ONE), (1.0, DVec3::new(2.5, 1.0, 0.4))] {
        let v = voronoi(jitter, stretch, 17);
        let scale = v.cell_size * stretch;
        let mut rng = TestRng(10);
        for _ in 0..10_000 {
            let p = rng.cube(15.0);
            let s = v.query(p);
            let stretched = |a: DVec3, b: DVec3| ((a - b) / stretch).length();
            assert!((s.f1 - stretched(p, s.feature_point)).abs() < 1e-9);
            assert!((s.f2 - stretched(p, s.second_feature_point)).abs() < 1e-9);
            assert!(s.f1 <= s.f2);
            let local = s.feature_point / scale - s.cell.as_dvec3();
            let half_box = 0.5 * jitter + 1e-12;
            assert!(
                (local - 0.5).abs().max_element() <= half_box,
                "site {local} outside its jitter box"
            );
        }
    }
}

/// Signed distance of q to the bisector plane of a and b is
/// ((q − m)·(b − a))/|b − a| with m = (a + b)/2, and
/// |q−a|² − |q−b|² = 2 (b − a)·(q − m), so for the second-nearest site b the
/// plane is (F2² − F1²)/(2|b − a|) away. The edge distance is a minimum over
/// all such planes, hence never larger.
#[test]
fn edge_distance_is_at_most_the_distance_to_the_second_sites_bisector() {
    let v = voronoi(1.0, DVec3::ONE, 23);
    let mut rng = TestRng(11);
    for _ in 0..20_000 {
        let p = rng.cube(15.0);
        let s = v.query(p);
        let separation = s.feature_point.distance(s.second_feature_point);
        let bound = (s.f2 * s.f2 - s.f1 * s.f1) / (2.0 * separation);
        assert!(s.edge_distance >= 0.0);
        assert!(s.edge_distance <= bound + 1e-12, "{s:?}");
    }
}

/// The edge distance is the radius of the largest ball around p inside its
/// cell: any step shorter than it keeps the nearest site.
#[test]
fn a_step_shorter_than_the_edge_distance_stays_in_the_cell() {
    let v = voronoi(1.0, DVec3::ONE, 29);
    let mut rng = TestRng(12);
    for _ in 0..20_000 {
        let p = rng.cube(15.0);
        let s = v.query(p);
        let step = rng.direction() * (0.999 * s.edge_distance);
        assert_eq!(
            v.nearest(p + step).cell_id,
            s.cell_id,
            "p = {p}, step = {step}"
        );
    }
}

/// Where the nearest cell changes along a segment, p is on a cell border: the
/// edge distance there is ~0 (found by bisection to 1e-13).
#[test]
fn edge_distance_vanishes_on_a_cell_border() {
    for (jitter, seed) in [(1.0, 31), (0.5, 32), (0.0, 33)] {
        let v = voronoi(jitter, DVec3::ONE, seed);
        let mut rng = TestRng(13 + seed);
        let mut borders = 0;
        for _ in 0..300 {
            let mut a = rng.cube(10.0);
            let mut b = a + rng.direction() * 1.5;
            let id_a = v.nearest(a).cell_id;
            if v.nearest(b).cell_id == id_a {
                continue;
            }
            for _ in 0..60 {
                let mid = 0.5 * (a + b);
                if v.nearest(mid).cell_id == id_a {
                    a = mid;
                } else {
                    b = mid;
                }
            }
            for end in [a, b] {
                let s = v.query(end);
                assert!(
                    s.edge_distance < 1e-9,
                    "edge {} at border {end}",
                    s.edge_distance
                );
                assert!(s.f2 - s.f1 < 1e-9);
            }
            borders += 1;
        }
        assert!(borders > 100, "only {borders} segments crossed a border");
    }
}

/// floor, not truncation: crossing a lattice plane (also at negative and zero
/// coordinates) changes nothing unless a cell border happens to be there.
#[test]
fn no_seams_at_lattice_planes() {
    let v = voronoi(1.0, DVec3::ONE, 37);
    let mut rng = TestRng(14);
    for k in -4..=4 {
        for _ in 0..500 {
            let mut p = rng.cube(5.0);
            let axis = (rng.unit() * 3.0) as usize;
            p[axis] = k as f64 * v.cell_size;
            let mut below = p;
            below[axis] -= 1e-9;
            let mut above = p;
            above[axis] += 1e-9;
            let (sb, sa) = (v.query(below), v.query(above));
            assert!((sb.f1 - sa.f1).abs() <= 2.1e-9, "F1 jumps at plane {k}");
            assert!((sb.edge_distance - sa.edge_distance).abs() <= 2.1e-9);
            if sb.edge_distance > 1e-6 {
                assert_eq!(sb.cell_id, sa.cell_id, "seam at plane {k}, p = {p}");
            }
        }
    }
}

#[test]
fn a_different_seed_gives_different_cells() {
    let (a, b) = (voronoi(1.0, DVec3::ONE, 1), voronoi(1.0, DVec3::ONE, 2));
    let mut rng = TestRng(15);
    let mut same = 0;
    for _ in 0..2000 {
        let p = rng.cube(15.0);
        let (sa, sb) = (a.query(p), b.query(p));
        if sa.cell_id == sb.cell_id || sa.feature_point == sb.feature_point {
            same += 1;
        }
    }
    assert_eq!(same, 0);
}

#[test]
fn queries_are_identical_on_one_and_eight_threads() {
    let v = voronoi(1.0, DVec3::new(1.5, 1.0, 1.0), 41);
    let mut rng = TestRng(16);
    let pts: Vec<DVec3> = (0..20_000).map(|_| rng.cube(20.0)).collect();
    let serial: Vec<VoronoiSample> = pts.iter().map(|&p| v.query(p)).collect();
    for threads in [1, 8] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let parallel: Vec<VoronoiSample> =
            pool.install(|| pts.par_iter().map(|&p| v.query(p)).collect());
        // PartialEq on f64 fields: exact equality (no NaN can occur here).
        assert!(serial == parallel, "{threads} threads differ");
    }
}

#[test]
fn the_sample_for_a_cell_does_not_depend_on_the_query_cell() {
    // Same site seen from different query cells: its object-space position is
    // a function of (cell, seed) only.
    let v = voronoi(1.0, DVec3::ONE, 43);
    let mut rng = TestRng(17);
    for _ in 0..2000 {
        let p = rng.cube(10.0);
        let s = v.query(p);
        let from_site = v.query(s.feature_point);
        assert_eq!(from_site.cell, s.cell);
        assert_eq!(from_site.cell_id, s.cell_id);
        assert!(from_site.f1 < 1e-12);
        assert!(from_site.feature_point.distance(s.feature_point) < 1e-12);
    }
}

#[test]
fn voronoi_types_are_send_and_sync() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<Voronoi>();
    assert_send_sync::<VoronoiSample>();
}

/// Ray hits are finite, but a bad recipe (zero cell size) or a runaway
/// coordinate must not panic or hang; the value is unspecified.
#[test]
fn extreme_input_neither_panics_nor_hangs() {
    let v = voronoi(1.0, DVec3::ONE, 3);
    let zero_size = Voronoi {
        cell_size: 0.0,
        ..v
    };
    let nan_jitter = Voronoi {
        jitter: f64::NAN,
        ..v
    };
    for p in [
        DVec3::splat(f64::NAN),
        DVec3::new(f64::INFINITY, 0.0, f64::NEG_INFINITY),
        DVec3::new(1e300, -1e300, 0.5),
        DVec3::splat(2.0e9),
    ] {
        for texture in [v, zero_size, nan_jitter] {
            let _ = texture.query(p);
            let _ = texture.nearest(p);
        }
    }
    // Just inside the documented domain the answer is still exact.
    let p = DVec3::new(-1.4e9, 1.4e9, 3.3) * v.cell_size;
    assert_agree(&v, p, &v.query(p), &v.query_brute_force(p));
}
