//! Pixel footprints as ray cones (Amanatides 1984; Akenine-Möller et al.
//! 2021), and when the flakes in one are too many to show one by one.
//!
//! A camera ray stands for its pixel: a cone whose width grows by the
//! pixel's angle per unit of distance. Specular events keep a cone (a
//! refraction narrows or widens its spread by the ratio of the indices; the
//! surface's curvature is left out, a factor of order one that only moves
//! where the blend below starts); any other event (a glossy or diffuse
//! reflection, a scattering in a medium, a flake's reflection) spreads the
//! path over more than any flake, so its cone becomes unbounded.
//!
//! Where a path meets a flake, the footprint's area over the flake's mean
//! projected area counts the flakes the footprint holds. Up to
//! [`FLAKES_BEFORE_BLEND`], the flake shows as itself: a pixel of tens of
//! flakes still sparkles, as the few of them that face the light make it
//! brighter than its neighbours, and the lobe's expected value would
//! smooth that texture away (a 64-px goldstone, about 25 flakes a pixel,
//! turns into an even glow). From [`FLAKES_FOR_AGGREGATE`], where a
//! pixel's spread from the mean is a few per cent, only their average
//! shows (the aggregate lobe of [`crate::render::flake_lobe`]); in between,
//! a share that rises with the log of the count blends the two, which keeps
//! the expected value either way: a flake at depth takes the lobe by a
//! random choice with that probability, a glitter facet both, as a mixture
//! of its own BRDF and its facets' mean weighted by the share
//! (`render::glitter_facets`; the same expected value with less noise).
//! (MoonRay's glitter blends its smooth lobe in over 100 to 900 flakes.)
//! A path whose cone is unbounded (after a glossy or diffuse event) shades
//! flakes by the lobe alone, and from its next such event on meets them as
//! a medium (`render::flake_medium`).

/// Flakes per footprint up to which each flake shows as itself.
pub(crate) const FLAKES_BEFORE_BLEND: f64 = 100.0;
/// Flakes per footprint from which the aggregate lobe alone shades them.
pub(crate) const FLAKES_FOR_AGGREGATE: f64 = 1000.0;

/// A ray cone: the footprint's width where the ray starts and its growth
/// per unit length (mm, radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RayCone {
    /// Width of the footprint at the ray's origin, mm.
    pub width_mm: f64,
    /// Growth of the width per mm along the ray (the cone's angle).
    pub spread_rad: f64,
}

impl RayCone {
    /// The cone of a camera ray: a point at the pinhole, growing by the
    /// pixel's angle.
    pub(crate) fn from_camera(pixel_angle_rad: f64) -> Self {
        Self {
            width_mm: 0.0,
            spread_rad: pixel_angle_rad,
        }
    }

    /// The cone after a non-specular event: wider than any flake.
    pub(crate) const UNBOUNDED: Self = Self {
        width_mm: f64::INFINITY,
        spread_rad: f64::INFINITY,
    };

    /// Whether the cone is unbounded: the path met a non-specular event.
    pub(crate) fn is_unbounded(self) -> bool {
        self.spread_rad.is_infinite()
    }

    /// The footprint's width at distance `t_mm` along the ray.
    pub(crate) fn width_at(self, t_mm: f64) -> f64 {
        if self.spread_rad.is_infinite() {
            return f64::INFINITY;
        }
        self.width_mm + self.spread_rad * t_mm
    }

    /// The cone of the ray that leaves a specular event at distance `t_mm`:
    /// the width reached there, the spread times `spread_factor` (1 for a
    /// mirror reflection, η₁/η₂ for a refraction from index η₁ into η₂,
    /// which bends the rays of the cone towards the normal by that ratio).
    pub(crate) fn continued(self, t_mm: f64, spread_factor: f64) -> Self {
        if self.spread_rad.is_infinite() {
            return Self::UNBOUNDED;
        }
        Self {
            width_mm: self.width_at(t_mm),
            spread_rad: self.spread_rad * spread_factor,
        }
    }
}

/// The share of a flake met by a footprint of width `width_mm` that its
/// population's aggregate lobe shades rather than its own normal (for a
/// flake at depth, the probability of the lobe),
/// for flakes of mean projected area `flake_area_mm2`: 0 up to
/// [`FLAKES_BEFORE_BLEND`] flakes per footprint, 1 from
/// [`FLAKES_FOR_AGGREGATE`], linear in the count's logarithm between.
pub(crate) fn aggregate_probability(width_mm: f64, flake_area_mm2: f64) -> f64 {
    let flakes = width_mm * width_mm / flake_area_mm2;
    if flakes.is_nan() || flakes <= FLAKES_BEFORE_BLEND {
        return 0.0;
    }
    ((flakes / FLAKES_BEFORE_BLEND).ln() / (FLAKES_FOR_AGGREGATE / FLAKES_BEFORE_BLEND).ln())
        .min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cone_grows_linearly_and_a_refraction_scales_its_spread() {
        let camera = RayCone::from_camera(0.002);
        assert_eq!(camera.width_at(0.0), 0.0);
        assert!((camera.width_at(100.0) - 0.2).abs() < 1e-15);
        // Into glass of index 1.5 at 100 mm, then 3 mm further inside.
        let inside = camera.continued(100.0, 1.0 / 1.5);
        assert!((inside.width_at(3.0) - (0.2 + 0.004)).abs() < 1e-15);
        assert_eq!(RayCone::UNBOUNDED.width_at(0.0), f64::INFINITY);
        assert_eq!(RayCone::UNBOUNDED.continued(5.0, 0.5), RayCone::UNBOUNDED);
    }

    #[test]
    fn the_blend_runs_from_the_flake_itself_to_the_aggregate() {
        let area = 0.01;
        // Footprints of 50, 100, 316, 1000 and 5000 flakes.
        let p = |flakes: f64| aggregate_probability((flakes * area).sqrt(), area);
        assert_eq!(p(50.0), 0.0);
        assert!(p(100.0) < 1e-12);
        assert!((p(100.0 * 10f64.sqrt()) - 0.5).abs() < 1e-9);
        assert!((p(1000.0) - 1.0).abs() < 1e-9);
        assert_eq!(p(5000.0), 1.0);
        assert_eq!(aggregate_probability(f64::INFINITY, area), 1.0);
        // Monotone in between.
        let mut last = 0.0;
        for k in 1..100 {
            let now = p(f64::from(k) * 12.0);
            assert!(now >= last);
            last = now;
        }
    }
}
