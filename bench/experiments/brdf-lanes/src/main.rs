//! A measurement for issue 6 (not part of lapidary; see README.md): what
//! the peer stone's layered BRDF costs per evaluation in lapidary, and what
//! a lean kernel for exactly that material (one smooth Blinn coat over a
//! Lambert base, with the compensation lobe) costs one lane at a time and
//! four lanes (f64x4, AVX2) at a time.
//!
//! Each measured call is what a path vertex on the stone pays per light or
//! BRDF sample: the wo-dependent part (`LayeredBrdf::at`: the compensation
//! lookup, Fresnel at wo, the mixture weights) and one evaluation with its
//! density (`BrdfAt::eval_and_pdf`). The (wi, wo) pairs mix the two kinds of
//! wi a vertex evaluates: two thirds drawn by lapidary's own BRDF sampling
//! (some on the smooth coat's specular peak, where D(h) ≠ 0 and the lean
//! kernel calls `exp` and `ln_1p` lane by lane), one third
//! cosine-distributed (as the sphere light's directions are to the BRDF).
//!
//! The lean kernel is checked against lapidary's result for every pair
//! (largest relative difference printed and bounded); its one-lane and
//! four-lane runs do the same operations and give the same sums.
use std::f64::consts::PI;
use std::time::Instant;

use glam::DVec3;
use lapidary::brdf::{Base, LayeredBrdf, MicrofacetModel};
use lapidary::recipe::load_material;
use lapidary::sampling::{cosine_hemisphere, Rng};

/// Lanes of the vector version (f64x4: one AVX2 register).
const LANES: usize = 4;
/// Intervals of the compensation table in s = √(1 − μ), as lapidary's.
const NODES: usize = 512;

type V3 = [f64; 3];

/// The peer material's constants, read from lapidary's compiled BRDF.
struct Coat {
    /// Relative index of the coat.
    eta: f64,
    /// Blinn exponent β of the coat's lobe.
    beta: f64,
    /// The base's colour / π.
    colour_over_pi: V3,
    /// lapidary's guess of the albedo below the coat (mixture weights).
    below_guess: f64,
    /// The compensation deficit D at s = j / NODES, j = 0…NODES.
    table: Box<[V3; NODES + 1]>,
    /// P̄ and X̄ of the compensation lobe.
    positive_average: V3,
    negative_average: V3,
}

impl Coat {
    fn of(brdf: &LayeredBrdf) -> Coat {
        let [itf] = brdf.interfaces.as_slice() else {
            panic!("the experiment's material has one coat");
        };
        let Base::Diffuse {
            colour,
            oren_nayar_sigma_rad,
        } = &brdf.base
        else {
            panic!("the experiment's material has a diffuse base");
        };
        assert!(*oren_nayar_sigma_rad <= 0.0 && itf.lobe.model == MicrofacetModel::Blinn);
        assert!(itf.thickness == 0.0 || itf.absorption_rgb == DVec3::ZERO);
        let c = brdf.compensation.as_ref().expect("compensation on");
        // As LayeredBrdf::new computes it.
        let t = itf.crossing_transmittance(1.0);
        let below_guess = brdf.base.albedo_guess() * ((t * t).element_sum() / 3.0);
        Coat {
            eta: itf.eta,
            beta: itf.lobe.blinn_exponent,
            colour_over_pi: (*colour / PI).to_array(),
            below_guess,
            table: Box::new(std::array::from_fn(|j| {
                let s = j as f64 / NODES as f64;
                c.albedo(1.0 - s * s).to_array()
            })),
            positive_average: c.positive_average.to_array(),
            negative_average: c.negative_average.to_array(),
        }
    }
}

#[inline(always)]
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The compensation table at cosine `mu` (lapidary's `Compensation::albedo`).
#[inline(always)]
fn deficit(c: &Coat, mu: f64) -> V3 {
    let x = (1.0 - mu.clamp(0.0, 1.0)).sqrt() * NODES as f64;
    let j = (x as i32).clamp(0, NODES as i32 - 1);
    let t = x - f64::from(j);
    let (a, b) = (c.table[j as usize], c.table[j as usize + 1]);
    [0, 1, 2].map(|k| a[k] * (1.0 - t) + b[k] * t)
}

/// cosθₜ by Snell from the cosine `cos` (|cos| ≤ 1 assumed clamped) and
/// whether the light is totally reflected.
#[inline(always)]
fn snell(cos: f64, eta: f64) -> (f64, bool) {
    let c = cos.abs().min(1.0);
    let sin2 = (1.0 - c * c) / (eta * eta);
    ((1.0 - sin2).max(0.0).sqrt(), sin2 >= 1.0)
}

/// The dielectric Fresnel reflectance, polarisations averaged, given cosθₜ.
#[inline(always)]
fn fresnel(cos: f64, cos_t: f64, eta: f64) -> f64 {
    let c = cos.abs().min(1.0);
    let rp = (eta * c - cos_t) / (eta * c + cos_t);
    let rs = (c - eta * cos_t) / (c + eta * cos_t);
    0.5 * (rp * rp + rs * rs)
}

/// The V-cavity shadowing-masking of the appendix `geom`.
#[inline(always)]
fn v_cavity(wi: V3, wo: V3, h: V3) -> f64 {
    let (ih, oh) = (dot(wi, h), dot(wo, h));
    let masking = 2.0 * h[2] * wo[2].abs() / oh.abs();
    let shadowing = 2.0 * h[2] * wi[2].abs() / ih.abs();
    let g = masking.min(shadowing).min(1.0);
    if ih * wi[2] <= 0.0 || oh * wo[2] <= 0.0 || h[2] <= 0.0 {
        0.0
    } else {
        g
    }
}

/// `w` refracted through `h` into the coat, pointing up inside it, and
/// whether it was totally reflected instead.
#[inline(always)]
fn refract_in(w: V3, h: V3, eta: f64) -> (V3, bool) {
    let cos_i = dot(w, h);
    let sin2 = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    let cos_t = (1.0 - sin2).max(0.0).sqrt();
    let k = cos_i / eta - cos_t;
    let v = [0, 1, 2].map(|a| -w[a] / eta + k * h[a]);
    let r = 1.0 / dot(v, v).sqrt();
    (v.map(|x| -(x * r)), sin2 >= 1.0)
}

/// What depends on wo alone (lapidary's `prepare`).
#[derive(Clone, Copy, Default)]
struct At {
    deficit_o: V3,
    p_comp: f64,
    fresnel_out: f64,
    p_top: f64,
    p_below: f64,
}

#[inline(always)]
fn prepare(c: &Coat, wo: V3) -> At {
    let deficit_o = deficit(c, wo[2]);
    let d = deficit_o.iter().map(|x| x.max(0.0)).sum::<f64>() / 3.0;
    let p_comp = (d / (d + 0.5)).min(0.5);
    let (cos_t, tir) = snell(wo[2], c.eta);
    let fresnel_out = if tir {
        1.0
    } else {
        fresnel(wo[2], cos_t, c.eta)
    };
    let top = fresnel_out.max(0.02);
    let below = (1.0 - fresnel_out) * c.below_guess;
    let total = top + below;
    let (p_top, p_below) = if total <= 0.0 {
        (0.0, 0.0)
    } else {
        (top / total, below / total)
    };
    At {
        deficit_o,
        p_comp,
        fresnel_out,
        p_top,
        p_below,
    }
}

/// The half vector and whether D(h) can be nonzero (β(cosθh − 1) ≥ −800).
#[inline(always)]
fn half(c: &Coat, wi: V3, wo: V3) -> (V3, bool) {
    let s = [0, 1, 2].map(|a| wi[a] + wo[a]);
    let r = 1.0 / dot(s, s).sqrt();
    let h = s.map(|x| x * r);
    (h, h[2] > 0.0 && c.beta * (h[2] - 1.0) >= -800.0)
}

/// The coat's own reflection where D(h) ≠ 0 (the rare, scalar part):
/// D·G·F(wi·h)/(4 cosθᵢ cosθₒ) and the lobe's density.
#[inline(always)]
fn peak(c: &Coat, wi: V3, wo: V3, h: V3) -> (f64, f64) {
    let d = (c.beta + 2.0) * (0.5 / PI) * (c.beta * (h[2] - 1.0).ln_1p()).exp();
    let value = d * v_cavity(wi, wo, h) / (4.0 * wi[2] * wo[2]);
    let oh = dot(wo, h);
    let pdf = if oh <= 0.0 || d == 0.0 {
        0.0
    } else {
        d * h[2] / (4.0 * oh)
    };
    let cos_ih = dot(wi, h);
    let (cos_t, tir) = snell(cos_ih, c.eta);
    let f = if tir {
        1.0
    } else {
        fresnel(cos_ih, cos_t, c.eta)
    };
    (value * f, pdf)
}

/// The rest of the evaluation (vectorisable): the layer below through the
/// refracted pair, the density, the compensation lobe. `f_top` and
/// `top_pdf` come from [`peak`] (0 off the peak).
#[inline(always)]
fn below_and_pdf(c: &Coat, at: &At, wi: V3, wo: V3, h: V3, f_top: f64, top_pdf: f64) -> (V3, f64) {
    let eta = c.eta;
    let (wi_in, tir_i) = refract_in(wi, h, eta);
    let (wo_in, tir_o) = refract_in(wo, h, eta);
    let through = !tir_i && !tir_o && wi_in[2] > 0.0 && wo_in[2] > 0.0;
    let (cos_t_i, tir_n) = snell(wi[2], eta);
    let transmission_in = 1.0
        - if tir_n {
            1.0
        } else {
            fresnel(wi[2], cos_t_i, eta)
        };
    let g = v_cavity(wi_in, wo_in, h);
    let tir = (1.0 - g) + (1.0 - at.fresnel_out) * g;
    let scale = transmission_in * tir / (eta * eta);
    let single = c
        .colour_over_pi
        .map(|k| if through { f_top + k * scale } else { f_top });
    // The stack's density: the coat's lobe, and the base's cosine density
    // carried through Snell at the macro-normal.
    let z = -wi[2] / eta + (wi[2] / eta - cos_t_i);
    let (x, y) = (-wi[0] / eta, -wi[1] / eta);
    let cos_in = -(z * (1.0 / ((x * x + y * y) + z * z).sqrt()));
    let jacobian = wi[2] / (eta * eta * cos_in);
    let below_pdf = if tir_n || cos_in <= 0.0 {
        0.0
    } else {
        at.p_below * (cos_in / PI) * jacobian
    };
    let stack_pdf = at.p_top * top_pdf + if at.p_below > 0.0 { below_pdf } else { 0.0 };
    // The compensation lobe.
    let di = deficit(c, wi[2]);
    let mut value = [0.0; 3];
    for k in 0..3 {
        let positive = di[k].max(0.0) * at.deficit_o[k].max(0.0);
        let negative = (-di[k]).max(0.0) * (-at.deficit_o[k]).max(0.0);
        let p = if c.positive_average[k] > 1e-12 {
            positive / c.positive_average[k]
        } else {
            0.0
        };
        let n = if c.negative_average[k] > 1e-12 {
            negative / c.negative_average[k]
        } else {
            0.0
        };
        value[k] = (single[k] + (p - n) * (1.0 / PI)).max(0.0);
    }
    let pdf = (1.0 - at.p_comp) * stack_pdf
        + if at.p_comp > 0.0 {
            at.p_comp * wi[2] / PI
        } else {
            0.0
        };
    (value, pdf)
}

/// One evaluation, one lane.
#[inline(always)]
fn lean_one(c: &Coat, wi: V3, wo: V3) -> (V3, f64) {
    let at = prepare(c, wo);
    let (h, on_peak) = half(c, wi, wo);
    let (f_top, top_pdf) = if on_peak {
        peak(c, wi, wo, h)
    } else {
        (0.0, 0.0)
    };
    below_and_pdf(c, &at, wi, wo, h, f_top, top_pdf)
}

/// Sum of every value channel and density: the checksum every run prints.
fn checksum(sum: &mut f64, (value, pdf): (V3, f64)) {
    *sum += value[0] + value[1] + value[2] + pdf;
}

#[target_feature(enable = "avx2,fma")]
unsafe fn lean_scalar(c: &Coat, pairs: &[(V3, V3)]) -> f64 {
    let mut sum = 0.0;
    for &(wi, wo) in pairs {
        checksum(&mut sum, lean_one(c, wi, wo));
    }
    sum
}

/// Four pairs at a time, the lanes' vectors stored as separate arrays per
/// component (structure of arrays), so that each step is a lane loop LLVM
/// compiles to AVX2 arithmetic; the peak (exp, ln_1p) is computed only for
/// the lanes on it, one at a time.
#[target_feature(enable = "avx2,fma")]
unsafe fn lean_lanes(c: &Coat, pairs: &[(V3, V3)]) -> f64 {
    let mut sum = 0.0;
    for chunk in pairs.chunks_exact(LANES) {
        let mut wi = [[0.0; LANES]; 3];
        let mut wo = [[0.0; LANES]; 3];
        for (l, &(i, o)) in chunk.iter().enumerate() {
            for a in 0..3 {
                wi[a][l] = i[a];
                wo[a][l] = o[a];
            }
        }
        let lane = |v: &[[f64; LANES]; 3], l: usize| [v[0][l], v[1][l], v[2][l]];
        let mut at = [At::default(); LANES];
        let mut h = [[0.0; LANES]; 3];
        let mut on_peak = [false; LANES];
        for l in 0..LANES {
            at[l] = prepare(c, lane(&wo, l));
            let (hl, p) = half(c, lane(&wi, l), lane(&wo, l));
            (h[0][l], h[1][l], h[2][l], on_peak[l]) = (hl[0], hl[1], hl[2], p);
        }
        let mut f_top = [0.0; LANES];
        let mut top_pdf = [0.0; LANES];
        if on_peak.iter().any(|&p| p) {
            for l in 0..LANES {
                if on_peak[l] {
                    (f_top[l], top_pdf[l]) = peak(c, lane(&wi, l), lane(&wo, l), lane(&h, l));
                }
            }
        }
        let mut value = [[0.0; LANES]; 3];
        let mut pdf = [0.0; LANES];
        for l in 0..LANES {
            let (v, p) = below_and_pdf(
                c,
                &at[l],
                lane(&wi, l),
                lane(&wo, l),
                lane(&h, l),
                f_top[l],
                top_pdf[l],
            );
            (value[0][l], value[1][l], value[2][l], pdf[l]) = (v[0], v[1], v[2], p);
        }
        for (l, p) in pdf.into_iter().enumerate() {
            checksum(&mut sum, (lane(&value, l), p));
        }
    }
    sum
}

#[target_feature(enable = "avx2,fma")]
unsafe fn lapidary_evals(brdf: &LayeredBrdf, pairs: &[(V3, V3)]) -> f64 {
    let mut sum = 0.0;
    for &(wi, wo) in pairs {
        let (value, pdf) = brdf.at(DVec3::from(wo)).eval_and_pdf(DVec3::from(wi));
        checksum(&mut sum, (value.to_array(), pdf));
    }
    sum
}

fn main() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/coat.ron");
    let brdf = load_material(path).expect("coat.ron compiles");
    let coat = Coat::of(&brdf);
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2_000_000);
    // The pairs: wo cosine-distributed; wi by lapidary's BRDF sampling for
    // two pairs in three, cosine-distributed for the third.
    let mut rng = Rng::new(7, 11);
    let mut pairs = Vec::with_capacity(n);
    while pairs.len() < n {
        let wo = cosine_hemisphere(rng.next_f64(), rng.next_f64());
        let wi = if pairs.len() % 3 == 2 {
            Some(cosine_hemisphere(rng.next_f64(), rng.next_f64()))
        } else {
            let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            brdf.at(wo).sample(u).map(|s| s.wi)
        };
        if let Some(wi) = wi.filter(|w| w.z > 0.0 && wo.z > 0.0) {
            pairs.push((wi.to_array(), wo.to_array()));
        }
    }
    let on_peak = pairs
        .iter()
        .filter(|(wi, wo)| half(&coat, *wi, *wo).1)
        .count();
    // The lean kernel against lapidary, pair by pair.
    let mut worst: f64 = 0.0;
    for &(wi, wo) in &pairs {
        let (value, pdf) = brdf.at(DVec3::from(wo)).eval_and_pdf(DVec3::from(wi));
        let (lean_value, lean_pdf) = lean_one(&coat, wi, wo);
        for (a, b) in value
            .to_array()
            .into_iter()
            .chain([pdf])
            .zip(lean_value.into_iter().chain([lean_pdf]))
        {
            worst = worst.max((a - b).abs() / a.abs().max(1e-300));
        }
    }
    println!(
        "{n} pairs, {on_peak} on the coat's peak; lean vs lapidary: largest relative difference {worst:.1e}"
    );
    assert!(worst < 1e-9, "the lean kernel computes something else");
    assert!(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"));
    for round in 0..3 {
        let time = |f: &dyn Fn() -> f64| {
            let start = Instant::now();
            let sum = f();
            (start.elapsed().as_secs_f64() / n as f64 * 1e9, sum)
        };
        // SAFETY: AVX2 and FMA were found above.
        let (t_lap, s_lap) = time(&|| unsafe { lapidary_evals(&brdf, &pairs) });
        let (t_one, s_one) = time(&|| unsafe { lean_scalar(&coat, &pairs) });
        let (t_four, s_four) = time(&|| unsafe { lean_lanes(&coat, &pairs) });
        println!(
            "round {round}: ns per prepare + evaluation: lapidary {t_lap:.1}, lean one lane {t_one:.1} ({:.2}x), lean f64x4 {t_four:.1} ({:.2}x; {:.2}x over lapidary); sums {s_lap:.6} {s_one:.6} {s_four:.6}",
            t_lap / t_one,
            t_one / t_four,
            t_lap / t_four
        );
    }
}
