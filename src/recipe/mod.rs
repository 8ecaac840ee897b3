//! RON recipes and materials: serde types with units as written, validation
//! with `file:line:col` errors, the embedded library, and compilation into
//! the plain data the renderer evaluates.

mod brackets;
pub mod compile;
pub mod error;
pub mod gem;
pub mod library;
pub mod material;
pub(crate) mod ranges;
mod ron_text;
pub mod table_cache;

pub use compile::{load_material, locate_material, parse_material};
pub use error::RecipeError;
pub use material::Material;
pub use table_cache::{TableCache, Tables};
