//! Shared geometry: poses and angle helpers.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// A rigid transform, `parent_from_child`: it maps coordinates in the child frame to the parent
/// frame. `world_from_body` is the pose of a body in the world.
pub type Pose = Isometry3<f64>;

/// Wraps an angle to `(-pi, pi]`.
pub fn wrap_angle(angle_rad: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut a = angle_rad % two_pi;
    if a <= -std::f64::consts::PI {
        a += two_pi;
    } else if a > std::f64::consts::PI {
        a -= two_pi;
    }
    a
}

/// Heading of a pose: the angle of its body x axis projected on the world's xy plane,
/// counter-clockwise from east.
pub fn yaw_of(world_from_body: &Pose) -> f64 {
    let forward = world_from_body.rotation * Vector3::x();
    forward.y.atan2(forward.x)
}

/// A pose from a position and roll/pitch/yaw (`R = Rz(yaw) Ry(pitch) Rx(roll)`).
pub fn pose_from_xyz_rpy(xyz: [f64; 3], rpy_rad: [f64; 3]) -> Pose {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy_rad[0], rpy_rad[1], rpy_rad[2]),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn wrap_stays_in_range() {
        for k in -20..20 {
            let a = k as f64 * 0.77;
            let w = wrap_angle(a);
            assert!(w > -PI && w <= PI, "{a} -> {w}");
            assert!(
                ((a - w) / std::f64::consts::TAU).fract().abs() < 1e-9
                    || (1.0 - ((a - w) / std::f64::consts::TAU).fract().abs()) < 1e-9
            );
        }
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
    }

    #[test]
    fn yaw_ignores_tilt() {
        let pose = pose_from_xyz_rpy([1.0, 2.0, 3.0], [0.2, -0.1, 1.3]);
        assert!((yaw_of(&pose) - 1.3).abs() < 1e-12);
    }
}
