//! χ² goodness of fit of every lobe's importance sampling and of the whole
//! stack's against the pdfs they claim (pbrt-v4 / Mitsuba 3 methodology:
//! histogram over (cosθ, φ), sparse cells pooled, 1 % significance with
//! Šidák correction over all tests of this file).

mod common;

use common::chi2::{chi2_directions, sidak, Chi2Outcome};
use glam::DVec3;
use lapidary::brdf::{LayeredBrdf, Microfacet, MicrofacetModel};
use lapidary::recipe::library::builtin_material_names;
use lapidary::recipe::load_material;
use lapidary::sampling::direction_from_degrees;

/// Lobe tests: 3 models × 3 roughnesses × 2 view angles; stack tests: every
/// library material at 2 view angles, as sampled at a camera vertex and
/// after a bounce.
fn significance() -> f64 {
    let n_tests = 3 * 3 * 2 + builtin_material_names().count() * 2 * 2 + 1;
    sidak(0.01, n_tests)
}

#[test]
fn microfacet_reflection_sampling_matches_its_pdf() {
    for model in [
        MicrofacetModel::Blinn,
        MicrofacetModel::Beckmann,
        MicrofacetModel::Ggx,
    ] {
        for roughness in [3.0, 15.0, 40.0] {
            let lobe = Microfacet::new(model, roughness);
            for theta in [10.0, 70.0] {
                let wo = direction_from_degrees(theta, 30.0);
                let outcome = chi2_directions(
                    |u| lobe.sample_reflection(wo, u[0], u[1]),
                    |wi| lobe.reflection_pdf(wi, wo),
                    200_000,
                    16,
                    32,
                    7,
                );
                assert!(
                    outcome.passes(significance()),
                    "{model:?} m={roughness} θo={theta}: {outcome}"
                );
            }
        }
    }
}

#[test]
fn cosine_sampling_of_diffuse_bases_matches_its_pdf() {
    let outcome = chi2_directions(
        |u| Some(lapidary::sampling::cosine_hemisphere(u[0], u[1])),
        lapidary::sampling::cosine_hemisphere_pdf,
        400_000,
        20,
        40,
        3,
    );
    assert!(outcome.passes(significance()), "{outcome}");
}

/// Runs `test(brdf, wo)`, a χ² test of one sampler against its density,
/// for every library material at two view angles, and asserts each passes.
fn for_every_library_material(test: impl Fn(&LayeredBrdf, DVec3) -> Chi2Outcome) {
    for name in builtin_material_names() {
        let brdf = load_material(name).unwrap();
        for theta in [20.0, 65.0] {
            let outcome = test(&brdf, direction_from_degrees(theta, 0.0));
            assert!(
                outcome.passes(significance()),
                "{name} θo={theta}: {outcome}"
            );
        }
    }
}

#[test]
fn layered_stack_sampling_matches_its_pdf_for_every_library_material() {
    for_every_library_material(|brdf, wo| {
        chi2_directions(
            |u| brdf.sample(wo, u).map(|s| s.wi),
            |wi| brdf.pdf(wi, wo),
            200_000,
            16,
            32,
            11,
        )
    });
}

/// After a bounce a coat's own lobe is sampled at least 75 % of the time
/// (`LayeredBrdf::at_after_bounce`): the prepared sampler still draws what
/// its density says, for every library material (the closed-form coat and
/// the general stack alike).
#[test]
fn sampling_after_a_bounce_matches_its_pdf_for_every_library_material() {
    for_every_library_material(|brdf, wo| {
        let at = brdf.at_after_bounce(wo);
        chi2_directions(
            |u| at.sample(u).map(|s| s.wi),
            |wi| at.eval_and_pdf(wi).1,
            100_000,
            16,
            32,
            13,
        )
    });
}
