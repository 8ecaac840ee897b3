//! The lobe of many flakes: how a population of flakes inside a body
//! reflects on average, for footprints that hold too many of them to show
//! one by one (`render::footprint`).
//!
//! A ray that meets a flake meets one whose normal n (turned to face the
//! ray, the flake reflecting from either side) has the density D(n)·(ωo·n)
//! / E(ωo), D the population's orientation density folded onto the
//! hemisphere about ωo and E(ωo) = ∫ D(n) (ωo·n) dn its mean projected
//! cosine: the flakes' projected area weighs them. Each flake's own lobe is
//! narrow against that spread of normals, so it is taken as a mirror that
//! reflects its material's directional albedo ρ(cos θ) (the same material
//! the flake has: energy is kept per flake). Where the spread of normals is
//! narrow (flakes aligned within a cone of a few degrees), the flakes' own
//! roughness is not narrow against it: D is then the cone's density
//! convolved with the half vectors the flake's BRDF reflects about its own
//! normal, tabulated. With h the half vector of ωo and ωi, the reflection
//! is then
//!
//! ```text
//! f·cosθi = ρ(ωo·h) · D(h) / (4 E(ωo))       (the mirror Jacobian dωi = 4(ωo·h) dh)
//! ```
//!
//! and ∫ f·cosθi dωi is the mean of ρ over the flakes a ray meets. Sampling
//! draws n from exactly that density and reflects ωo about it: ωi has the
//! density D(h)/(4 E) and the weight ρ(ωo·h). Isotropic normals (D = 1/2π,
//! E = 1/2) are cosine-weighted about ωo (ωi uniform, 1/4π); normals
//! about an axis are drawn from their tabulated density and kept with
//! probability ωo·n (rejection), E then tabulated against the cosine of
//! ωo and the axis.

use std::f64::consts::{FRAC_1_PI, TAU};
use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use crate::brdf::{LayeredBrdf, Rgb};
use crate::recipe::gem::{Body, Gem, Inclusions};
use crate::recipe::TableCache;
use crate::render::glitter_facets::{GlitterFacets, TableStore};
use crate::sampling::{cosine_hemisphere, sin_cos_turns, Rng};

/// Nodes of the albedo table, at cos θ = (k + ½)/N.
const ALBEDO_NODES: usize = 24;
/// Importance samples of the flake's BRDF per albedo node: a stratified
/// grid of this many a side in the first two of the sample's numbers.
const ALBEDO_STRATA: usize = 32;
/// Nodes of the mean-projected-cosine table of a cone, at |a·ωo| = k/(N−1).
const MEAN_COS_NODES: usize = 257;
/// Bins of the density of normals about an axis, uniform in
/// x = √(1 − |cos θ|) (nearly uniform in θ near the axis: 0.16° there).
const AXIAL_BINS: usize = 512;
/// Midpoint nodes in cos θ per bin when tabulating E.
const NODES_PER_BIN: usize = 4;
/// Strata a side of the grid (cone's cos θ × the BRDF's first number)
/// from which the density of normals about an axis is estimated, and
/// samples per stratum.
const SPREAD_STRATA: usize = 256;
const SPREAD_SAMPLES_PER_STRATUM: usize = 4;
/// Cones narrower than this (1 − cos of the half-angle: about 0.8°) are
/// left to the flakes themselves: their lobe is all but a mirror.
const NARROWEST_CONE: f64 = 1e-4;
/// Candidates a cone's rejection sampling draws before it gives up (the
/// acceptance rate is E ≥ 0.009 for the narrowest cone seen edge-on: a
/// miss about once in 10⁴ draws there, never elsewhere).
const MOST_CANDIDATES: u32 = 1024;

/// The orientation of a population's normals.
#[derive(Clone, Debug, PartialEq)]
enum Normals {
    /// Uniform over the sphere.
    Isotropic,
    /// About `axis` (object space), the density a function of |axis·h|.
    Axial(AxialNormals),
}

/// An axially symmetric density of normals folded onto one hemisphere,
/// piecewise constant over [`AXIAL_BINS`] bins of x = √(1 − |cos θ|).
#[derive(Clone, Debug, PartialEq)]
struct AxialNormals {
    axis: DVec3,
    /// The density per steradian in each bin.
    density: Vec<f64>,
    /// The probability of bins below k, k = 0 ..= N (the last is 1).
    cumulative: Vec<f64>,
    /// E at |axis·ωo| = k/(N − 1), k < [`MEAN_COS_NODES`].
    mean_abs_cos: Vec<f64>,
    /// The same for the flakes' own normals (the cone, before their BRDF
    /// spreads it): the share of a flake's area a ray along ωo meets.
    flake_mean_abs_cos: Vec<f64>,
}

/// The aggregate lobe of one flake population, in the stone's object space.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FlakeLobe {
    normals: Normals,
    /// ρ at cos θ = (k + ½)/N, the flake material's directional albedo.
    albedo: [Rgb; ALBEDO_NODES],
    /// Mean area a flake projects along a ray, mm² (isotropic: half its
    /// mean area), to count the flakes in a footprint.
    pub projected_area_mm2: f64,
}

impl FlakeLobe {
    /// The lobe of `population`, whose flakes have the material `brdf` (as
    /// seen from the body); None for a cone too narrow to need one.
    pub(crate) fn new(population: &Inclusions, brdf: &LayeredBrdf) -> Option<Self> {
        let normals = match population.aligned {
            None => Normals::Isotropic,
            Some((_, cos_max)) if 1.0 - cos_max < NARROWEST_CONE => return None,
            Some((axis, cos_max)) => Normals::Axial(AxialNormals::new(
                axis,
                &cone_spread_by(brdf, cos_max),
                &uniform_cone(cos_max),
            )),
        };
        let nodes: Vec<Rgb> = (0..ALBEDO_NODES)
            .into_par_iter()
            .map(|k| directional_albedo(brdf, (k as f64 + 0.5) / ALBEDO_NODES as f64, k as u64))
            .collect();
        let albedo = std::array::from_fn(|k| nodes[k]);
        Some(Self {
            normals,
            albedo,
            projected_area_mm2: 0.5 * population.mean_area_mm2(),
        })
    }

    /// The mean area one flake projects along the unit `direction` (object
    /// space), mm²: a straight path crosses the population's density times
    /// this many flakes per mm (their extinction as a medium).
    pub(crate) fn projected_area_along_mm2(&self, direction: DVec3) -> f64 {
        match &self.normals {
            Normals::Isotropic => self.projected_area_mm2,
            Normals::Axial(axial) => {
                2.0 * self.projected_area_mm2
                    * interpolate(&axial.flake_mean_abs_cos, direction.dot(axial.axis).abs())
            }
        }
    }

    /// ρ at `cos`, linear between the table's nodes.
    fn albedo_at(&self, cos: f64) -> Rgb {
        let x = (cos * ALBEDO_NODES as f64 - 0.5).clamp(0.0, (ALBEDO_NODES - 1) as f64);
        let k = (x as usize).min(ALBEDO_NODES - 2);
        let s = x - k as f64;
        self.albedo[k] * (1.0 - s) + self.albedo[k + 1] * s
    }

    /// The lobe for rays leaving towards the unit `wo` (object space, from
    /// the flake back along the arriving ray).
    pub(crate) fn at(&self, wo: DVec3) -> FlakeLobeAt<'_> {
        let mean_cos = match &self.normals {
            Normals::Isotropic => 0.5,
            Normals::Axial(axial) => axial.mean_abs_cos_at(wo),
        };
        FlakeLobeAt {
            lobe: self,
            wo,
            mean_cos,
        }
    }
}

/// A [`FlakeLobe`] for one direction ωo: what depends on it alone.
pub(crate) struct FlakeLobeAt<'a> {
    lobe: &'a FlakeLobe,
    wo: DVec3,
    /// E(ωo), the normals' mean projected cosine.
    mean_cos: f64,
}

impl FlakeLobeAt<'_> {
    /// D(h) for a unit `h` facing ωo (the folded orientation density).
    fn density(&self, h: DVec3) -> f64 {
        match &self.lobe.normals {
            Normals::Isotropic => 0.5 * FRAC_1_PI,
            Normals::Axial(axial) => axial.density[axial.bin(h)],
        }
    }

    /// f·cosθi towards the unit `wi` (object space) and the density with
    /// which [`Self::sample`] draws it.
    pub(crate) fn eval(&self, wi: DVec3) -> (Rgb, f64) {
        let sum = self.wo + wi;
        if sum.length_squared() < 1e-24 {
            return (Rgb::ZERO, 0.0);
        }
        let h = sum.normalize();
        let cos = self.wo.dot(h);
        let d = self.density(h);
        if d == 0.0 || cos <= 0.0 {
            return (Rgb::ZERO, 0.0);
        }
        let pdf = d / (4.0 * self.mean_cos);
        (self.lobe.albedo_at(cos) * pdf, pdf)
    }

    /// A reflected direction from three uniform numbers (an axial density's
    /// rejection draws its further candidates from a generator seeded by
    /// them): (wi, f·cosθi / pdf = ρ, pdf); None when the flake drawn is
    /// seen edge-on.
    pub(crate) fn sample(&self, u: [f64; 3]) -> Option<(DVec3, Rgb, f64)> {
        let normal = match &self.lobe.normals {
            Normals::Isotropic => {
                let (t, b) = self.wo.any_orthonormal_pair();
                let local = cosine_hemisphere(u[0], u[1]);
                t * local.x + b * local.y + self.wo * local.z
            }
            Normals::Axial(axial) => {
                let (at, ab) = axial.axis.any_orthonormal_pair();
                let facing_wo = |u: [f64; 3]| {
                    let cos_theta = axial.sample_cos(u[0]);
                    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                    let (sin_phi, cos_phi) = sin_cos_turns(u[1]);
                    let m = at * (sin_theta * cos_phi)
                        + ab * (sin_theta * sin_phi)
                        + axial.axis * cos_theta;
                    let normal = if m.dot(self.wo) < 0.0 { -m } else { m };
                    (u[2] < normal.dot(self.wo)).then_some(normal)
                };
                let mut more = Rng::new(u[0].to_bits(), u[1].to_bits() ^ u[2].to_bits());
                std::iter::once(u)
                    .chain(std::iter::repeat_with(|| more.next_3()))
                    .take(MOST_CANDIDATES as usize)
                    .find_map(facing_wo)?
            }
        };
        let cos = normal.dot(self.wo);
        if cos <= 0.0 {
            return None;
        }
        let wi = (normal * (2.0 * cos) - self.wo).normalize();
        Some((
            wi,
            self.lobe.albedo_at(cos),
            self.density(normal) / (4.0 * self.mean_cos),
        ))
    }
}

/// How a scene's flakes are shaded by their footprint
/// ([`FlakeLobes::of_gems`]): per gem, the aggregate lobes of the flake
/// populations of a translucent body, and the glitter facets of an opaque
/// one to draw where a footprint holds many
/// (`render::glitter_facets`). The default has none, and then every flake
/// and facet is shaded by its own normal.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FlakeLobes {
    /// Per gem, per flake population.
    populations: Vec<Arc<[Option<FlakeLobe>]>>,
    /// Per gem.
    facets: Vec<Option<GlitterFacets>>,
}

impl FlakeLobes {
    /// The lobes of every flake population, and the glitter facets, of
    /// every gem of a scene.
    pub fn of_gems(gems: &[Gem]) -> Self {
        Self::of_gems_keeping_tables(gems, None)
    }

    /// [`Self::of_gems`], the glitter facets' tables (built when first
    /// needed, `render::glitter_aggregate`) looked up in and kept by
    /// `tables` when given: built once per machine instead of per scene.
    pub fn of_gems_keeping_tables(gems: &[Gem], tables: Option<Arc<TableCache>>) -> Self {
        let store = TableStore(tables);
        Self {
            populations: lobes_of_gems(gems),
            facets: gems
                .iter()
                .map(|gem| GlitterFacets::of_gem(gem, &store))
                .collect(),
        }
    }

    /// The lobe of population `population` of gem `gem`, if it has one.
    pub(crate) fn get(&self, gem: usize, population: usize) -> Option<&FlakeLobe> {
        self.populations.get(gem)?.get(population)?.as_ref()
    }

    /// The glitter facets of gem `gem`, if they are shaded by footprint.
    pub(crate) fn facets(&self, gem: usize) -> Option<&GlitterFacets> {
        self.facets.get(gem)?.as_ref()
    }
}

/// Per gem, the lobes of its flake populations. Gems of one recipe under
/// different seeds share their materials and their flakes' shapes, sizes
/// and orientations, and so one set of lobes.
fn lobes_of_gems(gems: &[Gem]) -> Vec<Arc<[Option<FlakeLobe>]>> {
    let same_flakes = |a: &Inclusions, b: &Inclusions| {
        (a.shape, a.radius_mm, a.size_spread, a.aligned, a.material)
            == (b.shape, b.radius_mm, b.size_spread, b.aligned, b.material)
    };
    let mut lobes: Vec<Arc<[Option<FlakeLobe>]>> = Vec::with_capacity(gems.len());
    for (k, gem) in gems.iter().enumerate() {
        let Body::Translucent { inclusions, .. } = &gem.body else {
            lobes.push(Arc::from(Vec::new()));
            continue;
        };
        let shared = gems[..k].iter().zip(&lobes).find(|(other, _)| {
            let Body::Translucent {
                inclusions: theirs, ..
            } = &other.body
            else {
                return false;
            };
            Arc::ptr_eq(&other.brdfs, &gem.brdfs)
                && theirs.len() == inclusions.len()
                && theirs
                    .iter()
                    .zip(inclusions)
                    .all(|(a, b)| same_flakes(a, b))
        });
        lobes.push(match shared {
            Some((_, lobe)) => Arc::clone(lobe),
            None => inclusions
                .par_iter()
                .map(|population| {
                    FlakeLobe::new(population, &gem.brdfs[population.material as usize])
                })
                .collect::<Vec<_>>()
                .into(),
        });
    }
    lobes
}

/// The directional albedo ∫ f cosθi dωi of `brdf` seen at cos θo = `cos`:
/// the mean weight of its importance samples over a stratified grid (the
/// third number from a generator seeded by `seed`).
fn directional_albedo(brdf: &LayeredBrdf, cos: f64, seed: u64) -> Rgb {
    let wo = DVec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos);
    let mut rng = Rng::new(seed, 0xf1a4e);
    let at = brdf.at(wo);
    let strata = ALBEDO_STRATA as f64;
    let sum = (0..ALBEDO_STRATA * ALBEDO_STRATA).fold(Rgb::ZERO, |sum, k| {
        let u = [
            ((k % ALBEDO_STRATA) as f64 + rng.next_f64()) / strata,
            ((k / ALBEDO_STRATA) as f64 + rng.next_f64()) / strata,
            rng.next_f64(),
        ];
        sum + at.sample(u).map_or(Rgb::ZERO, |s| s.weight())
    });
    sum / (strata * strata)
}

impl AxialNormals {
    /// The density whose bins hold `masses` (of any scale, not all 0), for
    /// flakes whose own normals' bins hold `flake_masses`.
    fn new(axis: DVec3, masses: &[f64], flake_masses: &[f64]) -> Self {
        let total: f64 = masses.iter().sum();
        let mut cumulative: Vec<f64> = std::iter::once(0.0)
            .chain(masses.iter().scan(0.0, |sum, mass| {
                *sum += mass / total;
                Some(*sum)
            }))
            .collect();
        cumulative[AXIAL_BINS] = 1.0;
        let density = masses
            .iter()
            .enumerate()
            .map(|(k, mass)| mass / total / (TAU * bin_width(k)))
            .collect();
        Self {
            axis,
            density,
            cumulative,
            mean_abs_cos: mean_abs_cos_table(masses),
            flake_mean_abs_cos: mean_abs_cos_table(flake_masses),
        }
    }

    /// The bin of a unit `h`.
    fn bin(&self, h: DVec3) -> usize {
        bin_of(h.dot(self.axis).abs())
    }

    /// E at `wo`, linear between the table's nodes.
    fn mean_abs_cos_at(&self, wo: DVec3) -> f64 {
        interpolate(&self.mean_abs_cos, wo.dot(self.axis).abs())
    }

    /// |cos θ| about the axis drawn from the density by one uniform number:
    /// a bin by its probability, then uniform in solid angle within it.
    fn sample_cos(&self, u: f64) -> f64 {
        let k = (self.cumulative.partition_point(|&c| c <= u) - 1).min(AXIAL_BINS - 1);
        let (below, above) = (self.cumulative[k], self.cumulative[k + 1]);
        let s = ((u - below) / (above - below)).clamp(0.0, 1.0);
        bin_low(k) + bin_width(k) * (1.0 - s)
    }
}

/// E(c), the mean |cos| between ωo and normals whose axial bins hold
/// `masses` (of any scale, not all 0), at c = |axis·ωo| = k/(N − 1), k <
/// [`MEAN_COS_NODES`].
fn mean_abs_cos_table(masses: &[f64]) -> Vec<f64> {
    let total: f64 = masses.iter().sum();
    (0..MEAN_COS_NODES)
        .map(|j| {
            let cos_axis = j as f64 / (MEAN_COS_NODES - 1) as f64;
            masses
                .iter()
                .enumerate()
                .filter(|(_, mass)| **mass > 0.0)
                .map(|(k, mass)| {
                    let (low, width) = (bin_low(k), bin_width(k));
                    let nodes: f64 = (0..NODES_PER_BIN)
                        .map(|i| {
                            let cos_theta = low + width * (i as f64 + 0.5) / NODES_PER_BIN as f64;
                            azimuthal_mean_abs_cos(cos_theta, cos_axis)
                        })
                        .sum();
                    mass / total * nodes / NODES_PER_BIN as f64
                })
                .sum()
        })
        .collect()
}

/// A table of [`MEAN_COS_NODES`] nodes over c in [0, 1] read at `c`,
/// linear between nodes.
fn interpolate(table: &[f64], c: f64) -> f64 {
    let x = c.clamp(0.0, 1.0) * (MEAN_COS_NODES - 1) as f64;
    let k = (x as usize).min(MEAN_COS_NODES - 2);
    let s = x - k as f64;
    table[k] * (1.0 - s) + table[k + 1] * s
}

/// The masses over the axial bins of normals uniform in the cone cos θ ≥
/// `cos_max` (each bin's share of the cone's solid angle, exactly).
fn uniform_cone(cos_max: f64) -> Vec<f64> {
    (0..AXIAL_BINS)
        .map(|k| {
            let (low, high) = (bin_low(k), bin_low(k) + bin_width(k));
            (high.min(1.0) - low.max(cos_max)).max(0.0)
        })
        .collect()
}

/// The axial bin of |cos θ| = `cos_abs`.
fn bin_of(cos_abs: f64) -> usize {
    let x = (1.0 - cos_abs).max(0.0).sqrt();
    ((x * AXIAL_BINS as f64) as usize).min(AXIAL_BINS - 1)
}

/// The least |cos θ| of axial bin `k` (x = √(1 − |cos θ|) ≤ (k + 1)/N).
fn bin_low(k: usize) -> f64 {
    1.0 - ((k + 1) as f64 / AXIAL_BINS as f64).powi(2)
}

/// The range of |cos θ| of axial bin `k`, (2k + 1)/N²: its solid angle over
/// 2π.
fn bin_width(k: usize) -> f64 {
    (2 * k + 1) as f64 / (AXIAL_BINS * AXIAL_BINS) as f64
}

/// The masses over the axial bins of the half vectors about which a
/// population aligned within `cos_max` of its axis reflects: normals
/// uniform in the cone, each turned by the half vector of a sample of the
/// flakes' `brdf` seen along its normal, weighted by the sample's mean
/// weight over the channels (a stratified grid in the cone's cos θ and the
/// BRDF's first number, the rest from generators seeded per stratum row).
fn cone_spread_by(brdf: &LayeredBrdf, cos_max: f64) -> Vec<f64> {
    let at = brdf.at(DVec3::Z);
    let strata = SPREAD_STRATA as f64;
    let rows: Vec<Vec<f64>> = (0..SPREAD_STRATA)
        .into_par_iter()
        .map(|i| {
            let mut rng = Rng::new(i as u64, 0x5b4ead);
            let mut masses = vec![0.0; AXIAL_BINS];
            for j in 0..SPREAD_STRATA * SPREAD_SAMPLES_PER_STRATUM {
                let cos_theta = 1.0 - (i as f64 + rng.next_f64()) / strata * (1.0 - cos_max);
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let (sin_phi, cos_phi) = sin_cos_turns(rng.next_f64());
                let normal = DVec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta);
                let u = [
                    ((j / SPREAD_SAMPLES_PER_STRATUM) as f64 + rng.next_f64()) / strata,
                    rng.next_f64(),
                    rng.next_f64(),
                ];
                let Some(sample) = at.sample(u) else {
                    continue;
                };
                let local = (DVec3::Z + sample.wi).normalize();
                let (t, b) = normal.any_orthonormal_pair();
                let h = t * local.x + b * local.y + normal * local.z;
                masses[bin_of(h.z.abs())] += sample.weight().element_sum() / 3.0;
            }
            masses
        })
        .collect();
    rows.iter().fold(vec![0.0; AXIAL_BINS], |mut sum, row| {
        sum.iter_mut().zip(row).for_each(|(s, m)| *s += m);
        sum
    })
}

/// The mean over φ of |m·ωo| for m at `cos_theta` from an axis at cosine
/// `cos_axis` (≥ 0) from ωo: with A = sin θ sin ψ and B = cos θ cos ψ ≥ 0,
/// the mean of |A cos φ + B| is B when B ≥ A, else (2/π)(√(A² − B²) +
/// B asin(B/A)).
fn azimuthal_mean_abs_cos(cos_theta: f64, cos_axis: f64) -> f64 {
    let sin_axis = (1.0 - cos_axis * cos_axis).max(0.0).sqrt();
    let a = (1.0 - cos_theta * cos_theta).max(0.0).sqrt() * sin_axis;
    let b = cos_theta * cos_axis;
    if b >= a {
        b
    } else {
        2.0 * FRAC_1_PI * ((a * a - b * b).sqrt() + b * (b / a).asin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recipe::gem::{parse_gem, Body};
    use crate::recipe::library::builtin_gem_source;
    use crate::render::chi2_cells::{cap_grid, Tally};
    use crate::sampling::Rng;

    /// Goldstone's first population (isotropic copper triangles) and its
    /// material; with `cone`, the same flakes aligned within that cone.
    fn goldstone_population(cone: Option<(DVec3, f64)>) -> (Inclusions, LayeredBrdf) {
        let gem = parse_gem("goldstone", builtin_gem_source("goldstone").unwrap()).unwrap();
        let Body::Translucent { inclusions, .. } = &gem.body else {
            panic!("goldstone is translucent");
        };
        let mut population = inclusions[0].clone();
        population.aligned = cone;
        let brdf = gem.brdfs[population.material as usize].clone();
        (population, brdf)
    }

    fn unit(v: DVec3) -> DVec3 {
        v.normalize()
    }

    type Cone = Option<(DVec3, f64)>;

    /// Goldstone's first population's lobe, isotropic and aligned within
    /// cones about a tilted axis: (name, cone, lobe).
    fn lobes() -> Vec<(&'static str, Cone, FlakeLobe)> {
        let tilted = unit(DVec3::new(0.3, -0.2, 1.0));
        [
            ("isotropic", None),
            ("cone of 5°", Some((tilted, 5f64.to_radians().cos()))),
            ("cone of 25°", Some((tilted, 25f64.to_radians().cos()))),
            ("cone of 90°", Some((tilted, 0.0))),
        ]
        .into_iter()
        .map(|(name, cone)| {
            let (population, brdf) = goldstone_population(cone);
            (name, cone, FlakeLobe::new(&population, &brdf).unwrap())
        })
        .collect()
    }

    #[test]
    fn sampling_matches_the_pdf_and_the_value_over_the_pdf_is_the_weight() {
        // χ² of 10⁶ samples against the pdf integrated over 24 × 48 cells
        // of equal solid angle (each cell's integral from 24 × 24 sub-cells),
        // pooling cells expected below 5. The cells tile the sphere of the
        // half vector h = (ωo + ωi)/|ωo + ωi|, a one-to-one map of ωi with
        // dωi = 4 (ωo·h) dh, folded about the lobe's axis (h and −h share
        // a cell): a cone's pdf in ωi peaks towards −ωo (∝ 1/(ωo·h), flakes
        // seen edge-on), in h it follows the density of normals. A narrow
        // cone's cells cover the cap within 15° of its axis, and one more
        // cell the rest. Where the pdf jumps, sub-cells cannot integrate it
        // well: cells over which it varies more than fourfold are left out
        // of χ² and only their total is compared (within 3 % and 4σ). At
        // every sample, eval's pdf equals the sample's and its value over
        // the pdf the sample's weight.
        const N_COS: usize = 24;
        const N_PHI: usize = 48;
        const FINE: usize = 24;
        const OUTSIDE: usize = N_COS * N_PHI;
        for (name, cone, lobe) in lobes() {
            let (axis, z_min) = match cone {
                Some((axis, cos_max)) if cos_max > 0.99 => (axis, 15f64.to_radians().cos()),
                Some((axis, _)) => (axis, 0.0),
                None => (DVec3::Z, 0.0),
            };
            let (t, b) = axis.any_orthonormal_pair();
            let cell_of = |h: DVec3| {
                let h = if h.dot(axis) < 0.0 { -h } else { h };
                let z = h.dot(axis);
                if z < z_min {
                    return OUTSIDE;
                }
                let i = (((z - z_min) / (1.0 - z_min) * N_COS as f64) as usize).min(N_COS - 1);
                let phi = h.dot(b).atan2(h.dot(t)).rem_euclid(TAU);
                let j = ((phi / TAU * N_PHI as f64) as usize).min(N_PHI - 1);
                i * N_PHI + j
            };
            for wo in [
                DVec3::Z,
                unit(DVec3::new(1.0, 0.2, 0.4)),
                unit(DVec3::new(-0.3, 1.0, -0.1)),
            ] {
                let at = lobe.at(wo);
                let pdf_of_h = |h: DVec3| {
                    let cos = wo.dot(h);
                    if cos > 0.0 {
                        at.eval(h * (2.0 * cos) - wo).1 * 4.0 * cos
                    } else {
                        0.0
                    }
                };
                let mut expected = vec![0.0; OUTSIDE + 1];
                let mut range = vec![(f64::INFINITY, 0.0f64); OUTSIDE + 1];
                for (local, solid_angle) in cap_grid(z_min, N_COS * FINE, N_PHI * FINE) {
                    let h = t * local.x + b * local.y + axis * local.z;
                    let pdf = pdf_of_h(h) + pdf_of_h(-h);
                    let cell = cell_of(h);
                    expected[cell] += pdf * solid_angle;
                    let (least, most) = range[cell];
                    range[cell] = (least.min(pdf), most.max(pdf));
                }
                // Over the whole hemisphere the grid misses a little of a
                // cone's pdf where flakes seen edge-on send light straight
                // back (pdf ∝ 1/(ωo·h)); off a cap, the rest lies outside.
                let cap: f64 = expected.iter().sum();
                let total = if z_min > 0.0 {
                    expected[OUTSIDE] = 1.0 - cap;
                    1.0
                } else {
                    cap
                };
                assert!((cap - 1.0).abs() < 0.02, "{name}, {wo}: ∫pdf = {cap}");
                let samples = 1_000_000;
                let mut observed = vec![0u32; OUTSIDE + 1];
                let mut rng = Rng::new(4, 2);
                for _ in 0..samples {
                    let Some((wi, weight, pdf)) = at.sample(rng.next_3()) else {
                        continue;
                    };
                    let (value, eval_pdf) = at.eval(wi);
                    // Where ωi is nearly −ωo (a flake seen edge-on), h from
                    // their sum loses digits; such samples are left out.
                    if pdf < 1e3 {
                        assert!(
                            (eval_pdf - pdf).abs() <= 1e-6 * pdf,
                            "{name}: {eval_pdf} vs {pdf}"
                        );
                        let relative = (value / pdf - weight).abs() / weight.max(Rgb::splat(1e-9));
                        assert!(
                            relative.max_element() <= 1e-6,
                            "{name}: {value} / {pdf} vs {weight}"
                        );
                    }
                    observed[cell_of((wo + wi).normalize())] += 1;
                }
                let expected: Vec<f64> = expected
                    .iter()
                    .map(|e| e / total * samples as f64)
                    .collect();
                let tally = Tally::new(&expected, &observed, &range);
                tally.assert_agrees(20, &format!("{name}, {wo}"));
            }
        }
    }

    #[test]
    fn the_lobe_reflects_what_its_flakes_do() {
        // The flakes themselves: normals drawn from the orientation density,
        // kept with probability ωo·n (a ray meets a flake by its projected
        // area), each reflecting by the full BRDF in its own frame. Their
        // mean reflected energy must be the lobe's ∫ f·cosθi (its mean
        // sample weight) within 1 %, and the share reflected into each band
        // the lobe's within 0.02: for isotropic normals bands of the angle
        // between ωo and ωi, for aligned ones bands of the half vector's
        // angle to the axis in thirds of the cone's, which the flakes'
        // roughness (3° here) widens beyond the cone.
        const BANDS: usize = 6;
        for (name, cone, lobe) in lobes() {
            let (population, brdf) = goldstone_population(cone);
            for wo in [DVec3::Z, unit(DVec3::new(0.9, 0.1, 0.3))] {
                let band = |wi: DVec3| {
                    let x = match cone {
                        None => (1.0 - wo.dot(wi)) / 2.0 * BANDS as f64,
                        Some((axis, cos_max)) => {
                            let cos_h = (wo + wi).normalize().dot(axis).abs().min(1.0);
                            3.0 * cos_h.acos() / cos_max.acos()
                        }
                    };
                    (x as usize).min(BANDS - 1)
                };
                let mut rng = Rng::new(11, 3);
                let (mut flakes, mut kept) = ([0.0; BANDS], 0u32);
                let mut flakes_energy = Rgb::ZERO;
                while kept < 200_000 {
                    let [u, v, w] = rng.next_3();
                    let m = match population.aligned {
                        None => {
                            let z = 1.0 - 2.0 * u;
                            let r = (1.0 - z * z).sqrt();
                            DVec3::new(r * (TAU * v).cos(), r * (TAU * v).sin(), z)
                        }
                        Some((axis, cos_max)) => {
                            let c = 1.0 - u * (1.0 - cos_max);
                            let s = (1.0 - c * c).sqrt();
                            let (t, b) = axis.any_orthonormal_pair();
                            t * (s * (TAU * v).cos()) + b * (s * (TAU * v).sin()) + axis * c
                        }
                    };
                    let n = if m.dot(wo) < 0.0 { -m } else { m };
                    if w >= n.dot(wo) {
                        continue;
                    }
                    kept += 1;
                    let (t, b) = n.any_orthonormal_pair();
                    let local_wo = DVec3::new(wo.dot(t), wo.dot(b), wo.dot(n));
                    if let Some(s) = brdf.sample(local_wo, rng.next_3()) {
                        let wi = t * s.wi.x + b * s.wi.y + n * s.wi.z;
                        let weight = s.weight();
                        flakes_energy += weight;
                        flakes[band(wi)] += weight.element_sum() / 3.0;
                    }
                }
                let at = lobe.at(wo);
                let (mut aggregate, mut aggregate_energy) = ([0.0; BANDS], Rgb::ZERO);
                for _ in 0..200_000 {
                    if let Some((wi, weight, _)) = at.sample(rng.next_3()) {
                        aggregate_energy += weight;
                        aggregate[band(wi)] += weight.element_sum() / 3.0;
                    }
                }
                let ratio = aggregate_energy / flakes_energy;
                assert!(
                    (ratio - 1.0).abs().max_element() < 0.01,
                    "{name}, {wo}: energy {aggregate_energy} vs the flakes' {flakes_energy}"
                );
                let total: f64 = flakes.iter().sum();
                for k in 0..BANDS {
                    let (a, f) = (aggregate[k] / total, flakes[k] / total);
                    assert!(
                        (a - f).abs() < 0.02,
                        "{name}, {wo}, band {k}: {a:.3} vs {f:.3}"
                    );
                }
            }
        }
    }

    /// Normals uniform in the cone cos θ ≥ `cos_max` about z.
    fn uniform_cone_normals(cos_max: f64) -> AxialNormals {
        let masses = uniform_cone(cos_max);
        AxialNormals::new(DVec3::Z, &masses, &masses)
    }

    #[test]
    fn the_axial_mean_cosine_matches_its_closed_forms() {
        let at = |normals: &AxialNormals, cos_axis: f64| {
            normals.mean_abs_cos_at(DVec3::new(
                (1.0 - cos_axis * cos_axis).sqrt(),
                0.0,
                cos_axis,
            ))
        };
        // Along the axis: the mean of cos θ over the cone, (1 + cos_max)/2
        // (the bin the cone's edge cuts is spread over the whole bin).
        for cos_max in [0.0, 0.5, 0.95] {
            let e = at(&uniform_cone_normals(cos_max), 1.0);
            assert!((e - (1.0 + cos_max) / 2.0).abs() < 1e-5, "{e}");
        }
        // The whole hemisphere (cos_max 0) seen from anywhere: 1/2.
        let hemisphere = uniform_cone_normals(0.0);
        for cos_axis in [0.0, 0.3, 0.8] {
            let e = at(&hemisphere, cos_axis);
            assert!((e - 0.5).abs() < 1e-4, "{cos_axis}: {e}");
        }
        // Against brute force for a 30° cone seen at 70° from its axis.
        let (cos_max, cos_axis) = (30f64.to_radians().cos(), 70f64.to_radians().cos());
        let wo = DVec3::new((1.0 - cos_axis * cos_axis).sqrt(), 0.0, cos_axis);
        let mut rng = Rng::new(2, 2);
        let n = 400_000;
        let brute: f64 = (0..n)
            .map(|_| {
                let [u, v, _] = rng.next_3();
                let c = 1.0 - u * (1.0 - cos_max);
                let s = (1.0 - c * c).sqrt();
                DVec3::new(s * (TAU * v).cos(), s * (TAU * v).sin(), c)
                    .dot(wo)
                    .abs()
            })
            .sum::<f64>()
            / f64::from(n);
        let e = at(&uniform_cone_normals(cos_max), cos_axis);
        assert!((e - brute).abs() < 0.002, "{e} vs {brute}");
    }

    #[test]
    fn rough_flakes_widen_an_aligned_lobe_beyond_its_cone() {
        // A 5° cone of mirrors has no half vector beyond 5°; goldstone's 3°
        // copper puts a share of them there, and its 8° copper more.
        let beyond = |material: &str| {
            let gem = parse_gem("goldstone", builtin_gem_source("goldstone").unwrap()).unwrap();
            let brdf = &gem.brdfs[gem.material_index(material).unwrap() as usize];
            let cos_max = 5f64.to_radians().cos();
            let masses = cone_spread_by(brdf, cos_max);
            let total: f64 = masses.iter().sum();
            masses[bin_of(cos_max) + 1..].iter().sum::<f64>() / total
        };
        let (sharp, soft) = (beyond("copper-sharp"), beyond("copper-soft"));
        assert!(sharp > 0.05 && soft > sharp + 0.1, "{sharp:.3}, {soft:.3}");
    }
}
