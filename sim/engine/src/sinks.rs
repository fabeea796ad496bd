//! Where a live run's streams go besides the robots and the digest: a recording of every
//! message, command and true pose, and a dump of camera frames. The loop calls these traits
//! at fixed points of a tick and knows no file format; the formats (ROS 2 MCAP, EuRoC
//! datasets) are `hetsim-io`'s. Nothing a sink does reaches the digest.

use crate::cameras::Shot;
use hetsim_msgs::{Command, ImuSample, Pose, SensorMsg};
use hetsim_scene::Scenario;

/// Why a sink could not write: its own error, whose message the run's error carries.
pub type SinkError = Box<dyn std::error::Error + Send + Sync>;

/// What the physics measured of one robot, kept in a recording (a replay has no physics).
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedOutcome {
    /// The robot.
    pub name: String,
    /// Distance travelled in the xy plane, metres.
    pub distance_m: f64,
    /// Collisions (contact episodes).
    pub collisions: u32,
}

/// A recording of a live run: every message a robot receives, every command it sends and
/// every true pose, in the order the run produces them.
pub trait RunRecorder: Send {
    /// The run about to start: its scenario and whether its cameras are rendered. Called
    /// once, before the first pose.
    fn describe(&mut self, scenario: &Scenario, rendered: bool) -> Result<(), SinkError>;
    /// A robot's true pose (`world_from_body`), at every tick.
    fn truth(&mut self, robot: &str, stamp_ns: u64, pose: &Pose);
    /// A robot's command of the tick starting at `stamp_ns`.
    fn command(&mut self, robot: &str, stamp_ns: u64, cmd: &Command);
    /// A message delivered to `robot` on `topic` (`<robot>/<sensor>`), to be read at
    /// `received_ns`; `mount` is the sensor's `body_from_sensor` where it has one.
    fn sensor(
        &mut self,
        robot: &str,
        topic: &str,
        mount: Option<&Pose>,
        msg: &SensorMsg,
        received_ns: u64,
    );
    /// The run is over after `ticks` ticks: what only the physics knew.
    fn outcome(&mut self, ticks: u64, robots: &[RecordedOutcome]) -> Result<(), SinkError>;
}

/// An IMU of a robot, as a frame dump describes it.
#[derive(Clone, Debug)]
pub struct ImuSpec {
    /// `<robot>/<imu>`.
    pub topic: String,
    /// Samples per second (after rounding to whole ticks).
    pub rate_hz: f64,
    /// Angular-rate white noise per sample, rad/s.
    pub gyro_sigma_radps: f64,
    /// Acceleration white noise per sample, m/s^2.
    pub accel_sigma_mps2: f64,
    /// `body_from_sensor`.
    pub body_from_sensor: Pose,
    /// The run's true constant biases `(gyro rad/s, accel m/s^2)` in the sensor frame.
    pub bias: ([f64; 3], [f64; 3]),
}

/// A dump of camera frames, with the IMU samples and true poses that go with them.
pub trait FrameSink: Send {
    /// The cameras (`<robot>/<camera>[/left|right]`, robot-file order) and IMUs of the run.
    /// Called once, before the first frame.
    fn begin(&mut self, camera_topics: &[String], imus: &[ImuSpec]);
    /// Whether the frame of `topic` stamped `stamp_ns` is dumped: it is then rendered, with
    /// its ground-truth depth, whatever the robot wants.
    fn wants_frame(&self, topic: &str, stamp_ns: u64) -> bool;
    /// A rendered frame the sink wants.
    fn write(&mut self, shot: &Shot) -> Result<(), SinkError>;
    /// An IMU sample (the sink keeps those it wants).
    fn imu(&mut self, topic: &str, sample: &ImuSample);
    /// The run is over: each robot's true poses at the truth rate.
    fn finish(&self, truth: &[(&str, &[(u64, Pose)])]) -> Result<(), SinkError>;
}
