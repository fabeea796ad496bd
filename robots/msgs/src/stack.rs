//! The interface every robot stack implements.

use crate::{Command, Outgoing, Pose, SensorMsg, TeamReport};
use serde::{Deserialize, Serialize};

/// How far a stack has got with its mission.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct StackStatus {
    /// Goals (waypoints, vertices) reached so far.
    pub goals_reached: usize,
    /// Goals in the mission.
    pub goals_total: usize,
    /// Goals given up (unreachable).
    pub goals_skipped: usize,
}

impl StackStatus {
    /// Whether every goal is reached or given up.
    pub fn done(&self) -> bool {
        self.goals_reached + self.goals_skipped >= self.goals_total
    }
}

/// The robot software of one robot.
///
/// The engine calls [`RobotStack::step`] once per tick, before physics, with the messages
/// delivered to this robot since the previous call (in delivery order). A stack must be a pure
/// function of the messages it has seen: no clock, no ambient randomness.
pub trait RobotStack: Send {
    /// Turns the messages received since the last call into a command.
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Command;

    /// Progress with the mission.
    fn status(&self) -> StackStatus;

    /// Messages to send to other robots, taken after each [`RobotStack::step`]. The radio
    /// (range, latency, bandwidth, loss) decides whether and when they arrive.
    fn outbox(&mut self) -> Vec<Outgoing> {
        Vec::new()
    }

    /// Estimated trajectories the stack kept (for example `"vo"`), each a list of
    /// `(stamp_ns, world_from_body)`; the engine writes them as `<name>/<robot>.tum`.
    fn trajectories(&self) -> Vec<(String, Vec<(u64, Pose)>)> {
        Vec::new()
    }

    /// Whether the stack wants its cameras' images now. The engine renders a camera only
    /// when its robot wants images (a child that grabs on demand saves the renderer the
    /// frames it would drop); the camera's timing does not change.
    fn wants_images(&self) -> bool {
        true
    }

    /// A coverage parent's report (its image database and mission figures).
    fn team_report(&self) -> Option<TeamReport> {
        None
    }

    /// Whether the stack's mission is over and the run may end (a coverage parent whose
    /// plan is done). The engine ends a run two seconds after any stack says so.
    fn mission_over(&self) -> bool {
        false
    }

    /// Mapped 3D points in the world frame, with the sub-map each belongs to (a SLAM
    /// stack's map; the engine writes them to `map.ply`).
    fn map_points(&self) -> Vec<(usize, [f64; 3])> {
        Vec::new()
    }

    /// Mapped 3D segments (two endpoints) in the world frame, with the sub-map each belongs
    /// to (a SLAM stack's lines; the engine writes them to `map.ply` as edges).
    fn map_segments(&self) -> Vec<(usize, [[f64; 3]; 2])> {
        Vec::new()
    }

    /// Stamps of the frames the stack made key frames (a SLAM stack's sub-map origins), in
    /// order. The simulator's emulated image matcher matches other robots' frames against
    /// them.
    fn keyframes(&self) -> &[u64] {
        &[]
    }

    /// A SLAM stack's report (sub-map origins, pose covariances, events).
    fn slam_report(&self) -> Option<crate::SlamReport> {
        None
    }
}
