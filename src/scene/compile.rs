//! Parse and validate a scene: RON text → [`SceneSpec`] (numbers
//! range-checked while parsing) → [`Scene`] (directions, frames and
//! quaternions computed, paths resolved, shapes validated).
//!
//! Rules that involve several fields or another module (camera position ≠
//! look_at, 1 to `MAX_STONES` stones, at most `MAX_LIGHTS` lights, Rect
//! aim_at ≠ centre, the cabochon's own rules) are checked after parsing;
//! their errors are located by a small walk over the RON text (`Locator`)
//! at the field they concern.
//!
//! So are the scene's references: each stone's gem (a built-in name, or a
//! `.ron` file that must exist), the ground's material (likewise) and the
//! environment image (an existing `.hdr` or `.exr` file). A bad one is
//! reported at the string where it is written, with a did-you-mean among
//! the built-in names or the files beside the one named. What the files
//! hold is read and checked when the scene is rendered, with positions in
//! those files.

use super::spec::{
    BaseSpec, CameraSpec, EnvironmentKind, GroundSpec, LightKind, OutlineSpec, SceneSpec,
    ShapeSpec, StoneSpec,
};
use super::{
    Camera, EnvironmentSpec, Ground, LightSpec, Scene, StonePlacement, Turntable, MAX_LIGHTS,
    MAX_STONES,
};
use crate::brdf::Rgb;
use crate::geometry::{Base, Cabochon, CabochonParams, GeometryError, Outline};
use crate::recipe::compile::{parse_ron_all, read_ron_file, ron_error};
use crate::recipe::error::{
    blank_comments_and_strings, did_you_mean, folder_separator_hint, line_col_of_offset,
    RecipeError,
};
use crate::recipe::library::{builtin_gem_names, builtin_material_names};
use glam::{DQuat, DVec3};
use std::path::{Path, PathBuf};

/// The built-in default scene (`gem-recipes/scenes/studio.ron`): one oval
/// cabochon of the command line's gem on a dark ground in the studio.
pub const DEFAULT_SCENE_SOURCE: &str = include_str!("../../gem-recipes/scenes/studio.ron");

/// Display name of the built-in scene in error messages.
const DEFAULT_SCENE_NAME: &str = "builtin:studio";

/// A view or light axis closer than this (radians, ≈ the horizontal part of
/// a unit vector) to world z cannot use z to build its frame.
const VERTICAL_TOLERANCE: f64 = 1e-9;

/// Parse and validate scene `text`. `path` is the scene file, used in error
/// messages and to resolve relative paths (without one, errors say
/// `<scene>` and relative paths stay as written: relative to the current
/// directory). The gems, materials and environment image the scene names
/// must exist (see the module docs).
pub fn parse_scene(text: &str, path: Option<&Path>) -> Result<Scene, RecipeError> {
    let display = path.map_or_else(|| "<scene>".to_string(), |p| p.display().to_string());
    parse_named(text, &display, path)
}

/// Read, parse and validate the scene file at `path`; an unreadable,
/// missing or non-UTF-8 file is a [`RecipeError`] naming it.
pub fn load_scene(path: &Path) -> Result<Scene, RecipeError> {
    let text = read_ron_file(&path.display().to_string(), "scene file")?;
    parse_scene(&text, Some(path))
}

/// [`load_scene`], lit by the equirectangular map `environment` (unturned,
/// at intensity 1) instead of the scene's own environment, which is then
/// neither used nor needed: its file may be missing (`render --env`).
pub fn load_scene_under(path: &Path, environment: &Path) -> Result<Scene, RecipeError> {
    let text = read_ron_file(&path.display().to_string(), "scene file")?;
    compile_named(
        &text,
        &path.display().to_string(),
        Some(path),
        Some(environment),
    )
}

/// The built-in studio scene ([`DEFAULT_SCENE_SOURCE`]), parsed.
///
/// It is embedded at build time and pinned by `tests/scene_recipe.rs`, so
/// failing to parse it is a bug in lapidary, not bad input.
pub fn default_scene() -> Scene {
    parse_named(DEFAULT_SCENE_SOURCE, DEFAULT_SCENE_NAME, None)
        .unwrap_or_else(|e| panic!("the built-in studio scene is invalid: {e}"))
}

fn parse_named(text: &str, display: &str, path: Option<&Path>) -> Result<Scene, RecipeError> {
    compile_named(text, display, path, None)
}

/// The scene of `text` (shown as `display`, read from `path`), its
/// environment replaced by the map `environment` when given.
fn compile_named(
    text: &str,
    display: &str,
    path: Option<&Path>,
    environment: Option<&Path>,
) -> Result<Scene, RecipeError> {
    let spec: SceneSpec = parse_ron_all(text, |e| scene_ron_error(display, text, e))?;
    Compiler {
        display,
        locator: Locator::new(text),
        dir: path.and_then(Path::parent),
        environment_given: environment,
    }
    .scene(&spec, path)
}

/// Like [`ron_error`], with unknown enum variants (an outline `Hexagon`, a
/// light `Spot`) named by what they are and the allowed names listed.
fn scene_ron_error(path: &str, text: &str, e: ron::error::SpannedError) -> RecipeError {
    if let ron::error::Error::NoSuchEnumVariant {
        expected,
        found,
        outer,
    } = &e.code
    {
        let what = outer
            .as_deref()
            .map_or("variant".to_string(), str::to_lowercase);
        let hint = did_you_mean(found, expected.iter().copied())
            .map(|s| format!(" (did you mean `{s}`?)"))
            .unwrap_or_default();
        return RecipeError::at(
            path,
            e.span.start.line,
            e.span.start.col,
            format!(
                "unknown {what} `{found}`{hint}; allowed: {}",
                expected.join(", ")
            ),
        );
    }
    ron_error(path, text, e)
}

/// One step of a walk from the scene's top-level value to a field.
#[derive(Clone, Copy, Debug)]
enum Step<'a> {
    /// The value of a named field of the current struct.
    Field(&'a str),
    /// The n-th (0-based) element of the current list.
    Element(usize),
}

/// Finds where a value is written in the scene text, for errors found after
/// parsing. Works on a copy of the text with comments and string contents
/// blanked (byte offsets unchanged), so brackets and names in them do not
/// count; struct names are optional, as in RON.
struct Locator<'t> {
    text: &'t str,
    code: Vec<u8>,
}

impl<'t> Locator<'t> {
    fn new(text: &'t str) -> Self {
        Locator {
            text,
            code: blank_comments_and_strings(text),
        }
    }

    fn skip_ws(&self, mut i: usize) -> usize {
        while i < self.code.len() && self.code[i].is_ascii_whitespace() {
            i += 1;
        }
        i
    }

    /// End (exclusive) of the value starting at `start`: the first `,` or
    /// closing bracket at its own nesting depth.
    fn value_end(&self, start: usize) -> usize {
        let mut depth = 0usize;
        for (i, c) in self.code.iter().enumerate().skip(start) {
            match c {
                b'(' | b'[' | b'{' => depth += 1,
                b')' | b']' | b'}' if depth == 0 => return i,
                b')' | b']' | b'}' => depth -= 1,
                b',' if depth == 0 => return i,
                _ => {}
            }
        }
        self.code.len()
    }

    /// Offset of the first byte of the body of the struct-like value at
    /// `start` (after its `(`), looking through a `Some(…)` wrapper.
    fn body(&self, start: usize, end: usize) -> Option<usize> {
        let open = (start..end).find(|&i| self.code[i] == b'(')?;
        if self.code[start..open].trim_ascii() == b"Some" {
            let inner = (open + 1..end).find(|&i| self.code[i] == b'(')?;
            return Some(inner + 1);
        }
        Some(open + 1)
    }

    /// Offset of the name of field `name` at depth 0 of the struct body
    /// starting at `from` and the offset of its value.
    fn field(&self, from: usize, end: usize, name: &str) -> Option<(usize, usize)> {
        let mut depth = 0usize;
        let mut i = from;
        let is_word = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
        while i < end {
            match self.code[i] {
                b'(' | b'[' | b'{' => depth += 1,
                b')' | b']' | b'}' => {
                    if depth == 0 {
                        return None;
                    }
                    depth -= 1;
                }
                c if depth == 0 && is_word(c) && (i == 0 || !is_word(self.code[i - 1])) => {
                    let word_end = (i..end).find(|&k| !is_word(self.code[k])).unwrap_or(end);
                    let after = self.skip_ws(word_end);
                    if &self.code[i..word_end] == name.as_bytes()
                        && self.code.get(after) == Some(&b':')
                    {
                        return Some((i, self.skip_ws(after + 1)));
                    }
                    i = word_end;
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
        None
    }

    /// Start of the n-th element of the list value at `start`.
    fn element(&self, start: usize, end: usize, n: usize) -> Option<usize> {
        if self.code.get(start) != Some(&b'[') {
            return None;
        }
        let mut at = self.skip_ws(start + 1);
        for _ in 0..n {
            let stop = self.value_end(at);
            if stop >= end || self.code[stop] != b',' {
                return None;
            }
            at = self.skip_ws(stop + 1);
        }
        (at < end && self.code[at] != b']').then_some(at)
    }

    /// The deepest point of `steps` that could be found: its mark (a
    /// field's name, or a list element's start), the start and end of its
    /// value, and whether every step was found; `None` if not even the
    /// first step was found.
    fn walk(&self, steps: &[Step]) -> Option<(usize, usize, usize, bool)> {
        let mut start = self.skip_ws(0);
        let mut end = self.code.len();
        let mut best = None;
        for step in steps {
            let found = match *step {
                Step::Field(name) => self.body(start, end).and_then(|b| self.field(b, end, name)),
                Step::Element(n) => self.element(start, end, n).map(|e| (e, e)),
            };
            let Some((mark, value)) = found else {
                return best.map(|(mark, start, end, _)| (mark, start, end, false));
            };
            start = value;
            end = self.value_end(value);
            best = Some((mark, start, end, true));
        }
        best
    }

    /// (line, col) of the deepest point of `steps` that could be found
    /// (a field's name, or a list element's start); `None` if not even the
    /// first step was found.
    fn find(&self, steps: &[Step]) -> Option<(usize, usize)> {
        self.walk(steps)
            .map(|(mark, ..)| line_col_of_offset(self.text, mark))
    }

    /// (line, col) of the string literal (its opening quote) that is the
    /// value at `steps`, also inside a `Some(…)`: where a name or a path
    /// was written. Falls back to [`Locator::find`]'s place.
    fn find_string(&self, steps: &[Step]) -> Option<(usize, usize)> {
        let (mark, start, end, complete) = self.walk(steps)?;
        let quote = (start..end).find(|&i| self.code[i] == b'"');
        let offset = quote.filter(|_| complete).unwrap_or(mark);
        Some(line_col_of_offset(self.text, offset))
    }
}

/// Turns the parsed spec into plain data, with errors located in the text.
struct Compiler<'a> {
    display: &'a str,
    locator: Locator<'a>,
    /// Folder of the scene file, for relative paths.
    dir: Option<&'a Path>,
    /// A map that replaces the scene's environment (not read then).
    environment_given: Option<&'a Path>,
}

impl Compiler<'_> {
    fn error(&self, steps: &[Step], message: String) -> RecipeError {
        self.error_at(self.locator.find(steps), message)
    }

    /// An error at the string (a name or a path) written at `steps`.
    fn error_at_string(&self, steps: &[Step], message: String) -> RecipeError {
        self.error_at(self.locator.find_string(steps), message)
    }

    fn error_at(&self, place: Option<(usize, usize)>, message: String) -> RecipeError {
        match place {
            Some((line, col)) => RecipeError::at(self.display, line, col, message),
            None => RecipeError::whole_file(self.display, message),
        }
    }

    /// The scene, or every problem found in its camera, stones, ground,
    /// lights and environment, each part checked whatever the others gave
    /// (reported together, in the file's order).
    fn scene(&self, spec: &SceneSpec, path: Option<&Path>) -> Result<Scene, RecipeError> {
        let count = spec.stones.len();
        if count == 0 || count > MAX_STONES {
            return Err(self.error(
                &[Step::Field("stones")],
                format!("`stones` has {count} stones; allowed: 1 to {MAX_STONES} stones"),
            ));
        }
        if spec.lights.len() > MAX_LIGHTS {
            return Err(self.error(
                &[Step::Field("lights")],
                format!(
                    "`lights` has {} lights; allowed: 0 to {MAX_LIGHTS} lights",
                    spec.lights.len()
                ),
            ));
        }
        /// The value, or `None` with its error added to `errors`.
        fn kept<T>(errors: &mut Vec<RecipeError>, checked: Result<T, RecipeError>) -> Option<T> {
            checked.map_err(|e| errors.push(e)).ok()
        }
        let mut errors = Vec::new();
        let camera = kept(&mut errors, self.camera(&spec.camera));
        let stones: Vec<_> = (spec.stones.iter().enumerate())
            .filter_map(|(i, s)| kept(&mut errors, self.stone(i, s)))
            .collect();
        let ground = (spec.ground.as_ref()).map(|g| kept(&mut errors, self.ground(g)));
        let lights: Vec<_> = (spec.lights.iter().enumerate())
            .filter_map(|(i, l)| kept(&mut errors, self.light(i, l)))
            .collect();
        let environment = match self.environment_given {
            Some(map) => Some(EnvironmentSpec::File {
                path: map.to_path_buf(),
                rotation_deg: 0.0,
                intensity: 1.0,
            }),
            None => kept(&mut errors, self.environment(&spec.environment)),
        };
        let (Some(camera), Some(environment), true) = (camera, environment, errors.is_empty())
        else {
            // Not empty: a part is `None` only where `kept` added its error.
            let first = errors.remove(0);
            return Err(RecipeError::gathered(first, errors));
        };
        Ok(Scene {
            camera,
            stones,
            ground: ground.flatten(),
            lights,
            environment,
            turntable: spec.turntable.as_ref().map(|t| Turntable {
                frames: t.frames,
                turn: t.turn,
            }),
            path: path.map(Path::to_path_buf),
        })
    }

    fn camera(&self, spec: &CameraSpec) -> Result<Camera, RecipeError> {
        Ok(match *spec {
            CameraSpec::Orbit {
                target,
                distance,
                elevation_deg,
                azimuth_deg,
                vertical_fov_deg,
            } => {
                let target = DVec3::from_array(target);
                let (elevation, azimuth) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
                let horizontal = DVec3::new(azimuth.cos(), azimuth.sin(), 0.0);
                // Spherical coordinates about the target, z up.
                let offset = horizontal * elevation.cos() + DVec3::Z * elevation.sin();
                let up = if elevation.cos() < VERTICAL_TOLERANCE {
                    // The limit of z projected off the view as |elevation| → 90°:
                    // away from the camera's side when above, towards it below.
                    -horizontal * elevation.signum()
                } else {
                    DVec3::Z
                };
                Camera {
                    position: target + distance * offset,
                    look_at: target,
                    up,
                    vertical_fov_deg,
                }
            }
            CameraSpec::LookAt {
                position,
                look_at,
                vertical_fov_deg,
            } => {
                let (position, look_at) = (DVec3::from_array(position), DVec3::from_array(look_at));
                let view = unit(look_at - position).ok_or_else(|| {
                    self.error(
                        &[Step::Field("camera"), Step::Field("look_at")],
                        format!(
                            "camera `look_at` = {} is the camera `position`; allowed: any point other than `position`",
                            fmt_vec(look_at)
                        ),
                    )
                })?;
                let up = if view.truncate().length() < VERTICAL_TOLERANCE {
                    DVec3::Y
                } else {
                    DVec3::Z
                };
                Camera {
                    position,
                    look_at,
                    up,
                    vertical_fov_deg,
                }
            }
        })
    }

    fn stone(&self, index: usize, spec: &StoneSpec) -> Result<StonePlacement, RecipeError> {
        let at = |field| {
            [
                Step::Field("stones"),
                Step::Element(index),
                Step::Field(field),
            ]
        };
        let ShapeSpec::Cabochon {
            outline,
            length,
            width,
            dome_height,
            profile_exponent,
            girdle_height,
            base,
            buff_top,
        } = spec.shape;
        let shape = CabochonParams {
            outline: match outline {
                OutlineSpec::Round => Outline::Round,
                OutlineSpec::Oval => Outline::Oval,
                OutlineSpec::Cushion { exponent } => Outline::Cushion { exponent },
                OutlineSpec::Pear => Outline::Pear,
                OutlineSpec::Marquise => Outline::Marquise,
            },
            length,
            width,
            dome_height,
            profile_exponent,
            girdle_height,
            base: match base {
                BaseSpec::Flat => Base::Flat,
                BaseSpec::Domed { height } => Base::Domed { height },
            },
            buff_top,
        };
        Cabochon::new(shape).map_err(|e| self.shape_error(index, &e))?;
        // The gem it names, checked after its own shape.
        let recipe = match &spec.recipe {
            None => None,
            Some(name) => Some(self.name_or_path(
                name,
                &at("recipe"),
                &format!("stone {}", index + 1),
                "gem",
                &builtin_gem_names().collect::<Vec<_>>(),
            )?),
        };
        let [x, y, z] = spec.rotation_deg.map(f64::to_radians);
        Ok(StonePlacement {
            recipe,
            shape,
            position: DVec3::from_array(spec.position),
            // About world x first, then y, then z.
            rotation: DQuat::from_rotation_z(z)
                * DQuat::from_rotation_y(y)
                * DQuat::from_rotation_x(x),
            seed: spec.seed,
        })
    }

    /// A cabochon error at the offending field of stone `index`'s shape.
    fn shape_error(&self, index: usize, e: &GeometryError) -> RecipeError {
        let mut steps = vec![
            Step::Field("stones"),
            Step::Element(index),
            Step::Field("shape"),
        ];
        match e.name {
            "base.height" => steps.extend([Step::Field("base"), Step::Field("height")]),
            "exponent" => steps.extend([Step::Field("outline"), Step::Field("exponent")]),
            name => steps.push(Step::Field(name)),
        }
        self.error(&steps, format!("stone {}: {e}", index + 1))
    }

    fn ground(&self, spec: &GroundSpec) -> Result<Ground, RecipeError> {
        let material = self.name_or_path(
            &spec.material,
            &[Step::Field("ground"), Step::Field("material")],
            "ground",
            "material",
            &builtin_material_names().collect::<Vec<_>>(),
        )?;
        Ok(Ground {
            height: spec.height,
            material,
        })
    }

    fn light(&self, index: usize, spec: &LightKind) -> Result<LightSpec, RecipeError> {
        let rgb = Rgb::from_array;
        Ok(match *spec {
            LightKind::Sphere {
                centre,
                radius,
                radiance,
            } => LightSpec::Sphere {
                centre: DVec3::from_array(centre),
                radius,
                radiance: rgb(radiance),
            },
            LightKind::Point {
                position,
                intensity,
            } => LightSpec::Point {
                position: DVec3::from_array(position),
                intensity: rgb(intensity),
            },
            LightKind::Rect {
                centre,
                aim_at,
                width,
                height,
                radiance,
            } => {
                let centre = DVec3::from_array(centre);
                let normal = unit(DVec3::from_array(aim_at) - centre).ok_or_else(|| {
                    self.error(
                        &[Step::Field("lights"), Step::Element(index), Step::Field("aim_at")],
                        format!(
                            "light {}: Rect `aim_at` = {} is its `centre`; allowed: any point other than `centre`",
                            index + 1,
                            fmt_vec(centre)
                        ),
                    )
                })?;
                // Width runs horizontally, like a studio soft box, unless the
                // box faces straight up or down.
                let horizontal = DVec3::Z.cross(normal);
                let u_axis = if horizontal.length() < VERTICAL_TOLERANCE {
                    DVec3::X
                } else {
                    horizontal.normalize()
                };
                LightSpec::Rect {
                    centre,
                    normal,
                    u_axis,
                    v_axis: normal.cross(u_axis),
                    width,
                    height,
                    radiance: rgb(radiance),
                }
            }
            LightKind::Sun {
                elevation_deg,
                azimuth_deg,
                angular_diameter_deg,
                irradiance,
            } => {
                let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
                LightSpec::Sun {
                    direction: DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()),
                    angular_diameter_deg,
                    irradiance: rgb(irradiance),
                }
            }
        })
    }

    fn environment(&self, spec: &EnvironmentKind) -> Result<EnvironmentSpec, RecipeError> {
        Ok(match spec {
            EnvironmentKind::Constant { radiance } => {
                EnvironmentSpec::Constant(Rgb::from_array(*radiance))
            }
            EnvironmentKind::Studio {
                intensity,
                rotation_deg,
            } => EnvironmentSpec::Studio {
                intensity: *intensity,
                rotation_deg: *rotation_deg,
            },
            EnvironmentKind::File {
                path,
                rotation_deg,
                intensity,
            } => EnvironmentSpec::File {
                path: self.environment_file(path)?,
                rotation_deg: *rotation_deg,
                intensity: *intensity,
            },
        })
    }

    /// The environment image `written`, resolved against the scene's folder:
    /// it must be an existing `.hdr` or `.exr` file (its contents are read
    /// by the renderer).
    fn environment_file(&self, written: &str) -> Result<PathBuf, RecipeError> {
        const ALLOWED: &str =
            "an equirectangular .hdr or .exr image file, relative to the scene file";
        let at = [Step::Field("environment"), Step::Field("path")];
        if written.trim().is_empty() {
            return Err(self.error_at_string(
                &at,
                format!("environment: `path` is empty; allowed: {ALLOWED}"),
            ));
        }
        let resolved = self.resolve(written);
        let extension = resolved
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        if !ENVIRONMENT_EXTENSIONS.contains(&extension.as_str()) {
            let found = if extension.is_empty() {
                "no extension".to_string()
            } else {
                format!("the extension `.{extension}`")
            };
            return Err(self.error_at_string(
                &at,
                format!("environment: image file `{written}` has {found}; allowed: {ALLOWED}"),
            ));
        }
        if let Some(problem) = file_problem(written, &resolved, ENVIRONMENT_EXTENSIONS, None) {
            return Err(self.error_at_string(
                &at,
                format!("environment: image file `{written}` {problem}; allowed: {ALLOWED}"),
            ));
        }
        Ok(resolved)
    }

    /// A gem or material as written at `at` (`context` opens the messages):
    /// a name stays a name and must be one of the built-in `kind`s
    /// `builtins`; a path (with `/` or ending in `.ron`) is resolved against
    /// the scene's folder and must be an existing file (its contents are
    /// read and checked when the scene is rendered).
    fn name_or_path(
        &self,
        spec: &str,
        at: &[Step],
        context: &str,
        kind: &str,
        builtins: &[&str],
    ) -> Result<String, RecipeError> {
        let allowed = format!(
            "a built-in {kind} name ({}) or a .ron {kind} file (a path with `/` or ending in `.ron`, relative to the scene file)",
            builtins.join(", ")
        );
        if spec.trim().is_empty() {
            let field = match at.last() {
                Some(Step::Field(f)) => f,
                _ => "name",
            };
            return Err(self.error_at_string(
                at,
                format!("{context}: `{field}` is empty; allowed: {allowed}"),
            ));
        }
        if !(spec.contains('/') || spec.ends_with(".ron")) {
            if builtins.contains(&spec) {
                return Ok(spec.to_string());
            }
            let hint = did_you_mean(spec, builtins.iter().copied())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            return Err(self.error_at_string(
                at,
                format!("{context}: unknown {kind} `{spec}`{hint}; allowed: {allowed}"),
            ));
        }
        let resolved = self.resolve(spec);
        // A built-in named like a file (`goldstone.ron`) is a likely slip.
        let builtin = Path::new(spec)
            .file_stem()
            .and_then(|stem| did_you_mean(stem.to_str()?, builtins.iter().copied()))
            .map(|name| {
                format!(" (did you mean the built-in {kind} `{name}`, written without a path or `.ron`?)")
            });
        if let Some(problem) = file_problem(spec, &resolved, &["ron"], builtin) {
            return Err(self.error_at_string(
                at,
                format!("{context}: {kind} file `{spec}` {problem}; allowed: {allowed}"),
            ));
        }
        Ok(resolved.to_string_lossy().into_owned())
    }

    fn resolve(&self, path: &str) -> PathBuf {
        match self.dir {
            Some(dir) if Path::new(path).is_relative() => dir.join(path),
            _ => PathBuf::from(path),
        }
    }
}

/// The extensions (lower case) of the environment images the renderer
/// reads: Radiance RGBE and OpenEXR.
const ENVIRONMENT_EXTENSIONS: &[&str] = &["hdr", "exr"];

/// At most this many entries of a folder are read for a did-you-mean.
const MAX_SIBLINGS: usize = 4096;

/// Why the file a scene names as `written` (found at `resolved`) cannot be
/// used, if it cannot: it does not exist (with a did-you-mean among the
/// files beside it whose extension is one of `extensions`, else the hint
/// `otherwise`), is a folder, or cannot be looked at.
fn file_problem(
    written: &str,
    resolved: &Path,
    extensions: &[&str],
    otherwise: Option<String>,
) -> Option<String> {
    let place = if resolved.as_os_str() != written {
        format!(" at {}", resolved.display())
    } else if resolved.is_relative() {
        " in the current directory".to_string()
    } else {
        String::new()
    };
    match std::fs::metadata(resolved) {
        Ok(m) if m.is_dir() => Some(format!("is a directory{place}, not a file")),
        Ok(_) => None,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let hint = sibling_like(written, resolved, extensions)
                .map(|s| format!(" (did you mean `{s}`?)"))
                .or(otherwise)
                .unwrap_or_default();
            let separator = folder_separator_hint(written);
            Some(format!("not found{place}{separator}{hint}"))
        }
        Err(e) => Some(format!("cannot be read{place}: {e}")),
    }
}

/// `written` with its file name replaced by the closest name of a file
/// beside `resolved` with one of `extensions`, if one is close.
fn sibling_like(written: &str, resolved: &Path, extensions: &[&str]) -> Option<String> {
    let name = resolved.file_name()?.to_str()?;
    let folder = match resolved.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let siblings: Vec<String> = std::fs::read_dir(folder)
        .ok()?
        .take(MAX_SIBLINGS)
        .filter_map(|entry| entry.ok()?.file_name().into_string().ok())
        .filter(|s| {
            let extension = Path::new(s)
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase());
            extension.is_some_and(|e| extensions.contains(&e.as_str()))
        })
        .collect();
    let close = did_you_mean(name, siblings.iter().map(String::as_str))?;
    let folder_as_written = written.rfind('/').map_or("", |k| &written[..=k]);
    Some(format!("{folder_as_written}{close}"))
}

/// `v / |v|`, or `None` when `v` is zero (or so small that it cannot be
/// normalised).
fn unit(v: DVec3) -> Option<DVec3> {
    let length = v.length();
    let u = v / length;
    (length > 0.0 && u.is_finite()).then_some(u)
}

fn fmt_vec(v: DVec3) -> String {
    format!("({}, {}, {})", v.x, v.y, v.z)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locator_walks_fields_and_elements_past_comments_and_strings() {
        let text = "S(\n a: [ (b: \"x)]\"), /* b: ( */ (\n  // b: 0\n  b: 2) ],\n)";
        let l = Locator::new(text);
        // Element 1's field `b` is on line 4, column 3 (the comment on line 3
        // and the bracket in the string do not count).
        let steps = [Step::Field("a"), Step::Element(1), Step::Field("b")];
        assert_eq!(l.find(&steps), Some((4, 3)));
        assert_eq!(
            l.find(&[Step::Field("a"), Step::Element(0), Step::Field("b")]),
            Some((2, 8))
        );
        // A missing element falls back to the deepest place found: `a`.
        assert_eq!(l.find(&[Step::Field("a"), Step::Element(5)]), Some((2, 2)));
        assert_eq!(l.find(&[Step::Field("zz")]), None);
    }

    #[test]
    fn locator_finds_the_string_written_as_a_value() {
        // The same name in a comment and in another element first.
        let text = "S( // r: Some(\"g\")\n s: [(r: Some(\"g\")),\n  (q: 1, r: Some( \"g\" ))],\n e: F(p: \"g\"))";
        let l = Locator::new(text);
        let r1 = [Step::Field("s"), Step::Element(1), Step::Field("r")];
        assert_eq!(l.find_string(&r1), Some((3, 19)));
        assert_eq!(l.find(&r1), Some((3, 10)));
        let p = [Step::Field("e"), Step::Field("p")];
        assert_eq!(l.find_string(&p), Some((4, 10)));
        // A step not found: the deepest place found, not a string in it.
        let missing = [Step::Field("s"), Step::Element(1), Step::Field("zz")];
        assert_eq!(l.find_string(&missing), Some((3, 3)));
    }
}
