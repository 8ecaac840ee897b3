//! Argument definitions (clap) and dispatch to the subcommands.

mod batch;
mod brdf;
mod catalogue;
mod gallery;
mod maps;
mod memory;
mod merge;
mod new;
mod render;
mod validate;

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, LazyLock};

/// lapidary: procedural gemstones with layered micro-facet BRDFs.
#[derive(Parser, Debug)]
#[command(name = "lapidary", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// A catalogue or a turntable job over a render farm: the task list,
    /// `--task I` runs task I of it (a scheduler array's element),
    /// `--merge` assembles the images.
    Batch(batch::BatchArgs),
    /// Inspect a material's BRDF: albedo table, point values, or polar plots.
    Brdf(BrdfArgs),
    /// Print the section 3.4 class of a material, with the reason.
    Classify {
        /// A library name (see `lapidary list`) or a RON file.
        material: String,
    },
    /// Re-render every built-in gem, the contact sheet gallery.png, the
    /// figures 4.11, 3.2, 4.3 and 4.5 b of the course notes and a turntable
    /// strip into a folder.
    Gallery(gallery::GalleryArgs),
    /// List the built-in materials with their classes, and the built-in gems.
    List,
    /// Draw the figure 4.6 sheet of a gem: surface map, glitter map, facet
    /// normals and the combination, over the slice z = 0.
    Maps(MapsArgs),
    /// Merge the tiles of a render (`render --tile I/N`) into its image:
    /// the same bytes as rendering it on one machine.
    Merge(merge::MergeArgs),
    /// Render a gem (default: green-aventurine) on a cabochon in a scene
    /// (default: the studio scene), to PNG or EXR.
    Render(render::RenderArgs),
    /// Check gem recipes, material files, scene files, batch jobs (with
    /// every recipe and scene they name), folders of them or built-in
    /// names: prints `file: ok (…)` per valid input on stdout,
    /// `file:line:col: message` per error and `file: warning: …` on
    /// stderr; exit status 1 when any has an error.
    Validate {
        /// RON files (gem, material, scene or job, told apart by their
        /// top-level `Gem(`, `Material(`, `Scene(` or `Job(`), folders (their
        /// `.ron` files) or built-in names.
        #[arg(required = true, value_name = "RECIPE")]
        recipes: Vec<String>,
    },
    /// Start a new recipe NAME.ron from a built-in gem or material, with a
    /// header saying how to validate and render it.
    New(new::NewArgs),
}

/// Arguments of `lapidary maps`.
#[derive(clap::Args, Debug)]
struct MapsArgs {
    /// A built-in gem name (e.g. lavender-lepidolite) or a RON gem recipe.
    recipe: String,
    /// The PNG to write.
    #[arg(short = 'o', long = "output", value_name = "OUT.png")]
    output: PathBuf,
    /// Side of each of the four panels in pixels.
    #[arg(long, default_value_t = 256, allow_negative_numbers = true,
        value_parser = whole::<u32, 1, { maps::MAX_PANEL_PX as u64 }>)]
    size: u32,
    /// Half-width of the slice in texture units, one per 10 mm of stone
    /// (x, y ∈ [−E, E]; up to 1000).
    #[arg(
        long,
        value_name = "E",
        default_value_t = 1.0,
        allow_negative_numbers = true,
        value_parser = decimal("above 0 up to 1000 texture units")
    )]
    extent: f64,
}

/// Arguments of `lapidary brdf`.
#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("show").required(true).args(["albedo", "slice", "eval", "output"])))]
struct BrdfArgs {
    /// A library name (see `lapidary list`) or a RON material file.
    material: String,
    /// Print CSV `theta_deg,r,g,b`: directional albedo at 0, 5, … 85°.
    #[arg(long, conflicts_with_all = ["eval", "output", "slice"])]
    albedo: bool,
    /// Print CSV `theta_o_deg,r,g,b`: f·cosθₒ in the plane of incidence for
    /// light at THETA_I degrees, θₒ from −87 to 87 in steps of 3 (negative:
    /// on the light's side).
    #[arg(long, value_name = "THETA_I", conflicts_with_all = ["eval", "output"], allow_hyphen_values = true,
        value_parser = decimal("0 to 90 degrees"))]
    slice: Option<f64>,
    /// Print `r,g,b`, the BRDF value f (no cosine) for THETA_I,PHI_I,THETA_O,PHI_O in degrees.
    #[arg(
        long,
        value_name = "THETA_I,PHI_I,THETA_O,PHI_O",
        conflicts_with = "output",
        allow_hyphen_values = true,
        value_parser = brdf::parse_four_numbers
    )]
    eval: Option<[f64; 4]>,
    /// Write polar plots of the in-plane, cosine-weighted BRDF (PNG).
    #[arg(short = 'o', long = "output", value_name = "PLOT.png")]
    output: Option<PathBuf>,
    /// Overlay the Monte Carlo random-walk reference on the plot, or add its
    /// columns to --albedo or --slice.
    #[arg(long, conflicts_with = "eval")]
    reference: bool,
    /// Use the seed-faithful single-crossing model (no multiple-scattering compensation).
    #[arg(long)]
    single_crossing: bool,
}

/// Checks, before any work, that `path` names a PNG (what the command
/// writes) that can be written.
fn check_png_output(path: &std::path::Path) -> Result<(), String> {
    let is_png = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !is_png {
        return Err(format!(
            "{}: the output must end in .png (this command writes PNG)",
            path.display()
        ));
    }
    lapidary::output::check_writable(path).map_err(|e| e.to_string())
}

/// `n` and the noun `what`, plural unless n is 1: "1 frame", "4 tiles".
pub fn counted(n: impl Into<u64>, what: &str) -> String {
    let n = n.into();
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

/// Print one line to stdout. A closed pipe (`lapidary list | head`) ends
/// the program quietly with success instead of panicking like `println!`.
pub fn emit(line: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = writeln!(out, "{line}") {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(1);
    }
}

/// Most worker threads a command takes (`--threads`).
pub(crate) const MAX_THREADS: u64 = 1024;

/// Refuses a `--threads` outside 1 to [`MAX_THREADS`], before any work.
pub(crate) fn check_threads(threads: Option<usize>) -> Result<(), String> {
    match threads {
        Some(threads) if !(1..=MAX_THREADS).contains(&(threads as u64)) => {
            Err(format!("--threads {threads}: allowed 1 to {MAX_THREADS}"))
        }
        _ => Ok(()),
    }
}

/// A flag's whole number, of type `T`. A number that `T` holds passes: its
/// range, `LO` to `HI`, is checked where the value is used, naming the
/// flag (exit 1). A negative or too large number, or text that is no
/// whole number, is refused here with that range (clap's own message
/// would give the type's, `0..=4294967295`).
pub(crate) fn whole<T: TryFrom<u64>, const LO: u64, const HI: u64>(
    text: &str,
) -> Result<T, String> {
    let range = format!("allowed {LO} to {HI}");
    let text = text.trim();
    let digits = text.strip_prefix(['-', '+']).unwrap_or(text);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("not a whole number; {range}"));
    }
    // `-0` is 0; a number of more digits than i128 holds is out of range.
    text.parse::<i128>()
        .ok()
        .and_then(|n| u64::try_from(n).ok())
        .and_then(|n| T::try_from(n).ok())
        .ok_or(range)
}

/// A flag's decimal number: text that is none is refused here, with what
/// the flag allows in words (`allowed`; clap's own message gives no
/// range); the range is checked where the value is used, naming the flag
/// (exit 1).
pub(crate) fn decimal(
    allowed: &'static str,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |text| {
        text.trim()
            .parse()
            .map_err(|_| format!("not a number; allowed {allowed}"))
    }
}

/// Whether paths `a` and `b` name one existing file (through links and
/// `..`): an output that would replace an input.
pub(crate) fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    matches!((a.canonicalize(), b.canonicalize()), (Ok(a), Ok(b)) if a == b)
}

/// A duration for a progress or summary line: tenths of a second from
/// 0.1 s, else milliseconds (a small render's "0.0 s" said nothing).
pub(crate) fn duration(seconds: f64) -> String {
    if seconds >= 0.1 {
        format!("{seconds:.1} s")
    } else {
        format!("{:.1} ms", seconds * 1e3)
    }
}

/// A number a person typed, as a message repeats it: as Rust prints it,
/// or in exponent form from a million up and below a millionth (`5e6`,
/// `-1e308`, not 309 digits).
pub(crate) fn typed(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-6..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        v.to_string()
    }
}

/// The rayon pool a command renders in: `threads` workers, or one per
/// core when `None` (`--threads`); the message names what failed.
pub fn worker_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, String> {
    check_threads(threads)?;
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = threads {
        pool = pool.num_threads(threads);
    }
    pool.build()
        .map_err(|e| format!("cannot start worker threads: {e}"))
}

/// The copy of the pixel loop to render with: the best this CPU runs, or the
/// portable one when `LAPIDARY_SIMD=off` (to check that both write the
/// same bytes, or to rule the vector code out when chasing a problem).
pub fn code_path_from_env() -> lapidary::render::cpu::CodePath {
    use lapidary::render::cpu::CodePath;
    if switched_off("LAPIDARY_SIMD") {
        CodePath::Portable
    } else {
        CodePath::best_available()
    }
}

/// Whether the environment variable `name` is `off` (in any case); any
/// other value is said to be ignored, once per run.
pub(crate) fn switched_off(name: &str) -> bool {
    static WARNED: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let Some(value) = std::env::var_os(name).filter(|v| !v.is_empty()) else {
        return false;
    };
    if value.eq_ignore_ascii_case("off") {
        return true;
    }
    let mut warned = WARNED.lock().unwrap_or_else(|e| e.into_inner());
    if !warned.iter().any(|n| n == name) {
        warned.push(name.to_string());
        eprintln!(
            "warning: {name}={} is ignored; allowed: off, or leave it unset",
            value.to_string_lossy()
        );
    }
    false
}

/// The compensation-table cache of this run: in memory, and on disk in
/// `$LAPIDARY_CACHE_DIR`, else `$XDG_CACHE_HOME/lapidary`, else
/// `~/.cache/lapidary`; in memory only when `LAPIDARY_CACHE=off` or no
/// home is known.
pub fn table_cache_from_env() -> lapidary::recipe::TableCache {
    use lapidary::recipe::TableCache;
    use std::path::PathBuf;
    let set = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if switched_off("LAPIDARY_CACHE") {
        return TableCache::in_memory();
    }
    let folder = set("LAPIDARY_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| set("XDG_CACHE_HOME").map(|xdg| PathBuf::from(xdg).join("lapidary")))
        .or_else(|| set("HOME").map(|home| PathBuf::from(home).join(".cache").join("lapidary")));
    match folder {
        Some(folder) if folder.exists() && !folder.is_dir() => {
            eprintln!(
                "warning: the table cache {} is not a folder: tables are kept in memory only",
                folder.display()
            );
            TableCache::in_memory()
        }
        Some(folder) => TableCache::with_folder(folder),
        None => TableCache::in_memory(),
    }
}

/// Set by Ctrl-C; a command that stops on it by itself (a render, after
/// the rows in flight) reads it through [`interruption`].
static INTERRUPTED: LazyLock<Arc<AtomicBool>> = LazyLock::new(|| Arc::new(AtomicBool::new(false)));
/// Whether the running command stops on [`INTERRUPTED`] by itself.
static STOPS_BY_ITSELF: AtomicBool = AtomicBool::new(false);

/// Ctrl-C for every command: a command that has called [`interruption`]
/// stops by itself; any other is ended here, its output being written, if
/// any, removed (existing files stay as they were), with exit status 1.
/// Without a handler (none could be installed), Ctrl-C keeps its default.
fn handle_ctrl_c() {
    let _ = ctrlc::set_handler(|| {
        INTERRUPTED.store(true, Ordering::SeqCst);
        if !STOPS_BY_ITSELF.load(Ordering::SeqCst) {
            lapidary::output::remove_unfinished_outputs();
            eprintln!("\nerror: interrupted; no output was left half-written");
            std::process::exit(1);
        }
    });
}

/// The flag Ctrl-C sets, for a command that stops on it by itself: from
/// this call on, Ctrl-C no longer ends the process.
pub(crate) fn interruption() -> Arc<AtomicBool> {
    STOPS_BY_ITSELF.store(true, Ordering::SeqCst);
    Arc::clone(&INTERRUPTED)
}

/// Parse the command line and run; returns the process exit code.
pub fn run() -> i32 {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() { 2 } else { 0 };
        }
    };
    handle_ctrl_c();
    let result = match cli.command {
        Command::Batch(args) => batch::run(args),
        Command::Brdf(args) => brdf::run(args),
        Command::Classify { material } => catalogue::classify(&material),
        Command::Gallery(args) => gallery::run(args),
        Command::List => catalogue::list(),
        Command::Maps(args) => maps::run(args),
        Command::Merge(args) => merge::run(args),
        Command::Render(args) => render::run(args),
        Command::Validate { recipes } => validate::run(&recipes),
        Command::New(args) => new::run(args),
    };
    match result {
        Ok(()) => 0,
        Err(message) => {
            eprintln!("error: {message}");
            1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{duration, whole};

    #[test]
    fn a_duration_below_a_tenth_of_a_second_is_said_in_milliseconds() {
        assert_eq!(duration(0.0054), "5.4 ms");
        assert_eq!(duration(0.0999), "99.9 ms");
        assert_eq!(duration(0.1), "0.1 s");
        assert_eq!(duration(37.46), "37.5 s");
    }

    #[test]
    fn a_count_flag_takes_what_its_type_holds_and_names_its_range_otherwise() {
        let spp = whole::<u32, 1, 1048576>;
        // In the type: passed on (0 is refused later, naming the flag).
        assert_eq!(spp("64"), Ok(64));
        assert_eq!(spp(" 0 "), Ok(0));
        assert_eq!(spp("-0"), Ok(0));
        assert_eq!(spp("+7"), Ok(7));
        for outside in ["-1", "4294967296", &"9".repeat(60)] {
            assert_eq!(
                spp(outside),
                Err("allowed 1 to 1048576".into()),
                "{outside}"
            );
        }
        for text in ["1.5", "1e3", "", "-", "ten", "0x10"] {
            assert_eq!(
                spp(text),
                Err("not a whole number; allowed 1 to 1048576".into()),
                "{text:?}"
            );
        }
    }
}
