//! The compiled pattern tree of section 4.3.1 (figures 4.6 and 4.7): which
//! layered material, and which facet normal, a point of the stone has.
//!
//! # Layout
//!
//! The tree is stored flat, in the style of yocto-gl: [`Pattern::nodes`] is a
//! `Vec<Node>` and every reference is a `u32` index ([`Entry::Node`]) or a
//! material index ([`Entry::Material`]). There is no `Box<dyn>`, no
//! allocation and no recursion per query: [`Pattern::resolve`] walks from
//! [`Pattern::root`] down to a material in a loop. [`Pattern::new`] checks
//! that every index is in bounds and that no node reaches itself, so the walk
//! always ends (after at most `nodes.len()` steps).
//!
//! * [`SurfaceMap`] (figure 4.6 ①): Voronoi cells, each picking one entry
//!   (a material or a nested node) by a weighted hash of its cell id. The
//!   lepidolite puts maps of dark and bright tiles inside a map of bigger tiles.
//! * [`Switch`]: a Perlin / fBm / turbulence / marble function whose value
//!   range is partitioned into entries; evaluated per point or per Voronoi
//!   cell (the function sampled at the cell's feature point, so whole facets
//!   switch and stay polygonal), figure 4.7 (b).
//! * [`GlitterMap`] (②) with its [`FacetBumpMap`] (④): bigger cells, most
//!   transparent; filled cells hold a glitter material and tilted facets.
//! * [`Pattern::resolve`] combines them as ⑤: the glitter material with its
//!   facet normal where a glitter cell is filled, the surface map elsewhere.
//!
//! # Hash definition (a contract: tests re-implement it literally)
//!
//! With `u(h, s) = unit_f64(derive_stream(h, s))` (see [`crate::texture::hash`]):
//!
//! * a surface-map cell with id `h` (its [`Voronoi::nearest`] `cell_id`) takes
//!   entry `i`, the first index with `u(h, STREAM_ENTRY) < C[i]`, where
//!   `C[i] = (w₀ + … + wᵢ) / (w₀ + … + w_{n−1})` (the last `C` is exactly 1);
//! * a glitter cell `h` is filled iff `u(h, STREAM_FILL) < fill_fraction`, and
//!   then takes glitter entry `i` as above with `u(h, STREAM_GLITTER_ENTRY)`;
//! * a facet cell `h` has azimuth `φ = 2π · u(h, STREAM_AZIMUTH)` and tilt
//!   `θ = acos(1 − u(h, STREAM_TILT) · (1 − cos θmax))` (uniform cone: `cos θ`
//!   uniform in `[cos θmax, 1]`) or `θ = min(σ · |√(−2 ln(1 − u₁)) · cos(2π u₂)|, 90°)`
//!   with `u₁ = u(h, STREAM_TILT)`, `u₂ = u(h, STREAM_GAUSS)` (Box–Muller:
//!   `|N(0, σ)|`, clamped below the horizon).
//!
//! Everything is pure in `(seeds, point)` and every type is `Send + Sync`.
//!
//! # The resolve cache
//!
//! A render resolves runs of nearby points (a pixel's samples, then the next
//! pixel's). [`Pattern::resolve`] keeps, per thread, the last nearest site of
//! each Voronoi of the tree with a region where it provably stays the
//! nearest ([`CertifiedNearest`]), the entry each map chose for its site,
//! and a table of per-cell switch reads (the marble at inclusion sites).
//! Entries are tagged with [`Pattern::id`]. Nothing in the cache can change
//! an answer: it equals [`Pattern::resolve_uncached`] bit for bit
//! (`tests/texture_cache.rs`), so images do not depend on the thread count.

use glam::{DVec3, IVec3};
use std::cell::RefCell;
use std::f64::consts::TAU;
use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};

use super::hash::{derive_stream, unit_f64};
use super::noise_fns::{Fbm, Marble, PerlinNoise, Turbulence};
use super::voronoi::{floor_fast, CertifiedNearest, Voronoi, VoronoiNearest, VoronoiSite};
use crate::sampling::unit_direction;

/// Stream of a surface-map cell's entry choice.
pub const STREAM_ENTRY: u64 = 1;
/// Stream of a glitter cell's fill decision.
pub const STREAM_FILL: u64 = 2;
/// Stream of a filled glitter cell's entry choice.
pub const STREAM_GLITTER_ENTRY: u64 = 3;
/// Stream of a facet cell's tilt (`cos θ` or the Box–Muller radius).
pub(crate) const STREAM_TILT: u64 = 4;
/// Stream of a facet cell's azimuth.
pub(crate) const STREAM_AZIMUTH: u64 = 5;
/// Stream of the Box–Muller angle of a Gaussian tilt.
pub(crate) const STREAM_GAUSS: u64 = 6;

/// A reference inside the tree: a material (index into the gem's material
/// list) or another node (index into [`Pattern::nodes`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Entry {
    /// Leaf: material number `u32` of the gem.
    Material(u32),
    /// A nested surface map or switch, [`Pattern::nodes`]`[u32]`.
    Node(u32),
}

/// Why a pattern could not be built (bad indices, cycles, weights, ranges).
/// The recipe layer turns these into `file:line:col` errors before they can
/// happen; this type guards hand-built patterns.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PatternError(pub String);

impl fmt::Display for PatternError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PatternError {}

/// Entries with weights, stored as a cumulative table so that a pick is a
/// short search, not a sum, per query.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightedEntries<T> {
    items: Vec<T>,
    weights: Vec<f64>,
    cumulative: Vec<f64>,
}

impl<T: Copy> WeightedEntries<T> {
    /// Builds the table; weights must be finite and ≥ 0 with a positive sum.
    pub fn new(entries: Vec<(T, f64)>) -> Result<Self, PatternError> {
        if entries.is_empty() {
            return Err(PatternError(
                "a weighted list needs at least one entry".into(),
            ));
        }
        if let Some((_, w)) = entries.iter().find(|(_, w)| !w.is_finite() || *w < 0.0) {
            return Err(PatternError(format!(
                "weight {w} is not allowed; allowed: finite and >= 0"
            )));
        }
        let total: f64 = entries.iter().map(|(_, w)| w).sum();
        if total <= 0.0 || !total.is_finite() {
            return Err(PatternError(format!(
                "weights sum to {total}; allowed: at least one weight > 0"
            )));
        }
        let mut running = 0.0;
        let mut cumulative: Vec<f64> = entries
            .iter()
            .map(|(_, w)| {
                running += w;
                running / total
            })
            .collect();
        *cumulative.last_mut().expect("non-empty") = 1.0;
        Ok(WeightedEntries {
            items: entries.iter().map(|(t, _)| *t).collect(),
            weights: entries.iter().map(|(_, w)| *w).collect(),
            cumulative,
        })
    }

    /// The entry for a uniform `u ∈ [0, 1)`: the first `i` with `u < C[i]`.
    #[inline]
    pub(crate) fn pick(&self, u: f64) -> T {
        let i = self.cumulative.partition_point(|c| *c <= u);
        self.items[i.min(self.items.len() - 1)]
    }

    /// The entries in declaration order.
    pub fn items(&self) -> &[T] {
        &self.items
    }

    /// The weights as given.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Never true for a built table (kept for clippy's `len_without_is_empty`).
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }
}

/// Figure 4.6 ①: each Voronoi cell picks one entry by a weighted hash of
/// its cell id (module documentation), so a facet is one material throughout.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMap {
    /// The cells (their size sets the facet size).
    pub voronoi: Voronoi,
    /// What a cell may hold, with weights.
    pub entries: WeightedEntries<Entry>,
}

impl SurfaceMap {
    /// Builds a map; see [`WeightedEntries::new`] for the weight rules.
    pub fn new(voronoi: Voronoi, entries: Vec<(Entry, f64)>) -> Result<Self, PatternError> {
        check_cell_size(voronoi.cell_size, "surface map")?;
        Ok(SurfaceMap {
            voronoi,
            entries: WeightedEntries::new(entries)?,
        })
    }

    /// The entry chosen by the cell with id `cell_id`.
    #[inline]
    pub fn entry_of_cell(&self, cell_id: u64) -> Entry {
        self.entries
            .pick(unit_f64(derive_stream(cell_id, STREAM_ENTRY)))
    }
}

fn check_cell_size(cell_size: f64, what: &str) -> Result<(), PatternError> {
    if cell_size.is_finite() && cell_size > 0.0 {
        Ok(())
    } else {
        Err(PatternError(format!(
            "{what} cell size {cell_size} is not allowed; allowed: finite and > 0"
        )))
    }
}

/// The function a [`Switch`] reads (section 4.3.1: marble for the
/// lepidolite, Perlin functions for the patterned sunstone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SwitchFunction {
    /// Plain Perlin noise, values in `[-1, 1]`.
    Perlin(PerlinNoise),
    /// fBm, values in `[-B, B]` with `B` its amplitude bound.
    Fbm(Fbm),
    /// Turbulence, values in `[0, B]`.
    Turbulence(Turbulence),
    /// Marble, values in `[0, 1]`.
    Marble(Marble),
}

impl SwitchFunction {
    /// The function's value at `p`.
    #[inline]
    pub fn value(&self, p: DVec3) -> f64 {
        match self {
            SwitchFunction::Perlin(f) => f.value(p),
            SwitchFunction::Fbm(f) => f.value(p),
            SwitchFunction::Turbulence(f) => f.value(p),
            SwitchFunction::Marble(f) => f.value(p),
        }
    }

    /// `[min, max]` of the values: the interval a switch's ranges must
    /// partition.
    pub fn range(&self) -> (f64, f64) {
        match self {
            SwitchFunction::Perlin(_) => (-1.0, 1.0),
            SwitchFunction::Fbm(f) => (-f.amplitude_bound(), f.amplitude_bound()),
            SwitchFunction::Turbulence(f) => (0.0, f.amplitude_bound()),
            SwitchFunction::Marble(_) => (0.0, 1.0),
        }
    }
}

/// One value range `[from, to)` of a switch and the entry it selects (the
/// last range also takes `to` itself, the function's maximum).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchRange {
    /// Lower end (inclusive).
    pub from: f64,
    /// Upper end (exclusive, except for the last range).
    pub to: f64,
    /// What this range selects.
    pub entry: Entry,
}

/// Figure 4.7 (b): a function whose value picks the next node or material.
#[derive(Clone, Debug, PartialEq)]
pub struct Switch {
    /// The function read.
    pub function: SwitchFunction,
    /// Ranges in increasing order, partitioning `function.range()` exactly.
    ranges: Vec<SwitchRange>,
    /// If set, the function is read at the feature point of the cell of
    /// this Voronoi that contains the point, so whole cells switch together.
    pub per_cell: Option<Voronoi>,
    /// The ranges seen as arcs of marble phase (derived from `ranges` in
    /// [`Switch::new`]; used when `function` is a marble).
    marble_arcs: Option<PhaseArcs>,
}

/// A marble switch's ranges as arcs of the phase φ of
/// `0.5 + 0.5 sin φ` (noise_fns, Marble): the value crosses the inner range
/// boundary `t` only where `sin φ = 2t − 1`, at the *critical* phases
/// `asin(2t − 1)` and `π − asin(2t − 1)` (mod 2π). Between two neighbouring
/// critical phases the selected range cannot change, so a phase interval
/// that lies inside one arc (with a margin far above rounding) settles the
/// switch without the remaining octaves of turbulence.
#[derive(Clone, Debug, PartialEq)]
struct PhaseArcs {
    /// Critical phases in `[0, 2π)`, increasing.
    critical: Vec<f64>,
    /// `entries[j]`: the entry of the arc ending at `critical[j]`; the last
    /// one (arc after the last critical phase) equals `entries[0]` (wraps).
    entries: Vec<Entry>,
}

/// Range boundaries with `|2t − 1|` above this are left to the general
/// path: near an extremum of sin, rounding of the value maps to a wide
/// phase uncertainty (√ of it).
const MAX_ARC_SINE: f64 = 1.0 - 1e-6;

impl PhaseArcs {
    /// The arcs of `ranges` (partitioning `[0, 1]`); None when a boundary
    /// sits too close to 0 or 1 (see [`MAX_ARC_SINE`]).
    fn new(ranges: &[SwitchRange]) -> Option<Self> {
        let mut critical = Vec::new();
        for r in &ranges[..ranges.len() - 1] {
            let s = 2.0 * r.to - 1.0;
            if s.is_nan() || s.abs() >= MAX_ARC_SINE {
                return None;
            }
            let a = s.asin();
            critical.push(if a < 0.0 { a + TAU } else { a });
            critical.push(std::f64::consts::PI - a);
        }
        critical.sort_by(f64::total_cmp);
        let n = critical.len();
        let entry_at = |phase: f64| {
            let v = 0.5 + 0.5 * phase.sin();
            let i = ranges.partition_point(|r| r.to <= v).min(ranges.len() - 1);
            ranges[i].entry
        };
        let mut entries: Vec<Entry> = (0..n)
            .map(|j| {
                let start = if j == 0 {
                    critical[n - 1] - TAU
                } else {
                    critical[j - 1]
                };
                entry_at(0.5 * (start + critical[j]))
            })
            .collect();
        entries.push(entries.first().copied().unwrap_or(ranges[0].entry));
        Some(PhaseArcs { critical, entries })
    }

    /// The entry if every phase in `[low, high]` (widened by a margin of
    /// 10⁻⁹·(1 + |φ|) rad against rounding) lies inside one arc.
    #[inline]
    fn settle(&self, low: f64, high: f64) -> Option<Entry> {
        let n = self.critical.len();
        if n == 0 {
            return Some(self.entries[0]);
        }
        // Also false for NaN: the general path then decides.
        let width = high - low;
        if width.is_nan() || width >= TAU {
            return None;
        }
        let margin = 1e-9 * (1.0 + low.abs().max(high.abs()));
        let turns = floor_fast(low / TAU);
        let low_turn = low - turns * TAU;
        let high_turn = low_turn + width;
        let j = self.critical.partition_point(|c| *c <= low_turn);
        let previous = if j == 0 {
            self.critical[n - 1] - TAU
        } else {
            self.critical[j - 1]
        };
        let next = if j == n {
            self.critical[0] + TAU
        } else {
            self.critical[j]
        };
        (low_turn - margin > previous && high_turn + margin < next).then(|| self.entries[j])
    }
}

/// Relative tolerance for ranges meeting the function's ends and each other.
const RANGE_TOLERANCE: f64 = 1e-9;

/// Checks that `ranges` partition `[lo, hi]` (contiguous, increasing, no
/// gaps or overlaps, covering both ends); the error names the problem.
pub(crate) fn check_partition(ranges: &[(f64, f64)], lo: f64, hi: f64) -> Result<(), PatternError> {
    let tol = RANGE_TOLERANCE * (hi - lo).abs().max(1.0);
    let close = |a: f64, b: f64| (a - b).abs() <= tol;
    let Some(first) = ranges.first() else {
        return Err(PatternError("a switch needs at least one range".into()));
    };
    if !close(first.0, lo) {
        return Err(PatternError(format!(
            "the first range starts at {} but the function's values start at {lo}; \
             the ranges must cover [{lo}, {hi}] without gaps or overlaps",
            first.0
        )));
    }
    for (k, (from, to)) in ranges.iter().enumerate() {
        if !(from.is_finite() && to.is_finite() && from < to) {
            return Err(PatternError(format!(
                "range {} is [{from}, {to}); allowed: finite with from < to",
                k + 1
            )));
        }
        if k > 0 {
            let previous_to = ranges[k - 1].1;
            if !close(*from, previous_to) {
                let what = if *from > previous_to {
                    "gap"
                } else {
                    "overlap"
                };
                return Err(PatternError(format!(
                    "{what} between range {} (ends at {previous_to}) and range {} (starts at {from}); \
                     each range must start where the previous one ends",
                    k,
                    k + 1
                )));
            }
        }
    }
    let last = ranges.last().expect("non-empty").1;
    if !close(last, hi) {
        return Err(PatternError(format!(
            "the last range ends at {last} but the function's values reach {hi}; \
             the ranges must cover [{lo}, {hi}] without gaps or overlaps"
        )));
    }
    Ok(())
}

impl Switch {
    /// Builds a switch; the ranges must partition `function.range()`
    /// (`check_partition`). The outer ends are snapped to the exact range.
    pub fn new(
        function: SwitchFunction,
        mut ranges: Vec<SwitchRange>,
        per_cell: Option<Voronoi>,
    ) -> Result<Self, PatternError> {
        let (lo, hi) = function.range();
        let pairs: Vec<(f64, f64)> = ranges.iter().map(|r| (r.from, r.to)).collect();
        check_partition(&pairs, lo, hi)?;
        if let Some(v) = &per_cell {
            check_cell_size(v.cell_size, "switch per-cell")?;
        }
        ranges[0].from = lo;
        ranges.last_mut().expect("non-empty").to = hi;
        for k in 1..ranges.len() {
            ranges[k].from = ranges[k - 1].to;
        }
        let marble_arcs = match function {
            SwitchFunction::Marble(_) => PhaseArcs::new(&ranges),
            _ => None,
        };
        Ok(Switch {
            function,
            ranges,
            per_cell,
            marble_arcs,
        })
    }

    /// The ranges in increasing order.
    pub fn ranges(&self) -> &[SwitchRange] {
        &self.ranges
    }

    /// Index of the range holding value `v` (clamped into the function's range).
    #[inline]
    pub(crate) fn range_index(&self, v: f64) -> usize {
        let i = self.ranges.partition_point(|r| r.to <= v);
        i.min(self.ranges.len() - 1)
    }

    /// Where the function is read for point `p`: `p` itself, or the feature
    /// point of its cell when switching per cell.
    #[inline]
    pub(crate) fn sample_point(&self, p: DVec3) -> DVec3 {
        match &self.per_cell {
            Some(v) => v.nearest(p).feature_point,
            None => p,
        }
    }

    /// The entry selected at `p`.
    #[inline]
    pub fn select(&self, p: DVec3) -> Entry {
        self.select_at_sample(self.sample_point(p))
    }

    /// The entry selected when the function is read at `sample` (the
    /// result of `sample_point`).
    #[inline]
    pub fn select_at_sample(&self, sample: DVec3) -> Entry {
        // A marble is often settled before its last octaves (`PhaseArcs`);
        // the result is the same entry as the general path's, always.
        if let (SwitchFunction::Marble(m), Some(arcs)) = (&self.function, &self.marble_arcs) {
            return match m.value_unless(sample, |low, high| arcs.settle(low, high)) {
                Ok(entry) => entry,
                Err(v) => self.ranges[self.range_index(v)].entry,
            };
        }
        let v = self.function.value(sample);
        self.ranges[self.range_index(v)].entry
    }
}

/// Distribution of a facet's tilt angle θ away from its axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tilt {
    /// Normals uniform over the cone of half-angle `max_tilt_deg`
    /// (`cos θ` uniform in `[cos max, 1]`).
    UniformCone {
        /// Half-angle of the cone in degrees, `[0, 90]`.
        max_tilt_deg: f64,
    },
    /// `θ = |N(0, σ)|` (clamped at 90°): most flakes nearly aligned, a few
    /// strongly tilted.
    Gaussian {
        /// σ of the tilt in degrees, > 0.
        sigma_tilt_deg: f64,
    },
}

/// The axis facets are tilted around.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Around {
    /// The stone's (shading) normal at the hit: flakes lie roughly parallel
    /// to the surface.
    SurfaceNormal,
    /// A fixed object-space direction (unit): sunstone platelets parallel to
    /// one cleavage plane, whatever the cut.
    Direction(DVec3),
}

/// Figure 4.6 ④: the crystal-facet bump map of the filled glitter cells.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FacetBumpMap {
    /// The facet cells (cell size ≤ the glitter cells').
    pub voronoi: Voronoi,
    /// Tilt distribution.
    pub tilt: Tilt,
    /// Axis of the tilt.
    pub around: Around,
}

/// A facet's tilted normal: angles relative to an axis, and the axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlakeNormal {
    /// Tilt from the axis, radians, `[0, π/2]`.
    pub theta: f64,
    /// Azimuth around the axis, radians, `[0, 2π)`.
    pub phi: f64,
    /// Which axis the tilt is relative to.
    pub around: Around,
}

impl FlakeNormal {
    /// The normal in the local frame whose z axis is the tilt axis.
    #[inline]
    pub fn local(&self) -> DVec3 {
        let (s, c) = self.theta.sin_cos();
        let (sp, cp) = self.phi.sin_cos();
        DVec3::new(s * cp, s * sp, c)
    }

    /// The normal in object space, given the stone's normal at the hit
    /// (used when `around` is [`Around::SurfaceNormal`]; ignored otherwise).
    pub fn world(&self, surface_normal: DVec3) -> DVec3 {
        let axis = match self.around {
            Around::SurfaceNormal => surface_normal,
            Around::Direction(d) => d,
        }
        .normalize();
        let (t, b) = axis.any_orthonormal_pair();
        let l = self.local();
        t * l.x + b * l.y + axis * l.z
    }
}

impl FacetBumpMap {
    /// Builds a facet map; checks the cell size and the tilt parameters.
    pub fn new(voronoi: Voronoi, tilt: Tilt, around: Around) -> Result<Self, PatternError> {
        check_cell_size(voronoi.cell_size, "facet")?;
        match tilt {
            Tilt::UniformCone { max_tilt_deg } if !(0.0..=90.0).contains(&max_tilt_deg) => {
                return Err(PatternError(format!(
                    "max_tilt_deg = {max_tilt_deg}; allowed: 0 <= max_tilt_deg <= 90"
                )))
            }
            Tilt::Gaussian { sigma_tilt_deg }
                if !(sigma_tilt_deg > 0.0 && sigma_tilt_deg <= 90.0) =>
            {
                return Err(PatternError(format!(
                    "sigma_tilt_deg = {sigma_tilt_deg}; allowed: 0 < sigma_tilt_deg <= 90"
                )))
            }
            _ => {}
        }
        let around = match around {
            Around::Direction(d) => match unit_direction(d) {
                Some(unit) => Around::Direction(unit),
                None => {
                    return Err(PatternError(format!(
                    "facet direction ({:?}, {:?}, {:?}); allowed: any finite non-zero direction",
                    d.x, d.y, d.z
                )))
                }
            },
            a => a,
        };
        Ok(FacetBumpMap {
            voronoi,
            tilt,
            around,
        })
    }

    /// The tilted normal of the facet cell with id `cell_id` (module
    /// documentation for the exact formulas).
    #[inline]
    pub(crate) fn normal_of_cell(&self, cell_id: u64) -> FlakeNormal {
        self.normal_from(
            unit_f64(derive_stream(cell_id, STREAM_TILT)),
            || unit_f64(derive_stream(cell_id, STREAM_GAUSS)),
            unit_f64(derive_stream(cell_id, STREAM_AZIMUTH)),
        )
    }

    /// The tilted normal the numbers `u_tilt`, `u_gauss()` (asked for by
    /// a Gaussian tilt only) and `u_azimuth` in [0, 1) give: a facet
    /// cell's from its hashes, or any facet of the map's distribution.
    #[inline]
    pub(crate) fn normal_from(
        &self,
        u_tilt: f64,
        u_gauss: impl FnOnce() -> f64,
        u_azimuth: f64,
    ) -> FlakeNormal {
        let theta = match self.tilt {
            Tilt::UniformCone { max_tilt_deg } => {
                let cos_max = max_tilt_deg.to_radians().cos();
                (1.0 - u_tilt * (1.0 - cos_max)).clamp(-1.0, 1.0).acos()
            }
            Tilt::Gaussian { sigma_tilt_deg } => {
                let normal = (-2.0 * (1.0 - u_tilt).ln()).sqrt() * (TAU * u_gauss()).cos();
                (sigma_tilt_deg.to_radians() * normal.abs()).min(std::f64::consts::FRAC_PI_2)
            }
        };
        FlakeNormal {
            theta,
            phi: TAU * u_azimuth,
            around: self.around,
        }
    }

    /// The facet normal at `p` and the facet cell's id.
    #[inline]
    pub fn normal_at(&self, p: DVec3) -> (FlakeNormal, u64) {
        let id = self.voronoi.nearest(p).cell_id;
        (self.normal_of_cell(id), id)
    }
}

/// Figure 4.6 ②: big cells standing for whole particles; a cell is filled
/// iff `u(h, STREAM_FILL) < fill_fraction`, the rest are transparent.
#[derive(Clone, Debug, PartialEq)]
pub struct GlitterMap {
    /// The particle cells.
    pub voronoi: Voronoi,
    /// Expected fraction of filled cells, `[0, 1]` ("only very few" for
    /// the lepidolite).
    pub fill_fraction: f64,
    /// Optional modulation: the fill threshold becomes
    /// `fill_fraction · clamp(f(feature point), 0, 1)` (the patterned sunstone).
    pub fill_modulation: Option<SwitchFunction>,
    /// Glitter materials (metal base under the varnish) with weights.
    pub entries: WeightedEntries<u32>,
    /// The facets of the filled cells (④).
    pub facets: FacetBumpMap,
}

impl GlitterMap {
    /// Builds a glitter map; checks fill fraction, weights and that facets
    /// are no bigger than particles.
    pub fn new(
        voronoi: Voronoi,
        fill_fraction: f64,
        entries: Vec<(u32, f64)>,
        facets: FacetBumpMap,
    ) -> Result<Self, PatternError> {
        check_cell_size(voronoi.cell_size, "glitter")?;
        if !(0.0..=1.0).contains(&fill_fraction) {
            return Err(PatternError(format!(
                "fill_fraction = {fill_fraction}; allowed: 0 <= fill_fraction <= 1"
            )));
        }
        if facets.voronoi.cell_size > voronoi.cell_size {
            return Err(PatternError(format!(
                "facet cell size {} is larger than the glitter cell size {}; allowed: facet cell size <= glitter cell size",
                facets.voronoi.cell_size, voronoi.cell_size
            )));
        }
        Ok(GlitterMap {
            voronoi,
            fill_fraction,
            fill_modulation: None,
            entries: WeightedEntries::new(entries)?,
            facets,
        })
    }

    /// Whether the glitter cell with id `cell_id` (feature point `site`) is filled.
    #[inline]
    pub(crate) fn is_filled(&self, cell_id: u64, site: DVec3) -> bool {
        let threshold = match &self.fill_modulation {
            None => self.fill_fraction,
            Some(f) => self.fill_fraction * f.value(site).clamp(0.0, 1.0),
        };
        unit_f64(derive_stream(cell_id, STREAM_FILL)) < threshold
    }

    /// The glitter material of a filled cell.
    #[inline]
    pub(crate) fn material_of_cell(&self, cell_id: u64) -> u32 {
        self.entries
            .pick(unit_f64(derive_stream(cell_id, STREAM_GLITTER_ENTRY)))
    }
}

/// A node of the flat tree.
///
/// A switch holds its Perlin table inline (~300 bytes): nodes are few and
/// stored contiguously, and boxing would add a pointer chase per query.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    /// A Voronoi surface map (①).
    Map(SurfaceMap),
    /// A function switch (figure 4.7 b).
    Switch(Switch),
}

impl Node {
    fn children(&self) -> Vec<Entry> {
        match self {
            Node::Map(m) => m.entries.items().to_vec(),
            Node::Switch(s) => s.ranges().iter().map(|r| r.entry).collect(),
        }
    }
}

/// What a point of the stone is made of (figure 4.6 ⑤).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolved {
    /// Index of the material in the gem's material list.
    pub material: u32,
    /// The facet normal, for points in a filled glitter cell.
    pub flake_normal: Option<FlakeNormal>,
    /// Cell id of the deepest surface-map cell on the way (0 when the
    /// surface is a bare material).
    pub surface_cell: u64,
    /// Cell id of the filled glitter cell, if the point is glitter.
    pub glitter_cell: Option<u64>,
    /// Node index of the surface map that chose the surface material
    /// (`u32::MAX` when none did).
    pub map_index: u32,
}

impl Resolved {
    /// The point's answer from its surface `(material, cell, map index)`
    /// (what [`Pattern::resolve_surface`] returns) and, when it lies in a
    /// filled glitter cell, that flake's `(material, normal, cell)`, which
    /// covers the surface.
    #[inline]
    fn new(surface: (u32, u64, u32), flake: Option<(u32, FlakeNormal, u64)>) -> Resolved {
        let (surface_material, surface_cell, map_index) = surface;
        Resolved {
            material: flake.map_or(surface_material, |f| f.0),
            flake_normal: flake.map(|f| f.1),
            surface_cell,
            glitter_cell: flake.map(|f| f.2),
            map_index,
        }
    }
}

/// The compiled pattern: flat nodes, the surface root and the optional
/// glitter layer. Plain data, `Send + Sync`, immutable once built.
///
/// Equality compares the tree, not [`Pattern::id`]: two patterns built
/// alike are equal even though each has its own id.
#[derive(Clone, Debug)]
pub struct Pattern {
    nodes: Vec<Node>,
    root: Entry,
    glitter: Option<GlitterMap>,
    material_count: u32,
    id: u64,
}

impl PartialEq for Pattern {
    fn eq(&self, other: &Self) -> bool {
        self.nodes == other.nodes
            && self.root == other.root
            && self.glitter == other.glitter
            && self.material_count == other.material_count
    }
}

/// Source of [`Pattern::id`]s: each built pattern takes the next number
/// (ids start at 1; 0 marks an unused cache).
static NEXT_PATTERN_ID: AtomicU64 = AtomicU64::new(1);

impl Pattern {
    /// Builds a pattern over `material_count` materials; checks every index
    /// and that no node contains itself (directly or through others).
    pub fn new(
        nodes: Vec<Node>,
        root: Entry,
        glitter: Option<GlitterMap>,
        material_count: u32,
    ) -> Result<Self, PatternError> {
        let check = |e: Entry| match e {
            Entry::Material(m) if m >= material_count => Err(PatternError(format!(
                "material index {m} out of bounds ({material_count} materials)"
            ))),
            Entry::Node(n) if n as usize >= nodes.len() => Err(PatternError(format!(
                "node index {n} out of bounds ({} nodes)",
                nodes.len()
            ))),
            _ => Ok(()),
        };
        check(root)?;
        // Each node's children, listed once (a node may have many thousands).
        let children: Vec<Vec<Entry>> = nodes.iter().map(Node::children).collect();
        for child in children.iter().flatten() {
            check(*child)?;
        }
        if let Some(g) = &glitter {
            for m in g.entries.items() {
                check(Entry::Material(*m))?;
            }
        }
        // Cycle check: depth-first colouring.
        let mut state = vec![0u8; nodes.len()]; // 0 new, 1 on stack, 2 done
        for start in 0..nodes.len() {
            if state[start] != 0 {
                continue;
            }
            let mut stack = vec![(start, 0usize)];
            state[start] = 1;
            while let Some((n, k)) = stack.pop() {
                let children = &children[n];
                if k < children.len() {
                    stack.push((n, k + 1));
                    if let Entry::Node(c) = children[k] {
                        let c = c as usize;
                        match state[c] {
                            1 => {
                                return Err(PatternError(format!(
                                    "node {c} contains itself (through node {n})"
                                )))
                            }
                            0 => {
                                state[c] = 1;
                                stack.push((c, 0));
                            }
                            _ => {}
                        }
                    }
                } else {
                    state[n] = 2;
                }
            }
        }
        Ok(Pattern {
            nodes,
            root,
            glitter,
            material_count,
            id: NEXT_PATTERN_ID.fetch_add(1, Ordering::Relaxed),
        })
    }

    /// This pattern's identity for the per-thread resolve cache: unique
    /// among patterns built by [`Pattern::new`] in this process, shared by
    /// clones (which are equal and, like every pattern, immutable).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// The nodes.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The surface root.
    pub fn root(&self) -> Entry {
        self.root
    }

    /// The glitter layer, if any.
    pub fn glitter(&self) -> Option<&GlitterMap> {
        self.glitter.as_ref()
    }

    /// The surface side alone (figure 4.6 ①, through switches): material,
    /// deepest surface cell id and the map that chose it.
    #[inline]
    pub fn resolve_surface(&self, p: DVec3) -> (u32, u64, u32) {
        let mut entry = self.root;
        let mut cell = 0;
        let mut map_index = u32::MAX;
        // A per-cell switch and the map below it often share their cells
        // (`per_cell_of` in a recipe): reuse the last nearest-site query.
        let mut last: Option<(&Voronoi, VoronoiNearest)> = None;
        // Acyclic (checked in `new`), so at most nodes.len() steps.
        for _ in 0..=self.nodes.len() {
            match entry {
                Entry::Material(m) => return (m, cell, map_index),
                Entry::Node(n) => {
                    entry = match &self.nodes[n as usize] {
                        Node::Map(map) => {
                            let near = match last {
                                Some((v, near)) if *v == map.voronoi => near,
                                _ => map.voronoi.nearest(p),
                            };
                            last = Some((&map.voronoi, near));
                            cell = near.cell_id;
                            map_index = n;
                            map.entry_of_cell(near.cell_id)
                        }
                        Node::Switch(s) => match &s.per_cell {
                            Some(v) => {
                                let near = match last {
                                    Some((w, near)) if w == v => near,
                                    _ => v.nearest(p),
                                };
                                last = Some((v, near));
                                s.select_at_sample(near.feature_point)
                            }
                            None => s.select_at_sample(p),
                        },
                    }
                }
            }
        }
        unreachable!("pattern tree is acyclic by construction")
    }

    /// Figure 4.6 ⑤: glitter (with its facet normal) where the glitter cell
    /// is filled, the surface map's material elsewhere.
    ///
    /// Always exactly [`Pattern::resolve_uncached`]`(p)`, but cheaper for
    /// runs of nearby points (a pixel's samples): a per-thread cache keeps,
    /// per Voronoi of the tree, the last nearest site with a region where
    /// it provably stays the nearest ([`CertifiedNearest`]), and per node
    /// what it selected for that site (the marble read at an inclusion
    /// cell's feature point, a map's entry, a glitter cell's fill). Results
    /// never depend on what the cache holds, so images do not depend on the
    /// thread count or schedule (only the work done does).
    ///
    /// A plain stone (one material, no maps, no glitter) is answered
    /// inline without a call: what `resolve_surface` returns for a bare
    /// root, the material with cell 0 and no map (out of line, every stone
    /// hit paid for a call and the 64-byte answer through memory).
    #[inline(always)]
    pub fn resolve(&self, p: DVec3) -> Resolved {
        match (self.root, self.glitter.is_none()) {
            (Entry::Material(material), true) => Resolved::new((material, 0, u32::MAX), None),
            _ => self.resolve_textured(p),
        }
    }

    /// [`Pattern::resolve`] of a pattern with a map or glitter.
    #[inline(never)] // one call per hit; keeps callers' inlining stable
    fn resolve_textured(&self, p: DVec3) -> Resolved {
        RESOLVE_CACHE.with_borrow_mut(|cache| {
            if cache.pattern.pattern_id != self.id {
                cache.pattern = PatternMemos::EMPTY;
                cache.pattern.pattern_id = self.id;
            }
            self.resolve_cached(p, cache)
        })
    }

    /// [`Pattern::resolve`] through `cache`, which holds this pattern's
    /// entries (or none).
    #[inline]
    fn resolve_cached(&self, p: DVec3, cache: &mut ResolveCache) -> Resolved {
        let surface =
            self.resolve_surface_cached(p, &mut cache.pattern.nodes, &mut cache.switch_reads);
        if let Some(g) = &self.glitter {
            let glitter = &mut cache.pattern.glitter;
            let site = glitter.site(&g.voronoi, p);
            let filled_material = glitter.selection(site, |s| {
                g.is_filled(s.cell_id, s.feature_point)
                    .then(|| g.material_of_cell(s.cell_id))
            });
            if let Some(material) = filled_material {
                let facet_id = cache.pattern.facets.site(&g.facets.voronoi, p).cell_id;
                let flake = (material, g.facets.normal_of_cell(facet_id), site.cell_id);
                return Resolved::new(surface, Some(flake));
            }
        }
        Resolved::new(surface, None)
    }

    /// [`Pattern::resolve_surface`] through the per-node memos of a
    /// [`ResolveCache`]; nodes past the cache's size are looked up plainly.
    #[inline]
    fn resolve_surface_cached(
        &self,
        p: DVec3,
        memos: &mut [NodeMemo<Entry>; CACHED_NODES],
        switch_reads: &mut SwitchReads,
    ) -> (u32, u64, u32) {
        let mut entry = self.root;
        let mut cell = 0;
        let mut map_index = u32::MAX;
        // A per-cell switch and the map below it often share their cells.
        let mut last: Option<(&Voronoi, VoronoiSite)> = None;
        // Acyclic (checked in `new`), so at most nodes.len() steps.
        for _ in 0..=self.nodes.len() {
            let n = match entry {
                Entry::Material(m) => return (m, cell, map_index),
                Entry::Node(n) => n,
            };
            let node = &self.nodes[n as usize];
            let voronoi = match node {
                Node::Map(map) => &map.voronoi,
                Node::Switch(s) => match &s.per_cell {
                    Some(v) => v,
                    None => {
                        entry = s.select_at_sample(p);
                        continue;
                    }
                },
            };
            let mut memo = memos.get_mut(n as usize);
            let site = match last {
                Some((v, site)) if v == voronoi => site,
                _ => match memo.as_deref_mut() {
                    Some(memo) => memo.site(voronoi, p),
                    None => voronoi.nearest(p).site(),
                },
            };
            last = Some((voronoi, site));
            entry = match node {
                Node::Map(map) => {
                    cell = site.cell_id;
                    map_index = n;
                    match memo {
                        Some(memo) => memo.selection(site, |s| map.entry_of_cell(s.cell_id)),
                        None => map.entry_of_cell(site.cell_id),
                    }
                }
                // The marble read is the expensive part: memoised per site
                // in a table, as a row of pixels revisits the sites of the
                // row before.
                Node::Switch(s) => switch_reads.entry(self.id, n, &site, |site| {
                    s.select_at_sample(site.feature_point)
                }),
            };
        }
        unreachable!("pattern tree is acyclic by construction")
    }

    /// The reference [`Pattern::resolve`] is tested against: every Voronoi
    /// searched and every switch read afresh.
    #[inline]
    pub fn resolve_uncached(&self, p: DVec3) -> Resolved {
        let surface = self.resolve_surface(p);
        if let Some(g) = &self.glitter {
            let near = g.voronoi.nearest(p);
            if g.is_filled(near.cell_id, near.feature_point) {
                let (normal, _) = g.facets.normal_at(p);
                let flake = (g.material_of_cell(near.cell_id), normal, near.cell_id);
                return Resolved::new(surface, Some(flake));
            }
        }
        Resolved::new(surface, None)
    }
}

/// How many nodes of a tree get a memo in the per-thread cache (the built-in
/// gems have at most 5); the glitter and facet maps have their own.
const CACHED_NODES: usize = 8;

/// A cache entry for one Voronoi of a tree: the certified nearest site of
/// the last search, and what its node selected for the site it last saw.
#[derive(Clone, Copy)]
struct NodeMemo<T> {
    /// The last search's site and the region where it stays the nearest.
    certified: CertifiedNearest,
    /// The site the selection was made for (cell id and cell pin it down:
    /// the feature point is a function of them).
    selected_for: Option<(u64, IVec3)>,
    /// What the node selected for that site.
    selection: T,
    /// Whether the current certificate has answered a lookup. A certified
    /// search costs about 2.5 plain ones, so after a certificate that
    /// answered nothing (cells small against the steps between lookups)
    /// misses use plain searches, probing with a new certificate now and
    /// then: after 4 plain searches, twice as many after each further
    /// unpaid certificate (up to 64), so incoherent lookups cost little more
    /// than uncached ones.
    certificate_paid: bool,
    /// Unpaid certificates in a row (capped at [`MAX_UNPAID_STREAK`]).
    unpaid_streak: u32,
    /// Plain searches since the last certified one.
    plain_searches: u32,
}

/// Plain searches after one unpaid certificate before the next certified one.
const PLAIN_SEARCHES_BEFORE_PROBE: u32 = 4;

/// Cap of [`NodeMemo::unpaid_streak`]: at most `4 · 2⁴ = 64` plain searches
/// between probes.
const MAX_UNPAID_STREAK: u32 = 4;

impl<T: Copy> NodeMemo<T> {
    /// An entry that covers no point and has selected nothing.
    const fn empty(nothing: T) -> Self {
        NodeMemo {
            certified: CertifiedNearest::EMPTY,
            selected_for: None,
            selection: nothing,
            certificate_paid: true,
            unpaid_streak: 0,
            plain_searches: 0,
        }
    }

    /// The nearest site of `voronoi` at `p`: from the certificate when it
    /// covers `p`, else from a fresh certified search (kept for next time)
    /// or, while certificates do not pay, a plain one.
    #[inline]
    fn site(&mut self, voronoi: &Voronoi, p: DVec3) -> VoronoiSite {
        if voronoi.nearest_within(&self.certified, p) {
            self.certificate_paid = true;
            return self.certified.site;
        }
        if self.certificate_paid {
            self.unpaid_streak = 0;
        } else if self.plain_searches < PLAIN_SEARCHES_BEFORE_PROBE << self.unpaid_streak {
            self.plain_searches += 1;
            return voronoi.nearest(p).site();
        } else {
            self.unpaid_streak = (self.unpaid_streak + 1).min(MAX_UNPAID_STREAK);
        }
        self.certified = voronoi.certify_nearest(p);
        self.certificate_paid = false;
        self.plain_searches = 0;
        self.certified.site
    }

    /// `select(site)`, reusing the last selection when it was made for the
    /// same site (a pure function of the site, so the same value).
    #[inline]
    fn selection(&mut self, site: VoronoiSite, select: impl FnOnce(&VoronoiSite) -> T) -> T {
        let key = (site.cell_id, site.cell);
        if self.selected_for != Some(key) {
            self.selection = select(&site);
            self.selected_for = Some(key);
        }
        self.selection
    }
}

/// The per-thread memory of [`Pattern::resolve`] for the last pattern
/// resolved.
struct PatternMemos {
    /// [`Pattern::id`] of the pattern the entries belong to (0: none).
    pattern_id: u64,
    /// Per node (by index): its Voronoi's site and, for a map, the entry
    /// it selected.
    nodes: [NodeMemo<Entry>; CACHED_NODES],
    /// The glitter cells: the site and its filled material, if filled.
    glitter: NodeMemo<Option<u32>>,
    /// The facet cells of filled glitter cells (the selection is unused).
    facets: NodeMemo<()>,
}

impl PatternMemos {
    const EMPTY: PatternMemos = PatternMemos {
        pattern_id: 0,
        nodes: [NodeMemo::empty(Entry::Material(0)); CACHED_NODES],
        glitter: NodeMemo::empty(None),
        facets: NodeMemo::empty(()),
    };
}

/// Number of [`SwitchReads`] slots (a power of two): a 96-pixel row of the
/// lepidolite touches ~100 inclusion sites, so the row below finds most of
/// its sites still there (measured: 96 % of reads on a 96² render).
const SWITCH_READ_SLOTS: usize = 256;

/// One memoised per-cell switch read: which pattern, node and site it is
/// for, and the entry the switch selected there.
#[derive(Clone, Copy)]
struct SwitchRead {
    pattern_id: u64,
    node: u32,
    cell: IVec3,
    cell_id: u64,
    entry: Entry,
}

/// Direct-mapped memo of per-cell switch reads, indexed by the site's
/// cell id (already a well-mixed hash). The key holds the pattern id, so
/// the table survives a change of pattern and needs no clearing.
struct SwitchReads {
    slots: [SwitchRead; SWITCH_READ_SLOTS],
}

impl SwitchReads {
    const EMPTY: SwitchReads = SwitchReads {
        slots: [SwitchRead {
            pattern_id: 0, // no pattern has id 0: never matches
            node: 0,
            cell: IVec3::ZERO,
            cell_id: 0,
            entry: Entry::Material(0),
        }; SWITCH_READ_SLOTS],
    };

    /// `read(site)` for node `node` of pattern `pattern_id`, from the table
    /// when it holds exactly this read (a pure function of the site).
    #[inline]
    fn entry(
        &mut self,
        pattern_id: u64,
        node: u32,
        site: &VoronoiSite,
        read: impl FnOnce(&VoronoiSite) -> Entry,
    ) -> Entry {
        let index = (site.cell_id.wrapping_add(u64::from(node)) as usize) % SWITCH_READ_SLOTS;
        let slot = &mut self.slots[index];
        if slot.pattern_id != pattern_id
            || slot.node != node
            || slot.cell_id != site.cell_id
            || slot.cell != site.cell
        {
            *slot = SwitchRead {
                pattern_id,
                node,
                cell: site.cell,
                cell_id: site.cell_id,
                entry: read(site),
            };
        }
        slot.entry
    }
}

/// Everything a thread remembers between [`Pattern::resolve`] calls.
struct ResolveCache {
    /// Sites and selections of the last pattern resolved.
    pattern: PatternMemos,
    /// Per-cell switch reads of any pattern.
    switch_reads: SwitchReads,
}

impl ResolveCache {
    const EMPTY: ResolveCache = ResolveCache {
        pattern: PatternMemos::EMPTY,
        switch_reads: SwitchReads::EMPTY,
    };
}

thread_local! {
    /// Each rendering thread's [`ResolveCache`] (constant-initialised and
    /// without a destructor, so access is a plain thread-local load).
    static RESOLVE_CACHE: RefCell<ResolveCache> = const { RefCell::new(ResolveCache::EMPTY) };
}
