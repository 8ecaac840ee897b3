//! How numbers are written in messages to people.

/// `v` as a message writes it: as Rust prints it, or in exponent form
/// where that is shorter than the digits (`1e308`, not 309 digits;
/// `1e-300`, not 300 zeros).
pub(crate) fn number(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-6..1e16).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}
