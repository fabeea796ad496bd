//! `hetsim sweep --slurm --submit` end to end on a real Slurm: a one-node cluster on this
//! machine (Debian's slurm-wlm with munge, started by `tests/slurm/cluster.sh`), a rendered
//! village sweep and a lab-mission sweep submitted as job arrays with dependent merge jobs,
//! and each merged folder byte for byte the folder the same sweep writes on one machine
//! (every file but the runs' wall-time `timing.json`).
//!
//! Needs root and slurm-wlm (`.ci/setup.sh` installs it, as the README's test command runs
//! it first); without them the test fails and says so, it does not pass silently.

use hetsim_tests::{hetsim, repo};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// The cluster of a test: stopped when the test ends, however it ends.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Self {
        let script = repo().join("tests/slurm/cluster.sh");
        let out = Command::new("bash")
            .arg(&script)
            .arg("start")
            .arg(dir)
            .output()
            .expect("bash runs");
        assert!(
            out.status.success(),
            "starting the test cluster failed (root and Debian's slurm-wlm and munge are needed; `bash .ci/setup.sh` installs them):\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        Self {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        }
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// `JobState` of every record of a job (an array has one per task).
    fn states(&self, job: &str) -> Vec<String> {
        let out = self
            .command("scontrol")
            .args(["show", "job", job, "-o"])
            .output()
            .expect("scontrol runs");
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| {
                l.split_whitespace()
                    .find_map(|f| f.strip_prefix("JobState="))
                    .map(str::to_string)
            })
            .collect()
    }

    /// Waits until every record of `job` is finished; panics on a failed one or after
    /// `limit`, with the job's logs.
    fn wait(&self, job: &str, logs: &Path, limit: Duration) -> Vec<String> {
        // Polled every half second (no wall clock in this workspace's code).
        let poll = Duration::from_millis(500);
        for _ in 0..=limit.as_millis() / poll.as_millis() {
            let states = self.states(job);
            let done = |s: &String| {
                matches!(
                    s.as_str(),
                    "COMPLETED"
                        | "FAILED"
                        | "CANCELLED"
                        | "TIMEOUT"
                        | "NODE_FAIL"
                        | "OUT_OF_MEMORY"
                )
            };
            if !states.is_empty() && states.iter().all(done) {
                let failed: Vec<&String> = states.iter().filter(|s| *s != "COMPLETED").collect();
                assert!(
                    failed.is_empty(),
                    "job {job}: {states:?}\n{}",
                    read_logs(logs)
                );
                return states;
            }
            std::thread::sleep(poll);
        }
        panic!(
            "job {job} not finished after {limit:?}: {:?}\n{}",
            self.states(job),
            read_logs(logs)
        );
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new("bash")
            .arg(repo().join("tests/slurm/cluster.sh"))
            .arg("stop")
            .arg(&self.dir)
            .status();
    }
}

fn read_logs(dir: &Path) -> String {
    let mut text = String::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        let mut paths: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
        paths.sort();
        for p in paths {
            text.push_str(&format!(
                "--- {}\n{}\n",
                p.display(),
                std::fs::read_to_string(&p).unwrap_or_default()
            ));
        }
    }
    text
}

fn write_sweep(dir: &Path, name: &str, body: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!("schema_version = 1\nname = \"{name}\"\nkind = \"run\"\n{body}"),
    )
    .unwrap();
    path
}

#[test]
fn village_and_lab_sweeps_through_slurm_merge_to_the_files_of_one_machine() {
    let tmp = tempfile::tempdir().unwrap();
    let cluster = Cluster::start(&tmp.path().join("cluster"));
    let sweeps = [
        // Rendered: both robots' stereo benches, VO and SLAM, over Ressac's image noise.
        write_sweep(
            tmp.path(),
            "village",
            &format!(
                "base = \"{}\"\nseeds = 2\nfirst_seed = 1\nduration_secs = 3.0\nmetrics = [\"estimates.vo/ressac.ate_m\", \"estimates.slam/ressac.ate_m\", \"estimates.vo/dala.rpe_1s_m\", \"messages.ressac/stereo/left\"]\n[axes]\n\"robots.ressac.sensors.stereo.pixel_noise_sigma\" = [1.0, 6.0]\n",
                repo().join("scenarios/village-short.toml").display()
            ),
        ),
        // The lab's mission (rendered grabs) over the children's compass noise: the sweep
        // whose one-machine folder `sweep_runs` checks (crate::shared).
        crate::shared::lab_sweep_file().to_path_buf(),
    ];
    // Submit both (3 array tasks each, 4 runs: shards of 2, 1 and 1 runs), then wait.
    let mut jobs = Vec::new();
    for file in &sweeps {
        let out = tmp.path().join(format!(
            "{}-slurm",
            file.file_stem().unwrap().to_string_lossy()
        ));
        let run = cluster
            .command(hetsim_tests::hetsim_bin().to_str().unwrap())
            .current_dir(repo())
            .args([
                "sweep",
                file.to_str().unwrap(),
                "--slurm",
                "--submit",
                "--shards",
                "3",
            ])
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&run.stdout).to_string();
        assert!(
            run.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let line = stdout
            .lines()
            .find_map(|l| l.strip_prefix("submitted: array job "))
            .unwrap_or_else(|| panic!("no job ids in {stdout}"));
        let (array, rest) = line.split_once(", merge job ").unwrap();
        let merge = rest.split_whitespace().next().unwrap();
        let script = std::fs::read_to_string(out.join("slurm/array.sbatch")).unwrap();
        assert!(script.contains("#SBATCH --array=1-3"), "{script}");
        jobs.push((file.clone(), out, array.to_string(), merge.to_string()));
    }
    for (file, out, array, merge) in &jobs {
        let logs = out.join("slurm/logs");
        let tasks = cluster.wait(array, &logs, Duration::from_secs(900));
        assert_eq!(tasks.len(), 3, "array {array}: one record per task");
        cluster.wait(merge, &logs, Duration::from_secs(300));

        // The same sweep on one machine: the lab's is shared with `sweep_runs`.
        let local = if file == crate::shared::lab_sweep_file() {
            crate::shared::lab_sweep_one_job().to_path_buf()
        } else {
            let local = tmp.path().join(format!(
                "{}-local",
                file.file_stem().unwrap().to_string_lossy()
            ));
            let ran = hetsim(
                &[
                    "sweep",
                    file.to_str().unwrap(),
                    "--jobs",
                    "2",
                    "--out",
                    local.to_str().unwrap(),
                ],
                &[],
            );
            assert!(
                ran.status.success(),
                "{}",
                String::from_utf8_lossy(&ran.stderr)
            );
            local
        };
        hetsim_tests::assert_same_sweep_folders(&local, out);
        // Four runs, each with its results folder, in both.
        let runs = std::fs::read_to_string(out.join("runs.csv")).unwrap();
        assert_eq!(runs.lines().count(), 5, "{runs}");
        let manifests = hetsim_tests::sweep_folder_files(out)
            .iter()
            .filter(|(n, _)| n.ends_with("manifest.json"))
            .count();
        assert_eq!(manifests, 4);
    }
}
