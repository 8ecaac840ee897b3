//! Every ```ron block of docs/recipes.md parses (and compiles) as what it
//! claims to be — a material, a gem or a scene by its top-level struct name —
//! so that the reference cannot drift from the parser.

use lapidary::recipe::compile::{compile_material, parse_material, MaterialSource};
use lapidary::recipe::gem::parse_gem;
use lapidary::scene::parse_scene;

const DOC: &str = include_str!("../docs/recipes.md");

/// (1-based line of the opening fence, block text) of every ```ron block.
fn ron_blocks(doc: &str) -> Vec<(usize, String)> {
    let mut blocks = Vec::new();
    let mut current: Option<(usize, String)> = None;
    for (k, line) in doc.lines().enumerate() {
        match &mut current {
            None if line.trim_start() == "```ron" => current = Some((k + 1, String::new())),
            None => {}
            Some(_) if line.trim_start().starts_with("```") => {
                blocks.push(current.take().unwrap());
            }
            Some((_, text)) => {
                text.push_str(line);
                text.push('\n');
            }
        }
    }
    assert!(
        current.is_none(),
        "an unclosed ```ron block in docs/recipes.md"
    );
    blocks
}

/// The top-level struct name: the first word that is not in a comment.
fn kind(text: &str) -> &str {
    let code = text
        .lines()
        .map(|l| l.split("//").next().unwrap_or("").trim())
        .find(|l| !l.is_empty())
        .unwrap_or("");
    let end = code
        .find(|c: char| !c.is_alphanumeric() && c != '_')
        .unwrap_or(code.len());
    &code[..end]
}

#[test]
fn every_ron_block_parses_as_what_it_claims() {
    let blocks = ron_blocks(DOC);
    let mut counts = [0usize; 3];
    for (line, text) in &blocks {
        let place = format!("docs/recipes.md block at line {line}");
        match kind(text) {
            "Material" => {
                let mut m = parse_material(&place, text).unwrap_or_else(|e| panic!("{e}"));
                m.multiple_scattering = false;
                let source = MaterialSource {
                    path: place.clone(),
                    name: "doc".into(),
                    text: text.clone(),
                };
                compile_material(&source, &m).unwrap_or_else(|e| panic!("{e}"));
                counts[0] += 1;
            }
            "Gem" => {
                let gem = parse_gem(&place, text).unwrap_or_else(|e| panic!("{e}"));
                // Compile each material it uses too (as `lapidary validate` does).
                for (name, material) in &gem.materials {
                    let mut m = material.clone();
                    m.multiple_scattering = false;
                    let source = MaterialSource {
                        path: place.clone(),
                        name: name.clone(),
                        text: text.clone(),
                    };
                    compile_material(&source, &m).unwrap_or_else(|e| panic!("{e}"));
                }
                counts[1] += 1;
            }
            "Scene" => {
                parse_scene(text, None).unwrap_or_else(|e| panic!("{place}: {e}"));
                counts[2] += 1;
            }
            other => panic!("{place}: starts with `{other}`, not Material/Gem/Scene"),
        }
    }
    // The page promises a minimal and a full example of each kind.
    assert!(
        counts.iter().all(|&n| n >= 2),
        "examples per kind (material, gem, scene): {counts:?}"
    );
}

#[test]
fn the_full_examples_write_every_documented_field() {
    // Each field named in a table row (`| `field` |`) of the material, gem
    // and scene sections appears in some ```ron block, so the "full"
    // examples really show every field.
    let all_examples: String = ron_blocks(DOC).into_iter().map(|(_, t)| t).collect();
    let mut missing = Vec::new();
    for line in DOC.lines().filter(|l| l.starts_with('|')) {
        for cell in line.split('|').skip(1).take(2) {
            let cell = cell.trim();
            if let Some(field) = cell.strip_prefix('`').and_then(|c| c.strip_suffix('`')) {
                let is_name = field.chars().all(|c| c.is_ascii_lowercase() || c == '_');
                if is_name && !all_examples.contains(&format!("{field}:")) {
                    missing.push(field.to_string());
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "fields never written in an example: {missing:?}"
    );
}

#[test]
fn the_block_scanner_finds_blocks_and_kinds() {
    let doc = "text\n```ron\n// c: Gem(\nMaterial(base: Black)\n```\n```text\nGem()\n```\n";
    let blocks = ron_blocks(doc);
    assert_eq!(blocks.len(), 1);
    assert_eq!(blocks[0].0, 2);
    assert_eq!(kind(&blocks[0].1), "Material");
}
