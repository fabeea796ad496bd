//! The rapier3d world and the drive models that move the robots through it.
//!
//! Static geometry from [`hetsim_scene::world::World`] becomes fixed colliders (a heightfield
//! for the village terrain, cuboids for buildings, walls, obstacles and the indoor floor).
//! Each robot is a kinematic, position-based rigid body moved by its drive model:
//!
//! * **skid-steer / differential** ([`drive::GroundDrive`]): first-order wheel-speed response,
//!   longitudinal slip, the skid-steer instantaneous-centre-of-rotation expansion, and a
//!   slowly varying (Ornstein-Uhlenbeck) relative wheel-speed error drawn from the robot's own
//!   random stream. The body is swept against obstacles and other robots with a shape cast
//!   (stopping at contact and counting collisions) and seated on the ground by four ray casts
//!   at its corners, which also give its pitch and roll on the terrain;
//! * **helicopter** ([`drive::HeliDrive`]): first-order attitude and climb-rate response to
//!   the autopilot targets; the rotor thrust tilted with the body accelerates it horizontally
//!   against linear drag sized so that the top speed is reached at the largest tilt.
//!
//! Kinematic bodies keep the world deterministic and cheap to step (rapier is built with
//! `enhanced-determinism`, bodies and colliders are created in a fixed order) while rapier's
//! queries give exact contact with the same geometry the sensors and renderer see.

pub mod drive;
mod world;

pub use world::{Hit, Physics, RobotState};
