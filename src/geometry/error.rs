//! Parameter errors of the geometry module.

use crate::message::number;

/// A parameter that is out of its allowed range, named for a person.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("cabochon parameter `{name}` = {} is out of range: {allowed}", number(*.value))]
pub struct GeometryError {
    /// The parameter's name as written in [`super::CabochonParams`] or
    /// [`super::Outline`] (`length`, `dome_height`, `exponent`, ...).
    pub name: &'static str,
    /// The refused value.
    pub value: f64,
    /// What would have been accepted.
    pub allowed: String,
}

impl GeometryError {
    pub(crate) fn new(name: &'static str, value: f64, allowed: impl Into<String>) -> Self {
        Self {
            name,
            value,
            allowed: allowed.into(),
        }
    }
}

/// Refuses NaN, infinities and values ≤ 0.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64, GeometryError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(GeometryError::new(name, value, "must be finite and > 0"))
    }
}
