//! The rapier world: static colliders, robot bodies, and one step.

use crate::drive::{GroundDrive, HeliDrive};
use hetsim_core::SimRng;
use hetsim_msgs::{pose_from_xyz_rpy, Command, Pose};
use hetsim_scene::world::{SolidKind, World};
use hetsim_scene::{DriveKind, RobotModel};
use rapier3d::parry::query::ShapeCastOptions;
use rapier3d::parry::utils::Array2;
use rapier3d::prelude::*;

/// Collider tags kept in `user_data`.
const TAG_GROUND: u128 = 1;
const TAG_SOLID: u128 = 2;
/// Robot colliders carry `TAG_ROBOT + robot index`.
const TAG_ROBOT: u128 = 1 << 32;

/// Height at which downward ground rays start, metres (above any terrain or floor).
const RAY_START_M: f64 = 5_000.0;
/// Gap kept between a robot and what it bumped into, metres.
const SKIN_M: f64 = 0.002;
/// Gravity, m/s^2.
const GRAVITY: f64 = 9.81;

enum Drive {
    Ground(Box<GroundDrive>),
    Heli(HeliDrive),
}

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hit {
    /// Terrain or floor.
    Ground,
    /// A building, wall or obstacle.
    Solid,
    /// A robot, by index.
    Robot(usize),
}

/// What the simulator knows about a robot's motion.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RobotState {
    /// Collisions so far (contact episodes, counted once each).
    pub collisions: u32,
    /// Distance travelled in the xy plane, metres.
    pub distance_m: f64,
    /// Whether the last step ended in contact.
    pub in_contact: bool,
}

struct Robot {
    body: RigidBodyHandle,
    collider: ColliderHandle,
    half: [f64; 3],
    drive: Drive,
    /// Planar state: x, y, yaw (ground robots); full position for the helicopter.
    position: [f64; 3],
    pose: Pose,
    state: RobotState,
}

/// The physics world of a run.
pub struct Physics {
    world: PhysicsWorld,
    robots: Vec<Robot>,
    dt: f64,
    /// Colliders were added that rapier's query structure does not know yet.
    unindexed: bool,
}

fn to_glam(p: &Pose) -> rapier3d::math::Pose {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    rapier3d::math::Pose::from_parts(
        Vector::new(t.x, t.y, t.z),
        rapier3d::glamx::DQuat::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

impl Physics {
    /// Colliders for every static thing in `world`, in a fixed order: terrain, then solids.
    pub fn new(world: &World, dt_secs: f64) -> Self {
        let mut pw = PhysicsWorld {
            gravity: Vector::new(0.0, 0.0, -GRAVITY),
            ..PhysicsWorld::default()
        };
        pw.integration_parameters.dt = dt_secs;
        if let Some(t) = &world.terrain {
            // parry heightfields are y-up with rows along local z: rotate +90 deg about x so
            // local y is world z and local z is world -y (row 0 is the north edge).
            let (nrows, ncols) = (t.ny, t.nx);
            let mut data = vec![0.0; nrows * ncols];
            for col in 0..ncols {
                for row in 0..nrows {
                    data[col * nrows + row] = t.heights[(t.ny - 1 - row) * t.nx + col];
                }
            }
            let size_x = (t.nx - 1) as f64 * t.cell_m;
            let size_y = (t.ny - 1) as f64 * t.cell_m;
            let centre = Vector::new(t.origin[0] + size_x / 2.0, t.origin[1] + size_y / 2.0, 0.0);
            let collider = ColliderBuilder::new(SharedShape::heightfield(
                Array2::new(nrows, ncols, data),
                Vector::new(size_x, 1.0, size_y),
            ))
            .translation(centre)
            .rotation(Vector::new(std::f64::consts::FRAC_PI_2, 0.0, 0.0))
            .user_data(TAG_GROUND);
            pw.insert_collider(collider, None);
        }
        for s in &world.solids {
            let tag = if s.kind == SolidKind::Floor {
                TAG_GROUND
            } else {
                TAG_SOLID
            };
            let collider =
                ColliderBuilder::cuboid(s.half_extents[0], s.half_extents[1], s.half_extents[2])
                    .translation(Vector::new(s.centre[0], s.centre[1], s.centre[2]))
                    .rotation(Vector::new(0.0, 0.0, s.yaw_rad))
                    .user_data(tag);
            pw.insert_collider(collider, None);
        }
        let mut physics = Self {
            world: pw,
            robots: Vec::new(),
            dt: dt_secs,
            unindexed: true,
        };
        physics.index_new_colliders();
        physics
    }

    /// Queries only see colliders that a pipeline step has put into the broad phase (a
    /// collision-detection pass alone does not). With only fixed and kinematic bodies a step
    /// moves nothing, so one is taken whenever colliders were added.
    fn index_new_colliders(&mut self) {
        if self.unindexed {
            self.world.step();
            self.unindexed = false;
        }
    }

    /// The world of a scenario with every robot at its start, in scenario order; each robot's
    /// drive draws from the stream `<robot>/drive/wheel_error`.
    pub fn for_scenario(scenario: &hetsim_scene::Scenario, streams: &hetsim_core::Streams) -> Self {
        let mut physics = Self::new(&scenario.world, scenario.clock.dt_secs());
        for r in &scenario.robots {
            physics.add_robot(
                &r.model,
                r.spec.start.x,
                r.spec.start.y,
                r.spec.start.z,
                r.spec.start.yaw_deg.to_radians(),
                streams.stream(&format!("{}/drive/wheel_error", r.spec.name)),
            );
        }
        physics
    }

    /// Adds a robot at `(x, y)` with heading `yaw_rad`, `z_above_ground` metres above the
    /// ground (helicopters). Returns its index.
    pub fn add_robot(
        &mut self,
        model: &RobotModel,
        x: f64,
        y: f64,
        z_above_ground: f64,
        yaw_rad: f64,
        rng: SimRng,
    ) -> usize {
        let b = &model.body;
        let half = [b.length_m / 2.0, b.width_m / 2.0, b.height_m / 2.0];
        let drive = match (b.drive, &b.wheels, &b.helicopter) {
            (DriveKind::Helicopter, _, Some(h)) => {
                Drive::Heli(HeliDrive::new(model, h.clone(), yaw_rad, GRAVITY))
            }
            (_, Some(w), _) => {
                Drive::Ground(Box::new(GroundDrive::new(w.clone(), b.max_speed_mps, rng)))
            }
            _ => unreachable!("validated robot models always carry the table their drive needs"),
        };
        let index = self.robots.len();
        let body = self
            .world
            .insert_body(RigidBodyBuilder::kinematic_position_based());
        let collider = self.world.insert_collider(
            ColliderBuilder::cuboid(half[0], half[1], half[2])
                .translation(Vector::new(0.0, 0.0, half[2] + 0.02))
                .user_data(TAG_ROBOT + index as u128),
            Some(body),
        );
        let mut robot = Robot {
            body,
            collider,
            half,
            drive,
            position: [x, y, 0.0],
            pose: Pose::identity(),
            state: RobotState::default(),
        };
        let ground = self.ground_under(&robot, x, y, yaw_rad);
        match robot.drive {
            Drive::Heli(_) => {
                robot.position[2] = ground.0 + z_above_ground;
                robot.pose = pose_from_xyz_rpy(robot.position, [0.0, 0.0, yaw_rad]);
            }
            Drive::Ground(_) => {
                robot.position[2] = yaw_rad;
                robot.pose = pose_from_xyz_rpy([x, y, ground.0], [ground.1, ground.2, yaw_rad]);
            }
        }
        self.world.bodies[body].set_position(to_glam(&robot.pose), true);
        self.robots.push(robot);
        self.unindexed = true;
        index
    }

    /// Mean ground height under a footprint, and the roll and pitch of the plane it spans.
    fn ground_under(&self, robot: &Robot, x: f64, y: f64, yaw: f64) -> (f64, f64, f64) {
        let (s, c) = yaw.sin_cos();
        let [hl, hw, _] = robot.half;
        let filter =
            QueryFilter::default().predicate(&|_, co: &Collider| co.user_data == TAG_GROUND);
        let qp = self.world.query_pipeline_with_filter(filter);
        let height = |lx: f64, ly: f64| {
            let (px, py) = (x + c * lx - s * ly, y + s * lx + c * ly);
            // A ray exactly through a heightfield vertex can slip between its triangles:
            // retry nudged by a micrometre before giving up.
            [(0.0, 0.0), (1e-6, 1e-6), (-1e-6, 2e-6)]
                .iter()
                .find_map(|(dx, dy)| {
                    let ray = Ray::new(
                        Vector::new(px + dx, py + dy, RAY_START_M),
                        Vector::new(0.0, 0.0, -1.0),
                    );
                    qp.cast_ray(&ray, 2.0 * RAY_START_M, true)
                        .map(|(_, toi)| RAY_START_M - toi)
                })
                .unwrap_or(0.0)
        };
        let (fl, fr, bl, br) = (
            height(hl, hw),
            height(hl, -hw),
            height(-hl, hw),
            height(-hl, -hw),
        );
        let z = (fl + fr + bl + br) / 4.0;
        let pitch = (((bl + br) - (fl + fr)) / 2.0 / (2.0 * hl)).atan();
        let roll = (((fl + bl) - (fr + br)) / 2.0 / (2.0 * hw)).atan();
        (z, roll, pitch)
    }

    /// How far (fraction of `motion`) the robot's box can move before touching an obstacle,
    /// another robot, or (for a helicopter) the ground.
    fn sweep(&self, index: usize, motion: Vector) -> Option<f64> {
        let robot = &self.robots[index];
        let own = robot.collider;
        let heli = matches!(robot.drive, Drive::Heli(_));
        let predicate = move |h: ColliderHandle, co: &Collider| {
            h != own && (co.user_data != TAG_GROUND || heli)
        };
        let filter = QueryFilter::default().predicate(&predicate);
        let collider = &self.world.colliders[own];
        let options = ShapeCastOptions {
            max_time_of_impact: 1.0,
            target_distance: SKIN_M,
            stop_at_penetration: false,
            compute_impact_geometry_on_penetration: false,
        };
        self.world
            .cast_shape(
                collider.position(),
                motion,
                collider.shape(),
                options,
                filter,
            )
            .map(|(_, hit)| hit.time_of_impact)
    }

    /// Passes a command to a robot's actuators.
    pub fn command(&mut self, index: usize, cmd: &Command) {
        match &mut self.robots[index].drive {
            Drive::Ground(d) => d.command(cmd),
            Drive::Heli(d) => d.command(cmd),
        }
    }

    /// Advances every robot's drive by one step, moves the bodies, and steps rapier.
    pub fn step(&mut self) {
        self.index_new_colliders();
        for i in 0..self.robots.len() {
            self.step_robot(i);
        }
        self.world.step();
    }

    fn step_robot(&mut self, i: usize) {
        let dt = self.dt;
        let robot = &mut self.robots[i];
        let (motion, yaw_next) = match &mut robot.drive {
            Drive::Ground(d) => {
                let (forward, yaw_rate) = d.step(dt);
                let yaw = robot.position[2];
                let mid = yaw + yaw_rate * dt / 2.0;
                (
                    Vector::new(forward * dt * mid.cos(), forward * dt * mid.sin(), 0.0),
                    yaw + yaw_rate * dt,
                )
            }
            Drive::Heli(d) => {
                let m = d.step(dt);
                (Vector::new(m[0], m[1], m[2]), d.attitude[2])
            }
        };
        let moving = motion.length() > 0.0;
        let toi = if moving { self.sweep(i, motion) } else { None };
        let robot = &mut self.robots[i];
        let fraction = toi.map_or(1.0, |t| t.clamp(0.0, 1.0));
        let contact = toi.is_some_and(|t| t < 1.0);
        if contact && !robot.state.in_contact {
            robot.state.collisions += 1;
        }
        robot.state.in_contact = contact;
        if contact {
            match &mut robot.drive {
                Drive::Ground(d) => d.halt(),
                Drive::Heli(d) => d.halt(),
            }
        }
        let step = motion * fraction;
        robot.state.distance_m += step.x.hypot(step.y);
        let heli_attitude = match &robot.drive {
            Drive::Heli(d) => Some(d.attitude),
            Drive::Ground(_) => None,
        };
        let (x, y) = (
            robot.pose.translation.x + step.x,
            robot.pose.translation.y + step.y,
        );
        let pose = match heli_attitude {
            Some([roll, pitch, yaw]) => {
                let z = robot.pose.translation.z + step.z;
                pose_from_xyz_rpy([x, y, z], [roll, pitch, yaw])
            }
            None => {
                let robot = &self.robots[i];
                let (z, roll, pitch) = self.ground_under(robot, x, y, yaw_next);
                pose_from_xyz_rpy([x, y, z], [roll, pitch, yaw_next])
            }
        };
        let robot = &mut self.robots[i];
        if heli_attitude.is_none() {
            robot.position = [x, y, yaw_next];
        }
        robot.pose = pose;
        let body = robot.body;
        // Move the collider now so the next robot's sweep sees where this one went.
        self.world.bodies[body].set_position(to_glam(&pose), true);
        let co = self.robots[i].collider;
        let parent = *self.world.bodies[body].position();
        if let Some(c) = self.world.colliders.get_mut(co) {
            let offset = *c
                .position_wrt_parent()
                .unwrap_or(&rapier3d::math::Pose::IDENTITY);
            c.set_position(parent * offset);
        }
    }

    /// `world_from_body` of a robot.
    pub fn pose(&self, index: usize) -> Pose {
        self.robots[index].pose
    }

    /// Motion bookkeeping of a robot.
    pub fn state(&self, index: usize) -> RobotState {
        self.robots[index].state
    }

    /// Casts a ray from `origin` along the unit vector `dir` (world frame) up to `max_m`,
    /// against everything but robot `ignore`. Returns the distance and what was hit.
    pub fn cast_ray(
        &self,
        origin: [f64; 3],
        dir: [f64; 3],
        max_m: f64,
        ignore: Option<usize>,
    ) -> Option<(f64, Hit)> {
        let skip = ignore.map(|i| self.robots[i].collider);
        let predicate = move |h: ColliderHandle, _: &Collider| Some(h) != skip;
        let filter = QueryFilter::default().predicate(&predicate);
        let ray = Ray::new(
            Vector::new(origin[0], origin[1], origin[2]),
            Vector::new(dir[0], dir[1], dir[2]),
        );
        self.world
            .cast_ray(&ray, max_m, true, filter)
            .map(|(h, toi)| {
                let tag = self.world.colliders[h].user_data;
                let hit = match tag {
                    TAG_GROUND => Hit::Ground,
                    TAG_SOLID => Hit::Solid,
                    t => Hit::Robot((t - TAG_ROBOT) as usize),
                };
                (toi, hit)
            })
    }

    /// Whether the straight segment between two world points is free of static geometry
    /// and of every robot except those in `ignore`.
    pub fn clear_line(&self, from: [f64; 3], to: [f64; 3], ignore: &[usize]) -> bool {
        let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if len < 1e-12 {
            return true;
        }
        let skip: Vec<ColliderHandle> = ignore.iter().map(|&i| self.robots[i].collider).collect();
        let predicate = move |h: ColliderHandle, _: &Collider| !skip.contains(&h);
        let filter = QueryFilter::default().predicate(&predicate);
        let ray = Ray::new(
            Vector::new(from[0], from[1], from[2]),
            Vector::new(d[0] / len, d[1] / len, d[2] / len),
        );
        self.world.cast_ray(&ray, len, true, filter).is_none()
    }

    /// Actual wheel surface speeds `[left, right]` of a wheeled robot, m/s.
    pub fn wheel_speeds(&self, index: usize) -> Option<[f64; 2]> {
        match &self.robots[index].drive {
            Drive::Ground(d) => Some(d.actual()),
            Drive::Heli(_) => None,
        }
    }

    /// Number of robots.
    pub fn robot_count(&self) -> usize {
        self.robots.len()
    }

    /// Number of colliders (static and robots).
    pub fn collider_count(&self) -> usize {
        self.world.colliders.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_core::Streams;
    use hetsim_msgs::yaw_of;
    use hetsim_scene::world::{Solid, Terrain};

    fn model(name: &str) -> RobotModel {
        let text = std::fs::read_to_string(format!(
            "{}/../../robots/models/{name}.toml",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap();
        toml::from_str(&text).unwrap()
    }

    fn solid(kind: SolidKind, centre: [f64; 3], half: [f64; 3]) -> Solid {
        Solid {
            kind,
            centre,
            half_extents: half,
            yaw_rad: 0.0,
            material_seed: 0,
        }
    }

    #[test]
    fn a_robot_driving_into_a_wall_stops_at_it_and_counts_one_collision() {
        let world = World {
            half_extent: [5.0, 5.0],
            terrain: None,
            solids: vec![
                solid(SolidKind::Floor, [0.0, 0.0, -0.05], [5.0, 5.0, 0.05]),
                solid(SolidKind::Wall, [1.0, 0.0, 1.0], [0.05, 2.0, 1.0]),
            ],
            grid: None,
        };
        let mut physics = Physics::new(&world, 0.01);
        let bot = model("ctbot");
        let i = physics.add_robot(&bot, 0.0, 0.0, 0.0, 0.0, Streams::new(1).stream("bot"));
        for _ in 0..2000 {
            physics.command(
                i,
                &Command::Wheels {
                    left_mps: 0.15,
                    right_mps: 0.15,
                },
            );
            physics.step();
        }
        let x = physics.pose(i).translation.x;
        let front = x + bot.body.length_m / 2.0;
        assert!(
            front <= 0.95 + 1e-6 && front > 0.9,
            "front at {front}: stopped at the wall face (0.95)"
        );
        assert_eq!(
            physics.state(i).collisions,
            1,
            "pushing on is one contact episode"
        );
        assert!(physics.state(i).in_contact);
    }

    #[test]
    fn a_rover_on_a_slope_sits_on_the_terrain_and_pitches_with_it() {
        // A plane rising 0.1 m per metre towards +x.
        let (n, cell) = (41, 1.0);
        let heights = (0..n * n)
            .map(|k| 0.1 * ((k % n) as f64 * cell - 20.0))
            .collect();
        let world = World {
            half_extent: [20.0, 20.0],
            terrain: Some(Terrain {
                origin: [-20.0, -20.0],
                cell_m: cell,
                nx: n,
                ny: n,
                heights,
            }),
            solids: Vec::new(),
            grid: None,
        };
        let mut physics = Physics::new(&world, 0.01);
        let i = physics.add_robot(
            &model("dala"),
            2.0,
            3.0,
            0.0,
            0.0,
            Streams::new(1).stream("r"),
        );
        let pose = physics.pose(i);
        assert!(
            (pose.translation.z - 0.2).abs() < 1e-6,
            "z = {}",
            pose.translation.z
        );
        let (_, pitch, _) = pose.rotation.euler_angles();
        // Uphill ahead: the nose points up, which is negative pitch in R = Rz Ry Rx.
        assert!((pitch + 0.1f64.atan()).abs() < 1e-6, "pitch {pitch}");
        // Facing north the slope is sideways: roll instead (left side, +x, is higher? no: -x is
        // left when facing north, so the left side is lower and the robot rolls left-down).
        let j = physics.add_robot(
            &model("dala"),
            -5.0,
            -5.0,
            0.0,
            std::f64::consts::FRAC_PI_2,
            Streams::new(1).stream("s"),
        );
        let (roll, pitch, _) = physics.pose(j).rotation.euler_angles();
        assert!(
            pitch.abs() < 1e-6 && (roll - (-0.1f64).atan()).abs() < 1e-6,
            "roll {roll} pitch {pitch}"
        );
        assert!((yaw_of(&physics.pose(j)) - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    }
}
