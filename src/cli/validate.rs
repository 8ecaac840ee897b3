//! `lapidary validate RECIPE...`: check gem recipes, material files, scene
//! files, batch jobs and built-in names the way the renderer would read
//! them, and print `file:line:col: message` for each error or `file: ok
//! (…)` for each valid input.
//!
//! A file's kind is its RON top-level struct name (`Gem(`, `Material(`,
//! `Scene(`, `Job(`), read after comments and whitespace. Validation runs
//! the same parse and compile steps as `lapidary render` (the gem's
//! pattern tree, and every material compiled with `multiple_scattering`
//! off, which skips the slow compensation tables but none of the checks),
//! so semantic errors — unknown names, weights summing to zero, maps that
//! contain themselves — are caught here and not at render time; a job's
//! recipes and scenes are checked with it.

use super::counted;
use lapidary::farm::job::Job;
use lapidary::recipe::compile::{
    compile_material, locate_material, names_a_file, parse_material, read_ron_file, MaterialSource,
};
use lapidary::recipe::error::{
    did_you_mean, first_code_offset, folder_separator_hint, line_col_of_offset, RecipeError,
};
use lapidary::recipe::gem::{parse_gem, Body, BodySpec, Gem, GemSource, MapSpec};
use lapidary::recipe::library::{
    builtin_gem_names, builtin_gem_source, builtin_material_names, builtin_material_source,
};
use lapidary::recipe::material::BaseSpec;
use lapidary::render::environment::Environment;
use lapidary::render::overlaps::{placement_problems, viewpoint_problems};
use lapidary::render::prepare::stone_instances;
use lapidary::render::world::World;
use lapidary::scene::spec::{EnvironmentKind, SceneSpec};
use lapidary::scene::{parse_scene, EnvironmentSpec, DEFAULT_SCENE_SOURCE};
use std::collections::HashSet;
use std::path::Path;

/// Name under which `validate` accepts the built-in studio scene.
pub const BUILTIN_SCENE_NAME: &str = "studio";

/// What a RON file holds, by its top-level struct name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecipeKind {
    /// `Gem(…)`: a gem recipe (section 4.3.1).
    Gem,
    /// `Material(…)`: a layered material (section 4.1).
    Material,
    /// `Scene(…)`: a scene for `lapidary render --scene`.
    Scene,
    /// `Job(…)`: a batch job for `lapidary batch`.
    Job,
}

/// The kind of RON file `text` is, from its top-level struct name; an
/// error at the first token says what was expected otherwise.
pub fn recipe_kind(path: &str, text: &str) -> Result<RecipeKind, RecipeError> {
    const EXPECTED: &str =
        "expected a recipe starting with `Gem(`, `Material(`, `Scene(` or `Job(` (after comments)";
    let start = first_code_offset(text);
    if start >= text.len() {
        let what = if text.trim().is_empty() {
            "the file is empty"
        } else {
            "the file holds only comments"
        };
        return Err(RecipeError::whole_file(path, format!("{what}; {EXPECTED}")));
    }
    let word: String = text[start..]
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .collect();
    let kind = match word.as_str() {
        "Gem" => Some(RecipeKind::Gem),
        "Material" => Some(RecipeKind::Material),
        "Scene" => Some(RecipeKind::Scene),
        "Job" => Some(RecipeKind::Job),
        _ => None,
    };
    match kind {
        Some(kind) => Ok(kind),
        None => {
            let (line, col) = line_col_of_offset(text, start);
            let found = if word.is_empty() {
                text[start..]
                    .chars()
                    .next()
                    .map_or(String::new(), |c| c.to_string())
            } else {
                word.clone()
            };
            let hint = did_you_mean(&word, ["Gem", "Material", "Scene", "Job"])
                .filter(|_| !word.is_empty())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            Err(RecipeError::at(
                path,
                line,
                col,
                format!("found `{found}`{hint}; {EXPECTED}"),
            ))
        }
    }
}

/// What `validate` says of a valid input: its one-line summary, and its
/// warnings (`FILE: warning: …`: a sunk stone, a camera inside a light, a
/// map that is not 2:1), each a line of its own.
#[derive(Debug, Default)]
pub struct Checked {
    /// "ok (gem \"goldstone\", 3 materials, …)".
    pub summary: String,
    /// Each warning, `FILE: warning: …`.
    pub warnings: Vec<String>,
}

impl From<String> for Checked {
    /// A summary without warnings.
    fn from(summary: String) -> Self {
        Checked {
            summary,
            warnings: Vec::new(),
        }
    }
}

/// Validate a gem recipe: parse, compile the pattern, compile every
/// material it uses.
fn validate_gem(path: &str, text: &str) -> Result<Checked, RecipeError> {
    let gem = parse_gem(path, text)?;
    let warnings = unused_definitions(&gem)
        .into_iter()
        .chain(unshaded_surface(&gem))
        .map(|unused| format!("{path}: warning: {unused}"))
        .collect();
    let summary = format!(
        "ok (gem \"{}\", {}, {}{}{})",
        gem.name,
        counted(gem.materials.len() as u64, "material"),
        counted(gem.map_names.len() as u64, "map"),
        if gem.spec.glitter.is_some() {
            ", glitter"
        } else {
            ""
        },
        match gem.body {
            Body::Opaque => "",
            Body::Translucent { .. } => ", translucent body",
        }
    );
    Ok(Checked { summary, warnings })
}

/// A translucent gem whose surface is a map: the map's materials are not
/// shaded (the look comes from the body), only named in the EXR's
/// `material_id`, which a pattern written for its looks does not expect.
fn unshaded_surface(gem: &Gem) -> Option<String> {
    let spec = &gem.spec;
    let translucent = matches!(spec.body, BodySpec::Translucent { .. });
    (translucent && spec.maps.contains_key(&spec.surface)).then(|| {
        format!(
            "the surface `{}` is a map, but a translucent body's surface is not shaded by \
             its materials (they only name the surface in the EXR's `material_id`): the look \
             comes from the body's `absorption`, `scattering` and `inclusions`",
            spec.surface
        )
    })
}

/// The inline materials and the maps of `gem` that nothing uses (a
/// definition left behind, or a name misspelt where it is used, which the
/// library material of that name then quietly serves): each in words.
fn unused_definitions(gem: &Gem) -> Vec<String> {
    let spec = &gem.spec;
    // Maps reached from the surface's root, through entries, ranges and
    // `per_cell_of`; the materials they, the glitter and the inclusions
    // name.
    let mut reached: HashSet<&str> = HashSet::new();
    let mut used_materials: HashSet<&str> = HashSet::from([spec.surface.as_str()]);
    let mut to_visit = vec![spec.surface.as_str()];
    while let Some(name) = to_visit.pop() {
        let Some(map) = spec.maps.get(name).filter(|_| !reached.contains(&name)) else {
            continue;
        };
        reached.insert(name);
        let (maps, materials): (Vec<_>, Vec<_>) = match map {
            MapSpec::SurfaceMap { entries, .. } => entries
                .iter()
                .map(|e| (e.map.as_deref(), e.material.as_deref()))
                .unzip(),
            MapSpec::Switch {
                ranges,
                per_cell_of,
                ..
            } => ranges
                .iter()
                .map(|r| (r.map.as_deref(), r.material.as_deref()))
                .chain([(per_cell_of.as_deref(), None)])
                .unzip(),
        };
        to_visit.extend(maps.into_iter().flatten());
        used_materials.extend(materials.into_iter().flatten());
    }
    if let Some(glitter) = &spec.glitter {
        used_materials.extend(glitter.entries.iter().filter_map(|e| e.material.as_deref()));
    }
    if let BodySpec::Translucent { inclusions, .. } = &spec.body {
        used_materials.extend(inclusions.iter().map(|i| i.material.as_str()));
    }
    let materials: Vec<String> = spec
        .materials
        .keys()
        .filter(|name| !used_materials.contains(name.as_str()))
        .map(|name| format!("material `{name}` is used nowhere"))
        .collect();
    let maps: Vec<String> = spec
        .maps
        .keys()
        .filter(|name| !reached.contains(name.as_str()))
        .map(|name| format!("map `{name}` is used nowhere (the surface does not reach it)"))
        .collect();
    let mut warnings = Vec::new();
    for (list, kind) in [(materials, "materials"), (maps, "maps")] {
        let count = list.len();
        warnings.extend(list.into_iter().take(MOST_UNUSED_NAMED));
        if count > MOST_UNUSED_NAMED {
            warnings.push(format!(
                "… and {} more {kind} are used nowhere",
                count - MOST_UNUSED_NAMED
            ));
        }
    }
    warnings
}

/// The most unused materials (and maps) named one by one; the rest are
/// counted in one line.
const MOST_UNUSED_NAMED: usize = 10;

/// Validate a material file: parse and compile (without the compensation
/// tables).
fn validate_material(path: &str, name: &str, text: &str) -> Result<Checked, RecipeError> {
    let mut material = parse_material(path, text)?;
    material.multiple_scattering = false;
    let source = MaterialSource {
        path: path.to_string(),
        name: name.to_string(),
        text: text.to_string(),
    };
    compile_material(&source, &material)?;
    let base = match material.base {
        BaseSpec::Diffuse { .. } => "Diffuse",
        BaseSpec::Conductor { .. } => "Conductor",
        BaseSpec::Black => "Black",
    };
    Ok(Checked::from(format!(
        "ok (material, {}, {base} base)",
        counted(material.layers.len() as u64, "layer")
    )))
}

/// A referenced gem or material of a scene that does not load, reported at
/// the place the scene names it, with the inner error after it.
fn reference_error(
    path: &str,
    text: &str,
    written: &str,
    what: &str,
    inner: RecipeError,
) -> RecipeError {
    RecipeError::at_text(
        path,
        text,
        &format!("\"{written}\""),
        format!("{what} `{written}` does not load: {inner}"),
    )
}

/// An environment map's `message` placed at the map's name as `written`
/// in scene file `path` (whose text is `text`).
fn environment_error_at(path: &str, text: &str, written: &str, message: String) -> RecipeError {
    RecipeError::at_text(
        path,
        text,
        &format!("\"{written}\""),
        format!("environment: {message}"),
    )
}

/// `message`, an error of the environment map that scene file `scene`
/// names, placed at that name in the file (as `validate` reports it); as
/// it is where the file no longer reads or names no map.
pub(super) fn place_environment_error(scene: &Path, message: String) -> String {
    let path = scene.display().to_string();
    let Ok(text) = std::fs::read_to_string(scene) else {
        return message;
    };
    match ron::from_str::<SceneSpec>(&text) {
        Ok(SceneSpec {
            environment: EnvironmentKind::File { path: written, .. },
            ..
        }) => environment_error_at(&path, &text, &written, message).to_string(),
        _ => message,
    }
}

/// Validate a scene file: parse and compile it, then check that every gem
/// and the ground material it names exist and validate.
fn validate_scene(path: &str, file: Option<&Path>, text: &str) -> Result<Checked, RecipeError> {
    let scene = parse_scene(text, file).map_err(|mut e| {
        e.path = path.to_string();
        e
    })?;
    // The names as written (the compiled scene holds resolved paths).
    let spec: SceneSpec = ron::from_str(text)
        .map_err(|e| RecipeError::whole_file(path, format!("cannot re-read: {e}")))?;
    // Every stone's gem (each once), the ground's material and the map
    // are checked, and every one that does not load reported.
    let mut errors = Vec::new();
    let mut checked_gems = HashSet::new();
    for (stone, written) in scene.stones.iter().zip(&spec.stones) {
        let (Some(resolved), Some(written)) = (&stone.recipe, &written.recipe) else {
            continue;
        };
        if !checked_gems.insert(resolved.clone()) {
            continue;
        }
        let check = || -> Result<(), RecipeError> {
            let GemSource {
                path: gem_path,
                text: gem_text,
            } = GemSource::load(resolved)
                .map_err(|e| reference_error(path, text, written, "gem", e))?;
            let kind = recipe_kind(&gem_path, &gem_text)
                .map_err(|e| reference_error(path, text, written, "gem", e))?;
            if kind != RecipeKind::Gem {
                return Err(RecipeError::at_text(
                    path,
                    text,
                    &format!("\"{written}\""),
                    format!("`recipe` `{written}` is a {kind:?} file; allowed: a gem recipe (`Gem(`) or a built-in gem"),
                ));
            }
            validate_gem(&gem_path, &gem_text)
                .map_err(|e| reference_error(path, text, written, "gem", e))?;
            Ok(())
        };
        errors.extend(check().err());
    }
    if let (Some(ground), Some(written)) = (&scene.ground, &spec.ground) {
        let check = || -> Result<Checked, RecipeError> {
            let source = locate_material(&ground.material)?;
            validate_material(&source.path, &source.name, &source.text)
        };
        let checked = check()
            .map_err(|e| reference_error(path, text, &written.material, "ground material", e));
        errors.extend(checked.err());
    }
    // The map is read as a render reads it: a damaged file is found here,
    // not by every task of a farm array.
    let mut map_warning = None;
    if let (
        EnvironmentSpec::File {
            path: map,
            rotation_deg,
            intensity,
        },
        EnvironmentKind::File { path: written, .. },
    ) = (&scene.environment, &spec.environment)
    {
        match Environment::from_file(map, *rotation_deg, *intensity) {
            Ok(environment) => {
                map_warning = environment
                    .proportion_warning()
                    .map(|w| format!("{path}: warning: environment map {written}: {w}"));
            }
            Err(e) => errors.push(environment_error_at(path, text, written, e.to_string())),
        }
    }
    if let Some(error) = RecipeError::all(errors) {
        return Err(error);
    }
    let n = scene.stones.len();
    let l = scene.lights.len();
    // Placement: valid, but a sunk or crossing stone is worth a warning.
    let stones = stone_instances(&scene).map_err(|e| RecipeError::whole_file(path, e))?;
    let world = World::new(stones, scene.ground.as_ref().map(|g| g.height));
    let warnings = placement_problems(&world)
        .iter()
        .chain(&viewpoint_problems(&world, &scene))
        .map(|problem| format!("{path}: warning: {problem}"))
        .chain(map_warning)
        .collect();
    let summary = format!(
        "ok (scene, {}, {}{})",
        counted(n as u64, "stone"),
        counted(l as u64, "light"),
        if scene.ground.is_some() {
            ", ground"
        } else {
            ""
        }
    );
    Ok(Checked { summary, warnings })
}

/// Validate one text of known display path; `file` is the file on disk
/// (for a scene's relative paths), `None` for built-ins and texts not yet
/// written (`lapidary new`).
pub fn validate_text(
    path: &str,
    file: Option<&Path>,
    name: &str,
    text: &str,
) -> Result<Checked, RecipeError> {
    match recipe_kind(path, text)? {
        RecipeKind::Gem => validate_gem(path, text),
        RecipeKind::Material => validate_material(path, name, text),
        RecipeKind::Scene => validate_scene(path, file, text),
        RecipeKind::Job => validate_job(path, file.unwrap_or(Path::new(path)), text),
    }
}

/// Validate a batch job: the job itself ([`Job::load`]: fields, ranges,
/// image names, the task count) and every recipe and scene it names
/// ([`check_job_inputs`]).
pub fn validate_job(path: &str, file: &Path, text: &str) -> Result<Checked, RecipeError> {
    let job = Job::load(file)?;
    let warnings = check_job_inputs(path, text, &job)?;
    let summary = format!(
        "ok (job, {}: {} × {} × {})",
        counted(job.task_count(), "task"),
        counted(job.images.len() as u64, "image"),
        counted(job.turntable.map_or(1, |t| t.frames), "frame"),
        counted(job.tiles, "tile")
    );
    Ok(Checked { summary, warnings })
}

/// Every recipe and scene of `job` (read from `text` at `path`), each as
/// `validate` checks it, so that a farm array never starts on a broken
/// input; an input's error is placed where the job names it. Returns the
/// scenes' warnings (`FILE: warning: …`, a sunk stone, a camera inside a
/// light), each once.
pub fn check_job_inputs(path: &str, text: &str, job: &Job) -> Result<Vec<String>, RecipeError> {
    let recipes = job
        .images
        .iter()
        .map(|image| ("recipe", image.recipe.clone()));
    let scenes = job
        .images
        .iter()
        .filter_map(|image| image.scene.as_ref())
        .map(|scene| ("scene", scene.display().to_string()));
    // A task renders one tile, whose film must fit in what a task may
    // take; the tallest tile of each image decides.
    // Tiles hold whole rows: no more of them than the lowest image's rows.
    let most_tiles = job
        .images
        .iter()
        .map(|i| i.settings.height)
        .min()
        .unwrap_or(1);
    for image in &job.images {
        let settings = &image.settings;
        let rows = settings.height.div_ceil(job.tiles);
        let needed = super::memory::render_needs(settings.width, rows);
        let limit = super::render::DEFAULT_MAX_MEMORY_GIB;
        if super::memory::gib(needed) > limit {
            let per_row = super::memory::render_needs(settings.width, 1) as f64;
            let most_rows = ((limit * f64::from(1u32 << 30) / per_row).floor() as u32).max(1);
            let tiles_needed = settings.height.div_ceil(most_rows);
            let allowed = if tiles_needed <= most_tiles {
                format!(
                    "allowed: `tiles` from {tiles_needed} (`tiles` = {} now)",
                    job.tiles
                )
            } else {
                format!(
                    "it needs {tiles_needed} tiles, but an image {most_tiles} rows high allows at most {most_tiles}: give the large image a job of its own"
                )
            };
            return Err(RecipeError::at_text(
                path,
                text,
                "tiles",
                format!(
                    "image `{}`: a tile of {} × {rows} pixels needs {} of memory for its film, above the {limit} GiB a task may take; {allowed}",
                    image.name,
                    settings.width,
                    super::memory::amount(needed)
                ),
            ));
        }
    }
    let mut checked = HashSet::new();
    let mut warnings = Vec::new();
    // Every input is checked, and every one that does not load reported.
    let mut errors = Vec::new();
    for (what, spec) in recipes.chain(scenes) {
        if !checked.insert(spec.clone()) {
            continue;
        }
        let checked_ok = if what == "recipe" {
            GemSource::load(&spec).and_then(|source| validate_gem(&source.path, &source.text))
        } else {
            read_ron_file(&spec, "scene file")
                .and_then(|text| validate_scene(&spec, Some(Path::new(&spec)), &text))
        };
        match checked_ok {
            Ok(checked) => warnings.extend(checked.warnings),
            Err(e) => {
                // Where the job names it: a built-in's name in quotes, a
                // file's name (the job may write a folder before it).
                let written = if names_a_file(&spec) {
                    Path::new(&spec)
                        .file_name()
                        .map_or(spec.clone(), |n| n.to_string_lossy().into_owned())
                } else {
                    format!("\"{spec}\"")
                };
                errors.push(RecipeError::at_text(
                    path,
                    text,
                    &written,
                    format!("{what} `{spec}` does not load: {e}"),
                ));
            }
        }
    }
    RecipeError::all(errors).map_or(Ok(warnings), Err)
}

/// Validate one command-line argument (a file or a built-in name); returns
/// the display path and what was found, or the error.
pub fn validate_one(spec: &str) -> Result<(String, Checked), RecipeError> {
    if names_a_file(spec) {
        let text = read_ron_file(spec, "recipe (gem, material, scene or job)")?;
        let name = Path::new(spec)
            .file_stem()
            .map_or(spec.to_string(), |s| s.to_string_lossy().into_owned());
        let checked = validate_text(spec, Some(Path::new(spec)), &name, &text)?;
        return Ok((spec.to_string(), checked));
    }
    let builtin = |prefix: &str| format!("builtin:{prefix}");
    if let Some(text) = builtin_gem_source(spec) {
        let path = builtin(spec);
        return validate_gem(&path, text).map(|s| (path, s));
    }
    if let Some(text) = builtin_material_source(spec) {
        let path = builtin(spec);
        return validate_material(&path, spec, text).map(|s| (path, s));
    }
    if spec == BUILTIN_SCENE_NAME {
        let path = builtin(spec);
        return validate_scene(&path, None, DEFAULT_SCENE_SOURCE).map(|s| (path, s));
    }
    let names: Vec<&str> = builtin_gem_names()
        .chain(builtin_material_names())
        .chain([BUILTIN_SCENE_NAME])
        .collect();
    let hint = did_you_mean(spec, names.iter().copied())
        .map(|s| format!(" (did you mean `{s}`?)"))
        .unwrap_or_default();
    Err(RecipeError::whole_file(
        spec,
        format!(
            "no such file and no built-in gem, material or scene of that name{}{hint}; built-in: {}",
            folder_separator_hint(spec),
            names.join(", ")
        ),
    ))
}

/// The inputs of `validate`: each argument, a folder replaced by its
/// `.ron` files (not those of its subfolders), in name order; a folder
/// without any, or unreadable, is an error of its own.
fn inputs(specs: &[String]) -> Vec<Result<String, RecipeError>> {
    let mut inputs = Vec::new();
    for spec in specs {
        if !Path::new(spec).is_dir() {
            inputs.push(Ok(spec.clone()));
            continue;
        }
        let files = std::fs::read_dir(spec).map(|entries| {
            let mut files: Vec<String> = entries
                .filter_map(|entry| entry.ok().map(|entry| entry.path()))
                // Files, and what is not a folder (a link to nothing, a
                // pipe), which reading then reports.
                .filter(|path| {
                    !path.is_dir()
                        && path
                            .extension()
                            .is_some_and(|e| e.eq_ignore_ascii_case("ron"))
                })
                .map(|path| path.display().to_string())
                .collect();
            files.sort();
            files
        });
        match files {
            Ok(files) if !files.is_empty() => inputs.extend(files.into_iter().map(Ok)),
            Ok(_) => inputs.push(Err(RecipeError::whole_file(
                spec,
                "a folder without .ron files (its subfolders are not read)",
            ))),
            Err(e) => inputs.push(Err(RecipeError::whole_file(
                spec,
                format!("cannot read the folder: {e}"),
            ))),
        }
    }
    inputs
}

/// Run `lapidary validate`: one line per input (a folder's `.ron` files
/// each), on stdout for valid ones and stderr for errors and warnings;
/// fails when any input has an error.
pub fn run(recipes: &[String]) -> Result<(), String> {
    let mut failed = 0;
    let inputs = inputs(recipes);
    for spec in &inputs {
        match spec
            .as_ref()
            .map_err(Clone::clone)
            .and_then(|spec| validate_one(spec))
        {
            Ok((path, checked)) => {
                // The ok line on stdout, its warnings on stderr with the
                // errors (they stay seen under `> /dev/null`).
                super::emit(&format!("{path}: {}", checked.summary));
                for warning in &checked.warnings {
                    eprintln!("{warning}");
                }
            }
            Err(e) => {
                eprintln!("{e}");
                failed += 1;
            }
        }
    }
    if failed == 0 {
        Ok(())
    } else {
        Err(format!(
            "{failed} of {} ha{} errors",
            counted(inputs.len() as u64, "input"),
            if failed == 1 { "s" } else { "ve" }
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kind_is_read_after_comments_and_whitespace() {
        let text = "// a note: Material(\n/* Scene( */\n  Gem(surface: \"gold\")";
        assert_eq!(recipe_kind("t", text), Ok(RecipeKind::Gem));
        assert_eq!(
            recipe_kind("t", "#![enable(implicit_some)]\nScene()"),
            Ok(RecipeKind::Scene)
        );
    }

    #[test]
    fn an_unnamed_top_level_struct_is_located_and_explained() {
        let e = recipe_kind("t.ron", "// x\n  (base: Black)").unwrap_err();
        assert_eq!(e.position, Some((2, 3)));
        assert!(e.message.contains("`Gem(`"), "{e}");
        let e = recipe_kind("t.ron", "Materail(base: Black)").unwrap_err();
        assert!(e.message.contains("did you mean `Material`"), "{e}");
    }

    #[test]
    fn an_empty_file_says_so() {
        let e = recipe_kind("t.ron", " \n").unwrap_err();
        assert!(e.message.contains("empty"), "{e}");
        let e = recipe_kind("t.ron", "// only\n").unwrap_err();
        assert!(e.message.contains("only comments"), "{e}");
    }
}
