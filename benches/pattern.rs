//! Per-point cost of resolving the lavender-lepidolite pattern tree
//! (section 4.3.1, figure 4.7: marble switch per inclusion cell, big tiles
//! holding dark/bright tile maps, sparse glitter with facets). Each iteration
//! resolves the next of 1024 fixed points in a unit-sized stone, so branch
//! history and caches resemble a render rather than one repeated point
//! (and, for `resolve`, the per-thread cache rarely helps; the "pixel runs"
//! case shows it in a render's order).

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

/// 64 pixels of 16 samples each along a row across the stone: samples
/// within a 0.0028-unit footprint (a 96-pixel view of the peer scene).
fn pixel_run_points() -> Vec<DVec3> {
    let jitter = bench_points();
    const FOOTPRINT: f64 = 0.0028;
    (0..1024)
        .map(|k| {
            let pixel = (k / 16) as f64;
            let centre = DVec3::new(-0.09 + pixel * FOOTPRINT, 0.01, 0.03);
            centre + jitter[k] * (0.5 * FOOTPRINT)
        })
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
    c.bench_function("lepidolite resolve_uncached", |b| {
        b.iter(|| {
            i = (i + 1) & 1023;
            gem.pattern.resolve_uncached(black_box(points[i]))
        })
    });
    // A render's order: 16 samples spread over one pixel footprint (about
    // 1/3 of an inclusion cell), then the next pixel along a row; the
    // per-thread cache answers most of these without a Voronoi search.
    let pixel_runs = pixel_run_points();
    c.bench_function("lepidolite resolve, pixel runs", |b| {
        b.iter(|| {
            i = (i + 1) & 1023;
            gem.pattern.resolve(black_box(pixel_runs[i]))
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
