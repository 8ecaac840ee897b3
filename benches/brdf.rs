//! Criterion benchmarks of BRDF eval and sample for 1-, 2- and 3-layer
//! materials (`cargo bench --bench brdf`).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use lapidary::brdf::LayeredBrdf;
use lapidary::recipe::compile::{compile_material, parse_material, MaterialSource};
use lapidary::recipe::load_material;

/// A coat of `layers` varnish layers (IOR 1.5, 1.4, 1.6; 2°, 8°, 4°; tinted)
/// over a red Lambert base, compensation on.
fn stack_of(layers: usize) -> LayeredBrdf {
    let all = [
        "Layer(ior: 1.5, roughness_deg: 2.0, thickness: 0.2, absorption: (0.1, 0.3, 0.6))",
        "Layer(ior: 1.4, roughness_deg: 8.0)",
        "Layer(ior: 1.6, roughness_deg: 4.0, thickness: 0.5, absorption: (0.2, 0.1, 0.0))",
    ];
    let text = format!(
        "Material(layers: [{}], base: Diffuse(colour: (0.7, 0.2, 0.1)))",
        all[..layers].join(", ")
    );
    let source = MaterialSource {
        path: "bench".into(),
        name: format!("{layers}-layer"),
        text: text.clone(),
    };
    compile_material(&source, &parse_material("bench", &text).unwrap()).unwrap()
}
use lapidary::sampling::{direction_from_degrees, Rng};

fn bench_materials(c: &mut Criterion) {
    let mut materials = vec![load_material("gold").expect("library material")];
    materials.extend((1..=3).map(stack_of));
    for brdf in materials {
        let layers = brdf.interfaces.len();
        let name = brdf.name.clone();
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
