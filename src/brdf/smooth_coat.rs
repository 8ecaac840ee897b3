//! E_stack of one smooth coat over a rough base, without random walks: the
//! walk's light, trapped between the coat and the base, is a Markov chain
//! in one number, the cosine of its direction, whose escape probability
//! solves a small linear system.
//!
//! Under a smooth coat (roughness at the clamp `MIN_ROUGHNESS_DEG`) the
//! random walk of [`crate::brdf::reference`] does three things over and
//! over: it crosses the layer (Beer, T(ν) = exp(−αd/ν), eq. 3.4), scatters
//! at the base (a new direction and a weight), crosses the layer again and
//! meets the coat from inside, where the part 1 − F_in(ν) of the power
//! leaves and the part F_in(ν) is mirrored back down at the same cosine ν
//! (F_in = 1 beyond the critical angle: total internal reflection). Every
//! base of the model is isotropic, so where the base sends the light
//! depends on the incoming direction only through its cosine; so does
//! everything at the coat. The expected power U(ν) that finally leaves,
//! for unit power arriving at the base at cosine ν, therefore obeys
//!
//! U(ν) = E[ w · T(ν′) · (1 − F_in(ν′) + F_in(ν′) · T(ν′) · U(ν′)) ],
//!
//! the expectation over the base's sampled scattering ν → ν′ with weight w
//! (the walk's base scattering in expectation, by `scatter_base_stratified`:
//! its micro-facet albedo table and conductor Fresnel table included), and
//! the stack's albedo is
//!
//! E_stack(μ) = F(μ) + (1 − F(μ)) · T(μ′) · U(μ′),   μ′ the refracted cosine.
//!
//! U is represented by its values at `CHAIN_NODES` cosines with linear
//! interpolation between them. Each node's expectation is a stratified
//! average over `CHAIN_SAMPLES_SIDE`² base samples in which the escaping
//! term is exact for each sample's own ν′ (the Fresnel step at the critical
//! angle is never interpolated) and only U(ν′) of the light sent back is
//! interpolated. That gives U = b + M·U with M ≥ 0 and row sums below 1
//! (every bounce loses light to the base or out of the coat), solved by
//! Gaussian elimination, stable without pivoting for such a matrix.
//!
//! Against the walk: the lavender lepidolite's silver flakes under a
//! smooth coat keep light trapped beyond the critical angle for dozens of
//! bounces, so the walk needs its maximum 8192 paths at most grazing nodes
//! and still leaves a standard error of 2·10⁻³; the chain costs a fixed
//! number of base samples and has no such noise.

use crate::brdf::fresnel;
use crate::brdf::layer::{Base, Interface};
use crate::brdf::microfacet::MIN_ROUGHNESS_DEG;
use crate::brdf::reference::{scatter_base_stratified, WalkTables};
use crate::brdf::stack::LayeredBrdf;
use crate::brdf::Rgb;
use crate::sampling::Rng;
use glam::DVec3;
use rayon::prelude::*;

/// Cosines at which U is solved for: ν_j = (j + ½)/N.
pub(crate) const CHAIN_NODES: usize = 256;
/// Each node's expectation averages a jittered grid of this many squared
/// base samples.
pub(crate) const CHAIN_SAMPLES_SIDE: usize = 32;
/// The first bounce of [`SmoothCoatChain::albedo`], whose escaping part is
/// the answer's largest (a 32² grid leaves ~5·10⁻⁴ of noise there against
/// the closed form over Lambert; this one ~10⁻⁴), averages this many
/// squared samples.
pub(crate) const FIRST_BOUNCE_SAMPLES_SIDE: usize = 64;

/// E_stack of one smooth coat over a conductor, Oren-Nayar or any other
/// base, from the solved chain (see the module docs).
#[derive(Clone, Debug)]
pub struct SmoothCoatChain {
    /// The coat: its relative index and Beer transmittance.
    coat: Interface,
    /// The base, sampled as the walk samples it.
    base: Base,
    /// The walk's tables of the base (micro-facet albedo, conductor Fresnel).
    tables: WalkTables,
    /// U(ν_j) per channel.
    escape_at_node: Vec<Rgb>,
    /// The seed of the stratified base samples.
    seed: u64,
}

/// The one interface of `brdf` when it is its only one and smooth
/// (roughness at the clamp [`MIN_ROUGHNESS_DEG`]); None otherwise.
pub(crate) fn the_smooth_coat(brdf: &LayeredBrdf) -> Option<&Interface> {
    match brdf.interfaces.as_slice() {
        [coat] if coat.own_lobe.roughness_deg <= MIN_ROUGHNESS_DEG => Some(coat),
        _ => None,
    }
}

/// Whether light leaving `base` forgets its direction or never leaves:
/// a Lambertian (σ ≤ 0) or black base, under a smooth coat the case of the
/// closed form.
pub(crate) fn base_is_lambert_or_black(base: &Base) -> bool {
    match base {
        Base::Diffuse {
            oren_nayar_sigma_rad,
            ..
        } => *oren_nayar_sigma_rad <= 0.0,
        Base::Black => true,
        Base::Conductor { .. } => false,
    }
}

/// Rng stream of the base samples at chain node `j` (evaluation rows use
/// streams after the nodes').
fn node_stream(j: usize) -> u64 {
    0x5c0a_7000 + j as u64
}

impl SmoothCoatChain {
    /// The chain for `brdf` when it is one smooth coat over a base other
    /// than a Lambertian or black one (those have the exact closed form
    /// [`crate::brdf::compensation::SmoothCoatOverLambert`]); None for
    /// every other stack.
    pub fn of(brdf: &LayeredBrdf, seed: u64) -> Option<Self> {
        if base_is_lambert_or_black(&brdf.base) {
            return None;
        }
        Self::of_any_base(brdf, seed)
    }

    /// The chain for one smooth coat over any base, Lambertian included
    /// (where the tests compare it with the closed form).
    pub fn of_any_base(brdf: &LayeredBrdf, seed: u64) -> Option<Self> {
        let coat = the_smooth_coat(brdf)?;
        let mut chain = SmoothCoatChain {
            coat: coat.clone(),
            base: brdf.base.clone(),
            tables: WalkTables::of_base(&brdf.base),
            escape_at_node: Vec::new(),
            seed,
        };
        let rows: Vec<(Rgb, Vec<Rgb>)> = (0..CHAIN_NODES)
            .into_par_iter()
            .map(|j| chain.row(node_cosine(j), node_stream(j)))
            .collect();
        chain.escape_at_node = solve_escape(rows);
        Some(chain)
    }

    /// One node's expectation: the light leaving directly, and per node
    /// the weight with which U there contributes (tent interpolation of the
    /// light mirrored back down), for light arriving at the base at cosine
    /// `nu`.
    fn row(&self, nu: f64, stream: u64) -> (Rgb, Vec<Rgb>) {
        let mut sent_back = vec![Rgb::ZERO; CHAIN_NODES];
        let escaping = self.for_each_bounce(nu, stream, CHAIN_SAMPLES_SIDE, |nu_out, back| {
            let (j, t) = tent(nu_out);
            sent_back[j] += back * (1.0 - t);
            if t > 0.0 {
                sent_back[j + 1] += back * t;
            }
        });
        (escaping, sent_back)
    }

    /// Averages over a jittered `side` × `side` grid of base samples at
    /// cosine `nu`: returns the escaping part E[w·T(ν′)·(1 − F_in(ν′))]
    /// and calls `sent_back(ν′, w·T(ν′)²·F_in(ν′)/side²)` for every sample.
    fn for_each_bounce(
        &self,
        nu: f64,
        stream: u64,
        side: usize,
        mut sent_back: impl FnMut(f64, Rgb),
    ) -> Rgb {
        let w_away = DVec3::new((1.0 - nu * nu).max(0.0).sqrt(), 0.0, nu);
        let mut rng = Rng::new(self.seed, stream);
        let per_sample = 1.0 / (side * side) as f64;
        let mut escaping = Rgb::ZERO;
        for a in 0..side {
            for b in 0..side {
                let u = [
                    (a as f64 + rng.next_f64()) / side as f64,
                    (b as f64 + rng.next_f64()) / side as f64,
                ];
                let Some((w, weight)) =
                    scatter_base_stratified(&self.base, &self.tables, w_away, u)
                else {
                    continue;
                };
                let nu_out = w.z;
                let crossing = self.coat.crossing_transmittance(nu_out);
                let f_inside = fresnel::dielectric(nu_out, 1.0 / self.coat.eta);
                let carried = weight * crossing * per_sample;
                escaping += carried * (1.0 - f_inside);
                sent_back(nu_out, carried * crossing * f_inside);
            }
        }
        escaping
    }

    /// E_stack(μ) for light arriving from above at cosine `mu`; `stream`
    /// picks the base samples of the first bounce (the table node's index,
    /// so that each node has its own).
    pub fn albedo(&self, mu: f64, stream: u64) -> Rgb {
        let eta = self.coat.eta;
        // Snell once for F(μ) and the refracted cosine μ′.
        let snell = fresnel::Snell::at(mu, eta);
        let f = fresnel::dielectric_from_snell(mu, snell, eta);
        let Some(mu_inside) = snell.cos_t else {
            return Rgb::splat(f);
        };
        // The first bounce sampled afresh at the refracted cosine itself,
        // its escaping part exact, U interpolated only for what returns.
        let mut returned = Rgb::ZERO;
        let escaping = self.for_each_bounce(
            mu_inside,
            node_stream(CHAIN_NODES) + stream,
            FIRST_BOUNCE_SAMPLES_SIDE,
            |nu_out, back| returned += back * self.escape(nu_out),
        );
        Rgb::splat(f)
            + self.coat.crossing_transmittance(mu_inside) * (escaping + returned) * (1.0 - f)
    }

    /// U(ν) interpolated between the nodes.
    fn escape(&self, nu: f64) -> Rgb {
        let (j, t) = tent(nu);
        let low = self.escape_at_node[j] * (1.0 - t);
        if t > 0.0 {
            low + self.escape_at_node[j + 1] * t
        } else {
            low
        }
    }
}

/// Cosine of chain node `j`.
fn node_cosine(j: usize) -> f64 {
    (j as f64 + 0.5) / CHAIN_NODES as f64
}

/// The node below `nu` and the weight t of the node above it (0 outside the
/// nodes' range, where U is held constant).
fn tent(nu: f64) -> (usize, f64) {
    let x = (nu * CHAIN_NODES as f64 - 0.5).clamp(0.0, (CHAIN_NODES - 1) as f64);
    let j = (x as usize).min(CHAIN_NODES - 1);
    (j, x - j as f64)
}

/// Solves U = b + M·U, i.e. (I − M)·U = b, per channel, from the rows
/// (b_j, M_j·) by Gaussian elimination. I − M is a nonsingular M-matrix
/// (M ≥ 0, every row sum below 1), whose pivots stay positive without
/// row exchanges.
fn solve_escape(rows: Vec<(Rgb, Vec<Rgb>)>) -> Vec<Rgb> {
    let n = rows.len();
    let (mut rhs, mut matrix): (Vec<Rgb>, Vec<Vec<Rgb>>) = rows
        .into_iter()
        .enumerate()
        .map(|(i, (b, mut row))| {
            for value in row.iter_mut() {
                *value = -*value;
            }
            row[i] += Rgb::ONE;
            (b, row)
        })
        .unzip();
    for pivot in 0..n {
        let (upper, lower) = matrix.split_at_mut(pivot + 1);
        let pivot_row = &upper[pivot];
        let inverse = Rgb::ONE / pivot_row[pivot];
        let pivot_rhs = rhs[pivot];
        for (offset, row) in lower.iter_mut().enumerate() {
            let factor = row[pivot] * inverse;
            if factor == Rgb::ZERO {
                continue;
            }
            for (value, above) in row[pivot..].iter_mut().zip(&pivot_row[pivot..]) {
                *value -= factor * *above;
            }
            rhs[pivot + 1 + offset] -= factor * pivot_rhs;
        }
    }
    let mut solution = vec![Rgb::ZERO; n];
    for i in (0..n).rev() {
        let mut sum = rhs[i];
        for k in i + 1..n {
            sum -= matrix[i][k] * solution[k];
        }
        solution[i] = sum / matrix[i][i];
    }
    solution
}
