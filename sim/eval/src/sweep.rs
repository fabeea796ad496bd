//! Monte Carlo sweeps over scenario and robot-file parameters, resumable and shardable.
//!
//! A sweep file names a base scenario, parameter axes and a number of seeds. Runs are the
//! product of the axes (in key order, values as listed) and the seeds; run `i` always means
//! the same combination. Two kinds:
//!
//! - `kind = "plan"` (the default): grid-level coverage planning of the run's scenario, as
//!   in seed 002's simulations; the metrics are the planner's ([`METRICS`]).
//! - `kind = "run"`: whole lockstep runs of any scenario, rendered or not; each run's
//!   results folder is kept under `runs/<i>/`, and the metrics are dotted paths into its
//!   `metrics.json` (`estimates.vo/ressac.ate_m`, `team.coverage`), named by the sweep
//!   file. Running a scenario needs the engine, so the caller supplies the runner
//!   ([`run_sweep_with`]); the `hetsim` binary does.
//!
//! An axis is a dotted path to a scenario field (`coverage.children`), to a field of one
//! robot's file (`robots.<robot name>.<field>`, e.g. `robots.ressac.sensors.stereo.pixel_noise_sigma`,
//! written into that robot's `overrides`), or to a field of every robot of a model
//! (`models.<model>.<field>`, e.g. `models.ctbot.sensors.compass.sigma_deg`).
//!
//! Each finished run writes one row file `rows/<i>.csv` atomically, so an interrupted sweep
//! resumes without redoing finished runs and never leaves a half-written row; `runs.csv`,
//! `summary.csv`, `summary.md` and the box plots are rebuilt from the row files in run
//! order, so they depend neither on the number of jobs, nor on scheduling, nor on sharding
//! (`merge` joins shards into the same files).

use crate::coverage::CoverageMetrics;
use hetsim_core::files::{write_atomic, FileError};
use hetsim_scene::{load_scenario_text, LoadOptions};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod axes;
pub use axes::{apply_settings, SettingError};
mod runs;
mod summary;
pub use runs::{
    in_shard, merge, metrics_of_run, plan_runner, run_sweep, run_sweep_with, RunResult, Runner,
};
pub use summary::{summarize, Stat, SummaryCell, SweepSummary};

/// Why a sweep could not be loaded, run or summarized.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A file could not be read or written.
    #[error(transparent)]
    File(#[from] FileError),
    /// The sweep file is not valid TOML of the sweep schema.
    #[error("{}:{}: {message}", path.display(), line.map_or("?".to_string(), |l| l.to_string()))]
    Parse {
        /// The sweep file.
        path: PathBuf,
        /// 1-based line, where known.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// A field has a value that is not allowed.
    #[error("{}: field `{field}` = {value}: {allowed}", path.display())]
    Field {
        /// The sweep file.
        path: PathBuf,
        /// The field.
        field: String,
        /// Its value.
        value: String,
        /// What is allowed.
        allowed: String,
    },
    /// One run's scenario is refused, or the run failed.
    #[error("{}: run {index} ({values}): {message}", path.display())]
    Run {
        /// The sweep file.
        path: PathBuf,
        /// The run.
        index: usize,
        /// Its axis values and seed.
        values: String,
        /// What went wrong.
        message: String,
    },
    /// A row file is not a row of this sweep.
    #[error("{}: row {row}: {message}", path.display())]
    Row {
        /// The row file.
        path: PathBuf,
        /// 1-based record number in the file.
        row: usize,
        /// What is wrong.
        message: String,
    },
    /// Shards to merge do not hold every run of the sweep.
    #[error("{}: {missing} of {total} runs have no row in the shards merged (first missing: run {first}); a shard failed or was left out", path.display())]
    Incomplete {
        /// The sweep file.
        path: PathBuf,
        /// Runs without a row.
        missing: usize,
        /// Runs in the sweep.
        total: usize,
        /// The first run without a row.
        first: usize,
    },
    /// The output folder, or a shard to merge, holds the results of another sweep.
    #[error("{}: holds the results of another sweep ({what} differ from {sweep}'s); choose another --out, or remove the folder to start again", path.display(), sweep = sweep.display())]
    Mismatch {
        /// The folder.
        path: PathBuf,
        /// The sweep file.
        sweep: PathBuf,
        /// What differs.
        what: String,
    },
    /// The worker threads could not be started.
    #[error("starting {jobs} worker threads: {message}")]
    Threads {
        /// Threads asked for.
        jobs: usize,
        /// What failed.
        message: String,
    },
}

fn read(path: &Path) -> Result<Vec<u8>, SweepError> {
    Ok(std::fs::read(path).map_err(FileError::at(path))?)
}

/// What one run of a sweep is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepKind {
    /// Grid-level coverage planning (no engine, no rendering), as in seed 002's simulations.
    #[default]
    Plan,
    /// A whole lockstep run of the scenario, evaluated into its `metrics.json`.
    Run,
}

/// A sweep file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepFile {
    /// Must be 1.
    pub schema_version: i64,
    /// Name of the sweep.
    pub name: String,
    /// Base scenario, relative to the sweep file's folder (not with `recording`, which
    /// carries its scenario).
    #[serde(default)]
    pub base: String,
    /// `run` only: replay this recording (`hetsim run --record`, relative to the sweep
    /// file's folder) for each run instead of running live: the axes change the robot
    /// software's settings, the sensor data stay the recorded ones. One seed, the
    /// recording's.
    #[serde(default)]
    pub recording: Option<String>,
    /// `plan` (default) or `run`.
    #[serde(default)]
    pub kind: SweepKind,
    /// Seeds per combination: `first_seed .. first_seed + seeds`.
    pub seeds: u64,
    /// First seed.
    #[serde(default)]
    pub first_seed: u64,
    /// `run` only: dotted paths into each run's `metrics.json`, one column each.
    #[serde(default)]
    pub metrics: Vec<String>,
    /// `run` only: sim seconds of each run (default: the scenario's `duration_secs`).
    #[serde(default)]
    pub duration_secs: Option<f64>,
    /// `run` only: render the cameras (default true).
    #[serde(default)]
    pub render: Option<bool>,
    /// Axis (a dotted path, see the module doc) -> values.
    pub axes: BTreeMap<String, Vec<toml::Value>>,
}

/// One run of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRun {
    /// Run index.
    pub index: usize,
    /// Axis values, in axis order.
    pub values: Vec<toml::Value>,
    /// Seed.
    pub seed: u64,
}

/// A loaded sweep.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The sweep file, as an absolute path (so a run's manifest names the same base scenario
    /// wherever the sweep was started from).
    pub path: PathBuf,
    /// What it says.
    pub file: SweepFile,
    /// Base scenario path.
    pub base: PathBuf,
    /// Base scenario text.
    pub base_text: String,
    /// With `recording`: the recording (absolute) and the robot files it carries, by model.
    pub recording: Option<(PathBuf, BTreeMap<String, String>)>,
    /// All runs in index order.
    pub runs: Vec<SweepRun>,
}

/// Metric columns of a planning sweep's `runs.csv`, in order.
pub const METRICS: [&str; 14] = [
    "vertices",
    "parent_vertices",
    "following",
    "mapping_timesteps",
    "coordination_timesteps",
    "total_timesteps",
    "coverage",
    "uncoverable",
    "unreached",
    "robot_steps",
    "coverable_coverage",
    "skipped_stages",
    "revisited",
    "following_out_of_reach",
];

fn metric_values(m: &CoverageMetrics) -> Vec<f64> {
    vec![
        m.vertices as f64,
        m.parent_vertices as f64,
        m.following as f64,
        m.mapping_timesteps as f64,
        m.coordination_timesteps as f64,
        m.total_timesteps as f64,
        m.coverage,
        m.uncoverable as f64,
        m.unreached as f64,
        m.robot_steps as f64,
        m.coverable_coverage,
        m.skipped_stages as f64,
        m.revisited as f64,
        m.following_out_of_reach as f64,
    ]
}

fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Reads a sweep file, checks it and expands its runs; every combination's scenario is
/// loaded and validated once (first seed) before anything runs.
pub fn load_sweep(path: &Path) -> Result<Sweep, SweepError> {
    let bytes = read(path)?;
    let path = std::fs::canonicalize(path).map_err(FileError::at(path))?;
    let path = path.as_path();
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let file: SweepFile = toml::from_str(&text).map_err(|e| SweepError::Parse {
        path: path.to_path_buf(),
        line: e.span().map(|s| text[..s.start].matches('\n').count() + 1),
        message: e.message().to_string(),
    })?;
    let field = |field: &str, value: String, allowed: &str| SweepError::Field {
        path: path.to_path_buf(),
        field: field.to_string(),
        value,
        allowed: allowed.to_string(),
    };
    if file.schema_version != 1 {
        return Err(field(
            "schema_version",
            file.schema_version.to_string(),
            "schema_version = 1",
        ));
    }
    if file.seeds == 0 {
        return Err(field("seeds", "0".into(), "at least 1 seed"));
    }
    if file.seeds > 100_000 || file.first_seed.checked_add(file.seeds).is_none() {
        return Err(field(
            "seeds",
            file.seeds.to_string(),
            "at most 100000 seeds, first_seed + seeds below 2^64",
        ));
    }
    check_kind_fields(&file, &field)?;
    for (k, v) in &file.axes {
        if v.is_empty() {
            return Err(field(
                &format!("axes.\"{k}\""),
                "[]".into(),
                "at least one value",
            ));
        }
        if k.split('.').any(str::is_empty) {
            return Err(field(
                &format!("axes.\"{k}\""),
                format!("{:?}", k),
                "a dotted path of non-empty names (scenario field, robots.<robot>.<field> or models.<model>.<field>)",
            ));
        }
    }
    let combos: usize = file.axes.values().map(Vec::len).product();
    let total = combos.saturating_mul(file.seeds as usize);
    if total > 1_000_000 {
        return Err(field(
            "axes",
            format!("{combos} combinations x {} seeds", file.seeds),
            "at most 1000000 runs in one sweep",
        ));
    }
    let mut file = file;
    let (base, base_text, recording) = match &file.recording {
        Some(rec) => {
            let at = path.parent().unwrap_or(Path::new(".")).join(rec);
            let opened = hetsim_io::McapRecording::open(&at).map_err(|e| {
                field(
                    "recording",
                    format!("\"{rec}\""),
                    &format!("a recording `hetsim run SCENARIO --record FILE` wrote ({e})"),
                )
            })?;
            let run = opened.run;
            // The recording's seed; its duration unless the sweep asks for less.
            file.first_seed = run.seed;
            file.duration_secs = Some(
                file.duration_secs
                    .map_or(run.duration_secs, |d| d.min(run.duration_secs)),
            );
            (
                run.scenario_path,
                run.scenario_text,
                Some((at, run.robot_files)),
            )
        }
        None => {
            let base = path.parent().unwrap_or(Path::new(".")).join(&file.base);
            let base_text = std::fs::read_to_string(&base).map_err(|e| {
                field(
                    "base",
                    format!("\"{}\"", file.base),
                    &format!("a readable scenario file ({}: {e})", base.display()),
                )
            })?;
            (base, base_text, None)
        }
    };
    let mut combos: Vec<Vec<toml::Value>> = vec![Vec::new()];
    for values in file.axes.values() {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                values
                    .iter()
                    .map(move |v| [c.clone(), vec![v.clone()]].concat())
            })
            .collect();
    }
    let mut runs = Vec::with_capacity(total);
    for values in combos {
        for seed in file.first_seed..file.first_seed + file.seeds {
            runs.push(SweepRun {
                index: runs.len(),
                values: values.clone(),
                seed,
            });
        }
    }
    let sweep = Sweep {
        path: path.to_path_buf(),
        file,
        base,
        base_text,
        recording,
        runs,
    };
    // Every combination must make a valid scenario: check the first seed of each now.
    for run in sweep
        .runs
        .iter()
        .filter(|r| r.seed == sweep.file.first_seed)
    {
        sweep.scenario(run)?;
    }
    Ok(sweep)
}

/// The fields only one kind takes.
fn check_kind_fields(
    file: &SweepFile,
    field: &dyn Fn(&str, String, &str) -> SweepError,
) -> Result<(), SweepError> {
    if file.recording.is_some() {
        let refused = [
            (
                "kind",
                file.kind != SweepKind::Run,
                "kind = \"run\" with a recording",
            ),
            (
                "base",
                !file.base.is_empty(),
                "no base with a recording (it carries its scenario)",
            ),
            (
                "seeds",
                file.seeds != 1,
                "seeds = 1 with a recording (its seed)",
            ),
            (
                "first_seed",
                file.first_seed != 0,
                "no first_seed with a recording (its seed)",
            ),
            (
                "render",
                file.render.is_some(),
                "no render with a recording (replay renders nothing)",
            ),
        ];
        if let Some((name, _, allowed)) = refused.iter().find(|(_, bad, _)| *bad) {
            return Err(field(name, "(set)".into(), allowed));
        }
    } else if file.base.is_empty() {
        return Err(field(
            "base",
            "(missing)".into(),
            "a scenario file, relative to the sweep file",
        ));
    }
    match file.kind {
        SweepKind::Plan => {
            let only_run = [
                ("metrics", !file.metrics.is_empty()),
                ("duration_secs", file.duration_secs.is_some()),
                ("render", file.render.is_some()),
            ];
            if let Some((name, _)) = only_run.iter().find(|(_, set)| *set) {
                return Err(field(
                    name,
                    "(set)".into(),
                    "only with kind = \"run\" (a planning sweep's metrics are the planner's)",
                ));
            }
        }
        SweepKind::Run => {
            if file.metrics.is_empty() {
                return Err(field(
                    "metrics",
                    "[]".into(),
                    "at least one dotted path into a run's metrics.json, e.g. \"estimates.vo/dala.ate_m\"",
                ));
            }
            for (i, m) in file.metrics.iter().enumerate() {
                if m.split('.').any(str::is_empty) {
                    return Err(field(
                        &format!("metrics[{i}]"),
                        format!("{m:?}"),
                        "a dotted path of non-empty keys into metrics.json",
                    ));
                }
                if file.metrics[..i].contains(m) {
                    return Err(field(
                        &format!("metrics[{i}]"),
                        format!("{m:?}"),
                        "each metric once",
                    ));
                }
            }
            if let Some(d) = file.duration_secs {
                if !(d.is_finite() && d > 0.0 && d <= 86_400.0) {
                    return Err(field(
                        "duration_secs",
                        d.to_string(),
                        "a number of seconds in (0, 86400]",
                    ));
                }
            }
        }
    }
    Ok(())
}

impl Sweep {
    /// The axis names, in order.
    pub fn axes(&self) -> Vec<String> {
        self.file.axes.keys().cloned().collect()
    }

    /// The metric columns: the planner's for `plan`, the sweep file's for `run`.
    pub fn metrics(&self) -> Vec<String> {
        match self.file.kind {
            SweepKind::Plan => METRICS.iter().map(|s| s.to_string()).collect(),
            SweepKind::Run => self.file.metrics.clone(),
        }
    }

    /// `axis=value, ...` of a run, and its seed.
    pub fn describe(&self, run: &SweepRun) -> String {
        let mut parts: Vec<String> = self
            .axes()
            .iter()
            .zip(&run.values)
            .map(|(k, v)| format!("{k}={}", value_text(v)))
            .collect();
        parts.push(format!("seed={}", run.seed));
        parts.join(", ")
    }

    /// A run's failure, with the sweep file and the run's values.
    pub fn run_error(&self, run: &SweepRun, message: String) -> SweepError {
        SweepError::Run {
            path: self.path.clone(),
            index: run.index,
            values: self.describe(run),
            message,
        }
    }

    /// The run's scenario, loaded and validated (with the sweep's `duration_secs`).
    pub fn scenario(&self, run: &SweepRun) -> Result<hetsim_scene::Scenario, SweepError> {
        let text = self.scenario_text(run)?;
        load_scenario_text(
            &self.base,
            text,
            &LoadOptions {
                robot_files: self.recording.as_ref().map(|(_, files)| files.clone()),
                seed: Some(run.seed),
                duration_secs: self.file.duration_secs,
            },
        )
        .map_err(|e| self.run_error(run, e.to_string()))
    }

    /// Where a whole run's results folder is kept: `runs/<i>` under the sweep's folder.
    pub fn run_dir(out: &Path, run: &SweepRun) -> PathBuf {
        out.join("runs").join(format!("{:06}", run.index))
    }
}
