//! Commands from a robot stack to its actuators.

use serde::{Deserialize, Serialize};

/// What a stack asks its actuators to do until its next command.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Command {
    /// Wheel surface speeds of a skid-steer or differential-drive base, metres per second,
    /// positive forward.
    Wheels {
        /// Left side.
        left_mps: f64,
        /// Right side.
        right_mps: f64,
    },
    /// Attitude and climb-rate targets of a helicopter's autopilot inner loop.
    ///
    /// The attitude is `R = Rz(yaw) Ry(pitch) Rx(roll)` in the world frame: positive pitch
    /// tilts the nose down and accelerates forward, positive roll tilts the right side down
    /// and accelerates to the right.
    Helicopter {
        /// Roll target.
        roll_rad: f64,
        /// Pitch target.
        pitch_rad: f64,
        /// Yaw rate target, counter-clockwise positive.
        yaw_rate_radps: f64,
        /// Vertical speed target, up positive.
        climb_rate_mps: f64,
    },
    /// Hold still (zero wheel speeds, or hover).
    Stop,
}
