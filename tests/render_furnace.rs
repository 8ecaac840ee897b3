//! The renderer against light transport with known answers: furnace tests
//! and a mirror-like metal under a uniform sky.

use glam::{DQuat, DVec3};
use lapidary::brdf::Rgb;
use lapidary::geometry::{Cabochon, CabochonParams};
use lapidary::recipe::compile::metal_normal_incidence;
use lapidary::recipe::gem::{compile_gem, Gem, GemSource};
use lapidary::recipe::TableCache;
use lapidary::recipe::Tables;
use lapidary::render::camera::PinholeCamera;
use lapidary::render::environment::Environment;
use lapidary::render::film::{render, Film, FilmSettings};
use lapidary::render::flake_lobe::FlakeLobes;
use lapidary::render::render_scene::RenderScene;
use lapidary::render::world::{StoneInstance, World};

/// Compiles gem recipe `text` (`path` for messages) with its compensation
/// tables, computed afresh.
fn compile_text(path: &str, text: &str) -> Result<Gem, lapidary::recipe::RecipeError> {
    let cache = TableCache::in_memory();
    compile_gem(&GemSource::new(path, text), None, Tables::Computed(&cache))
}

/// One default oval stone under a constant sky, seen from straight above.
fn render_single_material(material: &str, sky: f64, size: u32, spp: u32, threads: usize) -> Film {
    let text = format!(r#"Gem(materials: {{"m": {material}}}, surface: "m")"#);
    let gem = compile_text("test", &text).unwrap();
    let stone = StoneInstance {
        cabochon: Cabochon::new(CabochonParams::default()).unwrap(),
        rotation: DQuat::IDENTITY,
        position: DVec3::ZERO,
        gem: 0,
    };
    let scene = RenderScene {
        world: World::new(vec![stone], None),
        material_id_bases: RenderScene::material_id_bases(std::slice::from_ref(&gem)),
        gems: vec![gem],
        ground_brdf: None,
        lights: vec![],
        environment: Environment::Constant(Rgb::splat(sky)),
        max_bounces: 4,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes: FlakeLobes::default(),
    };
    let camera = PinholeCamera::new(
        DVec3::new(0.0, 0.0, 60.0),
        DVec3::ZERO,
        DVec3::Y,
        12.0,
        size,
        size,
    );
    let settings = FilmSettings::new(size, size, spp, 1);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| render(&scene, &camera, &settings, &|_| {}))
}

#[test]
fn a_white_lambert_stone_in_a_white_furnace_disappears() {
    // A convex stone sees only the sky: L = ∫ (1/π) · 1 · cosθ dω = 1 at
    // every point, for every viewing direction (energy conservation with
    // albedo exactly 1).
    let film = render_single_material(
        r#"Material(layers: [], base: Diffuse(colour: (1, 1, 1)))"#,
        1.0,
        32,
        16,
        2,
    );
    let mut on_stone = 0;
    let mut sum = 0.0;
    for (rgb, alpha) in film.rgb.iter().zip(&film.alpha) {
        if *alpha == 1.0 {
            on_stone += 1;
            sum += f64::from(rgb[1]);
            for c in rgb {
                assert!((f64::from(*c) - 1.0).abs() < 0.15, "pixel {rgb:?}");
            }
        } else if *alpha == 0.0 {
            assert_eq!(*rgb, [1.0, 1.0, 1.0], "the sky itself");
        }
    }
    assert!(
        on_stone > 200,
        "the stone covers the middle of the film ({on_stone} px)"
    );
    let mean = sum / f64::from(on_stone);
    assert!(
        (mean - 1.0).abs() < 0.01,
        "mean radiance on the stone {mean}"
    );
    assert_eq!(film.stats.bad_samples, 0);
}

#[test]
fn a_varnished_white_stone_never_creates_energy() {
    // A clear IOR 1.5 coat over white Lambert: at most 1 (white furnace),
    // and with the multiple-scattering compensation close to 1.
    let film = render_single_material(
        r#"Material(layers: [Layer(ior: 1.5)], base: Diffuse(colour: (1, 1, 1)))"#,
        1.0,
        24,
        16,
        2,
    );
    let stone: Vec<f64> = film
        .rgb
        .iter()
        .zip(&film.alpha)
        .filter(|(_, a)| **a == 1.0)
        .map(|(rgb, _)| f64::from(rgb[1]))
        .collect();
    let mean = stone.iter().sum::<f64>() / stone.len() as f64;
    assert!(mean <= 1.01, "energy created: {mean}");
    assert!(mean > 0.9, "energy lost: {mean}");
}

#[test]
fn a_smooth_silver_stone_reflects_the_sky_scaled_by_fresnel() {
    // A near-mirror reflects a uniform sky of radiance 2 as 2·F(θ); at the
    // dome's apex, seen from straight above, θ ≈ 0: F(0) of silver from its
    // complex IOR (section 4.2.3 table).
    let film = render_single_material(
        r#"Material(layers: [], base: Conductor(metal: "silver", roughness_deg: 0.5))"#,
        2.0,
        33,
        8,
        2,
    );
    let f0 = metal_normal_incidence("silver").unwrap();
    let centre = film.rgb[16 * 33 + 16];
    for c in 0..3 {
        let expected = 2.0 * f0[c];
        let got = f64::from(centre[c]);
        assert!(
            (got - expected).abs() < 0.02 * expected,
            "channel {c}: {got} vs 2·F0 = {expected}"
        );
    }
}

#[test]
fn the_image_is_the_same_for_any_number_of_threads() {
    let material = r#"Material(layers: [Layer(ior: 1.5, roughness_deg: 5)], base: Diffuse(colour: (0.7, 0.3, 0.2)))"#;
    let one = render_single_material(material, 1.0, 16, 4, 1);
    let four = render_single_material(material, 1.0, 16, 4, 4);
    assert_eq!(one, four);
}
