//! The boundary of a translucent body: a dielectric interface between air
//! and the stone (eqs. 3.1–3.2), polished smooth (a delta lobe,
//! `cross_smooth_interface`) or rough ([`RoughInterface`], the microfacet
//! model of Walter, Marschner, Li and Torrance 2007, "Microfacet models
//! for refraction through rough surfaces", with the GGX distribution of
//! the layered BRDFs' `brdf::Microfacet`).

use glam::DVec3;

use crate::brdf::fresnel::{self, Snell};
use crate::brdf::microfacet::{ggx_visible_normal, reflect, refract};
use crate::brdf::{Microfacet, MicrofacetModel};
use crate::sampling::Rng;

/// Where a ray goes at a smooth dielectric interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Crossing {
    /// The new unit direction.
    pub(crate) direction: DVec3,
    /// True when it refracted through the interface, false when it
    /// reflected (by the Fresnel draw, or by total internal reflection).
    pub(crate) refracted: bool,
    /// True when the ray arrived from the outside (against the normal).
    pub(crate) from_outside: bool,
}

/// The ray `direction` (unit) meeting a smooth interface of outward unit
/// `normal` between air (outside) and a body of index `ior`: reflected with
/// the Fresnel reflectance F (eq. 3.1), which is 1 under total internal
/// reflection, else refracted by Snell's law (eq. 3.2), chosen by `u` in
/// [0, 1). Each choice is taken with its own probability, so the weight is
/// 1 either way; the radiance scale (η²) of refraction cancels between the
/// way in and the way out of the body.
pub(crate) fn cross_smooth_interface(
    direction: DVec3,
    normal: DVec3,
    ior: f64,
    u: f64,
) -> Crossing {
    let cos_outside = -direction.dot(normal);
    let from_outside = cos_outside > 0.0;
    // The normal on the side the ray comes from, the cosine to it and
    // η = n_transmitted / n_incident.
    let (facing, cos_i, eta) = if from_outside {
        (normal, cos_outside, ior)
    } else {
        (-normal, -cos_outside, 1.0 / ior)
    };
    if u < fresnel::dielectric(cos_i, eta) {
        return mirrored(direction, facing, cos_i, from_outside);
    }
    refracted(direction, facing, cos_i, eta, from_outside)
        .unwrap_or_else(|| mirrored(direction, facing, cos_i, from_outside))
}

/// The mirror reflection of `direction` about `facing` (the normal on its
/// side, cos_i = −direction·facing).
fn mirrored(direction: DVec3, facing: DVec3, cos_i: f64, from_outside: bool) -> Crossing {
    Crossing {
        direction: (direction + 2.0 * cos_i * facing).normalize(),
        refracted: false,
        from_outside,
    }
}

/// The refraction of `direction` by Snell's law (eq. 3.2) into a medium of
/// relative index `eta`, or None under total internal reflection.
fn refracted(
    direction: DVec3,
    facing: DVec3,
    cos_i: f64,
    eta: f64,
    from_outside: bool,
) -> Option<Crossing> {
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(Crossing {
        direction: (direction / eta + (cos_i / eta - cos_t) * facing).normalize(),
        refracted: true,
        from_outside,
    })
}

/// One branch of a split crossing: where it goes and what it carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Branch {
    /// The crossing this branch takes.
    pub(crate) crossing: Crossing,
    /// Its share of the radiance: F for the reflection, 1 − F for the
    /// refraction (eq. 3.1).
    pub(crate) weight: f64,
}

/// [`cross_smooth_interface`] taking both ways at once, for a ray arriving
/// from outside (where no total internal reflection can happen): the
/// reflection weighted by the Fresnel reflectance F, the refraction by
/// 1 − F. Their sum has the expectation of the Fresnel draw without its
/// noise.
pub(crate) fn split_smooth_interface(
    direction: DVec3,
    normal: DVec3,
    ior: f64,
) -> (Branch, Branch) {
    let cos_i = -direction.dot(normal);
    debug_assert!(cos_i > 0.0, "split only from outside");
    let reflectance = fresnel::dielectric(cos_i, ior);
    let reflection = Branch {
        crossing: mirrored(direction, normal, cos_i, true),
        weight: reflectance,
    };
    // From outside into the denser body: always refracts.
    let refraction = Branch {
        crossing: refracted(direction, normal, cos_i, ior, true)
            .unwrap_or_else(|| mirrored(direction, normal, cos_i, true)),
        weight: 1.0 - reflectance,
    };
    (reflection, refraction)
}

/// A rough dielectric interface between air (outside, index 1) and a body
/// of index `ior` (inside): GGX micro-facets of average slope
/// `roughness_deg` (α = tan m, as the layered BRDFs' lobes), each a smooth
/// Fresnel interface, with Smith shadowing (Walter et al. 2007).
///
/// Directions are in a local frame whose z axis is the OUTWARD normal, both
/// unit and pointing away from the surface: `wo` towards the previous
/// vertex of the path (the camera's side), `wi` towards where light comes
/// from; z < 0 is inside the body. A path from the camera carries radiance
/// divided by n² (the basic radiance that a smooth interface passes with
/// weight 1), so the transmission term is Walter's eq. 21 with the roles of
/// i and o exchanged, i = `wo`, o = `wi`; it obeys the generalised
/// reciprocity f(wo, wi)/n(wi)² = f(wi, wo)/n(wo)² (single scattering),
/// and its sampling weight is free of η.
///
/// Single scattering loses what the micro-facets shadow or send below
/// them (mostly total internal reflections inside): at 20° a lossless
/// stone would keep about 0.6 of the light. As the random-walk reference
/// of the layered BRDFs does (`brdf::reference`), each interaction's
/// value is divided by the single-scattering albedo E(|cos θo|) of its
/// side, tabulated when the interface is made, and sampling draws from the
/// lobe normalised by E (see [`RoughInterface::sample`]), so that the lost
/// light leaves with the single-scattering lobe's shape and a lossless
/// body keeps its energy (Kulla & Conty 2017 keep it so, in a lobe of its
/// own). The division is by the albedo of `wo`'s side and angle only: the
/// compensated interface is not reciprocal.
#[derive(Clone, Debug, PartialEq)]
pub struct RoughInterface {
    /// The micro-facet distribution (GGX with Smith G).
    lobe: Microfacet,
    /// Index of the body relative to the air around it (> 1).
    ior: f64,
    /// The single-scattering albedo E at |cos θo| = (j / (nodes − 1))²
    /// (closer where E changes fast, at grazing angles), from outside
    /// (`[0]`) and from inside (`[1]`).
    albedo: Box<[[f64; ALBEDO_NODES]; 2]>,
}

/// Nodes of [`RoughInterface`]'s albedo tables over |cos θo| in [0, 1].
const ALBEDO_NODES: usize = 64;
/// The most micro-normals [`RoughInterface::sample`] draws for one
/// sample before it gives up (a path lost): with probability (1 − E)^32,
/// below 10⁻⁴ where E is at least a quarter; at grazing angles, where E is
/// smaller, less of the loss is given back (at E = 0.05, 0.81 of it).
const MAX_DRAWS: u32 = 32;
/// Visible micro-normals per node: a side × side jittered grid.
const ALBEDO_GRID_SIDE: usize = 64;
/// The least albedo the compensation divides by: at grazing angles E
/// falls to 0, where dividing would give a few paths huge weights; below
/// it the light is compensated in part.
const LEAST_COMPENSATED_ALBEDO: f64 = 0.25;

/// The factor that gives back single scattering's loss where its albedo
/// is `albedo`: 1 / E, E taken as at least [`LEAST_COMPENSATED_ALBEDO`].
fn compensation_of(albedo: f64) -> f64 {
    1.0 / albedo.max(LEAST_COMPENSATED_ALBEDO)
}

/// A micro-normal drawn for `wo`: the normal on `wo`'s side, its cosine to
/// `wo` and the Fresnel reflectance there.
#[derive(Clone, Copy)]
struct DrawnNormal {
    m: DVec3,
    facing: DVec3,
    cos: f64,
    reflectance: f64,
}

/// A direction drawn by [`RoughInterface::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterfaceSample {
    /// The sampled direction `wi` (local frame, unit).
    pub wi: DVec3,
    /// f(wo, wi)·|cosθi| / pdf: E(wo) times the compensation of single
    /// scattering's loss, the same for every sample of `wo` (1 where E is
    /// at least 0.25).
    pub weight: f64,
    /// The density of `wi` per unit solid angle, Fresnel choice included.
    pub pdf: f64,
    /// True when `wi` is on the other side of the surface than `wo`.
    pub refracted: bool,
}

impl RoughInterface {
    /// The interface of a body of index `ior` (> 1: at 1 there is no
    /// interface and transmission is a delta) polished to an average
    /// micro-facet slope of `roughness_deg` (clamped as `Microfacet::new`
    /// does, to at least 0.01°).
    pub fn new(ior: f64, roughness_deg: f64) -> Self {
        debug_assert!(ior > 1.0, "a rough interface needs ior > 1, got {ior}");
        let mut interface = RoughInterface {
            lobe: Microfacet::new(MicrofacetModel::Ggx, roughness_deg),
            ior,
            albedo: Box::new([[1.0; ALBEDO_NODES]; 2]),
        };
        let grid = ALBEDO_GRID_SIDE as f64;
        for (side, sign) in [(0, 1.0), (1, -1.0)] {
            for node in 0..ALBEDO_NODES {
                let cos_o = (node as f64 / (ALBEDO_NODES - 1) as f64).powi(2).max(1e-4);
                let wo = DVec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, sign * cos_o);
                let mut jitter = Rng::new(node as u64, side as u64);
                let mut sum = 0.0;
                for a in 0..ALBEDO_GRID_SIDE {
                    for b in 0..ALBEDO_GRID_SIDE {
                        let [ja, jb, _] = jitter.next_3();
                        let u = [(a as f64 + ja) / grid, (b as f64 + jb) / grid];
                        let Some(drawn) = interface.draw_normal(wo, u) else {
                            continue;
                        };
                        let weight = |refracted| {
                            interface
                                .scatter(wo, &drawn, refracted)
                                .map_or(0.0, |s| s.weight)
                        };
                        sum += drawn.reflectance * weight(false)
                            + (1.0 - drawn.reflectance) * weight(true);
                    }
                }
                interface.albedo[side][node] = sum / (grid * grid);
            }
        }
        interface
    }

    /// The rough surface of a body of index `ior` polished to
    /// `roughness_deg`, or None where the interface is smooth (roughness 0)
    /// or absent (IOR 1: no interface to be rough).
    pub fn of_body(ior: f64, roughness_deg: f64) -> Option<Self> {
        (roughness_deg > 0.0 && ior > 1.0).then(|| Self::new(ior, roughness_deg))
    }

    /// The single-scattering albedo ∫ f |cos θi| dωi of the uncompensated
    /// interface for `wo` (interpolated in its table).
    pub fn single_scattering_albedo(&self, wo: DVec3) -> f64 {
        let table = &self.albedo[usize::from(wo.z < 0.0)];
        let x = wo.z.abs().min(1.0).sqrt() * (ALBEDO_NODES - 1) as f64;
        let node = (x as usize).min(ALBEDO_NODES - 2);
        let t = x - node as f64;
        table[node] * (1.0 - t) + table[node + 1] * t
    }

    /// The factor that compensates single scattering's loss for `wo`:
    /// 1 / E(|cos θo|) of its side, E taken as at least 0.25 (at grazing
    /// angles, where it falls to 0, the loss is given back in part).
    pub fn compensation(&self, wo: DVec3) -> f64 {
        compensation_of(self.single_scattering_albedo(wo))
    }

    /// The indices on the side of `wo` and on the other side.
    #[inline]
    fn indices(&self, wo_z: f64) -> (f64, f64) {
        if wo_z > 0.0 {
            (1.0, self.ior)
        } else {
            (self.ior, 1.0)
        }
    }

    /// The BSDF f(wo, wi) (per steradian, without the cosine) and the
    /// density with which [`RoughInterface::sample`] draws `wi`, both 0
    /// where the pair cannot occur.
    ///
    /// Reflection (same side): F(wo·h)·D(h)·G / (4 |cosθo| |cosθi|) with
    /// h ∝ wo + wi (Walter eq. 20). Transmission: with ηo, ηi the indices
    /// on the sides of wo and wi and the generalised half vector
    /// h ∝ −(ηo wo + ηi wi) (eq. 16),
    /// f = |wo·h| |wi·h| / (|cosθo| |cosθi|) · ηi² (1 − F) G D / (ηo wo·h + ηi wi·h)²
    /// (eq. 21, i = wo). The value returned is compensated (see the type);
    /// the density is f(wo, wi) |cos θi| / E(wo) of the uncompensated
    /// value, E from the table.
    pub fn eval_and_pdf(&self, wo: DVec3, wi: DVec3) -> (f64, f64) {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 || cos_i == 0.0 {
            return (0.0, 0.0);
        }
        let (eta_o, eta_i) = self.indices(cos_o);
        let same_side = cos_o * cos_i > 0.0;
        let sum = if same_side {
            wo + wi
        } else {
            -(eta_o * wo + eta_i * wi)
        };
        let h = sum.normalize_or_zero();
        // The micro-normal in the upper hemisphere, where D lives.
        let h = if h.z < 0.0 { -h } else { h };
        if h == DVec3::ZERO {
            return (0.0, 0.0);
        }
        let d = self.lobe.d(h);
        // G = 0 unless wo and wi each lie on the side of h that they lie
        // on of the surface (Walter eq. 7's χ⁺ factors).
        let g = self.lobe.g(wo, wi, h);
        if d == 0.0 || g == 0.0 {
            return (0.0, 0.0);
        }
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        let f = fresnel::dielectric(oh, eta_i / eta_o);
        let value = if same_side {
            f * d * g / (4.0 * cos_o.abs() * cos_i.abs())
        } else {
            let denominator = eta_o * oh + eta_i * ih;
            let jacobian = eta_i * eta_i * ih.abs() / (denominator * denominator);
            (1.0 - f) * d * g * oh.abs() * jacobian / (cos_o.abs() * cos_i.abs())
        };
        // Sampling keeps a draw with probability f |cos θi| / its density:
        // what it keeps has the lobe's own shape, normalised by E.
        let albedo = self.single_scattering_albedo(wo);
        if albedo <= 0.0 {
            return (0.0, 0.0);
        }
        (
            value * compensation_of(albedo),
            value * cos_i.abs() / albedo,
        )
    }

    /// Draws `wi` for `wo` from `u` in [0, 1)³ with density
    /// f(wo, wi) |cos θi| / E(wo), the single-scattering lobe normalised: a
    /// micro-normal m among those visible from `wo` (density D_wo(m),
    /// Heitz 2018) from `u[0]`, `u[1]`, reflection about m with probability
    /// F(wo·m) (1 under total internal reflection) by `u[2]`, else
    /// refraction through m by Snell's law, kept with probability
    /// G / G1(wo) (what the micro-facets pass on; the rest of `u[2]` past
    /// the Fresnel choice decides), else drawn again from numbers derived
    /// from `u` (at most 32 times; then None, a path lost).
    /// Every sample so weighs the same, E(wo) times the compensation (1
    /// where E is at least 0.25): single scattering's loss is given back
    /// without weights that grow along a path.
    pub fn sample(&self, wo: DVec3, u: [f64; 3]) -> Option<InterfaceSample> {
        let albedo = self.single_scattering_albedo(wo);
        if albedo <= 0.0 {
            return None;
        }
        // Further numbers, when a draw is refused, from `u` itself (made
        // at the first refusal: most first draws are kept).
        let mut more: Option<Rng> = None;
        let mut numbers = u;
        for _ in 0..MAX_DRAWS {
            let drawn = self.draw_normal(wo, [numbers[0], numbers[1]]);
            if let Some(drawn) = drawn {
                let f = drawn.reflectance;
                let refracted = numbers[2] >= f;
                // The Fresnel number past the choice: a fresh uniform.
                let keep = if refracted {
                    (numbers[2] - f) / (1.0 - f)
                } else {
                    numbers[2] / f
                };
                if let Some(sample) = self.scatter(wo, &drawn, refracted) {
                    if keep < sample.weight {
                        return Some(InterfaceSample {
                            weight: albedo * compensation_of(albedo),
                            pdf: sample.weight * sample.pdf / albedo,
                            ..sample
                        });
                    }
                }
            }
            numbers = more
                .get_or_insert_with(|| Rng::keyed_by(0x6a09_e667_f3bc_c909, &u))
                .next_3();
        }
        None
    }

    /// The micro-normal m visible from `wo` drawn from `u`, on `wo`'s
    /// side, with the Fresnel reflectance there; None when it faces away
    /// from `wo`.
    fn draw_normal(&self, wo: DVec3, u: [f64; 2]) -> Option<DrawnNormal> {
        if wo.z == 0.0 {
            return None;
        }
        let (eta_o, eta_i) = self.indices(wo.z);
        let m = self.visible_normal(wo, u);
        // The micro-normal on wo's side and the cosine to it.
        let facing = m * wo.z.signum();
        let cos = wo.dot(facing);
        if m.z <= 0.0 || cos <= 0.0 {
            return None;
        }
        let eta = eta_i / eta_o;
        let snell = Snell::at(cos, eta);
        let reflectance = fresnel::dielectric_from_snell(cos, snell, eta);
        Some(DrawnNormal {
            m,
            facing,
            cos,
            reflectance,
        })
    }

    /// A micro-normal (upper hemisphere) of the distribution of normals
    /// visible from `wo` (from either side), drawn from `u`: GGX's by
    /// Heitz 2018, density D_wo(m) = G1(wo) |wo·m| D(m) / |cos θo|.
    fn visible_normal(&self, wo: DVec3, u: [f64; 2]) -> DVec3 {
        ggx_visible_normal(self.lobe.alpha, wo, u)
    }

    /// The uncompensated sample for `wo` that reflects about the drawn
    /// normal, or refracts through it when `refracted`; None when the new
    /// direction falls on the wrong side of the surface (a path the
    /// model's G would give 0).
    fn scatter(&self, wo: DVec3, drawn: &DrawnNormal, refracted: bool) -> Option<InterfaceSample> {
        let side = wo.z.signum();
        let (eta_o, eta_i) = self.indices(wo.z);
        let DrawnNormal {
            m,
            facing,
            cos,
            reflectance: f,
        } = *drawn;
        let wi = if refracted {
            refract(wo, facing, eta_i / eta_o)?
        } else {
            reflect(wo, facing)
        };
        if (wi.z * side > 0.0) == refracted || wi.z == 0.0 {
            return None;
        }
        let g = self.lobe.g(wo, wi, m);
        if g == 0.0 {
            return None;
        }
        // The density of the visible normal, G1(wo) |wo·m| D(m) / |cos θo|.
        let g1 = self.lobe.smith_g1_of_cosine(wo.z.abs());
        let visible = g1 * cos * self.lobe.d(m) / wo.z.abs();
        let pdf = if refracted {
            let ih = wi.dot(m);
            let denominator = eta_o * wo.dot(m) + eta_i * ih;
            (1.0 - f) * visible * eta_i * eta_i * ih.abs() / (denominator * denominator)
        } else {
            f * visible / (4.0 * cos)
        };
        Some(InterfaceSample {
            wi,
            weight: g / g1,
            pdf,
            refracted,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_split_crossing_takes_both_ways_of_the_fresnel_draw_with_its_odds() {
        // The split's branches are the draw's two outcomes, weighted by
        // the probabilities the draw gives them: the same expectation.
        let ior = 1.53;
        let normal = DVec3::new(-0.3, 0.1, 1.0).normalize();
        let (t, _) = normal.any_orthonormal_pair();
        for theta_deg in [0.0f64, 30.0, 60.0, 80.0, 89.0] {
            let (sin, cos) = theta_deg.to_radians().sin_cos();
            let towards = -(normal * cos + t * sin);
            let (reflection, refraction) = split_smooth_interface(towards, normal, ior);
            assert!((reflection.weight + refraction.weight - 1.0).abs() < 1e-15);
            // The draw reflects for u below F, and refracts above.
            let reflectance = fresnel::dielectric(cos, ior);
            assert!((reflection.weight - reflectance).abs() < 1e-12);
            for (branch, u) in [(reflection, 0.0), (refraction, 1.0 - 1e-12)] {
                let drawn = cross_smooth_interface(towards, normal, ior, u);
                assert_eq!(branch.crossing.refracted, drawn.refracted);
                assert!((branch.crossing.direction - drawn.direction).length() < 1e-12);
            }
            // The fraction of a fine grid of u that reflects is F.
            let reflected = (0..100_000)
                .filter(|i| {
                    let u = (f64::from(*i) + 0.5) / 100_000.0;
                    !cross_smooth_interface(towards, normal, ior, u).refracted
                })
                .count();
            assert!((reflected as f64 / 100_000.0 - reflectance).abs() < 1e-4);
            assert!((reflected as f64 / 100_000.0 - reflection.weight).abs() < 1e-4);
            if theta_deg == 0.0 {
                // Normal incidence: ((n − 1)/(n + 1))².
                let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
                assert!((reflection.weight - f0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_smooth_interface_refracts_by_snell_and_reflects_by_fresnel() {
        let ior = 1.54;
        let normal = DVec3::new(0.2, -0.1, 1.0).normalize();
        for theta_deg in [0.0f64, 20.0, 45.0, 70.0, 85.0] {
            let (sin, cos) = theta_deg.to_radians().sin_cos();
            let (t, _) = normal.any_orthonormal_pair();
            let towards = -(normal * cos + t * sin); // arriving from outside
                                                     // u = 1 − ε always refracts (F < 1 from outside): Snell's law,
                                                     // n₁ sinθ₁ = n₂ sinθ₂, in the plane of incidence.
            let inward = cross_smooth_interface(towards, normal, ior, 1.0 - 1e-12);
            assert!(inward.refracted && inward.from_outside);
            let sin_t = inward.direction.cross(-normal).length();
            assert!(
                (sin - ior * sin_t).abs() < 1e-12,
                "θ {theta_deg}: {sin} vs {}",
                ior * sin_t
            );
            assert!(inward.direction.dot(normal) < 0.0, "goes in");
            // Reflection frequency over u ∈ [0, 1) is F(θ) (eq. 3.1).
            let n = 10_000;
            let reflected = (0..n)
                .filter(|i| {
                    let u = (f64::from(*i) + 0.5) / f64::from(n);
                    !cross_smooth_interface(towards, normal, ior, u).refracted
                })
                .count();
            let f = fresnel::dielectric(cos, ior);
            assert!(
                (reflected as f64 / f64::from(n) - f).abs() < 2e-4,
                "θ {theta_deg}"
            );
            // Back out along the reversed refracted ray: the same angle.
            let out = cross_smooth_interface(-inward.direction, normal, ior, 1.0 - 1e-12);
            assert!(out.refracted && !out.from_outside);
            assert!((out.direction + towards).length() < 1e-12, "reversible");
        }
        // Beyond the critical angle, inside: always reflected, mirror-like.
        let (t, _) = normal.any_orthonormal_pair();
        let grazing = (t * 0.8 + normal * 0.6).normalize(); // 53° from the normal
        let inside = cross_smooth_interface(grazing, normal, ior, 0.999);
        assert!(!inside.refracted && !inside.from_outside);
        let mirrored = grazing - 2.0 * grazing.dot(normal) * normal;
        assert!((inside.direction - mirrored).length() < 1e-12);
    }
}
