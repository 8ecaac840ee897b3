//! The built-in material library, embedded in the binary so that a recipe
//! naming `gold` works from any folder.

/// (name, RON source) of every file in `gem-recipes/materials/`.
pub(crate) const BUILTIN_MATERIALS: &[(&str, &str)] = &[
    (
        "acrylic-lacquer",
        include_str!("../../gem-recipes/materials/acrylic-lacquer.ron"),
    ),
    (
        "aluminium",
        include_str!("../../gem-recipes/materials/aluminium.ron"),
    ),
    (
        "blue-acrylic",
        include_str!("../../gem-recipes/materials/blue-acrylic.ron"),
    ),
    (
        "blue-metallic-car-paint",
        include_str!("../../gem-recipes/materials/blue-metallic-car-paint.ron"),
    ),
    (
        "blue-metallic-paint",
        include_str!("../../gem-recipes/materials/blue-metallic-paint.ron"),
    ),
    (
        "brass",
        include_str!("../../gem-recipes/materials/brass.ron"),
    ),
    (
        "ceramic-glazing",
        include_str!("../../gem-recipes/materials/ceramic-glazing.ron"),
    ),
    (
        "copper",
        include_str!("../../gem-recipes/materials/copper.ron"),
    ),
    (
        "frosted-gold-paint",
        include_str!("../../gem-recipes/materials/frosted-gold-paint.ron"),
    ),
    (
        "glass-quartz",
        include_str!("../../gem-recipes/materials/glass-quartz.ron"),
    ),
    ("gold", include_str!("../../gem-recipes/materials/gold.ron")),
    (
        "gold-metallic-paint",
        include_str!("../../gem-recipes/materials/gold-metallic-paint.ron"),
    ),
    (
        "green-acrylic",
        include_str!("../../gem-recipes/materials/green-acrylic.ron"),
    ),
    (
        "green-latex",
        include_str!("../../gem-recipes/materials/green-latex.ron"),
    ),
    ("ice", include_str!("../../gem-recipes/materials/ice.ron")),
    (
        "light-blue-house-paint",
        include_str!("../../gem-recipes/materials/light-blue-house-paint.ron"),
    ),
    (
        "plastics",
        include_str!("../../gem-recipes/materials/plastics.ron"),
    ),
    (
        "red-acrylic",
        include_str!("../../gem-recipes/materials/red-acrylic.ron"),
    ),
    (
        "red-garnet",
        include_str!("../../gem-recipes/materials/red-garnet.ron"),
    ),
    (
        "silver",
        include_str!("../../gem-recipes/materials/silver.ron"),
    ),
    (
        "silver-paint",
        include_str!("../../gem-recipes/materials/silver-paint.ron"),
    ),
    (
        "sugar",
        include_str!("../../gem-recipes/materials/sugar.ron"),
    ),
    (
        "teflon",
        include_str!("../../gem-recipes/materials/teflon.ron"),
    ),
    (
        "tinted-ceramic-glaze",
        include_str!("../../gem-recipes/materials/tinted-ceramic-glaze.ron"),
    ),
];

/// The RON source of a built-in material.
pub fn builtin_material_source(name: &str) -> Option<&'static str> {
    BUILTIN_MATERIALS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
}

/// Names of all built-in materials, sorted.
pub fn builtin_material_names() -> impl Iterator<Item = &'static str> {
    BUILTIN_MATERIALS.iter().map(|(n, _)| *n)
}

/// (name, RON source) of every gem recipe in `gem-recipes/`, sorted by name.
pub const BUILTIN_GEMS: &[(&str, &str)] = &[
    (
        "blue-goldstone",
        include_str!("../../gem-recipes/blue-goldstone.ron"),
    ),
    ("goldstone", include_str!("../../gem-recipes/goldstone.ron")),
    (
        "green-aventurine",
        include_str!("../../gem-recipes/green-aventurine.ron"),
    ),
    (
        "lavender-lepidolite",
        include_str!("../../gem-recipes/lavender-lepidolite.ron"),
    ),
    (
        "patterned-sunstone",
        include_str!("../../gem-recipes/patterned-sunstone.ron"),
    ),
    (
        "pink-sunstone",
        include_str!("../../gem-recipes/pink-sunstone.ron"),
    ),
    (
        "raspberry-aventurine",
        include_str!("../../gem-recipes/raspberry-aventurine.ron"),
    ),
    ("sunstone", include_str!("../../gem-recipes/sunstone.ron")),
];

/// The gem `lapidary render` draws when no recipe is named.
pub const DEFAULT_GEM: &str = "green-aventurine";

/// The RON source of a built-in gem.
pub fn builtin_gem_source(name: &str) -> Option<&'static str> {
    BUILTIN_GEMS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
}

/// Names of all built-in gems.
pub fn builtin_gem_names() -> impl Iterator<Item = &'static str> {
    BUILTIN_GEMS.iter().map(|(n, _)| *n)
}
