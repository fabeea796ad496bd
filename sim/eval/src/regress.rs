//! Regression of coverage planning against committed baselines (`results/baselines/`).
//!
//! Each baseline file names a scenario and seed, the metrics it produced, and a tolerance per
//! metric: a metric moved when `|now - baseline| > max(abs, rel * |baseline|)`. Plans are
//! deterministic, so on one platform nothing moves unless the planner or the world
//! generator changed; the tolerances say how much change is still acceptable without a
//! deliberate `--update`.
//!
//! Beside the baselines, every map is planned with 1 to [`REQUIRED_CHILDREN`] children
//! and each plan must image every vertex some vertex sees freely (Eq. 4 of seed 002 where its
//! assumption holds) and skip no stage: those are requirements, not baselines, and `--update`
//! does not lift them.

use crate::coverage::{plan_scenario, plan_scenario_with, CoverageMetrics};
use crate::EvalError;
use hetsim_core::files::write_atomic;
use hetsim_scene::{load_scenario, LoadOptions};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The scenarios `hetsim regress` covers by default.
pub const DEFAULT_SCENARIOS: [&str; 3] = [
    "scenarios/indoor-grid-0.toml",
    "scenarios/indoor-grid-20.toml",
    "scenarios/indoor-grid-40.toml",
];

/// Full coverage and every stage are required of every plan with 1 to this many children
/// (Tables I-II's range).
pub const REQUIRED_CHILDREN: usize = 8;

/// Allowed movement of one metric.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerance {
    /// Absolute tolerance.
    pub abs: f64,
    /// Tolerance relative to the baseline value.
    pub rel: f64,
}

/// A baseline file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Baseline {
    /// Scenario path relative to the repository root.
    pub scenario: String,
    /// Seed.
    pub seed: u64,
    /// Metric values.
    pub metrics: BTreeMap<String, f64>,
    /// Metric tolerances.
    pub tolerance: BTreeMap<String, Tolerance>,
}

/// Default tolerances of a new baseline.
fn default_tolerances() -> BTreeMap<String, Tolerance> {
    [
        ("parent_vertices", 0.0, 0.02),
        ("following", 1.0, 0.10),
        ("mapping_timesteps", 0.0, 0.05),
        ("coordination_timesteps", 0.0, 0.10),
        ("coverage", 0.005, 0.0),
    ]
    .into_iter()
    .map(|(k, abs, rel)| (k.to_string(), Tolerance { abs, rel }))
    .collect()
}

fn metrics_map(m: &CoverageMetrics) -> BTreeMap<String, f64> {
    [
        ("parent_vertices", m.parent_vertices as f64),
        ("following", m.following as f64),
        ("mapping_timesteps", m.mapping_timesteps as f64),
        ("coordination_timesteps", m.coordination_timesteps as f64),
        ("coverage", m.coverage),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// One compared metric.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Scenario.
    pub scenario: String,
    /// Metric.
    pub metric: String,
    /// Baseline value.
    pub baseline: f64,
    /// Value now.
    pub now: f64,
    /// Allowed absolute movement.
    pub allowed: f64,
    /// A requirement (full coverage, or no skipped stage), not a baseline: `--update` does
    /// not rewrite it.
    pub required: bool,
}

impl Comparison {
    /// Whether it moved beyond its tolerance.
    pub fn moved(&self) -> bool {
        (self.now - self.baseline).abs() > self.allowed + 1e-12
    }
}

fn baseline_path(root: &Path, scenario: &str) -> PathBuf {
    let stem = Path::new(scenario)
        .file_stem()
        .map_or("scenario".into(), |s| s.to_string_lossy().to_string());
    root.join("results/baselines").join(format!("{stem}.json"))
}

/// Runs every scenario, compares with (or, with `update`, rewrites) its baseline.
pub fn regress(
    root: &Path,
    scenarios: &[String],
    update: bool,
) -> Result<Vec<Comparison>, EvalError> {
    let mut out = Vec::new();
    for scenario in scenarios {
        let path = baseline_path(root, scenario);
        let existing: Option<Baseline> = match std::fs::read_to_string(&path) {
            Ok(text) => Some(serde_json::from_str(&text).map_err(|e| EvalError::Content {
                path: path.clone(),
                message: format!("line {}: {e}", e.line()),
            })?),
            Err(_) if update => None,
            Err(e) => {
                return Err(EvalError::Content {
                    path,
                    message: format!("{e} (run `hetsim regress --update` to create it)"),
                })
            }
        };
        let seed = existing.as_ref().map(|b| b.seed);
        let loaded = load_scenario(
            &root.join(scenario),
            &LoadOptions {
                robot_files: None,
                seed,
                duration_secs: None,
            },
        )?;
        let (_, _, plan) = plan_scenario(&loaded)?;
        let now = metrics_map(&CoverageMetrics::of(&plan));
        let full = requirements(scenario, &loaded)?;
        if update && full.iter().any(Comparison::moved) {
            // A baseline is not rewritten from a planner that fails the requirement.
            out.extend(full);
            continue;
        }
        if update {
            let baseline = Baseline {
                scenario: scenario.clone(),
                seed: loaded.seed,
                metrics: now.clone(),
                tolerance: existing.map_or_else(default_tolerances, |b| b.tolerance),
            };
            let text = serde_json::to_string_pretty(&baseline).expect("baselines serialize") + "\n";
            write_atomic(&path, text.as_bytes())?;
            for (metric, value) in &now {
                out.push(Comparison {
                    scenario: scenario.clone(),
                    metric: metric.clone(),
                    baseline: *value,
                    now: *value,
                    allowed: 0.0,
                    required: false,
                });
            }
            out.extend(full);
            continue;
        }
        let baseline = existing.expect("read above");
        for (metric, value) in &baseline.metrics {
            let tol = baseline
                .tolerance
                .get(metric)
                .cloned()
                .unwrap_or(Tolerance { abs: 0.0, rel: 0.0 });
            let now_value = *now.get(metric).ok_or_else(|| EvalError::Content {
                path: path.clone(),
                message: format!("unknown metric {metric}"),
            })?;
            out.push(Comparison {
                scenario: scenario.clone(),
                metric: metric.clone(),
                baseline: *value,
                now: now_value,
                allowed: tol.abs.max(tol.rel * value.abs()),
                required: false,
            });
        }
        out.extend(full);
    }
    Ok(out)
}

/// Two rows per number of children: the plan's coverage of the vertices some vertex sees
/// freely, which must be 1, and its skipped stages, which must be none (the robots get past
/// each other to every parent vertex).
fn requirements(
    scenario: &str,
    loaded: &hetsim_scene::Scenario,
) -> Result<Vec<Comparison>, EvalError> {
    let mut rows = Vec::new();
    for n in 1..=REQUIRED_CHILDREN {
        let (_, _, plan) = plan_scenario_with(loaded, Some(n))?;
        rows.push(Comparison {
            scenario: scenario.to_string(),
            metric: format!("coverable_coverage (children = {n})"),
            baseline: 1.0,
            now: plan.coverable_coverage(),
            allowed: 0.0,
            required: true,
        });
        rows.push(Comparison {
            scenario: scenario.to_string(),
            metric: format!("skipped_stages (children = {n})"),
            baseline: 0.0,
            now: plan.skipped_stages.len() as f64,
            allowed: 0.0,
            required: true,
        });
    }
    Ok(rows)
}
