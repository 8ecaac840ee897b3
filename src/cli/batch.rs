//! `lapidary batch`: a job of many renders as numbered tasks for a
//! scheduler's array (`--task I`), and the step that merges them
//! (`--merge`). Without either, the task list, one line per task.

use std::path::{Path, PathBuf};

use lapidary::farm::job::{FilterSpec, FormatSpec, Job, TonemapSpec};
use lapidary::farm::merge::{merge, read_tile};
use lapidary::farm::record::differing_line;
use lapidary::output::animation::write_apng;
use lapidary::recipe::compile::read_ron_file;
use lapidary::render::tiles::TileSplit;

use super::render::{FilterArg, RenderArgs, TaskOutcome, TonemapArg, ANIMATION_FRAMES_PER_SECOND};
use super::validate::check_job_inputs;
use super::{whole, MAX_THREADS};

/// Arguments of `lapidary batch`.
#[derive(clap::Args, Debug)]
pub struct BatchArgs {
    /// The job: recipes × scenes × settings, a turntable, tiles (RON).
    #[arg(value_name = "JOB.ron")]
    job: PathBuf,
    /// Run task I (from 0) of the list; a task whose tile is already
    /// written, complete and of this job, is skipped.
    #[arg(long, value_name = "I", conflicts_with = "merge", allow_negative_numbers = true,
        value_parser = whole::<u64, 0, { u64::MAX }>)]
    task: Option<u64>,
    /// Merge every task's tiles into the job's images (and animations);
    /// refused while any tile is missing.
    #[arg(long)]
    merge: bool,
    /// Worker threads (default: all cores). The images do not depend on it.
    #[arg(long, value_name = "N", allow_negative_numbers = true,
        value_parser = whole::<usize, 1, MAX_THREADS>)]
    threads: Option<usize>,
    /// No progress lines.
    #[arg(long, short = 'q')]
    quiet: bool,
}

/// Run `lapidary batch`.
pub fn run(args: BatchArgs) -> Result<(), String> {
    let job = Job::load(&args.job).map_err(|e| e.to_string())?;
    match (args.task, args.merge) {
        (Some(task), _) => run_task(&job, task, &args),
        (None, true) => merge_all(&job, &args),
        (None, false) => {
            // Every recipe and scene checked before the list a farm submits.
            let display = args.job.display().to_string();
            let text = read_ron_file(&display, "job file").map_err(|e| e.to_string())?;
            for warning in check_job_inputs(&display, &text, &job).map_err(|e| e.to_string())? {
                eprintln!("{warning}");
            }
            list_tasks(&job);
            Ok(())
        }
    }
}

/// One line per task on stdout, `I NAME` (NAME is the tile file's stem:
/// no spaces, so HTCondor's `queue task, name from` reads the list as
/// is); a summary on stderr.
fn list_tasks(job: &Job) {
    for index in 0..job.task_count() {
        let Some(task) = job.task(index) else { break };
        let path = job.tile_path(task);
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        super::emit(&format!("{index} {name}"));
    }
    eprintln!(
        "{}: {} × {} × {}; run each with `lapidary batch JOB --task I`, then `lapidary batch JOB --merge`",
        super::counted(job.task_count(), "task"),
        super::counted(job.images.len() as u64, "image"),
        super::counted(job.turntable.map_or(1, |t| t.frames), "frame"),
        super::counted(job.tiles, "tile")
    );
}

fn run_task(job: &Job, index: u64, args: &BatchArgs) -> Result<(), String> {
    let task = job.task(index).ok_or_else(|| {
        format!(
            "--task {index}: {} has {} tasks, allowed 0 to {}",
            args.job.display(),
            job.task_count(),
            job.task_count().saturating_sub(1)
        )
    })?;
    let image = &job.images[task.image];
    let path = job.tile_path(task);
    std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")))
        .map_err(|e| format!("{}: cannot create the folder: {e}", path.display()))?;
    let render_args = render_args(job, task.image, path.clone(), args);
    let settings = &image.settings;
    let split = TileSplit::new(task.tile, job.tiles, settings.height)?;
    let outcome = super::render::run_task(&render_args, job.turntable, task.frame, split, &path)?;
    if !args.quiet {
        match outcome {
            TaskOutcome::Rendered => eprintln!("task {index}: done"),
            TaskOutcome::AlreadyDone => {
                eprintln!(
                    "task {index}: {} is already complete, skipped",
                    path.display()
                )
            }
        }
    }
    Ok(())
}

/// What `lapidary render` is asked for by image `image` of `job`, to `output`.
fn render_args(job: &Job, image: usize, output: PathBuf, args: &BatchArgs) -> RenderArgs {
    let image = &job.images[image];
    let settings = &image.settings;
    RenderArgs {
        recipe: Some(image.recipe.clone()),
        scene: image.scene.clone(),
        output,
        size: None,
        width: Some(u64::from(settings.width)),
        height: Some(u64::from(settings.height)),
        spp: settings.spp,
        seed: settings.seed,
        threads: args.threads,
        env: None,
        exposure: settings.exposure_ev,
        tonemap: match settings.tonemap {
            TonemapSpec::Filmic => TonemapArg::Filmic,
            TonemapSpec::Linear => TonemapArg::Linear,
        },
        bounces: settings.bounces,
        filter: match settings.filter {
            FilterSpec::Tent => FilterArg::Tent,
            FilterSpec::Box => FilterArg::Box,
            FilterSpec::Gaussian => FilterArg::Gaussian,
        },
        ao: settings.ao_mm,
        exact_flakes: false,
        max_memory: super::render::DEFAULT_MAX_MEMORY_GIB,
        quiet: args.quiet,
        frames: None,
        frame: None,
        turn: None,
        tile: None,
    }
}

fn merge_all(job: &Job, args: &BatchArgs) -> Result<(), String> {
    let missing: Vec<PathBuf> = (0..job.task_count())
        .filter_map(|i| job.task(i))
        .map(|t| job.tile_path(t))
        .filter(|p| !p.is_file())
        .collect();
    if let Some(first) = missing.first() {
        return Err(format!(
            "{} of {} tiles are missing (the first: {}); run their tasks first (`lapidary batch {} --task I`)",
            missing.len(),
            job.task_count(),
            first.display(),
            args.job.display()
        ));
    }
    let pool = super::worker_pool(args.threads)?;
    let frames: Vec<Option<u32>> = match job.turntable {
        Some(t) => (0..t.frames).map(Some).collect(),
        None => vec![None],
    };
    let tiles_per_image = u64::from(job.tiles);
    let frame_count = frames.len() as u64;
    // Tiles of an earlier version of the job (its settings or files changed
    // since) are not this job's: every tile's record is checked before any
    // image is written; their tasks must run again.
    for image in 0..job.images.len() {
        for (f, frame) in frames.iter().enumerate() {
            let first = (image as u64 * frame_count + f as u64) * tiles_per_image;
            let wanted = render_args(job, image, job.image_path(image, *frame), args);
            let expected = super::render::expected_record(&wanted, job.turntable, *frame)?;
            let mut tiles = Vec::new();
            for (task, t) in
                (first..first + tiles_per_image).filter_map(|i| Some((i, job.task(i)?)))
            {
                let path = job.tile_path(t);
                let tile = read_tile(&path)?;
                if let Some(((key, theirs), (_, ours))) =
                    differing_line(&tile.record.render_lines, &expected.text_lines())
                {
                    return Err(format!(
                        "{} is a tile of another render than {} asks for now (its {key} is {theirs}, not {ours}): run its task again (`lapidary batch {} --task {task}`)",
                        path.display(),
                        args.job.display(),
                        args.job.display()
                    ));
                }
                tiles.push(tile);
            }
            // The frame's tiles merge (the result is made again below).
            merge(tiles)?;
        }
    }
    // Every image's file can be written, or none is: a merge that stops
    // midway would leave some images new and the rest old. So every tile
    // is read whole and checked (its pixels' checksum, its record, the
    // merge) above, before any image is written, at the cost of reading
    // each tile twice.
    for image in 0..job.images.len() {
        let stills = frames.iter().map(|frame| job.image_path(image, *frame));
        for path in stills.chain(job.animation_path(image)) {
            lapidary::output::check_writable(&path).map_err(|e| e.to_string())?;
        }
    }
    for (image, _) in job.images.iter().enumerate() {
        let mut pictures = Vec::new();
        for (f, frame) in frames.iter().enumerate() {
            let first = (image as u64 * frame_count + f as u64) * tiles_per_image;
            let tiles = (first..first + tiles_per_image)
                .filter_map(|i| job.task(i))
                .map(|t| read_tile(&job.tile_path(t)))
                .collect::<Result<Vec<_>, _>>()?;
            let output = job.image_path(image, *frame);
            let merged = merge(tiles)?;
            let png = job.images[image].settings.format == FormatSpec::Png;
            let picture = pool.install(|| super::merge::write_merged(&output, merged, png))?;
            pictures.extend(picture);
            if !args.quiet {
                eprintln!("merged {}", output.display());
            }
        }
        if let Some(path) = job.animation_path(image) {
            write_apng(&path, &pictures, ANIMATION_FRAMES_PER_SECOND).map_err(|e| e.to_string())?;
            if !args.quiet {
                eprintln!(
                    "wrote {} ({} frames, animated)",
                    path.display(),
                    pictures.len()
                );
            }
        }
    }
    Ok(())
}
