//! `hetsim report village RUN`: a village run's results as a page a reader can take in, for
//! `results/village/`: the accuracy of every estimate, the SLAM events with the errors before
//! and after them, the filters' consistency and counters, the radio, the run's speed, and the
//! Fig. 7 figures, all read from the run folder `hetsim run` wrote (nothing is re-run).

use crate::EvalError;
use hetsim_core::files::{write_dir_atomic, FileError};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Reads `name` in the run folder as JSON.
fn read_json(run: &Path, name: &str) -> Result<Value, EvalError> {
    let path = run.join(name);
    let bytes = std::fs::read(&path).map_err(FileError::at(&path))?;
    serde_json::from_slice(&bytes).map_err(|e| EvalError::Content {
        path,
        message: format!("line {}: not JSON: {e}", e.line()),
    })
}

/// A field of a JSON document by its dotted path, or an error naming the file and the field.
fn field<'a>(doc: &'a Value, path: &Path, dotted: &str) -> Result<&'a Value, EvalError> {
    dotted
        .split('.')
        .try_fold(doc, |v, key| v.get(key))
        .ok_or_else(|| EvalError::Content {
            path: path.to_path_buf(),
            message: format!("no field `{dotted}` (is this a village run's results folder?)"),
        })
}

fn num(doc: &Value, path: &Path, dotted: &str) -> Result<f64, EvalError> {
    field(doc, path, dotted)?
        .as_f64()
        .ok_or_else(|| EvalError::Content {
            path: path.to_path_buf(),
            message: format!("field `{dotted}` is not a number"),
        })
}

/// Writes the report of the village run in `run` as the folder `out` (replaced whole,
/// atomically): `README.md`, the run's `metrics.json` and `manifest.json`, and its Fig. 7
/// figures; with several runs (seeds), their section and every run's files under `seeds/`.
/// Returns `out`.
pub fn village_report(runs: &[PathBuf], out: &Path) -> Result<PathBuf, EvalError> {
    let run = runs.first().ok_or_else(|| EvalError::Content {
        path: out.to_path_buf(),
        message: "no run folder to report".into(),
    })?;
    let run = run.as_path();
    let metrics_path = run.join("metrics.json");
    let metrics = read_json(run, "metrics.json")?;
    let manifest = read_json(run, "manifest.json")?;
    let manifest_path = run.join("manifest.json");
    // Wall time is outside the digest (timing.json): a run without it still reports, but
    // one whose timing.json is there and unreadable is refused like any other file.
    let timing = if run.join("timing.json").exists() {
        Some(read_json(run, "timing.json")?)
    } else {
        None
    };
    let slam = field(&metrics, &metrics_path, "slam.robots")?
        .as_object()
        .ok_or_else(|| EvalError::Content {
            path: metrics_path.clone(),
            message: "field `slam.robots` is not a table of robots".into(),
        })?;
    let robots: Vec<&String> = slam.keys().collect();
    // Every robot's section must be whole: a page with a robot's events or counters silently
    // missing would read as "none happened".
    for robot in &robots {
        for (name, ok) in [
            (
                "events",
                slam[*robot].get("events").is_some_and(Value::is_array),
            ),
            (
                "counters",
                slam[*robot].get("counters").is_some_and(Value::is_object),
            ),
            (
                "nees_mean",
                slam[*robot].get("nees_mean").is_some_and(Value::is_number),
            ),
            (
                "nees_poses",
                slam[*robot].get("nees_poses").is_some_and(Value::is_number),
            ),
            (
                "submaps",
                slam[*robot].get("submaps").is_some_and(Value::is_number),
            ),
        ] {
            if !ok {
                return Err(EvalError::Content {
                    path: metrics_path.clone(),
                    message: format!(
                        "field `slam.robots.{robot}.{name}` is missing or of the wrong type"
                    ),
                });
            }
        }
    }
    // Whether any correction came from the emulated image matcher (an oracle the manifest
    // lists); the robots' own image matching is earned.
    let oracle_matches = manifest
        .get("oracles")
        .and_then(Value::as_array)
        .is_some_and(|o| o.iter().any(|o| o["kind"] == "image_match"))
        && robots.iter().any(|r| {
            slam[*r]["events"]
                .as_array()
                .is_some_and(|e| e.iter().any(|e| e["kind"] == "image_match"))
        });

    let mut md = String::new();
    let scenario = field(&manifest, &manifest_path, "scenario")
        .ok()
        .and_then(|s| s.get("name").or(Some(s)))
        .and_then(Value::as_str)
        .unwrap_or("village");
    let _ = writeln!(md, "# {scenario}: the cooperative SLAM run\n");
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
    let seed = field(&manifest, &manifest_path, "seed")?;
    let _ = writeln!(md, "| seed | {seed} |");
    let _ = writeln!(
        md,
        "| sim time | {:.1} s |",
        num(&metrics, &metrics_path, "sim_secs")?
    );
    if let Some(t) = &timing {
        let wall = t.get("wall_secs").and_then(Value::as_f64);
        let rtf = t.get("realtime_factor").and_then(Value::as_f64);
        let threads = t.get("threads").and_then(Value::as_u64);
        if let (Some(wall), Some(rtf)) = (wall, rtf) {
            let _ = writeln!(
                md,
                "| wall time | {wall:.1} s ({rtf:.2}x real time{}) |",
                threads.map_or(String::new(), |n| format!(", {n} threads"))
            );
        }
    }
    if let Some(a) = manifest.get("adapter").filter(|a| !a.is_null()) {
        let s = |k: &str| a.get(k).and_then(Value::as_str).unwrap_or("?");
        let _ = writeln!(
            md,
            "| adapter | {} ({}, {}) |",
            s("name"),
            s("backend"),
            s("driver")
        );
    }
    let digest = field(&manifest, &manifest_path, "digest")?;
    let _ = writeln!(md, "| digest | `{}` |", digest.as_str().unwrap_or("?"));

    // The truth rule: what the robots were given that they could not have had.
    let oracles = manifest
        .get("oracles")
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    if !oracles.is_empty() {
        let _ = writeln!(
            md,
            "\n## Oracles in this run\n\nThe manifest lists what reached a robot from the \
             simulator's truth. A figure that rests on one is not earned by the robot \
             software.\n"
        );
        let mut image_match = false;
        for o in &oracles {
            let s = |k: &str| o.get(k).and_then(Value::as_str).unwrap_or("?");
            image_match |= s("kind") == "image_match";
            let _ = writeln!(
                md,
                "- `{}/{}` ({}): {}",
                s("robot"),
                s("sensor"),
                s("kind"),
                s("gives")
            );
        }
        if image_match {
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
    for robot in &robots {
        for kind in ["slam", "slam-open", "vo"] {
            let key = format!("estimates.{kind}/{robot}");
            let Ok(e) = field(&metrics, &metrics_path, &key) else {
                continue;
            };
            let f = |k: &str| e.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN);
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
                f("length_m"),
                f("ate_m"),
                f("rpe_1s_m"),
                f("final_error_m")
            );
        }
    }

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
    for robot in &robots {
        let events = slam[*robot]
            .get("events")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        for e in &events {
            let f = |k: &str| e.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN);
            let s = |k: &str| e.get(k).and_then(Value::as_str).unwrap_or("");
            let _ = writeln!(
                md,
                "| {robot} | {} | {:.1} | {} | {:.3} -> {:.3} | {:.3} -> {:.3} |",
                s("kind"),
                f("time_s"),
                s("other"),
                f("error_before_m"),
                f("error_after_m"),
                f("altitude_error_before_m"),
                f("altitude_error_after_m")
            );
        }
    }

    matching_section(&mut md, &robots, slam);
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
    for robot in &robots {
        let r = &slam[*robot];
        // A counter the stack never incremented is absent: shown as 0 only where the stack
        // counts it from the start (the graph's unresolved links), "-" otherwise.
        let c = |k: &str| {
            r.get("counters")
                .and_then(|c| c.get(k))
                .and_then(Value::as_u64)
                .map_or_else(|| "-".to_string(), |n| n.to_string())
        };
        let f = |k: &str| r.get(k).and_then(Value::as_f64).unwrap_or(f64::NAN);
        let _ = writeln!(
            md,
            "| {robot} | {:.2} | {} | {} | {} / {} | {} / {} | {} | {} | {} / {} |",
            f("nees_mean"),
            f("nees_poses"),
            f("submaps"),
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
    if let Ok(comms) = field(&metrics, &metrics_path, "comms") {
        let _ = writeln!(
            md,
            "\nRadio: {}\n",
            comms
                .as_object()
                .map(|o| o
                    .iter()
                    .map(|(k, v)| format!("{k} {v}"))
                    .collect::<Vec<_>>()
                    .join(", "))
                .unwrap_or_default()
        );
    }

    let mut files = vec![
        (
            "metrics.json".to_string(),
            std::fs::read(&metrics_path).map_err(FileError::at(&metrics_path))?,
        ),
        (
            "manifest.json".to_string(),
            std::fs::read(&manifest_path).map_err(FileError::at(&manifest_path))?,
        ),
    ];
    let _ = writeln!(
        md,
        "## Figures\n\nThe seed paper's Fig. 7 (seed 000, the hierarchical SLAM paper) per robot, \
         for the first run above: the top view at equal scales, and the altitude against time \
         with the events marked.\n"
    );
    for robot in &robots {
        let name = format!("fig7-{robot}.png");
        let path = run.join("plots").join(&name);
        let bytes = std::fs::read(&path).map_err(FileError::at(&path))?;
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

/// The robots' image matching in one run: counters and each accepted link judged.
fn matching_section(md: &mut String, robots: &[&String], slam: &serde_json::Map<String, Value>) {
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
    for robot in robots {
        let r = &slam[*robot];
        let c = |k: &str| r["counters"].get(k).and_then(Value::as_u64).unwrap_or(0);
        let m = |k: &str| r["matching"].get(k).and_then(Value::as_u64).unwrap_or(0);
        let _ = writeln!(
            md,
            "| {robot} | {} | {} | {} | {} | {} | {} / {} / {} | {} / {} | {} |",
            c("match_attempts"),
            c("matches_accepted"),
            c("matches_too_few_inliers"),
            c("matches_gated"),
            m("false_matches"),
            m("found"),
            m("missed"),
            m("waiting"),
            c("keyframes"),
            c("keyframes_received"),
            c("keyframe_bytes_sent"),
        );
    }
    let _ = writeln!(
        md,
        "\n| robot | time s | key frame of | made at s | inliers | error m | error deg | NEES | false |\n|---|---|---|---|---|---|---|---|---|"
    );
    for robot in robots {
        let links = slam[*robot]["matching"]["links"]
            .as_array()
            .cloned()
            .unwrap_or_default();
        for l in &links {
            let f = |k: &str| l[k].as_f64().unwrap_or(f64::NAN);
            let _ = writeln!(
                md,
                "| {robot} | {:.1} | {} | {:.1} | {} | {:.3} | {:.3} | {:.2} | {} |",
                f("time_s"),
                l["other"].as_str().unwrap_or("?"),
                f("other_time_s"),
                l["inliers"],
                f("error_m"),
                f("error_deg"),
                f("nees"),
                if l["false_match"] == true {
                    "**yes**"
                } else {
                    "no"
                },
            );
        }
    }
}

mod seeds;
pub use seeds::chi2_quantile;

#[cfg(test)]
mod tests {
    use super::*;

    fn run_folder(dir: &Path, metrics: &Value) {
        std::fs::create_dir_all(dir.join("plots")).unwrap();
        std::fs::write(dir.join("metrics.json"), metrics.to_string()).unwrap();
        let manifest = serde_json::json!({"scenario": {"name": "village"}, "seed": 3, "digest": "ab",
            "oracles": [{"kind": "image_match", "robot": "ressac", "sensor": "image_match", "gives": "truth"}]});
        std::fs::write(dir.join("manifest.json"), manifest.to_string()).unwrap();
        std::fs::write(dir.join("plots/fig7-dala.png"), b"png").unwrap();
    }

    #[test]
    fn the_page_holds_the_runs_figures() {
        let tmp = tempfile::tempdir().unwrap();
        let run = tmp.path().join("run");
        let metrics = serde_json::json!({
            "sim_secs": 600.0,
            "estimates": {"slam/dala": {"length_m": 224.7, "ate_m": 2.144, "rpe_1s_m": 0.004, "final_error_m": 7.678}},
            "slam": {"robots": {"dala": {
                "nees_mean": 2.47, "nees_poses": 5999, "submaps": 32,
                "events": [{"kind": "rendezvous", "time_s": 380.5, "other": "ressac",
                            "error_before_m": 7.2765, "error_after_m": 7.2765,
                            "altitude_error_before_m": 0.58, "altitude_error_after_m": 0.58}],
                "counters": {"unresolved_links": 3}}}},
            "comms": {"sent": 242}
        });
        run_folder(&run, &metrics);
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
        run_folder(&run, &serde_json::json!({"sim_secs": 1.0}));
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
        let robot =
            serde_json::json!({"nees_mean": 1.0, "nees_poses": 1, "submaps": 1, "counters": {}});
        run_folder(
            &run,
            &serde_json::json!({"sim_secs": 1.0, "slam": {"robots": {"dala": robot}}}),
        );
        let err = village_report(std::slice::from_ref(&run), &out)
            .unwrap_err()
            .to_string();
        assert!(err.contains("slam.robots.dala.events"), "{err}");
        let mut whole = robot.clone();
        whole["events"] = serde_json::json!([]);
        run_folder(
            &run,
            &serde_json::json!({"sim_secs": 1.0, "slam": {"robots": {"dala": whole}}}),
        );
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
        let event = serde_json::json!({"kind": "image_match", "time_s": 197.0, "other": "dala",
            "error_before_m": 48.8, "error_after_m": 0.77,
            "altitude_error_before_m": 38.9, "altitude_error_after_m": 0.2});
        let robot = |events: serde_json::Value| {
            serde_json::json!({
            "nees_mean": 1.0, "nees_poses": 1, "submaps": 1, "counters": {}, "events": events})
        };
        let acc = serde_json::json!({"length_m": 1.0, "ate_m": 1.0, "rpe_1s_m": 1.0, "final_error_m": 1.0});
        let metrics = serde_json::json!({
            "sim_secs": 600.0,
            "estimates": {"slam/dala": acc, "vo/dala": acc},
            "slam": {"robots": {"dala": robot(serde_json::json!([])), "ressac": robot(serde_json::json!([event]))}}
        });
        run_folder(&run, &metrics);
        std::fs::write(run.join("plots/fig7-ressac.png"), b"png").unwrap();
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
