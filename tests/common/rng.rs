//! Deterministic test randomness (xorshift64*), independent of the
//! library's own hashes, so a test's inputs never share a bug with the code
//! under test.

use glam::DVec3;

/// A xorshift64* stream; the state must not be zero.
pub struct TestRng(pub u64);

impl TestRng {
    /// Uniform in [0, 1) with 53 random bits.
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [low, high).
    pub fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }

    /// Uniform in the box [lo, hi).
    pub fn point_in(&mut self, lo: DVec3, hi: DVec3) -> DVec3 {
        DVec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }

    /// Uniform in the cube [-half_extent, half_extent)³.
    pub fn cube(&mut self, half_extent: f64) -> DVec3 {
        self.point_in(DVec3::splat(-half_extent), DVec3::splat(half_extent))
    }

    /// A unit vector, uniform over the sphere (rejection from the cube,
    /// keeping lengths in (0.1, 1] so the normalisation is well conditioned).
    pub fn direction(&mut self) -> DVec3 {
        loop {
            let v = self.cube(1.0);
            let len = v.length();
            if len > 0.1 && len <= 1.0 {
                return v / len;
            }
        }
    }
}
