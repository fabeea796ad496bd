//! Running a scenario tick by tick.

use crate::stacks::build_stack;
use hetsim_core::{RunDigest, Streams};
use hetsim_msgs::{Command, Pose, PoseStamped, RobotStack, SensorMsg, StackStatus};
use hetsim_physics::Physics;
use hetsim_scene::Scenario;
use rayon::prelude::*;
use serde::Serialize;

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
    /// Indoor worlds with a `[coverage]` table: the grid-level coverage plan's figures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<crate::coverage::CoverageMetrics>,
}

/// Everything a run produced, before it is written.
pub struct RunResult {
    /// Ground-truth poses per robot (scenario order), at the truth rate.
    pub truth: Vec<(String, Vec<(u64, Pose)>)>,
    /// Metrics.
    pub metrics: Metrics,
    /// Digest of every command and message so far (outputs are added when written).
    pub digest: RunDigest,
}

/// Runs a scenario to its duration. `progress(tick, total)` is called every 1 % or so.
///
/// The loop itself runs on a rayon worker thread, so the per-tick fan-out to the stacks is a
/// cheap fork-join rather than a hand-off from an outside thread every tick.
pub fn run(scenario: &Scenario, progress: impl FnMut(u64, u64) + Send) -> RunResult {
    rayon::scope(|_| run_on_worker(scenario, progress))
}

fn run_on_worker(scenario: &Scenario, mut progress: impl FnMut(u64, u64)) -> RunResult {
    let clock = scenario.clock;
    let streams = Streams::new(scenario.seed);
    let mut physics = Physics::new(&scenario.world, clock.dt_secs());
    let mut stacks: Vec<Box<dyn RobotStack>> = Vec::new();
    for r in &scenario.robots {
        physics.add_robot(
            &r.model,
            r.spec.start.x,
            r.spec.start.y,
            r.spec.start.z,
            r.spec.start.yaw_deg.to_radians(),
            streams.stream(&format!("{}/drive/wheel_error", r.spec.name)),
        );
        stacks.push(build_stack(scenario, r));
    }
    let n = stacks.len();
    let total = clock.ticks_in(scenario.duration_secs);
    let truth_period = clock
        .period_ticks(scenario.file.truth_rate_hz)
        .expect("validated truth rate");
    let mut digest = RunDigest::new();
    let mut inboxes: Vec<Vec<SensorMsg>> = vec![Vec::new(); n];
    let mut truth: Vec<Vec<(u64, Pose)>> = vec![Vec::new(); n];
    let topics: Vec<(String, String)> = scenario
        .robots
        .iter()
        .map(|r| {
            (
                format!("{}/cmd", r.spec.name),
                format!("{}/truth", r.spec.name),
            )
        })
        .collect();
    // The initial pose, delivered before the first tick.
    deliver_truth(&physics, 0, &topics, &mut inboxes, &mut truth, &mut digest);
    let report_every = (total / 100).max(1);
    for tick in 0..total {
        let now = clock.time_ns(tick);
        // 1. stacks -> commands (in parallel; collected in robot order)
        let commands: Vec<Command> = stacks
            .par_iter_mut()
            .zip(inboxes.par_iter_mut())
            .map(|(stack, inbox)| {
                let cmd = stack.step(now, inbox);
                inbox.clear();
                cmd
            })
            .collect();
        // 2. commands -> actuators
        for (i, cmd) in commands.iter().enumerate() {
            digest.record(&topics[i].0, &encode(cmd));
            physics.command(i, cmd);
        }
        // 3. physics
        physics.step();
        // 4. sensors due at the end of this tick
        let after = tick + 1;
        if after % truth_period == 0 {
            deliver_truth(
                &physics,
                clock.time_ns(after),
                &topics,
                &mut inboxes,
                &mut truth,
                &mut digest,
            );
        }
        if tick % report_every == 0 {
            progress(tick, total);
        }
    }
    progress(total, total);
    let statuses: Vec<StackStatus> = stacks.iter().map(|s| s.status()).collect();
    let metrics = metrics(scenario, &physics, &statuses, total, digest.records());
    RunResult {
        truth: scenario
            .robots
            .iter()
            .map(|r| r.spec.name.clone())
            .zip(truth)
            .collect(),
        metrics,
        digest,
    }
}

fn deliver_truth(
    physics: &Physics,
    stamp_ns: u64,
    topics: &[(String, String)],
    inboxes: &mut [Vec<SensorMsg>],
    truth: &mut [Vec<(u64, Pose)>],
    digest: &mut RunDigest,
) {
    for (i, inbox) in inboxes.iter_mut().enumerate() {
        let pose = physics.pose(i);
        let msg = SensorMsg::TruthPose(PoseStamped { stamp_ns, pose });
        digest.record(&topics[i].1, &encode(&msg));
        inbox.push(msg);
        truth[i].push((stamp_ns, pose));
    }
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
        coverage: scenario
            .file
            .coverage
            .as_ref()
            .and_then(|_| crate::coverage::plan_scenario(scenario).ok())
            .map(|(_, _, plan)| crate::coverage::CoverageMetrics::of(&plan)),
    }
}
