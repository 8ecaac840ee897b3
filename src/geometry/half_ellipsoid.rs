//! The half ellipsoid's crossing test written without branches, for the
//! lane loops of the ground path kernel
//! ([`crate::render::ground_paths`]): the same IEEE operations in the same
//! order as `Cabochon::half_ellipsoid_crosses` (the chord of the dome
//! ellipsoid, clipped by the buff top and the base, long enough, with an
//! end inside the ray's range), with every `if` a select, so that sixteen
//! rays compile to vector arithmetic and each gets the scalar test's answer.

use glam::DVec3;

#[cfg(doc)]
use crate::geometry::Cabochon;

/// The constants of a half-ellipsoid [`Cabochon`] that its crossing test
/// reads (see [`Cabochon::half_ellipsoid_test`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfEllipsoidTest {
    /// 1 / semi-axes: object space to the unit sphere's space.
    pub(crate) inv_axes: DVec3,
    /// Whether a buff-top plane cuts the dome, at `z_top`.
    pub(crate) buffed: bool,
    /// Height of the buff-top plane.
    pub(crate) z_top: f64,
    /// Height of the flat base: −(girdle band) = −0 for a half ellipsoid.
    pub(crate) base_z: f64,
    /// The stone's largest extent (the shortest chord that counts).
    pub(crate) size: f64,
}

impl HalfEllipsoidTest {
    /// The largest semi-axis: every point the test can report lies on or
    /// inside the ellipsoid, so within this distance of the object origin.
    pub fn longest_semi_axis(&self) -> f64 {
        let axes = self.inv_axes.recip();
        axes.max_element()
    }

    /// Whether the object-space ray (`origin`, `dir`) crosses the stone's
    /// surface in (`t_min`, `t_max`): exactly
    /// `Cabochon::half_ellipsoid_crosses`, and so also whether
    /// `intersect_half_ellipsoid` finds a hit.
    #[inline(always)]
    pub fn crosses(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> bool {
        // `half_ellipsoid_chord`: the unit-sphere quadratic.
        let origin_scaled = origin * self.inv_axes;
        let dir_scaled = dir * self.inv_axes;
        let dd = dir_scaled.dot(dir_scaled);
        let od = origin_scaled.dot(dir_scaled);
        let c = origin_scaled.dot(origin_scaled) - 1.0;
        let disc = od * od - dd * c;
        // `!(disc < 0 || disc is NaN)` and a finite, non-zero direction.
        let mut hit = (disc >= 0.0) & (dd > 0.0) & (dd < f64::INFINITY);
        // `Chord::between_unit_roots`.
        let q = -(od + disc.sqrt().copysign(od));
        hit &= q != 0.0;
        let (r0, r1) = (q / dd, c / q);
        let (mut t_in, mut t_out) = (r0.min(r1), r0.max(r1));
        // `Span::clip` by the buff top (keep z ≤ z_top), then the base
        // (keep z ≥ base_z).
        if self.buffed {
            (t_in, t_out) = clip(t_in, t_out, origin.z, dir.z, self.z_top, true);
        }
        (t_in, t_out) = clip(t_in, t_out, origin.z, dir.z, self.base_z, false);
        // `long_enough`.
        let min_chord = 1e-8 * self.size / dir.length();
        hit &= t_out - t_in >= min_chord;
        // `Span::first_end`.
        let in_range = |t: f64| (t > t_min) & (t < t_max);
        hit & (in_range(t_in) | in_range(t_out))
    }
}

/// `Span::clip` of the span (`t_in`, `t_out`) by the plane z = `plane_z`
/// (keeping z ≤ `plane_z` if `below`), as selects.
#[inline(always)]
fn clip(t_in: f64, t_out: f64, origin_z: f64, dir_z: f64, plane_z: f64, below: bool) -> (f64, f64) {
    let parallel = dir_z == 0.0;
    let outside = if below {
        origin_z > plane_z
    } else {
        origin_z < plane_z
    };
    let t = (plane_z - origin_z) / dir_z;
    let cuts_exit = (dir_z > 0.0) == below;
    let new_out = if parallel {
        if outside {
            f64::NEG_INFINITY
        } else {
            t_out
        }
    } else if cuts_exit & (t < t_out) {
        t
    } else {
        t_out
    };
    let new_in = if !parallel & !cuts_exit & (t > t_in) {
        t
    } else {
        t_in
    };
    (new_in, new_out)
}

#[cfg(test)]
mod tests {
    use crate::geometry::{Base, Cabochon, CabochonParams, Outline};
    use crate::sampling::Rng;
    use glam::DVec3;

    fn half_ellipsoid(buff_top: Option<f64>) -> Cabochon {
        Cabochon::new(CabochonParams {
            outline: Outline::Oval,
            length: 2.0,
            width: 1.4,
            dome_height: 0.45,
            profile_exponent: 2.0,
            girdle_height: 0.0,
            base: Base::Flat,
            buff_top,
        })
        .unwrap()
    }

    #[test]
    fn the_select_form_answers_as_the_scalar_half_ellipsoid_test() {
        // Rays from all around, many aimed at the stone, some grazing its
        // rim or running along the base plane (dir.z = 0), with ranges that
        // cut the chord anywhere: both tests agree on every one, and both
        // answers occur often.
        for buff_top in [None, Some(0.6)] {
            let stone = half_ellipsoid(buff_top);
            assert!(stone.is_half_ellipsoid());
            let test = stone.half_ellipsoid_test();
            let mut rng = Rng::new(3, u64::from(buff_top.is_some()));
            let (mut crossing, mut missing) = (0, 0);
            for i in 0..200_000 {
                let r = |rng: &mut Rng, k: f64| (rng.next_f64() * 2.0 - 1.0) * k;
                let origin = DVec3::new(r(&mut rng, 3.0), r(&mut rng, 3.0), r(&mut rng, 2.0));
                let target = DVec3::new(r(&mut rng, 1.1), r(&mut rng, 0.8), rng.next_f64() * 0.5);
                let mut dir = (target - origin).normalize();
                match i % 7 {
                    0 => dir.z = 0.0,
                    1 => dir = -dir,
                    _ => {}
                }
                let origin = if i % 11 == 0 {
                    DVec3::new(origin.x, origin.y, 0.0)
                } else {
                    origin
                };
                let t_min = if i % 3 == 0 { 0.0 } else { rng.next_f64() };
                let t_max = if i % 5 == 0 {
                    f64::INFINITY
                } else {
                    t_min + rng.next_f64() * 4.0
                };
                let scalar = stone.half_ellipsoid_crosses(origin, dir, t_min, t_max);
                assert_eq!(
                    test.crosses(origin, dir, t_min, t_max),
                    scalar,
                    "origin {origin}, dir {dir}, ({t_min}, {t_max})"
                );
                if scalar {
                    crossing += 1;
                } else {
                    missing += 1;
                }
            }
            assert!(
                crossing > 20_000 && missing > 20_000,
                "{crossing} {missing}"
            );
        }
    }
}
