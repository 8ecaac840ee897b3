//! `lapidary gallery`: re-render every built-in gem, the contact sheet and
//! the course-notes figures into one folder.

use std::path::{Path, PathBuf};
use std::time::Instant;

use image::RgbImage;
use lapidary::gallery::figures::{
    encode_png_compact, figure_3_2, figure_4_11, figure_4_3, figure_4_5b, gem_sheet, render_gem,
    turntable_strip, FigureError, GallerySettings,
};
use lapidary::recipe::error::did_you_mean;
use lapidary::recipe::library::builtin_gem_names;
use lapidary::recipe::TableCache;
use lapidary::render::still::MAX_SPP;

use super::{duration, whole, MAX_THREADS};

/// The non-gem outputs, by the name `--only` knows them (file = name.png).
const FIGURES: [&str; 6] = [
    "gallery",
    "figure-4-11",
    "figure-3-2",
    "figure-4-3",
    "figure-4-5b",
    "turntable-goldstone",
];

/// Arguments of `lapidary gallery`.
#[derive(clap::Args, Debug)]
pub struct GalleryArgs {
    /// The folder to write into (created if missing).
    #[arg(
        short = 'o',
        long = "output",
        value_name = "DIR",
        default_value = "renders"
    )]
    output: PathBuf,
    /// Side of each gem image in pixels, 1 to 8192; the figures' spheres
    /// are a fifth of it (figure 4.3's a half), but at least 48.
    #[arg(long, value_name = "N", default_value_t = 768, allow_negative_numbers = true,
        value_parser = whole::<u32, 1, 8192>)]
    size: u32,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 256, allow_negative_numbers = true,
        value_parser = whole::<u32, 1, { MAX_SPP as u64 }>)]
    spp: u32,
    /// Write only these outputs: built-in gem names and `gallery`,
    /// `figure-4-11`, `figure-3-2`, `figure-4-3`, `figure-4-5b`,
    /// `turntable-goldstone` (the contact sheet still renders every gem).
    #[arg(long, value_name = "NAME", num_args = 1..)]
    only: Vec<String>,
    /// Worker threads (default: all cores). The images do not depend on it.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
        value_parser = whole::<usize, 1, MAX_THREADS>)]
    threads: Option<usize>,
    /// Compile materials without their multiple-scattering compensation
    /// (the single-crossing model): quicker previews, rough layered
    /// materials darker (by up to about a third).
    #[arg(long)]
    draft: bool,
    /// No progress lines.
    #[arg(long, short = 'q')]
    quiet: bool,
}

/// Checks `--only` names against the gems and figures; unknown names are an
/// error naming each with a did-you-mean hint.
fn check_only(only: &[String], gems: &[&str]) -> Result<(), String> {
    let known: Vec<&str> = gems.iter().copied().chain(FIGURES).collect();
    for name in only {
        if !known.contains(&name.as_str()) {
            let hint = did_you_mean(name, known.iter().copied())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            return Err(format!(
                "--only {name}: no built-in gem or figure of that name{hint}; allowed: {}",
                known.join(", ")
            ));
        }
    }
    Ok(())
}

/// Creates `dir` if missing; refuses a path that exists but is no folder.
fn prepare_dir(dir: &Path) -> Result<(), String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!(
            "{}: exists and is not a directory; -o needs a folder",
            dir.display()
        ));
    }
    std::fs::create_dir_all(dir)
        .map_err(|e| format!("{}: cannot create the directory: {e}", dir.display()))
}

/// Run `lapidary gallery`.
pub fn run(args: GalleryArgs) -> Result<(), String> {
    let settings = GallerySettings {
        size_px: args.size,
        samples_per_pixel: args.spp,
        draft: args.draft,
        ..GallerySettings::default()
    };
    settings.check().map_err(|e| e.to_string())?;
    super::check_threads(args.threads)?;
    // Its largest film is a gem's, --size on a side.
    let (needed, available) = (
        super::memory::render_needs(args.size, args.size),
        super::memory::available_bytes(),
    );
    if needed > available {
        return Err(format!(
            "--size {}: a gem's render needs {} of memory, but only {} is available; use a smaller --size",
            args.size,
            super::memory::amount(needed),
            super::memory::amount(available)
        ));
    }
    let gems: Vec<&str> = builtin_gem_names().collect();
    check_only(&args.only, &gems)?;
    prepare_dir(&args.output)?;
    let wanted = |name: &str| args.only.is_empty() || args.only.iter().any(|n| n == name);
    let pool = super::worker_pool(args.threads)?;
    let cache = super::table_cache_from_env();
    let started = Instant::now();
    // Gems are encoded as `lapidary render` encodes them (same bytes);
    // the sheets at the best compression (many renders in one PNG).
    let write = |name: &str, image: &RgbImage, since: Instant| -> Result<(), String> {
        let path = args.output.join(format!("{name}.png"));
        if gems.contains(&name) {
            lapidary::output::write_png(&path, image).map_err(|e| e.to_string())?;
        } else {
            let bytes = encode_png_compact(image)
                .map_err(|e| format!("{}: cannot encode PNG: {e}", path.display()))?;
            lapidary::output::write_atomically(&path, &bytes).map_err(|e| e.to_string())?;
        }
        if !args.quiet {
            eprintln!(
                "wrote {} ({} × {}) in {}",
                path.display(),
                image.width(),
                image.height(),
                duration(since.elapsed().as_secs_f64())
            );
        }
        Ok(())
    };
    pool.install(|| -> Result<(), String> {
        let need_sheet = wanted("gallery");
        let mut pictures = Vec::new();
        for name in &gems {
            if !(need_sheet || wanted(name)) {
                continue;
            }
            let since = Instant::now();
            let picture = render_gem(name, &settings, &cache).map_err(|e| e.to_string())?;
            if wanted(name) {
                write(name, &picture.image, since)?;
            }
            pictures.push(picture);
        }
        if need_sheet {
            write("gallery", &gem_sheet(&pictures), Instant::now())?;
        }
        type Figure = fn(&GallerySettings, &TableCache) -> Result<RgbImage, FigureError>;
        let figures: [(&str, Figure); 5] = [
            ("figure-4-11", figure_4_11),
            ("figure-3-2", figure_3_2),
            ("figure-4-3", figure_4_3),
            ("figure-4-5b", figure_4_5b),
            ("turntable-goldstone", |settings, cache| {
                turntable_strip("goldstone", settings, cache)
            }),
        ];
        for (name, make) in figures {
            if wanted(name) {
                let since = Instant::now();
                let image = make(&settings, &cache).map_err(|e| e.to_string())?;
                write(name, &image, since)?;
            }
        }
        Ok(())
    })?;
    if !args.quiet {
        eprintln!(
            "gallery done in {}",
            duration(started.elapsed().as_secs_f64())
        );
    }
    Ok(())
}
