//! The lockstep loop, the run digest, and the run's output files.
//!
//! One tick (DESIGN.md): every robot stack turns the messages it received into a command
//! (stacks run in parallel, commands are collected in robot order); commands go to the
//! actuators; physics steps once; every sensor due this tick samples the world and its message
//! is queued for the robot, to be read at the next tick. Nothing waits on the wall clock.
//!
//! Every command and message is added to the run digest (postcard-encoded, in robot order) as
//! it is produced, and every output file's bytes are added before the files are written, so the
//! digest covers everything the run produced. Wall-clock timings are kept apart, in
//! `timing.json`, and are not part of the digest.

pub mod cameras;
pub mod comms;
pub mod coverage;
pub mod frames;
pub mod localize;
mod output;
pub mod plot;
pub mod record;
pub mod regress;
pub mod report;
mod run;
pub mod slam;
mod stacks;
pub mod sweep;
pub mod team;
pub mod trajectory;

pub use output::{write_run, RunFiles, WriteError};
pub use run::{run, Estimate, Metrics, RobotMetrics, RunError, RunOptions, RunResult};
