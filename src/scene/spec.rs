//! The RON schema of a scene: plain serde data with units as written.
//!
//! ```ron
//! Scene(
//!     camera: Orbit(target: (0.0, 0.0, 1.0), distance: 45.0, elevation_deg: 35.0, azimuth_deg: -60.0, vertical_fov_deg: 22.0),
//!     stones: [
//!         Stone(
//!             recipe: Some("lavender-lepidolite"),
//!             shape: Cabochon(outline: Oval, length: 10.0, width: 8.0),
//!             position: (0.0, 0.0, 0.5),
//!         ),
//!     ],
//!     ground: Some(Ground(height: 0.0, material: "teflon")),
//!     lights: [Sphere(centre: (-4.0, -14.0, 21.0), radius: 1.5, radiance: (300.0, 300.0, 300.0))],
//!     environment: Studio(intensity: 1.0, rotation_deg: 0.0),
//! )
//! ```
//!
//! Every number is range-checked while parsing, so a bad value is reported
//! at its own `file:line:col` with the field's name and allowed range (the
//! same messages as `ranges`). The shape's numbers are
//! checked by [`crate::geometry::Cabochon::new`] when the scene is compiled
//! ([`super::compile`]), the rules between fields (camera position ≠
//! look_at, 1 to 1024 stones) there too.
//!
//! World space: z is up, lengths in scene units (millimetres, like the gem
//! recipes' object space).

use crate::message::number;
use crate::recipe::ranges::{checked, checked_rgb, whole_in};
use serde::{Deserialize, Deserializer};

/// A whole scene file as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Scene", deny_unknown_fields)]
pub struct SceneSpec {
    /// Where the picture is taken from.
    pub camera: CameraSpec,
    /// The stones, 1 to `MAX_STONES`.
    pub stones: Vec<StoneSpec>,
    /// A horizontal ground plane under the stones (default: none).
    #[serde(default)]
    pub ground: Option<GroundSpec>,
    /// Lights besides the environment (default: none).
    #[serde(default)]
    pub lights: Vec<LightKind>,
    /// What rays that leave the scene see (default: `Studio(intensity: 1.0)`).
    #[serde(default = "studio")]
    pub environment: EnvironmentKind,
    /// Render a turntable of this many frames instead of one still
    /// (default: none; `lapidary render --frames` overrides it).
    #[serde(default)]
    pub turntable: Option<TurntableSpec>,
}

/// A turntable: `frames` pictures evenly over a full turn.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Turntable", deny_unknown_fields)]
pub struct TurntableSpec {
    /// Frames of the full turn, 1 to `MAX_FRAMES`.
    #[serde(deserialize_with = "frames")]
    pub frames: u32,
    /// What turns (default: the stones).
    #[serde(default)]
    pub turn: TurnSpec,
}

/// What a turntable turns.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename = "Turn", deny_unknown_fields)]
pub enum TurnSpec {
    /// Every stone about the vertical through its own origin; the camera,
    /// lights and environment stay.
    #[default]
    Stone,
    /// The camera about the vertical through the point it looks at; the
    /// stones, lights and environment stay.
    Camera,
}

/// Most frames a turntable may have (one a tenth of a degree).
pub const MAX_FRAMES: u32 = 3600;

/// Deserialize `frames`, allowed 1 to [`MAX_FRAMES`].
fn frames<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    whole_in(d, "frames", 1, MAX_FRAMES)
}

fn studio() -> EnvironmentKind {
    EnvironmentKind::Studio {
        intensity: 1.0,
        rotation_deg: 0.0,
    }
}
fn one() -> f64 {
    1.0
}
fn two() -> f64 {
    2.0
}
fn half() -> f64 {
    0.5
}
fn four() -> f64 {
    4.0
}

/// The camera, either orbiting a target or placed explicitly (world z up).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Camera", deny_unknown_fields)]
pub enum CameraSpec {
    /// On a sphere around `target`: `position = target + distance ·
    /// (cos e cos a, cos e sin a, sin e)` with elevation e above the xy plane
    /// and azimuth a counter-clockwise from +x seen from above.
    Orbit {
        /// The point looked at.
        #[serde(deserialize_with = "target")]
        target: [f64; 3],
        /// Distance from the target, > 0.
        #[serde(deserialize_with = "distance")]
        distance: f64,
        /// Elevation above the target's horizontal plane, −90 to 90 degrees.
        #[serde(deserialize_with = "elevation_deg")]
        elevation_deg: f64,
        /// Azimuth counter-clockwise from +x seen from above, degrees.
        #[serde(deserialize_with = "azimuth_deg")]
        azimuth_deg: f64,
        /// Full vertical field of view, (0, 170) degrees.
        #[serde(deserialize_with = "vertical_fov_deg")]
        vertical_fov_deg: f64,
    },
    /// At `position`, looking at `look_at`.
    LookAt {
        /// The eye.
        #[serde(deserialize_with = "position")]
        position: [f64; 3],
        /// The point looked at (≠ position).
        #[serde(deserialize_with = "look_at")]
        look_at: [f64; 3],
        /// Full vertical field of view, (0, 170) degrees.
        #[serde(deserialize_with = "vertical_fov_deg")]
        vertical_fov_deg: f64,
    },
}

/// One stone: which gem, which shape, where.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Stone", deny_unknown_fields)]
pub struct StoneSpec {
    /// `None`: the gem named on the command line; `Some(name)`: a built-in
    /// gem, or a `.ron` gem file (a path with `/` or ending in `.ron`,
    /// relative to the scene file).
    #[serde(default)]
    pub recipe: Option<String>,
    /// The stone's geometry.
    pub shape: ShapeSpec,
    /// Where the object-space origin (the centre of the girdle plane) goes
    /// (default the world origin).
    #[serde(default, deserialize_with = "position")]
    pub position: [f64; 3],
    /// Euler angles about the world x, then y, then z axes, degrees
    /// (default none).
    #[serde(default, deserialize_with = "rotation_deg")]
    pub rotation_deg: [f64; 3],
    /// `None`: the gem's own seed; `Some(n)` replaces it, so two stones of
    /// one gem look different.
    #[serde(default, deserialize_with = "crate::recipe::ranges::optional_seed")]
    pub seed: Option<u64>,
}

/// A stone's geometry; one kind for now.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Shape", deny_unknown_fields)]
pub enum ShapeSpec {
    /// A cabochon ([`crate::geometry::CabochonParams`]); every field but
    /// `outline`, `length` and `width` defaults to
    /// `CabochonParams::default()`. Ranges are checked by
    /// [`crate::geometry::Cabochon::new`].
    Cabochon {
        /// The girdle's shape seen from above.
        outline: OutlineSpec,
        /// Extent along object x, > 0.
        length: f64,
        /// Extent along object y, > 0.
        width: f64,
        /// Dome height above the girdle plane, > 0 (default 4).
        #[serde(default = "four")]
        dome_height: f64,
        /// Dome profile exponent p, in (1, 16] (default 2: elliptical).
        #[serde(default = "two")]
        profile_exponent: f64,
        /// Height of the vertical girdle band, ≥ 0 (default 0.5).
        #[serde(default = "half")]
        girdle_height: f64,
        /// Flat or domed back (default `Flat`).
        #[serde(default)]
        base: BaseSpec,
        /// `Some(f)`: the dome polished flat inside the outline scaled by f
        /// in (0, 1); `None` (default): a full dome.
        #[serde(default)]
        buff_top: Option<f64>,
    },
}

/// The girdle outline ([`crate::geometry::Outline`]).
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(rename = "Outline", deny_unknown_fields)]
pub enum OutlineSpec {
    /// A circle (length = width).
    Round,
    /// An ellipse.
    Oval,
    /// A superellipse with exponent in (2, 16].
    Cushion {
        /// The superellipse exponent n.
        exponent: f64,
    },
    /// A teardrop pointing to +x (length > width).
    Pear,
    /// A lens pointed at ±x (length > width).
    Marquise,
}

/// The stone's back ([`crate::geometry::Base`]).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(rename = "Base", deny_unknown_fields)]
pub enum BaseSpec {
    /// A flat polished back.
    #[default]
    Flat,
    /// A second dome below the girdle band (a double cabochon).
    Domed {
        /// Depth of the lower dome, > 0.
        height: f64,
    },
}

/// A horizontal ground plane.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Ground", deny_unknown_fields)]
pub struct GroundSpec {
    /// Its z, any finite number.
    #[serde(deserialize_with = "height")]
    pub height: f64,
    /// A built-in material name, or a material `.ron` file (a path with `/`
    /// or ending in `.ron`, relative to the scene file).
    pub material: String,
}

/// A light as written (radiance in W·sr⁻¹·m⁻² per channel, scene units).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Light", deny_unknown_fields)]
pub enum LightKind {
    /// A uniformly emitting sphere.
    Sphere {
        /// Its centre.
        #[serde(deserialize_with = "centre")]
        centre: [f64; 3],
        /// Radius, > 0.
        #[serde(deserialize_with = "radius")]
        radius: f64,
        /// Emitted radiance, ≥ 0 per channel.
        #[serde(deserialize_with = "radiance")]
        radiance: [f64; 3],
    },
    /// An isotropic point light; irradiance falls off as intensity / d².
    Point {
        /// Its position.
        #[serde(deserialize_with = "position")]
        position: [f64; 3],
        /// Radiant intensity (W/sr-like), ≥ 0 per channel.
        #[serde(deserialize_with = "intensity_rgb")]
        intensity: [f64; 3],
    },
    /// A one-sided rectangular soft box facing `aim_at`.
    Rect {
        /// Its centre.
        #[serde(deserialize_with = "centre")]
        centre: [f64; 3],
        /// The point its emitting side faces (≠ centre).
        #[serde(deserialize_with = "aim_at")]
        aim_at: [f64; 3],
        /// Extent along its horizontal axis, > 0.
        #[serde(deserialize_with = "width")]
        width: f64,
        /// Extent along its other axis, > 0.
        #[serde(deserialize_with = "height_size")]
        height: f64,
        /// Emitted radiance, ≥ 0 per channel.
        #[serde(deserialize_with = "radiance")]
        radiance: [f64; 3],
    },
    /// A distant disc (the sun): parallel light from one direction.
    Sun {
        /// Elevation above the horizon, −90 to 90 degrees.
        #[serde(deserialize_with = "elevation_deg")]
        elevation_deg: f64,
        /// Azimuth counter-clockwise from +x seen from above, degrees.
        #[serde(deserialize_with = "azimuth_deg")]
        azimuth_deg: f64,
        /// Apparent diameter, (0, 20] degrees (the real sun: 0.53).
        #[serde(default = "sun_diameter", deserialize_with = "angular_diameter_deg")]
        angular_diameter_deg: f64,
        /// Irradiance on a surface facing the sun, ≥ 0 per channel.
        #[serde(deserialize_with = "irradiance")]
        irradiance: [f64; 3],
    },
}

fn sun_diameter() -> f64 {
    0.53
}

/// The environment as written.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Environment", deny_unknown_fields)]
pub enum EnvironmentKind {
    /// The same radiance in every direction.
    Constant {
        /// Radiance, ≥ 0 per channel.
        #[serde(deserialize_with = "radiance")]
        radiance: [f64; 3],
    },
    /// The renderer's built-in studio (soft boxes over a dark floor).
    Studio {
        /// Multiplier, 0 to 10⁶ (default 1).
        #[serde(default = "one", deserialize_with = "intensity")]
        intensity: f64,
        /// Turn about world z, degrees (default 0).
        #[serde(default, deserialize_with = "rotation_about_z_deg")]
        rotation_deg: f64,
    },
    /// An HDR/EXR environment map (latitude-longitude).
    File {
        /// The image, relative to the scene file.
        path: String,
        /// Turn about world z, degrees (default 0).
        #[serde(default, deserialize_with = "rotation_about_z_deg")]
        rotation_deg: f64,
        /// Multiplier, 0 to 10⁶ (default 1).
        #[serde(default = "one", deserialize_with = "intensity")]
        intensity: f64,
    },
}

// ---- Range-checked fields (messages as in `recipe::ranges`) -------------

/// The largest multiplier of an environment: far beyond any exposure a
/// scene needs, and small enough that the brightest studio texel times it
/// stays within what an environment map stores.
pub(crate) const MAX_ENVIRONMENT_INTENSITY: f64 = 1e6;

/// The largest radiance, intensity or irradiance of a light (per
/// channel): a 0.01 mm sphere 100 m away at this radiance still gives
/// finite samples, where 1e308 overflowed to infinity and its samples
/// were dropped from the image. Far above any exposure a scene needs.
pub(crate) const MAX_EMISSION: f64 = 1e12;

/// Largest coordinate of a point in a scene, mm (100 m). The stones' BVH
/// is built in f32 (obvhs), where 1e300 is infinite and its build panics;
/// and a light's solid angle from this far stays representable.
pub const MAX_COORDINATE_MM: f64 = 1e5;

/// A point or vector: three finite numbers, each within ±`max_abs`.
fn finite_vec3<'de, D: Deserializer<'de>>(
    d: D,
    field: &str,
    max_abs: f64,
) -> Result<[f64; 3], D::Error> {
    let v = <(f64, f64, f64)>::deserialize(d)?;
    if [v.0, v.1, v.2]
        .iter()
        .any(|c| !c.is_finite() || c.abs() > max_abs)
    {
        let allowed = if max_abs == f64::MAX {
            "three finite numbers (x, y, z)".to_string()
        } else {
            format!("three finite numbers (x, y, z) within ±{max_abs} (mm)")
        };
        return crate::recipe::ranges::refuse(
            [v.0, v.1, v.2],
            format!(
                "`{field}` = ({}, {}, {}) is out of range; allowed: {allowed}",
                number(v.0),
                number(v.1),
                number(v.2)
            ),
        );
    }
    Ok([v.0, v.1, v.2])
}

macro_rules! vec3_field {
    ($name:ident, $field:literal, $max_abs:expr) => {
        #[doc = concat!("Deserialize `", $field, "`: three finite numbers within ±", stringify!($max_abs), ".")]
        fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
            finite_vec3(d, $field, $max_abs)
        }
    };
}

macro_rules! scalar_field {
    ($name:ident, $field:literal, $allowed:literal, $ok:expr) => {
        #[doc = concat!("Deserialize `", $field, "`, allowed: ", $allowed, ".")]
        fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
            checked(d, $field, $allowed, $ok)
        }
    };
}

macro_rules! rgb_field {
    ($name:ident, $field:literal, $allowed:literal, $ok:expr) => {
        #[doc = concat!("Deserialize RGB `", $field, "`, allowed: ", $allowed, " per channel.")]
        fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
            checked_rgb(d, $field, $allowed, $ok)
        }
    };
}

vec3_field!(target, "target", MAX_COORDINATE_MM);
vec3_field!(position, "position", MAX_COORDINATE_MM);
vec3_field!(look_at, "look_at", MAX_COORDINATE_MM);
vec3_field!(centre, "centre", MAX_COORDINATE_MM);
vec3_field!(aim_at, "aim_at", MAX_COORDINATE_MM);
vec3_field!(rotation_deg, "rotation_deg", f64::MAX);

scalar_field!(distance, "distance", "0 < distance <= 100000 (mm)", |v| v
    > 0.0
    && v <= MAX_COORDINATE_MM);
scalar_field!(
    elevation_deg,
    "elevation_deg",
    "-90 <= elevation_deg <= 90 (degrees)",
    |v| (-90.0..=90.0).contains(&v)
);
scalar_field!(
    azimuth_deg,
    "azimuth_deg",
    "any finite azimuth_deg (degrees)",
    |_| true
);
scalar_field!(
    vertical_fov_deg,
    "vertical_fov_deg",
    "0 < vertical_fov_deg < 170 (degrees)",
    |v| v > 0.0 && v < 170.0
);
scalar_field!(height, "height", "-100000 <= height <= 100000 (mm)", |v| v
    .abs()
    <= MAX_COORDINATE_MM);
/// The smallest size of a light (a sphere's radius, a soft box's side),
/// mm, and of a sun's angular diameter, degrees (see the fields below).
pub(crate) const MIN_LIGHT_SIZE: f64 = 0.01;

// A sphere light smaller than 0.01 mm subtends too small a cone from far
// away for its pdf 1 / (2π (1 − cos θmax)) to stay finite.
scalar_field!(
    radius,
    "radius",
    "radius > 0 (mm), from 0.01 to 100000",
    |v| (MIN_LIGHT_SIZE..=MAX_COORDINATE_MM).contains(&v)
);
// A soft box below 0.01 mm has an area pdf d² / (cos · w · h) that overflows.
scalar_field!(width, "width", "width > 0 (mm), from 0.01 to 100000", |v| {
    (MIN_LIGHT_SIZE..=MAX_COORDINATE_MM).contains(&v)
});
scalar_field!(
    height_size,
    "height",
    "height > 0 (mm), from 0.01 to 100000",
    |v| (MIN_LIGHT_SIZE..=MAX_COORDINATE_MM).contains(&v)
);
scalar_field!(
    angular_diameter_deg,
    "angular_diameter_deg",
    "0 < angular_diameter_deg <= 20 (degrees), at least 0.01",
    |v| (MIN_LIGHT_SIZE..=20.0).contains(&v)
);
scalar_field!(intensity, "intensity", "0 <= intensity <= 1000000", |v| {
    (0.0..=MAX_ENVIRONMENT_INTENSITY).contains(&v)
});
scalar_field!(
    rotation_about_z_deg,
    "rotation_deg",
    "any finite rotation_deg (degrees)",
    |_| true
);
rgb_field!(radiance, "radiance", "0 <= radiance <= 1e12", |v| (0.0
    ..=MAX_EMISSION)
    .contains(&v));
rgb_field!(intensity_rgb, "intensity", "0 <= intensity <= 1e12", |v| {
    (0.0..=MAX_EMISSION).contains(&v)
});
rgb_field!(irradiance, "irradiance", "0 <= irradiance <= 1e12", |v| {
    (0.0..=MAX_EMISSION).contains(&v)
});
