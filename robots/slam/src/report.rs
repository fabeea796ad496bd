//! What a SLAM stack publishes for evaluation (as the `slam/report` artifact): its sub-map
//! origins with covariance, the covariance of every pose of its trajectory, its events.

use hetsim_msgs::Pose;
use serde::{Deserialize, Serialize};

/// The name of the report artifact a [`crate::stack::SlamStack`] publishes.
pub const REPORT_ARTIFACT: &str = "slam/report";

/// An event of a SLAM stack's global level, with the robot's estimate of its own pose
/// just before and just after the graph was optimized with it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlamEvent {
    /// `"rendezvous"` or `"image_match"`.
    pub kind: String,
    /// The frame at which it happened, nanoseconds.
    pub stamp_ns: u64,
    /// The other robot (empty for a GPS fix).
    pub other: String,
    /// The robot's pose estimate before, in the frame of `frame_before`.
    pub before: Pose,
    /// And after, in the frame of `frame_after`.
    pub after: Pose,
    /// The robot whose first origin is the frame of `before` (see [`SlamReport::frame`]).
    pub frame_before: String,
    /// And of `after`: an event that joins this robot to another's component changes it.
    pub frame_after: String,
    /// The link this robot measured (none for the other side of a partial rendezvous).
    pub link: Option<EventLink>,
}

/// A link an event measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EventLink {
    /// The other robot's frame it reaches (an origin, or the frame of a partial rendezvous).
    pub other_stamp_ns: u64,
    /// The measured `this body from the other body` at those frames.
    pub z: Pose,
    /// The covariance of its right perturbation `(δt, δθ)` (6 x 6, column-major).
    pub covariance: Vec<f64>,
    /// Image matching: the RANSAC inliers.
    pub inliers: Option<usize>,
    /// Image matching: the Mahalanobis distance squared to the graph's prediction.
    pub mahalanobis2: Option<f64>,
}

/// What a SLAM stack built, for the evaluation: sub-map origins with covariance, the
/// covariance of every pose of its `slam` trajectory, and its events.
///
/// Frames: a robot's estimates are in the frame of some robot's first sub-map origin (its
/// pose at its first stereo pair), never in the simulator's world, which robot software
/// does not know. `vo` and `slam-open` are in the robot's own frame; the `slam` trajectory,
/// the `map` and the origins in [`SlamReport::frame`]'s. [`SlamReport::own_origin_at_link`]
/// places the robot's own frame in another robot's.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SlamReport {
    /// The robot whose first origin is the frame of the `slam` trajectory, the `map` and the
    /// origins: the team's reference once an event has linked this robot to it, else its own.
    pub frame: String,
    /// Its sub-map origins: stamp, optimized world pose, marginal covariance of the right
    /// perturbation `(δt, δθ)` (6 x 6, column-major).
    pub origins: Vec<(u64, Pose, Vec<f64>)>,
    /// Covariance of each pose of the `slam` trajectory, in its order (same convention).
    pub covariances: Vec<Vec<f64>>,
    /// Events in order.
    pub events: Vec<SlamEvent>,
    /// Counters (observations used and gated, shares sent and received, unresolved links).
    pub counters: std::collections::BTreeMap<String, u64>,
    /// This robot's key frames (one per origin): stamp and the median depth of their points,
    /// metres.
    #[serde(default)]
    pub keyframes: Vec<(u64, f64)>,
    /// The frame this robot was localized in by its first link to it (the team's, through
    /// the rendezvous just after the start in the village), and its own first origin there
    /// as the graph had it once optimized with that link (and whatever else had arrived
    /// with it), before later events refined it; `None` while the robot is in its own
    /// frame. The open-loop estimate and VO have no events, so
    /// this is where they lie in the team's frame: as the seed's Fig. 7 draws them, all
    /// three estimates start from the same link.
    #[serde(default)]
    pub own_origin_at_link: Option<(String, Pose)>,
    /// The stamp of [`SlamReport::frame`]'s robot's first origin (where that robot's frame
    /// begins), so that the frame can be placed even when that robot published no report
    /// (a replay of this robot alone).
    #[serde(default)]
    pub frame_start_ns: Option<u64>,
}
