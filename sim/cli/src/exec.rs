//! Running one scenario and writing its results: `hetsim run` and `hetsim frames`.

use anyhow::{Context, Result};
use hetsim_core::lock::FolderLock;
use hetsim_io::record::{RecordEncoding, Recorder};
use hetsim_io::FrameDump;
use hetsim_render::RenderOptions;
use hetsim_scene::{load_scenario, LoadOptions, Scenario};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// Window and camera filter of a frame dump.
pub type DumpSpec = (Option<(f64, f64)>, Option<Vec<String>>);

/// What to do besides running.
pub struct Job<'a> {
    /// Results folder (default under `results/runs/`).
    pub out: Option<&'a Path>,
    /// MCAP recording, and its encoding.
    pub record: Option<(&'a Path, RecordEncoding)>,
    /// Render the cameras on this adapter choice.
    pub render: Option<RenderOptions>,
    /// Dump frames (window, cameras).
    pub dump: Option<DumpSpec>,
    /// SLAM stacks open loop.
    pub open_loop: bool,
    /// No progress bar (runs of a sweep, which shows its own).
    pub quiet: bool,
    /// Where to append (sim seconds, resident memory in MiB) at each progress report.
    pub memory: Option<&'a MemoryTrace>,
    /// Replace another run's results in `out` (otherwise refused; the same run's are
    /// rewritten).
    pub replace: bool,
    /// Record even where the recording's estimated size exceeds the free space.
    pub record_anyway: bool,
}

/// Claims the results folder `out` for `scenario`'s run before it starts: refused while
/// another process writes it ([`FolderLock`]) or when it holds another run's results and
/// `replace` is not given ([`hetsim_eval::results::check_destination`]), so that neither is
/// found out only when a long run ends. The claim is released when dropped.
pub fn claim(out: &Path, scenario: &Scenario, replace: bool) -> Result<FolderLock> {
    let lock = FolderLock::take(out)?;
    hetsim_eval::results::check_destination(out, scenario, replace)?;
    Ok(lock)
}

/// `--camera-profile`: `realistic` or `perfect` in place of the scenario's own (clap has
/// checked the word); the manifest's resolved scenario records what ran.
pub fn set_camera_profile(scenario: &mut Scenario, profile: Option<&str>) {
    match profile {
        Some("perfect") => scenario.file.camera_profile = hetsim_scene::CameraProfile::Perfect,
        Some("realistic") => scenario.file.camera_profile = hetsim_scene::CameraProfile::Realistic,
        _ => {}
    }
}

/// A run's resident memory against sim time, sampled at each progress report.
pub type MemoryTrace = std::sync::Mutex<Vec<(f64, f64)>>;

/// Appends (sim seconds, this process's resident memory in MiB) to a trace, if given.
pub fn sample_memory(trace: Option<&MemoryTrace>, sim_secs: f64) {
    if let (Some(t), Some(rss)) = (trace, resident_mib()) {
        t.lock().expect("memory trace lock").push((sim_secs, rss));
    }
}

/// This process's resident set (`VmRSS` of /proc/self/status), MiB; `None` off Linux.
pub fn resident_mib() -> Option<f64> {
    status_mib("VmRSS:")
}

/// This process's peak resident set so far (`VmHWM`), MiB; `None` off Linux.
pub fn peak_resident_mib() -> Option<f64> {
    status_mib("VmHWM:")
}

/// A memory trace as CSV (`sim_s,rss_mib`), then the process's peak as `peak,<MiB>`.
pub fn write_memory_trace(path: &Path, trace: &[(f64, f64)]) -> Result<()> {
    let mut csv = String::from("sim_s,rss_mib\n");
    for (t, m) in trace {
        csv.push_str(&format!("{t:.2},{m:.1}\n"));
    }
    csv.push_str(&format!(
        "peak,{:.1}\n",
        peak_resident_mib().unwrap_or(f64::NAN)
    ));
    hetsim_core::files::write_atomic(path, csv.as_bytes())?;
    Ok(())
}

/// A `kB` line of /proc/self/status, in MiB. Hand-written on purpose: the `memory-stats`
/// crate reports the current resident and virtual sizes but not the kernel's high-water mark
/// (`VmHWM`), which the recorded peaks need, and both come from the same line format.
fn status_mib(key: &str) -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix(key))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kb / 1024.0)
}

/// `hetsim frames`: renders and writes the frames of a time window.
pub fn frames(
    scenario: &Path,
    (from, to): (f64, f64),
    (cameras, camera_profile): (Option<String>, Option<&str>),
    seed: Option<u64>,
    (out, replace): (Option<PathBuf>, bool),
    render: RenderOptions,
) -> Result<()> {
    anyhow::ensure!(
        from.is_finite() && to.is_finite() && from >= 0.0 && from <= to,
        "--from {from} --to {to}: expected 0 <= from <= to seconds"
    );
    let dt = load_scenario(scenario, &LoadOptions::default())?
        .clock
        .dt_secs();
    let mut loaded = load_scenario(
        scenario,
        &LoadOptions {
            robot_files: None,
            seed,
            duration_secs: Some(to.max(dt)),
        },
    )?;
    set_camera_profile(&mut loaded, camera_profile);
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
        &Job {
            out: Some(&out),
            record: None,
            render: Some(render),
            dump: Some((Some((from, to)), list)),
            open_loop: false,
            quiet: false,
            memory: None,
            replace,
            record_anyway: false,
        },
    )
}

/// Runs a loaded scenario with the robot software its robots declare, evaluates it and
/// writes its results (and frames, and recording). Prints `results: DIR` and `digest: HEX`.
pub fn execute(loaded: &Scenario, job: &Job<'_>) -> Result<()> {
    let files = run_scenario(loaded, job)?;
    println!("results: {}", files.dir.display());
    println!("digest: {}", files.digest);
    Ok(())
}

/// What [`execute`] does, printing nothing: the results folder and digest.
pub fn run_scenario(loaded: &Scenario, job: &Job<'_>) -> Result<hetsim_eval::RunFiles> {
    let bar = if job.quiet {
        ProgressBar::hidden()
    } else {
        run_progress_bar(&loaded.file.name)
    };
    let _claim = job
        .out
        .map(|out| claim(out, loaded, job.replace))
        .transpose()?;
    // Without rendering a recording holds no images, and the estimate is of images.
    if let (Some((path, RecordEncoding::Ros2)), Some(_)) = (job.record, &job.render) {
        check_recording_fits(path, loaded, job.record_anyway)?;
    }
    let start = crate::bench::wall_clock();
    let clock = loaded.clock;
    let mut recorder = job
        .record
        .map(|(path, encoding)| Recorder::create(path, encoding))
        .transpose()?;
    if let Some(r) = recorder.as_mut() {
        r.set_open_loop(job.open_loop);
    }
    let frames_only = job
        .dump
        .as_ref()
        .is_some_and(|(window, cameras)| window.is_some() || cameras.is_some());
    let staging = PathBuf::from(
        job.out
            .and_then(|o| o.parent())
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("results/runs")),
    )
    .join(format!(".frames-{}-{}", std::process::id(), {
        // Several runs of one process (a sweep's) each stage their own frames.
        static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    }));
    let mut dumper = job
        .dump
        .clone()
        .map(|(window, cameras)| FrameDump::new(&staging, window, cameras));
    let options = hetsim_engine::RunOptions {
        recorder: recorder
            .as_mut()
            .map(|r| r as &mut dyn hetsim_engine::RunRecorder),
        render: job.render.clone(),
        dump: dumper
            .as_mut()
            .map(|d| d as &mut dyn hetsim_engine::FrameSink),
        frames_only,
    };
    let stacks = hetsim_stacks::build_stacks(loaded, job.open_loop);
    let result = hetsim_engine::run(
        loaded,
        stacks,
        |tick, total| {
            bar.set_length(total);
            bar.set_position(tick);
            let sim = clock.time_secs(tick);
            sample_memory(job.memory, sim);
            let wall = start.elapsed().as_secs_f64().max(1e-9);
            bar.set_message(format!(
                "{sim:.1} / {:.1} s sim, {:.2}x real time",
                clock.time_secs(total),
                sim / wall
            ));
        },
        options,
    );
    bar.finish_and_clear();
    let written = (|| {
        let result = result?;
        if let Some(r) = recorder {
            let path = r.finish()?;
            eprintln!("recorded: {}", path.display());
        }
        let metrics = hetsim_eval::Metrics::compute(loaded, &result)?;
        let wall = start.elapsed().as_secs_f64();
        let timing = hetsim_eval::manifest::Timing {
            frames_written: Some(dumper.as_ref().map_or(0, |d| d.written())),
            realtime_factor: result.sim_secs / wall.max(1e-9),
            replay_of: None,
            sim_secs: result.sim_secs,
            threads: Some(rayon_threads()),
            wall_secs: wall,
        };
        let files = hetsim_eval::write_run(
            loaded,
            result,
            &metrics,
            job.out,
            &timing,
            dumper.is_some().then_some(staging.as_path()),
            job.replace,
        )
        .context("writing results")?;
        anyhow::Ok(files)
    })();
    let files = match written {
        Ok(f) => f,
        Err(e) => {
            // Nothing half-written stays behind: staged frames, an unfinished recording.
            let _ = std::fs::remove_dir_all(&staging);
            if let Some((path, _)) = job.record {
                let _ = std::fs::remove_file(Recorder::partial_path(path));
            }
            return Err(e);
        }
    };
    Ok(files)
}

/// Refuses, before the run, a recording whose estimated size
/// ([`hetsim_io::record::estimated_bytes`]) exceeds the free space where it goes, unless
/// `force` (the estimate may be pessimistic for a scene that compresses well).
fn check_recording_fits(path: &Path, loaded: &Scenario, force: bool) -> Result<()> {
    use hetsim_core::files::{free_bytes, human_bytes};
    let need = hetsim_io::record::estimated_bytes(loaded);
    if let Some(free) = free_bytes(path) {
        anyhow::ensure!(
            force || need <= free,
            "{}: the recording needs about {} (the cameras' images over {} s, compressed as a \
             village minute compresses), and {} is free there; free space, record elsewhere, \
             or give --force to try anyway",
            path.display(),
            human_bytes(need),
            loaded.duration_secs,
            human_bytes(free)
        );
    }
    Ok(())
}

pub fn rayon_threads() -> usize {
    std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// A run's progress on a terminal's stderr: sim time, real-time factor, time left; hidden
/// when stderr is not a terminal (piped, CI).
fn run_progress_bar(name: &str) -> ProgressBar {
    bar_with(name, "{prefix} [{bar:30}] {msg}, {eta} left")
}

/// A progress bar on a terminal's stderr; hidden when stderr is not a terminal.
pub fn progress_bar(name: &str) -> ProgressBar {
    bar_with(
        name,
        "{prefix} [{bar:40}] {percent}% sim  {elapsed} elapsed, {eta} left",
    )
}

fn bar_with(name: &str, template: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(name.to_string());
    bar
}
