//! Cameras and scenes the render tests share.

use std::sync::OnceLock;

use glam::DVec3;
use lapidary::recipe::gem::Gem;
use lapidary::render::camera::PinholeCamera;
use lapidary::render::environment::Environment;
use lapidary::render::flake_lobe::FlakeLobes;
use lapidary::render::prepare::stone_instances;
use lapidary::render::render_scene::RenderScene;
use lapidary::render::world::World;
use lapidary::scene::{default_scene, EnvironmentSpec, Scene};

/// A camera 50 mm from the origin, 37° above the ground, 12° field: a
/// pixel of a 24-px image spans 0.44 mm at the origin.
pub fn three_quarter_camera(size: u32) -> PinholeCamera {
    PinholeCamera::new(
        DVec3::new(0.0, -40.0, 30.0),
        DVec3::ZERO,
        DVec3::Z,
        12.0,
        size,
        size,
    )
}

/// The studio scene's environment, baked once per test binary.
pub fn studio() -> &'static Environment {
    static STUDIO: OnceLock<Environment> = OnceLock::new();
    STUDIO.get_or_init(|| match default_scene().environment {
        EnvironmentSpec::Studio {
            intensity,
            rotation_deg,
        } => Environment::try_studio(intensity, rotation_deg).expect("the studio builds"),
        other => panic!("the default scene's environment changed: {other:?}"),
    })
}

/// The default scene without its ground (its BRDF would tabulate the
/// compensation every case): the stone shaded by `gem`, the lights, the
/// studio.
pub fn default_scene_without_ground(gem: Gem) -> (Scene, RenderScene) {
    let scene = default_scene();
    let stones = stone_instances(&scene).expect("the built-in stones are valid");
    let render_scene = RenderScene {
        world: World::new(stones, None),
        material_id_bases: RenderScene::material_id_bases(std::slice::from_ref(&gem)),
        gems: vec![gem],
        ground_brdf: None,
        lights: scene.lights.clone(),
        environment: studio().clone(),
        max_bounces: 4,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes: FlakeLobes::default(),
    };
    (scene, render_scene)
}
