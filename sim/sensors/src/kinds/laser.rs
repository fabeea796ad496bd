//! A planar laser scanner: one ray per beam against the physics world's colliders (the
//! carrying robot excluded), each range with white noise, beyond the maximum as infinity.

use super::{normal, At, Model};
use crate::ros2::{from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{LaserScan, SensorMsg};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub(crate) struct Laser {
    pub fov_deg: f64,
    pub resolution_deg: f64,
    pub max_range_m: f64,
    pub range_sigma_m: f64,
}

impl Model for Laser {
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let origin = at.world_from_sensor.translation.vector;
        let fov = self.fov_deg.to_radians();
        let step = self.resolution_deg.to_radians();
        let beams = (fov / step + 1e-9).floor() as usize + 1;
        let angle_min = -fov / 2.0;
        let mut ranges_m = Vec::with_capacity(beams);
        for b in 0..beams {
            let a = angle_min + b as f64 * step;
            let dir = at.world_from_sensor.rotation * Vector3::new(a.cos(), a.sin(), 0.0);
            let r = at
                .physics
                .cast_ray(
                    [origin.x, origin.y, origin.z],
                    [dir.x, dir.y, dir.z],
                    self.max_range_m,
                    Some(at.robot),
                )
                .map(|(d, _)| d + normal(rng, self.range_sigma_m))
                .filter(|d| *d <= self.max_range_m);
            ranges_m.push(r.map_or(f32::INFINITY, |d| d.max(0.0) as f32));
        }
        vec![SensorMsg::LaserScan(LaserScan {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            angle_min_rad: angle_min,
            angle_increment_rad: step,
            range_max_m: self.max_range_m,
            ranges_m,
        })]
    }
}

/// `sensor_msgs/msg/LaserScan`, as the recorder writes it.
#[derive(Serialize)]
struct Ros2LaserScan<'a> {
    header: Header,
    angle_min: f32,
    angle_max: f32,
    angle_increment: f32,
    time_increment: f32,
    scan_time: f32,
    range_min: f32,
    range_max: f32,
    ranges: &'a [f32],
    intensities: &'a [f32],
}

/// `sensor_msgs/msg/LaserScan`, as replay reads it.
#[derive(Deserialize)]
struct Ros2LaserScanIn {
    header: Header,
    angle_min: f32,
    _angle_max: f32,
    angle_increment: f32,
    _time_increment: f32,
    _scan_time: f32,
    _range_min: f32,
    range_max: f32,
    ranges: Vec<f32>,
    _intensities: Vec<f32>,
}

/// No return reads +inf (REP-117). The type holds the angles as `float32`: replay takes them
/// from the robot file (`hetsim_io`'s replay).
impl Ros2Message for LaserScan {
    const SCHEMA: &'static str = "sensor_msgs/msg/LaserScan";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n",
                &[HEADER, TIME],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let last =
            self.angle_min_rad + self.angle_increment_rad * (self.ranges_m.len().max(1) - 1) as f64;
        let m = Ros2LaserScan {
            header: frames.in_sensor(),
            angle_min: self.angle_min_rad as f32,
            angle_max: last as f32,
            angle_increment: self.angle_increment_rad as f32,
            time_increment: 0.0,
            scan_time: 0.0,
            range_min: 0.0,
            range_max: self.range_max_m as f32,
            ranges: &self.ranges_m,
            intensities: &[],
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2LaserScanIn = from_cdr(data)?;
        Ok(SensorMsg::LaserScan(LaserScan {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            angle_min_rad: m.angle_min as f64,
            angle_increment_rad: m.angle_increment as f64,
            range_max_m: m.range_max as f64,
            ranges_m: m.ranges,
        }))
    }
}
