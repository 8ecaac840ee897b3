//! Cameras the render tests share.

use glam::DVec3;
use lapidary::render::camera::PinholeCamera;

/// A camera 50 mm from the origin, 37° above the ground, 12° field: a
/// pixel of a 24-px image spans 0.44 mm at the origin.
pub fn three_quarter_camera(size: u32) -> PinholeCamera {
    PinholeCamera::new(
        DVec3::new(0.0, -40.0, 30.0),
        DVec3::ZERO,
        DVec3::Z,
        12.0,
        size,
        size,
    )
}
