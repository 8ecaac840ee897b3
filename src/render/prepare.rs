//! Compiling what the integrator needs from recipes: gems (pattern and
//! BRDFs) and single materials (the ground).

use std::path::Path;

use crate::geometry::Cabochon;
use crate::render::camera::PinholeCamera;
use crate::render::environment::Environment;
use crate::render::integrator::{RenderScene, MATERIAL_ID_FIRST_STONE};
use crate::render::world::{StoneInstance, World};
use crate::scene::{EnvironmentSpec, Scene};

use crate::brdf::LayeredBrdf;
use crate::recipe::compile::{
    compile_material_without_table, load_material_without_table, MaterialSource, COMPENSATION_SEED,
};
use crate::recipe::error::RecipeError;
use crate::recipe::gem::{load_gem_source, parse_gem_with_seed};
use crate::render::integrator::GemShading;

/// Loads gem `spec` (a built-in name or a `.ron` path), optionally with
/// another seed, and compiles every material's BRDF (the layered materials'
/// multiple-scattering compensation tables together, in parallel).
/// `material_id_base` is the `material_id` AOV value of its material 0.
pub fn compile_gem(
    spec: &str,
    seed: Option<u64>,
    material_id_base: u32,
) -> Result<(GemShading, String), RecipeError> {
    let (path, text) = load_gem_source(spec)?;
    compile_gem_source(&path, &text, seed, material_id_base)
}

/// [`compile_gem`] for recipe `text` already read from `path`.
pub fn compile_gem_source(
    path: &str,
    text: &str,
    seed: Option<u64>,
    material_id_base: u32,
) -> Result<(GemShading, String), RecipeError> {
    compile_gem_draft_or_full(path, text, seed, material_id_base, false)
}

/// [`compile_gem_source`]; with `draft`, every material is compiled without
/// its multiple-scattering compensation table (several times quicker, a
/// little darker: for previews and tests, never for final pictures).
pub fn compile_gem_draft_or_full(
    path: &str,
    text: &str,
    seed: Option<u64>,
    material_id_base: u32,
    draft: bool,
) -> Result<(GemShading, String), RecipeError> {
    let mut gem = gem_without_tables(path, text, seed, material_id_base, draft)?;
    fill_tables(gem.wanting_tables().collect());
    Ok((gem.shading, gem.name))
}

/// A gem compiled without its materials' compensation tables, so that the
/// tables of a whole scene can be computed together.
struct GemWithoutTables {
    shading: GemShading,
    name: String,
    /// Per material of `shading.brdfs`, whether it wants a table.
    wants_table: Vec<bool>,
}

impl GemWithoutTables {
    /// The materials that want a compensation table.
    fn wanting_tables(&mut self) -> impl Iterator<Item = &mut LayeredBrdf> {
        self.shading
            .brdfs
            .iter_mut()
            .zip(&self.wants_table)
            .filter_map(|(brdf, wants)| wants.then_some(brdf))
    }
}

/// Parses gem recipe `text` (from `path`) and compiles its materials
/// without their tables; with `draft` none of them wants one.
fn gem_without_tables(
    path: &str,
    text: &str,
    seed: Option<u64>,
    material_id_base: u32,
    draft: bool,
) -> Result<GemWithoutTables, RecipeError> {
    let gem = parse_gem_with_seed(path, text, seed)?;
    let mut brdfs = Vec::with_capacity(gem.materials.len());
    let mut wants_table = Vec::with_capacity(gem.materials.len());
    for (name, material) in &gem.materials {
        let source = MaterialSource {
            path: path.to_string(),
            name: name.clone(),
            text: text.to_string(),
        };
        brdfs.push(compile_material_without_table(&source, material)?);
        wants_table.push(material.multiple_scattering && !draft);
    }
    Ok(GemWithoutTables {
        shading: GemShading {
            pattern: gem.pattern,
            brdfs,
            material_id_base,
        },
        name: gem.name,
        wants_table,
    })
}

/// Gives every material of `brdfs` its compensation table, all computed
/// together (node by node in one parallel loop, each distinct material
/// once; see [`crate::brdf::cache::compensations`]): what
/// [`LayeredBrdf::with_compensation`] gives each one alone.
fn fill_tables(mut brdfs: Vec<&mut LayeredBrdf>) {
    let requests: Vec<(&LayeredBrdf, u64)> = brdfs
        .iter()
        .map(|brdf| (&**brdf, COMPENSATION_SEED))
        .collect();
    let tables = crate::brdf::cache::compensations(&requests);
    for (brdf, table) in brdfs.iter_mut().zip(tables) {
        brdf.compensation = table;
    }
}

/// Builds everything the integrator reads from a compiled scene.
///
/// Stones without a recipe use `default_gem`; `environment_file`, when
/// given, replaces the scene's environment (the `--env` option). Each
/// distinct (gem, seed) pair is compiled once. `report` hears what is being
/// compiled (slow layered materials tabulate their compensation). The
/// compensation tables of every gem and of the ground are computed together
/// while the environment is built (baked or loaded) beside them.
pub fn prepare_scene(
    scene: &Scene,
    default_gem: &str,
    environment_file: Option<&Path>,
    max_bounces: u32,
    report: &dyn Fn(&str),
) -> Result<RenderScene, String> {
    let mut keys: Vec<(String, Option<u64>)> = Vec::new();
    let mut stones = stone_instances(scene)?;
    for (stone, instance) in scene.stones.iter().zip(&mut stones) {
        let key = (
            stone
                .recipe
                .clone()
                .unwrap_or_else(|| default_gem.to_string()),
            stone.seed,
        );
        instance.gem = match keys.iter().position(|k| *k == key) {
            Some(i) => i,
            None => {
                keys.push(key);
                keys.len() - 1
            }
        };
    }
    let mut gems = Vec::with_capacity(keys.len());
    let mut material_id_base = MATERIAL_ID_FIRST_STONE;
    for (spec, seed) in &keys {
        report(&format!("compiling gem {spec}"));
        let (path, text) = load_gem_source(spec).map_err(|e| e.to_string())?;
        let gem = gem_without_tables(&path, &text, *seed, material_id_base, false)
            .map_err(|e| e.to_string())?;
        material_id_base += gem.shading.brdfs.len() as u32;
        gems.push(gem);
    }
    let mut ground = match &scene.ground {
        Some(ground) => {
            Some(load_material_without_table(&ground.material).map_err(|e| e.to_string())?)
        }
        None => None,
    };
    let ((), environment) = rayon::join(
        || {
            let ground_wanting = ground
                .iter_mut()
                .filter_map(|(brdf, wants)| wants.then_some(brdf));
            fill_tables(
                gems.iter_mut()
                    .flat_map(GemWithoutTables::wanting_tables)
                    .chain(ground_wanting)
                    .collect(),
            );
        },
        || match environment_file {
            Some(path) => Environment::from_file(path, 0.0, 1.0).map_err(|e| e.to_string()),
            None => environment_for_spec(&scene.environment),
        },
    );
    Ok(RenderScene {
        world: World::new(stones, scene.ground.as_ref().map(|g| g.height)),
        gems: gems.into_iter().map(|gem| gem.shading).collect(),
        ground_brdf: ground.map(|(brdf, _)| brdf),
        lights: scene.lights.clone(),
        environment: environment?,
        max_bounces,
        ambient_occlusion: None,
    })
}

/// The scene's stones, placed, every one shaded by gem 0 (callers with
/// several gems reassign [`StoneInstance::gem`]).
pub fn stone_instances(scene: &Scene) -> Result<Vec<StoneInstance>, String> {
    scene
        .stones
        .iter()
        .map(|stone| {
            Ok(StoneInstance {
                cabochon: Cabochon::new(stone.shape).map_err(|e| e.to_string())?,
                rotation: stone.rotation,
                position: stone.position,
                gem: 0,
            })
        })
        .collect()
}

/// The environment a scene describes, built (the studio baked, a file
/// loaded and checked).
pub fn environment_for_spec(spec: &EnvironmentSpec) -> Result<Environment, String> {
    match spec {
        EnvironmentSpec::Constant(radiance) => {
            Environment::try_constant(*radiance).map_err(|e| e.to_string())
        }
        EnvironmentSpec::Studio {
            intensity,
            rotation_deg,
        } => Environment::try_studio(*intensity, *rotation_deg).map_err(|e| e.to_string()),
        EnvironmentSpec::File {
            path,
            rotation_deg,
            intensity,
        } => Environment::from_file(path, *rotation_deg, *intensity).map_err(|e| e.to_string()),
    }
}

/// The scene camera on a film of `width × height` pixels.
pub fn camera_for(scene: &Scene, width: u32, height: u32) -> PinholeCamera {
    let c = &scene.camera;
    PinholeCamera::new(
        c.position,
        c.look_at,
        c.up,
        c.vertical_fov_deg,
        width,
        height,
    )
}
