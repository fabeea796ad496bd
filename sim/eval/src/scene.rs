//! What evaluation reads of the scenario and its truth: the pose at a stamp, a robot's camera,
//! the direction of mapping.

use hetsim_msgs::CameraGeometry;
use hetsim_msgs::Pose;
use hetsim_scene::{Scenario, Sensor};

/// The pose in a ground-truth track nearest a stamp.
pub fn truth_at(track: &[(u64, Pose)], stamp_ns: u64) -> Pose {
    let i = track.partition_point(|(t, _)| *t < stamp_ns);
    let candidates = [i.saturating_sub(1), i.min(track.len() - 1)];
    let best = candidates
        .into_iter()
        .min_by_key(|&k| track[k].0.abs_diff(stamp_ns))
        .expect("two candidates");
    track[best].1
}

/// A robot's (first) pinhole camera: its mount in the body frame, its intrinsics and its
/// pixel noise.
pub fn camera_of(robot: &hetsim_scene::ResolvedRobot) -> Option<(Pose, CameraGeometry, f64)> {
    robot.model.sensors.iter().find_map(|s| match s {
        Sensor::Camera {
            mount,
            width_px,
            height_px,
            hfov_deg,
            intrinsics,
            pixel_noise_sigma,
            ..
        } => Some((
            hetsim_msgs::pose_from_xyz_rpy(mount.xyz_m, mount.rpy_deg.map(f64::to_radians)),
            hetsim_scene::camera_geometry(*width_px, *height_px, *hfov_deg, intrinsics.as_ref()),
            *pixel_noise_sigma,
        )),
        _ => None,
    })
}

/// The direction of mapping of the scenario's `[coverage]` table, radians from east.
pub fn direction_rad(scenario: &Scenario) -> f64 {
    let (x, y) = hetsim_scene::coverage_params(scenario).direction.unit();
    y.atan2(x)
}
