//! `lapidary list` and `lapidary classify`.

use lapidary::brdf::classify::classify as classify_brdf;
use lapidary::recipe::compile::{compile_material, locate_material, parse_material};
use lapidary::recipe::library::{builtin_gem_names, builtin_gem_source, builtin_material_names};

/// Load a material without its compensation tables (classification and
/// listing need only the parameters).
fn load_parameters(spec: &str) -> Result<lapidary::brdf::LayeredBrdf, String> {
    let source = locate_material(spec).map_err(|e| e.to_string())?;
    let mut material = parse_material(&source.path, &source.text).map_err(|e| e.to_string())?;
    material.multiple_scattering = false;
    compile_material(&source, &material).map_err(|e| e.to_string())
}

/// Print the class of MATERIAL and the reason.
pub fn classify(spec: &str) -> Result<(), String> {
    let brdf = load_parameters(spec)?;
    let class = classify_brdf(&brdf);
    super::emit(&format!("{}: {}", brdf.name, class));
    super::emit(&format!("because: {}", class.reason));
    Ok(())
}

/// Print every built-in material with its class.
pub fn list() -> Result<(), String> {
    super::emit("Materials (gem-recipes/materials/, built in):");
    for name in builtin_material_names() {
        let brdf = load_parameters(name)?;
        super::emit(&format!("  {name:<26} {}", classify_brdf(&brdf)));
    }
    super::emit("Gems (gem-recipes/, built in):");
    for name in builtin_gem_names() {
        let text = builtin_gem_source(name).unwrap_or_default();
        let gem = lapidary::recipe::gem::parse_gem(&format!("builtin:{name}"), text)
            .map_err(|e| e.to_string())?;
        let line = gem
            .description
            .lines()
            .next()
            .unwrap_or("")
            .trim()
            .to_string();
        super::emit(&format!("  {name:<26} {line}"));
    }
    Ok(())
}
