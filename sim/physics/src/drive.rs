//! Drive models: actuator commands to body motion over one step.

use hetsim_core::SimRng;
use hetsim_msgs::Command;
use hetsim_scene::{Helicopter, RobotModel, Wheels};
use rand_distr::{Distribution, StandardNormal};

/// Wheel-speed state of a skid-steer or differential base.
#[derive(Clone, Debug)]
pub struct GroundDrive {
    wheels: Wheels,
    max_speed_mps: f64,
    /// Commanded wheel speeds, m/s.
    command: [f64; 2],
    /// Actual wheel surface speeds, m/s.
    actual: [f64; 2],
    /// Relative speed error per wheel (Ornstein-Uhlenbeck, 1 s correlation time).
    error: [f64; 2],
    rng: SimRng,
}

/// Correlation time of the wheel speed error, seconds.
const WHEEL_ERROR_TAU_S: f64 = 1.0;

impl GroundDrive {
    /// A drive at rest.
    pub fn new(wheels: Wheels, max_speed_mps: f64, rng: SimRng) -> Self {
        Self {
            wheels,
            max_speed_mps,
            command: [0.0; 2],
            actual: [0.0; 2],
            error: [0.0; 2],
            rng,
        }
    }

    /// Takes a command (non-wheel commands stop the base).
    pub fn command(&mut self, cmd: &Command) {
        self.command = match *cmd {
            Command::Wheels {
                left_mps,
                right_mps,
            } => [
                left_mps.clamp(-self.max_speed_mps, self.max_speed_mps),
                right_mps.clamp(-self.max_speed_mps, self.max_speed_mps),
            ],
            _ => [0.0; 2],
        };
    }

    /// Advances the wheels by `dt` and returns the body's (forward speed m/s, yaw rate rad/s).
    pub fn step(&mut self, dt: f64) -> (f64, f64) {
        let w = &self.wheels;
        let blend = if w.motor_time_constant_s > 0.0 {
            1.0 - (-dt / w.motor_time_constant_s).exp()
        } else {
            1.0
        };
        let decay = (-dt / WHEEL_ERROR_TAU_S).exp();
        let kick = w.speed_noise * (1.0 - decay * decay).sqrt();
        for k in 0..2 {
            let n: f64 = StandardNormal.sample(&mut self.rng);
            self.error[k] = self.error[k] * decay + kick * n;
            let target = self.command[k] * (1.0 + self.error[k]);
            self.actual[k] += (target - self.actual[k]) * blend;
        }
        let [left, right] = self.actual;
        let forward = (1.0 - w.longitudinal_slip) * (left + right) / 2.0;
        let yaw_rate = (right - left) / (w.track_m * w.icr_expansion);
        (forward, yaw_rate)
    }

    /// Stops the wheels at once (after a collision).
    pub fn halt(&mut self) {
        self.actual = [0.0; 2];
    }

    /// Actual wheel surface speeds `[left, right]`, m/s.
    pub fn actual(&self) -> [f64; 2] {
        self.actual
    }
}

/// Attitude and velocity state of a helicopter.
#[derive(Clone, Debug)]
pub struct HeliDrive {
    params: Helicopter,
    max_speed_mps: f64,
    max_yaw_rate: f64,
    target: [f64; 4],
    /// Roll, pitch, yaw, radians.
    pub attitude: [f64; 3],
    /// World velocity, m/s.
    pub velocity: [f64; 3],
    gravity: f64,
}

impl HeliDrive {
    /// A hovering helicopter with heading `yaw`.
    pub fn new(model: &RobotModel, params: Helicopter, yaw: f64, gravity: f64) -> Self {
        Self {
            params,
            max_speed_mps: model.body.max_speed_mps,
            max_yaw_rate: model.body.max_yaw_rate_deg_s.to_radians(),
            target: [0.0; 4],
            attitude: [0.0, 0.0, yaw],
            velocity: [0.0; 3],
            gravity,
        }
    }

    /// Takes a command (anything but a helicopter command means hover).
    pub fn command(&mut self, cmd: &Command) {
        let tilt = self.params.max_tilt_deg.to_radians();
        self.target = match *cmd {
            Command::Helicopter {
                roll_rad,
                pitch_rad,
                yaw_rate_radps,
                climb_rate_mps,
            } => [
                roll_rad.clamp(-tilt, tilt),
                pitch_rad.clamp(-tilt, tilt),
                yaw_rate_radps.clamp(-self.max_yaw_rate, self.max_yaw_rate),
                climb_rate_mps.clamp(-self.params.max_climb_mps, self.params.max_climb_mps),
            ],
            _ => [0.0; 4],
        };
    }

    /// Advances attitude and velocity by `dt`; returns the displacement.
    pub fn step(&mut self, dt: f64) -> [f64; 3] {
        let blend = |tau: f64| {
            if tau > 0.0 {
                1.0 - (-dt / tau).exp()
            } else {
                1.0
            }
        };
        let ba = blend(self.params.attitude_time_constant_s);
        self.attitude[0] += (self.target[0] - self.attitude[0]) * ba;
        self.attitude[1] += (self.target[1] - self.attitude[1]) * ba;
        self.attitude[2] += self.target[2] * dt;
        self.velocity[2] +=
            (self.target[3] - self.velocity[2]) * blend(self.params.climb_time_constant_s);
        // Thrust along body z, sized to hold the vertical motion: its horizontal part is
        // g * (tilted z axis)_xy / (tilted z axis)_z.
        let [roll, pitch, yaw] = self.attitude;
        let (sr, cr) = roll.sin_cos();
        let (sp, cp) = pitch.sin_cos();
        let (sy, cy) = yaw.sin_cos();
        let body_z = [cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr];
        let drag = self.gravity * self.params.max_tilt_deg.to_radians().tan() / self.max_speed_mps;
        for k in 0..2 {
            let accel = self.gravity * body_z[k] / body_z[2] - drag * self.velocity[k];
            self.velocity[k] += accel * dt;
        }
        [
            self.velocity[0] * dt,
            self.velocity[1] * dt,
            self.velocity[2] * dt,
        ]
    }

    /// Stops all motion (after a collision).
    pub fn halt(&mut self) {
        self.velocity = [0.0; 3];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_core::Streams;

    fn wheels(noise: f64) -> Wheels {
        Wheels {
            track_m: 0.5,
            motor_time_constant_s: 0.1,
            longitudinal_slip: 0.1,
            icr_expansion: 2.0,
            speed_noise: noise,
        }
    }

    #[test]
    fn skid_steer_loses_speed_to_slip_and_turns_slower() {
        let mut d = GroundDrive::new(wheels(0.0), 2.0, Streams::new(1).stream("t"));
        d.command(&Command::Wheels {
            left_mps: 0.5,
            right_mps: 1.5,
        });
        let mut out = (0.0, 0.0);
        for _ in 0..500 {
            out = d.step(0.01);
        }
        assert!((out.0 - 0.9 * 1.0).abs() < 1e-6, "forward {}", out.0);
        assert!(
            (out.1 - 1.0 / (0.5 * 2.0)).abs() < 1e-6,
            "yaw rate {}",
            out.1
        );
    }

    #[test]
    fn wheel_error_has_the_configured_spread() {
        let mut d = GroundDrive::new(wheels(0.05), 2.0, Streams::new(3).stream("t"));
        d.command(&Command::Wheels {
            left_mps: 1.0,
            right_mps: 1.0,
        });
        let mut samples = Vec::new();
        for k in 0..200_000 {
            d.step(0.01);
            if k > 1000 && k % 50 == 0 {
                samples.push(d.error[0]);
            }
        }
        let n = samples.len() as f64;
        let mean = samples.iter().sum::<f64>() / n;
        let std = (samples.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        // OU stationary std equals speed_noise; samples 0.5 s apart are correlated, so allow 15 %.
        assert!((std - 0.05).abs() < 0.0075, "std {std}");
        assert!(mean.abs() < 0.01, "mean {mean}");
    }

    #[test]
    fn helicopter_top_speed_is_reached_at_max_tilt() {
        let params = Helicopter {
            max_tilt_deg: 20.0,
            max_climb_mps: 3.0,
            attitude_time_constant_s: 0.3,
            climb_time_constant_s: 0.5,
        };
        let model: RobotModel =
            toml::from_str(include_str!("../../../robots/models/ressac.toml")).unwrap();
        let mut h = HeliDrive::new(&model, params, 0.0, 9.81);
        h.command(&Command::Helicopter {
            roll_rad: 0.0,
            pitch_rad: 1.0,
            yaw_rate_radps: 0.0,
            climb_rate_mps: 0.0,
        });
        for _ in 0..20_000 {
            h.step(0.01);
        }
        assert!(
            (h.velocity[0] - model.body.max_speed_mps).abs() < 1e-3,
            "{:?}",
            h.velocity
        );
        assert!(h.velocity[1].abs() < 1e-9);
        // Positive roll tilts the right side down: it accelerates to the right (-y).
        h.command(&Command::Helicopter {
            roll_rad: 0.1,
            pitch_rad: 0.0,
            yaw_rate_radps: 0.0,
            climb_rate_mps: 0.0,
        });
        for _ in 0..500 {
            h.step(0.01);
        }
        assert!(h.velocity[1] < -1.0, "{:?}", h.velocity);
    }
}
