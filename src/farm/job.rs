//! A batch job: recipes × scenes × settings, each a still or a turntable,
//! each image in tiles; every (image, frame, tile) one numbered task.
//!
//! ```ron
//! Job(
//!     output: "catalogue",                        // folder, relative to this file
//!     recipes: ["goldstone", "my-gem.ron"],       // built-in names or .ron files
//!     scenes: ["studio", "tray.ron"],             // default: the built-in studio
//!     settings: [Settings(width: 256, height: 256, spp: 64)],
//!     turntable: Some(Turntable(frames: 36, turn: Stone)),   // default: stills
//!     tiles: 4,                                   // default 1
//! )
//! ```
//!
//! Task `i` counts tiles fastest, then frames, settings, scenes, recipes.
//! Every task writes one tile EXR under `output/tiles/`; the merge step
//! writes `output/NAME.png` (or `.exr`) per still and `NAME-0007.png` per
//! frame plus the animation `NAME.png`, NAME being `recipe-scene` (and
//! `-s2` for the third settings when there are several).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Deserializer};

use crate::recipe::compile::{parse_ron_all, read_ron_file, ron_error};
use crate::recipe::error::RecipeError;
use crate::render::still::{DEFAULT_BOUNCES, MAX_BOUNCES, MAX_SIDE_PX, MAX_SPP};
use crate::scene::spec::{TurntableSpec, MAX_COORDINATE_MM};
use crate::scene::Turntable;

/// Most tasks one job may have.
pub const MAX_TASKS: u64 = 1_000_000;

/// A job file as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Job", deny_unknown_fields)]
pub struct JobSpec {
    /// The folder the images go to, relative to the job file.
    pub output: String,
    /// Gem recipes: built-in names or `.ron` files relative to the job file.
    pub recipes: Vec<String>,
    /// Scenes: `studio` (the built-in one) or `.ron` files relative to the
    /// job file (default: the studio).
    #[serde(default = "studio_only")]
    pub scenes: Vec<String>,
    /// Render settings, each a set of images (default: one, the defaults).
    #[serde(default = "default_settings")]
    pub settings: Vec<SettingsSpec>,
    /// A turntable for every image (default: stills).
    #[serde(default)]
    pub turntable: Option<TurntableSpec>,
    /// Tiles per image, 1 to the smallest image height (default 1).
    #[serde(default = "one_tile", deserialize_with = "tiles")]
    pub tiles: u32,
}

fn studio_only() -> Vec<String> {
    vec!["studio".into()]
}
fn default_settings() -> Vec<SettingsSpec> {
    vec![SettingsSpec::default()]
}
fn one_tile() -> u32 {
    1
}

/// Settings of a set of images; the defaults are `lapidary render`'s.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Settings", deny_unknown_fields)]
pub struct SettingsSpec {
    /// Image width in pixels, 1 to [`MAX_SIDE_PX`] (default 512).
    #[serde(default = "side", deserialize_with = "width")]
    pub width: u32,
    /// Image height in pixels, 1 to [`MAX_SIDE_PX`] (default 512).
    #[serde(default = "side", deserialize_with = "height")]
    pub height: u32,
    /// Samples per pixel, 1 to [`MAX_SPP`] (default 64).
    #[serde(default = "spp_default", deserialize_with = "spp")]
    pub spp: u32,
    /// Seed of the sample pattern (default 0).
    #[serde(default, deserialize_with = "crate::recipe::ranges::seed")]
    pub seed: u64,
    /// Bounces after the first hit, 0 to [`MAX_BOUNCES`] (default
    /// [`DEFAULT_BOUNCES`]).
    #[serde(default = "bounces_default", deserialize_with = "bounces")]
    pub bounces: u32,
    /// PNG exposure in stops, −64 to 64 (default 0).
    #[serde(default, deserialize_with = "exposure_ev")]
    pub exposure_ev: f64,
    /// PNG tone curve (default `Filmic`).
    #[serde(default)]
    pub tonemap: TonemapSpec,
    /// Pixel filter (default `Tent`, as `--filter`).
    #[serde(default)]
    pub filter: FilterSpec,
    /// Ambient occlusion within this many mm, > 0 (default: off).
    #[serde(default, deserialize_with = "ao_mm")]
    pub ao_mm: Option<f64>,
    /// What the merge writes (default `Png`).
    #[serde(default)]
    pub format: FormatSpec,
}

impl Default for SettingsSpec {
    fn default() -> Self {
        SettingsSpec {
            width: 512,
            height: 512,
            spp: 64,
            seed: 0,
            bounces: DEFAULT_BOUNCES,
            exposure_ev: 0.0,
            tonemap: TonemapSpec::Filmic,
            filter: FilterSpec::Tent,
            ao_mm: None,
            format: FormatSpec::Png,
        }
    }
}

/// The PNG tone curve.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename = "Tonemap")]
pub enum TonemapSpec {
    /// The filmic curve (as `--tonemap filmic`).
    #[default]
    Filmic,
    /// A clamp (as `--tonemap linear`).
    Linear,
}

/// The pixel filter.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename = "Filter")]
pub enum FilterSpec {
    /// A tent of radius one pixel (as `--filter tent`).
    #[default]
    Tent,
    /// The pixel's own square (as `--filter box`).
    Box,
    /// A round Gaussian, σ = ½ pixel (as `--filter gaussian`).
    Gaussian,
}

/// The format of the merged images.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename = "Format")]
pub enum FormatSpec {
    /// Tone-mapped sRGB PNG; a turntable also gets an animated PNG.
    #[default]
    Png,
    /// Linear EXR with the AOV layers.
    Exr,
}

fn side() -> u32 {
    512
}
fn spp_default() -> u32 {
    64
}
fn bounces_default() -> u32 {
    DEFAULT_BOUNCES
}

fn width<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    crate::recipe::ranges::whole_in(d, "width", 1, MAX_SIDE_PX)
}
fn height<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    crate::recipe::ranges::whole_in(d, "height", 1, MAX_SIDE_PX)
}
fn spp<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    crate::recipe::ranges::whole_in(d, "spp", 1, MAX_SPP)
}
fn bounces<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    crate::recipe::ranges::whole_in(d, "bounces", 0, MAX_BOUNCES)
}
fn tiles<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    crate::recipe::ranges::whole_in(d, "tiles", 1, MAX_SIDE_PX)
}
fn exposure_ev<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    crate::recipe::ranges::checked(d, "exposure_ev", "-64 to 64 (stops)", |v| v.abs() <= 64.0)
}
fn ao_mm<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    let v = Option::<f64>::deserialize(d)?;
    match v {
        Some(v) if !(v.is_finite() && v > 0.0 && v <= MAX_COORDINATE_MM) => {
            crate::recipe::ranges::refuse(
                Some(v),
                format!(
                    "`ao_mm` = {v} is out of range; allowed: a positive distance (mm), at most \
                     {MAX_COORDINATE_MM:e}"
                ),
            )
        }
        _ => Ok(v),
    }
}

/// One image of a job (a still, or a turntable's frames): what to render
/// and what its files are called.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageJob {
    /// `recipe-scene`, plus `-sN` when the job has several settings.
    pub name: String,
    /// The gem: a built-in name or a path (relative paths resolved
    /// against the job file).
    pub recipe: String,
    /// The scene file, or `None` for the built-in studio.
    pub scene: Option<PathBuf>,
    /// The settings.
    pub settings: SettingsSpec,
}

/// A task: one tile of one frame of one image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Task {
    /// Index into [`Job::images`].
    pub image: usize,
    /// The turntable frame, for a turntable.
    pub frame: Option<u32>,
    /// The tile, from 0, of [`Job::tiles`].
    pub tile: u32,
}

/// A validated job.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// The folder the images go to.
    pub output: PathBuf,
    /// Every image, recipes outermost, then scenes, then settings.
    pub images: Vec<ImageJob>,
    /// The turntable of every image, or `None` for stills.
    pub turntable: Option<Turntable>,
    /// Tiles per image.
    pub tiles: u32,
}

impl Job {
    /// Read and validate the job file at `path`: RON errors and values out
    /// of range at their `file:line:col`; too many tasks, more tiles than
    /// an image has rows, and two images of one name, against the file.
    pub fn load(path: &Path) -> Result<Job, RecipeError> {
        let display = path.display().to_string();
        let text = read_ron_file(&display, "job file")?;
        let spec: JobSpec = parse_ron_all(&text, |e| ron_error(&display, &text, e))?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Job::from_spec(&spec, dir)
            .map_err(|(needle, message)| RecipeError::at_text(&display, &text, needle, message))
    }

    /// A job from its spec, relative paths against `dir`; an error is the
    /// field to point at and the message.
    fn from_spec(spec: &JobSpec, dir: &Path) -> Result<Job, (&'static str, String)> {
        let resolve = |p: &str| {
            let p = Path::new(p);
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                dir.join(p)
            }
        };
        let names_a_file = |s: &str| s.ends_with(".ron") || s.contains('/');
        if spec.recipes.is_empty() {
            return Err((
                "recipes",
                "`recipes` is empty; give at least one gem".into(),
            ));
        }
        if spec.scenes.is_empty() {
            return Err((
                "scenes",
                "`scenes` is empty; give at least one (`studio` is the built-in one)".into(),
            ));
        }
        if spec.settings.is_empty() {
            return Err((
                "settings",
                "`settings` is empty; give at least one `Settings()`".into(),
            ));
        }
        if let Some(bad) = spec
            .scenes
            .iter()
            .find(|s| *s != "studio" && !names_a_file(s))
        {
            return Err((
                "scenes",
                format!("scene `{bad}`: allowed `studio` (the built-in one) or a .ron file"),
            ));
        }
        let lowest = spec.settings.iter().map(|s| s.height).min().unwrap_or(1);
        if spec.tiles > lowest {
            return Err((
                "tiles",
                format!(
                    "`tiles` = {} is out of range; allowed: 1 to {lowest} (the smallest image height: every tile holds whole rows)",
                    spec.tiles
                ),
            ));
        }
        let frames = spec.turntable.as_ref().map_or(1, |t| t.frames);
        let tasks = [spec.recipes.len(), spec.scenes.len(), spec.settings.len()]
            .iter()
            .try_fold(u64::from(frames) * u64::from(spec.tiles), |n, &k| {
                n.checked_mul(k as u64)
            })
            .filter(|n| *n <= MAX_TASKS);
        if tasks.is_none() {
            return Err((
                "recipes",
                format!("the job has more than {MAX_TASKS} tasks (recipes × scenes × settings × frames × tiles); split it"),
            ));
        }
        let stem = |s: &str| {
            Path::new(s)
                .file_stem()
                .map_or(s.to_string(), |n| n.to_string_lossy().into_owned())
        };
        let mut images: Vec<ImageJob> = Vec::new();
        for recipe in &spec.recipes {
            for scene in &spec.scenes {
                for (k, settings) in spec.settings.iter().enumerate() {
                    let mut name = format!("{}-{}", stem(recipe), stem(scene));
                    if spec.settings.len() > 1 {
                        name.push_str(&format!("-s{k}"));
                    }
                    if images.iter().any(|i| i.name == name) {
                        return Err((
                            "recipes",
                            format!("two images would both be named `{name}`: give the recipes or scenes distinct file names"),
                        ));
                    }
                    images.push(ImageJob {
                        name,
                        recipe: if names_a_file(recipe) {
                            resolve(recipe).display().to_string()
                        } else {
                            recipe.clone()
                        },
                        scene: (scene != "studio").then(|| resolve(scene)),
                        settings: settings.clone(),
                    });
                }
            }
        }
        let output = resolve(&spec.output);
        if output.exists() && !output.is_dir() {
            return Err((
                "output",
                format!(
                    "`output` {} is a file; allowed: a folder (made if missing) for the tiles and images",
                    output.display()
                ),
            ));
        }
        Ok(Job {
            output,
            images,
            turntable: spec.turntable.as_ref().map(|t| Turntable {
                frames: t.frames,
                turn: t.turn,
            }),
            tiles: spec.tiles,
        })
    }

    /// Frames per image: the turntable's, or 1 for stills.
    fn frames(&self) -> u32 {
        self.turntable.map_or(1, |t| t.frames)
    }

    /// How many tasks the job has.
    pub fn task_count(&self) -> u64 {
        self.images.len() as u64 * u64::from(self.frames()) * u64::from(self.tiles)
    }

    /// Task `index`, or `None` past the last.
    pub fn task(&self, index: u64) -> Option<Task> {
        if index >= self.task_count() {
            return None;
        }
        let tiles = u64::from(self.tiles);
        let frames = u64::from(self.frames());
        Some(Task {
            image: (index / tiles / frames) as usize,
            frame: self.turntable.map(|_| ((index / tiles) % frames) as u32),
            tile: (index % tiles) as u32,
        })
    }

    /// The tile EXR a task writes.
    pub fn tile_path(&self, task: Task) -> PathBuf {
        let image = &self.images[task.image];
        self.output.join("tiles").join(format!(
            "{}{}.tile{}of{}.exr",
            image.name,
            frame_suffix(task.frame),
            task.tile,
            self.tiles
        ))
    }

    /// The merged picture of one frame (or the still) of image `image`.
    pub fn image_path(&self, image: usize, frame: Option<u32>) -> PathBuf {
        let job = &self.images[image];
        let extension = match job.settings.format {
            FormatSpec::Png => "png",
            FormatSpec::Exr => "exr",
        };
        self.output
            .join(format!("{}{}.{extension}", job.name, frame_suffix(frame)))
    }

    /// The animated PNG of image `image`'s frames, for a PNG turntable.
    pub fn animation_path(&self, image: usize) -> Option<PathBuf> {
        let job = &self.images[image];
        (self.turntable.is_some() && job.settings.format == FormatSpec::Png)
            .then(|| self.output.join(format!("{}.png", job.name)))
    }
}

/// `-0007` for frame 7, nothing for a still: how a frame's file is named
/// beside its turntable's (`OUT-0007.png` beside `OUT.png`).
pub fn frame_suffix(frame: Option<u32>) -> String {
    frame.map_or(String::new(), |k| format!("-{k:04}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(text: &str) -> Result<Job, String> {
        let spec: JobSpec = ron::from_str(text).map_err(|e| e.to_string())?;
        Job::from_spec(&spec, Path::new("jobs")).map_err(|(_, m)| m)
    }

    #[test]
    fn tasks_count_tiles_fastest_and_cover_every_tile_of_every_frame_once() {
        let job = job(
            r#"Job(output: "out", recipes: ["goldstone", "a/b.ron"], settings: [Settings(height: 8), Settings(spp: 2)],
                   turntable: Some(Turntable(frames: 3)), tiles: 2)"#,
        )
        .unwrap();
        assert_eq!(job.task_count(), 2 * 2 * 3 * 2);
        assert_eq!(job.images[2].name, "b-studio-s0");
        assert_eq!(job.images[2].recipe, "jobs/a/b.ron");
        let mut seen = std::collections::HashSet::new();
        for i in 0..job.task_count() {
            assert!(seen.insert(job.tile_path(job.task(i).unwrap())));
        }
        assert_eq!(
            job.task(3),
            Some(Task {
                image: 0,
                frame: Some(1),
                tile: 1
            })
        );
        assert!(job.task(job.task_count()).is_none());
        assert_eq!(
            job.image_path(0, Some(2)),
            Path::new("jobs/out/goldstone-studio-s0-0002.png")
        );
    }

    #[test]
    fn a_settings_filter_is_read_and_defaults_to_the_tent() {
        let read = job(
            r#"Job(output: "o", recipes: ["goldstone"], settings: [Settings(filter: Box), Settings()])"#,
        )
        .unwrap();
        let filters: Vec<FilterSpec> = read.images.iter().map(|i| i.settings.filter).collect();
        assert_eq!(filters, [FilterSpec::Box, FilterSpec::Tent]);
        let e =
            job(r#"Job(output: "o", recipes: ["goldstone"], settings: [Settings(filter: Gauss)])"#)
                .unwrap_err();
        assert!(e.contains("Gauss"), "{e}");
    }

    #[test]
    fn impossible_jobs_are_refused_with_the_allowed_range() {
        let e = job(r#"Job(output: "o", recipes: ["goldstone"], settings: [Settings(height: 4)], tiles: 5)"#).unwrap_err();
        assert!(e.contains("allowed: 1 to 4"), "{e}");
        let e = job(r#"Job(output: "o", recipes: [])"#).unwrap_err();
        assert!(e.contains("`recipes` is empty"), "{e}");
        let e = job(r#"Job(output: "o", recipes: ["goldstone", "x/goldstone.ron"])"#).unwrap_err();
        assert!(e.contains("both be named `goldstone-studio`"), "{e}");
        let e = job(r#"Job(output: "o", recipes: ["goldstone"], settings: [Settings(spp: 0)])"#)
            .unwrap_err();
        assert!(
            e.contains("`spp` = 0 is out of range; allowed: 1 to 1048576"),
            "{e}"
        );
        let e = job(r#"Job(output: "o", recipes: ["goldstone"], scenes: ["tray"])"#).unwrap_err();
        assert!(e.contains("allowed `studio`"), "{e}");
        // An output that is a file (this crate's manifest) holds no tiles.
        let manifest = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
        let e = job(&format!(
            r#"Job(output: "{manifest}", recipes: ["goldstone"])"#
        ))
        .unwrap_err();
        assert!(e.contains("is a file; allowed: a folder"), "{e}");
    }
}
