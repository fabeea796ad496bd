//! Experiments over many runs: localization from coverage databases, Monte Carlo sweeps of
//! coverage planning, the coverage report, regression against the baselines.

use crate::exec::{execute, progress_bar, Job};
use anyhow::{Context, Result};
use hetsim_eval::{regress, sweep};
use hetsim_render::RenderOptions;
use hetsim_scene::{load_scenario, LoadOptions};
use std::path::{Path, PathBuf};

fn default_jobs(jobs: Option<usize>) -> usize {
    jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// `hetsim report coverage`.
pub fn report(
    what: &str,
    runs: Vec<PathBuf>,
    out: Option<PathBuf>,
    jobs: Option<usize>,
) -> Result<()> {
    if what == "village" {
        anyhow::ensure!(
            !runs.is_empty(),
            "hetsim report village RUN_DIR [RUN_DIR ...]: name the results folder of a village \
             run (`hetsim run scenarios/village.toml` prints it as `results: <dir>`), or of \
             several runs with other seeds for the mean and spread over seeds"
        );
        let out = out.unwrap_or_else(|| PathBuf::from("results/village"));
        let path = hetsim_eval::village::village_report(&runs, &out)?;
        println!("results: {}", path.display());
        return Ok(());
    }
    anyhow::ensure!(
        what == "coverage",
        "unknown report {what:?}: the reports are `coverage` and `village RUN_DIR`"
    );
    anyhow::ensure!(
        runs.is_empty() && out.is_none(),
        "hetsim report coverage takes no run folder and no --out: it writes results/coverage-tables.md"
    );
    let bar = progress_bar("report");
    let path = hetsim_eval::report::coverage_report(
        Path::new("."),
        default_jobs(jobs),
        &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    )?;
    bar.finish_and_clear();
    println!("results: {}", path.display());
    Ok(())
}

/// `hetsim regress`.
pub fn regress(update: bool, scenarios: Vec<String>) -> Result<()> {
    let scenarios = if scenarios.is_empty() {
        regress::DEFAULT_SCENARIOS
            .iter()
            .map(|s| s.to_string())
            .collect()
    } else {
        scenarios
    };
    let rows = regress::regress(Path::new("."), &scenarios, update)?;
    println!("| scenario | metric | baseline | now | allowed | |");
    println!("|---|---|---|---|---|---|");
    for r in &rows {
        let status = if r.required && r.moved() {
            "REQUIREMENT FAILED"
        } else if update && !r.required {
            "updated"
        } else if r.moved() {
            "MOVED"
        } else {
            "ok"
        };
        println!(
            "| {} | {} | {} | {} | {} | {status} |",
            r.scenario, r.metric, r.baseline, r.now, r.allowed
        );
    }
    let short = rows.iter().filter(|r| r.required && r.moved()).count();
    anyhow::ensure!(
        short == 0,
        "{short} requirement(s) failed: every plan must image every vertex some vertex sees freely (Eq. 4 of seed 002) and skip no stage (a stage at every parent vertex, Section IV)"
    );
    let moved = rows.iter().filter(|r| !update && r.moved()).count();
    anyhow::ensure!(moved == 0, "{moved} metric(s) moved beyond their tolerance; if the change is intended, run `hetsim regress --update` and commit the baselines");
    println!("regress: {} metrics within tolerance", rows.len());
    Ok(())
}

/// What `hetsim sweep` was asked: its command-line arguments.
#[derive(clap::Args)]
pub struct SweepArgs {
    /// The sweep file, or `merge`.
    pub target: String,
    /// With `merge`: the sweep file, then the shard folders.
    pub more: Vec<PathBuf>,
    /// Parallel runs (default: all cores); with --slurm, CPUs per array task (default 1).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Output folder (default: results/runs/sweep-<name>).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Run only shard K of N (1-based), e.g. `--shard 2/4`.
    #[arg(long)]
    pub shard: Option<String>,
    /// Write OUT/slurm/{array.sbatch, merge.sbatch, submit.sh} instead of running.
    #[arg(long)]
    pub slurm: bool,
    /// With --slurm: submit the array and the merge job (sbatch must be on PATH).
    #[arg(long)]
    pub submit: bool,
    /// With --slurm: array tasks, one shard each (default: the runs, at most 32).
    #[arg(long)]
    pub shards: Option<usize>,
    /// With --slurm: an extra #SBATCH option for both jobs, e.g. --sbatch=--partition=long
    /// (repeatable).
    #[arg(long, allow_hyphen_values = true)]
    pub sbatch: Vec<String>,
}

/// `hetsim sweep`, `hetsim sweep --slurm` and `hetsim sweep merge`.
pub fn sweep(args: SweepArgs) -> Result<()> {
    let merging = args.target == "merge";
    let (file, shards) = if merging {
        let (f, rest) = args
            .more
            .split_first()
            .context("usage: hetsim sweep merge SWEEP.toml SHARD_DIR... --out DIR")?;
        (f.clone(), rest.to_vec())
    } else {
        anyhow::ensure!(
            args.more.is_empty(),
            "unexpected arguments after the sweep file: {:?}",
            args.more
        );
        (PathBuf::from(&args.target), Vec::new())
    };
    anyhow::ensure!(
        args.slurm || (!args.submit && args.shards.is_none() && args.sbatch.is_empty()),
        "--submit, --shards and --sbatch go with --slurm"
    );
    anyhow::ensure!(
        !(args.slurm && (merging || args.shard.is_some())),
        "--slurm writes the whole sweep's job array: give it the sweep file, without --shard"
    );
    let loaded = sweep::load_sweep(&file)?;
    let out = args.out.unwrap_or_else(|| {
        PathBuf::from("results/runs").join(format!("sweep-{}", loaded.file.name))
    });
    if args.slurm {
        let options = crate::slurm::SlurmOptions {
            shards: args.shards.unwrap_or(loaded.runs.len().min(32)),
            cpus: args.jobs.unwrap_or(1),
            extra: args.sbatch,
        };
        let scripts = crate::slurm::write_scripts(&loaded, &out, &options)?;
        println!("array: {}", scripts.array.display());
        println!("merge: {}", scripts.merge.display());
        println!("submit: {}", scripts.submit.display());
        if args.submit {
            let (array, merge) = crate::slurm::submit(&scripts)?;
            println!("submitted: array job {array}, merge job {merge} (afterok:{array})");
            println!("results, once the merge job ends: {}", out.display());
        } else {
            println!("results, once submit.sh's jobs end: {}", out.display());
        }
        return Ok(());
    }
    let summary = if merging {
        anyhow::ensure!(!shards.is_empty(), "name the shard folders to merge");
        sweep::merge(&loaded, &out, &shards)?
    } else {
        let shard = match args.shard {
            None => (1, 1),
            Some(s) => {
                let parsed = s
                    .split_once('/')
                    .and_then(|(k, n)| Some((k.parse::<usize>().ok()?, n.parse::<usize>().ok()?)));
                match parsed {
                    Some((k, n)) if n >= 1 && (1..=n).contains(&k) => (k, n),
                    _ => anyhow::bail!("--shard {s}: expected K/N with 1 <= K <= N, e.g. 2/4"),
                }
            }
        };
        let jobs = default_jobs(args.jobs);
        let bar = progress_bar(&loaded.file.name);
        let progress = |done: usize, total: usize| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        };
        let summary = match loaded.file.kind {
            sweep::SweepKind::Plan => sweep::run_sweep(&loaded, &out, jobs, shard, &progress)?,
            sweep::SweepKind::Run => {
                sweep::run_sweep_with(&loaded, &out, jobs, shard, &progress, &whole_run)?
            }
        };
        bar.finish_and_clear();
        summary
    };
    println!(
        "{}",
        std::fs::read_to_string(out.join("summary.md")).unwrap_or_default()
    );
    println!("finished: {} of {} runs", summary.finished, summary.total);
    println!("results: {}", out.display());
    Ok(())
}

/// One run of a whole-run sweep: the scenario run, evaluated and written into `dir` (kept
/// when a killed sweep had finished it), and its metrics read back from there.
fn whole_run(
    sweep: &sweep::Sweep,
    run: &sweep::SweepRun,
    dir: &Path,
) -> Result<sweep::RunResult, sweep::SweepError> {
    if let (Some((recording, _)), false) = (&sweep.recording, dir.join("manifest.json").is_file()) {
        // A replay of the recording with the run's axis values set.
        let set = sweep
            .axes()
            .iter()
            .zip(&run.values)
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        crate::replay::replay(&crate::replay::ReplayArgs {
            source: recording.clone(),
            robots: Vec::new(),
            out: Some(dir.to_path_buf()),
            // Only a folder without results is replayed into (the sweep resumes the rest).
            replace: false,
            set,
            scenario: None,
            duration: sweep.file.duration_secs,
            quiet: true,
            memory: None,
            withhold_truth: false,
        })
        .map_err(|e| sweep.run_error(run, format!("{e:#}")))?;
    } else if !dir.join("manifest.json").is_file() {
        let loaded = sweep.scenario(run)?;
        let render = sweep
            .file
            .render
            .unwrap_or(true)
            .then(RenderOptions::default);
        crate::exec::run_scenario(
            &loaded,
            &Job {
                out: Some(dir),
                record: None,
                render,
                dump: None,
                open_loop: false,
                quiet: true,
                memory: None,
                // Only a folder without results is run into (the sweep resumes the rest).
                replace: false,
                record_anyway: false,
            },
        )
        .map_err(|e| sweep.run_error(run, format!("{e:#}")))?;
    }
    sweep::metrics_of_run(sweep, run, dir)
}

/// What made the finished run in a folder, from its manifest: the build (`build_sha256`, empty
/// for a run from before manifests named it), the scenario's files (`files_sha256`) and the
/// renderer's backend (`adapter.backend`, lower case; `None` for an unrendered run).
#[derive(Clone, Debug, Default, PartialEq)]
struct MadeBy {
    build: String,
    files: std::collections::BTreeMap<String, String>,
    backend: Option<String>,
}

/// What made the run in `dir`; `None` where there is no finished run.
fn made_by(dir: &Path) -> Result<Option<MadeBy>> {
    let path = dir.join("manifest.json");
    if !path.is_file() {
        return Ok(None);
    }
    /// The manifest's fields that say what made the run, each absent in some older manifest.
    #[derive(serde::Deserialize)]
    struct Fields {
        #[serde(default)]
        build_sha256: String,
        #[serde(default)]
        files_sha256: std::collections::BTreeMap<String, String>,
        #[serde(default)]
        adapter: Option<Backend>,
    }
    #[derive(serde::Deserialize)]
    struct Backend {
        backend: String,
    }
    let fields: Fields = serde_json::from_slice(
        &std::fs::read(&path).with_context(|| format!("{}", path.display()))?,
    )
    .with_context(|| format!("{}: not a run's manifest", path.display()))?;
    Ok(Some(MadeBy {
        build: fields.build_sha256,
        files: fields.files_sha256,
        backend: fields.adapter.map(|a| a.backend.to_ascii_lowercase()),
    }))
}

/// Why a run made as `made` cannot stand in a study by build `this` of scenario files
/// `files` on backend `backend` (`None`: any), or `None` where it can: the same build, one
/// that could read itself (`"unknown"` matches nothing), the same files, byte for byte, and
/// the backend asked for.
fn not_reusable(
    made: &MadeBy,
    this: &str,
    files: &std::collections::BTreeMap<String, String>,
    backend: Option<&str>,
) -> Option<String> {
    if made.build.is_empty() {
        return Some("was made by a hetsim that did not record its build".into());
    }
    if this == "unknown" || made.build != this {
        return Some(format!(
            "was made by another build of hetsim (build_sha256 {})",
            made.build.chars().take(12).collect::<String>()
        ));
    }
    if &made.files != files {
        let changed: std::collections::BTreeSet<&str> = files
            .keys()
            .chain(made.files.keys())
            .filter(|k| files.get(*k) != made.files.get(*k))
            .map(String::as_str)
            .collect();
        let changed: Vec<&str> = changed.into_iter().collect();
        return Some(format!(
            "was made from other scenario files ({} changed)",
            changed.join(", ")
        ));
    }
    match (backend, made.backend.as_deref()) {
        (Some(want), Some(got)) if want != got => {
            Some(format!("was rendered on {got}, not the {want} asked for"))
        }
        _ => None,
    }
}

/// `hetsim localize`: mapping runs, cross-validation, and each run's child localizing on its
/// own path after mapping (in lockstep).
pub fn localize(
    scenario: &Path,
    seeds: u64,
    out: Option<PathBuf>,
    render: RenderOptions,
) -> Result<()> {
    use hetsim_eval::localize::{cross_validate, load_database, PathRun};
    anyhow::ensure!(
        seeds >= 2,
        "--seeds {seeds}: cross-validation needs at least 2 runs"
    );
    let base = load_scenario(scenario, &LoadOptions::default())?;
    anyhow::ensure!(
        base.robots
            .iter()
            .any(|r| matches!(r.spec.mission, hetsim_scene::MissionSpec::CoverageParent)),
        "{}: no robot with mission coverage_parent; localization needs a coverage mission",
        scenario.display()
    );
    let out = out.unwrap_or_else(|| {
        PathBuf::from("results/runs").join(format!("localize-{}", base.file.name))
    });
    // The backend asked for (the option, else HETSIM_BACKEND); `any` asks for none.
    let backend = render
        .backend
        .clone()
        .or_else(|| std::env::var("HETSIM_BACKEND").ok())
        .map(|b| b.to_ascii_lowercase())
        .filter(|b| b != "any");
    let mut databases = Vec::new();
    let mut missions = Vec::new();
    for seed in 1..=seeds {
        let dir = out.join(format!("runs/seed-{seed}"));
        // `Some(None)`: a run to reuse; `Some(Some(why))`: a run to replace; `None`: no run.
        let verdict = made_by(&dir)?.map(|m| {
            let this = hetsim_eval::manifest::build_sha256();
            not_reusable(&m, this, &base.file_hashes, backend.as_deref())
        });
        if let Some(None) = verdict {
            eprintln!(
                "seed {seed}: reusing {} (made by this build from the same files)",
                dir.display()
            );
        } else {
            match verdict.flatten() {
                Some(why) => eprintln!(
                    "seed {seed}: {} {why}; running the mission again",
                    dir.display()
                ),
                None => eprintln!("seed {seed}: running the mission"),
            }
            let loaded = load_scenario(
                scenario,
                &LoadOptions {
                    robot_files: None,
                    seed: Some(seed),
                    duration_secs: None,
                },
            )?;
            execute(
                &loaded,
                &Job {
                    out: Some(&dir),
                    record: None,
                    render: Some(render.clone()),
                    dump: None,
                    open_loop: false,
                    quiet: false,
                    memory: None,
                    // The study's own folder: a run of another build is made again over it.
                    replace: true,
                    record_anyway: false,
                },
            )?;
        }
        let metrics: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.join("metrics.json"))
                .with_context(|| format!("{}", dir.display()))?,
        )?;
        missions.push(metrics["team"].clone());
        databases.push(load_database(&dir)?);
    }
    eprintln!("cross-validating {} databases", databases.len());
    let cross = cross_validate(&databases);
    // The paths the runs' children drove on their own after mapping.
    let mut pf: Vec<PathRun> = Vec::new();
    for (seed, m) in (1..=seeds).zip(&missions) {
        let dir = out.join(format!("runs/seed-{seed}"));
        // Runs from before the localization ran in lockstep have no such child (their
        // `localization` was driven after the run, from the truth): not to be mixed in.
        anyhow::ensure!(
            m.get("localization_child").is_some(),
            "{}: a run from an older hetsim (its localization was not run in lockstep); delete the folder to run it again",
            dir.display()
        );
        let runs: Vec<PathRun> =
            serde_json::from_value(m["localization"].clone()).with_context(|| {
                format!("{}: team.localization", dir.join("metrics.json").display())
            })?;
        pf.extend(runs);
    }
    let paths = pf.len() / hetsim_vision::appearance::Feature::ALL.len();
    let summary = hetsim_eval::localize::summarize(&missions, &cross, &pf);
    let json = serde_json::to_vec_pretty(&summary)?;
    let md = hetsim_eval::localize::markdown(&summary);
    hetsim_core::files::write_atomic(&out.join("localization.json"), &json)?;
    hetsim_core::files::write_atomic(&out.join("localization.md"), md.as_bytes())?;
    let png = hetsim_eval::charts::localization_png(
        &format!(
            "{}: particle filter error along {paths} paths driven in lockstep after mapping",
            base.file.name
        ),
        &pf,
    );
    hetsim_core::files::write_atomic(&out.join("localization.png"), &png)?;
    println!("{md}");
    println!("results: {}", out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{made_by, not_reusable, MadeBy};
    use std::collections::BTreeMap;

    fn files(hash: &str) -> BTreeMap<String, String> {
        BTreeMap::from([("scenarios/lab.toml".to_string(), hash.to_string())])
    }

    /// Only a run of this very build, from the same files, on the backend asked for is
    /// reused; a build that could not hash itself reuses nothing, not even a run of another
    /// build that could not either.
    #[test]
    fn only_a_run_of_this_build_and_these_files_is_reused() {
        let this = "ab".repeat(32);
        let made = MadeBy {
            build: this.clone(),
            files: files("11"),
            backend: Some("vulkan".into()),
        };
        assert_eq!(not_reusable(&made, &this, &files("11"), None), None);
        assert_eq!(
            not_reusable(&made, &this, &files("11"), Some("vulkan")),
            None
        );
        let why = |m: &MadeBy, this: &str, f: &BTreeMap<String, String>, b: Option<&str>| {
            not_reusable(m, this, f, b).unwrap_or_else(|| panic!("{m:?} reused"))
        };
        let old = MadeBy {
            build: String::new(),
            ..made.clone()
        };
        assert!(why(&old, &this, &files("11"), None).contains("did not record"));
        assert!(why(&made, &"cd".repeat(32), &files("11"), None).contains("another build"));
        let unknown = MadeBy {
            build: "unknown".into(),
            ..made.clone()
        };
        assert!(why(&unknown, "unknown", &files("11"), None).contains("another build"));
        let changed = why(&made, &this, &files("22"), None);
        assert!(changed.contains("scenarios/lab.toml changed"), "{changed}");
        let gl = why(&made, &this, &files("11"), Some("gl"));
        assert!(gl.contains("rendered on vulkan, not the gl"), "{gl}");
    }

    /// A seed's folder tells what made it: no run, a run without a recorded build, and one
    /// with its build, files and backend; a manifest that is not JSON is an error naming it.
    #[test]
    fn a_run_tells_what_made_it() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("seed-1");
        assert_eq!(made_by(&run).unwrap(), None, "no run yet");
        std::fs::create_dir_all(&run).unwrap();
        let write = |text: &str| std::fs::write(run.join("manifest.json"), text).unwrap();
        write(r#"{"digest": "ab"}"#);
        assert_eq!(
            made_by(&run).unwrap(),
            Some(MadeBy::default()),
            "nothing recorded"
        );
        let this = hetsim_eval::manifest::build_sha256();
        assert_eq!(this.len(), 64, "{this}");
        write(&format!(
            r#"{{"build_sha256": "{this}", "files_sha256": {{"scenarios/lab.toml": "11"}},
                "adapter": {{"backend": "Gl"}}}}"#
        ));
        assert_eq!(
            made_by(&run).unwrap(),
            Some(MadeBy {
                build: this.to_string(),
                files: files("11"),
                backend: Some("gl".into()),
            })
        );
        write("{");
        let err = format!("{:#}", made_by(&run).unwrap_err());
        assert!(err.contains("manifest.json"), "{err}");
    }
}
