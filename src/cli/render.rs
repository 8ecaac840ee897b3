//! `lapidary render`: a gem on a cabochon in a scene, to PNG or EXR.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use lapidary::output::exr::{film_channels, write_exr_owned};
use lapidary::output::tonemap::{DisplayTransform, ToneCurve};
use lapidary::recipe::gem::{GemSource, Tables};
use lapidary::recipe::library::DEFAULT_GEM;
use lapidary::render::film::{render_cancellable, FilmSettings, FILM_BYTES_PER_PIXEL};
use lapidary::render::prepare::{camera_for, prepare_scene};
use lapidary::scene::{default_scene, load_scene};

/// Largest image side accepted, in pixels.
pub const MAX_SIDE_PX: u32 = 32_768;
/// Most samples per pixel accepted.
pub const MAX_SPP: u32 = 1 << 20;
/// Default of `--max-memory`, GiB.
pub const DEFAULT_MAX_MEMORY_GIB: f64 = 4.0;
/// Most bounces accepted.
pub const MAX_BOUNCES: u32 = 64;

/// How the linear film becomes 8-bit PNG values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TonemapArg {
    /// A filmic curve with a soft shoulder (highlights roll off).
    Filmic,
    /// Clamp to [0, 1].
    Linear,
}

/// Arguments of `lapidary render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// A built-in gem (see `lapidary list`) or a RON gem recipe; default:
    /// green-aventurine. Used by every stone of the scene that names none.
    recipe: Option<String>,
    /// A RON scene (camera, stones, ground, lights, environment); default:
    /// the built-in studio scene.
    #[arg(long, value_name = "SCENE.ron")]
    scene: Option<PathBuf>,
    /// The image to write: .png (tone-mapped sRGB) or .exr (linear, with AOV layers).
    #[arg(short = 'o', long = "output", value_name = "OUT.png|OUT.exr")]
    output: PathBuf,
    /// Width and height of a square image in pixels.
    #[arg(long, value_name = "N", conflicts_with_all = ["width", "height"])]
    size: Option<u32>,
    /// Image width in pixels (default 512).
    #[arg(long, value_name = "W")]
    width: Option<u32>,
    /// Image height in pixels (default 512).
    #[arg(long, value_name = "H")]
    height: Option<u32>,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 64)]
    spp: u32,
    /// Seed of the sample pattern (the gems keep their recipe seeds).
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
    /// An equirectangular .hdr or .exr environment replacing the scene's.
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// Exposure in stops applied before tone mapping (PNG only).
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    exposure: f64,
    /// Tone curve for PNG output.
    #[arg(long, value_enum, default_value_t = TonemapArg::Filmic)]
    tonemap: TonemapArg,
    /// Bounces after the first hit (0: direct light only).
    #[arg(long, value_name = "N", default_value_t = 4)]
    bounces: u32,
    /// Ambient occlusion within DIST scene units (mm), as the appendix
    /// shader gathers it: adds an `ao` layer to EXR output; a PNG shows the
    /// occlusion itself (white: open, black: enclosed) instead of the beauty.
    #[arg(long, value_name = "DIST")]
    ao: Option<f64>,
    /// Largest film memory to allow, in GiB (default 4); the render is
    /// refused up front above it, and always above the memory available.
    #[arg(long, value_name = "GIB", default_value_t = DEFAULT_MAX_MEMORY_GIB)]
    max_memory: f64,
    /// No progress bar and no summary.
    #[arg(long, short = 'q')]
    quiet: bool,
}

enum Format {
    Png,
    Exr,
}

fn output_format(path: &Path) -> Result<Format, String> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("png") => Ok(Format::Png),
        Some("exr") => Ok(Format::Exr),
        _ => Err(format!(
            "{}: the output must end in .png or .exr",
            path.display()
        )),
    }
}

/// Memory the render needs, in bytes: the film, and as much again for the
/// output encoder's buffers at the end.
fn memory_needed(width: u32, height: u32) -> u64 {
    2 * u64::from(width) * u64::from(height) * FILM_BYTES_PER_PIXEL
}

/// Memory available for a render: MemAvailable from /proc/meminfo, or
/// 4 GiB where that cannot be read.
fn memory_available() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kib| kib.parse::<u64>().ok())
        })
        .map_or(4 << 30, |kib| kib * 1024)
}

fn gib(bytes: u64) -> f64 {
    bytes as f64 / f64::from(1u32 << 30)
}

fn check_settings(args: &RenderArgs) -> Result<(u32, u32), String> {
    let width = args.size.or(args.width).unwrap_or(512);
    let height = args.size.or(args.height).unwrap_or(512);
    for (name, value) in [("width", width), ("height", height)] {
        if value == 0 || value > MAX_SIDE_PX {
            return Err(format!(
                "--{name} {value}: allowed 1 to {MAX_SIDE_PX} pixels"
            ));
        }
    }
    if args.spp == 0 || args.spp > MAX_SPP {
        return Err(format!("--spp {}: allowed 1 to {MAX_SPP}", args.spp));
    }
    if args.bounces > MAX_BOUNCES {
        return Err(format!(
            "--bounces {}: allowed 0 to {MAX_BOUNCES}",
            args.bounces
        ));
    }
    if args.threads == Some(0) || args.threads.is_some_and(|t| t > 1024) {
        return Err(format!(
            "--threads {}: allowed 1 to 1024",
            args.threads.unwrap_or(0)
        ));
    }
    if !args.exposure.is_finite() || args.exposure.abs() > 64.0 {
        return Err(format!(
            "--exposure {}: allowed −64 to 64 stops",
            args.exposure
        ));
    }
    if let Some(distance) = args.ao {
        if !(distance.is_finite() && distance > 0.0) {
            return Err(format!(
                "--ao {distance}: must be a positive distance in scene units (mm)"
            ));
        }
    }
    if !(args.max_memory.is_finite() && args.max_memory > 0.0) {
        return Err(format!(
            "--max-memory {}: must be a positive number of GiB",
            args.max_memory
        ));
    }
    let needed = memory_needed(width, height);
    if gib(needed) > args.max_memory {
        return Err(format!(
            "a {width} × {height} render needs {:.2} GiB of memory for its film, above the --max-memory limit of {} GiB; raise it or use a smaller --size",
            gib(needed),
            args.max_memory
        ));
    }
    let available = memory_available();
    if needed > available {
        return Err(format!(
            "a {width} × {height} render needs {:.1} GiB of memory for its film, but only {:.1} GiB is available; use a smaller --size",
            gib(needed),
            gib(available)
        ));
    }
    Ok((width, height))
}

/// Run `lapidary render`.
pub fn run(args: RenderArgs) -> Result<(), String> {
    let format = output_format(&args.output)?;
    let (width, height) = check_settings(&args)?;
    let interrupted = Arc::new(AtomicBool::new(false));
    {
        let flag = Arc::clone(&interrupted);
        // Ctrl-C (from here on) stops the render after the rows in flight; nothing is written;
        // if a handler cannot be installed, Ctrl-C keeps its default (the
        // process dies before writing, which also leaves no file).
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    }

    lapidary::output::check_writable(&args.output).map_err(|e| e.to_string())?;
    let scene = match &args.scene {
        Some(path) => load_scene(path).map_err(|e| e.to_string())?,
        None => default_scene(),
    };
    let gem = GemSource::load(args.recipe.as_deref().unwrap_or(DEFAULT_GEM))
        .map_err(|e| e.to_string())?;
    let quiet = args.quiet;
    let report = |message: &str| {
        if !quiet {
            eprintln!("{message}");
        }
    };
    let started = Instant::now();
    let cache = super::table_cache_from_env();
    let tables = Tables::Computed(&cache);
    let mut render_scene = prepare_scene(
        &scene,
        &gem,
        args.env.as_deref(),
        args.bounces,
        tables,
        &report,
    )?;
    render_scene.ambient_occlusion = args.ao;
    // `LAPIDARY_MNEE=off` leaves light through smooth translucent surfaces
    // to path sampling alone, to measure what the connections gain.
    render_scene.connect_through_surfaces = std::env::var("LAPIDARY_MNEE").as_deref() != Ok("off");
    let camera = camera_for(&scene, width, height);
    let settings = FilmSettings {
        code_path: super::code_path_from_env(),
        ..FilmSettings::new(width, height, args.spp, args.seed)
    };
    let pool = super::worker_pool(args.threads)?;
    let bar = if !quiet && std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(u64::from(width) * u64::from(height));
        bar.set_style(
            ProgressStyle::with_template(
                "{bar:40} {percent:>3}% {elapsed_precise} eta {eta} {msg}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        Some(bar)
    } else {
        None
    };
    let tracing = Instant::now();
    let film = pool.install(|| {
        render_cancellable(
            &render_scene,
            &camera,
            &settings,
            &|pixels| {
                if let Some(bar) = &bar {
                    bar.inc(pixels);
                }
            },
            &interrupted,
        )
    });
    let seconds = tracing.elapsed().as_secs_f64();
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let Some(film) = film else {
        return Err(format!(
            "interrupted: the render stopped and {} was not written",
            args.output.display()
        ));
    };
    // The scene (materials, environment map, BVH) is no longer needed:
    // free it before the output is encoded, which is the memory peak.
    drop(render_scene);
    let stats = film.stats;
    match format {
        Format::Png => {
            let transform = DisplayTransform {
                exposure_ev: args.exposure,
                // Occlusion is a fraction: shown linearly, 1 as white.
                curve: match (args.tonemap, args.ao) {
                    (_, Some(_)) | (TonemapArg::Linear, None) => ToneCurve::Linear,
                    (TonemapArg::Filmic, None) => ToneCurve::Filmic,
                },
                dither_seed: args.seed,
            };
            let ao_grey: Vec<[f32; 3]>;
            let pixels = if args.ao.is_some() {
                ao_grey = film.ao.iter().map(|a| [*a, *a, *a]).collect();
                &ao_grey
            } else {
                &film.rgb
            };
            let image = pool.install(|| transform.encode(pixels, width, height));
            lapidary::output::write_png(&args.output, &image).map_err(|e| e.to_string())?;
        }
        Format::Exr => {
            let channels = film_channels(film, args.ao.is_some());
            write_exr_owned(&args.output, width, height, channels).map_err(|e| e.to_string())?;
        }
    }
    if stats.bad_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN, infinite or negative and were left out",
            stats.bad_samples
        );
    }
    let rays = stats.traced_rays + stats.shadow_rays;
    let samples = f64::from(width) * f64::from(height) * f64::from(args.spp);
    report(&format!(
        "wrote {} ({width} × {height}, {} spp) in {:.1} s: {:.2} Mrays/s, {:.2} M samples/s, {:.1} s total, {} code",
        args.output.display(),
        args.spp,
        seconds,
        rays as f64 / seconds / 1e6,
        samples / seconds / 1e6,
        started.elapsed().as_secs_f64(),
        settings.code_path.name(),
    ));
    Ok(())
}
