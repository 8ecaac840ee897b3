//! RON recipes.
