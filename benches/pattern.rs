//! Per-point cost of resolving the lavender-lepidolite pattern tree
//! (section 4.3.1, figure 4.7: marble switch per inclusion cell, big tiles
//! holding dark/bright tile maps, sparse glitter with facets). Each iteration
//! resolves the next of 1024 fixed points in a unit-sized stone, so branch
//! history and caches resemble a render rather than one repeated point.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use glam::DVec3;
use lapidary::recipe::gem::load_gem;

fn bench_points() -> Vec<DVec3> {
    let mut state = 0x1234_5678_9abc_def1_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..1024)
        .map(|_| DVec3::new(next(), next(), next()) * 2.0 - DVec3::ONE)
        .collect()
}

fn pattern(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/gem-recipes/lavender-lepidolite.ron"
    );
    let gem = load_gem(path).expect("lepidolite recipe");
    let points = bench_points();
    let mut i = 0;
    c.bench_function("lepidolite resolve", |b| {
        b.iter(|| {
            i = (i + 1) & 1023;
            gem.pattern.resolve(black_box(points[i]))
        })
    });
    c.bench_function("lepidolite resolve_surface", |b| {
        b.iter(|| {
            i = (i + 1) & 1023;
            gem.pattern.resolve_surface(black_box(points[i]))
        })
    });
}

criterion_group!(benches, pattern);
criterion_main!(benches);
