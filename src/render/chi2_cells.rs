//! What the tests of the aggregate lobes' sampling (`flake_lobe`,
//! `glitter_facets`, `glitter_aggregate`) share: grids of directions of
//! equal solid angle, and the χ² tally of cells with the probability the
//! pdf gives each and the samples that fell in it.

use std::f64::consts::TAU;

use glam::DVec3;

/// A χ² tally over cells: cells expected below five samples are pooled,
/// and cells over which the pdf varies more than fourfold (where a grid of
/// sub-cells cannot integrate it well) are only summed, to be compared in
/// total.
pub(crate) struct Tally {
    /// Pearson's χ² over the even cells (and the pool).
    chi2: f64,
    /// The cells (and the pool) it sums over.
    cells: usize,
    /// Samples expected and seen in the uneven cells.
    uneven_expected: f64,
    uneven_observed: f64,
}

impl Tally {
    /// The tally of `observed` samples per cell against `expected`
    /// samples, the least and most pdf over each cell in `range`.
    pub(crate) fn new(expected: &[f64], observed: &[u32], range: &[(f64, f64)]) -> Self {
        let mut tally = Tally {
            chi2: 0.0,
            cells: 0,
            uneven_expected: 0.0,
            uneven_observed: 0.0,
        };
        let (mut pooled_e, mut pooled_o) = (0.0, 0.0);
        for ((&e, &o), &(least, most)) in expected.iter().zip(observed).zip(range) {
            let o = f64::from(o);
            if most > 4.0 * least {
                tally.uneven_expected += e;
                tally.uneven_observed += o;
            } else if e < 5.0 {
                pooled_e += e;
                pooled_o += o;
            } else {
                tally.chi2 += (o - e).powi(2) / e;
                tally.cells += 1;
            }
        }
        if pooled_e >= 5.0 {
            tally.chi2 += (pooled_o - pooled_e).powi(2) / pooled_e;
            tally.cells += 1;
        }
        tally
    }

    /// Whether the uneven cells' total is within 3 % and 4σ of what they
    /// expect.
    fn uneven_cells_agree(&self) -> bool {
        (self.uneven_observed - self.uneven_expected).abs()
            <= 0.03 * self.uneven_expected + 4.0 * self.uneven_expected.sqrt()
    }

    /// Whether χ² lies below its mean (the cells less one) plus six of its
    /// standard deviations (√(2·cells)): far beyond chance.
    fn passes(&self) -> bool {
        let cells = self.cells as f64;
        self.chi2 < cells - 1.0 + 6.0 * (2.0 * cells).sqrt()
    }

    /// Asserts that the uneven cells agree, that more than `least_cells`
    /// cells were compared, and that χ² passes; `label` names the case in
    /// the message.
    pub(crate) fn assert_agrees(&self, least_cells: usize, label: &str) {
        assert!(
            self.uneven_cells_agree(),
            "{label}: {} samples in the uneven cells, expected {:.0}",
            self.uneven_observed,
            self.uneven_expected
        );
        assert!(self.cells > least_cells, "{label}: {} cells", self.cells);
        assert!(
            self.passes(),
            "{label}: χ² {:.0} over {} cells",
            self.chi2,
            self.cells
        );
    }
}

/// Directions on a (cos θ, φ) grid over the cap cos θ ≥ `z_min` about
/// z, of equal solid angle per cell: (direction, the cell's solid
/// angle).
pub(crate) fn cap_grid(
    z_min: f64,
    n_cos: usize,
    n_phi: usize,
) -> impl Iterator<Item = (DVec3, f64)> {
    let cell = TAU * (1.0 - z_min) / (n_cos * n_phi) as f64;
    (0..n_cos).flat_map(move |i| {
        (0..n_phi).map(move |j| {
            let z = z_min + (1.0 - z_min) * (i as f64 + 0.5) / n_cos as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = TAU * (j as f64 + 0.5) / n_phi as f64;
            (DVec3::new(r * phi.cos(), r * phi.sin(), z), cell)
        })
    })
}

/// The cell of a unit direction with z ≥ 0 in the grid of `n_cos` bands of
/// cos θ by `n_phi` sectors of φ over the hemisphere.
pub(crate) fn hemisphere_cell(w: DVec3, n_cos: usize, n_phi: usize) -> usize {
    let i = ((w.z * n_cos as f64) as usize).min(n_cos - 1);
    let phi = w.y.atan2(w.x).rem_euclid(TAU);
    let j = ((phi / TAU * n_phi as f64) as usize).min(n_phi - 1);
    i * n_phi + j
}

/// For each cell of that grid ([`hemisphere_cell`]), the probability the
/// density `pdf` (per steradian) gives it, integrated over `fine` × `fine`
/// sub-cells, and the least and most pdf met over it: what [`Tally::new`]
/// takes, once the probabilities are scaled to samples.
pub(crate) fn hemisphere_cells(
    pdf: impl Fn(DVec3) -> f64,
    n_cos: usize,
    n_phi: usize,
    fine: usize,
) -> (Vec<f64>, Vec<(f64, f64)>) {
    let mut probability = vec![0.0; n_cos * n_phi];
    let mut range = vec![(f64::INFINITY, 0.0f64); n_cos * n_phi];
    for (w, solid_angle) in cap_grid(0.0, n_cos * fine, n_phi * fine) {
        let p = pdf(w);
        let cell = hemisphere_cell(w, n_cos, n_phi);
        probability[cell] += p * solid_angle;
        let (least, most) = range[cell];
        range[cell] = (least.min(p), most.max(p));
    }
    (probability, range)
}
