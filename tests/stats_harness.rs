//! Tests of the statistical harness in `tests/common` itself: it must accept
//! correct samplers and reject wrong ones, otherwise the sampling tests built
//! on it prove nothing.

mod common;

use std::f64::consts::{FRAC_1_PI, PI, TAU};

use common::chi2::{
    chi2_directions, chi2_directions_with, integrate_pdf_sphere, sidak, Chi2Options, Chi2Outcome,
    SplitMix64,
};
use common::ks::{kolmogorov_sf, ks_test};
use glam::DVec3;

const N: usize = 1_000_000;

/// Direction from `cosθ` and `φ`.
fn spherical(cos_theta: f64, phi: f64) -> DVec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    DVec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Cosine-weighted hemisphere (Malley's method in polar form).
fn sample_cosine(u: [f64; 3]) -> Option<DVec3> {
    Some(spherical((1.0 - u[0]).sqrt(), TAU * u[1]))
}

fn pdf_cosine(d: DVec3) -> f64 {
    d.z.max(0.0) * FRAC_1_PI
}

fn pdf_uniform_hemisphere(d: DVec3) -> f64 {
    if d.z > 0.0 {
        0.5 / PI
    } else {
        0.0
    }
}

/// Normalized Phong-like lobe around +z, `(e+1)/(2π) cos^e θ`.
fn pdf_phong(e: f64) -> impl Fn(DVec3) -> f64 {
    move |d: DVec3| {
        if d.z > 0.0 {
            (e + 1.0) / TAU * d.z.powf(e)
        } else {
            0.0
        }
    }
}

/// Exact sampler of [`pdf_phong`]: `cosθ = u^(1/(e+1))`.
fn sample_phong(e: f64) -> impl FnMut([f64; 3]) -> Option<DVec3> {
    move |u: [f64; 3]| Some(spherical((1.0 - u[0]).powf(1.0 / (e + 1.0)), TAU * u[1]))
}

fn check(outcome: &Chi2Outcome, pass: bool, significance: f64) {
    eprintln!("{outcome}");
    assert_eq!(
        outcome.passes(significance),
        pass,
        "expected the test to {} at {significance}: {outcome}",
        if pass { "pass" } else { "fail" }
    );
}

#[test]
fn cosine_sampler_matches_cosine_pdf() {
    let out = chi2_directions(sample_cosine, pdf_cosine, N, 10, 20, 1);
    check(&out, true, 0.01);
    assert!(out.failure.is_none());
    assert_eq!((out.samples_taken, out.samples_failed), (N, 0));
    // Lower hemisphere (100 cells) has zero density and is skipped; the upper
    // 100 cells all expect 10^4 samples or more except the row at the horizon.
    assert!(out.dof >= 90, "dof {}", out.dof);
    assert!(
        (out.pdf_integral - 1.0).abs() < 1e-10,
        "{}",
        out.pdf_integral
    );
}

#[test]
fn cosine_sampler_rejected_against_uniform_pdf() {
    let out = chi2_directions(sample_cosine, pdf_uniform_hemisphere, N, 10, 20, 2);
    check(&out, false, 1e-6);
    assert!(
        out.failure.is_none(),
        "a statistical, not an immediate, failure"
    );
    assert!(out.statistic > 1000.0);
}

#[test]
fn peaky_phong_lobe_passes() {
    let e = 200.0;
    // Fine cosθ bins (width 0.01, about twice the lobe's 1/e scale) so the
    // histogram resolves the lobe's shape, not only its φ symmetry.
    let out = chi2_directions(sample_phong(e), pdf_phong(e), N, 200, 20, 3);
    check(&out, true, 0.01);
    assert!(out.dof >= 100, "dof {}", out.dof);
    assert!(
        (out.pdf_integral - 1.0).abs() < 1e-9,
        "{}",
        out.pdf_integral
    );
}

#[test]
fn phong_lobe_with_wrong_exponent_fails() {
    // A 5% error in the exponent of the sampler must be detected.
    let out = chi2_directions(sample_phong(190.0), pdf_phong(200.0), N, 200, 20, 4);
    check(&out, false, 1e-6);
}

#[test]
fn leaking_into_lower_hemisphere_fails_immediately() {
    // Mirror 1% (then 0.01%, about ten samples) of the samples below the
    // horizon, where the density is zero.
    for rate in [1e-2, 1e-4] {
        let leaky = |u: [f64; 3]| {
            let d = sample_cosine(u)?;
            Some(if u[2] < rate { -d } else { d })
        };
        let out = chi2_directions(leaky, pdf_cosine, 100_000, 10, 20, 5);
        check(&out, false, 1e-6);
        assert_eq!(out.p_value, 0.0);
        let why = out.failure.as_deref().expect("an immediate failure");
        assert!(why.contains("zero density"), "{why}");
        assert!(
            out.worst_cell.unwrap().cos_bin < 5,
            "the cell is below the horizon"
        );
    }
}

#[test]
fn thin_tail_of_a_lobe_is_not_impossible() {
    // With this seed one of 10^6 Phong samples lands in a tail cell that
    // expects 0.0023 samples. Calling every cell below 1e-8·n impossible
    // would fail this correct sampler (about 10% of seeds do); the
    // false-alarm budget keeps such cells in the χ² test instead.
    let e = 200.0;
    let strict = Chi2Options {
        impossible_budget: f64::INFINITY,
        ..Chi2Options::default()
    };
    let out = chi2_directions_with(sample_phong(e), pdf_phong(e), N, 200, 20, 103, &strict);
    check(&out, false, 0.01);
    assert!(out.failure.is_some());
    let out = chi2_directions(sample_phong(e), pdf_phong(e), N, 200, 20, 103);
    check(&out, true, 0.01);
}

#[test]
fn failed_samples_consistent_with_missing_mass() {
    // The sampler gives up 10% of the time and its density says so.
    let lossy = |u: [f64; 3]| if u[2] < 0.1 { None } else { sample_cosine(u) };
    let out = chi2_directions(lossy, |d| 0.9 * pdf_cosine(d), N, 10, 20, 6);
    check(&out, true, 0.01);
    assert!(
        (out.pdf_integral - 0.9).abs() < 1e-10,
        "{}",
        out.pdf_integral
    );
    let failed = out.samples_failed as f64 / N as f64;
    assert!((failed - 0.1).abs() < 0.002, "failed fraction {failed}");
}

#[test]
fn failed_samples_inconsistent_with_normalized_pdf_fail() {
    // Same sampler, but its density claims it never fails: every cell is 10%
    // short and the failed samples have no expected mass.
    let lossy = |u: [f64; 3]| if u[2] < 0.1 { None } else { sample_cosine(u) };
    let out = chi2_directions(lossy, pdf_cosine, N, 10, 20, 7);
    check(&out, false, 1e-6);
}

#[test]
fn outcome_is_reproducible_for_a_seed() {
    let a = chi2_directions(sample_cosine, pdf_cosine, 100_000, 10, 20, 42);
    let b = chi2_directions(sample_cosine, pdf_cosine, 100_000, 10, 20, 42);
    let c = chi2_directions(sample_cosine, pdf_cosine, 100_000, 10, 20, 43);
    assert_eq!(a.statistic, b.statistic);
    assert_eq!(a.p_value, b.p_value);
    assert_ne!(a.statistic, c.statistic);
}

#[test]
fn p_values_of_a_correct_sampler_are_uniform() {
    // Under the null hypothesis p-values are U(0, 1): check 40 seeds with KS.
    let mut ps: Vec<f64> = (0..40)
        .map(|seed| chi2_directions(sample_cosine, pdf_cosine, 20_000, 4, 8, 1000 + seed).p_value)
        .collect();
    let ks = ks_test(&mut ps, |x| x.clamp(0.0, 1.0));
    assert!(ks.passes(0.01), "{ks:?}, p-values {ps:?}");
}

#[test]
fn pdf_integrals_are_accurate() {
    assert!((integrate_pdf_sphere(pdf_cosine, 10, 20) - 1.0).abs() < 1e-12);
    assert!((integrate_pdf_sphere(|_| 0.25 / PI, 3, 5) - 1.0).abs() < 1e-12);
    for e in [1.0, 20.0, 200.0, 2000.0] {
        let total = integrate_pdf_sphere(pdf_phong(e), 10, 20);
        eprintln!(
            "Phong e = {e}, 10 x 20 cells: integral - 1 = {:e}",
            total - 1.0
        );
        assert!((total - 1.0).abs() < 1e-9, "Phong e = {e}: {total}");
    }
    // Odd cos_bins put the horizon discontinuity inside a cell; the
    // adaptive refinement still gets it close.
    let total = integrate_pdf_sphere(pdf_cosine, 9, 20);
    eprintln!(
        "cosine lobe, 9 x 20 cells: integral - 1 = {:e}",
        total - 1.0
    );
    assert!((total - 1.0).abs() < 1e-8, "{total}");
    // A cap whose edge (z = 0.29) is never a panel edge nor midpoint.
    let cap = |d: DVec3| if d.z > 0.29 { 1.0 / (TAU * 0.71) } else { 0.0 };
    let total = integrate_pdf_sphere(cap, 10, 20);
    eprintln!(
        "cap z > 0.29, 10 x 20 cells: integral - 1 = {:e}",
        total - 1.0
    );
    assert!((total - 1.0).abs() < 1e-6, "{total}");
}

#[test]
fn sidak_correction() {
    assert_eq!(sidak(0.01, 1), 0.01);
    let s = sidak(0.01, 10);
    assert!((s - 0.001_004_53).abs() < 1e-8, "{s}");
    assert!((1.0 - (1.0 - s).powi(10) - 0.01).abs() < 1e-15);
}

#[test]
fn ks_uniform_samples() {
    let mut rng = SplitMix64::new(9);
    let mut u: Vec<f64> = (0..100_000).map(|_| rng.next_f64()).collect();
    let ok = ks_test(&mut u, |x| x.clamp(0.0, 1.0));
    eprintln!("uniform vs x: {ok:?}");
    assert!(ok.passes(0.01), "{ok:?}");
    let bad = ks_test(&mut u, |x| x.clamp(0.0, 1.0).powi(2));
    eprintln!("uniform vs x^2: {bad:?}");
    assert!(!bad.passes(1e-6), "{bad:?}");
    assert!((bad.statistic - 0.25).abs() < 0.01, "sup |x − x²| = 1/4");
}

#[test]
fn ks_phong_cosines() {
    // cosθ of the Phong lobe has CDF c^(e+1) on [0, 1].
    let e: f64 = 200.0;
    let mut rng = SplitMix64::new(10);
    let mut sampler = sample_phong(e);
    let mut c: Vec<f64> = (0..100_000)
        .map(|_| sampler([rng.next_f64(), rng.next_f64(), 0.0]).unwrap().z)
        .collect();
    assert!(ks_test(&mut c, |x| x.clamp(0.0, 1.0).powf(e + 1.0)).passes(0.01));
    // A 5% error in the exponent: sup |c^(e+1) − c^(0.95(e+1))| ≈ 0.018.
    let wrong = ks_test(&mut c, |x| x.clamp(0.0, 1.0).powf(0.95 * (e + 1.0)));
    assert!(!wrong.passes(1e-6), "{wrong:?}");
}

#[test]
fn kolmogorov_distribution_values() {
    // Classical critical values: P(K > 1.3581) = 0.05, P(K > 1.6276) = 0.01.
    assert!((kolmogorov_sf(1.358_1) - 0.05).abs() < 1e-4);
    assert!((kolmogorov_sf(1.627_6) - 0.01).abs() < 1e-4);
    assert!((kolmogorov_sf(0.828) - 0.5).abs() < 1e-3);
    // Both series agree where the implementation switches between them.
    assert!((kolmogorov_sf(1.18 - 1e-12) - kolmogorov_sf(1.18 + 1e-12)).abs() < 1e-11);
    assert_eq!(kolmogorov_sf(0.0), 1.0);
    assert!(kolmogorov_sf(10.0) < 1e-80);
    // NaN input fails the test outright.
    let ks = ks_test(&mut [0.1, f64::NAN, 0.5], |x| x);
    assert_eq!(ks.p_value, 0.0);
}
