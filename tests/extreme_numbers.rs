//! Every number of every built-in gem recipe and of the built-in studio
//! scene, replaced in turn by 1e308, −1e308 and 1e-300: the text is either
//! refused with a message naming its line, or it compiles and renders
//! (8 × 8, 2 spp) to finite, non-negative pixels with no sample dropped as
//! NaN, infinite or negative. (A light's radiance of 1e308 was accepted and
//! its samples dropped: a picture without the light.)

mod common;

use std::path::Path;

use lapidary::recipe::gem::{compile_gem, GemSource};
use lapidary::recipe::library::{builtin_gem_names, builtin_gem_source};
use lapidary::recipe::Tables;
use lapidary::render::film::{render, FilmSettings};
use lapidary::render::prepare::{camera_for, prepare_scene};
use lapidary::render::render_scene::RenderScene;
use lapidary::scene::{parse_scene, DEFAULT_SCENE_SOURCE};

use common::scenes::default_scene_without_ground;

const EXTREMES: [&str; 3] = ["1e308", "-1e308", "1e-300"];
const SIDE: u32 = 8;

/// The byte ranges of the number literals of a RON text, outside comments
/// and strings.
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let bytes = text.as_bytes();
    let mut found = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'"' => {
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += 1;
                }
                i += 1;
            }
            b'0'..=b'9' | b'-' => {
                let word_before =
                    i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_');
                let start = i;
                i += 1;
                while i < bytes.len()
                    && (bytes[i].is_ascii_digit()
                        || bytes[i] == b'.'
                        || bytes[i] == b'e'
                        || (bytes[i] == b'-' && bytes[i - 1] == b'e'))
                {
                    i += 1;
                }
                let literal = &text[start..i];
                if !word_before && literal.bytes().any(|b| b.is_ascii_digit()) {
                    found.push((start, i));
                }
            }
            _ => i += 1,
        }
    }
    found
}

/// Each mutation of `text`: (where, the new text).
fn mutations(text: &str) -> impl Iterator<Item = (String, String)> + '_ {
    numbers(text).into_iter().flat_map(move |(start, end)| {
        let line = text[..start].lines().count().max(1);
        EXTREMES.iter().map(move |value| {
            (
                format!("line {line}: {} → {value}", &text[start..end]),
                format!("{}{value}{}", &text[..start], &text[end..]),
            )
        })
    })
}

/// Renders `scene` and checks every pixel and sample; `what` names the case.
fn render_checks(render_scene: &RenderScene, scene: &lapidary::scene::Scene, what: &str) {
    let camera = camera_for(scene, SIDE, SIDE);
    let film = render(
        render_scene,
        &camera,
        &FilmSettings::new(SIDE, SIDE, 2, 1),
        &|_| {},
    );
    assert!(
        film.rgb
            .iter()
            .flatten()
            .all(|c| c.is_finite() && *c >= 0.0),
        "{what}: a pixel is not finite and non-negative"
    );
    assert_eq!(film.stats.bad_samples, 0, "{what}: samples dropped");
}

#[test]
fn extreme_numbers_in_the_built_in_gems_are_refused_or_render_finite() {
    let (mut refused, mut rendered) = (0, 0);
    for name in builtin_gem_names() {
        let text = builtin_gem_source(name).expect("a built-in gem");
        for (place, mutated) in mutations(text) {
            let what = format!("{name}.ron {place}");
            match compile_gem(
                &GemSource::new("mutated.ron", &mutated),
                None,
                Tables::Skipped,
            ) {
                Err(error) => {
                    assert!(
                        error.to_string().starts_with("mutated.ron:"),
                        "{what}: the message names no place: {error}"
                    );
                    refused += 1;
                }
                Ok(gem) => {
                    let (scene, render_scene) = default_scene_without_ground(gem);
                    render_checks(&render_scene, &scene, &what);
                    rendered += 1;
                }
            }
        }
    }
    // Not vacuous: many of each.
    assert!(
        refused > 100 && rendered > 100,
        "{refused} refused, {rendered} rendered"
    );
}

#[test]
fn extreme_numbers_in_the_studio_scene_are_refused_or_render_finite() {
    let gem = GemSource::new("plain.ron", "Gem(materials: {\"m\": Material(base: Diffuse(colour: (0.5, 0.5, 0.5)), multiple_scattering: false)}, maps: {\"t\": SurfaceMap(cell_size: 0.1, entries: [(material: \"m\")])}, surface: \"t\")");
    let (mut refused, mut rendered) = (0, 0);
    for (place, mutated) in mutations(DEFAULT_SCENE_SOURCE) {
        let what = format!("studio.ron {place}");
        let scene = match parse_scene(&mutated, Some(Path::new("mutated.ron"))) {
            Err(error) => {
                assert!(
                    error.to_string().starts_with("mutated.ron:"),
                    "{what}: the message names no place: {error}"
                );
                refused += 1;
                continue;
            }
            Ok(scene) => scene,
        };
        match prepare_scene(&scene, &gem, None, 4, Tables::Skipped, &|_| {}) {
            Err(error) => {
                assert!(!error.message.is_empty(), "{what}: an empty message");
                refused += 1;
            }
            Ok(render_scene) => {
                render_checks(&render_scene, &scene, &what);
                rendered += 1;
            }
        }
    }
    assert!(
        refused > 10 && rendered > 10,
        "{refused} refused, {rendered} rendered"
    );
}
