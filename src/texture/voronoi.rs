//! 3-D Voronoi (cellular) texture: the cells of the surface, glitter and
//! crystal-facet maps of section 4.3.1 (figure 4.6, components ①, ② and ④).
//!
//! # Construction
//!
//! Object space is divided into a lattice of boxes of size
//! `cell_size · stretch` (per axis). In *lattice space* `q = p ⊘ (cell_size · stretch)`
//! these boxes are the unit cells `[c, c + 1)` of the integer lattice (found
//! with `floor`, so negative coordinates have no seam at 0). Each cell `c`
//! holds exactly one feature point (a "site")
//!
//! ```text
//! site(c) = c + 0.5 + jitter · (u − 0.5),   u = unit_triple_21bit(hash_cell(c, seed)) ∈ [0, 1)³
//! ```
//!
//! so `jitter = 0` gives a regular grid of cell centres (Voronoi cells are
//! exactly the lattice cells) and `jitter = 1` a site anywhere in the cell.
//!
//! # Units and the stretched metric
//!
//! All distances (`f1`, `f2`, `edge_distance`) are Euclidean distances in the
//! *stretched* space `p ⊘ stretch`, i.e. lattice distances times `cell_size`.
//! With `stretch = (1, 1, 1)` they are plain object-space distances. With an
//! anisotropic stretch the cells are elongated crystals and the distances are
//! measured as if the object were first squashed by `1 / stretch`; the cell
//! borders are still planes in object space, but `edge_distance` is measured
//! in the stretched metric, not the object-space one.
//!
//! # Why the fast search is exact (`0 ≤ jitter ≤ 1`)
//!
//! Let `q` lie in cell `c₀` with fractional part `f ∈ [0, 1)³`. A site of the
//! cell `c₀ + d` lies, along axis `i`, in `[dᵢ + ½ − j/2, dᵢ + ½ + j/2]` relative
//! to `c₀`, so every site of a cell with Chebyshev offset `r = max |dᵢ| ≥ 2`
//! is at least
//!
//! ```text
//! ring_bound(r) = minᵢ min(r + ½ − j/2 − fᵢ,  fᵢ + r − ½ − j/2)   ≥ r − 1
//! ```
//!
//! away from `q`, and `ring_bound` grows with `r`.
//!
//! * **F1, F2.** The own site is within √3 (both in one unit cube). Take the
//!   axis `i` where `aᵢ = max(fᵢ, 1 − fᵢ)` is largest and the face neighbour
//!   across the nearer face: its site is within `√((2 − aᵢ)² + 2 aᵢ²) ≤ √3`
//!   (maximum at `aᵢ = 1`). So F2 ≤ √3 < 2 ≤ `ring_bound(3)`: the 5×5×5 block
//!   always holds F1 and F2. The fast path scans the 3×3×3 block and then
//!   the ring `r = 2` only if `F2 > ring_bound(2)`, pruning ring cells whose
//!   jitter box is farther than the current F2.
//! * **Edge distance** to the boundary of the nearest site `a`:
//!   `E = min_b ((a+b)/2 − q) · (b − a) / |b − a| = min_b (|q−b|² − |q−a|²) / (2 |b − a|)`.
//!   Since `|b − a| ≤ |q − b| + F1`, every term is `≥ (|q − b| − F1) / 2`, so
//!   a site `b` can lower `E` only if `|q − b| < F1 + 2E`. The fast path
//!   computes `E` over the 3×3×3 block, then scans rings `r = 2, 3, …` (with the
//!   same per-cell pruning) while `F1 + 2E > ring_bound(r)`. This terminates by
//!   `r = 4`: the ball of radius `E` around `q` lies in the cell of `a`, whose
//!   points are all within the largest empty-ball radius (< √3, as any ball of
//!   radius √3 contains a whole unit cell, hence a site) of `a`; so
//!   `F1 + E < √3`, `F1 + 2E < 2√3 < 4 ≤ ring_bound(5)`.
//!
//! In the common case [`Voronoi::query`] hashes only the 27 inner cells
//! (1 + 3 + 9 + 27 mixes sharing the hash-chain prefixes of
//! [`crate::texture::hash`]); [`Voronoi::nearest`] also skips inner cells whose
//! jitter box is farther than the best site so far (about 8 of 27 at full
//! jitter). Measured over 10⁶ random points at full jitter, the ring `r = 2`
//! was needed for 0.4 % (F2) and 2.6 % (edge) of queries, and `F1 + 2E`
//! never exceeded 1.46, so rings 3 and 4 are a proven safety net only.
//!
//! # Domain
//!
//! Exact for `|p / (cell_size · stretch)| < 2³¹ − 8` per axis (the `i32` cell
//! coordinates). Outside that, or for non-finite input, the result is
//! meaningless but the query never panics and always terminates.

use glam::{DVec3, IVec3};

use super::hash::{hash_cell, hash_prefix, seed_key, triple_21bit, unit_triple_21bit};

/// A 3-D Voronoi texture: one jittered feature point per lattice cell.
/// Plain data, `Copy`, `Send + Sync`; queries are pure functions of `(self, p)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Voronoi {
    /// Edge length of a lattice cell in object-space units (before stretch).
    /// Must be > 0.
    pub cell_size: f64,
    /// How far a feature point may wander from its cell centre, as a fraction
    /// of the cell: 0 = regular grid, 1 = anywhere in the cell. Clamped to
    /// `[0, 1]` by the queries (the exactness proof needs `≤ 1`).
    pub jitter: f64,
    /// Anisotropic scale of the cells (each component > 0): `(3, 1, 1)` makes
    /// crystals three times longer along x. Distances are measured in `p ⊘ stretch`.
    pub stretch: DVec3,
    /// Seed of the cell hash; a different seed gives an unrelated pattern.
    pub seed: u64,
}

/// Everything a pattern needs to know about the Voronoi cell around a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiSample {
    /// Distance to the nearest feature point (stretched metric, object units).
    pub f1: f64,
    /// Distance to the second-nearest feature point (same metric).
    pub f2: f64,
    /// Id of the nearest feature point's cell: its [`hash_cell`] value, the
    /// root for per-cell choices (material entry, fill, facet tilt).
    pub cell_id: u64,
    /// Integer lattice coordinates of the nearest feature point's cell.
    pub cell: IVec3,
    /// The nearest feature point, in object space.
    pub feature_point: DVec3,
    /// The second-nearest feature point, in object space (the site across
    /// the border that F2 measures; useful for bevels and for tests).
    pub second_feature_point: DVec3,
    /// True distance (stretched metric) to the nearest border of the Voronoi
    /// cell: the minimum over all other sites `b` of the distance to the
    /// bisector plane between the nearest site and `b`. Not `F2 − F1`.
    pub edge_distance: f64,
}

/// The nearest feature point only: what a surface map needs to pick an entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiNearest {
    /// Distance to the nearest feature point (stretched metric, object units).
    pub f1: f64,
    /// Id of the nearest feature point's cell (its [`hash_cell`] value).
    pub cell_id: u64,
    /// Integer lattice coordinates of the nearest feature point's cell.
    pub cell: IVec3,
    /// The nearest feature point, in object space.
    pub feature_point: DVec3,
}

/// Which site is nearest, without the distance: what stays the same for
/// all points of a region of a [`CertifiedNearest`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoronoiSite {
    /// Id of the site's cell (its [`hash_cell`] value).
    pub cell_id: u64,
    /// Integer lattice coordinates of the site's cell.
    pub cell: IVec3,
    /// The site in object space, bit-identical to
    /// [`VoronoiNearest::feature_point`] (a function of the cell alone).
    pub feature_point: DVec3,
}

impl VoronoiNearest {
    /// The site, without F1.
    #[inline]
    pub fn site(&self) -> VoronoiSite {
        VoronoiSite {
            cell_id: self.cell_id,
            cell: self.cell,
            feature_point: self.feature_point,
        }
    }
}

/// A nearest site with a certificate that it stays the nearest nearby
/// ([`Voronoi::certify_nearest`], [`Voronoi::nearest_within`]): what lets a
/// per-thread cache answer consecutive, nearby lookups without a search and
/// still give exactly what [`Voronoi::nearest`] gives.
///
/// # Why the region is safe
///
/// In lattice space let `q₀` be the certified query, `a` its nearest site and
/// `F₂` the distance from `q₀` to the second-nearest site. For a point `q`
/// and any other site `b`, the triangle inequality gives
/// `|q − b| ≥ |q₀ − b| − |q − q₀| ≥ F₂ − |q − q₀|`, so `a` is strictly the
/// nearest site of `q` whenever
///
/// ```text
/// |q − a| + |q − q₀| < F₂ − m
/// ```
///
/// (a prolate ellipsoid with foci `q₀` and `a`; it contains the ball of
/// radius `(F₂ − F₁)/2` around `q₀`). The stored reach is a lower bound of
/// `F₂ − m`: from the computed `F₂²` less 10⁻¹² (far above the ~10⁻¹⁴ error of a
/// computed squared distance within 4 cells), with `m = 4·10⁻⁶ + 10⁻¹²·|q₀|∞`.
/// Then the true distances of `q` to `a` and to any other `b` differ by more
/// than 3·10⁻⁶, so their squares by more than 10⁻¹¹, which no rounding in
/// the search (site offsets, squared distances, the pruning gaps and ring
/// bounds, all within ~10⁻¹⁴) can reverse: the pruned search of
/// [`Voronoi::nearest`] keeps `a`, and returns `a`'s `cell_id`, `cell` and
/// `feature_point`, which depend on the site alone, not on the query.
/// The `10⁻¹²·|q₀|∞` term covers the rounding of `p ⊘ scale` and of the site's
/// lattice position at large coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CertifiedNearest {
    /// The nearest site of every point in the region.
    pub site: VoronoiSite,
    /// `q₀`: the certified query in lattice units.
    query_lattice: DVec3,
    /// `a`: the site in lattice units.
    site_lattice: DVec3,
    /// Lower bound of `F₂ − m` (lattice units); −∞ for an empty region.
    reach_lattice: f64,
    /// 1 ⊘ (`cell_size · stretch`): [`Voronoi::nearest_within`] maps a
    /// point to lattice space by this product instead of three divisions
    /// (a quarter of a lepidolite pattern's own time). The product differs
    /// from the quotient by at most two roundings, far inside the
    /// `10⁻¹²·|q₀|∞` term of the margin, so a region test near its border
    /// may answer either way, and either answer gives the same site.
    inverse_scale: DVec3,
}

impl CertifiedNearest {
    /// A certificate that covers no point (for initialising caches).
    pub const EMPTY: CertifiedNearest = CertifiedNearest {
        site: VoronoiSite {
            cell_id: 0,
            cell: IVec3::ZERO,
            feature_point: DVec3::ZERO,
        },
        query_lattice: DVec3::ZERO,
        site_lattice: DVec3::ZERO,
        reach_lattice: f64::NEG_INFINITY,
        inverse_scale: DVec3::ZERO,
    };
}

/// Slack on a computed squared distance (lattice units²): 10⁻¹² against
/// errors of ~10⁻¹⁴ ([`CertifiedNearest`]).
const CERTIFICATE_SLACK_SQ: f64 = 1e-12;

/// The certificate's reach `√(F₂² − slack) − m` for a query at `query`
/// (lattice units); −∞ (empty) for non-finite or very far queries, where
/// the `i32` cells of the search wrap.
#[inline]
fn certified_reach(second_distance_sq: f64, query: DVec3) -> f64 {
    const MAX_CERTIFIED_COORDINATE: f64 = (1u64 << 30) as f64;
    let size = query.abs().max_element();
    if !(query.is_finite() && size < MAX_CERTIFIED_COORDINATE) {
        return f64::NEG_INFINITY;
    }
    let margin = 4e-6 + 1e-12 * size;
    (second_distance_sq - CERTIFICATE_SLACK_SQ).max(0.0).sqrt() - margin
}

/// The query point in lattice space, split into cell and fraction.
#[derive(Clone, Copy)]
struct LatticePoint {
    /// Object units per lattice unit, per axis (`cell_size · stretch`).
    scale: DVec3,
    /// Integer cell containing the point (`floor`).
    cell: IVec3,
    /// Position inside that cell, in `[0, 1)³`.
    fraction: DVec3,
    /// Jitter clamped to `[0, 1]`.
    jitter: f64,
    /// `seed_key(seed)`: the start of the hash chain.
    key: u64,
}

/// A site found during a search, relative to the query point (lattice units).
#[derive(Clone, Copy)]
struct Candidate {
    /// `|site − q|²`.
    distance_sq: f64,
    /// `site − q`.
    offset_from_query: DVec3,
    /// Cell of the site relative to the query's cell.
    cell_offset: IVec3,
    /// `hash_cell` of the site's cell.
    hash: u64,
}

/// Largest ring the edge search can need (see the module proof).
const MAX_RING: i32 = 4;

/// `floor` without a library call. The baseline x86-64 target has no SSE4.1
/// `roundsd`, so `f64::floor` is a ~25-instruction software routine, a
/// visible share of a Voronoi query. Exact: below 2⁵² in magnitude the
/// integer conversion truncates exactly; at and above, every `f64` is
/// already an integer (NaN passes through).
#[inline(always)]
pub(crate) fn floor_fast(x: f64) -> f64 {
    const ALL_INTEGERS_FROM: f64 = 4_503_599_627_370_496.0; // 2⁵²
    if x.abs() < ALL_INTEGERS_FROM {
        let truncated = (x as i64) as f64;
        truncated - f64::from(u8::from(truncated > x))
    } else {
        x
    }
}

/// Site position inside its cell, relative to the cell's lower corner:
/// `0.5 + j·(u − 0.5)`, evaluated as `(0.5 − j/2) + j·u`.
#[inline(always)]
fn site_in_cell(cell_hash: u64, jitter: f64) -> DVec3 {
    let [ux, uy, uz] = unit_triple_21bit(cell_hash);
    let corner = 0.5 - 0.5 * jitter;
    DVec3::new(
        corner + jitter * ux,
        corner + jitter * uy,
        corner + jitter * uz,
    )
}

/// Smallest possible distance, along one axis, from a fraction `f ∈ [0, 1)`
/// to a site of the cell at integer offset `d` (its jitter interval).
#[inline(always)]
fn axis_gap(d: i32, f: f64, jitter: f64) -> f64 {
    let low = d as f64 + 0.5 - 0.5 * jitter;
    let high = d as f64 + 0.5 + 0.5 * jitter;
    (low - f).max(f - high).max(0.0)
}

/// Cell offset of entry `k` of the inner 3×3×3 block (x slowest, z fastest).
#[inline(always)]
fn inner_offset(k: usize) -> IVec3 {
    let k = k as i32;
    IVec3::new(k / 9 - 1, k / 3 % 3 - 1, k % 3 - 1)
}

/// The inner 3×3×3 block around a query: cell hashes and, per axis, the
/// site coordinate a zero hash would give (`d + (0.5 − j/2) − f`), so that
/// a site costs three conversions and three multiply-adds.
struct InnerBlock {
    /// `hash_cell` of the cell at `inner_offset(k)`.
    hash: [u64; 27],
    /// `bases[d + 1]` holds, per axis, `d + (0.5 − j/2) − f`.
    bases: [DVec3; 3],
    /// `j · 2⁻²¹`: `j·u = jitter_step · n` exactly (power-of-two scale).
    jitter_step: f64,
}

impl InnerBlock {
    /// Hashes the 27 cells around the point, sharing the chain prefixes of
    /// [`crate::texture::hash`]: 3 + 9 + 27 mixes instead of 27 × 3.
    #[inline(always)]
    fn new(lat: &LatticePoint) -> Self {
        const INV_2_POW_21: f64 = 1.0 / (1u64 << 21) as f64;
        let mut hash = [0; 27];
        let mut k = 0;
        for dx in -1..=1 {
            let hx = hash_prefix(lat.key, lat.cell.x.wrapping_add(dx));
            for dy in -1..=1 {
                let hxy = hash_prefix(hx, lat.cell.y.wrapping_add(dy));
                for dz in -1..=1 {
                    hash[k] = hash_prefix(hxy, lat.cell.z.wrapping_add(dz));
                    k += 1;
                }
            }
        }
        let corner = 0.5 - 0.5 * lat.jitter;
        let base = |d: f64| DVec3::splat(d + corner) - lat.fraction;
        InnerBlock {
            hash,
            bases: [base(-1.0), base(0.0), base(1.0)],
            jitter_step: lat.jitter * INV_2_POW_21,
        }
    }

    /// `site − q` for entry `k` (lattice units).
    #[inline(always)]
    fn offset_from_query(&self, k: usize) -> DVec3 {
        let [nx, ny, nz] = triple_21bit(self.hash[k]);
        DVec3::new(
            self.bases[k / 9].x + self.jitter_step * nx as f64,
            self.bases[k / 3 % 3].y + self.jitter_step * ny as f64,
            self.bases[k % 3].z + self.jitter_step * nz as f64,
        )
    }

    /// Calls `visit(k, site − q)` for all 27 entries in order. Nested loops
    /// rather than `offset_from_query(k)` per entry: the per-axis bases are
    /// then loop constants instead of `k / 9`, `k / 3 % 3`, `k % 3` lookups.
    #[inline(always)]
    fn for_each_offset(&self, mut visit: impl FnMut(usize, DVec3)) {
        let mut k = 0;
        for bx in self.bases {
            for by in self.bases {
                for bz in self.bases {
                    let [nx, ny, nz] = triple_21bit(self.hash[k]);
                    visit(
                        k,
                        DVec3::new(
                            bx.x + self.jitter_step * nx as f64,
                            by.y + self.jitter_step * ny as f64,
                            bz.z + self.jitter_step * nz as f64,
                        ),
                    );
                    k += 1;
                }
            }
        }
    }

    #[inline(always)]
    fn candidate(&self, k: usize) -> Candidate {
        let rel = self.offset_from_query(k);
        Candidate {
            distance_sq: rel.length_squared(),
            offset_from_query: rel,
            cell_offset: inner_offset(k),
            hash: self.hash[k],
        }
    }
}

impl LatticePoint {
    /// Lower bound on the distance from the point to any site in a cell of
    /// Chebyshev offset ≥ `ring` (`ring ≥ 1`).
    #[inline]
    fn ring_bound(&self, ring: i32) -> f64 {
        let f = self.fraction;
        // min(r + ½ − j/2 − f, f + r − ½ − j/2) = r − ½ − j/2 + min(f, 1 − f).
        let nearest_face = f.min(DVec3::ONE - f).min_element();
        ring as f64 - 0.5 - 0.5 * self.jitter + nearest_face
    }

    /// Lower bound on the squared distance to the site of the cell at `offset`.
    #[inline]
    fn cell_bound_sq(&self, offset: IVec3) -> f64 {
        let g = DVec3::new(
            axis_gap(offset.x, self.fraction.x, self.jitter),
            axis_gap(offset.y, self.fraction.y, self.jitter),
            axis_gap(offset.z, self.fraction.z, self.jitter),
        );
        g.length_squared()
    }

    /// The site of the cell at `offset`, as a candidate (full hash chain).
    #[inline]
    fn candidate(&self, offset: IVec3, seed: u64) -> Candidate {
        let h = hash_cell(self.cell.wrapping_add(offset), seed);
        let rel = offset.as_dvec3() + site_in_cell(h, self.jitter) - self.fraction;
        Candidate {
            distance_sq: rel.length_squared(),
            offset_from_query: rel,
            cell_offset: offset,
            hash: h,
        }
    }

    /// Visits the cells of Chebyshev offset exactly `ring` whose jitter box is
    /// closer than the search radius. `visit` returns the new radius, so the
    /// search tightens as better sites are found. Rarely needed (module doc).
    #[cold]
    fn for_each_in_ring(
        &self,
        ring: i32,
        seed: u64,
        initial_radius: f64,
        mut visit: impl FnMut(Candidate) -> f64,
    ) {
        let mut radius = initial_radius;
        for dx in -ring..=ring {
            for dy in -ring..=ring {
                for dz in -ring..=ring {
                    let offset = IVec3::new(dx, dy, dz);
                    if offset.abs().max_element() != ring
                        || self.cell_bound_sq(offset) >= radius * radius
                    {
                        continue;
                    }
                    radius = visit(self.candidate(offset, seed));
                }
            }
        }
    }

    /// The site of a candidate in object space.
    #[inline(always)]
    fn object_point(&self, c: &Candidate) -> DVec3 {
        let cell = self.cell.wrapping_add(c.cell_offset);
        (cell.as_dvec3() + site_in_cell(c.hash, self.jitter)) * self.scale
    }
}

/// Keeps the two nearest candidates (first found wins ties).
#[derive(Clone, Copy)]
struct TwoNearest {
    first: Candidate,
    second: Candidate,
}

impl TwoNearest {
    #[inline(always)]
    fn offer(&mut self, c: Candidate) {
        if c.distance_sq < self.second.distance_sq {
            if c.distance_sq < self.first.distance_sq {
                self.second = self.first;
                self.first = c;
            } else {
                self.second = c;
            }
        }
    }
}

/// Distance from the query (origin) to the bisector plane of sites `a`
/// (nearest) and `b`, both given relative to the query:
/// `(|b|² − |a|²) / (2 |b − a|)`; `None` if the sites coincide.
#[inline(always)]
fn bisector_distance(a: DVec3, a_sq: f64, b: DVec3, b_sq: f64) -> Option<f64> {
    let len_sq = (b - a).length_squared();
    (len_sq > 0.0).then(|| (b_sq - a_sq) / (2.0 * len_sq.sqrt()))
}

/// What a pruned search keeps of the sites it has seen: the nearest one
/// ([`Best`]) or also the second-nearest distance ([`BestTwo`], for
/// certificates). `radius_sq` is the squared distance beyond which a site
/// can no longer change what is kept: cells whose jitter box lies at or
/// beyond it are skipped before they are hashed.
trait Keeper {
    fn radius_sq(&self) -> f64;
    fn offer(&mut self, distance_sq: f64, hash: u64, index: usize);
}

/// The nearest site so far: squared distance, cell hash and its index
/// `9i + 3j + k` in the search's visiting order.
#[derive(Clone, Copy)]
struct Best {
    distance_sq: f64,
    hash: u64,
    index: usize,
}

impl Best {
    const NONE: Best = Best {
        distance_sq: f64::INFINITY,
        hash: 0,
        index: 0,
    };
}

impl Keeper for Best {
    #[inline(always)]
    fn radius_sq(&self) -> f64 {
        self.distance_sq
    }

    #[inline(always)]
    fn offer(&mut self, distance_sq: f64, hash: u64, index: usize) {
        // Selects, not a branch: which site wins is random.
        let closer = distance_sq < self.distance_sq;
        self.distance_sq = if closer {
            distance_sq
        } else {
            self.distance_sq
        };
        self.hash = if closer { hash } else { self.hash };
        self.index = if closer { index } else { self.index };
    }
}

/// The nearest site and the second-nearest squared distance.
#[derive(Clone, Copy)]
struct BestTwo {
    best: Best,
    second_distance_sq: f64,
}

impl Keeper for BestTwo {
    #[inline(always)]
    fn radius_sq(&self) -> f64 {
        self.second_distance_sq
    }

    #[inline(always)]
    fn offer(&mut self, distance_sq: f64, hash: u64, index: usize) {
        self.second_distance_sq = if distance_sq < self.best.distance_sq {
            self.best.distance_sq
        } else {
            self.second_distance_sq.min(distance_sq)
        };
        self.best.offer(distance_sq, hash, index);
    }
}

/// State of the pruned 3×3×3 site search of [`Voronoi::nearest`] and
/// [`Voronoi::certify_nearest`]: per axis the cell offsets, squared gaps and
/// zero-hash site bases in visiting order (own, nearer face, farther face),
/// and what is kept of the sites so far. Cells are visited in `(i, j, k)`
/// order; a cell replaces the best only if strictly closer, so ties go to
/// the first visited.
struct NearestSearch<K> {
    cell: IVec3,
    offsets: [[i32; 3]; 3],
    gaps_sq: [[f64; 3]; 3],
    bases: [[f64; 3]; 3],
    jitter_step: f64,
    kept: K,
}

impl<K: Keeper> NearestSearch<K> {
    /// Sets up the search around `lat`. Sites of the cell at offset d lie in
    /// [d + h, d + 1 − h] per axis, h = (1 − j)/2. With m = min(f, 1 − f)
    /// the distance from f to that interval is max(0, h − m) for the own
    /// cell, m + h across the nearer face and 1 − m + h across the farther one.
    #[inline(always)]
    fn new(lat: &LatticePoint, kept: K) -> Self {
        const INV_2_POW_21: f64 = 1.0 / (1u64 << 21) as f64;
        let half_gap = 0.5 - 0.5 * lat.jitter;
        let axis = |fa: f64| {
            let m = fa.min(1.0 - fa);
            let near = if fa < 0.5 { -1 } else { 1 };
            let own_gap = (half_gap - m).max(0.0);
            let gap_sq = [
                own_gap * own_gap,
                (m + half_gap).powi(2),
                (1.0 - m + half_gap).powi(2),
            ];
            let base = half_gap - fa; // site − q for offset 0 and a zero hash
            (
                [0, near, -near],
                gap_sq,
                [base, base + near as f64, base - near as f64],
            )
        };
        let (ox, gx, bx) = axis(lat.fraction.x);
        let (oy, gy, by) = axis(lat.fraction.y);
        let (oz, gz, bz) = axis(lat.fraction.z);
        NearestSearch {
            cell: lat.cell,
            offsets: [ox, oy, oz],
            gaps_sq: [gx, gy, gz],
            bases: [bx, by, bz],
            jitter_step: lat.jitter * INV_2_POW_21,
            kept,
        }
    }

    /// Searches the 27 cells. Fully unrolled (constant i, j, k after
    /// inlining): the per-axis tables stay in registers and every skip
    /// decision is its own branch, predicted from its own history.
    #[inline(always)]
    fn run(mut self, key: u64) -> Self {
        self.slab(key, 0);
        self.slab(key, 1);
        self.slab(key, 2);
        self
    }

    /// The cell offset (relative to the query's cell) of visiting index `index`.
    #[inline(always)]
    fn cell_offset(&self, index: usize) -> IVec3 {
        IVec3::new(
            self.offsets[0][index / 9],
            self.offsets[1][index / 3 % 3],
            self.offsets[2][index % 3],
        )
    }

    /// The slab `i` (x offset `offsets[0][i]`), skipped when its gap is
    /// farther than the search radius.
    #[inline(always)]
    fn slab(&mut self, key: u64, i: usize) {
        if self.gaps_sq[0][i] >= self.kept.radius_sq() {
            return;
        }
        let hx = hash_prefix(key, self.cell.x.wrapping_add(self.offsets[0][i]));
        self.row(hx, i, 0);
        self.row(hx, i, 1);
        self.row(hx, i, 2);
    }

    /// The row `(i, j)`, skipped when its gap is farther than the search radius.
    #[inline(always)]
    fn row(&mut self, hx: u64, i: usize, j: usize) {
        let row_gap_sq = self.gaps_sq[0][i] + self.gaps_sq[1][j];
        if row_gap_sq >= self.kept.radius_sq() {
            return;
        }
        let hxy = hash_prefix(hx, self.cell.y.wrapping_add(self.offsets[1][j]));
        self.site(hxy, row_gap_sq, i, j, 0);
        self.site(hxy, row_gap_sq, i, j, 1);
        self.site(hxy, row_gap_sq, i, j, 2);
    }

    /// The cell `(i, j, k)`: hashed and offered unless its jitter box is
    /// farther than the search radius.
    #[inline(always)]
    fn site(&mut self, hxy: u64, row_gap_sq: f64, i: usize, j: usize, k: usize) {
        if row_gap_sq + self.gaps_sq[2][k] >= self.kept.radius_sq() {
            return;
        }
        let h = hash_prefix(hxy, self.cell.z.wrapping_add(self.offsets[2][k]));
        let [nx, ny, nz] = triple_21bit(h);
        let rel = DVec3::new(
            self.bases[0][i] + self.jitter_step * nx as f64,
            self.bases[1][j] + self.jitter_step * ny as f64,
            self.bases[2][k] + self.jitter_step * nz as f64,
        );
        self.kept.offer(rel.length_squared(), h, 9 * i + 3 * j + k);
    }
}

impl Voronoi {
    /// A Voronoi texture with full jitter and no stretch.
    pub fn new(cell_size: f64, seed: u64) -> Self {
        Voronoi {
            cell_size,
            jitter: 1.0,
            stretch: DVec3::ONE,
            seed,
        }
    }

    #[inline(always)]
    fn lattice_point(&self, p: DVec3) -> LatticePoint {
        let scale = self.stretch * self.cell_size;
        let q = p / scale;
        let floor = DVec3::new(floor_fast(q.x), floor_fast(q.y), floor_fast(q.z));
        LatticePoint {
            scale,
            cell: floor.as_ivec3(),
            fraction: q - floor,
            jitter: self.jitter.clamp(0.0, 1.0),
            key: seed_key(self.seed),
        }
    }

    /// Nearest feature point only (F1, cell id, cell, feature point): the
    /// cheap query for surface maps. Exact (module proof).
    ///
    /// Worley's pruning: cells are visited own-side first (per axis: the
    /// own cell, the neighbour across the nearer face, then the one across
    /// the farther face), and a cell, row or slab is skipped, before it is
    /// hashed, when its jitter box is farther than the best site so far.
    /// The visiting order makes the skip decisions depend mostly on the
    /// cell's category, not on where `p` lies, so they predict well; typically
    /// 8–12 of the 27 cells are hashed. The pruned ring of the 5×5×5 block is
    /// searched only when F1 exceeds its lower bound.
    #[inline]
    pub fn nearest(&self, p: DVec3) -> VoronoiNearest {
        let lat = self.lattice_point(p);
        let search = NearestSearch::new(&lat, Best::NONE).run(lat.key);
        let mut best = Candidate {
            distance_sq: search.kept.distance_sq,
            offset_from_query: DVec3::ZERO, // not needed below
            cell_offset: search.cell_offset(search.kept.index),
            hash: search.kept.hash,
        };
        let bound = lat.ring_bound(2);
        if best.distance_sq > bound * bound {
            lat.for_each_in_ring(2, self.seed, best.distance_sq.sqrt(), |c| {
                if c.distance_sq < best.distance_sq {
                    best = c;
                }
                best.distance_sq.sqrt()
            });
        }
        VoronoiNearest {
            f1: best.distance_sq.sqrt() * self.cell_size,
            cell_id: best.hash,
            cell: lat.cell.wrapping_add(best.cell_offset),
            feature_point: lat.object_point(&best),
        }
    }

    /// The nearest site of `p` together with a certificate: a region around
    /// `p` inside which [`Voronoi::nearest`] returns this same site (same
    /// `cell_id`, `cell` and bit-identical `feature_point`), so that
    /// [`Voronoi::nearest_within`] can answer nearby queries without a search.
    ///
    /// The site is always exactly `nearest(p)`'s; the region may be empty
    /// (non-finite `p`, coordinates beyond 2³⁰ cells, or two sites within
    /// rounding of a tie). See [`CertifiedNearest`] for why the region is safe.
    /// Costs a little more than `nearest` (the search is pruned against the
    /// second-nearest site instead of the nearest).
    pub fn certify_nearest(&self, p: DVec3) -> CertifiedNearest {
        let lat = self.lattice_point(p);
        let search = NearestSearch::new(
            &lat,
            BestTwo {
                best: Best::NONE,
                second_distance_sq: f64::INFINITY,
            },
        )
        .run(lat.key);
        let mut two = TwoNearest {
            first: Candidate {
                distance_sq: search.kept.best.distance_sq,
                offset_from_query: DVec3::ZERO, // not needed below
                cell_offset: search.cell_offset(search.kept.best.index),
                hash: search.kept.best.hash,
            },
            second: Candidate {
                distance_sq: search.kept.second_distance_sq,
                offset_from_query: DVec3::ZERO,
                cell_offset: IVec3::ZERO,
                hash: 0,
            },
        };
        // F2 ≤ √3 < ring_bound(3) (module proof): ring 2 completes the search.
        let bound = lat.ring_bound(2);
        if two.second.distance_sq > bound * bound {
            lat.for_each_in_ring(2, self.seed, two.second.distance_sq.sqrt(), |c| {
                two.offer(c);
                two.second.distance_sq.sqrt()
            });
        }
        let first = two.first;
        let cell = lat.cell.wrapping_add(first.cell_offset);
        let query_lattice = p / lat.scale;
        let certified = CertifiedNearest {
            site: VoronoiSite {
                cell_id: first.hash,
                cell,
                feature_point: lat.object_point(&first),
            },
            query_lattice,
            site_lattice: cell.as_dvec3() + site_in_cell(first.hash, lat.jitter),
            reach_lattice: certified_reach(two.second.distance_sq, query_lattice),
            inverse_scale: lat.scale.recip(),
        };
        // The query itself must be inside (a strict nearest, by the margin);
        // otherwise the plain search decides and the region is empty.
        if self.nearest_within(&certified, p) {
            certified
        } else {
            CertifiedNearest {
                site: self.nearest(p).site(),
                ..CertifiedNearest::EMPTY
            }
        }
    }

    /// Whether `certified` (from [`Voronoi::certify_nearest`] on this same
    /// Voronoi) covers `p`, i.e. whether `nearest(p)` is its site. Two
    /// distances and a comparison instead of a search; false for a
    /// non-finite `p`.
    #[inline]
    pub fn nearest_within(&self, certified: &CertifiedNearest, p: DVec3) -> bool {
        let q = p * certified.inverse_scale;
        (q - certified.site_lattice).length() + (q - certified.query_lattice).length()
            < certified.reach_lattice
    }

    /// Full query: F1, F2, the nearest cell and the true distance to its
    /// border. Exact for `jitter ∈ [0, 1]` (see the module proof); usually
    /// touches only the 27 cells around `p`.
    pub fn query(&self, p: DVec3) -> VoronoiSample {
        let lat = self.lattice_point(p);
        let block = InnerBlock::new(&lat);
        let mut distance_sq = [0.0; 27];
        block.for_each_offset(|k, rel| distance_sq[k] = rel.length_squared());

        // Two running minima as selects, not branches (see `nearest`).
        let (mut d1, mut d2) = (f64::INFINITY, f64::INFINITY);
        let (mut i1, mut i2) = (0, 0);
        for (k, &d) in distance_sq.iter().enumerate() {
            let closer_than_first = d < d1;
            i2 = if closer_than_first {
                i1
            } else if d < d2 {
                k
            } else {
                i2
            };
            let closer_than_second = d < d2;
            d2 = if closer_than_first {
                d1
            } else if closer_than_second {
                d
            } else {
                d2
            };
            i1 = if closer_than_first { k } else { i1 };
            d1 = if closer_than_first { d } else { d1 };
        }
        let mut two = TwoNearest {
            first: block.candidate(i1),
            second: block.candidate(i2),
        };
        let bound = lat.ring_bound(2);
        if two.second.distance_sq > bound * bound {
            lat.for_each_in_ring(2, self.seed, two.second.distance_sq.sqrt(), |c| {
                two.offer(c);
                two.second.distance_sq.sqrt()
            });
        }

        let a = two.first;
        let f1 = a.distance_sq.sqrt();
        let lower_edge = |b: DVec3, b_sq: f64, edge: &mut f64| {
            if let Some(d) = bisector_distance(a.offset_from_query, a.distance_sq, b, b_sq) {
                *edge = edge.min(d);
            }
        };
        let mut edge = f64::INFINITY;
        lower_edge(
            two.second.offset_from_query,
            two.second.distance_sq,
            &mut edge,
        );
        // Only sites with |q − b| < F1 + 2E can lower E (module proof).
        for (k, &b_sq) in distance_sq.iter().enumerate() {
            let reach = f1 + 2.0 * edge;
            if b_sq < reach * reach {
                lower_edge(block.offset_from_query(k), b_sq, &mut edge);
            }
        }
        for ring in 2..=MAX_RING {
            if f1 + 2.0 * edge <= lat.ring_bound(ring) {
                break;
            }
            lat.for_each_in_ring(ring, self.seed, f1 + 2.0 * edge, |b| {
                let reach = f1 + 2.0 * edge;
                if b.distance_sq < reach * reach {
                    lower_edge(b.offset_from_query, b.distance_sq, &mut edge);
                }
                f1 + 2.0 * edge
            });
        }
        // Only coincident sites (probability ~0) leave no bisector at all.
        let edge = if edge.is_finite() { edge } else { 0.0 };

        VoronoiSample {
            f1: f1 * self.cell_size,
            f2: two.second.distance_sq.sqrt() * self.cell_size,
            cell_id: a.hash,
            cell: lat.cell.wrapping_add(a.cell_offset),
            feature_point: lat.object_point(&a),
            second_feature_point: lat.object_point(&two.second),
            edge_distance: edge * self.cell_size,
        }
    }

    /// The reference the fast [`Voronoi::query`] is tested against: no
    /// pruning, no shared hash prefixes, the bisector formula as written.
    ///
    /// F1 and F2 come from all 5×5×5 cells around `p` (enough: F2 ≤ √3 and
    /// every site outside is more than 2 away, module proof). The edge
    /// distance is `min_b |(q − (a+b)/2) · (b−a)| / |b−a|` over every site
    /// `b ≠ a` of the 9×9×9 cells around `p`: a site can matter only if it is
    /// within `F1 + 2E < 2√3 < 4` of `q`, and sites of cells 5 or more away
    /// are more than 4 away. About 850 hashes per call: for tests only.
    pub fn query_brute_force(&self, p: DVec3) -> VoronoiSample {
        let scale = self.stretch * self.cell_size;
        let q = p / scale;
        let cell0 = q.floor().as_ivec3();
        let jitter = self.jitter.clamp(0.0, 1.0);
        let site = |cell: IVec3| -> (DVec3, u64) {
            let h = hash_cell(cell, self.seed);
            (cell.as_dvec3() + site_in_cell(h, jitter), h)
        };
        let block = |radius: i32| {
            (-radius..=radius).flat_map(move |dx| {
                (-radius..=radius).flat_map(move |dy| {
                    (-radius..=radius).map(move |dz| cell0.wrapping_add(IVec3::new(dx, dy, dz)))
                })
            })
        };

        let mut nearest = (f64::INFINITY, DVec3::ZERO, 0u64, IVec3::ZERO);
        let mut second = (f64::INFINITY, DVec3::ZERO);
        for cell in block(2) {
            let (s, h) = site(cell);
            let d = (s - q).length();
            if d < nearest.0 {
                second = (nearest.0, nearest.1);
                nearest = (d, s, h, cell);
            } else if d < second.0 {
                second = (d, s);
            }
        }

        let a = nearest.1;
        let mut edge = f64::INFINITY;
        for cell in block(4) {
            let (b, _) = site(cell);
            let ab = b - a;
            let len = ab.length();
            if len == 0.0 {
                continue;
            }
            // q is on a's side of every bisector, so the signed value is ≤ 0:
            // its magnitude is the distance.
            edge = edge.min(((q - 0.5 * (a + b)).dot(ab) / len).abs());
        }

        VoronoiSample {
            f1: nearest.0 * self.cell_size,
            f2: second.0 * self.cell_size,
            cell_id: nearest.2,
            cell: nearest.3,
            feature_point: a * scale,
            second_feature_point: second.1 * scale,
            edge_distance: edge * self.cell_size,
        }
    }
}
