//! A pinhole camera: position, look-at point, up vector and vertical field
//! of view, mapped onto a film of `width × height` pixels.

use glam::DVec3;

/// A ray leaving the camera through a point of the film.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraRay {
    /// The pinhole, in world space.
    pub origin: DVec3,
    /// Unit direction through the film point.
    pub direction: DVec3,
}

/// A pinhole camera with square pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct PinholeCamera {
    position: DVec3,
    /// Unit vectors: right, up (on the film) and forward (the view axis).
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    /// tan(vertical_fov / 2) and the same times the aspect ratio.
    half_height: f64,
    half_width: f64,
    /// Film-plane units per pixel across, 2·half_width/width: a product
    /// per ray instead of a division on the way to every camera ray.
    film_units_per_px_x: f64,
    /// Film-plane units per pixel down, 2·half_height/height.
    film_units_per_px_y: f64,
}

impl PinholeCamera {
    /// A camera at `position` looking at `look_at`, with `up` (any vector
    /// not parallel to the view axis) pointing up on the film.
    pub fn new(
        position: DVec3,
        look_at: DVec3,
        up: DVec3,
        vertical_fov_deg: f64,
        width_px: u32,
        height_px: u32,
    ) -> Self {
        let forward = (look_at - position).normalize();
        let mut right = forward.cross(up);
        if right.length_squared() < 1e-12 {
            // Looking along `up`: any right vector keeps the image upright
            // enough; the scene compiler already avoids this case.
            right = forward.any_orthonormal_vector();
        }
        let right = right.normalize();
        let true_up = right.cross(forward);
        let half_height = (vertical_fov_deg.to_radians() * 0.5).tan();
        let aspect = f64::from(width_px) / f64::from(height_px);
        Self {
            position,
            right,
            up: true_up,
            forward,
            half_height,
            half_width: half_height * aspect,
            film_units_per_px_x: 2.0 * half_height * aspect / f64::from(width_px),
            film_units_per_px_y: 2.0 * half_height / f64::from(height_px),
        }
    }

    /// The angle one pixel spans at the film's centre, radians: the spread
    /// of a camera ray's footprint.
    pub fn pixel_angle_rad(&self) -> f64 {
        self.film_units_per_px_y
    }

    /// The ray through film point (x, y) in pixels, x to the right and y
    /// downward from the top-left corner; pixel (i, j) covers
    /// [i, i+1) × [j, j+1).
    pub fn ray(&self, x_px: f64, y_px: f64) -> CameraRay {
        let sx = x_px * self.film_units_per_px_x - self.half_width;
        let sy = self.half_height - y_px * self.film_units_per_px_y;
        let direction = (self.forward + self.right * sx + self.up * sy).normalize();
        CameraRay {
            origin: self.position,
            direction,
        }
    }

    /// [`PinholeCamera::ray`]'s directions through `N` film points at
    /// once, written as lane arrays that the compiler turns into vector
    /// instructions where the caller enables them (the film's AVX2 batch):
    /// the same operations in the same order, so the same bits as `ray`.
    #[inline(always)]
    pub fn directions<const N: usize>(&self, x_px: &[f64; N], y_px: &[f64; N]) -> [DVec3; N] {
        let (mut dx, mut dy, mut dz) = ([0.0; N], [0.0; N], [0.0; N]);
        for lane in 0..N {
            let sx = x_px[lane] * self.film_units_per_px_x - self.half_width;
            let sy = self.half_height - y_px[lane] * self.film_units_per_px_y;
            // (forward + right·sx) + up·sy, one component at a time.
            dx[lane] = (self.forward.x + self.right.x * sx) + self.up.x * sy;
            dy[lane] = (self.forward.y + self.right.y * sx) + self.up.y * sy;
            dz[lane] = (self.forward.z + self.right.z * sx) + self.up.z * sy;
        }
        let mut directions = [DVec3::ZERO; N];
        for lane in 0..N {
            // glam's `normalize`: v · (1/√(v·v)), v·v = (x² + y²) + z².
            let length_squared = (dx[lane] * dx[lane] + dy[lane] * dy[lane]) + dz[lane] * dz[lane];
            let recip = 1.0 / length_squared.sqrt();
            directions[lane] = DVec3::new(dx[lane] * recip, dy[lane] * recip, dz[lane] * recip);
        }
        directions
    }

    /// The camera's position.
    pub fn position(&self) -> DVec3 {
        self.position
    }

    /// The unit view axis.
    pub fn forward(&self) -> DVec3 {
        self.forward
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_film_centre_looks_at_the_target_and_corners_span_the_field_of_view() {
        let cam = PinholeCamera::new(
            DVec3::new(0.0, -10.0, 0.0),
            DVec3::ZERO,
            DVec3::Z,
            90.0,
            200,
            100,
        );
        let centre = cam.ray(100.0, 50.0);
        assert!((centre.direction - DVec3::Y).length() < 1e-12);
        // Top edge centre: 45° above the axis for a 90° vertical field.
        let top = cam.ray(100.0, 0.0).direction;
        assert!(
            (top.z - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12,
            "{top}"
        );
        // Right edge centre: atan(2) to the right for a 2:1 film.
        let right = cam.ray(200.0, 50.0).direction;
        assert!((right.x / right.y - 2.0).abs() < 1e-12, "{right}");
    }

    #[test]
    fn batched_directions_equal_single_rays_bit_for_bit() {
        let cam = PinholeCamera::new(
            DVec3::new(1.0, -4.0, 3.0),
            DVec3::new(0.1, 0.2, 0.0),
            DVec3::Z,
            35.0,
            320,
            200,
        );
        let mut rng = crate::sampling::Rng::new(5, 6);
        for _ in 0..100 {
            let xs: [f64; 8] = std::array::from_fn(|_| rng.next_f64() * 330.0 - 5.0);
            let ys: [f64; 8] = std::array::from_fn(|_| rng.next_f64() * 210.0 - 5.0);
            let batch = cam.directions(&xs, &ys);
            for lane in 0..8 {
                let single = cam.ray(xs[lane], ys[lane]).direction;
                assert_eq!(
                    batch[lane].to_array().map(f64::to_bits),
                    single.to_array().map(f64::to_bits)
                );
            }
        }
    }
}
