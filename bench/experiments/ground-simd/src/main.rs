//! A measurement for issue 6 (not part of lapidary; see README.md): what a
//! lean, straight-line path kernel costs for a *ground* sample of the peer
//! scene, one lane at a time and several lanes at a time, in f64 (as
//! lapidary computes) and in f32 (as Mitsuba's `llvm_ad_rgb` does).
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
//! The kernel is written once, generic over the float type ([`Real`]); the
//! one-lane and the many-lane versions do the same operations, so for one
//! float type they print the same mean radiance.
use std::f64::consts::PI;
use std::ops::{Add, Div, Mul, Neg, Sub};
use std::time::Instant;

/// The float type of a kernel: f64 (lapidary) or f32 (Mitsuba's LLVM
/// variant). Only what the kernel needs.
trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Lanes of this type in one AVX2 register (4 × f64, 8 × f32).
    const LANES: usize;
    /// 1.5 · 2^(mantissa bits): adding it rounds to an integer, whose low
    /// bits are then the integer's (the quadrant of `sincos_turns`).
    const ROUNDER: Self;
    /// The smallest positive normal number (a density's floor).
    const TINY: Self;
    fn of(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn sqrt(self) -> Self;
    fn max(self, other: Self) -> Self;
    fn copysign(self, sign: Self) -> Self;
    /// The two lowest bits of the representation.
    fn low_bits(self) -> u32;
}

/// `Real` for a primitive float `$t` with `$lanes` lanes to an AVX2
/// register and the rounding constant 1.5 · 2^(mantissa bits).
macro_rules! impl_real {
    ($t:ident, $lanes:expr, $rounder:expr) => {
        impl Real for $t {
            const LANES: usize = $lanes;
            const ROUNDER: $t = $rounder;
            const TINY: $t = $t::MIN_POSITIVE;
            fn of(x: f64) -> $t {
                x as $t
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn sqrt(self) -> $t {
                $t::sqrt(self)
            }
            fn max(self, other: $t) -> $t {
                $t::max(self, other)
            }
            fn copysign(self, sign: $t) -> $t {
                $t::copysign(self, sign)
            }
            fn low_bits(self) -> u32 {
                (self.to_bits() & 3) as u32
            }
        }
    };
}
impl_real!(f64, 4, 6_755_399_441_055_744.0);
impl_real!(f32, 8, 12_582_912.0);

/// The most lanes of any [`Real`] (the size of the lane arrays).
const MAX_LANES: usize = 8;

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
fn v3<T: Real>(v: [f64; 3]) -> [T; 3] {
    v.map(T::of)
}

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
/// A uniform number below 1 in `T` (rounding to f32 can reach 1.0).
#[inline(always)]
fn unit_in<T: Real>(i: u64, dim: u64) -> T {
    let u = T::of(unit(i, dim));
    if u < T::of(1.0) {
        u
    } else {
        T::of(0.0)
    }
}
#[inline(always)]
fn sincos_turns<T: Real>(t: T) -> (T, T) {
    let shifted = t * T::of(4.0) + T::ROUNDER;
    let quarter = shifted - T::ROUNDER;
    let quadrant = shifted.low_bits();
    let x = (t - quarter * T::of(0.25)) * T::of(2.0 * PI);
    let x2 = x * x;
    let k = T::of;
    let s = k(-1.0 / 6.0)
        + x2 * (k(1.0 / 120.0)
            + x2 * (k(-1.0 / 5040.0)
                + x2 * (k(1.0 / 362_880.0)
                    + x2 * (k(-1.0 / 39_916_800.0) + x2 * k(1.0 / 6_227_020_800.0)))));
    let c = k(-0.5)
        + x2 * (k(1.0 / 24.0)
            + x2 * (k(-1.0 / 720.0)
                + x2 * (k(1.0 / 40_320.0)
                    + x2 * (k(-1.0 / 3_628_800.0)
                        + x2 * (k(1.0 / 479_001_600.0) + x2 * k(-1.0 / 87_178_291_200.0))))));
    let sin = x * (k(1.0) + x2 * s);
    let cos = k(1.0) + x2 * c;
    // (sin, cos) of q·π/2 + x, selected without branches
    let odd = quadrant & 1 == 1;
    let (s_abs, c_abs) = if odd { (cos, sin) } else { (sin, cos) };
    let s_sign = if quadrant >= 2 { k(-1.0) } else { k(1.0) };
    let c_sign = if quadrant == 1 || quadrant == 2 {
        k(-1.0)
    } else {
        k(1.0)
    };
    (s_abs * s_sign, c_abs * c_sign)
}
#[inline(always)]
fn power<T: Real>(a: T, b: T) -> T {
    let (a, b) = (a * a, b * b);
    if a + b <= T::of(0.0) {
        T::of(0.0)
    } else {
        a / (a + b)
    }
}
#[inline(always)]
fn dot<T: Real>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// Does the ray (o, d) cross the ellipsoid in (tmin, tmax)? (one stone)
#[inline(always)]
fn stone_crosses<T: Real>(o: [T; 3], d: [T; 3], tmin: T, tmax: T) -> bool {
    let inv: [T; 3] = v3(INV_AXES);
    let os = [o[0] * inv[0], o[1] * inv[1], o[2] * inv[2]];
    let ds = [d[0] * inv[0], d[1] * inv[1], d[2] * inv[2]];
    let dd = dot(ds, ds);
    let od = dot(os, ds);
    let c = dot(os, os) - T::of(1.0);
    let disc = od * od - dd * c;
    let sq = disc.max(T::of(0.0)).sqrt();
    let t0 = (-od - sq) / dd;
    let t1 = (-od + sq) / dd;
    disc >= T::of(0.0) && t1 > tmin && t0 < tmax
}
#[inline(always)]
fn sphere_entry<T: Real>(o: [T; 3], d: [T; 3]) -> T {
    let centre: [T; 3] = v3(C);
    let oc = [o[0] - centre[0], o[1] - centre[1], o[2] - centre[2]];
    let b = dot(oc, d);
    let c = dot(oc, oc) - T::of(R * R);
    let disc = b * b - c;
    let t = -b - disc.max(T::of(0.0)).sqrt();
    if disc >= T::of(0.0) && t > T::of(0.0) {
        t
    } else {
        T::of(f64::INFINITY)
    }
}

/// Next-event estimation at the ground point (px, py): the sphere light's
/// MIS-weighted contribution (0 below the ground or behind the stone) and
/// the cone's density, from the uniform numbers u0, u1. Written without
/// early returns, so that the lane loops of [`run_lanes`] use it as it is.
#[inline(always)]
fn light_sample<T: Real>(px: T, py: T, u0: T, u1: T) -> (T, T) {
    let k = T::of;
    let (centre, r2) = (v3::<T>(C), k(R * R));
    let p = [px, py, k(GROUND_OFFSET)];
    let to = [centre[0] - p[0], centre[1] - p[1], centre[2] - p[2]];
    let d2 = dot(to, to);
    let dist_c = d2.sqrt();
    let axis = [to[0] / dist_c, to[1] / dist_c, to[2] / dist_c];
    let cos_max = (k(1.0) - r2 / d2).max(k(0.0)).sqrt();
    let cos_theta = k(1.0) - u0 * (k(1.0) - cos_max);
    let sin_theta = (k(1.0) - cos_theta * cos_theta).max(k(0.0)).sqrt();
    let (sp, cp) = sincos_turns(u1);
    let (pp, qq) = (sin_theta * cp, sin_theta * sp);
    let s = k(1.0).copysign(axis[2]);
    let a = -k(1.0) / (s + axis[2]);
    let w = s * axis[0] * pp + axis[1] * qq;
    let m = a * w + cos_theta;
    let dir = [
        pp + axis[0] * m,
        s * qq + axis[1] * m,
        axis[2] * cos_theta - w,
    ];
    let reach = dist_c * cos_theta
        - (r2 - d2 * (k(1.0) - cos_theta * cos_theta))
            .max(k(0.0))
            .sqrt();
    let pdf_l = k(1.0) / (k(2.0 * PI) * (k(1.0) - cos_max).max(T::TINY));
    let lit = dir[2] > k(0.0) && !stone_crosses(p, dir, k(0.0), reach);
    let f = k(ALBEDO / PI);
    let bpdf = dir[2] / k(PI);
    let contribution = f * k(LE) * dir[2] / pdf_l * power(pdf_l, bpdf);
    (if lit { contribution } else { k(0.0) }, pdf_l)
}

/// The cosine-sampled bounce from the ground point (px, py), from u2, u3:
/// what it brings back (the light, MIS-weighted against `pdf_l`, or the
/// sky) and whether it meets the stone (a sample for the general path).
#[inline(always)]
fn bounce<T: Real>(px: T, py: T, u2: T, u3: T, pdf_l: T) -> (T, bool) {
    let k = T::of;
    let p = [px, py, k(GROUND_OFFSET)];
    let r = u2.sqrt();
    let (s3, c3) = sincos_turns(u3);
    let wi = [r * c3, r * s3, (k(1.0) - u2).max(k(0.0)).sqrt()];
    let bpdf = wi[2] / k(PI);
    let blocked = stone_crosses(p, wi, k(0.0), k(f64::INFINITY));
    let brought = if sphere_entry(p, wi) < k(f64::INFINITY) {
        k(ALBEDO * LE) * power(bpdf, pdf_l)
    } else {
        k(ALBEDO * ENV)
    };
    (brought, blocked)
}

/// Whether the camera ray along `d` hits the open ground (not the stone,
/// not the light) and where: (ok, px, py).
#[inline(always)]
fn camera_ground<T: Real>(d: [T; 3]) -> (bool, T, T) {
    let o: [T; 3] = v3(CAM);
    let t = -o[2] / d[2];
    let ok = d[2] < T::of(0.0) && !stone_crosses(o, d, T::of(0.0), t) && sphere_entry(o, d) >= t;
    (ok, o[0] + d[0] * t, o[1] + d[1] * t)
}

/// One ground sample: radiance, or None when it needs the general path.
#[inline(always)]
fn ground_sample<T: Real>(i: u64, d: [T; 3]) -> Option<T> {
    let (ok, px, py) = camera_ground(d);
    if !ok {
        return None;
    }
    let (direct, pdf_l) = light_sample(px, py, unit_in(i, 1), unit_in(i, 2));
    let (brought, blocked) = bounce(px, py, unit_in(i, 3), unit_in(i, 4), pdf_l);
    (!blocked).then_some(direct + brought)
}

/// The samples one at a time: (sum of radiance, fallbacks).
#[inline(always)]
fn run_one_by_one<T: Real>(dirs: &[[T; 3]]) -> (f64, usize) {
    let mut sum = 0.0;
    let mut fallback = 0;
    for (k, d) in dirs.iter().enumerate() {
        match ground_sample(k as u64, *d) {
            Some(r) => sum += r.to_f64(),
            None => fallback += 1,
        }
    }
    (sum, fallback)
}

/// The samples `T::LANES` at a time, each step over the lanes written as a
/// lane loop that LLVM compiles to AVX2 `ymm` arithmetic (blends instead of
/// branches): (sum of radiance, fallbacks).
#[inline(always)]
fn run_lanes<T: Real>(dirs: &[[T; 3]]) -> (f64, usize) {
    let lanes = T::LANES;
    let zero = T::of(0.0);
    let mut sum = 0.0;
    let mut fallback = 0;
    for (chunk_i, chunk) in dirs.chunks_exact(lanes).enumerate() {
        let mut ok = [true; MAX_LANES];
        let mut px = [zero; MAX_LANES];
        let mut py = [zero; MAX_LANES];
        for l in 0..lanes {
            (ok[l], px[l], py[l]) = camera_ground(chunk[l]);
        }
        let mut out = [zero; MAX_LANES];
        let i0 = (chunk_i * lanes) as u64;
        for l in 0..lanes {
            let i = i0 + l as u64;
            let (direct, pdf_l) = light_sample(px[l], py[l], unit_in(i, 1), unit_in(i, 2));
            let (brought, blocked) = bounce(px[l], py[l], unit_in(i, 3), unit_in(i, 4), pdf_l);
            ok[l] &= !blocked;
            out[l] = direct + brought;
        }
        for l in 0..lanes {
            if ok[l] {
                sum += out[l].to_f64()
            } else {
                fallback += 1
            }
        }
    }
    (sum, fallback)
}

/// [`run_one_by_one`] compiled with AVX2 and FMA enabled.
#[target_feature(enable = "avx2,fma")]
unsafe fn one_by_one_avx2<T: Real>(dirs: &[[T; 3]]) -> (f64, usize) {
    run_one_by_one(dirs)
}
/// [`run_lanes`] compiled with AVX2 and FMA enabled.
#[target_feature(enable = "avx2,fma")]
unsafe fn lanes_avx2<T: Real>(dirs: &[[T; 3]]) -> (f64, usize) {
    run_lanes(dirs)
}

/// Nanoseconds per sample of `run`, its mean radiance and its fallbacks.
fn timed(n: usize, run: impl FnOnce() -> (f64, usize)) -> (f64, f64, usize) {
    let start = Instant::now();
    let (sum, fallbacks) = run();
    (
        start.elapsed().as_secs_f64() / n as f64 * 1e9,
        sum / n as f64,
        fallbacks,
    )
}

fn main() {
    // The polynomial sine and cosine agree with libm (the cost model is
    // only fair if the arithmetic is the real one).
    for k in 0..10_000 {
        let t = k as f64 / 10_000.0 - 0.5;
        let a = 2.0 * PI * t;
        let (s, c) = sincos_turns(t);
        assert!(
            (s - a.sin()).abs() < 1e-13 && (c - a.cos()).abs() < 1e-13,
            "sincos at {t}"
        );
        let (s, c) = sincos_turns(t as f32);
        assert!(
            (f64::from(s) - a.sin()).abs() < 1e-6 && (f64::from(c) - a.cos()).abs() < 1e-6,
            "f32 sincos at {t}"
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
    let dirs32: Vec<[f32; 3]> = dirs.iter().map(|d| d.map(|x| x as f32)).collect();
    for round in 0..3 {
        // SAFETY: the four kernels need AVX2 and FMA, which every x86-64
        // machine this measurement is run on has (checked below).
        assert!(is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"));
        let s64 = timed(n, || unsafe { one_by_one_avx2(&dirs) });
        let v64 = timed(n, || unsafe { lanes_avx2(&dirs) });
        let s32 = timed(n, || unsafe { one_by_one_avx2(&dirs32) });
        let v32 = timed(n, || unsafe { lanes_avx2(&dirs32) });
        println!(
            "round {round}: ns/sample f64 one lane {:.1}, f64x4 {:.1} ({:.2}x), f32 one lane {:.1}, f32x8 {:.1} ({:.2}x; f32x8 / f64x4 {:.2}x)",
            s64.0, v64.0, s64.0 / v64.0, s32.0, v32.0, s32.0 / v32.0, v64.0 / v32.0
        );
        println!(
            "         mean radiance {:.9} {:.9} | {:.9} {:.9} (f32 - f64: {:.1e}); fallbacks {} {} | {} {}",
            s64.1, v64.1, s32.1, v32.1, s32.1 - s64.1, s64.2, v64.2, s32.2, v32.2
        );
    }
}
