//! Where the frames of the robots' estimates lie in the simulator's world.
//!
//! Robot software estimates in its own frames (a SLAM stack in the frame of its robot's first
//! sub-map origin, or of the team's reference once an event has linked them); only the
//! evaluation places those frames in the world, with the truth. Both the trajectory and the
//! SLAM evaluation read this module, which reads neither.

use hetsim_engine::RunOutput;
use hetsim_msgs::Pose;
use hetsim_slam::report::{SlamReport, REPORT_ARTIFACT};
use std::collections::BTreeMap;

/// The SLAM reports as the stacks published them, in their robots' frames.
pub(crate) fn raw_reports(output: &RunOutput) -> Vec<(String, SlamReport)> {
    output
        .artifacts_named(REPORT_ARTIFACT)
        .filter_map(|(robot, a)| Some((robot.to_string(), a.decode()?)))
        .collect()
}

/// Where the frames of the SLAM stacks' estimates lie in the simulator's world, by robot.
///
/// Robot software never knows the world frame: it estimates in the frame of a robot's first
/// sub-map origin, its pose at its first stereo pair (see [`SlamReport`]). The evaluation,
/// and only it, places each such frame in the world with the truth: robot `r`'s frame is
/// `r`'s true pose at the stamp of its first origin (the nearest truth sample). Everything
/// the evaluation reports about SLAM estimates (trajectories, maps, event errors, plots) is
/// expressed in the world through this; aligned figures (ATE with SE(3) alignment) do not
/// depend on it.
pub fn world_frames(output: &RunOutput) -> BTreeMap<String, Pose> {
    let at = |robot: &str, stamp: u64| -> Option<Pose> {
        let truth = output.truth_of(robot)?;
        let (_, pose) = truth.iter().min_by_key(|(t, _)| t.abs_diff(stamp))?;
        Some(*pose)
    };
    let reports = raw_reports(output);
    let mut frames: BTreeMap<String, Pose> = reports
        .iter()
        .filter_map(|(robot, report)| {
            let start = report.origins.first()?.0;
            Some((robot.clone(), at(robot, start)?))
        })
        .collect();
    // The frame of a robot that published no report (replayed without it) is placed through
    // the stamp of its first origin that a linked robot's report names.
    for (_, report) in &reports {
        if let (false, Some(start)) = (frames.contains_key(&report.frame), report.frame_start_ns) {
            if let Some(pose) = at(&report.frame, start) {
                frames.insert(report.frame.clone(), pose);
            }
        }
    }
    frames
}

/// The world pose of the frame that robot `robot`'s artifact `name` is in, for robots with a
/// SLAM report; `None` for artifacts of other stacks, which are in the world already.
///
/// The `slam` estimate and the map are in the report's frame. `vo` and `slam-open` are in the
/// robot's own frame, which its first link to another robot's frame placed there
/// ([`SlamReport::own_origin_at_link`](hetsim_slam::report::SlamReport)): they go into the
/// world through that link as the robot estimated it, so that in the team's frame the three
/// estimates start from the same link and differ only by what later events did. A robot
/// never linked is placed by its own true first pose.
pub fn artifact_frame(output: &RunOutput, robot: &str, name: &str) -> Option<Pose> {
    let reports = raw_reports(output);
    let (_, report) = reports.iter().find(|(r, _)| r == robot)?;
    let frames = world_frames(output);
    match (name, &report.own_origin_at_link) {
        ("vo" | "slam-open", Some((frame, origin))) => frames.get(frame).map(|w| w * origin),
        ("vo" | "slam-open", None) => frames.get(robot).copied(),
        _ => frames.get(report.frame.as_str()).copied(),
    }
}
