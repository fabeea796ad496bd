//! Helicopter route following: position -> velocity -> attitude cascade.

use hetsim_msgs::{
    wrap_angle, yaw_of, Command, InboxGuard, InputError, Pose, RobotStack, SensorMsg, StackStatus,
};
use nalgebra::Vector3;

/// Parameters of a [`HeliPilot`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeliPilotParams {
    /// Cruise ground speed, metres per second.
    pub cruise_mps: f64,
    /// Largest commanded tilt (roll or pitch), radians.
    pub max_tilt_rad: f64,
    /// Largest commanded yaw rate, radians per second.
    pub max_yaw_rate_radps: f64,
    /// Largest commanded climb or sink rate, metres per second.
    pub max_climb_mps: f64,
    /// A waypoint counts as reached within this 3D distance, metres.
    pub arrive_m: f64,
    /// Gravity, metres per second squared.
    pub gravity_mps2: f64,
}

/// Follows a list of 3D waypoints, facing the direction of travel.
#[derive(Clone, Debug)]
pub struct HeliPilot {
    /// The boundary checks of what the stack is fed (stamp order per sensor).
    guard: InboxGuard,
    params: HeliPilotParams,
    route: Vec<[f64; 3]>,
    next: usize,
    last: Option<(u64, Pose)>,
    velocity: Vector3<f64>,
}

impl HeliPilot {
    /// A pilot for a route.
    pub fn new(params: HeliPilotParams, route: Vec<[f64; 3]>) -> Self {
        Self {
            guard: InboxGuard::new(),
            params,
            route,
            next: 0,
            last: None,
            velocity: Vector3::zeros(),
        }
    }
}

impl HeliPilot {
    /// The command for one step's messages, once the boundary has checked them
    /// ([`RobotStack::step`] checks, then calls this).
    pub fn command(&mut self, _now_ns: u64, inbox: &[SensorMsg]) -> Command {
        for msg in inbox {
            let SensorMsg::TruthPose(p) = msg else {
                continue;
            };
            if let Some((t0, pose0)) = self.last {
                let dt = (p.stamp_ns - t0) as f64 * 1e-9;
                if dt > 0.0 {
                    self.velocity = (p.pose.translation.vector - pose0.translation.vector) / dt;
                }
            }
            self.last = Some((p.stamp_ns, p.pose));
        }
        let Some((_, pose)) = self.last else {
            return Command::Stop;
        };
        let here = pose.translation.vector;
        while let Some(w) = self.route.get(self.next) {
            if (Vector3::from(*w) - here).norm() < self.params.arrive_m {
                self.next += 1;
            } else {
                break;
            }
        }
        let Some(target) = self.route.get(self.next).map(|w| Vector3::from(*w)) else {
            // Route done: hover (hold zero velocity).
            return self.hold(&pose, Vector3::zeros(), 0.0, None);
        };
        let error = target - here;
        let horizontal = Vector3::new(error.x, error.y, 0.0);
        let distance = horizontal.norm();
        let speed = self.params.cruise_mps.min(0.5 * distance);
        let velocity_wanted = if distance > 1e-9 {
            horizontal * (speed / distance)
        } else {
            Vector3::zeros()
        };
        let climb = (0.5 * error.z).clamp(-self.params.max_climb_mps, self.params.max_climb_mps);
        let heading = (distance > 5.0).then(|| error.y.atan2(error.x));
        self.hold(&pose, velocity_wanted, climb, heading)
    }
}

impl RobotStack for HeliPilot {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<Command, InputError> {
        self.guard.check(now_ns, inbox)?;
        Ok(self.command(now_ns, inbox))
    }

    fn status(&self) -> StackStatus {
        StackStatus {
            goals_reached: self.next.min(self.route.len()),
            goals_total: self.route.len(),
            goals_skipped: 0,
            ..StackStatus::default()
        }
    }
}

impl HeliPilot {
    /// Attitude targets that drive the horizontal velocity towards `velocity_wanted`.
    fn hold(
        &self,
        pose: &Pose,
        velocity_wanted: Vector3<f64>,
        climb_mps: f64,
        heading_rad: Option<f64>,
    ) -> Command {
        let g = self.params.gravity_mps2;
        let accel = (velocity_wanted - self.velocity) * 0.8; // velocity loop gain, 1/s
        let yaw = yaw_of(pose);
        let forward = accel.x * yaw.cos() + accel.y * yaw.sin();
        let left = -accel.x * yaw.sin() + accel.y * yaw.cos();
        let tilt = self.params.max_tilt_rad;
        let pitch = (forward / g).atan().clamp(-tilt, tilt);
        let roll = (-left * pitch.cos() / g).atan().clamp(-tilt, tilt);
        let yaw_rate = heading_rad.map_or(0.0, |h| {
            (1.0 * wrap_angle(h - yaw)).clamp(
                -self.params.max_yaw_rate_radps,
                self.params.max_yaw_rate_radps,
            )
        });
        Command::Helicopter {
            roll_rad: roll,
            pitch_rad: pitch,
            yaw_rate_radps: yaw_rate,
            climb_rate_mps: climb_mps,
        }
    }
}
