//! `metrics.json`: what a run measured, computed from its outputs and the scenario's truth.

use crate::coverage::CoverageMetrics;
use crate::slam::SlamMetrics;
use crate::team::{TeamMetrics, TeamOutcome};
use crate::trajectory::{estimates, Accuracy};
use crate::EvalError;
use hetsim_engine::comms::CommsStats;
use hetsim_engine::RunOutput;
use hetsim_scene::Scenario;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What a robot did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    pub estimates: BTreeMap<String, Accuracy>,
    /// Indoor worlds with a `[coverage]` table: the grid-level coverage plan's figures.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub coverage: Option<CoverageMetrics>,
    /// A coverage mission run in lockstep: what the team did, against ground truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub team: Option<TeamMetrics>,
    /// SLAM stacks: NEES of the robot pose, events, joint accuracy.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slam: Option<SlamMetrics>,
}

impl Metrics {
    /// The metrics of a results folder, read back from its `metrics.json` as the typed struct
    /// they were written from (a renamed or retyped field is an error here, not a missing key
    /// in a caller).
    pub fn read(results: &std::path::Path) -> Result<Self, EvalError> {
        crate::json::read(&results.join("metrics.json"))
    }

    /// Evaluates a run.
    pub fn compute(scenario: &Scenario, output: &RunOutput) -> Result<Self, EvalError> {
        let robots: Vec<RobotMetrics> = output
            .robots
            .iter()
            .map(|r| RobotMetrics {
                name: r.name.clone(),
                model: r.model.clone(),
                distance_m: r.distance_m,
                collisions: r.collisions,
                goals_reached: r.status.goals_reached,
                goals_total: r.status.goals_total,
                goals_skipped: r.status.goals_skipped,
                final_position_m: r.final_position_m,
            })
            .collect();
        let grid = scenario.world.grid.as_ref();
        let coverage = match &scenario.file.coverage {
            Some(_) if grid.is_some() => {
                let (_, _, plan) = crate::coverage::plan_scenario(scenario)?;
                Some(CoverageMetrics::of(&plan))
            }
            _ => None,
        };
        let team = TeamOutcome::of(output).map(|o| TeamMetrics::compute(scenario, &o, output));
        let estimates = estimates(output);
        let mut accuracies = BTreeMap::new();
        for e in &estimates {
            let truth = output.truth_of(&e.robot).unwrap_or_default();
            accuracies.insert(
                format!("{}/{}", e.kind, e.robot),
                crate::trajectory::evaluate(&e.poses, truth),
            );
        }
        let reports = crate::slam::reports(output);
        let slam = (!reports.is_empty()).then(|| {
            let mut slam = crate::slam::evaluate(&reports, &estimates, &output.truth);
            let raw = crate::frames::raw_reports(output);
            for (robot, m) in crate::matching::judge(scenario, &raw, &output.truth) {
                if let Some(r) = slam.robots.get_mut(&robot) {
                    r.matching = Some(m);
                }
            }
            slam
        });
        Ok(Self {
            ticks: output.ticks,
            sim_secs: output.sim_secs,
            records: output.records,
            robots,
            obstruction_ratio_requested: grid.map(|g| g.requested_ratio),
            obstruction_ratio_realised: grid.map(|g| g.realised_ratio),
            free_vertices: grid.map(|g| g.grid.free_count()),
            unreachable_vertices: grid.map(|g| g.unreachable.clone()),
            solids: scenario.world.solids.len(),
            messages: output.messages.clone(),
            comms: output.comms.clone(),
            estimates: accuracies,
            coverage,
            team,
            slam,
        })
    }
}
