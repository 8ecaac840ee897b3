//! Fuzz target: any gem recipe that validates, rendered 1×1 at 1 spp in the
//! built-in studio scene. Every film value must be finite (depth may be +∞
//! where nothing was hit, never NaN), and no sample may have been dropped
//! by the film's NaN guard; any panic is a bug.
//!
//! BRDFs are compiled without the multiple-scattering compensation (its
//! tables cost 0.1–1 s per material); the rest of the scene (world, ground,
//! lights, studio environment) is built once, like `prepare_scene` does.

#![no_main]

use std::sync::OnceLock;

use lapidary::recipe::gem::parse_gem;
use lapidary::recipe::library::DEFAULT_GEM;
use lapidary::render::camera::PinholeCamera;
use lapidary::render::film::{render, FilmSettings};
use lapidary::render::flake_lobe::FlakeLobes;
use lapidary::render::render_scene::RenderScene;
use lapidary::render::prepare::{camera_for, prepare_scene, stone_instances};
use lapidary::render::world::{StoneInstance, World};
use lapidary::scene::default_scene;
use libfuzzer_sys::fuzz_target;

const PATH: &str = "fuzz.ron";

/// The studio scene with the default gem, prepared once, its stones, and
/// the 1×1 camera.
fn base() -> &'static (RenderScene, Vec<StoneInstance>, Option<f64>, PinholeCamera) {
    type Base = (RenderScene, Vec<StoneInstance>, Option<f64>, PinholeCamera);
    static BASE: OnceLock<Base> = OnceLock::new();
    BASE.get_or_init(|| {
        let scene = default_scene();
        let cache = lapidary::recipe::TableCache::in_memory();
        let tables = lapidary::recipe::Tables::Computed(&cache);
        let prepared = prepare_scene(&scene, &lapidary::recipe::gem::GemSource::load(DEFAULT_GEM).expect("built-in"), None, 4, tables, &|_| {})
            .expect("the built-in scene prepares");
        let stones = stone_instances(&scene).expect("the built-in stones are valid");
        let ground = scene.ground.as_ref().map(|g| g.height);
        (prepared, stones, ground, camera_for(&scene, 1, 1))
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Compiled without compensation tables: every check, none of the
    // slow tabulation.
    let Ok(gem) = parse_gem(PATH, text) else {
        return;
    };
    let seed = gem.seed;
    let (base, stones, ground, camera) = base();
    let flake_lobes = FlakeLobes::of_gems(std::slice::from_ref(&gem));
    let scene = RenderScene {
        world: World::new(stones.clone(), *ground),
        material_id_bases: RenderScene::material_id_bases(std::slice::from_ref(&gem)),
        gems: vec![gem],
        ground_brdf: base.ground_brdf.clone(),
        lights: base.lights.clone(),
        environment: base.environment.clone(),
        max_bounces: 4,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes,
    };
    let settings = FilmSettings::new(1, 1, 1, seed);
    let film = render(&scene, camera, &settings, &|_| {});
    // The film guard drops NaN, infinite or negative samples; a valid recipe
    // must not produce any.
    assert_eq!(
        film.stats.bad_samples, 0,
        "samples dropped as NaN/inf/negative"
    );
    let finite3 = |v: &[[f32; 3]]| v.iter().flatten().all(|x| x.is_finite());
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    assert!(finite3(&film.rgb), "rgb {:?}", film.rgb);
    assert!(
        film.rgb.iter().flatten().all(|x| *x >= 0.0),
        "rgb {:?}",
        film.rgb
    );
    assert!(finite(&film.alpha), "alpha {:?}", film.alpha);
    assert!(finite3(&film.albedo), "albedo {:?}", film.albedo);
    assert!(finite3(&film.normal), "normal {:?}", film.normal);
    assert!(finite(&film.glitter), "glitter {:?}", film.glitter);
    assert!(finite(&film.ao), "ao {:?}", film.ao);
    assert!(
        film.depth.iter().all(|d| !d.is_nan() && *d >= 0.0),
        "depth {:?}",
        film.depth
    );
});
