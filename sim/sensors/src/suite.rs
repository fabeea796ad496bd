//! All non-visual sensors of a run.

use crate::relative::noisy_relative;
use hetsim_core::{SimClock, SimRng, Streams};
use hetsim_msgs::{
    pose_from_xyz_rpy, wrap_angle, yaw_of, ChildTracks, CompassReading, GpsFix, ImageMatch,
    ImuSample, LaserScan, Pose, Rendezvous, SensorMsg, Track, WheelOdometry,
};
use hetsim_physics::Physics;
use hetsim_scene::{Mount, Scenario, Sensor};
use nalgebra::Vector3;
use rand::RngExt;
use rand_distr::{Distribution, Normal, StandardNormal};

/// Gravity, m/s^2.
const GRAVITY: f64 = 9.81;

/// A message produced by a sensor, with the robot it is for and its topic.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// Index of the robot carrying the sensor.
    pub robot: usize,
    /// `<robot>/<sensor>`.
    pub topic: String,
    /// The message.
    pub msg: SensorMsg,
}

enum State {
    Plain,
    Odometry {
        scale: [f64; 2],
        travelled: [f64; 2],
    },
    Imu {
        gyro_bias: [f64; 3],
        accel_bias: [f64; 3],
        history: Vec<(u64, Pose)>,
    },
    Gps {
        next: usize,
    },
    /// Key frames already matched: `(robot, stamp)`.
    ImageMatch {
        used: std::collections::BTreeSet<(usize, u64)>,
    },
}

struct Instance {
    robot: usize,
    topic: String,
    spec: Sensor,
    body_from_sensor: Pose,
    period: u64,
    rng: SimRng,
    state: State,
}

/// An IMU as the simulator knows it, noise model and true biases: see [`SensorSuite::imus`].
#[derive(Clone, Debug)]
pub struct ImuTruth {
    /// `<robot>/<imu>`.
    pub topic: String,
    /// Samples per second, after rounding to whole ticks.
    pub rate_hz: f64,
    /// Angular-rate white noise per sample, rad/s.
    pub gyro_sigma_radps: f64,
    /// Acceleration white noise per sample, m/s^2.
    pub accel_sigma_mps2: f64,
    /// `body_from_sensor`.
    pub body_from_sensor: Pose,
    /// The run's constant gyro bias, rad/s, sensor frame.
    pub gyro_bias: [f64; 3],
    /// The run's constant accelerometer bias, m/s^2, sensor frame.
    pub accel_bias: [f64; 3],
}

/// The non-visual sensors of all robots, in robot order, then file order.
pub struct SensorSuite {
    sensors: Vec<Instance>,
    names: Vec<String>,
    models: Vec<String>,
    heights: Vec<f64>,
    clock: SimClock,
    /// Key frames the robots' stacks made: `(robot, stamp, true world_from_body)`.
    keyframes: Vec<(usize, u64, Pose)>,
}

fn mount_pose(m: &Mount) -> Pose {
    pose_from_xyz_rpy(
        m.xyz_m,
        [
            m.rpy_deg[0].to_radians(),
            m.rpy_deg[1].to_radians(),
            m.rpy_deg[2].to_radians(),
        ],
    )
}

fn normal(rng: &mut SimRng, sigma: f64) -> f64 {
    let n: f64 = StandardNormal.sample(rng);
    n * sigma
}

impl SensorSuite {
    /// The sensors of a scenario's robots (cameras and oracles excluded), with their random
    /// streams.
    pub fn new(scenario: &Scenario, streams: &Streams) -> Self {
        let clock = scenario.clock;
        let mut sensors = Vec::new();
        for (i, r) in scenario.robots.iter().enumerate() {
            for spec in &r.model.sensors {
                // Cameras are rendered by the engine, and the engine delivers the oracles.
                if matches!(
                    spec,
                    Sensor::Camera { .. }
                        | Sensor::StereoCamera { .. }
                        | Sensor::OmniCamera { .. }
                        | Sensor::OraclePose { .. }
                ) {
                    continue;
                }
                let topic = format!("{}/{}", r.spec.name, spec.name());
                let mut rng = streams.stream(&format!("{topic}/noise"));
                let state = match spec {
                    Sensor::WheelOdometry { scale_sigma, .. } => State::Odometry {
                        scale: [
                            normal(&mut rng, *scale_sigma),
                            normal(&mut rng, *scale_sigma),
                        ],
                        travelled: [0.0; 2],
                    },
                    Sensor::Imu {
                        gyro_bias_sigma_radps,
                        accel_bias_sigma_mps2,
                        ..
                    } => State::Imu {
                        gyro_bias: [0; 3].map(|_| normal(&mut rng, *gyro_bias_sigma_radps)),
                        accel_bias: [0; 3].map(|_| normal(&mut rng, *accel_bias_sigma_mps2)),
                        history: Vec::new(),
                    },
                    Sensor::Gps { .. } => State::Gps { next: 0 },
                    Sensor::ImageMatch { .. } => State::ImageMatch {
                        used: Default::default(),
                    },
                    _ => State::Plain,
                };
                sensors.push(Instance {
                    robot: i,
                    topic,
                    body_from_sensor: mount_pose(spec.mount()),
                    period: clock.period_ticks(spec.rate_hz()).expect("validated rate"),
                    spec: spec.clone(),
                    rng,
                    state,
                });
            }
        }
        Self {
            sensors,
            names: scenario
                .robots
                .iter()
                .map(|r| r.spec.name.clone())
                .collect(),
            models: scenario
                .robots
                .iter()
                .map(|r| r.spec.model.clone())
                .collect(),
            heights: scenario
                .robots
                .iter()
                .map(|r| r.model.body.height_m)
                .collect(),
            clock,
            keyframes: Vec::new(),
        }
    }

    /// Registers a key frame of `robot`'s stack: its stamp and the robot's true pose then,
    /// for the emulated image matcher.
    pub fn add_keyframe(&mut self, robot: usize, stamp_ns: u64, world_from_body: Pose) {
        self.keyframes.push((robot, stamp_ns, world_from_body));
    }

    /// Every IMU, in robot then file order: `(topic, rate after rounding to whole ticks,
    /// gyro and accel white-noise sigma, body_from_sensor, the run's true constant gyro and
    /// accel biases)`. Truth, for the datasets the simulator writes (EuRoC's ground truth
    /// carries the biases); robot software never sees it.
    pub fn imus(&self) -> Vec<ImuTruth> {
        self.sensors
            .iter()
            .filter_map(|s| match (&s.spec, &s.state) {
                (
                    Sensor::Imu {
                        gyro_sigma_radps,
                        accel_sigma_mps2,
                        ..
                    },
                    State::Imu {
                        gyro_bias,
                        accel_bias,
                        ..
                    },
                ) => Some(ImuTruth {
                    topic: s.topic.clone(),
                    rate_hz: 1.0 / self.clock.time_secs(s.period),
                    gyro_sigma_radps: *gyro_sigma_radps,
                    accel_sigma_mps2: *accel_sigma_mps2,
                    body_from_sensor: s.body_from_sensor,
                    gyro_bias: *gyro_bias,
                    accel_bias: *accel_bias,
                }),
                _ => None,
            })
            .collect()
    }

    /// Number of sensors.
    pub fn len(&self) -> usize {
        self.sensors.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.sensors.is_empty()
    }

    /// Samples every sensor due at the end of tick `tick` (i.e. at sim time of `tick + 1`),
    /// after physics has stepped; integrating sensors accumulate every tick.
    pub fn sample(&mut self, physics: &Physics, tick: u64) -> Vec<Sample> {
        let after = tick + 1;
        let now_ns = self.clock.time_ns(after);
        let dt = self.clock.dt_secs();
        let mut out = Vec::new();
        for k in 0..self.sensors.len() {
            let s = &mut self.sensors[k];
            if let (State::Odometry { travelled, .. }, Some(speeds)) =
                (&mut s.state, physics.wheel_speeds(s.robot))
            {
                travelled[0] += speeds[0] * dt;
                travelled[1] += speeds[1] * dt;
            }
            let due = match (&s.spec, &mut s.state) {
                (Sensor::Gps { schedule_s, .. }, State::Gps { next }) if !schedule_s.is_empty() => {
                    let t = now_ns as f64 / 1e9;
                    let mut fire = false;
                    while *next < schedule_s.len() && schedule_s[*next] <= t + 1e-12 {
                        *next += 1;
                        fire = true;
                    }
                    fire
                }
                _ => after % s.period == 0,
            };
            if !due {
                continue;
            }
            for msg in self.measure(k, physics, now_ns) {
                let s = &self.sensors[k];
                out.push(Sample {
                    robot: s.robot,
                    topic: s.topic.clone(),
                    msg,
                });
            }
        }
        out
    }

    fn measure(&mut self, k: usize, physics: &Physics, stamp_ns: u64) -> Vec<SensorMsg> {
        let names = &self.names;
        let keyframes = &self.keyframes;
        let models = &self.models;
        let heights = &self.heights;
        let s = &mut self.sensors[k];
        let world_from_body = physics.pose(s.robot);
        let world_from_sensor = world_from_body * s.body_from_sensor;
        let origin = world_from_sensor.translation.vector;
        let sensor = s.spec.name().to_string();
        match (&s.spec, &mut s.state) {
            (
                Sensor::Compass {
                    sigma_deg,
                    bias_deg,
                    distortion_deg,
                    ..
                },
                _,
            ) => {
                let yaw = yaw_of(&world_from_sensor);
                let heading = yaw
                    + bias_deg.to_radians()
                    + distortion_deg.to_radians() * yaw.sin()
                    + normal(&mut s.rng, sigma_deg.to_radians());
                vec![SensorMsg::Compass(CompassReading {
                    stamp_ns,
                    sensor,
                    heading_rad: wrap_angle(heading),
                })]
            }
            (
                Sensor::Gps {
                    sigma_m, outages_s, ..
                },
                _,
            ) => {
                let t = stamp_ns as f64 / 1e9;
                if outages_s.iter().any(|[a, b]| t >= *a && t <= *b) {
                    return Vec::new();
                }
                let position_m = [0, 1, 2].map(|a| origin[a] + normal(&mut s.rng, *sigma_m));
                vec![SensorMsg::Gps(GpsFix {
                    stamp_ns,
                    sensor,
                    position_m,
                    sigma_m: *sigma_m,
                })]
            }
            (Sensor::WheelOdometry { noise_per_m, .. }, State::Odometry { scale, travelled }) => {
                let read = |d: f64, sc: f64, rng: &mut SimRng| {
                    d * (1.0 + sc) + normal(rng, noise_per_m * d.abs())
                };
                let left_m = read(travelled[0], scale[0], &mut s.rng);
                let right_m = read(travelled[1], scale[1], &mut s.rng);
                *travelled = [0.0; 2];
                vec![SensorMsg::WheelOdometry(WheelOdometry {
                    stamp_ns,
                    sensor,
                    left_m,
                    right_m,
                })]
            }
            (
                Sensor::Imu {
                    gyro_sigma_radps,
                    accel_sigma_mps2,
                    ..
                },
                State::Imu {
                    gyro_bias,
                    accel_bias,
                    history,
                },
            ) => {
                history.push((stamp_ns, world_from_sensor));
                if history.len() > 3 {
                    history.remove(0);
                }
                let (angular, accel) = imu_truth(history);
                let angular_rate_radps = [0, 1, 2]
                    .map(|a| angular[a] + gyro_bias[a] + normal(&mut s.rng, *gyro_sigma_radps));
                let accel_mps2 = [0, 1, 2]
                    .map(|a| accel[a] + accel_bias[a] + normal(&mut s.rng, *accel_sigma_mps2));
                vec![SensorMsg::Imu(ImuSample {
                    stamp_ns,
                    sensor,
                    angular_rate_radps,
                    accel_mps2,
                })]
            }
            (
                Sensor::Laser {
                    fov_deg,
                    resolution_deg,
                    max_range_m,
                    range_sigma_m,
                    ..
                },
                _,
            ) => {
                let fov = fov_deg.to_radians();
                let step = resolution_deg.to_radians();
                let beams = (fov / step + 1e-9).floor() as usize + 1;
                let angle_min = -fov / 2.0;
                let mut ranges_m = Vec::with_capacity(beams);
                for b in 0..beams {
                    let a = angle_min + b as f64 * step;
                    let dir = world_from_sensor.rotation * Vector3::new(a.cos(), a.sin(), 0.0);
                    let r = physics
                        .cast_ray(
                            [origin.x, origin.y, origin.z],
                            [dir.x, dir.y, dir.z],
                            *max_range_m,
                            Some(s.robot),
                        )
                        .map(|(d, _)| d + normal(&mut s.rng, *range_sigma_m))
                        .filter(|d| *d <= *max_range_m);
                    ranges_m.push(r.map_or(f32::INFINITY, |d| d.max(0.0) as f32));
                }
                vec![SensorMsg::LaserScan(LaserScan {
                    stamp_ns,
                    sensor,
                    angle_min_rad: angle_min,
                    angle_increment_rad: step,
                    range_max_m: *max_range_m,
                    ranges_m,
                })]
            }
            (
                Sensor::ChildTracker {
                    range_m,
                    error_mean_m,
                    error_std_m,
                    tracks_model,
                    ..
                },
                _,
            ) => {
                let mut tracks = Vec::new();
                let error = Normal::new(*error_mean_m, *error_std_m).expect("validated std >= 0");
                for other in 0..names.len() {
                    if other == s.robot || models[other] != *tracks_model {
                        continue;
                    }
                    let p = physics.pose(other).translation.vector;
                    let hat = [p.x, p.y, p.z + heights[other]];
                    let horizontal = (hat[0] - origin.x).hypot(hat[1] - origin.y);
                    if horizontal > *range_m
                        || !physics.clear_line(
                            [origin.x, origin.y, origin.z],
                            hat,
                            &[s.robot, other],
                        )
                    {
                        continue;
                    }
                    let magnitude = error.sample(&mut s.rng).abs();
                    let angle = s.rng.random_range(0.0..std::f64::consts::TAU);
                    // The measured floor position, in the parent's body frame (its heading
                    // only: the floor position of a child, however the body tilts).
                    let here = world_from_body.translation.vector;
                    let (dx, dy) = (
                        p.x + magnitude * angle.cos() - here.x,
                        p.y + magnitude * angle.sin() - here.y,
                    );
                    let (sin, cos) = yaw_of(&world_from_body).sin_cos();
                    tracks.push(Track {
                        child: names[other].clone(),
                        position_m: [cos * dx + sin * dy, -sin * dx + cos * dy],
                    });
                }
                vec![SensorMsg::ChildTracks(ChildTracks {
                    stamp_ns,
                    sensor,
                    tracks,
                })]
            }
            (
                Sensor::Rendezvous {
                    range_m,
                    fov_deg,
                    sigma_m,
                    sigma_deg,
                    ..
                },
                _,
            ) => {
                // One message per robot seen, in robot order.
                let mut seen = Vec::new();
                for other in 0..names.len() {
                    if other == s.robot {
                        continue;
                    }
                    let other_pose = physics.pose(other);
                    let centre = other_pose.translation.vector
                        + Vector3::new(0.0, 0.0, heights[other] / 2.0);
                    let v = centre - origin;
                    let distance = v.norm();
                    let axis = world_from_sensor.rotation * Vector3::x();
                    let angle = (v.dot(&axis) / distance.max(1e-12)).clamp(-1.0, 1.0).acos();
                    if distance > *range_m || angle > fov_deg.to_radians() / 2.0 {
                        continue;
                    }
                    if !physics.clear_line(
                        [origin.x, origin.y, origin.z],
                        [centre.x, centre.y, centre.z],
                        &[s.robot, other],
                    ) {
                        continue;
                    }
                    let truth = world_from_body.inverse() * other_pose;
                    let sr = sigma_deg.to_radians();
                    let relative = noisy_relative(&truth, *sigma_m, sr, &mut s.rng);
                    seen.push(Rendezvous {
                        stamp_ns,
                        sensor: sensor.clone(),
                        other: names[other].clone(),
                        relative,
                        sigma_m: *sigma_m,
                        sigma_rad: sr,
                    });
                }
                seen.into_iter().map(SensorMsg::Rendezvous).collect()
            }
            (
                Sensor::ImageMatch {
                    range_m,
                    min_age_s,
                    sigma_m,
                    sigma_deg,
                    ..
                },
                State::ImageMatch { used },
            ) => {
                // The nearest unmatched key frame of another robot under this one, old enough.
                let here = world_from_body.translation.vector;
                let min_age_ns = (min_age_s * 1e9) as u64;
                let best = keyframes
                    .iter()
                    .filter(|(r, t, _)| {
                        *r != s.robot
                            && t.saturating_add(min_age_ns) <= stamp_ns
                            && !used.contains(&(*r, *t))
                    })
                    .map(|(r, t, p)| {
                        let d = (p.translation.vector - here).xy().norm();
                        (d, *r, *t, *p)
                    })
                    .filter(|(d, ..)| *d <= *range_m)
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                let Some((_, other, other_stamp_ns, kf)) = best else {
                    return Vec::new();
                };
                used.insert((other, other_stamp_ns));
                let truth = world_from_body.inverse() * kf;
                let sr = sigma_deg.to_radians();
                let relative = noisy_relative(&truth, *sigma_m, sr, &mut s.rng);
                vec![SensorMsg::ImageMatch(ImageMatch {
                    stamp_ns,
                    sensor,
                    other: names[other].clone(),
                    other_stamp_ns,
                    relative,
                    sigma_m: *sigma_m,
                    sigma_rad: sr,
                })]
            }
            _ => Vec::new(),
        }
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
