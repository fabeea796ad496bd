//! The boundary between the simulator and the robot software.
//!
//! Everything that crosses it is plain data: sensor messages in, commands out, plus the
//! geometry both sides share. The robot crates (`robots/*`) depend on this crate and never on
//! any `sim/*` crate, so a robot stack can run on recorded or hand-made messages, or on a real
//! robot.
//!
//! # Frames and units (ROS REP-103 / REP-105)
//!
//! * world frame `world`: x east, y north, z up, metres; the origin is the centre of the world
//!   the scenario describes;
//! * body frame: x forward, y left, z up, origin at the body's centre on the ground plane
//!   (ground robots) or at its centre of mass (helicopter);
//! * angles in radians unless a name says `_deg`; yaw is measured counter-clockwise from east;
//! * times are integer nanoseconds of sim time (`stamp_ns`).

mod camera;
mod check;
mod command;
mod geometry;
mod message;
pub mod params;
mod stack;

pub use camera::{mount_to_optical, CameraGeometry, Pinhole};
pub use check::{check_message, sensor_of, InboxGuard, InputError};
pub use command::Command;
pub use geometry::{pose_from_xyz_rpy, wrap_angle, yaw_of, Pose};
pub use message::{
    ChildTracks, CompassReading, CoverageMission, Delivered, GpsFix, Image, ImageMatch, ImuSample,
    LaserScan, Mission, OccupancyGrid, Outgoing, PixelEncoding, PoseStamped, Rendezvous, SensorMsg,
    Track, WheelOdometry,
};
pub use stack::{Artifact, ArtifactData, RobotStack, StackStatus};
