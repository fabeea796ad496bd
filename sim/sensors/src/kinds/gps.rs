//! A GPS receiver: the antenna's position with white noise, silent during outages, at its rate
//! or at the instants of a schedule.

use super::{normal, At, Model};
use hetsim_core::SimRng;
use hetsim_msgs::{GpsFix, SensorMsg};

pub(crate) struct Gps {
    pub sigma_m: f64,
    pub outages_s: Vec<[f64; 2]>,
    /// Fix instants, seconds (empty: every period).
    pub schedule_s: Vec<f64>,
    /// The next instant of the schedule.
    pub next: usize,
}

impl Model for Gps {
    fn due(&mut self, after: u64, period: u64, now_ns: u64) -> bool {
        if self.schedule_s.is_empty() {
            return after % period == 0;
        }
        let t = now_ns as f64 / 1e9;
        let mut fire = false;
        while self.next < self.schedule_s.len() && self.schedule_s[self.next] <= t + 1e-12 {
            self.next += 1;
            fire = true;
        }
        fire
    }

    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let t = at.stamp_ns as f64 / 1e9;
        if self.outages_s.iter().any(|[a, b]| t >= *a && t <= *b) {
            return Vec::new();
        }
        let origin = at.world_from_sensor.translation.vector;
        let position_m = [0, 1, 2].map(|a| origin[a] + normal(rng, self.sigma_m));
        vec![SensorMsg::Gps(GpsFix {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            position_m,
            sigma_m: self.sigma_m,
        })]
    }
}
