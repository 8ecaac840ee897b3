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
//!
//! On disk ([`cache_dir`]): one small text file per material, named by a
//! hash of the key and holding the format version, the key itself (checked
//! on reading, so a hash collision is a miss), the identity of the program
//! that wrote it (its size and modification time: any rebuild, which may
//! change how tables are computed, invalidates every file), and E_single and
//! E_stack per node as the hexadecimal bits of each `f64`, from which
//! [`Compensation::from_albedos`] rebuilds the table bit for bit. Files are
//! written to a temporary name and renamed, so a reader never sees half a
//! file; a file that cannot be read or parsed is ignored and rewritten.

use crate::brdf::compensation::Compensation;
use crate::brdf::compensation::{needs_no_table, AlbedoPair, TABLE_NODES};
use crate::brdf::stack::LayeredBrdf;
use crate::brdf::Rgb;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};

/// Version of the on-disk format (and of the way tables are computed, as
/// far as the program's identity does not already cover it).
pub const DISK_FORMAT_VERSION: u32 = 1;

/// Tables computed so far in this process, by [`material_key`].
fn tables() -> &'static Mutex<HashMap<String, Option<Compensation>>> {
    static TABLES: OnceLock<Mutex<HashMap<String, Option<Compensation>>>> = OnceLock::new();
    TABLES.get_or_init(Default::default)
}

/// E_single with a black and with a white diffuse base under each coat
/// computed so far (see `Compensation::compute_many`), by [`material_key`]
/// of the white material.
fn single_albedo_pairs() -> &'static Mutex<HashMap<String, AlbedoPair>> {
    static PAIRS: OnceLock<Mutex<HashMap<String, AlbedoPair>>> = OnceLock::new();
    PAIRS.get_or_init(Default::default)
}

/// The black- and white-base E_single tables of the coat of `white` (a
/// material with a white diffuse base), if this process has computed them.
/// Nothing waits for a pair being computed elsewhere: two batches that need
/// the same new pair at once both compute it (identically), since a rayon
/// worker blocked on another's parallel work could be the one that work
/// needs.
pub(crate) fn known_single_albedo_pair(white: &LayeredBrdf, seed: u64) -> Option<AlbedoPair> {
    let pairs = single_albedo_pairs()
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    pairs.get(&material_key(white, seed)).cloned()
}

/// Keeps the computed `pair` of the coat of `white` for the rest of the
/// process (see [`known_single_albedo_pair`]).
pub(crate) fn remember_single_albedo_pair(white: &LayeredBrdf, seed: u64, pair: &AlbedoPair) {
    single_albedo_pairs()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .entry(material_key(white, seed))
        .or_insert_with(|| pair.clone());
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
/// distinct set of parameters and seed, and read from the disk cache of
/// [`cache_dir`] when an earlier run of the same program computed it.
pub fn compensation(brdf: &LayeredBrdf, seed: u64) -> Option<Compensation> {
    compensations(&[(brdf, seed)]).pop().flatten()
}

/// [`compensation`] of every (material, seed) of `requests`, in order: the
/// tables neither this process nor the disk cache holds are computed
/// together, node by node in one parallel loop
/// ([`Compensation::compute_many`]), each distinct one once. Bare Lambert
/// surfaces ([`needs_no_table`]) need no table and touch neither cache.
pub fn compensations(requests: &[(&LayeredBrdf, u64)]) -> Vec<Option<Compensation>> {
    let keys: Vec<Option<String>> = requests
        .iter()
        .map(|(brdf, seed)| (!needs_no_table(brdf)).then(|| material_key(brdf, *seed)))
        .collect();
    let mut found: HashMap<&str, Option<Compensation>> = HashMap::new();
    {
        // A poisoned lock only means another thread panicked while
        // inserting; the map itself is still whole.
        let map = tables().lock().unwrap_or_else(|e| e.into_inner());
        for key in keys.iter().flatten() {
            if let Some(table) = map.get(key) {
                found.insert(key, table.clone());
            }
        }
    }
    let dir = cache_dir();
    let mut missing: Vec<(&str, (&LayeredBrdf, u64))> = Vec::new();
    for (key, request) in keys.iter().zip(requests) {
        let Some(key) = key.as_deref() else { continue };
        if found.contains_key(key) || missing.iter().any(|(k, _)| *k == key) {
            continue;
        }
        match dir.as_deref().and_then(|d| load(d, key)) {
            Some(table) => {
                found.insert(key, table);
            }
            None => missing.push((key, *request)),
        }
    }
    // Computed outside the lock: other materials compile meanwhile.
    let wanted: Vec<(&LayeredBrdf, u64)> = missing.iter().map(|(_, request)| *request).collect();
    let computed = Compensation::compute_many(&wanted);
    for ((key, _), table) in missing.iter().zip(computed) {
        if let Some(d) = dir.as_deref() {
            // A cache that cannot be written only costs the next run time.
            let _ = store(d, key, table.as_ref());
        }
        found.insert(key, table);
    }
    {
        let mut map = tables().lock().unwrap_or_else(|e| e.into_inner());
        for (key, table) in &found {
            map.entry(key.to_string()).or_insert_with(|| table.clone());
        }
    }
    keys.iter()
        .map(|key| key.as_deref().and_then(|k| found[k].clone()))
        .collect()
}

/// Where tables are kept between runs: `$LAPIDARY_CACHE_DIR`, else
/// `$XDG_CACHE_HOME/lapidary`, else `~/.cache/lapidary`; None when
/// `LAPIDARY_CACHE=off` or no home is known.
pub fn cache_dir() -> Option<PathBuf> {
    let set = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if std::env::var("LAPIDARY_CACHE").is_ok_and(|v| v == "off") {
        return None;
    }
    if let Some(dir) = set("LAPIDARY_CACHE_DIR") {
        return Some(PathBuf::from(dir));
    }
    if let Some(xdg) = set("XDG_CACHE_HOME") {
        return Some(PathBuf::from(xdg).join("lapidary"));
    }
    set("HOME").map(|home| PathBuf::from(home).join(".cache").join("lapidary"))
}

/// The running program's identity: its size and modification time, which
/// change with every rebuild ("unknown" when they cannot be read).
fn program_identity() -> &'static str {
    static IDENTITY: OnceLock<String> = OnceLock::new();
    IDENTITY.get_or_init(|| {
        let metadata = std::env::current_exe().and_then(std::fs::metadata);
        match metadata {
            Ok(m) => {
                let modified = m
                    .modified()
                    .ok()
                    .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                    .map_or(0, |d| d.as_nanos());
                format!("{} bytes, modified {modified} ns", m.len())
            }
            Err(_) => "unknown".to_string(),
        }
    })
}

/// FNV-1a 64-bit hash of `text`, for file names.
fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The file of `key` in `dir`.
pub fn cache_file(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!("compensation-{:016x}.txt", fnv1a(key)))
}

/// The first three lines of a file for `key` written by this program.
fn header(key: &str) -> String {
    format!(
        "lapidary compensation tables v{DISK_FORMAT_VERSION}\nkey {key}\nprogram {}\n",
        program_identity()
    )
}

/// Reads the tables of `key` from `dir`: None when there is no file, or it
/// is from another format or program, or for another key, or malformed.
/// `Some(None)`: stored as "no compensation needed".
pub fn load(dir: &Path, key: &str) -> Option<Option<Compensation>> {
    let text = std::fs::read_to_string(cache_file(dir, key)).ok()?;
    let body = text.strip_prefix(&header(key))?;
    if body.trim_end() == "none" {
        return Some(None);
    }
    let mut single = Vec::with_capacity(TABLE_NODES);
    let mut stack = Vec::with_capacity(TABLE_NODES);
    for line in body.lines() {
        let numbers: Vec<f64> = line
            .split_whitespace()
            .map(|word| u64::from_str_radix(word, 16).ok().map(f64::from_bits))
            .collect::<Option<_>>()?;
        let [s0, s1, s2, t0, t1, t2] = numbers.as_slice() else {
            return None;
        };
        if !numbers.iter().all(|x| x.is_finite()) {
            return None;
        }
        single.push(Rgb::new(*s0, *s1, *s2));
        stack.push(Rgb::new(*t0, *t1, *t2));
    }
    if single.len() != TABLE_NODES {
        return None;
    }
    Some(Some(Compensation::from_albedos(single, stack)?))
}

/// Writes the tables of `key` (None: "no compensation needed") to `dir`,
/// creating it, through a temporary file renamed into place.
pub fn store(dir: &Path, key: &str, table: Option<&Compensation>) -> std::io::Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    std::fs::create_dir_all(dir)?;
    let mut text = header(key);
    match table {
        None => text.push_str("none\n"),
        Some(t) => {
            for (s, e) in t.single_albedo.iter().zip(&t.stack_albedo) {
                let bits: Vec<String> = [s.x, s.y, s.z, e.x, e.y, e.z]
                    .iter()
                    .map(|x| format!("{:016x}", x.to_bits()))
                    .collect();
                text.push_str(&bits.join(" "));
                text.push('\n');
            }
        }
    }
    let target = cache_file(dir, key);
    let temporary = dir.join(format!(
        ".compensation-{}-{}.tmp",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&temporary, text)?;
    std::fs::rename(&temporary, &target).inspect_err(|_| {
        let _ = std::fs::remove_file(&temporary);
    })
}
