//! The RON examples in the README parse and compile, so the docs stay true.

fn readme() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap()
}

/// The ```ron block of the README that starts with `start`.
fn block_starting(text: &str, start: &str) -> String {
    let i = text
        .find(start)
        .unwrap_or_else(|| panic!("README has no `{start}` example"));
    let j = text[i..].find("```").unwrap() + i;
    text[i..j].to_string()
}

#[test]
fn readme_material_example_compiles() {
    let text = block_starting(&readme(), "Material(\n    layers: [");
    let source = lapidary::recipe::compile::MaterialSource {
        path: "README.md".into(),
        name: "readme".into(),
        text: text.clone(),
    };
    let mut m = lapidary::recipe::parse_material("README.md", &text).unwrap();
    m.multiple_scattering = false;
    let brdf = lapidary::recipe::compile::compile_material(&source, &m).unwrap();
    assert_eq!(brdf.interfaces.len(), 1);
}

#[test]
fn readme_gem_example_compiles() {
    let text = block_starting(&readme(), "Gem(\n    name: \"example\"");
    let gem = lapidary::recipe::gem::parse_gem("README.md", &text).unwrap();
    assert!(gem.pattern.glitter().is_some());
    assert_eq!(gem.map_names.len(), 2);
}

#[test]
fn readme_scene_example_parses_with_its_two_stones_and_three_lights() {
    let text = block_starting(&readme(), "Scene(\n    camera: Orbit");
    let scene = lapidary::scene::parse_scene(&text, None).unwrap();
    assert_eq!(scene.stones.len(), 2);
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(
        scene.stones[0].recipe.as_deref(),
        Some("lavender-lepidolite")
    );
}
