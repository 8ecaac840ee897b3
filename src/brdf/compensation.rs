//! Energy between layers: the multiple-scattering compensation lobe.
//!
//! The model of the notes lets light cross each layer once ("light travels
//! only once between layers", table 2.1), so a white Lambert base under a
//! clear IOR 1.5 coat reflects ≈ 0.43 of the light instead of ≈ 1: the
//! light reflected back down by the inside of the coat is lost. For a
//! diffuse base the missing series is ρ/(1 − ρ·F_dr); for rough and metallic
//! stacks it has no closed form.
//!
//! In the manner of Kulla & Conty (2017) we tabulate albedos when the
//! material is compiled: E_single(μ), the directional albedo of the
//! single-crossing model, and E_stack(μ), the albedo of the physical stack
//! from the random walk of [`crate::brdf::reference`] (the way Kulla & Conty's
//! tables are themselves Monte Carlo integrals). The deficit
//! D(μ) = E_stack − E_single is split into its positive part P (energy the
//! single crossing loses) and negative part X (energy it invents, e.g. at
//! grazing angles through rough coats, where the appendix's t term lets
//! shadowed light pass), each returned by a reciprocal lobe
//!
//! f_ms(ωᵢ, ωₒ) = P(μᵢ)·P(μₒ)/(π·P̄) − X(μᵢ)·X(μₒ)/(π·X̄),   P̄ = 2∫P(μ)μ dμ,
//!
//! whose albedo at every angle is exactly P(μ) − X(μ) = D(μ) (Kulla & Conty,
//! eq. 3, with 1 − E replaced by the deficit), per colour channel. The sum
//! with the single-crossing BRDF is clamped at zero by the caller.
//!
//! Cost (compiling must not dominate a render): a smooth coat over a
//! Lambertian or black base needs no walk, its series sums in closed form
//! ([`SmoothCoatOverLambert`]); a smooth coat over any other base (metal
//! flakes) is the walk's Markov chain in the cosine, solved
//! ([`crate::brdf::smooth_coat`]); other stacks trace stratified batches of
//! walks only until the node's standard error is below 10⁻³
//! ([`adaptive_walk_albedo`]); E_single takes one stratified batch of
//! samples, and more until its own standard error is below 10⁻³ where the
//! stack keeps nearly all light ([`needs_refined_single`]); E_single of a Lambertian base is mixed from
//! a black- and a white-base table shared by every colour under the same
//! coat. Tables are a pure function of the stack; the compiling layer
//! (`crate::recipe::TableCache`) keeps finished ones in memory and on disk.

use crate::brdf::fresnel;
use crate::brdf::layer::Base;
use crate::brdf::reference::{trace_path_with, PresetUniforms, WalkTables};
use crate::brdf::smooth_coat::{base_is_lambert_or_black, the_smooth_coat, SmoothCoatChain};
use crate::brdf::stack::{BrdfAt, LayeredBrdf};
use crate::brdf::Rgb;
use glam::DVec3;
use rayon::prelude::*;
use std::borrow::Cow;

pub use crate::brdf::compensation_lobe::{node_cosine, Compensation, TABLE_NODES};

/// The most random walks per node for E_stack (the fixed count of the
/// first version, whose standard error is ≲ 0.003 for the library).
const MAX_WALKS_PER_NODE: usize = 8192;
/// Walks are traced in stratified batches of this many squared (64) until
/// the estimated standard error of the node is below
/// [`TARGET_STANDARD_ERROR`] (or the maximum).
const WALK_BATCH_SIDE: usize = 8;
/// The fewest walks per node, enough for a trustworthy variance estimate.
const MIN_WALKS_PER_NODE: usize = 1024;
/// Standard error at which a node stops tracing walks: the first version's
/// actual noise for the library's rough coats (~10⁻³ with 8192 independent
/// walks, documented as ≲ 3·10⁻³), so stopping early keeps the tables as
/// accurate as before.
const TARGET_STANDARD_ERROR: f64 = 1e-3;
/// Stratified samples per batch of E_single: a 64 × 64 grid. One batch
/// leaves a standard error of up to ~6·10⁻³ for the library's rough coats
/// at grazing angles and ~10⁻² for stacks of many rough layers: since the
/// compensation returns E_stack − E_single, an E_single estimated low by
/// that much makes a lossless stack reflect more than it receives.
pub(crate) const SINGLE_SAMPLES_SIDE: usize = 64;
/// The most batches of E_single per node (65 536 samples): a quarter of one
/// batch's error where the target is out of reach.
const MAX_SINGLE_BATCHES: usize = 16;
/// E_stack above which a node's E_single is taken to its target error
/// ([`needs_refined_single`]): three times one batch's worst standard error.
const NEARLY_LOSSLESS: f64 = 0.95;

/// The direction at cosine `mu` in the x–z plane.
fn direction_at_cosine(mu: f64) -> DVec3 {
    DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu)
}

/// Directional albedo ∫ f(ωᵢ, ωₒ) cosθᵢ dωᵢ of the single-crossing model at
/// outgoing cosine `mu`, by stratified importance sampling in batches of
/// `SINGLE_SAMPLES_SIDE`² samples until the standard error of every
/// channel is below `TARGET_STANDARD_ERROR` (10⁻³), as E_stack's walks, or
/// after `MAX_SINGLE_BATCHES`. The first batch is the same whatever
/// follows (a table's one-batch value, when the material's own). A batch
/// with a low mean also tends to have a low estimated error, so stopping
/// early leans low, by up to about the target.
pub fn single_crossing_albedo(brdf: &LayeredBrdf, mu: f64, seed: u64) -> Rgb {
    let bare = without_compensation(brdf);
    let at = bare.at(direction_at_cosine(mu));
    let (mut sum, mut variance_sum) = (Rgb::ZERO, Rgb::ZERO);
    for batch in 0..MAX_SINGLE_BATCHES {
        let (mean, variance) = single_crossing_batch(&at, mu, seed, batch, SINGLE_SAMPLES_SIDE);
        sum += mean;
        variance_sum += variance;
        // The batches are independent: the variance of their average is
        // the sum of theirs over the count squared.
        let count = (batch + 1) as f64;
        if (variance_sum / (count * count)).max_element().sqrt() < TARGET_STANDARD_ERROR {
            return sum / count;
        }
    }
    sum / MAX_SINGLE_BATCHES as f64
}

/// [`single_crossing_albedo`]'s first batch alone, with `side`² samples (a
/// `side` × `side` jittered grid over the two uniforms that pick the
/// direction), so tests can compare the table's count with a finer one.
pub fn single_crossing_albedo_sampled(brdf: &LayeredBrdf, mu: f64, seed: u64, side: usize) -> Rgb {
    let bare = without_compensation(brdf);
    single_crossing_batch(&bare.at(direction_at_cosine(mu)), mu, seed, 0, side).0
}

/// The single crossing alone: `brdf` without its compensation lobe (its
/// sampler and fused eval and pdf, the closed form for a coat over
/// Lambert; equal to `sample_single_crossing`), copied only when it has one.
fn without_compensation(brdf: &LayeredBrdf) -> Cow<'_, LayeredBrdf> {
    if brdf.compensation.is_some() {
        let mut bare = brdf.clone();
        bare.compensation = None;
        Cow::Owned(bare)
    } else {
        Cow::Borrowed(brdf)
    }
}

/// Batch number `batch` of E_single at cosine `mu` from the single
/// crossing prepared for it, `at` (`side`² stratified samples): its mean and the estimated variance of that mean. The
/// variance is estimated from samples taken in pairs of neighbours:
/// E[(w − w′)²] = σ² + σ′² + (m − m′)², so Σ(w − w′)²/N² over the N/2
/// pairs bounds the stratified mean's variance Σσ²/N² from above by only
/// the change of the mean between neighbours (a smooth integrand's gain
/// from stratification is kept; independent samples' √(Var/N) would
/// overstate a smooth coat's error some fifteenfold). Two pairings, the
/// smaller taken: neighbouring cells of the direction's grid (whose lobe
/// choices are unrelated: it overstates the error of a mixture of lobes
/// 30-fold, as for a smooth coat over a polished metal), and neighbouring
/// strata of the lobe choice (whose directions are unrelated).
fn single_crossing_batch(
    at: &BrdfAt<'_>,
    mu: f64,
    seed: u64,
    batch: usize,
    side: usize,
) -> (Rgb, Rgb) {
    let n = side.max(1);
    let count = n * n;
    let (mut sum, mut cell_pairs) = (Rgb::ZERO, Rgb::ZERO);
    let mut previous = None;
    let mut by_lobe_stratum = vec![Rgb::ZERO; count];
    // Batch 0 is the stream the tables always used; later batches salt it.
    let stream = mu.to_bits() ^ (batch as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    for_each_jittered_uniform(seed, stream, n, |u, lobe_stratum| {
        let weight = at.sample(u).map_or(Rgb::ZERO, |sample| sample.weight());
        sum += weight;
        by_lobe_stratum[lobe_stratum] = weight;
        // Cells (a, 2c) and (a, 2c + 1) are neighbours in u₂.
        match previous.take() {
            None => previous = Some(weight),
            Some(first) => cell_pairs += (weight - first) * (weight - first),
        }
    });
    let lobe_pairs = by_lobe_stratum
        .chunks_exact(2)
        .fold(Rgb::ZERO, |acc, pair| {
            acc + (pair[0] - pair[1]) * (pair[0] - pair[1])
        });
    let count = count as f64;
    (sum / count, cell_pairs.min(lobe_pairs) / (count * count))
}

/// The uniforms E_single draws from stream `stream` (of `seed`), in order:
/// (u₁, u₂) one point in each cell of an `n` × `n` grid, and u₀ (the
/// sampler's lobe choice) one point in each of n² strata of [0, 1), the
/// strata dealt to the cells in random order (a Latin hypercube over u₀):
/// the choice between lobes whose weights differ several-fold is then as
/// stratified as the direction. `draw` also takes u₀'s stratum.
fn for_each_jittered_uniform(
    seed: u64,
    stream: u64,
    n: usize,
    mut draw: impl FnMut([f64; 3], usize),
) {
    let mut rng = crate::sampling::Rng::new(seed, stream);
    let count = n * n;
    let mut strata: Vec<usize> = (0..count).collect();
    shuffle(&mut strata, &mut rng);
    for a in 0..n {
        for b in 0..n {
            let stratum = strata[a * n + b];
            draw(
                [
                    (stratum as f64 + rng.next_f64()) / count as f64,
                    (a as f64 + rng.next_f64()) / n as f64,
                    (b as f64 + rng.next_f64()) / n as f64,
                ],
                stratum,
            );
        }
    }
}

/// Shuffles `items` in place (Fisher–Yates) with numbers from `rng`.
fn shuffle(items: &mut [usize], rng: &mut crate::sampling::Rng) {
    for i in (1..items.len()).rev() {
        let j = ((rng.next_f64() * (i + 1) as f64) as usize).min(i);
        items.swap(i, j);
    }
}

/// E_stack(μ) by random walks in batches of s² = 64, stopping once the
/// standard error of every channel is below `TARGET_STANDARD_ERROR` (10⁻³)
/// or after `MAX_WALKS_PER_NODE` (8192) walks, at least
/// `MIN_WALKS_PER_NODE` (1024).
///
/// In each batch the walks' first two uniforms (the top interface's
/// micro-facet normal, or a bare base's sample) lie on a jittered s × s grid
/// and the next two (the first base bounce below a coat) on a second grid in
/// random order, so every batch is stratified. The standard error is
/// estimated as if the walks were independent, √(Var/n) over single paths:
/// stratification only lowers the true error, so the estimate errs on the
/// safe side (the variance of batch means would be too noisy a guide: with
/// rare bright paths it stops early on a lucky, low value). The batches are
/// traced one after another from one generator: the result depends only on
/// `seed`, never on the number of threads.
pub fn adaptive_walk_albedo(brdf: &LayeredBrdf, tables: &WalkTables, mu: f64, seed: u64) -> Rgb {
    let wi = direction_at_cosine(mu);
    let mut rng = crate::sampling::Rng::new(seed, 0x5eed_a1be);
    let side = WALK_BATCH_SIDE;
    let batch = side * side;
    let (mut sum, mut sum_sq) = (Rgb::ZERO, Rgb::ZERO);
    let mut paths = 0usize;
    let mut order: Vec<usize> = (0..batch).collect();
    while paths < MAX_WALKS_PER_NODE {
        // A random pairing of the cells of the two grids.
        shuffle(&mut order, &mut rng);
        for (cell, other) in order.iter().enumerate() {
            let jitter = |c: usize, rng: &mut crate::sampling::Rng| {
                [
                    ((c / side) as f64 + rng.next_f64()) / side as f64,
                    ((c % side) as f64 + rng.next_f64()) / side as f64,
                ]
            };
            let (a, b) = (jitter(cell, &mut rng), jitter(*other, &mut rng));
            let mut uniforms = PresetUniforms {
                preset: [a[0], a[1], b[0], b[1]],
                used: 0,
                rng: &mut rng,
            };
            let mut path_total = Rgb::ZERO;
            trace_path_with(brdf, tables, wi, &mut uniforms, |_, p| path_total += p);
            sum += path_total;
            sum_sq += path_total * path_total;
        }
        paths += batch;
        if paths >= MIN_WALKS_PER_NODE {
            let n = paths as f64;
            let mean = sum / n;
            // √(Var/n) with the unbiased variance of single paths.
            let variance = ((sum_sq - mean * mean * n) / (n - 1.0)).max(Rgb::ZERO);
            if (variance / n).max_element().sqrt() < TARGET_STANDARD_ERROR {
                break;
            }
        }
    }
    sum / paths as f64
}

/// The closed form of E_stack for one smooth dielectric coat (roughness 0,
/// i.e. the clamp `MIN_ROUGHNESS_DEG`) over a
/// Lambertian (σ = 0) or black base, the only stack where the random
/// walk's series sums exactly:
///
/// E_stack(μ) = F(μ) + (1 − F(μ))·T(μ′)·ρ·a_esc / (1 − ρ·a_ref),
///
/// with μ′ the refracted cosine (Snell, eq. 3.2), T(ν) = exp(−αd/ν) the
/// layer's Beer transmittance (eq. 3.4), and for the cosine-distributed
/// light leaving the Lambertian base a_esc = 2∫T(ν)(1 − F_in(ν))ν dν the
/// part that escapes and a_ref = 2∫T(ν)²F_in(ν)ν dν the part reflected back
/// to the base (F_in: Fresnel from inside, 1 beyond the critical angle).
/// Without absorption a_esc = 1 − F_dr and a_ref = F_dr: the ρ/(1 − ρ·F_dr)
/// series of the module docs. A Lambertian base forgets the direction of
/// the light, so each bounce meets the same a_esc and a_ref.
#[derive(Clone, Debug)]
pub struct SmoothCoatOverLambert {
    /// Relative index η of the coat.
    eta: f64,
    /// Lambertian albedo ρ of the base (0 for a black base).
    colour: Rgb,
    /// The coat, for its Beer transmittance.
    coat: crate::brdf::layer::Interface,
    /// ρ·a_esc / (1 − ρ·a_ref) per channel.
    bounce_series: Rgb,
}

/// Midpoint steps of the cosine integrals of [`SmoothCoatOverLambert`]
/// (error ~10⁻⁷, the integrand's only kink is at the critical angle).
const CLOSED_FORM_STEPS: usize = 8192;

impl SmoothCoatOverLambert {
    /// The closed form for `brdf` when it is one smooth coat over a
    /// Lambertian or black base; None for every other stack.
    pub fn of(brdf: &LayeredBrdf) -> Option<Self> {
        let coat = the_smooth_coat(brdf)?;
        if !base_is_lambert_or_black(&brdf.base) {
            return None;
        }
        let colour = base_colour(brdf);
        let (mut escape, mut reflect) = (Rgb::ZERO, Rgb::ZERO);
        let step = 1.0 / CLOSED_FORM_STEPS as f64;
        for i in 0..CLOSED_FORM_STEPS {
            let nu = (i as f64 + 0.5) * step;
            let f_inside = fresnel::dielectric(nu, 1.0 / coat.eta);
            let t = coat.crossing_transmittance(nu);
            escape += t * ((1.0 - f_inside) * 2.0 * nu * step);
            reflect += t * t * (f_inside * 2.0 * nu * step);
        }
        Some(SmoothCoatOverLambert {
            eta: coat.eta,
            colour,
            coat: coat.clone(),
            bounce_series: colour * escape / (Rgb::ONE - colour * reflect),
        })
    }

    /// E_stack(μ) for light arriving at cosine `mu`.
    pub fn albedo(&self, mu: f64) -> Rgb {
        // Snell once for F(μ) and the refracted cosine μ′.
        let snell = fresnel::Snell::at(mu, self.eta);
        let f = fresnel::dielectric_from_snell(mu, snell, self.eta);
        let Some(mu_inside) = snell.cos_t.filter(|_| self.colour != Rgb::ZERO) else {
            return Rgb::splat(f);
        };
        Rgb::splat(f) + self.coat.crossing_transmittance(mu_inside) * self.bounce_series * (1.0 - f)
    }
}

/// The colour of a diffuse base (None for other bases).
fn base_colour(brdf: &LayeredBrdf) -> Rgb {
    match brdf.base {
        Base::Diffuse { colour, .. } => colour,
        _ => Rgb::ZERO,
    }
}

/// (1 − ρ)·E₀ + ρ·E₁ per channel: E_single for base colour ρ from the
/// albedos with a black (E₀) and a white (E₁) base.
fn colour_mix(black: Rgb, white: Rgb, colour: Rgb) -> Rgb {
    black * (Rgb::ONE - colour) + white * colour
}

/// The black- and the white-base twins of a Lambertian material (σ = 0),
/// None for other bases (Oren-Nayar included).
///
/// The single-crossing BRDF is linear in the base colour ρ: the base enters
/// f = f₁ + T₁₂·a·t·f₂/η² once, through f₂ = ρ/π (Lambert), so
/// E_single(ρ) = (1 − ρ)·E_single(0) +
/// ρ·E_single(1) exactly, per channel. Materials that differ only in their
/// base colour (the lavender lepidolite's 14 tiles under one coat) then
/// share one pair of tables, computed once per process (see
/// [`Compensation::compute_many_reusing`]). Each of the pair has
/// the noise of the direct estimate, and so has their convex combination.
fn black_and_white_twins(brdf: &LayeredBrdf) -> Option<(LayeredBrdf, LayeredBrdf)> {
    let Base::Diffuse {
        oren_nayar_sigma_rad,
        ..
    } = brdf.base
    else {
        return None;
    };
    // Oren-Nayar is not linear in ρ (its interreflection term goes as ρ²).
    if oren_nayar_sigma_rad > 0.0 {
        return None;
    }
    let with_colour = |colour: Rgb| {
        LayeredBrdf::new(
            &brdf.name,
            brdf.model,
            brdf.interfaces.clone(),
            Base::Diffuse {
                colour,
                oren_nayar_sigma_rad,
            },
        )
    };
    Some((with_colour(Rgb::ZERO), with_colour(Rgb::ONE)))
}

/// Whether `brdf` certainly needs no table, so that none is computed: a
/// bare Lambert surface (no layers, σ ≤ 0, every channel of its colour in
/// [0, 1], which recipes enforce). Its single-crossing model is already the
/// whole stack: both albedos are ρ at every angle, every sample and every
/// walk weighing exactly ρ to rounding (f·cosθ/pdf with the cosine density
/// pdf = cosθ/π), so the deficit is ~10⁻¹⁶, far below the 3·10⁻³ below
/// which [`Compensation::from_albedos`] drops a table (tested on a grid of
/// colours against the computed tables).
pub fn needs_no_table(brdf: &LayeredBrdf) -> bool {
    match brdf.base {
        Base::Diffuse {
            colour,
            oren_nayar_sigma_rad,
        } => {
            brdf.interfaces.is_empty()
                && oren_nayar_sigma_rad <= 0.0
                && colour.to_array().iter().all(|c| (0.0..=1.0).contains(c))
        }
        _ => false,
    }
}

/// How [`Compensation::compute`] finds E_stack.
enum StackMethod {
    /// Exactly, for one smooth coat over a Lambertian or black base.
    ClosedForm(SmoothCoatOverLambert),
    /// By the solved chain of light trapped under one smooth coat.
    Chain(SmoothCoatChain),
    /// By random walks through the stack.
    Walk(WalkTables),
}

impl StackMethod {
    /// The closed form where there is one, else the chain under a smooth
    /// coat, else the walk's tables (`seed`: the chain's base samples).
    fn of(brdf: &LayeredBrdf, seed: u64) -> Self {
        if let Some(c) = SmoothCoatOverLambert::of(brdf) {
            return StackMethod::ClosedForm(c);
        }
        match SmoothCoatChain::of(brdf, seed) {
            Some(chain) => StackMethod::Chain(chain),
            None => StackMethod::Walk(WalkTables::new(brdf)),
        }
    }

    /// E_stack at node `k` of `brdf` (clamped to 1).
    fn stack_albedo(&self, brdf: &LayeredBrdf, k: usize, seed: u64) -> Rgb {
        let mu = node_cosine(k);
        let stack = match self {
            StackMethod::ClosedForm(c) => c.albedo(mu),
            StackMethod::Chain(chain) => chain.albedo(mu, k as u64),
            StackMethod::Walk(tables) => adaptive_walk_albedo(brdf, tables, mu, seed ^ k as u64),
        };
        stack.min(Rgb::ONE)
    }
}

/// Where a table's E_single comes from.
enum SingleSource {
    /// Mixed from the black/white pair of index `pair` (its twins or its
    /// tables in [`TablePlan::pairs`]).
    Pair(usize),
    /// Estimated for the material itself.
    Direct,
}

/// One material of a [`Compensation::compute_many`] batch.
struct MaterialPlan<'a> {
    brdf: &'a LayeredBrdf,
    seed: u64,
    single: SingleSource,
    method: StackMethod,
}

/// A black/white pair of E_single tables a batch needs: already computed
/// in this process, or to be computed from the twins.
enum PairPlan {
    Known(AlbedoPair),
    /// The black and the white twin, and the seed.
    ToCompute(Box<(LayeredBrdf, LayeredBrdf)>, u64),
}

/// E_single of a black and of a white base at every node.
pub(crate) type AlbedoPair = (Vec<Rgb>, Vec<Rgb>);

/// Looks up a coat's black- and white-base E_single pair by the
/// [`material_key`] of its white twin (see
/// [`Compensation::compute_many_reusing`]).
pub(crate) type KnownPair<'a> = dyn Fn(&str) -> Option<AlbedoPair> + 'a;

/// What [`Compensation::compute_many_reusing`] computed.
pub(crate) struct ComputedTables {
    /// The table of each request, in order (None: no compensation needed).
    pub tables: Vec<Option<Compensation>>,
    /// The black- and white-base E_single pairs computed for this batch, by
    /// the [`material_key`] of the white twin.
    pub new_pairs: Vec<(String, AlbedoPair)>,
}

/// One table node to compute: the unit of the batch's parallel loop.
#[derive(Clone, Copy)]
enum NodeJob {
    /// E_stack of material `material` at node `k`.
    Stack { material: usize, k: usize },
    /// E_single of material `material` itself at node `k`.
    Single { material: usize, k: usize },
    /// E_single of the black (`white` false) or white twin of pair `pair`.
    PairSingle { pair: usize, white: bool, k: usize },
}

/// Everything a batch computes, planned before its one parallel loop.
struct TablePlan<'a> {
    /// Per request, its material's plan (None: no table needed).
    materials: Vec<Option<MaterialPlan<'a>>>,
    pairs: Vec<PairPlan>,
}

impl<'a> TablePlan<'a> {
    /// Plans the tables of `requests`: a stack method per material (walk
    /// tables built in parallel), and the black/white pairs, each once,
    /// that their Lambertian bases share.
    fn new(requests: &[(&'a LayeredBrdf, u64)], known_pair: &KnownPair<'_>) -> Self {
        let methods: Vec<Option<StackMethod>> = requests
            .par_iter()
            .map(|&(brdf, seed)| (!needs_no_table(brdf)).then(|| StackMethod::of(brdf, seed)))
            .collect();
        let mut pairs = Vec::new();
        let mut pair_keys: Vec<String> = Vec::new();
        let materials = requests
            .iter()
            .zip(methods)
            .map(|(&(brdf, seed), method)| {
                let method = method?;
                let single = match black_and_white_twins(brdf) {
                    None => SingleSource::Direct,
                    Some((black, white)) => {
                        let key = material_key(&white, seed);
                        let index = pair_keys.iter().position(|k| *k == key).unwrap_or_else(|| {
                            pairs.push(match known_pair(&key) {
                                Some(known) => PairPlan::Known(known),
                                None => PairPlan::ToCompute(Box::new((black, white)), seed),
                            });
                            pair_keys.push(key);
                            pairs.len() - 1
                        });
                        SingleSource::Pair(index)
                    }
                };
                Some(MaterialPlan {
                    brdf,
                    seed,
                    single,
                    method,
                })
            })
            .collect();
        TablePlan { materials, pairs }
    }

    /// Every node of the first parallel loop: the walks first (the longest
    /// jobs), then direct and paired E_single from one batch (nodes that
    /// need more follow in a second loop, once E_stack is known).
    fn jobs(&self) -> Vec<NodeJob> {
        let mut jobs = Vec::new();
        for (material, plan) in self.materials.iter().enumerate() {
            if plan.is_some() {
                jobs.extend((0..TABLE_NODES).map(|k| NodeJob::Stack { material, k }));
            }
        }
        for (material, plan) in self.materials.iter().enumerate() {
            if let Some(MaterialPlan {
                single: SingleSource::Direct,
                ..
            }) = plan
            {
                jobs.extend((0..TABLE_NODES).map(|k| NodeJob::Single { material, k }));
            }
        }
        for (pair, plan) in self.pairs.iter().enumerate() {
            if let PairPlan::ToCompute(..) = plan {
                for white in [false, true] {
                    jobs.extend((0..TABLE_NODES).map(|k| NodeJob::PairSingle { pair, white, k }));
                }
            }
        }
        jobs
    }

    /// The value of one node (the same call, with the same seed, as when
    /// tables were computed one after another).
    fn run(&self, job: NodeJob) -> Rgb {
        let material = |m: usize| self.materials[m].as_ref().expect("planned jobs only");
        match job {
            NodeJob::Stack { material: m, k } => {
                let plan = material(m);
                plan.method.stack_albedo(plan.brdf, k, plan.seed)
            }
            NodeJob::Single { material: m, k } => {
                let plan = material(m);
                single_albedo_at_node(plan.brdf, k, plan.seed)
            }
            NodeJob::PairSingle { pair, white, k } => match &self.pairs[pair] {
                PairPlan::ToCompute(twins, seed) => {
                    let twin = if white { &twins.1 } else { &twins.0 };
                    single_albedo_at_node(twin, k, *seed)
                }
                PairPlan::Known(_) => unreachable!("known pairs have no jobs"),
            },
        }
    }
}

/// The exact parameters of `brdf` and `seed` as a key: equal keys give
/// bit-identical tables (the name is left out: it does not change them).
/// Every `f64` is written in Rust's shortest round-trip form, so two
/// numbers print alike only when their bits are equal (−0.0 included).
pub fn material_key(brdf: &LayeredBrdf, seed: u64) -> String {
    format!(
        "seed {seed}; model {:?}; interfaces {:?}; base {:?}",
        brdf.model, brdf.interfaces, brdf.base
    )
}

/// E_single of `brdf` at table node `k` from one batch of samples, with
/// the stream every table of `seed` uses for it (salted apart from the
/// E_stack walks' streams).
fn single_albedo_at_node(brdf: &LayeredBrdf, k: usize, seed: u64) -> Rgb {
    single_crossing_albedo_sampled(brdf, node_cosine(k), seed ^ 0xa1b2, SINGLE_SAMPLES_SIDE)
}

/// E_single of `brdf` at table node `k` to its target error
/// ([`single_crossing_albedo`], whose first batch is
/// `single_albedo_at_node`'s), for a node that [`needs_refined_single`].
pub fn refined_single_albedo_at_node(brdf: &LayeredBrdf, k: usize, seed: u64) -> Rgb {
    single_crossing_albedo(brdf, node_cosine(k), seed ^ 0xa1b2)
}

/// Whether a node whose stack reflects `stack_albedo` takes E_single to
/// its target error rather than from one batch: where the stack keeps
/// nearly all light, an E_single estimated low by one batch's error (up
/// to ~0.02 for stacks of many rough layers) would make the compensated
/// model reflect more than it receives. Elsewhere that error moves the
/// albedo by as much, which the walk's own noise matches, at a fraction
/// of the compile time.
pub fn needs_refined_single(stack_albedo: Rgb) -> bool {
    stack_albedo.max_element() > NEARLY_LOSSLESS
}

impl LayeredBrdf {
    /// The same material with its multiple-scattering compensation table
    /// computed (see [`crate::brdf::compensation`]): a pure function of the
    /// material's parameters and `seed`. To compute each distinct table
    /// once, go through `crate::recipe::TableCache`.
    pub fn with_compensation(mut self, seed: u64) -> Self {
        self.compensation = Compensation::compute(&self, seed);
        self
    }
}

impl Compensation {
    /// Tabulate the deficit of `brdf`; None when it is below 3·10⁻³ at every
    /// node (the noise level of the tables).
    pub fn compute(brdf: &LayeredBrdf, seed: u64) -> Option<Self> {
        Self::compute_many(&[(brdf, seed)]).pop().flatten()
    }

    /// [`Compensation::compute`] of every (material, seed) of `requests`,
    /// in order, with all their nodes (E_stack, E_single, and the black and
    /// white E_single of each coat over a Lambertian base, once per coat)
    /// computed in one parallel loop: a gem's or a scene's materials keep
    /// every thread busy to the end instead of each table waiting on its
    /// slowest node, and a shared black/white pair does not hold the
    /// others up; then the nodes whose stack keeps nearly all light take
    /// the material's own E_single to its target error in a second
    /// ([`needs_refined_single`]). Each node is the same deterministic call either way, so the
    /// tables are bit for bit those of one-by-one computation, whatever the
    /// number of threads. Bare Lambert surfaces ([`needs_no_table`]) get
    /// None without any work.
    pub fn compute_many(requests: &[(&LayeredBrdf, u64)]) -> Vec<Option<Self>> {
        Self::compute_many_reusing(requests, &|_| None).tables
    }

    /// [`Compensation::compute_many`], taking the black- and white-base
    /// E_single pair of a coat from `known_pair` (by the [`material_key`]
    /// of the white twin) where a caller kept it from an earlier batch, and
    /// returning the pairs it computed so that the caller can keep them.
    /// The same tables, bit for bit, as without them.
    pub(crate) fn compute_many_reusing(
        requests: &[(&LayeredBrdf, u64)],
        known_pair: &KnownPair<'_>,
    ) -> ComputedTables {
        let plan = TablePlan::new(requests, known_pair);
        let jobs = plan.jobs();
        let values: Vec<Rgb> = jobs.par_iter().map(|job| plan.run(*job)).collect();
        let mut stack = vec![vec![Rgb::ZERO; TABLE_NODES]; plan.materials.len()];
        let mut single = stack.clone();
        let mut computed_pairs: Vec<AlbedoPair> =
            vec![(vec![Rgb::ZERO; TABLE_NODES], vec![Rgb::ZERO; TABLE_NODES]); plan.pairs.len()];
        for (job, value) in jobs.iter().zip(values) {
            match *job {
                NodeJob::Stack { material, k } => stack[material][k] = value,
                NodeJob::Single { material, k } => single[material][k] = value,
                NodeJob::PairSingle { pair, white, k } => {
                    let (black_column, white_column) = &mut computed_pairs[pair];
                    if white {
                        white_column[k] = value;
                    } else {
                        black_column[k] = value;
                    }
                }
            }
        }
        let mut new_pairs = Vec::new();
        let pairs: Vec<AlbedoPair> = plan
            .pairs
            .iter()
            .zip(computed_pairs)
            .map(|(pair, computed)| match pair {
                PairPlan::Known(known) => known.clone(),
                PairPlan::ToCompute(twins, seed) => {
                    new_pairs.push((material_key(&twins.1, *seed), computed.clone()));
                    computed
                }
            })
            .collect();
        // E_single from one batch, or mixed from its pair.
        for (material, single) in plan.materials.iter().zip(&mut single) {
            if let Some(MaterialPlan {
                single: SingleSource::Pair(p),
                brdf,
                ..
            }) = material
            {
                let (black, white) = &pairs[*p];
                let colour = base_colour(brdf);
                *single = (0..TABLE_NODES)
                    .map(|k| colour_mix(black[k], white[k], colour))
                    .collect();
            }
        }
        // Where the stack keeps nearly all light, E_single again, in
        // batches to its target (`single_crossing_albedo`).
        let refined: Vec<(usize, usize, &MaterialPlan)> = plan
            .materials
            .iter()
            .enumerate()
            .filter_map(|(m, material)| Some((m, material.as_ref()?)))
            .flat_map(|(m, material)| (0..TABLE_NODES).map(move |k| (m, k, material)))
            .filter(|&(m, k, _)| needs_refined_single(stack[m][k]))
            .collect();
        let values: Vec<Rgb> = refined
            .par_iter()
            .map(|&(_, k, material)| refined_single_albedo_at_node(material.brdf, k, material.seed))
            .collect();
        for (&(m, k, _), value) in refined.iter().zip(values) {
            single[m][k] = value;
        }
        let tables = plan
            .materials
            .iter()
            .zip(stack.into_iter().zip(single))
            .map(|(material, (stack, single))| {
                material.as_ref()?;
                Self::from_albedos(single, stack)
            })
            .collect();
        ComputedTables { tables, new_pairs }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn e_single_draws_every_number_stratified() {
        // One u₀ in each of the n² strata, one (u₁, u₂) in each grid cell.
        let n = 16;
        let (mut lobe, mut cells) = (vec![0; n * n], vec![0; n * n]);
        for_each_jittered_uniform(5, 0.3f64.to_bits(), n, |[u0, u1, u2], stratum| {
            assert_eq!((u0 * (n * n) as f64) as usize, stratum);
            lobe[(u0 * (n * n) as f64) as usize] += 1;
            cells[(u1 * n as f64) as usize * n + (u2 * n as f64) as usize] += 1;
        });
        assert!(lobe.iter().all(|&k| k == 1), "{lobe:?}");
        assert!(cells.iter().all(|&k| k == 1), "{cells:?}");
    }

    #[test]
    fn the_single_crossing_albedo_averages_the_general_samplers_weights() {
        // The tabulated E_single draws through `LayeredBrdf::at` (fused
        // eval and pdf, a coat's closed form); the same grid through the
        // general recursion gives the same average to rounding, for every
        // library material, its compensation lobe left out in both.
        let side = 12;
        for name in crate::recipe::library::builtin_material_names() {
            let mut brdf = crate::recipe::load_material(name).unwrap();
            brdf.compensation = None;
            for mu in [0.05, 0.5, 0.97] {
                let wo = direction_at_cosine(mu);
                let mut sum = Rgb::ZERO;
                for_each_jittered_uniform(3, mu.to_bits(), side, |u, _| {
                    if let Some((_, weight)) = brdf.sample_single_crossing(wo, u) {
                        sum += weight;
                    }
                });
                let expected = sum / (side * side) as f64;
                let albedo = single_crossing_albedo_sampled(&brdf, mu, 3, side);
                assert!(
                    (albedo - expected).abs().max_element() <= 1e-12 * expected.max_element(),
                    "{name} at μ {mu}: {albedo} against {expected}"
                );
                assert!(
                    expected.max_element() > 0.0,
                    "{name} at μ {mu}: nothing reflected"
                );
            }
        }
    }
}
