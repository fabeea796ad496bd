//! Wheel odometry: each wheel's distance since the last reading, with a per-run scale error
//! and noise growing with the distance.

use super::{normal, At, Model};
use crate::ros2::{from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{SensorMsg, WheelOdometry as Reading};
use hetsim_physics::Physics;
use serde::{Deserialize, Serialize};

pub(crate) struct WheelOdometry {
    noise_per_m: f64,
    /// Each wheel's scale error, drawn once per run.
    scale: [f64; 2],
    /// Each wheel's distance since the last reading, metres.
    travelled: [f64; 2],
}

impl WheelOdometry {
    pub fn new(scale_sigma: f64, noise_per_m: f64, rng: &mut SimRng) -> Self {
        Self {
            noise_per_m,
            scale: [normal(rng, scale_sigma), normal(rng, scale_sigma)],
            travelled: [0.0; 2],
        }
    }
}

impl Model for WheelOdometry {
    fn integrate(&mut self, physics: &Physics, robot: usize, dt: f64) {
        if let Some(speeds) = physics.wheel_speeds(robot) {
            self.travelled[0] += speeds[0] * dt;
            self.travelled[1] += speeds[1] * dt;
        }
    }

    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let noise_per_m = self.noise_per_m;
        let read =
            |d: f64, sc: f64, rng: &mut SimRng| d * (1.0 + sc) + normal(rng, noise_per_m * d.abs());
        let left_m = read(self.travelled[0], self.scale[0], rng);
        let right_m = read(self.travelled[1], self.scale[1], rng);
        self.travelled = [0.0; 2];
        vec![SensorMsg::WheelOdometry(Reading {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            left_m,
            right_m,
        })]
    }
}

/// `hetsim_msgs/msg/WheelOdometry`.
#[derive(Serialize, Deserialize)]
struct Ros2WheelOdometry {
    header: Header,
    left_m: f64,
    right_m: f64,
}

impl Ros2Message for Reading {
    const SCHEMA: &'static str = "hetsim_msgs/msg/WheelOdometry";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "# Distance each wheel rolled since the last message, metres.\nstd_msgs/Header header\nfloat64 left_m\nfloat64 right_m\n",
                &[HEADER, TIME],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let m = Ros2WheelOdometry {
            header: frames.in_sensor(),
            left_m: self.left_m,
            right_m: self.right_m,
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2WheelOdometry = from_cdr(data)?;
        Ok(SensorMsg::WheelOdometry(Reading {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            left_m: m.left_m,
            right_m: m.right_m,
        }))
    }
}
