//! A per-process cache of compensation tables (issue 6): a gem, a scene or
//! the gallery may name the same material (same parameters) several times,
//! under one name or several; its multiple-scattering tables
//! ([`Compensation::compute`], 0.01–0.2 s) are computed once per process.
//!
//! The key is the material's exact parameters: the `Debug` text of its
//! micro-facet model, interfaces and base, in which every `f64` is written
//! in Rust's shortest round-trip form (two numbers print alike only when
//! their bits are equal, −0.0 included), plus the seed. The display name is
//! not part of it. Two threads that miss on the same key at once both
//! compute it; the results are identical (the tables are deterministic), so
//! either may stay.

use crate::brdf::compensation::Compensation;
use crate::brdf::stack::LayeredBrdf;
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

/// Tables computed so far in this process, by [`material_key`].
fn tables() -> &'static Mutex<HashMap<String, Option<Compensation>>> {
    static TABLES: OnceLock<Mutex<HashMap<String, Option<Compensation>>>> = OnceLock::new();
    TABLES.get_or_init(Default::default)
}

/// The exact parameters of `brdf` and `seed` as a key: equal keys give
/// bit-identical tables (the name is left out: it does not change them).
pub fn material_key(brdf: &LayeredBrdf, seed: u64) -> String {
    format!(
        "seed {seed}; model {:?}; interfaces {:?}; base {:?}",
        brdf.model, brdf.interfaces, brdf.base
    )
}

/// The tables of `brdf` if this process has computed them already
/// (`Some(None)`: computed, and no compensation was needed).
pub fn cached(brdf: &LayeredBrdf, seed: u64) -> Option<Option<Compensation>> {
    let key = material_key(brdf, seed);
    // A poisoned lock only means another thread panicked while inserting;
    // the map itself is still whole.
    let map = tables().lock().unwrap_or_else(|e| e.into_inner());
    map.get(&key).cloned()
}

/// [`Compensation::compute`] of `brdf`, computed once per process for each
/// distinct set of parameters and seed.
pub fn compensation(brdf: &LayeredBrdf, seed: u64) -> Option<Compensation> {
    let key = material_key(brdf, seed);
    if let Some(found) = tables().lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return found.clone();
    }
    // Computed outside the lock: other materials compile meanwhile.
    let computed = Compensation::compute(brdf, seed);
    tables()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(key, computed.clone());
    computed
}
