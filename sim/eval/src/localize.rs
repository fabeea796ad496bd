//! Localization from coverage-mission image databases (seed 002, Section V.B): the
//! cross-validation of the paper over several mapping runs, and the errors of the child that
//! localized with the particle filter on a new path in lockstep after mapping.

use crate::stats::MeanStd;
use crate::EvalError;
use hetsim_vision::appearance::{best_match, Feature, Features};
use hetsim_vision::Gray;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// An image of a database, with its positions and features.
#[derive(Clone, Debug, PartialEq)]
pub struct DbImage {
    /// The vertex `(col, row)`.
    pub vertex: (usize, usize),
    /// The database's (the parent's) grab position, metres.
    pub estimated_xy: [f64; 2],
    /// The true grab position, metres.
    pub true_xy: [f64; 2],
    /// Features of the image.
    pub features: Features,
}

/// The database a parent reported, with true grab positions from the run's ground truth.
pub fn database_of(
    report: &hetsim_coverage::TeamReport,
    truth: &[(String, Vec<(u64, hetsim_msgs::Pose)>)],
) -> Vec<DbImage> {
    report
        .database
        .iter()
        .filter_map(|d| {
            let track = &truth.iter().find(|(n, _)| *n == d.child)?.1;
            let p = crate::scene::truth_at(track, d.image.stamp_ns)
                .translation
                .vector;
            let gray = Gray::from_image(&d.image)
                .expect("the child's stack accepted the image: its bytes are its size");
            Some(DbImage {
                vertex: d.vertex,
                estimated_xy: d.estimated_xy,
                true_xy: [p.x, p.y],
                features: Features::of(&gray),
            })
        })
        .collect()
}

/// Reads `coverage/database.json` and its images from a run's results directory.
pub fn load_database(run: &Path) -> Result<Vec<DbImage>, EvalError> {
    let dir = run.join("coverage");
    let path = dir.join("database.json");
    let content = |message: String| EvalError::Content {
        path: path.clone(),
        message,
    };
    let text = std::fs::read_to_string(&path)
        .map_err(|e| content(format!("{e} (not the results of a coverage mission?)")))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| content(format!("line {}: {e}", e.line())))?;
    let images = json["images"]
        .as_array()
        .ok_or_else(|| content("no \"images\" array".into()))?;
    images
        .iter()
        .enumerate()
        .map(|(k, entry)| {
            let field = |name: &str| {
                let v = &entry[name];
                match (v[0].as_f64(), v[1].as_f64()) {
                    (Some(a), Some(b)) => Ok([a, b]),
                    _ => Err(content(format!(
                        "images[{k}].{name} is {v}, expected [x, y]"
                    ))),
                }
            };
            let vertex = field("vertex")?;
            let file = entry["image"]
                .as_str()
                .ok_or_else(|| content(format!("images[{k}].image is not a file name")))?;
            let png = dir.join(file);
            let img = image::open(&png)
                .map_err(|e| EvalError::Content {
                    path: png.clone(),
                    message: e.to_string(),
                })?
                .to_rgb8();
            let gray = Gray::from_rgb(img.width() as usize, img.height() as usize, img.as_raw())
                .expect("an RGB image's buffer is w x h x 3");
            Ok(DbImage {
                vertex: (vertex[0] as usize, vertex[1] as usize),
                estimated_xy: field("estimated_xy_m")?,
                true_xy: field("true_xy_m")?,
                features: Features::of(&gray),
            })
        })
        .collect()
}

/// Localization errors of one feature.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureErrors {
    /// The feature.
    pub feature: String,
    /// Error, metres.
    pub error_m: MeanStd,
    /// Median error, metres.
    pub median_m: f64,
    /// Fraction of images matched to an image of their own vertex.
    pub same_vertex: f64,
}

fn errors_of(feature: Feature, errors: &[f64], same: usize) -> FeatureErrors {
    let mut sorted = errors.to_vec();
    sorted.sort_by(f64::total_cmp);
    FeatureErrors {
        feature: feature.name().into(),
        error_m: MeanStd::population(errors),
        median_m: sorted.get(sorted.len() / 2).copied().unwrap_or(0.0),
        same_vertex: same as f64 / errors.len().max(1) as f64,
    }
}

/// The cross-validation of the seed: every image of every run is matched against the images
/// of all the other runs; its error is the distance from its true grab position to the
/// database position of the image it matched.
pub fn cross_validate(runs: &[Vec<DbImage>]) -> Vec<FeatureErrors> {
    Feature::ALL
        .iter()
        .map(|&feature| {
            let (mut errors, mut same) = (Vec::new(), 0);
            for (r, run) in runs.iter().enumerate() {
                let others: Vec<&DbImage> = runs
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| *k != r)
                    .flat_map(|(_, x)| x.iter())
                    .collect();
                let db: Vec<Features> = others.iter().map(|d| d.features.clone()).collect();
                for q in run {
                    let Some(m) = best_match(&q.features, &db, feature) else {
                        continue;
                    };
                    let hit = others[m];
                    errors.push(
                        (q.true_xy[0] - hit.estimated_xy[0])
                            .hypot(q.true_xy[1] - hit.estimated_xy[1]),
                    );
                    same += usize::from(hit.vertex == q.vertex);
                }
            }
            errors_of(feature, &errors, same)
        })
        .collect()
}

/// The particle filter's run along a path.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PathRun {
    /// The feature.
    pub feature: String,
    /// Images taken along the path (one per vertex).
    pub steps: usize,
    /// Error of the estimate after each image, metres.
    pub errors_m: Vec<f64>,
    /// Distance driven when each image was taken (the true path's length so far), metres.
    pub distance_m: Vec<f64>,
    /// The first step from which the error stays under 0.5 m, if any.
    pub converged_at: Option<usize>,
    /// Error at the end, metres.
    pub final_error_m: f64,
}

/// The child's localization run in lockstep: its `pf-<feature>` trajectories (the particle
/// filters' estimates after every image of the path the parent gave it after mapping; see
/// `hetsim_coverage::team`), against its true positions at the images' stamps. Empty when no
/// run was made, it made no image, or the run has no truth of the child. A run the parent
/// gave up on, or the scenario's end cut short, has fewer steps than its path (see
/// `TeamMetrics::localization_timed_out`). `distance_m` is measured between the images' true
/// positions: straight lines, not every centimetre the wheels drove.
pub fn in_lockstep(
    report: &hetsim_coverage::TeamReport,
    output: &hetsim_engine::RunOutput,
) -> Vec<PathRun> {
    let Some(tour) = &report.tour else {
        return Vec::new();
    };
    let (Some(truth), Some((_, artifacts))) = (
        output.truth_of(&tour.child).filter(|t| !t.is_empty()),
        output.artifacts.iter().find(|(n, _)| *n == tour.child),
    ) else {
        return Vec::new();
    };
    Feature::ALL
        .iter()
        .filter_map(|f| {
            let name = format!("pf-{}", f.name());
            let poses = artifacts.iter().find_map(|a| match &a.data {
                hetsim_msgs::ArtifactData::Trajectory(p) if a.name == name => Some(p),
                _ => None,
            })?;
            if poses.is_empty() {
                return None;
            }
            let true_xy: Vec<[f64; 2]> = poses
                .iter()
                .map(|(t, _)| {
                    let p = crate::scene::truth_at(truth, *t).translation.vector;
                    [p.x, p.y]
                })
                .collect();
            let errors: Vec<f64> = poses
                .iter()
                .zip(&true_xy)
                .map(|((_, e), t)| {
                    let e = e.translation.vector;
                    (e.x - t[0]).hypot(e.y - t[1])
                })
                .collect();
            let distance_m = true_xy
                .iter()
                .scan((0.0, true_xy[0]), |(d, last), p| {
                    *d += (p[0] - last[0]).hypot(p[1] - last[1]);
                    *last = *p;
                    Some(*d)
                })
                .collect();
            Some(PathRun {
                feature: f.name().into(),
                steps: errors.len(),
                distance_m,
                converged_at: (0..errors.len()).find(|&i| errors[i..].iter().all(|e| *e < 0.5)),
                final_error_m: *errors.last()?,
                errors_m: errors,
            })
        })
        .collect()
}

/// Mission figures over several runs, localization by cross-validation and along paths.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Mapping runs.
    pub runs: usize,
    /// Runs whose mission finished.
    pub finished: usize,
    /// Images per run (mean).
    pub images_per_run: f64,
    /// Mission time over the runs, minutes (paper: 38.4 ± 1.7).
    pub mission_min: MeanStd,
    /// True grab position error, all runs' images, metres.
    pub position_error_m: MeanStd,
    /// Tracked grab position error (the paper's measure; paper: 0.10 ± 0.05 m).
    pub tracked_position_error_m: MeanStd,
    /// True heading error, all runs' images, degrees.
    pub heading_error_deg: MeanStd,
    /// Compass heading error (paper, by its tracker: 8.79 ± 9.99°).
    pub compass_heading_error_deg: MeanStd,
    /// Collisions, all runs together.
    pub collisions: u64,
    /// Tracking losses, all runs together.
    pub tracking_losses: u64,
    /// Images with another robot in view within r_los, all runs together.
    pub images_with_robot_in_view: u64,
    /// Images with another robot in view farther than r_los, all runs together (the paper's
    /// rule holds for every robot the camera can see).
    pub images_with_distant_robot_in_view: u64,
    /// Cross-validation (paper: WGOH 0.43 ± 0.59 m, pixelwise 0.54 ± 0.79 m).
    pub cross_validation: Vec<FeatureErrors>,
    /// Particle filter along the paths driven in lockstep after mapping, per feature.
    pub particle_filter: Vec<PathSummary>,
    /// Runs whose child reported its localization run done.
    pub localization_reported: usize,
    /// Runs whose localization run the parent gave up on (no report by the deadline).
    pub localization_timed_out: usize,
    /// Earliest and latest sim time at which a report came, minutes.
    pub localized_min_range: Option<[f64; 2]>,
    /// The encoders' scale each localizing child was sent, and the same hops on the truth
    /// (`TeamMetrics::localization_odometry_scale`, `_true`), per run that has both.
    pub odometry_scales: Vec<[f64; 2]>,
}

/// The particle filter's results over several paths, for one feature.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PathSummary {
    /// The feature.
    pub feature: String,
    /// Paths driven.
    pub paths: usize,
    /// Error at the end of the paths, metres.
    pub final_error_m: MeanStd,
    /// Paths whose error ended under 0.5 m for good.
    pub converged: usize,
    /// Images needed to converge, over the converged paths.
    pub images_to_converge: MeanStd,
    /// Each path.
    pub runs: Vec<PathRun>,
}

/// Pulls the summary together from the runs' `team` metrics and the localization results.
pub fn summarize(
    missions: &[serde_json::Value],
    cross: &[FeatureErrors],
    pf: &[PathRun],
) -> Summary {
    let values = |f: &dyn Fn(&serde_json::Value) -> Option<f64>| -> Vec<f64> {
        missions.iter().filter_map(f).collect()
    };
    // Pooled over the runs' images (runs have nearly equal image counts): the mean of the
    // means, and the spread of all images around it.
    let pooled = |key: &'static str| {
        let stats: Vec<MeanStd> = missions
            .iter()
            .filter_map(|m| {
                Some(MeanStd {
                    mean: m[key]["mean"].as_f64()?,
                    std: m[key]["std"].as_f64()?,
                })
            })
            .collect();
        MeanStd::pooled(&stats)
    };
    let total = |key: &'static str| missions.iter().filter_map(|m| m[key].as_u64()).sum::<u64>();
    let particle_filter = Feature::ALL
        .iter()
        .map(|f| {
            let runs: Vec<PathRun> = pf
                .iter()
                .filter(|r| r.feature == f.name())
                .cloned()
                .collect();
            let finals: Vec<f64> = runs.iter().map(|r| r.final_error_m).collect();
            let conv: Vec<f64> = runs
                .iter()
                .filter_map(|r| r.converged_at.map(|c| (c + 1) as f64))
                .collect();
            PathSummary {
                feature: f.name().into(),
                paths: runs.len(),
                final_error_m: MeanStd::population(&finals),
                converged: conv.len(),
                images_to_converge: MeanStd::population(&conv),
                runs,
            }
        })
        .collect();
    let reported: Vec<f64> = missions
        .iter()
        .filter(|m| m["localization_timed_out"].as_bool() == Some(false))
        .filter_map(|m| m["localized_min"].as_f64())
        .collect();
    Summary {
        localization_reported: reported.len(),
        localization_timed_out: missions
            .iter()
            .filter(|m| m["localization_timed_out"].as_bool() == Some(true))
            .count(),
        localized_min_range: (!reported.is_empty()).then(|| {
            [
                reported.iter().copied().fold(f64::INFINITY, f64::min),
                reported.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            ]
        }),
        odometry_scales: missions
            .iter()
            .filter_map(|m| {
                Some([
                    m["localization_odometry_scale"].as_f64()?,
                    m["localization_odometry_scale_true"].as_f64()?,
                ])
            })
            .collect(),
        runs: missions.len(),
        finished: missions
            .iter()
            .filter(|m| m["finished"].as_bool() == Some(true))
            .count(),
        images_per_run: MeanStd::population(&values(&|m| m["imaged"].as_f64())).mean,
        mission_min: MeanStd::population(&values(&|m| m["mission_min"].as_f64())),
        position_error_m: pooled("position_error_m"),
        tracked_position_error_m: pooled("tracked_position_error_m"),
        heading_error_deg: pooled("heading_error_deg"),
        compass_heading_error_deg: pooled("compass_heading_error_deg"),
        collisions: total("collisions"),
        tracking_losses: total("tracking_losses"),
        images_with_robot_in_view: total("images_with_robot_in_view"),
        images_with_distant_robot_in_view: total("images_with_distant_robot_in_view"),
        cross_validation: cross.to_vec(),
        particle_filter,
    }
}

/// The summary as a Markdown table beside the paper's figures.
pub fn markdown(s: &Summary) -> String {
    let ms = |m: &MeanStd, unit: &str| format!("{:.2} ± {:.2}{unit}", m.mean, m.std);
    let mut t = format!(
        "| figure ({} mapping runs, {} finished, {:.1} images each) | hetsim | paper (seed 002, V.B) |\n|---|---|---|\n",
        s.runs, s.finished, s.images_per_run
    );
    t += &format!(
        "| mission time | {} | 38.4 ± 1.7 min |\n",
        ms(&s.mission_min, " min")
    );
    t += &format!(
        "| grab position error, tracked (true) | {} ({}) | 0.10 ± 0.05 m |\n",
        ms(&s.tracked_position_error_m, " m"),
        ms(&s.position_error_m, " m")
    );
    t += &format!(
        "| grab heading error, compass (true) | {} ({}) | 8.79 ± 9.99° |\n",
        ms(&s.compass_heading_error_deg, "°"),
        ms(&s.heading_error_deg, "°")
    );
    t += &format!(
        "| collisions, tracking losses, images with a robot in view (within r_los; farther) | {}, {}, {}; {} | none, none, none |\n",
        s.collisions, s.tracking_losses, s.images_with_robot_in_view, s.images_with_distant_robot_in_view
    );
    for c in &s.cross_validation {
        let paper = if c.feature == "wgoh" {
            "0.43 ± 0.59 m"
        } else {
            "0.54 ± 0.79 m"
        };
        t += &format!(
            "| cross-validation, {} (median; same vertex) | {} ({:.2} m; {:.0} %) | {paper} |\n",
            c.feature,
            ms(&c.error_m, " m"),
            c.median_m,
            100.0 * c.same_vertex
        );
    }
    t += &format!(
        "| localization runs after mapping: reported (when, sim min), timed out | {} ({}), {} | - |\n",
        s.localization_reported,
        s.localized_min_range
            .map_or("-".into(), |[a, b]| format!("{a:.1}-{b:.1}")),
        s.localization_timed_out
    );
    if !s.odometry_scales.is_empty() {
        let range = |k: usize| {
            let v = s.odometry_scales.iter().map(|p| p[k]);
            let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                (a.min(x), b.max(x))
            });
            format!("{lo:.3}-{hi:.3}")
        };
        let off: Vec<f64> = s.odometry_scales.iter().map(|p| p[0] - p[1]).collect();
        // Three decimals: the difference is a few thousandths.
        let off = MeanStd::population(&off);
        t += &format!(
            "| encoders' scale sent to the localizing child (same hops on the truth; sent minus truth) | {} ({}; {:.3} ± {:.3}) | - |\n",
            range(0),
            range(1),
            off.mean,
            off.std
        );
    }
    // The worst path beside the mean: a mean can hide one that never converged.
    for p in &s.particle_filter {
        let largest = p
            .runs
            .iter()
            .map(|r| r.final_error_m)
            .max_by(f64::total_cmp)
            .map_or("-".into(), |e| format!("{e:.2} m"));
        let slowest = p.runs.iter().filter_map(|r| r.converged_at).max();
        t += &format!(
            "| particle filter in lockstep, {}: final error over {} paths, largest (converged; images to converge, most) | {}, {} ({}; {:.1}, {}) | - |\n",
            p.feature,
            p.paths,
            ms(&p.final_error_m, " m"),
            largest,
            p.converged,
            p.images_to_converge.mean,
            slowest.map_or("-".into(), |c| (c + 1).to_string())
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::{markdown, summarize};

    /// The study adds up, over its runs, the images with a robot in view within r_los and
    /// those with one farther, and its table shows both.
    #[test]
    fn the_summary_counts_robots_in_view_within_r_los_and_farther() {
        let run = |near: u64, far: u64| {
            serde_json::json!({
                "finished": true,
                "imaged": 76,
                "images_with_robot_in_view": near,
                "images_with_distant_robot_in_view": far,
            })
        };
        let s = summarize(&[run(1, 0), run(0, 2), run(0, 3)], &[], &[]);
        assert_eq!(
            (
                s.images_with_robot_in_view,
                s.images_with_distant_robot_in_view
            ),
            (1, 5)
        );
        let md = markdown(&s);
        assert!(
            md.contains("images with a robot in view (within r_los; farther) | 0, 0, 1; 5 |"),
            "{md}"
        );
    }
}
