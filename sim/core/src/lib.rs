//! Simulation time, named random streams and the run digest.
//!
//! This crate holds the three things every other simulator crate agrees on:
//!
//! * [`SimClock`]: sim time is an integer tick count with a fixed `dt` in integer nanoseconds,
//!   so that time never accumulates floating-point error and never comes from the wall clock.
//! * [`Streams`]: every random consumer draws from its own ChaCha stream derived from the
//!   master seed and a stable name (`"dala/stereo/left/pixel_noise"`). Adding a consumer never
//!   changes another consumer's stream.
//! * [`RunDigest`]: a SHA-256 over every message and output a run produces, in production
//!   order. Same inputs, same digest.
//! * [`files`]: atomic writes of output files and folders.

mod clock;
mod digest;
pub mod files;
pub mod lock;
mod streams;

pub use clock::{SimClock, Tick};
pub use digest::{PayloadHasher, RunDigest};
pub use streams::{SimRng, Streams};
