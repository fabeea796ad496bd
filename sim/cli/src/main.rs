//! `hetsim`: run scenarios headless, validate files, measure speed.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use hetsim_engine::{regress, run, sweep, write_run};
use hetsim_scene::{load_robot_model, load_scenario, LoadOptions};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Deterministic multi-robot simulator for cooperative visual mapping.
#[derive(Parser)]
#[command(name = "hetsim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
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
        /// Also record every message, command and ground-truth pose to this MCAP file.
        #[arg(long)]
        record: Option<PathBuf>,
        /// Write every camera frame (EuRoC layout, with depth and poses) under frames/.
        #[arg(long)]
        dump_frames: bool,
        /// Do not render the cameras (no images reach the robots).
        #[arg(long)]
        no_render: bool,
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
        /// Master seed (default: the scenario's).
        #[arg(long)]
        seed: Option<u64>,
        /// Output folder (default: results/runs/<name>-seed<seed>-frames-<from>-<to>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Renderer backend: vulkan, gl or any (default: HETSIM_BACKEND, else any).
        #[arg(long)]
        backend: Option<String>,
        /// Use the adapter whose name contains this (default: HETSIM_ADAPTER, else any).
        #[arg(long)]
        adapter: Option<String>,
    },
    /// Localization from coverage-mission image databases (seed 002, Section V.B): runs the
    /// scenario's mission for seeds 1..=N (reusing runs already in the output folder),
    /// cross-validates their databases (WGOH and pixelwise), and localizes a child driving
    /// new random paths with the particle filter. Writes localization.json and .md.
    Localize {
        /// Scenario with a coverage mission (e.g. scenarios/lab.toml).
        scenario: PathBuf,
        /// Mapping runs (seeds 1..=N).
        #[arg(long, default_value_t = 10)]
        seeds: u64,
        /// Particle filter paths.
        #[arg(long, default_value_t = 5)]
        paths: usize,
        /// Grid moves per path.
        #[arg(long, default_value_t = 20)]
        steps: usize,
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
    /// Check scenario and robot files without running anything.
    Validate {
        /// Scenario files or robot files (robots/models/*.toml).
        files: Vec<PathBuf>,
    },
    /// Run a Monte Carlo sweep of coverage planning (grid level, no rendering), or
    /// `hetsim sweep merge SWEEP.toml SHARD_DIR... --out DIR` to join shards.
    Sweep {
        /// The sweep file, or `merge`.
        target: String,
        /// With `merge`: the sweep file, then the shard folders.
        more: Vec<PathBuf>,
        /// Parallel runs (default: all cores).
        #[arg(long)]
        jobs: Option<usize>,
        /// Output folder (default: results/runs/sweep-<name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Run only shard K of N (1-based), e.g. `--shard 2/4`.
        #[arg(long)]
        shard: Option<String>,
    },
    /// Write results/coverage-tables.md and its figures (`hetsim report coverage`): runs or
    /// resumes the table1 and table2 sweeps first.
    Report {
        /// What to report: `coverage`.
        what: String,
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
    /// Measure sim seconds per wall second (physics and ground truth only).
    Bench {
        /// Scenarios to measure.
        #[arg(default_values = ["scenarios/village.toml", "scenarios/indoor-grid-20.toml"])]
        scenarios: Vec<PathBuf>,
        /// Sim seconds to run each.
        #[arg(long, default_value_t = 120.0)]
        sim_secs: f64,
        /// Instead: time coverage planning of each scenario (median of 5).
        #[arg(long)]
        coverage: bool,
        /// Instead: time one laser scan, and a tick with and without the non-visual sensors.
        #[arg(long)]
        sensors: bool,
        /// Instead: frames per second with readback (1024x768 mono, 1024x768 stereo pairs,
        /// 120x88) on the adapter HETSIM_BACKEND / HETSIM_ADAPTER choose.
        #[arg(long)]
        render: bool,
        /// Instead: milliseconds per 1024x768 stereo frame for Harris, stereo matching and
        /// a VO step, on rendered village frames of the rover moving 6 cm per frame.
        #[arg(long)]
        vision: bool,
        /// Instead: the local EKF's prediction and point and line updates per frame against
        /// the number of mapped landmarks (synthetic, a fifth of them lines, every landmark
        /// observed once per frame).
        #[arg(long)]
        slam: bool,
    },
}

fn main() -> ExitCode {
    match real_main() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn real_main() -> Result<()> {
    match Cli::parse().command {
        Cmd::Run {
            scenario,
            seed,
            duration,
            out,
            record,
            dump_frames,
            no_render,
            open_loop,
            backend,
            adapter,
        } => {
            let loaded = load_scenario(
                &scenario,
                &LoadOptions {
                    seed,
                    duration_secs: duration,
                },
            )?;
            let render = (!no_render).then_some(hetsim_render::RenderOptions { backend, adapter });
            execute(
                &loaded,
                out.as_deref(),
                record.as_deref(),
                render,
                dump_frames.then_some((None, None)),
                open_loop,
            )?;
        }
        Cmd::Frames {
            scenario,
            from,
            to,
            cameras,
            seed,
            out,
            backend,
            adapter,
        } => {
            anyhow::ensure!(
                from.is_finite() && to.is_finite() && from >= 0.0 && from <= to,
                "--from {from} --to {to}: expected 0 <= from <= to seconds"
            );
            let loaded = load_scenario(
                &scenario,
                &LoadOptions {
                    seed,
                    duration_secs: Some(to.max(loaded_dt(&scenario)?)),
                },
            )?;
            let list = cameras.map(|c| {
                c.split(',')
                    .map(|s| s.trim().to_string())
                    .filter(|s| !s.is_empty())
                    .collect::<Vec<_>>()
            });
            let out = out.unwrap_or_else(|| {
                PathBuf::from("results/runs").join(format!(
                    "{}-seed{}-frames-{from}-{to}",
                    loaded.file.name, loaded.seed
                ))
            });
            execute(
                &loaded,
                Some(&out),
                None,
                Some(hetsim_render::RenderOptions { backend, adapter }),
                Some((Some((from, to)), list)),
                false,
            )?;
        }
        Cmd::Localize {
            scenario,
            seeds,
            paths,
            steps,
            out,
            backend,
            adapter,
        } => localize(
            &scenario,
            seeds,
            paths,
            steps,
            out,
            hetsim_render::RenderOptions { backend, adapter },
        )?,
        Cmd::Validate { files } => {
            anyhow::ensure!(
                !files.is_empty(),
                "name at least one scenario or robot file"
            );
            for f in &files {
                if is_robot_file(f) {
                    load_robot_model(f, 1e-3)?;
                } else {
                    load_scenario(f, &LoadOptions::default())?;
                }
                println!("ok: {}", f.display());
            }
        }
        Cmd::Report { what, jobs } => {
            anyhow::ensure!(
                what == "coverage",
                "unknown report {what:?}: the only report is `coverage`"
            );
            let jobs =
                jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            let bar = progress_bar("report");
            let path = hetsim_engine::report::coverage_report(
                std::path::Path::new("."),
                jobs,
                &|done, total| {
                    bar.set_length(total as u64);
                    bar.set_position(done as u64);
                },
            )
            .map_err(anyhow::Error::msg)?;
            bar.finish_and_clear();
            println!("results: {}", path.display());
        }
        Cmd::Sweep {
            target,
            more,
            jobs,
            out,
            shard,
        } => sweep(target, more, jobs, out, shard)?,
        Cmd::Regress { update, scenarios } => {
            let scenarios = if scenarios.is_empty() {
                regress::DEFAULT_SCENARIOS
                    .iter()
                    .map(|s| s.to_string())
                    .collect()
            } else {
                scenarios
            };
            let rows = regress::regress(std::path::Path::new("."), &scenarios, update)
                .map_err(anyhow::Error::msg)?;
            println!("| scenario | metric | baseline | now | allowed | |");
            println!("|---|---|---|---|---|---|");
            for r in &rows {
                let status = if update {
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
            let moved = rows.iter().filter(|r| r.moved()).count();
            anyhow::ensure!(moved == 0, "{moved} metric(s) moved beyond their tolerance; if the change is intended, run `hetsim regress --update` and commit the baselines");
            println!("regress: {} metrics within tolerance", rows.len());
        }
        Cmd::Bench { slam: true, .. } => bench_slam(),
        Cmd::Bench { vision: true, .. } => {
            use hetsim_render::{CameraView, Intrinsics, RenderOptions, Renderer};
            use hetsim_vision::{harris, segments, stereo, vo::StereoVo, Camera, Gray};
            let loaded = load_scenario(
                std::path::Path::new("scenarios/village.toml"),
                &LoadOptions::default(),
            )?;
            let mut renderer = Renderer::new(&loaded.world, &RenderOptions::default())
                .map_err(anyhow::Error::msg)?;
            let k = Intrinsics::from_hfov(1024, 768, 60.0);
            let cam = Camera {
                alpha_u: k.alpha_u,
                alpha_v: k.alpha_v,
                u0: k.u0,
                v0: k.v0,
            };
            let bench = stereo::Bench {
                camera: cam,
                baseline_m: 0.35,
            };
            let d = &loaded.robots[0].spec.start;
            let pair = |renderer: &mut Renderer, forward: f64| {
                let yaw = d.yaw_deg.to_radians();
                let (x, y) = (d.x + forward * yaw.cos(), d.y + forward * yaw.sin());
                let left = hetsim_msgs::pose_from_xyz_rpy(
                    [x, y, loaded.world.ground_z(x, y) + 1.4],
                    [0.0, 8f64.to_radians(), yaw],
                );
                let right = left * hetsim_msgs::pose_from_xyz_rpy([0.0, -0.35, 0.0], [0.0; 3]);
                let views: Vec<CameraView> = [left, right]
                    .iter()
                    .map(|m| CameraView::from_mount(k, m, [0.05, 3000.0]))
                    .collect();
                let f = renderer.render(&views);
                (
                    Gray::from_rgb(1024, 768, &f[0].rgb),
                    Gray::from_rgb(1024, 768, &f[1].rgb),
                )
            };
            let frames: Vec<(Gray, Gray)> = (0..11)
                .map(|i| pair(&mut renderer, 0.06 * i as f64))
                .collect();
            let (mut t_detect, mut t_stereo, mut t_vo) = (0.0, 0.0, 0.0);
            let (mut t_lsd, mut t_track, mut n_segments) = (0.0, 0.0, 0usize);
            let mut previous: Vec<segments::Segment> = Vec::new();
            let mut vo = StereoVo::new(bench);
            let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
            let mut t_vo_lost = 0.0;
            for (i, (l, r)) in frames.iter().enumerate() {
                let start = wall_clock();
                let corners = harris::detect(l, 0.005, 8);
                let chosen = harris::select_new(&corners, l.width, l.height, &[], 25, 8.0);
                t_detect += start.elapsed().as_secs_f64();
                let start = wall_clock();
                std::hint::black_box(stereo::match_stereo(
                    l,
                    r,
                    &bench,
                    &chosen,
                    [0.5, 120.0],
                    0.85,
                ));
                t_stereo += start.elapsed().as_secs_f64();
                let start = wall_clock();
                std::hint::black_box(vo.process(l, r, &mut rng));
                // The first pair only initializes; the second searches five times wider
                // (no velocity yet, as after a loss); the rest are steady-state tracking.
                match i {
                    0 => {}
                    1 => t_vo_lost = start.elapsed().as_secs_f64(),
                    _ => t_vo += start.elapsed().as_secs_f64(),
                }
                let start = wall_clock();
                let found = segments::detect(l, &segments::DetectParams::default());
                t_lsd += start.elapsed().as_secs_f64();
                n_segments += found.len();
                let start = wall_clock();
                for s in &previous {
                    std::hint::black_box(segments::track(l, s, &segments::TrackParams::default()));
                }
                t_track += start.elapsed().as_secs_f64();
                previous = found;
            }
            let n = frames.len() as f64 / 1e3;
            println!("| stage, per 1024x768 stereo frame | ms |");
            println!("|---|---|");
            println!(
                "| Harris + 3x3 selection (left image) | {:.1} |",
                t_detect / n
            );
            println!(
                "| stereo matching and triangulation | {:.1} |",
                t_stereo / n
            );
            println!(
                "| full VO step, steady state (detection, stereo, tracking, RANSAC + Gauss-Newton) | {:.1} |",
                t_vo / (n - 2e-3)
            );
            println!(
                "| full VO step without a velocity (start, or after a loss: 5x wider search) | {:.1} |",
                t_vo_lost * 1e3
            );
            println!(
                "| segment detection, LSD-class (left image; {:.0} segments of 60 px or more) | {:.1} |",
                n_segments as f64 / frames.len() as f64,
                t_lsd / n
            );
            println!(
                "| segment tracking (all of the previous frame's segments) | {:.1} |",
                t_track / (n - 1e-3)
            );
        }
        Cmd::Bench {
            scenarios,
            render: true,
            ..
        } => {
            use hetsim_render::{CameraView, Intrinsics, RenderOptions, Renderer};
            let mut printed = false;
            for s in &scenarios {
                let loaded = load_scenario(s, &LoadOptions::default())?;
                let mut renderer = Renderer::new(&loaded.world, &RenderOptions::default())
                    .map_err(anyhow::Error::msg)?;
                if !printed {
                    let a = renderer.adapter();
                    println!("adapter: {} ({}, {})\n", a.name, a.backend, a.driver);
                    println!("| scenario | 1024x768 frames/s | 1024x768 stereo pairs/s | 120x88 frames/s |");
                    println!("|---|---|---|---|");
                    printed = true;
                }
                let r = &loaded.robots[0].spec.start;
                let ground = loaded.world.ground_z(r.x, r.y);
                let mut rates = Vec::new();
                for (k, pair) in [
                    (Intrinsics::from_hfov(1024, 768, 60.0), false),
                    (Intrinsics::from_hfov(1024, 768, 60.0), true),
                    (Intrinsics::from_hfov(120, 88, 80.0), false),
                ] {
                    let frames = if k.width > 200 { 40 } else { 300 };
                    let views = |i: usize| {
                        let yaw = r.yaw_deg.to_radians() + 0.01 * i as f64;
                        let mount = hetsim_msgs::pose_from_xyz_rpy(
                            [r.x, r.y, ground + 1.2],
                            [0.0, 0.1, yaw],
                        );
                        let mut v = vec![CameraView::from_mount(k, &mount, [0.02, 3000.0])];
                        if pair {
                            let right =
                                mount * hetsim_msgs::pose_from_xyz_rpy([0.0, -0.35, 0.0], [0.0; 3]);
                            v.push(CameraView::from_mount(k, &right, [0.02, 3000.0]));
                        }
                        v
                    };
                    renderer.render(&views(0));
                    let start = wall_clock();
                    for i in 0..frames {
                        std::hint::black_box(renderer.render(&views(i)));
                    }
                    rates.push(frames as f64 / start.elapsed().as_secs_f64());
                }
                println!(
                    "| {} | {:.1} | {:.1} | {:.1} |",
                    loaded.file.name, rates[0], rates[1], rates[2]
                );
            }
        }
        Cmd::Bench {
            scenarios,
            sensors: true,
            sim_secs,
            ..
        } => {
            println!("| scenario | laser scan (481 rays) us | tick, all sensors us | tick, physics + truth only us |");
            println!("|---|---|---|---|");
            for s in &scenarios {
                let loaded = load_for(s, sim_secs)?;
                let mut physics = hetsim_physics::Physics::for_scenario(
                    &loaded,
                    &hetsim_core::Streams::new(loaded.seed),
                );
                physics.step();
                let origin = physics.pose(0).translation.vector;
                let o = [origin.x, origin.y, origin.z + 0.3];
                let scans = 200;
                let start = wall_clock();
                let mut hits = 0usize;
                for _ in 0..scans {
                    for b in 0..481 {
                        let a = (-120.0 + 0.5 * b as f64).to_radians();
                        hits += usize::from(
                            physics
                                .cast_ray(o, [a.cos(), a.sin(), 0.0], 20.0, Some(0))
                                .is_some(),
                        );
                    }
                }
                let scan_us = start.elapsed().as_secs_f64() * 1e6 / scans as f64;
                let start = wall_clock();
                let result = run(&loaded, |_, _| {}, hetsim_engine::RunOptions::default())?;
                let with = start.elapsed().as_secs_f64() * 1e6 / result.metrics.ticks as f64;
                let bare = without_sensors(loaded.clone());
                let start = wall_clock();
                let result = run(&bare, |_, _| {}, hetsim_engine::RunOptions::default())?;
                let without = start.elapsed().as_secs_f64() * 1e6 / result.metrics.ticks as f64;
                println!(
                    "| {} | {scan_us:.0} | {with:.1} | {without:.1} |",
                    loaded.file.name
                );
                std::hint::black_box(hits);
            }
        }
        Cmd::Bench {
            scenarios,
            coverage: true,
            ..
        } => {
            println!(
                "| scenario | vertices | parent vertices | timesteps | planning ms (median of 5) |"
            );
            println!("|---|---|---|---|---|");
            for s in &scenarios {
                let loaded = load_scenario(s, &LoadOptions::default())?;
                let mut times = Vec::new();
                let mut last = None;
                for _ in 0..5 {
                    let start = wall_clock();
                    last = Some(
                        hetsim_engine::coverage::plan_scenario(&loaded)
                            .map_err(anyhow::Error::msg)?,
                    );
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                }
                times.sort_by(f64::total_cmp);
                let (_, _, plan) = last.expect("five plans");
                println!(
                    "| {} | {} | {} | {} | {:.1} |",
                    loaded.file.name,
                    plan.vertices,
                    plan.parent_vertices.len(),
                    plan.mapping_timesteps + plan.coordination_timesteps,
                    times[2]
                );
            }
        }
        Cmd::Bench {
            scenarios,
            sim_secs,
            ..
        } => {
            println!("| scenario | robots | sim s | wall s | sim s / wall s |");
            println!("|---|---|---|---|---|");
            for s in &scenarios {
                let loaded = load_for(s, sim_secs)?;
                // Physics and ground truth only: no sensor models.
                let loaded = without_sensors(loaded);
                let start = wall_clock();
                let result = run(&loaded, |_, _| {}, hetsim_engine::RunOptions::default())?;
                let wall = start.elapsed().as_secs_f64();
                println!(
                    "| {} | {} | {:.0} | {:.3} | {:.0} |",
                    loaded.file.name,
                    loaded.robots.len(),
                    result.metrics.sim_secs,
                    wall,
                    result.metrics.sim_secs / wall
                );
            }
        }
    }
    Ok(())
}

fn sweep(
    target: String,
    more: Vec<PathBuf>,
    jobs: Option<usize>,
    out: Option<PathBuf>,
    shard: Option<String>,
) -> Result<()> {
    let merging = target == "merge";
    let (file, shards) = if merging {
        let (f, rest) = more
            .split_first()
            .context("usage: hetsim sweep merge SWEEP.toml SHARD_DIR... --out DIR")?;
        (f.clone(), rest.to_vec())
    } else {
        anyhow::ensure!(
            more.is_empty(),
            "unexpected arguments after the sweep file: {more:?}"
        );
        (PathBuf::from(&target), Vec::new())
    };
    let loaded = sweep::load_sweep(&file).map_err(anyhow::Error::msg)?;
    let out = out.unwrap_or_else(|| {
        PathBuf::from("results/runs").join(format!("sweep-{}", loaded.file.name))
    });
    let summary = if merging {
        anyhow::ensure!(!shards.is_empty(), "name the shard folders to merge");
        sweep::merge(&loaded, &out, &shards).map_err(anyhow::Error::msg)?
    } else {
        let shard = match shard {
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
        let jobs =
            jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
        let bar = progress_bar(&loaded.file.name);
        let summary = sweep::run_sweep(&loaded, &out, jobs, shard, &|done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        })
        .map_err(anyhow::Error::msg)?;
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

/// A scenario with its own seed, run for `secs` sim seconds (benchmarks).
fn load_for(path: &std::path::Path, secs: f64) -> Result<hetsim_scene::Scenario> {
    Ok(load_scenario(
        path,
        &LoadOptions {
            seed: None,
            duration_secs: Some(secs),
        },
    )?)
}

/// The scenario with every robot's sensors (cameras included) removed: physics and ground
/// truth only.
fn without_sensors(mut scenario: hetsim_scene::Scenario) -> hetsim_scene::Scenario {
    for r in &mut scenario.robots {
        r.model.sensors.clear();
    }
    scenario
}

/// The scenario's tick, for a run that must last at least one tick.
fn loaded_dt(scenario: &std::path::Path) -> Result<f64> {
    Ok(load_scenario(scenario, &LoadOptions::default())?
        .clock
        .dt_secs())
}

/// Window and camera filter of a frame dump.
type DumpSpec = (Option<(f64, f64)>, Option<Vec<String>>);

/// Runs a loaded scenario and writes its results (and frames, and recording).
fn execute(
    loaded: &hetsim_scene::Scenario,
    out: Option<&std::path::Path>,
    record: Option<&std::path::Path>,
    render: Option<hetsim_render::RenderOptions>,
    dump: Option<DumpSpec>,
    open_loop: bool,
) -> Result<()> {
    let bar = progress_bar(&loaded.file.name);
    let start = wall_clock();
    let mut recorder = match record {
        Some(path) => {
            Some(hetsim_engine::record::Recorder::create(path).map_err(anyhow::Error::msg)?)
        }
        None => None,
    };
    let frames_only = dump
        .as_ref()
        .is_some_and(|(window, cameras)| window.is_some() || cameras.is_some());
    let staging = PathBuf::from(
        out.and_then(|o| o.parent())
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(std::path::Path::new("results/runs")),
    )
    .join(format!(".frames-{}", std::process::id()));
    let mut dumper = dump
        .map(|(window, cameras)| hetsim_engine::frames::FrameDump::new(&staging, window, cameras));
    let options = hetsim_engine::RunOptions {
        recorder: recorder.as_mut(),
        render,
        dump: dumper.as_mut(),
        frames_only,
        open_loop,
    };
    let result = run(
        loaded,
        |tick, total| {
            bar.set_length(total);
            bar.set_position(tick);
        },
        options,
    );
    bar.finish_and_clear();
    let result = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&staging);
            return Err(e.into());
        }
    };
    if let Some(r) = recorder {
        let path = r.finish().map_err(anyhow::Error::msg)?;
        eprintln!("recorded: {}", path.display());
    }
    let wall = start.elapsed().as_secs_f64();
    let timing = serde_json::json!({
        "wall_secs": wall,
        "sim_secs": result.metrics.sim_secs,
        "realtime_factor": result.metrics.sim_secs / wall.max(1e-9),
        "threads": rayon_threads(),
        "frames_written": dumper.as_ref().map_or(0, |d| d.written()),
    });
    let files = write_run(
        loaded,
        result,
        out,
        timing,
        dumper.is_some().then_some(staging.as_path()),
    );
    if files.is_err() {
        let _ = std::fs::remove_dir_all(&staging);
    }
    let files = files.context("writing results")?;
    println!("results: {}", files.dir.display());
    println!("digest: {}", files.digest);
    Ok(())
}

/// `hetsim bench --slam`: EKF time per frame against the number of landmarks.
fn bench_slam() {
    use hetsim_slam::ekf::LocalMap;
    use hetsim_slam::idp::Sensor;
    use hetsim_slam::lines::LinePrior;
    use nalgebra::{Isometry3, Matrix3, Matrix6, Translation3, UnitQuaternion, Vector2};
    let r = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    let sensor = Sensor::new(
        hetsim_vision::Camera {
            alpha_u: 887.0,
            alpha_v: 887.0,
            u0: 511.5,
            v0: 383.5,
        },
        &Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 1.4),
            UnitQuaternion::from_matrix(&r),
        ),
    );
    println!("| landmarks in the local map (points + lines) | state size | ms per frame (prediction + an update per landmark) | us per point update | us per line update |");
    println!("|---|---|---|---|---|");
    for n in [10usize, 25, 50, 100] {
        // A fifth of the landmarks are lines, about what the village's sub-maps hold.
        let lines = n / 5;
        let mut map = LocalMap::new();
        for k in 0..n - lines {
            let px = Vector2::new(40.0 + (k * 97 % 940) as f64, 40.0 + (k * 61 % 680) as f64);
            map.add_point(&sensor, &px, 1.0, 0.1, 0.2, k as u64);
        }
        let segment = |k: usize| {
            let a = Vector2::new(60.0 + (k * 131 % 800) as f64, 60.0 + (k * 89 % 560) as f64);
            (a, a + Vector2::new(120.0, 40.0 + (k * 37 % 80) as f64))
        };
        for k in 0..lines {
            let (a, b) = segment(k);
            map.add_line(&sensor, &a, &b, 1.0, &LinePrior::seed(), (n + k) as u64);
        }
        let frames = 20;
        let (mut points_s, mut lines_s) = (0.0, 0.0);
        let start = wall_clock();
        for f in 0..frames {
            map.predict(
                &Isometry3::translation(0.05, 0.0, 0.0),
                &Matrix6::from_diagonal_element(1e-6),
            );
            let t = wall_clock();
            for k in 0..map.points.len() {
                if let Some((pr, _)) = map.predict_point(&sensor, k, 1.0) {
                    let z = pr.pixel + Vector2::new(0.1 * (f % 3) as f64, -0.1);
                    std::hint::black_box(map.update(&sensor, k, &z, 1.0, 9.21));
                }
            }
            points_s += t.elapsed().as_secs_f64();
            let t = wall_clock();
            for j in 0..map.lines.len() {
                let (a, b) = segment(j);
                let shift = Vector2::new(0.0, 0.2 * (f % 3) as f64);
                std::hint::black_box(map.update_line(&sensor, j, &(a + shift), &b, 1.0, 9.21));
            }
            lines_s += t.elapsed().as_secs_f64();
            map.symmetrize();
        }
        let ms = start.elapsed().as_secs_f64() * 1e3 / frames as f64;
        let per = |total: f64, count: usize| total * 1e6 / (frames * count.max(1)) as f64;
        println!(
            "| {n} ({} + {}) | {} | {ms:.2} | {:.1} | {:.1} |",
            map.points.len(),
            map.lines.len(),
            map.x.len(),
            per(points_s, map.points.len()),
            per(lines_s, map.lines.len()),
        );
    }
}

/// `hetsim localize`: mapping runs, cross-validation, particle filter paths.
fn localize(
    scenario: &std::path::Path,
    seeds: u64,
    paths: usize,
    steps: usize,
    out: Option<PathBuf>,
    render: hetsim_render::RenderOptions,
) -> Result<()> {
    use hetsim_engine::localize::{cross_validate, load_database, particle_filter_path};
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
    let mut databases = Vec::new();
    let mut missions = Vec::new();
    for seed in 1..=seeds {
        let dir = out.join(format!("runs/seed-{seed}"));
        if dir.join("manifest.json").is_file() {
            eprintln!("seed {seed}: reusing {}", dir.display());
        } else {
            eprintln!("seed {seed}: running the mission");
            let loaded = load_scenario(
                scenario,
                &LoadOptions {
                    seed: Some(seed),
                    duration_secs: None,
                },
            )?;
            execute(&loaded, Some(&dir), None, Some(render.clone()), None, false)?;
        }
        let metrics: serde_json::Value = serde_json::from_slice(
            &std::fs::read(dir.join("metrics.json"))
                .with_context(|| format!("{}", dir.display()))?,
        )?;
        missions.push(metrics["team"].clone());
        databases.push(load_database(&dir).map_err(anyhow::Error::msg)?);
    }
    eprintln!("cross-validating {} databases", databases.len());
    let cross = cross_validate(&databases);
    let mut pf: Vec<hetsim_engine::localize::PathRun> = Vec::new();
    for p in 0..paths {
        eprintln!("particle filter path {}/{paths}", p + 1);
        let db = &databases[p % databases.len()];
        pf.extend(
            particle_filter_path(&base, db, steps, 1000 + p as u64, &render)
                .map_err(anyhow::Error::msg)?,
        );
    }
    let summary = hetsim_engine::localize::summarize(&missions, &cross, &pf);
    let json = serde_json::to_vec_pretty(&summary)?;
    let md = hetsim_engine::localize::markdown(&summary);
    for (name, bytes) in [
        ("localization.json", json),
        ("localization.md", md.clone().into_bytes()),
    ] {
        let tmp = out.join(format!(".{name}.partial"));
        std::fs::write(&tmp, bytes).with_context(|| tmp.display().to_string())?;
        std::fs::rename(&tmp, out.join(name))
            .with_context(|| out.join(name).display().to_string())?;
    }
    println!("{md}");
    println!("results: {}", out.display());
    Ok(())
}

/// A robot file is one whose folder is named `models`, or that declares `[body]`.
fn is_robot_file(path: &std::path::Path) -> bool {
    path.parent()
        .and_then(|p| p.file_name())
        .is_some_and(|n| n == "models")
        || std::fs::read_to_string(path).is_ok_and(|t| t.lines().any(|l| l.trim() == "[body]"))
}

/// Wall-clock start of a measurement. Wall time goes to `timing.json` and `hetsim bench`
/// only, never into anything the digest covers.
#[allow(clippy::disallowed_methods)]
fn wall_clock() -> Instant {
    Instant::now()
}

fn rayon_threads() -> usize {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// A progress bar on a terminal's stderr; hidden when stderr is not a terminal.
fn progress_bar(name: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix} [{bar:40}] {percent}% sim  {elapsed} elapsed, {eta} left",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(name.to_string());
    bar
}
