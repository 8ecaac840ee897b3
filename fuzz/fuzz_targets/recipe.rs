//! Fuzz target: any text as a gem recipe (parse, validate, compile every
//! material's BRDF) and as a material recipe (parse, compile). Any panic is a
//! bug: bad recipes must come back as `RecipeError`s.
//!
//! Multiple-scattering compensation is switched off before compiling: its
//! tables take 0.1–1 s per material, and they are a fixed integration over
//! an already-validated BRDF, not input handling.

#![no_main]

use lapidary::recipe::compile::{compile_material, MaterialSource};
use lapidary::recipe::gem::parse_gem;
use lapidary::recipe::parse_material;
use libfuzzer_sys::fuzz_target;

const PATH: &str = "fuzz.ron";

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(gem) = parse_gem(PATH, text) {
        for (name, material) in &gem.materials {
            let mut material = material.clone();
            material.multiple_scattering = false;
            let source = MaterialSource {
                path: PATH.to_string(),
                name: name.clone(),
                text: text.to_string(),
            };
            let _ = compile_material(&source, &material);
        }
    }
    if let Ok(mut material) = parse_material(PATH, text) {
        material.multiple_scattering = false;
        let source = MaterialSource {
            path: PATH.to_string(),
            name: "fuzz".to_string(),
            text: text.to_string(),
        };
        let _ = compile_material(&source, &material);
    }
});
