//! Running a sweep's runs (in parallel, resumable, one shard of it) and merging shards.

use super::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// What one run of a sweep gives: the metric values in the sweep's metric order, and for a
/// whole run its digest.
#[derive(Clone, Debug, PartialEq)]
pub struct RunResult {
    /// The run's digest (whole runs only).
    pub digest: Option<String>,
    /// One value per metric column; NaN where the run has none (a `null` in metrics.json).
    pub values: Vec<f64>,
}

/// Runs one run of a sweep: given the run and its folder (`runs/<i>` under the sweep's
/// output, for whole runs), returns its metrics. Called from several threads at once.
pub type Runner<'a> = dyn Fn(&Sweep, &SweepRun, &Path) -> Result<RunResult, SweepError> + Sync + 'a;

/// The runner of a planning sweep: the coverage plan of the run's scenario.
pub fn plan_runner(sweep: &Sweep, run: &SweepRun, _dir: &Path) -> Result<RunResult, SweepError> {
    let scenario = sweep.scenario(run)?;
    let (_, _, plan) = crate::coverage::plan_scenario(&scenario)
        .map_err(|e| sweep.run_error(run, e.to_string()))?;
    Ok(RunResult {
        digest: None,
        values: metric_values(&CoverageMetrics::of(&plan)),
    })
}

/// The metrics of a whole run whose results folder is `dir`: each of the sweep's dotted
/// paths looked up in its `metrics.json`, and the digest from its `manifest.json`.
pub fn metrics_of_run(sweep: &Sweep, run: &SweepRun, dir: &Path) -> Result<RunResult, SweepError> {
    let json = |name: &str| -> Result<serde_json::Value, SweepError> {
        let path = dir.join(name);
        serde_json::from_slice(&read(&path)?)
            .map_err(|e| sweep.run_error(run, format!("{}: {e}", path.display())))
    };
    let metrics = json("metrics.json")?;
    let digest = json("manifest.json")?["digest"]
        .as_str()
        .map(str::to_string)
        .ok_or_else(|| {
            sweep.run_error(
                run,
                format!("{}: no digest", dir.join("manifest.json").display()),
            )
        })?;
    let values = sweep
        .file
        .metrics
        .iter()
        .map(|path| metric_at(&metrics, path).map_err(|m| sweep.run_error(run, m.to_string())))
        .collect::<Result<_, _>>()?;
    Ok(RunResult {
        digest: Some(digest),
        values,
    })
}

/// Why a dotted path into `metrics.json` gives no number.
#[derive(Debug, thiserror::Error)]
pub enum MetricPathError {
    /// A key or index the document does not have at that point.
    #[error("metric {path:?}: no {key:?} in {here} ({offered})")]
    Missing {
        /// The dotted path asked for.
        path: String,
        /// The key not found.
        key: String,
        /// Where it was looked for (`metrics.json` or the path walked so far).
        here: String,
        /// What is there instead.
        offered: String,
    },
    /// The path ends at a number JSON holds but f64 cannot.
    #[error("metric {path:?}: {number} is not a number")]
    NotF64 {
        /// The dotted path.
        path: String,
        /// The number as written.
        number: String,
    },
    /// The path ends at a table, a list or text.
    #[error("metric {path:?} is {found}, not a number")]
    NotANumber {
        /// The dotted path.
        path: String,
        /// "a table", "a list" or "text".
        found: &'static str,
    },
}

/// The number at a dotted path of a JSON document; `null` reads as NaN (a figure the run
/// does not have, such as the error after an event that never fired).
fn metric_at(doc: &serde_json::Value, path: &str) -> Result<f64, MetricPathError> {
    let mut at = doc;
    let mut walked: Vec<&str> = Vec::new();
    for key in path.split('.') {
        let next = match at {
            serde_json::Value::Object(map) => map.get(key),
            serde_json::Value::Array(items) => key.parse::<usize>().ok().and_then(|i| items.get(i)),
            _ => None,
        };
        at = next.ok_or_else(|| {
            let here = if walked.is_empty() {
                "metrics.json".to_string()
            } else {
                walked.join(".")
            };
            let offered = match at {
                serde_json::Value::Object(map) => format!(
                    "keys there: {}",
                    map.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
                serde_json::Value::Array(items) => {
                    format!("a list of {} there (index 0..{})", items.len(), items.len())
                }
                other => format!("{here} is {other}, not a table"),
            };
            MetricPathError::Missing {
                path: path.to_string(),
                key: key.to_string(),
                here,
                offered,
            }
        })?;
        walked.push(key);
    }
    match at {
        serde_json::Value::Number(n) => n.as_f64().ok_or_else(|| MetricPathError::NotF64 {
            path: path.to_string(),
            number: n.to_string(),
        }),
        serde_json::Value::Bool(b) => Ok(if *b { 1.0 } else { 0.0 }),
        serde_json::Value::Null => Ok(f64::NAN),
        other => Err(MetricPathError::NotANumber {
            path: path.to_string(),
            found: match other {
                serde_json::Value::Object(_) => "a table",
                serde_json::Value::Array(_) => "a list",
                _ => "text",
            },
        }),
    }
}

impl Sweep {
    /// Columns before the metrics: run, the axes, seed, and for whole runs the digest.
    pub(super) fn id_columns(&self) -> usize {
        2 + self.file.axes.len() + usize::from(self.file.kind == SweepKind::Run)
    }

    /// A run's row: index, axis values, seed, (digest), metrics.
    fn row(&self, run: &SweepRun, r: &RunResult) -> Vec<String> {
        let mut fields = vec![run.index.to_string()];
        fields.extend(run.values.iter().map(value_text));
        fields.push(run.seed.to_string());
        if self.file.kind == SweepKind::Run {
            fields.push(r.digest.clone().unwrap_or_default());
        }
        fields.extend(r.values.iter().map(|v| format!("{v}")));
        fields
    }

    /// The header of `runs.csv`.
    pub(super) fn header(&self) -> Vec<String> {
        let mut fields = vec!["run".to_string()];
        fields.extend(self.axes());
        fields.push("seed".to_string());
        if self.file.kind == SweepKind::Run {
            fields.push("digest".to_string());
        }
        fields.extend(self.metrics());
        fields
    }
}

/// CSV text of some records.
pub(super) fn csv_text<I, R>(records: I) -> Vec<u8>
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
pub(super) fn read_row(path: &Path, header: &[String]) -> Result<Vec<String>, SweepError> {
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

fn row_path(out: &Path, run: &SweepRun) -> PathBuf {
    out.join("rows").join(format!("{:06}.csv", run.index))
}

impl Sweep {
    /// What makes two runs of this sweep the same run: hetsim's version and build (the
    /// executable's SHA-256: a rebuilt planner makes other rows), the kind, the base
    /// scenario's and every robot file's contents, the axes, seeds, metrics, and the duration
    /// and rendering as resolved (an omitted `render` is `true`, an omitted duration the
    /// scenario's). Written to the output folder as `identity.json`; a folder (or shard)
    /// with another identity is never resumed into or merged, so no row of another sweep is
    /// ever reported under this sweep's labels. Contents, not paths: shards that one
    /// executable made from checkouts in other folders merge. Compared as the bytes written.
    pub fn identity(&self) -> Result<Vec<u8>, SweepError> {
        use sha2::{Digest, Sha256};
        let hex = |bytes: &[u8]| -> String {
            Sha256::digest(bytes)
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect()
        };
        // The robot files every combination reads (an axis may switch a robot's model), by
        // content; each scenario's own entry (its text with the axis values written in) is
        // left out.
        let mut robot_files = std::collections::BTreeSet::new();
        let mut durations = std::collections::BTreeSet::new();
        for run in self.runs.iter().filter(|r| r.seed == self.file.first_seed) {
            let s = self.scenario(run)?;
            durations.insert(format!("{}", s.duration_secs));
            robot_files.extend(
                s.file_hashes
                    .iter()
                    .filter(|(path, _)| Path::new(path.as_str()) != s.path)
                    .map(|(_, h)| h.clone()),
            );
        }
        let render = match self.file.kind {
            SweepKind::Run if self.recording.is_some() => Some(false),
            SweepKind::Run => Some(self.file.render.unwrap_or(true)),
            SweepKind::Plan => None,
        };
        let identity = serde_json::json!({
            "hetsim_version": env!("CARGO_PKG_VERSION"),
            "build_sha256": crate::manifest::build_sha256(),
            "kind": format!("{:?}", self.file.kind).to_lowercase(),
            "base_scenario_sha256": hex(self.base_text.as_bytes()),
            "robot_files_sha256": robot_files,
            "axes": self.file.axes,
            "seeds": self.file.seeds,
            "first_seed": self.file.first_seed,
            "metrics": self.metrics(),
            "duration_secs": durations,
            "render": render,
            "recording_bytes": self
                .recording
                .as_ref()
                .map(|(path, _)| std::fs::metadata(path).map(|m| m.len()).unwrap_or(0)),
        });
        Ok(serde_json::to_vec_pretty(&identity).expect("JSON values serialize"))
    }

    /// Checks that `dir` holds results of this sweep (or nothing yet): its `identity.json`
    /// has the bytes of [`Sweep::identity`]. A folder with rows, runs or a `sweep.toml` but no
    /// identity is refused too (an older hetsim's, or a foreign one).
    fn check_identity(&self, dir: &Path, identity: &[u8]) -> Result<(), SweepError> {
        let path = dir.join("identity.json");
        let mismatch = |what: String| SweepError::Mismatch {
            path: dir.to_path_buf(),
            sweep: self.path.clone(),
            what,
        };
        if !path.is_file() {
            let used = |sub: &str| {
                std::fs::read_dir(dir.join(sub))
                    .map(|mut d| d.next().is_some())
                    .unwrap_or(false)
            };
            return if used("rows") || used("runs") || dir.join("sweep.toml").exists() {
                Err(mismatch(
                    "results without an identity.json (an older hetsim's, or a foreign folder)"
                        .into(),
                ))
            } else {
                Ok(())
            };
        }
        let bytes = read(&path)?;
        if bytes == identity {
            return Ok(());
        }
        // Which fields differ, with both values.
        let parse = |b: &[u8]| serde_json::from_slice::<serde_json::Value>(b).ok();
        let (theirs, ours) = (parse(&bytes), parse(identity));
        let differ: Vec<String> = match (
            theirs.as_ref().and_then(|v| v.as_object()),
            ours.as_ref().and_then(|v| v.as_object()),
        ) {
            (Some(t), Some(o)) => o
                .keys()
                .chain(t.keys())
                .collect::<std::collections::BTreeSet<_>>()
                .into_iter()
                .filter(|k| t.get(*k) != o.get(*k))
                .map(|k| {
                    let show = |v: Option<&serde_json::Value>| {
                        v.map_or("(none)".to_string(), |v| v.to_string())
                    };
                    format!(
                        "{k}: {} there, {} in this sweep",
                        show(t.get(k)),
                        show(o.get(k))
                    )
                })
                .collect(),
            _ => vec!["an unreadable identity.json".to_string()],
        };
        Err(mismatch(if differ.is_empty() {
            "its identity.json's bytes".to_string()
        } else {
            differ.join("; ")
        }))
    }
}

/// Runs a planning sweep's pending runs of a shard (see [`run_sweep_with`]). A whole-run
/// sweep needs the engine: the `hetsim` binary runs those.
pub fn run_sweep(
    sweep: &Sweep,
    out: &Path,
    jobs: usize,
    shard: (usize, usize),
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SweepSummary, SweepError> {
    if sweep.file.kind == SweepKind::Run {
        return Err(SweepError::Field {
            path: sweep.path.clone(),
            field: "kind".into(),
            value: "\"run\"".into(),
            allowed: "a whole-run sweep runs the engine: run it with `hetsim sweep`".into(),
        });
    }
    run_sweep_with(sweep, out, jobs, shard, progress, &plan_runner)
}

/// Runs the sweep's pending runs of a shard in parallel on `jobs` threads with `runner`,
/// writing row files under `out/rows/`, then rebuilds the summary files from every row
/// present. A run with a row is finished and never redone. `progress` is called with
/// (finished, total) after each run. The first failing run stops the sweep with its error
/// (runs already finished keep their rows).
pub fn run_sweep_with(
    sweep: &Sweep,
    out: &Path,
    jobs: usize,
    shard: (usize, usize),
    progress: &(dyn Fn(usize, usize) + Sync),
    runner: &Runner<'_>,
) -> Result<SweepSummary, SweepError> {
    let identity = sweep.identity()?;
    sweep.check_identity(out, &identity)?;
    write_atomic(&out.join("identity.json"), &identity)?;
    write_atomic(&out.join("sweep.toml"), &read(&sweep.path)?)?;
    remove_stale_partials(&out.join("runs"));
    let mine: Vec<&SweepRun> = sweep
        .runs
        .iter()
        .filter(|r| in_shard(r.index, shard))
        .collect();
    let pending: Vec<&SweepRun> = mine
        .iter()
        .copied()
        .filter(|r| !row_path(out, r).is_file())
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
    // try_for_each: the first failing run stops the sweep (runs already under way finish
    // and keep their rows), instead of every other run being run first.
    pool.install(|| {
        use rayon::prelude::*;
        pending.par_iter().try_for_each(|run| {
            let r = runner(sweep, run, &Sweep::run_dir(out, run))?;
            if r.values.len() != sweep.metrics().len() {
                return Err(sweep.run_error(
                    run,
                    format!(
                        "{} metric values for {} columns",
                        r.values.len(),
                        sweep.metrics().len()
                    ),
                ));
            }
            write_atomic(&row_path(out, run), &csv_text([sweep.row(run, &r)]))?;
            progress(done.fetch_add(1, Ordering::Relaxed) + 1, mine.len());
            Ok(())
        })
    })?;
    summarize(sweep, out)
}

/// A run killed while its results folder was written leaves a hidden `.<name>.partial-*`
/// folder beside it; it is never a result, so a resumed sweep removes it.
fn remove_stale_partials(runs: &Path) {
    let Ok(entries) = std::fs::read_dir(runs) else {
        return;
    };
    for e in entries.filter_map(Result::ok) {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') && name.contains(".partial-") {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// Copies a folder tree (a whole run's results) into `to`.
fn copy_tree(from: &Path, to: &Path) -> Result<(), SweepError> {
    std::fs::create_dir_all(to).map_err(FileError::at(to))?;
    let entries = std::fs::read_dir(from).map_err(FileError::at(from))?;
    let mut paths: Vec<PathBuf> = entries.filter_map(|e| e.ok()).map(|e| e.path()).collect();
    paths.sort();
    for p in paths {
        let target = to.join(p.file_name().expect("entries have names"));
        if p.is_dir() {
            copy_tree(&p, &target)?;
        } else {
            std::fs::copy(&p, &target).map_err(FileError::at(&target))?;
        }
    }
    Ok(())
}

/// Joins shard folders into `out`: their row files and, for whole runs, their runs'
/// results folders; then rebuilds the summary there. Every run of the sweep must have a row
/// in some shard.
pub fn merge(sweep: &Sweep, out: &Path, shards: &[PathBuf]) -> Result<SweepSummary, SweepError> {
    let identity = sweep.identity()?;
    sweep.check_identity(out, &identity)?;
    for dir in shards {
        if !dir.join("identity.json").is_file() {
            return Err(SweepError::Mismatch {
                path: dir.clone(),
                sweep: sweep.path.clone(),
                what: "no identity.json (not a shard of a sweep)".into(),
            });
        }
        sweep.check_identity(dir, &identity)?;
    }
    write_atomic(&out.join("identity.json"), &identity)?;
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
            let name = p.file_name().expect("row files have names");
            write_atomic(&out.join("rows").join(name), &read(&p)?)?;
            let run = Path::new(name).with_extension("");
            let results = dir.join("runs").join(&run);
            let target = out.join("runs").join(&run);
            if results.join("manifest.json").is_file() && !target.join("manifest.json").is_file() {
                // Copied whole into a hidden folder, then renamed: a killed merge leaves no
                // run folder that looks complete.
                let tmp = out.join("runs").join(format!(
                    ".{}.partial-{}",
                    run.display(),
                    std::process::id()
                ));
                let _ = std::fs::remove_dir_all(&tmp);
                copy_tree(&results, &tmp)?;
                let _ = std::fs::remove_dir_all(&target);
                std::fs::rename(&tmp, &target).map_err(FileError::at(&target))?;
            }
        }
    }
    write_atomic(&out.join("sweep.toml"), &read(&sweep.path)?)?;
    let missing: Vec<&SweepRun> = sweep
        .runs
        .iter()
        .filter(|r| !row_path(out, r).is_file())
        .collect();
    if let Some(first) = missing.first() {
        return Err(SweepError::Incomplete {
            path: sweep.path.clone(),
            missing: missing.len(),
            total: sweep.runs.len(),
            first: first.index,
        });
    }
    summarize(sweep, out)
}
