//! One module per sensor kind, each the kind's measurement model behind [`Model`]; [`model_of`]
//! is the registry that makes a robot file's sensor into its model. Cameras are rendered by the
//! engine and oracles delivered by it, so neither is here.
//!
//! Each module also implements its message's ROS 2 form ([`crate::ros2::Ros2Message`]:
//! definition, CDR encoding, decoding), which recordings and replay use.
//!
//! Adding a kind: its table in `hetsim_scene::Sensor` (with its checks), its message in
//! `hetsim_msgs`, a module here (model and ROS 2 form), its line in [`model_of`] and in
//! `ros2.rs`'s registry ([`crate::ros2::KINDS`], [`crate::ros2::encode`]), and its JSON
//! encoding in `hetsim-io` (`record/json.rs`).

mod child_tracker;
mod compass;
mod gps;
mod image_match;
mod imu;
mod laser;
mod odometry;
mod rendezvous;

use hetsim_core::SimRng;
use hetsim_msgs::{Pose, SensorMsg};
use hetsim_physics::Physics;
use hetsim_scene::Sensor;
use rand_distr::{Distribution, StandardNormal};

/// The robots of the run as the sensors that look at other robots need them.
pub(crate) struct Team {
    /// Robot names, in scenario order.
    pub names: Vec<String>,
    /// Whether each robot wears the tracker's orange hat (its robot file's `body.hat`).
    pub hats: Vec<bool>,
    /// Body heights, metres.
    pub heights: Vec<f64>,
}

/// What a sensor measures from: the world after physics stepped, at one stamp.
pub(crate) struct At<'a> {
    pub physics: &'a Physics,
    pub stamp_ns: u64,
    /// The robot carrying the sensor.
    pub robot: usize,
    pub world_from_body: Pose,
    pub world_from_sensor: Pose,
    /// The sensor's name, for its messages.
    pub sensor: String,
    pub team: &'a Team,
    /// Key frames the robots' stacks made: `(robot, stamp, true world_from_body)`.
    pub keyframes: &'a [(usize, u64, Pose)],
}

/// An IMU's noise model and its run's true biases.
pub(crate) struct ImuState {
    pub gyro_sigma_radps: f64,
    pub accel_sigma_mps2: f64,
    pub gyro_bias: [f64; 3],
    pub accel_bias: [f64; 3],
}

/// A sensor kind's model.
pub(crate) trait Model: Send {
    /// Every tick, after physics has stepped (integrating sensors accumulate here).
    fn integrate(&mut self, _physics: &Physics, _robot: usize, _dt: f64) {}

    /// Whether the sensor fires at the end of tick `after - 1` (stamp `now_ns`); by default
    /// every `period` ticks.
    fn due(&mut self, after: u64, period: u64, _now_ns: u64) -> bool {
        after % period == 0
    }

    /// The messages of one measurement (none, one, or one per robot seen).
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg>;

    /// An IMU's truth (noise and biases), for the datasets the simulator writes.
    fn imu(&self) -> Option<&ImuState> {
        None
    }
}

/// The model of a robot file's sensor, drawing its per-run constants (biases, scale errors)
/// from the sensor's stream; `None` for cameras and oracles.
pub(crate) fn model_of(spec: &Sensor, rng: &mut SimRng) -> Option<Box<dyn Model>> {
    Some(match spec {
        Sensor::Camera { .. }
        | Sensor::StereoCamera { .. }
        | Sensor::OmniCamera { .. }
        | Sensor::OraclePose { .. } => return None,
        Sensor::Compass {
            sigma_deg,
            bias_deg,
            distortion_deg,
            ..
        } => Box::new(compass::Compass {
            sigma_deg: *sigma_deg,
            bias_deg: *bias_deg,
            distortion_deg: *distortion_deg,
        }),
        Sensor::Gps {
            sigma_m,
            outages_s,
            schedule_s,
            ..
        } => Box::new(gps::Gps {
            sigma_m: *sigma_m,
            outages_s: outages_s.clone(),
            schedule_s: schedule_s.clone(),
            next: 0,
        }),
        Sensor::WheelOdometry {
            scale_sigma,
            noise_per_m,
            ..
        } => Box::new(odometry::WheelOdometry::new(
            *scale_sigma,
            *noise_per_m,
            rng,
        )),
        Sensor::Imu {
            gyro_sigma_radps,
            accel_sigma_mps2,
            gyro_bias_sigma_radps,
            accel_bias_sigma_mps2,
            ..
        } => Box::new(imu::Imu::new(
            *gyro_sigma_radps,
            *accel_sigma_mps2,
            *gyro_bias_sigma_radps,
            *accel_bias_sigma_mps2,
            rng,
        )),
        Sensor::Laser {
            fov_deg,
            resolution_deg,
            max_range_m,
            range_sigma_m,
            ..
        } => Box::new(laser::Laser {
            fov_deg: *fov_deg,
            resolution_deg: *resolution_deg,
            max_range_m: *max_range_m,
            range_sigma_m: *range_sigma_m,
        }),
        Sensor::ChildTracker {
            range_m,
            error_mean_m,
            error_std_m,
            ..
        } => Box::new(child_tracker::ChildTracker {
            range_m: *range_m,
            error_mean_m: *error_mean_m,
            error_std_m: *error_std_m,
        }),
        Sensor::Rendezvous {
            range_m,
            fov_deg,
            sigma_m,
            sigma_deg,
            ..
        } => Box::new(rendezvous::Rendezvous {
            range_m: *range_m,
            fov_deg: *fov_deg,
            sigma_m: *sigma_m,
            sigma_deg: *sigma_deg,
        }),
        Sensor::ImageMatch {
            range_m,
            min_age_s,
            sigma_m,
            sigma_deg,
            ..
        } => Box::new(image_match::ImageMatch {
            range_m: *range_m,
            min_age_s: *min_age_s,
            sigma_m: *sigma_m,
            sigma_deg: *sigma_deg,
            used: Default::default(),
        }),
    })
}

/// A zero-mean Gaussian draw.
pub(crate) fn normal(rng: &mut SimRng, sigma: f64) -> f64 {
    let n: f64 = StandardNormal.sample(rng);
    n * sigma
}
