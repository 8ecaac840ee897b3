//! One mirror flake under the flat polished window (buff top) of a clear
//! stone, lit by a small soft box: its highlight appears where Snell's law
//! (eq. 3.2) puts it, and seen from near the vertical its apparent depth is
//! d / n.
//!
//! The flake is a real inclusion: a population of one flake per 10 mm cell
//! (the sparsest a recipe allows), its normal aligned straight up, whose
//! seed puts exactly one flake inside the stone, under the window. Its
//! centre comes from the grid's own placement (`centre_and_radius`).
//!
//! Both tests fail if rays were not refracted at the window: the oblique
//! view's highlight would sit where the straight line to the flake crosses
//! the window, 46 pixels from Snell's prediction (the first test checks
//! that the two are more than 20 px apart), and from near the vertical a
//! flake d deep would appear about d deep rather than d / n. With
//! refraction (the flake 2.04 mm deep): 0.007 px off, and 1.319 mm
//! against d / n = 1.322 mm.

use glam::{DQuat, DVec3, IVec3};

use crate::brdf::Rgb;
use crate::geometry::{Cabochon, CabochonParams, Outline};
use crate::recipe::gem::{compile_gem, Body, Gem, GemSource};
use crate::recipe::Tables;
use crate::render::camera::PinholeCamera;
use crate::render::environment::Environment;
use crate::render::film::{render, Film, FilmSettings};
use crate::render::lights::Light;
use crate::render::render_scene::RenderScene;
use crate::render::world::{StoneInstance, World};

/// Refractive index of the stone.
const IOR: f64 = 1.54;
/// Distance from the camera to the window, mm.
const CAMERA_DISTANCE_MM: f64 = 40.0;
/// Film size, pixels (square).
const FILM_PX: u32 = 96;

/// A round stone with a buffed (flat) top 6 mm across, as
/// `tests/render_translucent.rs`'s flat window.
fn flat_window() -> CabochonParams {
    CabochonParams {
        outline: Outline::Round,
        length: 10.0,
        width: 10.0,
        dome_height: 3.0,
        girdle_height: 0.5,
        buff_top: Some(0.6),
        ..CabochonParams::default()
    }
}

/// A clear stone with one population of mirror flakes (smooth silver,
/// normals straight up, one per 10 mm cell) of recipe seed `seed`.
fn mirror_flake_gem(seed: u64) -> Gem {
    let text = format!(
        r#"Gem(surface: "teflon",
            materials: {{"mirror": Material(layers: [], base: Conductor(metal: "silver"))}},
            body: Translucent(ior: {IOR}, inclusions: [Inclusions(shape: Disc, size_mm: 0.3,
                density_per_mm3: 0.001, orientation: Aligned(direction: (0, 0, 1), spread_deg: 0),
                material: "mirror", seed: {seed})]))"#
    );
    compile_gem(&GemSource::new("test", &text), None, Tables::Skipped).unwrap()
}

/// A recipe seed whose population has exactly one flake in the stone,
/// under the window, 2.04 mm deep (found once by trying seeds; checked by
/// [`the_one_flake`]).
const ONE_FLAKE_SEED: u64 = 146;

/// The centre of the one flake of `gem` inside the stone (at the origin),
/// after checking that it is the only one, that it lies under the flat
/// window at least 0.5 mm from the rim and from both faces, and that it
/// faces straight up.
fn the_one_flake(gem: &Gem, cabochon: &Cabochon) -> DVec3 {
    let Body::Translucent { inclusions, .. } = &gem.body else {
        panic!("a translucent body");
    };
    let population = &inclusions[0];
    assert_eq!(population.aligned.map(|(axis, _)| axis), Some(DVec3::Z));
    let (lo, hi) = cabochon.bounds();
    let margin = population.radius_mm;
    let mut inside = Vec::new();
    // The stone's bounds lie within the 2 × 2 × 2 cells around the origin.
    assert!(lo.cmpgt(DVec3::splat(-population.cell_mm)).all());
    assert!(hi.cmplt(DVec3::splat(population.cell_mm)).all());
    for x in -1..=0 {
        for y in -1..=0 {
            for z in -1..=0 {
                let (_, centre, _) = population.centre_and_radius(IVec3::new(x, y, z));
                if (centre - (lo + hi) / 2.0)
                    .abs()
                    .cmplt((hi - lo) / 2.0 + margin)
                    .all()
                {
                    inside.push(centre);
                }
            }
        }
    }
    assert_eq!(inside.len(), 1, "flakes in the stone's bounds: {inside:?}");
    let centre = inside[0];
    let window_radius_mm = 0.6 * 5.0;
    assert!(centre.truncate().length() < window_radius_mm - 0.5 - margin);
    assert!(centre.z > lo.z + 0.5 && centre.z < hi.z - 0.5, "{centre}");
    centre
}

/// The scene: the stone at the origin, a small soft box, a black sky.
fn scene(gem: Gem, light: Light) -> RenderScene {
    let stone = StoneInstance {
        cabochon: Cabochon::new(flat_window()).unwrap(),
        rotation: DQuat::IDENTITY,
        position: DVec3::ZERO,
        gem: 0,
    };
    RenderScene {
        world: World::new(vec![stone], None),
        material_id_bases: RenderScene::material_id_bases(std::slice::from_ref(&gem)),
        gems: vec![gem],
        ground_brdf: None,
        lights: vec![light],
        environment: Environment::Constant(Rgb::ZERO),
        max_bounces: 8,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes: crate::render::flake_lobe::FlakeLobes::default(),
    }
}

/// Where the ray from the camera at `camera` must cross the window (the
/// plane z = `z_top`) to reach `flake` after refracting (eq. 3.2):
/// horizontal distance a from the flake's vertical solves
/// sinθᵢ = n·sinθₜ with tanθᵢ = (ρ − a)/h and tanθₜ = a/d (ρ, h: the
/// camera's horizontal distance and height; d: the flake's depth), found
/// by bisection (the left side falls and the right side rises with a).
fn snell_entry(camera: DVec3, flake: DVec3, z_top: f64) -> DVec3 {
    let towards_camera = (camera - flake).truncate();
    let rho = towards_camera.length();
    let h = camera.z - z_top;
    let depth = z_top - flake.z;
    let mismatch = |a: f64| (rho - a).atan2(h).sin() - IOR * a.atan2(depth).sin();
    let (mut lo, mut hi) = (0.0, rho);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mismatch(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a = 0.5 * (lo + hi);
    (flake.truncate() + towards_camera / rho * a).extend(z_top)
}

/// A 4 × 4 mm soft box 20 mm from the window, centred on the path that a
/// camera ray through `entry` takes after the mirror flake: a horizontal
/// mirror under a flat window sends it out with its vertical component
/// reversed (law of reflection, then Snell's law back), from the point
/// mirror-symmetric to `entry` about the flake's vertical.
fn light_on_the_reflection(camera: DVec3, entry: DVec3, flake: DVec3) -> Light {
    let v = (entry - camera).normalize();
    let out = DVec3::new(v.x, v.y, -v.z);
    let exit = (2.0 * flake.truncate() - entry.truncate()).extend(entry.z);
    let normal = -out;
    let (u_axis, v_axis) = normal.any_orthonormal_pair();
    Light::Rect {
        centre: exit + out * 20.0,
        normal,
        u_axis,
        v_axis,
        width: 4.0,
        height: 4.0,
        radiance: Rgb::splat(10.0),
    }
}

/// A camera at `position` aimed at `look_at`, `mm_per_px` across a pixel
/// at the distance of the window.
fn camera(position: DVec3, look_at: DVec3, mm_per_px: f64) -> PinholeCamera {
    let half_field_mm = 0.5 * f64::from(FILM_PX) * mm_per_px;
    let fov_deg = 2.0 * (half_field_mm / CAMERA_DISTANCE_MM).atan().to_degrees();
    PinholeCamera::new(position, look_at, DVec3::Z, fov_deg, FILM_PX, FILM_PX)
}

/// The film point (pixels, from the top-left corner) that `camera` sees
/// `point` through: the inverse of [`PinholeCamera::ray`], found by
/// Newton's method on the ray's direction (checked to converge).
fn project(camera: &PinholeCamera, point: DVec3) -> (f64, f64) {
    let target = (point - camera.position()).normalize();
    let (mut x, mut y) = (0.5 * f64::from(FILM_PX), 0.5 * f64::from(FILM_PX));
    let direction = |x: f64, y: f64| camera.ray(x, y).direction;
    for _ in 0..20 {
        let d = direction(x, y);
        let (dx, dy) = (direction(x + 1.0, y) - d, direction(x, y + 1.0) - d);
        // Least squares for the step: [dx dy]·s = target − d.
        let r = target - d;
        let (a, b, c) = (dx.dot(dx), dx.dot(dy), dy.dot(dy));
        let det = a * c - b * b;
        x += (c * dx.dot(r) - b * dy.dot(r)) / det;
        y += (a * dy.dot(r) - b * dx.dot(r)) / det;
    }
    assert!(direction(x, y).angle_between(target) < 1e-9);
    (x, y)
}

/// The film of scene `with` minus that of scene `without` (the same
/// camera, seed and sample numbers), summed over R, G, B: what the flake
/// adds. The window's own Fresnel reflection of the soft box, the same
/// paths in both, cancels.
fn flake_only(with: &RenderScene, without: &RenderScene, camera: &PinholeCamera) -> Vec<f64> {
    let settings = FilmSettings::new(FILM_PX, FILM_PX, 16, 3);
    let film = |scene: &RenderScene| -> Film { render(scene, camera, &settings, &|_| {}) };
    let (a, b) = (film(with), film(without));
    assert_eq!(a.stats.bad_samples + b.stats.bad_samples, 0);
    a.rgb
        .iter()
        .zip(&b.rgb)
        .map(|(p, q)| (0..3).map(|c| f64::from(p[c]) - f64::from(q[c])).sum())
        .collect()
}

/// The brightness-weighted centre (pixels, from the top-left corner) of
/// the pixels brighter than a quarter of the brightest.
fn highlight_centre(image: &[f64]) -> (f64, f64) {
    let peak = image.iter().cloned().fold(0.0, f64::max);
    assert!(peak > 1.0, "no highlight (peak {peak})");
    let (mut sum, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for (i, value) in image.iter().enumerate() {
        if *value > 0.25 * peak {
            let (x, y) = ((i % FILM_PX as usize) as f64, (i / FILM_PX as usize) as f64);
            sum += value;
            sx += value * (x + 0.5);
            sy += value * (y + 0.5);
        }
    }
    (sx / sum, sy / sum)
}

/// The gem with the one flake, the same gem without it, the flake's
/// centre and the height of the window (checked flat over the flake).
fn setup() -> (Gem, Gem, DVec3, f64) {
    let cabochon = Cabochon::new(flat_window()).unwrap();
    let z_top = cabochon.bounds().1.z;
    let gem = mirror_flake_gem(ONE_FLAKE_SEED);
    let flake = the_one_flake(&gem, &cabochon);
    let mut clear = gem.clone();
    if let Body::Translucent { inclusions, .. } = &mut clear.body {
        inclusions.clear();
    }
    // The window is flat over the flake, at z_top.
    let world = World::new(
        vec![StoneInstance {
            cabochon,
            rotation: DQuat::IDENTITY,
            position: DVec3::ZERO,
            gem: 0,
        }],
        None,
    );
    let hit = world
        .intersect_leaving(flake.with_z(10.0), -DVec3::Z, 0.0, f64::INFINITY, None)
        .unwrap();
    assert!((hit.point.z - z_top).abs() < 1e-9 && hit.normal == DVec3::Z);
    (gem, clear, flake, z_top)
}

#[test]
fn a_flake_under_a_flat_window_appears_where_snells_law_puts_it() {
    // Seen 40° from the vertical, the highlight is the flake's image
    // through the window: its centre is seen at the point of the window
    // where the refracted ray to the flake's centre enters.
    let (gem, clear, flake, z_top) = setup();
    let depth = z_top - flake.z;
    let theta = 40f64.to_radians();
    let position =
        flake.with_z(z_top) + DVec3::new(0.0, -theta.sin(), theta.cos()) * CAMERA_DISTANCE_MM;
    let entry = snell_entry(position, flake, z_top);
    // Where a straight line to the flake crosses the window.
    let straight = position + (flake - position) * ((position.z - z_top) / (position.z - flake.z));
    let camera = camera(position, (entry + straight) / 2.0, 0.012);
    let predicted = project(&camera, entry);
    let unrefracted = project(&camera, straight);
    let apart = (predicted.0 - unrefracted.0).hypot(predicted.1 - unrefracted.1);
    assert!(
        apart > 20.0,
        "refraction moves the image {apart} px (d = {depth} mm)"
    );

    let light = light_on_the_reflection(position, entry, flake);
    let image = flake_only(&scene(gem, light), &scene(clear, light), &camera);
    let seen = highlight_centre(&image);
    let error = (seen.0 - predicted.0).hypot(seen.1 - predicted.1);
    assert!(
        error < 1.0,
        "highlight at {seen:?}, Snell's law predicts {predicted:?} ({error} px off; a \
         straight line would put it at {unrefracted:?})"
    );
}

#[test]
fn seen_from_near_the_vertical_a_flake_lies_at_its_depth_over_n() {
    // Seen 6° from the vertical, the ray to the flake's centre, continued
    // straight past the window, crosses the flake's vertical at the
    // apparent depth d·tanθₜ/tanθᵢ, which tends to d / n as θ → 0 (0.3 %
    // less at 6°). Measured from the highlight's pixel: the camera's ray
    // through it meets the window at horizontal distance x from the
    // flake's vertical, at angle φ from the vertical: depth x / tan φ.
    let (gem, clear, flake, z_top) = setup();
    let depth = z_top - flake.z;
    let theta = 6f64.to_radians();
    let position =
        flake.with_z(z_top) + DVec3::new(theta.sin(), 0.0, theta.cos()) * CAMERA_DISTANCE_MM;
    let entry = snell_entry(position, flake, z_top);
    let camera = camera(position, flake.with_z(z_top), 0.006);
    let light = light_on_the_reflection(position, entry, flake);
    let image = flake_only(&scene(gem, light), &scene(clear, light), &camera);
    let (x, y) = highlight_centre(&image);
    let ray = camera.ray(x, y);
    let on_window = ray.origin + ray.direction * ((z_top - ray.origin.z) / ray.direction.z);
    let tan_phi = ray.direction.truncate().length() / -ray.direction.z;
    let apparent = (on_window - flake).truncate().length() / tan_phi;
    let expected = depth / IOR;
    assert!(
        (apparent - expected).abs() < 0.015 * expected,
        "apparent depth {apparent} mm, d / n = {expected} mm (d = {depth} mm)"
    );
}
