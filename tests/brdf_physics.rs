//! Physics of the layered BRDF: Fresnel tables, energy conservation (white
//! furnace), the random-walk reference against closed forms, and the
//! analytic model against the reference.

use glam::DVec3;
use lapidary::brdf::albedo::{directional_albedo, in_plane};
use lapidary::brdf::fresnel;
use lapidary::brdf::reference::{model_slice, reference_albedo, reference_slice};
use lapidary::brdf::{LayeredBrdf, Rgb};
use lapidary::recipe::compile::{compile_material, parse_material, MaterialSource};
use lapidary::recipe::library::builtin_material_names;
use lapidary::recipe::load_material;

fn material_from_ron(name: &str, text: &str) -> LayeredBrdf {
    let source = MaterialSource {
        path: format!("test:{name}"),
        name: name.into(),
        text: text.into(),
    };
    let m = parse_material(&source.path, text).expect("test material parses");
    compile_material(&source, &m).expect("test material compiles")
}

#[test]
fn a_material_from_its_text_is_the_library_s() {
    // `MaterialSource::new(path, text).compile()` is `load_material` from
    // text in memory: the same BRDF, named by the path's stem; a mistake
    // is placed in that path.
    let text = lapidary::recipe::library::builtin_material_source("brass").unwrap();
    let source = MaterialSource::new("my/brass.ron", text);
    assert_eq!(source.name, "brass");
    let (ours, library) = (source.compile().unwrap(), load_material("brass").unwrap());
    let (wi, wo) = (
        DVec3::new(0.3, 0.1, 0.95).normalize(),
        DVec3::new(-0.2, 0.0, 0.98).normalize(),
    );
    assert_eq!(ours.eval(wi, wo), library.eval(wi, wo));
    let broken = MaterialSource::new("my/broken.ron", "Material(layers: [Layer(ior: 9.0)])");
    let error = broken.compile().unwrap_err().to_string();
    assert!(error.starts_with("my/broken.ron:1:"), "{error}");
}

/// Hemispherical (cosine-weighted) average of the external dielectric
/// Fresnel reflectance, F̄ = 2∫F(μ)μ dμ, by the midpoint rule.
fn hemispherical_fresnel(eta: f64) -> f64 {
    let n = 100_000;
    (0..n)
        .map(|k| {
            let mu = (k as f64 + 0.5) / n as f64;
            2.0 * fresnel::dielectric(mu, eta) * mu / n as f64
        })
        .sum()
}

#[test]
fn conductor_fresnel_at_normal_incidence_matches_table_4_2() {
    // Table 4.2 of the notes, typed here independently of the RON files.
    let table = [
        ("gold", [0.1, 0.42, 1.56], [3.8, 2.5, 1.9]),
        ("silver", [0.14, 0.13, 0.157], [4.44, 3.25, 2.40]),
        ("aluminium", [1.94, 1.0, 0.6], [8.21, 6.69, 4.86]),
    ];
    for (name, n, k) in table {
        let brdf = load_material(name).unwrap();
        let lapidary::brdf::Base::Conductor {
            n_relative,
            k_relative,
            ..
        } = brdf.base
        else {
            panic!("{name} should be a bare conductor");
        };
        let f = fresnel::conductor(1.0, n_relative, k_relative);
        for c in 0..3 {
            let expected =
                ((n[c] - 1.0f64).powi(2) + k[c] * k[c]) / ((n[c] + 1.0f64).powi(2) + k[c] * k[c]);
            assert!(
                (f[c] - expected).abs() < 1e-12,
                "{name} channel {c}: {} vs {expected}",
                f[c]
            );
        }
    }
}

#[test]
fn reference_walk_over_black_returns_the_fresnel_reflectance() {
    let brdf = material_from_ron(
        "coat-over-black",
        "Material(layers: [Layer(ior: 1.5, roughness_deg: 0.0)], base: Black)",
    );
    for theta in [0.0f64, 45.0, 80.0] {
        let (albedo, _) = reference_albedo(&brdf, in_plane(theta), 2000, 1);
        let expected = fresnel::dielectric(theta.to_radians().cos(), 1.5);
        assert!(
            (albedo.x - expected).abs() < 1e-3,
            "θ={theta}: {} vs {expected}",
            albedo.x
        );
    }
}

#[test]
fn reference_walk_matches_the_closed_form_smooth_coat_over_lambert() {
    // Light enters with 1 − F(μ); inside, each upward crossing escapes with
    // (1 − F̄ₑ)/n² and is reflected back with F̄ᵢ = 1 − (1 − F̄ₑ)/n²; the
    // base returns ρ each time: R = F + (1 − F)·ρ(1 − F̄ₑ)/n² / (1 − ρF̄ᵢ).
    let n = 1.5;
    let fe = hemispherical_fresnel(n);
    let escape = (1.0 - fe) / (n * n);
    for rho in [1.0, 0.5] {
        let brdf = material_from_ron(
            "coat-over-lambert",
            &format!(
                "Material(layers: [Layer(ior: 1.5, roughness_deg: 0.0)], base: Diffuse(colour: ({rho}, {rho}, {rho})), multiple_scattering: false)"
            ),
        );
        for theta in [0.0f64, 40.0, 70.0] {
            let f = fresnel::dielectric(theta.to_radians().cos(), n);
            let expected = f + (1.0 - f) * rho * escape / (1.0 - rho * (1.0 - escape));
            let (albedo, err) = reference_albedo(&brdf, in_plane(theta), 40_000, 3);
            assert!(
                (albedo.x - expected).abs() < 4.0 * err.x + 2e-3,
                "ρ={rho} θ={theta}: walk {} vs closed form {expected}",
                albedo.x
            );
        }
    }
}

#[test]
fn single_crossing_white_lambert_under_clear_coat_reflects_about_0_43() {
    // The seed's model: F(0) + (1 − F(0))·(1 − F̄ₑ)/n² ≈ 0.43 (issue 2).
    let brdf = material_from_ron(
        "seed-faithful",
        "Material(layers: [Layer(ior: 1.5, roughness_deg: 0.01)], base: Diffuse(colour: (1.0, 1.0, 1.0)), multiple_scattering: false)",
    );
    let expected = 0.04 + 0.96 * (1.0 - hemispherical_fresnel(1.5)) / 2.25;
    let a = directional_albedo(&brdf, 0.0, 0.002, 1_000_000, 5);
    assert!(
        (a.mean.x - expected).abs() < 0.01,
        "{} vs {expected}",
        a.mean.x
    );
    assert!((expected - 0.43).abs() < 0.01);
}

#[test]
fn white_furnace_every_library_material_reflects_at_most_everything() {
    for name in builtin_material_names() {
        let brdf = load_material(name).unwrap();
        for k in 0..18 {
            let theta = k as f64 * 5.0;
            let a = directional_albedo(&brdf, theta, 0.004, 200_000, 11);
            let bound = Rgb::ONE + 3.0 * a.std_error;
            assert!(
                a.mean.cmple(bound).all(),
                "{name} at {theta}°: albedo {:?} ± {:?}",
                a.mean,
                a.std_error
            );
        }
    }
}

#[test]
fn compensated_clear_coats_over_white_lambert_keep_their_energy() {
    // Table 4.1's varnishes, smooth and rough, over a white Lambert base.
    for ior in [1.31, 1.45, 1.53, 1.7] {
        for roughness in [0.5, 10.0, 25.0] {
            let brdf = material_from_ron(
                "coat",
                &format!("Material(layers: [Layer(ior: {ior}, roughness_deg: {roughness})], base: Diffuse(colour: (1.0, 1.0, 1.0)))"),
            );
            for theta in [0.0, 20.0, 40.0, 60.0] {
                let a = directional_albedo(&brdf, theta, 0.003, 400_000, 13);
                assert!(
                    a.mean.min_element() >= 0.95,
                    "IOR {ior}, m {roughness}°, θ {theta}°: albedo {:?}",
                    a.mean
                );
            }
        }
    }
}

/// Lossless stacks over a white base that are hard on the walk and the
/// tables: sixteen rough Blinn layers (IOR 1.3–1.7, 10–19°), the same in
/// GGX, and one rough coat of IOR 5.
fn lossless_stacks() -> [(&'static str, String); 3] {
    let layers: Vec<String> = (0..16)
        .map(|i| {
            format!(
                "Layer(ior: {:.1}, roughness_deg: {})",
                1.3 + 0.1 * f64::from(i % 5),
                10 + 3 * (i % 4)
            )
        })
        .collect();
    let white = "base: Diffuse(colour: (1.0, 1.0, 1.0))";
    [
        (
            "sixteen layers",
            format!("Material(layers: [{}], {white})", layers.join(", ")),
        ),
        (
            "sixteen GGX layers",
            format!(
                "Material(layers: [{}], distribution: Ggx, {white})",
                layers.join(", ")
            ),
        ),
        (
            "IOR 5",
            format!("Material(layers: [Layer(ior: 5.0, roughness_deg: 30)], {white})"),
        ),
    ]
}

#[test]
fn the_walk_returns_all_light_from_lossless_stacks_of_many_rough_layers() {
    // Lossless layers over a white base: all light leaves, whatever the
    // stack. Sixteen rough layers (IOR 1.3–1.7, 10–19°) meet grazing angles
    // inside, and one coat of IOR 5 traps light for dozens of bounces:
    // with normals drawn from D(h) cosθh and weights divided by albedo
    // tables, the walk gave 0.64 to 2.50 and 0.65 to 0.79 at neighbouring
    // angles (100 000 paths). Visible normals, kept with probability G/G1,
    // make every interaction below the top weigh 1 (measured 0.994–1.006
    // at 100 000 paths; the top's split into reflected and transmitted
    // parts varies a path's power a little).
    for (name, text) in lossless_stacks() {
        let brdf = material_from_ron("stack", &text);
        for theta in (0..=85).step_by(5) {
            let (walk, error) = reference_albedo(&brdf, in_plane(f64::from(theta)), 20_000, 29);
            let bound = 0.01 + 4.0 * error.max_element();
            assert!(
                (walk.max_element() - 1.0).abs() < bound
                    && (walk.min_element() - 1.0).abs() < bound,
                "{name} at {theta}°: the walk returns {walk:?} ± {error:?}"
            );
        }
    }
}

#[test]
fn the_compensated_model_of_lossless_stacks_makes_no_energy() {
    // The compensation returns E_stack − E_single at each table node, so
    // the model reflects E_stack + (the true E_single − the table's) there:
    // an E_single estimated low makes light. From one 64 × 64 batch the
    // sixteen-layer stacks' tables were up to 0.023 low (0.009 standard
    // error a node) and the model returned up to 1.018; where the stack
    // keeps nearly all light (here everywhere), E_single is sampled in
    // batches until its standard error is 10⁻³ (at most sixteen: a
    // quarter of one batch's). The true E_single: four 256 × 256 grids of
    // other seeds (an eighth of one batch's error).
    use lapidary::brdf::compensation::{
        node_cosine, single_crossing_albedo_sampled, Compensation, TABLE_NODES,
    };
    use rayon::prelude::*;
    for (name, text) in lossless_stacks() {
        let mut brdf = material_from_ron("stack", &text);
        brdf.compensation = None;
        let table = Compensation::compute(&brdf, 7).expect("a rough stack needs a table");
        let true_single: Vec<Rgb> = (0..TABLE_NODES)
            .into_par_iter()
            .map(|k| {
                (1234..1238)
                    .map(|seed| single_crossing_albedo_sampled(&brdf, node_cosine(k), seed, 256))
                    .fold(Rgb::ZERO, |sum, e| sum + e)
                    / 4.0
            })
            .collect();
        for (k, true_single) in true_single.iter().enumerate() {
            let model = table.stack_albedo[k] + *true_single - table.single_albedo[k];
            assert!(
                model.max_element() <= 1.008,
                "{name} at node {k}: the model returns {model:?} (E_single {:?} in the \
                 table, {true_single:?} finely)",
                table.single_albedo[k]
            );
        }
    }
}

#[test]
fn analytic_albedo_is_within_0_02_of_the_random_walk_for_every_library_material() {
    let angles = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 85.0];
    for name in builtin_material_names() {
        let brdf = load_material(name).unwrap();
        for theta in angles {
            let analytic = directional_albedo(&brdf, theta, 0.002, 400_000, 17);
            let (walk, walk_err) = reference_albedo(&brdf, in_plane(theta), 20_000, 19);
            let diff = (analytic.mean - walk).abs().max_element();
            let noise = 3.0 * (analytic.std_error + walk_err).max_element();
            assert!(
                diff <= 0.02 + noise,
                "{name} at {theta}°: analytic {:?} vs walk {:?}",
                analytic.mean,
                walk
            );
        }
    }
}

#[test]
fn compensation_lobe_is_reciprocal() {
    let brdf = load_material("sugar").unwrap();
    let c = brdf.compensation.as_ref().expect("sugar is compensated");
    let a = DVec3::new(0.3, 0.1, 0.9).normalize();
    let b = DVec3::new(-0.7, 0.2, 0.3).normalize();
    assert_eq!(c.eval(a, b), c.eval(b, a));
}

// Thread-count independence of the tables is tested past the material
// cache in tests/compile_speed.rs (`walked_tables_are_identical_on_1_and_4_threads`).

#[test]
fn library_lobes_follow_the_random_walk_in_the_plane_of_incidence() {
    // The model as renders use it (compensation on) against its random
    // walk, both binned alike (squares of 0.02 on the projected disc),
    // light at 30°: the L1 error Σ|model − walk|·cosθₒ / Σ walk·cosθₒ over
    // the in-plane slice, green. Measured 2026-12-04 (bench/results/
    // 2026-12-04-lobe-accuracy.md): a varnish, a bare metal and a smooth
    // coat over colour 0.00, a rough coat over colour 0.03, a rough paint
    // 0.08. (The coated metals, 0.1–1.0 off under section 4.2.3's
    // roughness, wait on a decision and are not pinned here.)
    let angles: Vec<f64> = (0..=58).map(|k| -87.0 + f64::from(k) * 3.0).collect();
    for (name, limit) in [
        ("plastics", 0.03),
        ("gold", 0.03),
        ("red-acrylic", 0.03),
        ("red-garnet", 0.06),
        ("green-latex", 0.12),
    ] {
        let brdf = load_material(name).unwrap();
        let model = model_slice(&brdf, 30.0, &angles, 0.02);
        let walk = reference_slice(&brdf, 30.0, &angles, 2_000_000, 0.02, 7);
        let (mut difference, mut total) = (0.0, 0.0);
        for ((theta, m), w) in angles.iter().zip(&model).zip(&walk) {
            let cos = theta.to_radians().cos();
            difference += cos * (m.y - w.y).abs();
            total += cos * w.y;
        }
        let error = difference / total;
        assert!(error < limit, "{name}: L1 error {error:.3} (limit {limit})");
    }
}

#[test]
#[should_panic(expected = "theta_deg = NaN; allowed: 0 to 90 degrees")]
fn directional_albedo_refuses_an_angle_outside_the_hemisphere() {
    // A NaN angle gave an albedo of 0, silently.
    let brdf = lapidary::recipe::load_material("gold").unwrap();
    directional_albedo(&brdf, f64::NAN, 0.01, 4096, 1);
}
