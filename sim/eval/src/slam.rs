//! The SLAM stacks' reports against ground truth: the NEES of the robot pose, what each event
//! did to the robot's pose error, and the team's joint accuracy.

use crate::drift::error;
use crate::frames::{raw_reports, world_frames};
use crate::trajectory::Estimate;
use crate::trajectory::{evaluate_joint, Accuracy, Paired};
use hetsim_engine::RunOutput;
use hetsim_msgs::Pose;
use hetsim_slam::report::SlamReport;
use nalgebra::Matrix6;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One event, judged against the truth at its frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventMetrics {
    /// `gps`, `rendezvous` or `image_match`.
    pub kind: String,
    /// When, seconds.
    pub time_s: f64,
    /// The other robot (empty for GPS).
    pub other: String,
    /// Position error of the robot's estimate just before the event, metres.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub error_before_m: f64,
    /// And just after the graph was optimized with it.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub error_after_m: f64,
    /// Altitude error before, metres (absolute).
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub altitude_error_before_m: f64,
    /// Altitude error after, metres (absolute).
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub altitude_error_after_m: f64,
}

/// One robot's SLAM figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobotSlam {
    /// Mean normalized estimation error squared of the `slam` poses (6 degrees of freedom:
    /// 6 for a consistent estimate), over `nees_poses` poses.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub nees_mean: f64,
    /// Poses with truth and covariance.
    pub nees_poses: usize,
    /// `(time s, NEES)` at every whole second: runs of other seeds are averaged at the same
    /// times for the consistency test (`hetsim report village RUN...`).
    pub nees_series: Vec<(f64, f64)>,
    /// Each axis's squared error over its own variance, averaged over the poses (x, y, z in
    /// the body frame, then the rotation vector's three): 1 for a consistent estimate; which
    /// axis is overconfident, and by how much.
    pub nees_axes: [f64; 6],
    /// Sub-maps built.
    pub submaps: usize,
    /// The events, in order.
    pub events: Vec<EventMetrics>,
    /// The stack's counters.
    pub counters: BTreeMap<String, u64>,
    /// Its open-loop chain's edges against the truth, per axis ([`crate::drift`]): the
    /// drift the SLAM's `EdgeDrift` models.
    pub edge_drift: crate::drift::EdgeDriftFit,
    /// Its image matching against the truth ([`crate::matching`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matching: Option<crate::matching::MatchingMetrics>,
}

/// The SLAM section of `metrics.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SlamMetrics {
    /// Per robot.
    pub robots: BTreeMap<String, RobotSlam>,
    /// All robots together (one alignment), by estimate kind (`slam`, `slam-open`, `vo`).
    pub joint: BTreeMap<String, Accuracy>,
}

/// The SLAM reports the run's stacks published, by robot, in robot order, with their poses
/// expressed in the world ([`crate::frames::world_frames`]; covariances of right perturbations do not
/// change).
pub fn reports(output: &RunOutput) -> Vec<(String, SlamReport)> {
    let frames = world_frames(output);
    let place = |frame: &str, p: &Pose| frames.get(frame).map_or(*p, |w| w * p);
    raw_reports(output)
        .into_iter()
        .map(|(robot, mut report)| {
            for (_, p, _) in &mut report.origins {
                *p = place(&report.frame, p);
            }
            for e in &mut report.events {
                e.before = place(&e.frame_before, &e.before);
                e.after = place(&e.frame_after, &e.after);
            }
            (robot, report)
        })
        .collect()
}

/// Judges the reports (robot name, report) against the robots' truth.
pub fn evaluate(
    reports: &[(String, SlamReport)],
    estimates: &[Estimate],
    truth: &[(String, Vec<(u64, Pose)>)],
) -> SlamMetrics {
    let truth_of = |robot: &str| -> BTreeMap<u64, Pose> {
        truth
            .iter()
            .find(|(n, _)| n == robot)
            .map(|(_, t)| t.iter().copied().collect())
            .unwrap_or_default()
    };
    let mut robots = BTreeMap::new();
    for (robot, report) in reports {
        let truth = truth_of(robot);
        let slam = estimates
            .iter()
            .find(|e| e.kind == "slam" && e.robot == *robot);
        let mut nees = Vec::new();
        let mut series = Vec::new();
        let mut axes = [0.0; 6];
        if let Some(slam) = slam {
            for ((stamp, pose), cov) in slam.poses.iter().zip(&report.covariances) {
                let (Some(t), Some(inv)) = (
                    truth.get(stamp),
                    Matrix6::from_column_slice(cov).try_inverse(),
                ) else {
                    continue;
                };
                let e = error(pose, t);
                let c = Matrix6::from_column_slice(cov);
                for (k, a) in axes.iter_mut().enumerate() {
                    *a += e[k] * e[k] / c[(k, k)].max(1e-300);
                }
                let n = (e.transpose() * inv * e)[0];
                nees.push(n);
                // Whole seconds (one pose a second) for the Monte Carlo test across runs.
                if stamp % 1_000_000_000 == 0 {
                    series.push((*stamp as f64 * 1e-9, n));
                }
            }
        }
        let open: BTreeMap<u64, Pose> = estimates
            .iter()
            .find(|e| e.kind == "slam-open" && e.robot == *robot)
            .map(|e| e.poses.iter().copied().collect())
            .unwrap_or_default();
        let stamps: Vec<u64> = report.origins.iter().map(|(t, _, _)| *t).collect();
        let edge_drift = crate::drift::EdgeDriftFit::fit(&stamps, &open, &truth);
        let events = report
            .events
            .iter()
            .filter_map(|ev| {
                let t = truth.get(&ev.stamp_ns)?;
                let p = t.translation.vector;
                Some(EventMetrics {
                    kind: ev.kind.clone(),
                    time_s: ev.stamp_ns as f64 * 1e-9,
                    other: ev.other.clone(),
                    error_before_m: (ev.before.translation.vector - p).norm(),
                    error_after_m: (ev.after.translation.vector - p).norm(),
                    altitude_error_before_m: (ev.before.translation.z - p.z).abs(),
                    altitude_error_after_m: (ev.after.translation.z - p.z).abs(),
                })
            })
            .collect();
        robots.insert(
            robot.clone(),
            RobotSlam {
                nees_mean: nees.iter().sum::<f64>() / nees.len().max(1) as f64,
                nees_poses: nees.len(),
                nees_series: series,
                nees_axes: axes.map(|a| a / nees.len().max(1) as f64),
                submaps: report.origins.len(),
                events,
                counters: report.counters.clone(),
                edge_drift,
                matching: None,
            },
        );
    }
    let mut joint = BTreeMap::new();
    if reports.len() > 1 {
        for kind in ["slam", "slam-open", "vo"] {
            let parts: Vec<Paired<'_>> = estimates
                .iter()
                .filter(|e| e.kind == kind)
                .filter_map(|e| {
                    let t = &truth.iter().find(|(n, _)| *n == e.robot)?.1;
                    Some((e.poses.as_slice(), t.as_slice()))
                })
                .collect();
            if parts.len() > 1 {
                joint.insert(kind.to_string(), evaluate_joint(&parts));
            }
        }
    }
    SlamMetrics { robots, joint }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_msgs::pose_from_xyz_rpy;

    /// An estimate offset from the truth by exactly its standard deviation on one axis has a
    /// NEES of 1 at every pose; an event that halves the error is reported as such.
    #[test]
    fn nees_and_event_errors_are_computed_from_the_truth() {
        let truth: Vec<(u64, Pose)> = (0..10)
            .map(|k| {
                (
                    k * 100,
                    pose_from_xyz_rpy([k as f64, 0.0, 2.0], [0.0, 0.0, 0.3]),
                )
            })
            .collect();
        let shifted = |d: f64| -> Vec<(u64, Pose)> {
            truth
                .iter()
                .map(|(t, p)| (*t, p * pose_from_xyz_rpy([0.0, d, 0.0], [0.0; 3])))
                .collect()
        };
        let mut cov = Matrix6::<f64>::identity() * 0.01;
        cov[(1, 1)] = 0.04;
        let report = SlamReport {
            covariances: vec![cov.as_slice().to_vec(); 10],
            events: vec![hetsim_slam::report::SlamEvent {
                kind: "image_match".into(),
                stamp_ns: 500,
                other: "b".into(),
                before: truth[5].1 * pose_from_xyz_rpy([0.0, 0.0, 1.0], [0.0; 3]),
                after: truth[5].1 * pose_from_xyz_rpy([0.0, 0.0, 0.5], [0.0; 3]),
                frame_before: "a".into(),
                frame_after: "a".into(),
                link: None,
            }],
            ..SlamReport::default()
        };
        let estimates = vec![Estimate {
            kind: "slam".into(),
            robot: "a".into(),
            poses: shifted(0.2),
        }];
        let m = evaluate(
            &[("a".into(), report)],
            &estimates,
            &[("a".into(), truth.clone())],
        );
        let a = &m.robots["a"];
        assert_eq!(a.nees_poses, 10);
        assert!((a.nees_mean - 1.0).abs() < 1e-9, "{}", a.nees_mean);
        let e = &a.events[0];
        assert!((e.altitude_error_before_m - 1.0).abs() < 1e-9);
        assert!((e.altitude_error_after_m - 0.5).abs() < 1e-9);
        assert!(m.joint.is_empty(), "one robot: no joint figures");
    }
}
