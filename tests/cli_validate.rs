//! `lapidary validate` and `lapidary new`: the built-in recipes pass, and
//! recipes broken the way a new user breaks them fail with exit status 1
//! and a message naming the file, the place, the field and what is allowed.

mod common;

use common::cli::lapidary;
use std::path::Path;
use std::process::Command;

fn scratch(name: &str) -> common::cli::Scratch {
    common::cli::scratch("validate", name)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A minimal valid gem whose one map is `tiles`; the broken recipes below
/// are small edits of it, so each has exactly one mistake.
const GOOD_GEM: &str = r#"// a two-material gem
Gem(
    name: "good",
    seed: 3,
    materials: {
        "lilac": Material(
            layers: [Layer(ior: 1.5, roughness_deg: 2.0)],
            base: Diffuse(colour: (0.4, 0.3, 0.5)),
        ),
    },
    maps: {
        "tiles": SurfaceMap(cell_size: 0.1, entries: [
            (material: "lilac", weight: 2.0),
            (material: "gold"),
        ]),
    },
    surface: "tiles",
)
"#;

/// Write `contents` to `dir/name` and validate it; returns (exit code,
/// stdout, stderr).
fn validate_file(dir: &Path, name: &str, contents: &[u8]) -> (i32, String, String) {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    let out = lapidary(&["validate", path.to_str().unwrap()]);
    (
        out.status.code().unwrap_or(-1),
        text(&out.stdout),
        text(&out.stderr),
    )
}

/// `GOOD_GEM` with one edit, validated: must fail with every `expected`
/// fragment in the message, which starts `file:line:col:` at `line` (1-based,
/// when the mistake has a place) and names the file.
fn broken(dir: &Path, name: &str, contents: &str, line: Option<usize>, expected: &[&str]) {
    let (code, _, err) = validate_file(dir, name, contents.as_bytes());
    assert_eq!(code, 1, "{name}: exit {code}, stderr: {err}");
    assert!(!err.contains("panicked"), "{name} panicked: {err}");
    let file = dir.join(name).display().to_string();
    assert!(err.contains(&file), "{name}: the file is not named: {err}");
    if let Some(line) = line {
        let prefix = format!("{file}:{line}:");
        assert!(err.contains(&prefix), "{name}: expected {prefix}…: {err}");
    }
    for fragment in expected {
        assert!(err.contains(fragment), "{name}: no `{fragment}` in: {err}");
    }
}

#[test]
fn every_builtin_and_every_recipe_file_validates() {
    let mut args = vec!["validate".to_string()];
    for dir in ["gem-recipes", "gem-recipes/materials", "gem-recipes/scenes"] {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "ron") {
                args.push(path.display().to_string());
            }
        }
    }
    let files = args.len() - 1;
    // Built-in names: both gems, a material and the studio scene.
    for name in ["green-aventurine", "lavender-lepidolite", "brass", "studio"] {
        args.push(name.to_string());
    }
    let out = lapidary(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}{}", stdout, text(&out.stderr));
    // 2 gems + 24 materials + 1 scene on disk at the time of writing.
    assert!(files >= 27, "only {files} recipe files found");
    assert_eq!(stdout.lines().count(), args.len() - 1, "{stdout}");
    assert!(stdout.lines().all(|l| l.contains(": ok (")), "{stdout}");
    assert!(
        stdout.contains("builtin:lavender-lepidolite: ok (gem \"lavender-lepidolite\""),
        "{stdout}"
    );
}

#[test]
fn the_good_gem_is_reported_with_its_name_and_material_count() {
    let dir = scratch("good");
    let (code, out, err) = validate_file(&dir, "good.ron", GOOD_GEM.as_bytes());
    assert_eq!(code, 0, "{err}");
    // Two materials: the inline `lilac` and the library `gold`; one map.
    assert!(
        out.contains("ok (gem \"good\", 2 materials, 1 map)"),
        "{out}"
    );
}

#[test]
fn definitions_that_nothing_uses_are_warned_of() {
    // An inline material no map names and a map the surface does not
    // reach: valid (exit 0, the ok line), each with a warning on stderr.
    // The good gem and every built-in gem have none.
    let dir = scratch("unused");
    let (code, _, err) = validate_file(&dir, "good.ron", GOOD_GEM.as_bytes());
    assert!(code == 0 && !err.contains("warning"), "{err}");
    let recipe = GOOD_GEM
        .replace(
            "    materials: {\n",
            "    materials: {\n        \"spare\": Material(layers: [], base: Black),\n",
        )
        .replace(
            "    maps: {\n",
            "    maps: {\n        \"orphan\": SurfaceMap(cell_size: 0.1, entries: [(material: \"spare\")]),\n",
        );
    let (code, out, err) = validate_file(&dir, "unused.ron", recipe.as_bytes());
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("unused.ron: ok (gem"), "{out}");
    assert!(
        err.contains("unused.ron: warning: map `orphan` is used nowhere"),
        "{err}"
    );
    // `spare` is named by the unreached map only: still used nowhere.
    assert!(
        err.contains("unused.ron: warning: material `spare` is used nowhere"),
        "{err}"
    );
    // A translucent body under the good gem's map: the map is not shaded.
    let glass = GOOD_GEM.replace(
        "    surface: \"tiles\",\n",
        "    surface: \"tiles\",\n    body: Translucent(ior: 1.5),\n",
    );
    let (code, _, err) = validate_file(&dir, "glass.ron", glass.as_bytes());
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains(
            "glass.ron: warning: the surface `tiles` is a map, but a translucent body's surface \
             is not shaded by its materials"
        ),
        "{err}"
    );
    let gems: Vec<String> = lapidary::recipe::library::builtin_gem_names()
        .map(String::from)
        .collect();
    let mut args = vec!["validate"];
    args.extend(gems.iter().map(String::as_str));
    let out = lapidary(&args);
    assert!(
        out.status.success() && !text(&out.stderr).contains("warning"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn field_typos_get_a_did_you_mean_at_their_line() {
    let dir = scratch("typo");
    // Line 7: `rougness_deg` in the layer.
    let typo = GOOD_GEM.replace("roughness_deg: 2.0", "rougness_deg: 2.0");
    broken(
        &dir,
        "typo.ron",
        &typo,
        Some(7),
        &["rougness_deg", "did you mean `roughness_deg`"],
    );
    // A gem-level field: `sufrace` (line 17).
    let typo = GOOD_GEM.replace("surface:", "sufrace:");
    broken(
        &dir,
        "gemtypo.ron",
        &typo,
        Some(17),
        &["sufrace", "did you mean `surface`"],
    );
}

#[test]
fn a_missing_surface_is_named() {
    let dir = scratch("missing");
    let gem = GOOD_GEM.replace("    surface: \"tiles\",\n", "");
    broken(
        &dir,
        "nosurface.ron",
        &gem,
        None,
        &["missing field `surface`"],
    );
}

#[test]
fn a_value_of_the_wrong_type_names_its_field() {
    let dir = scratch("type");
    // A string where the IOR number goes (line 7).
    let gem = GOOD_GEM.replace("ior: 1.5", "ior: \"1.5\"");
    broken(
        &dir,
        "type.ron",
        &gem,
        Some(7),
        &["`ior`", "a number such as 1.5"],
    );
}

#[test]
fn unknown_material_and_map_names_suggest_the_close_one() {
    let dir = scratch("names");
    // `lilak` for `lilac` on line 13.
    let gem = GOOD_GEM.replace("(material: \"lilac\"", "(material: \"lilak\"");
    broken(
        &dir,
        "material.ron",
        &gem,
        Some(13),
        &["unknown material `lilak`", "did you mean `lilac`"],
    );
    // `tyles` for the map `tiles` as surface (line 17).
    let gem = GOOD_GEM.replace("surface: \"tiles\"", "surface: \"tyles\"");
    broken(
        &dir,
        "surface.ron",
        &gem,
        Some(17),
        &["`tyles`", "did you mean `tiles`"],
    );
    // A library name with a typo: `gould` (line 14).
    let gem = GOOD_GEM.replace("(material: \"gold\")", "(material: \"gould\")");
    broken(
        &dir,
        "library.ron",
        &gem,
        Some(14),
        &["unknown material `gould`", "did you mean `gold`"],
    );
}

#[test]
fn out_of_range_numbers_give_the_allowed_range() {
    let dir = scratch("ranges");
    // IOR 0.5 (below vacuum's 1), line 7.
    let gem = GOOD_GEM.replace("ior: 1.5", "ior: 0.5");
    broken(
        &dir,
        "ior.ron",
        &gem,
        Some(7),
        &["`ior` = 0.5", "1 <= ior <= 5"],
    );
    // Roughness 95°: slopes are below 90°.
    let gem = GOOD_GEM.replace("roughness_deg: 2.0", "roughness_deg: 95");
    broken(
        &dir,
        "rough.ron",
        &gem,
        Some(7),
        &["`roughness_deg` = 95", "0 <= roughness_deg < 90"],
    );
    // A negative thickness.
    let gem = GOOD_GEM.replace("roughness_deg: 2.0", "roughness_deg: 2.0, thickness: -1.0");
    broken(
        &dir,
        "thick.ron",
        &gem,
        Some(7),
        &["`thickness` = -1", "thickness >= 0"],
    );
    // NaN is a number RON accepts but no field does.
    let gem = GOOD_GEM.replace("cell_size: 0.1", "cell_size: NaN");
    broken(
        &dir,
        "nan.ron",
        &gem,
        Some(12),
        &["`cell_size` = NaN", "cell_size > 0"],
    );
    // A colour channel above 1 (a diffuse base reflects at most all light).
    let gem = GOOD_GEM.replace("(0.4, 0.3, 0.5)", "(0.4, 1.3, 0.5)");
    broken(
        &dir,
        "colour.ron",
        &gem,
        Some(8),
        &["`colour`", "0 <= colour <= 1"],
    );
    // 1.3 is no 8-bit value of a colour picker: no such hint; (26, 140,
    // 77) is, and gets the fractions it stands for.
    let (_, _, err) = validate_file(&dir, "colour.ron", gem.as_bytes());
    assert!(!err.contains("8-bit"), "{err}");
    let gem = GOOD_GEM.replace("(0.4, 0.3, 0.5)", "(26, 140, 77)");
    broken(
        &dir,
        "picker.ron",
        &gem,
        Some(8),
        &["(8-bit values? divided by 255 they are (0.102, 0.549, 0.302))"],
    );
}

#[test]
fn weights_that_sum_to_zero_are_refused_at_the_map() {
    let dir = scratch("weights");
    let gem = GOOD_GEM
        .replace("weight: 2.0", "weight: 0.0")
        .replace("(material: \"gold\")", "(material: \"gold\", weight: 0.0)");
    // Reported at the map's definition `"tiles":` on line 12.
    broken(
        &dir,
        "weights.ron",
        &gem,
        Some(12),
        &["`tiles`", "sum to 0", "at least one > 0"],
    );
}

#[test]
fn maps_containing_themselves_are_refused_directly_and_through_another() {
    let dir = scratch("cycles");
    let gem = GOOD_GEM.replace("(material: \"gold\")", "(map: \"tiles\")");
    broken(
        &dir,
        "self.ron",
        &gem,
        Some(12),
        &["`tiles` contains itself directly"],
    );
    let gem = GOOD_GEM.replace(
        "(material: \"gold\")",
        "(map: \"other\")]),\n        \"other\": SurfaceMap(cell_size: 0.2, entries: [(map: \"tiles\")",
    );
    broken(
        &dir,
        "through.ron",
        &gem,
        None,
        &["contains itself through", "other → tiles"],
    );
}

#[test]
fn a_material_problem_inside_a_gem_points_at_that_material() {
    let dir = scratch("layer");
    // A layer with both `ior` and `varnish`: only the compile step sees it.
    let gem = GOOD_GEM.replace("ior: 1.5,", "ior: 1.5, varnish: \"ice\",");
    broken(
        &dir,
        "layer.ron",
        &gem,
        Some(7),
        &["exactly one of `ior`, `reflectivity` or `varnish`"],
    );
    // A material file naming an unknown metal.
    let material = "Material(\n    base: Conductor(metal: \"sliver\"),\n)\n";
    broken(
        &dir,
        "metal.ron",
        material,
        Some(2),
        &["unknown metal `sliver`", "did you mean `silver`"],
    );
}

#[test]
fn broken_files_name_the_file_and_what_was_expected() {
    let dir = scratch("files");
    // Truncated in the middle of the maps.
    let cut = &GOOD_GEM[..GOOD_GEM.find("(material: \"gold\")").unwrap()];
    broken(
        &dir,
        "truncated.ron",
        cut,
        Some(13),
        &["the file ends here"],
    );
    // A stray bracket after a map entry: its line, no field of the closed
    // entry, and what it may be.
    let stray = GOOD_GEM.replace("(material: \"gold\"),", "(material: \"gold\")),");
    broken(
        &dir,
        "stray.ron",
        &stray,
        Some(14),
        &[":14:31: Expected comma (is this `)` one too many, or the wrong kind of bracket?)"],
    );
    // A material's closing bracket missing at the end of its line: RON
    // stops lines later; the message names the bracket left open.
    let unclosed = GOOD_GEM.replace("(colour: (0.4, 0.3, 0.5)),", "(colour: (0.4, 0.3, 0.5),");
    broken(
        &dir,
        "unclosed.ron",
        &unclosed,
        Some(10),
        &[
            "is a `)` missing on line 8? the `(` of `Diffuse(` at 8:26 is still open where \
             line 9 begins",
        ],
    );
    // A closing quote missing.
    let unquoted = GOOD_GEM.replace("name: \"good\",", "name: \"good,");
    broken(
        &dir,
        "unquoted.ron",
        &unquoted,
        None,
        &["is a closing `\"` missing? the string opened at 3:11 runs on past the end of its line"],
    );
    // Not UTF-8 (a Latin-1 `é` in a comment).
    let mut bytes = b"// caf\xe9\n".to_vec();
    bytes.extend_from_slice(GOOD_GEM.as_bytes());
    let (code, _, err) = validate_file(&dir, "latin1.ron", &bytes);
    assert_eq!(code, 1);
    assert!(
        err.contains("latin1.ron") && err.contains("not UTF-8"),
        "{err}"
    );
    // Empty, and no top-level struct name.
    broken(
        &dir,
        "empty.ron",
        "",
        None,
        &[
            "the file is empty",
            "expected a .ron recipe (gem, material, scene or job)",
        ],
    );
    broken(
        &dir,
        "anonymous.ron",
        "// note\n(base: Black)\n",
        Some(2),
        &["found `(`", "`Gem(`"],
    );
    // A folder: each of its .ron files (the broken ones above), in name
    // order; a folder without any is an error of its own.
    // A link to nothing is not skipped in silence.
    std::os::unix::fs::symlink("nowhere.ron", dir.join("gone.ron")).unwrap();
    let out = lapidary(&["validate", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    let anonymous = err.find("anonymous.ron:2:1: found `(`");
    let empty = err.find("empty.ron: the file is empty");
    assert!(anonymous.is_some() && anonymous < empty, "{err}");
    assert!(err.contains("gone.ron: cannot read"), "{err}");
    let none = dir.join("none");
    std::fs::create_dir_all(&none).unwrap();
    std::fs::write(none.join("notes.txt"), "not a recipe").unwrap();
    let out = lapidary(&["validate", none.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains("a folder without .ron files"), "{err}");
    // Any other command is given a folder for a file: said so.
    let out = lapidary(&["render", dir.to_str().unwrap(), "-o", "x.png"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("is a directory"),
        "{}",
        text(&out.stderr)
    );
    // A missing file.
    let missing = dir.join("missing.ron");
    let out = lapidary(&["validate", missing.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.contains("missing.ron") && err.contains("cannot read"),
        "{err}"
    );
}

/// A valid scene naming the built-in gem and ground material; its stone's
/// girdle (0.5 mm below the dome) rests on the ground.
const GOOD_SCENE: &str = r#"Scene(
    camera: Orbit(target: (0.0, 0.0, 1.0), distance: 40.0, elevation_deg: 30.0, azimuth_deg: 0.0, vertical_fov_deg: 25.0),
    stones: [
        Stone(
            recipe: Some("green-aventurine"),
            shape: Cabochon(outline: Oval, length: 10.0, width: 8.0), position: (0.0, 0.0, 0.5),
        ),
    ],
    ground: Some(Ground(height: 0.0, material: "teflon")),
)
"#;

#[test]
fn stones_sunk_into_the_ground_or_crossing_each_other_are_warned_of() {
    let dir = scratch("placement");
    let (code, out, err) = validate_file(&dir, "resting.ron", GOOD_SCENE.as_bytes());
    assert_eq!(code, 0, "{err}");
    assert!(
        !out.contains("warning") && !err.contains("warning"),
        "{err}"
    );
    // At the default position the girdle sinks 0.5 mm; a second stone 6 mm
    // along x crosses the first (both are 10 mm long along x).
    let scene = GOOD_SCENE.replace("position: (0.0, 0.0, 0.5)", "position: (0.0, 0.0, 0.0)");
    let scene = scene.replace(
        "    ],\n    ground",
        "        Stone(shape: Cabochon(outline: Oval, length: 10.0, width: 8.0), position: (6.0, 0.0, 0.5)),\n    ],\n    ground",
    );
    let (code, out, err) = validate_file(&dir, "placed.ron", scene.as_bytes());
    assert_eq!(code, 0, "a warning is not an error: {err}");
    assert!(!out.contains("warning"), "warnings go to stderr: {out}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 2, "{err}");
    assert!(
        warnings[0].contains("placed.ron: warning: stone 1 sinks 0.500 mm into the ground"),
        "{err}"
    );
    assert!(
        warnings[1].contains("placed.ron: warning: stones 1 and 2 overlap"),
        "{err}"
    );
    // `render` says the same, even when quiet, and still renders.
    let path = dir.join("placed.ron");
    let image = dir.join("placed.png");
    let out = lapidary(&[
        "render",
        "--scene",
        path.to_str().unwrap(),
        "--size",
        "8",
        "--spp",
        "1",
        "-q",
        "-o",
        image.to_str().unwrap(),
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert_eq!(err.matches("warning:").count(), 2, "{err}");
    assert!(err.contains("stones 1 and 2 overlap"), "{err}");
    assert!(image.exists());
}

#[test]
fn a_camera_or_light_inside_a_stone_is_warned_of() {
    let dir = scratch("inside");
    // The orbit's eye 0.001 mm from its target in the stone's dome; a
    // point light there too, and a sphere light well outside.
    let scene = GOOD_SCENE.replace("distance: 40.0", "distance: 0.001").replace(
        "    ground",
        "    lights: [\n        Sphere(centre: (0.0, 0.0, 30.0), radius: 1.0, radiance: (10.0, 10.0, 10.0)),\n        Point(position: (0.0, 0.0, 1.0), intensity: (10.0, 10.0, 10.0)),\n    ],\n    ground",
    );
    let (code, out, err) = validate_file(&dir, "inside.ron", scene.as_bytes());
    assert_eq!(code, 0, "a warning is not an error: {err}");
    assert!(!out.contains("warning"), "warnings go to stderr: {out}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 2, "{err}");
    assert!(
        warnings[0].contains("the camera is inside stone 1"),
        "{err}"
    );
    assert!(warnings[1].contains("light 2 is inside stone 1"), "{err}");
}

#[test]
fn a_sphere_light_around_the_scene_and_things_below_the_ground_are_warned_of() {
    let dir = scratch("enclosing");
    let with_lights = |lights: &str| {
        GOOD_SCENE.replace(
            "    ground",
            &format!("    lights: [\n        {lights}\n    ],\n    ground"),
        )
    };
    let warnings = |name: &str, scene: &str| -> Vec<String> {
        let (code, out, err) = validate_file(&dir, name, scene.as_bytes());
        assert_eq!(code, 0, "a warning is not an error: {err}");
        assert!(!out.contains("warning"), "warnings go to stderr: {out}");
        err.lines()
            .filter(|l| l.contains("warning"))
            .map(str::to_string)
            .collect()
    };
    // A light dome centred in the stone: around the camera and the stone,
    // not inside the stone.
    let dome =
        with_lights("Sphere(centre: (0.0, 0.0, 1.0), radius: 100.0, radiance: (1.0, 1.0, 1.0)),");
    let found = warnings("dome.ron", &dome);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found[0].contains("the camera is inside light 1"),
        "{found:?}"
    );
    assert!(found[1].contains("stone 1 is inside light 1"), "{found:?}");
    // A point light inside a small sphere light away from the stone, and a
    // sphere light only partly inside it (not warned of).
    let nested = with_lights(
        "Sphere(centre: (30.0, 0.0, 10.0), radius: 2.0, radiance: (1.0, 1.0, 1.0)),\n        \
         Point(position: (30.5, 0.0, 10.0), intensity: (1.0, 1.0, 1.0)),\n        \
         Sphere(centre: (31.5, 0.0, 10.0), radius: 1.0, radiance: (1.0, 1.0, 1.0)),",
    );
    let found = warnings("nested.ron", &nested);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].contains("light 2 is inside light 1, a sphere that emits outwards only"),
        "{found:?}"
    );
    // A sphere under the ground, a sun below the horizon.
    let below = with_lights(
        "Sphere(centre: (0.0, 0.0, -20.0), radius: 2.0, radiance: (1.0, 1.0, 1.0)),\n        \
         Sun(elevation_deg: -5.0, azimuth_deg: 0.0, angular_diameter_deg: 0.5, irradiance: (1.0, 1.0, 1.0)),",
    );
    let found = warnings("below.ron", &below);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found[0].contains("light 1 is below the ground"),
        "{found:?}"
    );
    assert!(
        found[1].contains("light 2, a sun, is at or below the horizon"),
        "{found:?}"
    );
    // The camera under the ground.
    let under = GOOD_SCENE.replace("elevation_deg: 30.0", "elevation_deg: -30.0");
    let found = warnings("under.ron", &under);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].contains("the camera is below the ground"),
        "{found:?}"
    );
}

#[test]
fn scenes_are_checked_with_the_gems_and_materials_they_name() {
    let dir = scratch("scene");
    let (code, out, err) = validate_file(&dir, "good-scene.ron", GOOD_SCENE.as_bytes());
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("ok (scene, 1 stone, 0 lights, ground)"),
        "{out}"
    );
    // A stone of negative length (line 6).
    let scene = GOOD_SCENE.replace("length: 10.0", "length: -10.0");
    broken(&dir, "length.ron", &scene, Some(6), &["length", "> 0"]);
    // A stone naming a gem with a typo.
    let scene = GOOD_SCENE.replace("\"green-aventurine\"", "\"green-aventurin\"");
    broken(
        &dir,
        "gemname.ron",
        &scene,
        Some(5),
        &["green-aventurin", "did you mean `green-aventurine`"],
    );
    // A ground material with a typo.
    let scene = GOOD_SCENE.replace("\"teflon\"", "\"teflom\"");
    broken(
        &dir,
        "ground.ron",
        &scene,
        Some(9),
        &["teflom", "did you mean `teflon`"],
    );
}

#[test]
fn a_scene_or_job_reports_every_input_that_does_not_load() {
    let dir = scratch("every-input");
    // Two gem files, each with an unknown material.
    std::fs::write(dir.join("a.ron"), GOOD_GEM.replace("\"gold\"", "\"golt\"")).unwrap();
    std::fs::write(
        dir.join("b.ron"),
        GOOD_GEM.replace("\"lilac\", weight", "\"lilak\", weight"),
    )
    .unwrap();
    // A scene of three stones: a.ron twice (reported once) and b.ron.
    let stone = |gem: &str, x: f64| {
        format!("        Stone(recipe: Some(\"{gem}\"), shape: Cabochon(outline: Oval, length: 10.0, width: 8.0), position: ({x:.1}, 0.0, 0.5)),\n")
    };
    let stones = [
        stone("a.ron", 0.0),
        stone("a.ron", 20.0),
        stone("b.ron", 40.0),
    ]
    .concat();
    let scene = GOOD_SCENE.replace(
        &GOOD_SCENE[GOOD_SCENE.find("        Stone(").unwrap()..GOOD_SCENE.find("    ],").unwrap()],
        &stones,
    );
    let (code, _, err) = validate_file(&dir, "scene.ron", scene.as_bytes());
    assert_eq!(code, 1, "{err}");
    assert_eq!(err.matches("unknown material `golt`").count(), 1, "{err}");
    let (golt, lilak) = (err.find("`golt`"), err.find("`lilak`"));
    assert!(golt.is_some() && lilak.is_some() && golt < lilak, "{err}");
    // `render` compiles every gem before it stops, and says so of both.
    let picture = dir.join("scene.png");
    let scene_path = dir.join("scene.ron");
    let out = lapidary(&[
        "render",
        "--scene",
        scene_path.to_str().unwrap(),
        "--size",
        "8",
        "-o",
        picture.to_str().unwrap(),
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let (golt, lilak) = (err.find("`golt`"), err.find("`lilak`"));
    assert!(golt.is_some() && lilak.is_some() && golt < lilak, "{err}");
    assert!(!picture.exists());
    // A job naming a gem that is no gem, a broken gem and the scene.
    let job = "Job(\n    output: \"out\",\n    recipes: [\"goldstonee\", \"b.ron\"],\n    scenes: [\"scene.ron\"],\n)\n";
    let (code, _, err) = validate_file(&dir, "job.ron", job.as_bytes());
    assert_eq!(code, 1, "{err}");
    for needle in [
        "job.ron:3:15: recipe `goldstonee` does not load",
        "job.ron:3:30: recipe `",
        "b.ron` does not load",
        "job.ron:4:15: scene `",
        "scene.ron` does not load",
        "unknown material `golt`",
    ] {
        assert!(err.contains(needle), "`{needle}` missing:\n{err}");
    }
}

#[test]
fn several_inputs_one_bad_fail_and_still_report_the_good_ones() {
    let dir = scratch("several");
    let good = dir.join("good.ron");
    let bad = dir.join("bad.ron");
    std::fs::write(&good, GOOD_GEM).unwrap();
    std::fs::write(&bad, GOOD_GEM.replace("ior: 1.5", "ior: 0.5")).unwrap();
    let out = lapidary(&[
        "validate",
        good.to_str().unwrap(),
        bad.to_str().unwrap(),
        "gold",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = text(&out.stdout);
    let stderr = text(&out.stderr);
    assert!(
        stdout.contains(&format!("{}: ok (gem \"good\"", good.display())),
        "{stdout}"
    );
    assert!(stdout.contains("builtin:gold: ok (material"), "{stdout}");
    assert!(
        stderr.contains(&format!("{}:7:", bad.display())),
        "{stderr}"
    );
    assert!(stderr.contains("1 of 3 inputs"), "{stderr}");
}

#[test]
fn an_unknown_builtin_name_suggests_the_close_one() {
    let out = lapidary(&["validate", "lavender-lepidolit"]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains("did you mean `lavender-lepidolite`"), "{err}");
}

#[test]
fn new_writes_a_recipe_that_validates_and_names_the_gem() {
    let dir = scratch("new");
    let path = dir.join("my-stone.ron");
    let out = lapidary(&[
        "new",
        "my-stone",
        "--from",
        "lavender-lepidolite",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let written = std::fs::read_to_string(&path).unwrap();
    assert!(written.starts_with("// my-stone:"), "{written}");
    assert!(written.contains("lapidary validate"), "{written}");
    assert!(written.contains("lapidary render"), "{written}");
    assert!(written.contains("name: \"my-stone\""), "{written}");
    assert!(
        written.contains("description: \"my-stone, started from lavender-lepidolite: "),
        "{written}"
    );
    // The template's own name is gone from the `name:` field only.
    assert!(
        !written.contains("name: \"lavender-lepidolite\""),
        "{written}"
    );
    let out = lapidary(&["validate", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("ok (gem \"my-stone\""));
    // A material template, to the default NAME.ron in the working folder.
    let out = Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(["new", "my-paint", "--from", "brass"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = lapidary(&["validate", dir.join("my-paint.ron").to_str().unwrap()]);
    assert!(
        text(&out.stdout).contains("ok (material, 2 layers"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn new_never_overwrites_and_refuses_unknown_templates() {
    let dir = scratch("refuse");
    let path = dir.join("taken.ron");
    std::fs::write(&path, "precious").unwrap();
    let out = lapidary(&[
        "new",
        "taken",
        "--from",
        "gold",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("already exists"),
        "{}",
        text(&out.stderr)
    );
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "precious");

    let other = dir.join("other.ron");
    let out = lapidary(&[
        "new",
        "other",
        "--from",
        "green-aventurin",
        "-o",
        other.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(err.contains("did you mean `green-aventurine`"), "{err}");
    assert!(
        err.contains("lavender-lepidolite") && err.contains("teflon"),
        "{err}"
    );
    assert!(!other.exists());
    // A name that would read as an option, and `-o -`, write nothing.
    let out = lapidary(&["new", "--from", "gold", "--", "-x"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("must not start with `-`"),
        "{}",
        text(&out.stderr)
    );
    let out = lapidary(&["new", "dash", "--from", "gold", "-o", "-"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("-o -: `lapidary new` writes a file"),
        "{}",
        text(&out.stderr)
    );
    assert!(!Path::new("-").exists() && !Path::new("-x.ron").exists());
    // RON text is not written into a file named as an image.
    let picture = dir.join("stone.png");
    let out = lapidary(&[
        "new",
        "stone",
        "--from",
        "gold",
        "-o",
        picture.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("allowed: a path ending in .ron"),
        "{}",
        text(&out.stderr)
    );
    assert!(!picture.exists());
}
