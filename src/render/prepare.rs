//! Compiling what the integrator needs from recipes: gems (pattern and
//! BRDFs) and single materials (the ground).

use rayon::prelude::*;

use crate::brdf::LayeredBrdf;
use crate::recipe::compile::{compile_material, MaterialSource};
use crate::recipe::error::RecipeError;
use crate::recipe::gem::{load_gem_source, parse_gem_with_seed};
use crate::render::integrator::GemShading;

/// Loads gem `spec` (a built-in name or a `.ron` path), optionally with
/// another seed, and compiles every material's BRDF (in parallel: each
/// layered material tabulates its multiple-scattering compensation).
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
    let gem = parse_gem_with_seed(path, text, seed)?;
    let brdfs = gem
        .materials
        .par_iter()
        .map(|(name, material)| {
            let source = MaterialSource {
                path: path.to_string(),
                name: name.clone(),
                text: text.to_string(),
            };
            compile_material(&source, material)
        })
        .collect::<Result<Vec<LayeredBrdf>, RecipeError>>()?;
    Ok((
        GemShading {
            pattern: gem.pattern,
            brdfs,
            material_id_base,
        },
        gem.name,
    ))
}
