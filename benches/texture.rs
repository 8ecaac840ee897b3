//! Per-call cost of the texture primitives (evaluated once per ray hit).
//! Each iteration queries the next of 1024 fixed points, so branch history
//! and cache behaviour resemble a render rather than one repeated point.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use glam::DVec3;
use lapidary::texture::noise_fns::{Fbm, Marble, PerlinSource, Turbulence};
use lapidary::texture::voronoi::Voronoi;
use noise::NoiseFn;

fn bench_points() -> Vec<DVec3> {
    let mut state = 0x1234_5678_9abc_def1_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..1024)
        .map(|_| DVec3::new(next(), next(), next()) * 20.0 - DVec3::splat(10.0))
        .collect()
}

fn per_point<T>(c: &mut Criterion, name: &str, f: impl Fn(DVec3) -> T) {
    let points = bench_points();
    let mut i = 0;
    c.bench_function(name, |b| {
        b.iter(|| {
            i = (i + 1) & 1023;
            f(black_box(points[i]))
        })
    });
}

fn texture(c: &mut Criterion) {
    let voronoi = Voronoi {
        cell_size: 0.37,
        jitter: 1.0,
        stretch: DVec3::ONE,
        seed: 7,
    };
    let stretched = Voronoi {
        stretch: DVec3::new(3.0, 1.0, 1.0),
        ..voronoi
    };
    let turbulence = Turbulence {
        source: PerlinSource::new(7),
        frequency: 1.3,
        octaves: 4,
        lacunarity: 2.0,
        gain: 0.5,
    };
    let fbm = Fbm {
        source: PerlinSource::new(7),
        frequency: 1.3,
        octaves: 4,
        lacunarity: 2.0,
        gain: 0.5,
    };
    let marble = Marble {
        direction: DVec3::X,
        frequency: 6.0,
        amplitude: 5.0,
        turbulence,
    };
    let source = PerlinSource::new(7);

    per_point(c, "voronoi_nearest_f1_id", |p| {
        let s = voronoi.nearest(p);
        (s.f1, s.cell_id)
    });
    // The miss path of the resolve cache: nearest site plus the region
    // where it stays nearest; and the hit path, one containment test.
    per_point(c, "voronoi_certify_nearest", |p| {
        voronoi.certify_nearest(p).site
    });
    let certified = voronoi.certify_nearest(DVec3::splat(0.1));
    per_point(c, "voronoi_nearest_within", |p| {
        voronoi.nearest_within(&certified, DVec3::splat(0.1) + p * 1e-3)
    });
    per_point(c, "voronoi_query_full", |p| voronoi.query(p));
    per_point(c, "voronoi_query_full_stretched", |p| stretched.query(p));
    per_point(c, "voronoi_brute_force_reference", |p| {
        voronoi.query_brute_force(p)
    });
    per_point(c, "perlin", |p| source.value(p));
    let crate_perlin = noise::Perlin::new(7);
    per_point(c, "perlin_noise_crate_for_comparison", |p| {
        crate_perlin.get([p.x, p.y, p.z])
    });
    per_point(c, "fbm_4_octaves", |p| fbm.value(p));
    per_point(c, "marble_4_octaves", |p| marble.value(p));
}

criterion_group!(benches, texture);
criterion_main!(benches);
