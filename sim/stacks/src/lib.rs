//! Which robot software runs on which robot: the wiring between scenario files and the robot
//! crates. The engine knows no robot software; the binary, the tests and the sweeps build one
//! stack per robot here and hand them to `hetsim_engine::run`.
//!
//! | mission (scenario) | robot | stack |
//! |---|---|---|
//! | `waypoints`, `lawnmower` | helicopter | [`HeliPilot`] |
//! | `waypoints`, `grid_goals` | wheeled | [`GroundPilot`] |
//! | any of those | with a stereo bench | the SLAM stack (`hetsim-slam`) around the pilot |
//! | `coverage_parent` | | [`hetsim_coverage::ParentStack`] |
//! | `coverage_child` | | [`hetsim_coverage::ChildStack`] |

use hetsim_core::Streams;
use hetsim_msgs::{Mission, RobotStack};
use hetsim_pilot::{lawnmower, GroundPilot, GroundPilotParams, HeliPilot, HeliPilotParams};
use hetsim_scene::{
    coverage_params, stereo_bench, DriveKind, MissionSpec, ResolvedRobot, Scenario, Sensor,
    StereoBench,
};

/// One stack per robot of the scenario, in scenario order; the SLAM stacks open loop (no
/// events, no radio) when `open_loop`. Each stack's random seed comes from its own named
/// stream (`<robot>/vo/ransac`).
pub fn build_stacks(scenario: &Scenario, open_loop: bool) -> Vec<Box<dyn RobotStack>> {
    let streams = Streams::new(scenario.seed);
    scenario
        .robots
        .iter()
        .map(|r| {
            let seed =
                rand::Rng::next_u64(&mut streams.stream(&format!("{}/vo/ransac", r.spec.name)));
            build_stack(scenario, r, seed, open_loop)
        })
        .collect()
}

/// The stack for a robot: the waypoint followers of `hetsim-pilot` on ground truth, and, for
/// robots with a stereo bench, stereo visual odometry and the local level of the SLAM beside
/// them (`hetsim-slam`), open loop (no events, no radio) when `open_loop`.
pub fn build_stack(
    scenario: &Scenario,
    robot: &ResolvedRobot,
    seed: u64,
    open_loop: bool,
) -> Box<dyn RobotStack> {
    let pilot = build_pilot(scenario, robot);
    let stereo = stereo_bench(robot);
    match stereo {
        Some(StereoBench {
            name,
            intrinsics: k,
            baseline_m: baseline,
            body_from_mount,
        }) => {
            let camera = k.k;
            let body_from_camera = nalgebra::Isometry3::from_parts(
                body_from_mount.translation,
                body_from_mount.rotation * hetsim_msgs::mount_to_optical(),
            );
            // The seed's SLAM (which carries the stereo VO): local EKF sub-maps with
            // inverse-depth points, initialized with the seed's values for the robot kind.
            let mut params = robot
                .model
                .slam_params()
                .expect("the [slam] table was checked when its robot file was loaded");
            params.cooperative = !open_loop;
            // The team's frame is the first sub-map of the scenario's first robot (seed
            // Section V: Dala's); every other robot starts in its own until an event links it.
            params.reference_robot = scenario.robots.first().map(|r| r.spec.name.clone());
            Box::new(hetsim_slam::stack::SlamStack::new(
                pilot,
                &robot.spec.name,
                &name,
                hetsim_vision::stereo::Bench {
                    camera,
                    baseline_m: baseline,
                },
                body_from_camera,
                params,
                seed,
            ))
        }
        None => pilot,
    }
}

fn build_pilot(scenario: &Scenario, robot: &ResolvedRobot) -> Box<dyn RobotStack> {
    let model = &robot.model;
    let pilot = &model.pilot;
    let mission = mission(scenario, &robot.spec.mission);
    if let Some(stack) = coverage_stack(scenario, robot, &mission) {
        return stack;
    }
    match model.body.drive {
        DriveKind::Helicopter => {
            let h = model
                .body
                .helicopter
                .as_ref()
                .expect("validated helicopter has [body.helicopter]");
            let route = match mission {
                Mission::Waypoints(points) => points,
                _ => Vec::new(),
            };
            Box::new(HeliPilot::new(
                HeliPilotParams {
                    cruise_mps: pilot.cruise_mps,
                    max_tilt_rad: h.max_tilt_deg.to_radians(),
                    max_yaw_rate_radps: model.body.max_yaw_rate_deg_s.to_radians(),
                    max_climb_mps: h.max_climb_mps,
                    arrive_m: pilot.arrive_m,
                    gravity_mps2: 9.81,
                },
                route,
            ))
        }
        DriveKind::SkidSteer | DriveKind::Differential => {
            Box::new(GroundPilot::new(ground_params(robot), mission))
        }
    }
}

/// The waypoint pilot's parameters of a wheeled robot.
fn ground_params(robot: &ResolvedRobot) -> GroundPilotParams {
    let model = &robot.model;
    let pilot = &model.pilot;
    let w = model
        .body
        .wheels
        .as_ref()
        .expect("validated wheeled robot has [body.wheels]");
    GroundPilotParams {
        track_m: w.track_m,
        max_wheel_mps: model.body.max_speed_mps,
        cruise_mps: pilot.cruise_mps,
        max_yaw_rate_radps: model.body.max_yaw_rate_deg_s.to_radians(),
        arrive_m: pilot.arrive_m,
        steering: pilot.steering(),
    }
}

/// The coverage mission's stacks (seed 002): the parent and its teleoperated children.
fn coverage_stack(
    scenario: &Scenario,
    robot: &ResolvedRobot,
    mission: &Mission,
) -> Option<Box<dyn RobotStack>> {
    match mission {
        Mission::CoverageParent(_) => {
            let mut params = hetsim_coverage::ParentParams::with_pilot(ground_params(robot));
            // The localization's random numbers: the stream `<robot>/mcl`.
            params.seed = rand::Rng::next_u64(
                &mut Streams::new(scenario.seed).stream(&format!("{}/mcl", robot.spec.name)),
            );
            // The path a child localizes along after mapping: the stream `<robot>/tour`.
            params.tour_seed = rand::Rng::next_u64(
                &mut Streams::new(scenario.seed).stream(&format!("{}/tour", robot.spec.name)),
            );
            // The laser the parent localizes with: its first, as mounted (planar: x, y, yaw).
            params.laser_mount = robot.model.sensors.iter().find_map(|s| match s {
                Sensor::Laser { mount, .. } => Some([
                    mount.xyz_m[0],
                    mount.xyz_m[1],
                    mount.rpy_deg[2].to_radians(),
                ]),
                _ => None,
            });
            params.hat_tracker = hat_tracker(scenario, robot);
            Some(Box::new(hetsim_coverage::ParentStack::new(params, mission)))
        }
        Mission::Teleoperated { .. } => {
            let model = &robot.model;
            let w = model
                .body
                .wheels
                .as_ref()
                .expect("validated wheeled robot has [body.wheels]");
            Some(Box::new(hetsim_coverage::ChildStack::new(
                hetsim_coverage::ChildParams {
                    track_m: w.track_m,
                    speed_mps: model.pilot.cruise_mps,
                    max_turn_radps: model.body.max_yaw_rate_deg_s.to_radians().min(1.0),
                    aim_tolerance_rad: model.pilot.aim_tolerance_rad(),
                    settle_ns: 200_000_000,
                    // Its particle filters' random numbers: the stream `<robot>/pf`.
                    seed: rand::Rng::next_u64(
                        &mut Streams::new(scenario.seed).stream(&format!("{}/pf", robot.spec.name)),
                    ),
                },
                mission,
            )))
        }
        _ => None,
    }
}

/// The parent's hat tracker on its first omnidirectional camera, calibrated from its robot
/// file (the panorama, the mount) and the children's (the hats' height: the teleoperated
/// robots' first hatted model; every scenario's children share one). `None` without such a
/// camera, or without hatted children: the parent then takes an emulated tracker's fixes.
fn hat_tracker(scenario: &Scenario, robot: &ResolvedRobot) -> Option<hetsim_coverage::HatTracker> {
    let child = scenario
        .robots
        .iter()
        .find(|r| matches!(r.spec.mission, MissionSpec::CoverageChild) && r.model.body.hat)?;
    let b = &child.model.body;
    let hat_height_m = b.height_m + hetsim_scene::HAT_THICKNESS_M;
    let hat_size_m = [b.length_m, b.width_m].map(|side| side * hetsim_scene::HAT_SCALE);
    robot.model.sensors.iter().find_map(|s| match s {
        Sensor::OmniCamera {
            name,
            mount,
            width_px,
            height_px,
            elevation_deg,
            ..
        } => Some(hetsim_coverage::HatTracker {
            camera: name.clone(),
            mount: [
                mount.xyz_m[0],
                mount.xyz_m[1],
                mount.rpy_deg[2].to_radians(),
            ],
            finder: hetsim_vision::hats::HatFinder {
                panorama: hetsim_vision::hats::Panorama {
                    width: *width_px,
                    height: *height_px,
                    elevation_rad: elevation_deg.map(f64::to_radians),
                },
                camera_height_m: mount.xyz_m[2],
                hat_height_m,
                min_pixels: 4,
                hat_size_m,
                hat_thickness_m: hetsim_scene::HAT_THICKNESS_M,
            },
            range_m: coverage_params(scenario).r_los_m,
            gate_m: 0.3,
        }),
        _ => None,
    })
}

/// The mission message for a mission as written.
fn mission(scenario: &Scenario, spec: &MissionSpec) -> Mission {
    match spec {
        MissionSpec::Idle => Mission::Idle,
        MissionSpec::Waypoints { points } => Mission::Waypoints(
            points
                .iter()
                .map(|p| [p[0], p[1], p.get(2).copied().unwrap_or(0.0)])
                .collect(),
        ),
        MissionSpec::Lawnmower {
            from,
            to,
            width_m,
            spacing_m,
            altitude_m,
            then,
        } => {
            let mut route = lawnmower(*from, *to, *width_m, *spacing_m, *altitude_m);
            route.extend(then.iter().map(|p| [p[0], p[1], *altitude_m]));
            Mission::Waypoints(route)
        }
        MissionSpec::CoverageParent => match &scenario.world.grid {
            Some(g) => {
                let params = coverage_params(scenario);
                let children = scenario
                    .robots
                    .iter()
                    .filter(|r| matches!(r.spec.mission, MissionSpec::CoverageChild))
                    .filter_map(|r| {
                        g.grid
                            .cell_of(r.spec.start.x, r.spec.start.y)
                            .map(|cell| (r.spec.name.clone(), cell))
                    })
                    .collect::<Vec<_>>();
                let parent_start = scenario
                    .robots
                    .iter()
                    .find(|r| matches!(r.spec.mission, MissionSpec::CoverageParent))
                    .map_or([0.0; 3], |r| operator_start(scenario, r));
                let child_speed_mps = scenario
                    .robots
                    .iter()
                    .find(|r| matches!(r.spec.mission, MissionSpec::CoverageChild))
                    .map_or(0.15, |r| r.model.pilot.cruise_mps);
                Mission::CoverageParent(hetsim_msgs::CoverageMission {
                    grid: g.grid.clone(),
                    children,
                    r_los_m: params.r_los_m,
                    direction: format!("{:?}", params.direction).to_lowercase(),
                    child_fov_deg: params.child_fov_deg,
                    view_margin_deg: params.view_margin_deg,
                    view_margin_m: params.view_margin_m,
                    parent_radius_m: params.parent_radius_m,
                    child_radius_m: params.child_radius_m,
                    f_factor: params.f_factor,
                    child_speed_mps,
                    parent_start,
                    localize_steps: scenario
                        .file
                        .coverage
                        .clone()
                        .unwrap_or_default()
                        .localize_steps,
                })
            }
            None => Mission::Idle,
        },
        MissionSpec::CoverageChild => Mission::Teleoperated {
            parent: scenario
                .robots
                .iter()
                .find(|r| matches!(r.spec.mission, MissionSpec::CoverageParent))
                .map(|r| r.spec.name.clone())
                .unwrap_or_default(),
        },
        MissionSpec::GridGoals { goals } => match &scenario.world.grid {
            Some(g) => Mission::GridGoals {
                grid: g.grid.clone(),
                goals: goals.iter().map(|v| (v[0], v[1])).collect(),
            },
            None => Mission::Idle,
        },
    }
}

/// The start pose an operator gives a robot that localizes against a map (as one sets a ROS
/// `amcl` initial pose, by eye on a marked spot): the scenario's start, off by a seeded error
/// of σ 0.05 m on x and y and 2° on the heading (stream `<robot>/operator_start`), so that
/// the localization's prior is not centred on the truth.
fn operator_start(scenario: &Scenario, robot: &ResolvedRobot) -> [f64; 3] {
    use rand::RngExt;
    let mut rng =
        Streams::new(scenario.seed).stream(&format!("{}/operator_start", robot.spec.name));
    let mut normal = || {
        // Box-Muller.
        let u1: f64 = rng.random_range(1e-12..1.0);
        let u2: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let s = &robot.spec.start;
    [
        s.x + 0.05 * normal(),
        s.y + 0.05 * normal(),
        (s.yaw_deg + 2.0 * normal()).to_radians(),
    ]
}
