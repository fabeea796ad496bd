//! An IMU: angular rate and specific force from the sensor's last three poses, with per-run
//! constant biases and white noise.

use super::{normal, At, ImuState, Model};
use crate::ros2::{self, from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, QUATERNION, TIME, VECTOR3};
use hetsim_core::SimRng;
use hetsim_msgs::{ImuSample, Pose, SensorMsg};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Gravity, m/s^2.
const GRAVITY: f64 = 9.81;

pub(crate) struct Imu {
    state: ImuState,
    /// The sensor's last three stamped poses.
    history: Vec<(u64, Pose)>,
}

impl Imu {
    pub fn new(
        gyro_sigma_radps: f64,
        accel_sigma_mps2: f64,
        gyro_bias_sigma_radps: f64,
        accel_bias_sigma_mps2: f64,
        rng: &mut SimRng,
    ) -> Self {
        let gyro_bias = [0; 3].map(|_| normal(rng, gyro_bias_sigma_radps));
        let accel_bias = [0; 3].map(|_| normal(rng, accel_bias_sigma_mps2));
        Self {
            state: ImuState {
                gyro_sigma_radps,
                accel_sigma_mps2,
                gyro_bias,
                accel_bias,
            },
            history: Vec::new(),
        }
    }
}

impl Model for Imu {
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        self.history.push((at.stamp_ns, at.world_from_sensor));
        if self.history.len() > 3 {
            self.history.remove(0);
        }
        let (angular, accel) = imu_truth(&self.history);
        let s = &self.state;
        let angular_rate_radps =
            [0, 1, 2].map(|a| angular[a] + s.gyro_bias[a] + normal(rng, s.gyro_sigma_radps));
        let accel_mps2 =
            [0, 1, 2].map(|a| accel[a] + s.accel_bias[a] + normal(rng, s.accel_sigma_mps2));
        vec![SensorMsg::Imu(ImuSample {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            angular_rate_radps,
            accel_mps2,
        })]
    }

    fn imu(&self) -> Option<&ImuState> {
        Some(&self.state)
    }
}

/// Angular rate (sensor frame) and specific force (sensor frame) from the last three poses.
fn imu_truth(history: &[(u64, Pose)]) -> ([f64; 3], [f64; 3]) {
    let n = history.len();
    if n < 2 {
        let r = history[0].1.rotation;
        let f = r.inverse() * Vector3::new(0.0, 0.0, GRAVITY);
        return ([0.0; 3], [f.x, f.y, f.z]);
    }
    let (t1, p1) = history[n - 1];
    let (t0, p0) = history[n - 2];
    let dt = (t1 - t0) as f64 / 1e9;
    let delta = p0.rotation.inverse() * p1.rotation;
    let w = delta.scaled_axis() / dt;
    let accel = if n >= 3 {
        let (tm, pm) = history[n - 3];
        let dtm = (t0 - tm) as f64 / 1e9;
        let v1 = (p1.translation.vector - p0.translation.vector) / dt;
        let v0 = (p0.translation.vector - pm.translation.vector) / dtm;
        (v1 - v0) / ((dt + dtm) / 2.0)
    } else {
        Vector3::zeros()
    };
    let f = p1.rotation.inverse() * (accel + Vector3::new(0.0, 0.0, GRAVITY));
    ([w.x, w.y, w.z], [f.x, f.y, f.z])
}

/// `sensor_msgs/msg/Imu`.
#[derive(Serialize, Deserialize)]
struct Ros2Imu {
    header: Header,
    orientation: ros2::Quaternion,
    orientation_covariance: [f64; 9],
    angular_velocity: ros2::Vector3,
    angular_velocity_covariance: [f64; 9],
    linear_acceleration: ros2::Vector3,
    linear_acceleration_covariance: [f64; 9],
}

/// Without an orientation (`orientation_covariance[0] = -1`, as the type says).
impl Ros2Message for ImuSample {
    const SCHEMA: &'static str = "sensor_msgs/msg/Imu";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
                &[HEADER, TIME, QUATERNION, VECTOR3],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let [wx, wy, wz] = self.angular_rate_radps;
        let [ax, ay, az] = self.accel_mps2;
        let mut no_orientation = [0.0; 9];
        no_orientation[0] = -1.0;
        let m = Ros2Imu {
            header: frames.in_sensor(),
            orientation: ros2::Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            },
            orientation_covariance: no_orientation,
            angular_velocity: ros2::Vector3 {
                x: wx,
                y: wy,
                z: wz,
            },
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: ros2::Vector3 {
                x: ax,
                y: ay,
                z: az,
            },
            linear_acceleration_covariance: [0.0; 9],
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2Imu = from_cdr(data)?;
        let v = |v: ros2::Vector3| [v.x, v.y, v.z];
        Ok(SensorMsg::Imu(ImuSample {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            angular_rate_radps: v(m.angular_velocity),
            accel_mps2: v(m.linear_acceleration),
        }))
    }
}
