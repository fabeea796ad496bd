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
use hetsim_scene::{load_scenario_text, LoadOptions};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

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
pub fn load_sweep(path: &Path) -> Result<Sweep, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let file: SweepFile = toml::from_str(&text).map_err(|e| {
        let line = e.span().map(|s| text[..s.start].matches('\n').count() + 1);
        format!(
            "{}:{}: {}",
            path.display(),
            line.map_or("?".into(), |l| l.to_string()),
            e.message()
        )
    })?;
    if file.schema_version != 1 {
        return Err(format!(
            "{}: field `schema_version` = {}: schema_version = 1",
            path.display(),
            file.schema_version
        ));
    }
    if file.seeds == 0 {
        return Err(format!(
            "{}: field `seeds` = 0: at least 1 seed",
            path.display()
        ));
    }
    for (k, v) in &file.axes {
        if v.is_empty() {
            return Err(format!(
                "{}: field `axes.\"{k}\"` = []: at least one value",
                path.display()
            ));
        }
    }
    let base = path.parent().unwrap_or(Path::new(".")).join(&file.base);
    let base_text = std::fs::read_to_string(&base).map_err(|e| {
        format!(
            "{}: field `base` = \"{}\": cannot read {}: {e}",
            path.display(),
            file.base,
            base.display()
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
        sweep
            .scenario_text(run)
            .and_then(|t| {
                load_scenario_text(
                    &sweep.base,
                    t,
                    &LoadOptions {
                        seed: Some(run.seed),
                        duration_secs: None,
                    },
                )
                .map(|_| ())
                .map_err(|e| e.to_string())
            })
            .map_err(|e| {
                format!(
                    "{}: run {} ({}): {e}",
                    path.display(),
                    run.index,
                    sweep.describe(run)
                )
            })?;
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

    /// The base scenario with a run's axis values written in.
    pub fn scenario_text(&self, run: &SweepRun) -> Result<String, String> {
        let mut table: toml::Table = toml::from_str(&self.base_text).map_err(|e| e.to_string())?;
        for (key, value) in self.axes().iter().zip(&run.values) {
            let mut segments: Vec<&str> = key.split('.').collect();
            let last = segments.pop().ok_or("empty axis name")?;
            let mut at = &mut table;
            for seg in segments {
                at = at
                    .entry(seg.to_string())
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()))
                    .as_table_mut()
                    .ok_or(format!(
                        "axis {key}: {seg} is not a table in the base scenario"
                    ))?;
            }
            at.insert(last.to_string(), value.clone());
        }
        toml::to_string(&table).map_err(|e| e.to_string())
    }

    /// Runs one run: the coverage plan of the run's scenario.
    pub fn run_one(&self, run: &SweepRun) -> Result<CoverageMetrics, String> {
        let text = self.scenario_text(run)?;
        let scenario = load_scenario_text(
            &self.base,
            text,
            &LoadOptions {
                seed: Some(run.seed),
                duration_secs: None,
            },
        )
        .map_err(|e| e.to_string())?;
        let (_, _, plan) = plan_scenario(&scenario)?;
        Ok(CoverageMetrics::of(&plan))
    }

    fn row(&self, run: &SweepRun, m: &CoverageMetrics) -> String {
        let mut fields = vec![run.index.to_string()];
        fields.extend(run.values.iter().map(value_text));
        fields.push(run.seed.to_string());
        fields.extend(metric_values(m).iter().map(|v| format!("{v}")));
        fields.join(",") + "\n"
    }

    fn header(&self) -> String {
        let mut fields = vec!["run".to_string()];
        fields.extend(self.axes());
        fields.push("seed".to_string());
        fields.extend(METRICS.iter().map(|s| s.to_string()));
        fields.join(",") + "\n"
    }
}

fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    let tmp = path.with_extension(format!("tmp-{}", std::process::id()));
    std::fs::write(&tmp, bytes).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
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
) -> Result<SweepSummary, String> {
    let rows = out.join("rows");
    std::fs::create_dir_all(&rows).map_err(|e| format!("{}: {e}", rows.display()))?;
    write_atomic(
        &out.join("sweep.toml"),
        std::fs::read(&sweep.path)
            .map_err(|e| e.to_string())?
            .as_slice(),
    )?;
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
        .map_err(|e| e.to_string())?;
    let results: Vec<Result<(), String>> = pool.install(|| {
        use rayon::prelude::*;
        pending
            .par_iter()
            .map(|run| {
                let m = sweep
                    .run_one(run)
                    .map_err(|e| format!("run {} ({}): {e}", run.index, sweep.describe(run)))?;
                write_atomic(
                    &rows.join(format!("{:06}.csv", run.index)),
                    sweep.row(run, &m).as_bytes(),
                )?;
                progress(done.fetch_add(1, Ordering::Relaxed) + 1, mine.len());
                Ok(())
            })
            .collect()
    });
    results.into_iter().collect::<Result<Vec<()>, String>>()?;
    summarize(sweep, out)
}

/// Copies the row files of shard folders into `out` and rebuilds the summary there.
pub fn merge(sweep: &Sweep, out: &Path, shards: &[PathBuf]) -> Result<SweepSummary, String> {
    let rows = out.join("rows");
    std::fs::create_dir_all(&rows).map_err(|e| format!("{}: {e}", rows.display()))?;
    for dir in shards {
        let entries = std::fs::read_dir(dir.join("rows"))
            .map_err(|e| format!("{}: {e}", dir.join("rows").display()))?;
        let mut names: Vec<PathBuf> = entries
            .filter_map(|e| e.ok())
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "csv"))
            .collect();
        names.sort();
        for p in names {
            let bytes = std::fs::read(&p).map_err(|e| format!("{}: {e}", p.display()))?;
            write_atomic(
                &rows.join(p.file_name().expect("row files have names")),
                &bytes,
            )?;
        }
    }
    write_atomic(
        &out.join("sweep.toml"),
        std::fs::read(&sweep.path)
            .map_err(|e| e.to_string())?
            .as_slice(),
    )?;
    summarize(sweep, out)
}

/// One metric over the seeds of a cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one sample).
    pub std: f64,
    /// The values, in run order.
    pub samples: Vec<f64>,
}

/// The runs of one combination of axis values.
#[derive(Clone, Debug, PartialEq)]
pub struct SummaryCell {
    /// Axis values, in axis order.
    pub values: Vec<String>,
    /// One [`Stat`] per entry of [`METRICS`].
    pub stats: Vec<Stat>,
}

impl SummaryCell {
    /// The statistics of a metric by name.
    pub fn stat(&self, metric: &str) -> &Stat {
        &self.stats[METRICS
            .iter()
            .position(|m| *m == metric)
            .expect("a metric of METRICS")]
    }
}

/// Mean and sample standard deviation of each metric per combination of axis values.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepSummary {
    /// Rows present.
    pub finished: usize,
    /// Runs in the sweep.
    pub total: usize,
    /// Cells in combination order.
    pub cells: Vec<SummaryCell>,
}

/// Rebuilds `runs.csv`, `summary.csv` and `summary.md` from the row files.
pub fn summarize(sweep: &Sweep, out: &Path) -> Result<SweepSummary, String> {
    let rows_dir = out.join("rows");
    let mut runs_csv = sweep.header();
    let mut cells: Vec<(Vec<String>, Vec<Vec<f64>>)> = Vec::new();
    let mut finished = 0;
    for run in &sweep.runs {
        let path = rows_dir.join(format!("{:06}.csv", run.index));
        let Ok(line) = std::fs::read_to_string(&path) else {
            continue;
        };
        finished += 1;
        runs_csv.push_str(&line);
        let fields: Vec<&str> = line.trim_end().split(',').collect();
        let skip = 2 + sweep.axes().len();
        let values: Vec<f64> = fields[skip..]
            .iter()
            .map(|f| {
                f.parse::<f64>()
                    .map_err(|e| format!("{}: {e}", path.display()))
            })
            .collect::<Result<_, _>>()?;
        let key: Vec<String> = run.values.iter().map(value_text).collect();
        match cells.iter_mut().find(|(k, _)| *k == key) {
            Some((_, cols)) => cols.iter_mut().zip(values).for_each(|(c, v)| c.push(v)),
            None => cells.push((key, values.into_iter().map(|v| vec![v]).collect())),
        }
    }
    let stats: Vec<SummaryCell> = cells
        .into_iter()
        .map(|(values, cols)| SummaryCell {
            values,
            stats: cols
                .into_iter()
                .map(|samples| {
                    let n = samples.len() as f64;
                    let mean = samples.iter().sum::<f64>() / n;
                    let std = if samples.len() > 1 {
                        (samples.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
                    } else {
                        0.0
                    };
                    Stat { mean, std, samples }
                })
                .collect(),
        })
        .collect();
    let axes = sweep.axes();
    let mut summary_csv = axes.join(",") + ",runs";
    for m in METRICS {
        summary_csv.push_str(&format!(",{m}_mean,{m}_std"));
    }
    summary_csv.push('\n');
    let mut md = format!("# Sweep `{}`\n\nBase scenario `{}`, {} seeds per cell, {} of {} runs finished. Mean ± sample standard deviation.\n\n", sweep.file.name, sweep.file.base, sweep.file.seeds, finished, sweep.runs.len());
    let shown = [
        "parent_vertices",
        "following",
        "mapping_timesteps",
        "coordination_timesteps",
        "total_timesteps",
        "coverage",
    ];
    md.push_str(&format!(
        "| {} | runs | {} |\n",
        axes.join(" | "),
        shown.join(" | ")
    ));
    md.push_str(&format!(
        "|{}\n",
        "---|".repeat(axes.len() + 1 + shown.len())
    ));
    for cell in &stats {
        let runs = cell.stats[0].samples.len();
        summary_csv.push_str(&format!("{},{runs}", cell.values.join(",")));
        for st in &cell.stats {
            summary_csv.push_str(&format!(",{},{}", st.mean, st.std));
        }
        summary_csv.push('\n');
        let shown_cells: Vec<String> = shown
            .iter()
            .map(|m| {
                let st = cell.stat(m);
                if *m == "coverage" {
                    format!("{:.4} ± {:.4}", st.mean, st.std)
                } else {
                    format!("{:.1} ± {:.1}", st.mean, st.std)
                }
            })
            .collect();
        md.push_str(&format!(
            "| {} | {runs} | {} |\n",
            cell.values.join(" | "),
            shown_cells.join(" | ")
        ));
    }
    if let Some(png) = boxplot(sweep, &stats) {
        let tmp = out.join("boxplot.png.tmp");
        png.save_with_format(&tmp, image::ImageFormat::Png)
            .map_err(|e| format!("{}: {e}", tmp.display()))?;
        std::fs::rename(&tmp, out.join("boxplot.png"))
            .map_err(|e| format!("{}: {e}", out.display()))?;
    }
    write_atomic(&out.join("runs.csv"), runs_csv.as_bytes())?;
    write_atomic(&out.join("summary.csv"), summary_csv.as_bytes())?;
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    Ok(SweepSummary {
        finished,
        total: sweep.runs.len(),
        cells: stats,
    })
}

/// Box plots in the style of Figs. 3 and 4 when the sweep varies `coverage.children`: one
/// panel per combination of the other axes, one stacked box per number of children.
fn boxplot(sweep: &Sweep, cells: &[SummaryCell]) -> Option<image::RgbImage> {
    let axes = sweep.axes();
    let kids = axes.iter().position(|a| a == "coverage.children")?;
    let mut panels: Vec<(String, Vec<crate::plot::StackedBox>)> = Vec::new();
    for cell in cells {
        let title: Vec<&str> = cell
            .values
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != kids)
            .map(|(_, v)| v.as_str())
            .collect();
        let title = title.join(" ");
        let b = crate::plot::StackedBox {
            label: cell.values[kids].clone(),
            mapping: cell.stat("mapping_timesteps").samples.clone(),
            coordination: cell.stat("coordination_timesteps").samples.clone(),
        };
        match panels.iter_mut().find(|(t, _)| *t == title) {
            Some((_, boxes)) => boxes.push(b),
            None => panels.push((title, vec![b])),
        }
    }
    Some(crate::plot::stacked_boxes(&panels))
}
