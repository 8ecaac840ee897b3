//! Gem recipes: the RON schema of a procedural stone (section 4.3.1,
//! figures 4.6 and 4.7) and its compilation into the flat
//! [`crate::texture::pattern::Pattern`] plus the list of layered
//! materials the pattern's indices refer to.
//!
//! ```ron
//! Gem(
//!     name: "example",
//!     seed: 7,
//!     materials: {
//!         "dark-lilac": Material(layers: [Layer(ior: 1.56)], base: Diffuse(colour: (0.35, 0.25, 0.45))),
//!     },
//!     maps: {
//!         "tiles": SurfaceMap(cell_size: 0.05, entries: [
//!             (material: "dark-lilac", weight: 2.0),
//!             (material: "red-garnet"),            // a library material, weight 1
//!         ]),
//!         "veins": Switch(
//!             function: Marble(frequency: 4.0, amplitude: 2.0),
//!             per_cell_of: "tiles",                // whole tiles switch
//!             ranges: [(from: 0.0, to: 0.8, map: "tiles"), (from: 0.8, to: 1.0, material: "silver")],
//!         ),
//!     },
//!     surface: "veins",
//!     glitter: Some(GlitterMap(
//!         cell_size: 0.2, fill_fraction: 0.02,
//!         entries: [(material: "silver")],
//!         facets: FacetBumpMap(cell_size: 0.05, tilt: UniformCone(max_tilt_deg: 20.0)),
//!     )),
//! )
//! ```
//!
//! Names: `materials` (inline) and the built-in library share one namespace
//! (an inline material shadows a library one); `maps` are a second namespace,
//! and an entry says which it means (`material:` or `map:`). `surface` names
//! a map or a material (the opaque sunstone has no surface map).
//!
//! Every number is range-checked while parsing (its own `file:line:col`);
//! the rules that involve several fields (names, cycles, weight sums, switch
//! partitions, facet vs glitter size) are checked after parsing and
//! reported at the map's definition or the offending name.
//!
//! Seeds: every map derives its own seed from the gem seed and its *name*,
//! so adding or renaming another map does not reshuffle this one.

use crate::brdf::{LayeredBrdf, Rgb};
use crate::recipe::compile::{
    compile_material_seen_from, locate_material, parse_material, parse_ron_all, ron_error,
    MaterialSource, COMPENSATION_SEED,
};
use crate::recipe::error::{
    did_you_mean, find_in_code, line_col_of_offset, nth_in_code, RecipeError,
};
use crate::recipe::library::{builtin_material_names, builtin_material_source};
use crate::recipe::material::{BaseSpec, Material};
use crate::recipe::ranges;
use crate::recipe::ron_text::{key_definitions, KeyDefinition};
use crate::recipe::table_cache::Tables;
use crate::render::dielectric::RoughInterface;
use crate::sampling::unit_direction;
use crate::texture::hash::{derive_stream, hash_prefix, seed_key};
use crate::texture::noise_fns::{Fbm, Marble, PerlinNoise, PerlinSource, Turbulence};
use crate::texture::pattern::{
    check_partition, Around, Entry, FacetBumpMap, GlitterMap, Node, Pattern, SurfaceMap, Switch,
    SwitchFunction, SwitchRange, Tilt,
};
use crate::texture::voronoi::Voronoi;
use glam::DVec3;
use serde::{Deserialize, Deserializer};
use std::collections::BTreeMap;
use std::sync::Arc;

fn some_string<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    String::deserialize(d).map(Some)
}
fn one() -> f64 {
    1.0
}
fn ones() -> [f64; 3] {
    [1.0; 3]
}
fn x_axis() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn four() -> u32 {
    4
}
fn two() -> f64 {
    2.0
}
fn half() -> f64 {
    0.5
}

/// A gem's `materials`, each name once ([`ranges::named_once`]).
fn materials_named_once<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<BTreeMap<String, Material>, D::Error> {
    ranges::named_once(d, "material")
}

/// A gem's `maps`, each name once ([`ranges::named_once`]).
fn maps_named_once<'de, D: Deserializer<'de>>(d: D) -> Result<BTreeMap<String, MapSpec>, D::Error> {
    ranges::named_once(d, "map")
}

/// A whole gem recipe as written (figure 4.6: surface side, glitter side).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Gem", deny_unknown_fields)]
pub struct GemSpec {
    /// Display name.
    #[serde(default)]
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Seed of every texture of the stone.
    #[serde(default, deserialize_with = "ranges::seed")]
    pub seed: u64,
    /// Inline materials by name (library names work without this).
    #[serde(default, deserialize_with = "materials_named_once")]
    pub materials: BTreeMap<String, Material>,
    /// Surface maps and switches by name.
    #[serde(default, deserialize_with = "maps_named_once")]
    pub maps: BTreeMap<String, MapSpec>,
    /// The map (or material) at the root of the surface side.
    pub surface: String,
    /// The glitter map over the surface (②, ④), if any.
    #[serde(default)]
    pub glitter: Option<GlitterSpec>,
    /// What is under the surface: `Opaque` (the surface pattern, the
    /// default) or a `Translucent` dielectric body.
    #[serde(default)]
    pub body: BodySpec,
}

/// A stone's body as written.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum BodySpec {
    /// The surface model of the course notes: the pattern's layered BRDFs.
    #[default]
    Opaque,
    /// A dielectric body behind a polished surface, smooth or rough
    /// (`roughness_deg`): light refracts in (Fresnel, total internal
    /// reflection on the way out), is absorbed
    /// along its path by Beer–Lambert (eq. 3.4) and scattered by a
    /// Henyey–Greenstein phase function. The surface pattern is not used.
    Translucent {
        /// Refractive index of the body.
        #[serde(deserialize_with = "ranges::body_ior")]
        ior: f64,
        /// Absorption coefficient per millimetre of path, per channel.
        #[serde(default, deserialize_with = "ranges::body_absorption")]
        absorption: [f64; 3],
        /// Scattering coefficient per millimetre of path, per channel.
        #[serde(default, deserialize_with = "ranges::body_scattering")]
        scattering: [f64; 3],
        /// Henyey–Greenstein g: the mean cosine of the scattering angle.
        #[serde(default, deserialize_with = "ranges::anisotropy")]
        anisotropy: f64,
        /// Polish of the surface: the average micro-facet slope in degrees
        /// (0, the default, is a smooth surface; at most 45°).
        #[serde(default, deserialize_with = "ranges::body_roughness_deg")]
        roughness_deg: f64,
        /// Colour zoning: the absorption varies through the body with a
        /// switch function (None, the default: the same everywhere).
        #[serde(default)]
        zoning: Option<ZoningSpec>,
        /// Populations of flakes (platelets) through the body.
        #[serde(default)]
        inclusions: Vec<InclusionsSpec>,
    },
}

/// Colour zoning of a translucent body, as written: at an object point p
/// the absorption is lerp(body `absorption`, zoning `absorption`,
/// clamp(f(p), 0, 1)), per channel, with f read in texture space as the
/// surface's switch functions are.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Zoning")]
pub struct ZoningSpec {
    /// The function whose clamped value mixes the two absorptions.
    pub function: FunctionSpec,
    /// Absorption per millimetre, per channel, where the function is ≥ 1.
    #[serde(deserialize_with = "ranges::body_absorption")]
    pub absorption: [f64; 3],
}

/// One population of flat crystals inside a translucent body, as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, rename = "Inclusions")]
pub struct InclusionsSpec {
    /// The platelet's outline.
    pub shape: FlakeShape,
    /// Mean size (circumscribed diameter) in mm.
    #[serde(deserialize_with = "ranges::flake_size_mm")]
    pub size_mm: f64,
    /// Each flake's size is the mean times a factor uniform in
    /// [1 − spread, 1 + spread].
    #[serde(default, deserialize_with = "ranges::size_spread")]
    pub size_spread: f64,
    /// Flakes per mm³ (one in each cell of a jittered grid of that density).
    #[serde(deserialize_with = "ranges::density_per_mm3")]
    pub density_per_mm3: f64,
    /// How the flakes' normals are distributed.
    #[serde(default)]
    pub orientation: OrientationSpec,
    /// The flakes' material: inline or built-in, as a map entry's.
    pub material: String,
    /// Seed of the population (with the gem's).
    #[serde(default, deserialize_with = "ranges::seed")]
    pub seed: u64,
    /// Patches: a cell keeps its flake with probability clamp(f, 0, 1), f
    /// this switch function at the flake's centre (None, the default:
    /// every cell keeps its flake).
    #[serde(default)]
    pub density_modulation: Option<FunctionSpec>,
}

/// A platelet's outline, of circumscribed radius r in its own plane.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
pub enum FlakeShape {
    /// A disc of radius r.
    Disc,
    /// A regular hexagon (hexagonal copper or mica platelets).
    Hexagon,
    /// An equilateral triangle (copper crystals in goldstone).
    Triangle,
    /// A 2:1 rectangle (hematite laths).
    Rectangle,
}

/// How inclusion normals are oriented, as written.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum OrientationSpec {
    /// Uniform over the sphere.
    #[default]
    Isotropic,
    /// Within a cone about a direction of the stone (a cleavage plane's
    /// normal): uniform in solid angle up to `spread_deg` from it.
    Aligned {
        /// The axis in the stone's object space (not all zero).
        #[serde(deserialize_with = "ranges::direction")]
        direction: [f64; 3],
        /// Half-angle of the cone, degrees.
        #[serde(default, deserialize_with = "ranges::spread_deg")]
        spread_deg: f64,
    },
}

/// A compiled stone body (see [`BodySpec`]).
#[derive(Clone, Debug, PartialEq)]
pub enum Body {
    /// Shaded by the pattern's layered BRDFs at the surface.
    Opaque,
    /// A dielectric interface, smooth or rough, over an absorbing,
    /// scattering volume with flakes in it.
    Translucent {
        /// Refractive index of the body relative to the air around it.
        ior: f64,
        /// Average micro-facet slope of the surface in degrees; 0 is a
        /// smooth (delta) interface.
        roughness_deg: f64,
        /// The surface's micro-facets with their compensation tables when
        /// it is rough (`roughness_deg` > 0 and `ior` > 1), else None.
        rough_surface: Option<RoughInterface>,
        /// What happens along a path inside; with zoning, its absorption is
        /// the least the zoning reaches, per channel.
        medium: Medium,
        /// The absorption above the medium's, where it varies (boxed: a
        /// switch function is large, and most bodies have none).
        zoning: Option<Box<Zoning>>,
        /// The flake populations.
        inclusions: Vec<Inclusions>,
    },
}

/// A compiled flake population (see [`InclusionsSpec`] and
/// `crate::render::inclusions` for the flakes it stands for).
#[derive(Clone, Debug, PartialEq)]
pub struct Inclusions {
    /// The outline.
    pub shape: FlakeShape,
    /// Mean circumscribed radius, mm.
    pub radius_mm: f64,
    /// Relative spread of the radius.
    pub size_spread: f64,
    /// Side of the grid cell that holds one flake, mm: density^(−1/3).
    pub cell_mm: f64,
    /// Normals: None isotropic, else (unit axis, cos of the cone's half-angle).
    pub aligned: Option<(glam::DVec3, f64)>,
    /// Index of the flakes' material in [`Gem::brdfs`].
    pub material: u32,
    /// The population's own seed (the gem's and its own, mixed).
    pub seed: u64,
    /// Keep a cell's flake with probability clamp(f, 0, 1), f read at the
    /// flake's centre in texture space; None keeps every flake.
    pub density_modulation: Option<SwitchFunction>,
}

/// A compiled colour zoning (see [`ZoningSpec`]): the residual absorption
/// σr(p) = σa(p) − σa,min ≥ 0 per channel over the body's medium, whose
/// absorption is σa,min, the least of the two ends per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Zoning {
    /// The function read at object point × texture units per mm.
    pub function: SwitchFunction,
    /// σr per mm where clamp(f, 0, 1) = 0.
    pub residual_low_per_mm: Rgb,
    /// σr per mm where clamp(f, 0, 1) = 1.
    pub residual_high_per_mm: Rgb,
    /// σ̄: a bound on every channel's σr, the rate of ratio tracking's
    /// tentative collisions (0 when nothing varies).
    pub majorant_per_mm: f64,
}

impl Zoning {
    /// The zoning of the absorptions `low` (where clamp(f, 0, 1) = 0) and
    /// `high` (where it is 1), and the medium's per-channel minimum.
    pub fn new(function: SwitchFunction, low: Rgb, high: Rgb) -> (Self, Rgb) {
        let minimum = low.min(high);
        let (residual_low, residual_high) = (low - minimum, high - minimum);
        let zoning = Self {
            function,
            residual_low_per_mm: residual_low,
            residual_high_per_mm: residual_high,
            majorant_per_mm: residual_low.max(residual_high).max_element(),
        };
        (zoning, minimum)
    }

    /// σr per mm at the texture-space point `p`: the linear mix of the two
    /// residuals by clamp(f(p), 0, 1), each channel within [0, σ̄].
    pub fn residual_per_mm(&self, p: DVec3) -> Rgb {
        let mix = self.function.value(p).clamp(0.0, 1.0);
        self.residual_low_per_mm + (self.residual_high_per_mm - self.residual_low_per_mm) * mix
    }
}

/// A homogeneous participating medium, coefficients per millimetre (scene
/// unit) per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Medium {
    /// σa: absorption per mm.
    pub absorption_per_mm: Rgb,
    /// σs: scattering per mm.
    pub scattering_per_mm: Rgb,
    /// Henyey–Greenstein g, in [−0.99, 0.99].
    pub anisotropy: f64,
}

/// A named node: a Voronoi surface map or a function switch.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum MapSpec {
    /// Figure 4.6 ①: each cell picks one entry by weight.
    SurfaceMap {
        /// Cell size (object units), > 0.
        #[serde(deserialize_with = "ranges::cell_size")]
        cell_size: f64,
        /// Feature-point jitter, 0 (grid) to 1 (default).
        #[serde(default = "one", deserialize_with = "ranges::jitter")]
        jitter: f64,
        /// Anisotropic cell stretch per axis (default 1, 1, 1).
        #[serde(default = "ones", deserialize_with = "ranges::stretch")]
        stretch: [f64; 3],
        /// What cells hold.
        entries: Vec<EntrySpec>,
    },
    /// Figure 4.7 (b): a function's value range picks the entry.
    Switch {
        /// The function read.
        function: FunctionSpec,
        /// Ranges partitioning the function's values.
        ranges: Vec<RangeSpec>,
        /// Read the function once per cell of this size (whole cells switch).
        #[serde(default, deserialize_with = "ranges::per_cell_size")]
        per_cell_size: Option<f64>,
        /// Read the function once per cell of this surface map's cells.
        #[serde(default, deserialize_with = "some_string")]
        per_cell_of: Option<String>,
    },
}

/// One weighted entry: exactly one of `material` or `map`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Entry", deny_unknown_fields)]
pub struct EntrySpec {
    /// A material name (inline or library).
    #[serde(default, deserialize_with = "some_string")]
    pub material: Option<String>,
    /// A map name.
    #[serde(default, deserialize_with = "some_string")]
    pub map: Option<String>,
    /// Relative weight, ≥ 0 (default 1).
    #[serde(default = "one", deserialize_with = "ranges::weight")]
    pub weight: f64,
}

/// One switch range `[from, to)`: exactly one of `material` or `map`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Range", deny_unknown_fields)]
pub struct RangeSpec {
    /// Lower end.
    #[serde(deserialize_with = "ranges::range_end")]
    pub from: f64,
    /// Upper end.
    #[serde(deserialize_with = "ranges::range_end")]
    pub to: f64,
    /// A material name.
    #[serde(default, deserialize_with = "some_string")]
    pub material: Option<String>,
    /// A map name.
    #[serde(default, deserialize_with = "some_string")]
    pub map: Option<String>,
}

/// A switch function (section 4.3.1: marble, Perlin functions).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum FunctionSpec {
    /// Perlin noise in `[-1, 1]`.
    Perlin {
        /// Lattice cells per object unit.
        #[serde(deserialize_with = "ranges::frequency")]
        frequency: f64,
    },
    /// fBm in `[-B, B]`, `B = Σ gainᵏ`.
    Fbm {
        /// First-octave frequency.
        #[serde(deserialize_with = "ranges::frequency")]
        frequency: f64,
        /// Octaves, 1–16 (default 4).
        #[serde(default = "four", deserialize_with = "ranges::octaves")]
        octaves: u32,
        /// Frequency ratio (default 2).
        #[serde(default = "two", deserialize_with = "ranges::lacunarity")]
        lacunarity: f64,
        /// Amplitude ratio (default 0.5).
        #[serde(default = "half", deserialize_with = "ranges::gain")]
        gain: f64,
    },
    /// Turbulence in `[0, B]`.
    Turbulence {
        /// First-octave frequency.
        #[serde(deserialize_with = "ranges::frequency")]
        frequency: f64,
        /// Octaves, 1–16 (default 4).
        #[serde(default = "four", deserialize_with = "ranges::octaves")]
        octaves: u32,
        /// Frequency ratio (default 2).
        #[serde(default = "two", deserialize_with = "ranges::lacunarity")]
        lacunarity: f64,
        /// Amplitude ratio (default 0.5).
        #[serde(default = "half", deserialize_with = "ranges::gain")]
        gain: f64,
    },
    /// Marble `0.5 + 0.5 sin(frequency · p·direction + amplitude · turbulence)`, in `[0, 1]`.
    Marble {
        /// Stripe phase rate (radians per unit along `direction`).
        #[serde(deserialize_with = "ranges::frequency")]
        frequency: f64,
        /// Turbulence strength (radians).
        #[serde(deserialize_with = "ranges::amplitude")]
        amplitude: f64,
        /// Stripe axis (default x).
        #[serde(default = "x_axis", deserialize_with = "ranges::direction")]
        direction: [f64; 3],
        /// Turbulence octaves, 1–16 (default 4).
        #[serde(default = "four", deserialize_with = "ranges::octaves")]
        octaves: u32,
        /// Turbulence first-octave frequency (default 1).
        #[serde(default = "one", deserialize_with = "ranges::frequency")]
        turbulence_frequency: f64,
    },
}

/// The glitter map ② with its facet bump map ④.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "GlitterMap", deny_unknown_fields)]
pub struct GlitterSpec {
    /// Particle cell size, > 0.
    #[serde(deserialize_with = "ranges::cell_size")]
    pub cell_size: f64,
    /// Feature-point jitter (default 1).
    #[serde(default = "one", deserialize_with = "ranges::jitter")]
    pub jitter: f64,
    /// Fraction of filled cells, 0–1.
    #[serde(deserialize_with = "ranges::fill_fraction")]
    pub fill_fraction: f64,
    /// Optional modulation of the fill by a function (patterned sunstone).
    #[serde(default)]
    pub fill_modulation: Option<FunctionSpec>,
    /// Glitter materials (`material:` entries only).
    pub entries: Vec<EntrySpec>,
    /// The facets of filled cells.
    pub facets: FacetSpec,
}

/// The crystal-facet bump map ④.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "FacetBumpMap", deny_unknown_fields)]
pub struct FacetSpec {
    /// Facet cell size, > 0 and ≤ the glitter cell size.
    #[serde(deserialize_with = "ranges::cell_size")]
    pub cell_size: f64,
    /// Feature-point jitter (default 1).
    #[serde(default = "one", deserialize_with = "ranges::jitter")]
    pub jitter: f64,
    /// Tilt distribution.
    pub tilt: TiltSpec,
    /// Tilt axis (default the surface normal).
    #[serde(default)]
    pub around: AroundSpec,
}

/// Tilt distribution of the facets.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum TiltSpec {
    /// Uniform in the cone of half-angle `max_tilt_deg`.
    UniformCone {
        /// Half-angle, 0–90°.
        #[serde(deserialize_with = "ranges::max_tilt_deg")]
        max_tilt_deg: f64,
    },
    /// `|N(0, σ)|`.
    Gaussian {
        /// σ, (0, 90]°.
        #[serde(deserialize_with = "ranges::sigma_tilt_deg")]
        sigma_tilt_deg: f64,
    },
}

/// Tilt axis of the facets.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
pub enum AroundSpec {
    /// The stone's normal at the hit.
    #[default]
    SurfaceNormal,
    /// A fixed object-space direction `Direction(x, y, z)`.
    Direction(f64, f64, f64),
}

/// A gem ready to render: its pattern and one compiled BRDF per material
/// the pattern's indices refer to. Made only by [`compile_gems`] (and its
/// one-gem form [`compile_gem`]).
#[derive(Clone, Debug)]
pub struct Gem {
    /// Display name.
    pub name: String,
    /// Free text.
    pub description: String,
    /// The recipe seed (or the seed that replaced it).
    pub seed: u64,
    /// The flat pattern tree (figure 4.6) in texture space.
    pub pattern: Pattern,
    /// `(name, material)` per material index, as written.
    pub materials: Vec<(String, Material)>,
    /// Index of refraction of the medium each material is seen from, per
    /// material index: 1 (air) for the surface's, the body's for its
    /// inclusions'. A material used in both places has an index for each.
    pub seen_from_ior: Vec<f64>,
    /// The compiled BRDF per material index. Shared by the gems of one
    /// recipe with different seeds (a seed changes the pattern, never a
    /// material): a tray of 1000 lepidolites holds 19 BRDFs, not 19 000.
    pub brdfs: Arc<[LayeredBrdf]>,
    /// Map name per node index.
    pub map_names: Vec<String>,
    /// What is under the surface.
    pub body: Body,
    /// The parsed recipe.
    pub spec: GemSpec,
}

impl Gem {
    /// Node index of the map called `name`.
    pub fn map_index(&self, name: &str) -> Option<u32> {
        self.map_names
            .iter()
            .position(|n| n == name)
            .map(|i| i as u32)
    }

    /// Material index of the material called `name`.
    pub fn material_index(&self, name: &str) -> Option<u32> {
        self.materials
            .iter()
            .position(|(n, _)| n == name)
            .map(|i| i as u32)
    }
}

/// A gem recipe's text and where it came from (a path, or `builtin:NAME`),
/// for error messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GemSource {
    /// The display path.
    pub path: String,
    /// The RON text.
    pub text: String,
}

impl GemSource {
    /// Recipe `text` read from `path`.
    pub fn new(path: &str, text: &str) -> Self {
        Self {
            path: path.to_string(),
            text: text.to_string(),
        }
    }

    /// Finds RECIPE as a file (if it names one: ends in `.ron` or has a
    /// `/`) or as a built-in gem.
    pub fn load(recipe: &str) -> Result<Self, RecipeError> {
        let (path, text) = load_gem_source(recipe)?;
        Ok(Self { path, text })
    }
}

/// Compiles one gem recipe with its seed replaced by `seed` when given:
/// [`compile_gems`] of one request.
pub fn compile_gem(
    source: &GemSource,
    seed: Option<u64>,
    tables: Tables<'_>,
) -> Result<Gem, RecipeError> {
    let mut gems = compile_gems(&[(source, seed)], tables, &mut [])?;
    Ok(gems.remove(0))
}

/// The one way from recipe text to a [`Gem`]: each request's text is
/// parsed into its [`GemSpec`], validated and compiled (pattern and
/// materials) with its seed replaced when given. The requests of one
/// recipe (the same source) parse it and compile its materials once and
/// share the BRDFs; every request gets its own pattern. With
/// [`Tables::Computed`], the compensation tables of all the gems' materials
/// and of `more_materials` (e.g. a scene's ground, compiled by
/// [`crate::recipe::compile::load_material_without_table`]) are computed
/// together, node by node in one parallel loop.
pub fn compile_gems(
    requests: &[(&GemSource, Option<u64>)],
    tables: Tables<'_>,
    more_materials: &mut [&mut LayeredBrdf],
) -> Result<Vec<Gem>, RecipeError> {
    // Per distinct source: its spec and compiled materials, with whether
    // each wants a table.
    let mut recipes: Vec<(&GemSource, GemSpec, Vec<LayeredBrdf>, Vec<bool>)> = Vec::new();
    let mut recipe_of = Vec::with_capacity(requests.len());
    let mut compiled = Vec::with_capacity(requests.len());
    // Every distinct recipe is compiled; the errors of all that fail are
    // reported together (each once: a recipe that failed is not tried again).
    let mut errors = Vec::new();
    let mut failed: Vec<&GemSource> = Vec::new();
    for &(source, seed) in requests {
        if failed.contains(&source) {
            continue;
        }
        let mut compile_one = || -> Result<(), RecipeError> {
            let index = match recipes.iter().position(|r| r.0 == source) {
                Some(index) => index,
                None => {
                    let spec = parse_gem_spec(&source.path, &source.text)?;
                    recipes.push((source, spec, Vec::new(), Vec::new()));
                    recipes.len() - 1
                }
            };
            let (_, spec, brdfs, wants_table) = &mut recipes[index];
            let gem = compile_gem_spec(&source.path, &source.text, spec.clone(), seed)?;
            if brdfs.is_empty() {
                // Where each inline material is defined, found in one pass.
                let definitions = key_definitions(&source.text);
                for ((name, material), &ior_outside) in gem.materials.iter().zip(&gem.seen_from_ior)
                {
                    let inline = gem
                        .spec
                        .materials
                        .contains_key(name)
                        .then(|| definitions.get(name.as_str()).copied());
                    brdfs.push(compile_gem_material(
                        &source.path,
                        &source.text,
                        (name, material),
                        inline,
                        ior_outside,
                    )?);
                    wants_table.push(material.multiple_scattering);
                }
            }
            recipe_of.push(index);
            compiled.push(gem);
            Ok(())
        };
        if let Err(e) = compile_one() {
            errors.push(e);
            failed.push(source);
        }
    }
    if let Some(error) = RecipeError::all(errors) {
        return Err(error);
    }
    if let Tables::Computed(cache) = tables {
        let mut wanting: Vec<&mut LayeredBrdf> = recipes
            .iter_mut()
            .flat_map(|(_, _, brdfs, wants)| {
                brdfs
                    .iter_mut()
                    .zip(wants.iter())
                    .filter_map(|(brdf, wants)| wants.then_some(brdf))
            })
            .chain(more_materials.iter_mut().map(|brdf| &mut **brdf))
            .collect();
        let requests: Vec<(&LayeredBrdf, u64)> = wanting
            .iter()
            .map(|brdf| (&**brdf, COMPENSATION_SEED))
            .collect();
        let computed = cache.compensations(&requests);
        for (brdf, table) in wanting.iter_mut().zip(computed) {
            brdf.compensation = table;
        }
    }
    let shared: Vec<Arc<[LayeredBrdf]>> = recipes
        .into_iter()
        .map(|(_, _, brdfs, _)| Arc::from(brdfs))
        .collect();
    Ok(compiled
        .into_iter()
        .zip(recipe_of)
        .map(|(gem, index)| Gem {
            brdfs: Arc::clone(&shared[index]),
            ..gem
        })
        .collect())
}

/// Whether a material has a metal base (a glitter or silver-tile entry).
pub fn has_conductor_base(m: &Material) -> bool {
    matches!(m.base, BaseSpec::Conductor { .. })
}

/// Read and compile a gem recipe file, without compensation tables
/// ([`compile_gem`] with [`Tables::Skipped`]: for checks and patterns; its
/// rough layered materials are darker than a render's).
pub fn load_gem(path: &str) -> Result<Gem, RecipeError> {
    let text = crate::recipe::compile::read_ron_file(path, "gem recipe")?;
    parse_gem(path, &text)
}

/// Parse, validate and compile gem recipe `text` (`path` is for messages),
/// without compensation tables ([`compile_gem`] with [`Tables::Skipped`]:
/// for checks and patterns; its rough layered materials are darker than a
/// render's).
pub fn parse_gem(path: &str, text: &str) -> Result<Gem, RecipeError> {
    compile_gem(&GemSource::new(path, text), None, Tables::Skipped)
}

/// Compiles material `name` of a gem without its compensation table. An
/// inline material (`inline`: Some, with where its `"name":` is defined,
/// when found) is compiled against its own definition's text, so that its
/// errors point into its own `Layer(`s; the position is then shifted back
/// to the whole file. A library material is compiled from its own text.
fn compile_gem_material(
    path: &str,
    text: &str,
    (name, material): (&str, &Material),
    inline: Option<Option<KeyDefinition>>,
    ior_outside: f64,
) -> Result<LayeredBrdf, RecipeError> {
    let Some(definition) = inline else {
        return compile_material_seen_from(&locate_material(name)?, material, ior_outside);
    };
    let (base, own_text) = match definition {
        Some(KeyDefinition {
            offset,
            line_col,
            value_end,
        }) => (line_col, &text[offset..value_end]),
        None => ((1, 1), text),
    };
    let source = MaterialSource {
        path: path.to_string(),
        name: name.to_string(),
        text: own_text.to_string(),
    };
    compile_material_seen_from(&source, material, ior_outside).map_err(|mut e| {
        if let Some((line, col)) = e.position {
            e.position = Some(if line == 1 {
                (base.0, base.1 + col - 1)
            } else {
                (base.0 + line - 1, col)
            });
        }
        e
    })
}

/// Gem recipe `text` (from `path`) read into its spec, not yet compiled.
fn parse_gem_spec(path: &str, text: &str) -> Result<GemSpec, RecipeError> {
    parse_ron_all::<GemSpec>(text, |e| match &e.code {
        ron::error::Error::NoSuchStructField { found, outer, .. }
            if found == "host_ior" && outer.as_deref() == Some("Gem") =>
        {
            let (line, col) = (e.span.start.line, e.span.start.col);
            RecipeError::at(path, line, col, HOST_IOR_RETIRED)
        }
        _ => ron_error(path, text, e),
    })
}

/// The message for a recipe that still sets `host_ior`, a field that was
/// parsed and never used: the index of a stone that refracts is its body's.
const HOST_IOR_RETIRED: &str = "`host_ior` is retired (it was never used): a translucent \
     stone's index of refraction is written `body: Translucent(ior: …)`; an opaque stone's \
     layers carry their own `ior`. Delete the `host_ior` line";

/// Compiles `spec`'s pattern and material list (BRDFs empty), read by
/// [`parse_gem_spec`] from `text` at `path` (both for error messages), with
/// its seed replaced by `seed` when given.
fn compile_gem_spec(
    path: &str,
    text: &str,
    mut spec: GemSpec,
    seed: Option<u64>,
) -> Result<Gem, RecipeError> {
    if let Some(seed) = seed {
        spec.seed = seed;
    }
    Compiler::new(path, text, &spec).compile(spec.clone())
}

/// Seed of a named texture: the gem seed and the name's bytes through the
/// cell-hash chain, then stream `purpose`.
fn named_seed(seed: u64, name: &str, purpose: u64) -> u64 {
    let h = name
        .bytes()
        .fold(seed_key(seed), |h, b| hash_prefix(h, b as i32));
    derive_stream(h, purpose)
}

/// The most maps on a way from a map down to a material: far more than a
/// recipe nests, few enough that evaluating the pattern (by recursion)
/// stays within a render thread's stack.
const MAX_MAP_DEPTH: usize = 64;

const PURPOSE_CELLS: u64 = 0;
const PURPOSE_NOISE: u64 = 1;
const PURPOSE_PER_CELL: u64 = 2;
const GLITTER_NAME: &str = "#glitter";
const FACETS_NAME: &str = "#facets";
const ZONING_NAME: &str = "#zoning";

/// A marble switch function written along the zero vector.
struct ZeroDirection;

/// What is wrong with a marble function along a zero direction, `of_what`
/// naming its owner.
fn zero_marble_direction(of_what: &str) -> String {
    format!("marble `direction` of {of_what} is (0, 0, 0); allowed: any non-zero vector")
}

struct Compiler<'a> {
    path: &'a str,
    text: &'a str,
    spec: &'a GemSpec,
    map_names: Vec<String>,
    materials: Vec<(String, Material)>,
    /// Per material index, the index of the medium it is seen from (None:
    /// an inline material not used yet).
    seen_from_ior: Vec<Option<f64>>,
    /// Unknown names and maps that did not compile so far, each reported
    /// at the end with the rest (a recipe's mistakes are listed at once,
    /// not one a run).
    deferred: Vec<RecipeError>,
}

impl<'a> Compiler<'a> {
    fn new(path: &'a str, text: &'a str, spec: &'a GemSpec) -> Self {
        Compiler {
            path,
            text,
            spec,
            map_names: spec.maps.keys().cloned().collect(),
            materials: Vec::new(),
            seen_from_ior: Vec::new(),
            deferred: Vec::new(),
        }
    }

    /// The index `found`, or where it names nothing, 0 in its place and its
    /// error kept for the end ([`Compiler::compile`] reports them together).
    fn or_deferred(&mut self, found: Result<u32, RecipeError>) -> u32 {
        found.unwrap_or_else(|e| {
            self.deferred.push(e);
            0
        })
    }

    fn error_at(&self, needle: &str, message: String) -> RecipeError {
        RecipeError::at_text(self.path, self.text, needle, message)
    }

    /// Error at `field` of the body's inclusion population `index`
    /// (0-based, the `index`-th `Inclusions(` written), or at that entry
    /// when the field is left to its default; as [`Compiler::error_at`]
    /// where the entries are written without their name.
    fn error_at_inclusion(&self, index: usize, field: &str, message: String) -> RecipeError {
        const ENTRY: &str = "Inclusions(";
        let Some(start) = nth_in_code(self.text, ENTRY, index) else {
            return self.error_at(field, message);
        };
        let end = nth_in_code(self.text, ENTRY, index + 1).unwrap_or(self.text.len());
        let offset = find_in_code(&self.text[start..end], field).map_or(start, |at| start + at);
        let (line, col) = line_col_of_offset(self.text, offset);
        RecipeError::at(self.path, line, col, message)
    }

    /// Error at the definition `"name":` of a map (else its first mention).
    fn error_at_map(&self, name: &str, message: String) -> RecipeError {
        let quoted = format!("\"{name}\"");
        let definition = self
            .text
            .match_indices(&quoted)
            .find(|(i, _)| self.text[i + quoted.len()..].trim_start().starts_with(':'));
        match definition {
            Some((offset, _)) => {
                let (l, c) = crate::recipe::error::line_col_of_offset(self.text, offset);
                RecipeError::at(self.path, l, c, message)
            }
            None => self.error_at(&quoted, message),
        }
    }

    /// An error about `name` where it is written as `role: "name"` (an
    /// entry's `material:` or `map:`, outside comments), so that a name
    /// used in the wrong role is found at that use and not at an earlier,
    /// right one; else as [`Compiler::error_at`] finds the quoted name.
    fn error_at_use(&self, role: &str, name: &str, message: String) -> RecipeError {
        let quoted = format!("\"{name}\"");
        let mut from = 0;
        while let Some(found) = self.text[from..].find(role).map(|i| i + from) {
            from = found + role.len();
            let line_start = self.text[..found].rfind('\n').map_or(0, |i| i + 1);
            let in_comment = self.text[line_start..found].contains("//");
            let word_start = found == 0
                || !self.text[..found]
                    .chars()
                    .next_back()
                    .is_some_and(|c| c.is_alphanumeric() || c == '_');
            let rest = self.text[from..].trim_start();
            let Some(value) = rest.strip_prefix(':').map(str::trim_start) else {
                continue;
            };
            if !in_comment && word_start && value.starts_with(&quoted) {
                let offset = self.text.len() - value.len();
                let (line, col) = line_col_of_offset(self.text, offset);
                return RecipeError::at(self.path, line, col, message);
            }
        }
        self.error_at(&quoted, message)
    }

    /// The index of material `name` seen from air.
    fn material_index(&mut self, name: &str) -> Result<u32, RecipeError> {
        self.material_index_seen_from(name, 1.0)
    }

    /// The index of material `name` seen from a medium of index
    /// `ior_outside`: its first use from that medium adds it.
    fn material_index_seen_from(
        &mut self,
        name: &str,
        ior_outside: f64,
    ) -> Result<u32, RecipeError> {
        let mut known = None;
        for (i, (n, m)) in self.materials.iter().enumerate() {
            if n == name {
                match self.seen_from_ior[i] {
                    Some(ior) if ior != ior_outside => known = Some(m.clone()),
                    _ => {
                        self.seen_from_ior[i] = Some(ior_outside);
                        return Ok(i as u32);
                    }
                }
            }
        }
        let material = if let Some(m) = known {
            m
        } else if let Some(m) = self.spec.materials.get(name) {
            m.clone()
        } else if let Some(source) = builtin_material_source(name) {
            parse_material(&format!("builtin:{name}"), source)?
        } else {
            let spec: &'a GemSpec = self.spec;
            let inline: Vec<&'a str> = spec.materials.keys().map(String::as_str).collect();
            let mut candidates: Vec<String> = inline.iter().map(|s| s.to_string()).collect();
            candidates.extend(builtin_material_names().map(String::from));
            let hint = did_you_mean(name, candidates.iter().map(String::as_str))
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            let also_map = if self.spec.maps.contains_key(name) {
                format!(" (`{name}` is a map: write `map: \"{name}\"`)")
            } else {
                String::new()
            };
            return Err(self.error_at_use(
                "material",
                name,
                format!(
                    "unknown material `{name}`{hint}{also_map}; allowed: a name from `materials` ({}) or a library material ({})",
                    if inline.is_empty() { "none".to_string() } else { inline.join(", ") },
                    builtin_material_names().collect::<Vec<_>>().join(", ")
                ),
            ));
        };
        self.materials.push((name.to_string(), material));
        self.seen_from_ior.push(Some(ior_outside));
        Ok(self.materials.len() as u32 - 1)
    }

    fn map_index(&self, name: &str) -> Result<u32, RecipeError> {
        match self.map_names.iter().position(|n| n == name) {
            Some(i) => Ok(i as u32),
            None => {
                let hint = did_you_mean(name, self.map_names.iter().map(String::as_str))
                    .map(|s| format!(" (did you mean `{s}`?)"))
                    .unwrap_or_default();
                let also_material = if self.spec.materials.contains_key(name)
                    || builtin_material_source(name).is_some()
                {
                    format!(" (`{name}` is a material: write `material: \"{name}\"`)")
                } else {
                    String::new()
                };
                Err(self.error_at_use(
                    "map",
                    name,
                    format!(
                        "unknown map `{name}`{hint}{also_material}; allowed: a name from `maps` ({})",
                        if self.map_names.is_empty() {
                            "none".to_string()
                        } else {
                            self.map_names.join(", ")
                        }
                    ),
                ))
            }
        }
    }

    /// Resolve `material:` / `map:` (exactly one) of an entry of map `owner`.
    fn entry(
        &mut self,
        owner: &str,
        material: &Option<String>,
        map: &Option<String>,
    ) -> Result<Entry, RecipeError> {
        match (material, map) {
            (Some(m), None) => {
                let found = self.material_index(m);
                Ok(Entry::Material(self.or_deferred(found)))
            }
            (None, Some(m)) => {
                let found = self.map_index(m);
                Ok(Entry::Node(self.or_deferred(found)))
            }
            _ => Err(self.error_at_map(
                owner,
                format!("an entry of `{owner}` needs exactly one of `material` or `map`"),
            )),
        }
    }

    /// Names of the maps `spec` refers to.
    fn children(spec: &MapSpec) -> Vec<&str> {
        match spec {
            MapSpec::SurfaceMap { entries, .. } => {
                entries.iter().filter_map(|e| e.map.as_deref()).collect()
            }
            MapSpec::Switch {
                ranges,
                per_cell_of: _,
                ..
            } => ranges.iter().filter_map(|r| r.map.as_deref()).collect(),
        }
    }

    /// Cycle detection over the name graph, with the cycle in the message,
    /// and the nesting's depth: at most [`MAX_MAP_DEPTH`] maps on the way
    /// from any map to a material (the pattern is evaluated by recursion).
    fn check_cycles(&self) -> Result<(), RecipeError> {
        /// A nesting that is refused: a cycle, or a chain too deep.
        enum Refused<'s> {
            Cycle(Vec<&'s str>),
            TooDeep(Vec<&'s str>),
        }
        /// The most maps on a way down from `name` to a material (0 for a
        /// name that is no map), every map on `path` above it.
        fn height<'s>(
            name: &'s str,
            maps: &'s BTreeMap<String, MapSpec>,
            path: &mut Vec<&'s str>,
            heights: &mut BTreeMap<&'s str, usize>,
        ) -> Result<usize, Refused<'s>> {
            if let Some(k) = path.iter().position(|n| *n == name) {
                let mut cycle = path[k..].to_vec();
                cycle.push(name);
                return Err(Refused::Cycle(cycle));
            }
            let Some(spec) = maps.get(name) else {
                return Ok(0); // a material; unknown names are reported later
            };
            let known = heights.get(name).copied();
            if path.len() + known.unwrap_or(1) > MAX_MAP_DEPTH {
                let mut chain = path.clone();
                chain.push(name);
                return Err(Refused::TooDeep(chain));
            }
            if let Some(known) = known {
                return Ok(known);
            }
            path.push(name);
            let mut below = 0;
            for child in Compiler::children(spec) {
                below = below.max(height(child, maps, path, heights)?);
            }
            path.pop();
            heights.insert(name, below + 1);
            Ok(below + 1)
        }
        let mut heights = BTreeMap::new();
        for name in self.spec.maps.keys() {
            match height(name, &self.spec.maps, &mut Vec::new(), &mut heights) {
                Ok(_) => {}
                Err(Refused::Cycle(cycle)) => {
                    let first = cycle[0];
                    let how = if cycle.len() == 2 {
                        "directly".to_string()
                    } else {
                        format!("through {}", cycle[1..cycle.len() - 1].join(" → "))
                    };
                    return Err(self.error_at_map(
                        first,
                        format!(
                            "map `{first}` contains itself {how} ({}); allowed: maps that nest without cycles",
                            cycle.join(" → ")
                        ),
                    ));
                }
                Err(Refused::TooDeep(chain)) => {
                    let first = chain[0];
                    let shown = if chain.len() > 4 {
                        format!(
                            "{} → {} → … → {}",
                            chain[0],
                            chain[1],
                            chain[chain.len() - 1]
                        )
                    } else {
                        chain.join(" → ")
                    };
                    return Err(self.error_at_map(
                        first,
                        format!(
                            "map `{first}` nests more than {MAX_MAP_DEPTH} maps deep ({shown} → …); allowed: at most {MAX_MAP_DEPTH} maps from a map down to its materials"
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    fn voronoi(&self, name: &str, cell_size: f64, jitter: f64, stretch: [f64; 3]) -> Voronoi {
        Voronoi {
            cell_size,
            jitter,
            stretch: DVec3::from_array(stretch),
            seed: named_seed(self.spec.seed, name, PURPOSE_CELLS),
        }
    }

    /// The switch function `f` of `owner` (its name seeds the noise); Err
    /// for a marble along a zero direction, which the caller places
    /// ([`zero_marble_direction`] says it).
    fn function(&self, owner: &str, f: &FunctionSpec) -> Result<SwitchFunction, ZeroDirection> {
        let source = PerlinSource::new(named_seed(self.spec.seed, owner, PURPOSE_NOISE));
        Ok(match *f {
            FunctionSpec::Perlin { frequency } => {
                SwitchFunction::Perlin(PerlinNoise { source, frequency })
            }
            FunctionSpec::Fbm {
                frequency,
                octaves,
                lacunarity,
                gain,
            } => SwitchFunction::Fbm(Fbm {
                source,
                frequency,
                octaves,
                lacunarity,
                gain,
            }),
            FunctionSpec::Turbulence {
                frequency,
                octaves,
                lacunarity,
                gain,
            } => SwitchFunction::Turbulence(Turbulence {
                source,
                frequency,
                octaves,
                lacunarity,
                gain,
            }),
            FunctionSpec::Marble {
                frequency,
                amplitude,
                direction,
                octaves,
                turbulence_frequency,
            } => {
                let direction =
                    unit_direction(DVec3::from_array(direction)).ok_or(ZeroDirection)?;
                SwitchFunction::Marble(Marble {
                    direction,
                    frequency,
                    amplitude,
                    turbulence: Turbulence {
                        source,
                        frequency: turbulence_frequency,
                        octaves,
                        lacunarity: 2.0,
                        gain: 0.5,
                    },
                })
            }
        })
    }

    fn weights_error(&self, owner: &str, entries: &[EntrySpec]) -> Option<RecipeError> {
        if entries.is_empty() {
            return Some(self.error_at_map(
                owner,
                format!("`{owner}` has no entries; allowed: at least one entry with weight > 0"),
            ));
        }
        let total: f64 = entries.iter().map(|e| e.weight).sum();
        (total <= 0.0).then(|| {
            self.error_at_map(
                owner,
                format!("the `weight`s of `{owner}` sum to {total}; allowed: each weight >= 0 and at least one > 0"),
            )
        })
    }

    fn node(&mut self, name: &str, spec: &MapSpec) -> Result<Node, RecipeError> {
        match spec {
            MapSpec::SurfaceMap {
                cell_size,
                jitter,
                stretch,
                entries,
            } => {
                if let Some(e) = self.weights_error(name, entries) {
                    return Err(e);
                }
                let mut list = Vec::with_capacity(entries.len());
                for e in entries {
                    list.push((self.entry(name, &e.material, &e.map)?, e.weight));
                }
                let v = self.voronoi(name, *cell_size, *jitter, *stretch);
                SurfaceMap::new(v, list)
                    .map(Node::Map)
                    .map_err(|e| self.error_at_map(name, format!("map `{name}`: {e}")))
            }
            MapSpec::Switch {
                function,
                ranges,
                per_cell_size,
                per_cell_of,
            } => {
                let f = self.function(name, function).map_err(|ZeroDirection| {
                    self.error_at_map(name, zero_marble_direction(&format!("`{name}`")))
                })?;
                let (lo, hi) = f.range();
                let pairs: Vec<(f64, f64)> = ranges.iter().map(|r| (r.from, r.to)).collect();
                check_partition(&pairs, lo, hi).map_err(|e| {
                    self.error_at_map(
                        name,
                        format!(
                            "switch `{name}`: {e}; allowed: ranges (from, to) in increasing order covering [{lo}, {hi}], the values of its function"
                        ),
                    )
                })?;
                let mut list = Vec::with_capacity(ranges.len());
                for r in ranges {
                    list.push(SwitchRange {
                        from: r.from,
                        to: r.to,
                        entry: self.entry(name, &r.material, &r.map)?,
                    });
                }
                let per_cell = match (per_cell_size, per_cell_of) {
                    (None, None) => None,
                    (Some(size), None) => Some(Voronoi {
                        seed: named_seed(self.spec.seed, name, PURPOSE_PER_CELL),
                        ..Voronoi::new(*size, 0)
                    }),
                    (None, Some(of)) => match self.spec.maps.get(of) {
                        Some(MapSpec::SurfaceMap {
                            cell_size,
                            jitter,
                            stretch,
                            ..
                        }) => Some(self.voronoi(of, *cell_size, *jitter, *stretch)),
                        Some(_) => {
                            return Err(self.error_at(
                                &format!("\"{of}\""),
                                format!("`per_cell_of` of `{name}` names `{of}`, a switch; allowed: a SurfaceMap"),
                            ))
                        }
                        None => {
                            self.map_index(of)?;
                            unreachable!("map_index fails for unknown names")
                        }
                    },
                    (Some(_), Some(_)) => {
                        return Err(self.error_at_map(
                            name,
                            format!("switch `{name}` has both `per_cell_size` and `per_cell_of`; allowed: at most one"),
                        ))
                    }
                };
                Switch::new(f, list, per_cell)
                    .map(Node::Switch)
                    .map_err(|e| self.error_at_map(name, format!("switch `{name}`: {e}")))
            }
        }
    }

    fn glitter(&mut self, g: &GlitterSpec) -> Result<GlitterMap, RecipeError> {
        if g.facets.cell_size > g.cell_size {
            return Err(self.error_at(
                "FacetBumpMap",
                format!(
                    "facet `cell_size` {} is larger than the glitter `cell_size` {}; allowed: facet cell_size <= glitter cell_size (facets subdivide a particle)",
                    g.facets.cell_size, g.cell_size
                ),
            ));
        }
        if let Some(e) = self.weights_error("glitter", &g.entries) {
            return Err(match e.position {
                Some(_) if self.text.contains("\"glitter\"") => e,
                _ => self.error_at("GlitterMap", e.message),
            });
        }
        let mut entries = Vec::with_capacity(g.entries.len());
        for e in &g.entries {
            match (&e.material, &e.map) {
                (Some(m), None) => {
                    let found = self.material_index(m);
                    entries.push((self.or_deferred(found), e.weight));
                }
                _ => return Err(self.error_at(
                    "GlitterMap",
                    "a glitter entry needs `material` (and no `map`): glitter cells hold materials"
                        .to_string(),
                )),
            }
        }
        let tilt = match g.facets.tilt {
            TiltSpec::UniformCone { max_tilt_deg } => Tilt::UniformCone { max_tilt_deg },
            TiltSpec::Gaussian { sigma_tilt_deg } => Tilt::Gaussian { sigma_tilt_deg },
        };
        let around = match g.facets.around {
            AroundSpec::SurfaceNormal => Around::SurfaceNormal,
            AroundSpec::Direction(x, y, z) => Around::Direction(DVec3::new(x, y, z)),
        };
        let facet_cells = self.voronoi(FACETS_NAME, g.facets.cell_size, g.facets.jitter, [1.0; 3]);
        let facets = FacetBumpMap::new(facet_cells, tilt, around)
            .map_err(|e| self.error_at("FacetBumpMap", e.to_string()))?;
        let cells = self.voronoi(GLITTER_NAME, g.cell_size, g.jitter, [1.0; 3]);
        let mut map = GlitterMap::new(cells, g.fill_fraction, entries, facets)
            .map_err(|e| self.error_at("GlitterMap", e.to_string()))?;
        if let Some(f) = &g.fill_modulation {
            let function = self.function(GLITTER_NAME, f).map_err(|ZeroDirection| {
                self.error_at(
                    "fill_modulation",
                    zero_marble_direction("the glitter's `fill_modulation`"),
                )
            })?;
            map.fill_modulation = Some(function);
        }
        Ok(map)
    }

    /// The compiled body; its inclusions' materials join the gem's.
    fn body(&mut self, spec: &GemSpec) -> Result<Body, RecipeError> {
        let BodySpec::Translucent {
            ior,
            absorption,
            scattering,
            anisotropy,
            roughness_deg,
            zoning,
            inclusions,
        } = &spec.body
        else {
            return Ok(Body::Opaque);
        };
        let mut compiled = Vec::with_capacity(inclusions.len());
        for (k, inclusion) in inclusions.iter().enumerate() {
            let cell_mm = inclusion.density_per_mm3.powf(-1.0 / 3.0);
            // Each population's problems are reported with the gem's other
            // gathered ones (the compile goes on; no gem is returned).
            let largest = inclusion.size_mm * (1.0 + inclusion.size_spread);
            if largest > 0.9 * cell_mm {
                let error = self.error_at_inclusion(
                    k,
                    "size_mm",
                    format!(
                        "inclusions {}: flakes up to {largest:.4} mm do not fit the {cell_mm:.4} mm cells of density {} per mm³; allowed: size_mm × (1 + size_spread) ≤ 0.9 × density_per_mm3^(−1/3)",
                        k + 1,
                        inclusion.density_per_mm3
                    ),
                );
                self.deferred.push(error);
            }
            let aligned = match &inclusion.orientation {
                OrientationSpec::Isotropic => None,
                OrientationSpec::Aligned {
                    direction,
                    spread_deg,
                } => {
                    let axis = unit_direction(DVec3::from_array(*direction)).unwrap_or_else(|| {
                        let error = self.error_at_inclusion(
                            k,
                            "Aligned",
                            format!("inclusions {}: `direction` is zero; allowed: any non-zero direction", k + 1),
                        );
                        self.deferred.push(error);
                        DVec3::Z
                    });
                    Some((axis, spread_deg.to_radians().cos()))
                }
            };
            let density_modulation = inclusion.density_modulation.as_ref().and_then(|f| {
                let function = self.function(&format!("#inclusions-{}", k + 1), f);
                function
                    .map_err(|ZeroDirection| {
                        let message = format!(
                            "inclusions {}: {}",
                            k + 1,
                            zero_marble_direction("`density_modulation`")
                        );
                        let error = self.error_at_inclusion(k, "density_modulation", message);
                        self.deferred.push(error);
                    })
                    .ok()
            });
            compiled.push(Inclusions {
                density_modulation,
                shape: inclusion.shape,
                radius_mm: 0.5 * inclusion.size_mm,
                size_spread: inclusion.size_spread,
                cell_mm,
                aligned,
                material: {
                    let found = self.material_index_seen_from(&inclusion.material, *ior);
                    self.or_deferred(found)
                },
                seed: derive_stream(seed_key(spec.seed ^ inclusion.seed), 16 + k as u64),
            });
        }
        let (zoning, absorption_per_mm) = match zoning {
            Some(z) => {
                let function =
                    self.function(ZONING_NAME, &z.function)
                        .map_err(|ZeroDirection| {
                            self.error_at("zoning", zero_marble_direction("the `zoning` function"))
                        })?;
                let (zoning, minimum) = Zoning::new(
                    function,
                    Rgb::from_array(*absorption),
                    Rgb::from_array(z.absorption),
                );
                (Some(Box::new(zoning)), minimum)
            }
            None => (None, Rgb::from_array(*absorption)),
        };
        Ok(Body::Translucent {
            ior: *ior,
            roughness_deg: *roughness_deg,
            rough_surface: RoughInterface::of_body(*ior, *roughness_deg),
            zoning,
            medium: Medium {
                absorption_per_mm,
                scattering_per_mm: Rgb::from_array(*scattering),
                anisotropy: *anisotropy,
            },
            inclusions: compiled,
        })
    }

    /// The gem, or every unknown name and every map that does not compile,
    /// with the first other error (in the order they are written).
    fn compile(mut self, spec: GemSpec) -> Result<Gem, RecipeError> {
        let compiled = self.compile_all(spec);
        if self.deferred.is_empty() {
            return compiled;
        }
        let mut unknown = std::mem::take(&mut self.deferred);
        let first = compiled.err().unwrap_or_else(|| unknown.remove(0));
        Err(RecipeError::gathered(first, unknown))
    }

    fn compile_all(&mut self, spec: GemSpec) -> Result<Gem, RecipeError> {
        // Inline materials first, in name order, so their indices are stable.
        for name in self.spec.materials.keys() {
            self.materials
                .push((name.clone(), self.spec.materials[name].clone()));
            self.seen_from_ior.push(None);
        }
        if let Some(name) = self
            .spec
            .maps
            .keys()
            .find(|name| self.spec.materials.contains_key(*name))
        {
            return Err(self.error_at_map(
                name,
                format!("`{name}` names both a map and a material; allowed: a name for one of them only"),
            ));
        }
        self.check_cycles()?;
        let mut nodes = Vec::with_capacity(self.spec.maps.len());
        for (name, map) in &self.spec.maps {
            // A map that does not compile is reported with the rest.
            match self.node(name, map) {
                Ok(node) => nodes.push(node),
                Err(e) => self.deferred.push(e),
            }
        }
        let surface = &self.spec.surface;
        let root = if self.spec.maps.contains_key(surface) {
            Entry::Node(self.map_index(surface)?)
        } else if self.spec.materials.contains_key(surface)
            || builtin_material_source(surface).is_some()
        {
            Entry::Material(self.material_index(surface)?)
        } else {
            let hint = did_you_mean(
                surface,
                self.map_names
                    .iter()
                    .map(String::as_str)
                    .chain(self.spec.materials.keys().map(String::as_str))
                    .chain(builtin_material_names().map(|name| -> &str { name })),
            )
            .map(|s| format!(" (did you mean `{s}`?)"))
            .unwrap_or_default();
            let unknown = self.error_at(
                "surface",
                format!(
                    "`surface` names `{surface}`, which is neither a map nor a material{hint}; allowed: a name from `maps` ({}) or a material",
                    if self.map_names.is_empty() {
                        "none here".to_string()
                    } else {
                        self.map_names.join(", ")
                    }
                ),
            );
            self.deferred.push(unknown);
            Entry::Material(0)
        };
        let glitter = match &self.spec.glitter {
            Some(g) => {
                let glitter = self.glitter(g);
                glitter.map_err(|e| self.deferred.push(e)).ok()
            }
            None => None,
        };
        if glitter.is_some() && matches!(spec.body, BodySpec::Translucent { .. }) {
            return Err(self.error_at(
                "glitter",
                "`glitter` on a translucent body would not be shaded (its surface's materials are not: the look comes from inside); allowed: a glitter map with `body: Opaque`, or flakes at depth as the body's `inclusions`".to_string(),
            ));
        }
        let body = self.body(&spec)?;
        // Placeholders stand for unknown names: no pattern of them.
        if let Some(unknown) = self.deferred.pop() {
            return Err(unknown);
        }
        let pattern = Pattern::new(nodes, root, glitter, self.materials.len() as u32)
            .map_err(|e| RecipeError::whole_file(self.path, e.to_string()))?;
        Ok(Gem {
            brdfs: Arc::from([]),
            name: spec.name.clone(),
            description: spec.description.clone(),
            seed: spec.seed,
            body,
            pattern,
            materials: std::mem::take(&mut self.materials),
            seen_from_ior: std::mem::take(&mut self.seen_from_ior)
                .into_iter()
                .map(|ior| ior.unwrap_or(1.0))
                .collect(),
            map_names: std::mem::take(&mut self.map_names),
            spec,
        })
    }
}

/// Find RECIPE as a file (if it names one, ends in `.ron` or has a `/`) or
/// as a built-in gem; returns the display path and the text.
fn load_gem_source(spec: &str) -> Result<(String, String), RecipeError> {
    use crate::recipe::error::{did_you_mean, folder_separator_hint};
    use crate::recipe::library::{builtin_gem_names, builtin_gem_source};
    if spec.trim().is_empty() {
        return Err(RecipeError::whole_file(
            "(empty gem name)",
            format!(
                "the gem name is empty; allowed: a built-in gem ({}) or a .ron gem file",
                builtin_gem_names().collect::<Vec<_>>().join(", ")
            ),
        ));
    }
    if crate::recipe::compile::names_a_file(spec) {
        let text = crate::recipe::compile::read_ron_file(spec, "gem recipe")?;
        return Ok((spec.to_string(), text));
    }
    match builtin_gem_source(spec) {
        Some(text) => Ok((format!("builtin:{spec}"), text.to_string())),
        None if crate::recipe::library::builtin_material_source(spec).is_some() => {
            Err(RecipeError::whole_file(
                spec,
                format!(
                    "`{spec}` is a built-in material, not a gem: `lapidary brdf {spec}` shows it, and a gem names it in its maps (`lapidary new NAME --from goldstone` starts one); built-in gems: {}",
                    builtin_gem_names().collect::<Vec<_>>().join(", ")
                ),
            ))
        }
        None => {
            let hint = did_you_mean(spec, builtin_gem_names())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            Err(RecipeError::whole_file(
                spec,
                format!(
                    "no such file and no built-in gem of that name{}{hint}; built-in gems: {}",
                    folder_separator_hint(spec),
                    builtin_gem_names().collect::<Vec<_>>().join(", ")
                ),
            ))
        }
    }
}
