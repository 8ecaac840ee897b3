//! Range-checked number fields: validation happens while RON is parsed, so
//! every out-of-range, NaN or infinite value is reported at its own line and
//! column with the field's name and allowed range.

use std::cell::Cell;
use std::collections::BTreeMap;
use std::marker::PhantomData;

use serde::de::{Error, MapAccess, Visitor};
use serde::{Deserialize, Deserializer};

use crate::message::number;

thread_local! {
    /// For the parse running on this thread: how many more refused values
    /// it lets through, and whether its last refusal stopped it.
    static REFUSALS: Cell<(usize, bool)> = const { Cell::new((0, false)) };
}

/// The most refusals [`every_refusal`] looks for after the first.
const MAX_LATER_REFUSALS: usize = 19;

/// A value out of its range: `Ok(value)` where the parse lets this refusal
/// through ([`every_refusal`]'s later runs, whose result is thrown away),
/// else the error `message`. Every range check of a RON schema refuses
/// through here.
pub(crate) fn refuse<T, E: Error>(value: T, message: String) -> Result<T, E> {
    REFUSALS.with(|refusals| match refusals.get() {
        (left @ 1.., _) => {
            refusals.set((left - 1, false));
            Ok(value)
        }
        (0, _) => {
            refusals.set((0, true));
            Err(E::custom(message))
        }
    })
}

/// `parse`'s value, or its error and, where a range check stopped it, the
/// next ones: `parse` runs again with every refusal so far let through, so
/// that each run stops at the next refused value, placed by RON as the
/// first was. Stops at a run that passes, at an error of another kind
/// (kept), or after [`MAX_LATER_REFUSALS`].
pub(crate) fn every_refusal<T>(
    parse: impl Fn() -> Result<T, ron::error::SpannedError>,
) -> Result<T, Box<(ron::error::SpannedError, Vec<ron::error::SpannedError>)>> {
    let run = |let_through: usize| {
        REFUSALS.with(|refusals| refusals.set((let_through, false)));
        let result = parse();
        let (_, refused) = REFUSALS.with(|refusals| refusals.replace((0, false)));
        (result, refused)
    };
    let (first, mut refused) = match run(0) {
        (Ok(value), _) => return Ok(value),
        (Err(first), refused) => (first, refused),
    };
    let place = |e: &ron::error::SpannedError| (e.span.start.line, e.span.start.col);
    let mut later: Vec<ron::error::SpannedError> = Vec::new();
    while refused && later.len() < MAX_LATER_REFUSALS {
        let (Err(next), next_refused) = run(later.len() + 1) else {
            break;
        };
        // Each run stops further on (a guard: it always should).
        if place(&next) <= later.last().map_or(place(&first), place) {
            break;
        }
        refused = next_refused;
        later.push(next);
    }
    Err(Box::new((first, later)))
}

/// Parse a finite f64 and check `ok`, else an error naming `field` and `allowed`.
/// Public so that other RON schemas (the scene) report ranges the same way.
pub fn checked<'de, D: Deserializer<'de>>(
    d: D,
    field: &str,
    allowed: &str,
    ok: impl Fn(f64) -> bool,
) -> Result<f64, D::Error> {
    let v = f64::deserialize(d)?;
    if !v.is_finite() || !ok(v) {
        return refuse(
            v,
            format!(
                "`{field}` = {} is out of range; allowed: {allowed}",
                number(v)
            ),
        );
    }
    Ok(v)
}

/// Parse a whole number from `min` to `max`, else an error naming `field`
/// and the range. Read wide (as 128 bits), so that −1 or 10³⁰ is told the
/// range too, not RON's "Integer is out of bounds".
pub(crate) fn whole_in<'de, D: Deserializer<'de>>(
    d: D,
    field: &str,
    min: u32,
    max: u32,
) -> Result<u32, D::Error> {
    let v = i128::deserialize(d)?;
    match u32::try_from(v).ok().filter(|v| (min..=max).contains(v)) {
        Some(v) => Ok(v),
        None => refuse(
            min,
            format!("`{field}` = {v} is out of range; allowed: {min} to {max}"),
        ),
    }
}

/// Parse an RGB triple, each component checked (public like [`checked`]).
pub(crate) fn checked_rgb<'de, D: Deserializer<'de>>(
    d: D,
    field: &str,
    allowed: &str,
    ok: impl Fn(f64) -> bool,
) -> Result<[f64; 3], D::Error> {
    let v = <(f64, f64, f64)>::deserialize(d)?;
    let rgb = [v.0, v.1, v.2];
    if rgb.iter().any(|&c| !c.is_finite() || !ok(c)) {
        // A colour picker's 8-bit values (whole numbers 0 to 255) where
        // fractions are meant: say what they would be.
        let eight_bit = rgb
            .iter()
            .all(|&c| (0.0..=255.0).contains(&c) && c.fract() == 0.0)
            && rgb.iter().any(|&c| c > 1.0)
            && rgb.iter().all(|&c| ok(c / 255.0));
        let hint = if eight_bit {
            let [r, g, b] = rgb.map(|c| number((c / 255.0 * 1000.0).round() / 1000.0));
            format!(" (8-bit values? divided by 255 they are ({r}, {g}, {b}))")
        } else {
            String::new()
        };
        return refuse(
            rgb,
            format!(
                "`{field}` = ({}, {}, {}) has a component out of range; allowed: {allowed} per channel{hint}",
                number(v.0),
                number(v.1),
                number(v.2)
            ),
        );
    }
    Ok(rgb)
}

macro_rules! scalar_field {
    ($name:ident, $field:literal, $allowed:literal, $ok:expr) => {
        #[doc = concat!("Deserialize `", $field, "`, allowed: ", $allowed, ".")]
        pub fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
            checked(d, $field, $allowed, $ok)
        }
    };
}

macro_rules! optional_scalar_field {
    ($name:ident, $field:literal, $allowed:literal, $ok:expr) => {
        #[doc = concat!("Deserialize optional `", $field, "` written as a plain number, allowed: ", $allowed, ".")]
        pub fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
            checked(d, $field, $allowed, $ok).map(Some)
        }
    };
}

macro_rules! rgb_field {
    ($name:ident, $field:literal, $allowed:literal, $ok:expr) => {
        #[doc = concat!("Deserialize RGB `", $field, "`, allowed: ", $allowed, " per channel.")]
        pub fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
            checked_rgb(d, $field, $allowed, $ok)
        }
    };
}

macro_rules! optional_rgb_field {
    ($name:ident, $field:literal, $allowed:literal, $ok:expr) => {
        #[doc = concat!("Deserialize optional RGB `", $field, "`, allowed: ", $allowed, " per channel.")]
        pub fn $name<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
            checked_rgb(d, $field, $allowed, $ok).map(Some)
        }
    };
}

scalar_field!(
    roughness_deg,
    "roughness_deg",
    "0 <= roughness_deg < 90 (degrees)",
    |v| (0.0..90.0).contains(&v)
);
scalar_field!(thickness, "thickness", "thickness >= 0", |v| v >= 0.0);
scalar_field!(
    sigma_rad,
    "oren_nayar_sigma_rad",
    "0 <= oren_nayar_sigma_rad <= 1.57 (radians)",
    |v| (0.0..=1.57).contains(&v)
);
optional_scalar_field!(ior, "ior", "1 <= ior <= 5", |v| (1.0..=5.0).contains(&v));
optional_scalar_field!(
    reflectivity,
    "reflectivity",
    "0 <= reflectivity <= 1 (IOR = 1 + 5p², eq. 4.1)",
    |v| (0.0..=1.0).contains(&v)
);
rgb_field!(absorption, "absorption", "absorption >= 0", |v| v >= 0.0);
rgb_field!(colour, "colour", "0 <= colour <= 1", |v| (0.0..=1.0)
    .contains(&v));
// n ≥ 0.01: below every real metal (silver ≈ 0.04 in the blue), and far
// from 0, where the Fresnel equations (eq. 3.3) divide 0 by 0.
optional_rgb_field!(conductor_n, "n", "0.01 <= n <= 20", |v| (0.01..=20.0)
    .contains(&v));
optional_rgb_field!(conductor_k, "k", "0 <= k <= 20", |v| (0.0..=20.0)
    .contains(&v));

// ---- Gem recipes (section 4.3.1): textures and the pattern tree ----------

scalar_field!(
    cell_size,
    "cell_size",
    "cell_size > 0 (texture units)",
    |v| v > 0.0
);
optional_scalar_field!(
    per_cell_size,
    "per_cell_size",
    "per_cell_size > 0 (texture units)",
    |v| v > 0.0
);
scalar_field!(jitter, "jitter", "0 <= jitter <= 1", |v| (0.0..=1.0)
    .contains(&v));
scalar_field!(
    weight,
    "weight",
    "weight >= 0 (at least one > 0 per map)",
    |v| v >= 0.0
);
scalar_field!(
    fill_fraction,
    "fill_fraction",
    "0 <= fill_fraction <= 1",
    |v| (0.0..=1.0).contains(&v)
);
scalar_field!(
    max_tilt_deg,
    "max_tilt_deg",
    "0 <= max_tilt_deg <= 90 (degrees)",
    |v| (0.0..=90.0).contains(&v)
);
scalar_field!(
    sigma_tilt_deg,
    "sigma_tilt_deg",
    "0 < sigma_tilt_deg <= 90 (degrees)",
    |v| v > 0.0 && v <= 90.0
);
scalar_field!(frequency, "frequency", "frequency > 0", |v| v > 0.0);
scalar_field!(amplitude, "amplitude", "any finite amplitude", |_| true);
scalar_field!(lacunarity, "lacunarity", "1 <= lacunarity <= 8", |v| (1.0
    ..=8.0)
    .contains(&v));
scalar_field!(gain, "gain", "0 <= gain <= 1", |v| (0.0..=1.0).contains(&v));
scalar_field!(range_end, "from/to", "a finite number", |_| true);
scalar_field!(body_ior, "ior", "1 <= ior <= 5", |v| (1.0..=5.0)
    .contains(&v));
rgb_field!(
    body_absorption,
    "absorption",
    "0 <= absorption <= 1000 (per mm)",
    |v| (0.0..=1000.0).contains(&v)
);
rgb_field!(
    body_scattering,
    "scattering",
    "0 <= scattering <= 1000 (per mm)",
    |v| (0.0..=1000.0).contains(&v)
);
scalar_field!(
    anisotropy,
    "anisotropy",
    "-0.99 <= anisotropy <= 0.99",
    |v| (-0.99..=0.99).contains(&v)
);
scalar_field!(
    body_roughness_deg,
    "roughness_deg",
    "0 <= roughness_deg <= 45 (degrees)",
    |v| (0.0..=45.0).contains(&v)
);
scalar_field!(
    flake_size_mm,
    "size_mm",
    "0.001 <= size_mm <= 10 (mm)",
    |v| (0.001..=10.0).contains(&v)
);
scalar_field!(size_spread, "size_spread", "0 <= size_spread <= 0.9", |v| {
    (0.0..=0.9).contains(&v)
});
scalar_field!(
    density_per_mm3,
    "density_per_mm3",
    "0.001 <= density_per_mm3 <= 100000",
    |v| (0.001..=100_000.0).contains(&v)
);
scalar_field!(
    spread_deg,
    "spread_deg",
    "0 <= spread_deg <= 90 (degrees)",
    |v| (0.0..=90.0).contains(&v)
);
rgb_field!(stretch, "stretch", "stretch > 0", |v| v > 0.0);
rgb_field!(direction, "direction", "finite, not all zero", |_| true);

/// Deserialize `octaves`, allowed: 1 to 16.
pub fn octaves<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    // Read wide, so that −1 or 10³⁰ is told its range too.
    let v = i128::deserialize(d)?;
    match u32::try_from(v) {
        Ok(v) if (1..=16).contains(&v) => Ok(v),
        _ => refuse(
            1,
            format!("`octaves` = {v} is out of range; allowed: 1 <= octaves <= 16"),
        ),
    }
}

/// Deserialize a `seed`: a whole number from 0 to 2⁶⁴ − 1 (read wide, so
/// that −1 is told the range as every other field is).
pub fn seed<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
    seed_of(i128::deserialize(d)?)
}

/// [`seed`] of a field written `Some(n)` or `None` (checked inside the
/// `Some`, so that RON places a refusal at the number).
pub fn optional_seed<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u64>, D::Error> {
    struct SomeSeed;
    impl<'de> Visitor<'de> for SomeSeed {
        type Value = Option<u64>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("`Some(seed)` or `None`")
        }
        fn visit_none<E: Error>(self) -> Result<Self::Value, E> {
            Ok(None)
        }
        fn visit_some<S: Deserializer<'de>>(self, d: S) -> Result<Self::Value, S::Error> {
            seed(d).map(Some)
        }
    }
    d.deserialize_option(SomeSeed)
}

fn seed_of<E: Error>(v: i128) -> Result<u64, E> {
    u64::try_from(v).or_else(|_| {
        refuse(
            0,
            format!(
                "`seed` = {v} is out of range; allowed: a whole number from 0 to {}",
                u64::MAX
            ),
        )
    })
}

/// A name → definition map whose names are each given once: a name given
/// twice (an entry copied and not renamed) is an error naming it, where a
/// map would keep the last silently. `what` is "material" or "map".
pub(crate) fn named_once<'de, D: Deserializer<'de>, V: Deserialize<'de>>(
    d: D,
    what: &'static str,
) -> Result<BTreeMap<String, V>, D::Error> {
    struct Entries<V> {
        what: &'static str,
        value: PhantomData<V>,
    }
    impl<'de, V: Deserialize<'de>> Visitor<'de> for Entries<V> {
        type Value = BTreeMap<String, V>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            write!(f, "{{ \"name\": definition, … }} of {}s", self.what)
        }
        fn visit_map<A: MapAccess<'de>>(self, mut entries: A) -> Result<Self::Value, A::Error> {
            let mut map = BTreeMap::new();
            while let Some((name, value)) = entries.next_entry::<String, V>()? {
                if map.contains_key(&name) {
                    return Err(A::Error::custom(format!(
                        "{} `{name}` is defined twice (the second would replace the first); \
                         allowed: each name once",
                        self.what
                    )));
                }
                map.insert(name, value);
            }
            Ok(map)
        }
    }
    d.deserialize_map(Entries {
        what,
        value: PhantomData,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    struct Thicknesses {
        #[allow(dead_code)]
        all: Vec<Thickness>,
    }

    #[derive(Debug, Deserialize)]
    #[allow(dead_code)]
    struct Thickness(#[serde(deserialize_with = "thickness")] f64);

    fn parse(text: &str) -> Result<Thicknesses, ron::error::SpannedError> {
        ron::from_str(text)
    }

    #[test]
    fn every_refusal_finds_each_value_out_of_range_up_to_its_cap() {
        let values: Vec<String> = (0..30)
            .map(|k| {
                if k % 2 == 0 {
                    format!("({k}.0)")
                } else {
                    format!("(-{k}.0)")
                }
            })
            .collect();
        let text = format!("(all: [{}])", values.join(", "));
        let (first, later) = *every_refusal(|| parse(&text)).expect_err("refused");
        assert!(first.to_string().contains("`thickness` = -1 is"), "{first}");
        // 15 refused values: the first and 14 later, each further on.
        assert_eq!(later.len(), 14);
        assert!(later[13].to_string().contains("= -29 is"), "{}", later[13]);
        // Forty refused values: the first and at most 19 later.
        let text = format!("(all: [{}])", vec!["(-1.0)"; 40].join(", "));
        let (_, later) = *every_refusal(|| parse(&text)).expect_err("refused");
        assert_eq!(later.len(), MAX_LATER_REFUSALS);
        // A parse afterwards lets nothing through; a good text passes.
        assert!(parse("(all: [(-1.0)])").is_err());
        assert!(every_refusal(|| parse("(all: [(1.0)])")).is_ok());
    }
}
