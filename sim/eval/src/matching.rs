//! The robots' image matching judged against the truth: which accepted matches were false,
//! and which chances to match were missed.
//!
//! * **False match**: an accepted `image_match` link whose measured relative pose is more than
//!   [`FALSE_M`] or [`FALSE_DEG`] from the true one (the robots' true body poses at the two
//!   frames). A wrong association lands metres or tens of degrees off; a right one within
//!   decimetres (`tests/tests/it/place.rs` measures 0.02-0.1 m and under 0.2 degree on rendered
//!   views). Each link's NEES under its own covariance is reported too.
//! * **Missed pass**: the truth, not the robot, decides where a match was possible. A robot's
//!   frame is a chance to match a key frame (any robot's sub-map origin, as its report lists
//!   them with their median depth) when, in the true poses, the key frame's looked-at point
//!   (its median depth along its optical axis) projects into the central half of the frame's
//!   image (half the width and half the height, about half the views overlapping), the optical
//!   axes are within [`MAX_VIEW_DEG`] (the matcher's own limit: interest points do not survive
//!   larger viewpoint changes), and the robot's view has left the key frame's since it was
//!   made (its looked-at point was once farther than 1.5 footprint radii from the key
//!   frame's, as the robot's own rule has it): a loop, not the chain. Chances less than a second apart make one pass; a pass is found if
//!   the robot accepted an image match within it (a second either side), missed otherwise.
//!   The robot waits `image_match_period_s` (30 s) between matches with the same robot, so
//!   passes that start within 30 s of its last match are counted apart.

use hetsim_msgs::Pose;
use hetsim_scene::Scenario;
use hetsim_slam::report::SlamReport;
use nalgebra::{Matrix6, Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A link farther than this from the truth is a false match, metres.
pub const FALSE_M: f64 = 2.0;
/// Or farther than this, degrees.
pub const FALSE_DEG: f64 = 5.0;
/// The matcher's limit on the angle between the optical axes, degrees.
pub const MAX_VIEW_DEG: f64 = 40.0;
/// A key frame is left once the looked-at points are this many footprint radii apart (the
/// robot's own rule).
const LEAVE: f64 = 1.5;
/// The robot's least time between two matches with the same robot, seconds.
const PERIOD_S: f64 = 30.0;

/// One accepted link judged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinkJudged {
    /// When, seconds.
    pub time_s: f64,
    /// The robot whose key frame matched.
    pub other: String,
    /// When that key frame was made, seconds.
    pub other_time_s: f64,
    /// RANSAC inliers.
    pub inliers: Option<usize>,
    /// Position error of the measured relative pose, metres.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub error_m: f64,
    /// Its rotation error, degrees.
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub error_deg: f64,
    /// Its NEES under the link's own covariance (6 degrees of freedom).
    #[serde(deserialize_with = "crate::stats::f64_or_null")]
    pub nees: f64,
    /// Whether it is a false match ([`FALSE_M`], [`FALSE_DEG`]).
    pub false_match: bool,
}

/// A robot's image matching against the truth.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MatchingMetrics {
    /// The accepted matches.
    pub links: Vec<LinkJudged>,
    /// How many of them are false.
    pub false_matches: usize,
    /// Passes over a key frame the truth says could match.
    pub passes: usize,
    /// Passes with an accepted match.
    pub found: usize,
    /// Passes without one, starting 30 s or more after the robot's last match.
    pub missed: usize,
    /// Passes without one within 30 s of its last match (the robot waits by design).
    pub waiting: usize,
    /// The missed passes, `[start, end]` seconds.
    pub missed_at_s: Vec<[f64; 2]>,
}

/// A stereo bench as the evaluation needs it: the left optical frame in the body, the image
/// size and intrinsics.
struct View {
    body_from_camera: Pose,
    k: hetsim_msgs::CameraGeometry,
}

fn view_of(scenario: &Scenario, robot: &str) -> Option<View> {
    let r = scenario.robots.iter().find(|r| r.spec.name == robot)?;
    let b = hetsim_scene::stereo_bench(r)?;
    Some(View {
        body_from_camera: Pose::from_parts(
            b.body_from_mount.translation,
            b.body_from_mount.rotation * hetsim_msgs::mount_to_optical(),
        ),
        k: b.intrinsics,
    })
}

/// Judges every robot's matches and passes.
pub fn judge(
    scenario: &Scenario,
    reports: &[(String, SlamReport)],
    truth: &[(String, Vec<(u64, Pose)>)],
) -> BTreeMap<String, MatchingMetrics> {
    let truth_of = |robot: &str| -> BTreeMap<u64, Pose> {
        truth
            .iter()
            .find(|(n, _)| n == robot)
            .map(|(_, t)| t.iter().copied().collect())
            .unwrap_or_default()
    };
    // Every key frame: robot, stamp, true camera pose, median depth.
    let mut keyframes = Vec::new();
    for (robot, report) in reports {
        let (Some(v), t) = (view_of(scenario, robot), truth_of(robot)) else {
            continue;
        };
        for (stamp, depth) in &report.keyframes {
            if let Some(body) = t.get(stamp) {
                keyframes.push((robot.clone(), *stamp, body * v.body_from_camera, *depth));
            }
        }
    }
    let mut out = BTreeMap::new();
    for (robot, report) in reports {
        let Some(v) = view_of(scenario, robot) else {
            continue;
        };
        let t = truth_of(robot);
        let links: Vec<LinkJudged> = report
            .events
            .iter()
            .filter(|e| e.kind == "image_match")
            .filter_map(|e| {
                let link = e.link.as_ref()?;
                let a = t.get(&e.stamp_ns)?;
                let b = truth_of(&e.other).get(&link.other_stamp_ns).copied()?;
                let err = link.z.inverse() * (a.inverse() * b);
                let r = err.rotation.scaled_axis();
                let x = hetsim_slam::graph::log(&err);
                let nees = Matrix6::from_column_slice(&link.covariance)
                    .try_inverse()
                    .map_or(f64::INFINITY, |i| (x.transpose() * i * x)[0]);
                let (error_m, error_deg) = (err.translation.vector.norm(), r.norm().to_degrees());
                Some(LinkJudged {
                    time_s: e.stamp_ns as f64 * 1e-9,
                    other: e.other.clone(),
                    other_time_s: link.other_stamp_ns as f64 * 1e-9,
                    inliers: link.inliers,
                    error_m,
                    error_deg,
                    nees,
                    false_match: error_m > FALSE_M || error_deg > FALSE_DEG,
                })
            })
            .collect();
        // The robot's frames: the stamps of its own trajectory covariances are not kept, so
        // its truth at 10 Hz (every frame of a 10 Hz bench).
        let frames: Vec<(u64, Pose)> = t
            .iter()
            .filter(|(s, _)| *s % 100_000_000 == 0)
            .map(|(s, p)| (*s, p * v.body_from_camera))
            .collect();
        let mut left = vec![false; keyframes.len()];
        let mut chances = Vec::new();
        let (w, h) = (v.k.width as f64, v.k.height as f64);
        for (stamp, cam) in &frames {
            let mut any = false;
            for (i, (_, kf_stamp, kf_cam, depth)) in keyframes.iter().enumerate() {
                if stamp <= kf_stamp {
                    continue;
                }
                let point = kf_cam * Point3::new(0.0, 0.0, *depth);
                let p = cam.inverse() * point;
                let angle = (kf_cam.rotation * Vector3::z())
                    .dot(&(cam.rotation * Vector3::z()))
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees();
                let radius = depth * (w / 2.0) / v.k.k.alpha_u;
                let here = cam * Point3::new(0.0, 0.0, p.z.max(0.0));
                if angle > MAX_VIEW_DEG || (here - point).norm() > LEAVE * radius {
                    left[i] = true;
                }
                let central = p.z > 0.0 && {
                    let (u, vv) = (
                        v.k.k.alpha_u * p.x / p.z + v.k.k.u0,
                        v.k.k.alpha_v * p.y / p.z + v.k.k.v0,
                    );
                    (u - v.k.k.u0).abs() < w / 4.0 && (vv - v.k.k.v0).abs() < h / 4.0
                };
                any |= left[i] && central && angle <= MAX_VIEW_DEG;
            }
            if any {
                chances.push(*stamp as f64 * 1e-9);
            }
        }
        let mut passes: Vec<[f64; 2]> = Vec::new();
        for c in chances {
            match passes.last_mut() {
                Some(p) if c - p[1] <= 1.0 => p[1] = c,
                _ => passes.push([c, c]),
            }
        }
        let mut m = MatchingMetrics {
            false_matches: links.iter().filter(|l| l.false_match).count(),
            passes: passes.len(),
            ..Default::default()
        };
        for p in &passes {
            let matched = links
                .iter()
                .any(|l| l.time_s >= p[0] - 1.0 && l.time_s <= p[1] + 1.0);
            let waiting = links
                .iter()
                .any(|l| l.time_s < p[0] && p[0] - l.time_s < PERIOD_S);
            if matched {
                m.found += 1;
            } else if waiting {
                m.waiting += 1;
            } else {
                m.missed += 1;
                m.missed_at_s.push(*p);
            }
        }
        m.links = links;
        out.insert(robot.clone(), m);
    }
    out
}
