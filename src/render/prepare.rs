//! Compiling what the integrator needs from recipes: gems (pattern and
//! BRDFs) and single materials (the ground).

use std::path::Path;
use std::sync::Arc;

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
use crate::recipe::gem::{compile_gem_spec, load_gem_source, parse_gem_spec, GemSpec};
use crate::render::integrator::GemShading;
use crate::texture::pattern::Pattern;

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
    let spec = parse_gem_spec(path, text)?;
    let mut gem = gem_without_tables((path, text, spec), seed, material_id_base, draft, None)?;
    fill_tables(gem.wanting_tables().collect());
    Ok(finish_gems(vec![gem]).remove(0))
}

/// A gem compiled without its materials' compensation tables, so that the
/// tables of a whole scene can be computed together.
struct GemWithoutTables {
    pattern: Pattern,
    /// The materials' BRDFs; empty when `shares_brdfs_of` is set.
    brdfs: Vec<LayeredBrdf>,
    /// The gem (an index into the scene's gems) of the same recipe with
    /// another seed whose BRDFs this one uses.
    shares_brdfs_of: Option<usize>,
    material_id_base: u32,
    name: String,
    /// Per material of `brdfs`, whether it wants a table.
    wants_table: Vec<bool>,
}

impl GemWithoutTables {
    /// The materials that want a compensation table.
    fn wanting_tables(&mut self) -> impl Iterator<Item = &mut LayeredBrdf> {
        self.brdfs
            .iter_mut()
            .zip(&self.wants_table)
            .filter_map(|(brdf, wants)| wants.then_some(brdf))
    }
}

/// The finished gems of a scene: each recipe's BRDFs once, shared by its
/// other seeds.
fn finish_gems(gems: Vec<GemWithoutTables>) -> Vec<(GemShading, String)> {
    let mut finished: Vec<(GemShading, String)> = Vec::with_capacity(gems.len());
    for gem in gems {
        let brdfs = match gem.shares_brdfs_of {
            Some(first) => Arc::clone(&finished[first].0.brdfs),
            None => Arc::from(gem.brdfs),
        };
        finished.push((
            GemShading {
                pattern: gem.pattern,
                brdfs,
                material_id_base: gem.material_id_base,
            },
            gem.name,
        ));
    }
    finished
}

/// Compiles gem `spec` (read from recipe `text` at `path`) and its
/// materials without their tables; with `draft` none of them wants one.
/// With `shares_brdfs_of`, the gem of that index (the same recipe, another
/// seed) lends its BRDFs and only the pattern is compiled: a seed changes
/// the pattern, never a material.
fn gem_without_tables(
    (path, text, spec): (&str, &str, GemSpec),
    seed: Option<u64>,
    material_id_base: u32,
    draft: bool,
    shares_brdfs_of: Option<usize>,
) -> Result<GemWithoutTables, RecipeError> {
    let gem = compile_gem_spec(path, text, spec, seed)?;
    let mut brdfs = Vec::new();
    let mut wants_table = Vec::new();
    if shares_brdfs_of.is_none() {
        for (name, material) in &gem.materials {
            let source = MaterialSource {
                path: path.to_string(),
                name: name.clone(),
                text: text.to_string(),
            };
            brdfs.push(compile_material_without_table(&source, material)?);
            wants_table.push(material.multiple_scattering && !draft);
        }
    }
    Ok(GemWithoutTables {
        pattern: gem.pattern,
        brdfs,
        shares_brdfs_of,
        material_id_base,
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
/// given, replaces the scene's environment (the `--env` option). Each gem
/// recipe is read and its materials compiled once; each distinct (gem,
/// seed) pair gets its own pattern and shares the recipe's BRDFs. `report`
/// hears what is being compiled (slow layered materials tabulate their
/// compensation). The compensation tables of every gem and of the ground
/// are computed together while the environment is built (baked or loaded)
/// beside them.
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
    let mut gems: Vec<GemWithoutTables> = Vec::with_capacity(keys.len());
    // Per recipe, read once: its name, path, text and spec, and its first gem.
    let mut recipes: Vec<(&str, String, String, GemSpec, usize)> = Vec::new();
    let mut material_id_base = MATERIAL_ID_FIRST_STONE;
    for (name, seed) in &keys {
        let recipe = match recipes.iter().position(|r| r.0 == name) {
            Some(i) => i,
            None => {
                report(&format!("compiling gem {name}"));
                let (path, text) = load_gem_source(name).map_err(|e| e.to_string())?;
                let spec = parse_gem_spec(&path, &text).map_err(|e| e.to_string())?;
                recipes.push((name, path, text, spec, gems.len()));
                recipes.len() - 1
            }
        };
        let (_, path, text, spec, first) = &recipes[recipe];
        let shares_brdfs_of = (*first != gems.len()).then_some(*first);
        let gem = gem_without_tables(
            (path, text, spec.clone()),
            *seed,
            material_id_base,
            false,
            shares_brdfs_of,
        )
        .map_err(|e| e.to_string())?;
        let first = gem.shares_brdfs_of.map_or(&gem, |first| &gems[first]);
        material_id_base += first.brdfs.len() as u32;
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
        gems: finish_gems(gems)
            .into_iter()
            .map(|(shading, _)| shading)
            .collect(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;
    use glam::DVec3;

    /// Three stones: the default gem with seeds 1 and 2, then goldstone.
    const THREE_STONES: &str = r#"Scene(
        camera: Orbit(target: (0.0, 0.0, 0.0), distance: 5.0, elevation_deg: 35.0,
                      azimuth_deg: -90.0, vertical_fov_deg: 30.0),
        stones: [
            Stone(shape: Cabochon(outline: Oval, length: 1.0, width: 0.7, dome_height: 0.3),
                  position: (-1.0, 0.0, 0.0), seed: Some(1)),
            Stone(shape: Cabochon(outline: Oval, length: 1.0, width: 0.7, dome_height: 0.3),
                  position: (0.0, 0.0, 0.0), seed: Some(2)),
            Stone(recipe: Some("goldstone"),
                  shape: Cabochon(outline: Oval, length: 1.0, width: 0.7, dome_height: 0.3),
                  position: (1.0, 0.0, 0.0)),
        ],
        lights: [],
        environment: Constant(radiance: (1.0, 1.0, 1.0)),
    )"#;

    #[test]
    fn seeds_of_one_recipe_share_its_brdfs_and_keep_their_own_patterns() {
        let scene = parse_scene(THREE_STONES, None).unwrap();
        let prepared = prepare_scene(&scene, "green-aventurine", None, 2, &|_| {}).unwrap();
        let gems = &prepared.gems;
        assert_eq!(gems.len(), 3);
        assert!(Arc::ptr_eq(&gems[0].brdfs, &gems[1].brdfs));
        assert!(!Arc::ptr_eq(&gems[0].brdfs, &gems[2].brdfs));
        // material_id AOV values: each gem its own run, as without sharing.
        assert_eq!(gems[0].material_id_base, MATERIAL_ID_FIRST_STONE);
        let n = gems[0].brdfs.len() as u32;
        assert_eq!(gems[1].material_id_base, MATERIAL_ID_FIRST_STONE + n);
        assert_eq!(gems[2].material_id_base, MATERIAL_ID_FIRST_STONE + 2 * n);

        // The shared BRDFs are those of seed 2 compiled alone, bit for bit,
        // compensation tables included.
        let (alone, _) = compile_gem("green-aventurine", Some(2), 0).unwrap();
        assert_eq!(alone.brdfs.len(), gems[1].brdfs.len());
        let (wi, wo) = (
            DVec3::new(0.3, -0.2, 0.9).normalize(),
            DVec3::new(-0.5, 0.1, 0.7).normalize(),
        );
        for (a, b) in alone.brdfs.iter().zip(gems[1].brdfs.iter()) {
            assert_eq!(a.compensation.is_some(), b.compensation.is_some());
            assert_eq!(a.eval(wi, wo), b.eval(wi, wo), "{}", a.name);
            assert_eq!(a.pdf(wi, wo), b.pdf(wi, wo), "{}", a.name);
        }

        // The seeds still change the pattern: the surface cells differ.
        let differing = (0..64)
            .map(|i| DVec3::new(0.013 * f64::from(i), 0.007 * f64::from(i), 0.02))
            .filter(|p| {
                gems[0].pattern.resolve(*p).surface_cell != gems[1].pattern.resolve(*p).surface_cell
            })
            .count();
        assert!(differing > 32, "only {differing} of 64 points differ");
    }
}
