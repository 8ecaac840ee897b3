//! The pictures of `lapidary gallery`: every built-in gem in the studio, a
//! labelled contact sheet of them, and three figures of the course notes
//! re-rendered with our materials on spheres.
//!
//! - figure 4.11: the material library, one sphere per material;
//! - figure 3.2: white diffuse spheres under a yellow varnish of growing
//!   thickness (section 3.1.3, Beer–Lambert absorption, eqs. 3.5–3.7);
//! - figure 4.3: frosted metal (4.11i) against patina (4.11e), both of
//!   effective roughness m = 17° (sections 4.2.5–4.2.6), each with an
//!   in-plane BRDF slice under it showing one highlight lobe against two.
//!
//! Everything here is a pure function of its settings: the sample pattern
//! is keyed by (seed, pixel, sample) ([`crate::render::film`]), so the bytes
//! do not depend on the thread count. Nothing prints; the command line
//! reports progress and writes the files.
//!
//! A sphere is a cabochon with a round outline, an elliptical dome of
//! height r over a girdle of diameter 2r, no girdle band and a domed back of
//! depth r (`sphere_shape`). Each sphere is rendered in an image of its
//! own with the camera on its centre, and the images are tiled by
//! `contact_sheet`: a tile's centre is its sphere's centre.

use glam::{DQuat, DVec3};
use image::imageops::{self, FilterType};
use image::{Rgb, RgbImage};
use rayon::prelude::*;

use crate::brdf::classify::classify;
use crate::brdf::LayeredBrdf;
use crate::gallery::plot::text::{draw_text_centred, text_height, text_width, ClipRect};
use crate::gallery::plot::{in_plane_panel, polar_plot, PolarPlotStyle};
use crate::geometry::{Base, CabochonParams, Outline};
use crate::output::tonemap::DisplayTransform;
use crate::recipe::compile::load_material_with;
use crate::recipe::error::RecipeError;
use crate::recipe::gem::{compile_gem, Gem, GemSource};
use crate::recipe::library::builtin_material_names;
use crate::recipe::TableCache;
use crate::recipe::Tables;
use crate::render::camera::PinholeCamera;
use crate::render::environment::Environment;
use crate::render::film::{render, FilmSettings};
use crate::render::flake_lobe::FlakeLobes;
use crate::render::prepare::{camera_for, environment_for_spec, stone_instances};
use crate::render::render_scene::RenderScene;
use crate::render::still::{DEFAULT_BOUNCES, MAX_BOUNCES, MAX_SPP as MAX_SAMPLES_PER_PIXEL};
use crate::render::world::World;
use crate::sampling::direction_from_degrees;
use crate::scene::{default_scene, Camera, Scene, StonePlacement};

/// Largest image side accepted, in pixels (a bound on film memory: the
/// gallery holds every gem's image for the contact sheet).
pub(crate) const MAX_SIZE_PX: u32 = 8192;

/// Radius of the figure spheres in scene units (mm): about the size of the
/// default scene's 10 × 8 mm stone, so the studio's key light (1.5 mm at
/// ≈ 24 mm) and ground look the same on both.
pub(crate) const SPHERE_RADIUS_MM: f64 = 4.0;

/// Layer thicknesses of figure 3.2, as listed in its caption.
pub const FIGURE_3_2_THICKNESSES: [f64; 12] =
    [0.0, 0.2, 0.4, 0.6, 0.8, 1.2, 1.6, 3.0, 5.0, 7.5, 10.0, 15.0];

/// Absorption coefficient α of figure 3.2's yellow varnish per unit of
/// thickness (R, G, B). The notes give no value; a yellow filter absorbs
/// blue most and red least. With Beer–Lambert along the in and out paths
/// (eq. 3.5, `T = exp(−α d (1/cosθv' + 1/cosθl'))`, ≈ `exp(−2αd)` at normal
/// incidence) the caption's thicknesses then run from white (d = 0) through
/// pale and saturated yellow (d ≈ 0.4–1.6, blue gone: `exp(−2.9)` at 1.6)
/// to orange (d = 3–5, green falls) and a dark red-brown (d = 15: red keeps
/// `exp(−1.5)` ≈ 0.22): the notes' "progressive changes in colour,
/// saturation and hue".
pub(crate) const FIGURE_3_2_ABSORPTION: [f64; 3] = [0.05, 0.1, 0.9];

/// Diffuse reflectance of figure 3.2's "white" base: a white paint's, with
/// headroom below 1 so the tone curve keeps the colour at d = 0 visible.
pub(crate) const FIGURE_3_2_BASE_WHITE: f64 = 0.8;

/// The two materials of figure 4.3 with what the notes call them:
/// blue metallic paint (4.11i, frosted metal: a rough 17° varnish over a
/// 1° aluminium) and silver paint (4.11e, patina: a 7° varnish over a 10°
/// silver), effective roughness 17° both (section 4.2.6).
pub(crate) const FIGURE_4_3_MATERIALS: [(&str, &str); 2] = [
    ("blue-metallic-paint", "frosted metal (4.11i): one lobe"),
    ("silver-paint", "patina (4.11e): two lobes"),
];

/// Azimuths of [`turntable_strip`], evenly over a full turn.
const TURNTABLE_FRAMES: u32 = 8;

/// Figure 4.5 b's sunstones, left to right, with what their bodies are.
const FIGURE_4_5B_GEMS: [(&str, &str); 3] = [
    ("sunstone", "opaque"),
    ("pink-sunstone", "translucent"),
    ("patterned-sunstone", "translucent"),
];

/// Incidence angle of figure 4.3's BRDF slices, degrees from the normal.
pub(crate) const FIGURE_4_3_INCIDENCE_DEG: f64 = 30.0;

/// Background of the sheets.
pub(crate) const SHEET_BACKGROUND: Rgb<u8> = Rgb([22, 24, 30]);
/// The one-pixel frame drawn around every tile's image: a colour no label
/// uses, so a program can find the tiles by their frames.
pub const FRAME_COLOUR: Rgb<u8> = Rgb([92, 98, 118]);
/// Colour of a tile's first label line (the name) and of the title.
pub(crate) const NAME_COLOUR: Rgb<u8> = Rgb([232, 232, 238]);
/// Colour of a tile's further label lines.
pub(crate) const CAPTION_COLOUR: Rgb<u8> = Rgb([150, 156, 172]);

/// Side of a gem thumbnail on the contact sheet at most, pixels.
pub(crate) const THUMBNAIL_MAX_PX: u32 = 256;
/// Smallest side of a figure sphere, pixels: small enough to be quick,
/// large enough that the label under it fits and a sphere has a centre.
pub(crate) const MIN_SPHERE_PX: u32 = 48;
/// Narrowest tile: room for 24 label characters at text scale 1 (the
/// longest library name, `blue-metallic-car-paint`, has 23).
pub(crate) const MIN_CELL_WIDTH_PX: u32 = 192;
/// Space between tiles and around the sheet, pixels.
pub(crate) const GUTTER_PX: u32 = 12;

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// A recipe (gem or material) failed to load or compile.
    #[error(transparent)]
    Recipe(#[from] RecipeError),
    /// The scene could not be built (shape, ground, environment).
    #[error("{0}")]
    Scene(String),
    /// A setting out of its range.
    #[error("{field} {value}: allowed {min} to {max}")]
    Setting {
        /// The setting, as the command line spells it (`--size`).
        field: &'static str,
        /// The value given.
        value: u64,
        /// Smallest allowed value.
        min: u64,
        /// Largest allowed value.
        max: u64,
    },
}

/// How to render the gallery's images.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GallerySettings {
    /// Side of each gem image, pixels (1 to `MAX_SIZE_PX`). The figures
    /// scale with it: spheres of `size_px / 5` (figures 4.11, 3.2) and
    /// `size_px / 2` (figure 4.3), at least `MIN_SPHERE_PX`.
    pub size_px: u32,
    /// Samples per pixel (1 to `MAX_SAMPLES_PER_PIXEL`).
    pub samples_per_pixel: u32,
    /// Seed of the sample pattern (the gems keep their recipe seeds).
    pub seed: u64,
    /// Bounces after the first hit (0 to [`MAX_BOUNCES`]).
    pub max_bounces: u32,
    /// Compile every material without its multiple-scattering
    /// compensation (the notes' single-crossing model): several times
    /// quicker to prepare, rough layered materials darker (by up to about a
    /// third). For previews and tests; the committed gallery is not a
    /// draft.
    pub draft: bool,
}

impl Default for GallerySettings {
    /// 768 px, 256 spp, seed 0, [`DEFAULT_BOUNCES`] bounces.
    fn default() -> Self {
        Self {
            size_px: 768,
            samples_per_pixel: 256,
            seed: 0,
            max_bounces: DEFAULT_BOUNCES,
            draft: false,
        }
    }
}

impl GallerySettings {
    /// Checks every field against its range, naming the command-line flag.
    pub fn check(&self) -> Result<(), FigureError> {
        let in_range = |field, value: u32, min: u32, max: u32| {
            if (min..=max).contains(&value) {
                Ok(())
            } else {
                Err(FigureError::Setting {
                    field,
                    value: u64::from(value),
                    min: u64::from(min),
                    max: u64::from(max),
                })
            }
        };
        in_range("--size", self.size_px, 1, MAX_SIZE_PX)?;
        in_range("--spp", self.samples_per_pixel, 1, MAX_SAMPLES_PER_PIXEL)?;
        in_range("--bounces", self.max_bounces, 0, MAX_BOUNCES)
    }

    /// Side of a sphere of figures 4.11 and 3.2, pixels.
    pub(crate) fn small_sphere_px(&self) -> u32 {
        // A fifth keeps the 24-sphere figure 4.11 near 1 MB as a PNG at 768.
        (self.size_px / 5).max(MIN_SPHERE_PX)
    }

    /// Side of a sphere of figure 4.3 (a magnification), pixels.
    pub(crate) fn large_sphere_px(&self) -> u32 {
        (self.size_px / 2).max(MIN_SPHERE_PX)
    }
}

/// A rendered built-in gem with the words its tile needs.
#[derive(Clone, Debug, PartialEq)]
pub struct GemPicture {
    /// The gem's name (`green-aventurine`).
    pub name: String,
    /// The first sentence of its recipe's description.
    pub summary: String,
    /// The tone-mapped render, `size_px` square.
    pub image: RgbImage,
}

/// Tone-maps a render for PNG output: the filmic curve at 0 EV, dithered
/// with the sample seed (as `lapidary render` does by default).
fn develop(scene: &RenderScene, camera: &PinholeCamera, settings: &FilmSettings) -> RgbImage {
    let film = render(scene, camera, settings, &|_| {});
    let transform = DisplayTransform {
        dither_seed: settings.seed,
        ..DisplayTransform::default()
    };
    transform.encode(&film.rgb, settings.width, settings.height)
}

fn film_settings(side_px: u32, settings: &GallerySettings) -> FilmSettings {
    FilmSettings::new(side_px, side_px, settings.samples_per_pixel, settings.seed)
}

/// Compiles gem recipe `source` with the recipe's seed; with `draft`
/// every material without its compensation table.
pub(crate) fn compile_gem_draft_or_final(
    source: &GemSource,
    draft: bool,
    cache: &TableCache,
) -> Result<Gem, FigureError> {
    let tables = tables_for(draft, cache);
    Ok(compile_gem(source, None, tables)?)
}

/// The tables of a draft (none) or of a final picture (through `cache`).
fn tables_for(draft: bool, cache: &TableCache) -> Tables<'_> {
    if draft {
        Tables::Skipped
    } else {
        Tables::Computed(cache)
    }
}

/// Loads and compiles library material (or material file) `spec`; with
/// `draft`, without its compensation table.
pub(crate) fn compile_material_spec(
    spec: &str,
    draft: bool,
    cache: &TableCache,
) -> Result<LayeredBrdf, FigureError> {
    let tables = tables_for(draft, cache);
    Ok(load_material_with(spec, tables)?)
}

/// Renders built-in gem `name` on the default scene's cabochon in the
/// default studio scene: without `draft`, the same bytes as
/// `lapidary render NAME -o NAME.png --size N --spp S` with the same seed.
pub fn render_gem(
    name: &str,
    settings: &GallerySettings,
    cache: &TableCache,
) -> Result<GemPicture, FigureError> {
    settings.check()?;
    let source = GemSource::load(name)?;
    let studio = Studio::new(default_scene(), settings, cache)?;
    let gem = compile_gem_draft_or_final(&source, settings.draft, cache)?;
    let summary = first_sentence(&gem.description).to_string();
    Ok(GemPicture {
        name: name.to_string(),
        summary,
        image: studio.render(gem, settings.size_px, settings)?,
    })
}

/// The first sentence of `text`: up to the first `.`, `!` or `?` followed
/// by white space or the end (so "section 4.3.1" does not end it), with
/// runs of white space made single spaces.
pub(crate) fn first_sentence(text: &str) -> String {
    let words: Vec<&str> = text.split_whitespace().collect();
    let mut out = Vec::new();
    for word in words {
        out.push(word);
        if word.ends_with(['.', '!', '?']) {
            break;
        }
    }
    out.join(" ")
}

/// A sphere of radius `radius_mm` as a cabochon: round outline of diameter
/// 2r, elliptical dome (profile exponent 2) of height r, no girdle band, a
/// domed back of depth r. The object-space origin is the sphere's centre.
pub(crate) fn sphere_shape(radius_mm: f64) -> CabochonParams {
    CabochonParams {
        outline: Outline::Round,
        length: 2.0 * radius_mm,
        width: 2.0 * radius_mm,
        dome_height: radius_mm,
        profile_exponent: 2.0,
        girdle_height: 0.0,
        base: Base::Domed { height: radius_mm },
        buff_top: None,
    }
}

/// Full vertical field of view of the sphere camera, degrees (the default
/// scene's short telephoto).
const SPHERE_FOV_DEG: f64 = 22.0;
/// Share of the frame's height the sphere's diameter fills.
const SPHERE_FILL: f64 = 0.8;
/// Elevation of the sphere camera above the sphere's centre, degrees: low,
/// so the ground shows as a horizon behind the sphere as in figure 4.11.
const SPHERE_CAMERA_ELEVATION_DEG: f64 = 15.0;
/// Azimuth of the sphere camera (the camera on the −y side, looking along
/// +y): the default scene's key light (azimuth ≈ −106°) is then front-left
/// and its highlight sits up-left of the sphere's centre, not on it.
const SPHERE_CAMERA_AZIMUTH_DEG: f64 = -90.0;

/// The default studio scene (its ground, key light and environment) with
/// one sphere of `radius_mm` resting on the ground, filmed by a camera
/// aimed at the sphere's centre, so the centre of the image is the centre
/// of the sphere.
pub(crate) fn sphere_scene(radius_mm: f64) -> Scene {
    let mut scene = default_scene();
    let ground = scene.ground.as_ref().map_or(0.0, |g| g.height);
    let centre = DVec3::new(0.0, 0.0, ground + radius_mm);
    // The sphere's diameter 2r fills SPHERE_FILL of the frame height
    // 2 · distance · tan(fov / 2).
    let distance = radius_mm / (SPHERE_FILL * (SPHERE_FOV_DEG.to_radians() / 2.0).tan());
    let view = direction_from_degrees(
        90.0 - SPHERE_CAMERA_ELEVATION_DEG,
        SPHERE_CAMERA_AZIMUTH_DEG,
    );
    scene.camera = Camera {
        position: centre + distance * view,
        look_at: centre,
        up: DVec3::Z,
        vertical_fov_deg: SPHERE_FOV_DEG,
    };
    scene.stones = vec![StonePlacement {
        recipe: None,
        shape: sphere_shape(radius_mm),
        position: centre,
        rotation: DQuat::IDENTITY,
        seed: None,
    }];
    scene
}

/// A scene with its ground material and environment compiled once, into
/// which one compiled gem at a time is put (every stone shows it).
struct Studio {
    scene: Scene,
    ground_brdf: Option<LayeredBrdf>,
    environment: Environment,
    max_bounces: u32,
}

impl Studio {
    fn new(
        scene: Scene,
        settings: &GallerySettings,
        cache: &TableCache,
    ) -> Result<Self, FigureError> {
        let ground_brdf = match &scene.ground {
            Some(ground) => Some(compile_material_spec(
                &ground.material,
                settings.draft,
                cache,
            )?),
            None => None,
        };
        let environment = environment_for_spec(&scene.environment).map_err(FigureError::Scene)?;
        Ok(Self {
            scene,
            ground_brdf,
            environment,
            max_bounces: settings.max_bounces,
        })
    }

    /// Renders the scene with `gem` on every stone, `side_px` square.
    fn render(
        &self,
        gem: Gem,
        side_px: u32,
        settings: &GallerySettings,
    ) -> Result<RgbImage, FigureError> {
        self.render_turned(gem, side_px, settings, 0.0)
    }

    /// [`Studio::render`] with every stone turned by `turn_deg` about the
    /// vertical through its own origin (counter-clockwise seen from above):
    /// its pattern and inclusions turn with it, the lights and camera stay.
    fn render_turned(
        &self,
        gem: Gem,
        side_px: u32,
        settings: &GallerySettings,
        turn_deg: f64,
    ) -> Result<RgbImage, FigureError> {
        let turn = DQuat::from_rotation_z(turn_deg.to_radians());
        let mut stones = stone_instances(&self.scene).map_err(FigureError::Scene)?;
        for stone in &mut stones {
            stone.rotation = turn * stone.rotation;
        }
        // As `lapidary render` shades them: by footprint.
        let flake_lobes = FlakeLobes::of_gems(std::slice::from_ref(&gem));
        let render_scene = RenderScene {
            world: World::new(stones, self.scene.ground.as_ref().map(|g| g.height)),
            material_id_bases: RenderScene::material_id_bases(std::slice::from_ref(&gem)),
            gems: vec![gem],
            ground_brdf: self.ground_brdf.clone(),
            lights: self.scene.lights.clone(),
            environment: self.environment.clone(),
            max_bounces: self.max_bounces,
            ambient_occlusion: None,
            connect_through_surfaces: true,
            flake_lobes,
        };
        let camera = camera_for(&self.scene, side_px, side_px);
        Ok(develop(
            &render_scene,
            &camera,
            &film_settings(side_px, settings),
        ))
    }
}

/// A gem recipe whose whole surface is library material `material`
/// (library names need no inline material).
pub(crate) fn library_sphere_gem(material: &str) -> String {
    format!(
        "Gem(name: \"{material}\", description: \"a sphere of {material}\", seed: 1, surface: \"{material}\")"
    )
}

/// A gem recipe whose surface is figure 3.2's material: a smooth clear
/// varnish of IOR 1.5 (the notes' usual varnish, section 4.2) with the
/// yellow absorption [`FIGURE_3_2_ABSORPTION`] and thickness
/// `thickness`, over a white Lambertian base.
pub(crate) fn varnish_sphere_gem(thickness: f64) -> String {
    let [r, g, b] = FIGURE_3_2_ABSORPTION;
    let w = FIGURE_3_2_BASE_WHITE;
    format!(
        "Gem(name: \"yellow-varnish\", description: \"figure 3.2\", seed: 1, \
         materials: {{\"varnish\": Material(\
         layers: [Layer(ior: 1.5, roughness_deg: 2.0, thickness: {thickness:?}, absorption: ({r:?}, {g:?}, {b:?}))], \
         base: Diffuse(colour: ({w:?}, {w:?}, {w:?})))}}, surface: \"varnish\")"
    )
}

/// Compiles `(path, text)` gem recipes in parallel (each layered material
/// tabulates its multiple-scattering compensation, the slow part).
fn compile_all(
    recipes: &[(String, String)],
    draft: bool,
    cache: &TableCache,
) -> Result<Vec<Gem>, FigureError> {
    recipes
        .par_iter()
        .map(|(path, text)| compile_gem_draft_or_final(&GemSource::new(path, text), draft, cache))
        .collect()
}

/// Renders one sphere per gem recipe, `side_px` square each, in order.
fn render_spheres(
    recipes: &[(String, String)],
    side_px: u32,
    settings: &GallerySettings,
    cache: &TableCache,
) -> Result<Vec<RgbImage>, FigureError> {
    settings.check()?;
    let studio = Studio::new(sphere_scene(SPHERE_RADIUS_MM), settings, cache)?;
    compile_all(recipes, settings.draft, cache)?
        .into_iter()
        .map(|gem| studio.render(gem, side_px, settings))
        .collect()
}

/// Figure 4.11: every library material on a sphere, labelled with its name
/// and its section 3.4 class, six to a row.
pub fn figure_4_11(
    settings: &GallerySettings,
    cache: &TableCache,
) -> Result<RgbImage, FigureError> {
    let names: Vec<&str> = builtin_material_names().collect();
    let recipes: Vec<(String, String)> = names
        .iter()
        .map(|name| (format!("builtin:{name}"), library_sphere_gem(name)))
        .collect();
    let spheres = render_spheres(&recipes, settings.small_sphere_px(), settings, cache)?;
    let mut tiles = Vec::with_capacity(names.len());
    for (name, image) in names.iter().zip(spheres) {
        // The class reads only the parameters: no compensation needed.
        let class = classify(&compile_material_spec(name, true, cache)?).to_string();
        tiles.push(Tile {
            image,
            lines: vec![name.to_string(), class],
        });
    }
    Ok(contact_sheet(
        "Figure 4.11: the material library on spheres",
        &tiles,
        6,
    ))
}

/// Figure 3.2: white diffuse spheres under the yellow varnish of
/// `varnish_sphere_gem` at the caption's thicknesses, labelled
/// `d = thickness`, six to a row.
pub fn figure_3_2(settings: &GallerySettings, cache: &TableCache) -> Result<RgbImage, FigureError> {
    let recipes: Vec<(String, String)> = FIGURE_3_2_THICKNESSES
        .iter()
        .map(|d| (format!("figure-3.2:d={d}"), varnish_sphere_gem(*d)))
        .collect();
    let spheres = render_spheres(&recipes, settings.small_sphere_px(), settings, cache)?;
    let tiles: Vec<Tile> = FIGURE_3_2_THICKNESSES
        .iter()
        .zip(spheres)
        .map(|(d, image)| Tile {
            image,
            lines: vec![format!("d = {d}")],
        })
        .collect();
    Ok(contact_sheet(
        "Figure 3.2: a yellow varnish of thickness d on white",
        &tiles,
        6,
    ))
}

/// Figure 4.3: the two materials of `FIGURE_4_3_MATERIALS` on larger
/// spheres, each over its BRDF slice at `FIGURE_4_3_INCIDENCE_DEG`: the
/// frosted metal's single highlight lobe against the patina's sharp lobe
/// on a broad one.
pub fn figure_4_3(settings: &GallerySettings, cache: &TableCache) -> Result<RgbImage, FigureError> {
    let recipes: Vec<(String, String)> = FIGURE_4_3_MATERIALS
        .iter()
        .map(|(name, _)| (format!("builtin:{name}"), library_sphere_gem(name)))
        .collect();
    let side_px = settings.large_sphere_px();
    let spheres = render_spheres(&recipes, side_px, settings, cache)?;
    let mut tiles = Vec::with_capacity(spheres.len());
    for ((name, what), sphere) in FIGURE_4_3_MATERIALS.iter().zip(spheres) {
        let brdf = compile_material_spec(name, settings.draft, cache)?;
        let style = PolarPlotStyle {
            panel_size_px: side_px,
            title: format!("{name}: f·cos θo"),
        };
        let plot = polar_plot(&[in_plane_panel(&brdf, FIGURE_4_3_INCIDENCE_DEG)], &style);
        tiles.push(Tile {
            image: stack_vertically(&sphere, &plot),
            lines: vec![name.to_string(), what.to_string()],
        });
    }
    Ok(contact_sheet(
        "Figure 4.3: the same effective roughness m = 17°",
        &tiles,
        2,
    ))
}

/// The three sunstones of figure 4.5 b, as the course notes show them:
/// "only the specimen on the top right is opaque; the other two are
/// translucent, volumetric objects" - `sunstone` (opaque) beside
/// `pink-sunstone` and `patterned-sunstone` (translucent bodies with copper
/// platelets at depth), each on the studio's cabochon at half the gem size.
pub fn figure_4_5b(
    settings: &GallerySettings,
    cache: &TableCache,
) -> Result<RgbImage, FigureError> {
    let side_px = settings.large_sphere_px();
    let studio = Studio::new(default_scene(), settings, cache)?;
    let tiles = FIGURE_4_5B_GEMS
        .iter()
        .map(|(name, body)| {
            let gem = compile_gem_draft_or_final(&GemSource::load(name)?, settings.draft, cache)?;
            Ok(Tile {
                image: studio.render(gem, side_px, settings)?,
                lines: vec![name.to_string(), body.to_string()],
            })
        })
        .collect::<Result<Vec<_>, FigureError>>()?;
    Ok(contact_sheet(
        "Figure 4.5 b: one opaque sunstone, two translucent",
        &tiles,
        3,
    ))
}

/// A turntable strip: built-in gem `name` turned through
/// `TURNTABLE_FRAMES` azimuths of a full turn under the studio's fixed key
/// light, side by side at a quarter of the gem size. In a translucent
/// stone single platelets at different depths catch the light in one frame
/// and are dark in the next.
pub fn turntable_strip(
    name: &str,
    settings: &GallerySettings,
    cache: &TableCache,
) -> Result<RgbImage, FigureError> {
    let side_px = (settings.size_px / 4).max(MIN_SPHERE_PX);
    let studio = Studio::new(default_scene(), settings, cache)?;
    let gem = compile_gem_draft_or_final(&GemSource::load(name)?, settings.draft, cache)?;
    let tiles = (0..TURNTABLE_FRAMES)
        .map(|frame| {
            let turn_deg = 360.0 * f64::from(frame) / f64::from(TURNTABLE_FRAMES);
            Ok(Tile {
                image: studio.render_turned(gem.clone(), side_px, settings, turn_deg)?,
                lines: vec![format!("{turn_deg:.0}°")],
            })
        })
        .collect::<Result<Vec<_>, FigureError>>()?;
    Ok(contact_sheet(
        &format!("{name} on a turntable: platelets at depth flash on and off"),
        &tiles,
        TURNTABLE_FRAMES,
    ))
}

/// `top` above `bottom`, each centred horizontally, on the sheet
/// background.
fn stack_vertically(top: &RgbImage, bottom: &RgbImage) -> RgbImage {
    let width = top.width().max(bottom.width());
    let mut out = RgbImage::from_pixel(width, top.height() + bottom.height(), SHEET_BACKGROUND);
    imageops::replace(&mut out, top, i64::from((width - top.width()) / 2), 0);
    imageops::replace(
        &mut out,
        bottom,
        i64::from((width - bottom.width()) / 2),
        i64::from(top.height()),
    );
    out
}

/// The gallery's contact sheet: every gem's render scaled to at most
/// `THUMBNAIL_MAX_PX`, with its name and the first sentence of its
/// description, four to a row.
pub fn gem_sheet(gems: &[GemPicture]) -> RgbImage {
    let tiles: Vec<Tile> = gems
        .iter()
        .map(|gem| {
            let side = gem.image.width().min(THUMBNAIL_MAX_PX);
            let image = if side == gem.image.width() {
                gem.image.clone()
            } else {
                let height = (u64::from(gem.image.height()) * u64::from(side)
                    / u64::from(gem.image.width().max(1))) as u32;
                imageops::resize(&gem.image, side, height.max(1), FilterType::Triangle)
            };
            Tile {
                image,
                lines: vec![gem.name.clone(), gem.summary.clone()],
            }
        })
        .collect();
    contact_sheet("lapidary: the built-in gems", &tiles, 4)
}

/// PNG bytes of `image` at the encoder's best compression with adaptive
/// row filters: sheets of many renders stay smaller (the gallery keeps
/// each PNG under about 1 MB) at the cost of encoding time.
pub fn encode_png_compact(image: &RgbImage) -> Result<Vec<u8>, image::ImageError> {
    use image::codecs::png::{CompressionType, FilterType as PngFilter, PngEncoder};
    use image::{ExtendedColorType, ImageEncoder};
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Best, PngFilter::Adaptive)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            ExtendedColorType::Rgb8,
        )?;
    Ok(bytes)
}

/// One picture of a sheet with the words under it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Tile {
    /// The picture.
    pub image: RgbImage,
    /// Its label: the first line in [`NAME_COLOUR`], the others (wrapped to
    /// the tile's width) in [`CAPTION_COLOUR`].
    pub lines: Vec<String>,
}

/// Where everything of a contact sheet goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SheetLayout {
    /// Tiles per row.
    pub columns: u32,
    /// Rows of tiles.
    pub rows: u32,
    /// Width of one tile's cell: the widest framed image, at least
    /// [`MIN_CELL_WIDTH_PX`].
    pub cell_width_px: u32,
    /// Height of the tallest framed image.
    pub image_height_px: u32,
    /// Integer scale of the label text (1 below 384-px cells, else 2, so
    /// a line holds at least 24 characters).
    pub text_scale: u32,
    /// Label lines under every image (the most any tile needs, at most 4).
    pub label_lines: u32,
}

/// Most label lines under a tile; longer captions end in "...".
const MAX_LABEL_LINES: usize = 4;
/// Pixels between two label lines at text scale 1.
const LINE_GAP_PX: u32 = 3;

impl SheetLayout {
    /// Height of the title band above the tiles.
    pub(crate) fn title_height_px(&self) -> u32 {
        GUTTER_PX + text_height(self.text_scale)
    }

    /// Height of one label line with its gap.
    pub(crate) fn line_height_px(&self) -> u32 {
        text_height(self.text_scale) + LINE_GAP_PX * self.text_scale
    }

    /// Height of one row: image, a gap, the label lines.
    pub(crate) fn row_height_px(&self) -> u32 {
        self.image_height_px
            + LINE_GAP_PX * self.text_scale
            + self.label_lines * self.line_height_px()
    }

    /// Width and height of the whole sheet.
    pub fn size_px(&self) -> (u32, u32) {
        (
            GUTTER_PX + self.columns * (self.cell_width_px + GUTTER_PX),
            self.title_height_px() + GUTTER_PX + self.rows * (self.row_height_px() + GUTTER_PX),
        )
    }

    /// Top-left corner of tile `index`'s cell (reading order).
    pub(crate) fn cell_origin_px(&self, index: u32) -> (u32, u32) {
        let (column, row) = (index % self.columns, index / self.columns);
        (
            GUTTER_PX + column * (self.cell_width_px + GUTTER_PX),
            self.title_height_px() + GUTTER_PX + row * (self.row_height_px() + GUTTER_PX),
        )
    }

    /// Characters of label that fit on one line of a cell.
    pub(crate) fn chars_per_line(&self) -> usize {
        (self.cell_width_px / text_width("m", self.text_scale).max(1)) as usize
    }
}

/// Greedy word wrap of `text` into lines of at most `width` characters (a
/// longer word is cut), keeping at most `max_lines`; text left over ends
/// the last line in "...".
fn wrap(text: &str, width: usize, max_lines: usize) -> Vec<String> {
    let width = width.max(4);
    let mut lines: Vec<String> = Vec::new();
    let mut current = String::new();
    for word in text.split_whitespace() {
        let mut word: String = word.to_string();
        loop {
            let used = current.chars().count();
            let len = word.chars().count();
            let needed = if used == 0 { len } else { used + 1 + len };
            if needed <= width {
                if used > 0 {
                    current.push(' ');
                }
                current.push_str(&word);
                break;
            }
            if used > 0 {
                lines.push(std::mem::take(&mut current));
                continue;
            }
            // A word longer than a line: cut it.
            let head: String = word.chars().take(width).collect();
            lines.push(head);
            word = word.chars().skip(width).collect();
            if word.is_empty() {
                break;
            }
        }
    }
    if !current.is_empty() {
        lines.push(current);
    }
    if lines.len() > max_lines {
        lines.truncate(max_lines);
        if let Some(last) = lines.last_mut() {
            let keep = width.saturating_sub(3).min(last.chars().count());
            let head: String = last.chars().take(keep).collect();
            *last = head.trim_end().to_string() + "...";
        }
    }
    lines
}

/// The lines a tile's label takes, each of its lines wrapped to
/// `chars_per_line`, at most [`MAX_LABEL_LINES`] in all; `true` marks the
/// name's lines.
fn label_lines(tile: &Tile, chars_per_line: usize) -> Vec<(String, bool)> {
    let mut out = Vec::new();
    for (i, line) in tile.lines.iter().enumerate() {
        let room = MAX_LABEL_LINES - out.len();
        if room == 0 {
            break;
        }
        for wrapped in wrap(line, chars_per_line, room) {
            out.push((wrapped, i == 0));
        }
    }
    out
}

/// The layout [`contact_sheet`] uses for `tiles` at most `columns` wide.
pub(crate) fn sheet_layout(tiles: &[Tile], columns: u32) -> SheetLayout {
    let count = u32::try_from(tiles.len()).unwrap_or(u32::MAX);
    let columns = columns.clamp(1, count.max(1));
    let image_width = tiles.iter().map(|t| t.image.width() + 2).max().unwrap_or(0);
    let image_height_px = tiles
        .iter()
        .map(|t| t.image.height() + 2)
        .max()
        .unwrap_or(0);
    let cell_width_px = image_width.max(MIN_CELL_WIDTH_PX);
    let text_scale = if cell_width_px >= 384 { 2 } else { 1 };
    let mut layout = SheetLayout {
        columns,
        rows: count.div_ceil(columns),
        cell_width_px,
        image_height_px,
        text_scale,
        label_lines: 0,
    };
    let chars = layout.chars_per_line();
    layout.label_lines = tiles
        .iter()
        .map(|t| label_lines(t, chars).len() as u32)
        .max()
        .unwrap_or(0);
    layout
}

/// Tiles `tiles` in reading order, at most `columns` to a row, under
/// `title`: each image centred in its cell inside a one-pixel
/// [`FRAME_COLOUR`] frame, its label lines centred under it.
pub(crate) fn contact_sheet(title: &str, tiles: &[Tile], columns: u32) -> RgbImage {
    let layout = sheet_layout(tiles, columns);
    let (width, height) = layout.size_px();
    let mut sheet = RgbImage::from_pixel(width, height, SHEET_BACKGROUND);
    let whole = ClipRect::of_image(&sheet);
    let scale = layout.text_scale;
    draw_text_centred(
        &mut sheet,
        whole,
        (i64::from(width / 2), i64::from(GUTTER_PX)),
        title,
        scale,
        NAME_COLOUR,
    );
    let chars = layout.chars_per_line();
    for (index, tile) in tiles.iter().enumerate() {
        let (x0, y0) = layout.cell_origin_px(index as u32);
        let (w, h) = (tile.image.width() + 2, tile.image.height() + 2);
        let fx = x0 + (layout.cell_width_px - w) / 2;
        let fy = y0 + (layout.image_height_px - h) / 2;
        for x in fx..fx + w {
            sheet.put_pixel(x, fy, FRAME_COLOUR);
            sheet.put_pixel(x, fy + h - 1, FRAME_COLOUR);
        }
        for y in fy..fy + h {
            sheet.put_pixel(fx, y, FRAME_COLOUR);
            sheet.put_pixel(fx + w - 1, y, FRAME_COLOUR);
        }
        imageops::replace(
            &mut sheet,
            &tile.image,
            i64::from(fx + 1),
            i64::from(fy + 1),
        );
        let clip = ClipRect {
            left: x0,
            top: y0,
            width: layout.cell_width_px,
            height: layout.row_height_px(),
        };
        let centre_x = i64::from(x0 + layout.cell_width_px / 2);
        let mut y = y0 + layout.image_height_px + LINE_GAP_PX * scale;
        for (line, is_name) in label_lines(tile, chars) {
            let colour = if is_name { NAME_COLOUR } else { CAPTION_COLOUR };
            draw_text_centred(
                &mut sheet,
                clip,
                (centre_x, i64::from(y)),
                &line,
                scale,
                colour,
            );
            y += layout.line_height_px();
        }
    }
    sheet
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_sentence_stops_at_a_full_stop_not_a_section_number() {
        // "4.3.1" has full stops inside a word; the sentence ends at ". ".
        assert_eq!(
            first_sentence("Lepidolite, section 4.3.1.  A mica.\nMore."),
            "Lepidolite, section 4.3.1."
        );
        assert_eq!(first_sentence("no stop at all"), "no stop at all");
    }

    #[test]
    fn wrap_keeps_lines_within_width_and_marks_cut_text() {
        let lines = wrap("aaa bbb ccc ddd eee", 7, 2);
        // "aaa bbb" fits 7 exactly; the rest needs two more lines, so the
        // second line is cut and ends in "...".
        assert_eq!(lines, vec!["aaa bbb".to_string(), "ccc...".to_string()]);
        assert!(lines.iter().all(|l| l.chars().count() <= 7));
        assert_eq!(wrap("abcdefghij", 4, 5), vec!["abcd", "efgh", "ij"]);
    }

    #[test]
    fn sphere_shape_is_a_valid_sphere_of_the_radius() {
        let shape = sphere_shape(2.0);
        assert!(crate::geometry::Cabochon::new(shape).is_ok());
        // Height above and depth below the girdle plane equal the radius,
        // and the girdle's diameter is 2r: the three semi-axes of a sphere.
        assert_eq!(shape.dome_height, 2.0);
        assert_eq!(shape.base, Base::Domed { height: 2.0 });
        assert_eq!((shape.length, shape.width), (4.0, 4.0));
    }

    #[test]
    fn sheet_size_follows_the_tile_count() {
        let tile = |w, h| Tile {
            image: RgbImage::new(w, h),
            lines: vec!["name".to_string()],
        };
        let tiles: Vec<Tile> = (0..5).map(|_| tile(200, 100)).collect();
        let layout = sheet_layout(&tiles, 4);
        // Five tiles four to a row: 4 columns, 2 rows; cells 202 wide (the
        // image and its frame), each column adds a cell and a gutter.
        assert_eq!((layout.columns, layout.rows), (4, 2));
        let image = contact_sheet("t", &tiles, 4);
        assert_eq!(image.width(), GUTTER_PX + 4 * (202 + GUTTER_PX));
        assert_eq!((image.width(), image.height()), layout.size_px());
        // Two tiles only need two columns.
        assert_eq!(sheet_layout(&tiles[..2], 4).columns, 2);
    }

    #[test]
    fn settings_out_of_range_name_the_flag() {
        let bad = GallerySettings {
            size_px: 0,
            ..GallerySettings::default()
        };
        let message = bad.check().unwrap_err().to_string();
        assert!(message.contains("--size 0") && message.contains("1 to 8192"));
    }

    #[test]
    fn varnish_recipe_compiles_with_the_thickness() {
        let text = varnish_sphere_gem(7.5);
        let gem = crate::recipe::gem::parse_gem("figure-3.2", &text).unwrap();
        assert_eq!(gem.materials.len(), 1);
        assert_eq!(gem.materials[0].1.layers[0].thickness, 7.5);
        assert_eq!(
            gem.materials[0].1.layers[0].absorption,
            FIGURE_3_2_ABSORPTION
        );
    }
}
