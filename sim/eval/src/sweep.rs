//! Monte Carlo sweeps over scenario parameters, resumable and shardable.
//!
//! A sweep file names a base scenario, parameter axes (dotted paths to any scenario field)
//! and a number of seeds. Runs are the product of the axes (in key order, values as listed)
//! and the seeds; run `i` always means the same combination. Each finished run writes one
//! row file `rows/<i>.csv` atomically, so an interrupted sweep resumes without redoing
//! finished runs and never leaves a half-written row; `runs.csv`, `summary.csv` and
//! `summary.md` (and `boxplot.png` when the sweep varies `coverage.children`) are rebuilt
//! from the row files in run order, so they do not depend on the
//! number of jobs, on scheduling, or on sharding (`merge` joins shards into the same files).

use crate::coverage::{plan_scenario, CoverageMetrics};
use hetsim_core::files::{write_atomic, FileError};
use hetsim_scene::{load_scenario_text, LoadOptions};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

mod summary;
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
    /// One run's scenario is refused or its plan failed.
    #[error("{}: run {index} ({values}): {message}", path.display())]
    Run {
        /// The sweep file.
        path: PathBuf,
        /// The run.
        index: usize,
        /// Its axis values.
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

/// A sweep file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepFile {
    /// Must be 1.
    pub schema_version: i64,
    /// Name of the sweep.
    pub name: String,
    /// Base scenario, relative to the sweep file's folder.
    pub base: String,
    /// Seeds per combination: `first_seed .. first_seed + seeds`.
    pub seeds: u64,
    /// First seed.
    #[serde(default)]
    pub first_seed: u64,
    /// Dotted scenario field -> values.
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
    /// The sweep file.
    pub path: PathBuf,
    /// What it says.
    pub file: SweepFile,
    /// Base scenario path.
    pub base: PathBuf,
    /// Base scenario text.
    pub base_text: String,
    /// All runs in index order.
    pub runs: Vec<SweepRun>,
}

/// Metric columns of `runs.csv`, in order.
pub const METRICS: [&str; 10] = [
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
];

fn metric_values(m: &CoverageMetrics) -> [f64; 10] {
    [
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
    ]
}

fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Reads a sweep file and expands its runs.
pub fn load_sweep(path: &Path) -> Result<Sweep, SweepError> {
    let text = String::from_utf8_lossy(&read(path)?).into_owned();
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
    for (k, v) in &file.axes {
        if v.is_empty() {
            return Err(field(
                &format!("axes.\"{k}\""),
                "[]".into(),
                "at least one value",
            ));
        }
    }
    let base = path.parent().unwrap_or(Path::new(".")).join(&file.base);
    let base_text = std::fs::read_to_string(&base).map_err(|e| {
        field(
            "base",
            format!("\"{}\"", file.base),
            &format!("a readable scenario file ({}: {e})", base.display()),
        )
    })?;
    let axes: Vec<&Vec<toml::Value>> = file.axes.values().collect();
    let mut combos: Vec<Vec<toml::Value>> = vec![Vec::new()];
    for values in axes {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                values
                    .iter()
                    .map(move |v| [c.clone(), vec![v.clone()]].concat())
            })
            .collect();
    }
    let mut runs = Vec::new();
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

impl Sweep {
    /// The axis names, in order.
    pub fn axes(&self) -> Vec<String> {
        self.file.axes.keys().cloned().collect()
    }

    /// `axis=value, ...` of a run.
    pub fn describe(&self, run: &SweepRun) -> String {
        self.axes()
            .iter()
            .zip(&run.values)
            .map(|(k, v)| format!("{k}={}", value_text(v)))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// A run's failure, with the sweep file and the run's values.
    fn run_error(&self, run: &SweepRun, message: String) -> SweepError {
        SweepError::Run {
            path: self.path.clone(),
            index: run.index,
            values: self.describe(run),
            message,
        }
    }

    /// The run's scenario, loaded and validated.
    pub fn scenario(&self, run: &SweepRun) -> Result<hetsim_scene::Scenario, SweepError> {
        let text = self.scenario_text(run)?;
        load_scenario_text(
            &self.base,
            text,
            &LoadOptions {
                seed: Some(run.seed),
                duration_secs: None,
            },
        )
        .map_err(|e| self.run_error(run, e.to_string()))
    }

    /// The base scenario with a run's axis values written in.
    pub fn scenario_text(&self, run: &SweepRun) -> Result<String, SweepError> {
        let fail = |message: String| self.run_error(run, message);
        let mut table: toml::Table =
            toml::from_str(&self.base_text).map_err(|e| fail(e.to_string()))?;
        for (key, value) in self.axes().iter().zip(&run.values) {
            let mut segments: Vec<&str> = key.split('.').collect();
            let last = segments
                .pop()
                .ok_or_else(|| fail("empty axis name".into()))?;
            let mut at = &mut table;
            for seg in segments {
                at = at
                    .entry(seg.to_string())
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                    .as_table_mut()
                    .ok_or_else(|| {
                        fail(format!(
                            "axis {key}: {seg} is not a table in the base scenario"
                        ))
                    })?;
            }
            at.insert(last.to_string(), value.clone());
        }
        toml::to_string(&table).map_err(|e| fail(e.to_string()))
    }

    /// Runs one run: the coverage plan of the run's scenario.
    pub fn run_one(&self, run: &SweepRun) -> Result<CoverageMetrics, SweepError> {
        let scenario = self.scenario(run)?;
        let (_, _, plan) =
            plan_scenario(&scenario).map_err(|e| self.run_error(run, e.to_string()))?;
        Ok(CoverageMetrics::of(&plan))
    }

    /// A run's row: index, axis values, seed, metrics.
    fn row(&self, run: &SweepRun, m: &CoverageMetrics) -> Vec<String> {
        let mut fields = vec![run.index.to_string()];
        fields.extend(run.values.iter().map(value_text));
        fields.push(run.seed.to_string());
        fields.extend(metric_values(m).iter().map(|v| format!("{v}")));
        fields
    }

    /// The header of `runs.csv`.
    fn header(&self) -> Vec<String> {
        let mut fields = vec!["run".to_string()];
        fields.extend(self.axes());
        fields.push("seed".to_string());
        fields.extend(METRICS.iter().map(|s| s.to_string()));
        fields
    }
}

/// CSV text of some records.
fn csv_text<I, R>(records: I) -> Vec<u8>
where
    I: IntoIterator<Item = R>,
    R: IntoIterator,
    R::Item: AsRef<[u8]>,
{
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in records {
        w.write_record(r).expect("CSV writes to memory");
    }
    w.into_inner().expect("CSV flushes to memory")
}

/// The one record of a row file, checked against the sweep's header.
fn read_row(path: &Path, header: &[String]) -> Result<Vec<String>, SweepError> {
    let bytes = read(path)?;
    let row_error = |row: usize, message: String| SweepError::Row {
        path: path.to_path_buf(),
        row,
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(bytes.as_slice());
    let mut records = reader.records();
    let record = records
        .next()
        .ok_or_else(|| row_error(1, "empty row file".into()))?
        .map_err(|e| row_error(1, e.to_string()))?;
    if records.next().is_some() {
        return Err(row_error(2, "a row file holds one record".into()));
    }
    if record.len() != header.len() {
        return Err(row_error(
            1,
            format!(
                "{} fields where the sweep has {} columns ({})",
                record.len(),
                header.len(),
                header.join(",")
            ),
        ));
    }
    Ok(record.iter().map(str::to_string).collect())
}

/// Which runs a shard `k` of `n` (1-based) owns.
pub fn in_shard(index: usize, shard: (usize, usize)) -> bool {
    index % shard.1 == shard.0 - 1
}

/// Runs the sweep's pending runs of a shard in parallel on `jobs` threads, writing row files
/// under `out/rows/`, then rebuilds the summary files from every row present. `progress`
/// is called with (finished, total) after each run.
pub fn run_sweep(
    sweep: &Sweep,
    out: &Path,
    jobs: usize,
    shard: (usize, usize),
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SweepSummary, SweepError> {
    let rows = out.join("rows");
    write_atomic(&out.join("sweep.toml"), &read(&sweep.path)?)?;
    let mine: Vec<&SweepRun> = sweep
        .runs
        .iter()
        .filter(|r| in_shard(r.index, shard))
        .collect();
    let pending: Vec<&SweepRun> = mine
        .iter()
        .copied()
        .filter(|r| !rows.join(format!("{:06}.csv", r.index)).is_file())
        .collect();
    let done = AtomicUsize::new(mine.len() - pending.len());
    progress(done.load(Ordering::Relaxed), mine.len());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()
        .map_err(|e| SweepError::Threads {
            jobs,
            message: e.to_string(),
        })?;
    let results: Vec<Result<(), SweepError>> = pool.install(|| {
        use rayon::prelude::*;
        pending
            .par_iter()
            .map(|run| {
                let m = sweep.run_one(run)?;
                write_atomic(
                    &rows.join(format!("{:06}.csv", run.index)),
                    &csv_text([sweep.row(run, &m)]),
                )?;
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, mine.len());
                Ok(())
            })
            .collect()
    });
    results.into_iter().collect::<Result<Vec<()>, _>>()?;
    summarize(sweep, out)
}

/// Copies the row files of shard folders into `out` and rebuilds the summary there.
pub fn merge(sweep: &Sweep, out: &Path, shards: &[PathBuf]) -> Result<SweepSummary, SweepError> {
    let rows = out.join("rows");
    for dir in shards {
        let from = dir.join("rows");
        let entries = std::fs::read_dir(&from).map_err(FileError::at(&from))?;
        let mut names: Vec<PathBuf> = entries
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "csv"))
            .collect();
        names.sort();
        for p in names {
            write_atomic(
                &rows.join(p.file_name().expect("row files have names")),
                &read(&p)?,
            )?;
        }
    }
    write_atomic(&out.join("sweep.toml"), &read(&sweep.path)?)?;
    summarize(sweep, out)
}
