//! The glitter facets of opaque stones shaded by their footprint
//! (`render::glitter_facets`): where a pixel holds thousands of facets, a
//! vertex draws facets from the map's tilt distribution instead of taking
//! the one under its point. The picture's expected value stays that of
//! the facets one by one; its noise falls.

use glam::{DQuat, DVec3};
use lapidary::brdf::Rgb;
use lapidary::geometry::{Cabochon, CabochonParams};
use lapidary::recipe::gem::{compile_gem, GemSource};
use lapidary::recipe::Tables;
use lapidary::render::environment::Environment;
use lapidary::render::film::{render, Film, FilmSettings};
use lapidary::render::flake_lobe::FlakeLobes;
use lapidary::render::lights::Light;
use lapidary::render::render_scene::RenderScene;
use lapidary::render::world::{StoneInstance, World};

mod common;
use common::scenes::three_quarter_camera;

/// One opaque stone at the origin: a white Lambert surface under a
/// glitter map of silver facets (cells of `facet_cell` texture units,
/// [`FINE`]: 0.01 mm, thousands to a pixel of [`three_quarter_camera`]
/// at 24 px) whose material is `glitter`; facets by footprint when
/// `footprints`.
fn scene(
    (glitter, facet_cell): (&str, f64),
    environment: Environment,
    lights: Vec<Light>,
    footprints: bool,
) -> RenderScene {
    let text = format!(
        r#"Gem(surface: "white", materials: {{"white": Material(layers: [], base: Diffuse(colour: (1, 1, 1))), "glitter": {glitter}}}, glitter: Some(GlitterMap(cell_size: {}, fill_fraction: 0.5, entries: [(material: "glitter")], facets: FacetBumpMap(cell_size: {facet_cell}, tilt: UniformCone(max_tilt_deg: 25.0), around: SurfaceNormal))))"#,
        2.0 * facet_cell
    );
    let gem = compile_gem(&GemSource::new("test", &text), None, Tables::Skipped).unwrap();
    let stone = StoneInstance {
        cabochon: Cabochon::new(CabochonParams::default()).unwrap(),
        rotation: DQuat::IDENTITY,
        position: DVec3::ZERO,
        gem: 0,
    };
    let gems = vec![gem];
    RenderScene {
        world: World::new(vec![stone], None),
        material_id_bases: RenderScene::material_id_bases(&gems),
        flake_lobes: if footprints {
            FlakeLobes::of_gems(&gems)
        } else {
            FlakeLobes::default()
        },
        gems,
        ground_brdf: None,
        lights,
        environment,
        max_bounces: 4,
        ambient_occlusion: None,
        connect_through_surfaces: true,
    }
}

/// Facet cells of 0.01 mm.
const FINE: f64 = 0.001;

const SILVER: &str =
    r#"Material(layers: [Layer(ior: 1.5)], base: Conductor(metal: "silver", roughness_deg: 2.0))"#;

/// A small bright sphere light off to one side: the facets that face it
/// glint.
fn small_light() -> Light {
    Light::Sphere {
        centre: DVec3::new(25.0, -30.0, 45.0),
        radius: 1.0,
        radiance: Rgb::splat(2000.0),
    }
}

/// Linear RGB of the pixels wholly on the stone.
fn stone_pixels(film: &Film) -> Vec<DVec3> {
    film.rgb
        .iter()
        .zip(&film.alpha)
        .filter(|(_, a)| **a == 1.0)
        .map(|(p, _)| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
        .collect()
}

fn mean(pixels: &[DVec3]) -> DVec3 {
    pixels.iter().sum::<DVec3>() / pixels.len() as f64
}

/// The root mean square difference of two renders' stone pixels (their
/// noise, √2 times one render's, when both converge to one image).
fn rms_difference(a: &[DVec3], b: &[DVec3]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    (sum / a.len() as f64).sqrt()
}

/// Silver facets of cells `facet_cell` under a small light, 24 px: the
/// stone's mean colour by footprint against one by one (1024 spp) must
/// agree within 2 % (the facets' table, `render::glitter_aggregate`, is
/// Monte Carlo: 1–2 % a region, and its cells are constant over a few
/// degrees, which a small light sees), and two 16-spp renders of
/// different sample seeds must differ less than `noise_ratio` times as
/// much as one by one's.
fn assert_mean_kept_and_noise_below(facet_cell: f64, noise_ratio: f64) {
    let environment = Environment::Constant(Rgb::splat(0.1));
    let by_footprint = scene(
        (SILVER, facet_cell),
        environment.clone(),
        vec![small_light()],
        true,
    );
    let one_by_one = scene(
        (SILVER, facet_cell),
        environment,
        vec![small_light()],
        false,
    );
    let shot = |scene: &RenderScene, spp: u32, seed: u64| {
        stone_pixels(&render(
            scene,
            &three_quarter_camera(24),
            &FilmSettings::new(24, 24, spp, seed),
            &|_| {},
        ))
    };
    let (footprint_mean, exact_mean) = (
        mean(&shot(&by_footprint, 1024, 1)),
        mean(&shot(&one_by_one, 1024, 1)),
    );
    eprintln!("stone mean: by footprint {footprint_mean}, one by one {exact_mean}");
    let ratio = footprint_mean / exact_mean;
    assert!(
        (ratio - DVec3::ONE).abs().max_element() < 0.02,
        "by footprint {footprint_mean} against one by one {exact_mean}"
    );
    let noise = |scene: &RenderScene| rms_difference(&shot(scene, 16, 2), &shot(scene, 16, 3));
    let (footprint_noise, exact_noise) = (noise(&by_footprint), noise(&one_by_one));
    eprintln!("noise at 16 spp: by footprint {footprint_noise}, one by one {exact_noise}");
    assert!(
        footprint_noise < noise_ratio * exact_noise,
        "noise {footprint_noise} by footprint against {exact_noise} one by one"
    );
}

#[test]
fn facets_drawn_by_footprint_keep_the_mean_and_lower_the_noise() {
    // Thousands of facets to a pixel: the mean agrees (measured: 1.5 %
    // above; its pixels' footprints read the facets' table), and the
    // noise is less than half (measured: 0.15 against 0.81).
    assert_mean_kept_and_noise_below(FINE, 0.5);
}

#[test]
fn facets_blended_with_their_mean_keep_the_mean_and_lower_the_noise() {
    // Facets three times as wide, about 300 to a pixel: each vertex's
    // own facet blends with the facets' mean by about half
    // (`render::footprint`). The mean agrees (measured: 0.9 % above) and
    // the noise is less than 0.63 times (measured: 0.57; when the blend
    // picked one of the two at random, 0.69).
    assert_mean_kept_and_noise_below(3.0 * FINE, 0.63);
}

#[test]
fn glitter_drawn_by_footprint_never_outshines_a_white_furnace() {
    // White Lambert between facets of a smooth varnish over black, in a
    // white sky: every facet reflects at most what arrives, so no pixel of
    // the stone exceeds the sky; and the stone's mean is that of its
    // facets shaded one by one within 1 %.
    let glitter = r#"Material(layers: [Layer(ior: 1.5)], base: Black)"#;
    let furnace = |footprints| {
        let scene = scene(
            (glitter, FINE),
            Environment::Constant(Rgb::ONE),
            vec![],
            footprints,
        );
        stone_pixels(&render(
            &scene,
            &three_quarter_camera(24),
            &FilmSettings::new(24, 24, 256, 4),
            &|_| {},
        ))
    };
    let (by_footprint, one_by_one) = (furnace(true), furnace(false));
    let brightest = by_footprint
        .iter()
        .map(|p| p.max_element())
        .fold(0.0, f64::max);
    assert!(
        brightest <= 1.0 + 1e-6,
        "a stone pixel at {brightest} in a sky of 1"
    );
    let (a, b) = (mean(&by_footprint), mean(&one_by_one));
    assert!(
        ((a / b) - DVec3::ONE).abs().max_element() < 0.01,
        "{a} against {b}"
    );
}
