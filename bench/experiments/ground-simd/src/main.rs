//! A measurement for issue 6 (not part of lapidary; see README.md): what a
//! lean, straight-line path kernel costs for a *ground* sample of the peer
//! scene, one lane at a time and four lanes (f64x4, AVX2) at a time.
//!
//! The work per sample is lapidary's for a ground sample: the camera ray's
//! ground hit and its tests against the stone (a half ellipsoid of semi-axes
//! 1 × 0.7 × 0.45) and the sphere light; next-event estimation (uniform cone
//! sampling of the sphere light with the same polynomial sine/cosine and
//! Duff et al. basis, a shadow test against the stone, the Lambert value
//! and the power-heuristic weight); cosine sampling of the bounce; the
//! bounce's tests against the stone and the light, and the constant sky.
//! Random numbers come from a hash (lapidary's Sobol batch and camera rays,
//! film accumulation and AOVs are not included). Samples whose camera ray
//! or bounce meets the stone, or whose camera ray sees the sky or the light,
//! are counted as "fallbacks" (lapidary's general loop would take them).
//!
//! Both versions do the same operations and print the same mean radiance.
use std::f64::consts::PI;
use std::time::Instant;

/// Lanes of the vector version (f64x4: one AVX2 register).
const L: usize = 4;
type V = [f64; L];

// The peer scene (bench/peer-scene.ron): light centre, radius, radiance;
// sky; ground albedo; the stone's inverse semi-axes; the camera position.
const C: [f64; 3] = [2.5, -2.0, 4.0];
const R: f64 = 0.25;
const LE: f64 = 500.0;
const ENV: f64 = 0.2;
const ALBEDO: f64 = 0.5;
const INV_AXES: [f64; 3] = [1.0, 1.0 / 0.7, 1.0 / 0.45];
const CAM: [f64; 3] = [0.0, -4.0957, 2.8679];
/// Height of a ground point above the plane (lapidary's ray offset).
const GROUND_OFFSET: f64 = 1e-9;

#[inline(always)]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}
#[inline(always)]
fn unit(i: u64, dim: u64) -> f64 {
    (mix(i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ dim) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}
#[inline(always)]
fn sincos_turns(t: f64) -> (f64, f64) {
    const ROUNDER: f64 = 6_755_399_441_055_744.0;
    let shifted = t * 4.0 + ROUNDER;
    let quarter = shifted - ROUNDER;
    let quadrant = shifted.to_bits() & 3;
    let x = (t - quarter * 0.25) * (2.0 * PI);
    let x2 = x * x;
    let s = -1.0 / 6.0
        + x2 * (1.0 / 120.0
            + x2 * (-1.0 / 5040.0
                + x2 * (1.0 / 362_880.0
                    + x2 * (-1.0 / 39_916_800.0 + x2 * (1.0 / 6_227_020_800.0)))));
    let c = -0.5
        + x2 * (1.0 / 24.0
            + x2 * (-1.0 / 720.0
                + x2 * (1.0 / 40_320.0
                    + x2 * (-1.0 / 3_628_800.0
                        + x2 * (1.0 / 479_001_600.0 + x2 * (-1.0 / 87_178_291_200.0))))));
    let sin = x * (1.0 + x2 * s);
    let cos = 1.0 + x2 * c;
    // (sin, cos) of q·π/2 + x, selected without branches
    let odd = quadrant & 1 == 1;
    let (s_abs, c_abs) = if odd { (cos, sin) } else { (sin, cos) };
    let s_sign = if quadrant >= 2 { -1.0 } else { 1.0 };
    let c_sign = if quadrant == 1 || quadrant == 2 {
        -1.0
    } else {
        1.0
    };
    (s_abs * s_sign, c_abs * c_sign)
}
#[inline(always)]
fn power(a: f64, b: f64) -> f64 {
    let (a, b) = (a * a, b * b);
    if a + b <= 0.0 {
        0.0
    } else {
        a / (a + b)
    }
}
/// Does the ray (o, d) cross the ellipsoid in (tmin, tmax)? (one stone)
#[inline(always)]
fn stone_crosses(o: [f64; 3], d: [f64; 3], tmin: f64, tmax: f64) -> bool {
    let os = [o[0] * INV_AXES[0], o[1] * INV_AXES[1], o[2] * INV_AXES[2]];
    let ds = [d[0] * INV_AXES[0], d[1] * INV_AXES[1], d[2] * INV_AXES[2]];
    let dd = ds[0] * ds[0] + ds[1] * ds[1] + ds[2] * ds[2];
    let od = os[0] * ds[0] + os[1] * ds[1] + os[2] * ds[2];
    let c = os[0] * os[0] + os[1] * os[1] + os[2] * os[2] - 1.0;
    let disc = od * od - dd * c;
    let sq = disc.max(0.0).sqrt();
    let t0 = (-od - sq) / dd;
    let t1 = (-od + sq) / dd;
    disc >= 0.0 && t1 > tmin && t0 < tmax
}
#[inline(always)]
fn sphere_entry(o: [f64; 3], d: [f64; 3]) -> f64 {
    let oc = [o[0] - C[0], o[1] - C[1], o[2] - C[2]];
    let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    let c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - R * R;
    let disc = b * b - c;
    let t = -b - disc.max(0.0).sqrt();
    if disc >= 0.0 && t > 0.0 {
        t
    } else {
        f64::INFINITY
    }
}

/// Next-event estimation at the ground point (px, py): the sphere light's
/// MIS-weighted contribution (0 below the ground or behind the stone) and
/// the cone's density, from the uniform numbers u0, u1. Written without
/// early returns, so that the lane loops of [`run_vector`] use it as it is.
#[inline(always)]
fn light_sample(px: f64, py: f64, u0: f64, u1: f64) -> (f64, f64) {
    let p = [px, py, GROUND_OFFSET];
    let to = [C[0] - p[0], C[1] - p[1], C[2] - p[2]];
    let d2 = to[0] * to[0] + to[1] * to[1] + to[2] * to[2];
    let dist_c = d2.sqrt();
    let axis = [to[0] / dist_c, to[1] / dist_c, to[2] / dist_c];
    let cos_max = (1.0 - R * R / d2).max(0.0).sqrt();
    let cos_theta = 1.0 - u0 * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (sp, cp) = sincos_turns(u1);
    let (pp, qq) = (sin_theta * cp, sin_theta * sp);
    let s = 1.0f64.copysign(axis[2]);
    let a = -1.0 / (s + axis[2]);
    let w = s * axis[0] * pp + axis[1] * qq;
    let m = a * w + cos_theta;
    let dir = [
        pp + axis[0] * m,
        s * qq + axis[1] * m,
        axis[2] * cos_theta - w,
    ];
    let reach = dist_c * cos_theta - (R * R - d2 * (1.0 - cos_theta * cos_theta)).max(0.0).sqrt();
    let pdf_l = 1.0 / (2.0 * PI * (1.0 - cos_max).max(1e-300));
    let lit = dir[2] > 0.0 && !stone_crosses(p, dir, 0.0, reach);
    let f = ALBEDO / PI;
    let bpdf = dir[2] / PI;
    let contribution = f * LE * dir[2] / pdf_l * power(pdf_l, bpdf);
    (if lit { contribution } else { 0.0 }, pdf_l)
}

/// The cosine-sampled bounce from the ground point (px, py), from u2, u3:
/// what it brings back (the light, MIS-weighted against `pdf_l`, or the
/// sky) and whether it meets the stone (a sample for the general path).
#[inline(always)]
fn bounce(px: f64, py: f64, u2: f64, u3: f64, pdf_l: f64) -> (f64, bool) {
    let p = [px, py, GROUND_OFFSET];
    let r = u2.sqrt();
    let (s3, c3) = sincos_turns(u3);
    let wi = [r * c3, r * s3, (1.0 - u2).max(0.0).sqrt()];
    let bpdf = wi[2] / PI;
    let blocked = stone_crosses(p, wi, 0.0, f64::INFINITY);
    let brought = if sphere_entry(p, wi).is_finite() {
        ALBEDO * LE * power(bpdf, pdf_l)
    } else {
        ALBEDO * ENV
    };
    (brought, blocked)
}

/// One ground sample: radiance, or NaN when it needs the general path.
#[inline(always)]
fn ground_sample(i: u64, d: [f64; 3]) -> f64 {
    let o = CAM;
    if d[2] >= 0.0 {
        return f64::NAN;
    }
    let t = -o[2] / d[2];
    if stone_crosses(o, d, 0.0, t) || sphere_entry(o, d) < t {
        return f64::NAN;
    }
    let (px, py) = (o[0] + d[0] * t, o[1] + d[1] * t);
    let (direct, pdf_l) = light_sample(px, py, unit(i, 1), unit(i, 2));
    let (brought, blocked) = bounce(px, py, unit(i, 3), unit(i, 4), pdf_l);
    if blocked {
        return f64::NAN;
    }
    direct + brought
}

#[target_feature(enable = "avx2,fma")]
unsafe fn run_scalar(dirs: &[[f64; 3]], base: u64) -> (f64, usize) {
    let mut sum = 0.0;
    let mut fallback = 0;
    for (k, d) in dirs.iter().enumerate() {
        let r = ground_sample(base + k as u64, *d);
        if r.is_nan() {
            fallback += 1
        } else {
            sum += r
        }
    }
    (sum, fallback)
}

#[target_feature(enable = "avx2,fma")]
unsafe fn run_vector(dirs: &[[f64; 3]], base: u64) -> (f64, usize) {
    let mut sum = 0.0;
    let mut fallback = 0;
    for (chunk_i, chunk) in dirs.chunks_exact(L).enumerate() {
        let mut out: V = [0.0; L];
        // each step over lanes, written as lane loops LLVM vectorises
        let mut dz: V = [0.0; L];
        let mut dx: V = [0.0; L];
        let mut dy: V = [0.0; L];
        for l in 0..L {
            dx[l] = chunk[l][0];
            dy[l] = chunk[l][1];
            dz[l] = chunk[l][2];
        }
        let mut ok = [true; L];
        let mut t: V = [0.0; L];
        for l in 0..L {
            t[l] = -CAM[2] / dz[l];
            ok[l] = dz[l] < 0.0;
        }
        let mut px: V = [0.0; L];
        let mut py: V = [0.0; L];
        for l in 0..L {
            px[l] = CAM[0] + dx[l] * t[l];
            py[l] = CAM[1] + dy[l] * t[l];
        }
        for l in 0..L {
            ok[l] &= !stone_crosses(CAM, [dx[l], dy[l], dz[l]], 0.0, t[l])
                && !(sphere_entry(CAM, [dx[l], dy[l], dz[l]]) < t[l]);
        }
        let i0 = base + (chunk_i * L) as u64;
        for l in 0..L {
            let i = i0 + l as u64;
            let (direct, pdf_l) = light_sample(px[l], py[l], unit(i, 1), unit(i, 2));
            let (brought, blocked) = bounce(px[l], py[l], unit(i, 3), unit(i, 4), pdf_l);
            ok[l] &= !blocked;
            out[l] = direct + brought;
        }
        for l in 0..L {
            if ok[l] {
                sum += out[l]
            } else {
                fallback += 1
            }
        }
    }
    (sum, fallback)
}

fn main() {
    // The polynomial sine and cosine agree with libm (the cost model is
    // only fair if the arithmetic is the real one).
    for k in 0..10_000 {
        let t = k as f64 / 10_000.0 - 0.5;
        let (s, c) = sincos_turns(t);
        let a = 2.0 * PI * t;
        assert!(
            (s - a.sin()).abs() < 1e-13 && (c - a.cos()).abs() < 1e-13,
            "sincos at {t}"
        );
    }
    let n: usize = std::env::var("N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4_000_000);
    // camera directions towards the ground around the stone's foot (2-8 units ahead)
    let dirs: Vec<[f64; 3]> = (0..n as u64)
        .map(|i| {
            let (a, b) = (unit(i, 7) - 0.5, unit(i, 8) - 0.5);
            let f = [0.0, 0.819, -0.574];
            let up = [0.0, 0.574, 0.819];
            let v = [
                a * 0.536,
                f[1] + b * 0.536 * up[1],
                f[2] + b * 0.536 * up[2],
            ];
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            [v[0] / len, v[1] / len, v[2] / len]
        })
        .collect();
    for round in 0..3 {
        let t = Instant::now();
        let (s1, f1) = unsafe { run_scalar(&dirs, 0) };
        let ts = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let (s2, f2) = unsafe { run_vector(&dirs, 0) };
        let tv = t.elapsed().as_secs_f64();
        println!("round {round}: scalar {:.1} ns/sample, vector {:.1} ns/sample, ratio {:.2}; sums {:.6} {:.6}, fallbacks {} {}", ts / n as f64 * 1e9, tv / n as f64 * 1e9, ts / tv, s1 / n as f64, s2 / n as f64, f1, f2);
    }
}
