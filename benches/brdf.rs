//! Criterion benchmarks of BRDF eval and sample for 1-, 2- and 3-layer
//! materials (`cargo bench --bench brdf`).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use lapidary::recipe::load_material;
use lapidary::sampling::{direction_from_degrees, Rng};

fn bench_materials(c: &mut Criterion) {
    // 0 layers: gold; 1: red-garnet; 2: light-blue-house-paint / brass.
    for name in ["gold", "red-garnet", "light-blue-house-paint", "brass"] {
        let brdf = load_material(name).expect("library material");
        let layers = brdf.interfaces.len();
        let wo = direction_from_degrees(35.0, 10.0);
        let wi = direction_from_degrees(50.0, 200.0);
        c.bench_function(&format!("eval/{layers}-layer/{name}"), |b| {
            b.iter(|| black_box(brdf.eval(black_box(wi), black_box(wo))))
        });
        let mut rng = Rng::new(1, 2);
        c.bench_function(&format!("sample/{layers}-layer/{name}"), |b| {
            b.iter(|| black_box(brdf.sample(black_box(wo), rng.next_3())))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = bench_materials
}
criterion_main!(benches);
