//! The Monte Carlo reference: a random walk of light through the same stack
//! of rough dielectric interfaces, absorbing layers and base, with as many
//! bounces between the layers as it takes (the method of pbrt-v4's
//! `LayeredBxDF`, generalised to any number of layers).
//!
//! Light enters from direction ωᵢ; at each interface a micro-facet normal is
//! drawn among those visible from ω (density G1(ω, h)|ω·h|D(h)/cosθ, Heitz
//! & d'Eon 2014), the path reflects about it with the Fresnel probability
//! or refracts through it, and the new direction is kept with probability
//! G/G1(ω, h), the fraction of power the visible micro-facets pass on
//! (Walter et al. 2007, eq. 41, over that density), else drawn again.
//! Inside a layer the power decays by Beer's law exp(−αd/|cosθ|) (eq. 3.4);
//! at the base it scatters by the base BRDF. Each interface uses its *own*
//! roughness: the broadening that the analytic model approximates by
//! accumulating roughness (section 4.2.3) happens here by refraction itself.
//!
//! Light that single-scattering micro-facet theory loses to shadowing is, on
//! a real microsurface, scattered again and leaves (Heitz et al. 2016). In the
//! manner of Kulla & Conty we keep it: redrawing what shadowing refuses
//! draws from the single-scattering lobe divided by its own albedo E(μ), so
//! the lost light leaves with the lobe's shape and every interaction weighs
//! exactly 1 (a conductor base: its Fresnel reflectance). A lossless stack
//! over a white base therefore returns every path with the power it had
//! below the top (where reflection and transmission are split in
//! expectation), however many layers and grazing angles it meets inside:
//! no weights multiply along a path (a path that runs out of draws or
//! events is lost, a few in 10⁴ for 16 rough layers). (Normals drawn from D(h)·cosθh weigh G·|ω·h|/(cosθ·cosθh),
//! unbounded at grazing angles; divided by a tabulated E, as this walk
//! once did, a stack of many layers had heavy-tailed noise: 0.64 to 2.50
//! for sixteen lossless layers over white at neighbouring angles.)

use crate::brdf::fresnel;
use crate::brdf::layer::Base;
use crate::brdf::microfacet::{reflect, refract, Microfacet};
use crate::brdf::stack::LayeredBrdf;
use crate::brdf::Rgb;
use crate::sampling::{cosine_hemisphere, Rng};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Below this power (largest channel) a path plays Russian roulette: it
/// goes on with probability q = power / this, its power divided by q, so
/// its expected contribution is unchanged (unbiased), while light trapped
/// between a smooth coat and a bright metal (hundreds of bounces) stops
/// after a few.
const ROULETTE_BELOW: f64 = 0.01;
/// Paths stop after this many scattering events (never reached in practice
/// for the library: with IOR ≤ 2 a bounce keeps at most ~0.9 of the power).
const MAX_EVENTS: usize = 512;

/// Draws of a micro-facet normal for one interaction before the path is
/// given up: a draw is kept with probability G/G1, on average the
/// interface's single-scattering albedo E, so (1 − E)⁶⁴ of the power is
/// lost, none that matters unless E < 0.05 (the roughest interfaces at
/// the most grazing angles).
const MAX_DRAWS: usize = 64;

/// Cosine nodes of the albedo tables.
const TABLE_NODES: usize = 32;
/// Micro-facet normals per node when tabulating: a 32 × 32 jittered grid.
const TABLE_SIDE: usize = 32;

/// What the walk reads of a stack besides its layers: the top interface's
/// single-scattering albedo E(μ) for light from above, where both outcomes
/// are followed in expectation, and the conductor base's Fresnel
/// reflectance; and, for `scatter_base_stratified`, the conductor base's
/// single-scattering albedo.
#[derive(Clone, Debug)]
pub struct WalkTables {
    /// The top interface's E(μ) for light from above, at
    /// [`TABLE_NODES`] cosines (empty without layers).
    top_from_above: Vec<f64>,
    /// The conductor base's E(μ) (geometry only), empty for other bases.
    base: Vec<f64>,
    /// The conductor base's Fresnel reflectance (eq. 3.3) at cosines
    /// j/[`FRESNEL_TABLE_INTERVALS`], j = 0…N (linear interpolation is
    /// within ~10⁻⁶ of the exact value, which costs a complex square root
    /// and divisions per channel at every bounce); empty for other bases.
    base_fresnel: Vec<Rgb>,
}

/// Intervals of [`WalkTables`]'s conductor Fresnel table.
const FRESNEL_TABLE_INTERVALS: usize = 2048;

/// The conductor Fresnel table at cosine `cos` (in [0, 1]).
fn lookup_fresnel(table: &[Rgb], cos: f64) -> Rgb {
    let x = cos.clamp(0.0, 1.0) * FRESNEL_TABLE_INTERVALS as f64;
    let j = (x as usize).min(FRESNEL_TABLE_INTERVALS - 1);
    let t = x - j as f64;
    table[j] * (1.0 - t) + table[j + 1] * t
}

impl WalkTables {
    /// The tables of `brdf`'s walk.
    pub fn new(brdf: &LayeredBrdf) -> Self {
        let top_from_above = brdf.interfaces.first().map_or(Vec::new(), |top| {
            tabulate(|w, u| {
                split_dielectric(&top.own_lobe, w, top.eta, u).map_or(0.0, |split| split.albedo())
            })
        });
        WalkTables {
            top_from_above,
            ..Self::of_base(&brdf.base)
        }
    }

    /// The tables of `base` (what [`scatter_base`] and
    /// [`scatter_base_stratified`] read).
    pub(crate) fn of_base(base: &Base) -> Self {
        let base_albedo = match base {
            Base::Conductor { own_lobe, .. } => tabulate(|w, u| {
                projected_reflection(own_lobe, w, u).map_or(0.0, |(_, _, weight)| weight)
            }),
            _ => Vec::new(),
        };
        let base_fresnel = match base {
            Base::Conductor {
                n_relative,
                k_relative,
                ..
            } => (0..=FRESNEL_TABLE_INTERVALS)
                .map(|j| {
                    let cos = j as f64 / FRESNEL_TABLE_INTERVALS as f64;
                    fresnel::conductor(cos, *n_relative, *k_relative)
                })
                .collect(),
            _ => Vec::new(),
        };
        WalkTables {
            top_from_above: Vec::new(),
            base: base_albedo,
            base_fresnel,
        }
    }
}

/// E at cosine `mu` from a table of [`TABLE_NODES`] (linear between
/// the nodes, at least 10⁻³); 1 from an empty table (no such interface).
fn lookup(table: &[f64], mu: f64) -> f64 {
    if table.is_empty() {
        return 1.0;
    }
    let n = table.len();
    let x = (mu.clamp(0.0, 1.0) * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
    let k = (x.floor() as usize).min(n - 2);
    let t = x - k as f64;
    (table[k] * (1.0 - t) + table[k + 1] * t).max(1e-3)
}

/// E(μ) at [`TABLE_NODES`] cosines, each the mean of `weight_at` over
/// a jittered √N × √N grid of the two uniforms that pick the micro-facet
/// normal (stratified: far less noise than N independent draws). The nodes
/// are independent (one generator each), so running them in parallel gives
/// the same table on any number of threads.
fn tabulate(weight_at: impl Fn(DVec3, [f64; 2]) -> f64 + Sync) -> Vec<f64> {
    (0..TABLE_NODES)
        .into_par_iter()
        .map(|k| {
            let mu = (k as f64 + 0.5) / TABLE_NODES as f64;
            let w = DVec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let mut rng = Rng::new(0x7ab1e, k as u64);
            let side = TABLE_SIDE as f64;
            let mut sum = 0.0;
            for a in 0..TABLE_SIDE {
                for b in 0..TABLE_SIDE {
                    let u = [
                        (a as f64 + rng.next_f64()) / side,
                        (b as f64 + rng.next_f64()) / side,
                    ];
                    sum += weight_at(w, u);
                }
            }
            sum / (TABLE_SIDE * TABLE_SIDE) as f64
        })
        .collect()
}

/// A source of uniform numbers in [0, 1) for the walk: the generator itself,
/// or [`PresetUniforms`] whose first numbers are chosen by the caller.
pub(crate) trait Uniforms {
    /// The next uniform number.
    fn next_f64(&mut self) -> f64;
}

impl Uniforms for Rng {
    fn next_f64(&mut self) -> f64 {
        Rng::next_f64(self)
    }
}

/// Uniforms whose first four are given (e.g. a point of a stratified set,
/// so that the first micro-facet normal and the first base bounce of a
/// batch of walks are stratified), the rest drawn from a generator.
pub(crate) struct PresetUniforms<'a> {
    /// The first four numbers handed out.
    pub preset: [f64; 4],
    /// How many of `preset` have been handed out.
    pub used: usize,
    /// Where the numbers after the preset ones come from.
    pub rng: &'a mut Rng,
}

impl Uniforms for PresetUniforms<'_> {
    fn next_f64(&mut self) -> f64 {
        match self.preset.get(self.used) {
            Some(u) => {
                self.used += 1;
                *u
            }
            None => self.rng.next_f64(),
        }
    }
}

/// Two uniforms from `rng`, in order.
fn uniform_pair(rng: &mut impl Uniforms) -> [f64; 2] {
    let u1 = rng.next_f64();
    [u1, rng.next_f64()]
}

/// Flip a direction between the frame of the upper and lower side.
fn flip(w: DVec3) -> DVec3 {
    DVec3::new(w.x, w.y, -w.z)
}

/// Both outcomes of light from `w_away` (z > 0) at a dielectric
/// interface about one normal visible from it drawn from `u`.
struct DielectricSplit {
    /// The Fresnel reflectance at the normal.
    fresnel: f64,
    /// The reflected direction (z > 0) and its weight G/G1, if it exists.
    reflected: Option<(DVec3, f64)>,
    /// The transmitted direction (z < 0) and its weight G/G1, if it exists.
    transmitted: Option<(DVec3, f64)>,
}

impl DielectricSplit {
    /// The interaction's weight in expectation over the Fresnel choice:
    /// the mean of this over the normals is the single-scattering albedo E.
    fn albedo(&self) -> f64 {
        self.fresnel * self.reflected.map_or(0.0, |r| r.1)
            + (1.0 - self.fresnel) * self.transmitted.map_or(0.0, |t| t.1)
    }
}

/// [`DielectricSplit`] of light from `w_away` at an interface of relative
/// index `eta` (n_other_side / n_this_side); None when the drawn normal
/// faces away.
fn split_dielectric(
    lobe: &Microfacet,
    w_away: DVec3,
    eta: f64,
    u: [f64; 2],
) -> Option<DielectricSplit> {
    if w_away.z <= 0.0 {
        return None;
    }
    let h = lobe.sample_visible_normal(w_away, u);
    let (wh, visible) = (w_away.dot(h), lobe.visible_g1(w_away, h));
    if wh <= 0.0 || visible <= 0.0 {
        return None;
    }
    let r = reflect(w_away, h);
    Some(DielectricSplit {
        fresnel: fresnel::dielectric(wh, eta),
        reflected: (r.z > 0.0).then(|| (r, lobe.g(w_away, r, h) / visible)),
        transmitted: refract(w_away, h, eta)
            .filter(|t| t.z < 0.0)
            .map(|t| (t, lobe.g(w_away, t, h) / visible)),
    })
}

/// One interaction at a dielectric interface for light arriving from
/// `w_away` (pointing away from the interface, z > 0; the frame's +z is
/// the incident side), `eta` = n_other_side / n_this_side: a normal
/// visible from `w_away`, reflection about it with the Fresnel
/// probability (1 under total internal reflection) or else refraction
/// through it, kept with probability G/G1 and otherwise drawn again (see
/// the module notes; weight 1). Returns the new direction (z > 0
/// reflected, z < 0 transmitted) and whether it was reflected; None when
/// no draw is kept within [`MAX_DRAWS`].
fn scatter_dielectric(
    lobe: &Microfacet,
    w_away: DVec3,
    eta: f64,
    rng: &mut impl Uniforms,
) -> Option<(DVec3, bool)> {
    let (w, _, reflected) = keep_what_shadowing_passes(lobe, w_away, rng, |h, rng| {
        let choice = rng.next_f64();
        let wh = w_away.dot(h);
        if wh <= 0.0 {
            return None;
        }
        let reflected = choice < fresnel::dielectric(wh, eta);
        let w = if reflected {
            Some(reflect(w_away, h)).filter(|r| r.z > 0.0)
        } else {
            refract(w_away, h, eta).filter(|t| t.z < 0.0)
        };
        w.map(|w| (w, reflected))
    })?;
    Some((w, reflected))
}

/// A conductor's micro-facet reflection of light from `w_away` (z > 0)
/// about a normal visible from it, kept with probability G/G1 and
/// otherwise drawn again: the direction and the normal (the Fresnel
/// reflectance at it is the weight); None when no draw is kept within
/// [`MAX_DRAWS`].
fn conductor_scatter(
    lobe: &Microfacet,
    w_away: DVec3,
    rng: &mut impl Uniforms,
) -> Option<(DVec3, DVec3)> {
    let (w, h, ()) = keep_what_shadowing_passes(lobe, w_away, rng, |h, _| {
        Some((reflect(w_away, h), ())).filter(|(w, _)| w.z > 0.0)
    })?;
    Some((w, h))
}

/// The rejection both interactions share: a normal h visible from
/// `w_away` (z > 0), a direction `propose`d for it (which may draw numbers
/// of its own, e.g. the Fresnel choice, and carries a tag), kept with
/// probability G/G1(w_away, h) by the next number, else all drawn again, at
/// most [`MAX_DRAWS`] times. Returns the kept direction, its normal and
/// the tag.
fn keep_what_shadowing_passes<U: Uniforms, T>(
    lobe: &Microfacet,
    w_away: DVec3,
    rng: &mut U,
    mut propose: impl FnMut(DVec3, &mut U) -> Option<(DVec3, T)>,
) -> Option<(DVec3, DVec3, T)> {
    if w_away.z <= 0.0 {
        return None;
    }
    for _ in 0..MAX_DRAWS {
        let h = lobe.sample_visible_normal(w_away, uniform_pair(rng));
        let proposed = propose(h, rng);
        let keep = rng.next_f64();
        let visible = lobe.visible_g1(w_away, h);
        if visible <= 0.0 {
            continue;
        }
        if let Some((w, tag)) = proposed {
            if keep * visible < lobe.g(w_away, w, h) {
                return Some((w, h, tag));
            }
        }
    }
    None
}

/// A conductor's reflection of light from `w_away` (z > 0) about a normal
/// drawn from D(h) cosθh by `u`: the direction, the normal and its weight
/// G·(ω·h)/(cosθ cosθh) (Walter et al. 2007, eq. 41; unbounded at grazing
/// angles, so only for stratified averages); None where the normal faces
/// away or the reflection points below the surface.
fn projected_reflection(
    lobe: &Microfacet,
    w_away: DVec3,
    u: [f64; 2],
) -> Option<(DVec3, DVec3, f64)> {
    let h = lobe.sample_normal(u[0], u[1]);
    let wh = w_away.dot(h);
    let w = reflect(w_away, h);
    if wh <= 0.0 || w.z <= 0.0 {
        return None;
    }
    Some((w, h, lobe.g(w_away, w, h) * wh / (w_away.z * h.z)))
}

/// Scatter at the base: light arrives from `w_away` (z > 0, in the frame of
/// the last layer) and leaves upward. Returns the new direction and weight.
pub(crate) fn scatter_base(
    base: &Base,
    tables: &WalkTables,
    w_away: DVec3,
    rng: &mut impl Uniforms,
) -> Option<(DVec3, Rgb)> {
    match base {
        Base::Diffuse { .. } => scatter_base_stratified(base, tables, w_away, uniform_pair(rng)),
        Base::Conductor { own_lobe, .. } => {
            let (w, h) = conductor_scatter(own_lobe, w_away, rng)?;
            Some((w, lookup_fresnel(&tables.base_fresnel, w_away.dot(h))))
        }
        Base::Black => None,
    }
}

/// [`scatter_base`] for one sample of a stratified set `u` (the two
/// uniforms pick the whole scattering): a conductor's micro-facet normal
/// is drawn from D(h) cosθh and weighs F·G·(ω·h)/(cosθ cosθh) over the
/// table's E(cosθ), in expectation the same as `scatter_base`'s redrawn
/// visible normal, whose mirror choice and redraws would take numbers
/// outside the stratified pair.
pub(crate) fn scatter_base_stratified(
    base: &Base,
    tables: &WalkTables,
    w_away: DVec3,
    u: [f64; 2],
) -> Option<(DVec3, Rgb)> {
    match base {
        Base::Diffuse { .. } => {
            let w = cosine_hemisphere(u[0], u[1]);
            // weight f·cos/pdf with pdf = cos/π
            Some((w, base.eval(w_away, w) * PI))
        }
        Base::Conductor { own_lobe, .. } => {
            let (w, h, weight) = projected_reflection(own_lobe, w_away, u)?;
            let weight = weight / lookup(&tables.base, w_away.z);
            Some((
                w,
                lookup_fresnel(&tables.base_fresnel, w_away.dot(h)) * weight,
            ))
        }
        Base::Black => None,
    }
}

/// Follow one path of light arriving from direction `wi` (z > 0) and call
/// `tally(exit_direction, power)` for every part of it that leaves the top.
pub(crate) fn trace_path(
    brdf: &LayeredBrdf,
    tables: &WalkTables,
    wi: DVec3,
    rng: &mut Rng,
    tally: impl FnMut(DVec3, Rgb),
) {
    trace_path_with(brdf, tables, wi, rng, tally)
}

/// [`trace_path`] drawing its random numbers from any [`Uniforms`].
pub(crate) fn trace_path_with(
    brdf: &LayeredBrdf,
    tables: &WalkTables,
    wi: DVec3,
    rng: &mut impl Uniforms,
    mut tally: impl FnMut(DVec3, Rgb),
) {
    let layers = &brdf.interfaces;
    if layers.is_empty() {
        if let Some((w, weight)) = scatter_base(&brdf.base, tables, wi, rng) {
            tally(w, weight);
        }
        return;
    }
    // Entering the top interface from above: tally the reflection, carry on
    // with the transmitted power (both in expectation, which removes the
    // noise of the escape decision; weights G/G1 over the table's E).
    let top_albedo = lookup(&tables.top_from_above, wi.z);
    let Some(split) = split_dielectric(&layers[0].own_lobe, wi, layers[0].eta, uniform_pair(rng))
    else {
        return;
    };
    if let Some((r, g)) = split.reflected {
        tally(r, Rgb::splat(split.fresnel * g / top_albedo));
    }
    let Some((mut dir, g)) = split.transmitted else {
        return;
    };
    let mut power = Rgb::splat((1.0 - split.fresnel) * g / top_albedo);
    // `medium` = 1 + index of the interface above the current position.
    let mut medium = 1usize;
    for _ in 0..MAX_EVENTS {
        let strongest = power.max_element();
        if strongest < ROULETTE_BELOW {
            let survival = strongest / ROULETTE_BELOW;
            if strongest <= 0.0 || rng.next_f64() >= survival {
                return;
            }
            power /= survival;
        }
        // Beer-Lambert across the layer we are in (eq. 3.4).
        power *= layers[medium - 1].crossing_transmittance(dir.z);
        if dir.z < 0.0 {
            if medium == layers.len() {
                let Some((w, weight)) = scatter_base(&brdf.base, tables, -dir, rng) else {
                    return;
                };
                dir = w;
                power *= weight;
            } else {
                // The next interface down, from above.
                let itf = &layers[medium];
                let Some((w, reflected)) = scatter_dielectric(&itf.own_lobe, -dir, itf.eta, rng)
                else {
                    return;
                };
                dir = w;
                if !reflected {
                    medium += 1;
                }
            }
        } else {
            // The interface above, from below: in the flipped frame.
            let itf = &layers[medium - 1];
            let Some((w, reflected)) =
                scatter_dielectric(&itf.own_lobe, flip(-dir), 1.0 / itf.eta, rng)
            else {
                return;
            };
            dir = flip(w);
            if !reflected {
                medium -= 1;
                if medium == 0 {
                    tally(dir, power);
                    return;
                }
            }
        }
    }
}

/// Directional albedo of the physical stack for light from `wi`: the
/// fraction of power that leaves the top, with its standard error, from
/// `paths` random walks seeded by `seed`.
pub fn reference_albedo(brdf: &LayeredBrdf, wi: DVec3, paths: usize, seed: u64) -> (Rgb, Rgb) {
    let tables = WalkTables::new(brdf);
    reference_albedo_with(brdf, &tables, wi, paths, seed)
}

/// [`reference_albedo`] with tables computed once by the caller.
pub fn reference_albedo_with(
    brdf: &LayeredBrdf,
    tables: &WalkTables,
    wi: DVec3,
    paths: usize,
    seed: u64,
) -> (Rgb, Rgb) {
    let mut rng = Rng::new(seed, 0x5eed_a1be);
    let (mut sum, mut sum_sq) = (Rgb::ZERO, Rgb::ZERO);
    for _ in 0..paths {
        let mut path_total = Rgb::ZERO;
        trace_path(brdf, tables, wi, &mut rng, |_, p| path_total += p);
        sum += path_total;
        sum_sq += path_total * path_total;
    }
    let n = paths.max(1) as f64;
    let mean = sum / n;
    let variance = (sum_sq / n - mean * mean).max(Rgb::ZERO);
    (mean, (variance / n).map(f64::sqrt))
}

/// Grid points per side with which [`model_slice`] averages the model over
/// one of [`reference_slice`]'s squares.
const SLICE_GRID: usize = 16;

/// The model's in-plane slice binned exactly as [`reference_slice`] bins
/// the walk's, to compare the two like with like: f·cosθₒ at signed
/// outgoing angles `theta_o_deg` (light on the φ = π side), f averaged
/// over the square of side `bin` on the projected unit disc about each
/// angle's projection (a 16 × 16 grid; points off the disc count 0, as no
/// path exits there). A lobe much narrower than the grid's spacing
/// (bin/16; a mirror-like coat) is a spike the grid does not resolve.
pub fn model_slice(
    brdf: &LayeredBrdf,
    theta_i_deg: f64,
    theta_o_deg: &[f64],
    bin: f64,
) -> Vec<Rgb> {
    let wi = crate::sampling::direction_from_degrees(theta_i_deg, 180.0);
    let step = bin / SLICE_GRID as f64;
    theta_o_deg
        .iter()
        .map(|t| {
            let centre = t.to_radians().sin();
            let mut sum = Rgb::ZERO;
            for i in 0..SLICE_GRID {
                for j in 0..SLICE_GRID {
                    let x = centre - bin / 2.0 + (i as f64 + 0.5) * step;
                    let y = -bin / 2.0 + (j as f64 + 0.5) * step;
                    let z_squared = 1.0 - x * x - y * y;
                    if z_squared > 0.0 {
                        sum += brdf.eval(wi, DVec3::new(x, y, z_squared.sqrt()));
                    }
                }
            }
            sum / (SLICE_GRID * SLICE_GRID) as f64 * t.to_radians().cos()
        })
        .collect()
}

/// In-plane slice of the reference BRDF for the polar plots: f·cosθₒ at
/// signed outgoing angles `theta_o_deg` (φ = 0 for positive, π for negative
/// angles, the light at φ = π side), estimated by counting exits in small
/// squares of side `bin` on the projected unit disc (solid angle bin²/cosθ).
pub fn reference_slice(
    brdf: &LayeredBrdf,
    theta_i_deg: f64,
    theta_o_deg: &[f64],
    paths: usize,
    bin: f64,
    seed: u64,
) -> Vec<Rgb> {
    let wi = crate::sampling::direction_from_degrees(theta_i_deg, 180.0);
    let centres: Vec<f64> = theta_o_deg.iter().map(|t| t.to_radians().sin()).collect();
    let mut sums = vec![Rgb::ZERO; centres.len()];
    let mut rng = Rng::new(seed, theta_i_deg.to_bits());
    let tables = WalkTables::new(brdf);
    for _ in 0..paths {
        trace_path(brdf, &tables, wi, &mut rng, |w, p| {
            if w.y.abs() >= bin / 2.0 {
                return;
            }
            for (k, c) in centres.iter().enumerate() {
                if (w.x - c).abs() < bin / 2.0 {
                    sums[k] += p;
                }
            }
        });
    }
    // Σ power / N ≈ ∫_bin f cosθ dω = f · bin²  ⇒  f cosθ = Σ/(N bin²) · cosθ.
    sums.iter()
        .zip(theta_o_deg)
        .map(|(s, t)| *s / (paths as f64 * bin * bin) * t.to_radians().cos())
        .collect()
}
