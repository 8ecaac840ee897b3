//! Parse, validate and compile a material: RON text → [`Material`] →
//! [`LayeredBrdf`] (IORs resolved, roughness accumulated, compensation
//! tabulated).

use crate::brdf::fresnel;
use crate::brdf::{Base, Interface, LayeredBrdf, Microfacet, Rgb};
use crate::file_kind::{not_a_regular_file, FileKind};
use crate::recipe::error::{
    did_you_mean, field_before, first_code_offset, folder_separator_hint, line_col_of_offset,
    nth_in_code, with_ron_hints, RecipeError,
};
use crate::recipe::library::{builtin_gem_source, builtin_material_names, builtin_material_source};
use crate::recipe::material::{BaseSpec, Material};
use crate::recipe::table_cache::Tables;
use std::io::Read;
use std::path::Path;

/// Seed of the compensation tables: they are part of the compiled material,
/// so every compile of the same file gives the same numbers.
pub const COMPENSATION_SEED: u64 = 0x1a9d_a41e;

/// Parse RON text into a [`Material`], mapping every RON/serde error to
/// `path:line:col: message` with the field name added where RON omits it.
pub fn parse_material(path: &str, source: &str) -> Result<Material, RecipeError> {
    parse_ron_all::<Material>(source, |e| ron_error(path, source, e))
}

/// [`parse_ron`], and where it fails, its error and every later value out
/// of range in `text` ([`crate::recipe::ranges::every_refusal`]), each made
/// a [`RecipeError`] by `error`, as one.
pub(crate) fn parse_ron_all<T: serde::de::DeserializeOwned>(
    text: &str,
    error: impl Fn(ron::error::SpannedError) -> RecipeError,
) -> Result<T, RecipeError> {
    crate::recipe::ranges::every_refusal(|| parse_ron::<T>(text)).map_err(|errors| {
        let (first, later) = *errors;
        RecipeError::gathered(error(first), later.into_iter().map(&error).collect())
    })
}

/// `ron::from_str` of a user's file `text`, read as if it ended with a
/// newline: RON places an error at the end of a file without one on its
/// last character, where [`ron_error`] could not tell it from an error at
/// that character (a file cut short after a `)` would not be said to end
/// there). Every other position is the same.
pub(crate) fn parse_ron<T: serde::de::DeserializeOwned>(
    text: &str,
) -> Result<T, ron::error::SpannedError> {
    if text.ends_with('\n') {
        ron::from_str(text)
    } else {
        ron::from_str(&format!("{text}\n"))
    }
}

/// Turn a RON error into a [`RecipeError`] a person can act on.
pub(crate) fn ron_error(path: &str, source: &str, e: ron::error::SpannedError) -> RecipeError {
    use ron::error::Error as E;
    let (line, mut col) = (e.span.start.line, e.span.start.col);
    // RON places an error in a negative number after its sign: place it
    // at the sign, where the number starts.
    let at_line = source
        .lines()
        .nth(line.saturating_sub(1))
        .unwrap_or_default();
    let mut before_and_at = at_line.chars().skip(col.saturating_sub(2));
    if col > 1
        && before_and_at.next() == Some('-')
        && before_and_at
            .next()
            .is_some_and(|c| c.is_ascii_digit() || ".iN".contains(c))
    {
        col -= 1;
    }
    let message = match &e.code {
        E::NoSuchStructField {
            expected,
            found,
            outer,
        } => {
            let hint = did_you_mean(found, expected.iter().copied())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            format!(
                "unknown field `{found}` in {}{hint}; expected one of: {}",
                outer.as_deref().unwrap_or("this item"),
                expected.join(", ")
            )
        }
        E::NoSuchEnumVariant {
            expected, found, ..
        } => {
            let hint = did_you_mean(found, expected.iter().copied())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            let field = field_before(source, line, col)
                .map(|field| format!("field `{field}`: "))
                .unwrap_or_default();
            format!(
                "{field}unknown variant `{found}`{hint}; expected one of: {}",
                expected.join(", ")
            )
        }
        E::MissingStructField { field, outer } => format!(
            "missing field `{field}` in {}",
            outer.as_deref().unwrap_or("this item")
        ),
        E::Message(m) => m.clone(),
        // A struct inside a file (`Glitter(` for `GlitterMap(`): a name to
        // correct, not a file of another kind.
        E::ExpectedDifferentStructName { expected, found }
            if ![*expected, found.as_str()]
                .iter()
                .any(|name| ["Gem", "Material", "Scene", "Job"].contains(name)) =>
        {
            let field = field_before(source, line, col)
                .map(|field| format!("field `{field}`: "))
                .unwrap_or_default();
            format!("{field}`{found}(…)` where `{expected}(…)` was expected (did you mean `{expected}`?)")
        }
        E::ExpectedDifferentStructName { expected, found } => {
            let what = |kind: &str| match kind {
                "Gem" => "a gem recipe",
                "Material" => "a material",
                "Scene" => "a scene",
                "Job" => "a batch job",
                _ => "a file",
            };
            let use_it = match found.as_str() {
                "Gem" => "; render it with `lapidary render FILE`",
                "Material" => "; inspect it with `lapidary brdf FILE`",
                "Scene" => "; render it with `lapidary render --scene FILE`",
                "Job" => "; list its tasks with `lapidary batch FILE`",
                _ => "",
            };
            format!(
                "this is {} (`{found}(…)`) where {} (`{expected}(…)`) was expected{use_it}",
                what(found),
                what(expected)
            )
        }
        other => {
            let text = other.to_string();
            match field_before(source, line, col) {
                Some(field) => format!("field `{field}`: {text}"),
                None => text,
            }
        }
    };
    RecipeError::at(path, line, col, with_ron_hints(message, source, line, col))
}

/// Where a material comes from: the built-in library or a file.
#[derive(Clone, Debug)]
pub struct MaterialSource {
    /// Display path (`builtin:gold` or the file path).
    pub path: String,
    /// Short name (library name or file stem).
    pub name: String,
    /// The RON text.
    pub text: String,
}

impl MaterialSource {
    /// Material `text` read from `path` (or made in memory: `path` is only
    /// for messages), named by the path's file stem.
    pub fn new(path: &str, text: &str) -> Self {
        MaterialSource {
            path: path.to_string(),
            name: Path::new(path)
                .file_stem()
                .map_or(path.to_string(), |s| s.to_string_lossy().into_owned()),
            text: text.to_string(),
        }
    }

    /// Parse, check and compile it, with its compensation table when it
    /// asks for one (as [`load_material`], from this text).
    pub fn compile(&self) -> Result<LayeredBrdf, RecipeError> {
        compile_material(self, &parse_material(&self.path, &self.text)?)
    }
}

/// Whether a command-line argument names a file rather than a library entry:
/// it exists, ends in `.ron`, or contains a `/`.
pub fn names_a_file(spec: &str) -> bool {
    Path::new(spec).exists() || spec.ends_with(".ron") || spec.contains('/')
}

/// The largest RON file read: recipes, scenes and jobs are kilobytes, a
/// tray of 1024 stones a few hundred; anything near this is no recipe.
const MAX_RON_BYTES: u64 = 16 << 20;

/// Read a RON file as UTF-8 text; `what` names the kind of file expected in
/// the message for a directory ("material file", "gem recipe"). A pipe, a
/// device or a socket is refused before it is opened (a pipe would keep
/// the command waiting, `/dev/zero` never ends), and so is a file above
/// 16 MiB.
pub fn read_ron_file(spec: &str, what: &str) -> Result<String, RecipeError> {
    let path = Path::new(spec);
    if let Some(kind) = not_a_regular_file(path) {
        return Err(RecipeError::whole_file(
            spec,
            format!("is {kind}, expected a .ron {what}"),
        ));
    }
    let cannot_read = |e: std::io::Error| {
        RecipeError::whole_file(
            spec,
            format!("cannot read: {e}{}", folder_separator_hint(spec)),
        )
    };
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|file| file.take(MAX_RON_BYTES + 1).read_to_end(&mut bytes))
        .map_err(cannot_read)?;
    if bytes.len() as u64 > MAX_RON_BYTES {
        return Err(RecipeError::whole_file(
            spec,
            format!(
                "is larger than {} MiB; allowed: a .ron {what} of at most {} MiB",
                MAX_RON_BYTES >> 20,
                MAX_RON_BYTES >> 20
            ),
        ));
    }
    if let Some((kind, hint)) = file_of_another_kind(&bytes) {
        return Err(RecipeError::whole_file(
            spec,
            format!("this is {kind}, not a .ron {what}{hint}"),
        ));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        // Where the first byte that is not UTF-8 stands, as line:col of the
        // valid text before it.
        let valid = e.utf8_error().valid_up_to();
        let before = String::from_utf8_lossy(&e.as_bytes()[..valid]);
        let (line, col) = line_col_of_offset(&before, before.len());
        RecipeError::at(
            spec,
            line,
            col,
            format!(
                "not UTF-8 text: byte 0x{:02x} is not a character; allowed: a text file in UTF-8",
                e.as_bytes()[valid]
            ),
        )
    })?;
    // A byte-order mark some editors write first is not RON: it is left out.
    let text = match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    };
    // Said in words, where RON would say it expected a `(`.
    if first_code_offset(&text) >= text.len() {
        let holds = if text.trim().is_empty() {
            "the file is empty"
        } else {
            "the file holds only comments"
        };
        return Err(RecipeError::whole_file(
            spec,
            format!("{holds}; expected a .ron {what}"),
        ));
    }
    Ok(text)
}

/// What a file that is not UTF-8 text is, from its first bytes (an image,
/// UTF-16 text), and what to do with it.
fn file_of_another_kind(bytes: &[u8]) -> Option<(&'static str, &'static str)> {
    let kind = FileKind::of(bytes)?;
    let hint = match kind {
        FileKind::OpenExr | FileKind::RadianceHdr => {
            "; an environment map goes to `render --env FILE` or a scene's `environment: File(path: …)`"
        }
        FileKind::Utf16 => "; save it as UTF-8",
        _ => "",
    };
    Some((kind.name(), hint))
}

/// Find MATERIAL as a file (if it names one or ends in `.ron`) or as a
/// library name; unknown names get a did-you-mean.
pub fn locate_material(spec: &str) -> Result<MaterialSource, RecipeError> {
    if names_a_file(spec) {
        let text = read_ron_file(spec, "material file")?;
        return Ok(MaterialSource::new(spec, &text));
    }
    match builtin_material_source(spec) {
        Some(text) => Ok(MaterialSource {
            path: format!("builtin:{spec}"),
            name: spec.to_string(),
            text: text.to_string(),
        }),
        None if builtin_gem_source(spec).is_some() => Err(RecipeError::whole_file(
            spec,
            format!("`{spec}` is a built-in gem, not a material: `lapidary render {spec}` renders it; a material is one of the library (`lapidary list`) or a `Material(…)` file"),
        )),
        None => {
            let hint = did_you_mean(spec, builtin_material_names())
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            Err(RecipeError::whole_file(
                spec,
                format!(
                    "no such file and no built-in material of that name{}{hint}; `lapidary list` shows the library",
                    folder_separator_hint(spec)
                ),
            ))
        }
    }
}

/// Load, parse and compile MATERIAL (a library name or a RON file), with its
/// compensation table when it asks for one (`multiple_scattering`, the
/// default), computed here and not cached: see
/// [`crate::recipe::TableCache`] to keep tables between calls.
pub fn load_material(spec: &str) -> Result<LayeredBrdf, RecipeError> {
    locate_material(spec)?.compile()
}

/// [`load_material`] without the compensation table, and whether the
/// material asks for one (`multiple_scattering`), for callers that compute
/// several tables together.
pub fn load_material_without_table(spec: &str) -> Result<(LayeredBrdf, bool), RecipeError> {
    let source = locate_material(spec)?;
    let material = parse_material(&source.path, &source.text)?;
    let brdf = compile_material_without_table(&source, &material)?;
    Ok((brdf, material.multiple_scattering))
}

/// [`load_material`] with its compensation table from `tables` (through
/// the cache, or none with [`Tables::Skipped`]).
pub fn load_material_with(spec: &str, tables: Tables<'_>) -> Result<LayeredBrdf, RecipeError> {
    let (mut brdf, wants_table) = load_material_without_table(spec)?;
    if let (true, Tables::Computed(cache)) = (wants_table, tables) {
        brdf.compensation = cache.compensation(&brdf, COMPENSATION_SEED);
    }
    Ok(brdf)
}

/// The IOR of a built-in varnish (a library material of one layer).
fn varnish_ior(name: &str) -> Option<f64> {
    let text = builtin_material_source(name)?;
    let m = ron::from_str::<Material>(text).ok()?;
    match m.layers.as_slice() {
        [only] => only.ior,
        _ => None,
    }
}

/// The (n, k) of a built-in metal (a library material with a conductor base).
fn metal_nk(name: &str) -> Option<([f64; 3], [f64; 3])> {
    let text = builtin_material_source(name)?;
    let m = ron::from_str::<Material>(text).ok()?;
    match m.base {
        BaseSpec::Conductor {
            n: Some(n),
            k: Some(k),
            ..
        } => Some((n, k)),
        _ => None,
    }
}

/// An unknown library `kind` (varnish, metal) at the place its name is
/// written, with a did-you-mean among the library entries that are one.
fn unknown_name(
    path: &str,
    text: &str,
    kind: &str,
    name: &str,
    is_kind: impl Fn(&str) -> bool,
) -> RecipeError {
    let known: Vec<&str> = builtin_material_names().filter(|n| is_kind(n)).collect();
    let hint = did_you_mean(name, known.iter().copied())
        .map(|s| format!(" (did you mean `{s}`?)"))
        .unwrap_or_default();
    RecipeError::at_text(
        path,
        text,
        &format!("\"{name}\""),
        format!("unknown {kind} `{name}`{hint}; known: {}", known.join(", ")),
    )
}

/// Resolve names, check the rules serde cannot, and build the BRDF (with
/// its compensation table when `m.multiple_scattering`).
pub fn compile_material(source: &MaterialSource, m: &Material) -> Result<LayeredBrdf, RecipeError> {
    let brdf = compile_material_without_table(source, m)?;
    Ok(if m.multiple_scattering {
        brdf.with_compensation(COMPENSATION_SEED)
    } else {
        brdf
    })
}

/// [`compile_material`] without the compensation table, for callers that
/// compute the tables of several materials together
/// ([`crate::recipe::TableCache::compensations`] with [`COMPENSATION_SEED`]).
pub(crate) fn compile_material_without_table(
    source: &MaterialSource,
    m: &Material,
) -> Result<LayeredBrdf, RecipeError> {
    compile_material_seen_from(source, m, 1.0)
}

/// The most varnish layers a material may have: far more than any
/// material of the course notes (at most two), few enough that the
/// layer-by-layer evaluation and its compensation tables stay quick.
pub(crate) const MAX_LAYERS: usize = 16;

/// [`compile_material_without_table`] for a material seen from a medium of
/// index `ior_outside` instead of air (a flake inside a translucent body):
/// its top interface refracts with η = n / `ior_outside` and a bare metal
/// base reflects with (n, k) / `ior_outside` (eqs. 3.2–3.3 take relative
/// indices).
pub(crate) fn compile_material_seen_from(
    source: &MaterialSource,
    m: &Material,
    ior_outside: f64,
) -> Result<LayeredBrdf, RecipeError> {
    let path = source.path.as_str();
    let text = source.text.as_str();
    // The `index`-th `Layer(` written as code (not in a comment).
    let layer_error = |index: usize, message: String| match nth_in_code(text, "Layer(", index) {
        Some(offset) => {
            let (l, c) = line_col_of_offset(text, offset);
            RecipeError::at(path, l, c, message)
        }
        None => RecipeError::whole_file(path, message),
    };
    if m.layers.len() > MAX_LAYERS {
        return Err(layer_error(
            MAX_LAYERS,
            format!(
                "`layers` has {} layers; allowed: at most {MAX_LAYERS}",
                m.layers.len()
            ),
        ));
    }
    let mut interfaces = Vec::with_capacity(m.layers.len());
    let mut ior_above = ior_outside;
    let mut roughness_above_deg = 0.0;
    for (index, layer) in m.layers.iter().enumerate() {
        let given = [
            layer.ior.is_some(),
            layer.reflectivity.is_some(),
            layer.varnish.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(layer_error(
                index,
                format!(
                    "layer {} needs exactly one of `ior`, `reflectivity` or `varnish`",
                    index + 1
                ),
            ));
        }
        let ior = if let Some(ior) = layer.ior {
            ior
        } else if let Some(p) = layer.reflectivity {
            1.0 + 5.0 * p * p // eq. 4.1
        } else {
            let name = layer.varnish.as_deref().unwrap_or_default();
            varnish_ior(name).ok_or_else(|| {
                unknown_name(path, text, "varnish", name, |n| varnish_ior(n).is_some())
            })?
        };
        let accumulated = roughness_above_deg + layer.roughness_deg;
        interfaces.push(Interface {
            ior_below: ior,
            eta: ior / ior_above,
            lobe: Microfacet::new(m.distribution, accumulated),
            own_lobe: Microfacet::new(m.distribution, layer.roughness_deg),
            thickness: layer.thickness,
            absorption_rgb: Rgb::from_array(layer.absorption),
        });
        ior_above = ior;
        roughness_above_deg = accumulated;
    }
    let base = match &m.base {
        BaseSpec::Diffuse {
            colour,
            oren_nayar_sigma_rad,
        } => Base::Diffuse {
            colour: Rgb::from_array(*colour),
            oren_nayar_sigma_rad: *oren_nayar_sigma_rad,
        },
        BaseSpec::Conductor {
            n,
            k,
            metal,
            roughness_deg,
        } => {
            let (n, k) = match (n, k, metal) {
                (Some(n), Some(k), None) => (*n, *k),
                (None, None, Some(name)) => metal_nk(name).ok_or_else(|| {
                    unknown_name(path, text, "metal", name, |n| metal_nk(n).is_some())
                })?,
                _ => {
                    let found = match (n.is_some(), k.is_some(), metal.is_some()) {
                        (_, _, true) => "`metal` together with `n` or `k`",
                        (true, false, false) => "`n` without `k`",
                        (false, true, false) => "`k` without `n`",
                        _ => "neither",
                    };
                    return Err(RecipeError::at_text(
                        path,
                        text,
                        "Conductor",
                        format!(
                            "a Conductor base takes either `metal` (a named metal) or both `n` and `k`, \
                             not both ways; found {found}"
                        ),
                    ));
                }
            };
            // Complex IOR relative to the varnish above (eq. 3.3).
            Base::Conductor {
                n_relative: Rgb::from_array(n) / ior_above,
                k_relative: Rgb::from_array(k) / ior_above,
                lobe: Microfacet::new(m.distribution, roughness_above_deg + roughness_deg),
                own_lobe: Microfacet::new(m.distribution, *roughness_deg),
            }
        }
        BaseSpec::Black => Base::Black,
    };
    Ok(LayeredBrdf::new(
        &source.name,
        m.distribution,
        interfaces,
        base,
    ))
}

/// Normal-incidence reflectance of a library metal, for the table tests.
pub fn metal_normal_incidence(name: &str) -> Option<Rgb> {
    let (n, k) = metal_nk(name)?;
    Some(Rgb::new(
        fresnel::conductor_normal_incidence(n[0], k[0]),
        fresnel::conductor_normal_incidence(n[1], k[1]),
        fresnel::conductor_normal_incidence(n[2], k[2]),
    ))
}
