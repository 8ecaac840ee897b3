//! What a render is, written into each tile it is split into, so that a
//! merge can tell which tiles belong together: the inputs (names and a
//! SHA-256 of their bytes), every setting that changes a byte of the
//! image, the frame, the version; and per tile its place and a SHA-256 of
//! its pixels.
//!
//! The record is text, `key: value` a line, in one fixed order, stored as
//! one EXR header attribute ([`TILE_NOTE`]). Strings are written with
//! Rust's debug escapes (no line break can split a value) and only ever
//! compared, never unescaped.

use std::fmt::Write as _;
use std::path::Path;

use sha2::{Digest, Sha256};

use crate::file_kind::not_a_regular_file;
use crate::output::exr::{ChannelData, ExrChannel};
use crate::output::tonemap::{DisplayTransform, ToneCurve};
use crate::recipe::gem::GemSource;
use crate::render::film::PixelFilter;
use crate::render::tiles::TileSplit;
use crate::scene::{EnvironmentSpec, Scene, TurnSpec};

/// Name of the EXR header attribute that holds a tile's record.
pub const TILE_NOTE: &str = "lapidary.tile";

/// First line of every tile record; a new layout gets a new number.
const RECORD_HEADER: &str = "lapidary tile record 1";

/// Frame `frame` of a turntable of `frames`, turning `turn`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameOf {
    /// The frame, from 0.
    pub frame: u32,
    /// Frames of the full turn.
    pub frames: u32,
    /// What turns.
    pub turn: TurnSpec,
}

/// Everything that decides the bytes of one image (a still, or one frame).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderRecord {
    /// The lapidary version that rendered it.
    pub version: String,
    /// The gem of stones that name none, as given (a built-in name or a path).
    pub recipe: String,
    /// The scene file as given, or `builtin:studio`.
    pub scene: String,
    /// The environment image replacing the scene's, as given.
    pub environment: Option<String>,
    /// Image width in pixels.
    pub width_px: u32,
    /// Image height in pixels.
    pub height_px: u32,
    /// Samples per pixel.
    pub samples_per_pixel: u32,
    /// Seed of the sample pattern and of the PNG dither.
    pub seed: u64,
    /// Bounces after the first hit.
    pub bounces: u32,
    /// Ambient-occlusion distance in mm, when on.
    pub ao_distance_mm: Option<f64>,
    /// Exposure of the PNG, stops.
    pub exposure_ev: f64,
    /// Tone curve of the PNG.
    pub tone_curve: ToneCurve,
    /// Whether light is connected through translucent surfaces
    /// (`LAPIDARY_MNEE`).
    pub connections: bool,
    /// Whether flakes are shaded by their footprint (the default; off with
    /// `--exact-flakes`).
    pub flake_footprints: bool,
    /// The pixel filter.
    pub filter: PixelFilter,
    /// The turntable frame, for an animation.
    pub frame: Option<FrameOf>,
    /// SHA-256 (hex) of the bytes of every input file the render read.
    pub inputs_sha256: String,
}

impl RenderRecord {
    /// How the PNG of this render is encoded from its linear film: the same
    /// for a single render and for merged tiles.
    pub fn display_transform(&self) -> DisplayTransform {
        display_of(
            self.exposure_ev,
            self.tone_curve,
            self.ao_distance_mm.is_some(),
            self.seed,
        )
    }

    /// The record's `key: value` lines as a tile stores them (what
    /// [`ReadRecord::render_lines`] reads back).
    pub fn text_lines(&self) -> Vec<(String, String)> {
        self.lines()
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect()
    }

    /// `key: value` lines in a fixed order.
    fn lines(&self) -> Vec<(&'static str, String)> {
        let text = |s: &str| format!("{s:?}");
        let frame = match self.frame {
            Some(f) => format!("{} of {} turning {:?}", f.frame, f.frames, f.turn),
            None => "still".to_string(),
        };
        vec![
            ("version", text(&self.version)),
            ("recipe", text(&self.recipe)),
            ("scene", text(&self.scene)),
            (
                "environment",
                self.environment.as_deref().map_or("none".into(), text),
            ),
            ("size", format!("{}x{}", self.width_px, self.height_px)),
            ("spp", self.samples_per_pixel.to_string()),
            ("seed", self.seed.to_string()),
            ("bounces", self.bounces.to_string()),
            (
                "ao_mm",
                self.ao_distance_mm.map_or("off".into(), |d| d.to_string()),
            ),
            ("exposure_ev", self.exposure_ev.to_string()),
            ("tonemap", format!("{:?}", self.tone_curve)),
            ("connections", self.connections.to_string()),
            ("flake_footprints", self.flake_footprints.to_string()),
            ("filter", format!("{:?}", self.filter)),
            ("frame", frame),
            ("inputs_sha256", self.inputs_sha256.clone()),
        ]
    }
}

/// The PNG encoding of a render's film: its exposure and tone curve, but
/// ambient occlusion (a fraction) as it is, neither exposed nor curved.
fn display_of(exposure_ev: f64, curve: ToneCurve, occlusion: bool, seed: u64) -> DisplayTransform {
    DisplayTransform {
        exposure_ev: if occlusion { 0.0 } else { exposure_ev },
        curve: if occlusion { ToneCurve::Linear } else { curve },
        dither_seed: seed,
    }
}

/// One `key: value` line of a record.
pub type RecordLine = (String, String);

/// The record lines that name the inputs (`recipe`, `scene`,
/// `environment`: as typed, so relative to the working folder, or a
/// built-in name). Tiles whose `inputs_sha256` agree read the same bytes
/// whatever these say.
const INPUT_NAME_KEYS: [&str; 3] = ["recipe", "scene", "environment"];

/// The first pair of `key: value` lines of two renders' records (as
/// [`RenderRecord::text_lines`] and [`ReadRecord::render_lines`] hold
/// them) that tells two renders apart, `ours` first; `None` for one
/// render. The inputs' names count only where the inputs' bytes differ
/// too (then the name, the more telling line, is the one given), so the
/// same files named from another working folder make the same render.
pub fn differing_line<'a>(
    ours: &'a [RecordLine],
    theirs: &'a [RecordLine],
) -> Option<(&'a RecordLine, &'a RecordLine)> {
    let inputs = |lines: &'a [(String, String)]| lines.iter().find(|(k, _)| k == "inputs_sha256");
    let same_inputs = inputs(ours) == inputs(theirs);
    ours.iter()
        .zip(theirs)
        .find(|(a, b)| a != b && !(same_inputs && INPUT_NAME_KEYS.contains(&a.0.as_str())))
}

/// One tile of a render as its file records it.
#[derive(Clone, Debug, PartialEq)]
pub struct TileRecord {
    /// The render it is part of.
    pub render: RenderRecord,
    /// Which tile, from 0.
    pub tile: u32,
    /// Of how many.
    pub tiles: u32,
    /// SHA-256 (hex) of its channels ([`pixels_sha256`]).
    pub pixels_sha256: String,
    /// Samples that were NaN, infinite or negative and left out.
    pub bad_samples: u64,
}

impl TileRecord {
    /// The record as the text stored in the tile's header.
    pub fn to_text(&self) -> String {
        let mut text = format!("{RECORD_HEADER}\n");
        let tile_lines = [
            ("tile", format!("{} of {}", self.tile, self.tiles)),
            ("pixels_sha256", self.pixels_sha256.clone()),
            ("bad_samples", self.bad_samples.to_string()),
        ];
        for (key, value) in self.render.lines().into_iter().chain(tile_lines) {
            let _ = writeln!(text, "{key}: {value}");
        }
        text
    }
}

/// A tile record read back: its render's lines (compared as text), and
/// the fields a merge needs parsed.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadRecord {
    /// The render's `key: value` lines as written, in order.
    pub render_lines: Vec<(String, String)>,
    /// Image width and height in pixels.
    pub size_px: (u32, u32),
    /// Which tile, from 0, and of how many.
    pub tile: (u32, u32),
    /// SHA-256 (hex) of its channels.
    pub pixels_sha256: String,
    /// Samples left out.
    pub bad_samples: u64,
    /// The PNG encoding of the merged image, and whether its picture is
    /// the ambient occlusion (not the beauty).
    pub display: (DisplayTransform, bool),
}

impl ReadRecord {
    /// Parse the text of [`TileRecord::to_text`]; the error says what is
    /// not as written (another layout, a line missing or out of place, a
    /// value that does not parse), naming the line.
    pub fn parse(text: &str) -> Result<ReadRecord, String> {
        let mut lines = text.lines();
        let first = lines.next().unwrap_or_default();
        if first != RECORD_HEADER {
            return Err(format!(
                "its first line is `{first}`, not `{RECORD_HEADER}` (another version's record?)"
            ));
        }
        let mut pairs: Vec<(String, String)> = Vec::new();
        for (k, line) in lines.enumerate() {
            let (key, value) = line
                .split_once(": ")
                .ok_or_else(|| format!("line {} is `{line}`, not `key: value`", k + 2))?;
            pairs.push((key.to_string(), value.to_string()));
        }
        // The same keys in the same order as written, nothing else.
        let mut expected = RenderRecord::example_keys();
        expected.extend(["tile", "pixels_sha256", "bad_samples"]);
        let written: Vec<&str> = pairs.iter().map(|(k, _)| k.as_str()).collect();
        if let Some(k) =
            (0..expected.len().max(written.len())).find(|&k| written.get(k) != expected.get(k))
        {
            return Err(match (written.get(k), expected.get(k)) {
                (Some(found), Some(wanted)) => {
                    format!("line {} is `{found}`, where `{wanted}` belongs", k + 2)
                }
                (Some(found), None) => format!("line {} (`{found}`) is one too many", k + 2),
                (None, Some(wanted)) => format!("its `{wanted}` line is missing"),
                (None, None) => unreachable!("k is below the longer length"),
            });
        }
        let get = |key: &str| {
            let at = written.iter().position(|k| *k == key).unwrap_or_default();
            (at + 2, pairs[at].1.as_str())
        };
        let value = |key: &str| get(key).1;
        let bad = |key: &str, allowed: &str| {
            let (line, value) = get(key);
            format!("line {line}: `{key}` is `{value}`; allowed: {allowed}")
        };
        let number = |key: &str| -> Result<u64, String> {
            value(key)
                .parse()
                .map_err(|_| bad(key, "a whole number from 0"))
        };
        let pair = |key: &str, separator: &str, allowed: &str| -> Result<(u32, u32), String> {
            value(key)
                .split_once(separator)
                .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
                .ok_or_else(|| bad(key, allowed))
        };
        let size_px = pair("size", "x", "WIDTHxHEIGHT in pixels")?;
        let tile = pair("tile", " of ", "I of N")?;
        let curve = match value("tonemap") {
            "Filmic" => ToneCurve::Filmic,
            "Linear" => ToneCurve::Linear,
            _ => return Err(bad("tonemap", "Filmic or Linear")),
        };
        let ao = match value("ao_mm") {
            "off" => None,
            d => Some(
                d.parse::<f64>()
                    .map_err(|_| bad("ao_mm", "off or a distance"))?,
            ),
        };
        let exposure_ev: f64 = value("exposure_ev")
            .parse()
            .map_err(|_| bad("exposure_ev", "a number of stops"))?;
        let seed = number("seed")?;
        let display = display_of(exposure_ev, curve, ao.is_some(), seed);
        Ok(ReadRecord {
            size_px,
            tile,
            pixels_sha256: value("pixels_sha256").to_string(),
            bad_samples: number("bad_samples")?,
            display: (display, ao.is_some()),
            render_lines: pairs.into_iter().take(expected.len() - 3).collect(),
        })
    }
}

impl RenderRecord {
    /// The render keys of a record, in their order.
    fn example_keys() -> Vec<&'static str> {
        let example = RenderRecord {
            version: String::new(),
            recipe: String::new(),
            scene: String::new(),
            environment: None,
            width_px: 1,
            height_px: 1,
            samples_per_pixel: 1,
            seed: 0,
            bounces: 0,
            ao_distance_mm: None,
            exposure_ev: 0.0,
            tone_curve: ToneCurve::Filmic,
            connections: true,
            flake_footprints: true,
            filter: PixelFilter::Tent,
            frame: None,
            inputs_sha256: String::new(),
        };
        example.lines().into_iter().map(|(k, _)| k).collect()
    }
}

/// SHA-256 (hex) of channels: each channel's name, type and samples
/// (little-endian) in the order given.
pub fn pixels_sha256(channels: &[ExrChannel]) -> String {
    let mut hash = Sha256::new();
    for channel in channels {
        hash.update((channel.name.len() as u64).to_le_bytes());
        hash.update(channel.name.as_bytes());
        match &channel.data {
            ChannelData::F32(v) => {
                hash.update(b"f32");
                v.iter().for_each(|x| hash.update(x.to_le_bytes()));
            }
            ChannelData::U32(v) => {
                hash.update(b"u32");
                v.iter().for_each(|x| hash.update(x.to_le_bytes()));
            }
        }
    }
    hex(&hash.finalize())
}

/// SHA-256 (hex) of every file a render reads: the gem recipe, the scene,
/// the recipes its stones name, the ground's material file, the
/// environment image (the scene's or `environment_file`); built-in ones
/// by their embedded text. An unreadable file is an error naming it.
pub fn inputs_sha256(
    scene_bytes: &[u8],
    scene: &Scene,
    gem: &GemSource,
    environment_file: Option<&Path>,
) -> Result<String, String> {
    let mut hash = Sha256::new();
    let mut add = |label: &str, bytes: &[u8]| {
        hash.update((label.len() as u64).to_le_bytes());
        hash.update(label.as_bytes());
        hash.update((bytes.len() as u64).to_le_bytes());
        hash.update(bytes);
    };
    add("scene", scene_bytes);
    add("gem", gem.text.as_bytes());
    for stone in &scene.stones {
        if let Some(recipe) = &stone.recipe {
            let source = GemSource::load(recipe).map_err(|e| e.to_string())?;
            add("stone gem", source.text.as_bytes());
        }
    }
    // A pipe would keep the render waiting here, a device never ends.
    let read = |path: &Path| match not_a_regular_file(path) {
        Some(kind) => Err(format!("{}: is {kind}, not a file", path.display())),
        None => std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display())),
    };
    if let Some(ground) = &scene.ground {
        let path = Path::new(&ground.material);
        if path.is_file() {
            add("ground material", &read(path)?);
        } else {
            add("ground material", ground.material.as_bytes());
        }
    }
    // The scene's map is turned and scaled as the scene's text says; an
    // `environment_file` (`--env`) replaces it unturned at intensity 1, so
    // the same file gives another render: it is hashed under its own label.
    match (environment_file, &scene.environment) {
        (Some(path), _) => add("environment replacing the scene's", &read(path)?),
        (None, EnvironmentSpec::File { path, .. }) => add("environment", &read(path)?),
        _ => {}
    }
    Ok(hex(&hash.finalize()))
}

/// The tile record of tile `split` of `render`, for `channels` as they
/// will be stored (sorted by name).
pub fn tile_record(
    render: &RenderRecord,
    split: TileSplit,
    channels: &[ExrChannel],
    bad_samples: u64,
) -> TileRecord {
    TileRecord {
        render: render.clone(),
        tile: split.index(),
        tiles: split.count(),
        pixels_sha256: pixels_sha256(channels),
        bad_samples,
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_named_otherwise_are_one_render_only_while_their_bytes_agree() {
        let lines = |recipe: &str, spp: &str, inputs: &str| -> Vec<RecordLine> {
            [("recipe", recipe), ("spp", spp), ("inputs_sha256", inputs)]
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .to_vec()
        };
        let ours = lines("\"job/gem.ron\"", "4", "ab");
        // The same bytes named from another folder: one render.
        assert_eq!(
            differing_line(&ours, &lines("\"gem.ron\"", "4", "ab")),
            None
        );
        // Other bytes: the name is the line given, being the more telling.
        let theirs = lines("\"other.ron\"", "4", "cd");
        assert_eq!(
            differing_line(&ours, &theirs).map(|(a, _)| a.0.as_str()),
            Some("recipe")
        );
        // A setting differs whatever the names.
        let theirs = lines("\"gem.ron\"", "8", "ab");
        assert_eq!(
            differing_line(&ours, &theirs).map(|(a, _)| a.0.as_str()),
            Some("spp")
        );
    }

    #[test]
    fn a_map_replacing_the_scene_s_is_another_input_than_the_same_file_as_the_scene_s() {
        // `--env sky.hdr` lights unturned at intensity 1; the scene's
        // `File(path: "sky.hdr", rotation_deg: 90)` turned: other pixels
        // from the same bytes, so other inputs.
        let path = std::env::temp_dir().join(format!("lapidary-record-{}.hdr", std::process::id()));
        std::fs::write(&path, b"the map's bytes").unwrap();
        let mut scene = crate::scene::default_scene();
        scene.environment = EnvironmentSpec::File {
            path: path.clone(),
            rotation_deg: 90.0,
            intensity: 1.0,
        };
        let gem = GemSource::new("gem.ron", "Gem()");
        let own = inputs_sha256(b"scene", &scene, &gem, None).unwrap();
        let replaced = inputs_sha256(b"scene", &scene, &gem, Some(&path)).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_ne!(own, replaced);
    }

    fn record() -> RenderRecord {
        RenderRecord {
            version: "0.1.0".into(),
            recipe: "my\ngem.ron".into(),
            scene: "builtin:studio".into(),
            environment: None,
            width_px: 32,
            height_px: 24,
            samples_per_pixel: 4,
            seed: 9,
            bounces: 4,
            ao_distance_mm: None,
            exposure_ev: 0.1,
            tone_curve: ToneCurve::Filmic,
            connections: true,
            flake_footprints: true,
            filter: PixelFilter::Tent,
            frame: Some(FrameOf {
                frame: 3,
                frames: 8,
                turn: TurnSpec::Camera,
            }),
            inputs_sha256: "ab".into(),
        }
    }

    #[test]
    fn a_record_reads_back_with_its_fields_and_a_line_break_cannot_split_it() {
        let tile = TileRecord {
            render: record(),
            tile: 2,
            tiles: 3,
            pixels_sha256: "cd".into(),
            bad_samples: 5,
        };
        let text = tile.to_text();
        let read = ReadRecord::parse(&text).unwrap();
        assert_eq!(read.size_px, (32, 24));
        assert_eq!(read.tile, (2, 3));
        assert_eq!(read.bad_samples, 5);
        assert_eq!(read.display.0, record().display_transform());
        assert!(read
            .render_lines
            .iter()
            .any(|(k, v)| k == "recipe" && v == "\"my\\ngem.ron\""));
        // A missing or extra line, or another header, is not a record.
        let refused = |text: &str| ReadRecord::parse(text).unwrap_err();
        assert!(refused(&text.replace("seed: 9\n", "")).contains("where `seed` belongs"));
        assert!(refused(&format!("{text}extra: 1\n")).contains("(`extra`) is one too many"));
        assert!(refused(&text.replace("record 1", "record 2")).starts_with("its first line is"));
        let seed_line = text.lines().position(|l| l.starts_with("seed: ")).unwrap() + 1;
        assert_eq!(
            refused(&text.replace("seed: 9\n", "seed: -9\n")),
            format!("line {seed_line}: `seed` is `-9`; allowed: a whole number from 0")
        );
    }
}
