//! Running a scenario tick by tick.

use crate::cameras::Cameras;
use crate::comms::{Comms, CommsStats};
use crate::frames::FrameDump;
use crate::record::Recorder;
use crate::stacks::build_stack;
use hetsim_core::{RunDigest, Streams};
use hetsim_msgs::{
    pose_from_xyz_rpy, Command, Pose, PoseStamped, RobotStack, SensorMsg, StackStatus,
};
use hetsim_physics::Physics;
use hetsim_render::{AdapterSummary, RenderError, RenderOptions};
use hetsim_scene::Scenario;
use hetsim_sensors::SensorSuite;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// What a robot did.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RobotMetrics {
    /// Robot name.
    pub name: String,
    /// Robot model.
    pub model: String,
    /// Distance travelled in the xy plane, metres.
    pub distance_m: f64,
    /// Collisions (contact episodes).
    pub collisions: u32,
    /// Mission progress.
    pub goals_reached: usize,
    /// Goals in the mission.
    pub goals_total: usize,
    /// Goals given up as unreachable.
    pub goals_skipped: usize,
    /// Final position, metres.
    pub final_position_m: [f64; 3],
}

/// What the run measured (deterministic: part of the digest).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Ticks simulated.
    pub ticks: u64,
    /// Sim time simulated, seconds.
    pub sim_secs: f64,
    /// Messages and commands produced.
    pub records: u64,
    /// Per robot, in scenario order.
    pub robots: Vec<RobotMetrics>,
    /// Indoor worlds: requested obstruction ratio.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub obstruction_ratio_requested: Option<f64>,
    /// Indoor worlds: realised obstruction ratio.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub obstruction_ratio_realised: Option<f64>,
    /// Indoor worlds: free vertices and unreachable free vertices.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub free_vertices: Option<usize>,
    /// Indoor worlds: free vertices not reachable from the robots' component.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unreachable_vertices: Option<Vec<(usize, usize)>>,
    /// Number of buildings, walls and obstacles.
    pub solids: usize,
    /// Messages delivered per topic (sensors, ground truth, radio).
    pub messages: BTreeMap<String, u64>,
    /// What the radio did.
    pub comms: CommsStats,
    /// Estimated trajectories against truth, by `<kind>/<robot>`.
    pub estimates: BTreeMap<String, crate::trajectory::Accuracy>,
    /// Indoor worlds with a `[coverage]` table: the grid-level coverage plan's figures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<crate::coverage::CoverageMetrics>,
    /// A coverage mission run in lockstep: what the team did, against ground truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub team: Option<crate::team::TeamMetrics>,
    /// SLAM stacks: NEES of the robot pose, events, joint accuracy.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slam: Option<crate::slam::SlamMetrics>,
}

/// Everything a run produced, before it is written.
pub struct RunResult {
    /// Ground-truth poses per robot (scenario order), at the truth rate.
    pub truth: Vec<(String, Vec<(u64, Pose)>)>,
    /// Metrics.
    pub metrics: Metrics,
    /// Digest of every command and message so far (outputs are added when written).
    pub digest: RunDigest,
    /// The adapter that rendered the cameras, if any.
    pub adapter: Option<AdapterSummary>,
    /// Estimated trajectories the stacks kept.
    pub estimates: Vec<Estimate>,
    /// A coverage mission's outcome (the parent's report).
    pub team: Option<crate::team::TeamOutcome>,
    /// The SLAM stacks' mapped points in the world frame: (robot, sub-map, point).
    pub map_points: Vec<(String, usize, [f64; 3])>,
    /// The SLAM stacks' mapped line segments in the world frame: (robot, sub-map, endpoints).
    pub map_segments: Vec<(String, usize, [[f64; 3]; 2])>,
    /// The SLAM stacks' reports, by robot.
    pub slam: Vec<(String, hetsim_msgs::SlamReport)>,
}

/// A trajectory a robot stack estimated.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// What estimated it, e.g. `vo`.
    pub kind: String,
    /// The robot.
    pub robot: String,
    /// `(stamp_ns, world_from_body)`.
    pub poses: Vec<(u64, Pose)>,
}

/// Runs a scenario to its duration. `progress(tick, total)` is called every 1 % or so. With
/// a recorder, every command, message and ground-truth pose also goes to its MCAP file.
///
/// The loop itself runs on a rayon worker thread, so the per-tick fan-out to the stacks is a
/// cheap fork-join rather than a hand-off from an outside thread every tick.
pub fn run(
    scenario: &Scenario,
    progress: impl FnMut(u64, u64) + Send,
    options: RunOptions<'_>,
) -> Result<RunResult, RunError> {
    rayon::scope(|_| run_on_worker(scenario, progress, options))
}

/// What a run does besides simulating.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// Record every message, command and ground-truth pose.
    pub recorder: Option<&'a mut Recorder>,
    /// Render the robots' cameras on this adapter choice; `None`: no cameras.
    pub render: Option<RenderOptions>,
    /// Write camera frames.
    pub dump: Option<&'a mut FrameDump>,
    /// Render only the frames the dump wants (for `hetsim frames`).
    pub frames_only: bool,
    /// SLAM stacks run open loop (no events, no graph exchange).
    pub open_loop: bool,
}

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// No renderer.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Frames could not be written.
    #[error("writing frames: {0}")]
    Frames(String),
    /// The particle filter's path could not be rendered.
    #[error("localizing on the mission's database: {0}")]
    Localize(String),
}

/// Where messages go: the robot's inbox, the digest, the recording and the counts.
struct Post<'a> {
    names: Vec<String>,
    inboxes: Vec<Vec<SensorMsg>>,
    digest: RunDigest,
    recorder: Option<&'a mut Recorder>,
    counts: BTreeMap<String, u64>,
}

impl Post<'_> {
    fn deliver(&mut self, robot: usize, topic: &str, msg: SensorMsg, mount: Option<&Pose>) {
        self.digest.record(topic, &encode(&msg));
        if let Some(r) = self.recorder.as_deref_mut() {
            r.sensor(&self.names[robot], topic, mount, &msg);
        }
        *self.counts.entry(topic.to_string()).or_default() += 1;
        self.inboxes[robot].push(msg);
    }
}

fn run_on_worker(
    scenario: &Scenario,
    mut progress: impl FnMut(u64, u64),
    options: RunOptions<'_>,
) -> Result<RunResult, RunError> {
    let RunOptions {
        recorder,
        render,
        mut dump,
        frames_only,
        open_loop,
    } = options;
    let clock = scenario.clock;
    let streams = Streams::new(scenario.seed);
    let mut physics = Physics::for_scenario(scenario, &streams);
    let mut stacks: Vec<Box<dyn RobotStack>> = scenario
        .robots
        .iter()
        .map(|r| {
            let seed =
                rand::Rng::next_u64(&mut streams.stream(&format!("{}/vo/ransac", r.spec.name)));
            build_stack(scenario, r, seed, open_loop)
        })
        .collect();
    let names: Vec<String> = scenario
        .robots
        .iter()
        .map(|r| r.spec.name.clone())
        .collect();
    let mut sensors = SensorSuite::new(scenario, &streams);
    let mut cameras = match &render {
        Some(o) => Cameras::new(scenario, &streams, o)?,
        None => None,
    };
    let mut comms = Comms::new(scenario.file.comms.clone(), clock, names.clone(), streams);
    let n = stacks.len();
    let total = clock.ticks_in(scenario.duration_secs);
    let truth_period = clock
        .period_ticks(scenario.file.truth_rate_hz)
        .expect("validated truth rate");
    let mut post = Post {
        names: names.clone(),
        inboxes: vec![Vec::new(); n],
        digest: RunDigest::new(),
        recorder,
        counts: BTreeMap::new(),
    };
    let mut truth: Vec<Vec<(u64, Pose)>> = vec![Vec::new(); n];
    let mut keyframes_seen = vec![0usize; n];
    let cmd_topics: Vec<String> = names.iter().map(|r| format!("{r}/cmd")).collect();
    let truth_topics: Vec<String> = names.iter().map(|r| format!("{r}/truth")).collect();
    let radio_topics: Vec<String> = names.iter().map(|r| format!("{r}/radio")).collect();
    let mounts: BTreeMap<String, Pose> = scenario
        .robots
        .iter()
        .flat_map(|r| {
            r.model
                .sensors
                .iter()
                .map(move |s| (format!("{}/{}", r.spec.name, s.name()), s.mount().clone()))
        })
        .map(|(k, m)| {
            (
                k,
                pose_from_xyz_rpy(m.xyz_m, m.rpy_deg.map(f64::to_radians)),
            )
        })
        .collect();
    let deliver_truth =
        |post: &mut Post, truth: &mut Vec<Vec<(u64, Pose)>>, physics: &Physics, stamp_ns: u64| {
            for i in 0..n {
                let pose = physics.pose(i);
                post.deliver(
                    i,
                    &truth_topics[i],
                    SensorMsg::TruthPose(PoseStamped { stamp_ns, pose }),
                    None,
                );
                truth[i].push((stamp_ns, pose));
            }
        };
    // The initial pose, delivered before the first tick.
    deliver_truth(&mut post, &mut truth, &physics, 0);
    let report_every = (total / 100).max(1);
    // A mission that ends before the scenario's duration ends the run two seconds later.
    let mut end = total;
    let linger = clock.ticks_in(2.0);
    let mut ticks = 0;
    for tick in 0..total {
        if tick >= end {
            break;
        }
        ticks = tick + 1;
        let now = clock.time_ns(tick);
        // 1. stacks -> commands (in parallel; collected in robot order)
        let commands: Vec<Command> = stacks
            .par_iter_mut()
            .zip(post.inboxes.par_iter_mut())
            .map(|(stack, inbox)| {
                let cmd = stack.step(now, inbox);
                inbox.clear();
                cmd
            })
            .collect();
        // Key frames the stacks made, with the true pose then, for the emulated image matcher.
        for (i, stack) in stacks.iter().enumerate() {
            for &stamp in &stack.keyframes()[keyframes_seen[i]..] {
                let k = truth[i].partition_point(|(t, _)| *t <= stamp);
                if let Some((_, pose)) = k.checked_sub(1).map(|k| truth[i][k]) {
                    sensors.add_keyframe(i, stamp, pose);
                }
            }
            keyframes_seen[i] = stack.keyframes().len();
        }
        // 2. commands -> actuators; outgoing radio messages -> the radio
        let positions: Vec<[f64; 3]> = (0..n)
            .map(|i| physics.pose(i).translation.vector.into())
            .collect();
        for (i, cmd) in commands.iter().enumerate() {
            post.digest.record(&cmd_topics[i], &encode(cmd));
            if let Some(r) = post.recorder.as_deref_mut() {
                r.command(&names[i], now, cmd);
            }
            physics.command(i, cmd);
            for msg in stacks[i].outbox() {
                post.digest.record(&radio_topics[i], &encode(&msg));
                comms.send(tick, i, msg, &positions);
            }
        }
        // 3. physics
        physics.step();
        // 4. sensors due at the end of this tick
        let after = tick + 1;
        if after % truth_period == 0 {
            deliver_truth(&mut post, &mut truth, &physics, clock.time_ns(after));
        }
        for sample in sensors.sample(&physics, tick) {
            let mount = mounts.get(&sample.topic);
            post.deliver(sample.robot, &sample.topic, sample.msg, mount);
        }
        // Cameras (all due ones in one batch).
        if let Some(cams) = cameras.as_mut() {
            let stamp = clock.time_ns(after);
            // A robot that wants no images now (a child between grabs) gets none rendered;
            // the dump's frames are rendered whatever the stack wants.
            let stack_wants: Vec<bool> = stacks.iter().map(|s| s.wants_images()).collect();
            let wanted = |topic: &str| {
                let dumped = dump
                    .as_ref()
                    .is_some_and(|d| d.wants(topic) && d.in_window(stamp));
                if frames_only {
                    return dumped;
                }
                let robot = topic.split('/').next().unwrap_or_default();
                dumped
                    || names
                        .iter()
                        .position(|n| n == robot)
                        .is_none_or(|i| stack_wants[i])
            };
            for shot in cams.capture(&physics, tick, stamp, &wanted) {
                if let Some(d) = dump.as_deref_mut() {
                    if d.wants(&shot.topic) && d.in_window(stamp) {
                        d.write(&shot).map_err(RunError::Frames)?;
                    }
                }
                post.deliver(shot.robot, &shot.topic, SensorMsg::Image(shot.image), None);
            }
        }
        // 5. radio deliveries
        for (to, delivered) in comms.deliver(after) {
            post.deliver(to, &radio_topics[to], SensorMsg::Comms(delivered), None);
        }
        if end == total && stacks.iter().any(|s| s.mission_over()) {
            end = (tick + 1 + linger).min(total);
        }
        if tick % report_every == 0 {
            progress(tick, total);
        }
    }
    progress(total, total);
    let statuses: Vec<StackStatus> = stacks.iter().map(|s| s.status()).collect();
    let mut metrics = metrics(scenario, &physics, &statuses, ticks, post.digest.records());
    metrics.messages = post.counts;
    metrics.comms = comms.stats.clone();
    if let Some(d) = dump.as_deref() {
        d.finish().map_err(RunError::Frames)?;
    }
    let adapter = cameras.as_ref().map(|c| c.adapter().clone());
    let team = stacks.iter().enumerate().find_map(|(i, s)| {
        s.team_report().map(|report| crate::team::TeamOutcome {
            parent: names[i].clone(),
            report,
        })
    });
    metrics.team = team
        .as_ref()
        .map(|t| crate::team::TeamMetrics::compute(scenario, &physics, t, &truth, &metrics.robots));
    // The children then localize from the images: a particle filter on a new path.
    if let (Some(t), Some(m), Some(r)) = (&team, metrics.team.as_mut(), &render) {
        let named: Vec<(String, Vec<(u64, Pose)>)> =
            names.iter().cloned().zip(truth.iter().cloned()).collect();
        let db = crate::localize::database_of(&t.report, &named);
        if m.finished && !db.is_empty() {
            m.localization =
                crate::localize::particle_filter_path(scenario, &db, 20, scenario.seed, r)
                    .map_err(RunError::Localize)?;
        }
    }
    let map_points = per_robot(&stacks, &names, |s| s.map_points());
    let map_segments = per_robot(&stacks, &names, |s| s.map_segments());
    let mut estimates = Vec::new();
    for (i, stack) in stacks.iter().enumerate() {
        for (kind, poses) in stack.trajectories() {
            if poses.len() >= 2 {
                estimates.push(Estimate {
                    kind,
                    robot: names[i].clone(),
                    poses,
                });
            }
        }
    }
    for e in &estimates {
        let i = names
            .iter()
            .position(|n| *n == e.robot)
            .expect("a robot of this run");
        metrics.estimates.insert(
            format!("{}/{}", e.kind, e.robot),
            crate::trajectory::evaluate(&e.poses, &truth[i]),
        );
    }
    let slam: Vec<(String, hetsim_msgs::SlamReport)> = stacks
        .iter()
        .zip(&names)
        .filter_map(|(s, n)| Some((n.clone(), s.slam_report()?)))
        .collect();
    let named_truth: Vec<(String, Vec<(u64, Pose)>)> = names.into_iter().zip(truth).collect();
    if !slam.is_empty() {
        metrics.slam = Some(crate::slam::evaluate(&slam, &estimates, &named_truth));
    }
    Ok(RunResult {
        truth: named_truth,
        slam,
        metrics,
        digest: post.digest,
        adapter,
        estimates,
        team,
        map_points,
        map_segments,
    })
}

/// What `items` gives for each stack, tagged with its robot's name: `(robot, sub-map, item)`.
fn per_robot<T>(
    stacks: &[Box<dyn RobotStack>],
    names: &[String],
    items: impl Fn(&dyn RobotStack) -> Vec<(usize, T)>,
) -> Vec<(String, usize, T)> {
    stacks
        .iter()
        .zip(names)
        .flat_map(|(s, name)| {
            items(s.as_ref())
                .into_iter()
                .map(move |(node, x)| (name.clone(), node, x))
        })
        .collect()
}

fn encode<T: Serialize>(value: &T) -> Vec<u8> {
    postcard::to_stdvec(value).expect("plain-data messages always encode")
}

fn metrics(
    scenario: &Scenario,
    physics: &Physics,
    statuses: &[StackStatus],
    ticks: u64,
    records: u64,
) -> Metrics {
    let robots = scenario
        .robots
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let state = physics.state(i);
            let t = physics.pose(i).translation.vector;
            RobotMetrics {
                name: r.spec.name.clone(),
                model: r.spec.model.clone(),
                distance_m: state.distance_m,
                collisions: state.collisions,
                goals_reached: statuses[i].goals_reached,
                goals_total: statuses[i].goals_total,
                goals_skipped: statuses[i].goals_skipped,
                final_position_m: [t.x, t.y, t.z],
            }
        })
        .collect();
    let grid = scenario.world.grid.as_ref();
    Metrics {
        ticks,
        sim_secs: scenario.clock.time_secs(ticks),
        records,
        robots,
        obstruction_ratio_requested: grid.map(|g| g.requested_ratio),
        obstruction_ratio_realised: grid.map(|g| g.realised_ratio),
        free_vertices: grid.map(|g| g.grid.free_count()),
        unreachable_vertices: grid.map(|g| g.unreachable.clone()),
        solids: scenario.world.solids.len(),
        messages: BTreeMap::new(),
        comms: CommsStats::default(),
        estimates: BTreeMap::new(),
        team: None,
        slam: None,
        coverage: scenario
            .file
            .coverage
            .as_ref()
            .and_then(|_| crate::coverage::plan_scenario(scenario).ok())
            .map(|(_, _, plan)| crate::coverage::CoverageMetrics::of(&plan)),
    }
}
