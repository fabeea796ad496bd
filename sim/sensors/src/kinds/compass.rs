//! A magnetic compass: the sensor's heading plus a constant bias, a heading-dependent
//! distortion and white noise.

use super::{normal, At, Model};
use hetsim_core::SimRng;
use hetsim_msgs::{wrap_angle, yaw_of, CompassReading, SensorMsg};

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
