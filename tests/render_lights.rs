//! Direct light from every light kind onto a white Lambert floor, against
//! closed forms: the reflected radiance is E/π for irradiance E, whatever
//! the viewing direction. BRDF sampling and light sampling are combined by
//! MIS in the integrator, so these also check that the weights sum to one.

use std::f64::consts::PI;

use glam::{DQuat, DVec3};
use lapidary::brdf::Rgb;
use lapidary::geometry::{Cabochon, CabochonParams};
use lapidary::recipe::compile::{compile_material, MaterialSource};
use lapidary::recipe::gem::{compile_gem, Gem, GemSource};
use lapidary::recipe::parse_material;
use lapidary::recipe::TableCache;
use lapidary::recipe::Tables;
use lapidary::render::camera::PinholeCamera;
use lapidary::render::environment::{Environment, EnvironmentMap};
use lapidary::render::film::{render, FilmSettings, PixelFilter};
use lapidary::render::flake_lobe::FlakeLobes;
use lapidary::render::lights::Light;
use lapidary::render::render_scene::RenderScene;
use lapidary::render::world::{StoneInstance, World};

fn white_lambert() -> lapidary::brdf::LayeredBrdf {
    material("Material(layers: [], base: Diffuse(colour: (1, 1, 1)))")
}

/// The material of recipe text `text`.
fn material(text: &str) -> lapidary::brdf::LayeredBrdf {
    let m = parse_material("test", text).unwrap();
    let source = MaterialSource {
        path: "test".into(),
        name: "test".into(),
        text: text.into(),
    };
    compile_material(&source, &m).unwrap()
}

/// Compiles gem recipe `text` (`path` for messages) with its compensation
/// tables, computed afresh.
fn compile_text(path: &str, text: &str) -> Result<Gem, lapidary::recipe::RecipeError> {
    let cache = TableCache::in_memory();
    compile_gem(&GemSource::new(path, text), None, Tables::Computed(&cache))
}

/// Radiance of the floor point at the origin seen from an oblique camera
/// (the mean over a 3 × 3 block of pixels around the film centre).
fn floor_radiance(lights: Vec<Light>, stones: Vec<StoneInstance>, spp: u32) -> f64 {
    floor_radiance_in(Environment::constant(Rgb::ZERO), lights, stones, spp)
}

/// [`floor_radiance`] under `environment`.
fn floor_radiance_in(
    environment: Environment,
    lights: Vec<Light>,
    stones: Vec<StoneInstance>,
    spp: u32,
) -> f64 {
    floor_radiance_bouncing(environment, lights, stones, spp, 0)
}

/// [`floor_radiance_in`] with paths of up to `max_bounces` bounces.
fn floor_radiance_bouncing(
    environment: Environment,
    lights: Vec<Light>,
    stones: Vec<StoneInstance>,
    spp: u32,
    max_bounces: u32,
) -> f64 {
    floor_radiance_of(
        white_lambert(),
        environment,
        lights,
        stones,
        spp,
        max_bounces,
    )
}

/// [`floor_radiance_bouncing`] on a floor of material `ground`.
fn floor_radiance_of(
    ground: lapidary::brdf::LayeredBrdf,
    environment: Environment,
    lights: Vec<Light>,
    stones: Vec<StoneInstance>,
    spp: u32,
    max_bounces: u32,
) -> f64 {
    let gems = if stones.is_empty() {
        vec![]
    } else {
        let text = r#"Gem(materials: {"m": Material(layers: [], base: Diffuse(colour: (0.5, 0.5, 0.5)))}, surface: "m")"#;
        vec![compile_text("test", text).unwrap()]
    };
    let scene = RenderScene {
        world: World::new(stones, Some(0.0)),
        material_id_bases: RenderScene::material_id_bases(&gems),
        gems,
        ground_brdf: Some(ground),
        lights,
        environment,
        max_bounces,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes: FlakeLobes::default(),
    };
    // Narrow field: the 3 × 3 block sees the floor within 0.01 of the origin.
    let camera = PinholeCamera::new(
        DVec3::new(-30.0, 0.0, 40.0),
        DVec3::ZERO,
        DVec3::Z,
        0.05,
        9,
        9,
    );
    let settings = FilmSettings::new(9, 9, spp, 3);
    let film = render(&scene, &camera, &settings, &|_| {});
    let mut sum = 0.0;
    for y in 3..6 {
        for x in 3..6 {
            sum += f64::from(film.rgb[y * 9 + x][1]);
        }
    }
    sum / 9.0
}

fn assert_close(got: f64, expected: f64, tolerance: f64, what: &str) {
    assert!(
        (got - expected).abs() <= tolerance * expected,
        "{what}: rendered {got}, closed form {expected}"
    );
}

#[test]
fn a_point_light_follows_the_inverse_square_and_cosine_laws() {
    // I = 100 at (3, 0, 4): d = 5, cosθ = 4/5, E = I cosθ / d² = 3.2.
    let light = Light::Point {
        position: DVec3::new(3.0, 0.0, 4.0),
        intensity: Rgb::splat(100.0),
    };
    assert_close(
        floor_radiance(vec![light], vec![], 4),
        3.2 / PI,
        1e-4,
        "point light",
    );
}

#[test]
fn a_sphere_light_gives_pi_l_sin2() {
    // A sphere of radiance L and radius r at distance d on the normal:
    // E = π L (r/d)² (a disc of angular radius asin(r/d)).
    let light = Light::Sphere {
        centre: DVec3::new(0.0, 0.0, 10.0),
        radius: 2.0,
        radiance: Rgb::splat(5.0),
    };
    let expected = PI * 5.0 * 0.04 / PI;
    assert_close(
        floor_radiance(vec![light], vec![], 256),
        expected,
        0.02,
        "sphere light",
    );
}

/// A square soft box of half-side 3 at height 6 facing down, centred above
/// the floor point, of radiance `radiance`, and its form factor 4F from
/// the point: four corner rectangles, each with
/// F = (1/2π)[X/√(1+X²)·atan(Y/√(1+X²)) + Y/√(1+Y²)·atan(X/√(1+Y²))],
/// X = Y = a/h. It gives the floor irradiance π L · 4F.
fn overhead_soft_box(radiance: f64) -> (Light, f64) {
    let (a, h) = (3.0_f64, 6.0_f64);
    let x = a / h;
    let s = (1.0 + x * x).sqrt();
    let form_factor = 4.0 * (2.0 * x / s * (x / s).atan()) / (2.0 * PI);
    let light = Light::Rect {
        centre: DVec3::new(0.0, 0.0, h),
        normal: -DVec3::Z,
        u_axis: DVec3::X,
        v_axis: DVec3::Y,
        width: 2.0 * a,
        height: 2.0 * a,
        radiance: Rgb::splat(radiance),
    };
    (light, form_factor)
}

#[test]
fn a_square_soft_box_gives_its_form_factor() {
    // E = π L · 4F (see `overhead_soft_box`).
    let (light, form_factor) = overhead_soft_box(4.0);
    let expected = 4.0 * form_factor;
    assert_close(
        floor_radiance(vec![light], vec![], 256),
        expected,
        0.02,
        "soft box",
    );
}

#[test]
fn a_sun_gives_its_irradiance_times_the_cosine() {
    // Elevation 30°: cosθ = sin 30° = 1/2; E = 2 · 1/2 = 1.
    let direction = DVec3::new(30f64.to_radians().cos(), 0.0, 0.5);
    let sun = Light::sun(direction, 0.53, Rgb::splat(2.0));
    assert_close(floor_radiance(vec![sun], vec![], 64), 1.0 / PI, 0.01, "sun");
}

#[test]
fn with_more_lights_than_a_vertex_samples_their_irradiances_still_add() {
    // Four lights, of which each vertex samples three (chosen by strata,
    // mostly by their estimated irradiance there), weighted against BRDF
    // sampling with their densities times 3 × their choice probability:
    // the floor's radiance is still the sum of the four closed forms above.
    let (soft_box_light, form_factor) = overhead_soft_box(4.0);
    let soft_box = PI * 4.0 * form_factor;
    // A sphere wholly above the horizon: E = π L (r/d)² cos θ, here at
    // d = 10 with cos θ = 0.6.
    let sphere = PI * 20.0 * 0.04 * 0.6;
    let expected = (3.2 + sphere + soft_box + 1.0) / PI;
    let lights = vec![
        Light::Point {
            position: DVec3::new(3.0, 0.0, 4.0),
            intensity: Rgb::splat(100.0),
        },
        Light::Sphere {
            centre: DVec3::new(-8.0, 0.0, 6.0),
            radius: 2.0,
            radiance: Rgb::splat(20.0),
        },
        soft_box_light,
        Light::sun(
            DVec3::new(30f64.to_radians().cos(), 0.0, 0.5),
            0.53,
            Rgb::splat(2.0),
        ),
    ];
    assert_close(
        floor_radiance(lights.clone(), vec![], 1024),
        expected,
        0.01,
        "four lights",
    );
    // Two point lights, the sun and a sky map (sampled like a light): a
    // sky of radiance 0.5 over the upper hemisphere (the 8 × 4 map's top
    // two rows) gives the floor π · 0.5 (the sun hides none of it that
    // matters: 10⁻⁵ of it).
    // I = 50 at (−3, 2, 5): E = I cos θ / d² = 50 · 5 / 38^1.5.
    let second_point = Light::Point {
        position: DVec3::new(-3.0, 2.0, 5.0),
        intensity: Rgb::splat(50.0),
    };
    let second = 250.0 / 38f64.powf(1.5);
    assert_close(
        floor_radiance_in(
            upper_sky(0.5),
            vec![lights[0], second_point, lights[3]],
            vec![],
            1024,
        ),
        (3.2 + second + 1.0) / PI + 0.5,
        0.01,
        "two point lights, the sun and a sky map",
    );
}

/// A rough clear coat over a grey base: the closed form of one interface
/// over Lambert, whose vertices evaluate their light samples in lanes
/// when they draw two or more.
fn grey_coat() -> lapidary::brdf::LayeredBrdf {
    material(
        "Material(layers: [Layer(ior: 1.5, roughness_deg: 20.0)], \
         base: Diffuse(colour: (0.5, 0.5, 0.5)))",
    )
}

#[test]
fn lights_shading_a_coat_together_add_up_to_each_alone() {
    // With one emitter a vertex shades its light sample as it draws it;
    // with two it gathers them and evaluates the coat at both and at its
    // BRDF sample in one call of vector lanes. Light adds: the floor
    // under both lights is the sum of the floor under each. Point lights
    // at bounce 0 leave nothing random but where a pixel's samples land
    // (the same points in the three renders): equal to the film's single
    // precision.
    let point = |position: DVec3, intensity: f64| Light::Point {
        position,
        intensity: Rgb::splat(intensity),
    };
    let first = point(DVec3::new(3.0, 1.0, 4.0), 100.0);
    let second = point(DVec3::new(-4.0, -2.0, 6.0), 60.0);
    let floor = |lights: Vec<Light>, spp: u32, bounces: u32| {
        floor_radiance_of(
            grey_coat(),
            Environment::constant(Rgb::ZERO),
            lights,
            vec![],
            spp,
            bounces,
        )
    };
    let (alone, other, both) = (
        floor(vec![first], 16, 0),
        floor(vec![second], 16, 0),
        floor(vec![first, second], 16, 0),
    );
    assert!(alone > 0.0 && other > 0.0);
    assert_close(both, alone + other, 1e-6, "two point lights on a coat");
    // Area lights, with BRDF samples that reach them weighted by MIS
    // against the light samples: equal in expectation (0.04 % apart; a
    // BRDF sample's density taken 1.5 times too large in the gathered
    // vertex's evaluation puts them 1.6 % apart).
    let (soft_box, _) = overhead_soft_box(4.0);
    let sphere = Light::Sphere {
        centre: DVec3::new(-8.0, 0.0, 6.0),
        radius: 2.0,
        radiance: Rgb::splat(20.0),
    };
    let (alone, other, both) = (
        floor(vec![soft_box], 2048, 1),
        floor(vec![sphere], 2048, 1),
        floor(vec![soft_box, sphere], 2048, 1),
    );
    assert_close(
        both,
        alone + other,
        0.005,
        "a soft box and a sphere on a coat",
    );
}

/// An 8 × 4 sky map of `radiance` over the upper hemisphere (its top two
/// rows), black below.
fn upper_sky(radiance: f64) -> Environment {
    let (width, height) = (8, 4);
    let texels = (0..width * height)
        .map(|i| {
            if i < 2 * width {
                Rgb::splat(radiance)
            } else {
                Rgb::ZERO
            }
        })
        .collect();
    Environment::Map(EnvironmentMap::new(width, height, texels, 0.0).unwrap())
}

#[test]
fn a_light_hides_the_sky_behind_it_from_light_samples_too() {
    // A soft box overhead in front of a sky of radiance 2: the floor sees
    // the box (π L 4F) and the sky less the box's form factor 4F; light
    // samples of the sky that pass through the box must count as blocked,
    // as BRDF samples stop at it (else the hidden sky counts by its light
    // samples' MIS weight). Alone, and with a point light and a sphere
    // (four emitters, three sampled a vertex), whose (r/d)² cos θ = 0.024
    // of the sky it also hides.
    let l = 1.0;
    let (soft_box, form_factor) = overhead_soft_box(l);
    assert_close(
        floor_radiance_in(upper_sky(2.0), vec![soft_box], vec![], 1024),
        l * form_factor + 2.0 * (1.0 - form_factor),
        0.01,
        "a soft box in front of the sky",
    );
    let point = Light::Point {
        position: DVec3::new(3.0, 0.0, 4.0),
        intensity: Rgb::splat(100.0),
    };
    let sphere = Light::Sphere {
        centre: DVec3::new(-8.0, 0.0, 6.0),
        radius: 2.0,
        radiance: Rgb::splat(20.0),
    };
    assert_close(
        floor_radiance_in(upper_sky(2.0), vec![point, sphere, soft_box], vec![], 1024),
        3.2 / PI + 20.0 * 0.024 + l * form_factor + 2.0 * (1.0 - form_factor - 0.024),
        0.01,
        "a soft box and a sphere in front of the sky, and a point light",
    );
}

#[test]
fn a_stone_between_the_light_and_the_floor_casts_a_shadow() {
    // The light at (20, 0, 2) is seen from the origin through (10, 0, 1),
    // inside a 10 × 8 × 4.5 stone centred at x = 10.
    let light = Light::Point {
        position: DVec3::new(20.0, 0.0, 2.0),
        intensity: Rgb::splat(100.0),
    };
    let stone = StoneInstance {
        cabochon: Cabochon::new(CabochonParams::default()).unwrap(),
        rotation: DQuat::IDENTITY,
        position: DVec3::new(10.0, 0.0, 0.5),
        gem: 0,
    };
    let lit = floor_radiance(vec![light], vec![], 1);
    // Unshadowed: E = I cosθ / d² with d² = 404, cosθ = 2/√404.
    let expected = 100.0 * (2.0 / 404f64.sqrt()) / 404.0 / PI;
    assert_close(lit, expected, 1e-3, "unshadowed floor");
    let shadowed = floor_radiance(vec![light], vec![stone], 1);
    assert_eq!(shadowed, 0.0, "shadowed floor");
}

/// A 64 × 32 map: a sky of radiance 0.5 over the upper hemisphere, black
/// below, and a one-texel sun of 2000 at row 5 (θ ≈ 30°) holding 76 % of
/// the power, so that it is sampled as a part of its own; and the
/// irradiance it gives an upward floor, texel by texel (the sky 16 % of
/// it).
fn sky_and_sun() -> (Environment, f64) {
    let (width, height) = (64, 32);
    let radiance = |i: usize| match (i / width, i % width) {
        (5, 10) => 2.0e3,
        (row, _) if row < height / 2 => 0.5,
        _ => 0.0,
    };
    let texels = (0..width * height)
        .map(|i| Rgb::splat(radiance(i)))
        .collect();
    let map = EnvironmentMap::new(width, height, texels, 0.0).unwrap();
    assert_eq!(map.parts(), 2);
    // Each texel: L Δφ (sin²θ₁ − sin²θ₀) / 2 (its cosine-weighted solid angle).
    let irradiance = (0..width * height / 2)
        .map(|i| {
            let row = (i / width) as f64;
            let (t0, t1) = (PI * row / height as f64, PI * (row + 1.0) / height as f64);
            radiance(i) * (2.0 * PI / width as f64) * 0.5 * (t1.sin().powi(2) - t0.sin().powi(2))
        })
        .sum();
    (Environment::Map(map), irradiance)
}

#[test]
fn a_sun_sampled_apart_from_its_sky_gives_the_map_s_irradiance() {
    // The camera's vertex takes one sample of the sun and one of the sky,
    // each weighted against BRDF sampling by its own part's density.
    let (environment, irradiance) = sky_and_sun();
    assert_close(
        floor_radiance_in(environment, vec![], vec![], 1024),
        irradiance / PI,
        0.01,
        "a sun and a sky sampled apart",
    );
}

/// A default stone 7 mm from the floor point the tests look at, whose
/// light reaches it after a bounce.
fn stone_beside_the_point() -> StoneInstance {
    StoneInstance {
        cabochon: Cabochon::new(CabochonParams::default()).unwrap(),
        rotation: DQuat::IDENTITY,
        position: DVec3::new(0.0, 7.0, 0.0),
        gem: 0,
    }
}

#[test]
fn sampling_a_sun_apart_at_the_camera_s_vertices_keeps_the_image_s_expectation() {
    // With bounces off a grey stone beside the point: the camera's
    // vertices sample the map's two parts apart, the later ones the whole
    // map. Two black point lights make four emitters with the parts, more
    // than a vertex samples apart, so every vertex then samples the whole
    // map: the same expected image by other estimators.
    let (environment, _) = sky_and_sun();
    let stone = stone_beside_the_point();
    let black = |x: f64| Light::Point {
        position: DVec3::new(x, 0.0, 5.0),
        intensity: Rgb::ZERO,
    };
    let apart = floor_radiance_bouncing(environment.clone(), vec![], vec![stone.clone()], 2048, 3);
    let whole = floor_radiance_bouncing(
        environment,
        vec![black(3.0), black(-3.0)],
        vec![stone],
        2048,
        3,
    );
    assert_close(apart, whole, 0.01, "parts apart against the whole map");
}

#[test]
fn a_sun_sampled_apart_renders_the_same_bytes_on_any_thread_count() {
    // The sky part's numbers come from a side generator of each vertex:
    // still a pure function of the pixel and sample.
    let (environment, _) = sky_and_sun();
    let stone = stone_beside_the_point();
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            floor_radiance_bouncing(environment.clone(), vec![], vec![stone.clone()], 64, 3)
        })
    };
    assert_eq!(on(1).to_bits(), on(3).to_bits());
}

/// Columns of an 8 × 8 render looking straight down at the edge x = 0 of
/// a soft box of radiance 1 lying on z = 0 and covering x > 0 (black
/// beyond): the edge runs between columns 3 and 4. The mean of each
/// column, ordered from the dark side to the lit one.
fn columns_across_an_edge(filter: PixelFilter) -> Vec<f64> {
    let light = Light::Rect {
        centre: DVec3::new(50.0, 0.0, 0.0),
        normal: DVec3::Z,
        u_axis: DVec3::X,
        v_axis: DVec3::Y,
        width: 100.0,
        height: 200.0,
        radiance: Rgb::splat(1.0),
    };
    let scene = RenderScene {
        world: World::new(vec![], None),
        material_id_bases: vec![],
        gems: vec![],
        ground_brdf: None,
        lights: vec![light],
        environment: Environment::constant(Rgb::ZERO),
        max_bounces: 0,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes: FlakeLobes::default(),
    };
    let camera = PinholeCamera::new(
        DVec3::new(0.0, 0.0, 10.0),
        DVec3::ZERO,
        DVec3::Y,
        10.0,
        8,
        8,
    );
    let settings = FilmSettings {
        filter,
        ..FilmSettings::new(8, 8, 64, 5)
    };
    let film = render(&scene, &camera, &settings, &|_| {});
    let mut columns: Vec<f64> = (0..8)
        .map(|x| {
            (0..8)
                .map(|y| f64::from(film.rgb[y * 8 + x][1]))
                .sum::<f64>()
                / 8.0
        })
        .collect();
    if columns[0] > columns[7] {
        columns.reverse();
    }
    columns
}

#[test]
fn the_box_filter_keeps_an_edge_in_its_pixels_and_the_tent_and_the_gaussian_spread_it_as_their_densities_say(
) {
    // Filter importance sampling: a pixel's samples cross the film where
    // its filter puts them. The box keeps them in the pixel: the dark
    // column beside the edge stays black and the lit one sees the light
    // whole. The tent of radius one pixel puts ∫ (1 − t) dt over
    // t ∈ [½, 1] = 1/8 of them beyond the edge, from either side.
    let boxed = columns_across_an_edge(PixelFilter::Box);
    assert_eq!(boxed[..4], [0.0; 4], "box, dark side: {boxed:?}");
    for lit in &boxed[4..] {
        assert!((lit - 1.0).abs() < 1e-3, "box, lit side: {boxed:?}");
    }
    // The round Gaussian (σ = ½, cut off at R = 3/2): P(x > ½) =
    // ∫ from ½ to R of (acos(½/r)/π) (r/σ²) e^(−r²/2σ²) dr / (1 − e^(−R²/2σ²)),
    // by the midpoint rule; nothing reaches the column beyond.
    let (sigma, radius) = (0.5f64, 1.5f64);
    let steps = 20_000;
    let step = (radius - 0.5) / f64::from(steps);
    let beyond: f64 = (0..steps)
        .map(|i| {
            let r = 0.5 + (f64::from(i) + 0.5) * step;
            (0.5 / r).acos() / PI * r / (sigma * sigma) * (-r * r / (2.0 * sigma * sigma)).exp()
        })
        .sum::<f64>()
        * step
        / (1.0 - (-radius * radius / (2.0 * sigma * sigma)).exp());
    assert!((beyond - 0.1559).abs() < 1e-3, "{beyond}");
    let gaussian = columns_across_an_edge(PixelFilter::Gaussian);
    assert_eq!(gaussian[..3], [0.0; 3], "gaussian, dark side: {gaussian:?}");
    assert!(
        (gaussian[3] - beyond).abs() < 0.01,
        "gaussian, beside the edge: {gaussian:?}"
    );
    assert!(
        (gaussian[4] - (1.0 - beyond)).abs() < 0.01,
        "gaussian, beside the edge: {gaussian:?}"
    );
    let tent = columns_across_an_edge(PixelFilter::Tent);
    assert_eq!(tent[..3], [0.0; 3], "tent, dark side: {tent:?}");
    assert!(
        (tent[3] - 0.125).abs() < 0.01,
        "tent, beside the edge: {tent:?}"
    );
    assert!(
        (tent[4] - 0.875).abs() < 0.01,
        "tent, beside the edge: {tent:?}"
    );
    for lit in &tent[5..] {
        assert!((lit - 1.0).abs() < 1e-3, "tent, lit side: {tent:?}");
    }
}
