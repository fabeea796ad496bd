//! What a run produced, before evaluation: the engine's raw outputs.

use crate::comms::CommsStats;
use hetsim_core::RunDigest;
use hetsim_msgs::{Artifact, Pose, StackStatus};
use hetsim_render::AdapterSummary;
use hetsim_sensors::camera::calibration::CameraCalibration;
use std::collections::BTreeMap;

/// What one robot did, as the simulator saw it.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotOutcome {
    /// Robot name.
    pub name: String,
    /// Robot model.
    pub model: String,
    /// Distance travelled in the xy plane, metres.
    pub distance_m: f64,
    /// Collisions (contact episodes).
    pub collisions: u32,
    /// The stack's last status.
    pub status: StackStatus,
    /// Final position, metres.
    pub final_position_m: [f64; 3],
    /// SHA-256 over everything the robot's stack computed (its commands and radio messages, in
    /// order): two runs whose stacks computed the same bytes have the same stack digest.
    pub stack_digest: String,
}

/// Everything a run produced, before evaluation and writing.
pub struct RunOutput {
    /// Ticks simulated.
    pub ticks: u64,
    /// Sim time simulated, seconds.
    pub sim_secs: f64,
    /// Messages and commands digested during the run.
    pub records: u64,
    /// Per robot, in scenario order.
    pub robots: Vec<RobotOutcome>,
    /// Ground-truth poses per robot (scenario order), at the truth rate.
    pub truth: Vec<(String, Vec<(u64, Pose)>)>,
    /// What each robot's stack published at the end (scenario order).
    pub artifacts: Vec<(String, Vec<Artifact>)>,
    /// Messages delivered per topic (sensors, ground truth, radio).
    pub messages: BTreeMap<String, u64>,
    /// What the radio did.
    pub comms: CommsStats,
    /// Digest of every command and message so far (outputs are added when written).
    pub digest: RunDigest,
    /// The adapter that rendered the cameras, if any.
    pub adapter: Option<AdapterSummary>,
    /// Every camera's topic with the calibration its robot was given and the one it had, in
    /// camera order (empty for an unrendered run or a replay).
    pub cameras: Vec<(String, CameraCalibration)>,
}

impl RunOutput {
    /// The truth of a robot, by name.
    pub fn truth_of(&self, robot: &str) -> Option<&[(u64, Pose)]> {
        self.truth
            .iter()
            .find(|(n, _)| n == robot)
            .map(|(_, t)| t.as_slice())
    }

    /// Every artifact named `name`, with its robot, in robot order.
    pub fn artifacts_named<'a>(
        &'a self,
        name: &'a str,
    ) -> impl Iterator<Item = (&'a str, &'a Artifact)> + 'a {
        self.artifacts.iter().flat_map(move |(robot, list)| {
            list.iter()
                .filter(move |a| a.name == name)
                .map(move |a| (robot.as_str(), a))
        })
    }
}

/// One line of a TUM trajectory: `t tx ty tz qx qy qz qw` (seconds, metres, unit quaternion
/// with w last).
pub fn tum_line(stamp_ns: u64, pose: &Pose) -> String {
    let t = pose.translation.vector;
    let q = pose.rotation.quaternion();
    format!(
        "{}.{:09} {:.6} {:.6} {:.6} {:.9} {:.9} {:.9} {:.9}\n",
        stamp_ns / 1_000_000_000,
        stamp_ns % 1_000_000_000,
        t.x,
        t.y,
        t.z,
        q.i,
        q.j,
        q.k,
        q.w
    )
}
