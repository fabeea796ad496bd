//! The interface every robot stack implements, and what a stack publishes at the end of a run.

use crate::{Command, InputError, Outgoing, Pose, SensorMsg};
use serde::{Deserialize, Serialize};

/// How far a stack has got with its mission, and what it wants from the simulator now.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct StackStatus {
    /// Goals (waypoints, vertices) reached so far.
    pub goals_reached: usize,
    /// Goals in the mission.
    pub goals_total: usize,
    /// Goals given up (unreachable).
    pub goals_skipped: usize,
    /// Whether the stack wants its cameras' images now. The engine renders a camera only when
    /// its robot wants images (a child that grabs on demand saves the renderer the frames it
    /// would drop); the camera's timing does not change.
    pub wants_images: bool,
    /// Whether the stack's mission is over and the run may end (a coverage parent whose plan is
    /// done). The engine ends a run two seconds after any stack says so.
    pub mission_over: bool,
}

impl Default for StackStatus {
    /// No goals, images wanted, mission going on.
    fn default() -> Self {
        Self {
            goals_reached: 0,
            goals_total: 0,
            goals_skipped: 0,
            wants_images: true,
            mission_over: false,
        }
    }
}

impl StackStatus {
    /// Whether every goal is reached or given up.
    pub fn done(&self) -> bool {
        self.goals_reached + self.goals_skipped >= self.goals_total
    }
}

/// Something a stack made that outlives the run: the run writes it, evaluation reads it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Artifact {
    /// What it is, unique per robot: a trajectory's kind (`vo`, `slam`), `map`, or a report's
    /// name (`slam/report`, `coverage/team`).
    pub name: String,
    /// The content.
    pub data: ArtifactData,
}

/// The content of an [`Artifact`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum ArtifactData {
    /// An estimated trajectory, `(stamp_ns, world_from_body)` in stamp order; the run writes it
    /// as `<name>/<robot>.tum`.
    Trajectory(Vec<(u64, Pose)>),
    /// A map in the world frame: points and segments (two endpoints), each with the sub-map it
    /// belongs to; the run writes every robot's map into `map.ply`.
    Map {
        /// Mapped points.
        points: Vec<(usize, [f64; 3])>,
        /// Mapped segments.
        segments: Vec<(usize, [[f64; 3]; 2])>,
    },
    /// A report whose type the publishing crate owns, postcard-encoded (see
    /// [`Artifact::report`] and [`Artifact::decode`]).
    Report(Vec<u8>),
}

impl Artifact {
    /// A trajectory artifact.
    pub fn trajectory(name: &str, poses: Vec<(u64, Pose)>) -> Self {
        Self {
            name: name.to_string(),
            data: ArtifactData::Trajectory(poses),
        }
    }

    /// A report artifact: `value` postcard-encoded under `name`.
    pub fn report<T: Serialize>(name: &str, value: &T) -> Self {
        Self {
            name: name.to_string(),
            data: ArtifactData::Report(
                postcard::to_stdvec(value).expect("plain-data reports always encode"),
            ),
        }
    }

    /// Decodes a report artifact as `T`; `None` if this is not a report or its bytes are not a
    /// `T`.
    pub fn decode<T: for<'de> Deserialize<'de>>(&self) -> Option<T> {
        match &self.data {
            ArtifactData::Report(bytes) => postcard::from_bytes(bytes).ok(),
            _ => None,
        }
    }
}

/// The robot software of one robot.
///
/// The engine calls [`RobotStack::step`] once per tick, before physics, with the messages
/// delivered to this robot since the previous call (in delivery order), then takes its
/// [`RobotStack::outbox`] and reads its [`RobotStack::status`]. At the end of the run it takes
/// the stack's [`RobotStack::artifacts`]. A stack must be a pure function of the messages it
/// has seen: no clock, no ambient randomness, no ground truth beyond the oracle sensors its
/// robot file declares.
pub trait RobotStack: Send {
    /// Turns the messages received since the last call into a command. A stack checks what it
    /// is fed first ([`crate::InboxGuard`], and what only it knows, such as its cameras'
    /// sizes) and refuses a bad message with an [`InputError`], before it computes anything
    /// on it; the caller stops there.
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<Command, InputError>;

    /// Progress with the mission, and what the stack wants now (read after every step).
    fn status(&self) -> StackStatus;

    /// Messages to send to other robots, taken after each [`RobotStack::step`]. The radio
    /// (range, latency, bandwidth, loss) decides whether and when they arrive.
    fn outbox(&mut self) -> Vec<Outgoing> {
        Vec::new()
    }

    /// What the stack publishes at the end of the run (trajectories, maps, reports), in a
    /// fixed order.
    fn artifacts(&self) -> Vec<Artifact> {
        Vec::new()
    }

    /// **Oracle, the one exception to "the simulator learns nothing from a stack"**: stamps of
    /// the frames a SLAM stack made key frames (its sub-map origins), in order. The simulator's
    /// emulated `image_match` sensor pairs them with the truth; the manifest lists that sensor
    /// as an oracle. It goes when image matching runs as robot software.
    fn oracle_keyframes(&self) -> &[u64] {
        &[]
    }
}
