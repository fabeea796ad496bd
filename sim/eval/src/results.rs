//! A run's results folder: the files, in the order the digest covers them, written atomically.
//!
//! Everything is written into a hidden temporary directory beside the destination, which is
//! renamed into place only when every file is complete: an interrupted run never leaves a
//! directory that looks like finished results.

use crate::metrics::Metrics;
use crate::trajectory::{estimates, Estimate};
use crate::EvalError;
use hetsim_core::files::{write_dir_atomic, FileError};
use hetsim_engine::{tum_line, RunOutput};
use hetsim_msgs::{ArtifactData, Pose};
use hetsim_scene::Scenario;
use std::path::{Path, PathBuf};

/// Where the results went.
#[derive(Clone, Debug, PartialEq)]
pub struct RunFiles {
    /// The results directory.
    pub dir: PathBuf,
    /// The run digest (hex).
    pub digest: String,
}

/// The map every robot published, in robot order: points, then segments.
type MapParts = (
    Vec<(String, usize, [f64; 3])>,
    Vec<(String, usize, [[f64; 3]; 2])>,
);

fn maps(output: &RunOutput) -> MapParts {
    let (mut points, mut segments) = (Vec::new(), Vec::new());
    for (robot, a) in output.artifacts_named("map") {
        if let ArtifactData::Map {
            points: p,
            segments: s,
        } = &a.data
        {
            // In the world, as every estimate the evaluation writes.
            let frame = crate::frames::artifact_frame(output, robot, "map");
            let place = |x: &[f64; 3]| -> [f64; 3] {
                frame.map_or(*x, |w| (w * nalgebra::Point3::from(*x)).coords.into())
            };
            points.extend(p.iter().map(|(k, x)| (robot.to_string(), *k, place(x))));
            segments.extend(
                s.iter()
                    .map(|(k, x)| (robot.to_string(), *k, [place(&x[0]), place(&x[1])])),
            );
        }
    }
    (points, segments)
}

/// Whether `dir` may receive `scenario`'s results: it does not exist, or it holds the results
/// of the same run ([`crate::manifest::Manifest::differs_from`]), or `replace` says another
/// run's may be replaced. A folder that is not a results folder (no `manifest.json`) is
/// never replaced. Callers check before a run starts, so that a long run is not made for
/// nothing; [`write_run`] checks again before it writes.
pub fn check_destination(dir: &Path, scenario: &Scenario, replace: bool) -> Result<(), EvalError> {
    if !dir.exists() {
        return Ok(());
    }
    if !dir.join("manifest.json").is_file() {
        return Err(EvalError::Occupied(dir.to_path_buf()));
    }
    if replace {
        return Ok(());
    }
    let there = crate::manifest::Manifest::read(dir)?;
    match there.differs_from(scenario) {
        None => Ok(()),
        Some(differs) => Err(other_run(dir, there, differs)),
    }
}

/// The refusal of `dir`, which holds the run `there` describes.
fn other_run(dir: &Path, there: crate::manifest::Manifest, differs: &'static str) -> EvalError {
    EvalError::OtherRun {
        dir: dir.to_path_buf(),
        scenario: there.scenario,
        seed: there.seed,
        digest: there.digest.chars().take(16).collect(),
        differs,
    }
}

/// Writes a run's results to `dest` (or to `results/runs/<name>-seed<seed>-<digest8>` when
/// `dest` is `None`), adding every output file to the digest first, and returns the directory
/// and final digest. `timing` is written to `timing.json` outside the digest. `frames`, a
/// folder of dumped camera frames staged during the run, is moved in as `frames/` (the images
/// are in the digest as messages already). A `dest` holding another run's results is
/// refused unless `replace` ([`check_destination`]).
pub fn write_run(
    scenario: &Scenario,
    mut result: RunOutput,
    metrics: &Metrics,
    dest: Option<&Path>,
    timing: &crate::manifest::Timing,
    frames: Option<&Path>,
    replace: bool,
) -> Result<RunFiles, EvalError> {
    let mut files = files(scenario, &result, metrics);
    for (name, bytes) in &files {
        result.digest.record(&format!("file/{name}"), bytes);
    }
    let digest = result.digest.hex();
    files.push((
        "manifest.json".to_string(),
        serde_json::to_vec_pretty(&crate::manifest::Manifest::of(scenario, &result, &digest))
            .expect("manifest serializes"),
    ));
    files.push((
        "timing.json".to_string(),
        serde_json::to_vec_pretty(timing).expect("timing serializes"),
    ));
    let dir = match dest {
        Some(d) => d.to_path_buf(),
        None => PathBuf::from("results/runs").join(format!(
            "{}-seed{}-{}",
            scenario.file.name,
            scenario.seed,
            &digest[..8]
        )),
    };
    // The same run computes the same bytes: a folder whose digest differs holds another run
    // even where the scenario matched (a run option such as --open-loop or --no-render
    // changes the bytes, not the scenario), and is replaced only when asked.
    if !replace && dir.join("manifest.json").is_file() {
        let there = crate::manifest::Manifest::read(&dir)?;
        if there.digest != digest {
            return Err(other_run(
                &dir,
                there,
                "digest (a run option: --open-loop, --no-render, frames)",
            ));
        }
    } else {
        check_destination(&dir, scenario, true)?;
    }
    write_dir_atomic(&dir, &files, |tmp| {
        if let Some(staged) = frames.filter(|f| f.exists()) {
            std::fs::rename(staged, tmp.join("frames")).map_err(FileError::at(staged))?;
        }
        Ok(())
    })?;
    Ok(RunFiles { dir, digest })
}

/// The run's files in the order the digest covers them (everything but the manifest and
/// `timing.json`).
fn files(scenario: &Scenario, result: &RunOutput, metrics: &Metrics) -> Vec<(String, Vec<u8>)> {
    let estimates = estimates(result);
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    for (name, poses) in &result.truth {
        let mut text = String::new();
        for (t, p) in poses {
            text.push_str(&tum_line(*t, p));
        }
        files.push((format!("truth/{name}.tum"), text.into_bytes()));
    }
    for e in &estimates {
        let text: String = e.poses.iter().map(|(t, p)| tum_line(*t, p)).collect();
        files.push((format!("{}/{}.tum", e.kind, e.robot), text.into_bytes()));
        // A picture: estimate against truth over the estimate's time span (sim time).
        let (first, last) = (e.poses[0].0, e.poses[e.poses.len() - 1].0);
        let xyz = |p: &Pose| p.translation.vector.into();
        let truth: Vec<(u64, [f64; 3])> = result
            .truth
            .iter()
            .find(|(n, _)| *n == e.robot)
            .map(|(_, poses)| {
                poses
                    .iter()
                    .filter(|(t, _)| *t >= first && *t <= last)
                    .map(|(t, p)| (*t, xyz(p)))
                    .collect()
            })
            .unwrap_or_default();
        let estimate: Vec<(u64, [f64; 3])> = e.poses.iter().map(|(t, p)| (*t, xyz(p))).collect();
        let png = crate::charts::trajectories_png(
            &format!("{}: {} against truth", e.robot, series_label(&e.kind)),
            &truth,
            &[crate::charts::Series {
                label: series_label(&e.kind),
                points: &estimate,
            }],
            &event_marks(metrics, &e.robot),
        );
        files.push((format!("plots/{}-{}.png", e.kind, e.robot), png));
    }
    let (map_points, map_segments) = maps(result);
    if !map_points.is_empty() || !map_segments.is_empty() {
        files.push(("map.ply".to_string(), ply(&map_points, &map_segments)));
    }
    // The SLAM's global level per robot: sub-map origins with covariance, and the events.
    for (robot, report) in &crate::slam::reports(result) {
        let origins: Vec<serde_json::Value> = report
            .origins
            .iter()
            .map(|(t, p, cov)| {
                let q = p.rotation;
                serde_json::json!({
                    "time_s": *t as f64 * 1e-9,
                    "position_m": [p.translation.x, p.translation.y, p.translation.z],
                    "quaternion_xyzw": [q.i, q.j, q.k, q.w],
                    "covariance": cov.chunks(6).map(<[f64]>::to_vec).collect::<Vec<_>>(),
                })
            })
            .collect();
        let events = metrics
            .slam
            .as_ref()
            .and_then(|m| m.robots.get(robot))
            .map(|r| r.events.clone())
            .unwrap_or_default();
        let doc = serde_json::json!({
            "robot": robot,
            "covariance_convention": "right perturbation (dx, dy, dz, rx, ry, rz) of world_from_origin, 6x6",
            "origins": origins,
            "events": events,
        });
        files.push((
            format!("slam/{robot}-graph.json"),
            serde_json::to_vec_pretty(&doc).expect("JSON encodes"),
        ));
    }
    // Fig. 7 of seed 000 per robot: VO, open-loop and event-corrected SLAM against truth.
    for (robot, truth) in &result.truth {
        let kinds = ["vo", "slam-open", "slam"];
        let series: Vec<&Estimate> = kinds
            .iter()
            .filter_map(|k| estimates.iter().find(|e| e.kind == *k && e.robot == *robot))
            .collect();
        if series.len() < kinds.len() {
            continue;
        }
        let first = series[0].poses[0].0;
        let xyz = |(t, p): &(u64, Pose)| (*t, p.translation.vector.into());
        let last = series[0].poses[series[0].poses.len() - 1].0;
        let truth: Vec<(u64, [f64; 3])> = truth
            .iter()
            .filter(|(t, _)| *t >= first && *t <= last)
            .map(xyz)
            .collect();
        let lines: Vec<Vec<(u64, [f64; 3])>> = series
            .iter()
            .map(|e| e.poses.iter().map(xyz).collect())
            .collect();
        let named: Vec<crate::charts::Series> = series
            .iter()
            .zip(&lines)
            .map(|(e, points)| crate::charts::Series {
                label: series_label(&e.kind),
                points,
            })
            .collect();
        let png = crate::charts::trajectories_png(
            &format!(
                "{robot}: VO, open-loop and cooperative SLAM against truth (Fig. 7, seed 000)"
            ),
            &truth,
            &named,
            &event_marks(metrics, robot),
        );
        files.push((format!("plots/fig7-{robot}.png"), png));
    }
    if let Some(team) = crate::team::TeamOutcome::of(result) {
        files.extend(crate::team::files(scenario, &team, &result.truth));
    }
    let metrics = serde_json::to_vec_pretty(metrics).expect("metrics serialize");
    files.push(("metrics.json".to_string(), metrics));
    files
}

/// A trajectory kind's name in figures.
fn series_label(kind: &str) -> &str {
    match kind {
        "vo" => "VO",
        "slam-open" => "open-loop SLAM",
        "slam" => "cooperative SLAM",
        other => other,
    }
}

/// A robot's SLAM events as marks on a figure's time axis (sim seconds).
fn event_marks(metrics: &Metrics, robot: &str) -> Vec<crate::charts::Mark> {
    metrics
        .slam
        .as_ref()
        .and_then(|m| m.robots.get(robot))
        .map(|r| {
            r.events
                .iter()
                .map(|e| (e.time_s, e.kind.replace('_', " ")))
                .collect()
        })
        .unwrap_or_default()
}

/// An ASCII PLY of mapped points, coloured by robot (in order of first appearance), with
/// each point's robot index and sub-map as properties.
/// The SLAM map as PLY: a vertex per point, then two per segment (its endpoints) joined by an
/// edge; coloured by robot.
fn ply(
    points: &[(String, usize, [f64; 3])],
    segments: &[(String, usize, [[f64; 3]; 2])],
) -> Vec<u8> {
    const COLOURS: [[u8; 3]; 4] = [[204, 0, 0], [52, 101, 164], [78, 154, 6], [117, 80, 123]];
    let mut robots: Vec<&str> = Vec::new();
    for r in points
        .iter()
        .map(|p| &p.0)
        .chain(segments.iter().map(|s| &s.0))
    {
        if !robots.contains(&r.as_str()) {
            robots.push(r);
        }
    }
    let mut out = format!(
        "ply\nformat ascii 1.0\ncomment hetsim SLAM map in the world frame (x east, y north, z up, metres)\ncomment robots: {}\ncomment {} points, then the two endpoints of each of the {} line segments (edges)\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty int robot\nproperty int submap\nelement edge {}\nproperty int vertex1\nproperty int vertex2\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        robots.join(" "),
        points.len(),
        segments.len(),
        points.len() + 2 * segments.len(),
        segments.len()
    );
    let colour = |r: &String| {
        let k = robots.iter().position(|x| x == r).unwrap_or(0);
        (k, COLOURS[k % COLOURS.len()])
    };
    let vertices = points.iter().map(|(r, node, p)| (r, node, p)).chain(
        segments
            .iter()
            .flat_map(|(r, node, e)| e.iter().map(move |p| (r, node, p))),
    );
    for (r, node, p) in vertices {
        let (k, c) = colour(r);
        out.push_str(&format!(
            "{:.4} {:.4} {:.4} {} {} {} {k} {node}\n",
            p[0], p[1], p[2], c[0], c[1], c[2]
        ));
    }
    for (i, (r, _, _)) in segments.iter().enumerate() {
        let (_, c) = colour(r);
        let v = points.len() + 2 * i;
        out.push_str(&format!("{v} {} {} {} {}\n", v + 1, c[0], c[1], c[2]));
    }
    out.into_bytes()
}

#[cfg(test)]
mod tests {
    #[test]
    fn ply_has_a_vertex_per_point_and_an_edge_per_segment_coloured_by_robot() {
        let pts = vec![
            ("dala".to_string(), 0, [1.0, 2.0, 3.0]),
            ("ressac".to_string(), 2, [4.0, 5.0, 6.0]),
            ("dala".to_string(), 1, [7.0, 8.0, 9.0]),
        ];
        let segs = vec![("ressac".to_string(), 3, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.5]])];
        let text = String::from_utf8(super::ply(&pts, &segs)).unwrap();
        assert!(
            text.contains("element vertex 5\n")
                && text.contains("element edge 1\n")
                && text.contains("comment robots: dala ressac")
        );
        let body: Vec<&str> = text.split("end_header\n").nth(1).unwrap().lines().collect();
        assert_eq!(
            body,
            [
                "1.0000 2.0000 3.0000 204 0 0 0 0",
                "4.0000 5.0000 6.0000 52 101 164 1 2",
                "7.0000 8.0000 9.0000 204 0 0 0 1",
                "0.0000 0.0000 0.0000 52 101 164 1 3",
                "1.0000 0.0000 0.5000 52 101 164 1 3",
                "3 4 52 101 164"
            ]
        );
    }
}
