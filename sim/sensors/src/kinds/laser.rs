//! A planar laser scanner: one ray per beam against the physics world's colliders (the
//! carrying robot excluded), each range with white noise, beyond the maximum as infinity.

use super::{normal, At, Model};
use hetsim_core::SimRng;
use hetsim_msgs::{LaserScan, SensorMsg};
use nalgebra::Vector3;

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
