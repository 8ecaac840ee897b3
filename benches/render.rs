//! Whole-renderer speed on the built-in studio scene with the default gem
//! (green aventurine) and on issue 6's peer scene (`bench/peer-scene.ron`:
//! the plain glossy stone, and the same stone in lavender lepidolite), each
//! a 128² image at 16 samples per pixel with the materials compiled
//! beforehand, so the ratio lepidolite / plain is the cost of the pattern
//! and its richer materials in tracing; and the obvhs traversal alone
//! (camera rays through `World::intersect`).
//!
//! Run with `cargo bench --bench render`; criterion reports the time per
//! image and per ray batch, from which samples/s and Mrays/s follow
//! (samples = 128 · 128 · 16 = 262 144 per image; 16 384 rays per batch).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use lapidary::recipe::library::DEFAULT_GEM;
use lapidary::render::film::{render, FilmSettings};
use lapidary::render::prepare::{camera_for, prepare_scene};
use lapidary::scene::{default_scene, load_scene};
use std::path::Path;

const SIDE: u32 = 128;
const SPP: u32 = 16;

fn renderer(c: &mut Criterion) {
    let scene = default_scene();
    let default_gem = lapidary::recipe::gem::GemSource::load(DEFAULT_GEM).expect("built-in");
    let cache = lapidary::recipe::TableCache::in_memory();
    let tables = lapidary::recipe::Tables::Computed(&cache);
    let prepared =
        prepare_scene(&scene, &default_gem, None, 4, tables, &|_| {}).expect("default scene");
    let camera = camera_for(&scene, SIDE, SIDE);
    let settings = FilmSettings::new(SIDE, SIDE, SPP, 0);

    let mut group = c.benchmark_group("render");
    group.sample_size(10);
    group.throughput(Throughput::Elements(u64::from(SIDE * SIDE * SPP)));
    group.bench_function("studio_128px_16spp_samples", |b| {
        b.iter(|| render(&prepared, &camera, &settings, &|_| {}))
    });
    for (name, file) in [
        ("peer_plain_128px_16spp_samples", "peer-scene.ron"),
        (
            "peer_lepidolite_128px_16spp_samples",
            "peer-scene-lepidolite.ron",
        ),
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("bench")
            .join(file);
        let peer = load_scene(&path).expect("the peer scene");
        let peer_prepared =
            prepare_scene(&peer, &default_gem, None, 4, tables, &|_| {}).expect("peer");
        let peer_camera = camera_for(&peer, SIDE, SIDE);
        group.bench_function(name, |b| {
            b.iter(|| render(&peer_prepared, &peer_camera, &settings, &|_| {}))
        });
    }
    group.finish();

    // Traversal alone: one camera ray per pixel through the BVH.
    let rays: Vec<_> = (0..SIDE * SIDE)
        .map(|i| camera.ray(f64::from(i % SIDE) + 0.5, f64::from(i / SIDE) + 0.5))
        .collect();
    let mut group = c.benchmark_group("bvh");
    group.throughput(Throughput::Elements(rays.len() as u64));
    group.bench_function("closest_hit_rays", |b| {
        b.iter(|| {
            rays.iter()
                .filter(|r| {
                    prepared
                        .world
                        .intersect(r.origin, r.direction, 0.0, f64::INFINITY)
                        .is_some()
                })
                .count()
        })
    });
    group.finish();
}

criterion_group!(benches, renderer);
criterion_main!(benches);
