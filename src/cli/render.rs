//! `lapidary render`: a gem on a cabochon in a scene, to PNG or EXR.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use lapidary::farm::job::frame_suffix;
use lapidary::farm::merge::{read_tile, read_tile_record};
use lapidary::farm::record::{
    differing_line, inputs_sha256, tile_record, FrameOf, RenderRecord, TILE_NOTE,
};
use lapidary::output::animation::write_apng;
use lapidary::output::exr::{film_channels, write_exr_owned, write_exr_with_note, Band};
use lapidary::output::tonemap::ToneCurve;
use lapidary::recipe::error::{did_you_mean, folder_separator_hint};
use lapidary::recipe::gem::{Body, GemSource};
use lapidary::recipe::library::DEFAULT_GEM;
use lapidary::recipe::Tables;
use lapidary::render::film::{render_rows_cancellable, FilmSettings, PixelFilter};
use lapidary::render::overlaps::{placement_problems, viewpoint_problems};
use lapidary::render::prepare::{camera_for, prepare_scene};
use lapidary::render::render_scene::RenderScene;
use lapidary::render::tiles::TileSplit;
use lapidary::render::turntable::{orbited_camera, turned_stones};
use lapidary::render::world::{StoneInstance, World};
use lapidary::scene::spec::{MAX_COORDINATE_MM, MAX_FRAMES};
use lapidary::scene::{
    default_scene, load_scene, load_scene_under, EnvironmentSpec, Scene, TurnSpec, Turntable,
    DEFAULT_SCENE_SOURCE,
};

use super::validate::BUILTIN_SCENE_NAME;
use super::{decimal, duration, whole, MAX_THREADS};

pub use lapidary::render::still::{DEFAULT_BOUNCES, MAX_BOUNCES, MAX_SIDE_PX, MAX_SPP};
/// Default of `--max-memory`, GiB.
pub const DEFAULT_MAX_MEMORY_GIB: f64 = 4.0;

/// How the linear film becomes 8-bit PNG values.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TonemapArg {
    /// A filmic curve with a soft shoulder (highlights roll off).
    Filmic,
    /// Clamp to [0, 1].
    Linear,
}

/// The pixel filter (see [`PixelFilter`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FilterArg {
    /// A tent of radius one pixel: smoother edges; a glint shows in its
    /// neighbours too.
    #[default]
    Tent,
    /// The pixel's own square: crisper; a glint stays in its pixel
    /// (Mitsuba's `box` film).
    Box,
    /// A round Gaussian, σ = ½ pixel, cut off at 1.5 pixels: the softest.
    Gaussian,
}

impl From<FilterArg> for PixelFilter {
    fn from(filter: FilterArg) -> Self {
        match filter {
            FilterArg::Tent => PixelFilter::Tent,
            FilterArg::Box => PixelFilter::Box,
            FilterArg::Gaussian => PixelFilter::Gaussian,
        }
    }
}

/// Arguments of `lapidary render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// A built-in gem (see `lapidary list`) or a RON gem recipe; default:
    /// green-aventurine. Used by every stone of the scene that names none.
    pub(super) recipe: Option<String>,
    /// A RON scene (camera, stones, ground, lights, environment); default:
    /// the built-in studio scene (also `--scene studio`).
    #[arg(long, value_name = "SCENE.ron")]
    pub(super) scene: Option<PathBuf>,
    /// The image to write: .png (tone-mapped sRGB) or .exr (linear, with AOV layers).
    #[arg(short = 'o', long = "output", value_name = "OUT.png|OUT.exr")]
    pub(super) output: PathBuf,
    /// Width and height of a square image in pixels.
    #[arg(long, value_name = "N", conflicts_with_all = ["width", "height"], allow_negative_numbers = true,
        value_parser = whole::<u64, 1, { MAX_SIDE_PX as u64 }>)]
    pub(super) size: Option<u64>,
    /// Image width in pixels (default 512).
    #[arg(long, value_name = "W", allow_negative_numbers = true,
        value_parser = whole::<u64, 1, { MAX_SIDE_PX as u64 }>)]
    pub(super) width: Option<u64>,
    /// Image height in pixels (default 512).
    #[arg(long, value_name = "H", allow_negative_numbers = true,
        value_parser = whole::<u64, 1, { MAX_SIDE_PX as u64 }>)]
    pub(super) height: Option<u64>,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 64, allow_negative_numbers = true,
        value_parser = whole::<u32, 1, { MAX_SPP as u64 }>)]
    pub(super) spp: u32,
    /// Seed of the sample pattern (the gems keep their recipe seeds).
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true,
        value_parser = whole::<u64, 0, { u64::MAX }>)]
    pub(super) seed: u64,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
        value_parser = whole::<usize, 1, MAX_THREADS>)]
    pub(super) threads: Option<usize>,
    /// An equirectangular .hdr or .exr environment replacing the scene's.
    #[arg(long, value_name = "FILE")]
    pub(super) env: Option<PathBuf>,
    /// Exposure in stops applied before tone mapping (PNG only).
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_negative_numbers = true,
        value_parser = decimal("−64 to 64 stops")
    )]
    pub(super) exposure: f64,
    /// Tone curve for PNG output.
    #[arg(long, value_enum, default_value_t = TonemapArg::Filmic)]
    pub(super) tonemap: TonemapArg,
    /// Bounces after the first hit, 0 to 64 (0: direct light only; a
    /// translucent stone's inside needs 1; its flakes and scattering are
    /// not bounces, its internal reflections are: 8 is within about 0.3 %
    /// of 32, 4 about 4 % below).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_BOUNCES, allow_negative_numbers = true,
        value_parser = whole::<u32, 0, { MAX_BOUNCES as u64 }>)]
    pub(super) bounces: u32,
    /// Pixel (reconstruction) filter.
    #[arg(long, value_enum, default_value_t = FilterArg::Tent)]
    pub(super) filter: FilterArg,
    /// Ambient occlusion within DIST scene units (mm), as the appendix
    /// shader gathers it: adds an `ao` layer to EXR output; a PNG shows the
    /// occlusion itself (white: open, black: enclosed; no exposure or tone
    /// curve) instead of the beauty.
    #[arg(long, value_name = "DIST", allow_negative_numbers = true,
        value_parser = decimal("a positive distance in mm, at most 1e5"))]
    pub(super) ao: Option<f64>,
    /// Shade every flake inside a translucent stone, and every glitter
    /// facet of an opaque one, by its own normal, at any scale. By default a flake met where the pixel's footprint holds
    /// hundreds is shaded by its population's average lobe, and a path
    /// past the vertex where the pixel's footprint ends meets the flakes as
    /// a medium of the same flakes: less noise and time, the same picture
    /// within noise
    /// (where a pixel holds over a thousand, the recipe's average stone, a
    /// few per cent from this stone's own flakes). Likewise the glitter
    /// facets of an opaque stone: where a footprint holds hundreds, a
    /// vertex draws 8 facets from the map's tilts instead of taking the one
    /// under its point (the same expected picture, less noise).
    #[arg(long)]
    pub(super) exact_flakes: bool,
    /// Largest film memory to allow, in GiB (default 4); the render is
    /// refused up front above it, and always above the memory available.
    #[arg(long, value_name = "GIB", default_value_t = DEFAULT_MAX_MEMORY_GIB, allow_negative_numbers = true,
        value_parser = decimal("a positive number of GiB"))]
    pub(super) max_memory: f64,
    /// No progress bar and no summary.
    #[arg(long, short = 'q')]
    pub(super) quiet: bool,
    /// Render a turntable of N frames over a full turn: frame K is written
    /// as OUT-000K.png (or .exr), and a PNG turntable also as an animated
    /// OUT.png. Overrides the scene's `turntable`.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
        value_parser = whole::<u32, 1, { MAX_FRAMES as u64 }>)]
    pub(super) frames: Option<u32>,
    /// Render frame K (from 0) of the turntable alone, as OUT-000K.png.
    #[arg(long, value_name = "K", allow_negative_numbers = true,
        value_parser = whole::<u32, 0, { MAX_FRAMES as u64 - 1 }>)]
    pub(super) frame: Option<u32>,
    /// What a turntable turns: the stones about their own verticals, or
    /// the camera round the point it looks at (default: the scene's, else
    /// stone).
    #[arg(long, value_enum, value_name = "WHAT")]
    pub(super) turn: Option<TurnArg>,
    /// Render tile I of N (from 0; bands of rows) into an EXR that records
    /// what it is; `lapidary merge` puts the tiles back together.
    #[arg(long, value_name = "I/N", value_parser = parse_tile)]
    pub(super) tile: Option<(u32, u32)>,
}

/// What a turntable turns (`--turn`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TurnArg {
    /// The stones, each about the vertical through its origin.
    Stone,
    /// The camera, round the point it looks at.
    Camera,
}

/// `I/N` of `--tile`: two whole numbers (ranges are checked against the
/// image height later).
fn parse_tile(text: &str) -> Result<(u32, u32), String> {
    let parse = |s: &str| s.trim().parse::<u32>().ok();
    text.split_once('/')
        .and_then(|(i, n)| Some((parse(i)?, parse(n)?)))
        .ok_or_else(|| format!("`{text}` is not I/N: tile I (from 0) of N tiles, e.g. 0/4"))
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
            "{}: the output must end in .png or .exr{}",
            path.display(),
            if path.extension().is_none()
                && path.file_name().is_some_and(
                    |n| n.eq_ignore_ascii_case(".png") || n.eq_ignore_ascii_case(".exr")
                )
            {
                ", after a name (`gem.png`)"
            } else {
                ""
            }
        )),
    }
}

/// Whether `path` names a PNG (else an EXR); another extension is refused.
pub(super) fn is_png_output(path: &Path) -> Result<bool, String> {
    Ok(matches!(output_format(path)?, Format::Png))
}

fn check_settings(args: &RenderArgs) -> Result<(u32, u32), String> {
    let width = args.size.or(args.width).unwrap_or(512);
    let height = args.size.or(args.height).unwrap_or(512);
    // Named as the user typed it: --size sets both sides.
    let (width_flag, height_flag) = if args.size.is_some() {
        ("size", "size")
    } else {
        ("width", "height")
    };
    // Read as u64, so that any whole number gets this message.
    for (name, value) in [(width_flag, width), (height_flag, height)] {
        if value == 0 || value > u64::from(MAX_SIDE_PX) {
            return Err(format!(
                "--{name} {value}: allowed 1 to {MAX_SIDE_PX} pixels"
            ));
        }
    }
    let (width, height) = (width as u32, height as u32);
    if args.spp == 0 || args.spp > MAX_SPP {
        return Err(format!("--spp {}: allowed 1 to {MAX_SPP}", args.spp));
    }
    if args.bounces > MAX_BOUNCES {
        return Err(format!(
            "--bounces {}: allowed 0 to {MAX_BOUNCES}",
            args.bounces
        ));
    }
    super::check_threads(args.threads)?;
    if !args.exposure.is_finite() || args.exposure.abs() > 64.0 {
        return Err(format!(
            "--exposure {}: allowed −64 to 64 stops",
            super::typed(args.exposure)
        ));
    }
    if let Some(distance) = args.ao {
        if !(distance.is_finite() && distance > 0.0 && distance <= MAX_COORDINATE_MM) {
            return Err(format!(
                "--ao {}: must be a positive distance in scene units (mm), at most {MAX_COORDINATE_MM:e}",
                super::typed(distance)
            ));
        }
    }
    if !(args.max_memory.is_finite() && args.max_memory > 0.0) {
        return Err(format!(
            "--max-memory {}: must be a positive number of GiB",
            args.max_memory
        ));
    }
    // A tile's film holds its own rows only (a tile count out of range is
    // refused later, with its own message).
    let (rows, what) = match args.tile.map(|(i, n)| (i, n, TileSplit::new(i, n, height))) {
        Some((i, n, Ok(split))) => (
            split.rows().len() as u32,
            format!("tile {i}/{n} of a {width} × {height} render"),
        ),
        _ => (height, format!("a {width} × {height} render")),
    };
    let needed = super::memory::render_needs(width, rows);
    let more_tiles = if args.tile.is_some() {
        "more --tile"
    } else {
        "--tile"
    };
    let smaller = if width.max(height) > 1 {
        "use a smaller --size or "
    } else {
        ""
    };
    if super::memory::gib(needed) > args.max_memory {
        return Err(format!(
            "{what} needs {} of memory for its film ({:.1} MiB), above the --max-memory limit of {} GiB \
             ({:.1} MiB); raise it, {smaller}split it with {more_tiles}",
            super::memory::amount(needed),
            needed as f64 / f64::from(1u32 << 20),
            args.max_memory,
            args.max_memory * 1024.0
        ));
    }
    let available = super::memory::available_bytes();
    if needed > available {
        return Err(format!(
            "{what} needs {} of memory for its film, but only {} is available; {smaller}split it with {more_tiles}",
            super::memory::amount(needed),
            super::memory::amount(available)
        ));
    }
    Ok((width, height))
}

/// Refuses, before any frame is rendered, an animated PNG whose frames
/// (kept until the last is done, 3 bytes a pixel) and film would not fit
/// in `--max-memory` or in the memory available.
fn check_animation_memory(
    args: &RenderArgs,
    width: u32,
    height: u32,
    frames: usize,
) -> Result<(), String> {
    use super::memory::{amount, available_bytes, gib, render_needs};
    let held = 3 * u64::from(width) * u64::from(height) * frames as u64;
    let needed = render_needs(width, height).saturating_add(held);
    let limit = if gib(needed) > args.max_memory {
        format!("the --max-memory limit of {} GiB", args.max_memory)
    } else if needed > available_bytes() {
        format!("the {} available", amount(available_bytes()))
    } else {
        return Ok(());
    };
    Err(format!(
        "{}: an animated PNG of {frames} frames of {width} × {height} keeps every frame until the last: \
         {} with the film, above {limit}; render fewer --frames or a smaller --size, write .exr frames \
         (no animation), or render frame by frame with --frame K",
        args.output.display(),
        amount(needed)
    ))
}

/// Run `lapidary render`: a still, a turntable's frames (and its animated
/// PNG), one frame, or one tile of any of them.
pub fn run(args: RenderArgs) -> Result<(), String> {
    let format = output_format(&args.output)?;
    let (width, height) = check_settings(&args)?;
    let inputs = Inputs::load(&args)?;
    let turntable = turntable_of(&args, &inputs.scene)?;
    let frames: Vec<Option<u32>> = match (turntable, args.frame) {
        (None, _) => vec![None],
        (Some(t), Some(k)) => vec![Some(k)].into_iter().filter(|_| k < t.frames).collect(),
        (Some(t), None) => (0..t.frames).map(Some).collect(),
    };
    if frames.is_empty() {
        let frames = turntable.map_or(0, |t| t.frames);
        return Err(format!(
            "--frame {}: the turntable has {frames} frames, allowed 0 to {}",
            args.frame.unwrap_or(0),
            frames.saturating_sub(1)
        ));
    }
    let split = match args.tile {
        Some((index, count)) => Some(
            TileSplit::new(index, count, height)
                .map_err(|e| format!("--tile {index}/{count}: {e}"))?,
        ),
        None => None,
    };
    if split.is_some() && !matches!(format, Format::Exr) {
        return Err(format!(
            "{}: --tile writes a tile EXR: the output must end in .exr (`lapidary merge` makes the PNG)",
            args.output.display()
        ));
    }
    let outputs: Vec<PathBuf> = frames
        .iter()
        .map(|frame| frame_output(&args.output, *frame))
        .collect();
    for path in &outputs {
        lapidary::output::check_writable(path).map_err(|e| e.to_string())?;
    }
    // Writing over the map the render reads would lose it.
    let map = match (&args.env, &inputs.scene.environment) {
        (Some(path), _) | (None, EnvironmentSpec::File { path, .. }) => Some(path),
        _ => None,
    };
    if let Some(path) = map.and_then(|map| outputs.iter().find(|out| super::same_file(out, map))) {
        return Err(format!(
            "{}: the output is the environment map the render reads; allowed: another file",
            path.display()
        ));
    }
    // A PNG turntable rendered whole also becomes an animated PNG at OUT.
    let animation = (turntable.is_some()
        && args.frame.is_none()
        && split.is_none()
        && matches!(format, Format::Png))
    .then(|| args.output.clone());
    if let Some(path) = &animation {
        lapidary::output::check_writable(path).map_err(|e| e.to_string())?;
        check_animation_memory(&args, width, height, frames.len())?;
    }
    let mut renderer = Renderer::prepare(&args, inputs, width, height, turntable)?;
    if let Some(split) = split {
        for (frame, path) in frames.iter().zip(&outputs) {
            refuse_over_another_tile(&renderer.record(*frame), split, path, &args.output)?;
        }
    }
    let mut pictures = Vec::new();
    for (frame, path) in frames.iter().zip(&outputs) {
        let picture = renderer.render_to(*frame, split, path)?;
        if animation.is_some() {
            pictures.extend(picture);
        }
    }
    if let Some(path) = animation {
        write_apng(&path, &pictures, ANIMATION_FRAMES_PER_SECOND).map_err(|e| e.to_string())?;
        renderer.report(&format!(
            "wrote {} ({} frames, animated)",
            path.display(),
            pictures.len()
        ));
    }
    Ok(())
}

/// Refuses to write tile `split` to `path` (a frame's file of `output`)
/// where `path` holds another tile of the same render (`expected`'s, by
/// its header's record alone): two tiles given one `-o` would leave
/// `merge` one short, silently.
fn refuse_over_another_tile(
    expected: &RenderRecord,
    split: TileSplit,
    path: &Path,
    output: &Path,
) -> Result<(), String> {
    let Some(record) = path.exists().then(|| read_tile_record(path).ok()).flatten() else {
        return Ok(());
    };
    let (index, count) = record.tile;
    if index == split.index()
        || count != split.count()
        || differing_line(&record.render_lines, &expected.text_lines()).is_some()
    {
        return Ok(());
    }
    let stem = output
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    Err(format!(
        "{}: holds tile {index} of {count} of this render, which tile {} would replace; \
         give each tile its own -o (e.g. -o {stem}-t{}.exr)",
        path.display(),
        split.index(),
        split.index()
    ))
}

/// What a batch task did.
pub(super) enum TaskOutcome {
    /// It rendered and wrote its tile.
    Rendered,
    /// Its tile was already there, complete and of this render.
    AlreadyDone,
}

/// Render one tile of one frame (a batch task) to `path`, unless `path`
/// already holds that very tile, complete (a re-queued task resumes).
/// `turntable` replaces the scene's.
pub(super) fn run_task(
    args: &RenderArgs,
    turntable: Option<Turntable>,
    frame: Option<u32>,
    split: TileSplit,
    path: &Path,
) -> Result<TaskOutcome, String> {
    let (width, height) = check_settings(args)?;
    let inputs = Inputs::load(args)?;
    let renderer = Renderer::prepare_lazily(args, inputs, width, height, turntable)?;
    if path.exists() {
        if let Ok(tile) = read_tile(path) {
            let expected = renderer.record(frame);
            // This render's tile (its inputs' names may be typed from
            // another folder, as merge accepts), complete: `read_tile`
            // checked its pixels against its record, whose size and PNG
            // encoding follow from its render lines.
            if differing_line(&tile.record.render_lines, &expected.text_lines()).is_none()
                && tile.record.tile == (split.index(), split.count())
            {
                return Ok(TaskOutcome::AlreadyDone);
            }
        }
    }
    // After the skip: a complete tile made read-only is still this task's.
    lapidary::output::check_writable(path).map_err(|e| e.to_string())?;
    let mut renderer = renderer.compiled(args)?;
    renderer.render_to(frame, Some(split), path)?;
    Ok(TaskOutcome::Rendered)
}

/// The record of frame `frame` (or the still) of the render `args` and
/// `turntable` ask for: what its tiles must say they are.
pub(super) fn expected_record(
    args: &RenderArgs,
    turntable: Option<Turntable>,
    frame: Option<u32>,
) -> Result<RenderRecord, String> {
    let (width, height) = check_settings(args)?;
    let inputs = Inputs::load(args)?;
    Ok(Renderer::prepare_lazily(args, inputs, width, height, turntable)?.record(frame))
}

/// Frames per second of a turntable's animated PNG.
pub(super) const ANIMATION_FRAMES_PER_SECOND: u16 = 12;

/// The file of frame `frame` beside `output`: `OUT-0007.png`; `output`
/// itself for a still.
pub(super) fn frame_output(output: &Path, frame: Option<u32>) -> PathBuf {
    if frame.is_none() {
        return output.to_path_buf();
    }
    let stem = output
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let extension = output
        .extension()
        .map_or_else(String::new, |e| format!(".{}", e.to_string_lossy()));
    output.with_file_name(format!("{stem}{}{extension}", frame_suffix(frame)))
}

/// The turntable to render: `--frames` (with `--turn`, else the scene's
/// motion, else the stones), else the scene's; `--frame` needs one.
fn turntable_of(args: &RenderArgs, scene: &Scene) -> Result<Option<Turntable>, String> {
    let turn = args.turn.map(|t| match t {
        TurnArg::Stone => TurnSpec::Stone,
        TurnArg::Camera => TurnSpec::Camera,
    });
    let turntable = match args.frames {
        Some(frames) if frames == 0 || frames > MAX_FRAMES => {
            return Err(format!("--frames {frames}: allowed 1 to {MAX_FRAMES}"));
        }
        Some(frames) => Some(Turntable {
            frames,
            turn: turn.or(scene.turntable.map(|t| t.turn)).unwrap_or_default(),
        }),
        None => scene.turntable.map(|t| Turntable {
            turn: turn.unwrap_or(t.turn),
            ..t
        }),
    };
    if turntable.is_none() && (args.frame.is_some() || args.turn.is_some()) {
        return Err(format!(
            "--{} needs a turntable: give --frames N, or a scene with `turntable`",
            if args.frame.is_some() {
                "frame"
            } else {
                "turn"
            }
        ));
    }
    Ok(turntable)
}

/// For a gem name that is neither built in nor a file: a `.ron` file of
/// the working folder it may mean (`malachit` for `malachite.ron`, written
/// without its extension), as " (did you mean `malachite.ron`, a file
/// here?)"; empty when there is none.
fn recipe_file_here_hint(name: Option<&str>) -> String {
    let Some(name) = name.filter(|n| !n.contains('/') && !n.ends_with(".ron")) else {
        return String::new();
    };
    let files: Vec<String> = std::fs::read_dir(".")
        .map(|entries| {
            entries
                .filter_map(|e| e.ok()?.file_name().into_string().ok())
                .filter(|f| f.ends_with(".ron"))
                .collect()
        })
        .unwrap_or_default();
    let stems = files.iter().map(|f| f.trim_end_matches(".ron"));
    match did_you_mean(name, stems) {
        Some(stem) => format!(" (did you mean `{stem}.ron`, a file here?)"),
        None => String::new(),
    }
}

/// The inputs of a render, read and checked.
struct Inputs {
    scene: Scene,
    gem: GemSource,
    /// SHA-256 of every input file's bytes.
    sha256: String,
}

/// The scene file `--scene` names; None for the built-in studio scene
/// (no `--scene`, or `--scene studio` where no file of that name is, as
/// `validate` and batch jobs name it).
fn scene_file(args: &RenderArgs) -> Option<&Path> {
    args.scene
        .as_deref()
        .filter(|path| *path != Path::new(BUILTIN_SCENE_NAME) || path.exists())
}

impl Inputs {
    fn load(args: &RenderArgs) -> Result<Inputs, String> {
        let (scene, scene_bytes) = match scene_file(args) {
            Some(path) => {
                let name = path.to_string_lossy();
                if !path.exists() && GemSource::load(&name).is_ok() {
                    return Err(format!(
                        "--scene {name}: `{name}` is a built-in gem, not a scene: `lapidary render {name}` renders it in the studio, `--scene FILE` takes a `Scene(…)` file or `studio`"
                    ));
                }
                if !path.exists() {
                    let hint = did_you_mean(&name, ["studio"])
                        .map(|s| format!(" (did you mean `{s}`, the built-in scene?)"))
                        .unwrap_or_default();
                    return Err(format!(
                        "--scene {name}: no such file{}{hint}; --scene takes a `Scene(…)` file or `studio`",
                        folder_separator_hint(&name)
                    ));
                }
                (
                    // Under --env the scene's own map is not read (nor needed).
                    match args.env.as_deref() {
                        Some(map) => load_scene_under(path, map),
                        None => load_scene(path),
                    }
                    .map_err(|e| e.to_string())?,
                    std::fs::read(path)
                        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?,
                )
            }
            None => (default_scene(), DEFAULT_SCENE_SOURCE.as_bytes().to_vec()),
        };
        let gem = GemSource::load(args.recipe.as_deref().unwrap_or(DEFAULT_GEM))
            .map_err(|e| format!("{e}{}", recipe_file_here_hint(args.recipe.as_deref())))?;
        if let Some(recipe) = &args.recipe {
            if !scene.stones.is_empty() && scene.stones.iter().all(|s| s.recipe.is_some()) {
                eprintln!(
                    "warning: every stone of the scene names its own recipe: {recipe} is not used"
                );
            }
        }
        if let Some(env) = args.env.as_deref().filter(|path| !path.exists()) {
            return Err(format!(
                "--env {}: no such file{}; --env takes an equirectangular .hdr or .exr map (the procedural studio light is a scene's `environment: Studio(…)`, the built-in scene's own: leave --env out for it)",
                env.display(),
                folder_separator_hint(&env.to_string_lossy())
            ));
        }
        if let Some(env) = args.env.as_deref().filter(|path| path.is_dir()) {
            return Err(format!(
                "--env {}: is a folder; --env takes an equirectangular .hdr or .exr map file",
                env.display()
            ));
        }
        let sha256 = inputs_sha256(&scene_bytes, &scene, &gem, args.env.as_deref())?;
        Ok(Inputs { scene, gem, sha256 })
    }
}

/// A scene compiled for rendering, with everything each frame shares.
struct Renderer {
    scene: Scene,
    gem: GemSource,
    record: RenderRecord,
    turntable: Option<Turntable>,
    /// The compiled scene, or `None` until [`Renderer::compiled`].
    traced: Option<(RenderScene, Vec<StoneInstance>)>,
    settings: FilmSettings,
    pool: rayon::ThreadPool,
    interrupted: Arc<AtomicBool>,
    quiet: bool,
    started: Instant,
}

impl Renderer {
    /// The record of the render and its compiled scene.
    fn prepare(
        args: &RenderArgs,
        inputs: Inputs,
        width: u32,
        height: u32,
        turntable: Option<Turntable>,
    ) -> Result<Renderer, String> {
        Renderer::prepare_lazily(args, inputs, width, height, turntable)?.compiled(args)
    }

    /// The record of the render, its scene not compiled yet.
    fn prepare_lazily(
        args: &RenderArgs,
        inputs: Inputs,
        width: u32,
        height: u32,
        turntable: Option<Turntable>,
    ) -> Result<Renderer, String> {
        // `LAPIDARY_MNEE=off` leaves light through smooth translucent surfaces
        // to path sampling alone, to measure what the connections gain.
        let connections = !super::switched_off("LAPIDARY_MNEE");
        let record = RenderRecord {
            version: env!("CARGO_PKG_VERSION").to_string(),
            recipe: args
                .recipe
                .clone()
                .unwrap_or_else(|| DEFAULT_GEM.to_string()),
            scene: args
                .scene
                .as_ref()
                .map_or_else(|| "builtin:studio".to_string(), |p| p.display().to_string()),
            environment: args.env.as_ref().map(|p| p.display().to_string()),
            width_px: width,
            height_px: height,
            samples_per_pixel: args.spp,
            seed: args.seed,
            bounces: args.bounces,
            ao_distance_mm: args.ao,
            exposure_ev: args.exposure,
            tone_curve: match args.tonemap {
                TonemapArg::Filmic => ToneCurve::Filmic,
                TonemapArg::Linear => ToneCurve::Linear,
            },
            connections,
            flake_footprints: !args.exact_flakes,
            filter: args.filter.into(),
            frame: None,
            inputs_sha256: inputs.sha256,
        };
        // Ctrl-C (from here on) stops the render after the rows in flight;
        // nothing is written.
        let interrupted = super::interruption();
        Ok(Renderer {
            scene: inputs.scene,
            gem: inputs.gem,
            record,
            turntable,
            traced: None,
            settings: FilmSettings {
                code_path: super::code_path_from_env(),
                filter: args.filter.into(),
                ..FilmSettings::new(width, height, args.spp, args.seed)
            },
            pool: super::worker_pool(args.threads)?,
            interrupted,
            quiet: args.quiet,
            started: Instant::now(),
        })
    }

    /// This renderer with its scene compiled (gems, materials, environment).
    fn compiled(mut self, args: &RenderArgs) -> Result<Renderer, String> {
        let cache = super::table_cache_from_env();
        let quiet = self.quiet;
        let report = |message: &str| {
            if !quiet {
                eprintln!("{message}");
            }
        };
        let mut traced = prepare_scene(
            &self.scene,
            &self.gem,
            args.env.as_deref(),
            args.bounces,
            Tables::Computed(&cache),
            &report,
        )
        .map_err(|e| match scene_file(args) {
            Some(scene) if args.env.is_none() && e.message.starts_with("environment map") => {
                super::validate::place_environment_error(scene, e.message)
            }
            _ => e.message,
        })?;
        if let Some(warning) = traced.environment.proportion_warning() {
            let map = match (&args.env, &self.scene.environment) {
                (Some(path), _) | (None, EnvironmentSpec::File { path, .. }) => {
                    path.display().to_string()
                }
                _ => String::new(),
            };
            eprintln!("warning: environment map {map}: {warning}");
        }
        // A stone sunk into the ground or crossing another renders, but
        // not as the physics assumes: said even when quiet.
        let scene_name = scene_file(args).map_or_else(
            || "the studio scene".to_string(),
            |p| p.display().to_string(),
        );
        let problems = placement_problems(&traced.world);
        for problem in problems
            .iter()
            .chain(&viewpoint_problems(&traced.world, &self.scene))
        {
            eprintln!("warning: {scene_name}: {problem}");
        }
        if let Some(warning) = inside_needs_bounces(&traced, args.bounces) {
            eprintln!("warning: {warning}");
        }
        traced.ambient_occlusion = args.ao;
        traced.connect_through_surfaces = self.record.connections;
        if self.record.flake_footprints {
            traced.shade_flakes_by_footprint(Some(std::sync::Arc::new(cache)));
        }
        let stones = traced.world.stones().to_vec();
        self.traced = Some((traced, stones));
        Ok(self)
    }

    /// The record of frame `frame` (or the still).
    fn record(&self, frame: Option<u32>) -> RenderRecord {
        RenderRecord {
            frame: frame.zip(self.turntable).map(|(frame, t)| FrameOf {
                frame,
                frames: t.frames,
                turn: t.turn,
            }),
            ..self.record.clone()
        }
    }

    fn report(&self, message: &str) {
        if !self.quiet {
            eprintln!("{message}");
        }
    }

    /// Render frame `frame` (or the still), or tile `split` of it, and write
    /// it to `path`; returns the PNG picture when one was written. The
    /// summary line on stderr says which frame of how many it was.
    fn render_to(
        &mut self,
        frame: Option<u32>,
        split: Option<TileSplit>,
        path: &Path,
    ) -> Result<Option<image::RgbImage>, String> {
        let turn_deg = frame
            .zip(self.turntable)
            .map_or(0.0, |(k, t)| t.turn_deg(k));
        let Some((traced, stones)) = &mut self.traced else {
            unreachable!("render_to runs on a compiled renderer");
        };
        let (width, height) = (self.settings.width, self.settings.height);
        let mut view = self.scene.clone();
        match self.turntable.map(|t| t.turn) {
            Some(TurnSpec::Stone) => {
                let ground = traced.world.ground_height();
                traced.world = World::new(turned_stones(stones, turn_deg), ground);
            }
            Some(TurnSpec::Camera) => view.camera = orbited_camera(&self.scene.camera, turn_deg),
            None => {}
        }
        let traced: &RenderScene = traced;
        let camera = camera_for(&view, width, height);
        let rows = split.map_or(0..height, |s| s.rows());
        let bar = if !self.quiet && std::io::stderr().is_terminal() {
            let bar = ProgressBar::new(u64::from(width) * u64::from(rows.end - rows.start));
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
        let film = self.pool.install(|| {
            render_rows_cancellable(
                traced,
                &camera,
                &self.settings,
                rows.clone(),
                &|pixels| {
                    if let Some(bar) = &bar {
                        bar.inc(pixels);
                    }
                },
                &self.interrupted,
            )
        });
        let seconds = tracing.elapsed().as_secs_f64();
        if let Some(bar) = &bar {
            bar.finish_and_clear();
        }
        let Some(film) = film else {
            return Err(format!(
                "interrupted: the render stopped and {} was not written",
                path.display()
            ));
        };
        let stats = film.stats;
        let record = self.record(frame);
        let with_ao = record.ao_distance_mm.is_some();
        let mut picture = None;
        match (split, output_format(path)?) {
            (Some(split), _) => {
                let mut channels = film_channels(film, with_ao);
                channels.sort_by(|a, b| a.name.as_bytes().cmp(b.name.as_bytes()));
                let note = tile_record(&record, split, &channels, stats.bad_samples).to_text();
                let band = Band {
                    rows: rows.clone(),
                    image_height_px: height,
                };
                write_exr_with_note(path, width, band, channels, (TILE_NOTE, &note))
                    .map_err(|e| e.to_string())?;
            }
            (None, Format::Png) => {
                let transform = record.display_transform();
                let ao_grey: Vec<[f32; 3]>;
                let pixels = if with_ao {
                    ao_grey = film.ao.iter().map(|a| [*a, *a, *a]).collect();
                    &ao_grey
                } else {
                    &film.rgb
                };
                let image = self
                    .pool
                    .install(|| transform.encode(pixels, width, height));
                lapidary::output::write_png(path, &image).map_err(|e| e.to_string())?;
                picture = Some(image);
            }
            (None, Format::Exr) => {
                let channels = film_channels(film, with_ao);
                write_exr_owned(path, width, height, channels).map_err(|e| e.to_string())?;
            }
        }
        if stats.bad_samples > 0 {
            eprintln!(
                "warning: {} samples were NaN, infinite or negative and were left out",
                stats.bad_samples
            );
        }
        let rays = stats.traced_rays + stats.shadow_rays;
        let samples = f64::from(width)
            * f64::from(rows.end - rows.start)
            * f64::from(self.settings.samples_per_pixel);
        let what = match (frame.zip(self.turntable), split) {
            (Some((k, t)), _) => format!("frame {k} of {} ({turn_deg:.1}°): ", t.frames),
            _ => String::new(),
        };
        let tile = split.map_or(String::new(), |s| {
            format!(
                ", tile {} of {}: rows {}..{}",
                s.index(),
                s.count(),
                rows.start,
                rows.end
            )
        });
        // The filter when it is not the default tent.
        let filter = match self.settings.filter {
            PixelFilter::Tent => "",
            PixelFilter::Box => ", box filter",
            PixelFilter::Gaussian => ", Gaussian filter",
        };
        // A PNG of a render with --ao is the occlusion, not the beauty.
        let filter = match (self.record.ao_distance_mm, is_png_output(path)) {
            (Some(d), Ok(true)) => format!("{filter}, ambient occlusion within {d} mm"),
            _ => filter.to_string(),
        };
        self.report(&format!(
            "{what}wrote {} ({width} × {height}{tile}, {} spp{filter}) in {}: {:.2} Mrays/s, {:.2} M samples/s, {} total, {} code",
            path.display(),
            self.settings.samples_per_pixel,
            duration(seconds),
            rays as f64 / seconds / 1e6,
            samples / seconds / 1e6,
            duration(self.started.elapsed().as_secs_f64()),
            self.settings.code_path.name(),
        ));
        Ok(picture)
    }
}

/// Bounces a path needs to show a translucent stone's inside: the
/// refraction in (flakes and scattering inside are no bounces, and the
/// lights reach them through the surface within it).
const BOUNCES_TO_SEE_INSIDE: u32 = 1;

/// The warning for `--bounces` too few to show the inside of a translucent
/// stone of the scene (it renders as its surface's reflections over
/// black), None otherwise.
fn inside_needs_bounces(traced: &RenderScene, bounces: u32) -> Option<String> {
    let translucent = traced
        .gems
        .iter()
        .any(|gem| matches!(gem.body, Body::Translucent { .. }));
    (translucent && bounces < BOUNCES_TO_SEE_INSIDE).then(|| {
        format!(
            "--bounces {bounces}: a translucent stone shows only its surface's reflections; \
             its body and flakes need --bounces {BOUNCES_TO_SEE_INSIDE} or more"
        )
    })
}
