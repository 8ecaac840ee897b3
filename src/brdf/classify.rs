//! The material classes of section 3.4 (figures 3.8 and 3.9), computed from
//! the parameters by the decision tree of the notes.

use crate::brdf::layer::Base;
use crate::brdf::stack::LayeredBrdf;
use std::fmt;

/// Surfaces below this roughness count as smooth: the notes give 0.01°–4°
/// for smooth layers and at least 5° for rough ones (sections 4.2.1–4.2.5).
pub(crate) const SMOOTH_BELOW_DEG: f64 = 5.0;

/// The six basic groups of figure 3.8 (plus bare varnish, and black).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialGroup {
    /// Smooth layer over a diffuse base.
    GlossyPaint,
    /// Rough layer over a diffuse base.
    FrostedPaint,
    /// Smooth layer over a smooth metal.
    MetallicFoil,
    /// Smooth layer over a rough metal.
    MetallicPaint,
    /// Rough layer over a smooth metal.
    FrostedMetal,
    /// Rough layer over a rough metal.
    Patina,
    /// A dielectric over nothing (a varnish on its own).
    Varnish,
    /// No reflecting layer over a black base: it reflects nothing.
    Black,
}

impl fmt::Display for MaterialGroup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MaterialGroup::GlossyPaint => "glossy paint",
            MaterialGroup::FrostedPaint => "frosted paint",
            MaterialGroup::MetallicFoil => "metallic foil",
            MaterialGroup::MetallicPaint => "metallic paint",
            MaterialGroup::FrostedMetal => "frosted metal",
            MaterialGroup::Patina => "patina",
            MaterialGroup::Varnish => "varnish",
            MaterialGroup::Black => "black",
        })
    }
}

/// A material's class: its group, the two modifiers of figure 3.9, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Classification {
    /// The basic group.
    pub group: MaterialGroup,
    /// Some layer absorbs (a coloured varnish).
    pub tinted: bool,
    /// More than one reflecting layer above the base.
    pub multi_layer: bool,
    /// The decisions taken, in words.
    pub reason: String,
}

impl fmt::Display for Classification {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.group)?;
        if self.tinted {
            write!(f, ", tinted")?;
        }
        if self.multi_layer {
            write!(f, ", multi-layer")?;
        }
        Ok(())
    }
}

fn smoothness(roughness_deg: f64) -> &'static str {
    if roughness_deg < SMOOTH_BELOW_DEG {
        "smooth"
    } else {
        "rough"
    }
}

/// Classify by the decision tree of figure 3.8: metallic or not (the base),
/// then the roughness of the top surface and, for metals, of the base.
pub fn classify(brdf: &LayeredBrdf) -> Classification {
    // Layers of IOR 1 reflect nothing (brass's tinting layer): they tint but
    // do not count as a surface. Layers are counted by their own IOR, not the
    // ratio to the layer above: the house paint's two IOR 1.3 layers are the
    // notes' multi-layer example (section 4.2.7).
    let reflecting: Vec<_> = brdf
        .interfaces
        .iter()
        .filter(|i| i.ior_below != 1.0)
        .collect();
    let tinted = brdf
        .interfaces
        .iter()
        .any(|i| i.thickness > 0.0 && i.absorption_rgb.max_element() > 0.0);
    let multi_layer = reflecting.len() > 1;
    let top = reflecting.first().map(|i| i.own_lobe.roughness_deg);
    let mut reason = Vec::new();
    let group = match (&brdf.base, top) {
        (Base::Black, None) => {
            reason.push("no reflecting layer over a black base: it reflects nothing".to_string());
            MaterialGroup::Black
        }
        (Base::Black, Some(_)) => {
            reason.push("nothing below the varnish reflects".to_string());
            MaterialGroup::Varnish
        }
        (Base::Diffuse { .. }, None) => {
            reason.push("bare diffuse base (a paint without varnish)".to_string());
            MaterialGroup::FrostedPaint
        }
        (Base::Diffuse { .. }, Some(m)) => {
            reason.push(format!(
                "non-metallic (diffuse base); top layer {} (m = {m}°)",
                smoothness(m)
            ));
            if m < SMOOTH_BELOW_DEG {
                MaterialGroup::GlossyPaint
            } else {
                MaterialGroup::FrostedPaint
            }
        }
        (Base::Conductor { own_lobe, .. }, top) => {
            let base_m = own_lobe.roughness_deg;
            match top {
                None => {
                    reason.push(format!(
                        "bare metal, its own surface {} (m = {base_m}°)",
                        smoothness(base_m)
                    ));
                    if base_m < SMOOTH_BELOW_DEG {
                        MaterialGroup::MetallicFoil
                    } else {
                        MaterialGroup::FrostedMetal
                    }
                }
                Some(m) => {
                    reason.push(format!(
                        "metallic base {} (m = {base_m}°) under a {} top layer (m = {m}°)",
                        smoothness(base_m),
                        smoothness(m)
                    ));
                    match (m < SMOOTH_BELOW_DEG, base_m < SMOOTH_BELOW_DEG) {
                        (true, true) => MaterialGroup::MetallicFoil,
                        (true, false) => MaterialGroup::MetallicPaint,
                        (false, true) => MaterialGroup::FrostedMetal,
                        (false, false) => MaterialGroup::Patina,
                    }
                }
            }
        }
    };
    if tinted {
        reason.push("a layer absorbs (tinted varnish)".to_string());
    }
    if multi_layer {
        reason.push(format!("{} reflecting layers", reflecting.len()));
    }
    reason.insert(
        0,
        format!("smooth means m < {SMOOTH_BELOW_DEG}° (sections 4.2.1–4.2.5)"),
    );
    Classification {
        group,
        tinted,
        multi_layer,
        reason: reason.join("; "),
    }
}
