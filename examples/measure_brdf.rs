//! Measurements quoted in the README: per library material, the worst
//! difference between the analytic albedo and the random-walk reference
//! (0–85°), and the worst reciprocity error |f(i,o) − f(o,i)| / max.
//!
//! `cargo run --release --example measure_brdf`

use lapidary::brdf::albedo::{albedo_angles_deg, directional_albedo, in_plane};
use lapidary::brdf::reference::reference_albedo;
use lapidary::recipe::library::builtin_material_names;
use lapidary::recipe::load_material;
use lapidary::sampling::{direction_from_degrees, Rng};

fn main() {
    println!("| material | worst \\|analytic − walk\\| albedo, 0–85° (at θ) | same, seed model (no compensation) | reciprocity, θ ≤ 60° | reciprocity, θ ≤ 85° |");
    println!("|---|---|---|---|---|");
    for name in builtin_material_names() {
        let brdf = load_material(name).expect("library material");
        let mut seed_model = brdf.clone();
        seed_model.compensation = None;
        let (mut worst, mut worst_at, mut worst_seed) = (0.0f64, 0.0, 0.0f64);
        for theta in albedo_angles_deg() {
            let (walk, _) = reference_albedo(&brdf, in_plane(theta), 40_000, 19);
            let a = directional_albedo(&brdf, theta, 0.0015, 1_000_000, 17);
            let s = directional_albedo(&seed_model, theta, 0.0015, 1_000_000, 17);
            let d = (a.mean - walk).abs().max_element();
            if d > worst {
                worst = d;
                worst_at = theta;
            }
            worst_seed = worst_seed.max((s.mean - walk).abs().max_element());
        }
        // Reciprocity over random pairs away from the specular spike.
        let mut rng = Rng::new(5, 0);
        let (mut recip, mut recip_60) = (0.0f64, 0.0f64);
        for _ in 0..20_000 {
            let (ti, to) = (rng.next_f64() * 85.0, rng.next_f64() * 85.0);
            let wi = direction_from_degrees(ti, rng.next_f64() * 360.0);
            let wo = direction_from_degrees(to, rng.next_f64() * 360.0);
            let (a, b) = (brdf.eval(wi, wo), brdf.eval(wo, wi));
            let scale = a.max_element().max(b.max_element());
            if scale > 1e-3 {
                let e = (a - b).abs().max_element() / scale;
                recip = recip.max(e);
                if ti <= 60.0 && to <= 60.0 {
                    recip_60 = recip_60.max(e);
                }
            }
        }
        println!(
            "| {name} | {worst:.4} ({worst_at}°) | {worst_seed:.3} | {recip_60:.3} | {recip:.3} |"
        );
    }
}
