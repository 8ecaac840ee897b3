//! Environment lighting: radiance arriving from infinitely far away, from a
//! constant colour, the built-in "studio" or an equirectangular HDR/EXR map,
//! importance-sampled by luminance for next-event estimation with MIS.
//!
//! # Conventions
//!
//! * World **z is up**. A direction `ω` is a unit vector pointing *away*
//!   from the shading point, towards the environment.
//! * Spherical angles: `θ = acos(ω_z) ∈ [0, π]` from the zenith and
//!   `φ = atan2(ω_y, ω_x) ∈ [0, 2π)` counter-clockwise from +x seen from
//!   above.
//! * A map is turned by `rotation_deg` about +z: a positive rotation turns
//!   the environment counter-clockwise seen from above, so the map's own
//!   azimuth is `φ_map = φ − rotation`. Map texel column `u = φ_map / 2π`,
//!   row `v = θ / π`: column 0 starts at the map's +x, **row 0 is straight
//!   up**, the last row straight down (the usual lat-long layout of HDR
//!   panoramas, top row = sky).
//! * Radiance is piecewise constant: a direction gets the texel it falls in
//!   (no filtering), exactly the function the sampling density follows.
//!   Texels are stored with 9 significant bits and a shared exponent
//!   (8 bytes per texel with their sampling tables; see [`EnvironmentMap`]).
//! * Sampling: a texel with probability ∝ luminance × its solid angle, by
//!   two alias tables (a row, then a column of that row; O(1) per sample),
//!   then a direction uniform in solid angle inside it, so the density per
//!   solid angle is constant on each texel and ∝ its luminance (pbrt-v4
//!   §12.5.2 samples the same texels uniformly in (u, v) instead, a
//!   density ∝ 1/sinθ inside each). Texels far dimmer than their row's
//!   mean may get density 0 and are left to BRDF sampling. A map whose
//!   power is mostly in a few very bright texels (a sun) samples those
//!   apart, as a second part with its own sample (see [`EnvironmentMap`]).
//! * [`Environment::Constant`] is sampled uniformly over the sphere,
//!   `p(ω) = 1/4π`.
//! * `intensity` multiplies the radiance (applied when a texel is read).
//!
//! [`Environment::sample`] returns exactly [`Environment::radiance`] and
//! [`Environment::pdf`] of the direction it returns (the integrator's MIS
//! weights rely on it).

use std::f64::consts::{FRAC_1_PI, FRAC_PI_2, PI, TAU};
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

#[cfg(test)]
use glam::DVec2;
use glam::DVec3;

use super::cpu::prefetch;
use super::distribution::{alias_table, bucket_of_draw, draw, AliasTable};
use super::shared_exponent::{decode, encode, exponent_scales, TEXEL_BITS, TEXEL_MASK};
use crate::brdf::Rgb;
use crate::file_kind::{not_a_regular_file, FileKind};
use crate::sampling::sin_cos_turns;

/// Largest accepted map width in texels (a 16K panorama).
pub(crate) const MAX_MAP_WIDTH: usize = 16384;
/// Largest accepted map height in texels.
pub(crate) const MAX_MAP_HEIGHT: usize = 8192;
/// Width of the baked studio map: 0.35° texels keep soft-box edges crisp.
pub const STUDIO_WIDTH: usize = 1024;
/// The largest intensity the studio takes: its brightest texel (below 12)
/// times it stays within what a map texel stores
/// ([`MAX_TEXEL_RADIANCE`]).
pub const MAX_STUDIO_INTENSITY: f64 = MAX_TEXEL_RADIANCE / 12.0;
/// Height of the baked studio map.
pub const STUDIO_HEIGHT: usize = 512;

/// The brightest channel a map's texel may have in its file (before
/// `intensity`), 511 × 2²³ ≈ 4.29 × 10⁹.
pub use super::shared_exponent::MAX_RADIANCE as MAX_TEXEL_RADIANCE;

/// Name used in errors for maps that come from memory, not from a file.
const IN_MEMORY: &str = "<in-memory environment map>";

/// Why an environment cannot be built or loaded. Every message names the
/// file (or says the map came from memory) and what would be accepted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnvironmentError {
    /// The file does not exist.
    #[error("environment map {}: file not found", .path.display())]
    NotFound {
        /// The path as given.
        path: PathBuf,
    },
    /// The file exists but could not be opened or read (permissions, a
    /// directory, an I/O failure).
    #[error("environment map {}: cannot read the file: {message}", .path.display())]
    Io {
        /// The path as given.
        path: PathBuf,
        /// The operating system's reason.
        message: String,
    },
    /// A valid OpenEXR image without the colour an environment needs.
    #[error("environment map {}: no layer has R, G and B channels (its channels: {channels}); allowed: a colour map", .path.display())]
    NotColour {
        /// The path as given.
        path: PathBuf,
        /// The channels it has, comma separated.
        channels: String,
    },
    /// The bytes are not a valid image of the format its extension claims.
    #[error("environment map {}: corrupt or unreadable {format} data: {message}", .path.display())]
    Decode {
        /// The path as given.
        path: PathBuf,
        /// "Radiance HDR" or "OpenEXR".
        format: &'static str,
        /// The decoder's reason.
        message: String,
    },
    /// The file's first bytes are not those of the format its extension
    /// names: another image kind (a PNG, a JPEG, …), the other of the two
    /// map formats, or not an image at all.
    #[error("environment map {}: {found}; {advice}", .path.display())]
    WrongKind {
        /// The path as given.
        path: PathBuf,
        /// What the bytes are, against what the extension says ("it is a
        /// PNG image, not Radiance HDR").
        found: String,
        /// What to do about it.
        advice: &'static str,
    },
    /// Neither `.hdr` nor `.exr`.
    #[error(
        "environment map {}: unsupported file type `{extension}`; allowed: .hdr (Radiance RGBE) \
         or .exr (OpenEXR), equirectangular",
        .path.display()
    )]
    UnsupportedExtension {
        /// The path as given.
        path: PathBuf,
        /// The extension found (empty when there is none).
        extension: String,
    },
    /// A map with no texels.
    #[error("environment map {origin}: image is {width}×{height} texels; it must be at least 1×1")]
    Empty {
        /// The file path, or a note that the map came from memory.
        origin: String,
        /// Width found.
        width: usize,
        /// Height found.
        height: usize,
    },
    /// A map beyond `MAX_MAP_WIDTH` × `MAX_MAP_HEIGHT`.
    #[error(
        "environment map {origin}: image is {width}×{height} texels; allowed: at most \
         {MAX_MAP_WIDTH} wide and {MAX_MAP_HEIGHT} high (downscale it first)"
    )]
    TooLarge {
        /// The file path, or a note that the map came from memory.
        origin: String,
        /// Width found.
        width: usize,
        /// Height found.
        height: usize,
    },
    /// Texel data whose length is not width × height.
    #[error("environment map {origin}: {len} texels given for a {width}×{height} map")]
    WrongTexelCount {
        /// The file path, or a note that the map came from memory.
        origin: String,
        /// Width stated.
        width: usize,
        /// Height stated.
        height: usize,
        /// Texels given.
        len: usize,
    },
    /// A NaN, infinite or negative radiance value.
    #[error(
        "environment map {origin}: texel at x = {x}, y = {y} (column, row from the top-left) is \
         ({}, {}, {}); radiance must be finite and ≥ 0 in every channel",
        .value.x, .value.y, .value.z
    )]
    BadTexel {
        /// The file path, or a note that the map came from memory.
        origin: String,
        /// Column of the first bad texel.
        x: usize,
        /// Row of the first bad texel (0 = top = straight up).
        y: usize,
        /// Its radiance, as in the file (before `intensity`).
        value: Rgb,
    },
    /// A texel brighter than [`MAX_TEXEL_RADIANCE`] (before `intensity`).
    #[error(
        "environment map {origin}: texel at x = {x}, y = {y} (column, row from the top-left) has \
         a channel of {value:.4e}, above the {MAX_TEXEL_RADIANCE:.4e} a texel can hold; scale the map \
         down and raise `intensity` instead (a scene's `environment: File(path: …, intensity: …)`)"
    )]
    TooBright {
        /// The file path, or a note that the map came from memory.
        origin: String,
        /// Column of the first such texel.
        x: usize,
        /// Row of the first such texel (0 = top = straight up).
        y: usize,
        /// Its brightest channel, as in the file.
        value: f64,
    },
    /// An out-of-range parameter (`intensity`, `rotation_deg`, `radiance`).
    #[error("environment `{field}` = {value} is out of range: {allowed}")]
    Parameter {
        /// The parameter's name.
        field: &'static str,
        /// The refused value (the first bad component for colours).
        value: f64,
        /// What would have been accepted.
        allowed: &'static str,
    },
}

/// The texel of a map that a direction falls in, found by
/// [`Environment::prefetch_direction`] so that the lookup after the ray's
/// trace need not find it again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Texel {
    row: usize,
    col: usize,
}

/// One direction drawn from an [`Environment`], for next-event estimation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvironmentSample {
    /// Unit world direction towards the environment.
    pub direction: DVec3,
    /// `Environment::radiance(direction)` (for a map: the texel the sample
    /// was drawn in, which is the direction's own except on a texel edge).
    pub radiance: Rgb,
    /// `Environment::pdf(direction)` to rounding, per unit solid angle, > 0.
    pub pdf: f64,
}

/// Light from infinitely far away: a constant colour or a map.
#[derive(Debug, Clone, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction (a white furnace when 1).
    Constant(Rgb),
    /// An equirectangular map (from a file, or the baked studio).
    Map(EnvironmentMap),
}

impl Environment {
    /// The same `radiance` from every direction. Negative or non-finite
    /// components become 0 (use [`Environment::try_constant`] to refuse
    /// them instead).
    pub fn constant(radiance: Rgb) -> Self {
        let clean = |c: f64| if c.is_finite() && c > 0.0 { c } else { 0.0 };
        Environment::Constant(Rgb::new(
            clean(radiance.x),
            clean(radiance.y),
            clean(radiance.z),
        ))
    }

    /// [`Environment::constant`], refusing negative or non-finite
    /// components with an error.
    pub fn try_constant(radiance: Rgb) -> Result<Self, EnvironmentError> {
        for c in radiance.to_array() {
            if !(c.is_finite() && c >= 0.0) {
                return Err(EnvironmentError::Parameter {
                    field: "radiance",
                    value: c,
                    allowed: "every component finite and ≥ 0",
                });
            }
        }
        Ok(Environment::Constant(radiance))
    }

    /// The built-in studio (the default lighting of every render), its
    /// radiance scaled by `intensity` and turned by `rotation_deg` about +z,
    /// baked at [`STUDIO_WIDTH`] × [`STUDIO_HEIGHT`]. See [`studio_radiance`]
    /// for the layout. A non-finite rotation becomes 0° and a negative or
    /// non-finite intensity 0, and one above [`MAX_STUDIO_INTENSITY`]
    /// that maximum (use [`Environment::try_studio`] to refuse them
    /// instead).
    pub fn studio(intensity: f64, rotation_deg: f64) -> Self {
        let intensity = if intensity.is_finite() && intensity > 0.0 {
            intensity.min(MAX_STUDIO_INTENSITY)
        } else {
            0.0
        };
        let rotation_deg = if rotation_deg.is_finite() {
            rotation_deg
        } else {
            0.0
        };
        Environment::Map(EnvironmentMap::bake_studio(intensity, rotation_deg))
    }

    /// [`Environment::studio`], refusing a negative, non-finite or too
    /// large (above [`MAX_STUDIO_INTENSITY`]) intensity and a non-finite
    /// rotation with an error.
    pub fn try_studio(intensity: f64, rotation_deg: f64) -> Result<Self, EnvironmentError> {
        check_intensity(intensity)?;
        if intensity > MAX_STUDIO_INTENSITY {
            return Err(EnvironmentError::Parameter {
                field: "intensity",
                value: intensity,
                allowed: "at most 3.6e8 for the studio (its brightest texel, 12, times it must stay storable)",
            });
        }
        check_rotation(rotation_deg)?;
        Ok(Environment::Map(EnvironmentMap::bake_studio(
            intensity,
            rotation_deg,
        )))
    }

    /// Loads an equirectangular `.hdr` (Radiance RGBE, via the `image`
    /// crate) or `.exr` (the first layer with R, G, B channels, via the `exr`
    /// crate; alpha is ignored), scales it by `intensity` and turns it by
    /// `rotation_deg`. Every failure is an [`EnvironmentError`] naming the
    /// file: missing, unreadable, corrupt, wrong extension, empty, larger
    /// than `MAX_MAP_WIDTH` × `MAX_MAP_HEIGHT`, or a NaN, infinite or
    /// negative texel.
    pub fn from_file(
        path: &Path,
        rotation_deg: f64,
        intensity: f64,
    ) -> Result<Self, EnvironmentError> {
        check_intensity(intensity)?;
        check_rotation(rotation_deg)?;
        let (width, height, texels) = read_map_file(path)?;
        let origin = path.display().to_string();
        let map =
            EnvironmentMap::from_packed(origin, width, height, texels, intensity, rotation_deg)?;
        Ok(Environment::Map(map))
    }

    /// For a map that is not twice as wide as high (within 1 %), what a
    /// user should know: it is read as latitude-longitude all the same,
    /// so its sky comes out stretched. `None` for a 2:1 map or no map.
    pub fn proportion_warning(&self) -> Option<String> {
        let Environment::Map(map) = self else {
            return None;
        };
        let (width, height) = (map.width(), map.height());
        ((width as f64 / height as f64 - 2.0).abs() > 0.02).then(|| {
            format!(
                "it is {width}×{height} texels, not twice as wide as high: it is read as a \
                 latitude-longitude (equirectangular) map all the same, so its sky is stretched"
            )
        })
    }

    /// A rough luminance of the irradiance it gives a surface (π · the
    /// mean radiance's luminance), for choosing among emitters.
    pub(crate) fn irradiance_estimate(&self) -> f64 {
        match self {
            Environment::Constant(c) => PI * luminance(*c),
            Environment::Map(map) => map.irradiance_estimate(),
        }
    }

    /// Radiance arriving from the unit world `direction` (black for a zero
    /// or non-finite direction). Inlined: a constant sky's answer is a few
    /// instructions, which a call would double on every escaping path.
    #[inline(always)]
    pub fn radiance(&self, direction: DVec3) -> Rgb {
        match self {
            Environment::Constant(c) => {
                if direction.is_finite() && direction != DVec3::ZERO {
                    *c
                } else {
                    Rgb::ZERO
                }
            }
            Environment::Map(map) => map.radiance(direction),
        }
    }

    /// [`Environment::radiance`] and [`Environment::pdf`] of one direction,
    /// converting it to map coordinates once (an `acos` and an `atan2`
    /// fewer): what a path escaping to a light-sampled sky needs.
    pub fn radiance_and_pdf(&self, direction: DVec3) -> (Rgb, f64) {
        match self {
            Environment::Constant(_) => (self.radiance(direction), self.pdf(direction)),
            Environment::Map(map) => map.radiance_and_pdf(direction),
        }
    }

    /// Draws a direction with density proportional to luminance (a map)
    /// or uniform over the sphere (a constant). `None` for a map that is
    /// black everywhere.
    pub fn sample(&self, u: [f64; 2]) -> Option<EnvironmentSample> {
        match self {
            Environment::Constant(_) => self.sample_part(0, u),
            Environment::Map(map) => map.sample(u),
        }
    }

    /// Draws a direction of part `part` (below [`Environment::parts`])
    /// with density proportional to luminance within the part; radiance
    /// and density ([`Environment::part_pdf`]) are the direction's. A
    /// constant has one part, sampled as [`Environment::sample`] samples
    /// it. `None` for a part that is black everywhere, or no part.
    pub fn sample_part(&self, part: usize, u: [f64; 2]) -> Option<EnvironmentSample> {
        match self {
            Environment::Constant(c) => {
                // Uniform sphere (pbrt-v4 eq. A.15): z = 1 − 2u₀, φ = 2πu₁.
                let z = 1.0 - 2.0 * u[0];
                let r = (1.0 - z * z).max(0.0).sqrt();
                let (s, co) = sin_cos_turns(u[1]);
                (part == 0).then(|| EnvironmentSample {
                    direction: DVec3::new(r * co, r * s, z),
                    radiance: *c,
                    pdf: 0.25 * FRAC_1_PI,
                })
            }
            Environment::Map(map) => map.sample_part(part, u),
        }
    }

    /// How many parts that do not overlap the environment can be sampled
    /// in, one sample of each ([`Environment::sample_part`]): 2 for a map
    /// whose few brightest texels carry most of its power (a sun, see
    /// [`EnvironmentMap`]), else 1.
    pub fn parts(&self) -> usize {
        match self {
            Environment::Constant(_) => 1,
            Environment::Map(map) => map.parts(),
        }
    }

    /// Starts loading the texel [`Environment::radiance_and_pdf`] reads
    /// for `direction` (see [`EnvironmentMap::prefetch_direction`]) and
    /// returns it, for [`Environment::radiance_and_pdfs_in`]; nothing for a
    /// constant, at the cost of one test.
    #[inline(always)]
    pub(crate) fn prefetch_direction(&self, direction: DVec3) -> Option<Texel> {
        match self {
            Environment::Map(map) => map.prefetch_direction(direction),
            Environment::Constant(_) => None,
        }
    }

    /// [`Environment::radiance`], [`Environment::pdf`] and
    /// [`Environment::part_pdf`] of `direction`, read from `texel` when
    /// [`Environment::prefetch_direction`] found it for that direction
    /// (the same answer, without finding the texel again): what a path
    /// escaping to a light-sampled sky needs.
    #[inline(always)]
    pub(crate) fn radiance_and_pdfs_in(
        &self,
        direction: DVec3,
        texel: Option<Texel>,
    ) -> (Rgb, f64, f64) {
        match (self, texel) {
            (Environment::Map(map), Some(texel)) => map.texel_radiance_and_pdfs(texel),
            (Environment::Map(map), None) => map.radiance_and_pdfs(direction),
            (Environment::Constant(_), _) => {
                let pdf = self.pdf(direction);
                (self.radiance(direction), pdf, pdf)
            }
        }
    }

    /// [`Environment::radiance`] of `direction`, read from `texel` as
    /// [`Environment::radiance_and_pdfs_in`] does.
    pub(crate) fn radiance_in(&self, direction: DVec3, texel: Option<Texel>) -> Rgb {
        match (self, texel) {
            (Environment::Map(map), Some(texel)) => map.texel_radiance(texel),
            _ => self.radiance(direction),
        }
    }

    /// Density of [`Environment::sample`] per unit solid angle at the unit
    /// world `direction`.
    pub fn pdf(&self, direction: DVec3) -> f64 {
        match self {
            Environment::Constant(_) => 0.25 * FRAC_1_PI,
            Environment::Map(map) => map.pdf(direction),
        }
    }

    /// Density per unit solid angle at the unit world `direction` of
    /// [`Environment::sample_part`] of the part the direction lies in.
    pub fn part_pdf(&self, direction: DVec3) -> f64 {
        match self {
            Environment::Constant(_) => 0.25 * FRAC_1_PI,
            Environment::Map(map) => map.radiance_and_pdfs(direction).2,
        }
    }
}

/// An equirectangular radiance map with its luminance sampling tables
/// (conventions in the module documentation).
///
/// # Storage: 8 bytes per texel
///
/// Each texel is one `u64`: its radiance in the low 33 bits (three 9-bit
/// mantissas and a shared exponent, see `shared_exponent.rs`: every
/// channel within 2⁻⁹ × the brightest channel of the source), and in the
/// other 31 bits the bucket of its row's alias table that sits at its
/// column: a 16-bit threshold, the 14-bit column of its alias, and one bit,
/// the texel's extra unit (below). Radiance and sampling data of a texel
/// share a cache line, so a light sample reads at most two texels and a
/// density lookup one. Per row the map keeps a few numbers
/// (`RowSampling`), and the rows themselves are drawn from an
/// [`AliasTable`]: both O(1), whatever the map's size and contrast.
///
/// # Sampling weights that the texel itself gives back
///
/// Within row `r`, texel `i` has the integer weight `w_i = ⌊Y_i s_r⌋ +
/// extra_i` (`Y` its luminance, `s_r` the row's units per luminance,
/// `extra_i` its stored bit), and the weights of a row sum to exactly
/// `width × 2¹⁵`, the row table's total: the floors, plus one unit for
/// each of the lit texels with the largest remainders. The row's alias
/// table, built in integers, draws texel `i` with probability exactly
/// `w_i / (width × 2¹⁵)`, and a density lookup recomputes `w_i` from the
/// texel it reads anyway. Rows are drawn with probability ∝ `Σ Y × Ω_row`,
/// and inside a texel the direction is uniform in solid angle (uniform in
/// `cosθ` and in `φ`), so the density per solid angle is constant on each
/// texel, ∝ its luminance, and finite at the poles. A texel whose
/// luminance is below one unit of its row (2⁻¹⁵ of the row's mean) may get
/// weight 0: it is then never light-sampled and reports density 0, which
/// the integrator's MIS reads as "left to BRDF sampling" (unbiased).
///
/// # Two parts: a sun apart from its sky
///
/// Sampled by luminance alone, a map with a small, very bright source (the
/// sun of an outdoor panorama, a lamp) spends nearly every light sample
/// on it, and the rest of the sky reaches a shading point through BRDF
/// samples alone: a diffuse base in the sun's light gets its skylight with
/// the noise of cosine sampling. Where a few texels (at most 1 in 256),
/// each at least 64 times the map's mean luminance, carry at least half of
/// its power and leave the rest at least 1/1024 of it, those texels are a
/// part of their own, drawn by a small alias table
/// (`HotPart`), and the row tables sample the rest with those texels at
/// weight 0. [`EnvironmentMap::sample_part`] draws from one part, and
/// [`EnvironmentMap::sample`] from the whole map: a part chosen by its
/// share of the power, so that it draws what one table over every texel
/// would. The parts do not overlap, so a texel's density in its part, and
/// in the whole map (that times the part's share), are one lookup. The
/// integrator takes one sample of each part where a pixel sees a vertex
/// sharply, and one of the whole map elsewhere. Maps that do not qualify
/// (smooth skies, the studio) stay one part.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    /// Row-major, row 0 straight up: packed radiance and alias bucket (see
    /// the type's documentation).
    texels: Vec<u64>,
    /// What each shared exponent stands for, `intensity` included (boxed:
    /// 512 bytes inline would make every [`Environment`] that large).
    scales: Box<[f64; 64]>,
    /// Per row: how its texels' weights and densities follow from them.
    rows: Vec<RowSampling>,
    /// The distribution of rows; `None` when every texel is black.
    marginal: Option<AliasTable>,
    /// The brightest texels, sampled apart (see the type's documentation);
    /// `None` for a map sampled as one part.
    hot: Option<HotPart>,
    /// The luminance from which a texel belongs to `hot` (∞ without one):
    /// one comparison tells a density lookup which part a texel is in.
    hot_threshold: f64,
    /// The probability with which [`Self::sample`] draws from the rest
    /// (the rows' tables): 1 − `hot`'s share, 1 without a hot part (kept
    /// for every density lookup of a row's texel).
    rest_share: f64,
    /// ∫ Y dω / 4 over the sphere: the luminance of the irradiance on a
    /// plane that faces a uniform sky of the map's mean (π · mean), by
    /// which a vertex weighs the map against lights when it chooses
    /// among more emitters than it samples.
    irradiance_estimate: f64,
    rotation_deg: f64,
    /// The rotation in radians, for the reference mapping in tests.
    #[cfg(test)]
    rotation_rad: f64,
    /// The rotation in turns (of 2π), for [`sin_cos_turns`].
    rotation_turns: f64,
    /// `(cos φ_c, sin φ_c)` of the world azimuth `φ_c = 2π (c/width +
    /// rotation_turns)` where column `c` starts, for `c = 0..=width`: the
    /// same expression as a sample drawn at the column's edge, so that a
    /// lookup and the sampler split the azimuths alike (see
    /// [`EnvironmentMap::column_of`]). 16 bytes a column.
    column_edges: Vec<[f64; 2]>,
}

/// How one row of an [`EnvironmentMap`] turns a texel into its sampling
/// weight and density.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RowSampling {
    /// `s_r`: a texel's weight is `⌊luminance × s_r⌋` + its extra unit
    /// (0 for a row that is never sampled).
    units_per_luminance: f64,
    /// Density per unit solid angle of one unit of weight: the row's
    /// probability over (2¹⁵ × its solid angle).
    pdf_per_unit: f64,
    /// cosθ at the row's upper edge.
    z_top: f64,
    /// cosθ at the row's lower edge.
    z_bottom: f64,
}

/// A texel is bright enough to be sampled apart from the rest of its map
/// at this many times the map's mean luminance over the sphere (a sun is
/// 10⁴–10⁶ times its sky's; the studio's soft boxes, the brightest
/// sources that should stay in one part, about 20 times its mean).
const HOT_OVER_MEAN: f64 = 64.0;
/// ... when such texels carry at least this share of the map's power (the
/// rest of the map then gets at most half the light samples of one part).
const HOT_MIN_SHARE: f64 = 0.5;
/// ... and when they are at most one texel in this many (a compact source,
/// whose own table stays small: a 0.5° sun is about 100 texels of a
/// 4096 × 2048 map).
const HOT_MAX_TEXELS_PER: usize = 256;
/// ... and the rest carries at least this share (a black sky with a sun is
/// one part: a sample of its rest would find nothing).
const REST_MIN_SHARE: f64 = 1.0 / 1024.0;

/// The hot texels of a map sampled as two parts (see [`EnvironmentMap`]).
#[derive(Debug, Clone, PartialEq)]
struct HotPart {
    /// Flat indices (`row × width + col`) of the texels, ascending.
    texels: Vec<u32>,
    /// Draws one of `texels` with probability ∝ luminance × solid angle.
    table: AliasTable,
    /// The part's share of the map's power, in (0, 1).
    share: f64,
}

/// Units of each bucket of a row's alias table (2¹⁵: a threshold fits in
/// 16 bits, 0 to 2¹⁵ inclusive).
const COLUMN_CAPACITY: u64 = 1 << 15;
/// Where a texel's bucket threshold starts in its `u64`.
const THRESHOLD_SHIFT: u32 = TEXEL_BITS;
/// Where the texel's extra unit of weight is.
const EXTRA_UNIT_SHIFT: u32 = THRESHOLD_SHIFT + 16;
/// Where its bucket's alias column starts (14 bits, the rest of the word).
const ALIAS_SHIFT: u32 = EXTRA_UNIT_SHIFT + 1;
const _: () = assert!(ALIAS_SHIFT + 14 == 64 && MAX_MAP_WIDTH <= 1 << 14);

/// A texel's bucket: (threshold, alias column).
#[inline]
fn bucket(bits: u64) -> (u64, usize) {
    (
        (bits >> THRESHOLD_SHIFT) & 0xffff,
        (bits >> ALIAS_SHIFT) as usize,
    )
}

impl EnvironmentMap {
    /// A map from row-major `texels` (row 0 straight up, column 0 at the
    /// map's +x), turned by `rotation_deg` about +z. Refuses an empty or
    /// oversized grid, a texel count other than `width × height`, a
    /// NaN/infinite/negative texel, one brighter than
    /// [`MAX_TEXEL_RADIANCE`] and a non-finite rotation. The texels are
    /// stored with 9 significant bits (see the type's documentation).
    pub fn new(
        width: usize,
        height: usize,
        texels: Vec<Rgb>,
        rotation_deg: f64,
    ) -> Result<Self, EnvironmentError> {
        check_rotation(rotation_deg)?;
        check_size(IN_MEMORY, width, height)?;
        Self::from_texels(
            IN_MEMORY.to_string(),
            width,
            height,
            &texels,
            1.0,
            rotation_deg,
        )
    }

    /// Validates and packs texels, then builds the sampling tables.
    fn from_texels(
        origin: String,
        width: usize,
        height: usize,
        texels: &[Rgb],
        intensity: f64,
        rotation_deg: f64,
    ) -> Result<Self, EnvironmentError> {
        check_size(&origin, width, height)?;
        if texels.len() != width * height {
            return Err(EnvironmentError::WrongTexelCount {
                origin,
                width,
                height,
                len: texels.len(),
            });
        }
        let packed = texels
            .iter()
            .enumerate()
            .map(|(i, t)| {
                pack_texel(t.to_array())
                    .map_err(|bad| bad.into_error(origin.clone(), i % width, i / width))
            })
            .collect::<Result<Vec<u64>, _>>()?;
        Self::from_packed(origin, width, height, packed, intensity, rotation_deg)
    }

    /// Builds the sampling tables of packed texels (radiance bits only)
    /// whose radiance is scaled by `intensity`: every row's alias table in
    /// parallel (each a pure function of its texels), then the rows'.
    fn from_packed(
        origin: String,
        width: usize,
        height: usize,
        mut texels: Vec<u64>,
        intensity: f64,
        rotation_deg: f64,
    ) -> Result<Self, EnvironmentError> {
        use rayon::prelude::*;
        let scales = Box::new(exponent_scales(intensity));
        let built: Vec<Result<RowLuminance, usize>> = texels
            .par_chunks_mut(width)
            .map(|row| build_row_table(row, &scales, f64::INFINITY))
            .collect();
        let z: Vec<f64> = (0..=height)
            .map(|row| (PI * row as f64 / height as f64).cos())
            .collect();
        let mut luminances = Vec::with_capacity(height);
        for (row, built) in built.iter().enumerate() {
            luminances.push(built.map_err(|col| EnvironmentError::BadTexel {
                origin: origin.clone(),
                x: col,
                y: row,
                value: decode(texels[row * width + col], &scales),
            })?);
        }
        // ∫ Y dω over the sphere, every texel counted (before the hot part
        // leaves the rows' tables).
        let luminance_integral: f64 = (0..height)
            .map(|row| luminances[row].sum / width as f64 * TAU * (z[row] - z[row + 1]))
            .sum();
        let hot = hot_part(&texels, width, &z, &luminances, &scales);
        let hot_threshold = match &hot {
            Some((part, threshold)) => {
                // The rows holding hot texels again, with those at weight 0.
                let mut hot_rows: Vec<usize> =
                    part.texels.iter().map(|&i| i as usize / width).collect();
                hot_rows.dedup();
                for row in hot_rows {
                    let texels = &mut texels[row * width..][..width];
                    luminances[row] = build_row_table(texels, &scales, *threshold)
                        .expect("the row was built once; zeroing texels keeps its sum finite");
                }
                *threshold
            }
            None => f64::INFINITY,
        };
        // ∝ Σ Y × Ω_row: the density per solid angle follows luminance.
        let row_weights: Vec<f64> = (0..height)
            .map(|row| luminances[row].sum * TAU * (z[row] - z[row + 1]))
            .collect();
        // Only all-black rows (or a sum overflowing to ∞) fail here.
        let marginal = AliasTable::new(&row_weights).ok();
        let rows = (0..height)
            .map(|row| {
                let (z_top, z_bottom) = (z[row], z[row + 1]);
                let probability = marginal.as_ref().map_or(0.0, |m| m.probability(row));
                let sum = luminances[row].sum;
                RowSampling {
                    units_per_luminance: if probability > 0.0 {
                        row_units_per_luminance(sum, width)
                    } else {
                        0.0
                    },
                    pdf_per_unit: probability / (COLUMN_CAPACITY as f64 * TAU * (z_top - z_bottom)),
                    z_top,
                    z_bottom,
                }
            })
            .collect();
        Ok(Self {
            width,
            height,
            texels,
            scales,
            rows,
            marginal,
            rest_share: hot.as_ref().map_or(1.0, |(part, _)| 1.0 - part.share),
            hot: hot.map(|(part, _)| part),
            hot_threshold,
            irradiance_estimate: luminance_integral / 4.0,
            rotation_deg,
            #[cfg(test)]
            rotation_rad: rotation_deg.to_radians(),
            rotation_turns: rotation_deg / 360.0,
            column_edges: (0..=width)
                .map(|col| {
                    let (sin, cos) =
                        sin_cos_turns(col as f64 / width as f64 + rotation_deg / 360.0);
                    [cos, sin]
                })
                .collect(),
        })
    }

    /// Bakes [`studio_radiance`] with 4 × 4 samples per texel, so that the
    /// soft-box edges are anti-aliased over one 0.35° texel; `intensity`
    /// scales it when decoding, like a file's.
    fn bake_studio(intensity: f64, rotation_deg: f64) -> Self {
        let (w, h) = (STUDIO_WIDTH, STUDIO_HEIGHT);
        let texels = bake_studio_texels(w, h, 1.0);
        Self::from_texels(
            "<studio>".to_string(),
            w,
            h,
            &texels,
            intensity,
            rotation_deg,
        )
        .expect("the studio's texels are finite, non-negative and below 12")
    }

    /// A rough luminance of the irradiance the map gives a surface (see
    /// the field).
    pub(crate) fn irradiance_estimate(&self) -> f64 {
        self.irradiance_estimate
    }

    /// Columns (azimuth bins).
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows (polar bins; row 0 straight up).
    pub fn height(&self) -> usize {
        self.height
    }

    /// The rotation about +z this map was built with, in degrees.
    pub fn rotation_deg(&self) -> f64 {
        self.rotation_deg
    }

    /// Radiance of texel (`col`, `row`), intensity included, as stored
    /// (9 significant bits); black outside the map.
    pub fn texel(&self, col: usize, row: usize) -> Rgb {
        if col < self.width && row < self.height {
            decode(self.texels[row * self.width + col], &self.scales)
        } else {
            Rgb::ZERO
        }
    }

    /// Map coordinates `(u, v) ∈ [0, 1)²` of a world direction (after
    /// undoing the rotation) by `acos` and `atan2`; `None` for a zero or
    /// non-finite direction: the reference [`Self::texel_index`] is tested
    /// against.
    #[cfg(test)]
    pub(crate) fn direction_to_uv(&self, direction: DVec3) -> Option<DVec2> {
        let len = direction.length();
        if !(len.is_finite() && len > 0.0) {
            return None;
        }
        let theta = (direction.z / len).clamp(-1.0, 1.0).acos();
        let phi_map = wrap_to_full_turn(direction.y.atan2(direction.x) - self.rotation_rad);
        // rem_euclid may round up to exactly 2π; keep u < 1.
        let u = (phi_map / TAU).min(1.0_f64.next_down());
        let v = (theta * FRAC_1_PI).min(1.0_f64.next_down());
        Some(DVec2::new(u, v))
    }

    /// Row and column of the texel a direction falls in; `None` for a zero
    /// or non-finite direction. The texels of `θ = acos(z)` and `φ_map`
    /// (module conventions), found without `acos` or `atan2`: polynomial
    /// guesses within 2·10⁻⁸ rad, then the row's and the column's own
    /// edges decide (one comparison each way; a texel is at least
    /// π/8192 ≈ 3.8·10⁻⁴ rad across).
    #[inline]
    fn texel_index(&self, direction: DVec3) -> Option<(usize, usize)> {
        let len = direction.length();
        if !(len.is_finite() && len > 0.0) {
            return None;
        }
        let z = (direction.z / len).clamp(-1.0, 1.0);
        Some((self.row_of(z), self.column_of(direction.x, direction.y)))
    }

    /// The row whose band of cosines `(z_bottom, z_top]` holds `z` (the
    /// half-open band a sample of the row is drawn from): the guess
    /// `⌊acos(z) H/π⌋`, moved one row where `z` lies beyond its edges.
    #[inline]
    fn row_of(&self, z: f64) -> usize {
        let height = self.height;
        // `as usize` saturates: a guess just below 0 is row 0.
        let mut row = ((acos_approx(z) * (height as f64 * FRAC_1_PI)) as usize).min(height - 1);
        let band = &self.rows[row];
        if row > 0 && z > band.z_top {
            row -= 1;
        } else if row + 1 < height && z <= band.z_bottom {
            row += 1;
        }
        row
    }

    /// The column whose azimuths run from its edge `c` (included) to edge
    /// `c + 1`, for the direction's `(x, y)`: the guess from
    /// [`atan2_approx`], moved one column (wrapping round) where the
    /// direction lies clockwise of the column's first edge or not
    /// clockwise of its last; `(x, y)` lies counter-clockwise of an edge
    /// `e` when `e × (x, y) = e_x y − e_y x > 0` (a column spans less than
    /// half a turn for any width from 3 up; widths 1 and 2 are exact
    /// halves and whole turns, where the guess alone decides except on the
    /// edges themselves).
    #[inline]
    fn column_of(&self, x: f64, y: f64) -> usize {
        let width = self.width;
        let turns = atan2_approx(y, x) * (0.5 * FRAC_1_PI) - self.rotation_turns;
        // Into [0, 1]: `as i64` truncates towards zero.
        let mut fraction = turns - (turns as i64) as f64;
        if fraction < 0.0 {
            fraction += 1.0;
        }
        let mut col = ((fraction * width as f64) as usize).min(width - 1);
        if width < 3 {
            return col;
        }
        let cross = |edge: [f64; 2]| edge[0] * y - edge[1] * x;
        if cross(self.column_edges[col]) < 0.0 {
            col = if col == 0 { width - 1 } else { col - 1 };
        } else if cross(self.column_edges[col + 1]) >= 0.0 {
            col = if col + 1 == width { 0 } else { col + 1 };
        }
        col
    }

    /// Radiance from the unit world `direction`: the texel it falls in.
    pub fn radiance(&self, direction: DVec3) -> Rgb {
        match self.texel_index(direction) {
            Some((row, col)) => self.texel_radiance(Texel { row, col }),
            None => Rgb::ZERO,
        }
    }

    /// The radiance of a texel found by [`Self::prefetch_direction`].
    fn texel_radiance(&self, Texel { row, col }: Texel) -> Rgb {
        decode(self.texels[row * self.width + col], &self.scales)
    }

    /// Solid-angle density of [`Self::sample`] at `direction`: constant on
    /// each texel (see the type's documentation).
    pub fn pdf(&self, direction: DVec3) -> f64 {
        self.radiance_and_pdf(direction).1
    }

    /// [`Self::radiance`] and [`Self::pdf`] of one direction, from one
    /// texel read; equal to the separate calls.
    pub fn radiance_and_pdf(&self, direction: DVec3) -> (Rgb, f64) {
        let (radiance, pdf, _) = self.radiance_and_pdfs(direction);
        (radiance, pdf)
    }

    /// [`Self::radiance`], [`Self::pdf`] and the density of
    /// [`Self::sample_part`] of the part the direction lies in, from one
    /// texel read.
    fn radiance_and_pdfs(&self, direction: DVec3) -> (Rgb, f64, f64) {
        match self.texel_index(direction) {
            Some((row, col)) => self.texel_radiance_and_pdfs(Texel { row, col }),
            None => (Rgb::ZERO, 0.0, 0.0),
        }
    }

    /// [`Self::radiance_and_pdfs`] of a texel found by
    /// [`Self::prefetch_direction`].
    #[inline(always)]
    fn texel_radiance_and_pdfs(&self, texel: Texel) -> (Rgb, f64, f64) {
        let bits = self.texels[texel.row * self.width + texel.col];
        let radiance = decode(bits, &self.scales);
        let (whole, part) = self.texel_pdfs(texel, bits, radiance);
        (radiance, whole, part)
    }

    /// The densities at `texel`, read as `bits` (its decoded `radiance`
    /// passed in): [`Self::sample`]'s, and that of the part it is in (the
    /// hot part's when its luminance reaches the hot threshold, else its
    /// row's, [`texel_pdf`]); the first is the second times the part's
    /// share of the whole map's draws.
    #[inline(always)]
    fn texel_pdfs(&self, texel: Texel, bits: u64, radiance: Rgb) -> (f64, f64) {
        let y = luminance(radiance);
        if y >= self.hot_threshold {
            return self.hot_texel_pdfs(texel);
        }
        let part = texel_pdf(bits, y, &self.rows[texel.row]);
        (part * self.rest_share, part)
    }

    /// [`Self::texel_pdfs`] of a texel of the hot part: its probability in
    /// the part's table over its solid angle (a draw is uniform in solid
    /// angle inside it), and that times the part's share. Out of line:
    /// only directions towards the sun need it.
    #[inline(never)]
    fn hot_texel_pdfs(&self, Texel { row, col }: Texel) -> (f64, f64) {
        let Some(hot) = &self.hot else {
            return (0.0, 0.0);
        };
        let index = (row * self.width + col) as u32;
        match hot.texels.binary_search(&index) {
            Ok(i) => {
                let part = hot.table.probability(i) / self.texel_solid_angle(row);
                (part * hot.share, part)
            }
            Err(_) => (0.0, 0.0),
        }
    }

    /// The solid angle of a texel of `row`.
    fn texel_solid_angle(&self, row: usize) -> f64 {
        let band = &self.rows[row];
        TAU * (band.z_top - band.z_bottom) / self.width as f64
    }

    /// The texels sampled apart from the rest and their share of the map's
    /// power, when it has two parts (see the type's documentation): what
    /// `lapidary render` reports of a map with a sun.
    pub fn sampled_apart(&self) -> Option<(usize, f64)> {
        self.hot.as_ref().map(|hot| (hot.texels.len(), hot.share))
    }

    /// How many parts [`Self::sample_part`] draws from: 2 for a map whose
    /// brightest texels are sampled apart from the rest, else 1 (see the
    /// type's documentation).
    pub fn parts(&self) -> usize {
        1 + usize::from(self.hot.is_some())
    }

    /// Starts loading the texel [`Self::radiance_and_pdf`] reads for
    /// `direction`, for a caller who will look it up after other work (a
    /// ray that may escape, traced first), and returns it (None for a zero
    /// or non-finite direction). A hint, like [`Self::prefetch_sample`],
    /// and the texel, for the lookup.
    #[inline(never)]
    pub(crate) fn prefetch_direction(&self, direction: DVec3) -> Option<Texel> {
        let (row, col) = self.texel_index(direction)?;
        prefetch(&self.texels[row * self.width + col]);
        Some(Texel { row, col })
    }

    /// Starts loading the texel that [`Self::sample_part`] of the rows'
    /// part (and so [`Self::sample`] of a map of one part) reads first for
    /// `u` (a map larger than the caches misses on it nearly every draw), so
    /// that a caller who knows its numbers early overlaps the wait with
    /// other work. A hint: nothing observable changes.
    #[inline]
    pub(crate) fn prefetch_sample(&self, u: [f64; 2]) {
        if let Some(marginal) = self.marginal.as_ref() {
            let (row, _) = marginal.sample_bin(u[1]);
            prefetch(&self.texels[row * self.width + bucket_of_draw(u[0], self.width)]);
        }
    }

    /// Draws a direction with density ∝ luminance per solid angle; radiance
    /// and pdf are those of the returned direction (see
    /// [`Environment::sample`]): a part chosen by its share of the map's
    /// power (`u[0]` below the hot part's share picks it, the rest of
    /// `u[0]` rescaled), then [`Self::sample_part`] of it.
    pub fn sample(&self, u: [f64; 2]) -> Option<EnvironmentSample> {
        let Some(HotPart { share: hot, .. }) = self.hot else {
            return self.sample_part(0, u);
        };
        let rest = self.rest_share;
        let (part, u0, share) = if u[0] < hot {
            (1, u[0] / hot, hot)
        } else {
            (0, ((u[0] - hot) / rest).min(1.0_f64.next_down()), rest)
        };
        let sample = self.sample_part(part, [u0, u[1]])?;
        Some(EnvironmentSample {
            pdf: sample.pdf * share,
            ..sample
        })
    }

    /// Draws a direction of part `part` (0: the rows' tables; 1: the hot
    /// texels, when [`Self::parts`] is 2) with density ∝ luminance per
    /// solid angle within the part; radiance and density are those of the
    /// returned direction (see [`Environment::sample_part`]). In part 0
    /// `u[1]` picks the row and the height in it, `u[0]` the column and
    /// the azimuth in it, each by an alias table; in part 1 `u[0]` picks
    /// the texel and the azimuth in it, `u[1]` the height.
    pub fn sample_part(&self, part: usize, u: [f64; 2]) -> Option<EnvironmentSample> {
        // The part's density of the texel drawn: a row's texel is never a
        // hot one (those have weight 0 there), so each branch reads its
        // own part's density, as `texel_pdfs` would.
        let (row, col, u_within, v_within, radiance, pdf) = if part == 0 {
            let (row, v_within) = self.marginal.as_ref()?.sample_bin(u[1]);
            let texels = &self.texels[row * self.width..][..self.width];
            let (col, u_within) = draw(u[0], self.width, COLUMN_CAPACITY, |j| bucket(texels[j]));
            let bits = texels[col];
            let radiance = decode(bits, &self.scales);
            let pdf = texel_pdf(bits, luminance(radiance), &self.rows[row]);
            (row, col, u_within, v_within, radiance, pdf)
        } else {
            let hot = self.hot.as_ref().filter(|_| part == 1)?;
            let (i, u_within) = hot.table.sample_bin(u[0]);
            let index = hot.texels[i] as usize;
            let (row, col) = (index / self.width, index % self.width);
            let radiance = decode(self.texels[index], &self.scales);
            let pdf = hot.table.probability(i) / self.texel_solid_angle(row);
            (row, col, u_within, u[1], radiance, pdf)
        };
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        // Uniform in solid angle over the texel: cosθ uniform over the
        // row's band, φ uniform over the column (φ = 2π·turns + rotation).
        let band = &self.rows[row];
        let z = band.z_top - v_within * (band.z_top - band.z_bottom);
        let sin_theta = ((1.0 - z) * (1.0 + z)).max(0.0).sqrt();
        let turns = (col as f64 + u_within) / self.width as f64 + self.rotation_turns;
        let (sin_phi, cos_phi) = sin_cos_turns(turns);
        Some(EnvironmentSample {
            direction: DVec3::new(sin_theta * cos_phi, sin_theta * sin_phi, z),
            radiance,
            pdf,
        })
    }
}

/// The density of a texel read as `bits` (the `luminance` of its decoded
/// radiance passed in) in its row's table: its integer weight `⌊Y s_r⌋ +
/// extra` times the row's density per unit; the same expression at build
/// time made the weights the row's alias table samples.
#[inline]
fn texel_pdf(bits: u64, luminance: f64, row: &RowSampling) -> f64 {
    let units = floor_units(luminance, row.units_per_luminance) + ((bits >> EXTRA_UNIT_SHIFT) & 1);
    units as f64 * row.pdf_per_unit
}

/// `⌊y s⌋` for `0 ≤ y s ≤ 2²⁹` (a texel's share of its row's units): the
/// one expression both the table build and the density lookup use.
/// Through `i64`, a few instructions cheaper than `u64`'s conversion.
#[inline]
fn floor_units(y: f64, s: f64) -> u64 {
    (y * s) as i64 as u64
}

/// `s_r` for a row of `width` texels whose luminances sum to `sum > 0`: a
/// hair under `width × 2¹⁵ / sum`, so that the floors `⌊Y_i s_r⌋` sum to
/// at most the total and miss it by at most one unit per lit texel. (The
/// computed Σ Y_i s_r is within a relative 2⁻³⁸ of the exact `(1 − 2⁻³⁰)
/// × total` for rows of at most 2¹⁴ texels, so it lies below the total,
/// and above it minus half a unit, as the total is at most 2²⁹; each floor
/// loses less than one.)
fn row_units_per_luminance(sum: f64, width: usize) -> f64 {
    (width as u64 * COLUMN_CAPACITY) as f64 / sum * (1.0 - 2f64.powi(-30))
}

/// What building a row's table found: the luminance it samples, and its
/// brightest texel's.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RowLuminance {
    /// The sum of the luminances the row's table samples (0 for a row
    /// that is not to be sampled).
    sum: f64,
    /// The largest luminance of the row's texels, hot ones included.
    brightest: f64,
}

/// Fills the alias bits of one row of packed texels, its texels from
/// luminance `hot_threshold` up at weight 0 (they are sampled apart), and
/// returns the luminance its table samples, or the column of a texel
/// whose luminance (or the row's sum) overflows. A black row gets buckets
/// that keep all their units (never read: the row is never drawn).
fn build_row_table(
    row: &mut [u64],
    scales: &[f64; 64],
    hot_threshold: f64,
) -> Result<RowLuminance, usize> {
    let width = row.len();
    let mut luminances: Vec<f64> = row.iter().map(|&b| luminance(decode(b, scales))).collect();
    if let Some(col) = luminances.iter().position(|y| !y.is_finite()) {
        return Err(col);
    }
    let brightest = luminances.iter().fold(0.0, |a: f64, &y| a.max(y));
    for y in &mut luminances {
        if *y >= hot_threshold {
            *y = 0.0;
        }
    }
    let sum: f64 = luminances.iter().sum();
    if !sum.is_finite() {
        let brightest = (0..width).max_by(|&a, &b| luminances[a].total_cmp(&luminances[b]));
        return Err(brightest.unwrap_or(0));
    }
    let sampled = RowLuminance { sum, brightest };
    let total = width as u64 * COLUMN_CAPACITY;
    let weights = (sum > 0.0)
        .then(|| row_weights(&luminances, row_units_per_luminance(sum, width), total))
        .flatten();
    let Some((weights, extra)) = weights else {
        for (col, bits) in row.iter_mut().enumerate() {
            *bits = (*bits & TEXEL_MASK)
                | COLUMN_CAPACITY << THRESHOLD_SHIFT
                | (col as u64) << ALIAS_SHIFT;
        }
        // Black, or (never) weights that could not be made exact: a row
        // the marginal leaves out.
        return Ok(RowLuminance {
            sum: 0.0,
            ..sampled
        });
    };
    for (col, ((threshold, alias), bits)) in alias_table(&weights, COLUMN_CAPACITY)
        .into_iter()
        .zip(row.iter_mut())
        .enumerate()
    {
        *bits = (*bits & TEXEL_MASK)
            | threshold << THRESHOLD_SHIFT
            | u64::from(extra[col]) << EXTRA_UNIT_SHIFT
            | (alias as u64) << ALIAS_SHIFT;
    }
    Ok(sampled)
}

/// The hot part of a map whose rows were built as one part, and the
/// luminance from which a texel is in it, when the map qualifies (see
/// [`EnvironmentMap`]'s "Two parts"): texels from [`HOT_OVER_MEAN`] × the
/// mean luminance over the sphere, at most one in
/// [`HOT_MAX_TEXELS_PER`], carrying at least [`HOT_MIN_SHARE`] of the
/// power and leaving at least [`REST_MIN_SHARE`] to the rest. `z` holds
/// the rows' edge cosines.
fn hot_part(
    texels: &[u64],
    width: usize,
    z: &[f64],
    rows: &[RowLuminance],
    scales: &[f64; 64],
) -> Option<(HotPart, f64)> {
    // Power ∝ Σ Y × texel solid angle, 2π Δz / width per texel of a row.
    let texel_solid_angle = |row: usize| TAU * (z[row] - z[row + 1]) / width as f64;
    let power: f64 = (0..rows.len())
        .map(|row| rows[row].sum * texel_solid_angle(row))
        .sum();
    let threshold = HOT_OVER_MEAN * power / (4.0 * PI);
    if !(threshold > 0.0 && threshold.is_finite()) {
        return None;
    }
    let most = texels.len() / HOT_MAX_TEXELS_PER;
    let mut indices = Vec::new();
    let mut weights = Vec::new();
    for (row, _) in rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.brightest >= threshold)
    {
        for (col, &bits) in texels[row * width..][..width].iter().enumerate() {
            let y = luminance(decode(bits, scales));
            if y >= threshold {
                if indices.len() == most {
                    return None;
                }
                indices.push((row * width + col) as u32);
                weights.push(y * texel_solid_angle(row));
            }
        }
    }
    let hot_power: f64 = weights.iter().sum();
    let qualifies =
        hot_power >= HOT_MIN_SHARE * power && power - hot_power >= REST_MIN_SHARE * power;
    let table = AliasTable::new(&weights).ok().filter(|_| qualifies)?;
    Some((
        HotPart {
            texels: indices,
            table,
            share: hot_power / power,
        },
        threshold,
    ))
}

/// The integer weights `⌊Y_i s⌋ + extra_i` of a row and the extra bits:
/// one extra unit to each of the lit texels with the largest remainders,
/// as many as the floors fall short of `total`. `None` if the floors
/// overshoot the total or fall short by more than the lit texels (never,
/// see [`row_units_per_luminance`]; such a row would then not be sampled).
fn row_weights(luminances: &[f64], s: f64, total: u64) -> Option<(Vec<u64>, Vec<bool>)> {
    let mut weights: Vec<u64> = luminances.iter().map(|&y| floor_units(y, s)).collect();
    let missing = total.checked_sub(weights.iter().sum())? as usize;
    let lit: Vec<usize> = (0..luminances.len())
        .filter(|&i| luminances[i] > 0.0)
        .collect();
    if missing > lit.len() {
        return None;
    }
    let mut extra = vec![false; luminances.len()];
    if missing == lit.len() {
        // Every lit texel (a row of one colour, often): no selection.
        for &i in &lit {
            weights[i] += 1;
            extra[i] = true;
        }
    } else if missing > 0 {
        // The `missing` largest remainders, ties by column: keys (bits of
        // the remainder descending, column) in a total order, so the set
        // chosen does not depend on the selection algorithm; a remainder
        // is in [0, 1), where the order of the bits is the order of the
        // values.
        let mut keys: Vec<(u64, u32)> = lit
            .iter()
            .map(|&i| {
                let remainder = luminances[i] * s - weights[i] as f64;
                (u64::MAX - remainder.to_bits(), i as u32)
            })
            .collect();
        keys.select_nth_unstable(missing - 1);
        for &(_, i) in &keys[..missing] {
            weights[i as usize] += 1;
            extra[i as usize] = true;
        }
    }
    Some((weights, extra))
}

/// Why one texel cannot be stored.
enum BadTexel {
    /// NaN, infinite or negative.
    Invalid([f64; 3]),
    /// Above [`MAX_TEXEL_RADIANCE`].
    TooBright([f64; 3]),
}

impl BadTexel {
    /// The error for this texel at (`x`, `y`) of `origin`.
    fn into_error(self, origin: String, x: usize, y: usize) -> EnvironmentError {
        match self {
            BadTexel::Invalid(rgb) => EnvironmentError::BadTexel {
                origin,
                x,
                y,
                value: Rgb::from_array(rgb),
            },
            BadTexel::TooBright(rgb) => EnvironmentError::TooBright {
                origin,
                x,
                y,
                value: rgb[0].max(rgb[1]).max(rgb[2]),
            },
        }
    }
}

/// The radiance bits of one source texel.
fn pack_texel(rgb: [f64; 3]) -> Result<u64, BadTexel> {
    encode(rgb).ok_or_else(|| {
        if rgb.iter().all(|c| c.is_finite() && *c >= 0.0) {
            BadTexel::TooBright(rgb)
        } else {
            BadTexel::Invalid(rgb)
        }
    })
}

/// `acos(z)` for `z ∈ [−1, 1]` within 2·10⁻⁸ rad: Abramowitz & Stegun
/// 4.4.46, `√(1 − |z|)` times a polynomial of degree 7 in `|z|`, and
/// `π − acos(−z)` below 0. Only a guess of a texel's row (see
/// [`EnvironmentMap::row_of`]).
#[inline]
fn acos_approx(z: f64) -> f64 {
    const C: [f64; 8] = [
        1.570_796_305_0,
        -0.214_598_801_6,
        0.088_978_987_4,
        -0.050_174_304_6,
        0.030_891_881_0,
        -0.017_088_125_6,
        0.006_670_090_1,
        -0.001_262_491_1,
    ];
    let a = z.abs();
    let poly = C[..7].iter().rev().fold(C[7], |acc, &c| acc * a + c);
    let r = (1.0 - a).max(0.0).sqrt() * poly;
    if z < 0.0 {
        PI - r
    } else {
        r
    }
}

/// `atan2(y, x) ∈ [−π, π]` within 2·10⁻⁸ rad: Abramowitz & Stegun 4.4.49
/// (an odd polynomial of degree 17) on the octant `min/max(|x|, |y|) ≤ 1`,
/// unfolded by the signs and the larger of `|x|`, `|y|`; 0 at the origin.
/// Only a guess of a texel's column (see [`EnvironmentMap::column_of`]).
#[inline]
fn atan2_approx(y: f64, x: f64) -> f64 {
    const C: [f64; 9] = [
        1.0,
        -0.333_331_452_8,
        0.199_935_508_5,
        -0.142_088_994_4,
        0.106_562_639_3,
        -0.075_289_640_0,
        0.042_909_613_8,
        -0.016_165_736_7,
        0.002_866_225_7,
    ];
    let (ax, ay) = (x.abs(), y.abs());
    // (Finite inputs: plain comparisons, not `min`/`max`'s NaN handling.)
    let (small, large) = if ax < ay { (ax, ay) } else { (ay, ax) };
    let a = if large > 0.0 { small / large } else { 0.0 };
    let a2 = a * a;
    let mut angle = a * C[..8].iter().rev().fold(C[8], |acc, &c| acc * a2 + c);
    if ay > ax {
        angle = FRAC_PI_2 - angle;
    }
    if x < 0.0 {
        angle = PI - angle;
    }
    if y < 0.0 {
        -angle
    } else {
        angle
    }
}

#[cfg(test)]
/// `angle_rad.rem_euclid(2π)`, the angle in `[0, 2π]`, without the `fmod`
/// call when it is within one turn of zero (always for a map turned by less
/// than a turn): there the remainder is the angle itself, exactly, and a
/// negative one gets one turn added, as `rem_euclid` does.
fn wrap_to_full_turn(angle_rad: f64) -> f64 {
    if angle_rad.abs() < TAU {
        if angle_rad < 0.0 {
            angle_rad + TAU
        } else {
            angle_rad
        }
    } else {
        angle_rad.rem_euclid(TAU)
    }
}

/// Rec. 709 / sRGB luminance of linear RGB, the importance of a texel.
pub fn luminance(c: Rgb) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Unit vector of polar angle `theta` (from +z) and azimuth `phi` (from +x).
fn spherical_direction(theta: f64, phi: f64) -> DVec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    DVec3::new(st * cp, st * sp, ct)
}

// ---------------------------------------------------------------------------
// The built-in studio.
// ---------------------------------------------------------------------------

/// Radiance of the grey dome at the zenith.
const STUDIO_ZENITH: f64 = 0.25;
/// Radiance of the dome at the horizon (linear in `cosθ` up to the zenith).
const STUDIO_HORIZON: f64 = 0.10;
/// Radiance of the dark floor below the horizon.
const STUDIO_FLOOR: f64 = 0.03;

/// A rectangular soft box, a flat emitter seen from the origin: a direction
/// is inside when its gnomonic projection onto the plane facing
/// `(azimuth_deg, elevation_deg)` lies within `±tan(width_deg/2)` across and
/// `±tan(height_deg/2)` up, so its edges are straight lines in a mirror.
struct SoftBox {
    azimuth_deg: f64,
    elevation_deg: f64,
    width_deg: f64,
    height_deg: f64,
    radiance: Rgb,
}

/// The studio's lights, in map coordinates (rotation 0). "Front" is −y
/// (azimuth −90°): a camera at −y looking towards +y has −x on its left
/// and +x on its right. `rotation_deg` turns the whole set.
const STUDIO_BOXES: [SoftBox; 3] = [
    // Key: a large box high in front-left (azimuth −135°, elevation 50°),
    // 44° × 30°, radiance 12, slightly warm. Makes the main window
    // highlight on the upper left of a dome.
    SoftBox {
        azimuth_deg: -135.0,
        elevation_deg: 50.0,
        width_deg: 44.0,
        height_deg: 30.0,
        radiance: Rgb::new(12.0, 11.6, 11.0),
    },
    // Strip: a tall narrow box on the right (azimuth −15°, elevation 25°),
    // 8° × 40° (from 5° to 45° elevation), radiance 8, neutral. A thin
    // vertical rim highlight on the right flank.
    SoftBox {
        azimuth_deg: -15.0,
        elevation_deg: 25.0,
        width_deg: 8.0,
        height_deg: 40.0,
        radiance: Rgb::new(8.0, 8.0, 8.0),
    },
    // Fill: a weak wide box behind (azimuth +90°, elevation 30°), 60° × 20°,
    // radiance 2.5, slightly cool. Lifts the back edge of the stone.
    SoftBox {
        azimuth_deg: 90.0,
        elevation_deg: 30.0,
        width_deg: 60.0,
        height_deg: 20.0,
        radiance: Rgb::new(2.4, 2.5, 2.7),
    },
];

/// Radiance of the unrotated studio in direction `d` (unit, z up): a grey
/// dome from `STUDIO_HORIZON` (0.10) at the horizon to `STUDIO_ZENITH`
/// (0.25) at the zenith (linear in `cosθ`), a `STUDIO_FLOOR` (0.03) floor
/// below the horizon, and the soft boxes of `STUDIO_BOXES` (key front-left,
/// strip right, fill behind; positions, sizes and radiances are documented
/// there) replacing the dome where they are.
pub fn studio_radiance(d: DVec3) -> Rgb {
    studio_radiance_masked(&STUDIO_BOXES.map(|b| b.frame()), ALL_BOXES, d)
}

/// Bit `b` of a box mask: box `b` of `STUDIO_BOXES` is tested.
const ALL_BOXES: u8 = 0b111;

/// [`studio_radiance`] with the soft boxes' frames already worked out (in
/// the order of `STUDIO_BOXES`), testing only the boxes whose bit is set in
/// `mask`: the bake leaves out those that cannot contain `d` (see
/// [`SoftBoxFrame::mark_reachable_columns`]).
fn studio_radiance_masked(frames: &[SoftBoxFrame; 3], mask: u8, d: DVec3) -> Rgb {
    for (b, frame) in frames.iter().enumerate() {
        if mask & (1 << b) != 0 && frame.contains(d) {
            return frame.radiance;
        }
    }
    let level = if d.z >= 0.0 {
        STUDIO_HORIZON + (STUDIO_ZENITH - STUDIO_HORIZON) * d.z
    } else {
        STUDIO_FLOOR
    };
    Rgb::splat(level)
}

/// What the gnomonic test of one [`SoftBox`] needs, computed once from its
/// angles (two `sin_cos`, a normalisation and two `tan`, which per sampled
/// direction were most of the studio bake).
struct SoftBoxFrame {
    /// Unit direction of the box's centre.
    centre: DVec3,
    /// Unit horizontal axis of the box plane, z × centre normalised.
    across: DVec3,
    /// The plane's "up" axis, centre × across.
    up: DVec3,
    /// tan(width/2): the largest |across coordinate| inside the box.
    half_width_tan: f64,
    /// tan(height/2): the largest |up coordinate| inside the box.
    half_height_tan: f64,
    /// The centre's azimuth φ_c = atan2(c_y, c_x).
    centre_azimuth: f64,
    /// The centre's horizontal length √(c_x² + c_y²).
    centre_horizontal: f64,
    /// A little below the cosine of the angle from the centre to a corner,
    /// 1/√(1 + tan²(w/2) + tan²(h/2)): no direction inside the box has
    /// d·centre below it (see [`SoftBoxFrame::contains`]).
    least_inside_cosine: f64,
    /// The box's radiance.
    radiance: Rgb,
}

impl SoftBox {
    /// The box's plane and bounds (the box is never at the zenith, so
    /// z × centre is not zero).
    fn frame(&self) -> SoftBoxFrame {
        let centre = spherical_direction(
            (90.0 - self.elevation_deg).to_radians(),
            self.azimuth_deg.to_radians(),
        );
        let across = DVec3::Z.cross(centre).normalize();
        let half_width_tan = (0.5 * self.width_deg).to_radians().tan();
        let half_height_tan = (0.5 * self.height_deg).to_radians().tan();
        let corner_cosine = 1.0
            / (1.0 + half_width_tan * half_width_tan + half_height_tan * half_height_tan).sqrt();
        SoftBoxFrame {
            centre,
            across,
            up: centre.cross(across),
            half_width_tan,
            half_height_tan,
            centre_azimuth: centre.y.atan2(centre.x),
            centre_horizontal: centre.truncate().length(),
            // 10⁻⁹ covers every rounding of d (unit to 10⁻¹⁵) and of t.
            least_inside_cosine: corner_cosine - 1e-9,
            radiance: self.radiance,
        }
    }
}

impl SoftBoxFrame {
    /// Whether direction `d` sees the box: its gnomonic projection
    /// (x, y) = (d·across, d·up)/(d·centre) lies within the half-width and
    /// half-height tangents.
    ///
    /// Directions far from the box are turned away by t = d·centre alone:
    /// a unit d = t·centre + a·across + b·up has x = a/t, y = b/t and
    /// t²(1 + x² + y²) = 1, so inside the box t ≥ 1/√(1 + tan²(w/2) +
    /// tan²(h/2)). Only the answer's cost changes, never the answer.
    fn contains(&self, d: DVec3) -> bool {
        let t = d.dot(self.centre);
        if t <= 0.0 || t < self.least_inside_cosine {
            return false;
        }
        let (x, y) = (d.dot(self.across) / t, d.dot(self.up) / t);
        x.abs() <= self.half_width_tan && y.abs() <= self.half_height_tan
    }

    /// Sets `bit` in `masks[col]` for every column `col` of a `width`
    /// column map (column c spans azimuths 2πc/w to 2π(c + 1)/w) where a
    /// direction of polar sine and cosine (`sin_theta`, `cos_theta`) may be
    /// in the box.
    ///
    /// At azimuth φ, d·centre = A·cos(φ − φ_c) + B with A = sinθ·√(c_x² +
    /// c_y²), B = cosθ·c_z and φ_c the centre's azimuth; inside the box it
    /// is at least [`Self::least_inside_cosine`] (L), so cos(φ − φ_c) ≥
    /// (L − B)/A: the columns within acos((L − B)/A) of φ_c, widened by one
    /// column each side, and the bound loosened by 10⁻⁶ (far more than any
    /// rounding of d, A or B). None when even φ = φ_c falls short; all near
    /// the poles (A < 10⁻⁶). Only which boxes are tested changes, never the
    /// answer of [`SoftBoxFrame::contains`].
    fn mark_reachable_columns(&self, sin_theta: f64, cos_theta: f64, bit: u8, masks: &mut [u8]) {
        let width = masks.len() as i64;
        let along = sin_theta.abs() * self.centre_horizontal;
        let across = cos_theta * self.centre.z;
        let least = self.least_inside_cosine - 1e-9;
        if along + across < least {
            return;
        }
        let cos_limit = if along > 1e-6 {
            (least - across) / along - 1e-6
        } else {
            -1.0
        };
        if cos_limit <= -1.0 {
            masks.iter_mut().for_each(|m| *m |= bit);
            return;
        }
        let spread = cos_limit.min(1.0).acos();
        let columns_per_radian = width as f64 / TAU;
        let first = ((self.centre_azimuth - spread) * columns_per_radian).floor() as i64 - 1;
        let last = ((self.centre_azimuth + spread) * columns_per_radian).floor() as i64 + 1;
        if last - first + 1 >= width {
            masks.iter_mut().for_each(|m| *m |= bit);
            return;
        }
        for col in first..=last {
            masks[col.rem_euclid(width) as usize] |= bit;
        }
    }
}

/// Sub-samples per texel side of the studio bake (4 × 4 per texel).
const STUDIO_SUBSAMPLES: usize = 4;

/// The studio's texels on a `width × height` map (row 0 straight up), each
/// the mean of [`studio_radiance`] over a 4 × 4 grid of sub-sample
/// directions (θ = πv, φ = 2πu at the sub-sample centres), times
/// `intensity`.
///
/// Every direction is a sine and cosine of its row's θ and of its column's
/// φ, so those are computed once per sub-sample row and column (2·h·4 and
/// 2·w·4 calls instead of 4 per sub-sample: three quarters of the bake
/// was `sin_cos`), each sub-sample tests only the soft boxes its row and
/// column can reach, the texels that reach none are one value per row (the
/// dome depends on θ alone), and rows are filled in parallel. Each texel is the same
/// f64 operations in the same order as the per-sub-sample formula, so the
/// map is bit for bit the one it gave (see the environment tests).
pub fn bake_studio_texels(width: usize, height: usize, intensity: f64) -> Vec<Rgb> {
    use rayon::prelude::*;
    const SUB: usize = STUDIO_SUBSAMPLES;
    let frames = STUDIO_BOXES.map(|b| b.frame());
    // (sin φ, cos φ) of sub-sample column sx of column col, at col·SUB + sx.
    let azimuths: Vec<(f64, f64)> = (0..width * SUB)
        .map(|i| {
            let (col, sx) = (i / SUB, i % SUB);
            let u = (col as f64 + (sx as f64 + 0.5) / SUB as f64) / width as f64;
            (TAU * u).sin_cos()
        })
        .collect();
    let mut texels = vec![Rgb::ZERO; width * height];
    texels
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(row, out)| {
            // (sin θ, cos θ) of the row's sub-sample rows.
            let polar: [(f64, f64); SUB] = std::array::from_fn(|sy| {
                let v = (row as f64 + (sy as f64 + 0.5) / SUB as f64) / height as f64;
                (PI * v).sin_cos()
            });
            // Per sub-sample row and column, the boxes it may see (most
            // rows see none, the others see each box over a few columns).
            let mut masks: [Vec<u8>; SUB] = std::array::from_fn(|_| vec![0u8; width]);
            for (&(st, ct), row_masks) in polar.iter().zip(&mut masks) {
                for (b, frame) in frames.iter().enumerate() {
                    frame.mark_reachable_columns(st, ct, 1 << b, row_masks);
                }
            }
            let texel_at = |col: usize, texel_masks: [u8; SUB]| {
                let mut sum = Rgb::ZERO;
                for (&(st, ct), mask) in polar.iter().zip(texel_masks) {
                    for &(sp, cp) in &azimuths[col * SUB..(col + 1) * SUB] {
                        let d = DVec3::new(st * cp, st * sp, ct);
                        sum += studio_radiance_masked(&frames, mask, d);
                    }
                }
                sum * (intensity / (SUB * SUB) as f64)
            };
            // A texel that sees no box sees only the dome, whose level
            // depends on d.z = cosθ alone: every such texel of the row is
            // the same sum of the same terms.
            let dome_only = texel_at(0, [0; SUB]);
            for (col, texel) in out.iter_mut().enumerate() {
                let texel_masks = masks.each_ref().map(|row_masks| row_masks[col]);
                *texel = if texel_masks == [0; SUB] {
                    dome_only
                } else {
                    texel_at(col, texel_masks)
                };
            }
        });
    texels
}

// ---------------------------------------------------------------------------
// Files and checks.
// ---------------------------------------------------------------------------

fn check_intensity(intensity: f64) -> Result<(), EnvironmentError> {
    if intensity.is_finite() && intensity >= 0.0 {
        Ok(())
    } else {
        Err(EnvironmentError::Parameter {
            field: "intensity",
            value: intensity,
            allowed: "finite and ≥ 0",
        })
    }
}

fn check_rotation(rotation_deg: f64) -> Result<(), EnvironmentError> {
    if rotation_deg.is_finite() {
        Ok(())
    } else {
        Err(EnvironmentError::Parameter {
            field: "rotation_deg",
            value: rotation_deg,
            allowed: "any finite angle in degrees",
        })
    }
}

/// Refuses empty maps and maps beyond the size limit, before any texel
/// memory is allocated.
fn check_size(origin: &str, width: usize, height: usize) -> Result<(), EnvironmentError> {
    if width == 0 || height == 0 {
        return Err(EnvironmentError::Empty {
            origin: origin.to_string(),
            width,
            height,
        });
    }
    if width > MAX_MAP_WIDTH || height > MAX_MAP_HEIGHT {
        return Err(EnvironmentError::TooLarge {
            origin: origin.to_string(),
            width,
            height,
        });
    }
    Ok(())
}

/// Width, height and row-major packed texels (radiance bits only, row 0 at
/// the top) of a `.hdr` or `.exr` file.
type PackedTexels = (usize, usize, Vec<u64>);

/// Reads a map file by extension, turning every failure (a decoder panic
/// included) into an error naming the path. Texels are packed as they are
/// decoded: no full-precision copy of the image is ever held. A bad
/// texel's error reports it as in the file.
fn read_map_file(path: &Path) -> Result<PackedTexels, EnvironmentError> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let reader: fn(&Path) -> Result<PackedTexels, EnvironmentError> = match extension.as_str() {
        "hdr" => read_hdr,
        "exr" => read_exr,
        _ => {
            return Err(EnvironmentError::UnsupportedExtension {
                path: path.to_path_buf(),
                extension: if extension.is_empty() {
                    "(none)".to_string()
                } else {
                    format!(".{extension}")
                },
            })
        }
    };
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(EnvironmentError::NotFound {
                path: path.to_path_buf(),
            })
        }
        Err(e) => return Err(io_error(path, &e)),
        Ok(_) => {}
    }
    // A pipe would keep the render waiting at its opening, a device never
    // ends: neither is opened.
    if let Some(kind) = not_a_regular_file(path) {
        return Err(EnvironmentError::Io {
            path: path.to_path_buf(),
            message: format!("it is {kind}, not an image file"),
        });
    }
    check_kind(path, &extension)?;
    // Decoders of untrusted files have panicked on malformed input before;
    // a panic here must still come back as an error naming the file.
    std::panic::catch_unwind(|| reader(path)).unwrap_or_else(|_| {
        Err(EnvironmentError::Decode {
            path: path.to_path_buf(),
            format: if extension == "hdr" {
                "Radiance HDR"
            } else {
                "OpenEXR"
            },
            message: "the decoder failed on malformed data".to_string(),
        })
    })
}

/// Compares the file's first bytes with what its extension (`hdr` or
/// `exr`) promises, so that a renamed PNG, or an EXR named `.hdr`, is
/// named as what it is rather than reported by a decoder's "signature not
/// found".
fn check_kind(path: &Path, extension: &str) -> Result<(), EnvironmentError> {
    const CONVERT: &str = "allowed: .hdr (Radiance RGBE) or .exr (OpenEXR), \
        equirectangular (convert it to one of them)";
    let mut start = [0u8; 8];
    let read = File::open(path)
        .and_then(|mut f| {
            let mut n = 0;
            while n < start.len() {
                match f.read(&mut start[n..])? {
                    0 => break,
                    k => n += k,
                }
            }
            Ok(n)
        })
        .map_err(|e| io_error(path, &e))?;
    let start = &start[..read];
    let (format, wanted) = if extension == "hdr" {
        ("Radiance HDR", FileKind::RadianceHdr)
    } else {
        ("OpenEXR", FileKind::OpenExr)
    };
    let kind = FileKind::of(start);
    if kind == Some(wanted) {
        return Ok(());
    }
    let (found, advice) = match kind {
        Some(kind) => (
            format!("it is {}, not {format}", kind.name()),
            match kind {
                FileKind::RadianceHdr => "name it .hdr",
                FileKind::OpenExr => "name it .exr",
                _ => CONVERT,
            },
        ),
        None if start.is_empty() => ("the file is empty".to_string(), CONVERT),
        None => (
            format!(
                "it does not begin as {format} does ({}): another kind of file, or damaged",
                if extension == "hdr" {
                    "`#?RADIANCE`"
                } else {
                    "bytes 76 2f 31 01"
                }
            ),
            CONVERT,
        ),
    };
    Err(EnvironmentError::WrongKind {
        path: path.to_path_buf(),
        found,
        advice,
    })
}

/// A read's failure in words; the end of the file met early is said so.
fn read_failure(e: &std::io::Error) -> String {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        "the file ends early (cut short?)".to_string()
    } else {
        e.to_string()
    }
}

fn io_error(path: &Path, e: &std::io::Error) -> EnvironmentError {
    EnvironmentError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Radiance RGBE: the header (and its size check) through the `image`
/// crate, then the scanlines read here one at a time and packed, since
/// `image` 0.25 decodes only into a whole-image `f32` buffer (12 bytes a
/// texel). A texel is `m × 2^(e − 136)` as `image` reads it (0 for `e = 0`).
fn read_hdr(path: &Path) -> Result<PackedTexels, EnvironmentError> {
    let decode_error = |message: String| EnvironmentError::Decode {
        path: path.to_path_buf(),
        format: "Radiance HDR",
        message,
    };
    let file = File::open(path).map_err(|e| io_error(path, &e))?;
    let mut reader = BufReader::new(file);
    let (width, height) = {
        use image::ImageDecoder;
        let header = image::codecs::hdr::HdrDecoder::new(&mut reader).map_err(|e| match e {
            image::ImageError::IoError(io) => {
                decode_error(format!("its header: {}", read_failure(&io)))
            }
            other => decode_error(other.to_string()),
        })?;
        let (w, h) = header.dimensions();
        (w as usize, h as usize)
    };
    let origin = path.display().to_string();
    check_size(&origin, width, height)?;
    let mut texels = Vec::with_capacity(width * height);
    let mut line = vec![[0u8; 4]; width];
    for y in 0..height {
        read_rgbe_scanline(&mut reader, &mut line)
            .map_err(|why| decode_error(format!("scanline {} of {height}: {why}", y + 1)))?;
        for (x, &[r, g, b, e]) in line.iter().enumerate() {
            let scale = if e == 0 {
                0.0
            } else {
                2f64.powi(i32::from(e) - 136)
            };
            let rgb = [r, g, b].map(|m| f64::from(m) * scale);
            texels.push(pack_texel(rgb).map_err(|bad| bad.into_error(origin.clone(), x, y))?);
        }
    }
    Ok((width, height, texels))
}

/// One scanline of RGBE pixels, in the new (per-component run-length) or
/// the old (run-marker) encoding, as `image` 0.25 reads them.
fn read_rgbe_scanline(r: &mut impl Read, line: &mut [[u8; 4]]) -> Result<(), String> {
    let width = line.len();
    let byte = |r: &mut dyn Read| {
        let mut b = [0u8];
        r.read_exact(&mut b)
            .map(|_| b[0])
            .map_err(|e| read_failure(&e))
    };
    let too_long = |end: usize| format!("a run reaches column {end} of a {width}-texel scanline");
    let mut first = [0u8; 4];
    r.read_exact(&mut first).map_err(|e| read_failure(&e))?;
    if first[0] == 2 && first[1] == 2 && first[2] < 128 {
        for component in 0..4 {
            let mut x = 0;
            while x < width {
                let count = byte(r)?;
                if count <= 128 {
                    let end = x + usize::from(count);
                    if end > width {
                        return Err(too_long(end));
                    }
                    let mut values = [0u8; 128];
                    let values = &mut values[..usize::from(count)];
                    r.read_exact(values).map_err(|e| read_failure(&e))?;
                    for (pixel, &v) in line[x..end].iter_mut().zip(values.iter()) {
                        pixel[component] = v;
                    }
                    x = end;
                } else {
                    let end = x + usize::from(count - 128);
                    if end > width {
                        return Err(too_long(end));
                    }
                    let v = byte(r)?;
                    line[x..end]
                        .iter_mut()
                        .for_each(|pixel| pixel[component] = v);
                    x = end;
                }
            }
        }
        return Ok(());
    }
    // The old encoding: (1, 1, 1, n) repeats the previous pixel n times,
    // consecutive markers scaling by 256 each.
    let is_marker = |p: [u8; 4]| p[..3] == [1, 1, 1];
    if is_marker(first) {
        return Err("the scanline starts with a run-length marker".to_string());
    }
    line[0] = first;
    let (mut x, mut multiplier, mut previous) = (1usize, 1usize, first);
    while x < width {
        let mut pixel = [0u8; 4];
        r.read_exact(&mut pixel).map_err(|e| read_failure(&e))?;
        if is_marker(pixel) {
            let end = x.saturating_add(usize::from(pixel[3]).saturating_mul(multiplier));
            multiplier = multiplier.saturating_mul(256);
            if end > width {
                return Err(too_long(end));
            }
            line[x..end].fill(previous);
            x = end;
        } else {
            multiplier = 1;
            previous = pixel;
            line[x] = pixel;
            x += 1;
        }
    }
    Ok(())
}

/// OpenEXR through the `exr` crate: the first layer with R, G and B
/// channels, largest resolution level; its size is checked from the header
/// before the texels are decoded, and each texel is packed as the decoder
/// delivers it (into its place, whatever the file's block order).
fn read_exr(path: &Path) -> Result<PackedTexels, EnvironmentError> {
    let decode_error = |message: String| EnvironmentError::Decode {
        path: path.to_path_buf(),
        format: "OpenEXR",
        message,
    };
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| match e {
        exr::error::Error::Io(io) => io_error(path, &io),
        other => decode_error(other.to_string()),
    })?;
    let has =
        |h: &exr::meta::header::Header, name: &str| h.channels.list.iter().any(|c| c.name.eq(name));
    let header = meta
        .headers
        .iter()
        .find(|h| has(h, "R") && has(h, "G") && has(h, "B"))
        .ok_or_else(|| EnvironmentError::NotColour {
            path: path.to_path_buf(),
            channels: meta
                .headers
                .iter()
                .flat_map(|h| h.channels.list.iter().map(|c| c.name.to_string()))
                .collect::<Vec<_>>()
                .join(", "),
        })?;
    let (width, height) = (header.layer_size.width(), header.layer_size.height());
    let origin = path.display().to_string();
    check_size(&origin, width, height)?;
    /// The texels so far, the first (row-major) that cannot be stored, a
    /// bit per texel delivered (a damaged file's blocks may repeat a part
    /// of the image and leave another out: its offset table points twice
    /// at one block) and the first texel delivered twice.
    struct Packing {
        width: usize,
        texels: Vec<u64>,
        first_bad: Option<(usize, BadTexel)>,
        delivered: Vec<u64>,
        first_repeated: Option<usize>,
    }
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| Packing {
            width: size.width(),
            texels: vec![0; size.area()],
            first_bad: None,
            delivered: vec![0; size.area().div_ceil(64)],
            first_repeated: None,
        },
        |packing: &mut Packing, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = pos.y() * packing.width + pos.x();
            let (word, bit) = (i / 64, 1u64 << (i % 64));
            if packing.delivered[word] & bit != 0 && packing.first_repeated.is_none() {
                packing.first_repeated = Some(i);
            }
            packing.delivered[word] |= bit;
            match pack_texel([r, g, b].map(f64::from)) {
                Ok(bits) => packing.texels[i] = bits,
                Err(bad) => {
                    if packing.first_bad.as_ref().is_none_or(|(j, _)| i < *j) {
                        packing.first_bad = Some((i, bad));
                    }
                }
            }
        },
    )
    .map_err(|e| match e {
        exr::error::Error::Io(io) => decode_error(read_failure(&io)),
        // What the `exr` crate says of a file cut short.
        exr::error::Error::Invalid(why) if why.contains("missing bytes") => {
            decode_error("the file ends early (cut short?)".to_string())
        }
        other => decode_error(other.to_string()),
    })?;
    let packing = image.layer_data.channel_data.pixels;
    let row_of = |i: usize| i / packing.width.max(1);
    if let Some(i) = packing.first_repeated {
        return Err(decode_error(format!(
            "row {} is stored twice (a damaged offset table?)",
            row_of(i)
        )));
    }
    let delivered: usize = packing
        .delivered
        .iter()
        .map(|w| w.count_ones() as usize)
        .sum();
    if delivered != packing.texels.len() {
        let missing = (0..packing.texels.len())
            .find(|&i| packing.delivered[i / 64] & (1 << (i % 64)) == 0)
            .unwrap_or(0);
        return Err(decode_error(format!(
            "row {} is missing from the file (a damaged offset table?)",
            row_of(missing)
        )));
    }
    if let Some((i, bad)) = packing.first_bad {
        let x = i % packing.width.max(1);
        return Err(bad.into_error(origin, x, row_of(i)));
    }
    let w = packing.width;
    let h = packing.texels.len().checked_div(w).unwrap_or(0);
    if (w, h) != (width, height) {
        return Err(decode_error(format!(
            "the header says {width}×{height} but the first RGB layer is {w}×{h}"
        )));
    }
    Ok((width, height, packing.texels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn wrapping_to_a_full_turn_equals_rem_euclid_bit_for_bit() {
        let mut rng = Rng::new(41, 42);
        let mut angles = vec![
            0.0,
            -0.0,
            TAU,
            -TAU,
            TAU.next_down(),
            TAU.next_up(),
            (-TAU).next_up(),
            (-TAU).next_down(),
            PI,
            -PI,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            -1e-300,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e20,
            -1e20,
        ];
        // atan2's range shifted by rotations of up to several turns.
        angles.extend((0..50_000).map(|_| (rng.next_f64() - 0.5) * 8.0 * TAU));
        angles.extend((0..10_000).map(|_| (rng.next_f64() - 0.5) * 1e-12));
        for a in angles {
            assert_eq!(
                wrap_to_full_turn(a).to_bits(),
                a.rem_euclid(TAU).to_bits(),
                "angle {a}"
            );
        }
    }

    #[test]
    fn prefetching_any_numbers_or_direction_stays_inside_the_map_and_finds_the_lookup_s_texel() {
        let black = EnvironmentMap::new(4, 2, vec![Rgb::ZERO; 8], 0.0).unwrap();
        let lit = grey_map(5, 3, 33.0);
        let numbers = [
            0.0,
            1.0,
            1.0_f64.next_down(),
            -1.0,
            7.0,
            f64::NAN,
            f64::INFINITY,
        ];
        let directions = [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            DVec3::ZERO,
            DVec3::splat(f64::NAN),
            DVec3::new(1e-300, 0.0, -1.0),
        ];
        // Every texel its own radiance, so that a wrong texel shows.
        let varied = (0..35)
            .map(|i| Rgb::new(0.1 + 0.05 * f64::from(i), 0.2, 0.3))
            .collect();
        let varied = EnvironmentMap::new(7, 5, varied, 20.0).unwrap();
        for map in [black, lit, varied] {
            for a in numbers {
                for b in numbers {
                    map.prefetch_sample([a, b]);
                }
            }
            let environment = Environment::Map(map);
            let mut rng = crate::sampling::Rng::new(6, 1);
            let random = (0..2000).map(|_| {
                let [u, v, w] = rng.next_3();
                DVec3::new(u - 0.5, v - 0.5, w - 0.5).normalize()
            });
            for d in directions.into_iter().chain(random) {
                // The texel the prefetch found reads what a lookup reads.
                let texel = environment.prefetch_direction(d);
                let (radiance, pdf) = environment.radiance_and_pdf(d);
                let expected = (radiance, pdf, environment.part_pdf(d));
                assert_eq!(environment.radiance_and_pdfs_in(d, texel), expected);
                assert_eq!(environment.radiance_and_pdfs_in(d, None), expected);
                assert_eq!(environment.radiance_in(d, texel), radiance);
            }
        }
    }

    /// A map of `width × height` texels of one colour each (their
    /// radiance does not matter to where a direction falls).
    fn grey_map(width: usize, height: usize, rotation_deg: f64) -> EnvironmentMap {
        EnvironmentMap::new(width, height, vec![Rgb::ONE; width * height], rotation_deg).unwrap()
    }

    #[test]
    fn texel_index_without_acos_or_atan2_is_the_reference_texel() {
        // The polynomial guesses corrected by the texel edges against
        // ⌊acos(z) H/π⌋ and ⌊φ_map W/2π⌋: the same texel everywhere but
        // within rounding of an edge (where either answer is the measure-
        // zero boundary), over sizes from 1 to the largest, rotations of
        // several turns either way, the poles and the axes.
        let mut rng = Rng::new(43, 44);
        let sizes = [
            (1, 1),
            (2, 1),
            (3, 2),
            (4, 2),
            (7, 5),
            (64, 32),
            (2048, 1024),
            (16384, 3),
            (3, 8192),
        ];
        let mut checked = 0;
        for (width, height) in sizes {
            for rotation_deg in [0.0, 37.5, -200.0, 725.0, -1000.25] {
                let map = grey_map(width, height, rotation_deg);
                let mut directions = vec![
                    DVec3::Z,
                    -DVec3::Z,
                    DVec3::X,
                    -DVec3::X,
                    DVec3::Y,
                    -DVec3::Y,
                    DVec3::new(1.0, 1.0, 0.0),
                ];
                directions.extend((0..20_000).map(|_| {
                    let [a, b, c] = rng.next_3();
                    DVec3::new(a - 0.5, b - 0.5, c - 0.5)
                }));
                for d in directions {
                    let uv = map.direction_to_uv(d).unwrap();
                    let (x, y) = (uv.x * width as f64, uv.y * height as f64);
                    let reference = ((y as usize).min(height - 1), (x as usize).min(width - 1));
                    let fast = map.texel_index(d).unwrap();
                    let near_edge = |s: f64| (s - s.round()).abs() < 1e-9 * s.abs().max(1.0);
                    let at_pole = d.x == 0.0 && d.y == 0.0;
                    if fast.0 != reference.0 {
                        assert!(
                            near_edge(y),
                            "{d} {width}×{height}: row {fast:?} {reference:?}"
                        );
                    }
                    if fast.1 != reference.1 {
                        let wrapped = x == 0.0 || near_edge(x);
                        assert!(
                            at_pole || wrapped,
                            "{d} {width}×{height}: {fast:?} {reference:?}"
                        );
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked > 500_000);
        let map = grey_map(8, 4, 0.0);
        assert_eq!(map.texel_index(DVec3::ZERO), None);
        assert_eq!(map.texel_index(DVec3::new(f64::NAN, 0.0, 1.0)), None);
    }

    #[test]
    fn acos_and_atan2_guesses_are_within_their_bounds() {
        let mut rng = Rng::new(45, 46);
        for _ in 0..200_000 {
            let z = 2.0 * rng.next_f64() - 1.0;
            assert!((acos_approx(z) - z.acos()).abs() < 2.5e-8, "acos {z}");
            let [a, b] = [rng.next_f64() - 0.5, rng.next_f64() - 0.5];
            assert!(
                (atan2_approx(b, a) - b.atan2(a)).abs() < 2.5e-8,
                "atan2 {b} {a}"
            );
        }
        for z in [-1.0, 1.0, 0.0, -0.0] {
            assert!((acos_approx(z) - z.acos()).abs() < 2.5e-8);
        }
        assert_eq!(atan2_approx(0.0, 0.0), 0.0);
    }
}
