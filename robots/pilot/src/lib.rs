//! Low-level guidance: waypoint followers that turn a pose estimate into actuator commands.
//!
//! These are the stacks robots run until the SLAM and coverage stacks take over, and the motion
//! primitives those stacks reuse:
//!
//! * [`GroundPilot`]: skid-steer / differential-drive waypoint following, either smooth
//!   (pure-pursuit-like, the rover and the parent) or rotate-then-straight with re-aiming as the
//!   seed prescribes for the c't-Bots (rotate towards the goal, drive straight, re-aim within
//!   0.2 m, Section V.B of `002_4e4d2d7b10a09d98`);
//! * [`HeliPilot`]: a cascaded position -> velocity -> attitude controller for the helicopter;
//! * [`grid_path`]: shortest up/down/left/right path between free grid cells;
//! * [`lawnmower`]: the helicopter's survey route;
//! * [`PilotTable`]: the robot file's `[pilot]` table these are set from.
//!
//! The pilots read only [`SensorMsg::TruthPose`](hetsim_msgs::SensorMsg) for now; the pose
//! source becomes the SLAM estimate in a later stage without changing this crate's interface.

mod grid;
mod ground;
mod heli;
mod route;
mod table;

pub use grid::grid_path;
pub use ground::{GroundPilot, GroundPilotParams, Steering};
pub use heli::{HeliPilot, HeliPilotParams};
pub use route::lawnmower;
pub use table::{PilotTable, SteeringKind};
