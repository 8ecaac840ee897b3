//! TEMPORARY STUB (replaced by the environment module from wt-env).
use crate::brdf::Rgb;
use glam::DVec3;
/// stub
pub enum Environment {
    /// stub
    Constant(Rgb),
}
/// stub
pub struct EnvironmentSample {
    /// stub
    pub direction: DVec3,
    /// stub
    pub radiance: Rgb,
    /// stub
    pub pdf: f64,
}
impl Environment {
    /// stub
    pub fn radiance(&self, _d: DVec3) -> Rgb {
        match self {
            Environment::Constant(c) => *c,
        }
    }
    /// stub
    pub fn pdf(&self, _d: DVec3) -> f64 {
        1.0 / (4.0 * std::f64::consts::PI)
    }
    /// stub
    pub fn sample(&self, u: [f64; 2]) -> Option<EnvironmentSample> {
        let z = 1.0 - 2.0 * u[0];
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u[1];
        let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
        Some(EnvironmentSample {
            direction: d,
            radiance: self.radiance(d),
            pdf: self.pdf(d),
        })
    }
}
