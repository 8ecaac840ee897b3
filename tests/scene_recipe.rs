//! Scene files: the built-in default, camera and stone placement maths,
//! lights, path resolution, and an error naming field, range and line for
//! every kind of bad input.

use glam::DVec3;
use lapidary::geometry::{Base, CabochonParams, Outline};
use lapidary::recipe::library::builtin_material_source;
use lapidary::scene::{
    default_scene, load_scene, parse_scene, Camera, EnvironmentSpec, LightSpec, Scene,
    DEFAULT_SCENE_SOURCE,
};
use std::path::{Path, PathBuf};

fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
    (a - b).length() <= tol
}

/// The camera's orthonormal frame (right, up, forward) built the way any
/// pinhole renderer does: up projected off the view direction.
fn frame(c: &Camera) -> (DVec3, DVec3, DVec3) {
    let forward = (c.look_at - c.position).normalize();
    let right = forward.cross(c.up).normalize();
    (right, right.cross(forward), forward)
}

/// Image coordinates in [-1, 1]² of a world point for a square frame.
fn project(c: &Camera, p: DVec3) -> (f64, f64) {
    let (right, up, forward) = frame(c);
    let d = p - c.position;
    let tan_half = (0.5 * c.vertical_fov_deg).to_radians().tan();
    let depth = d.dot(forward);
    (
        d.dot(right) / depth / tan_half,
        d.dot(up) / depth / tan_half,
    )
}

#[test]
fn default_scene_is_the_documented_studio() {
    let scene = default_scene();
    assert_eq!(scene, parse_scene(DEFAULT_SCENE_SOURCE, None).unwrap());
    assert_eq!(scene.path, None);

    // One 10 × 8 oval, dome 4, girdle 0.5, flat back, full dome.
    assert_eq!(scene.stones.len(), 1);
    let stone = &scene.stones[0];
    assert_eq!(stone.recipe, None, "the command line's gem");
    assert_eq!(stone.seed, None);
    assert_eq!(
        stone.shape,
        CabochonParams {
            outline: Outline::Oval,
            length: 10.0,
            width: 8.0,
            dome_height: 4.0,
            profile_exponent: 2.0,
            girdle_height: 0.5,
            base: Base::Flat,
            buff_top: None,
        }
    );

    // The flat back (object z = −girdle_height) rests on the ground.
    let ground = scene.ground.as_ref().expect("a ground plane");
    let bottom = stone.position.z - stone.shape.girdle_height;
    assert!(
        (ground.height - bottom).abs() < 1e-12,
        "{ground:?} {bottom}"
    );
    assert!(
        builtin_material_source(&ground.material).is_some(),
        "ground material `{}` is in the library",
        ground.material
    );

    assert_eq!(
        scene.environment,
        EnvironmentSpec::Studio {
            intensity: 1.0,
            rotation_deg: 0.0
        }
    );

    // A 3/4 view from 35–40° above the horizon.
    let c = &scene.camera;
    let view = c.position - c.look_at;
    let elevation_deg = (view.z / view.length()).asin().to_degrees();
    assert!((35.0..=40.0).contains(&elevation_deg), "{elevation_deg}");

    // The stone fills 60–70 % of a square frame's width and fits vertically:
    // project points of its dome, z = h·sqrt(1 − s²) over the oval (rotation
    // is identity here, so world = object + position), and its girdle band.
    assert_eq!(stone.rotation, glam::DQuat::IDENTITY);
    let (a, b, h, g) = (5.0, 4.0, 4.0, 0.5);
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for k in 0..360 {
        let phi = (k as f64).to_radians();
        for t in 0..=20 {
            let s = t as f64 / 20.0;
            let rim = DVec3::new(a * s * phi.cos(), b * s * phi.sin(), 0.0);
            for z in [h * (1.0 - s * s).sqrt(), -g] {
                let (x, y) = project(c, stone.position + rim + DVec3::Z * z);
                xs.push(x);
                ys.push(y);
            }
        }
    }
    let span = |v: &[f64]| {
        let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let (x_lo, x_hi) = span(&xs);
    let (y_lo, y_hi) = span(&ys);
    let fill = 0.5 * (x_hi - x_lo);
    assert!(
        (0.6..=0.7).contains(&fill),
        "stone fills {fill} of the width"
    );
    assert!(x_lo > -1.0 && x_hi < 1.0 && y_lo > -1.0 && y_hi < 1.0);

    // One small sphere light, high and front-left of the camera.
    assert_eq!(scene.lights.len(), 1);
    let LightSpec::Sphere {
        centre,
        radius,
        radiance,
    } = scene.lights[0]
    else {
        panic!("expected a sphere light, got {:?}", scene.lights[0]);
    };
    assert!((1.0..=2.0).contains(&radius), "{radius}");
    assert!(radiance.min_element() > 0.0);
    let (right, _, forward) = frame(c);
    let to_light = centre - c.look_at;
    assert!(to_light.dot(right) < 0.0, "left of the camera");
    assert!(
        to_light.dot(forward) < 0.0,
        "in front: on the camera's side"
    );
    let light_elevation_deg = (to_light.z / to_light.length()).asin().to_degrees();
    assert!(light_elevation_deg > 40.0, "{light_elevation_deg}");
    // Far enough to look small (a sparkle, not a soft box): under 10°.
    let subtended_deg = 2.0 * (radius / to_light.length()).asin().to_degrees();
    assert!(subtended_deg < 10.0, "{subtended_deg}");
}

/// A one-stone scene with `camera` and `lights` spliced in.
fn scene_with(camera: &str, lights: &str, path: Option<&Path>) -> Scene {
    let text = format!(
        "Scene(camera: {camera}, stones: [Stone(shape: Cabochon(outline: Round, length: 6.0, width: 6.0))], lights: [{lights}])"
    );
    parse_scene(&text, path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn orbit_straight_above_is_at_distance_with_a_usable_up() {
    let orbit = |elevation: f64| {
        scene_with(
            &format!("Orbit(target: (1.0, 2.0, 3.0), distance: 10.0, elevation_deg: {elevation}, azimuth_deg: 0.0, vertical_fov_deg: 30.0)"),
            "",
            None,
        )
        .camera
    };
    let c = orbit(90.0);
    assert!(
        close(c.position, DVec3::new(1.0, 2.0, 13.0), 1e-12),
        "{c:?}"
    );
    assert_eq!(c.look_at, DVec3::new(1.0, 2.0, 3.0));
    assert!((c.up.length() - 1.0).abs() < 1e-12);
    let forward = (c.look_at - c.position).normalize();
    assert!(c.up.cross(forward).length() > 0.999, "up ⊥ view: {c:?}");
    // Continuity: just below 90° world z still works, and its projection off
    // the view is (nearly) the up chosen at 90°.
    let near = orbit(89.99);
    let (_, near_up, _) = frame(&near);
    let (_, up, _) = frame(&c);
    assert!(close(near_up, up, 1e-3), "{near_up} vs {up}");
    // An ordinary orbit: azimuth 90, elevation 0 puts the camera on +y.
    let side = scene_with("Orbit(target: (0.0, 0.0, 0.0), distance: 5.0, elevation_deg: 0.0, azimuth_deg: 90.0, vertical_fov_deg: 30.0)", "", None).camera;
    assert!(close(side.position, DVec3::new(0.0, 5.0, 0.0), 1e-12));
    assert_eq!(side.up, DVec3::Z);
    // A LookAt camera looking straight down also gets a frame.
    let down = scene_with(
        "LookAt(position: (0.0, 0.0, 20.0), look_at: (0.0, 0.0, 0.0), vertical_fov_deg: 30.0)",
        "",
        None,
    )
    .camera;
    let forward = (down.look_at - down.position).normalize();
    assert!(down.up.cross(forward).length() > 0.999, "{down:?}");
}

#[test]
fn euler_angles_apply_about_x_then_y_then_z() {
    let rotated = |angles: &str| {
        let text = format!(
            "Scene(camera: LookAt(position: (0, -30, 10), look_at: (0, 0, 0), vertical_fov_deg: 20), stones: [Stone(shape: Cabochon(outline: Oval, length: 10, width: 8), rotation_deg: {angles})])"
        );
        parse_scene(&text, None)
            .unwrap_or_else(|e| panic!("{e}"))
            .stones[0]
            .rotation
    };
    let q = rotated("(0.0, 0.0, 90.0)");
    assert!(close(q * DVec3::X, DVec3::Y, 1e-12), "{}", q * DVec3::X);
    // x first: +y → +z under Rx(90°), then Rz(90°) leaves +z. The other
    // order would take +y → −x → −x.
    let q = rotated("(90.0, 0.0, 90.0)");
    assert!(close(q * DVec3::Y, DVec3::Z, 1e-12), "{}", q * DVec3::Y);
    assert!(close(q * DVec3::X, DVec3::Y, 1e-12), "{}", q * DVec3::X);
}

#[test]
fn each_light_kind_parses_with_its_values() {
    let scene = scene_with(
        "Orbit(target: (0.0, 0.0, 0.0), distance: 40.0, elevation_deg: 30.0, azimuth_deg: 0.0, vertical_fov_deg: 25.0)",
        "Sphere(centre: (1.0, 2.0, 3.0), radius: 2.0, radiance: (4.0, 5.0, 6.0)),
         Point(position: (-1.0, 0.0, 9.0), intensity: (10.0, 0.0, 1.0)),
         Rect(centre: (20.0, 0.0, 10.0), aim_at: (0.0, 0.0, 10.0), width: 20.0, height: 10.0, radiance: (7.0, 7.0, 7.0)),
         Rect(centre: (3.0, 4.0, 30.0), aim_at: (3.0, 4.0, 0.0), width: 5.0, height: 6.0, radiance: (1.0, 1.0, 1.0)),
         Sun(elevation_deg: 90.0, azimuth_deg: 30.0, angular_diameter_deg: 0.53, irradiance: (1.0, 0.9, 0.8)),
         Sun(elevation_deg: 0.0, azimuth_deg: 90.0, irradiance: (2.0, 2.0, 2.0))",
        None,
    );
    // Left out: no ground, and the documented default environment.
    assert_eq!(scene.ground, None);
    assert_eq!(
        scene.environment,
        EnvironmentSpec::Studio {
            intensity: 1.0,
            rotation_deg: 0.0
        }
    );
    let l = &scene.lights;
    assert_eq!(l.len(), 6);
    assert_eq!(
        l[0],
        LightSpec::Sphere {
            centre: DVec3::new(1.0, 2.0, 3.0),
            radius: 2.0,
            radiance: DVec3::new(4.0, 5.0, 6.0)
        }
    );
    assert_eq!(
        l[1],
        LightSpec::Point {
            position: DVec3::new(-1.0, 0.0, 9.0),
            intensity: DVec3::new(10.0, 0.0, 1.0)
        }
    );
    for (light, aim) in [
        (&l[2], DVec3::new(0.0, 0.0, 10.0)),
        (&l[3], DVec3::new(3.0, 4.0, 0.0)),
    ] {
        let LightSpec::Rect {
            centre,
            normal,
            u_axis,
            v_axis,
            ..
        } = *light
        else {
            panic!("{light:?}")
        };
        // The normal points from the centre at aim_at.
        let to_aim = aim - centre;
        assert!(
            close(centre + normal * to_aim.length(), aim, 1e-12),
            "{light:?}"
        );
        // (u, v, normal) is orthonormal and right-handed.
        for (x, y) in [(u_axis, v_axis), (u_axis, normal), (v_axis, normal)] {
            assert!(x.dot(y).abs() < 1e-12);
        }
        for v in [normal, u_axis, v_axis] {
            assert!((v.length() - 1.0).abs() < 1e-12);
        }
        assert!(close(u_axis.cross(v_axis), normal, 1e-12));
    }
    // The horizontal soft box has its width horizontal and its height vertical.
    if let LightSpec::Rect {
        u_axis,
        v_axis,
        width,
        height,
        ..
    } = l[2]
    {
        assert_eq!((width, height), (20.0, 10.0));
        assert!(u_axis.z.abs() < 1e-12);
        assert!((v_axis.z.abs() - 1.0).abs() < 1e-12);
    }
    // Sun at the zenith, and on the horizon at azimuth 90° (+y); the
    // angular diameter defaults to the real sun's 0.53°.
    assert_eq!(
        l[4],
        LightSpec::Sun {
            direction: l[4].sun_direction(),
            angular_diameter_deg: 0.53,
            irradiance: DVec3::new(1.0, 0.9, 0.8)
        }
    );
    assert!(close(l[4].sun_direction(), DVec3::Z, 1e-12));
    assert!(close(l[5].sun_direction(), DVec3::Y, 1e-12));
    assert!(
        matches!(l[5], LightSpec::Sun { angular_diameter_deg, .. } if angular_diameter_deg == 0.53)
    );
}

/// The direction of a sun light (panics for other kinds).
trait SunDirection {
    fn sun_direction(&self) -> DVec3;
}
impl SunDirection for LightSpec {
    fn sun_direction(&self) -> DVec3 {
        match self {
            LightSpec::Sun { direction, .. } => *direction,
            other => panic!("not a sun: {other:?}"),
        }
    }
}

const PATHS: &str = r#"Scene(
    camera: LookAt(position: (0.0, -30.0, 10.0), look_at: (0.0, 0.0, 0.0), vertical_fov_deg: 20.0),
    stones: [
        Stone(recipe: Some("gems/opal.ron"), shape: Cabochon(outline: Oval, length: 10.0, width: 8.0)),
        Stone(recipe: Some("lavender-lepidolite"), shape: Cabochon(outline: Oval, length: 10.0, width: 8.0)),
        Stone(recipe: Some("ABSOLUTE/gem.ron"), shape: Cabochon(outline: Oval, length: 10.0, width: 8.0)),
        Stone(recipe: Some("my-gem.ron"), shape: Cabochon(outline: Oval, length: 10.0, width: 8.0)),
    ],
    ground: Some(Ground(height: 0.0, material: "../materials/velvet.ron")),
    environment: File(path: "hdr/studio.hdr", rotation_deg: 15.0, intensity: 0.5),
)"#;

/// A fresh folder `root/shots` holding every file [`PATHS`] names (empty
/// files: the scene checks that they exist, the renderer reads them), and
/// PATHS with its absolute path pointing into `root/elsewhere`.
fn paths_scene(name: &str) -> (PathBuf, String) {
    let root = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&root);
    let dir = root.join("shots");
    for file in [
        "shots/gems/opal.ron",
        "shots/my-gem.ron",
        "shots/hdr/studio.hdr",
        "materials/velvet.ron",
        "elsewhere/gem.ron",
    ] {
        let path = root.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, "").unwrap();
    }
    let text = PATHS.replace("ABSOLUTE", root.join("elsewhere").to_str().unwrap());
    (dir, text)
}

#[test]
fn relative_paths_resolve_against_the_scene_folder() {
    let (dir, text) = paths_scene("scene_recipe_paths");
    let scene = parse_scene(&text, Some(&dir.join("ring.ron"))).unwrap();
    let recipes: Vec<Option<String>> = scene.stones.iter().map(|s| s.recipe.clone()).collect();
    let in_dir = |p: &str| Some(dir.join(p).to_string_lossy().into_owned());
    let absolute = dir.parent().unwrap().join("elsewhere/gem.ron");
    assert_eq!(
        recipes,
        [
            in_dir("gems/opal.ron"),
            Some("lavender-lepidolite".to_string()),
            Some(absolute.to_string_lossy().into_owned()),
            in_dir("my-gem.ron"),
        ]
    );
    assert_eq!(
        Some(scene.ground.unwrap().material),
        in_dir("../materials/velvet.ron")
    );
    assert_eq!(
        scene.environment,
        EnvironmentSpec::File {
            path: dir.join("hdr/studio.hdr"),
            rotation_deg: 15.0,
            intensity: 0.5
        }
    );
    assert_eq!(scene.path.as_deref(), Some(dir.join("ring.ron").as_path()));

    // Without a scene file, paths stay as written: relative to the current
    // directory (the crate's root under `cargo test`).
    let bare = text
        .replace("gems/opal.ron", "gem-recipes/goldstone.ron")
        .replace("my-gem.ron", "./gem-recipes/sunstone.ron")
        .replace("../materials/velvet.ron", "gem-recipes/materials/gold.ron")
        .replace("hdr/studio.hdr", "tests/scene_recipe.rs");
    // (an existing file, but not an image)
    let err = parse_scene(&bare, None).unwrap_err().to_string();
    assert!(err.starts_with("<scene>:10:29: environment"), "{err}");
    assert!(
        err.contains("`tests/scene_recipe.rs` has the extension `.rs`"),
        "{err}"
    );
    let bare = bare.replace("tests/scene_recipe.rs", "gem-recipes/nope.hdr");
    let err = parse_scene(&bare, None).unwrap_err().to_string();
    assert!(
        err.starts_with("<scene>:10:29: environment: image file `gem-recipes/nope.hdr` not found in the current directory;"),
        "{err}"
    );
    let bare = bare.replace(
        "File(path: \"gem-recipes/nope.hdr\", rotation_deg: 15.0, intensity: 0.5)",
        "Studio(intensity: 1.0)",
    );
    let scene = parse_scene(&bare, None).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        scene.stones[0].recipe.as_deref(),
        Some("gem-recipes/goldstone.ron")
    );
    assert_eq!(
        scene.stones[3].recipe.as_deref(),
        Some("./gem-recipes/sunstone.ron")
    );
    assert_eq!(
        scene.ground.unwrap().material,
        "gem-recipes/materials/gold.ron"
    );
    // … and a file missing there is named as looked for there.
    let missing = bare.replace("gem-recipes/goldstone.ron", "gem-recipes/goldstones.ron");
    let err = parse_scene(&missing, None).unwrap_err().to_string();
    assert!(
        err.starts_with("<scene>:4:28: stone 1: gem file `gem-recipes/goldstones.ron` not found in the current directory (did you mean `gem-recipes/goldstone.ron`?)"),
        "{err}"
    );
}

#[test]
fn load_scene_reads_a_file_and_names_a_missing_one() {
    let (dir, text) = paths_scene("scene_recipe_load");
    let file = dir.join("paths.ron");
    std::fs::write(&file, text).unwrap();
    let scene = load_scene(&file).unwrap();
    assert_eq!(
        scene.stones[0].recipe,
        Some(dir.join("gems/opal.ron").to_string_lossy().into_owned())
    );
    let missing = dir.join("no-such-scene.ron");
    let err = load_scene(&missing).unwrap_err().to_string();
    assert!(
        err.starts_with(&missing.display().to_string()) && err.contains("cannot read"),
        "{err}"
    );
}

/// A valid scene, one field per line, that the bad inputs below modify.
const GOOD: &str = r#"// A test scene.
Scene(
    camera: LookAt(
        position: (30.0, -30.0, 25.0),
        look_at: (0.0, 0.0, 1.0),
        vertical_fov_deg: 25.0,
    ),
    stones: [
        Stone(
            shape: Cabochon(
                outline: Cushion(exponent: 4.0),
                length: 10.0,
                width: 8.0,
                base: Domed(height: 2.0),
            ),
            position: (0.0, 0.0, 2.5),
        ),
    ],
    lights: [
        Sphere(
            centre: (0.0, 0.0, 20.0),
            radius: 2.0,
            radiance: (5.0, 5.0, 5.0),
        ),
        Rect(
            centre: (20.0, 0.0, 10.0),
            aim_at: (0.0, 0.0, 0.0),
            width: 20.0,
            height: 10.0,
            radiance: (1.0, 1.0, 1.0),
        ),
        Sun(
            elevation_deg: 45.0,
            azimuth_deg: 30.0,
            angular_diameter_deg: 0.53,
            irradiance: (1.0, 1.0, 1.0),
        ),
    ],
    ground: Some(Ground(
        height: 0.0,
        material: "teflon",
    )),
    environment: Constant(radiance: (0.1, 0.1, 0.1)),
)
"#;

/// 1-based line of the first line containing `marker`.
fn line_of(text: &str, marker: &str) -> usize {
    text.lines()
        .position(|l| l.contains(marker))
        .unwrap_or_else(|| panic!("marker {marker} not in scene"))
        + 1
}

/// Parses GOOD with `from` replaced by `to`, expects an error on the line
/// holding `marker` whose message contains every `needle`.
fn expect_error(from: &str, to: &str, marker: &str, needles: &[&str]) {
    assert!(GOOD.contains(from), "{from}");
    let text = GOOD.replacen(from, to, 1);
    let err = parse_scene(&text, Some(Path::new("bad.ron"))).expect_err("should be rejected");
    let message = err.to_string();
    let line = line_of(&text, marker);
    let prefix = format!("bad.ron:{line}:");
    assert!(
        message.starts_with(&prefix),
        "expected {prefix}… got {message}"
    );
    let col = message[prefix.len()..].split(':').next().unwrap();
    assert!(col.parse::<usize>().is_ok(), "no column: {message}");
    for needle in needles {
        assert!(
            message.contains(needle),
            "`{needle}` missing from: {message}"
        );
    }
}

#[test]
fn good_scene_parses() {
    let scene = parse_scene(GOOD, None).unwrap();
    assert_eq!(
        scene.stones[0].shape.outline,
        Outline::Cushion { exponent: 4.0 }
    );
    assert_eq!(scene.stones[0].shape.base, Base::Domed { height: 2.0 });
    // Fields left out take CabochonParams::default()'s values.
    let d = CabochonParams::default();
    assert_eq!(scene.stones[0].shape.dome_height, d.dome_height);
    assert_eq!(scene.stones[0].shape.girdle_height, d.girdle_height);
    assert_eq!(scene.stones[0].shape.profile_exponent, d.profile_exponent);
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(scene.ground.as_ref().unwrap().material, "teflon");
    assert_eq!(
        scene.environment,
        EnvironmentSpec::Constant(DVec3::splat(0.1))
    );
}

#[test]
fn unknown_field_is_named_with_a_suggestion() {
    expect_error(
        "radius: 2.0",
        "radios: 2.0",
        "radios",
        &[
            "unknown field `radios`",
            "did you mean `radius`",
            "radiance",
        ],
    );
}

#[test]
fn unknown_outline_lists_the_allowed_ones() {
    expect_error(
        "outline: Cushion(exponent: 4.0)",
        "outline: Hexagon",
        "Hexagon",
        &[
            "unknown outline `Hexagon`",
            "allowed: Round, Oval, Cushion, Pear, Marquise",
        ],
    );
    expect_error(
        "        Sun(",
        "        Spot(",
        "Spot(",
        &["unknown light `Spot`", "allowed: Sphere, Point, Rect, Sun"],
    );
}

#[test]
fn bad_shape_parameters_are_reported_at_their_field() {
    expect_error(
        "length: 10.0",
        "length: -3.0",
        "length: -3.0",
        &["stone 1", "`length` = -3", "> 0"],
    );
    expect_error(
        "Domed(height: 2.0)",
        "Domed(height: 0.0)",
        "Domed(height: 0.0)",
        &["`base.height` = 0", "> 0"],
    );
    expect_error(
        "exponent: 4.0",
        "exponent: 40.0",
        "exponent: 40.0",
        &["`exponent` = 40", "(2, 16]"],
    );
}

#[test]
fn nan_is_out_of_range() {
    expect_error(
        "radius: 2.0",
        "radius: NaN",
        "radius: NaN",
        &["`radius` = NaN", "allowed: radius > 0"],
    );
    expect_error(
        "look_at: (0.0, 0.0, 1.0)",
        "look_at: (0.0, NaN, 1.0)",
        "look_at: (0.0, NaN",
        &["`look_at`", "allowed: three finite numbers"],
    );
    expect_error(
        "width: 8.0",
        "width: NaN",
        "width: NaN",
        &["`width` = NaN", "finite and > 0"],
    );
}

#[test]
fn field_of_view_must_be_open() {
    for bad in ["0.0", "170.0", "-5.0"] {
        expect_error(
            "vertical_fov_deg: 25.0",
            &format!("vertical_fov_deg: {bad}"),
            "vertical_fov_deg",
            &[
                "`vertical_fov_deg` =",
                "allowed: 0 < vertical_fov_deg < 170",
            ],
        );
    }
    expect_error(
        "elevation_deg: 45.0",
        "elevation_deg: 95.0",
        "elevation_deg",
        &["`elevation_deg` = 95", "-90 <= elevation_deg <= 90"],
    );
}

/// GOOD with its `stones: [...]` list replaced by `stones`.
fn with_stones(stones: &str) -> String {
    let start = GOOD.find("    stones: [").unwrap();
    let end = GOOD[start..].find("\n    ],\n").unwrap() + start + "\n    ],\n".len();
    format!("{}{stones}{}", &GOOD[..start], &GOOD[end..])
}

#[test]
fn stone_count_must_be_1_to_1024() {
    let empty = with_stones("    stones: [],\n");
    let err = parse_scene(&empty, Some(Path::new("bad.ron")))
        .unwrap_err()
        .to_string();
    let line = line_of(&empty, "stones: []");
    assert!(err.starts_with(&format!("bad.ron:{line}:")), "{err}");
    assert!(
        err.contains("`stones` has 0 stones; allowed: 1 to 1024"),
        "{err}"
    );

    let one = "Stone(shape: Cabochon(outline: Round, length: 1.0, width: 1.0)),";
    let many = with_stones(&format!("    stones: [{}],\n", one.repeat(1025)));
    let err = parse_scene(&many, None).unwrap_err().to_string();
    assert!(err.contains("has 1025 stones; allowed: 1 to 1024"), "{err}");
    let max = with_stones(&format!("    stones: [{}],\n", one.repeat(1024)));
    assert_eq!(parse_scene(&max, None).unwrap().stones.len(), 1024);
}

#[test]
fn sun_diameter_is_at_most_20_degrees() {
    expect_error(
        "angular_diameter_deg: 0.53",
        "angular_diameter_deg: 30.0",
        "angular_diameter_deg",
        &[
            "`angular_diameter_deg` = 30",
            "allowed: 0 < angular_diameter_deg <= 20",
        ],
    );
}

#[test]
fn an_absurd_environment_intensity_is_refused_at_its_field() {
    // 1e305 overflowed the studio's texels (a panic while baking it).
    for environment in [
        "Studio(intensity: 1e305)",
        "File(path: \"sky.hdr\", intensity: 2e6)",
        "Studio(intensity: -1.0)",
    ] {
        expect_error(
            "Constant(radiance: (0.1, 0.1, 0.1))",
            environment,
            "environment:",
            &["`intensity`", "allowed: 0 <= intensity <= 1000000"],
        );
    }
}

#[test]
fn negative_radiance_is_refused() {
    expect_error(
        "radiance: (5.0, 5.0, 5.0)",
        "radiance: (5.0, -1.0, 5.0)",
        "radiance: (5.0, -1.0",
        &[
            "`radiance` = (5, -1, 5)",
            "allowed: 0 <= radiance <= 1e12 per channel",
        ],
    );
}

#[test]
fn radiance_beyond_1e12_is_refused() {
    // 1e308 overflowed to infinity in the light's samples, which the film
    // then dropped: a picture without the light, and exit code 0.
    expect_error(
        "radiance: (5.0, 5.0, 5.0)",
        "radiance: (5.0, 1e308, 5.0)",
        "radiance: (5.0, 1e308",
        &[
            "`radiance` = (5, 1e308, 5)",
            "allowed: 0 <= radiance <= 1e12 per channel",
        ],
    );
}

#[test]
fn camera_at_its_look_at_point_is_refused() {
    expect_error(
        "look_at: (0.0, 0.0, 1.0)",
        "look_at: (30.0, -30.0, 25.0)",
        "look_at: (30.0",
        &["`look_at`", "`position`", "allowed: any point other than"],
    );
}

#[test]
fn rect_aimed_at_its_own_centre_is_refused() {
    expect_error(
        "aim_at: (0.0, 0.0, 0.0)",
        "aim_at: (20.0, 0.0, 10.0)",
        "aim_at: (20.0",
        &[
            "light 2",
            "`aim_at`",
            "`centre`",
            "allowed: any point other than",
        ],
    );
}

#[test]
fn comments_and_strings_do_not_confuse_error_locations() {
    // A comment naming a field before the real one, and a bracket in a string.
    let text = GOOD
        .replace("// A test scene.", "// stones: [ (length: 1) ] \"")
        .replace(
            "        Stone(\n",
            "        Stone(\n            recipe: Some(\"odd(name].ron\"), // length: 0\n",
        )
        .replace("length: 10.0", "length: 0.0");
    let err = parse_scene(&text, Some(Path::new("bad.ron")))
        .unwrap_err()
        .to_string();
    let line = line_of(&text, "length: 0.0");
    assert!(err.starts_with(&format!("bad.ron:{line}:")), "{err}");
}

#[test]
fn empty_names_are_refused_at_their_field() {
    expect_error(
        "material: \"teflon\"",
        "material: \"\"",
        "material: \"\"",
        &[
            "ground: `material` is empty",
            "allowed: a built-in material name (acrylic-lacquer, ",
            "or a .ron material file",
        ],
    );
    expect_error(
        "            position: (0.0, 0.0, 2.5),",
        "            position: (0.0, 0.0, 2.5),\n            recipe: Some(\" \"),",
        "recipe: Some",
        &[
            "stone 1: `recipe` is empty",
            "allowed: a built-in gem name (blue-goldstone, ",
            "or a .ron gem file",
        ],
    );
}

// ---- references: gems, materials and files a scene names ----------------------

/// 1-based (line, col) of the `nth` (0-based) occurrence of `needle`.
fn place(text: &str, needle: &str, nth: usize) -> (usize, usize) {
    let offset = text
        .match_indices(needle)
        .nth(nth)
        .unwrap_or_else(|| panic!("`{needle}` #{nth} not in the scene"))
        .0;
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().unwrap().chars().count() + 1;
    (line, col)
}

/// A scene of two stones in `dir` (holding `gems/real.ron` and `sky.hdr`)
/// naming the gems, ground material and environment image given; the
/// names also appear in a comment and in the other stone, so a position
/// found by searching the text for them would be wrong.
fn scene_naming(stone_1: &str, stone_2: &str, ground: &str, environment: &str) -> String {
    format!(
        r#"// Names in a comment do not count: "{stone_1}" "{stone_2}" "{ground}" "{environment}"
Scene(
    ground: Some(Ground(height: 0.0, material: "{ground}")),
    camera: Orbit(target: (0.0, 0.0, 1.0), distance: 40.0, elevation_deg: 30.0, azimuth_deg: 0.0, vertical_fov_deg: 25.0),
    stones: [
        Stone(
            recipe: Some("{stone_1}"),
            shape: Cabochon(outline: Oval, length: 10.0, width: 8.0),
        ),
        Stone(recipe: Some("{stone_2}"), shape: Cabochon(outline: Round, length: 6.0, width: 6.0), position: (12.0, 0.0, 0.0)),
    ],
    environment: File(path: "{environment}"),
)
"#
    )
}

/// A folder for the reference tests, holding `gems/real.ron` and `sky.hdr`.
fn reference_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("scene_recipe_references");
    std::fs::create_dir_all(dir.join("gems")).unwrap();
    std::fs::create_dir_all(dir.join("folder.ron")).unwrap();
    std::fs::write(dir.join("gems/real.ron"), "").unwrap();
    std::fs::write(dir.join("sky.hdr"), "").unwrap();
    dir
}

/// Loads `text` as `dir/scene.ron`; its error must start with
/// `scene.ron:LINE:COL: ` at the `nth` occurrence of `at` and hold every
/// needle.
fn expect_reference_error(text: &str, at: &str, nth: usize, needles: &[&str]) -> String {
    let dir = reference_dir();
    let file = dir.join("scene.ron");
    let message = parse_scene(text, Some(&file))
        .expect_err("should be rejected")
        .to_string();
    let (line, col) = place(text, at, nth);
    let prefix = format!("{}:{line}:{col}: ", file.display());
    assert!(
        message.starts_with(&prefix),
        "expected {prefix}… got {message}"
    );
    for needle in needles {
        assert!(
            message.contains(needle),
            "`{needle}` missing from: {message}"
        );
    }
    message
}

#[test]
fn the_reference_scene_is_good_as_written() {
    let dir = reference_dir();
    let text = scene_naming("goldstone", "gems/real.ron", "teflon", "sky.hdr");
    let scene = parse_scene(&text, Some(&dir.join("scene.ron"))).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.stones[0].recipe.as_deref(), Some("goldstone"));
    assert_eq!(
        scene.stones[1].recipe,
        Some(dir.join("gems/real.ron").to_string_lossy().into_owned())
    );
    assert_eq!(scene.ground.unwrap().material, "teflon");
}

#[test]
fn an_unknown_gem_name_is_reported_where_written_with_did_you_mean() {
    let text = scene_naming("goldstone", "goldston", "teflon", "sky.hdr");
    expect_reference_error(
        &text,
        "\"goldston\"",
        1, // the comment's, then the second stone's
        &[
            "stone 2: unknown gem `goldston` (did you mean `goldstone`?)",
            "allowed: a built-in gem name (blue-goldstone, goldstone, ",
        ],
    );
}

#[test]
fn a_name_valid_in_one_place_is_refused_in_another() {
    // `gold` is a built-in material (the ground, written first) but no gem.
    let text = scene_naming("gold", "goldstone", "gold", "sky.hdr");
    expect_reference_error(&text, "\"gold\"", 3, &["stone 1: unknown gem `gold`"]);
}

#[test]
fn a_missing_gem_file_is_reported_where_written() {
    let dir = reference_dir();
    let text = scene_naming("goldstone", "gems/reel.ron", "teflon", "sky.hdr");
    let looked_for = dir.join("gems/reel.ron");
    expect_reference_error(
        &text,
        "\"gems/reel.ron\"",
        1,
        &[
            "stone 2: gem file `gems/reel.ron` not found at ",
            &looked_for.display().to_string(),
            "(did you mean `gems/real.ron`?)",
        ],
    );
    // A built-in written as a file.
    let text = scene_naming("goldstone.ron", "gems/real.ron", "teflon", "sky.hdr");
    expect_reference_error(
        &text,
        "\"goldstone.ron\"",
        1,
        &[
            "stone 1: gem file `goldstone.ron` not found at ",
            "(did you mean the built-in gem `goldstone`, written without a path or `.ron`?)",
        ],
    );
    // A folder.
    let text = scene_naming("folder.ron", "gems/real.ron", "teflon", "sky.hdr");
    expect_reference_error(
        &text,
        "\"folder.ron\"",
        1,
        &["stone 1: gem file `folder.ron` is a directory at "],
    );
}

#[test]
fn an_unknown_ground_material_is_reported_where_written_with_did_you_mean() {
    let text = scene_naming("goldstone", "gems/real.ron", "teflom", "sky.hdr");
    expect_reference_error(
        &text,
        "\"teflom\"",
        1,
        &[
            "ground: unknown material `teflom` (did you mean `teflon`?)",
            "allowed: a built-in material name (acrylic-lacquer, ",
        ],
    );
    let text = scene_naming("goldstone", "gems/real.ron", "mats/velvet.ron", "sky.hdr");
    expect_reference_error(
        &text,
        "\"mats/velvet.ron\"",
        1,
        &["ground: material file `mats/velvet.ron` not found at "],
    );
}

#[test]
fn a_missing_environment_file_is_reported_where_written() {
    let dir = reference_dir();
    let text = scene_naming("goldstone", "gems/real.ron", "teflon", "skye.hdr");
    expect_reference_error(
        &text,
        "\"skye.hdr\"",
        1,
        &[
            "environment: image file `skye.hdr` not found at ",
            &dir.join("skye.hdr").display().to_string(),
            "(did you mean `sky.hdr`?)",
            "allowed: an equirectangular .hdr or .exr image file",
        ],
    );
    // Not an image the renderer reads, though it exists.
    let text = scene_naming("goldstone", "gems/real.ron", "teflon", "gems/real.ron");
    expect_reference_error(
        &text,
        "\"gems/real.ron\"",
        3, // twice in the comment, the second stone's, then the environment's
        &["environment: image file `gems/real.ron` has the extension `.ron`"],
    );
}

#[test]
fn a_stone_of_the_command_line_gem_names_nothing_to_check() {
    // `recipe: None` (and no recipe) is the gem given to `lapidary render`.
    let text = scene_naming("goldstone", "goldstone", "teflon", "sky.hdr")
        .replace("recipe: Some(\"goldstone\")", "recipe: None");
    let scene = parse_scene(&text, Some(&reference_dir().join("scene.ron"))).unwrap();
    assert_eq!(scene.stones[0].recipe, None);
}

#[test]
fn a_scene_built_in_code_is_checked_before_it_renders() {
    // Every light kind, as a scene file gives them, passes; so does the studio.
    let good = scene_with(
        "Orbit(target: (0.0, 0.0, 0.0), distance: 40.0, elevation_deg: 90.0, azimuth_deg: 0.0, vertical_fov_deg: 25.0)",
        "Sphere(centre: (1.0, 2.0, 3.0), radius: 2.0, radiance: (4.0, 5.0, 6.0)),
         Point(position: (-1.0, 0.0, 9.0), intensity: (10.0, 0.0, 1.0)),
         Rect(centre: (20.0, 0.0, 10.0), aim_at: (0.0, 0.0, 10.0), width: 20.0, height: 10.0, radiance: (7.0, 7.0, 7.0)),
         Sun(elevation_deg: 40.0, azimuth_deg: 30.0, angular_diameter_deg: 0.53, irradiance: (1.0, 0.9, 0.8))",
        None,
    );
    assert_eq!(good.check(), Ok(()));
    assert_eq!(default_scene().check(), Ok(()));
    // What a scene built in code can get wrong, each once (these rendered
    // black, flat or with dropped samples, without a word).
    type Spoil = Box<dyn Fn(&mut Scene)>;
    let broken: Vec<(&str, Spoil)> = vec![
        ("camera", Box::new(|s| s.camera.position = s.camera.look_at)),
        (
            "vertical_fov_deg = 0",
            Box::new(|s| s.camera.vertical_fov_deg = 0.0),
        ),
        ("stone 1", Box::new(|s| s.stones[0].rotation.x = 0.5)),
        ("stone 1", Box::new(|s| s.stones[0].position.z = f64::NAN)),
        (
            "light 1",
            Box::new(|s| {
                if let LightSpec::Sphere { radius, .. } = &mut s.lights[0] {
                    *radius = -1.0;
                }
            }),
        ),
        (
            "light 2",
            Box::new(|s| {
                if let LightSpec::Point { intensity, .. } = &mut s.lights[1] {
                    intensity.x = f64::NAN;
                }
            }),
        ),
        (
            "light 3",
            Box::new(|s| {
                if let LightSpec::Rect { u_axis, normal, .. } = &mut s.lights[2] {
                    *u_axis = *normal;
                }
            }),
        ),
        (
            "environment",
            Box::new(|s| {
                s.environment = EnvironmentSpec::Constant(DVec3::new(1.0, -1.0, 1.0));
            }),
        ),
    ];
    for (named, spoil) in broken {
        let mut scene = good.clone();
        spoil(&mut scene);
        let message = scene.check().expect_err(named);
        assert!(message.contains(named), "{named}: {message}");
        assert!(
            message.contains("allowed") || message.contains("must"),
            "{message}"
        );
    }
}

#[test]
fn the_renderer_s_preparation_refuses_an_unchecked_scene() {
    let mut blind = default_scene();
    blind.camera.vertical_fov_deg = 180.0;
    let gem = lapidary::GemSource::load("sunstone").unwrap();
    let cache = lapidary::TableCache::in_memory();
    let prepared = lapidary::render::prepare::prepare_scene(
        &blind,
        &gem,
        None,
        4,
        lapidary::Tables::Computed(&cache),
        &|_| {},
    );
    assert!(prepared.is_err_and(|e| e.message.contains("vertical_fov_deg = 180")));
}

#[test]
#[should_panic(expected = "a film needs at least one pixel and one sample per pixel")]
fn a_film_without_samples_is_refused() {
    // Zero samples per pixel made a film of NaN, encoded as a black PNG.
    lapidary::render::film::FilmSettings::new(8, 8, 0, 0);
}
