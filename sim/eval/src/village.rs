//! `hetsim report village RUN`: a village run's results as a page a reader can take in, for
//! `results/village/`: the accuracy of every estimate, the SLAM events with the errors before
//! and after them, the filters' consistency and counters, the radio, the run's speed, and the
//! Fig. 7 figures, all read from the run folder `hetsim run` wrote (nothing is re-run).

use crate::manifest::{Manifest, Timing};
use crate::slam::RobotSlam;
use crate::{EvalError, Metrics};
use hetsim_core::files::{write_dir_atomic, FileError};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Files to write: `(name, bytes)`.
type Files = Vec<(String, Vec<u8>)>;

/// One village run's folder, read back into the types it was written from.
struct RunFolder<'a> {
    path: &'a Path,
    metrics: Metrics,
    manifest: Manifest,
    timing: Option<Timing>,
}

impl<'a> RunFolder<'a> {
    /// Reads the run in `path`; a folder whose metrics hold no SLAM robots is no village run.
    fn read(path: &'a Path) -> Result<Self, EvalError> {
        let run = Self {
            path,
            metrics: Metrics::read(path)?,
            manifest: Manifest::read(path)?,
            timing: Timing::read(path)?,
        };
        run.slam()?;
        Ok(run)
    }

    /// The SLAM section of every robot, in name order.
    fn slam(&self) -> Result<&BTreeMap<String, RobotSlam>, EvalError> {
        self.metrics
            .slam
            .as_ref()
            .map(|s| &s.robots)
            .ok_or_else(|| EvalError::Content {
                path: self.path.join("metrics.json"),
                message: "no field `slam.robots` (is this a village run's results folder?)".into(),
            })
    }

    /// Whether any correction came from the emulated image matcher (an oracle the manifest
    /// lists); the robots' own image matching is earned.
    fn oracle_matches(&self) -> bool {
        self.manifest.has_image_match_oracle()
            && self.metrics.slam.iter().any(|s| {
                s.robots
                    .values()
                    .any(|r| r.events.iter().any(|e| e.kind == "image_match"))
            })
    }
}

/// Writes the report of the village run in `run` as the folder `out` (replaced whole,
/// atomically): `README.md`, the run's `metrics.json` and `manifest.json`, and its Fig. 7
/// figures; with several runs (seeds), their section and every run's files under `seeds/`.
/// Returns `out`.
pub fn village_report(runs: &[PathBuf], out: &Path) -> Result<PathBuf, EvalError> {
    let first = runs.first().ok_or_else(|| EvalError::Content {
        path: out.to_path_buf(),
        message: "no run folder to report".into(),
    })?;
    let run = RunFolder::read(first)?;
    let slam = run.slam()?;
    let oracle_matches = run.oracle_matches();
    let mut md = String::new();
    summary(&mut md, runs, &run);
    oracles_section(&mut md, &run.manifest);
    accuracy_section(&mut md, &run.metrics, slam, oracle_matches);
    events_section(&mut md, slam);
    matching_section(&mut md, slam);
    filters_section(&mut md, &run.metrics, slam);
    let mut files = vec![
        ("metrics.json".to_string(), copy(run.path, "metrics.json")?),
        (
            "manifest.json".to_string(),
            copy(run.path, "manifest.json")?,
        ),
    ];
    files.extend(figures_section(&mut md, run.path, slam, oracle_matches)?);
    if runs.len() > 1 {
        let (section, figures) = seeds::section(runs)?;
        md.push_str(&section);
        files.extend(figures);
        files.extend(seeds::run_files(runs)?);
    }
    files.push(("README.md".to_string(), md.into_bytes()));
    write_dir_atomic(out, &files, |_| Ok(()))?;
    Ok(out.to_path_buf())
}

/// The bytes of the file `name` in the run folder `run`.
fn copy(run: &Path, name: &str) -> Result<Vec<u8>, EvalError> {
    let path = run.join(name);
    Ok(std::fs::read(&path).map_err(FileError::at(&path))?)
}

/// The page's title and the run's table: seed, time, speed, adapter and digest.
fn summary(md: &mut String, runs: &[PathBuf], run: &RunFolder) {
    let manifest = &run.manifest;
    let _ = writeln!(md, "# {}: the cooperative SLAM run\n", manifest.scenario);
    let _ = writeln!(
        md,
        "Written by `hetsim report village {}` from the runs' `metrics.json` (the first \
         run's copied here, every run's under `seeds/`); every figure below is computed by the \
         evaluation from the robots' published estimates against the simulator's truth.\n",
        runs.iter()
            .map(|r| r.display().to_string())
            .collect::<Vec<_>>()
            .join(" ")
    );
    let _ = writeln!(md, "| | |\n|---|---|");
    let _ = writeln!(md, "| seed | {} |", manifest.seed);
    let _ = writeln!(md, "| sim time | {:.1} s |", run.metrics.sim_secs);
    if let Some(t) = &run.timing {
        let _ = writeln!(
            md,
            "| wall time | {:.1} s ({:.2}x real time{}) |",
            t.wall_secs,
            t.realtime_factor,
            t.threads
                .map_or(String::new(), |n| format!(", {n} threads"))
        );
    }
    if let Some(a) = &manifest.adapter {
        let _ = writeln!(md, "| adapter | {} ({}, {}) |", a.name, a.backend, a.driver);
    }
    let _ = writeln!(md, "| digest | `{}` |", manifest.digest);
}

/// The truth rule: what the robots were given that they could not have had.
fn oracles_section(md: &mut String, manifest: &Manifest) {
    if manifest.oracles.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "\n## Oracles in this run\n\nThe manifest lists what reached a robot from the \
         simulator's truth. A figure that rests on one is not earned by the robot \
         software.\n"
    );
    for o in &manifest.oracles {
        let _ = writeln!(md, "- `{}/{}` ({}): {}", o.robot, o.sensor, o.kind, o.gives);
    }
    if manifest.has_image_match_oracle() {
        let _ = writeln!(
            md,
            "\nThe `image_match` events below come from that oracle: the truth chooses \
             the key frame and measures the relative pose. Their corrections, and \
             whatever the team's graph carries from them to the other robot, rest on \
             truth; the rendezvous events come from a sensor with an honest noise model \
             and do not. The `oracle_pose` sensors drive the waypoint pilots only; the \
             SLAM stacks never read them \
             (`tests/tests/it/slam.rs`, \
             `the_slam_stack_computes_the_same_bytes_with_the_truth_withheld`)."
        );
    }
}

/// Every estimate's accuracy against the truth.
fn accuracy_section(
    md: &mut String,
    metrics: &Metrics,
    slam: &BTreeMap<String, RobotSlam>,
    oracle_matches: bool,
) {
    let _ = writeln!(
        md,
        "\n## Accuracy\n\nATE after SE(3) alignment of the whole trajectory (as evo's \
         `evo_ape --align`), RPE over 1 s, and the error of the last pose without alignment. \
         `slam` is the cooperative estimate (events and the radio), `slam-open` the chain of \
         sub-maps without events, `vo` the chained stereo VO. Without alignment, all three \
         are in Dala's frame: `slam-open` and `vo` where the robot's first link put its \
         first origin.\n"
    );
    let _ = writeln!(
        md,
        "| robot | estimate | path length m | ATE m | RPE 1 s m | final error m | rests on an oracle |\n|---|---|---|---|---|---|---|"
    );
    for robot in slam.keys() {
        for kind in ["slam", "slam-open", "vo"] {
            let Some(e) = metrics.estimates.get(&format!("{kind}/{robot}")) else {
                continue;
            };
            // The cooperative estimate carries every event the team's graph holds: with an
            // image-match oracle's link anywhere in it, every robot's estimate rests on it.
            let oracle = if kind == "slam" && oracle_matches {
                "**yes**: the image-match oracle's links"
            } else {
                "no"
            };
            let _ = writeln!(
                md,
                "| {robot} | {kind} | {:.1} | {:.3} | {:.4} | {:.3} | {oracle} |",
                e.length_m, e.ate_m, e.rpe_1s_m, e.final_error_m
            );
        }
    }
}

/// Each SLAM event with the robot's error before and after it.
fn events_section(md: &mut String, slam: &BTreeMap<String, RobotSlam>) {
    let _ = writeln!(
        md,
        "\n## Events\n\nEach event as the robot's SLAM handled it, with the robot's position \
         error (and altitude error) against the truth just before it and just after the \
         team's graph was optimized with it.\n"
    );
    let _ = writeln!(
        md,
        "| robot | kind | time s | with | error before -> after m | altitude error before -> after m |\n|---|---|---|---|---|---|"
    );
    for (robot, r) in slam {
        for e in &r.events {
            let _ = writeln!(
                md,
                "| {robot} | {} | {:.1} | {} | {:.3} -> {:.3} | {:.3} -> {:.3} |",
                e.kind,
                e.time_s,
                e.other,
                e.error_before_m,
                e.error_after_m,
                e.altitude_error_before_m,
                e.altitude_error_after_m
            );
        }
    }
}

/// The robots' image matching in one run: counters and each accepted link judged.
fn matching_section(md: &mut String, slam: &BTreeMap<String, RobotSlam>) {
    let _ = writeln!(
        md,
        "\n## Image matching\n\nThe robots' own matcher (`robots/vision/src/place.rs`): \
         attempts, matches accepted, rejected by the inlier count or by the Mahalanobis gate \
         against the graph's prediction; the passes the truth says could match (found / \
         missed / within 30 s of the robot's last match); key-frame bytes sent on the radio. \
         Then each accepted link against the truth: a link more than 2 m or 5 degrees off is \
         a false match.\n"
    );
    let _ = writeln!(
        md,
        "| robot | attempts | accepted | too few inliers | gated | false | passes found / missed / waiting | key frames made / received | key-frame bytes sent |\n|---|---|---|---|---|---|---|---|---|"
    );
    for (robot, r) in slam {
        let c = |k: &str| r.counters.get(k).copied().unwrap_or(0);
        let m = r.matching.clone().unwrap_or_default();
        let _ = writeln!(
            md,
            "| {robot} | {} | {} | {} | {} | {} | {} / {} / {} | {} / {} | {} |",
            c("match_attempts"),
            c("matches_accepted"),
            c("matches_too_few_inliers"),
            c("matches_gated"),
            m.false_matches,
            m.found,
            m.missed,
            m.waiting,
            c("keyframes"),
            c("keyframes_received"),
            c("keyframe_bytes_sent"),
        );
    }
    let _ = writeln!(
        md,
        "\n| robot | time s | key frame of | made at s | inliers | error m | error deg | NEES | false |\n|---|---|---|---|---|---|---|---|---|"
    );
    for (robot, r) in slam {
        for l in r.matching.iter().flat_map(|m| &m.links) {
            let _ = writeln!(
                md,
                "| {robot} | {:.1} | {} | {:.1} | {} | {:.3} | {:.3} | {:.2} | {} |",
                l.time_s,
                l.other,
                l.other_time_s,
                l.inliers.map_or("-".to_string(), |n| n.to_string()),
                l.error_m,
                l.error_deg,
                l.nees,
                if l.false_match { "**yes**" } else { "no" },
            );
        }
    }
}

/// The filters' consistency and counters, and the radio.
fn filters_section(md: &mut String, metrics: &Metrics, slam: &BTreeMap<String, RobotSlam>) {
    let _ = writeln!(
        md,
        "\n## The filters\n\nMean NEES of the robot pose over the run (6 degrees of freedom: \
         6 expected of a consistent estimate; one run's poses are correlated in time, so \
         Monte Carlo runs, not this mean alone, decide consistency), and the stacks' \
         counters.\n"
    );
    let _ = writeln!(
        md,
        "| robot | NEES mean | poses | sub-maps | point observations used / gated | line observations used / gated | lines initialized | unresolved links | graph shares sent / received |\n|---|---|---|---|---|---|---|---|---|"
    );
    for (robot, r) in slam {
        // A counter the stack never incremented is absent: shown as 0 only where the stack
        // counts it from the start (the graph's unresolved links), "-" otherwise.
        let c = |k: &str| {
            r.counters
                .get(k)
                .map_or_else(|| "-".to_string(), |n| n.to_string())
        };
        let _ = writeln!(
            md,
            "| {robot} | {:.2} | {} | {} | {} / {} | {} / {} | {} | {} | {} / {} |",
            r.nees_mean,
            r.nees_poses,
            r.submaps,
            c("observations_used"),
            c("observations_gated"),
            c("line_observations_used"),
            c("line_observations_gated"),
            c("lines_initialized"),
            c("unresolved_links"),
            c("shares_sent"),
            c("shares_received"),
        );
    }
    let radio = &metrics.comms;
    let _ = writeln!(
        md,
        "\nRadio: delivered {}, dropped_loss {}, dropped_range {}, dropped_unknown {}, sent {}\n",
        radio.delivered, radio.dropped_loss, radio.dropped_range, radio.dropped_unknown, radio.sent
    );
}

/// Fig. 7 of seed 000 per robot for the first run, and the figures' files.
fn figures_section(
    md: &mut String,
    run: &Path,
    slam: &BTreeMap<String, RobotSlam>,
    oracle_matches: bool,
) -> Result<Files, EvalError> {
    let _ = writeln!(
        md,
        "## Figures\n\nThe seed paper's Fig. 7 (seed 000, the hierarchical SLAM paper) per robot, \
         for the first run above: the top view at equal scales, and the altitude against time \
         with the events marked.\n"
    );
    let mut files = Vec::new();
    for robot in slam.keys() {
        let name = format!("fig7-{robot}.png");
        let bytes = copy(&run.join("plots"), &name)?;
        let _ = writeln!(md, "![Fig. 7, {robot}]({name})\n");
        if oracle_matches {
            let _ = writeln!(
                md,
                "*{robot}: the cooperative SLAM line includes the corrections of the \
                 image-match oracle (see \"Oracles in this run\"); the VO and open-loop \
                 lines do not.*\n"
            );
        }
        files.push((name, bytes));
    }
    Ok(files)
}

mod seeds;
pub use seeds::chi2_quantile;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::manifest::Oracle;
    use crate::slam::{EventMetrics, SlamMetrics};
    use crate::trajectory::Accuracy;

    /// An estimate's accuracy with every figure `a`, but its length.
    pub(super) fn accuracy(length_m: f64, a: f64) -> Accuracy {
        Accuracy {
            poses: 10,
            length_m,
            ate_m: a,
            ate_unaligned_m: 2.0 * a,
            rpe_1s_m: a,
            final_error_m: a,
        }
    }

    /// A robot's SLAM figures with these events, an empty NEES series and no counters.
    pub(super) fn robot(events: Vec<EventMetrics>) -> RobotSlam {
        RobotSlam {
            nees_mean: 1.0,
            nees_poses: 1,
            nees_series: Vec::new(),
            nees_axes: [1.0; 6],
            submaps: 1,
            events,
            counters: BTreeMap::new(),
            edge_drift: Default::default(),
            matching: None,
        }
    }

    /// The metrics of a village run: these robots' SLAM and these estimates.
    pub(super) fn metrics(
        robots: Vec<(&str, RobotSlam)>,
        estimates: Vec<(&str, Accuracy)>,
    ) -> Metrics {
        Metrics {
            ticks: 1,
            sim_secs: 600.0,
            records: 1,
            robots: Vec::new(),
            obstruction_ratio_requested: None,
            obstruction_ratio_realised: None,
            free_vertices: None,
            unreachable_vertices: None,
            solids: 0,
            messages: BTreeMap::new(),
            comms: hetsim_engine::comms::CommsStats {
                sent: 242,
                ..Default::default()
            },
            estimates: estimates
                .into_iter()
                .map(|(k, a)| (k.to_string(), a))
                .collect(),
            coverage: None,
            team: None,
            slam: Some(SlamMetrics {
                robots: robots
                    .into_iter()
                    .map(|(k, r)| (k.to_string(), r))
                    .collect(),
                joint: BTreeMap::new(),
            }),
            cameras: BTreeMap::new(),
        }
    }

    /// A run's manifest with this seed and these oracles.
    pub(super) fn manifest(seed: u64, oracles: Vec<Oracle>) -> Manifest {
        Manifest {
            adapter: None,
            build_sha256: String::new(),
            cameras: Vec::new(),
            digest: "ab".into(),
            dt_secs: 0.01,
            duration_secs: 600.0,
            files_sha256: BTreeMap::new(),
            hetsim_version: "0".into(),
            oracles,
            records: 1,
            resolved: serde_json::Value::Null,
            scenario: "village".into(),
            seed,
            stacks: Vec::new(),
        }
    }

    /// Writes a run folder holding `metrics` and `manifest` as JSON, and Fig. 7 of `robots`.
    pub(super) fn run_folder(dir: &Path, metrics: &impl serde::Serialize, manifest: &Manifest) {
        std::fs::create_dir_all(dir.join("plots")).unwrap();
        std::fs::write(
            dir.join("metrics.json"),
            serde_json::to_vec(metrics).unwrap(),
        )
        .unwrap();
        std::fs::write(
            dir.join("manifest.json"),
            serde_json::to_vec(manifest).unwrap(),
        )
        .unwrap();
        for robot in ["dala", "ressac"] {
            std::fs::write(dir.join(format!("plots/fig7-{robot}.png")), b"png").unwrap();
        }
    }

    fn image_match_oracle() -> Vec<Oracle> {
        vec![Oracle {
            gives: "truth".into(),
            kind: "image_match".into(),
            rate_hz: None,
            robot: "ressac".into(),
            sensor: "image_match".into(),
        }]
    }

    fn event(
        kind: &str,
        time_s: f64,
        other: &str,
        before: [f64; 2],
        after: [f64; 2],
    ) -> EventMetrics {
        EventMetrics {
            kind: kind.into(),
            time_s,
            other: other.into(),
            error_before_m: before[0],
            error_after_m: after[0],
            altitude_error_before_m: before[1],
            altitude_error_after_m: after[1],
        }
    }

    #[test]
    fn the_page_holds_the_runs_figures() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        let mut dala = robot(vec![event(
            "rendezvous",
            380.5,
            "ressac",
            [7.2765, 0.58],
            [7.2765, 0.58],
        )]);
        (dala.nees_mean, dala.nees_poses, dala.submaps) = (2.47, 5999, 32);
        dala.counters.insert("unresolved_links".into(), 3);
        let mut slam = accuracy(224.7, 2.144);
        (slam.rpe_1s_m, slam.final_error_m) = (0.004, 7.678);
        let m = metrics(vec![("dala", dala)], vec![("slam/dala", slam)]);
        run_folder(&run, &m, &manifest(3, image_match_oracle()));
        let out = tmp.path().join("village");
        village_report(std::slice::from_ref(&run), &out).unwrap();
        let md = std::fs::read_to_string(out.join("README.md")).unwrap();
        assert!(
            md.contains("| dala | slam | 224.7 | 2.144 | 0.0040 | 7.678 |"),
            "{md}"
        );
        assert!(
            md.contains("| dala | rendezvous | 380.5 | ressac | 7.277 -> 7.277 |"),
            "{md}"
        );
        assert!(md.contains("| dala | 2.47 | 5999 | 32 |"), "{md}");
        assert!(
            md.contains("| 3 | - / - |"),
            "unresolved links, absent counters: {md}"
        );
        assert!(md.contains("Radio: delivered 0, "), "{md}");
        assert!(md.contains("![Fig. 7, dala](fig7-dala.png)"));
        assert!(
            md.contains("- `ressac/image_match` (image_match): truth"),
            "{md}"
        );
        assert!(md.contains("rest on truth"), "{md}");
        assert_eq!(std::fs::read(out.join("fig7-dala.png")).unwrap(), b"png");
    }

    #[test]
    fn a_folder_that_is_no_village_run_is_refused_by_name_and_nothing_is_written() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        let mut no_slam = metrics(Vec::new(), Vec::new());
        no_slam.slam = None;
        run_folder(&run, &no_slam, &manifest(3, Vec::new()));
        let out = tmp.path().join("village");
        let err = village_report(std::slice::from_ref(&run), &out)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("metrics.json") && err.contains("slam.robots"),
            "{err}"
        );
        assert!(!out.exists());
        let err = village_report(&[tmp.path().join("none")], &out)
            .unwrap_err()
            .to_string();
        assert!(err.contains("metrics.json"), "{err}");
        // A robot's section with its events missing, or an unreadable timing.json, is refused
        // by name rather than reported as "no events" or without its wall time.
        let whole = metrics(vec![("dala", robot(Vec::new()))], Vec::new());
        let mut doc = serde_json::to_value(&whole).unwrap();
        doc["slam"]["robots"]["dala"]
            .as_object_mut()
            .unwrap()
            .remove("events");
        run_folder(&run, &doc, &manifest(3, Vec::new()));
        let err = village_report(std::slice::from_ref(&run), &out)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("metrics.json")
                && err.contains("slam.robots.dala")
                && err.contains("missing field `events`"),
            "{err}"
        );
        run_folder(&run, &whole, &manifest(3, Vec::new()));
        std::fs::write(run.join("timing.json"), b"{ not json").unwrap();
        let err = village_report(std::slice::from_ref(&run), &out)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("timing.json") && err.contains("line 1"),
            "{err}"
        );
        assert!(!out.exists());
        std::fs::remove_file(run.join("timing.json")).unwrap();
        assert!(
            village_report(std::slice::from_ref(&run), &out).is_ok(),
            "without timing.json it reports"
        );
    }

    #[test]
    fn estimates_that_carry_image_match_oracle_links_are_marked() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        let matched = event("image_match", 197.0, "dala", [48.8, 38.9], [0.77, 0.2]);
        let m = metrics(
            vec![
                ("dala", robot(Vec::new())),
                ("ressac", robot(vec![matched])),
            ],
            vec![
                ("slam/dala", accuracy(1.0, 1.0)),
                ("vo/dala", accuracy(1.0, 1.0)),
            ],
        );
        run_folder(&run, &m, &manifest(3, image_match_oracle()));
        let out = tmp.path().join("village");
        village_report(std::slice::from_ref(&run), &out).unwrap();
        let md = std::fs::read_to_string(out.join("README.md")).unwrap();
        // Dala made no image match itself, but its cooperative estimate carries Ressac's.
        assert!(
            md.contains("| dala | slam | 1.0 | 1.000 | 1.0000 | 1.000 | **yes**"),
            "{md}"
        );
        assert!(
            md.contains("| dala | vo | 1.0 | 1.000 | 1.0000 | 1.000 | no |"),
            "{md}"
        );
        assert!(
            md.contains("*dala: the cooperative SLAM line includes"),
            "{md}"
        );
    }
}
