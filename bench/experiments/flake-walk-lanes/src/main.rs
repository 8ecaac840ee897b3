//! The flake walk of `src/render/inclusions.rs` (`Inclusions::nearest`,
//! as of 2026-12-05) against the same walk testing four cells at a time
//! in AVX2 lanes, without a branch per cell. See README.md.

use std::arch::x86_64::*;
use std::f64::consts::PI;
use std::time::Instant;

const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;
const CELL_STRIDES: [u64; 3] = [
    0x9e37_79b9_7f4a_7c15,
    0xc2b2_ae3d_27d4_eb4f,
    0x1656_67b1_9e37_79f9,
];
const INV_2_POW_16: f64 = 1.0 / 65_536.0;
const INV_2_POW_21: f64 = 1.0 / (1u64 << 21) as f64;
const ROUNDER: f64 = 6_755_399_441_055_744.0;
const MAX_CELLS_WALKED: usize = 1 << 16;
const EARLY_EXIT: bool = option_env!("NO_EARLY_EXIT").is_none();

const fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn field_16(h: u64, k: u32) -> f64 {
    (f64::from((h >> (16 * k)) as u16) + 0.5) * INV_2_POW_16
}

const SIN_TERMS: [f64; 6] = [
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
    1.0 / 6_227_020_800.0,
];
const COS_TERMS: [f64; 7] = [
    -1.0 / 2.0,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
    -1.0 / 87_178_291_200.0,
];

/// lapidary's `sampling::sin_cos_turns`.
fn sin_cos_turns(t: f64) -> (f64, f64) {
    let shifted = t * 4.0 + ROUNDER;
    let (quarter, quadrant) = (shifted - ROUNDER, shifted.to_bits() & 3);
    let x = (t - quarter * 0.25) * (2.0 * PI);
    let x2 = x * x;
    let horner = |terms: &[f64]| {
        let (last, rest) = terms.split_last().unwrap();
        rest.iter().rev().fold(*last, |acc, c| c + x2 * acc)
    };
    let sin = x * (1.0 + x2 * horner(&SIN_TERMS));
    let cos = 1.0 + x2 * horner(&COS_TERMS);
    let odd = quadrant & 1 == 1;
    let (sin_abs, cos_abs) = if odd { (cos, sin) } else { (sin, cos) };
    (
        f64::from_bits(sin_abs.to_bits() ^ ((quadrant & 2) << 62)),
        f64::from_bits(cos_abs.to_bits() ^ (((quadrant + 1) & 2) << 62)),
    )
}

type V3 = [f64; 3];
fn dot(a: V3, b: V3) -> f64 {
    (a[0] * b[0]) + (a[1] * b[1]) + (a[2] * b[2])
}

/// One isotropic population of triangular flakes (goldstone's first).
struct Pop {
    cell_mm: f64,
    radius_mm: f64,
    size_spread: f64,
    seed_key: u64,
    /// (cos, sin) of the triangle's edge normals.
    edges: [(f64, f64); 3],
}

impl Pop {
    fn goldstone() -> Self {
        let edges = std::array::from_fn(|k| {
            let (s, c) = (90.0 + 120.0 * k as f64).to_radians().sin_cos();
            (c, s)
        });
        Pop {
            cell_mm: 150f64.powf(-1.0 / 3.0),
            radius_mm: 0.06,
            size_spread: 0.4,
            seed_key: mix64(1u64.wrapping_add(GOLDEN_GAMMA)),
            edges,
        }
    }

    fn crossing(&self, h: u64, centre: V3, radius: f64, o: V3, d: V3, t_max: f64) -> Option<(f64, V3)> {
        let q = [centre[0] - o[0], centre[1] - o[1], centre[2] - o[2]];
        let h2 = mix64(h.wrapping_add(GOLDEN_GAMMA));
        let (u, v, w) = (
            (h2 >> 43) as f64 * INV_2_POW_21,
            ((h2 >> 22) & ((1 << 21) - 1)) as f64 * INV_2_POW_21,
            ((h2 >> 1) & ((1 << 21) - 1)) as f64 * INV_2_POW_21,
        );
        let ct = 1.0 - 2.0 * u;
        let (sp, cp) = sin_cos_turns(v);
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        // The frame of +z: glam's any_orthonormal_pair of (0, 0, 1).
        let (tf, bf) = ([1.0, -0.0, -0.0], [-0.0, 1.0, -0.0]);
        let raw: V3 = std::array::from_fn(|i| tf[i] * (st * cp) + bf[i] * (st * sp) + [0.0, 0.0, 1.0][i] * ct);
        let inv = 1.0 / dot(raw, raw).sqrt();
        let n = raw.map(|x| x * inv);
        let along = dot(d, n);
        if along == 0.0 {
            return None;
        }
        let t = dot(q, n) / along;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        let e: V3 = std::array::from_fn(|i| o[i] + d[i] * t - centre[i]);
        if dot(e, e) > radius * radius {
            return None;
        }
        let sign = n[2].signum();
        let a = -1.0 / (sign + n[2]);
        let b = n[0] * n[1] * a;
        let a0 = [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]];
        let a1 = [b, sign + n[1] * n[1] * a, -n[1]];
        let (sw, cw) = sin_cos_turns(w);
        let e0: V3 = std::array::from_fn(|i| a0[i] * cw + a1[i] * sw);
        let e1: V3 = std::array::from_fn(|i| a1[i] * cw - a0[i] * sw);
        let (x, y) = (dot(e, e0), dot(e, e1));
        self.edges
            .iter()
            .all(|&(c, s)| x * c + y * s <= radius / 2.0)
            .then_some((t, n))
    }

    /// The walk's set-up: the start cell, its hash sum, t_next, t_delta,
    /// the steps and strides.
    fn start(&self, o: V3, d: V3) -> ([f64; 3], u64, [f64; 3], [f64; 3], [f64; 3], [u64; 3]) {
        let c = self.cell_mm;
        let scaled = o.map(|x| x / c);
        let cell = scaled.map(|x| {
            let tr = x as i64 as f64;
            tr - if tr > x { 1.0 } else { 0.0 }
        });
        let step: V3 = std::array::from_fn(|i| if d[i] >= 0.0 { 1.0 } else { -1.0 });
        let t_next: V3 = std::array::from_fn(|i| {
            let boundary = cell[i] + if step[i] > 0.0 { 1.0 } else { 0.0 };
            if d[i] != 0.0 {
                (boundary - scaled[i]) * c / d[i]
            } else {
                f64::INFINITY
            }
        });
        let t_delta: V3 =
            std::array::from_fn(|i| if d[i] != 0.0 { c / d[i].abs() } else { f64::INFINITY });
        let stride: [u64; 3] = std::array::from_fn(|i| {
            CELL_STRIDES[i].wrapping_mul(if step[i] > 0.0 { 1 } else { u64::MAX })
        });
        let sum = (0..3).fold(self.seed_key, |sum, i| {
            sum.wrapping_add((cell[i] as i64 as u64).wrapping_mul(CELL_STRIDES[i]))
        });
        (cell, sum, t_next, t_delta, step, stride)
    }

    /// Today's walk: scalars, a branch per step and per sphere test.
    fn nearest(&self, o: V3, d: V3, t_max: f64, cells: &mut u64) -> Option<(f64, V3)> {
        let (cell, mut sum, t_next, t_delta, step, stride) = self.start(o, d);
        let [mut tx, mut ty, mut tz] = t_next;
        let [mut cx, mut cy, mut cz] = cell;
        let c = self.cell_mm;
        let mut t_enter = 0.0;
        for _ in 0..MAX_CELLS_WALKED {
            if t_enter >= t_max {
                return None;
            }
            *cells += 1;
            let h = mix64(sum);
            let radius = self.radius_mm * (1.0 + self.size_spread * (2.0 * field_16(h, 0) - 1.0));
            let span = c - 2.0 * radius;
            let p = [
                cx * c + radius + field_16(h, 1) * span,
                cy * c + radius + field_16(h, 2) * span,
                cz * c + radius + field_16(h, 3) * span,
            ];
            let q = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            let closest = q[0] * d[0] + q[1] * d[1] + q[2] * d[2];
            if q[0] * q[0] + q[1] * q[1] + q[2] * q[2] - closest * closest <= radius * radius {
                if let Some(hit) = self.crossing(h, p, radius, o, d, t_max) {
                    return Some(hit);
                }
            }
            if tx <= ty && tx <= tz {
                t_enter = tx;
                tx += t_delta[0];
                cx += step[0];
                sum = sum.wrapping_add(stride[0]);
            } else if ty <= tz {
                t_enter = ty;
                ty += t_delta[1];
                cy += step[1];
                sum = sum.wrapping_add(stride[1]);
            } else {
                t_enter = tz;
                tz += t_delta[2];
                cz += step[2];
                sum = sum.wrapping_add(stride[2]);
            }
        }
        None
    }

    /// Four cells at a time: the steps by masks (scalar), then the whole
    /// test of the four cells in AVX2 lanes, the same operations in the
    /// same order per lane (no FMA), and one branch per four cells.
    #[target_feature(enable = "avx2")]
    unsafe fn nearest_lanes(&self, o: V3, d: V3, t_max: f64, cells: &mut u64) -> Option<(f64, V3)> {
        let (cell, mut sum, t_next, t_delta, step, stride) = self.start(o, d);
        let [mut tx, mut ty, mut tz] = t_next;
        let [mut cx, mut cy, mut cz] = cell;
        let mut t_enter = 0.0;
        let s = _mm256_set1_pd;
        let (add, sub, mul, div) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd, _mm256_div_pd);
        let le = |a, b| _mm256_cmp_pd::<_CMP_LE_OQ>(a, b);
        // u64 lanes below 2^52 as f64, exactly.
        let magic = _mm256_set1_epi64x(0x4330_0000_0000_0000);
        let to_f64 = |v: __m256i| sub(_mm256_castsi256_pd(_mm256_or_si256(v, magic)), s(4_503_599_627_370_496.0));
        // 64-bit product mod 2^64 with a constant.
        let mul64 = |a: __m256i, k: u64| {
            let kv = _mm256_set1_epi64x(k as i64);
            let lo = _mm256_mul_epu32(a, kv);
            let cross = _mm256_add_epi64(
                _mm256_mul_epu32(_mm256_srli_epi64::<32>(a), kv),
                _mm256_mul_epu32(a, _mm256_srli_epi64::<32>(kv)),
            );
            _mm256_add_epi64(lo, _mm256_slli_epi64::<32>(cross))
        };
        let xorshift = |z: __m256i, k: i32| match k {
            30 => _mm256_xor_si256(z, _mm256_srli_epi64::<30>(z)),
            27 => _mm256_xor_si256(z, _mm256_srli_epi64::<27>(z)),
            _ => _mm256_xor_si256(z, _mm256_srli_epi64::<31>(z)),
        };
        let sin_cos = |t: __m256d| {
            let shifted = add(mul(t, s(4.0)), s(ROUNDER));
            let quarter = sub(shifted, s(ROUNDER));
            let quadrant = _mm256_and_si256(_mm256_castpd_si256(shifted), _mm256_set1_epi64x(3));
            let x = mul(sub(t, mul(quarter, s(0.25))), s(2.0 * PI));
            let x2 = mul(x, x);
            let mut hs = s(SIN_TERMS[5]);
            for c in SIN_TERMS[..5].iter().rev() {
                hs = add(s(*c), mul(x2, hs));
            }
            let mut hc = s(COS_TERMS[6]);
            for c in COS_TERMS[..6].iter().rev() {
                hc = add(s(*c), mul(x2, hc));
            }
            let sin = mul(x, add(s(1.0), mul(x2, hs)));
            let cos = add(s(1.0), mul(x2, hc));
            let odd = _mm256_castsi256_pd(_mm256_cmpeq_epi64(
                _mm256_and_si256(quadrant, _mm256_set1_epi64x(1)),
                _mm256_set1_epi64x(1),
            ));
            let sin_abs = _mm256_blendv_pd(sin, cos, odd);
            let cos_abs = _mm256_blendv_pd(cos, sin, odd);
            let two = _mm256_set1_epi64x(2);
            let sin_flip = _mm256_slli_epi64::<62>(_mm256_and_si256(quadrant, two));
            let cos_flip = _mm256_slli_epi64::<62>(_mm256_and_si256(
                _mm256_add_epi64(quadrant, _mm256_set1_epi64x(1)),
                two,
            ));
            (
                _mm256_xor_pd(sin_abs, _mm256_castsi256_pd(sin_flip)),
                _mm256_xor_pd(cos_abs, _mm256_castsi256_pd(cos_flip)),
            )
        };
        let c = self.cell_mm;
        for _ in 0..MAX_CELLS_WALKED / 4 {
            let mut h = [0u64; 4];
            let mut corner = [[0.0f64; 4]; 3];
            let mut open = [0.0f64; 4];
            for k in 0..4 {
                h[k] = mix64(sum);
                corner[0][k] = cx;
                corner[1][k] = cy;
                corner[2][k] = cz;
                open[k] = f64::from_bits(u64::from(t_enter < t_max).wrapping_neg());
                *cells += u64::from(t_enter < t_max);
                let x_next = tx <= ty && tx <= tz;
                let y_next = !x_next && ty <= tz;
                let z_next = !x_next && !y_next;
                let [mx, my, mz] = [x_next, y_next, z_next].map(|n| u64::from(n).wrapping_neg());
                let m = |v: f64, mask: u64| f64::from_bits(v.to_bits() & mask);
                t_enter = m(tx, mx) + m(ty, my) + m(tz, mz);
                tx += m(t_delta[0], mx);
                ty += m(t_delta[1], my);
                tz += m(t_delta[2], mz);
                cx += m(step[0], mx);
                cy += m(step[1], my);
                cz += m(step[2], mz);
                sum = sum
                    .wrapping_add(stride[0] & mx)
                    .wrapping_add(stride[1] & my)
                    .wrapping_add(stride[2] & mz);
            }
            let hv = _mm256_loadu_si256(h.as_ptr().cast());
            let field = |shifted: __m256i| {
                mul(
                    add(to_f64(_mm256_and_si256(shifted, _mm256_set1_epi64x(0xffff))), s(0.5)),
                    s(INV_2_POW_16),
                )
            };
            let f0 = field(hv);
            let f1 = field(_mm256_srli_epi64::<16>(hv));
            let f2 = field(_mm256_srli_epi64::<32>(hv));
            let f3 = field(_mm256_srli_epi64::<48>(hv));
            let radius = mul(s(self.radius_mm), add(s(1.0), mul(s(self.size_spread), sub(mul(s(2.0), f0), s(1.0)))));
            let span = sub(s(c), mul(s(2.0), radius));
            let load = |a: &[f64; 4]| _mm256_loadu_pd(a.as_ptr());
            let px = add(add(mul(load(&corner[0]), s(c)), radius), mul(f1, span));
            let py = add(add(mul(load(&corner[1]), s(c)), radius), mul(f2, span));
            let pz = add(add(mul(load(&corner[2]), s(c)), radius), mul(f3, span));
            let (qx, qy, qz) = (sub(px, s(o[0])), sub(py, s(o[1])), sub(pz, s(o[2])));
            let dot3 = |ax, ay, az, bx, by, bz| add(add(mul(ax, bx), mul(ay, by)), mul(az, bz));
            let (dx, dy, dz) = (s(d[0]), s(d[1]), s(d[2]));
            let closest = dot3(qx, qy, qz, dx, dy, dz);
            let r2 = mul(radius, radius);
            let near = le(sub(dot3(qx, qy, qz, qx, qy, qz), mul(closest, closest)), r2);
            let mut mask = _mm256_and_pd(near, load(&open));
            if EARLY_EXIT && _mm256_movemask_pd(mask) == 0 {
                if t_enter >= t_max {
                    return None;
                }
                continue;
            }
            // derive_stream(h, 0) = mix64(h + γ).
            let mut z = _mm256_add_epi64(hv, _mm256_set1_epi64x(GOLDEN_GAMMA as i64));
            z = mul64(xorshift(z, 30), 0xbf58_476d_1ce4_e5b9);
            z = mul64(xorshift(z, 27), 0x94d0_49bb_1331_11eb);
            let h2 = xorshift(z, 31);
            let m21 = _mm256_set1_epi64x((1 << 21) - 1);
            let u = mul(to_f64(_mm256_srli_epi64::<43>(h2)), s(INV_2_POW_21));
            let v = mul(to_f64(_mm256_and_si256(_mm256_srli_epi64::<22>(h2), m21)), s(INV_2_POW_21));
            let w = mul(to_f64(_mm256_and_si256(_mm256_srli_epi64::<1>(h2), m21)), s(INV_2_POW_21));
            let ct = sub(s(1.0), mul(s(2.0), u));
            let (sp, cp) = sin_cos(v);
            let st = _mm256_sqrt_pd(_mm256_max_pd(sub(s(1.0), mul(ct, ct)), s(0.0)));
            let (stc, sts) = (mul(st, cp), mul(st, sp));
            // t = (1, −0, −0), b = (−0, 1, −0), axis = (0, 0, 1).
            let rx = add(add(mul(s(1.0), stc), mul(s(-0.0), sts)), mul(s(0.0), ct));
            let ry = add(add(mul(s(-0.0), stc), mul(s(1.0), sts)), mul(s(0.0), ct));
            let rz = add(add(mul(s(-0.0), stc), mul(s(-0.0), sts)), mul(s(1.0), ct));
            let inv = div(s(1.0), _mm256_sqrt_pd(dot3(rx, ry, rz, rx, ry, rz)));
            let (nx, ny, nz) = (mul(rx, inv), mul(ry, inv), mul(rz, inv));
            let along = dot3(dx, dy, dz, nx, ny, nz);
            let t = div(dot3(qx, qy, qz, nx, ny, nz), along);
            mask = _mm256_and_pd(mask, _mm256_cmp_pd::<_CMP_NEQ_UQ>(along, s(0.0)));
            mask = _mm256_and_pd(mask, _mm256_cmp_pd::<_CMP_GT_OQ>(t, s(0.0)));
            mask = _mm256_and_pd(mask, _mm256_cmp_pd::<_CMP_LT_OQ>(t, s(t_max)));
            let ex = sub(add(s(o[0]), mul(dx, t)), px);
            let ey = sub(add(s(o[1]), mul(dy, t)), py);
            let ez = sub(add(s(o[2]), mul(dz, t)), pz);
            mask = _mm256_and_pd(mask, le(dot3(ex, ey, ez, ex, ey, ez), r2));
            let sign = _mm256_or_pd(_mm256_and_pd(nz, s(-0.0)), s(1.0));
            let a = div(s(-1.0), add(sign, nz));
            let b = mul(mul(nx, ny), a);
            let neg_sign = _mm256_xor_pd(sign, s(-0.0));
            let a0 = [add(s(1.0), mul(mul(mul(sign, nx), nx), a)), mul(sign, b), mul(neg_sign, nx)];
            let a1 = [b, add(sign, mul(mul(ny, ny), a)), _mm256_xor_pd(ny, s(-0.0))];
            let (sw, cw) = sin_cos(w);
            let e0: [__m256d; 3] = std::array::from_fn(|i| add(mul(a0[i], cw), mul(a1[i], sw)));
            let e1: [__m256d; 3] = std::array::from_fn(|i| sub(mul(a1[i], cw), mul(a0[i], sw)));
            let x = dot3(ex, ey, ez, e0[0], e0[1], e0[2]);
            let y = dot3(ex, ey, ez, e1[0], e1[1], e1[2]);
            let apothem = div(radius, s(2.0));
            for &(ce, se) in &self.edges {
                mask = _mm256_and_pd(mask, le(add(mul(x, s(ce)), mul(y, s(se))), apothem));
            }
            let bits = _mm256_movemask_pd(mask);
            if bits != 0 {
                let k = bits.trailing_zeros() as usize;
                let lane = |v: __m256d| {
                    let mut a = [0.0; 4];
                    _mm256_storeu_pd(a.as_mut_ptr(), v);
                    a[k]
                };
                return Some((lane(t), [lane(nx), lane(ny), lane(nz)]));
            }
            if t_enter >= t_max {
                return None;
            }
        }
        None
    }
}

fn main() {
    assert!(is_x86_feature_detected!("avx2"), "needs AVX2");
    let n: usize = std::env::var("N").ok().and_then(|v| v.parse().ok()).unwrap_or(200_000);
    let pop = Pop::goldstone();
    // Rays from random points of a 10 × 8 × 4 mm box, random directions,
    // lengths 0.5–6 mm (a stone's chords).
    let mut state = 12345u64;
    let mut next = || {
        state = state.wrapping_add(GOLDEN_GAMMA);
        (mix64(state) >> 11) as f64 / (1u64 << 53) as f64
    };
    let rays: Vec<(V3, V3, f64)> = (0..n)
        .map(|_| {
            let o = [10.0 * next() - 5.0, 8.0 * next() - 4.0, 4.0 * next()];
            let z = 2.0 * next() - 1.0;
            let phi = 2.0 * PI * next();
            let r = (1.0 - z * z).sqrt();
            (o, [r * phi.cos(), r * phi.sin(), z], 0.5 + 5.5 * next())
        })
        .collect();
    // The same hits, bit for bit.
    let (mut cells_a, mut cells_b, mut hits) = (0u64, 0u64, 0u64);
    for &(o, d, t) in &rays {
        let a = pop.nearest(o, d, t, &mut cells_a);
        let b = unsafe { pop.nearest_lanes(o, d, t, &mut cells_b) };
        let bits = |h: Option<(f64, V3)>| h.map(|(t, n)| (t.to_bits(), n.map(f64::to_bits)));
        assert_eq!(bits(a), bits(b), "ray {o:?} {d:?} {t}");
        hits += u64::from(a.is_some());
    }
    println!("{n} rays, {hits} hits, {cells_a} cells walked (lanes: {cells_b} tested)");
    for round in 0..3 {
        let mut cells = 0;
        let start = Instant::now();
        let mut checksum = 0.0;
        for &(o, d, t) in &rays {
            checksum += pop.nearest(o, d, t, &mut cells).map_or(0.0, |h| h.0);
        }
        let scalar = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let mut cells_l = 0;
        for &(o, d, t) in &rays {
            checksum -= unsafe { pop.nearest_lanes(o, d, t, &mut cells_l) }.map_or(0.0, |h| h.0);
        }
        let lanes = start.elapsed().as_secs_f64();
        println!(
            "round {round}: today's walk {:.1} ns a cell, four lanes {:.1} ns a cell ({:.3}x), checksum {checksum}",
            scalar * 1e9 / cells as f64,
            lanes * 1e9 / cells as f64,
            lanes / scalar
        );
    }
}
