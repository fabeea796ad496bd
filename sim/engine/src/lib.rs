//! The lockstep loop and the radio: robot stacks stepped, commands to actuators, physics,
//! sensors (cameras included), radio deliveries, the digest, and the run's raw outputs; and
//! the same loop fed from a recording (replay).
//!
//! One tick (ARCHITECTURE.md, "The tick loop") is a sequence of named stages (`run`'s
//! `LiveRun`): every robot stack turns the messages it received into a command (stacks run
//! in parallel, commands are collected in robot order); commands go to the actuators;
//! physics steps once; every sensor due this tick samples the world and its message is
//! queued for the robot, to be read at the next tick; radio messages arrive. A replay
//! ([`replay()`]) shares the stages that step the stacks, publish what they sent and post
//! messages (`stages`). Nothing waits on the wall clock.
//!
//! Every command and message is added to the run digest (postcard-encoded, in robot order) as
//! it is produced. The engine knows no seed's mission, no robot software and no file format:
//! the caller hands it one [`hetsim_msgs::RobotStack`] per robot, optionally a
//! [`sinks::RunRecorder`] and a [`sinks::FrameSink`] (`hetsim-io` writes ROS 2 MCAP and EuRoC
//! datasets through them), and a [`replay::Recording`] to replay; evaluation (`hetsim-eval`)
//! reads the [`RunOutput`] it returns.

pub mod cameras;
pub mod comms;
mod output;
pub mod replay;
mod run;
pub mod sinks;
mod stages;

/// The renderer's error, which [`RunError`] carries.
pub use hetsim_render::RenderError;
pub use output::{tum_line, RobotOutcome, RunOutput};
pub use replay::{replay, replay_withholding_truth, ReplayError};
pub use run::{run, RunError, RunOptions};
pub use sinks::{FrameSink, ImuSpec, RecordedOutcome, RunRecorder, SinkError};
