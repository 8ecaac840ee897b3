//! The compiled pattern tree (section 4.3.1, figure 4.6): entry frequencies,
//! fill fractions and tilt distributions against their declared laws, switch
//! partitions, golden values from the documented hash definition
//! re-implemented here, determinism across threads and seeds.

mod common;

use common::ks::ks_test;
use glam::{DVec3, IVec3};
use lapidary::texture::noise_fns::{Marble, PerlinNoise, PerlinSource, Turbulence};
use lapidary::texture::pattern::{
    Around, Entry, FacetBumpMap, GlitterMap, Node, Pattern, SurfaceMap, Switch, SwitchFunction,
    SwitchRange, Tilt,
};
use lapidary::texture::voronoi::Voronoi;
use rayon::prelude::*;
use statrs::distribution::{ChiSquared, ContinuousCDF};

// ---- The documented hash definition, re-implemented literally -------------

const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

fn mix64(mut z: u64) -> u64 {
    z ^= z >> 30;
    z = z.wrapping_mul(0xbf58476d1ce4e5b9);
    z ^= z >> 27;
    z = z.wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

fn hash_cell(c: IVec3, seed: u64) -> u64 {
    let mut h = mix64(seed.wrapping_add(GOLDEN_GAMMA));
    for x in [c.x, c.y, c.z] {
        h = mix64(h.wrapping_add(x as i64 as u64));
    }
    h
}

fn derive_stream(h: u64, stream: u64) -> u64 {
    mix64(h.wrapping_add((stream + 1).wrapping_mul(GOLDEN_GAMMA)))
}

fn unit(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// First index `i` with `u < (w₀+…+wᵢ)/Σw`.
fn weighted_pick(weights: &[f64], u: f64) -> usize {
    let total: f64 = weights.iter().sum();
    let mut running = 0.0;
    for (i, w) in weights.iter().enumerate() {
        running += w;
        if i + 1 == weights.len() || u < running / total {
            return i;
        }
    }
    unreachable!()
}

// Stream numbers as documented in `texture::pattern`.
const STREAM_ENTRY: u64 = 1;
const STREAM_FILL: u64 = 2;
const STREAM_GLITTER_ENTRY: u64 = 3;

// ---- Helpers ----------------------------------------------------------------

/// A regular grid (jitter 0): the cell containing the centre of lattice cell
/// `c` is `c` itself, so tests can address cells directly.
fn grid(cell_size: f64, seed: u64) -> Voronoi {
    Voronoi {
        cell_size,
        jitter: 0.0,
        stretch: DVec3::ONE,
        seed,
    }
}

fn centre(c: IVec3, cell_size: f64) -> DVec3 {
    (c.as_dvec3() + DVec3::splat(0.5)) * cell_size
}

/// Lattice cells of a cube of side `n` starting at `-n/2`.
fn cube_cells(n: i32) -> impl Iterator<Item = IVec3> {
    (0..n).flat_map(move |x| {
        (0..n).flat_map(move |y| (0..n).map(move |z| IVec3::new(x, y, z) - IVec3::splat(n / 2)))
    })
}

fn materials(weights: &[f64]) -> Vec<(Entry, f64)> {
    weights
        .iter()
        .enumerate()
        .map(|(i, w)| (Entry::Material(i as u32), *w))
        .collect()
}

fn facets(cell_size: f64, seed: u64, tilt: Tilt) -> FacetBumpMap {
    FacetBumpMap::new(grid(cell_size, seed), tilt, Around::SurfaceNormal).unwrap()
}

fn marble(seed: u64) -> Marble {
    Marble {
        direction: DVec3::X,
        frequency: 4.0,
        amplitude: 2.0,
        turbulence: Turbulence {
            source: PerlinSource::new(seed),
            frequency: 1.0,
            octaves: 4,
            lacunarity: 2.0,
            gain: 0.5,
        },
    }
}

/// A lepidolite-like tree: dark (9) and bright (5) tiles in a map of bigger
/// tiles, a marble switch to small inclusion tiles, sparse glitter.
fn lepidolite_like(seed: u64) -> Pattern {
    let v = |cell_size: f64, k: u64| Voronoi::new(cell_size, seed.wrapping_mul(31).wrapping_add(k));
    let dark = SurfaceMap::new(v(0.05, 1), materials(&[1.0; 9])).unwrap();
    let bright = SurfaceMap::new(
        v(0.05, 2),
        (9..14).map(|m| (Entry::Material(m), 1.0)).collect(),
    )
    .unwrap();
    let tiles = SurfaceMap::new(
        v(0.3, 3),
        vec![(Entry::Node(0), 1.0), (Entry::Node(1), 1.0)],
    )
    .unwrap();
    let inclusions = SurfaceMap::new(
        v(0.01, 4),
        vec![
            (Entry::Material(14), 1.0),
            (Entry::Material(15), 1.0),
            (Entry::Material(16), 1.0),
            (Entry::Node(0), 0.5),
            (Entry::Node(1), 0.5),
        ],
    )
    .unwrap();
    let switch = Switch::new(
        SwitchFunction::Marble(marble(seed)),
        vec![
            SwitchRange {
                from: 0.0,
                to: 0.8,
                entry: Entry::Node(2),
            },
            SwitchRange {
                from: 0.8,
                to: 1.0,
                entry: Entry::Node(3),
            },
        ],
        Some(v(0.01, 4)),
    )
    .unwrap();
    let glitter = GlitterMap::new(
        v(0.2, 5),
        0.02,
        (17..21).map(|m| (m, 1.0)).collect(),
        FacetBumpMap::new(
            v(0.05, 6),
            Tilt::UniformCone { max_tilt_deg: 20.0 },
            Around::SurfaceNormal,
        )
        .unwrap(),
    )
    .unwrap();
    Pattern::new(
        vec![
            Node::Map(dark),
            Node::Map(bright),
            Node::Map(tiles),
            Node::Map(inclusions),
            Node::Switch(switch),
        ],
        Entry::Node(4),
        Some(glitter),
        21,
    )
    .unwrap()
}

fn test_points(n: usize, seed: u64) -> Vec<DVec3> {
    // The library's SplitMix64: deterministic points in a cube around the origin.
    let mut rng = lapidary::sampling::Rng::new(seed, 0);
    (0..n)
        .map(|_| DVec3::from_array(rng.next_3()) * 4.0 - DVec3::splat(2.0))
        .collect()
}

// ---- Tests ------------------------------------------------------------------

#[test]
fn entry_frequencies_match_weights_chi_squared() {
    let weights = [1.0, 2.0, 3.0, 4.0, 0.5];
    let map = SurfaceMap::new(grid(0.1, 11), materials(&weights)).unwrap();
    let pattern = Pattern::new(vec![Node::Map(map)], Entry::Node(0), None, 5).unwrap();
    let mut counts = [0u64; 5];
    let mut n = 0u64;
    for c in cube_cells(47) {
        // 47³ = 103 823 cells.
        counts[pattern.resolve(centre(c, 0.1)).material as usize] += 1;
        n += 1;
    }
    let total: f64 = weights.iter().sum();
    let chi2: f64 = counts
        .iter()
        .zip(weights)
        .map(|(&o, w)| {
            let e = n as f64 * w / total;
            (o as f64 - e).powi(2) / e
        })
        .sum();
    let critical = ChiSquared::new((weights.len() - 1) as f64)
        .unwrap()
        .inverse_cdf(0.999);
    assert!(
        chi2 < critical,
        "χ² = {chi2} ≥ {critical} (p < 0.001); counts {counts:?}"
    );
}

#[test]
fn glitter_fill_fraction_within_one_percent() {
    for fill in [0.3, 0.02, 0.97] {
        let glitter = GlitterMap::new(
            grid(0.2, 5),
            fill,
            vec![(1, 1.0)],
            facets(0.05, 6, Tilt::UniformCone { max_tilt_deg: 10.0 }),
        )
        .unwrap();
        let pattern = Pattern::new(vec![], Entry::Material(0), Some(glitter), 2).unwrap();
        let (mut filled, mut n) = (0u64, 0u64);
        for c in cube_cells(47) {
            let r = pattern.resolve(centre(c, 0.2));
            if r.glitter_cell.is_some() {
                assert_eq!(r.material, 1);
                assert!(r.flake_normal.is_some());
                filled += 1;
            } else {
                assert_eq!(r.material, 0);
                assert!(r.flake_normal.is_none());
            }
            n += 1;
        }
        let measured = filled as f64 / n as f64;
        assert!(
            (measured - fill).abs() <= 0.01,
            "fill {fill}: measured {measured} over {n} cells"
        );
    }
}

fn tilt_samples(tilt: Tilt) -> Vec<f64> {
    let map = facets(0.1, 99, tilt);
    cube_cells(32)
        .map(|c| {
            let (normal, _) = map.normal_at(centre(c, 0.1));
            let local = normal.local();
            assert!((local.length() - 1.0).abs() < 1e-12);
            assert!((local.z - normal.theta.cos()).abs() < 1e-12);
            normal.theta
        })
        .collect()
}

#[test]
fn uniform_cone_tilt_follows_declared_cdf() {
    let max = 20f64.to_radians();
    let mut theta = tilt_samples(Tilt::UniformCone { max_tilt_deg: 20.0 });
    assert!(theta.iter().all(|t| (0.0..=max + 1e-12).contains(t)));
    let outcome = ks_test(&mut theta, |t| {
        ((1.0 - t.cos()) / (1.0 - max.cos())).clamp(0.0, 1.0)
    });
    assert!(outcome.p_value >= 0.001, "{outcome:?}");
}

#[test]
fn gaussian_tilt_follows_half_normal_cdf() {
    let sigma = 10f64.to_radians();
    let mut theta = tilt_samples(Tilt::Gaussian {
        sigma_tilt_deg: 10.0,
    });
    let outcome = ks_test(&mut theta, |t| {
        if t <= 0.0 {
            0.0
        } else {
            statrs::function::erf::erf(t / (sigma * std::f64::consts::SQRT_2))
        }
    });
    assert!(outcome.p_value >= 0.001, "{outcome:?}");
    // And it is not the uniform cone of the same mean: sanity that the
    // test can fail.
    let wrong = ks_test(&mut theta, |t| (t / (2.0 * sigma)).clamp(0.0, 1.0));
    assert!(wrong.p_value < 0.001);
}

#[test]
fn fixed_direction_flakes_do_not_follow_the_surface() {
    let d = DVec3::new(0.0, 1.0, 1.0).normalize();
    let map = FacetBumpMap::new(
        grid(0.1, 3),
        Tilt::UniformCone { max_tilt_deg: 5.0 },
        Around::Direction(DVec3::new(0.0, 2.0, 2.0)),
    )
    .unwrap();
    for c in cube_cells(6) {
        let (normal, _) = map.normal_at(centre(c, 0.1));
        let a = normal.world(DVec3::Z);
        let b = normal.world(DVec3::X);
        assert!((a - b).length() < 1e-12);
        assert!(a.dot(d) >= 5f64.to_radians().cos() - 1e-12);
    }
    let around_surface = facets(0.1, 3, Tilt::UniformCone { max_tilt_deg: 5.0 });
    let (normal, _) = around_surface.normal_at(DVec3::splat(0.05));
    let n = DVec3::new(1.0, -2.0, 0.5).normalize();
    assert!((normal.world(n).dot(n) - normal.theta.cos()).abs() < 1e-12);
}

fn three_range_switch(per_cell: Option<Voronoi>) -> Switch {
    Switch::new(
        SwitchFunction::Marble(marble(4)),
        vec![
            SwitchRange {
                from: 0.0,
                to: 0.3,
                entry: Entry::Material(0),
            },
            SwitchRange {
                from: 0.3,
                to: 0.8,
                entry: Entry::Material(1),
            },
            SwitchRange {
                from: 0.8,
                to: 1.0,
                entry: Entry::Material(2),
            },
        ],
        per_cell,
    )
    .unwrap()
}

#[test]
fn switch_ranges_partition_the_function_values() {
    let bounds = [(0.0, 0.3), (0.3, 0.8), (0.8, 1.0)];
    let m = marble(4);
    let pattern = Pattern::new(
        vec![Node::Switch(three_range_switch(None))],
        Entry::Node(0),
        None,
        3,
    )
    .unwrap();
    let mut seen = [0usize; 3];
    for p in test_points(20_000, 5) {
        let v = m.value(p);
        let holding: Vec<usize> = (0..3)
            .filter(|&k| bounds[k].0 <= v && (v < bounds[k].1 || (k == 2 && v <= 1.0)))
            .collect();
        assert_eq!(holding.len(), 1, "value {v} is in ranges {holding:?}");
        assert_eq!(pattern.resolve(p).material as usize, holding[0]);
        seen[holding[0]] += 1;
    }
    assert!(seen.iter().all(|&s| s > 100), "{seen:?}");
}

#[test]
fn switch_rejects_gaps_overlaps_and_uncovered_ends() {
    let f = SwitchFunction::Perlin(PerlinNoise {
        source: PerlinSource::new(1),
        frequency: 1.0,
    });
    let r = |from, to| SwitchRange {
        from,
        to,
        entry: Entry::Material(0),
    };
    let cases = [
        (vec![r(-1.0, 0.0), r(0.1, 1.0)], "gap"),
        (vec![r(-1.0, 0.2), r(0.1, 1.0)], "overlap"),
        (vec![r(-0.5, 1.0)], "starts at -0.5"),
        (vec![r(-1.0, 0.9)], "ends at 0.9"),
        (vec![], "at least one range"),
    ];
    for (ranges, expected) in cases {
        let err = Switch::new(f, ranges, None).unwrap_err().to_string();
        assert!(err.contains(expected), "{err}");
    }
    assert!(Switch::new(f, vec![r(-1.0, 0.0), r(0.0, 1.0)], None).is_ok());
}

#[test]
fn per_cell_switch_switches_whole_cells() {
    let cells = grid(0.25, 8);
    let switch = three_range_switch(Some(cells));
    // Every point of a lattice cell (jitter 0: the Voronoi cell) gets the
    // entry of the cell's centre.
    let m = marble(4);
    for c in cube_cells(8) {
        let at_centre = switch.select(centre(c, 0.25));
        let v = m.value(centre(c, 0.25));
        let expected = if v < 0.3 {
            0
        } else if v < 0.8 {
            1
        } else {
            2
        };
        assert_eq!(at_centre, Entry::Material(expected));
        for k in 0..8 {
            let offset =
                DVec3::new((k & 1) as f64, ((k >> 1) & 1) as f64, (k >> 2) as f64) * 0.2 - 0.1;
            assert_eq!(switch.select(centre(c, 0.25) + offset), at_centre);
        }
    }
}

#[test]
fn golden_entries_from_the_documented_hash() {
    let seed = 42;
    let weights = [1.0, 0.0, 2.0, 5.0];
    let map = SurfaceMap::new(grid(0.5, seed), materials(&weights)).unwrap();
    let glitter_seed = 77;
    let glitter_weights = [3.0, 1.0];
    let glitter = GlitterMap::new(
        grid(1.0, glitter_seed),
        0.4,
        vec![(4, 3.0), (5, 1.0)],
        facets(0.5, 1, Tilt::UniformCone { max_tilt_deg: 10.0 }),
    )
    .unwrap();
    let pattern = Pattern::new(vec![Node::Map(map)], Entry::Node(0), Some(glitter), 6).unwrap();
    let cells = [
        IVec3::new(0, 0, 0),
        IVec3::new(1, 2, 3),
        IVec3::new(-1, -1, -1),
        IVec3::new(-7, 3, 12),
        IVec3::new(100, -200, 5),
        IVec3::new(2, 2, -9),
    ];
    let mut glitter_hits = 0;
    for c in cells {
        // A point at the centre of surface cell c; the glitter cell (size 1)
        // containing it is floor(c / 2).
        let p = centre(c, 0.5);
        let g = IVec3::new(c.x.div_euclid(2), c.y.div_euclid(2), c.z.div_euclid(2));
        let surface_id = hash_cell(c, seed);
        let glitter_id = hash_cell(g, glitter_seed);
        let r = pattern.resolve(p);
        assert_eq!(r.surface_cell, surface_id);
        let filled = unit(derive_stream(glitter_id, STREAM_FILL)) < 0.4;
        if filled {
            glitter_hits += 1;
            let k = weighted_pick(
                &glitter_weights,
                unit(derive_stream(glitter_id, STREAM_GLITTER_ENTRY)),
            );
            assert_eq!(r.material, 4 + k as u32, "cell {c}");
            assert_eq!(r.glitter_cell, Some(glitter_id));
        } else {
            let k = weighted_pick(&weights, unit(derive_stream(surface_id, STREAM_ENTRY)));
            assert_ne!(k, 1, "zero weight picked");
            assert_eq!(r.material, k as u32, "cell {c}");
            assert_eq!(r.glitter_cell, None);
        }
        // The surface choice is also visible through resolve_surface.
        let k = weighted_pick(&weights, unit(derive_stream(surface_id, STREAM_ENTRY)));
        assert_eq!(pattern.resolve_surface(p).0, k as u32);
    }
    // Both branches are exercised by this fixed cell list.
    assert!(
        glitter_hits > 0 && glitter_hits < cells.len(),
        "{glitter_hits}"
    );
}

#[test]
fn same_pattern_on_1_and_8_threads_and_seed_matters() {
    let pattern = lepidolite_like(7);
    let points = test_points(20_000, 3);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                points
                    .par_iter()
                    .map(|p| pattern.resolve(*p))
                    .collect::<Vec<_>>()
            })
    };
    let one = run(1);
    let eight = run(8);
    assert_eq!(one, eight);
    let serial: Vec<_> = points.iter().map(|p| pattern.resolve(*p)).collect();
    assert_eq!(one, serial);
    // The three maps holding materials and the glitter contribute; the map
    // of big tiles holds only maps, so it never chooses a material itself.
    let glitter = one.iter().filter(|r| r.glitter_cell.is_some()).count();
    assert!(glitter > 0 && glitter < points.len() / 10, "{glitter}");
    for map in [0, 1, 3] {
        assert!(
            one.iter().any(|r| r.map_index == map),
            "map {map} never used"
        );
    }
    assert!(one.iter().all(|r| r.map_index != 2));
    let other = lepidolite_like(8);
    let differ = points
        .iter()
        .zip(&one)
        .filter(|(p, r)| other.resolve(**p).material != r.material)
        .count();
    assert!(differ > points.len() / 2, "only {differ} points differ");
}

#[test]
fn pattern_rejects_cycles_and_bad_indices() {
    let map = |children: Vec<Entry>| {
        Node::Map(
            SurfaceMap::new(
                grid(0.1, 1),
                children.into_iter().map(|e| (e, 1.0)).collect(),
            )
            .unwrap(),
        )
    };
    let direct = Pattern::new(vec![map(vec![Entry::Node(0)])], Entry::Node(0), None, 1);
    assert!(direct.unwrap_err().to_string().contains("contains itself"));
    let indirect = Pattern::new(
        vec![
            map(vec![Entry::Material(0), Entry::Node(1)]),
            map(vec![Entry::Node(2)]),
            map(vec![Entry::Node(0)]),
        ],
        Entry::Node(0),
        None,
        1,
    );
    assert!(indirect
        .unwrap_err()
        .to_string()
        .contains("contains itself"));
    let shared = Pattern::new(
        vec![
            map(vec![Entry::Node(1), Entry::Node(2)]),
            map(vec![Entry::Node(2)]),
            map(vec![Entry::Material(0)]),
        ],
        Entry::Node(0),
        None,
        1,
    );
    assert!(shared.is_ok(), "a diamond is not a cycle");
    assert!(Pattern::new(vec![], Entry::Material(3), None, 3).is_err());
    assert!(Pattern::new(vec![], Entry::Node(0), None, 3).is_err());
}

#[test]
fn constructors_reject_bad_parameters() {
    let bad_weights = SurfaceMap::new(grid(0.1, 1), materials(&[0.0, 0.0]));
    assert!(bad_weights
        .unwrap_err()
        .to_string()
        .contains("at least one weight > 0"));
    assert!(SurfaceMap::new(grid(0.1, 1), materials(&[1.0, -1.0])).is_err());
    assert!(SurfaceMap::new(grid(0.0, 1), materials(&[1.0])).is_err());
    assert!(SurfaceMap::new(grid(f64::NAN, 1), materials(&[1.0])).is_err());
    let f = facets(
        0.5,
        1,
        Tilt::Gaussian {
            sigma_tilt_deg: 5.0,
        },
    );
    assert!(
        GlitterMap::new(grid(0.2, 1), 0.1, vec![(0, 1.0)], f).is_err(),
        "facets bigger than glitter"
    );
    let f = facets(
        0.1,
        1,
        Tilt::Gaussian {
            sigma_tilt_deg: 5.0,
        },
    );
    assert!(GlitterMap::new(grid(0.2, 1), 1.5, vec![(0, 1.0)], f).is_err());
    assert!(GlitterMap::new(grid(0.2, 1), 0.5, vec![(0, 1.0)], f).is_ok());
}

/// The tree walk written naively from the public parts (no reuse of
/// nearest-site queries between a per-cell switch and the map below it).
fn naive_surface(pattern: &Pattern, p: DVec3) -> u32 {
    let mut entry = pattern.root();
    loop {
        match entry {
            Entry::Material(m) => return m,
            Entry::Node(n) => {
                entry = match &pattern.nodes()[n as usize] {
                    Node::Map(map) => map.entry_of_cell(map.voronoi.nearest(p).cell_id),
                    Node::Switch(s) => s.select(p),
                }
            }
        }
    }
}

#[test]
fn resolve_agrees_with_a_naive_walk() {
    let pattern = lepidolite_like(21);
    let mut inclusion_points = 0;
    for p in test_points(20_000, 9) {
        let (material, _, map) = pattern.resolve_surface(p);
        assert_eq!(material, naive_surface(&pattern, p), "at {p}");
        inclusion_points += usize::from(map == 3);
        let r = pattern.resolve(p);
        if r.glitter_cell.is_none() {
            assert_eq!(r.material, material);
        } else {
            assert!((17..21).contains(&r.material));
        }
    }
    // The shared-cell path (switch per inclusion cell, then the inclusion
    // map) is exercised.
    assert!(inclusion_points > 100, "{inclusion_points}");
}

#[test]
fn fill_modulation_scales_the_threshold_at_the_feature_point() {
    let fill = 0.6;
    let m = marble(12);
    let mut glitter = GlitterMap::new(
        grid(0.2, 31),
        fill,
        vec![(1, 1.0)],
        facets(0.05, 6, Tilt::UniformCone { max_tilt_deg: 10.0 }),
    )
    .unwrap();
    glitter.fill_modulation = Some(SwitchFunction::Marble(m));
    let pattern = Pattern::new(vec![], Entry::Material(0), Some(glitter), 2).unwrap();
    let (mut filled, mut n) = (0, 0);
    for c in cube_cells(20) {
        let site = centre(c, 0.2); // jitter 0: the feature point is the centre
        let id = hash_cell(c, 31);
        let expected = unit(derive_stream(id, STREAM_FILL)) < fill * m.value(site).clamp(0.0, 1.0);
        // Any point of the cell, not only the site, follows the cell's decision.
        let r = pattern.resolve(site + DVec3::new(0.07, -0.05, 0.03));
        assert_eq!(r.glitter_cell.is_some(), expected, "cell {c}");
        filled += usize::from(expected);
        n += 1;
    }
    // Modulation lowers the fill below the unmodulated fraction.
    let fraction = filled as f64 / n as f64;
    assert!(fraction > 0.1 && fraction < fill - 0.1, "{fraction}");
}

#[test]
fn pattern_types_are_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<Pattern>();
    check::<lapidary::texture::pattern::Resolved>();
}

/// Marbles of several shapes: the recipe defaults, the lepidolite's, a
/// negative gain (turbulence then alternates in sign), a negative
/// amplitude and a single octave (nothing to skip).
fn marble_variants() -> Vec<Marble> {
    let with = |direction: DVec3, frequency: f64, amplitude: f64, octaves: u32, gain: f64| Marble {
        direction,
        frequency,
        amplitude,
        turbulence: Turbulence {
            source: PerlinSource::new(17 + octaves as u64),
            frequency: 1.5,
            octaves,
            lacunarity: 2.0,
            gain,
        },
    };
    vec![
        marble(4),
        with(DVec3::new(1.0, 0.3, 0.0), 6.0, 3.0, 4, 0.5),
        with(DVec3::new(0.2, 1.0, -0.4), 3.0, 5.0, 6, -0.6),
        with(DVec3::Z, 2.0, -4.0, 3, 0.7),
        with(DVec3::X, 5.0, 2.5, 1, 0.5),
    ]
}

/// Ranges over `[0, 1]` with the given inner boundaries, entry `i` for range `i`.
fn ranges_with(boundaries: &[f64]) -> Vec<SwitchRange> {
    let mut ends = vec![0.0];
    ends.extend_from_slice(boundaries);
    ends.push(1.0);
    ends.windows(2)
        .enumerate()
        .map(|(i, w)| SwitchRange {
            from: w[0],
            to: w[1],
            entry: Entry::Material(i as u32),
        })
        .collect()
}

#[test]
fn marble_switch_early_exit_selects_what_the_full_value_selects() {
    // The marble switch may stop after a few octaves (phase arcs); the entry
    // must be the one the definition gives: the range of the full value.
    let boundary_sets: [&[f64]; 5] = [
        &[0.85],
        &[0.3, 0.8],
        &[0.1, 0.45, 0.5, 0.93],
        &[0.5],
        &[1e-8], // too close to 0: left to the general path
    ];
    let points = test_points(20_000, 99);
    let mut checked = 0usize;
    for m in marble_variants() {
        for boundaries in boundary_sets {
            let ranges = ranges_with(boundaries);
            let switch = Switch::new(SwitchFunction::Marble(m), ranges.clone(), None).unwrap();
            for p in &points {
                let v = m.value(*p);
                let i = ranges.partition_point(|r| r.to <= v).min(ranges.len() - 1);
                assert_eq!(
                    switch.select_at_sample(*p),
                    ranges[i].entry,
                    "at {p}, value {v}"
                );
                checked += 1;
            }
            // Points right on the boundaries' level sets: bisect the value
            // along a segment that crosses a boundary, then check there.
            for b in boundaries.iter() {
                for p in points.iter().take(200) {
                    let (mut lo, mut hi) = (*p, *p + DVec3::new(0.37, 0.11, -0.23));
                    if (m.value(lo) - b) * (m.value(hi) - b) > 0.0 {
                        continue;
                    }
                    for _ in 0..80 {
                        let mid = 0.5 * (lo + hi);
                        if (m.value(mid) - b) * (m.value(lo) - b) > 0.0 {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    for q in [lo, hi] {
                        let v = m.value(q);
                        let i = ranges.partition_point(|r| r.to <= v).min(ranges.len() - 1);
                        assert_eq!(
                            switch.select_at_sample(q),
                            ranges[i].entry,
                            "at {q}, value {v}"
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(checked > 500_000, "{checked}");
}

#[test]
fn marble_phase_bounds_hold_the_final_phase_and_the_value_is_bit_exact() {
    // `value_unless` must report intervals that contain the final phase
    // (written out here from the definition), and fall back to exactly
    // `value` when nothing settles.
    let points = test_points(5_000, 7);
    let mut intervals = 0usize;
    for m in marble_variants() {
        for p in &points {
            let phase = m.frequency * p.dot(m.direction) + m.amplitude * m.turbulence.value(*p);
            let mut previous_width = f64::INFINITY;
            let result = m.value_unless(*p, |low, high| -> Option<()> {
                assert!(
                    low <= phase + 1e-12 && phase <= high + 1e-12,
                    "{low} {phase} {high}"
                );
                assert!(high - low <= previous_width + 1e-12, "intervals shrink");
                previous_width = high - low;
                intervals += 1;
                None
            });
            assert_eq!(result.unwrap_err().to_bits(), m.value(*p).to_bits());
        }
    }
    // (3 + 3 + 5 + 2 + 0) checks per point.
    assert_eq!(intervals, 13 * points.len());
}
