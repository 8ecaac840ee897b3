//! The mean reflection of many glitter facets as one tabulated lobe, for a
//! pixel footprint that holds hundreds of them (issue 27's aggregate).
//!
//! A footprint of many facets reflects their mean, A(ωi, ωo) = E_n[f_n(ωi,
//! ωo)·cosθi(n)] over the map's facet normals n, each shaded by the full
//! layered BRDF in its own frame with the fall-back to the stone's normal
//! of `render::glitter_facets` (figure 4.6 ③). For facets tilted about the
//! stone's normal, A depends on the directions only through θo, θi and
//! φi − φo, and is symmetric in φi − φo. It is tabulated here once per
//! material: rows of θo, each a grid of rings of θi by sectors of φi − φo,
//! filled by Monte Carlo (facets drawn as a vertex draws them, each sampled
//! by its own BRDF, the weights f·cos/pdf summed into the cell of ωi).
//!
//! A vertex then costs one lookup instead of eight BRDF evaluations, and
//! its noise is that of a smooth lobe instead of eight sharp ones. The lobe
//! is sampled exactly: a row by the interpolation weight, a cell by the
//! row's cumulative table, a direction uniform in the cell's solid angle;
//! the density is the rows' interpolated cell densities, so sampling and
//! pdf agree by construction. Its value is approximate: constant over a
//! cell (2.8° of θi, 5.6° of φ), linear between rows 2.8° of θo apart,
//! and with the table's own Monte Carlo noise. Against the eight drawn
//! facets, fine glitter's pixels differed by no more than the noise of
//! 8192-spp renders, the stone's mean by 0.2 % in the studio and 1.3 %
//! under a small light (`bench/results/2026-12-04-glitter-aggregate-table.md`;
//! 16 rows put the studio's mean 1 % high: the mean is convex in θo).
//!
//! A table takes about 0.35 s of one core. It is built the first time a
//! pixel's footprint needs it (`GlitterFacets::aggregate`) and, when the
//! scene was handed a `TableCache` (`lapidary render` hands its own), kept
//! there as numbers, bit for bit, for the next render; paths after a
//! glossy or diffuse event keep drawing facets, so stones whose facets are
//! larger than their pixels (every built-in gem at its usual sizes) never
//! build one.

use std::f64::consts::{FRAC_PI_2, TAU};

use glam::{DQuat, DVec3};

use crate::brdf::compensation::material_key;
use crate::brdf::{LayeredBrdf, Rgb};
use crate::render::drawn_facets::{draw_facet_normals, Facet, FACETS_PER_VERTEX};
use crate::sampling::{sin_cos_turns, Rng};
use crate::texture::pattern::FacetBumpMap;

/// Rows over θo, at the centres of equal steps of θo in [0, π/2].
const THETA_O_ROWS: usize = 32;
/// Rings of equal steps of θi in [0, π/2] (equal steps of cos θi would
/// make the ring about the normal, where a head-on lobe peaks, 14° wide).
const THETA_I_RINGS: usize = 32;
/// Sectors of φi − φo over the full turn.
const PHI_SECTORS: usize = 64;
/// Cells of one row.
const CELLS: usize = THETA_I_RINGS * PHI_SECTORS;
/// Sets of [`FACETS_PER_VERTEX`] facets drawn per row while building.
const FACET_DRAWS_PER_ROW: usize = 1024;
/// BRDF samples per drawn facet while building.
const SAMPLES_PER_FACET: usize = 4;

/// θ bounds (radians) of ring or row step `k` of `steps` over [0, π/2].
fn theta_step(k: usize, steps: usize) -> (f64, f64) {
    let width = FRAC_PI_2 / steps as f64;
    (k as f64 * width, (k + 1) as f64 * width)
}

/// Solid angle of a cell in ring `ring`.
fn cell_sr(ring: usize) -> f64 {
    let (lo, hi) = theta_step(ring, THETA_I_RINGS);
    (lo.cos() - hi.cos()) * TAU / PHI_SECTORS as f64
}

/// The cell of a unit direction above the plane, in the frame whose z is
/// the stone's normal and whose x points towards ωo.
fn cell_of(local: DVec3) -> usize {
    let theta = local.z.clamp(-1.0, 1.0).acos();
    let ring = ((theta / FRAC_PI_2 * THETA_I_RINGS as f64) as usize).min(THETA_I_RINGS - 1);
    let phi = local.y.atan2(local.x).rem_euclid(TAU);
    let sector = ((phi / TAU * PHI_SECTORS as f64) as usize).min(PHI_SECTORS - 1);
    ring * PHI_SECTORS + sector
}

/// One θo row: per cell the mean f·cosθi (per steradian), the sampling
/// density, and the running total of density × solid angle (the last 1,
/// or 0 for a row that reflects nothing).
#[derive(Clone, Debug, PartialEq)]
struct Row {
    value: Vec<Rgb>,
    pdf: Vec<f64>,
    cumulative: Vec<f64>,
}

impl Row {
    /// The row for cos θo = `cos_o` (see the module's comment), from its
    /// own generator `rng`.
    fn build(facets: &FacetBumpMap, brdf: &LayeredBrdf, cos_o: f64, rng: &mut Rng) -> Self {
        let wo = DVec3::new((1.0 - cos_o * cos_o).max(0.0).sqrt(), 0.0, cos_o);
        let mut sums = vec![Rgb::ZERO; CELLS];
        for _ in 0..FACET_DRAWS_PER_ROW {
            let normals =
                draw_facet_normals(facets, (DVec3::Z, DVec3::Z, DQuat::IDENTITY), wo, rng);
            for normal in normals {
                let facet = Facet::new(brdf, normal, wo);
                for _ in 0..SAMPLES_PER_FACET {
                    let Some((wi, weight)) = facet.sample(rng.next_3()) else {
                        continue;
                    };
                    // Light from below the stone's surface reaches no facet.
                    if wi.z > 0.0 {
                        sums[cell_of(wi)] += weight;
                    }
                }
            }
        }
        let count = (FACET_DRAWS_PER_ROW * FACETS_PER_VERTEX * SAMPLES_PER_FACET) as f64;
        // The mean of each cell and its mirror image in φ (the lobe is
        // symmetric: half the noise), per steradian.
        let mut value: Vec<Rgb> = (0..CELLS)
            .map(|cell| {
                let (ring, sector) = (cell / PHI_SECTORS, cell % PHI_SECTORS);
                let mirror = ring * PHI_SECTORS + PHI_SECTORS - 1 - sector;
                (sums[cell] + sums[mirror]) * (0.5 / (count * cell_sr(ring)))
            })
            .collect();
        // Energy: the facets reflect at most what falls on them, but the
        // estimate of a lossless material may exceed it by its noise.
        let albedo = value.iter().enumerate().fold(Rgb::ZERO, |sum, (cell, v)| {
            sum + *v * cell_sr(cell / PHI_SECTORS)
        });
        let excess = albedo.max_element();
        if excess > 1.0 {
            value.iter_mut().for_each(|v| *v /= excess);
        }
        Self::from_value(value)
    }

    /// The row of these mean values per cell: its sampling density (by the
    /// mean of the three channels) and their running total.
    fn from_value(value: Vec<Rgb>) -> Self {
        let weight: Vec<f64> = value.iter().map(|v| (v.x + v.y + v.z) / 3.0).collect();
        let total: f64 = weight
            .iter()
            .enumerate()
            .map(|(cell, w)| w * cell_sr(cell / PHI_SECTORS))
            .sum();
        let pdf: Vec<f64> = weight
            .iter()
            .map(|w| if total > 0.0 { w / total } else { 0.0 })
            .collect();
        let cumulative = pdf
            .iter()
            .enumerate()
            .scan(0.0, |running, (cell, p)| {
                *running += p * cell_sr(cell / PHI_SECTORS);
                Some(*running)
            })
            .collect();
        Self {
            value,
            pdf,
            cumulative,
        }
    }
}

/// The tabulated mean reflection of one material's glitter facets (see the
/// module's comment).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct AggregateTable {
    rows: Vec<Row>,
}

impl AggregateTable {
    /// The table of `brdf` over the facets of `facets`, whose tilts must
    /// be about the stone's normal. A pure function of its arguments.
    ///
    /// The rows are built on as many scoped threads as the current rayon
    /// pool has (each row from its own generator, so the table does not
    /// depend on how many): the caller is a render task waiting in a
    /// `OnceLock`, and rayon's own workers, waiting for a part of this
    /// build, could take up another render task that waits on the same lock.
    pub(crate) fn build(facets: &FacetBumpMap, brdf: &LayeredBrdf) -> Self {
        let row = |row: usize| {
            let (lo, hi) = theta_step(row, THETA_O_ROWS);
            let mut rng = Rng::new(row as u64, TABLE_STREAM);
            Row::build(facets, brdf, (0.5 * (lo + hi)).cos(), &mut rng)
        };
        let workers = rayon::current_num_threads().clamp(1, THETA_O_ROWS);
        let mut rows: Vec<(usize, Row)> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..workers)
                .map(|first| {
                    scope.spawn(move || {
                        (first..THETA_O_ROWS)
                            .step_by(workers)
                            .map(|r| (r, row(r)))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            handles
                .into_iter()
                .flat_map(|handle| {
                    handle
                        .join()
                        .unwrap_or_else(|e| std::panic::resume_unwind(e))
                })
                .collect()
        });
        rows.sort_unstable_by_key(|(r, _)| *r);
        Self {
            rows: rows.into_iter().map(|(_, row)| row).collect(),
        }
    }

    /// The table as numbers: each row's cells' values, R, G, B in turn.
    pub(crate) fn to_numbers(&self) -> Vec<f64> {
        self.rows
            .iter()
            .flat_map(|row| row.value.iter().flat_map(|v| [v.x, v.y, v.z]))
            .collect()
    }

    /// The table of [`Self::to_numbers`]'s numbers (the same table, bit for
    /// bit); None for a list of the wrong length or with a value below 0.
    pub(crate) fn from_numbers(numbers: &[f64]) -> Option<Self> {
        if numbers.len() != THETA_O_ROWS * CELLS * 3
            || numbers.iter().any(|x| x.is_nan() || *x < 0.0)
        {
            return None;
        }
        let rows = numbers
            .chunks_exact(CELLS * 3)
            .map(|row| {
                Row::from_value(
                    row.chunks_exact(3)
                        .map(|v| Rgb::new(v[0], v[1], v[2]))
                        .collect(),
                )
            })
            .collect();
        Some(Self { rows })
    }

    /// The key under which the table of `brdf` over facets tilted as
    /// `facets` is kept (its material, its tilts, how it is built).
    pub(crate) fn key(facets: &FacetBumpMap, brdf: &LayeredBrdf) -> String {
        format!(
            "glitter aggregate v1; rows {THETA_O_ROWS}, rings {THETA_I_RINGS}, sectors {PHI_SECTORS}, \
             draws {FACET_DRAWS_PER_ROW} x {FACETS_PER_VERTEX}, samples {SAMPLES_PER_FACET}; \
             tilt {:?} about {:?}; {}",
            facets.tilt,
            facets.around,
            material_key(brdf, TABLE_STREAM)
        )
    }

    /// The rows on either side of cos θo = `cos_o` and the second's weight
    /// (linear in θo; the first or last row alone beyond the rows' centres).
    fn rows_about(&self, cos_o: f64) -> (&Row, &Row, f64) {
        let theta = cos_o.clamp(0.0, 1.0).acos();
        let x =
            (theta / FRAC_PI_2 * THETA_O_ROWS as f64 - 0.5).clamp(0.0, (THETA_O_ROWS - 1) as f64);
        let first = (x as usize).min(THETA_O_ROWS - 1);
        let second = (first + 1).min(THETA_O_ROWS - 1);
        (&self.rows[first], &self.rows[second], x - first as f64)
    }

    /// A·cos and the sampling density (per steradian) towards `wi`, in the
    /// frame whose z is the stone's normal and whose x points towards ωo,
    /// for cos θo = `cos_o`.
    fn eval(&self, cos_o: f64, wi: DVec3) -> (Rgb, f64) {
        if wi.z <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let (first, second, weight) = self.rows_about(cos_o);
        let cell = cell_of(wi);
        (
            first.value[cell] * (1.0 - weight) + second.value[cell] * weight,
            first.pdf[cell] * (1.0 - weight) + second.pdf[cell] * weight,
        )
    }

    /// A direction in the frame of [`Self::eval`] from three uniform
    /// numbers: the row by the first, the cell by the second (whose place
    /// within the cell's share also gives φ within the cell), cos θi within
    /// the ring by the third. `None` where the row reflects nothing.
    fn sample(&self, cos_o: f64, u: [f64; 3]) -> Option<DVec3> {
        let (first, second, weight) = self.rows_about(cos_o);
        let row = if u[0] < weight { second } else { first };
        let total = *row.cumulative.last()?;
        if total <= 0.0 {
            return None;
        }
        let target = u[1] * total;
        let cell = row
            .cumulative
            .partition_point(|&c| c <= target)
            .min(CELLS - 1);
        let below = if cell == 0 {
            0.0
        } else {
            row.cumulative[cell - 1]
        };
        let share = row.cumulative[cell] - below;
        let within = if share > 0.0 {
            ((target - below) / share).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let (ring, sector) = (cell / PHI_SECTORS, cell % PHI_SECTORS);
        let (lo, hi) = theta_step(ring, THETA_I_RINGS);
        // Uniform in cos θ within the ring and in φ within the sector:
        // uniform in solid angle over the cell.
        let cos_i = lo.cos() + (hi.cos() - lo.cos()) * u[2];
        let sin_i = (1.0 - cos_i * cos_i).max(0.0).sqrt();
        let (sin_phi, cos_phi) = sin_cos_turns((sector as f64 + within) / PHI_SECTORS as f64);
        Some(DVec3::new(sin_i * cos_phi, sin_i * sin_phi, cos_i))
    }
}

/// The stream of the table's generator, apart from the render's.
const TABLE_STREAM: u64 = 0x61_6767_7265;

/// A table seen from one vertex: the frame of its stone's normal and ωo.
#[derive(Clone, Copy)]
pub(crate) struct TableAt<'a> {
    table: &'a AggregateTable,
    towards_wo: DVec3,
    across: DVec3,
    normal: DVec3,
    cos_o: f64,
}

impl<'a> TableAt<'a> {
    /// `table` at a vertex whose stone's unit normal is `normal` (world),
    /// seen from the unit `wo` (world).
    pub(crate) fn new(table: &'a AggregateTable, normal: DVec3, wo: DVec3) -> Self {
        let cos_o = wo.dot(normal).clamp(0.0, 1.0);
        let tangential = wo - normal * cos_o;
        // Head on, φo is any direction: the rows there are nearly round.
        let towards_wo = if tangential.length_squared() > 1e-20 {
            tangential.normalize()
        } else {
            normal.any_orthonormal_pair().0
        };
        Self {
            table,
            towards_wo,
            across: normal.cross(towards_wo),
            normal,
            cos_o,
        }
    }

    /// The table's f·cosθi towards the unit `wi` (world) and the density
    /// with which [`Self::sample_direction`] draws it.
    pub(crate) fn eval_cos_and_pdf(&self, wi: DVec3) -> (Rgb, f64) {
        let local = DVec3::new(
            wi.dot(self.towards_wo),
            wi.dot(self.across),
            wi.dot(self.normal),
        );
        self.table.eval(self.cos_o, local)
    }

    /// A direction (world) from three uniform numbers, with the density
    /// [`Self::eval_cos_and_pdf`] gives.
    pub(crate) fn sample_direction(&self, u: [f64; 3]) -> Option<DVec3> {
        let local = self.table.sample(self.cos_o, u)?;
        Some(self.towards_wo * local.x + self.across * local.y + self.normal * local.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recipe::compile::load_material_without_table;
    use crate::recipe::gem::parse_gem;
    use crate::recipe::library::builtin_gem_source;
    use crate::render::chi2_cells::{cap_grid, hemisphere_cell, hemisphere_cells, Tally};
    use crate::render::glitter_facets::FacetMix;

    /// The lavender lepidolite's glitter facets (a 20° cone about the
    /// stone's normal).
    fn lepidolite_facets() -> FacetBumpMap {
        let source = builtin_gem_source("lavender-lepidolite").unwrap();
        let gem = parse_gem("lavender-lepidolite", source).unwrap();
        gem.pattern.glitter().expect("a glitter map").facets
    }

    /// Views from head on to grazing: at a row's centre and between rows.
    fn views() -> Vec<DVec3> {
        [0.0f64, 20.0, 47.0, 81.0]
            .iter()
            .map(|deg| {
                let (s, c) = deg.to_radians().sin_cos();
                DVec3::new(s, 0.0, c)
            })
            .collect()
    }

    #[test]
    fn a_table_kept_as_numbers_is_the_same_table() {
        // What the table cache keeps and gives back: the same table, bit
        // for bit (so a render from the cache is the same bytes); a list
        // of the wrong length or with a negative or NaN value is refused.
        let (brdf, _) = load_material_without_table("green-latex").unwrap();
        let table = AggregateTable::build(&lepidolite_facets(), &brdf);
        let numbers = table.to_numbers();
        assert_eq!(AggregateTable::from_numbers(&numbers), Some(table));
        assert_eq!(AggregateTable::from_numbers(&numbers[1..]), None);
        for bad in [-1e-9, f64::NAN] {
            let mut damaged = numbers.clone();
            damaged[7] = bad;
            assert_eq!(AggregateTable::from_numbers(&damaged), None);
        }
    }

    #[test]
    fn sampling_matches_the_pdf_and_the_weight_is_the_table_s() {
        // χ² of 4·10⁵ samples against the pdf integrated over 24 × 48
        // cells of equal solid angle (each from 10 × 10 sub-cells; the
        // table's own cells are finer in θ near the normal, so the grids
        // differ); at every sample eval's pdf is the sample's and its
        // f·cosθi over the pdf the weight. A rough paint's facets: a lobe
        // wide enough for the grid.
        const N_COS: usize = 24;
        const N_PHI: usize = 48;
        let (brdf, _) = load_material_without_table("green-latex").unwrap();
        let table = AggregateTable::build(&lepidolite_facets(), &brdf);
        for (view, wo) in views().into_iter().enumerate() {
            let at = TableAt::new(&table, DVec3::Z, wo);
            let (expected, range) =
                hemisphere_cells(|w| at.eval_cos_and_pdf(w).1, N_COS, N_PHI, 10);
            let samples = 400_000;
            let mut observed = vec![0u32; N_COS * N_PHI];
            let mut rng = Rng::new(view as u64, 3);
            for _ in 0..samples {
                let Some((wi, weight, pdf)) = FacetMix::tabulated(at).sample(rng.next_3()) else {
                    continue;
                };
                let (value, eval_pdf) = at.eval_cos_and_pdf(wi);
                assert!((eval_pdf - pdf).abs() <= 1e-12 * pdf, "{eval_pdf} vs {pdf}");
                assert!((value / pdf - weight).abs().max_element() <= 1e-12 * weight.max_element());
                observed[hemisphere_cell(wi, N_COS, N_PHI)] += 1;
            }
            let expected: Vec<f64> = expected.iter().map(|e| e * samples as f64).collect();
            Tally::new(&expected, &observed, &range).assert_agrees(100, &format!("view {view}"));
        }
    }

    #[test]
    fn the_table_reflects_what_the_drawn_facets_reflect_where_they_reflect_it() {
        // The expected value the drawn facets estimate, E over draws of the
        // mixture's f·cosθi, integrated over eight regions of the
        // hemisphere (θi below or above 45°, four quadrants of φi − φo) by
        // sampling the mixtures (2000 draws, 64 samples each: the weights
        // summed by region, a different estimator from the table's
        // facet-by-facet one), against the table's integrals over the same
        // regions, whose edges are edges of its cells, as a share of the
        // largest region: within 3 % for a rough paint (measured up to
        // 2.7 %) and 4 % for white Lambert (up to 3.2 %), scattered both
        // ways (the table's own noise is 1–2 % a region, the mixtures'
        // below 1 %). White Lambert is the lossless furnace: its drawn
        // mixtures reflect exactly what does not leave below the stone's
        // plane. Its rows also reflect at most 1 (the build scales a row
        // whose noise puts it above) and more than 0.9.
        let (paint, _) = load_material_without_table("green-latex").unwrap();
        let white = crate::render::glitter_facets::white_lambert();
        let facets = lepidolite_facets();
        let region = |w: DVec3| {
            let quadrant = (w.y.atan2(w.x).rem_euclid(TAU) / (TAU / 4.0)) as usize;
            usize::from(w.z < std::f64::consts::FRAC_1_SQRT_2) * 4 + quadrant.min(3)
        };
        for (name, brdf, tolerance) in [("paint", &paint, 0.03), ("white", &white, 0.04)] {
            let table = AggregateTable::build(&facets, brdf);
            for (view, wo) in views().into_iter().enumerate() {
                let (mut drawn, mut tabulated) = ([Rgb::ZERO; 8], [Rgb::ZERO; 8]);
                let mut rng = Rng::new(view as u64, 8);
                let (draws, samples) = (2000, 64);
                for _ in 0..draws {
                    let normals = draw_facet_normals(
                        &facets,
                        (DVec3::Z, DVec3::Z, DQuat::IDENTITY),
                        wo,
                        &mut rng,
                    );
                    let mix = FacetMix::new(brdf, &normals, wo);
                    for _ in 0..samples {
                        if let Some((wi, weight, _)) = mix.sample(rng.next_3()) {
                            if wi.z > 0.0 {
                                drawn[region(wi)] += weight / (draws * samples) as f64;
                            }
                        }
                    }
                }
                let at = TableAt::new(&table, DVec3::Z, wo);
                for (ring, sector) in
                    (0..THETA_I_RINGS).flat_map(|i| (0..PHI_SECTORS).map(move |j| (i, j)))
                {
                    let (lo, hi) = theta_step(ring, THETA_I_RINGS);
                    let (theta, phi) = (
                        0.5 * (lo + hi),
                        (sector as f64 + 0.5) / PHI_SECTORS as f64 * TAU,
                    );
                    let w = DVec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    );
                    tabulated[region(w)] += at.eval_cos_and_pdf(w).0 * cell_sr(ring);
                }
                let largest = drawn.iter().map(|v| v.max_element()).fold(0.0, f64::max);
                for (k, (d, t)) in drawn.iter().zip(&tabulated).enumerate() {
                    assert!(
                        (*d - *t).abs().max_element() < tolerance * largest,
                        "{name}, view {view}, region {k}: drawn {d}, table {t}"
                    );
                }
            }
        }
        let table = AggregateTable::build(&facets, &white);
        for row in 0..THETA_O_ROWS {
            let (lo, hi) = theta_step(row, THETA_O_ROWS);
            let cos_o = (0.5 * (lo + hi)).cos();
            let albedo = cap_grid(0.0, 360, 720).fold(Rgb::ZERO, |sum, (w, solid_angle)| {
                sum + table.eval(cos_o, w).0 * solid_angle
            });
            assert!(
                albedo.max_element() <= 1.0 + 1e-3 && albedo.min_element() > 0.9,
                "row {row}: {albedo}"
            );
        }
    }
}
