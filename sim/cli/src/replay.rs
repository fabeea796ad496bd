//! `hetsim replay`: a recording `hetsim run --record` wrote, or a EuRoC dataset, fed to the
//! robot software with no physics and no rendering; the results folder a live run writes.

use anyhow::{bail, Context, Result};
use hetsim_engine::replay::{Recording, RunDescription};
use hetsim_io::euroc_in::BenchSpec;
use hetsim_io::{EurocRecording, McapRecording};
use hetsim_scene::{load_scenario_text, LoadOptions, Scenario};
use std::path::{Path, PathBuf};

/// What to replay, and how.
pub struct ReplayArgs<'a> {
    /// An MCAP recording, or a EuRoC dataset's `mav0` folder.
    pub source: PathBuf,
    /// Replay only these robots (default: all; a EuRoC dataset needs exactly one).
    pub robots: Vec<String>,
    /// Results folder (default: results/runs/replay-<source name>).
    pub out: Option<PathBuf>,
    /// Replace the results of another run there.
    pub replace: bool,
    /// `key=value` settings written into the scenario (`robots.<robot>.<field>`,
    /// `models.<model>.<field>`, scenario fields), values in TOML syntax.
    pub set: Vec<String>,
    /// The scenario to replay into (default for a recording: the one it carries; required
    /// for a EuRoC dataset).
    pub scenario: Option<PathBuf>,
    /// Replay only this many sim seconds.
    pub duration: Option<f64>,
    /// No progress bar.
    pub quiet: bool,
    /// Where to append (sim seconds, resident MiB) at each progress report.
    pub memory: Option<&'a crate::exec::MemoryTrace>,
    /// Withhold every oracle message from the stacks (commands are then not checked).
    pub withhold_truth: bool,
}

/// `key=value` settings parsed (values as TOML, bare words as strings).
fn settings(set: &[String]) -> Result<Vec<(String, toml::Value)>> {
    set.iter()
        .map(|s| {
            let (k, v) = s.split_once('=').with_context(|| {
                format!("--set {s}: expected KEY=VALUE, e.g. robots.dala.slam.sigma_px=1.5")
            })?;
            let value = toml::from_str::<toml::Table>(&format!("v = {v}"))
                .ok()
                .and_then(|mut t| t.remove("v"))
                .unwrap_or_else(|| toml::Value::String(v.to_string()));
            Ok((k.trim().to_string(), value))
        })
        .collect()
}

/// The scenario text with the settings written in, loaded.
fn load(path: &Path, text: &str, set: &[String], options: LoadOptions) -> Result<Scenario> {
    let settings = settings(set)?;
    let refs: Vec<(&str, &toml::Value)> = settings.iter().map(|(k, v)| (k.as_str(), v)).collect();
    // Unchanged when nothing is set: the same text, the same file hash as the live run's.
    let text = if refs.is_empty() {
        text.to_string()
    } else {
        hetsim_eval::sweep::apply_settings(text, &refs)
            .map_err(|e| anyhow::anyhow!("--set: {e}"))?
    };
    Ok(load_scenario_text(path, text, &options)?)
}

/// Replays and writes the results folder; prints `results:` and `digest:`.
pub fn replay(args: &ReplayArgs<'_>) -> Result<hetsim_eval::RunFiles> {
    let start = crate::bench::wall_clock();
    let (scenario, mut recording, open_loop) = if args.source.is_dir() {
        let (scenario, recording) = open_euroc(args)?;
        (scenario, recording, false)
    } else {
        open_mcap(args)?
    };
    let names: Vec<&str> = scenario
        .robots
        .iter()
        .map(|r| r.spec.name.as_str())
        .collect();
    check_robots(&args.robots, &names)?;
    let out = out_dir(args);
    let _claim = crate::exec::claim(&out, &scenario, args.replace)?;
    let stacks = replayed_stacks(&scenario, open_loop, &names, &args.robots);
    let output = replay_with_progress(args, &scenario, stacks, recording.as_mut())?;
    let metrics = hetsim_eval::Metrics::compute(&scenario, &output)?;
    let wall = start.elapsed().as_secs_f64();
    let timing = hetsim_eval::manifest::Timing {
        frames_written: None,
        realtime_factor: output.sim_secs / wall.max(1e-9),
        replay_of: Some(args.source.display().to_string()),
        sim_secs: output.sim_secs,
        threads: None,
        wall_secs: wall,
    };
    let files = hetsim_eval::write_run(
        &scenario,
        output,
        &metrics,
        Some(&out),
        &timing,
        None,
        args.replace,
    )
    .context("writing results")?;
    Ok(files)
}

/// A EuRoC dataset opened as the recording of `--robot`'s stereo bench, with the scenario
/// `--scenario` names, run until the robot has seen the last image.
fn open_euroc(args: &ReplayArgs<'_>) -> Result<(Scenario, Box<dyn Recording>)> {
    let Some(path) = &args.scenario else {
        bail!(
            "{}: a EuRoC dataset carries no scenario: give --scenario FILE and --robot NAME (the robot whose stereo bench it feeds)",
            args.source.display()
        );
    };
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut scenario = load(
        path,
        &text,
        &args.set,
        LoadOptions {
            duration_secs: args.duration,
            ..LoadOptions::default()
        },
    )?;
    let [robot] = args.robots.as_slice() else {
        bail!("a EuRoC dataset feeds one robot: give exactly one --robot NAME");
    };
    let r = scenario
        .robots
        .iter()
        .find(|r| r.spec.name == *robot)
        .with_context(|| format!("--robot {robot}: not a robot of {}", path.display()))?;
    let bench = hetsim_scene::stereo_bench(r)
        .with_context(|| format!("--robot {robot}: its robot file has no stereo bench"))?;
    let k = bench.intrinsics;
    let spec = BenchSpec {
        robot: robot.clone(),
        bench: bench.name,
        width: k.width,
        height: k.height,
        intrinsics: [k.k.alpha_u, k.k.alpha_v, k.k.u0, k.k.v0],
        baseline_m: bench.baseline_m,
        dt_ns: scenario.clock.dt_ns(),
    };
    let euroc = EurocRecording::open(&args.source, spec)?;
    // Until the robot has seen the last image.
    let dt = scenario.clock.dt_secs();
    let last = euroc.last_image_ns() as f64 * 1e-9 + dt;
    scenario.duration_secs = scenario.duration_secs.min(last);
    Ok((scenario, Box::new(euroc)))
}

/// An MCAP recording opened, with the scenario to replay it into (checked to keep the
/// recording's tick) and whether the recorded run was open loop.
fn open_mcap(args: &ReplayArgs<'_>) -> Result<(Scenario, Box<dyn Recording>, bool)> {
    let mcap = McapRecording::open(&args.source)?;
    let run = mcap.run.clone();
    let duration = args
        .duration
        .map_or(run.duration_secs, |d| d.min(run.duration_secs));
    if args.duration.is_some_and(|d| d > run.duration_secs) {
        eprintln!(
            "note: {} holds {} sim seconds; replaying those",
            args.source.display(),
            run.duration_secs
        );
    }
    let scenario = mcap_scenario(args, &run, duration)?;
    // The recording's messages sit on its tick grid: another tick would feed them at
    // other ticks than the live run did.
    if scenario.clock.dt_ns() != run.dt_ns {
        bail!(
            "{}: recorded with a {} ns tick, the scenario replayed into has {} ns (dt_secs must stay the recording's)",
            args.source.display(),
            run.dt_ns,
            scenario.clock.dt_ns()
        );
    }
    let open_loop = run.open_loop;
    Ok((scenario, Box::new(mcap), open_loop))
}

/// The scenario to replay the recorded `run` into, for `duration` sim seconds: the file
/// `--scenario` names, else the one the recording carries with its robot files.
fn mcap_scenario(args: &ReplayArgs<'_>, run: &RunDescription, duration: f64) -> Result<Scenario> {
    let scenario = match &args.scenario {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            let options = LoadOptions {
                seed: Some(run.seed),
                duration_secs: Some(duration),
                robot_files: None,
            };
            load(path, &text, &args.set, options)?
        }
        None => load(
            &run.scenario_path,
            &run.scenario_text,
            &args.set,
            LoadOptions {
                seed: Some(run.seed),
                duration_secs: Some(duration),
                robot_files: Some(run.robot_files.clone()),
            },
        )
        .with_context(|| {
            format!(
                "the scenario {} carries ({})",
                args.source.display(),
                run.scenario_path.display()
            )
        })?,
    };
    let mut scenario = scenario;
    // The cameras the live run had (a `--camera-profile` is not in the scenario's text).
    if let Some(profile) = run.camera_profile {
        scenario.file.camera_profile = profile;
    }
    Ok(scenario)
}

/// Refuses a `--robot` that is not one of the scenario's robots `names`.
fn check_robots(robots: &[String], names: &[&str]) -> Result<()> {
    for r in robots {
        if !names.contains(&r.as_str()) {
            bail!(
                "--robot {r}: not a robot of the scenario (robots: {})",
                names.join(", ")
            );
        }
    }
    Ok(())
}

/// The scenario's robot stacks in scenario order, `None` for a robot `--robot` leaves out
/// (none left out when `robots` is empty).
fn replayed_stacks(
    scenario: &Scenario,
    open_loop: bool,
    names: &[&str],
    robots: &[String],
) -> Vec<Option<Box<dyn hetsim_msgs::RobotStack>>> {
    hetsim_stacks::build_stacks(scenario, open_loop)
        .into_iter()
        .zip(names)
        .map(|(s, n)| (robots.is_empty() || robots.iter().any(|r| r == n)).then_some(s))
        .collect()
}

/// The recording replayed into `stacks`, with a progress bar (unless quiet) and the memory
/// trace sampled at each progress report.
fn replay_with_progress(
    args: &ReplayArgs<'_>,
    scenario: &Scenario,
    stacks: Vec<Option<Box<dyn hetsim_msgs::RobotStack>>>,
    recording: &mut dyn Recording,
) -> Result<hetsim_engine::RunOutput, hetsim_engine::ReplayError> {
    let bar = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        crate::exec::progress_bar(&format!("replay {}", scenario.file.name))
    };
    let clock = scenario.clock;
    let output = hetsim_engine::replay_withholding_truth(
        scenario,
        stacks,
        recording,
        args.withhold_truth,
        |tick, total| {
            bar.set_length(total);
            bar.set_position(tick);
            crate::exec::sample_memory(args.memory, clock.time_secs(tick));
        },
    );
    bar.finish_and_clear();
    output
}

/// The results folder: `--out`, else results/runs/replay-<the recording's name>.
fn out_dir(args: &ReplayArgs<'_>) -> PathBuf {
    // A EuRoC dataset is named by the folder above mav0 (frames/<robot>/mav0: the robot).
    let named = match args.source.file_name() {
        Some(n) if n == "mav0" => args.source.parent().and_then(Path::file_name),
        _ => args.source.file_stem(),
    };
    let stem = named.map_or("recording".into(), |s| s.to_string_lossy().into_owned());
    args.out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results/runs").join(format!("replay-{stem}")))
}
