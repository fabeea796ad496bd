//! A magnetic compass: the sensor's heading plus a constant bias, a heading-dependent
//! distortion and white noise.

use super::{normal, At, Model};
use crate::ros2::{from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{wrap_angle, yaw_of, CompassReading, SensorMsg};
use serde::{Deserialize, Serialize};

pub(crate) struct Compass {
    pub sigma_deg: f64,
    pub bias_deg: f64,
    pub distortion_deg: f64,
}

impl Model for Compass {
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let yaw = yaw_of(&at.world_from_sensor);
        let heading = yaw
            + self.bias_deg.to_radians()
            + self.distortion_deg.to_radians() * yaw.sin()
            + normal(rng, self.sigma_deg.to_radians());
        vec![SensorMsg::Compass(CompassReading {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            heading_rad: wrap_angle(heading),
        })]
    }
}

/// `hetsim_msgs/msg/Compass`.
#[derive(Serialize, Deserialize)]
struct Ros2Compass {
    header: Header,
    heading_rad: f64,
}

impl Ros2Message for CompassReading {
    const SCHEMA: &'static str = "hetsim_msgs/msg/Compass";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "# Heading, radians counter-clockwise from east.\nstd_msgs/Header header\nfloat64 heading_rad\n",
                &[HEADER, TIME],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let m = Ros2Compass {
            header: frames.in_sensor(),
            heading_rad: self.heading_rad,
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2Compass = from_cdr(data)?;
        Ok(SensorMsg::Compass(CompassReading {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            heading_rad: m.heading_rad,
        }))
    }
}
