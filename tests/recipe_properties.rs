//! Property: every gem recipe written inside the schema's documented ranges
//! parses, compiles and renders (4×4, 1 spp, the built-in studio scene) to
//! finite, non-negative pixels, with no sample dropped as NaN, infinite or
//! negative.
//!
//! Recipes are generated as RON text from the schema (docs/recipes.md and
//! the range table of `src/recipe/ranges.rs`): 1–3 materials of 0–3 layers
//! (IOR given as `ior`, `reflectivity` or a library `varnish`) over diffuse,
//! conductor (library metal or n, k) or black bases; a surface map; an
//! optional switch over it with a valid partition of its function's
//! documented value range; an optional glitter map with facets no larger
//! than its cells. Every material has `multiple_scattering: false`: the
//! compensation tables cost 0.1–1 s per material and are not input handling.

mod common;

use lapidary::recipe::gem::{compile_gem, Gem, GemSource};
use lapidary::recipe::TableCache;
use lapidary::recipe::Tables;
use lapidary::render::film::{render, FilmSettings};
use lapidary::render::prepare::camera_for;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

use common::scenes::default_scene_without_ground;

/// One layer as RON.
fn layer() -> impl Strategy<Value = String> {
    let ior = prop_oneof![
        (1.0f64..=3.0).prop_map(|n| format!("ior: {n:?}")),
        (0.0f64..=1.0).prop_map(|p| format!("reflectivity: {p:?}")),
        prop::sample::select(vec!["plastics", "ice", "teflon"])
            .prop_map(|v| format!("varnish: \"{v}\"")),
    ];
    (
        ior,
        0.0f64..60.0,
        0.0f64..2.0,
        prop::array::uniform3(0.0f64..3.0),
    )
        .prop_map(|(ior, roughness_deg, thickness, a)| {
            format!(
                "Layer({ior}, roughness_deg: {roughness_deg:?}, thickness: {thickness:?}, absorption: ({:?}, {:?}, {:?}))",
                a[0], a[1], a[2]
            )
        })
}

/// A base as RON.
fn base() -> impl Strategy<Value = String> {
    prop_oneof![
        (prop::array::uniform3(0.0f64..=1.0), 0.0f64..=1.0).prop_map(|(c, sigma)| format!(
            "Diffuse(colour: ({:?}, {:?}, {:?}), oren_nayar_sigma_rad: {sigma:?})",
            c[0], c[1], c[2]
        )),
        (
            prop::sample::select(vec!["gold", "silver", "aluminium", "copper"]),
            0.0f64..60.0
        )
            .prop_map(|(metal, r)| format!("Conductor(metal: \"{metal}\", roughness_deg: {r:?})")),
        (
            prop::array::uniform3(0.05f64..=5.0),
            prop::array::uniform3(0.0f64..=8.0),
            0.0f64..60.0
        )
            .prop_map(|(n, k, r)| format!(
                "Conductor(n: ({:?}, {:?}, {:?}), k: ({:?}, {:?}, {:?}), roughness_deg: {r:?})",
                n[0], n[1], n[2], k[0], k[1], k[2]
            )),
        Just("Black".to_string()),
    ]
}

/// A whole material as RON.
fn material() -> impl Strategy<Value = String> {
    (
        prop::collection::vec(layer(), 0..=3),
        base(),
        prop::sample::select(vec!["Blinn", "Beckmann", "Ggx"]),
    )
        .prop_map(|(layers, base, distribution)| {
            format!(
                "Material(layers: [{}], base: {base}, distribution: {distribution}, multiple_scattering: false)",
                layers.join(", ")
            )
        })
}

/// A switch function as RON with its documented value range `[lo, hi]`.
fn function() -> impl Strategy<Value = (String, f64, f64)> {
    prop_oneof![
        (0.5f64..20.0).prop_map(|f| (format!("Perlin(frequency: {f:?})"), -1.0, 1.0)),
        (0.5f64..20.0, -4.0f64..4.0).prop_map(|(f, a)| (
            format!("Marble(frequency: {f:?}, amplitude: {a:?})"),
            0.0,
            1.0
        )),
        // Turbulence lies in [0, B] with B = Σ gainᵏ over the octaves:
        // 1 + 0.5 = 1.5 for two octaves of gain 0.5.
        (0.5f64..20.0).prop_map(|f| (
            format!("Turbulence(frequency: {f:?}, octaves: 2, gain: 0.5)"),
            0.0,
            1.5
        )),
    ]
}

/// A switch function with its value range `[lo, hi]`, the interior cuts as
/// fractions of that range, and a material index per range.
type SwitchParams = ((String, f64, f64), Vec<f64>, Vec<usize>);

/// Parameters of one recipe, turned into RON by [`recipe_text`].
#[derive(Debug, Clone)]
struct Recipe {
    seed: u64,
    materials: Vec<String>,
    cell_size: f64,
    jitter: f64,
    /// (material index, weight) per surface-map entry.
    entries: Vec<(usize, f64)>,
    /// Function, its range, interior cut fractions and material per range.
    switch: Option<SwitchParams>,
    /// Glitter cell size, fill fraction, facet size fraction, tilt, material.
    glitter: Option<(f64, f64, f64, f64, usize)>,
}

fn recipe() -> impl Strategy<Value = Recipe> {
    (
        any::<u64>(),
        prop::collection::vec(material(), 1..=3),
        0.02f64..0.5,
        0.0f64..=1.0,
        prop::collection::vec((0usize..3, 0.0f64..3.0), 1..=3),
        prop::option::of((
            function(),
            prop::collection::vec(0.05f64..0.95, 0..=3),
            prop::collection::vec(0usize..3, 4),
        )),
        prop::option::of((
            0.05f64..0.5,
            0.0f64..=1.0,
            0.1f64..=1.0,
            0.0f64..=60.0,
            0usize..3,
        )),
    )
        .prop_map(
            |(seed, materials, cell_size, jitter, mut entries, switch, glitter)| {
                // At least one weight > 0 per map (the schema's rule).
                entries[0].1 += 0.5;
                Recipe {
                    seed,
                    materials,
                    cell_size,
                    jitter,
                    entries,
                    switch,
                    glitter,
                }
            },
        )
}

fn recipe_text(r: &Recipe) -> String {
    let n = r.materials.len();
    let name = |i: usize| format!("m{}", i % n);
    let materials: Vec<String> = r
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| format!("        \"m{i}\": {m},\n"))
        .collect();
    let entries: Vec<String> = r
        .entries
        .iter()
        .map(|(i, w)| format!("(material: \"{}\", weight: {w:?})", name(*i)))
        .collect();
    let mut maps = format!(
        "        \"tiles\": SurfaceMap(cell_size: {:?}, jitter: {:?}, entries: [{}]),\n",
        r.cell_size,
        r.jitter,
        entries.join(", ")
    );
    let mut surface = "tiles";
    if let Some(((function, lo, hi), cuts, picks)) = &r.switch {
        let mut cuts = cuts.clone();
        cuts.sort_by(f64::total_cmp);
        cuts.dedup_by(|a, b| (*a - *b).abs() < 0.01);
        let mut ends = vec![*lo];
        ends.extend(cuts.iter().map(|c| lo + c * (hi - lo)));
        ends.push(*hi);
        let ranges: Vec<String> = ends
            .windows(2)
            .enumerate()
            .map(|(k, w)| {
                // The first range holds the surface map, the others materials.
                let target = if k == 0 {
                    "map: \"tiles\"".to_string()
                } else {
                    format!("material: \"{}\"", name(picks[k]))
                };
                format!("(from: {:?}, to: {:?}, {target})", w[0], w[1])
            })
            .collect();
        maps += &format!(
            "        \"veins\": Switch(function: {function}, ranges: [{}]),\n",
            ranges.join(", ")
        );
        surface = "veins";
    }
    let glitter = match r.glitter {
        Some((cell, fill, facet_fraction, tilt, m)) => format!(
            "Some(GlitterMap(cell_size: {cell:?}, fill_fraction: {fill:?}, entries: [(material: \"{}\")], \
             facets: FacetBumpMap(cell_size: {:?}, tilt: UniformCone(max_tilt_deg: {tilt:?}))))",
            name(m),
            cell * facet_fraction
        ),
        None => "None".to_string(),
    };
    format!(
        "Gem(\n    name: \"generated\",\n    seed: {},\n    materials: {{\n{}    }},\n    maps: {{\n{maps}    }},\n    surface: \"{surface}\",\n    glitter: {glitter},\n)\n",
        r.seed,
        materials.concat()
    )
}

const SIDE: u32 = 4;

proptest! {
    // A fixed seed: the cases are the same every run (the house rule of
    // determinism); no failure file is written into the source tree.
    #![proptest_config(ProptestConfig {
        cases: 128,
        rng_seed: RngSeed::Fixed(0x6e4d_7a12),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn valid_recipes_compile_and_render_finite(r in recipe()) {
        let text = recipe_text(&r);
        let gem = compile_text("generated.ron", &text)
            .map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        prop_assert_eq!(gem.brdfs.len(), r.materials.len(), "{}", text);

        let (scene, render_scene) = default_scene_without_ground(gem);
        let camera = camera_for(&scene, SIDE, SIDE);
        let settings = FilmSettings::new(SIDE, SIDE, 1, r.seed);
        let film = render(&render_scene, &camera, &settings, &|_| {});

        prop_assert_eq!(film.rgb.len(), (SIDE * SIDE) as usize);
        for (i, p) in film.rgb.iter().enumerate() {
            prop_assert!(p.iter().all(|c| c.is_finite() && *c >= 0.0), "pixel {} = {:?}\n{}", i, p, text);
        }
        prop_assert_eq!(film.stats.bad_samples, 0, "samples dropped as NaN/inf/negative\n{}", text);
        // Not vacuous: the image centre is the orbit target, the stone's
        // middle, so the ray through it meets the stone being shaded.
        let centre = camera.ray(f64::from(SIDE) / 2.0, f64::from(SIDE) / 2.0);
        prop_assert!(
            render_scene.world.intersect(centre.origin, centre.direction, 0.0, f64::INFINITY).is_some(),
            "the centre ray missed the stone"
        );
    }
}

/// The generator itself: a fixed recipe of every kind of node comes out as
/// RON the parser reads back with the structure that was asked for.
#[test]
fn the_generator_writes_what_it_was_asked_for() {
    let r = Recipe {
        seed: 9,
        materials: vec![
            "Material(base: Black, multiple_scattering: false)".to_string(),
            "Material(base: Conductor(metal: \"gold\"), multiple_scattering: false)".to_string(),
        ],
        cell_size: 0.1,
        jitter: 0.5,
        entries: vec![(0, 1.0), (1, 2.0)],
        switch: Some((
            ("Perlin(frequency: 2.0)".to_string(), -1.0, 1.0),
            vec![0.5],
            vec![0, 1, 0, 0],
        )),
        glitter: Some((0.2, 0.1, 0.5, 20.0, 1)),
    };
    let text = recipe_text(&r);
    let gem = lapidary::recipe::gem::parse_gem("generated.ron", &text)
        .unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(gem.seed, 9);
    assert_eq!(gem.materials.len(), 2);
    assert_eq!(gem.map_names.len(), 2, "{:?}", gem.map_names);
    assert!(gem.spec.glitter.is_some());
    assert!(
        text.contains(
            "(from: -1.0, to: 0.0, map: \"tiles\"), (from: 0.0, to: 1.0, material: \"m1\")"
        ),
        "{text}"
    );
}

/// Compiles gem recipe `text` (`path` for messages) with its compensation
/// tables, computed afresh.
fn compile_text(path: &str, text: &str) -> Result<Gem, lapidary::recipe::RecipeError> {
    let cache = TableCache::in_memory();
    compile_gem(&GemSource::new(path, text), None, Tables::Computed(&cache))
}

/// Renders `text` (a valid gem) like the property above and returns the
/// number of samples dropped as NaN, infinite or negative.
fn bad_samples_of(text: &str) -> u64 {
    let gem = compile_text("extreme.ron", text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    let (scene, render_scene) = default_scene_without_ground(gem);
    let side = 16;
    let camera = camera_for(&scene, side, side);
    let settings = FilmSettings::new(side, side, 2, 1);
    let film = render(&render_scene, &camera, &settings, &|_| {});
    assert!(film
        .rgb
        .iter()
        .flatten()
        .all(|c| c.is_finite() && *c >= 0.0));
    film.stats.bad_samples
}

/// Numbers at the edges of their allowed ranges (found by fuzzing and by
/// hand): each is valid, so each must shade without a NaN.
#[test]
fn extreme_valid_numbers_shade_without_nan() {
    let gem = |material: &str| {
        format!(
            "Gem(materials: {{\"m\": Material({material}, multiple_scattering: false)}}, \
             maps: {{\"t\": SurfaceMap(cell_size: 0.1, entries: [(material: \"m\")])}}, surface: \"t\")"
        )
    };
    for material in [
        // α·d overflows in one channel while another has α = 0: Beer's law
        // gives 0 and 1, never 0 · ∞.
        "layers: [Layer(ior: 1.5, roughness_deg: 5.0, thickness: 1e308, absorption: (1e308, 0.0, 0.3))], base: Diffuse(colour: (0.5, 0.5, 0.5))",
        // The smallest allowed metal index, no extinction, nearly flat facets.
        "base: Conductor(n: (0.01, 0.01, 0.01), k: (0.0, 0.0, 0.0), roughness_deg: 0.0)",
        // The smallest metal index under the densest varnish.
        "layers: [Layer(ior: 5.0, roughness_deg: 89.9)], base: Conductor(n: (0.01, 20.0, 1.0), k: (20.0, 0.0, 0.0), roughness_deg: 89.9)",
        // Nearly the largest roughness everywhere.
        "layers: [Layer(ior: 1.0, roughness_deg: 89.9999), Layer(reflectivity: 1.0, roughness_deg: 89.9999)], base: Diffuse(colour: (1.0, 1.0, 1.0), oren_nayar_sigma_rad: 1.57)",
    ] {
        let text = gem(material);
        assert_eq!(bad_samples_of(&text), 0, "{text}");
    }
}
