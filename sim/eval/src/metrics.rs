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
    /// Each pinhole camera's drawn calibration error, by topic, as a calibration report
    /// would give it (cameras calibrated exactly are left out).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub cameras: BTreeMap<String, CalibrationErrorMetrics>,
}

/// A camera's drawn calibration error in pixels: where the given calibration puts what the
/// true camera sees (`hetsim_sensors::camera::calibration::reprojection_rms_px`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationErrorMetrics {
    /// The intrinsics' and distortion's alone, as a calibration report's reprojection
    /// error is, pixels.
    pub lens_rms_px: f64,
    /// RMS over the image of points at `depth_m`, pixels (intrinsics, distortion, mount and,
    /// for a bench's right camera, the pair's relative pose).
    pub reprojection_rms_px: f64,
    /// The depth of those points, metres.
    pub depth_m: f64,
    /// The same for points at infinity (the mount's translation left out), pixels.
    pub rays_rms_px: f64,
    /// The stamp's offset against the true mid-exposure, milliseconds.
    pub time_offset_ms: f64,
}

/// Every pinhole camera's calibration error, where one was drawn (the `perfect` profile and
/// a robot file without `calibration_error` have none; the omnidirectional camera is
/// calibrated exactly, and has no pinhole to reproject with).
fn calibration_errors(output: &RunOutput) -> BTreeMap<String, CalibrationErrorMetrics> {
    use hetsim_engine::cameras::{
        reprojection_rms_px, Calibration, CameraCalibration, REPROJECTION_DEPTH_M,
    };
    output
        .cameras
        .iter()
        .filter(|(_, c)| {
            c.given.geometry.k.alpha_u > 0.0 && (c.truth != c.given || c.time_offset_s != 0.0)
        })
        .map(|(topic, c)| {
            let lens = CameraCalibration {
                truth: Calibration {
                    body_from_mount: c.given.body_from_mount,
                    ..c.truth
                },
                ..*c
            };
            let m = CalibrationErrorMetrics {
                lens_rms_px: reprojection_rms_px(&lens, f64::INFINITY),
                reprojection_rms_px: reprojection_rms_px(c, REPROJECTION_DEPTH_M),
                depth_m: REPROJECTION_DEPTH_M,
                rays_rms_px: reprojection_rms_px(c, f64::INFINITY),
                time_offset_ms: c.time_offset_s * 1e3,
            };
            (topic.clone(), m)
        })
        .collect()
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
            cameras: calibration_errors(output),
        })
    }
}
