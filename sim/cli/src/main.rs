//! `hetsim`: run scenarios headless, validate files, evaluate, sweep, measure speed.
//!
//! This file holds the command line and dispatches; [`exec`] runs scenarios and writes their
//! results, [`study`] holds the experiments over many runs (localization, sweeps, reports,
//! regression), [`bench`] the speed figures.

mod bench;
mod bench_replay;
mod exec;
mod replay;
mod slurm;
mod study;

use anyhow::Result;
use clap::{Parser, Subcommand};
use hetsim_scene::{load_robot_model, load_scenario, LoadOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Deterministic multi-robot simulator for cooperative visual mapping.
#[derive(Parser)]
#[command(name = "hetsim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
    /// The memory a world may need (e.g. 8G, 500M; default: this machine's available
    /// memory): a village whose terrain needs more is refused before it is built.
    #[arg(long, global = true, value_parser = parse_bytes)]
    max_memory: Option<u64>,
}

/// `8G`, `500M`, `64k` or a plain number of bytes (decimal units).
fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (digits, unit) = match t.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => (&t[..i], &t[i..]),
        None => (t, ""),
    };
    let scale = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "m" | "mb" => 1e6,
        "g" | "gb" => 1e9,
        "t" | "tb" => 1e12,
        _ => return Err(format!("{s}: expected bytes, e.g. 8G, 500M or 64k")),
    };
    let n: f64 = digits
        .trim()
        .parse()
        .map_err(|_| format!("{s}: expected bytes, e.g. 8G, 500M or 64k"))?;
    if !(n.is_finite() && n > 0.0) {
        return Err(format!("{s}: expected a positive size"));
    }
    Ok((n * scale) as u64)
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a scenario headless and write its results directory.
    Run {
        /// Scenario file (scenarios/*.toml).
        scenario: PathBuf,
        /// Master seed (default: the scenario's `seed`).
        #[arg(long)]
        seed: Option<u64>,
        /// Sim seconds to run (default: the scenario's `duration_secs`).
        #[arg(long)]
        duration: Option<f64>,
        /// Results directory (default: results/runs/<name>-seed<seed>-<digest8>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another run in --out (by default refused; the same run,
        /// same files, settings, seed, duration and build, is always rewritten), and record
        /// even where the recording's estimated size exceeds the free space.
        #[arg(long)]
        force: bool,
        /// Also record every message, command and ground-truth pose to this MCAP file
        /// (ROS 2: CDR messages, ros2msg schemas).
        #[arg(long)]
        record: Option<PathBuf>,
        /// The recording's encoding: ros2 (CDR; ros2 bag, rosbags and Foxglove read it) or
        /// json (Foxglove's JSON schemas, images as base64 PNG).
        #[arg(long, default_value = "ros2", value_parser = ["ros2", "json"])]
        record_encoding: String,
        /// Write every camera frame (EuRoC layout, with depth and poses) under frames/.
        #[arg(long)]
        dump_frames: bool,
        /// Do not render the cameras (no images reach the robots).
        #[arg(long)]
        no_render: bool,
        /// Camera imperfections: `realistic` (the robot files' calibration errors and
        /// exposures) or `perfect` (none); default: the scenario's `camera_profile`.
        #[arg(long, value_parser = ["realistic", "perfect"])]
        camera_profile: Option<String>,
        /// Run the SLAM open loop: no GPS, rendezvous or image-matching events, no graph
        /// exchange (the comparison run of Fig. 7).
        #[arg(long)]
        open_loop: bool,
        /// Renderer backend: vulkan, gl or any (default: HETSIM_BACKEND, else any).
        #[arg(long)]
        backend: Option<String>,
        /// Use the adapter whose name contains this (default: HETSIM_ADAPTER, else any).
        #[arg(long)]
        adapter: Option<String>,
    },
    /// Render and write the frames of a time window (EuRoC layout), e.g.
    /// `hetsim frames scenarios/village.toml --from 10 --to 12 --cameras dala/stereo`.
    Frames {
        /// Scenario file.
        scenario: PathBuf,
        /// Start of the window, sim seconds.
        #[arg(long)]
        from: f64,
        /// End of the window, sim seconds (the run stops there).
        #[arg(long)]
        to: f64,
        /// Cameras, comma-separated: `robot/camera` or `robot` (default: all).
        #[arg(long)]
        cameras: Option<String>,
        /// Camera imperfections: `realistic` (the robot files' calibration errors and
        /// exposures) or `perfect` (none); default: the scenario's `camera_profile`.
        #[arg(long, value_parser = ["realistic", "perfect"])]
        camera_profile: Option<String>,
        /// Master seed (default: the scenario's).
        #[arg(long)]
        seed: Option<u64>,
        /// Output folder (default: results/runs/<name>-seed<seed>-frames-<from>-<to>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another run in --out (by default refused; the same run,
        /// same files, settings, seed, duration and build, is always rewritten).
        #[arg(long)]
        force: bool,
        /// Renderer backend: vulkan, gl or any (default: HETSIM_BACKEND, else any).
        #[arg(long)]
        backend: Option<String>,
        /// Use the adapter whose name contains this (default: HETSIM_ADAPTER, else any).
        #[arg(long)]
        adapter: Option<String>,
    },
    /// Localization from coverage-mission image databases (seed 002, Section V.B): runs the
    /// scenario's mission for seeds 1..=N (reusing runs this build already made in the output
    /// folder; a run of another build is made again),
    /// cross-validates their databases (WGOH and pixelwise), and gathers the particle filter
    /// runs of the child each mission sent on a new path after mapping (`[coverage]
    /// localize_steps`). Writes localization.json, .md and .png.
    Localize {
        /// Scenario with a coverage mission (e.g. scenarios/lab.toml).
        scenario: PathBuf,
        /// Mapping runs (seeds 1..=N).
        #[arg(long, default_value_t = 10)]
        seeds: u64,
        /// Output folder (default: results/runs/localize-<name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Renderer backend: vulkan, gl or any (default: HETSIM_BACKEND, else any).
        #[arg(long)]
        backend: Option<String>,
        /// Use the adapter whose name contains this (default: HETSIM_ADAPTER, else any).
        #[arg(long)]
        adapter: Option<String>,
    },
    /// Feed a recording (`hetsim run --record`) or a EuRoC dataset's mav0 folder to the robot
    /// software, with no physics and no rendering, and write the results folder a live run
    /// writes. Every command a stack sends is checked against the recorded one.
    Replay {
        /// The MCAP recording, or a EuRoC dataset's mav0 folder.
        source: PathBuf,
        /// Replay only this robot (repeatable; default: all). The others' recorded radio
        /// messages still reach it. A EuRoC dataset feeds exactly one.
        #[arg(long = "robot")]
        robots: Vec<String>,
        /// Results directory (default: results/runs/replay-<recording name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Replace the results of another run in --out (by default refused; the same run,
        /// same files, settings, seed, duration and build, is always rewritten).
        #[arg(long)]
        force: bool,
        /// Change a setting before replaying, e.g. `--set robots.dala.slam.sigma_px=1.5` or
        /// `--set models.ressac.slam.lines=false` (repeatable; values in TOML syntax).
        #[arg(long)]
        set: Vec<String>,
        /// Scenario to replay into (default: the one the recording carries; required for a
        /// EuRoC dataset).
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// Replay only the first SECS sim seconds.
        #[arg(long)]
        duration: Option<f64>,
        /// Also write this process's resident memory at each progress report (every sim
        /// second, or every 1 % of a run shorter than 100 s) to FILE (CSV: sim_s,rss_mib),
        /// and its peak as the last row (`peak`).
        #[arg(long)]
        memory_trace: Option<PathBuf>,
        /// Withhold every oracle message (true poses) from the robot software; commands are
        /// then not checked against the recording (a pilot that steers by the oracle stands
        /// still). The estimators' outputs must not change: they read no truth.
        #[arg(long)]
        withhold_truth: bool,
    },
    /// Check scenario and robot files without running anything.
    Validate {
        /// Scenario files or robot files (robots/models/*.toml).
        files: Vec<PathBuf>,
    },
    /// Run a Monte Carlo sweep: of whole runs of any scenario (`kind = "run"`) or of coverage
    /// planning (`kind = "plan"`); `--slurm` writes (and with `--submit` submits) it as a
    /// Slurm job array with a dependent merge job; `hetsim sweep merge SWEEP.toml
    /// SHARD_DIR... --out DIR` joins shards.
    Sweep(study::SweepArgs),
    /// Write results/coverage-tables.md and its figures (`hetsim report coverage`: runs or
    /// resumes the table1 and table2 sweeps first), or a village run's results page
    /// (`hetsim report village RUN_DIR [RUN_DIR ...]`: results/village/ from the run's folder,
    /// with the mean and spread over seeds when given the runs of several).
    Report {
        /// What to report: `coverage` or `village`.
        what: String,
        /// `village`: the results folder of the run to report; more folders (runs of the same
        /// scenario with other seeds) add the mean and spread over the seeds and the Monte
        /// Carlo consistency test.
        run: Vec<PathBuf>,
        /// `village`: where to write the page (default: results/village).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Parallel runs (default: all cores).
        #[arg(long)]
        jobs: Option<usize>,
    },
    /// Compare coverage planning on the indoor scenarios with results/baselines/*.json.
    Regress {
        /// Rewrite the baselines with today's values (keeps their tolerances).
        #[arg(long)]
        update: bool,
        /// Scenarios (default: indoor-grid-0, -20, -40).
        scenarios: Vec<String>,
    },
    /// Measure sim seconds per wall second (physics and ground truth only), or with one of
    /// the mode flags another figure.
    #[command(group(clap::ArgGroup::new("mode").multiple(false)))]
    Bench {
        /// Scenarios to measure.
        #[arg(default_values = ["scenarios/village.toml", "scenarios/indoor-grid-20.toml"])]
        scenarios: Vec<PathBuf>,
        /// Sim seconds to run each.
        #[arg(long, default_value_t = 120.0)]
        sim_secs: f64,
        /// Instead: time coverage planning of each scenario (median of 5).
        #[arg(long, group = "mode")]
        coverage: bool,
        /// Instead: time one laser scan, and a tick with and without the non-visual sensors.
        #[arg(long, group = "mode")]
        sensors: bool,
        /// Instead: frames per second with readback (1024x768 mono, 1024x768 stereo pairs,
        /// 120x88) on the adapter HETSIM_BACKEND / HETSIM_ADAPTER choose.
        #[arg(long, group = "mode")]
        render: bool,
        /// Instead: milliseconds per stereo frame for Harris, stereo matching, a VO step and
        /// line segments, on rendered frames of the first scenario's first stereo robot
        /// (default: the village's rover) moving 6 cm per frame.
        #[arg(long, group = "mode")]
        vision: bool,
        /// Instead: the local EKF's prediction and point and line updates per frame against
        /// the number of mapped landmarks (synthetic, a fifth of them lines, every landmark
        /// observed once per frame).
        #[arg(long, group = "mode")]
        slam: bool,
        /// Instead: the first scenario run for --sim-secs rendered and recorded, then its
        /// recording replayed (`hetsim replay`), back to back: both speeds, their ratio, the
        /// recording's size per sim minute, peak resident memory, and whether the replay has
        /// the live run's digest. With --out DIR, memory.csv and memory.png (resident memory
        /// against sim time).
        #[arg(long, group = "mode")]
        replay: bool,
        /// With --replay: where to write memory.csv and memory.png.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print the figures as one JSON object instead of a Markdown table.
        #[arg(long)]
        json: bool,
    },
}

fn main() -> ExitCode {
    quiet_display_probe();
    match real_main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Headless rendering needs no display, but the graphics stack probes for a Wayland one
/// (libwayland, loaded by Mesa's EGL and Vulkan drivers), and on a machine without a desktop
/// session, where `XDG_RUNTIME_DIR` is not set, that probe prints `error: XDG_RUNTIME_DIR is
/// invalid or not set in the environment.`: an error line on a healthy machine. So point it
/// at the temporary folder, once, before any thread starts; nothing of ours reads it, and an
/// absolute path the user set is kept (libwayland refuses any other value the same way).
fn quiet_display_probe() {
    let set = std::env::var_os("XDG_RUNTIME_DIR");
    if !set.is_some_and(|dir| std::path::Path::new(&dir).is_absolute()) {
        std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    }
}

fn real_main() -> Result<()> {
    let cli = Cli::parse();
    if let Some(bytes) = cli.max_memory {
        hetsim_scene::budget::set_max_memory(bytes);
    }
    match cli.command {
        Cmd::Run {
            scenario,
            seed,
            duration,
            out,
            force,
            record,
            record_encoding,
            dump_frames,
            no_render,
            camera_profile,
            open_loop,
            backend,
            adapter,
        } => {
            let mut loaded = load_scenario(
                &scenario,
                &LoadOptions {
                    robot_files: None,
                    seed,
                    duration_secs: duration,
                },
            )?;
            exec::set_camera_profile(&mut loaded, camera_profile.as_deref());
            let render = (!no_render).then_some(render_options(backend, adapter));
            exec::execute(
                &loaded,
                &exec::Job {
                    out: out.as_deref(),
                    record: recording(record.as_deref(), &record_encoding),
                    render,
                    dump: dump_frames.then_some((None, None)),
                    open_loop,
                    quiet: false,
                    memory: None,
                    replace: force,
                    record_anyway: force,
                },
            )?;
        }
        Cmd::Frames {
            scenario,
            from,
            to,
            cameras,
            camera_profile,
            seed,
            out,
            force,
            backend,
            adapter,
        } => exec::frames(
            &scenario,
            (from, to),
            (cameras, camera_profile.as_deref()),
            seed,
            (out, force),
            render_options(backend, adapter),
        )?,
        Cmd::Localize {
            scenario,
            seeds,
            out,
            backend,
            adapter,
        } => study::localize(&scenario, seeds, out, render_options(backend, adapter))?,
        Cmd::Replay {
            source,
            robots,
            out,
            force,
            set,
            scenario,
            duration,
            memory_trace,
            withhold_truth,
        } => replay_recording(
            replay::ReplayArgs {
                source,
                robots,
                out,
                replace: force,
                set,
                scenario,
                duration,
                quiet: false,
                memory: None,
                withhold_truth,
            },
            memory_trace,
        )?,
        Cmd::Validate { files } => validate(&files)?,
        Cmd::Report {
            what,
            run,
            out,
            jobs,
        } => study::report(&what, run, out, jobs)?,
        Cmd::Sweep(args) => study::sweep(args)?,
        Cmd::Regress { update, scenarios } => study::regress(update, scenarios)?,
        Cmd::Bench {
            scenarios,
            sim_secs,
            coverage,
            sensors,
            render,
            vision,
            slam,
            replay,
            out,
            json,
        } => {
            let figures = if replay {
                bench_replay::replay(&scenarios[0], sim_secs, out.as_deref())?
            } else if slam {
                bench::slam()
            } else if vision {
                bench::vision(&scenarios[0])?
            } else if render {
                bench::render(&scenarios, &hetsim_render::RenderOptions::default())?
            } else if sensors {
                bench::sensors(&scenarios, sim_secs)?
            } else if coverage {
                bench::coverage(&scenarios)?
            } else {
                bench::physics(&scenarios, sim_secs)?
            };
            figures.print(json);
        }
    }
    Ok(())
}

/// The renderer options `--backend` and `--adapter` choose.
fn render_options(
    backend: Option<String>,
    adapter: Option<String>,
) -> hetsim_render::RenderOptions {
    hetsim_render::RenderOptions {
        backend,
        adapter,
        anisotropy: None,
    }
}

/// The recording `--record` and `--record-encoding` ask for, if any.
fn recording<'a>(
    record: Option<&'a Path>,
    record_encoding: &str,
) -> Option<(&'a Path, hetsim_io::RecordEncoding)> {
    record.map(|p| {
        let encoding = if record_encoding == "json" {
            hetsim_io::RecordEncoding::Json
        } else {
            hetsim_io::RecordEncoding::Ros2
        };
        (p, encoding)
    })
}

/// `hetsim replay`: replays `args` (its memory trace kept when `memory_trace` names a file,
/// then written there) and prints `results:` and `digest:`.
fn replay_recording(args: replay::ReplayArgs<'_>, memory_trace: Option<PathBuf>) -> Result<()> {
    let trace = exec::MemoryTrace::default();
    let files = replay::replay(&replay::ReplayArgs {
        memory: memory_trace.is_some().then_some(&trace),
        ..args
    })?;
    if let Some(path) = memory_trace {
        exec::write_memory_trace(&path, &trace.into_inner().expect("memory trace lock"))?;
    }
    println!("results: {}", files.dir.display());
    println!("digest: {}", files.digest);
    Ok(())
}

/// `hetsim validate`: loads each scenario or robot file, printing `ok:` for each.
fn validate(files: &[PathBuf]) -> Result<()> {
    anyhow::ensure!(
        !files.is_empty(),
        "name at least one scenario or robot file"
    );
    for f in files {
        if is_robot_file(f) {
            load_robot_model(f, 1e-3)?;
        } else {
            load_scenario(f, &LoadOptions::default())?;
        }
        println!("ok: {}", f.display());
    }
    Ok(())
}

/// A robot file is one whose folder is named `models`, or that declares `[body]`.
fn is_robot_file(path: &std::path::Path) -> bool {
    path.parent()
        .and_then(|p| p.file_name())
        .is_some_and(|n| n == "models")
        || std::fs::read_to_string(path).is_ok_and(|t| t.lines().any(|l| l.trim() == "[body]"))
}
