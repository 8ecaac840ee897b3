//! Broken inputs through the real binary (`validate`, `render`, `maps`,
//! `brdf`): each is a mistake a person really makes. Every one must end with
//! exit status 1, a message naming the file (with `line:col` where the
//! mistake has a place) and what is wrong, no panic, no output file
//! created, and an existing output file left byte-for-byte as it was.
//!
//! Renders that could start use `--size 8 --spp 1`, and the recipes turn the
//! multiple-scattering compensation off, so the whole file runs in seconds.

mod common;

use common::cli::Scratch;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A valid gem with every kind of node (surface map, switch, glitter with
/// facets), one field per line so each mistake below has its own line.
const GOOD_GEM: &str = r#"Gem(
    name: "test",
    seed: 3,
    materials: {
        "lilac": Material(
            layers: [
                Layer(ior: 1.5, roughness_deg: 5.0, thickness: 0.1, absorption: (0.1, 0.2, 0.3)),
            ],
            base: Diffuse(colour: (0.4, 0.3, 0.5)),
            multiple_scattering: false,
        ),
        "foil": Material(
            base: Conductor(metal: "silver", roughness_deg: 4.0),
            multiple_scattering: false,
        ),
    },
    maps: {
        "tiles": SurfaceMap(
            cell_size: 0.1,
            entries: [
                (material: "lilac", weight: 2.0),
                (material: "foil", weight: 1.0),
            ],
        ),
        "veins": Switch(
            function: Marble(frequency: 4.0, amplitude: 2.0),
            ranges: [
                (from: 0.0, to: 0.8, map: "tiles"),
                (from: 0.8, to: 1.0, material: "foil"),
            ],
        ),
    },
    surface: "veins",
    glitter: Some(GlitterMap(
        cell_size: 0.2,
        fill_fraction: 0.02,
        entries: [(material: "foil")],
        facets: FacetBumpMap(cell_size: 0.05, tilt: UniformCone(max_tilt_deg: 20.0)),
    )),
)
"#;

/// A valid material file.
const GOOD_MATERIAL: &str = r#"Material(
    layers: [
        Layer(
            ior: 1.5,
            roughness_deg: 3.0,
            thickness: 0.2,
            absorption: (0.1, 0.4, 0.8),
        ),
    ],
    base: Diffuse(colour: (0.8, 0.2, 0.1)),
    multiple_scattering: false,
)
"#;

/// A valid scene: the gem named on the command line on a cushion stone.
const GOOD_SCENE: &str = r#"Scene(
    camera: LookAt(
        position: (30.0, -30.0, 25.0),
        look_at: (0.0, 0.0, 1.0),
        vertical_fov_deg: 25.0,
    ),
    stones: [
        Stone(
            shape: Cabochon(
                outline: Oval,
                length: 10.0,
                width: 8.0,
            ),
            position: (0.0, 0.0, 0.5),
        ),
    ],
    environment: Constant(radiance: (0.5, 0.5, 0.5)),
)
"#;

/// Bytes a pre-existing output holds; a failed command must not touch them.
const KNOWN_BYTES: &[u8] = b"not an image: bytes that must survive a failed command\n";

fn lapidary<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(args)
        .output()
        .expect("binary runs")
}

/// A fresh empty directory for one case, removed when the test passes.
fn scratch(name: &str) -> Scratch {
    common::cli::scratch("bad", name)
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// `path:LINE:` where LINE is the 1-based line of the first line of `text`
/// holding `marker`: where a person would look for the mistake.
fn at_line(path: &Path, text: &str, marker: &str) -> String {
    let line = text
        .lines()
        .position(|l| l.contains(marker))
        .unwrap_or_else(|| panic!("marker `{marker}` not in the input"))
        + 1;
    format!("{}:{line}:", path.display())
}

/// Exit status 1, no panic, and every needle in the messages; where a
/// needle is `file:LINE:` it must be followed by a column number.
fn assert_refused(case: &str, out: &Output, needles: &[String]) {
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let all = format!("{stdout}{stderr}");
    assert_eq!(
        out.status.code(),
        Some(1),
        "{case}: exit status {:?}\n{all}",
        out.status
    );
    assert!(!all.contains("panicked"), "{case}: panicked\n{all}");
    assert!(!all.contains("RUST_BACKTRACE"), "{case}: panicked\n{all}");
    for needle in needles {
        let Some(at) = all.find(needle.as_str()) else {
            panic!("{case}: message lacks `{needle}`:\n{all}");
        };
        if needle.ends_with(':') && needle.rsplit(':').nth(1).is_some_and(is_number) {
            let col: String = all[at + needle.len()..]
                .chars()
                .take_while(char::is_ascii_digit)
                .collect();
            assert!(
                !col.is_empty() && all[at + needle.len() + col.len()..].starts_with(':'),
                "{case}: `{needle}` is not followed by a column:\n{all}"
            );
        }
    }
}

fn is_number(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit())
}

/// Runs a command that writes `-o OUT` twice: once with no OUT (none may be
/// created, nothing else left in its folder) and once with OUT holding
/// [`KNOWN_BYTES`] (they must be unchanged). `args` go before `-o OUT`.
fn assert_refused_writing(case: &str, args: &[OsString], out_name: &str, needles: &[String]) {
    let dir = scratch(&format!("{case}-out"));
    let output = dir.join(out_name);
    let with_output = |args: &[OsString]| {
        let mut all = args.to_vec();
        all.push("-o".into());
        all.push(output.clone().into());
        lapidary(&all)
    };
    let out = with_output(args);
    assert_refused(case, &out, needles);
    assert!(
        files_in(&dir).is_empty(),
        "{case}: left {:?} behind",
        files_in(&dir)
    );

    std::fs::write(&output, KNOWN_BYTES).unwrap();
    let out = with_output(args);
    assert_refused(case, &out, needles);
    assert_eq!(
        std::fs::read(&output).unwrap(),
        KNOWN_BYTES,
        "{case}: the existing output was changed"
    );
    assert_eq!(files_in(&dir), [out_name], "{case}: extra files left");
    let _ = std::fs::remove_dir_all(&dir);
}

fn os(args: &[&str]) -> Vec<OsString> {
    args.iter().map(OsString::from).collect()
}

/// A gem recipe made from [`GOOD_GEM`] by replacing `from` with `to`; the
/// mistake is on the line holding `marker`. Checked through `validate`,
/// `render` and `maps`: each names `file:line:col` and says what is wrong
/// (every needle).
fn bad_gem(case: &str, from: &str, to: &str, marker: &str, needles: &[&str]) {
    assert!(GOOD_GEM.contains(from), "{case}: `{from}` not in GOOD_GEM");
    let text = GOOD_GEM.replacen(from, to, 1);
    let dir = scratch(case);
    let path = dir.join(format!("{case}.ron"));
    std::fs::write(&path, &text).unwrap();
    let mut expected = vec![at_line(&path, &text, marker)];
    expected.extend(needles.iter().map(|s| s.to_string()));

    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused(case, &out, &expected);
    let render = [
        OsString::from("render"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
        "-q".into(),
    ];
    assert_refused_writing(case, &render, "gem.png", &expected);
    let maps = [
        OsString::from("maps"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing(case, &maps, "maps.png", &expected);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scratch folder `name` holding [`GOOD_GEM`], [`GOOD_MATERIAL`] and
/// [`GOOD_SCENE`] as `gem.ron`, `material.ron` and `scene.ron`: the folder
/// and the three paths.
fn good_files(name: &str) -> (Scratch, PathBuf, PathBuf, PathBuf) {
    let dir = scratch(name);
    let paths = ["gem.ron", "material.ron", "scene.ron"].map(|file| dir.join(file));
    for (path, text) in paths.iter().zip([GOOD_GEM, GOOD_MATERIAL, GOOD_SCENE]) {
        std::fs::write(path, text).unwrap();
    }
    let [gem, material, scene] = paths;
    (dir, gem, material, scene)
}

#[test]
fn the_good_inputs_are_accepted() {
    // The bad inputs below are one mistake away from these: they must be
    // valid, or the refusals would prove nothing.
    let (dir, gem, material, scene) = good_files("good");
    let out = lapidary(&[
        OsString::from("validate"),
        gem.clone().into(),
        material.clone().into(),
        scene.clone().into(),
    ]);
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let png = dir.join("gem.png");
    let out = lapidary(&[
        OsString::from("render"),
        gem.into(),
        "--scene".into(),
        scene.into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
        "-q".into(),
        "-o".into(),
        png.clone().into(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(png.is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

// ---- gem recipes: field names and types --------------------------------

#[test]
fn typo_in_a_map_field_name() {
    bad_gem(
        "typo-map-field",
        "cell_size: 0.1,",
        "cell_sise: 0.1,",
        "cell_sise",
        &["unknown field `cell_sise`", "cell_size"],
    );
}

#[test]
fn typo_in_a_top_level_field_name() {
    bad_gem(
        "typo-top-field",
        "surface: \"veins\",",
        "surfce: \"veins\",",
        "surfce",
        &["unknown field `surfce`", "surface"],
    );
}

#[test]
fn the_retired_host_ior_field() {
    // An older recipe's `host_ior` (parsed, never used): refused at its
    // line, naming what replaced it.
    bad_gem(
        "host-ior",
        "seed: 3,",
        "seed: 3,\n    host_ior: 1.56,",
        "host_ior",
        &["`host_ior` is retired", "body: Translucent(ior: …)"],
    );
}

#[test]
fn typo_in_a_layer_field_name() {
    bad_gem(
        "typo-layer-field",
        "roughness_deg: 5.0,",
        "roughnes_deg: 5.0,",
        "roughnes_deg",
        &["unknown field `roughnes_deg`", "roughness_deg"],
    );
}

#[test]
fn a_string_where_a_number_belongs() {
    bad_gem(
        "string-for-number",
        "cell_size: 0.1,",
        "cell_size: \"0.1\",",
        "cell_size: \"0.1\"",
        &["cell_size", "allowed: a number such as 1.5, without quotes"],
    );
}

#[test]
fn a_number_where_a_name_belongs() {
    bad_gem(
        "number-for-name",
        "surface: \"veins\",",
        "surface: 7,",
        "surface: 7",
        &["surface"],
    );
}

#[test]
fn an_unknown_base_variant() {
    bad_gem(
        "unknown-base",
        "base: Diffuse(colour: (0.4, 0.3, 0.5)),",
        "base: Glossy(colour: (0.4, 0.3, 0.5)),",
        "Glossy",
        &["Glossy", "Diffuse"],
    );
}

// ---- gem recipes: numbers out of range ---------------------------------

#[test]
fn nan_ior() {
    bad_gem(
        "nan-ior",
        "ior: 1.5,",
        "ior: NaN,",
        "ior: NaN",
        &["ior", "NaN", "1 <= ior <= 5"],
    );
}

#[test]
fn infinite_thickness() {
    bad_gem(
        "inf-thickness",
        "thickness: 0.1,",
        "thickness: inf,",
        "thickness: inf",
        &["thickness", "inf", "thickness >= 0"],
    );
}

#[test]
fn ior_below_one() {
    bad_gem(
        "ior-below-one",
        "ior: 1.5,",
        "ior: 0.8,",
        "ior: 0.8",
        &["ior", "0.8", "1 <= ior <= 5"],
    );
}

#[test]
fn a_hexadecimal_number_where_a_fraction_belongs() {
    // RON reads `0x…` for whole numbers only: it reads the 0, then stops at
    // the `x` (or the range check refuses the 0 first).
    bad_gem(
        "hex-ior",
        "ior: 1.5,",
        "ior: 0x2,",
        "ior: 0x2",
        &["`0x2` is read as 0 followed by `x2`", "decimal digits"],
    );
    bad_gem(
        "binary-thickness",
        "thickness: 0.1,",
        "thickness: 0b1,",
        "thickness: 0b1",
        &["field `thickness`", "`0b1` is read as 0 followed by `b1`"],
    );
}

#[test]
fn negative_thickness() {
    bad_gem(
        "negative-thickness",
        "thickness: 0.1,",
        "thickness: -0.1,",
        "thickness: -0.1",
        &["thickness", "-0.1", "thickness >= 0"],
    );
}

#[test]
fn layer_roughness_of_90_degrees() {
    bad_gem(
        "layer-roughness-90",
        "roughness_deg: 5.0,",
        "roughness_deg: 90.0,",
        "roughness_deg: 90",
        &["roughness_deg", "90"],
    );
}

#[test]
fn metal_roughness_above_90_degrees() {
    bad_gem(
        "metal-roughness-120",
        "roughness_deg: 4.0",
        "roughness_deg: 120.0",
        "roughness_deg: 120",
        &["roughness_deg", "120"],
    );
}

#[test]
fn colour_above_one() {
    bad_gem(
        "colour-above-one",
        "colour: (0.4, 0.3, 0.5)",
        "colour: (1.4, 0.3, 0.5)",
        "colour: (1.4",
        &["colour", "1.4"],
    );
}

#[test]
fn negative_absorption() {
    bad_gem(
        "negative-absorption",
        "absorption: (0.1, 0.2, 0.3)",
        "absorption: (0.1, -0.2, 0.3)",
        "absorption: (0.1, -0.2",
        &["absorption", "-0.2"],
    );
}

#[test]
fn a_metal_with_a_refractive_index_of_zero() {
    bad_gem(
        "metal-n-zero",
        "Conductor(metal: \"silver\", roughness_deg: 4.0)",
        "Conductor(n: (0.0, 0.13, 0.157), k: (0.0, 3.25, 2.40), roughness_deg: 4.0)",
        "n: (0.0",
        &["`n`", "0.01 <= n <= 20"],
    );
}

#[test]
fn zero_cell_size() {
    bad_gem(
        "zero-cell-size",
        "cell_size: 0.1,",
        "cell_size: 0.0,",
        "cell_size: 0.0",
        &["cell_size", "0"],
    );
}

// ---- gem recipes: rules across fields ----------------------------------

#[test]
fn an_empty_entry_list() {
    bad_gem(
        "empty-entries",
        "entries: [(material: \"foil\")],",
        "entries: [],",
        "glitter: Some",
        &["`glitter` has no entries"],
    );
}

#[test]
fn an_empty_surface_map() {
    let from =
        "(material: \"lilac\", weight: 2.0),\n                (material: \"foil\", weight: 1.0),";
    bad_gem(
        "empty-surface-map",
        from,
        "",
        "\"tiles\": SurfaceMap",
        &["tiles", "no entries"],
    );
}

#[test]
fn weights_all_zero() {
    let from =
        "(material: \"lilac\", weight: 2.0),\n                (material: \"foil\", weight: 1.0),";
    let to =
        "(material: \"lilac\", weight: 0.0),\n                (material: \"foil\", weight: 0.0),";
    bad_gem(
        "weights-all-zero",
        from,
        to,
        "\"tiles\": SurfaceMap",
        &["weight", "tiles"],
    );
}

#[test]
fn a_negative_weight() {
    bad_gem(
        "negative-weight",
        "weight: 2.0",
        "weight: -2.0",
        "weight: -2.0",
        &["weight", "-2"],
    );
}

#[test]
fn a_map_that_contains_itself() {
    bad_gem(
        "self-map",
        "(material: \"foil\", weight: 1.0),",
        "(map: \"tiles\", weight: 1.0),",
        "\"tiles\": SurfaceMap",
        &["map `tiles` contains itself directly"],
    );
}

#[test]
fn a_map_that_contains_itself_through_another() {
    // tiles → veins (in its entries) → tiles (in its first range).
    bad_gem(
        "cycle-map",
        "(material: \"foil\", weight: 1.0),",
        "(map: \"veins\", weight: 1.0),",
        "\"tiles\": SurfaceMap",
        &["map `tiles` contains itself through veins"],
    );
}

#[test]
fn maps_nested_deeper_than_the_pattern_can_evaluate() {
    // A chain of SurfaceMaps m0 → m1 → … → mN → a material: N + 1 maps.
    let chain = |maps: usize| {
        let mut text = String::from("Gem(\n    maps: {\n");
        for k in 0..maps - 1 {
            text += &format!(
                "        \"m{k}\": SurfaceMap(cell_size: 0.1, entries: [(map: \"m{}\")]),\n",
                k + 1
            );
        }
        text += &format!(
            "        \"m{}\": SurfaceMap(cell_size: 0.1, entries: [(material: \"gold\")]),\n",
            maps - 1
        );
        text + "    },\n    surface: \"m0\",\n)\n"
    };
    let dir = scratch("deep-maps");
    let (deepest, too_deep, far_too_deep) = (
        dir.join("deepest.ron"),
        dir.join("too-deep.ron"),
        dir.join("far-too-deep.ron"),
    );
    std::fs::write(&deepest, chain(64)).unwrap();
    let out = lapidary(&[OsString::from("validate"), deepest.into()]);
    assert!(
        out.status.success(),
        "64 maps deep is allowed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Twenty thousand overflowed the render threads' stacks (an abort).
    for (path, maps) in [(&too_deep, 65), (&far_too_deep, 20_000)] {
        std::fs::write(path, chain(maps)).unwrap();
        let out = lapidary(&[OsString::from("validate"), path.into()]);
        assert_refused(
            "deep maps",
            &out,
            &[
                format!("{}:3:", path.display()),
                "map `m0` nests more than 64 maps deep".to_string(),
            ],
        );
    }
}

#[test]
fn a_map_and_a_material_of_one_name() {
    bad_gem(
        "map-and-material",
        "\"tiles\": SurfaceMap(",
        "\"foil\": SurfaceMap(",
        "\"foil\": Material(",
        &["`foil` names both a map and a material"],
    );
}

#[test]
fn more_layers_than_allowed() {
    let layer = "Layer(ior: 1.5, roughness_deg: 5.0, thickness: 0.1, absorption: (0.1, 0.2, 0.3)),";
    bad_gem(
        "seventeen-layers",
        layer,
        &format!(
            "{}\n                Layer(ior: 1.4), // the 17th",
            layer.repeat(16)
        ),
        "the 17th",
        &["`layers` has 17 layers; allowed: at most 16"],
    );
}

#[test]
fn a_glitter_map_on_a_translucent_body() {
    bad_gem(
        "translucent-glitter",
        "surface: \"veins\",",
        "surface: \"veins\",\n    body: Translucent(ior: 1.5),",
        "glitter: Some(",
        &["`glitter` on a translucent body", "inclusions"],
    );
}

#[test]
fn a_misspelt_variant_and_library_material_have_a_suggestion() {
    bad_gem(
        "variant-typo",
        "base: Diffuse(colour: (0.4, 0.3, 0.5)),",
        "base: Difuse(colour: (0.4, 0.3, 0.5)),",
        "Difuse",
        &["field `base`: unknown variant `Difuse` (did you mean `Diffuse`?)"],
    );
    bad_gem(
        "library-typo",
        "surface: \"veins\",",
        "surface: \"silvr\",",
        "surface: \"silvr\"",
        &["did you mean `silver`?"],
    );
}

#[test]
fn an_unknown_material_name() {
    bad_gem(
        "unknown-material",
        "(material: \"lilac\", weight: 2.0),",
        "(material: \"lilak\", weight: 2.0),",
        "lilak",
        &["unknown material `lilak`", "lilac"],
    );
}

/// `path:line:col: ` of byte `offset` of `text` (columns in characters).
fn place_of(path: &Path, text: &str, offset: usize) -> String {
    let line = text[..offset].matches('\n').count() + 1;
    let col = text[..offset]
        .rsplit('\n')
        .next()
        .unwrap_or_default()
        .chars()
        .count()
        + 1;
    format!("{}:{line}:{col}: ", path.display())
}

/// Exit status 1 and every one of `expected` on stderr, in that order;
/// returns stderr.
fn refused_in_order(out: &Output, expected: &[String]) -> String {
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let at: Vec<usize> = expected
        .iter()
        .map(|e| {
            stderr
                .find(e.as_str())
                .unwrap_or_else(|| panic!("no `{e}`:\n{stderr}"))
        })
        .collect();
    assert!(
        at.windows(2).all(|w| w[0] < w[1]),
        "out of order:\n{stderr}"
    );
    stderr
}

#[test]
fn a_map_that_does_not_compile_is_reported_with_the_unknown_names() {
    let text = GOOD_GEM
        .replacen("weight: 2.0", "weight: 0.0", 1)
        .replacen("weight: 1.0", "weight: 0.0", 1)
        .replacen(
            "entries: [(material: \"foil\")],",
            "entries: [(material: \"foyl\")],",
            1,
        );
    let dir = scratch("map-and-name");
    let path = dir.join("gem.ron");
    std::fs::write(&path, &text).unwrap();
    let expected = [
        "the `weight`s of `tiles` sum to 0".to_string(),
        "unknown material `foyl`".to_string(),
    ];
    refused_in_order(
        &lapidary(&[OsString::from("validate"), path.into()]),
        &expected,
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `validate` refuses the recipe `text` (written as `name`/gem.ron) with each
/// `(written, message)`: the message at the place where `written` first
/// occurs, in that order.
fn validate_refuses_at(name: &str, text: &str, expected: &[(&str, &str)]) {
    let dir = scratch(name);
    let path = dir.join("gem.ron");
    std::fs::write(&path, text).unwrap();
    let expected: Vec<String> = expected
        .iter()
        .map(|(written, message)| {
            let at = text.find(written).expect("written");
            format!("{}{message}", place_of(&path, text, at))
        })
        .collect();
    refused_in_order(
        &lapidary(&[OsString::from("validate"), path.into()]),
        &expected,
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_inclusion_population_that_does_not_compile_is_reported_at_its_entry() {
    // goldstone's two populations of copper crystals, each made too large
    // for its cells, the second also aligned along a zero direction: every
    // problem at its own entry (the second's were placed at the first's
    // `size_mm`, and the run stopped at the first).
    let text = include_str!("../gem-recipes/goldstone.ron")
        .replacen("size_mm: 0.12,", "size_mm: 0.5,", 1)
        .replacen("size_mm: 0.1,", "size_mm: 0.6,", 1)
        .replacen(
            "density_per_mm3: 100.0, orientation: Isotropic",
            "density_per_mm3: 100.0, orientation: Aligned(direction: (0.0, 0.0, 0.0), spread_deg: 3.0)",
            1,
        );
    validate_refuses_at(
        "inclusions-every-problem",
        &text,
        &[
            (
                "size_mm: 0.5,",
                "inclusions 1: flakes up to 0.7000 mm do not fit",
            ),
            (
                "size_mm: 0.6,",
                "inclusions 2: flakes up to 0.7200 mm do not fit",
            ),
            ("Aligned(", "inclusions 2: `direction` is zero"),
        ],
    );
}

#[test]
fn a_layer_s_problem_is_placed_at_the_layer_not_at_a_comment_naming_one() {
    // The n-th `Layer(` is counted in the code only: a comment above that
    // writes one took the error (line 1).
    let text = "// A coat written Layer(ior: 1.5) over gold.\nMaterial(\n    layers: [Layer(ior: 1.5, reflectivity: 0.5)],\n    base: Conductor(metal: \"gold\"),\n)\n";
    validate_refuses_at(
        "layer-after-comment",
        text,
        &[(
            "Layer(ior: 1.5, r",
            "layer 1 needs exactly one of `ior`, `reflectivity` or `varnish`",
        )],
    );
}

#[test]
fn a_marble_along_a_zero_direction_is_placed_at_the_field_that_holds_it() {
    // patterned sunstone's zoning and its platelets' density modulation,
    // each a marble along (0, 0, 0): both said, each at its field (they
    // were "`#inclusions-1`", placed nowhere in the file, one a run).
    let marble = "Marble(frequency: 3.0, amplitude: 1.0, direction: (0.0, 0.0, 0.0), octaves: 2, turbulence_frequency: 1.0)";
    let text = include_str!("../gem-recipes/patterned-sunstone.ron")
        .replacen(
            "function: Perlin(frequency: 1.8),",
            &format!("function: {marble},"),
            1,
        )
        .replacen(
            "density_modulation: Some(Perlin(frequency: 3.0)),",
            &format!("density_modulation: Some({marble}),"),
            1,
        );
    validate_refuses_at(
        "zero-marble",
        &text,
        &[
            (
                "zoning:",
                "marble `direction` of the `zoning` function is (0, 0, 0)",
            ),
            (
                "density_modulation:",
                "inclusions 1: marble `direction` of `density_modulation` is (0, 0, 0)",
            ),
        ],
    );
}

#[test]
fn every_value_out_of_range_is_reported_at_its_place() {
    // Each refused value is placed where RON places the first: the parse
    // runs again past the ones found so far. The place is `at` bytes into
    // what is written (RON places a tuple's error at its closing bracket).
    let place = |text: &str, path: &Path, written: &str, at: usize| {
        place_of(path, text, text.find(written).expect("written") + at)
    };
    let dir = scratch("ranges");
    let gem = GOOD_GEM.replacen("ior: 1.5,", "ior: 9.5,", 1).replacen(
        "roughness_deg: 4.0",
        "roughness_deg: -4.5",
        1,
    );
    let gem_path = dir.join("gem.ron");
    std::fs::write(&gem_path, &gem).unwrap();
    let expected = [
        format!(
            "{}`ior` = 9.5 is out of range",
            place(&gem, &gem_path, "9.5", 0)
        ),
        format!(
            "{}`roughness_deg` = -4.5 is out of range",
            place(&gem, &gem_path, "-4.5", 0)
        ),
    ];
    refused_in_order(
        &lapidary(&[OsString::from("validate"), gem_path.into()]),
        &expected,
    );
    let scene = GOOD_SCENE
        .replacen("vertical_fov_deg: 25.0", "vertical_fov_deg: 250.0", 1)
        .replacen("position: (0.0, 0.0, 0.5)", "position: (0.0, 0.0, 7e5)", 1);
    let scene_path = dir.join("scene.ron");
    std::fs::write(&scene_path, &scene).unwrap();
    let expected = [
        format!(
            "{}`vertical_fov_deg` = 250 is out of range",
            place(&scene, &scene_path, "250.0", 0)
        ),
        format!(
            "{}`position` = (0, 0, 700000) is out of range",
            place(&scene, &scene_path, "7e5)", 3)
        ),
    ];
    refused_in_order(
        &lapidary(&[OsString::from("validate"), scene_path.into()]),
        &expected,
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_unknown_name_of_a_recipe_is_reported_at_once() {
    // Three typos: a map entry's material, a switch range's map and the
    // glitter's material; each named at its place, in the file's order,
    // by `validate` and by `render` alike.
    let text = GOOD_GEM
        .replacen(
            "(material: \"lilac\", weight: 2.0),",
            "(material: \"lilak\", weight: 2.0),",
            1,
        )
        .replacen("map: \"tiles\"),", "map: \"tils\"),", 1)
        .replacen(
            "entries: [(material: \"foil\")],",
            "entries: [(material: \"foyl\")],",
            1,
        );
    let dir = scratch("three-typos");
    let path = dir.join("typos.ron");
    std::fs::write(&path, &text).unwrap();
    let place = |written: &str| place_of(&path, &text, text.find(written).expect("written"));
    let expected = [
        format!("{}unknown material `lilak`", place("\"lilak\"")),
        format!("{}unknown map `tils`", place("\"tils\"")),
        format!("{}unknown material `foyl`", place("\"foyl\"")),
    ];
    let render = lapidary(&[
        OsString::from("render"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
        "-o".into(),
        dir.join("gem.png").into(),
    ]);
    for out in [lapidary(&[OsString::from("validate"), path.into()]), render] {
        refused_in_order(&out, &expected);
    }
    assert!(!dir.join("gem.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_part_of_a_scene_is_checked_and_its_problems_reported_together() {
    // A stone naming a missing recipe, a ground of an unknown material and
    // a camera looking at itself: three problems in one run, in order.
    let text = GOOD_SCENE
        .replacen(
            "look_at: (0.0, 0.0, 1.0),",
            "look_at: (30.0, -30.0, 25.0),",
            1,
        )
        .replacen(
            STONE_SHAPE,
            &format!("            recipe: Some(\"nowhere.ron\"),\n{STONE_SHAPE}"),
            1,
        )
        .replacen(
            "    environment:",
            "    ground: Some(Ground(height: 0.0, material: \"teflom\")),\n    environment:",
            1,
        );
    let dir = scratch("scene-problems");
    let path = dir.join("problems.ron");
    std::fs::write(&path, &text).unwrap();
    let line_of = |written: &str| {
        text[..text.find(written).expect("written")]
            .matches('\n')
            .count()
            + 1
    };
    let expected = [
        format!("problems.ron:{}:", line_of("look_at: (30.0")),
        format!("problems.ron:{}:", line_of("nowhere.ron")),
        format!("problems.ron:{}:", line_of("teflom")),
    ];
    let render = lapidary(&[
        OsString::from("render"),
        "--scene".into(),
        path.clone().into(),
        "--size".into(),
        "8".into(),
        "-o".into(),
        dir.join("scene.png").into(),
    ]);
    for out in [lapidary(&[OsString::from("validate"), path.into()]), render] {
        let stderr = refused_in_order(&out, &expected);
        assert!(stderr.contains("unknown material `teflom`"), "{stderr}");
    }
    assert!(!dir.join("scene.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_unknown_surface_map() {
    bad_gem(
        "unknown-surface",
        "surface: \"veins\",",
        "surface: \"vein\",",
        "surface: \"vein\"",
        &["vein", "veins"],
    );
}

#[test]
fn an_entry_with_a_material_and_a_map() {
    bad_gem(
        "entry-both",
        "(from: 0.8, to: 1.0, material: \"foil\"),",
        "(from: 0.8, to: 1.0, material: \"foil\", map: \"tiles\"),",
        "\"veins\": Switch",
        &["an entry of `veins` needs exactly one of `material` or `map`"],
    );
}

#[test]
fn switch_ranges_with_a_gap() {
    bad_gem(
        "range-gap",
        "(from: 0.8, to: 1.0, material: \"foil\"),",
        "(from: 0.85, to: 1.0, material: \"foil\"),",
        "\"veins\": Switch",
        &["veins", "0.8"],
    );
}

#[test]
fn a_layer_with_two_iors() {
    bad_gem(
        "two-iors",
        "Layer(ior: 1.5,",
        "Layer(ior: 1.5, reflectivity: 0.3,",
        "reflectivity: 0.3",
        &["exactly one of `ior`, `reflectivity` or `varnish`"],
    );
}

#[test]
fn a_layer_with_two_iors_after_a_raw_string_with_a_quote() {
    // The raw string's quote and bracket must not hide where the
    // material is defined.
    bad_gem(
        "two-iors-raw",
        "    seed: 3,\n    materials: {\n        \"lilac\": Material(\n            layers: [\n                Layer(ior: 1.5,",
        "    seed: 3,\n    description: r#\"a 6\" (stone\"#,\n    materials: {\n        \"lilac\": Material(\n            layers: [\n                Layer(ior: 1.5, reflectivity: 0.3,",
        "reflectivity: 0.3",
        &["exactly one of `ior`, `reflectivity` or `varnish`"],
    );
}

#[test]
fn an_unknown_metal() {
    bad_gem(
        "unknown-metal",
        "metal: \"silver\"",
        "metal: \"platinum\"",
        "platinum",
        &["platinum", "silver"],
    );
}

#[test]
fn a_truncated_file() {
    // Cut in the middle of the maps: the file ends inside a list.
    let cut = GOOD_GEM.find("(from: 0.8").unwrap();
    let text = GOOD_GEM[..cut].trim_end();
    let dir = scratch("truncated");
    let path = dir.join("truncated.ron");
    std::fs::write(&path, text).unwrap();
    let line = text.lines().count();
    let needles = [
        format!("{}:{line}:", path.display()),
        "the file ends here".to_string(),
    ];
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused("truncated", &out, &needles);
    let render = [
        OsString::from("render"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing("truncated", &render, "gem.png", &needles);
    // Cut after a closing bracket, with no final newline: RON places the
    // error on the last character, and the message still says where the
    // file ends (the column after it).
    let text = &GOOD_GEM[..GOOD_GEM.rfind("))").unwrap() + 2];
    std::fs::write(&path, text).unwrap();
    let last = text.lines().last().unwrap().chars().count();
    let needles = [
        format!("{}:{}:{}: ", path.display(), text.lines().count(), last + 1),
        "the file ends here".to_string(),
    ];
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused("truncated after a bracket", &out, &needles);
    // One closing bracket too many at the end.
    std::fs::write(&path, format!("{GOOD_GEM})")).unwrap();
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused(
        "one bracket too many",
        &out,
        &["after the end of the recipe (is a closing bracket before it one too many?)".into()],
    );
}

#[test]
fn a_file_of_another_kind() {
    // A scene given where a gem belongs, a material where a scene belongs,
    // a gem where a material belongs: each says what it is, what was
    // expected and how that kind of file is used.
    let (_dir, gem, material, scene) = good_files("other-kind");
    let at = |path: &Path| format!("{}:1:", path.display());
    let render_gem = [
        OsString::from("render"),
        scene.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing(
        "scene-as-gem",
        &render_gem,
        "gem.png",
        &[
            at(&scene),
            "this is a scene (`Scene(…)`) where a gem recipe (`Gem(…)`) was expected".into(),
            "lapidary render --scene FILE".into(),
        ],
    );
    let render_scene = [
        OsString::from("render"),
        "--scene".into(),
        material.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing(
        "material-as-scene",
        &render_scene,
        "scene.png",
        &[
            at(&material),
            "this is a material (`Material(…)`) where a scene (`Scene(…)`) was expected".into(),
            "lapidary brdf FILE".into(),
        ],
    );
    let out = lapidary(&[
        OsString::from("brdf"),
        gem.clone().into(),
        "--albedo".into(),
    ]);
    assert_refused(
        "gem-as-material",
        &out,
        &[
            at(&gem),
            "this is a gem recipe (`Gem(…)`) where a material (`Material(…)`) was expected".into(),
            "lapidary render FILE".into(),
        ],
    );
}

// ---- files that are not recipes ------------------------------------------

#[test]
fn a_file_of_another_kind_and_an_output_without_a_name() {
    // Markdown starts with `#`, which RON reads as an attribute.
    // (`validate` tells the kinds apart before parsing; `render` parses.)
    let readme = concat!(env!("CARGO_MANIFEST_DIR"), "/README.md");
    let render = os(&["render", readme, "--size", "8", "--spp", "1"]);
    assert_refused_writing(
        "markdown",
        &render,
        "gem.png",
        &["is this a RON file?".to_string()],
    );
    let render = os(&["render", "--size", "8", "--spp", "1"]);
    assert_refused_writing(
        "nameless",
        &render,
        ".png",
        &["after a name (`gem.png`)".to_string()],
    );
}

#[test]
fn a_byte_order_mark_is_read_past() {
    // Some editors start a UTF-8 file with U+FEFF; it is not RON.
    let dir = scratch("bom");
    let path = dir.join("bom.ron");
    std::fs::write(&path, format!("\u{feff}{GOOD_MATERIAL}")).unwrap();
    let out = lapidary(&[OsString::from("validate"), path.into()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn an_invisible_character_pasted_into_a_recipe_is_named_at_its_place() {
    // A zero-width space inside a field name (RON reads `rough` and stops)
    // and a no-break space before a colon: each named at line 5.
    for (name, bad, found) in [
        (
            "zero-width",
            "rough\u{200b}ness_deg: 3.0",
            "line 5 holds a zero-width space (U+200B) at column 18",
        ),
        (
            "no-break",
            "roughness_deg\u{a0}: 3.0",
            "line 5 holds a no-break space (U+00A0) at column 26",
        ),
        (
            "nul",
            "roughness_deg:\0 3.0",
            "line 5 holds a NUL byte (U+0000) at column 27",
        ),
    ] {
        let dir = scratch(name);
        let path = dir.join("pasted.ron");
        std::fs::write(&path, GOOD_MATERIAL.replace("roughness_deg: 3.0", bad)).unwrap();
        let out = lapidary(&[OsString::from("validate"), path.into()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("pasted.ron:5:"), "{stderr}");
        assert!(stderr.contains(found), "{stderr}");
    }
}

#[test]
fn a_control_character_in_a_name_is_written_as_its_escape() {
    // A NUL inside a quoted name reaches the message through the name: it
    // is shown as `\u{0}`, not sent to the terminal.
    let dir = scratch("nul-name");
    let path = dir.join("nul.ron");
    let text = GOOD_SCENE.replacen(
        "environment: Constant(radiance: (0.5, 0.5, 0.5))",
        "environment: File(path: \"sky\0.exr\")",
        1,
    );
    assert_ne!(text, GOOD_SCENE);
    std::fs::write(&path, text).unwrap();
    let out = lapidary(&[OsString::from("validate"), path.into()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(!stderr.contains('\0'), "{stderr:?}");
    assert!(stderr.contains("sky\\u{0}.exr"), "{stderr}");
}

#[test]
fn an_image_or_utf_16_file_given_as_a_recipe_is_named_for_what_it_is() {
    let dir = scratch("other-kinds");
    for (name, bytes, says) in [
        (
            "sky.hdr",
            &b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n\x80\x80\x80\x81"[..],
            "this is a Radiance HDR image, not a .ron recipe",
        ),
        ("shot.png", &b"\x89PNG\r\n\x1a\n"[..], "this is a PNG image"),
        (
            "wide.ron",
            &b"\xff\xfeG\x00e\x00m\x00(\x00"[..],
            "this is UTF-16 text",
        ),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let out = lapidary(&[OsString::from("validate"), path.into()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says), "{stderr}");
    }
}

#[test]
fn a_batch_job_given_as_a_material_says_how_to_run_it() {
    let dir = scratch("job-as-material");
    let path = dir.join("job.ron");
    std::fs::write(&path, r#"Job(output: "out", recipes: ["sunstone"])"#).unwrap();
    let out = lapidary(&[OsString::from("classify"), path.into()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("this is a batch job (`Job(…)`) where a material (`Material(…)`) was expected; list its tasks with `lapidary batch FILE`"),
        "{stderr}"
    );
}

#[test]
fn a_path_written_with_backslashes_gets_a_hint() {
    for args in [
        &["render", "gems\\mine.ron", "-o", "x.png"][..],
        &["render", "--scene", "scenes\\mine.ron", "-o", "x.png"][..],
        &["validate", "gems\\mine"][..],
    ] {
        let out = lapidary(args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("(write `/` between folders, not `\\`)"),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn a_negative_or_exponent_seed_says_what_a_whole_number_is() {
    // Placed at the sign, where the number starts (RON places it after).
    bad_scene_reference(
        "negative-seed",
        "position: (0.0, 0.0, 0.5),",
        "position: (0.0, 0.0, 0.5),\n            seed: Some(-1),",
        "-1),",
        &["`seed` = -1 is out of range; allowed: a whole number from 0 to 18446744073709551615"],
    );
    bad_scene(
        "exponent-seed",
        "position: (0.0, 0.0, 0.5),",
        "position: (0.0, 0.0, 0.5),\n            seed: Some(1e20),",
        "seed: Some(1e20)",
        &["allowed: a whole number written in digits only"],
    );
}

#[test]
fn a_fraction_where_a_whole_number_belongs() {
    bad_scene(
        "fraction-frames",
        "environment: Constant",
        "turntable: Some(Turntable(frames: 4.5)),\n    environment: Constant",
        "frames: 4.5",
        &[
            "field `frames`",
            "a whole number such as 4, without a fraction",
        ],
    );
}

#[test]
fn non_utf8_bytes() {
    let dir = scratch("non-utf8");
    let path = dir.join("latin1.ron");
    // "Gem(name: "Grüner")" written in Latin-1 by an old editor.
    let mut bytes = b"Gem(name: \"Gr".to_vec();
    bytes.push(0xfc);
    bytes.extend_from_slice(b"ner\", surface: \"gold\")\n");
    std::fs::write(&path, &bytes).unwrap();
    // Placed at the byte, as line:col (`Gr` ends at column 14).
    let needles = [format!(
        "{}:1:14: not UTF-8 text: byte 0xfc",
        path.display()
    )];
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused("non-utf8", &out, &needles);
    let render = [
        OsString::from("render"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing("non-utf8", &render, "gem.png", &needles);
    let maps = [
        OsString::from("maps"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing("non-utf8-maps", &maps, "maps.png", &needles);
}

#[test]
fn a_directory_instead_of_a_file() {
    let dir = scratch("directory");
    let recipe = dir.join("recipes.ron");
    std::fs::create_dir_all(&recipe).unwrap();
    let needles = [recipe.display().to_string(), "directory".to_string()];
    let out = lapidary(&[OsString::from("validate"), recipe.clone().into()]);
    assert_refused("directory", &out, &needles);
    let render = [
        OsString::from("render"),
        recipe.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing("directory", &render, "gem.png", &needles);
    let maps = [
        OsString::from("maps"),
        recipe.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing("directory-maps", &maps, "maps.png", &needles);
    let out = lapidary(&[OsString::from("brdf"), recipe.into(), "--albedo".into()]);
    assert_refused("directory-brdf", &out, &needles);
}

/// Runs lapidary, failing the test (not hanging it) when the command is
/// still running after 60 s.
fn lapidary_within_a_minute(args: &[OsString]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("binary runs");
    let started = std::time::Instant::now();
    while child.try_wait().expect("waits").is_none() {
        if started.elapsed() > std::time::Duration::from_secs(60) {
            let _ = child.kill();
            panic!("lapidary {args:?} still runs after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().expect("output")
}

#[cfg(unix)]
#[test]
fn a_pipe_or_a_device_instead_of_a_file_is_refused_without_waiting() {
    let dir = scratch("pipe");
    let made = |name: &str| {
        let path = dir.join(name);
        let status = Command::new("mkfifo")
            .arg(&path)
            .status()
            .expect("mkfifo runs");
        assert!(status.success(), "mkfifo {}", path.display());
        path
    };
    let (recipe, map, tile) = (made("gem.ron"), made("sky.exr"), made("tile.exr"));
    let small = ["--size", "8", "--spp", "1"].map(OsString::from);
    let render = |extra: &[OsString]| {
        let mut args = vec![OsString::from("render")];
        args.extend_from_slice(extra);
        args.extend_from_slice(&small);
        args
    };
    let cases: [(&str, Vec<OsString>, String); 6] = [
        (
            "validate",
            vec!["validate".into(), recipe.clone().into()],
            format!("{}: is a pipe, expected a .ron", recipe.display()),
        ),
        (
            "render",
            render(&[recipe.clone().into()]),
            format!(
                "{}: is a pipe, expected a .ron gem recipe",
                recipe.display()
            ),
        ),
        (
            "scene",
            render(&["--scene".into(), recipe.clone().into()]),
            format!("{}: is a pipe", recipe.display()),
        ),
        (
            "device",
            render(&["--scene".into(), "/dev/zero".into()]),
            "/dev/zero: is a device".to_string(),
        ),
        (
            "map",
            render(&["--env".into(), map.clone().into()]),
            format!("{}: is a pipe", map.display()),
        ),
        (
            "merge",
            vec![
                "merge".into(),
                tile.clone().into(),
                "-o".into(),
                dir.join("m.png").into(),
            ],
            format!("{}: is a pipe, not a tile file", tile.display()),
        ),
    ];
    for (case, mut args, needle) in cases {
        if args[0] == "render" {
            args.extend(["-o".into(), dir.join(format!("{case}.png")).into()]);
        }
        let out = lapidary_within_a_minute(&args);
        assert_refused(case, &out, &[needle]);
    }
    assert_eq!(files_in(&dir), ["gem.ron", "sky.exr", "tile.exr"]);
}

#[test]
fn a_recipe_file_larger_than_any_recipe_is_refused_unread() {
    let dir = scratch("huge");
    let recipe = dir.join("huge.ron");
    let mut text = GOOD_GEM.to_string();
    text.push_str(&" ".repeat(17 << 20));
    std::fs::write(&recipe, text).unwrap();
    let out = lapidary(&[OsString::from("validate"), recipe.clone().into()]);
    assert_refused(
        "huge",
        &out,
        &[format!(
            "{}: is larger than 16 MiB; allowed: a .ron recipe (gem, material, scene or job) of at most 16 MiB",
            recipe.display()
        )],
    );
}

#[test]
fn a_missing_recipe_file() {
    let dir = scratch("missing");
    let path = dir.join("no-such-gem.ron");
    let needles = [path.display().to_string(), "cannot read".to_string()];
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused("missing", &out, &needles);
    let render = [
        OsString::from("render"),
        path.into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing("missing", &render, "gem.png", &needles);
}

#[test]
fn an_empty_file() {
    let dir = scratch("empty");
    let path = dir.join("empty.ron");
    std::fs::write(&path, "").unwrap();
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused(
        "empty",
        &out,
        &[format!("{}: the file is empty", path.display())],
    );
    let render = [
        OsString::from("render"),
        path.clone().into(),
        "--size".into(),
        "8".into(),
    ];
    assert_refused_writing(
        "empty",
        &render,
        "gem.png",
        &[format!(
            "{}: the file is empty; expected a .ron gem recipe",
            path.display()
        )],
    );
}

#[test]
fn a_misspelt_builtin_gem() {
    let render = os(&["render", "green-aventurin", "--size", "8", "--spp", "1"]);
    assert_refused_writing(
        "misspelt-gem",
        &render,
        "gem.png",
        &[
            "green-aventurin".to_string(),
            "green-aventurine".to_string(),
        ],
    );
}

// ---- material files and `brdf` ---------------------------------------------

/// A material made from [`GOOD_MATERIAL`] by replacing `from` with `to`,
/// through `validate`, `brdf --albedo` and `brdf -o`.
fn bad_material(case: &str, from: &str, to: &str, marker: &str, needles: &[&str]) {
    assert!(
        GOOD_MATERIAL.contains(from),
        "{case}: `{from}` not in GOOD_MATERIAL"
    );
    let text = GOOD_MATERIAL.replacen(from, to, 1);
    let dir = scratch(case);
    let path = dir.join(format!("{case}.ron"));
    std::fs::write(&path, &text).unwrap();
    let mut expected = vec![at_line(&path, &text, marker)];
    expected.extend(needles.iter().map(|s| s.to_string()));
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused(case, &out, &expected);
    let out = lapidary(&[
        OsString::from("brdf"),
        path.clone().into(),
        "--albedo".into(),
    ]);
    assert_refused(case, &out, &expected);
    assert!(out.stdout.is_empty(), "{case}: brdf printed a table");
    let plot = [OsString::from("brdf"), path.into()];
    assert_refused_writing(case, &plot, "plot.png", &expected);
}

#[test]
fn material_with_a_misspelt_field() {
    bad_material(
        "material-typo",
        "absorption:",
        "absorbtion:",
        "absorbtion",
        &["unknown field `absorbtion`", "absorption"],
    );
}

#[test]
fn material_with_ior_below_one() {
    bad_material(
        "material-ior",
        "ior: 1.5,",
        "ior: 0.5,",
        "ior: 0.5",
        &["ior", "0.5", "1 <= ior <= 5"],
    );
}

#[test]
fn material_with_a_boolean_written_as_a_word() {
    bad_material(
        "material-bool",
        "multiple_scattering: false,",
        "multiple_scattering: no,",
        "multiple_scattering: no",
        &["multiple_scattering"],
    );
}

#[test]
fn unknown_names_and_names_of_the_other_kind() {
    let out = lapidary(&os(&["brdf", "golld", "--albedo"]));
    assert_refused(
        "brdf-unknown",
        &out,
        &["golld".to_string(), "gold".to_string()],
    );
    // A material's name where a gem belongs, and a gem's where a material
    // belongs: what each is and which command takes it.
    let out = lapidary(&os(&["render", "brass", "-o", "/nonexistent/x.png"]));
    assert_refused(
        "render-a-material",
        &out,
        &["`brass` is a built-in material, not a gem: `lapidary brdf brass` shows it".to_string()],
    );
    for args in [
        &["brdf", "goldstone", "--albedo"][..],
        &["classify", "goldstone"],
    ] {
        let out = lapidary(&os(args));
        assert_refused(
            "brdf-of-a-gem",
            &out,
            &["`goldstone` is a built-in gem, not a material: `lapidary render goldstone` renders it"
                .to_string()],
        );
    }
}

// ---- scenes -------------------------------------------------------------------

/// A scene made from [`GOOD_SCENE`] by replacing `from` with `to`, through
/// `validate` and `render --scene`.
fn bad_scene(case: &str, from: &str, to: &str, marker: &str, needles: &[&str]) {
    assert!(
        GOOD_SCENE.contains(from),
        "{case}: `{from}` not in GOOD_SCENE"
    );
    let text = GOOD_SCENE.replacen(from, to, 1);
    let dir = scratch(case);
    let path = dir.join(format!("{case}.ron"));
    std::fs::write(&path, &text).unwrap();
    let mut expected = vec![at_line(&path, &text, marker)];
    expected.extend(needles.iter().map(|s| s.to_string()));
    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused(case, &out, &expected);
    let render = [
        OsString::from("render"),
        "--scene".into(),
        path.into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
    ];
    assert_refused_writing(case, &render, "scene.png", &expected);
}

#[test]
fn a_stone_too_high_names_its_dome() {
    bad_scene(
        "stone-too-high",
        "width: 8.0,",
        "width: 8.0,\n                dome_height: 1e300,",
        "dome_height: 1e300",
        &["`dome_height` = 1e300 is out of range", "at most 100000 mm"],
    );
}

#[test]
fn a_value_where_an_option_belongs_says_what_to_write() {
    bad_scene(
        "seed-not-option",
        "position: (0.0, 0.0, 0.5),",
        "position: (0.0, 0.0, 0.5),\n            seed: 5,",
        "seed: 5",
        &[
            "field `seed`: Expected option",
            "`Some(…)` around the value",
        ],
    );
}

#[test]
fn scene_with_a_misspelt_field() {
    bad_scene(
        "scene-typo",
        "look_at:",
        "lookat:",
        "lookat",
        &["unknown field `lookat`", "look_at"],
    );
}

#[test]
fn scene_with_a_nan_position() {
    bad_scene(
        "scene-nan",
        "position: (0.0, 0.0, 0.5)",
        "position: (0.0, NaN, 0.5)",
        "NaN",
        &["position", "NaN"],
    );
}

#[test]
fn scene_with_a_field_of_view_of_180_degrees() {
    bad_scene(
        "scene-fov",
        "vertical_fov_deg: 25.0",
        "vertical_fov_deg: 180.0",
        "vertical_fov_deg",
        &["vertical_fov_deg", "180"],
    );
}

#[test]
fn scene_with_a_stone_a_light_year_away() {
    // Beyond f32: the BVH build over the stones used to panic in obvhs.
    bad_scene(
        "scene-far-stone",
        "position: (0.0, 0.0, 0.5)",
        "position: (1e300, 0.0, 0.5)",
        "1e300",
        &["`position`", "within ±100000"],
    );
}

#[test]
fn scene_with_a_stone_of_astronomical_size() {
    bad_scene(
        "scene-huge-stone",
        "length: 10.0",
        "length: 1e300",
        "length: 1e300",
        &[
            "stone 1",
            "`length` = 1e300 is out of range",
            "at most 100000 mm",
        ],
    );
}

#[test]
fn scene_with_a_point_sized_sphere_light() {
    // A sphere light of radius 1e-300 made every sample NaN (its cone pdf
    // overflowed) and the picture black.
    bad_scene(
        "scene-tiny-light",
        "    environment:",
        "    lights: [Sphere(centre: (0.0, 0.0, 20.0), radius: 1e-300, radiance: (1.0, 1.0, 1.0))],\n    environment:",
        "radius: 1e-300",
        &["`radius`", "from 0.01"],
    );
}

#[test]
fn scene_with_a_sun_of_zero_size() {
    bad_scene(
        "scene-point-sun",
        "    environment:",
        "    lights: [Sun(elevation_deg: 45.0, azimuth_deg: 0.0, angular_diameter_deg: 0.0, irradiance: (1.0, 1.0, 1.0))],\n    environment:",
        "angular_diameter_deg: 0.0",
        &["`angular_diameter_deg`", "at least 0.01"],
    );
}

#[test]
fn scene_with_an_empty_stone_list() {
    let from = GOOD_SCENE
        .split("stones: [")
        .nth(1)
        .and_then(|s| s.split("\n    ],").next())
        .unwrap();
    bad_scene("scene-no-stones", from, "", "stones: [", &["stones"]);
}

#[test]
fn scene_with_more_lights_than_allowed() {
    let lights: Vec<String> = (0..1025)
        .map(|k| format!("Point(position: ({k}.0, 0.0, 30.0), intensity: (1.0, 1.0, 1.0))"))
        .collect();
    bad_scene(
        "scene-lights",
        "    environment:",
        &format!(
            "    lights: [\n        {}\n    ],\n    environment:",
            lights.join(",\n        ")
        ),
        "lights: [",
        &["`lights` has 1025 lights; allowed: 0 to 1024 lights"],
    );
}

/// A scene made from [`GOOD_SCENE`] by replacing `from` with `to`, naming
/// something that does not resolve: the string `written` (with its quotes,
/// first occurrence). `validate` and `render --scene` must both refuse it
/// with `scene:LINE:COL: ` at that string, on stderr, then every needle,
/// and `render` must write no picture.
fn bad_scene_reference(case: &str, from: &str, to: &str, written: &str, needles: &[&str]) {
    assert!(
        GOOD_SCENE.contains(from),
        "{case}: `{from}` not in GOOD_SCENE"
    );
    let text = GOOD_SCENE.replacen(from, to, 1);
    let dir = scratch(case);
    let path = dir.join(format!("{case}.ron"));
    std::fs::write(&path, &text).unwrap();
    let place = place_of(
        &path,
        &text,
        text.find(written).expect("the name is written"),
    );
    let mut expected = vec![place.clone()];
    expected.extend(
        needles
            .iter()
            .map(|s| s.replace("{dir}", dir.to_str().unwrap())),
    );

    let out = lapidary(&[OsString::from("validate"), path.clone().into()]);
    assert_refused(case, &out, &expected);
    let render = [
        OsString::from("render"),
        "--scene".into(),
        path.clone().into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
    ];
    // On stderr, as one message: the place, then what is wrong.
    let picture = dir.join("direct.png");
    let mut args = render.to_vec();
    args.extend(["-o".into(), picture.clone().into()]);
    let out = lapidary(&args);
    assert_eq!(out.status.code(), Some(1), "{case}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let message = stderr
        .lines()
        .find(|l| l.contains(&place))
        .unwrap_or_else(|| panic!("{case}: no `{place}` on stderr:\n{stderr}"));
    for needle in &expected[1..] {
        assert!(
            message.contains(needle.as_str()),
            "{case}: `{needle}` missing: {message}"
        );
    }
    assert!(!picture.exists(), "{case}: a picture was written");
    assert_refused_writing(case, &render, "scene.png", &expected);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Where [`GOOD_SCENE`]'s stone gets a `recipe:` line.
const STONE_SHAPE: &str = "            shape: Cabochon(";

#[test]
fn scene_naming_an_unknown_gem() {
    bad_scene_reference(
        "scene-unknown-gem",
        STONE_SHAPE,
        "            recipe: Some(\"goldston\"),\n            shape: Cabochon(",
        "\"goldston\"",
        &[
            "stone 1: unknown gem `goldston` (did you mean `goldstone`?)",
            "allowed: a built-in gem name (",
        ],
    );
}

#[test]
fn scene_naming_a_missing_gem_file() {
    bad_scene_reference(
        "scene-missing-gem",
        STONE_SHAPE,
        "            recipe: Some(\"gems/opal.ron\"),\n            shape: Cabochon(",
        "\"gems/opal.ron\"",
        &["stone 1: gem file `gems/opal.ron` not found at {dir}/gems/opal.ron"],
    );
}

#[test]
fn scene_naming_an_unknown_ground_material() {
    bad_scene_reference(
        "scene-unknown-ground",
        "    environment:",
        "    ground: Some(Ground(height: 0.0, material: \"teflom\")),\n    environment:",
        "\"teflom\"",
        &[
            "ground: unknown material `teflom` (did you mean `teflon`?)",
            "allowed: a built-in material name (",
        ],
    );
}

#[test]
fn scene_naming_a_missing_environment_file() {
    bad_scene_reference(
        "scene-missing-env",
        "environment: Constant(radiance: (0.5, 0.5, 0.5))",
        "environment: File(path: \"nope.exr\", intensity: 1.0)",
        "\"nope.exr\"",
        &["environment: image file `nope.exr` not found at {dir}/nope.exr"],
    );
}

// ---- the command line and the output -----------------------------------------

#[test]
fn a_corrupt_environment_map() {
    let dir = scratch("corrupt-env");
    let env = dir.join("studio.hdr");
    // A Radiance header with its pixels cut off, as after a failed download.
    std::fs::write(
        &env,
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 128\n\x02\x02",
    )
    .unwrap();
    let gem = dir.join("gem.ron");
    std::fs::write(&gem, GOOD_GEM).unwrap();
    let render = [
        OsString::from("render"),
        gem.into(),
        "--env".into(),
        env.clone().into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
        "-q".into(),
    ];
    assert_refused_writing(
        "corrupt-env",
        &render,
        "gem.png",
        &[env.display().to_string(), "corrupt".to_string()],
    );
}

#[test]
fn a_grey_exr_environment_is_refused_for_its_channels_not_as_corrupt() {
    use exr::prelude::*;
    let dir = scratch("grey-env");
    let env = dir.join("grey.exr");
    let luminance = AnyChannel::new("Y", FlatSamples::F32(vec![0.5; 8 * 4]));
    let layer = Layer::new(
        (8, 4),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(vec![luminance].into()),
    );
    Image::from_layer(layer).write().to_file(&env).unwrap();
    let render = [
        OsString::from("render"),
        "--env".into(),
        env.clone().into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
        "-q".into(),
    ];
    assert_refused_writing(
        "grey-env",
        &render,
        "gem.png",
        &[
            env.display().to_string(),
            "no layer has R, G and B channels (its channels: Y)".to_string(),
        ],
    );
}

#[test]
fn validate_reads_a_scene_s_environment_map() {
    // `validate` (and with it a batch job's check) reads the map as the
    // render would: a damaged one is refused there, at its `path`, not by
    // every task of a farm array.
    let dir = scratch("validate-env");
    std::fs::write(
        dir.join("sky.hdr"),
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 64 +X 128\n\x02\x02",
    )
    .unwrap();
    let text = GOOD_SCENE.replace(
        "environment: Constant(radiance: (0.5, 0.5, 0.5)),",
        "environment: File(path: \"sky.hdr\"),",
    );
    let scene = dir.join("scene.ron");
    std::fs::write(&scene, &text).unwrap();
    let out = lapidary(&[OsString::from("validate"), scene.clone().into()]);
    let expected = [
        at_line(&scene, &text, "sky.hdr"),
        "environment map".to_string(),
        "scanline 1 of 64: the file ends early".to_string(),
    ];
    assert_refused("validate-env", &out, &expected);
    // The render names the same place in the scene.
    let render = [
        OsString::from("render"),
        "--scene".into(),
        scene.into(),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
    ];
    assert_refused_writing("render-env", &render, "sky.png", &expected);
}

#[test]
fn a_map_that_is_not_twice_as_wide_as_high_is_warned_of() {
    // An equirectangular map is 2:1; a square one (a cropped photo, a
    // mirror ball) renders, stretched, with a warning from `validate` and
    // `render` alike. A 2:1 map has none.
    let dir = scratch("env-proportion");
    let grey = |_: usize, _: usize| [0.5f32; 3];
    common::maps::write_hdr(&dir.join("square.hdr"), 8, 8, grey);
    common::maps::write_hdr(&dir.join("wide.hdr"), 16, 8, grey);
    for (map, warned) in [("square.hdr", true), ("wide.hdr", false)] {
        let scene = dir.join(format!("{map}.ron"));
        let text = GOOD_SCENE.replace(
            "environment: Constant(radiance: (0.5, 0.5, 0.5)),",
            &format!("environment: File(path: \"{map}\"),"),
        );
        std::fs::write(&scene, text).unwrap();
        let validate = lapidary(&[OsString::from("validate"), scene.clone().into()]);
        let out = dir.join("out.png");
        let render = lapidary(&[
            OsString::from("render"),
            "--scene".into(),
            scene.into(),
            "--size".into(),
            "8".into(),
            "--spp".into(),
            "1".into(),
            "-q".into(),
            "-o".into(),
            out.into(),
        ]);
        for run in [validate, render] {
            let stderr = String::from_utf8_lossy(&run.stderr);
            assert!(run.status.success(), "{map}: {stderr}");
            // `validate` names the map as written, `render` as resolved.
            let warning = format!("{map}: it is 8×8 texels, not twice as wide as high");
            assert_eq!(stderr.contains(&warning), warned, "{map}: {stderr}");
            assert_eq!(stderr.contains("warning"), warned, "{map}: {stderr}");
        }
    }
}

#[test]
fn a_missing_environment_map_names_the_flag_and_what_it_takes() {
    // `--env studio` (the built-in scene's light is called so) is not a
    // file: the message says what --env takes and where the studio is.
    let render = os(&[
        "render", "--env", "studio", "--size", "8", "--spp", "1", "-q",
    ]);
    assert_refused_writing(
        "missing-env",
        &render,
        "gem.png",
        &[
            "--env studio: no such file".to_string(),
            ".hdr or .exr".to_string(),
            "leave --env out".to_string(),
        ],
    );
}

#[test]
fn negative_and_overflowing_counts_get_the_flag_s_range() {
    // `--spp -1` reached clap as a stray argument ("tip: use '-- -1'"), and
    // `--frames=4294967296` was said to be outside `0..=4294967295`: each
    // now names its flag and its own range, written either way (exit 2,
    // usage); a count in range of its type but not of the flag stays
    // exit 1, as do negative distances.
    let usage: [(&[&str], &str); 9] = [
        (
            &["render", "--spp", "-1"],
            "'--spp <N>': allowed 1 to 1048576",
        ),
        (&["render", "--spp=-1"], "'--spp <N>': allowed 1 to 1048576"),
        (
            &["render", "--size", "-1"],
            "'--size <N>': allowed 1 to 32768",
        ),
        (
            &["render", "--frames=4294967296"],
            "'--frames <N>': allowed 1 to 3600",
        ),
        (
            &["render", "--bounces", "1.5"],
            "'--bounces <N>': not a whole number; allowed 0 to 64",
        ),
        (
            &["gallery", "--threads", "-2"],
            "'--threads <N>': allowed 1 to 1024",
        ),
        // Decimal flags: text that is no number gets the flag's range too.
        (
            &["render", "--exposure", "abc"],
            "'--exposure <EV>': not a number; allowed −64 to 64 stops",
        ),
        (
            &["render", "--ao", "1,5"],
            "'--ao <DIST>': not a number; allowed a positive distance in mm, at most 1e5",
        ),
        (
            &["maps", "goldstone", "--extent", "x"],
            "'--extent <E>': not a number; allowed above 0 up to 1000 texture units",
        ),
    ];
    let dir = scratch("negative-counts");
    let out = dir.join("x.png");
    for (args, expected) in usage {
        let mut all = os(args);
        all.extend([OsString::from("-o"), out.clone().into()]);
        let run = lapidary(&all);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        assert!(!stderr.contains("tip:"), "{args:?}: {stderr}");
    }
    for args in [["render", "--ao", "-1"], ["render", "--max-memory", "-1"]] {
        let mut all = os(&args);
        all.extend([OsString::from("-o"), out.clone().into()]);
        let run = lapidary(&all);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&format!("{} -1: must be a positive", args[1])),
            "{stderr}"
        );
    }
    // A huge number is repeated as typed, not as its 309 digits.
    for (args, expected) in [
        (
            &["render", "--exposure", "-1e308"][..],
            "--exposure -1e308: allowed",
        ),
        (&["render", "--ao", "1e300"][..], "--ao 1e300: must be"),
        (
            &["maps", "gold", "--extent", "1e300"][..],
            "--extent 1e300: allowed",
        ),
    ] {
        let mut all = os(args);
        all.extend([OsString::from("-o"), out.clone().into()]);
        let run = lapidary(&all);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
    }
    assert!(files_in(&dir).is_empty());
}

#[test]
fn an_image_of_a_million_by_a_million_pixels() {
    let render = os(&[
        "render", "--width", "1000000", "--height", "1000000", "--spp", "1",
    ]);
    assert_refused_writing(
        "huge",
        &render,
        "huge.png",
        &["--width 1000000".to_string(), "32768".to_string()],
    );
}

#[test]
fn a_misspelt_built_in_scene_has_a_suggestion() {
    let render = os(&["render", "--scene", "studo", "--size", "8", "--spp", "1"]);
    assert_refused_writing(
        "scene-typo-name",
        &render,
        "gem.png",
        &["--scene studo: no such file (did you mean `studio`, the built-in scene?)".to_string()],
    );
}

#[test]
fn a_gem_file_of_the_folder_named_without_its_extension_is_suggested() {
    // `render malachit` in a folder holding malachite.ron listed the
    // built-in gems only.
    let dir = scratch("gem-file-here");
    let text = lapidary::GemSource::load("sunstone").unwrap().text;
    std::fs::write(dir.join("malachite.ron"), text).unwrap();
    for typed in ["malachit", "malachite"] {
        let out = Command::new(env!("CARGO_BIN_EXE_lapidary"))
            .args(["render", typed, "--size", "8", "--spp", "1", "-o", "x.png"])
            .current_dir(&*dir)
            .output()
            .expect("binary runs");
        assert_refused(
            "gem-file-here",
            &out,
            &["(did you mean `malachite.ron`, a file here?)".to_string()],
        );
    }
    assert!(!dir.join("x.png").exists());
}

#[test]
fn a_size_beyond_32_bits_gets_the_same_range_message() {
    let render = os(&["render", "--size", "99999999999", "--spp", "1"]);
    assert_refused_writing(
        "size-u64",
        &render,
        "huge.png",
        &["--size 99999999999: allowed 1 to 32768 pixels".to_string()],
    );
}

#[test]
fn an_image_over_the_memory_limit() {
    // 20 000² pixels is a legal size, but its film alone is far above 1 GiB:
    // the refusal must come before anything is allocated, with the number.
    let render = os(&[
        "render",
        "--size",
        "20000",
        "--spp",
        "1",
        "--max-memory",
        "1",
    ]);
    assert_refused_writing(
        "memory",
        &render,
        "big.exr",
        &["GiB".to_string(), "--max-memory".to_string()],
    );
}

#[test]
fn a_render_beyond_the_address_space_limit_is_refused_up_front() {
    // Under `ulimit -v` (1 GB here) the film of a 4000² render (2 GB) could
    // not be allocated: the process aborted with a backtrace midway.
    let dir = scratch("ulimit");
    let output = dir.join("big.png");
    let out = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 1000000 && exec \"$0\" render --size 4000 --spp 1 --threads 1 -q -o \"$1\"")
        .arg(env!("CARGO_BIN_EXE_lapidary"))
        .arg(&output)
        .output()
        .expect("sh runs");
    assert_refused(
        "ulimit",
        &out,
        &[
            "a 4000 × 4000 render needs 2.00 GiB".to_string(),
            "available".to_string(),
        ],
    );
    assert!(!output.exists());
}

#[test]
fn an_output_that_cannot_be_made_is_refused_before_the_render() {
    // /proc takes no new files, whoever runs this. The refusal comes before
    // the gem is compiled (it came after the render).
    let out = lapidary(&[
        "render",
        "--size",
        "8",
        "--spp",
        "1",
        "-o",
        "/proc/lapidary.png",
    ]);
    assert_refused(
        "unwritable",
        &out,
        &["/proc/lapidary.png: cannot write".to_string()],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("compiling"), "{stderr}");
    // A turntable's animated PNG at a folder's name is refused up front too.
    let dir = scratch("animation-folder");
    let folder = dir.join("spin.png");
    std::fs::create_dir(&folder).unwrap();
    let out = lapidary(&[
        "render",
        "--size",
        "8",
        "--spp",
        "1",
        "--frames",
        "2",
        "-o",
        folder.to_str().unwrap(),
    ]);
    assert_refused("animation-folder", &out, &["is a directory".to_string()]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("compiling"));
    assert_eq!(files_in(&dir), ["spin.png"], "frames were written");
    // A read-only file is kept, before any work, as it was.
    let dir = scratch("read-only-output");
    let kept = dir.join("keep.png");
    std::fs::write(&kept, b"mine").unwrap();
    let mut permissions = std::fs::metadata(&kept).unwrap().permissions();
    permissions.set_readonly(true);
    std::fs::set_permissions(&kept, permissions).unwrap();
    let out = lapidary(&[
        "render",
        "--size",
        "8",
        "--spp",
        "1",
        "-o",
        kept.to_str().unwrap(),
    ]);
    assert_refused(
        "read-only output",
        &out,
        &[format!("{}: is read-only, and is kept", kept.display())],
    );
    assert!(!String::from_utf8_lossy(&out.stderr).contains("compiling"));
    assert_eq!(std::fs::read(&kept).unwrap(), b"mine");
    assert_eq!(files_in(&dir), ["keep.png"]);
}

#[test]
fn a_tile_needs_the_memory_of_its_own_rows() {
    // The whole 20 000² film is far above 1 GiB, a tile of 2 of its 20 000
    // rows far below: the tile renders (the check once took the whole film).
    let dir = scratch("tile-memory");
    let tile = dir.join("tile.exr");
    let out = lapidary(&[
        "render",
        "--size",
        "20000",
        "--spp",
        "1",
        "--max-memory",
        "1",
        "--tile",
        "0/10000",
        "-q",
        "--scene",
        "bench/peer-scene.ron",
        "-o",
        tile.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(tile.exists());
    // Half of the film is still too much, and the message says to split more.
    let render = os(&[
        "render",
        "--size",
        "20000",
        "--spp",
        "1",
        "--max-memory",
        "1",
        "--tile",
        "0/2",
    ]);
    assert_refused_writing(
        "tile-memory",
        &render,
        "half.exr",
        &[
            "tile 0/2 of a 20000 × 20000 render".to_string(),
            "more --tile".to_string(),
        ],
    );
}

#[test]
fn zero_samples_per_pixel() {
    let render = os(&["render", "--size", "8", "--spp", "0"]);
    assert_refused_writing(
        "spp-zero",
        &render,
        "gem.png",
        &["--spp 0".to_string(), "allowed 1".to_string()],
    );
}

#[test]
fn an_output_with_an_unknown_extension() {
    let render = os(&["render", "--size", "8", "--spp", "1"]);
    assert_refused_writing(
        "jpeg",
        &render,
        "gem.jpg",
        &["gem.jpg".to_string(), ".png or .exr".to_string()],
    );
}

#[test]
fn an_output_in_a_missing_directory() {
    let dir = scratch("missing-dir");
    let output = dir.join("renders").join("gem.png");
    for args in [
        os(&["render", "--size", "8", "--spp", "1", "-q"]),
        os(&["maps", "goldstone", "--size", "8"]),
    ] {
        let mut args = args;
        args.push("-o".into());
        args.push(output.clone().into());
        let out = lapidary(&args);
        assert_refused(
            "missing-dir",
            &out,
            &[output.display().to_string(), "does not exist".to_string()],
        );
        assert!(files_in(&dir).is_empty(), "left {:?}", files_in(&dir));
    }
}

#[test]
fn an_output_that_is_a_directory() {
    let dir = scratch("output-dir");
    let output = dir.join("gem.png");
    std::fs::create_dir_all(&output).unwrap();
    let out = lapidary(&[
        OsString::from("render"),
        "--size".into(),
        "8".into(),
        "--spp".into(),
        "1".into(),
        "-o".into(),
        output.clone().into(),
    ]);
    assert_refused(
        "output-dir",
        &out,
        &[output.display().to_string(), "directory".to_string()],
    );
    assert!(files_in(&output).is_empty());
}

#[test]
fn an_output_in_a_read_only_directory() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("read-only");
    let locked = dir.join("locked");
    std::fs::create_dir_all(&locked).unwrap();
    let existing = locked.join("existing.png");
    std::fs::write(&existing, KNOWN_BYTES).unwrap();
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
    // Root ignores directory permissions: probe whether this process can
    // still create a file there, and skip only this case if so.
    let probe = locked.join("probe");
    if std::fs::write(&probe, b"x").is_ok() {
        let _ = std::fs::remove_file(&probe);
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
        eprintln!("note: running with permission to write into a 0o555 directory (root?): read-only output case skipped");
        return;
    }
    for name in ["new.png", "existing.png"] {
        let output = locked.join(name);
        let out = lapidary(&[
            OsString::from("render"),
            "--size".into(),
            "8".into(),
            "--spp".into(),
            "1".into(),
            "-q".into(),
            "-o".into(),
            output.clone().into(),
        ]);
        assert_refused(
            "read-only",
            &out,
            &[output.display().to_string(), "ermission".to_string()],
        );
        assert_eq!(files_in(&locked), ["existing.png"]);
        assert_eq!(std::fs::read(&existing).unwrap(), KNOWN_BYTES);
    }
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o755)).unwrap();
}
