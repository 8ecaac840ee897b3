//! Building what the integrator reads from a scene: its gems compiled
//! through [`crate::recipe::gem::compile_gems`], the ground's material, the
//! placed stones, the environment and the camera.

use std::path::Path;

use crate::geometry::Cabochon;
use crate::recipe::compile::load_material_without_table;
use crate::recipe::gem::{compile_gems, GemSource};
use crate::recipe::Tables;
use crate::render::camera::PinholeCamera;
use crate::render::environment::Environment;
use crate::render::render_scene::RenderScene;
use crate::render::world::{StoneInstance, World};
use crate::scene::{EnvironmentSpec, Scene};

/// Why a scene could not be prepared or rendered: a setting out of its
/// range, or a scene or recipe that does not load. The message names the
/// file, line, field and what is allowed, as the command's errors do.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct RenderError {
    /// The whole message.
    pub message: String,
}

impl From<String> for RenderError {
    fn from(message: String) -> Self {
        RenderError { message }
    }
}

impl From<RenderError> for String {
    fn from(error: RenderError) -> Self {
        error.message
    }
}

/// Builds everything the integrator reads from a compiled scene.
///
/// Stones without a recipe use `default_gem` (loaded by
/// [`GemSource::load`]); `environment_file`, when
/// given, replaces the scene's environment (the `--env` option). Each gem
/// recipe is read and its materials compiled once; each distinct (gem,
/// seed) pair gets its own pattern and shares the recipe's BRDFs
/// ([`compile_gems`]). `report` hears what is being compiled (slow layered
/// materials tabulate their compensation). The compensation tables of
/// every gem and of the ground are computed together, with `tables`, while
/// the environment is built (baked or loaded) beside them.
pub fn prepare_scene(
    scene: &Scene,
    default_gem: &GemSource,
    environment_file: Option<&Path>,
    max_bounces: u32,
    tables: Tables<'_>,
    report: &dyn Fn(&str),
) -> Result<RenderScene, RenderError> {
    scene.check()?;
    // Each distinct (recipe, seed) is one gem; `None` is `default_gem`.
    let mut keys: Vec<(Option<&str>, Option<u64>)> = Vec::new();
    let mut stones = stone_instances(scene)?;
    for (stone, instance) in scene.stones.iter().zip(&mut stones) {
        let key = (stone.recipe.as_deref(), stone.seed);
        instance.gem = match keys.iter().position(|k| *k == key) {
            Some(i) => i,
            None => {
                keys.push(key);
                keys.len() - 1
            }
        };
    }
    // Each recipe read once; `source_of_key[k]` is key k's in `sources`.
    let mut sources: Vec<(Option<&str>, GemSource)> = Vec::new();
    let mut source_of_key = Vec::with_capacity(keys.len());
    for (recipe, _) in &keys {
        let index = match sources.iter().position(|(r, _)| r == recipe) {
            Some(index) => index,
            None => {
                let source = match recipe {
                    Some(name) => GemSource::load(name).map_err(|e| e.to_string())?,
                    None => default_gem.clone(),
                };
                report(&format!(
                    "compiling gem {}",
                    source.path.strip_prefix("builtin:").unwrap_or(&source.path)
                ));
                sources.push((*recipe, source));
                sources.len() - 1
            }
        };
        source_of_key.push(index);
    }
    let requests: Vec<(&GemSource, Option<u64>)> = keys
        .iter()
        .zip(&source_of_key)
        .map(|((_, seed), &index)| (&sources[index].1, *seed))
        .collect();
    let mut ground = match &scene.ground {
        Some(ground) => {
            Some(load_material_without_table(&ground.material).map_err(|e| e.to_string())?)
        }
        None => None,
    };
    let (gems, environment) = rayon::join(
        || {
            let mut ground_wanting: Vec<&mut crate::brdf::LayeredBrdf> = ground
                .iter_mut()
                .filter_map(|(brdf, wants)| wants.then_some(brdf))
                .collect();
            compile_gems(&requests, tables, &mut ground_wanting).map_err(|e| e.to_string())
        },
        || match environment_file {
            Some(path) => Environment::from_file(path, 0.0, 1.0).map_err(|e| e.to_string()),
            None => environment_for_spec(&scene.environment),
        },
    );
    let gems = gems?;
    let environment = environment?;
    if let Environment::Map(map) = &environment {
        if let Some((texels, share)) = map.sampled_apart() {
            report(&format!(
                "environment map: its {} {:.1} % of its power (a sun): sampled apart from \
                 the rest where the camera sees a surface",
                if texels == 1 {
                    "brightest texel holds".to_string()
                } else {
                    format!("{texels} brightest texels hold")
                },
                100.0 * share
            ));
        }
    }
    Ok(RenderScene {
        world: World::new(stones, scene.ground.as_ref().map(|g| g.height)),
        material_id_bases: RenderScene::material_id_bases(&gems),
        gems,
        ground_brdf: ground.map(|(brdf, _)| brdf),
        lights: scene.lights.clone(),
        environment,
        max_bounces,
        ambient_occlusion: None,
        connect_through_surfaces: true,
        flake_lobes: crate::render::flake_lobe::FlakeLobes::default(),
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
pub(crate) fn environment_for_spec(spec: &EnvironmentSpec) -> Result<Environment, String> {
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
    use crate::recipe::gem::compile_gem;
    use crate::recipe::TableCache;
    use crate::render::render_scene::MATERIAL_ID_FIRST_STONE;
    use crate::scene::parse_scene;
    use glam::DVec3;
    use std::sync::Arc;

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
        let cache = TableCache::in_memory();
        let tables = Tables::Computed(&cache);
        let default_gem = GemSource::load("lavender-lepidolite").unwrap();
        let prepared = prepare_scene(&scene, &default_gem, None, 2, tables, &|_| {}).unwrap();
        let gems = &prepared.gems;
        assert_eq!(gems.len(), 3);
        assert!(Arc::ptr_eq(&gems[0].brdfs, &gems[1].brdfs));
        assert!(!Arc::ptr_eq(&gems[0].brdfs, &gems[2].brdfs));
        // material_id AOV values: each gem its own run, as without sharing.
        let bases = &prepared.material_id_bases;
        assert_eq!(bases[0], MATERIAL_ID_FIRST_STONE);
        let n = gems[0].brdfs.len() as u32;
        assert_eq!(bases[1], MATERIAL_ID_FIRST_STONE + n);
        assert_eq!(bases[2], MATERIAL_ID_FIRST_STONE + 2 * n);

        // The shared BRDFs are those of seed 2 compiled alone, bit for bit,
        // compensation tables included (computed afresh, not from the cache).
        let source = GemSource::load("lavender-lepidolite").unwrap();
        let fresh = TableCache::in_memory();
        let alone = compile_gem(&source, Some(2), Tables::Computed(&fresh)).unwrap();
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
