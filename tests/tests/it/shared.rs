//! Runs and sweeps that more than one test reads, made once per test process (the first test
//! to ask makes it; the others wait for it).
//!
//! - The lab's whole mission on Vulkan, recorded: golden's Vulkan run checks its digest and
//!   outputs, and the replay test replays its recording. Before, each made its own (about
//!   100 s of CPU, and 180 s with the recording), of the same scenario on the same adapter:
//!   the digest depends neither on the worker threads nor on the recording (DESIGN.md,
//!   determinism contract; golden checks the first, the replay test the second).
//! - A four-run lab sweep, one run at a time: `sweep_runs` compares its shards and its
//!   resumption with it, and `slurm` the cluster's folder (which before was compared with a
//!   local run of another four, about 50 s of CPU).

use hetsim_tests::{hetsim, hetsim_release, repo};
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::OnceLock;

/// A run made once for several tests: its results folder, its ROS 2 recording and what the
/// process printed.
pub struct SharedRun {
    pub out: PathBuf,
    pub recording: PathBuf,
    pub output: Output,
}

impl SharedRun {
    /// Whether the run found no adapter for its backend (a machine without that backend);
    /// the tests that read it then skip it or make their own run on another backend.
    pub fn had_no_adapter(&self) -> bool {
        !self.output.status.success()
            && String::from_utf8_lossy(&self.output.stderr).contains("no usable graphics adapter")
    }
}

/// `hetsim run scenarios/lab.toml --backend vulkan --record ...` on one worker thread (the
/// thread count golden's Vulkan runs use). Made in the target folder's test scratch space:
/// the replay test deletes the recording (2.2 GB) once it has read it; a run that never
/// reaches it (filtered, or failed) leaves it until the next test process. The recording
/// costs golden's own Vulkan run about 80 s of CPU, the replay test's run (180 s) saved.
pub fn recorded_lab_on_vulkan() -> &'static SharedRun {
    static RUN: OnceLock<SharedRun> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = fresh_dir("shared-lab-vulkan");
        let (out, recording) = (dir.join("lab-vulkan"), dir.join("lab.mcap"));
        let output = hetsim_release(
            &[
                "run",
                "scenarios/lab.toml",
                "--backend",
                "vulkan",
                "--record",
                recording.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ],
            &[("RAYON_NUM_THREADS", "1")],
        );
        SharedRun {
            out,
            recording,
            output,
        }
    })
}

/// A lab sweep cut to its first 120 sim seconds (rendered grabs, tracker, radio): two compass
/// noises on every c't-Bot x two seeds. The file only; [`lab_sweep_one_job`] runs it.
pub fn lab_sweep_file() -> &'static Path {
    static FILE: OnceLock<PathBuf> = OnceLock::new();
    FILE.get_or_init(|| {
        let file = fresh_dir("shared-lab-sweep").join("lab-runs.toml");
        std::fs::write(
            &file,
            format!(
                "schema_version = 1\nname = \"lab-runs\"\nkind = \"run\"\nbase = \"{}\"\nseeds = 2\nfirst_seed = 3\nduration_secs = 120.0\nmetrics = [\"team.imaged\", \"team.compass_heading_error_deg.mean\", \"robots.0.distance_m\", \"comms.sent\"]\n\n[axes]\n\"models.ctbot.sensors.compass.sigma_deg\" = [1.0, 16.0]\n",
                repo().join("scenarios/lab.toml").display()
            ),
        )
        .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        file
    })
}

/// The folder [`lab_sweep_file`]'s sweep writes one run at a time: `sweep_runs` checks its
/// rows and that shards, jobs and resumption give this folder; `slurm` that the cluster
/// gives it. Read only: a test that changes it works on a copy.
pub fn lab_sweep_one_job() -> &'static Path {
    // The outcome is kept, success or not: a failed sweep fails every test that reads it
    // without running it again.
    static FOLDER: OnceLock<(PathBuf, Output)> = OnceLock::new();
    let (folder, out) = FOLDER.get_or_init(|| {
        let folder = fresh_dir("shared-lab-sweep-jobs1").join("jobs1");
        let out = hetsim(
            &[
                "sweep",
                lab_sweep_file().to_str().unwrap(),
                "--jobs",
                "1",
                "--out",
                folder.to_str().unwrap(),
            ],
            &[],
        );
        (folder, out)
    });
    assert!(
        out.status.success(),
        "the shared lab sweep: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    folder
}

/// `name` in the target folder's test scratch space, emptied, for this test process alone
/// (`<name>-<pid>`: two test processes on one target folder keep apart). Folders of the
/// same name left by processes that have ended (a recording 2.2 GB) are removed first.
fn fresh_dir(name: &str) -> PathBuf {
    let scratch = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    let prefix = format!("{name}-");
    for entry in std::fs::read_dir(&scratch).into_iter().flatten().flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let ended = file_name
            .strip_prefix(&prefix)
            .and_then(|pid| pid.parse::<u32>().ok())
            .is_some_and(|pid| !Path::new(&format!("/proc/{pid}")).exists());
        if ended {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
    let dir = scratch.join(format!("{prefix}{}", std::process::id()));
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}
