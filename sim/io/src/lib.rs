//! hetsim's file formats, apart from the loop that produces and consumes them:
//!
//! * [`record`]: `hetsim run --record` writes every message, command and true pose of a run
//!   as ROS 2 MCAP (CDR messages, `ros2msg` schemas), or as JSON, through the engine's
//!   [`hetsim_engine::RunRecorder`];
//! * [`mcap_in`]: such a recording read back, streaming, as the engine's
//!   [`hetsim_engine::replay::Recording`] for `hetsim replay`;
//! * [`frames`]: camera frames, IMU samples and ground truth written as EuRoC MAV datasets
//!   (`--dump-frames`, `hetsim frames`), through the engine's [`hetsim_engine::FrameSink`];
//! * [`euroc_in`]: a EuRoC dataset read back as stereo input for one robot's VO and SLAM.
//!
//! The engine knows none of these formats; the binary wires them to a run.

mod cdr_in;
pub mod euroc_in;
pub mod frames;
pub mod mcap_in;
pub mod record;

pub use euroc_in::EurocRecording;
pub use frames::FrameDump;
pub use mcap_in::McapRecording;
pub use record::{RecordEncoding, Recorder};
