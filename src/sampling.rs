//! Deterministic random numbers and hemisphere warps shared by the BRDF
//! estimators and (later) the renderer.
//!
//! Every estimator in lapidary is a pure function of its seed: there is no
//! global RNG. [`Rng`] is SplitMix64 (Steele, Lea & Flood 2014), small,
//! fast, and identical on every platform.

use glam::DVec3;
use std::f64::consts::PI;

/// A SplitMix64 generator: a 64-bit counter passed through a strong mixer.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator for one independent stream, e.g. `Rng::new(seed, angle_index)`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Rng {
            state: seed ^ mix64(stream.wrapping_add(0x632b_e59b_d9b4_e019)),
        };
        rng.next_u64();
        rng
    }

    /// The next 64 uniformly distributed bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// A uniform number in [0, 1) with 53 bits of precision.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Three uniform numbers, the argument every `sample` function takes.
    pub fn next_3(&mut self) -> [f64; 3] {
        [self.next_f64(), self.next_f64(), self.next_f64()]
    }
}

/// The SplitMix64 output mixer (a bijection on u64 with full avalanche).
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Cosine-weighted direction on the upper hemisphere (z up); pdf = cosθ/π.
pub fn cosine_hemisphere(u1: f64, u2: f64) -> DVec3 {
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    DVec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Density of [`cosine_hemisphere`] with respect to solid angle.
pub fn cosine_hemisphere_pdf(w: DVec3) -> f64 {
    if w.z > 0.0 {
        w.z / PI
    } else {
        0.0
    }
}

/// Unit direction from spherical angles in degrees (θ from the normal z, φ from x).
pub fn direction_from_degrees(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}
