//! Accuracy of an estimated trajectory against ground truth.
//!
//! Poses are paired by stamp (estimates are stamped at camera times, which are also truth
//! times). ATE: the estimated positions are aligned to the true ones by the rigid motion
//! minimising the squared error (Horn/Umeyama without scale, as `evo_ape --align`), then the
//! root-mean-square position error. RPE: over every pair of estimates 1 s apart, the
//! root-mean-square error of the relative translation (as `evo_rpe --delta 1 --delta_unit s`).

use hetsim_engine::RunOutput;
use hetsim_msgs::{ArtifactData, Pose};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// How good an estimated trajectory is. A figure the trajectory is too short for is NaN,
/// written `null` in metrics.json, and read back as NaN.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    /// Poses paired with truth.
    pub poses: usize,
    /// Length of the true path over those poses, metres.
    pub length_m: f64,
    /// Absolute trajectory error after SE(3) alignment, RMSE, metres.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub ate_m: f64,
    /// The same without alignment, RMSE, metres: the estimate where its frame lies in the
    /// world ([`crate::frames::artifact_frame`]: the team's frame, Dala's first origin, placed
    /// by the truth; open loop and VO where the robot's first link put them in it; a robot
    /// never linked, by its own first true pose).
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub ate_unaligned_m: f64,
    /// Relative pose error of translation over 1 s, RMSE, metres.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub rpe_1s_m: f64,
    /// Position error of the last pose without alignment, metres.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub final_error_m: f64,
}

/// An estimated trajectory and its robot's truth, each `(stamp_ns, world_from_body)`.
pub type Paired<'a> = (&'a [(u64, Pose)], &'a [(u64, Pose)]);

/// Pairs by stamp and evaluates.
pub fn evaluate(estimate: &[(u64, Pose)], truth: &[(u64, Pose)]) -> Accuracy {
    evaluate_joint(&[(estimate, truth)])
}

/// Evaluates several robots' trajectories together (each paired with its own truth): one
/// alignment for all of them, RPE over every robot's pairs; `length_m` is their sum and
/// `final_error_m` the largest final error.
pub fn evaluate_joint(parts: &[Paired<'_>]) -> Accuracy {
    let mut est = Vec::new();
    let mut gt = Vec::new();
    let mut length_m = 0.0;
    let mut sq = Vec::new();
    let mut final_error_m = f64::NAN;
    for (estimate, truth) in parts {
        let by_stamp: BTreeMap<u64, &Pose> = truth.iter().map(|(t, p)| (*t, p)).collect();
        let pairs: Vec<(u64, &Pose, &Pose)> = estimate
            .iter()
            .filter_map(|(t, e)| by_stamp.get(t).map(|g| (*t, e, *g)))
            .collect();
        let e: Vec<Vector3<f64>> = pairs.iter().map(|p| p.1.translation.vector).collect();
        let g: Vec<Vector3<f64>> = pairs.iter().map(|p| p.2.translation.vector).collect();
        length_m += g.windows(2).map(|w| (w[1] - w[0]).norm()).sum::<f64>();
        for (i, a) in pairs.iter().enumerate() {
            if let Some(b) = pairs[i..].iter().find(|b| b.0 >= a.0 + 1_000_000_000) {
                let rel_est = a.1.inverse() * b.1;
                let rel_gt = a.2.inverse() * b.2;
                sq.push((rel_est.translation.vector - rel_gt.translation.vector).norm_squared());
            }
        }
        if let (Some(a), Some(b)) = (e.last(), g.last()) {
            final_error_m = final_error_m.max((a - b).norm());
        }
        est.extend(e);
        gt.extend(g);
    }
    let ate_m = match hetsim_vision::vo::kabsch(&est, &gt) {
        Some(align) => (est
            .iter()
            .zip(&gt)
            .map(|(e, g)| ((align * nalgebra::Point3::from(*e)).coords - g).norm_squared())
            .sum::<f64>()
            / est.len() as f64)
            .sqrt(),
        None => f64::NAN,
    };
    let ate_unaligned_m = if est.is_empty() {
        f64::NAN
    } else {
        (est.iter()
            .zip(&gt)
            .map(|(e, g)| (e - g).norm_squared())
            .sum::<f64>()
            / est.len() as f64)
            .sqrt()
    };
    let rpe_1s_m = if sq.is_empty() {
        f64::NAN
    } else {
        (sq.iter().sum::<f64>() / sq.len() as f64).sqrt()
    };
    Accuracy {
        poses: est.len(),
        length_m,
        ate_m,
        ate_unaligned_m,
        rpe_1s_m,
        final_error_m,
    }
}

/// A trajectory a robot stack estimated (a trajectory artifact with at least two poses).
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// What estimated it, e.g. `vo`.
    pub kind: String,
    /// The robot.
    pub robot: String,
    /// `(stamp_ns, world_from_body)`.
    pub poses: Vec<(u64, Pose)>,
}

/// Every estimated trajectory of the run, in robot order and then in the order each stack
/// published them, in the world frame (a SLAM stack's estimates are placed there by
/// [`crate::frames::artifact_frame`]); trajectories of fewer than two poses are left out.
pub fn estimates(output: &RunOutput) -> Vec<Estimate> {
    let mut out = Vec::new();
    for (robot, artifacts) in &output.artifacts {
        for a in artifacts {
            if let ArtifactData::Trajectory(poses) = &a.data {
                if poses.len() >= 2 {
                    let frame = crate::frames::artifact_frame(output, robot, &a.name);
                    out.push(Estimate {
                        kind: a.name.clone(),
                        robot: robot.clone(),
                        poses: poses
                            .iter()
                            .map(|(t, p)| (*t, frame.map_or(*p, |w| w * p)))
                            .collect(),
                    });
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_accuracy_too_short_for_its_figures_reads_back_from_json_as_nan() {
        // Two poses 0.1 s apart: no 1 s RPE.
        let track: Vec<(u64, Pose)> = (0..2)
            .map(|k| (k * 100_000_000, Pose::identity()))
            .collect();
        let a = evaluate(&track, &track);
        assert!(a.rpe_1s_m.is_nan(), "{a:?}");
        let json = serde_json::to_string(&a).unwrap();
        assert!(json.contains("\"rpe_1s_m\":null"), "{json}");
        let back: Accuracy = serde_json::from_str(&json).unwrap();
        assert!(back.rpe_1s_m.is_nan());
        // Every figure comes back: numbers as they were, NaN as NaN.
        let figures = |x: &Accuracy| {
            [
                x.length_m,
                x.ate_m,
                x.ate_unaligned_m,
                x.rpe_1s_m,
                x.final_error_m,
            ]
            .map(|v| (v.is_nan(), if v.is_nan() { 0.0 } else { v }))
        };
        assert_eq!((back.poses, figures(&back)), (a.poses, figures(&a)));
    }
    use hetsim_msgs::pose_from_xyz_rpy;

    #[test]
    fn a_rigidly_moved_copy_has_zero_ate_and_a_scaled_one_does_not() {
        let truth: Vec<(u64, Pose)> = (0..50)
            .map(|k| {
                (
                    k * 100_000_000,
                    pose_from_xyz_rpy(
                        [k as f64 * 0.1, (k as f64 * 0.2).sin(), 0.0],
                        [0.0, 0.0, k as f64 * 0.02],
                    ),
                )
            })
            .collect();
        let offset = pose_from_xyz_rpy([5.0, -2.0, 1.0], [0.0, 0.0, 0.3]);
        let moved: Vec<(u64, Pose)> = truth.iter().map(|(t, p)| (*t, offset * p)).collect();
        let a = evaluate(&moved, &truth);
        assert_eq!(a.poses, 50);
        assert!(a.ate_m < 1e-9 && a.rpe_1s_m < 1e-9, "{a:?}");
        assert!(
            a.final_error_m > 1.0,
            "unaligned final error sees the offset"
        );
        let scaled: Vec<(u64, Pose)> = truth
            .iter()
            .map(|(t, p)| {
                (
                    *t,
                    pose_from_xyz_rpy(
                        [p.translation.x * 1.1, p.translation.y * 1.1, 0.0],
                        [0.0; 3],
                    ),
                )
            })
            .collect();
        let b = evaluate(&scaled, &truth);
        assert!(b.ate_m > 0.05 && b.rpe_1s_m > 0.05, "{b:?}");
    }
}
