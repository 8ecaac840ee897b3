//! Gem recipes (section 4.3.1): the lepidolite recipe as the notes describe
//! it, and bad recipes rejected with `file:line:col`, the field or name, and
//! the allowed values.

use glam::DVec3;
use lapidary::recipe::compile::{compile_material, MaterialSource};
use lapidary::recipe::gem::{has_conductor_base, load_gem, parse_gem};
use lapidary::recipe::material::BaseSpec;
use lapidary::texture::pattern::{Entry, Node};

const LEPIDOLITE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/gem-recipes/lavender-lepidolite.ron"
);

fn points(n: usize) -> Vec<DVec3> {
    // The library's SplitMix64: deterministic points in a cube around the origin.
    let mut rng = lapidary::sampling::Rng::new(0x2545_f491_4f6c_dd1d, 0);
    (0..n)
        .map(|_| DVec3::from_array(rng.next_3()) * 6.0 - DVec3::splat(3.0))
        .collect()
}

#[test]
fn lepidolite_matches_section_4_3_1() {
    let gem = load_gem(LEPIDOLITE).unwrap_or_else(|e| panic!("{e}"));
    let map = |name: &str| match &gem.pattern.nodes()[gem.map_index(name).unwrap() as usize] {
        Node::Map(m) => m.clone(),
        Node::Switch(_) => panic!("{name} is a switch"),
    };
    let material_of = |e: &Entry| match e {
        Entry::Material(m) => &gem.materials[*m as usize],
        Entry::Node(_) => panic!("expected a material entry"),
    };
    // Dark tiles: 9 entries, exactly one with a (silver) conductor base,
    // the other 8 Lambertian under a smooth IOR 1.56 layer in 6 colours.
    let dark = map("dark-tiles");
    assert_eq!(dark.entries.len(), 9);
    let conductors: Vec<_> = dark
        .entries
        .items()
        .iter()
        .map(material_of)
        .filter(|(_, m)| has_conductor_base(m))
        .collect();
    assert_eq!(conductors.len(), 1);
    match &conductors[0].1.base {
        BaseSpec::Conductor {
            metal,
            roughness_deg,
            ..
        } => {
            assert_eq!(metal.as_deref(), Some("silver"));
            assert_eq!(*roughness_deg, 1.0);
        }
        _ => unreachable!(),
    }
    let mut colours = Vec::new();
    for (_, m) in dark.entries.items().iter().map(material_of) {
        assert_eq!(m.layers.len(), 1);
        assert_eq!(m.layers[0].ior, Some(1.56));
        assert_eq!(m.layers[0].roughness_deg, 0.0, "smooth layer");
        if let BaseSpec::Diffuse { colour, .. } = m.base {
            if !colours.contains(&colour) {
                colours.push(colour);
            }
        }
    }
    assert_eq!(colours.len(), 6, "6 different dark colours");
    // Bright tiles: 5 colours, all brighter than every dark colour.
    let bright = map("bright-tiles");
    assert_eq!(bright.entries.len(), 5);
    let luminance = |c: [f64; 3]| c[0] + c[1] + c[2];
    let darkest_bright = bright
        .entries
        .items()
        .iter()
        .map(|e| match material_of(e).1.base {
            BaseSpec::Diffuse { colour, .. } => luminance(colour),
            _ => panic!("bright tiles are Lambertian"),
        })
        .fold(f64::INFINITY, f64::min);
    assert!(colours.iter().all(|c| luminance(*c) < darkest_bright));
    // Same size, inside a map of bigger tiles; inclusions much smaller.
    let tiles = map("tiles");
    assert_eq!(dark.voronoi.cell_size, bright.voronoi.cell_size);
    assert!(tiles.voronoi.cell_size > 2.0 * dark.voronoi.cell_size);
    assert_eq!(
        tiles.entries.items(),
        &[
            Entry::Node(gem.map_index("dark-tiles").unwrap()),
            Entry::Node(gem.map_index("bright-tiles").unwrap())
        ]
    );
    let inclusions = map("inclusions");
    assert!(inclusions.voronoi.cell_size * 4.0 < dark.voronoi.cell_size);
    // Glitter: 4 silver-base entries.
    let glitter = gem.pattern.glitter().expect("a glitter map");
    assert_eq!(glitter.entries.len(), 4);
    for m in glitter.entries.items() {
        assert!(matches!(
            &gem.materials[*m as usize].1.base,
            BaseSpec::Conductor { metal: Some(s), .. } if s == "silver"
        ));
    }
    // Very few glitter cells are filled: measured over 10⁵ points.
    let pts = points(100_000);
    let resolved: Vec<_> = pts.iter().map(|p| gem.pattern.resolve(*p)).collect();
    let fraction = resolved.iter().filter(|r| r.glitter_cell.is_some()).count() as f64 / 1e5;
    eprintln!("lepidolite glitter fraction over 10^5 points: {fraction}");
    assert!(fraction > 0.005 && fraction < 0.04, "{fraction}");
    // Every map that holds materials is reached, inclusions included.
    for name in ["dark-tiles", "bright-tiles", "inclusions"] {
        let index = gem.map_index(name).unwrap();
        assert!(resolved.iter().any(|r| r.map_index == index), "{name}");
    }
    // The distinct kinds of material compile to BRDFs (one of each: building
    // the compensation tables of all 19 takes seconds).
    let text = std::fs::read_to_string(LEPIDOLITE).unwrap();
    let kinds = ["dark-lilac", "pink-silver", "glitter-4"];
    for (name, m) in gem
        .materials
        .iter()
        .filter(|(n, _)| kinds.contains(&n.as_str()))
    {
        let source = MaterialSource {
            path: LEPIDOLITE.to_string(),
            name: name.clone(),
            text: text.clone(),
        };
        compile_material(&source, m).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

/// A small valid recipe; the bad ones below change one thing.
const GOOD: &str = r#"Gem(
    seed: 3,
    materials: {
        "lilac": Material(layers: [Layer(ior: 1.56)], base: Diffuse(colour: (0.5, 0.4, 0.6))),
    },
    maps: {
        "small": SurfaceMap(cell_size: 0.05, entries: [(material: "lilac", weight: 2.0), (material: "red-garnet")]),
        "big": SurfaceMap(cell_size: 0.3, entries: [(map: "small"), (material: "silver")]),
        "veins": Switch(
            function: Marble(frequency: 4.0, amplitude: 2.0),
            per_cell_size: 0.02,
            ranges: [(from: 0.0, to: 0.7, map: "big"), (from: 0.7, to: 1.0, material: "lilac")],
        ),
    },
    surface: "veins",
    glitter: Some(GlitterMap(
        cell_size: 0.2,
        fill_fraction: 0.1,
        entries: [(material: "gold")],
        facets: FacetBumpMap(cell_size: 0.05, tilt: Gaussian(sigma_tilt_deg: 8.0), around: Direction(0.0, 0.0, 1.0)),
    )),
)
"#;

/// [`GOOD`] without its glitter map, which a translucent body refuses.
fn without_glitter() -> String {
    let start = GOOD.find("    glitter: Some(").expect("GOOD has glitter");
    let end = GOOD.find(")),\n)").expect("the glitter map ends GOOD") + ")),\n".len();
    format!("{}{}", &GOOD[..start], &GOOD[end..])
}

/// 1-based line of the first line containing `marker`.
fn line_of(text: &str, marker: &str) -> usize {
    text.lines()
        .position(|l| l.contains(marker))
        .unwrap_or_else(|| panic!("marker {marker} not in recipe"))
        + 1
}

/// Parses `text` (GOOD with `from` replaced by `to`), expects an error on
/// the line holding `marker`, whose message contains every `needle`.
fn expect_error(from: &str, to: &str, marker: &str, needles: &[&str]) {
    assert!(GOOD.contains(from), "{from}");
    let text = GOOD.replacen(from, to, 1);
    let err = parse_gem("bad.ron", &text).expect_err("should be rejected");
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
fn a_name_defined_twice_is_refused_not_replaced() {
    // A material or map copied and not renamed: the map kept the last one
    // without a word (the first one's colour vanished from the picture).
    expect_error(
        "        \"lilac\": Material(",
        "        \"lilac\": Material(layers: [], base: Black),\n        \"lilac\": Material(",
        "(ior: 1.56)",
        &[
            "material `lilac` is defined twice",
            "allowed: each name once",
        ],
    );
    expect_error(
        "        \"big\": SurfaceMap(",
        "        \"small\": SurfaceMap(",
        "(map: \"small\")",
        &["map `small` is defined twice"],
    );
}

#[test]
fn a_misspelt_struct_name_is_named_with_the_one_expected() {
    // It was "this is a file (`Glitter(…)`) where a file (`GlitterMap(…)`)
    // was expected", as for a whole file of another kind.
    expect_error(
        "glitter: Some(GlitterMap(",
        "glitter: Some(Glitter(",
        "Some(Glitter(",
        &["field `glitter`: `Glitter(…)` where `GlitterMap(…)` was expected (did you mean `GlitterMap`?)"],
    );
}

#[test]
fn a_comment_of_another_language_is_named_as_one() {
    // `# …` and `-- …` stopped RON with "Expected identifier" and a tip to
    // write Rust's raw identifier `r#--`.
    for mark in ["#", "--"] {
        expect_error(
            "    seed: 3,",
            &format!("    seed: 3, {mark} the textures' seed"),
            "seed: 3",
            &[&format!(
                "(is `{mark}` a comment? RON's comments are `// …` and `/* … */`)"
            )],
        );
    }
    let text = GOOD.replacen("    seed: 3,", "    seed: 3, -- the seed", 1);
    let message = parse_gem("bad.ron", &text).unwrap_err().to_string();
    assert!(!message.contains("raw identifier"), "{message}");
    assert!(
        message.contains("found `--` where a field name or a value was expected"),
        "{message}"
    );
}

#[test]
fn a_material_named_as_a_map_says_so() {
    // The other way round from `material: "small"` (a map), which says so.
    expect_error(
        "(map: \"small\")",
        "(map: \"lilac\")",
        "(map: \"lilac\")",
        &[
            "unknown map `lilac`",
            "(`lilac` is a material: write `material: \"lilac\"`)",
        ],
    );
}

#[test]
fn good_recipe_compiles() {
    let gem = parse_gem("good.ron", GOOD).unwrap_or_else(|e| panic!("{e}"));
    // lilac inline, then library red-garnet, silver, gold on first use.
    let names: Vec<_> = gem.materials.iter().map(|(n, _)| n.as_str()).collect();
    for n in ["lilac", "red-garnet", "silver", "gold"] {
        assert!(names.contains(&n), "{names:?}");
    }
    assert_eq!(gem.map_names, ["big", "small", "veins"]);
    let gold = gem.material_index("gold").unwrap();
    let mut flakes = 0;
    for p in points(5_000) {
        let r = gem.pattern.resolve(p);
        assert!((r.material as usize) < gem.materials.len());
        if let Some(normal) = r.flake_normal {
            // Gold glitter, flakes around the fixed direction (0, 0, 1)
            // whatever the surface normal.
            assert_eq!(r.material, gold);
            let n = normal.world(DVec3::X);
            assert!((n - normal.world(DVec3::Y)).length() < 1e-12);
            assert!((n.z - normal.theta.cos()).abs() < 1e-12);
            flakes += 1;
        }
    }
    assert!(
        flakes > 100 && flakes < 1_500,
        "{flakes} of 5000 (fill 0.1)"
    );
}

#[test]
fn unknown_material_name() {
    expect_error(
        r#"(material: "red-garnet")"#,
        r#"(material: "red-granet")"#,
        "red-granet",
        &[
            "unknown material `red-granet`",
            "did you mean `red-garnet`",
            "allowed:",
            "lilac",
        ],
    );
}

#[test]
fn unknown_map_name() {
    expect_error(
        r#"(map: "small")"#,
        r#"(map: "smal")"#,
        r#""smal""#,
        &[
            "unknown map `smal`",
            "did you mean `small`",
            "allowed: a name from `maps` (big, small, veins)",
        ],
    );
}

/// Parses `text`, expects an error at `line:col` whose message contains
/// every `needle`.
fn expect_error_at(text: &str, line: usize, col: usize, needles: &[&str]) {
    let message = parse_gem("bad.ron", text)
        .expect_err("should be rejected")
        .to_string();
    let prefix = format!("bad.ron:{line}:{col}: ");
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
}

#[test]
fn names_in_comments_and_descriptions_do_not_place_errors() {
    // `surface` and the name in a comment and in a string before the field.
    let text = GOOD
        .replacen(
            "Gem(\n",
            "// The surface: \"vein\" stripes.\nGem(\n    description: \"a surface of veins\",\n",
            1,
        )
        .replace("surface: \"veins\"", "surface: \"vein\"");
    let line = line_of(&text, "    surface: \"vein\"");
    expect_error_at(
        &text,
        line,
        5,
        &["`surface` names `vein`", "did you mean `veins`"],
    );
}

#[test]
fn a_reference_is_placed_at_its_use_not_at_a_definition_of_the_name() {
    // `lilac` is defined above (as a material) and used here as a map.
    let text = GOOD.replacen(
        r#"(material: "lilac", weight: 2.0)"#,
        r#"(map: "lilac", weight: 2.0)"#,
        1,
    );
    let line = line_of(&text, r#"(map: "lilac""#);
    let col = text
        .lines()
        .nth(line - 1)
        .unwrap()
        .find(r#""lilac""#)
        .unwrap()
        + 1;
    expect_error_at(
        &text,
        line,
        col,
        &[
            "unknown map `lilac`",
            "allowed: a name from `maps` (big, small, veins)",
        ],
    );
}

#[test]
fn map_containing_itself_directly() {
    expect_error(
        r#"(map: "small")"#,
        r#"(map: "big")"#,
        r#""big": SurfaceMap"#,
        &[
            "map `big` contains itself directly",
            "big → big",
            "allowed:",
        ],
    );
}

#[test]
fn map_containing_itself_through_another() {
    expect_error(
        r#"(material: "lilac", weight: 2.0)"#,
        r#"(map: "big", weight: 2.0)"#,
        r#""big": SurfaceMap"#,
        &[
            "map `big` contains itself through small",
            "big → small → big",
        ],
    );
}

#[test]
fn all_weights_zero() {
    expect_error(
        r#"(material: "lilac", weight: 2.0), (material: "red-garnet")"#,
        r#"(material: "lilac", weight: 0.0), (material: "red-garnet", weight: 0.0)"#,
        r#""small":"#,
        &[
            "`weight`s of `small` sum to 0",
            "allowed: each weight >= 0 and at least one > 0",
        ],
    );
}

#[test]
fn negative_weight() {
    expect_error(
        "weight: 2.0",
        "weight: -2.0",
        "weight: -2.0",
        &["`weight` = -2 is out of range", "allowed: weight >= 0"],
    );
}

#[test]
fn fill_fraction_out_of_range() {
    expect_error(
        "fill_fraction: 0.1",
        "fill_fraction: 1.5",
        "fill_fraction",
        &[
            "`fill_fraction` = 1.5 is out of range",
            "allowed: 0 <= fill_fraction <= 1",
        ],
    );
}

#[test]
fn cell_size_zero_and_nan() {
    for bad in ["0.0", "NaN"] {
        expect_error(
            "cell_size: 0.3",
            &format!("cell_size: {bad}"),
            r#""big""#,
            &["`cell_size` =", "out of range", "allowed: cell_size > 0"],
        );
    }
}

#[test]
fn switch_ranges_with_gap_or_overlap() {
    for (to, what) in [
        ("(from: 0.75, to: 1.0", "gap"),
        ("(from: 0.6, to: 1.0", "overlap"),
    ] {
        expect_error(
            "(from: 0.7, to: 1.0",
            to,
            r#""veins""#,
            &[what, "switch `veins`", "allowed: ranges", "covering [0, 1]"],
        );
    }
    expect_error(
        "(from: 0.7, to: 1.0",
        "(from: 0.7, to: 0.9",
        r#""veins""#,
        &["the last range ends at 0.9", "covering [0, 1]"],
    );
}

#[test]
fn facets_bigger_than_glitter_cells() {
    expect_error(
        "FacetBumpMap(cell_size: 0.05",
        "FacetBumpMap(cell_size: 0.5",
        "FacetBumpMap",
        &[
            "facet `cell_size` 0.5 is larger than the glitter `cell_size` 0.2",
            "allowed: facet cell_size <= glitter cell_size",
        ],
    );
}

#[test]
fn unknown_field_is_named() {
    expect_error(
        "per_cell_size: 0.02",
        "per_cel_size: 0.02",
        "per_cel_size",
        &[
            "unknown field `per_cel_size`",
            "did you mean `per_cell_size`",
        ],
    );
}

#[test]
fn unknown_surface() {
    expect_error(
        r#"surface: "veins""#,
        r#"surface: "vein""#,
        "surface:",
        &["`surface` names `vein`", "did you mean `veins`", "allowed:"],
    );
}

#[test]
fn a_name_in_the_wrong_role_is_placed_at_that_use() {
    // `lilac` is a material, used rightly on the "small" line first; the
    // error is about `map: "lilac"`, so it points there, at the name.
    let wrong = r#"(from: 0.7, to: 1.0, map: "lilac")"#;
    let text = GOOD.replacen(r#"(from: 0.7, to: 1.0, material: "lilac")"#, wrong, 1);
    let line = line_of(&text, wrong);
    let col = text
        .lines()
        .nth(line - 1)
        .unwrap()
        .find(r#""lilac")"#)
        .unwrap()
        + 1;
    expect_error_at(&text, line, col, &["unknown map `lilac`", "allowed:"]);
}

#[test]
fn the_retired_host_ior_is_refused_with_its_replacement_named() {
    // Anywhere among the gem's fields, whatever its value: the message
    // names the body's `ior` instead of listing the fields.
    for value in ["1.56", "9.0"] {
        expect_error(
            r#"surface: "veins","#,
            &format!("host_ior: {value},\n    surface: \"veins\","),
            "host_ior",
            &["`host_ior` is retired", "body: Translucent(ior: …)"],
        );
    }
    // Another structure's unknown `host_ior` is an ordinary typo.
    let err = parse_gem(
        "bad.ron",
        &GOOD.replacen(
            r#"surface: "veins","#,
            "surface: \"veins\",\n    body: Translucent(ior: 1.5, host_ior: 1.5),",
            1,
        ),
    )
    .expect_err("unknown field");
    assert!(
        err.to_string().contains("unknown field `host_ior`"),
        "{err}"
    );
}

#[test]
fn translucent_body_fields_are_range_checked() {
    for (body, needles) in [
        (
            "body: Translucent(ior: 0.5),",
            &["`ior`", "1 <= ior <= 5"][..],
        ),
        (
            "body: Translucent(ior: 1.5, absorption: (0.1, -1.0, 0.1)),",
            &["`absorption`", "0 <= absorption <= 1000 (per mm)"][..],
        ),
        (
            "body: Translucent(ior: 1.5, scatering: (1.0, 1.0, 1.0)),",
            &["scatering"][..],
        ),
        (
            "body: Translucent(absorption: (1.0, 1.0, 1.0)),",
            &["ior"][..],
        ),
        (
            "body: Translucent(ior: 1.5, roughness_deg: 50.0),",
            &["`roughness_deg`", "0 <= roughness_deg <= 45 (degrees)"][..],
        ),
        (
            "body: Translucent(ior: 1.5, roughness_deg: -1.0),",
            &["`roughness_deg`", "0 <= roughness_deg <= 45 (degrees)"][..],
        ),
        (
            "body: Translucent(ior: 1.5, roughness_deg: NaN),",
            &["`roughness_deg`", "0 <= roughness_deg <= 45 (degrees)"][..],
        ),
    ] {
        expect_error(
            r#"surface: "veins","#,
            &format!("surface: \"veins\",\n    {body}"),
            "body:",
            needles,
        );
    }
    let text = without_glitter().replacen(
        r#"surface: "veins","#,
        "surface: \"veins\",\n    body: Translucent(ior: 1.54, absorption: (0.1, 0.2, 0.3)),",
        1,
    );
    let gem = parse_gem("good.ron", &text).unwrap();
    assert_eq!(
        gem.body,
        lapidary::recipe::gem::Body::Translucent {
            ior: 1.54,
            roughness_deg: 0.0,
            rough_surface: None,
            medium: lapidary::recipe::gem::Medium {
                absorption_per_mm: lapidary::brdf::Rgb::new(0.1, 0.2, 0.3),
                scattering_per_mm: lapidary::brdf::Rgb::ZERO,
                anisotropy: 0.0,
            },
            zoning: None,
            inclusions: vec![],
        }
    );
    assert_eq!(
        parse_gem("good.ron", GOOD).unwrap().body,
        lapidary::recipe::gem::Body::Opaque
    );
    // The polish of the surface, when written, reaches the compiled body.
    let rough = without_glitter().replacen(
        r#"surface: "veins","#,
        "surface: \"veins\",\n    body: Translucent(ior: 1.54, roughness_deg: 12.5),",
        1,
    );
    let lapidary::recipe::gem::Body::Translucent { roughness_deg, .. } =
        parse_gem("good.ron", &rough).unwrap().body
    else {
        panic!("not translucent");
    };
    assert_eq!(roughness_deg, 12.5);
}

#[test]
fn zoning_and_density_modulation_are_range_checked_and_reach_the_compiled_body() {
    // Each bad value on its own line: the error names that line.
    for (fields, marker, needles) in [
        (
            "zoning: Some(Zoning(function: Perlin(frequency: 2.0),\n        absorption: (0.1, -0.5, 0.1))),",
            "absorption: (0.1, -0.5",
            &["`absorption`", "0 <= absorption <= 1000 (per mm)"][..],
        ),
        (
            "zoning: Some(Zoning(function: Perlin(frequency: 2.0),\n        absorption: (0.1, NaN, 0.1))),",
            "absorption: (0.1, NaN",
            &["`absorption`", "0 <= absorption <= 1000 (per mm)"][..],
        ),
        (
            "zoning: Some(Zoning(\n        function: Perlin(frequency: -1.0), absorption: (1.0, 1.0, 1.0))),",
            "function: Perlin",
            &["`frequency`"][..],
        ),
        (
            "zoning: Some(Zoning(function: Perlin(frequency: 2.0))),",
            "zoning:",
            &["absorption"][..],
        ),
        (
            "inclusions: [Inclusions(shape: Disc, size_mm: 0.1, density_per_mm3: 10.0, material: \"silver\",\n        density_modulation: Some(Marble(frequency: NaN, amplitude: 1.0)))],",
            "density_modulation",
            &["`frequency`"][..],
        ),
    ] {
        expect_error(
            r#"surface: "veins","#,
            &format!("surface: \"veins\",\n    body: Translucent(ior: 1.5,\n        {fields}),"),
            marker,
            needles,
        );
    }
    // A good zoning: the medium keeps the least absorption per channel and
    // the zoning what lies above it, σ̄ the largest difference.
    let text = without_glitter().replacen(
        r#"surface: "veins","#,
        "surface: \"veins\",\n    body: Translucent(ior: 1.54, absorption: (0.1, 0.8, 0.3), \
         zoning: Some(Zoning(function: Perlin(frequency: 2.0), absorption: (0.5, 0.2, 0.3))), \
         inclusions: [Inclusions(shape: Disc, size_mm: 0.1, density_per_mm3: 10.0, material: \"silver\", \
         density_modulation: Some(Perlin(frequency: 3.0)))]),",
        1,
    );
    let gem = parse_gem("good.ron", &text).unwrap_or_else(|e| panic!("{e}"));
    let lapidary::recipe::gem::Body::Translucent {
        medium,
        zoning: Some(zoning),
        inclusions,
        ..
    } = gem.body
    else {
        panic!("no zoning: {:?}", gem.body);
    };
    use lapidary::brdf::Rgb;
    assert_eq!(medium.absorption_per_mm, Rgb::new(0.1, 0.2, 0.3));
    assert_eq!(
        zoning.residual_low_per_mm,
        Rgb::new(0.0, 0.6000000000000001, 0.0)
    );
    assert_eq!(zoning.residual_high_per_mm, Rgb::new(0.4, 0.0, 0.0));
    assert_eq!(zoning.majorant_per_mm, 0.6000000000000001);
    assert!(inclusions[0].density_modulation.is_some());
}

#[test]
fn a_flake_in_a_body_reflects_with_its_index_relative_to_the_body() {
    // Fresnel (eq. 3.3) takes a metal's index relative to the medium it is
    // seen from: copper platelets in glass of n = 1.5 reflect F₀(n/1.5,
    // k/1.5) at normal incidence, not copper's F₀ in air (blue: 0.42
    // against 0.51). The same library metal as the surface (seen from air)
    // and as inclusions gets a BRDF for each.
    use lapidary::brdf::albedo::directional_albedo;
    use lapidary::brdf::fresnel::conductor;
    use lapidary::brdf::Rgb;
    use lapidary::recipe::gem::{compile_gem, Body, GemSource};
    use lapidary::recipe::Tables;
    let text = r#"Gem(
    name: "copper in glass",
    surface: "copper",
    body: Translucent(ior: 1.5, inclusions: [
        Inclusions(shape: Disc, size_mm: 0.1, density_per_mm3: 10.0, material: "copper"),
    ]),
)"#;
    let gem = compile_gem(&GemSource::new("copper.ron", text), None, Tables::Skipped)
        .unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<_> = gem.materials.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["copper", "copper"]);
    assert_eq!(gem.seen_from_ior, [1.0, 1.5]);
    let Body::Translucent { inclusions, .. } = &gem.body else {
        panic!("a translucent body");
    };
    assert_eq!(inclusions[0].material, 1);
    let (n, k) = (Rgb::new(0.200, 0.924, 1.102), Rgb::new(3.913, 2.453, 2.142));
    let mut blue = Vec::new();
    for (index, ior) in [(0, 1.0), (1, 1.5)] {
        let albedo = directional_albedo(&gem.brdfs[index], 0.0, 5e-4, 1 << 18, 7).mean;
        let f0 = conductor(1.0, n / ior, k / ior);
        for (c, got) in albedo.to_array().into_iter().enumerate() {
            let expected = f0[c];
            assert!(
                (got - expected).abs() < 0.01 * expected,
                "seen from n = {ior}, channel {c}: albedo {got}, F₀ {expected}"
            );
        }
        blue.push(albedo.to_array()[2]);
    }
    assert!(blue[1] < 0.85 * blue[0], "{blue:?}");
}

#[test]
fn a_flake_axis_of_any_finite_size_is_its_direction_and_zero_is_refused() {
    // The same axis written tiny or huge compiles to the same gem: the
    // squared length of (1e-300, …) underflowed to 0 and was refused as
    // zero, that of (1e300, …) overflowed and gave no axis at all.
    let body = |direction: &str| {
        let text = without_glitter().replacen(
            r#"surface: "veins","#,
            &format!(
                "surface: \"veins\",\n    body: Translucent(ior: 1.5, inclusions: [Inclusions(shape: Disc, \
                 size_mm: 0.1, density_per_mm3: 10.0, material: \"silver\",\n        \
                 orientation: Aligned(direction: {direction}, spread_deg: 5.0))]),"
            ),
            1,
        );
        parse_gem("good.ron", &text).map(|gem| format!("{:?}", gem.body))
    };
    let plain = body("(1.0, -2.0, 4.0)").unwrap_or_else(|e| panic!("{e}"));
    for scaled in ["(1e-300, -2e-300, 4e-300)", "(1e300, -2e300, 4e300)"] {
        assert_eq!(
            body(scaled).unwrap_or_else(|e| panic!("{e}")),
            plain,
            "{scaled}"
        );
    }
    let message = body("(0.0, 0.0, 0.0)")
        .expect_err("a zero axis")
        .to_string();
    assert!(message.contains("`direction` is zero"), "{message}");
}
