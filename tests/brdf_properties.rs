//! proptest: for random valid parameters and directions the BRDF, its
//! samples and its pdf are finite and never negative; the reciprocal parts
//! of the model are reciprocal.

use glam::DVec3;
use lapidary::brdf::{Base, Interface, LayeredBrdf, Microfacet, MicrofacetModel, Rgb};
use proptest::prelude::*;

fn unit_upper(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

fn model() -> impl Strategy<Value = MicrofacetModel> {
    prop_oneof![
        Just(MicrofacetModel::Blinn),
        Just(MicrofacetModel::Beckmann),
        Just(MicrofacetModel::Ggx)
    ]
}

fn layer() -> impl Strategy<Value = (f64, f64, f64, f64)> {
    (1.0f64..3.0, 0.0f64..89.0, 0.0f64..5.0, 0.0f64..5.0)
}

fn base() -> impl Strategy<Value = (u8, f64, f64, f64, f64)> {
    (0u8..3, 0.0f64..1.0, 0.0f64..1.5, 0.05f64..5.0, 0.0f64..89.0)
}

fn build(
    model: MicrofacetModel,
    layers: &[(f64, f64, f64, f64)],
    b: (u8, f64, f64, f64, f64),
) -> LayeredBrdf {
    let mut interfaces = Vec::new();
    let (mut ior_above, mut m_above) = (1.0, 0.0);
    for &(ior, m, d, a) in layers {
        interfaces.push(Interface {
            ior_below: ior,
            eta: ior / ior_above,
            lobe: Microfacet::new(model, m + m_above),
            own_lobe: Microfacet::new(model, m),
            thickness: d,
            absorption_rgb: Rgb::new(a, a * 0.5, 0.0),
        });
        ior_above = ior;
        m_above += m;
    }
    let base = match b.0 {
        0 => Base::Diffuse {
            colour: Rgb::splat(b.1),
            oren_nayar_sigma_rad: b.2,
        },
        1 => Base::Conductor {
            n_relative: Rgb::splat(b.3) / ior_above,
            k_relative: Rgb::splat(b.3) / ior_above,
            lobe: Microfacet::new(model, b.4 + m_above),
            own_lobe: Microfacet::new(model, b.4),
        },
        _ => Base::Black,
    };
    LayeredBrdf::new("random", model, interfaces, base)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn eval_sample_and_pdf_are_finite_and_non_negative(
        model in model(),
        layers in prop::collection::vec(layer(), 0..4),
        b in base(),
        ti in 0.0f64..std::f64::consts::FRAC_PI_2, pi in 0.0f64..std::f64::consts::TAU, to in 0.0f64..std::f64::consts::FRAC_PI_2, po in 0.0f64..std::f64::consts::TAU,
        u in prop::array::uniform3(0.0f64..1.0),
    ) {
        let brdf = build(model, &layers, b);
        let (wi, wo) = (unit_upper(ti, pi), unit_upper(to, po));
        let f = brdf.eval(wi, wo);
        prop_assert!(f.is_finite() && f.min_element() >= 0.0, "f = {:?}", f);
        let pdf = brdf.pdf(wi, wo);
        prop_assert!(pdf.is_finite() && pdf >= 0.0, "pdf = {}", pdf);
        if let Some(s) = brdf.sample(wo, u) {
            let w = s.weight();
            prop_assert!(w.is_finite() && w.min_element() >= 0.0, "weight = {:?}", w);
            prop_assert!(s.wi.z > 0.0 && (s.wi.length() - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn bare_lobes_and_diffuse_bases_are_reciprocal(
        model in model(),
        b in base(),
        ti in 0.0f64..1.5, pi in 0.0f64..std::f64::consts::TAU, to in 0.0f64..1.5, po in 0.0f64..std::f64::consts::TAU,
    ) {
        let brdf = build(model, &[], b);
        let (wi, wo) = (unit_upper(ti, pi), unit_upper(to, po));
        let (a, c) = (brdf.eval(wi, wo), brdf.eval(wo, wi));
        prop_assert!((a - c).abs().max_element() <= 1e-9 * (1.0 + a.max_element()), "{:?} vs {:?}", a, c);
    }
}
