//! A turntable's frames: the stones turned about their own verticals, or
//! the camera orbiting the point it looks at ([`crate::scene::Turntable`]).
//!
//! Frame k of N is turned by 360°·k/N. Frame 0 is the scene as written,
//! bit for bit, so it equals a still render. Both motions turn the same
//! way as seen through the camera: the stones counter-clockwise seen from
//! above, or the camera clockwise round them. With the camera, the lights
//! and the environment stay with the stones; with the stones, they stay
//! with the camera.

use glam::DQuat;

use crate::render::world::StoneInstance;
use crate::scene::Camera;

/// The stones, each turned by `turn_deg` about the vertical through its
/// own origin (counter-clockwise seen from above); the same stones, bit for
/// bit, at 0°.
pub fn turned_stones(stones: &[StoneInstance], turn_deg: f64) -> Vec<StoneInstance> {
    let mut stones = stones.to_vec();
    if turn_deg != 0.0 {
        let turn = DQuat::from_rotation_z(turn_deg.to_radians());
        for stone in &mut stones {
            stone.rotation = turn * stone.rotation;
        }
    }
    stones
}

/// The camera orbited by `turn_deg` clockwise seen from above, about the
/// vertical through the point it looks at, so that the stones seem to turn
/// as [`turned_stones`] turns them; the same camera at 0°.
pub fn orbited_camera(camera: &Camera, turn_deg: f64) -> Camera {
    if turn_deg == 0.0 {
        return *camera;
    }
    let turn = DQuat::from_rotation_z(-turn_deg.to_radians());
    Camera {
        position: camera.look_at + turn * (camera.position - camera.look_at),
        up: turn * camera.up,
        ..*camera
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::default_scene;
    use glam::DVec3;

    #[test]
    fn a_quarter_orbit_keeps_the_distance_and_the_point_looked_at() {
        let camera = default_scene().camera;
        let moved = orbited_camera(&camera, 90.0);
        assert_eq!(moved.look_at, camera.look_at);
        let (a, b) = (
            camera.position - camera.look_at,
            moved.position - moved.look_at,
        );
        assert!((a.length() - b.length()).abs() < 1e-9);
        assert!((a.z - b.z).abs() < 1e-9, "the height changed: {a} → {b}");
        // Clockwise seen from above: the horizontal offset turns by −90°.
        let expected = DVec3::new(a.y, -a.x, a.z);
        assert!((b - expected).length() < 1e-9, "{b} ≠ {expected}");
        assert_eq!(orbited_camera(&camera, 0.0), camera);
    }
}
