//! The lockstep loop: robot stacks stepped, commands to actuators, physics, sensors (cameras
//! included), the radio, recording, the digest, and the run's raw outputs.
//!
//! One tick (DESIGN.md): every robot stack turns the messages it received into a command
//! (stacks run in parallel, commands are collected in robot order); commands go to the
//! actuators; physics steps once; every sensor due this tick samples the world and its message
//! is queued for the robot, to be read at the next tick; radio messages arrive. Nothing waits
//! on the wall clock.
//!
//! Every command and message is added to the run digest (postcard-encoded, in robot order) as
//! it is produced. The engine knows no seed's mission and no robot software: the caller hands
//! it one [`hetsim_msgs::RobotStack`] per robot, and evaluation (`hetsim-eval`) reads the
//! [`RunOutput`] it returns.

pub mod cameras;
pub mod comms;
pub mod frames;
mod output;
pub mod record;
pub mod replay;
mod run;

pub use output::{tum_line, RobotOutcome, RunOutput};
pub use replay::{replay, replay_withholding_truth, ReplayError};
pub use run::{run, RunError, RunOptions};
