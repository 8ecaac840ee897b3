//! Compensation tables computed once: [`TableCache`], an in-process
//! memo and an optional folder on disk, owned by whoever compiles
//! materials and passed in (the `lapidary` command makes one per run).
//! It also keeps other tables of numbers by their owner's key
//! ([`TableCache::values`]: the glitter facets' means of
//! `render::glitter_aggregate`), as the `f64` bits they were built with,
//! in a file `values-HASH.bin` of the same header and checks.
//! The tables themselves are a pure function of a material's parameters
//! ([`Compensation::compute_many`]); a gem, a scene or the gallery may name
//! the same material (same parameters) several times, under one name or
//! several, and each distinct table (0.01–0.2 s) is computed once.
//!
//! The key is [`material_key`]: the material's exact parameters and the
//! seed, not its display name. Two threads that miss on the same key at
//! once both compute it; the results are identical (the tables are
//! deterministic), so either may stay.
//!
//! On disk: one small text file per material, named by a hash of the key
//! and of the program's identity (builds that share a folder keep their
//! own files), and holding the format version, the key itself (checked on
//! reading, so a hash collision is a miss), the identity of the program
//! that wrote it (its size and modification time: any rebuild, which may
//! change how tables are computed, reads none of the files of the builds
//! before it), and E_single and E_stack
//! per node as the hexadecimal bits of each `f64`, from which
//! [`Compensation::from_albedos`] rebuilds the table bit for bit. Files are
//! written to a temporary name and renamed, so a reader never sees half a
//! file; a file that cannot be read or parsed is ignored and rewritten.
//! The folder keeps at most 256 MiB of tables (`MAX_FOLDER_BYTES`): a write
//! removes the files read or written least recently beyond it.

use crate::brdf::compensation::{
    material_key, needs_no_table, AlbedoPair, Compensation, TABLE_NODES,
};
use crate::brdf::{LayeredBrdf, Rgb};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// How compiled materials get their multiple-scattering compensation
/// tables (section 4.2's energy the single-crossing model loses).
#[derive(Clone, Copy)]
pub enum Tables<'a> {
    /// Every material that asks for one gets its table, through the cache.
    Computed(&'a TableCache),
    /// No tables: several times quicker to compile, but darker: rough
    /// layered materials lose their multiple scattering, up to about a
    /// third of their light (lavender lepidolite). For previews, patterns
    /// and tests, never for final pictures.
    Skipped,
}

/// Version of the on-disk format (and of the way tables are computed, as
/// far as the program's identity does not already cover it).
pub(crate) const DISK_FORMAT_VERSION: u32 = 1;

/// Compensation tables computed so far, in memory and optionally on disk.
#[derive(Default)]
pub struct TableCache {
    /// Tables by [`material_key`] (`None`: no compensation needed).
    tables: Mutex<HashMap<String, Option<Compensation>>>,
    /// The black- and white-base E_single pairs of coats over Lambertian
    /// bases, by the [`material_key`] of the white twin: materials that
    /// differ only in their base colour share them.
    single_albedo_pairs: Mutex<HashMap<String, AlbedoPair>>,
    /// Other tables of numbers, by their owner's key (the glitter facets'
    /// means of `render::glitter_aggregate`), kept as they are given.
    values: Mutex<HashMap<String, Arc<[f64]>>>,
    /// Where tables are kept between runs, if anywhere.
    folder: Option<PathBuf>,
}

impl std::fmt::Debug for TableCache {
    /// Its folder and how many tables it holds (not the tables).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let count = |map: &Mutex<HashMap<String, Option<Compensation>>>| {
            map.lock().map_or(0, |tables| tables.len())
        };
        f.debug_struct("TableCache")
            .field("folder", &self.folder)
            .field("tables", &count(&self.tables))
            .finish_non_exhaustive()
    }
}

impl TableCache {
    /// A cache in memory only.
    pub fn in_memory() -> Self {
        Self::default()
    }

    /// A cache in memory that also reads and writes the files of `folder`
    /// (created when first written).
    pub fn with_folder(folder: PathBuf) -> Self {
        Self {
            folder: Some(folder),
            ..Self::default()
        }
    }

    /// The folder on disk, if any.
    pub fn folder(&self) -> Option<&Path> {
        self.folder.as_deref()
    }

    /// The table of numbers stored under `key` ([`Self::store_values`]),
    /// from memory or the folder: None if neither holds it (or the file is
    /// from another program or damaged).
    pub fn values(&self, key: &str) -> Option<Arc<[f64]>> {
        if let Some(values) = lock(&self.values).get(key) {
            return Some(values.clone());
        }
        let values: Arc<[f64]> = load_values(self.folder.as_deref()?, key)?.into();
        lock(&self.values).insert(key.to_string(), values.clone());
        Some(values)
    }

    /// Keeps `values` under `key`, in memory and in the folder (a file that
    /// cannot be written is only a cache miss next time).
    pub fn store_values(&self, key: &str, values: &[f64]) {
        lock(&self.values).insert(key.to_string(), values.into());
        if let Some(folder) = &self.folder {
            let _ = write_atomically(
                folder,
                &values_file(folder, key),
                &values_bytes(key, values),
            );
        }
    }

    /// The tables of `brdf` if this cache holds them in memory already
    /// (`Some(None)`: computed, and no compensation was needed).
    pub fn cached(&self, brdf: &LayeredBrdf, seed: u64) -> Option<Option<Compensation>> {
        lock(&self.tables).get(&material_key(brdf, seed)).cloned()
    }

    /// [`Compensation::compute`] of `brdf` through the cache.
    pub fn compensation(&self, brdf: &LayeredBrdf, seed: u64) -> Option<Compensation> {
        self.compensations(&[(brdf, seed)]).pop().flatten()
    }

    /// [`Compensation::compute`] of every (material, seed) of `requests`, in
    /// order: the tables neither memory nor the folder holds are computed
    /// together, node by node in one parallel loop
    /// ([`Compensation::compute_many_reusing`]), each distinct one once.
    /// Bare Lambert surfaces ([`needs_no_table`]) need no table and touch
    /// neither memory nor disk.
    pub(crate) fn compensations(
        &self,
        requests: &[(&LayeredBrdf, u64)],
    ) -> Vec<Option<Compensation>> {
        let keys: Vec<Option<String>> = requests
            .iter()
            .map(|(brdf, seed)| (!needs_no_table(brdf)).then(|| material_key(brdf, *seed)))
            .collect();
        let mut found: HashMap<&str, Option<Compensation>> = HashMap::new();
        {
            let map = lock(&self.tables);
            for key in keys.iter().flatten() {
                if let Some(table) = map.get(key) {
                    found.insert(key, table.clone());
                }
            }
        }
        let mut missing: Vec<(&str, (&LayeredBrdf, u64))> = Vec::new();
        for (key, request) in keys.iter().zip(requests) {
            let Some(key) = key.as_deref() else { continue };
            if found.contains_key(key) || missing.iter().any(|(k, _)| *k == key) {
                continue;
            }
            match self.folder.as_deref().and_then(|d| load(d, key)) {
                Some(table) => {
                    found.insert(key, table);
                }
                None => missing.push((key, *request)),
            }
        }
        // Computed outside the locks: other materials compile meanwhile.
        // Nothing waits for a pair being computed elsewhere: two batches
        // that need the same new pair at once both compute it
        // (identically), since a rayon worker blocked on another's parallel
        // work could be the one that work needs.
        let wanted: Vec<(&LayeredBrdf, u64)> =
            missing.iter().map(|(_, request)| *request).collect();
        let known_pair = |key: &str| lock(&self.single_albedo_pairs).get(key).cloned();
        let computed = Compensation::compute_many_reusing(&wanted, &known_pair);
        {
            let mut pairs = lock(&self.single_albedo_pairs);
            for (key, pair) in computed.new_pairs {
                pairs.entry(key).or_insert(pair);
            }
        }
        for ((key, _), table) in missing.iter().zip(computed.tables) {
            if let Some(d) = self.folder.as_deref() {
                // A cache that cannot be written only costs the next run time.
                let _ = store(d, key, table.as_ref());
            }
            found.insert(key, table);
        }
        {
            let mut map = lock(&self.tables);
            for (key, table) in &found {
                map.entry(key.to_string()).or_insert_with(|| table.clone());
            }
        }
        keys.iter()
            .map(|key| key.as_deref().and_then(|k| found[k].clone()))
            .collect()
    }
}

/// A poisoned lock only means another thread panicked while inserting;
/// the map itself is still whole.
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
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

/// The hash that names the files of `key` written by the program of
/// `identity`: two builds that share a folder (one installed, one being
/// developed; two versions on a farm) keep their own files side by side
/// instead of rewriting each other's on every run.
fn file_hash(identity: &str, key: &str) -> u64 {
    fnv1a(&format!("{identity}\n{key}"))
}

/// The file of `key` in `dir`, for this program.
pub fn cache_file(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!(
        "{COMPENSATION_PREFIX}{:016x}.txt",
        file_hash(program_identity(), key)
    ))
}

/// How file names of compensation tables and of tables of numbers begin.
const COMPENSATION_PREFIX: &str = "compensation-";
/// See [`COMPENSATION_PREFIX`].
const VALUES_PREFIX: &str = "values-";

/// The most bytes of table files a folder keeps: beyond it, each write
/// removes the files used least recently (a build's tables are about
/// 2 MB a material, so this holds dozens of builds' worth).
const MAX_FOLDER_BYTES: u64 = 256 << 20;

/// How old a temporary table file must be to count as left by a writer
/// that was stopped between its write and its rename (Ctrl-C, a killed
/// farm task): a live writer renames it within milliseconds.
const ABANDONED_TEMPORARY_AGE: std::time::Duration = std::time::Duration::from_secs(3600);

/// Removes the table files of `dir` used least recently (by modification
/// time, which a read renews) until the rest take at most `limit` bytes,
/// and the temporary files of writers stopped midway (older than
/// [`ABANDONED_TEMPORARY_AGE`]). Files it cannot read or remove are left
/// (a cache only costs time).
fn prune(dir: &Path, limit: u64) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let now = std::time::SystemTime::now();
    let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = entries
        .flatten()
        .filter_map(|entry| {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            let metadata = entry.metadata().ok()?;
            let modified = metadata.modified().ok()?;
            if name.starts_with(".table-") && name.ends_with(".tmp") {
                if now
                    .duration_since(modified)
                    .is_ok_and(|age| age > ABANDONED_TEMPORARY_AGE)
                {
                    let _ = std::fs::remove_file(entry.path());
                }
                return None;
            }
            (name.starts_with(COMPENSATION_PREFIX) || name.starts_with(VALUES_PREFIX))
                .then(|| (modified, metadata.len(), entry.path()))
        })
        .collect();
    let mut total: u64 = files.iter().map(|(_, size, _)| size).sum();
    files.sort();
    for (_, size, path) in files {
        if total <= limit {
            break;
        }
        if std::fs::remove_file(&path).is_ok() {
            total -= size;
        }
    }
}

/// Marks `path` as just used (its modification time), so that
/// [`prune`] keeps it longest.
fn mark_used(path: &Path) {
    if let Ok(file) = std::fs::File::options().append(true).open(path) {
        let _ = file.set_modified(std::time::SystemTime::now());
    }
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
    let path = cache_file(dir, key);
    let text = std::fs::read_to_string(&path).ok()?;
    let body = text.strip_prefix(&header(key))?;
    mark_used(&path);
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
    write_atomically(dir, &cache_file(dir, key), text.as_bytes())
}

/// Writes `bytes` to `target` in `dir` (created if missing) through a
/// temporary file renamed into place, so that a reader never sees half.
fn write_atomically(dir: &Path, target: &Path, bytes: &[u8]) -> std::io::Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    std::fs::create_dir_all(dir)?;
    let temporary = dir.join(format!(
        ".table-{}-{}.tmp",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&temporary, bytes)?;
    std::fs::rename(&temporary, target).inspect_err(|_| {
        let _ = std::fs::remove_file(&temporary);
    })?;
    prune(dir, MAX_FOLDER_BYTES);
    Ok(())
}

/// The file of the table of numbers `key` in `dir`, for this program.
fn values_file(dir: &Path, key: &str) -> PathBuf {
    dir.join(format!(
        "{VALUES_PREFIX}{:016x}.bin",
        file_hash(program_identity(), key)
    ))
}

/// The header of a file of numbers for `key` written by this program.
fn values_header(key: &str) -> String {
    format!(
        "lapidary table of numbers v{DISK_FORMAT_VERSION}\nkey {key}\nprogram {}\n",
        program_identity()
    )
}

/// A file of numbers: its header, then each number's bits, little-endian
/// (the numbers exactly as built, so that a render from the file is the
/// same bytes as one that built them).
fn values_bytes(key: &str, values: &[f64]) -> Vec<u8> {
    let mut bytes = values_header(key).into_bytes();
    bytes.extend(values.iter().flat_map(|x| x.to_bits().to_le_bytes()));
    bytes
}

/// The numbers of `key` from `dir`: None when there is no file, or it is
/// from another format or program, for another key, cut short or holds a
/// number that is not finite.
fn load_values(dir: &Path, key: &str) -> Option<Vec<f64>> {
    let path = values_file(dir, key);
    let bytes = std::fs::read(&path).ok()?;
    let body = bytes.strip_prefix(values_header(key).as_bytes())?;
    mark_used(&path);
    if body.len() % 8 != 0 {
        return None;
    }
    body.chunks_exact(8)
        .map(|chunk| {
            let x = f64::from_bits(u64::from_le_bytes(chunk.try_into().ok()?));
            x.is_finite().then_some(x)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_of_numbers_come_back_bit_for_bit_and_damaged_files_are_misses() {
        let folder = std::env::temp_dir().join(format!("lapidary-values-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&folder);
        let numbers = [0.0, 1.5, f64::MIN_POSITIVE, 0.1 + 0.2, 1e300];
        TableCache::with_folder(folder.clone()).store_values("a key", &numbers);
        // A fresh cache (another run) reads the file.
        let fresh = TableCache::with_folder(folder.clone());
        assert_eq!(fresh.values("a key").as_deref(), Some(&numbers[..]));
        assert_eq!(fresh.values("another key"), None);
        // Cut short, or a number that is not finite: a miss.
        let file = values_file(&folder, "a key");
        let bytes = std::fs::read(&file).unwrap();
        std::fs::write(&file, &bytes[..bytes.len() - 3]).unwrap();
        assert_eq!(
            TableCache::with_folder(folder.clone()).values("a key"),
            None
        );
        let mut infinite = bytes.clone();
        let last = infinite.len() - 8;
        infinite[last..].copy_from_slice(&f64::INFINITY.to_bits().to_le_bytes());
        std::fs::write(&file, &infinite).unwrap();
        assert_eq!(
            TableCache::with_folder(folder.clone()).values("a key"),
            None
        );
        // In memory only: kept for this run, nothing written.
        let memory = TableCache::in_memory();
        memory.store_values("k", &numbers);
        assert_eq!(memory.values("k").as_deref(), Some(&numbers[..]));
        let _ = std::fs::remove_dir_all(&folder);
    }

    #[test]
    fn builds_name_their_files_apart_and_the_folder_keeps_the_files_used_last() {
        // Another program's file of the same key has another name.
        assert_ne!(
            file_hash("100 bytes, modified 1 ns", "k"),
            file_hash("100 bytes, modified 2 ns", "k")
        );
        assert_ne!(file_hash("p", "k"), file_hash("p", "k2"));
        let folder = std::env::temp_dir().join(format!("lapidary-prune-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&folder);
        std::fs::create_dir_all(&folder).unwrap();
        let epoch = std::time::UNIX_EPOCH;
        let write = |name: &str, size: usize, age_s: u64| {
            let path = folder.join(name);
            std::fs::write(&path, vec![0u8; size]).unwrap();
            let file = std::fs::File::options().append(true).open(&path).unwrap();
            file.set_modified(epoch + std::time::Duration::from_secs(1_000_000 - age_s))
                .unwrap();
        };
        write("values-old.bin", 400, 300);
        write("compensation-middle.txt", 400, 200);
        write("values-new.bin", 400, 100);
        write("someone-else.txt", 4000, 400);
        // A writer stopped between its write and its rename left one
        // temporary file long ago; another writer's is being written now.
        write(".table-1-0.tmp", 10, 0);
        let now = folder.join(".table-2-0.tmp");
        std::fs::write(&now, b"being written").unwrap();
        // Reading a file marks it used: the oldest becomes the newest.
        mark_used(&folder.join("values-old.bin"));
        prune(&folder, 900);
        let mut left: Vec<String> = std::fs::read_dir(&folder)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(
            left,
            [
                ".table-2-0.tmp",
                "someone-else.txt",
                "values-new.bin",
                "values-old.bin"
            ],
            "the least recently used table goes first, then an abandoned temporary file; \
             other files stay"
        );
        let _ = std::fs::remove_dir_all(&folder);
    }
}
