//! All non-visual sensors of a run: each robot's sensors in file order, each one its kind's
//! model ([`crate::kinds`]) with its own random stream, sampled at its rate after physics.

use crate::kinds::{model_of, At, Model, Team};
use hetsim_core::{SimClock, SimRng, Streams};
use hetsim_msgs::{pose_from_xyz_rpy, Pose, SensorMsg};
use hetsim_physics::Physics;
use hetsim_scene::{Mount, Scenario};

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

struct Instance {
    robot: usize,
    topic: String,
    /// The sensor's name on its robot.
    name: String,
    model: Box<dyn Model>,
    body_from_sensor: Pose,
    period: u64,
    rng: SimRng,
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
    team: Team,
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

impl SensorSuite {
    /// The sensors of a scenario's robots (cameras and oracles excluded), with their random
    /// streams.
    pub fn new(scenario: &Scenario, streams: &Streams) -> Self {
        let clock = scenario.clock;
        let mut sensors = Vec::new();
        for (i, r) in scenario.robots.iter().enumerate() {
            for spec in &r.model.sensors {
                let topic = format!("{}/{}", r.spec.name, spec.name());
                let mut rng = streams.stream(&format!("{topic}/noise"));
                // Cameras are rendered by the engine, and the engine delivers the oracles.
                let Some(model) = model_of(spec, &mut rng) else {
                    continue;
                };
                sensors.push(Instance {
                    robot: i,
                    topic,
                    name: spec.name().to_string(),
                    model,
                    body_from_sensor: mount_pose(spec.mount()),
                    period: clock.period_ticks(spec.rate_hz()).expect("validated rate"),
                    rng,
                });
            }
        }
        let robots = &scenario.robots;
        Self {
            sensors,
            team: Team {
                names: robots.iter().map(|r| r.spec.name.clone()).collect(),
                hats: robots.iter().map(|r| r.model.body.hat).collect(),
                heights: robots.iter().map(|r| r.model.body.height_m).collect(),
            },
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
            .filter_map(|s| {
                let imu = s.model.imu()?;
                Some(ImuTruth {
                    topic: s.topic.clone(),
                    rate_hz: 1.0 / self.clock.time_secs(s.period),
                    gyro_sigma_radps: imu.gyro_sigma_radps,
                    accel_sigma_mps2: imu.accel_sigma_mps2,
                    body_from_sensor: s.body_from_sensor,
                    gyro_bias: imu.gyro_bias,
                    accel_bias: imu.accel_bias,
                })
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
        for s in &mut self.sensors {
            s.model.integrate(physics, s.robot, dt);
            if !s.model.due(after, s.period, now_ns) {
                continue;
            }
            let world_from_body = physics.pose(s.robot);
            let at = At {
                physics,
                stamp_ns: now_ns,
                robot: s.robot,
                world_from_body,
                world_from_sensor: world_from_body * s.body_from_sensor,
                sensor: s.name.clone(),
                team: &self.team,
                keyframes: &self.keyframes,
            };
            for msg in s.model.measure(&at, &mut s.rng) {
                out.push(Sample {
                    robot: s.robot,
                    topic: s.topic.clone(),
                    msg,
                });
            }
        }
        out
    }
}
