//! The RON schema of a material: plain serde data with units as written.
//!
//! ```ron
//! Material(
//!     layers: [
//!         Layer(ior: 1.5, roughness_deg: 1.0, thickness: 0.5, absorption: (0.1, 0.5, 0.9)),
//!     ],
//!     base: Diffuse(colour: (0.8, 0.1, 0.1), oren_nayar_sigma_rad: 0.0),
//!     distribution: Blinn,
//!     multiple_scattering: true,
//! )
//! ```

use crate::brdf::MicrofacetModel;
use crate::recipe::ranges;
use serde::{Deserialize, Deserializer};

fn default_true() -> bool {
    true
}

fn some_string<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    String::deserialize(d).map(Some)
}

/// A layered material as written in a RON file (section 4.1's parameters).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Dielectric layers from the top down; may be empty (a bare base).
    #[serde(default)]
    pub layers: Vec<LayerSpec>,
    /// What lies under the last layer.
    pub base: BaseSpec,
    /// Micro-facet distribution for every lobe (default: the seed's Blinn).
    #[serde(default)]
    pub distribution: MicrofacetModel,
    /// Add the multiple-scattering compensation lobe (default on); off gives
    /// the seed-faithful single-crossing model.
    #[serde(default = "default_true")]
    pub multiple_scattering: bool,
}

/// One varnish layer. Its IOR is given by exactly one of `ior`,
/// `reflectivity` (the artist's p, IOR = 1 + 5p², eq. 4.1) or `varnish` (a
/// table 4.1 varnish of the library by name).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(rename = "Layer", deny_unknown_fields)]
pub struct LayerSpec {
    /// Index of refraction, 1–5.
    #[serde(default, deserialize_with = "ranges::ior")]
    pub ior: Option<f64>,
    /// Artist's reflectivity p in [0, 1] (eq. 4.1).
    #[serde(default, deserialize_with = "ranges::reflectivity")]
    pub reflectivity: Option<f64>,
    /// Name of a library varnish (`plastics`, `ice`, …).
    #[serde(default, deserialize_with = "some_string")]
    pub varnish: Option<String>,
    /// Average micro-facet slope m in degrees, [0, 90).
    #[serde(default, deserialize_with = "ranges::roughness_deg")]
    pub roughness_deg: f64,
    /// Thickness of the layer (length unit of 1/absorption), ≥ 0.
    #[serde(default, deserialize_with = "ranges::thickness")]
    pub thickness: f64,
    /// Absorption coefficient per channel (Beer, eq. 3.4), ≥ 0.
    #[serde(default, deserialize_with = "ranges::absorption")]
    pub absorption: [f64; 3],
}

/// The base of a material.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub enum BaseSpec {
    /// Oren-Nayar diffuse base (σ in radians; 0 is Lambert).
    Diffuse {
        /// Diffuse reflectance per channel in [0, 1].
        #[serde(deserialize_with = "ranges::colour")]
        colour: [f64; 3],
        /// Oren-Nayar σ in radians (default 0).
        #[serde(default, deserialize_with = "ranges::sigma_rad")]
        oren_nayar_sigma_rad: f64,
    },
    /// A metal with complex IOR n + ik per channel (R, G, B at 680, 525,
    /// 450 nm), given directly or as a library `metal` name.
    Conductor {
        /// Real part of the IOR per channel.
        #[serde(default, deserialize_with = "ranges::conductor_n")]
        n: Option<[f64; 3]>,
        /// Extinction coefficient per channel.
        #[serde(default, deserialize_with = "ranges::conductor_k")]
        k: Option<[f64; 3]>,
        /// Library metal (`gold`, `silver`, `aluminium`, `copper`).
        #[serde(default, deserialize_with = "some_string")]
        metal: Option<String>,
        /// Average micro-facet slope of the metal in degrees, [0, 90).
        #[serde(default, deserialize_with = "ranges::roughness_deg")]
        roughness_deg: f64,
    },
    /// Nothing below reflects: the varnish's own reflection only.
    Black,
}
