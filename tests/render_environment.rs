//! Environment lighting: the piecewise-constant distributions it samples
//! with, its sampling densities, its integrals against exact texel sums, the
//! rotation convention, and loading `.hdr` / `.exr` files (good and bad).

mod common;

use std::f64::consts::{PI, TAU};

use glam::DVec3;
use lapidary::brdf::Rgb;
use lapidary::render::distribution::{AliasTable, DistributionError};
use lapidary::render::environment::{
    luminance, Environment, EnvironmentError, EnvironmentMap, STUDIO_HEIGHT, STUDIO_WIDTH,
};
use lapidary::sampling::Rng;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Unit vector from polar angle θ (from +z) and azimuth φ (from +x), in
/// degrees; written here, independently of the library.
fn dir_deg(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// Six bins with a zero bin, a dominant bin and a 1:50 range.
const WEIGHTS: [f64; 6] = [1.0, 2.0, 0.0, 25.0, 0.5, 7.0];

#[test]
fn alias_table_histogram_matches_weights_chi_square() {
    let table = AliasTable::new(&WEIGHTS).unwrap();
    let total: f64 = WEIGHTS.iter().sum();
    // Each bin split in 4, so uniformity inside a bin is tested too.
    let sub = 4;
    let mut counts = vec![0u64; sub * WEIGHTS.len()];
    let n = 400_000;
    let mut rng = Rng::new(7, 0);
    for _ in 0..n {
        let (x, pdf, bin) = table.sample(rng.next_f64());
        assert!((0.0..1.0).contains(&x) && pdf > 0.0 && table.bin(x) == bin);
        counts[(x * (sub * WEIGHTS.len()) as f64) as usize] += 1;
    }
    let mut chi2 = 0.0;
    let mut dof = 0;
    for (k, &observed) in counts.iter().enumerate() {
        let w = WEIGHTS[k / sub];
        if w == 0.0 {
            assert_eq!(observed, 0, "sample in the zero-weight bin");
            continue;
        }
        let expected = n as f64 * w / total / sub as f64;
        chi2 += (observed as f64 - expected).powi(2) / expected;
        dof += 1;
    }
    let p = ChiSquared::new((dof - 1) as f64).unwrap().sf(chi2);
    assert!(p > 1e-4, "chi2 = {chi2} with {} dof, p = {p}", dof - 1);
}

#[test]
fn alias_table_sample_pdf_agree_and_integrate_to_one() {
    let table = AliasTable::new(&WEIGHTS).unwrap();
    let mean: f64 = WEIGHTS.iter().sum::<f64>() / WEIGHTS.len() as f64;
    let mut integral = 0.0;
    for (i, w) in WEIGHTS.iter().enumerate() {
        let centre = (i as f64 + 0.5) / WEIGHTS.len() as f64;
        assert!((table.pdf(centre) - w / mean).abs() < 1e-12 * (w / mean).max(1.0));
        integral += table.probability(i);
    }
    assert!((integral - 1.0).abs() < 1e-15, "Σ p = {integral}");
    assert_eq!(table.pdf(1.0), 0.0);
    assert_eq!(table.pdf(-1e-9), 0.0);
    // sample() reports the pdf of the point it returns, including u at the
    // ends of [0, 1) and outside it.
    let mut rng = Rng::new(3, 1);
    let mut us: Vec<f64> = (0..20_000).map(|_| rng.next_f64()).collect();
    us.extend([0.0, 1.0_f64.next_down(), 1.0, -0.5, f64::NAN, 0.5]);
    for u in us {
        let (x, pdf, bin) = table.sample(u);
        assert_eq!(pdf, table.pdf(x), "u = {u} → x = {x}");
        assert_eq!(table.bin(x), bin);
        assert!(pdf > 0.0);
    }
}

#[test]
fn alias_table_samples_continuously_within_a_bin() {
    // Weights 1, 3 on [0, ½), [½, 1): the probabilities are ¼ and ¾, and
    // a fine grid of u spreads evenly over each half.
    let table = AliasTable::new(&[1.0, 3.0]).unwrap();
    assert_eq!(table.probability(0), 0.25);
    assert_eq!(table.probability(1), 0.75);
    let steps = 4096;
    let mut xs: Vec<f64> = (0..steps)
        .map(|k| table.sample((k as f64 + 0.5) / steps as f64).0)
        .collect();
    xs.sort_by(f64::total_cmp);
    let (low, high) = xs.split_at(steps / 4);
    for (k, x) in low.iter().enumerate() {
        let want = 0.5 * (k as f64 + 0.5) / low.len() as f64;
        assert!((x - want).abs() < 1e-3, "{x} vs {want}");
    }
    for (k, x) in high.iter().enumerate() {
        let want = 0.5 + 0.5 * (k as f64 + 0.5) / high.len() as f64;
        assert!((x - want).abs() < 1e-3, "{x} vs {want}");
    }
}

#[test]
fn alias_table_refuses_bad_weights() {
    assert_eq!(AliasTable::new(&[0.0; 6]), Err(DistributionError::AllZero));
    let mut weights = [1.0; 6];
    weights[4] = f64::NAN;
    let err = AliasTable::new(&weights).unwrap_err();
    assert!(
        matches!(err, DistributionError::BadWeight { index: 4, .. }),
        "{err}"
    );
    weights[4] = f64::INFINITY;
    assert!(AliasTable::new(&weights).is_err());
    weights[4] = -1.0;
    let msg = AliasTable::new(&weights).unwrap_err().to_string();
    assert!(msg.contains("weight 4") && msg.contains("≥ 0"), "{msg}");
    assert!(matches!(
        AliasTable::new(&[]),
        Err(DistributionError::BadLength { len: 0 })
    ));
    assert_eq!(
        AliasTable::new(&[f64::MAX, f64::MAX]),
        Err(DistributionError::AllZero)
    );
}

/// An 8 × 4 hand-made map: a dim sky, a black texel, a bright texel
/// (col 2, row 1) and a coloured floor, rotated by 30°.
fn small_map(rotation_deg: f64) -> EnvironmentMap {
    let (w, h) = (8, 4);
    let mut texels = Vec::new();
    for row in 0..h {
        for col in 0..w {
            let base = match row {
                0 => Rgb::new(0.3, 0.4, 0.6),
                1 => Rgb::splat(0.2 + 0.05 * col as f64),
                2 => Rgb::new(0.05, 0.1, 0.02),
                _ => Rgb::new(0.01, 0.01, 0.01),
            };
            texels.push(base);
        }
    }
    texels[w + 2] = Rgb::new(40.0, 30.0, 20.0);
    texels[2 * w + 5] = Rgb::ZERO;
    EnvironmentMap::new(w, h, texels, rotation_deg).unwrap()
}

#[test]
fn sample_returns_radiance_and_pdf_of_its_direction() {
    let envs = [
        Environment::studio(1.0, 20.0),
        Environment::Map(small_map(30.0)),
        Environment::Map(sun_map(-70.0)),
        Environment::constant(Rgb::new(0.5, 0.6, 0.7)),
    ];
    for env in &envs {
        let mut rng = Rng::new(11, 2);
        for i in 0..10_000 {
            let u = [rng.next_f64(), rng.next_f64()];
            // Every other sample from a part, with the part's density.
            let part = i / 2 % env.parts();
            if i % 2 == 1 {
                let s = env.sample_part(part, u).expect("a lit part always samples");
                assert_eq!(s.radiance, env.radiance(s.direction));
                assert_eq!(s.pdf, env.part_pdf(s.direction));
                continue;
            }
            let s = env.sample(u).expect("a lit environment always samples");
            assert!((s.direction.length() - 1.0).abs() < 1e-12);
            // The sample's radiance and density come from the texel it was
            // drawn in; the direction converted back must find the same
            // texel and so the same density, to the bit (a direction within
            // rounding of a texel edge, probability ~1e-13, could differ).
            assert_eq!(s.radiance, env.radiance(s.direction));
            assert_eq!(s.pdf, env.pdf(s.direction));
            assert!(s.pdf > 0.0 && s.pdf.is_finite());
        }
    }
}

/// χ² of a map's samples (of part `part`, or of the whole map for None)
/// against their pdf: bins regular in (θ, φ), each texel of the `w × h`
/// map split `sub × sub`, edges turned with the map. The density is
/// constant per solid angle on a texel, so a bin's probability is exactly
/// pdf(midpoint) × Δφ × (cosθ₀ − cosθ₁) (for a part, where `in_part` holds
/// at the midpoint, else 0). Also checks that the bins' probabilities sum
/// to 1 and that no sample lands where the pdf is 0. Returns the p-value.
#[allow(clippy::too_many_arguments)]
fn map_chi_square(
    env: &Environment,
    (w, h): (usize, usize),
    rotation_deg: f64,
    sub: usize,
    n: usize,
    seed: u64,
    part: Option<usize>,
    in_part: impl Fn(DVec3) -> bool,
) -> f64 {
    let (bw, bh) = (sub * w, sub * h);
    let (d_phi, d_theta) = (TAU / bw as f64, PI / bh as f64);
    let rot = rotation_deg.to_radians();
    let mut expected = vec![0.0; bw * bh];
    for by in 0..bh {
        let (t0, t1) = (by as f64 * d_theta, (by + 1) as f64 * d_theta);
        let theta = 0.5 * (t0 + t1);
        for bx in 0..bw {
            let phi = rot + (bx as f64 + 0.5) * d_phi;
            let d = DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let pdf = match part {
                Some(_) if !in_part(d) => 0.0,
                Some(_) => env.part_pdf(d),
                None => env.pdf(d),
            };
            expected[by * bw + bx] = pdf * d_phi * (t0.cos() - t1.cos());
        }
    }
    let total: f64 = expected.iter().sum();
    assert!((total - 1.0).abs() < 1e-12, "∫ p dω = {total}");

    let mut counts = vec![0u64; bw * bh];
    let mut rng = Rng::new(seed, 3);
    for _ in 0..n {
        let u = [rng.next_f64(), rng.next_f64()];
        let s = match part {
            Some(part) => env.sample_part(part, u),
            None => env.sample(u),
        }
        .unwrap();
        let theta = s.direction.z.clamp(-1.0, 1.0).acos();
        let phi = (s.direction.y.atan2(s.direction.x) - rot).rem_euclid(TAU);
        let by = ((theta / d_theta) as usize).min(bh - 1);
        let bx = ((phi / d_phi) as usize).min(bw - 1);
        counts[by * bw + bx] += 1;
    }
    // Bins expecting fewer than 5 samples (near the poles, where a bin's
    // solid angle vanishes) are pooled into one.
    let (mut chi2, mut cells, mut pooled) = (0.0, 0, (0.0, 0.0));
    for (&o, &p) in counts.iter().zip(&expected) {
        let e = p * n as f64;
        if p == 0.0 {
            assert_eq!(o, 0, "sample where the density is 0");
        } else if e < 5.0 {
            pooled = (pooled.0 + o as f64, pooled.1 + e);
        } else {
            chi2 += (o as f64 - e).powi(2) / e;
            cells += 1;
        }
    }
    if pooled.1 > 0.0 {
        assert!(pooled.1 >= 5.0, "the pooled bins expect {}", pooled.1);
        chi2 += (pooled.0 - pooled.1).powi(2) / pooled.1;
        cells += 1;
    }
    let p_value = ChiSquared::new((cells - 1) as f64).unwrap().sf(chi2);
    eprintln!("chi2 = {chi2}, {} dof, p = {p_value}", cells - 1);
    p_value
}

#[test]
fn map_sampling_matches_its_pdf_chi_square() {
    let map = small_map(30.0);
    let env = Environment::Map(map.clone());
    assert_eq!(map.parts(), 1);
    let everywhere = |_| true;
    let p = map_chi_square(
        &env,
        (map.width(), map.height()),
        30.0,
        2,
        300_000,
        5,
        None,
        everywhere,
    );
    assert!(p > 1e-4, "p = {p}");
}

/// A 64 × 32 sky (a gradient, a dark ground, a few texels a billion times
/// dimmer than the rest) with a one-texel sun 20 000 times the sky, which
/// carries most of the map's power.
fn sun_map(rotation_deg: f64) -> EnvironmentMap {
    let (w, h) = (64, 32);
    let mut texels = Vec::new();
    for row in 0..h {
        for col in 0..w {
            let sky = if row < h / 2 {
                Rgb::new(0.4, 0.6, 1.0) * (1.0 - row as f64 / h as f64)
            } else {
                Rgb::new(0.08, 0.07, 0.05)
            };
            texels.push(if (col + row) % 29 == 3 {
                sky * 1e-9
            } else {
                sky
            });
        }
    }
    texels[7 * w + 41] = Rgb::new(2.0e4, 1.9e4, 1.7e4);
    EnvironmentMap::new(w, h, texels, rotation_deg).unwrap()
}

#[test]
fn sun_map_sampling_matches_its_pdf_chi_square() {
    let map = sun_map(-20.0);
    let env = Environment::Map(map.clone());
    // The sun has ~97 % of the power: its texel must be split finely and
    // the sky still get ≥ 5 samples per bin.
    let size = (map.width(), map.height());
    let p = map_chi_square(&env, size, -20.0, 2, 3_000_000, 6, None, |_| true);
    assert!(p > 1e-4, "p = {p}");
    // It is also a part of its own, the rest of the map the other.
    assert_eq!(map.parts(), 2);
    let sun = |d: DVec3| luminance(env.radiance(d)) > 1e3;
    let p = map_chi_square(&env, size, -20.0, 2, 300_000, 7, Some(0), |d| !sun(d));
    assert!(p > 1e-4, "the sky: p = {p}");
    let p = map_chi_square(&env, size, -20.0, 8, 100_000, 8, Some(1), sun);
    assert!(p > 1e-4, "the sun: p = {p}");
}

#[test]
fn map_pdf_integrates_to_one_texel_by_texel() {
    // The density is constant on each texel: Σ pdf × texel solid angle is
    // the exact integral, 1 for the whole map and for each part.
    let envs = [
        (Environment::Map(sun_map(15.0)), 15.0),
        (Environment::Map(small_map(30.0)), 30.0),
        (Environment::studio(1.0, 20.0), 20.0),
    ];
    for (env, rotation_deg) in &envs {
        let Environment::Map(map) = env else {
            unreachable!()
        };
        let (w, h) = (map.width(), map.height());
        let (mut integral, mut parts_integral) = (0.0, 0.0);
        for row in 0..h {
            let solid_angle = texel_solid_angle(row, h, w);
            for col in 0..w {
                let centre = dir_deg(
                    180.0 * (row as f64 + 0.5) / h as f64,
                    360.0 * (col as f64 + 0.5) / w as f64 + rotation_deg,
                );
                integral += env.pdf(centre) * solid_angle;
                parts_integral += env.part_pdf(centre) * solid_angle;
            }
        }
        assert!(
            (integral - 1.0).abs() < 1e-12,
            "{w}×{h}: ∫ p dω = {integral}"
        );
        let parts = env.parts() as f64;
        assert!(
            (parts_integral - parts).abs() < 1e-12,
            "{w}×{h}: Σ ∫ p_part dω = {parts_integral}, {parts} parts"
        );
    }
}

#[test]
fn constant_environment_is_uniform() {
    let env = Environment::constant(Rgb::new(1.0, 2.0, 3.0));
    for d in [DVec3::Z, -DVec3::Z, dir_deg(70.0, 200.0)] {
        assert_eq!(env.pdf(d), 1.0 / (4.0 * PI));
        assert_eq!(env.radiance(d), Rgb::new(1.0, 2.0, 3.0));
    }
    let integral = common::chi2::integrate_pdf_sphere(|d| env.pdf(d), 4, 8);
    assert!((integral - 1.0).abs() < 1e-12);
    let outcome = common::chi2::chi2_directions(
        |u| env.sample([u[0], u[1]]).map(|s| s.direction),
        |d| env.pdf(d),
        100_000,
        10,
        20,
        9,
    );
    assert!(outcome.passes(1e-4), "{outcome}");
    // Negative or NaN radiance is refused by the checked constructor.
    assert!(Environment::try_constant(Rgb::new(1.0, -1.0, 0.0)).is_err());
    assert!(Environment::try_constant(Rgb::new(f64::NAN, 0.0, 0.0)).is_err());
}

/// Solid angle of texel row `row` of `h` clipped to the upper hemisphere,
/// times cosθ: `Δφ ∫ cosθ sinθ dθ = Δφ (sin²θ₁ − sin²θ₀) / 2`.
fn row_cosine_weight(row: usize, h: usize, w: usize) -> f64 {
    let t0 = PI * row as f64 / h as f64;
    let t1 = (PI * (row + 1) as f64 / h as f64).min(PI / 2.0);
    if t0 >= PI / 2.0 {
        return 0.0;
    }
    TAU / w as f64 * 0.5 * (t1.sin().powi(2) - t0.sin().powi(2))
}

/// Solid angle of one texel of row `row`: `Δφ (cosθ₀ − cosθ₁)`.
fn texel_solid_angle(row: usize, h: usize, w: usize) -> f64 {
    let t0 = PI * row as f64 / h as f64;
    let t1 = PI * (row + 1) as f64 / h as f64;
    TAU / w as f64 * (t0.cos() - t1.cos())
}

/// Exact ∫ L dω and ∫ L max(cosθ, 0) dω of a map (luminance), summed over
/// texels. Valid for an unrotated or rotated map alike: rotation about z
/// changes neither.
fn exact_integrals(map: &EnvironmentMap) -> (f64, f64) {
    let (w, h) = (map.width(), map.height());
    let (mut total, mut irradiance) = (0.0, 0.0);
    for row in 0..h {
        let (sa, cw) = (texel_solid_angle(row, h, w), row_cosine_weight(row, h, w));
        for col in 0..w {
            let y = luminance(map.texel(col, row));
            total += y * sa;
            irradiance += y * cw;
        }
    }
    (total, irradiance)
}

/// Importance-sampled estimates (mean, standard error) of ∫ L dω and of
/// ∫ L max(cosθ, 0) dω: each estimate one sample of the whole map
/// (`by_parts` false) or the sum of one sample of each part.
fn estimates(env: &Environment, n: usize, seed: u64, by_parts: bool) -> [(f64, f64); 2] {
    let mut rng = Rng::new(seed, 0);
    let mut sums = [[0.0f64; 2]; 2];
    for _ in 0..n {
        let (mut f, mut g) = (0.0, 0.0);
        let draws = if by_parts { env.parts() } else { 1 };
        for part in 0..draws {
            let u = [rng.next_f64(), rng.next_f64()];
            let s = if by_parts {
                env.sample_part(part, u)
            } else {
                env.sample(u)
            };
            let s = s.unwrap();
            let x = luminance(s.radiance) / s.pdf;
            f += x;
            g += x * s.direction.z.max(0.0);
        }
        for (acc, x) in sums.iter_mut().zip([f, g]) {
            acc[0] += x;
            acc[1] += x * x;
        }
    }
    sums.map(|[s, s2]| {
        let mean = s / n as f64;
        let var = (s2 / n as f64 - mean * mean).max(0.0);
        (mean, (var / n as f64).sqrt())
    })
}

/// Both estimates, of the whole map and by its parts, match the texel sums.
fn assert_estimates_match(env: &Environment, map: &EnvironmentMap, n: usize) {
    let (total, irradiance) = exact_integrals(map);
    for by_parts in [false, true] {
        let [(t_est, t_se), (e_est, e_se)] = estimates(env, n, 17, by_parts);
        assert!(
            (t_est - total).abs() <= 4.0 * t_se + 1e-9 * total,
            "∫L dω (by parts: {by_parts}): estimate {t_est} ± {t_se}, exact {total}"
        );
        assert!(
            (e_est - irradiance).abs() <= 4.0 * e_se + 1e-9 * irradiance,
            "irradiance (by parts: {by_parts}): estimate {e_est} ± {e_se}, exact {irradiance}"
        );
    }
}

#[test]
fn sun_map_monte_carlo_of_both_parts_matches_texel_sums() {
    let map = sun_map(40.0);
    assert_eq!(map.parts(), 2);
    assert_estimates_match(&Environment::Map(map.clone()), &map, 100_000);
}

/// `sun_map`'s sky with its sun `sun_over_sky` times the sky's brightest,
/// `sky_scale` times the sky (0: black).
fn sky_with_sun(sun_over_sky: f64, sky_scale: f64) -> EnvironmentMap {
    let (w, h) = (64, 32);
    let sky = |row: usize| Rgb::new(0.4, 0.6, 1.0) * (1.0 - row as f64 / h as f64) * sky_scale;
    let mut texels: Vec<Rgb> = (0..w * h).map(|i| sky(i / w)).collect();
    texels[7 * w + 41] = Rgb::splat(sun_over_sky);
    EnvironmentMap::new(w, h, texels, 0.0).unwrap()
}

#[test]
fn only_a_compact_source_with_most_of_the_power_and_a_lit_rest_is_sampled_apart() {
    // The sun texel carries ≈ 97 % of the power.
    assert_eq!(sky_with_sun(2.0e4, 1.0).parts(), 2);
    // ≈ 25 %: the sky keeps most samples in one part.
    assert_eq!(sky_with_sun(200.0, 1.0).parts(), 1);
    // A sun in a black sky: nothing to sample apart from it.
    assert_eq!(sky_with_sun(2.0e4, 0.0).parts(), 1);
    // 32 bright texels of 2048 (1 in 64): not compact.
    let (w, h) = (64, 32);
    let mut texels = vec![Rgb::splat(0.1); w * h];
    for col in 0..32 {
        texels[5 * w + col] = Rgb::splat(1.0e4);
    }
    assert_eq!(EnvironmentMap::new(w, h, texels, 0.0).unwrap().parts(), 1);
    // The studio's soft boxes (≈ 20 × its mean) and a smooth map stay one.
    assert_eq!(Environment::studio(1.0, 0.0).parts(), 1);
    assert_eq!(small_map(0.0).parts(), 1);
}

/// Skylight where the sun does not shine is why the parts exist: the
/// irradiance of a surface facing straight down (the sun is above the
/// horizon) estimated from the sky part has a small fraction of the
/// variance that one luminance table for the whole map would give it (that
/// table draws the ground below the horizon with probability q, its share
/// of the map's power, so its relative variance is at least 1/q − 1).
#[test]
fn a_surface_the_sun_misses_gets_its_skylight_from_the_sky_part() {
    let map = sun_map(0.0);
    let env = Environment::Map(map.clone());
    let (w, h) = (map.width(), map.height());
    // Exact: the ground rows' luminance times their cosine weight.
    let row_sum = |row: usize| {
        (0..w)
            .map(|col| luminance(map.texel(col, row)))
            .sum::<f64>()
    };
    let exact: f64 = (h / 2..h)
        .map(|row| {
            let (t0, t1) = (PI * row as f64 / h as f64, PI * (row + 1) as f64 / h as f64);
            row_sum(row) * TAU / w as f64 * 0.5 * (t0.sin().powi(2) - t1.sin().powi(2))
        })
        .sum();
    let power = |rows: std::ops::Range<usize>| -> f64 {
        rows.map(|row| row_sum(row) * texel_solid_angle(row, h, w))
            .sum()
    };
    let ground_share = power(h / 2..h) / power(0..h);

    let mut rng = Rng::new(23, 0);
    let n = 20_000;
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..n {
        let s = env
            .sample_part(0, [rng.next_f64(), rng.next_f64()])
            .unwrap();
        let x = luminance(s.radiance) / s.pdf * (-s.direction.z).max(0.0);
        sum += x;
        sum2 += x * x;
    }
    let mean = sum / n as f64;
    let variance = sum2 / n as f64 - mean * mean;
    let standard_error = (variance / n as f64).sqrt();
    assert!(
        (mean - exact).abs() < 4.0 * standard_error,
        "{mean} ± {standard_error} against {exact}"
    );
    let one_table_at_least = 1.0 / ground_share - 1.0;
    let relative_variance = variance / (mean * mean);
    assert!(
        relative_variance < 0.2 * one_table_at_least,
        "relative variance {relative_variance}, one table's at least {one_table_at_least}"
    );
}

#[test]
fn small_map_monte_carlo_matches_texel_sums() {
    let map = small_map(30.0);
    assert_estimates_match(&Environment::Map(map.clone()), &map, 100_000);
}

#[test]
fn studio_monte_carlo_matches_texel_sums_and_pdf_integrates_to_one() {
    let env = Environment::studio(1.0, 0.0);
    let Environment::Map(map) = &env else {
        panic!("the studio is a map")
    };
    assert_eq!((map.width(), map.height()), (STUDIO_WIDTH, STUDIO_HEIGHT));
    assert_estimates_match(&env, map, 100_000);

    // ∫ p dω = ∫∫ p(θ, φ) sinθ dθ dφ by the midpoint rule on a grid that
    // is not aligned with the texels (error ~ texel edges / grid).
    let (nt, np) = (1500, 2000);
    let mut integral = 0.0;
    for i in 0..nt {
        let theta = PI * (i as f64 + 0.5) / nt as f64;
        let band = theta.sin() * (PI / nt as f64) * (TAU / np as f64);
        for j in 0..np {
            let phi = TAU * (j as f64 + 0.5) / np as f64;
            let d = DVec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            integral += env.pdf(d) * band;
        }
    }
    assert!((integral - 1.0).abs() < 2e-3, "∫ p dω = {integral}");
}

#[test]
fn studio_has_dome_floor_and_bright_key() {
    let env = Environment::studio(1.0, 0.0);
    // Straight down is the dark floor, just above the horizon the dome is
    // dimmer than at the zenith (gradient), no box at the zenith.
    let floor = env.radiance(dir_deg(170.0, 10.0));
    let zenith = env.radiance(dir_deg(1.0, 0.0));
    let horizon = env.radiance(dir_deg(88.0, 180.0));
    assert!(floor.max_element() < 0.05, "floor {floor}");
    assert!(zenith.x > horizon.x && horizon.x > floor.x);
    // The key box is documented at azimuth −135°, elevation 50° (θ = 40°).
    let key = env.radiance(dir_deg(40.0, -135.0));
    assert!(key.min_element() >= 5.0, "key {key}");
    // Intensity scales radiance linearly.
    let bright = Environment::studio(2.0, 0.0);
    assert!((bright.radiance(dir_deg(40.0, -135.0)) - 2.0 * key).length() < 1e-12);
    // Most of the light's power comes from the boxes: the key is sampled far
    // more often than the dome around it.
    assert!(env.pdf(dir_deg(40.0, -135.0)) > 20.0 * env.pdf(dir_deg(40.0, 45.0)));
}

#[test]
fn rotation_turns_the_map_counter_clockwise_from_above() {
    // Only texel (col 2, row 1) is lit: map azimuth [90°, 135°), polar
    // angle [45°, 90°). Rotated by +90° it must appear at world azimuth
    // [180°, 225°).
    let (w, h) = (8, 4);
    let mut texels = vec![Rgb::ZERO; w * h];
    texels[w + 2] = Rgb::new(5.0, 5.0, 5.0);
    let unrotated = Environment::Map(EnvironmentMap::new(w, h, texels.clone(), 0.0).unwrap());
    let rotated = Environment::Map(EnvironmentMap::new(w, h, texels, 90.0).unwrap());
    assert_eq!(unrotated.radiance(dir_deg(67.5, 112.5)), Rgb::splat(5.0));
    assert_eq!(rotated.radiance(dir_deg(67.5, 112.5)), Rgb::ZERO);
    assert_eq!(rotated.radiance(dir_deg(67.5, 202.5)), Rgb::splat(5.0));
    assert_eq!(rotated.radiance(dir_deg(67.5, -157.5)), Rgb::splat(5.0));
    assert_eq!(rotated.radiance(dir_deg(30.0, 202.5)), Rgb::ZERO);
    // Every sample comes from the lit texel, where it now is.
    let mut rng = Rng::new(1, 1);
    for _ in 0..2_000 {
        let s = rotated.sample([rng.next_f64(), rng.next_f64()]).unwrap();
        let phi = s
            .direction
            .y
            .atan2(s.direction.x)
            .rem_euclid(TAU)
            .to_degrees();
        let theta = s.direction.z.acos().to_degrees();
        assert!((180.0..225.0).contains(&phi), "φ = {phi}");
        assert!((45.0..=90.0).contains(&theta), "θ = {theta}");
    }
    // The same holds for the studio: the key box moves with the rotation.
    let studio = Environment::studio(1.0, 60.0);
    assert!(studio.radiance(dir_deg(40.0, -75.0)).min_element() >= 5.0);
    assert!(studio.radiance(dir_deg(40.0, -135.0)).max_element() < 1.0);
}

#[test]
fn black_map_samples_nothing() {
    let env = Environment::Map(EnvironmentMap::new(4, 2, vec![Rgb::ZERO; 8], 0.0).unwrap());
    assert_eq!(env.parts(), 1);
    assert!(env.sample([0.3, 0.7]).is_none());
    assert!(env.sample_part(0, [0.3, 0.7]).is_none());
    assert!(env.sample_part(1, [0.3, 0.7]).is_none());
    assert_eq!(env.pdf(DVec3::Z), 0.0);
    assert_eq!(env.radiance(dir_deg(45.0, 45.0)), Rgb::ZERO);
}

#[test]
fn in_memory_map_errors_name_the_problem() {
    let mut texels = vec![Rgb::ONE; 8];
    texels[6] = Rgb::new(0.0, f64::NAN, 0.0);
    let msg = EnvironmentMap::new(4, 2, texels, 0.0)
        .unwrap_err()
        .to_string();
    assert!(msg.contains("x = 2, y = 1"), "{msg}");
    let err = EnvironmentMap::new(0, 2, vec![], 0.0).unwrap_err();
    assert!(matches!(err, EnvironmentError::Empty { .. }), "{err}");
    let err = EnvironmentMap::new(4, 2, vec![Rgb::ONE; 7], 0.0).unwrap_err();
    assert!(
        matches!(err, EnvironmentError::WrongTexelCount { .. }),
        "{err}"
    );
    let err = EnvironmentMap::new(20_000, 10, vec![], 0.0).unwrap_err();
    assert!(
        err.to_string()
            .contains("allowed: at most 16384 wide and 8192 high"),
        "{err}"
    );
    let err = Environment::try_studio(-1.0, 0.0).unwrap_err().to_string();
    assert!(err.contains("intensity") && err.contains("≥ 0"), "{err}");
    assert!(Environment::try_studio(1.0, f64::INFINITY).is_err());
    // An intensity whose studio no texel could store: an error, not a
    // panic while baking; the infallible form takes the largest.
    let err = Environment::try_studio(1e305, 0.0).unwrap_err().to_string();
    assert!(
        err.contains("intensity") && err.contains("at most"),
        "{err}"
    );
    let Environment::Map(map) = Environment::studio(1e305, 0.0) else {
        panic!("the studio is a map");
    };
    assert!(map.radiance(DVec3::Z).max_element().is_finite());
}

/// A fresh directory under the system temp dir, unique to this process and
/// test (removed at the end of the test).
/// Texel values of the 4 × 2 test image: exact in RGBE (one shared
/// exponent, 8-bit mantissas) and in f32.
fn test_texel(col: usize, row: usize) -> [f32; 3] {
    let table = [
        [1.0, 0.5, 0.25],
        [2.0, 2.0, 2.0],
        [0.5, 0.25, 0.125],
        [4.0, 1.0, 0.5],
        [0.0, 0.0, 0.0],
        [8.0, 4.0, 2.0],
        [0.25, 0.25, 0.5],
        [1.0, 1.0, 1.0],
    ];
    table[row * 4 + col]
}

/// Direction through the centre of texel (col, row) of a 4 × 2 map turned
/// by `rotation_deg`: θ = 90°·(row + ½), φ = 90°·(col + ½) + rotation.
fn texel_centre(col: usize, row: usize, rotation_deg: f64) -> DVec3 {
    dir_deg(
        90.0 * (row as f64 + 0.5),
        90.0 * (col as f64 + 0.5) + rotation_deg,
    )
}

fn check_loaded(env: &Environment, rotation_deg: f64, intensity: f64) {
    for row in 0..2 {
        for col in 0..4 {
            let [r, g, b] = test_texel(col, row);
            let want = Rgb::new(r as f64, g as f64, b as f64) * intensity;
            let got = env.radiance(texel_centre(col, row, rotation_deg));
            assert_eq!(got, want, "texel ({col}, {row})");
        }
    }
}

#[test]
fn loads_hdr_and_exr_files() {
    let dir = common::cli::scratch("env", "load");
    let hdr = dir.join("tiny.hdr");
    common::maps::write_hdr(&hdr, 4, 2, test_texel);
    let env = Environment::from_file(&hdr, 0.0, 1.0).unwrap();
    check_loaded(&env, 0.0, 1.0);
    let env = Environment::from_file(&hdr, 45.0, 3.0).unwrap();
    check_loaded(&env, 45.0, 3.0);

    let exr_path = dir.join("tiny.exr");
    exr::prelude::write_rgba_file(&exr_path, 4, 2, |x, y| {
        let [r, g, b] = test_texel(x, y);
        (r, g, b, 1.0f32)
    })
    .unwrap();
    let env = Environment::from_file(&exr_path, -30.0, 0.5).unwrap();
    check_loaded(&env, -30.0, 0.5);
    // Upper-case extensions are the same formats.
    let upper = dir.join("TINY.EXR");
    std::fs::copy(&exr_path, &upper).unwrap();
    assert!(Environment::from_file(&upper, 0.0, 1.0).is_ok());
}

fn error_text(path: &std::path::Path) -> String {
    let err = Environment::from_file(path, 0.0, 1.0)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&path.display().to_string()),
        "message does not name the file: {err}"
    );
    err
}

#[test]
fn bad_files_give_errors_naming_the_file() {
    let dir = common::cli::scratch("env", "bad");
    let missing = dir.join("missing.hdr");
    assert!(error_text(&missing).contains("not found"));

    for (name, format) in [("corrupt.hdr", "Radiance HDR"), ("corrupt.exr", "OpenEXR")] {
        let path = dir.join(name);
        std::fs::write(&path, b"this is not an image at all\n\0\x01\x02").unwrap();
        let err = error_text(&path);
        assert!(
            err.contains(&format!("does not begin as {format} does")),
            "{err}"
        );
    }
    // A valid header promising more scanlines than the file holds.
    let truncated = dir.join("truncated.hdr");
    std::fs::write(
        &truncated,
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 4\n\x80\x80",
    )
    .unwrap();
    let err = error_text(&truncated);
    assert!(
        err.contains("scanline 1 of 4: the file ends early"),
        "{err}"
    );
    // Another kind of file under a map's extension is named as what it is:
    // a renamed PNG, each map format under the other's name, nothing.
    let kinds: [(&str, &[u8], &str); 4] = [
        (
            "photo.hdr",
            b"\x89PNG\r\n\x1a\n",
            "it is a PNG image, not Radiance HDR",
        ),
        (
            "sky.exr",
            b"#?RADIANCE\n",
            "it is a Radiance HDR image, not OpenEXR; name it .hdr",
        ),
        (
            "sky2.hdr",
            b"\x76\x2f\x31\x01\x02\0\0\0",
            "it is an OpenEXR image, not Radiance HDR; name it .exr",
        ),
        ("empty.exr", b"", "the file is empty"),
    ];
    for (name, bytes, expected) in kinds {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let err = error_text(&path);
        assert!(err.contains(expected), "{name}: {err}");
    }

    let png = dir.join("sky.png");
    std::fs::write(&png, b"\x89PNG").unwrap();
    let err = error_text(&png);
    assert!(
        err.contains(".png") && err.contains(".hdr") && err.contains(".exr"),
        "{err}"
    );

    // A header claiming 20000 × 10000 texels: refused before decoding.
    let huge = dir.join("huge.hdr");
    std::fs::write(
        &huge,
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 10000 +X 20000\n",
    )
    .unwrap();
    let err = error_text(&huge);
    assert!(
        err.contains("20000×10000 texels; allowed: at most 16384 wide and 8192 high"),
        "{err}"
    );

    // NaN and negative texels (EXR stores raw floats; RGBE cannot).
    for (name, bad) in [("nan.exr", f32::NAN), ("negative.exr", -1.0)] {
        let path = dir.join(name);
        exr::prelude::write_rgba_file(&path, 4, 2, move |x, y| {
            let g = if (x, y) == (3, 1) { bad } else { 1.0 };
            (1.0f32, g, 1.0f32, 1.0f32)
        })
        .unwrap();
        let err = error_text(&path);
        assert!(err.contains("x = 3, y = 1"), "{err}");
    }
    // The texel as in the file, whatever the `intensity`: (1, −1, 1).
    let err = Environment::from_file(&dir.join("negative.exr"), 0.0, 2.0)
        .unwrap_err()
        .to_string();
    assert!(err.contains("is (1, -1, 1)"), "{err}");

    // An EXR cut short in its pixels says so (not the decoder's "reference
    // to missing bytes").
    let whole = std::fs::read(dir.join("nan.exr")).unwrap();
    let cut = dir.join("cut.exr");
    std::fs::write(&cut, &whole[..whole.len() - 40]).unwrap();
    let err = error_text(&cut);
    assert!(err.contains("the file ends early"), "{err}");

    // An offset table whose entries all point at the first block: the
    // decoder delivers that block's rows again and again, and the rest of
    // the map would stay black. The table starts where its first entry
    // points 8 bytes a block before.
    let tall = dir.join("tall.exr");
    exr::prelude::write_rgba_file(&tall, 4, 256, |_, y| (1.0f32, y as f32, 1.0f32, 1.0f32))
        .unwrap();
    assert!(Environment::from_file(&tall, 0.0, 1.0).is_ok());
    let whole = std::fs::read(&tall).unwrap();
    let blocks = exr::meta::MetaData::read_from_file(&tall, false)
        .unwrap()
        .headers[0]
        .chunk_count;
    let table = (0..whole.len() - 8)
        .find(|&at| {
            let first = u64::from_le_bytes(whole[at..at + 8].try_into().unwrap());
            first == (at + 8 * blocks) as u64
        })
        .expect("the offset table");
    assert!(blocks > 1, "{blocks} blocks");
    let mut forged = whole.clone();
    let first_block = whole[table..table + 8].to_vec();
    for k in 1..blocks {
        forged[table + 8 * k..table + 8 * (k + 1)].copy_from_slice(&first_block);
    }
    let path = dir.join("one-block.exr");
    std::fs::write(&path, &forged).unwrap();
    let err = error_text(&path);
    assert!(
        err.contains("is stored twice (a damaged offset table?)"),
        "{err}"
    );

    // A directory with an allowed extension is not a file.
    let subdir = dir.join("folder.hdr");
    std::fs::create_dir(&subdir).unwrap();
    assert!(error_text(&subdir).contains("directory"));
}

#[test]
fn radiance_and_pdf_together_equal_the_separate_calls() {
    let envs = [
        Environment::studio(1.0, 20.0),
        Environment::Map(small_map(30.0)),
        Environment::constant(Rgb::new(0.5, 0.6, 0.7)),
    ];
    let mut rng = Rng::new(12, 3);
    for env in &envs {
        for _ in 0..5_000 {
            let d = DVec3::new(
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
                rng.next_f64() - 0.5,
            )
            .normalize();
            assert_eq!(env.radiance_and_pdf(d), (env.radiance(d), env.pdf(d)));
        }
    }
}

/// The studio bake as it was first written: per sub-sample, the direction
/// from its own `sin_cos` of θ and φ, and per soft box its frame worked out
/// again (the gnomonic test of `studio_radiance`, spelled out here).
fn studio_texels_per_subsample(width: usize, height: usize, intensity: f64) -> Vec<Rgb> {
    const SUB: usize = 4;
    // (azimuth, elevation, width, height) in degrees and radiance, in the
    // library's order: key, strip, fill.
    let boxes: [(f64, f64, f64, f64, Rgb); 3] = [
        (-135.0, 50.0, 44.0, 30.0, Rgb::new(12.0, 11.6, 11.0)),
        (-15.0, 25.0, 8.0, 40.0, Rgb::new(8.0, 8.0, 8.0)),
        (90.0, 30.0, 60.0, 20.0, Rgb::new(2.4, 2.5, 2.7)),
    ];
    let spherical = |theta: f64, phi: f64| {
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        DVec3::new(st * cp, st * sp, ct)
    };
    let radiance = |d: DVec3| {
        for &(azimuth, elevation, w, h, radiance) in &boxes {
            let centre = spherical((90.0 - elevation).to_radians(), azimuth.to_radians());
            let t = d.dot(centre);
            if t <= 0.0 {
                continue;
            }
            let across = DVec3::Z.cross(centre).normalize();
            let up = centre.cross(across);
            let (x, y) = (d.dot(across) / t, d.dot(up) / t);
            if x.abs() <= (0.5 * w).to_radians().tan() && y.abs() <= (0.5 * h).to_radians().tan() {
                return radiance;
            }
        }
        Rgb::splat(if d.z >= 0.0 {
            0.10 + (0.25 - 0.10) * d.z
        } else {
            0.03
        })
    };
    let mut texels = Vec::with_capacity(width * height);
    for row in 0..height {
        for col in 0..width {
            let mut sum = Rgb::ZERO;
            for sy in 0..SUB {
                let v = (row as f64 + (sy as f64 + 0.5) / SUB as f64) / height as f64;
                for sx in 0..SUB {
                    let u = (col as f64 + (sx as f64 + 0.5) / SUB as f64) / width as f64;
                    sum += radiance(spherical(PI * v, TAU * u));
                }
            }
            texels.push(sum * (intensity / (SUB * SUB) as f64));
        }
    }
    texels
}

#[test]
fn studio_bake_with_hoisted_angles_is_bit_identical_to_the_per_subsample_formula() {
    let bits = |t: &Rgb| t.to_array().map(f64::to_bits);
    // The studio itself, with 1 and 3 threads: the bake bit for bit, and
    // the map's stored texels (9 significant bits, intensity applied when
    // read) within the format's bound of it and equal across threads.
    let expected = studio_texels_per_subsample(STUDIO_WIDTH, STUDIO_HEIGHT, 1.0);
    let mut maps = Vec::new();
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a pool");
        let baked = pool.install(|| {
            lapidary::render::environment::bake_studio_texels(STUDIO_WIDTH, STUDIO_HEIGHT, 1.0)
        });
        assert_eq!(
            baked.iter().map(bits).collect::<Vec<_>>(),
            expected.iter().map(bits).collect::<Vec<_>>(),
            "{threads} threads"
        );
        let Environment::Map(map) = pool.install(|| Environment::studio(1.7, 25.0)) else {
            panic!("the studio is a map")
        };
        for row in 0..STUDIO_HEIGHT {
            for col in 0..STUDIO_WIDTH {
                let source = expected[row * STUDIO_WIDTH + col] * 1.7;
                assert_within_format_bound(map.texel(col, row), source, (col, row));
            }
        }
        maps.push(map);
    }
    assert_eq!(
        maps[0], maps[1],
        "the map does not depend on the thread count"
    );
    // Other sizes (odd, tiny, one row) and intensities.
    for (width, height, intensity) in [(37, 19, 1.0), (1, 1, 0.5), (64, 1, 3.0), (3, 200, 0.0)] {
        let hoisted = lapidary::render::environment::bake_studio_texels(width, height, intensity);
        let reference = studio_texels_per_subsample(width, height, intensity);
        assert_eq!(
            hoisted.iter().map(bits).collect::<Vec<_>>(),
            reference.iter().map(bits).collect::<Vec<_>>(),
            "{width} × {height}"
        );
    }
}

/// A stored texel is within 2⁻⁹ × the brightest channel of its source
/// (plus the rounding of multiplying by an intensity), channel by channel.
fn assert_within_format_bound(stored: Rgb, source: Rgb, (col, row): (usize, usize)) {
    let bound = source.max_element() * (2f64.powi(-9) + 1e-15);
    assert!(
        (stored - source).abs().max_element() <= bound,
        "texel ({col}, {row}): stored {stored}, source {source}"
    );
}

#[test]
fn stored_texels_are_within_the_format_bound_of_the_source() {
    // Magnitudes from 10⁻⁸ to 10⁹, channels up to 10⁴ apart, through the
    // in-memory constructor and through an EXR file (f32 texels) with an
    // intensity.
    let (w, h) = (64, 32);
    let mut rng = Rng::new(17, 18);
    let source: Vec<[f32; 3]> = (0..w * h)
        .map(|_| {
            let max = 10f64.powf(rng.next_f64() * 17.0 - 8.0);
            let rgb = [0; 3].map(|_| 1e-4f64.powf(rng.next_f64()));
            let brightest = rgb[0].max(rgb[1]).max(rgb[2]);
            rgb.map(|c| (max * c / brightest) as f32)
        })
        .collect();
    let rgb = |t: [f32; 3]| Rgb::new(t[0] as f64, t[1] as f64, t[2] as f64);
    let map = EnvironmentMap::new(w, h, source.iter().map(|&t| rgb(t)).collect(), 0.0).unwrap();
    let dir = common::cli::scratch("env", "bound");
    let path = dir.join("random.exr");
    exr::prelude::write_rgb_file(&path, w, h, |x, y| {
        let [r, g, b] = source[y * w + x];
        (r, g, b)
    })
    .unwrap();
    let Environment::Map(loaded) = Environment::from_file(&path, 0.0, 2.5).unwrap() else {
        panic!("a file is a map")
    };
    for row in 0..h {
        for col in 0..w {
            let t = rgb(source[row * w + col]);
            assert_within_format_bound(map.texel(col, row), t, (col, row));
            assert_within_format_bound(loaded.texel(col, row), t * 2.5, (col, row));
        }
    }
}

#[test]
fn too_bright_texels_are_refused_with_the_limit() {
    use lapidary::render::environment::MAX_TEXEL_RADIANCE;
    let mut texels = vec![Rgb::ONE; 8];
    texels[5] = Rgb::new(1.0, 5e9, 1.0);
    let err = EnvironmentMap::new(4, 2, texels, 0.0).unwrap_err();
    let msg = err.to_string();
    assert!(
        matches!(err, EnvironmentError::TooBright { x: 1, y: 1, .. }) && msg.contains("intensity"),
        "{msg}"
    );
    let mut texels = vec![Rgb::ONE; 8];
    texels[2] = Rgb::splat(MAX_TEXEL_RADIANCE);
    assert!(EnvironmentMap::new(4, 2, texels, 0.0).is_ok());
    // In a file, the first such texel in reading order, named with the file.
    let dir = common::cli::scratch("env", "bright");
    let path = dir.join("sun.exr");
    exr::prelude::write_rgb_file(&path, 4, 2, |x, y| {
        let v = if y == 1 && x >= 2 { 1e10f32 } else { 1.0 };
        (v, v, v)
    })
    .unwrap();
    let err = error_text(&path);
    assert!(
        err.contains("x = 2, y = 1") && err.contains("above"),
        "{err}"
    );
}

#[test]
fn hdr_scanlines_read_as_the_image_crate_reads_them() {
    // Wide enough for run-length encoded scanlines, with runs (flat areas)
    // and literals (noise), compared with `image`'s own whole-image decode.
    let dir = common::cli::scratch("env", "rle");
    let path = dir.join("rle.hdr");
    let (w, h) = (97, 13);
    let value = |col: usize, row: usize| -> [f32; 3] {
        if col < 40 {
            [0.5, 0.25, 2.0]
        } else {
            let t = lapidary::sampling::mix64((row * w + col) as u64) as f32 / u64::MAX as f32;
            [t * 100.0, t * t, 0.001 + t]
        }
    };
    common::maps::write_hdr(&path, w, h, value);
    let reference = image::open(&path).unwrap().into_rgb32f();
    let Environment::Map(map) = Environment::from_file(&path, 0.0, 1.0).unwrap() else {
        panic!("a file is a map")
    };
    for row in 0..h {
        for col in 0..w {
            let [r, g, b] = reference.get_pixel(col as u32, row as u32).0;
            // RGBE values fit the texel format exactly.
            assert_eq!(
                map.texel(col, row),
                Rgb::new(r as f64, g as f64, b as f64),
                "texel ({col}, {row})"
            );
        }
    }
    // The same file cut short in the middle of its scanlines.
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.join("cut.hdr");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let err = error_text(&cut);
    assert!(err.contains("the file ends early"), "{err}");
}
