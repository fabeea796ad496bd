//! What robot software is given from the files besides its messages, read the same way by the
//! stacks that give it and the evaluation that judges the run: a robot's stereo bench as its
//! robot file declares it, and the coverage planner's parameters from the scenario's
//! `[coverage]` table and its robots (whose roles come from what their files declare: the
//! parent carries the laser, the children wear hats).

use crate::{ResolvedRobot, Scenario, Sensor};
use hetsim_coverage::{CoverageParams, PlannedTeam};

/// A robot's (first) stereo bench, as the robot file declares it.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoBench {
    /// The sensor's name (its cameras are `<name>/left` and `<name>/right`).
    pub name: String,
    /// The left camera's pinhole intrinsics (the right one's are the same).
    pub intrinsics: hetsim_msgs::CameraGeometry,
    /// Baseline, metres (the right camera sits at -baseline along the left's y).
    pub baseline_m: f64,
    /// The left camera's mount in the body frame (body axis convention, x along the view).
    pub body_from_mount: hetsim_msgs::Pose,
}

/// The robot's first stereo bench, if it has one.
pub fn stereo_bench(robot: &ResolvedRobot) -> Option<StereoBench> {
    robot.model.sensors.iter().find_map(|s| match s {
        Sensor::StereoCamera {
            name,
            width_px,
            height_px,
            hfov_deg,
            intrinsics,
            baseline_m,
            mount,
            ..
        } => Some(StereoBench {
            name: name.clone(),
            intrinsics: crate::camera_geometry(
                *width_px,
                *height_px,
                *hfov_deg,
                intrinsics.as_ref(),
            ),
            baseline_m: *baseline_m,
            body_from_mount: hetsim_msgs::pose_from_xyz_rpy(
                mount.xyz_m,
                mount.rpy_deg.map(f64::to_radians),
            ),
        }),
        _ => None,
    })
}

/// Planning parameters from the scenario's `[coverage]` table and its robots.
pub fn coverage_params(scenario: &Scenario) -> CoverageParams {
    // The parent is the robot with the laser, the children the robots with hats.
    let radius = |role: fn(&crate::RobotModel) -> bool, default: f64| {
        scenario
            .robots
            .iter()
            .find(|r| role(&r.model))
            .map_or(default, |r| {
                r.model.body.length_m.max(r.model.body.width_m) / 2.0
            })
    };
    let team = PlannedTeam {
        parent_radius_m: radius(crate::RobotModel::has_laser, 0.225),
        child_radius_m: radius(crate::RobotModel::is_tracked_child, 0.06),
        children: scenario
            .robots
            .iter()
            .filter(|r| r.model.is_tracked_child())
            .count(),
    };
    scenario
        .file
        .coverage
        .clone()
        .unwrap_or_default()
        .params(team)
}
