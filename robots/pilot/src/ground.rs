//! Waypoint following for skid-steer and differential-drive bases.

use crate::grid_path;
use hetsim_msgs::{
    wrap_angle, yaw_of, Command, InboxGuard, InputError, Mission, Pose, RobotStack, SensorMsg,
    StackStatus,
};

/// How a ground pilot steers towards its next waypoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Steering {
    /// Turn while driving, slowing down with the heading error; turn in place beyond
    /// `turn_in_place_rad`. For the rover and the parent.
    Smooth {
        /// Heading error above which the robot stops and turns in place.
        turn_in_place_rad: f64,
    },
    /// The c't-Bot procedure of the seed: rotate in place until aimed within
    /// `aim_tolerance_rad`, drive straight; within `reaim_m` of the goal rotate again if needed
    /// and drive straight on until the goal is reached or passed.
    RotateThenDrive {
        /// Distance to the goal at which the robot is re-aimed (0.2 m in the seed).
        reaim_m: f64,
        /// Heading error accepted before driving straight.
        aim_tolerance_rad: f64,
    },
}

/// Parameters of a [`GroundPilot`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundPilotParams {
    /// Distance between the left and right wheel contact lines, metres.
    pub track_m: f64,
    /// Largest wheel surface speed, metres per second.
    pub max_wheel_mps: f64,
    /// Forward speed when on course, metres per second.
    pub cruise_mps: f64,
    /// Largest commanded yaw rate, radians per second.
    pub max_yaw_rate_radps: f64,
    /// A waypoint counts as reached within this distance, metres.
    pub arrive_m: f64,
    /// Steering behaviour.
    pub steering: Steering,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Waypoint {
    xy: [f64; 2],
    /// Index of the mission goal this waypoint completes, if any.
    goal: Option<usize>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Aim,
    Drive { reaimed: bool },
}

/// A ground robot's waypoint follower, driven by pose messages.
#[derive(Clone, Debug)]
pub struct GroundPilot {
    /// The boundary checks of what the stack is fed (stamp order per sensor).
    guard: InboxGuard,
    params: GroundPilotParams,
    mission: Mission,
    waypoints: Option<Vec<Waypoint>>,
    next: usize,
    phase: Phase,
    pose: Option<Pose>,
    status: StackStatus,
}

impl GroundPilot {
    /// A pilot for a mission. Grid missions are planned when the first pose arrives.
    pub fn new(params: GroundPilotParams, mission: Mission) -> Self {
        let goals_total = match &mission {
            Mission::Waypoints(w) => w.len(),
            Mission::GridGoals { goals, .. } => goals.len(),
            Mission::Idle | Mission::CoverageParent(_) | Mission::Teleoperated { .. } => 0,
        };
        Self {
            guard: InboxGuard::new(),
            params,
            mission,
            waypoints: None,
            next: 0,
            phase: Phase::Aim,
            pose: None,
            status: StackStatus {
                goals_total,
                ..StackStatus::default()
            },
        }
    }

    /// Expands the mission into waypoints from the robot's current position.
    fn plan(&mut self, start: &Pose) -> Vec<Waypoint> {
        match &self.mission {
            Mission::Waypoints(points) => points
                .iter()
                .enumerate()
                .map(|(i, p)| Waypoint {
                    xy: [p[0], p[1]],
                    goal: Some(i),
                })
                .collect(),
            Mission::Idle | Mission::CoverageParent(_) | Mission::Teleoperated { .. } => Vec::new(),
            Mission::GridGoals { grid, goals } => {
                let t = start.translation.vector;
                let Some(mut here) = grid.cell_of(t.x, t.y) else {
                    self.status.goals_skipped = goals.len();
                    return Vec::new();
                };
                let mut out = Vec::new();
                for (i, goal) in goals.iter().enumerate() {
                    match grid_path(grid, here, *goal) {
                        Some(path) => {
                            let last = path.len() - 1;
                            // The first cell is where the robot already is.
                            for (k, cell) in path.into_iter().enumerate().skip(1) {
                                out.push(Waypoint {
                                    xy: grid.centre_of(cell.0, cell.1),
                                    goal: (k == last).then_some(i),
                                });
                            }
                            if here == *goal {
                                out.push(Waypoint {
                                    xy: grid.centre_of(goal.0, goal.1),
                                    goal: Some(i),
                                });
                            }
                            here = *goal;
                        }
                        None => self.status.goals_skipped += 1,
                    }
                }
                out
            }
        }
    }

    fn wheels(&self, forward_mps: f64, yaw_rate_radps: f64) -> Command {
        let half = self.params.track_m / 2.0;
        let (mut left, mut right) = (
            forward_mps - yaw_rate_radps * half,
            forward_mps + yaw_rate_radps * half,
        );
        let biggest = left.abs().max(right.abs());
        if biggest > self.params.max_wheel_mps {
            let scale = self.params.max_wheel_mps / biggest;
            left *= scale;
            right *= scale;
        }
        Command::Wheels {
            left_mps: left,
            right_mps: right,
        }
    }

    fn turn_rate(&self, heading_error: f64) -> f64 {
        (2.0 * heading_error).clamp(
            -self.params.max_yaw_rate_radps,
            self.params.max_yaw_rate_radps,
        )
    }

    fn advance(&mut self, reached: Waypoint) {
        if reached.goal.is_some() {
            self.status.goals_reached += 1;
        }
        self.next += 1;
        self.phase = Phase::Aim;
    }
}

impl GroundPilot {
    /// The command for one step's messages, once the boundary has checked them
    /// ([`RobotStack::step`] checks, then calls this).
    pub fn command(&mut self, _now_ns: u64, inbox: &[SensorMsg]) -> Command {
        for msg in inbox {
            if let SensorMsg::TruthPose(p) = msg {
                self.pose = Some(p.pose);
            }
        }
        let Some(pose) = self.pose else {
            return Command::Stop;
        };
        if self.waypoints.is_none() {
            self.waypoints = Some(self.plan(&pose));
        }
        let Some(target) = self
            .waypoints
            .as_ref()
            .and_then(|w| w.get(self.next).copied())
        else {
            return Command::Stop;
        };
        let here = pose.translation.vector;
        let (dx, dy) = (target.xy[0] - here.x, target.xy[1] - here.y);
        let distance = dx.hypot(dy);
        let yaw = yaw_of(&pose);
        let error = wrap_angle(dy.atan2(dx) - yaw);
        if distance < self.params.arrive_m {
            self.advance(target);
            return self.command(_now_ns, &[]);
        }
        match self.params.steering {
            Steering::Smooth { turn_in_place_rad } => {
                if error.abs() > turn_in_place_rad {
                    self.wheels(0.0, self.turn_rate(error))
                } else {
                    let forward = self.params.cruise_mps * error.cos().max(0.2);
                    self.wheels(forward, self.turn_rate(error))
                }
            }
            Steering::RotateThenDrive {
                reaim_m,
                aim_tolerance_rad,
            } => match self.phase {
                Phase::Aim => {
                    if error.abs() <= aim_tolerance_rad {
                        self.phase = Phase::Drive {
                            reaimed: distance < reaim_m,
                        };
                        self.wheels(self.params.cruise_mps, 0.0)
                    } else {
                        self.wheels(0.0, self.turn_rate(error))
                    }
                }
                Phase::Drive { reaimed } => {
                    // Along-track distance left: negative once the goal is passed.
                    let along = dx * yaw.cos() + dy * yaw.sin();
                    if along <= 0.0 && reaimed {
                        self.advance(target);
                        return self.command(_now_ns, &[]);
                    }
                    if !reaimed && distance < reaim_m {
                        self.phase = if error.abs() > aim_tolerance_rad {
                            Phase::Aim
                        } else {
                            Phase::Drive { reaimed: true }
                        };
                        if self.phase == Phase::Aim {
                            return self.wheels(0.0, self.turn_rate(error));
                        }
                    }
                    self.wheels(self.params.cruise_mps, 0.0)
                }
            },
        }
    }
}

impl RobotStack for GroundPilot {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<Command, InputError> {
        self.guard.check(now_ns, inbox)?;
        Ok(self.command(now_ns, inbox))
    }

    fn status(&self) -> StackStatus {
        self.status
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_msgs::{pose_from_xyz_rpy, OccupancyGrid, PoseStamped};

    fn params(steering: Steering) -> GroundPilotParams {
        GroundPilotParams {
            track_m: 0.1,
            max_wheel_mps: 0.3,
            cruise_mps: 0.15,
            max_yaw_rate_radps: 2.0,
            arrive_m: 0.03,
            steering,
        }
    }

    /// Integrates ideal differential-drive kinematics: the pilot must reach its goals.
    fn drive(
        pilot: &mut GroundPilot,
        mut x: f64,
        mut y: f64,
        mut yaw: f64,
        steps: usize,
    ) -> (f64, f64) {
        let dt = 0.01;
        let track = pilot.params.track_m;
        for k in 0..steps {
            let msg = SensorMsg::TruthPose(PoseStamped {
                stamp_ns: k as u64 * 10_000_000,
                pose: pose_from_xyz_rpy([x, y, 0.0], [0.0, 0.0, yaw]),
            });
            let (l, r) = match pilot
                .step(k as u64 * 10_000_000, &[msg])
                .expect("valid poses")
            {
                Command::Wheels {
                    left_mps,
                    right_mps,
                } => (left_mps, right_mps),
                _ => (0.0, 0.0),
            };
            let v = (l + r) / 2.0;
            yaw += (r - l) / track * dt;
            x += v * yaw.cos() * dt;
            y += v * yaw.sin() * dt;
            if pilot.status().done() {
                break;
            }
        }
        (x, y)
    }

    #[test]
    fn rotate_then_drive_reaches_grid_goals_in_unit_steps() {
        let grid = OccupancyGrid {
            origin_x: 0.0,
            origin_y: 0.0,
            cell_m: 0.5,
            cols: 4,
            rows: 4,
            occupied: vec![false; 16],
        };
        let mission = Mission::GridGoals {
            grid,
            goals: vec![(2, 0), (2, 3)],
        };
        let mut pilot = GroundPilot::new(
            params(Steering::RotateThenDrive {
                reaim_m: 0.2,
                aim_tolerance_rad: 0.03,
            }),
            mission,
        );
        let (x, y) = drive(&mut pilot, 0.25, 0.25, 1.0, 20_000);
        assert_eq!(pilot.status().goals_reached, 2);
        let waypoints = pilot.waypoints.clone().unwrap();
        assert_eq!(waypoints.len(), 2 + 3, "unit steps along the grid");
        assert!(
            (x - 1.25).abs() < 0.05 && (y - 1.75).abs() < 0.05,
            "{x} {y}"
        );
    }

    #[test]
    fn smooth_reaches_waypoints() {
        let mission = Mission::Waypoints(vec![[3.0, 0.0, 0.0], [3.0, 3.0, 0.0]]);
        let mut pilot = GroundPilot::new(
            GroundPilotParams {
                track_m: 0.6,
                max_wheel_mps: 1.5,
                cruise_mps: 1.0,
                max_yaw_rate_radps: 1.0,
                arrive_m: 0.3,
                steering: Steering::Smooth {
                    turn_in_place_rad: 1.0,
                },
            },
            mission,
        );
        drive(&mut pilot, 0.0, 0.0, 0.0, 5_000);
        assert!(pilot.status().done());
        assert_eq!(pilot.status().goals_reached, 2);
    }

    #[test]
    fn unreachable_grid_goal_is_skipped_not_looped_on() {
        let mut occupied = vec![false; 9];
        // A wall across the middle row (row 1, cells 3..6).
        occupied[3..6].fill(true);
        let grid = OccupancyGrid {
            origin_x: 0.0,
            origin_y: 0.0,
            cell_m: 0.5,
            cols: 3,
            rows: 3,
            occupied,
        };
        let mut pilot = GroundPilot::new(
            params(Steering::RotateThenDrive {
                reaim_m: 0.2,
                aim_tolerance_rad: 0.03,
            }),
            Mission::GridGoals {
                grid,
                goals: vec![(1, 2), (2, 0)],
            },
        );
        drive(&mut pilot, 0.25, 0.25, 0.0, 10_000);
        let status = pilot.status();
        assert_eq!((status.goals_reached, status.goals_skipped), (1, 1));
    }
}
