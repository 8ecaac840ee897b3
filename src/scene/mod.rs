//! Scenes: a camera, stones placed in the world, a ground plane, lights and
//! an environment (the files of `lapidary render --scene SCENE.ron`, or
//! built in code).
//!
//! A scene file ([`spec`], units as written) is parsed and validated into
//! the plain data below ([`compile`]): angles become directions and
//! quaternions, relative paths are resolved against the scene file's
//! folder, the gems, materials and environment image it names exist, and
//! each stone's shape has passed [`crate::geometry::Cabochon::new`]. Errors
//! are [`crate::recipe::RecipeError`]s, `file:line:col: message`, naming the
//! field (or the name as written) and what is allowed.
//!
//! World space: z is up; lengths are scene units (millimetres, the unit of
//! the gem recipes' object space).
//!
//! ```
//! let scene = lapidary::scene::default_scene();
//! assert_eq!(scene.stones.len(), 1);
//! ```

#![deny(missing_docs)]

pub mod compile;
pub mod spec;

pub use compile::{default_scene, load_scene, load_scene_under, parse_scene, DEFAULT_SCENE_SOURCE};
pub use spec::TurnSpec;

use crate::brdf::Rgb;
use crate::geometry::CabochonParams;
use glam::{DQuat, DVec3};
use std::path::PathBuf;

/// Most stones one scene may hold (a bound on memory and BVH build time
/// for a hand-written file; a typo like `1e9` copies cannot slip through).
pub(crate) const MAX_STONES: usize = 1024;

/// Most lights one scene may hold (each vertex chooses among them, and the
/// checks of where they stand compare them in pairs; a typo like `1e9`
/// copies cannot slip through).
pub(crate) const MAX_LIGHTS: usize = 1024;

/// A validated scene, ready for the renderer.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The pinhole camera.
    pub camera: Camera,
    /// The stones, 1 to 1024 (a scene file with more is refused).
    pub stones: Vec<StonePlacement>,
    /// A horizontal ground plane, if any.
    pub ground: Option<Ground>,
    /// Lights besides the environment.
    pub lights: Vec<LightSpec>,
    /// What rays leaving the scene see.
    pub environment: EnvironmentSpec,
    /// The turntable the scene file names, if any.
    pub turntable: Option<Turntable>,
    /// The scene file (`None` for text parsed without one, e.g. the
    /// built-in default).
    pub path: Option<PathBuf>,
}

impl Scene {
    /// Checks what the renderer assumes of a scene built in code (a scene
    /// file is checked as it is read, each value at its place): a camera
    /// whose eye is not its target and whose field of view is in (0, 170)
    /// degrees; finite places within 10⁵ mm and unit rotations; lights of
    /// at least 0.01 mm (a sun 0.01° to 20°) with unit directions and
    /// orthonormal axes, emitting finite, non-negative amounts up to 10¹²;
    /// an environment of finite, non-negative radiance. The message names
    /// the part and what is allowed. [`crate::render::prepare::prepare_scene`]
    /// calls it.
    pub fn check(&self) -> Result<(), String> {
        use spec::{MAX_COORDINATE_MM, MAX_EMISSION, MAX_ENVIRONMENT_INTENSITY, MIN_LIGHT_SIZE};
        let place = |v: DVec3| v.is_finite() && v.abs().max_element() <= MAX_COORDINATE_MM;
        let unit = |v: DVec3| v.is_finite() && (v.length() - 1.0).abs() < 1e-9;
        let emission =
            |c: Rgb| c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= MAX_EMISSION;
        let size = |s: f64| (MIN_LIGHT_SIZE..=MAX_COORDINATE_MM).contains(&s);
        let fail = |what: String| Err(format!("scene: {what}"));
        let c = &self.camera;
        if !(place(c.position) && place(c.look_at) && c.position != c.look_at) {
            return fail("the camera's position and look_at must be two different finite points within 1e5 mm".into());
        }
        if !(c.up.is_finite() && c.up.cross(c.look_at - c.position) != DVec3::ZERO) {
            return fail("the camera's up must be finite and not along its view".into());
        }
        if !(c.vertical_fov_deg > 0.0 && c.vertical_fov_deg < 170.0) {
            return fail(format!(
                "the camera's vertical_fov_deg = {} is out of range; allowed: (0, 170) degrees",
                c.vertical_fov_deg
            ));
        }
        if self.stones.len() > MAX_STONES {
            return fail(format!(
                "{} stones; allowed: at most {MAX_STONES}",
                self.stones.len()
            ));
        }
        if self.lights.len() > MAX_LIGHTS {
            return fail(format!(
                "{} lights; allowed: at most {MAX_LIGHTS}",
                self.lights.len()
            ));
        }
        for (k, stone) in self.stones.iter().enumerate() {
            let rotation_is_unit =
                stone.rotation.is_finite() && (stone.rotation.length() - 1.0).abs() < 1e-9;
            if !(place(stone.position) && rotation_is_unit) {
                return fail(format!(
                    "stone {}: its position must be finite within 1e5 mm and its rotation a unit quaternion",
                    k + 1
                ));
            }
        }
        if let Some(ground) = &self.ground {
            if !(ground.height.is_finite() && ground.height.abs() <= MAX_COORDINATE_MM) {
                return fail("the ground's height must be finite within 1e5 mm".into());
            }
        }
        for (k, light) in self.lights.iter().enumerate() {
            let ok = match *light {
                LightSpec::Point {
                    position,
                    intensity,
                } => place(position) && emission(intensity),
                LightSpec::Sphere {
                    centre,
                    radius,
                    radiance,
                } => place(centre) && size(radius) && emission(radiance),
                LightSpec::Rect {
                    centre,
                    normal,
                    u_axis,
                    v_axis,
                    width,
                    height,
                    radiance,
                } => {
                    place(centre)
                        && [normal, u_axis, v_axis].into_iter().all(unit)
                        && normal.dot(u_axis).abs() < 1e-9
                        && normal.dot(v_axis).abs() < 1e-9
                        && u_axis.dot(v_axis).abs() < 1e-9
                        && size(width)
                        && size(height)
                        && emission(radiance)
                }
                LightSpec::Sun {
                    direction,
                    angular_diameter_deg,
                    irradiance,
                } => {
                    unit(direction)
                        && (MIN_LIGHT_SIZE..=20.0).contains(&angular_diameter_deg)
                        && emission(irradiance)
                }
            };
            if !ok {
                return fail(format!(
                    "light {} is out of range; allowed: finite places within 1e5 mm, sizes from 0.01 mm (a sun 0.01° to 20°), unit directions and orthonormal axes, emission from 0 to 1e12 per channel",
                    k + 1
                ));
            }
        }
        let environment_ok = match self.environment {
            EnvironmentSpec::Constant(radiance) => emission(radiance),
            EnvironmentSpec::Studio {
                intensity,
                rotation_deg,
            }
            | EnvironmentSpec::File {
                intensity,
                rotation_deg,
                ..
            } => (0.0..=MAX_ENVIRONMENT_INTENSITY).contains(&intensity) && rotation_deg.is_finite(),
        };
        if !environment_ok {
            return fail("the environment's radiance or intensity is out of range; allowed: finite, from 0 (radiance up to 1e12, intensity up to 1e6)".into());
        }
        Ok(())
    }
}

/// A turntable: `frames` pictures evenly over a full turn; frame k is
/// turned by 360°·k/`frames` ([`Turntable::turn_deg`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Turntable {
    /// Frames of the full turn, 1 to [`spec::MAX_FRAMES`].
    pub frames: u32,
    /// What turns.
    pub turn: TurnSpec,
}

impl Turntable {
    /// The turn of frame `frame`, degrees counter-clockwise seen from above.
    pub fn turn_deg(&self, frame: u32) -> f64 {
        360.0 * f64::from(frame) / f64::from(self.frames)
    }
}

/// A pinhole camera in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The eye.
    pub position: DVec3,
    /// The point at the image centre (≠ `position`).
    pub look_at: DVec3,
    /// Unit vector that should point up in the image: world +z, except when
    /// the view is vertical (within 1e-9 rad), where z cannot define a frame
    /// and a horizontal vector is used instead (for an orbit, the one the
    /// view approaches as the elevation tends to ±90°). Not necessarily
    /// perpendicular to the view direction: the renderer orthonormalises it.
    pub up: DVec3,
    /// Full vertical field of view, (0, 170) degrees.
    pub vertical_fov_deg: f64,
}

/// One stone in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct StonePlacement {
    /// `None`: the gem named on the command line; otherwise a built-in gem
    /// name, or the path of an existing file, already resolved against the
    /// scene file's folder.
    pub recipe: Option<String>,
    /// The stone's geometry, already validated by
    /// [`crate::geometry::Cabochon::new`].
    pub shape: CabochonParams,
    /// World position of the object-space origin (the girdle plane's centre).
    pub position: DVec3,
    /// Object → world rotation (applied before the translation):
    /// `Rz · Ry · Rx`, i.e. about world x first, then y, then z.
    pub rotation: DQuat,
    /// Replaces the gem's own seed when `Some`.
    pub seed: Option<u64>,
}

/// A horizontal ground plane `z = height`.
#[derive(Clone, Debug, PartialEq)]
pub struct Ground {
    /// Its z.
    pub height: f64,
    /// A built-in material name, or the path of an existing file, resolved
    /// against the scene file's folder.
    pub material: String,
}

/// A light, with directions and frames computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightSpec {
    /// An isotropic point light: irradiance `intensity · cos θ / d²`.
    Point {
        /// Its position.
        position: DVec3,
        /// Radiant intensity per channel, ≥ 0.
        intensity: Rgb,
    },
    /// A uniformly emitting sphere.
    Sphere {
        /// Its centre.
        centre: DVec3,
        /// Radius, > 0.
        radius: f64,
        /// Emitted radiance per channel, ≥ 0.
        radiance: Rgb,
    },
    /// A one-sided rectangle emitting on the side of `normal`, spanning
    /// `centre ± width/2 · u_axis ± height/2 · v_axis`.
    Rect {
        /// Its centre.
        centre: DVec3,
        /// Unit normal of the emitting side (towards the scene's `aim_at`).
        normal: DVec3,
        /// Unit axis along `width`: horizontal (⊥ world z) unless the
        /// normal is vertical, then world x.
        u_axis: DVec3,
        /// Unit axis along `height`: `normal × u_axis`, so (u, v, normal)
        /// is right-handed and orthonormal.
        v_axis: DVec3,
        /// Extent along `u_axis`, > 0.
        width: f64,
        /// Extent along `v_axis`, > 0.
        height: f64,
        /// Emitted radiance per channel, ≥ 0.
        radiance: Rgb,
    },
    /// A distant disc: parallel light.
    Sun {
        /// Unit vector from the scene towards the sun.
        direction: DVec3,
        /// Apparent diameter, (0, 20] degrees.
        angular_diameter_deg: f64,
        /// Irradiance on a surface facing the sun, per channel, ≥ 0.
        irradiance: Rgb,
    },
}

/// The environment seen by rays that leave the scene.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentSpec {
    /// The same radiance in every direction.
    Constant(Rgb),
    /// The renderer's built-in studio, scaled and turned about world z.
    Studio {
        /// Multiplier, ≥ 0.
        intensity: f64,
        /// Turn about world z, degrees.
        rotation_deg: f64,
    },
    /// A latitude-longitude HDR/EXR image.
    File {
        /// The image path (`.hdr` or `.exr`), resolved against the scene
        /// file's folder; the file existed when the scene was loaded, its
        /// contents are read by the renderer.
        path: PathBuf,
        /// Turn about world z, degrees.
        rotation_deg: f64,
        /// Multiplier, ≥ 0.
        intensity: f64,
    },
}
