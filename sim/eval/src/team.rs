//! A coverage mission run in lockstep (seed 002, Section V.B): its figures against ground
//! truth, and its image database and plots as files.

use crate::scene::{camera_of, direction_rad, truth_at};
use crate::stats::MeanStd;
use hetsim_coverage::{TeamReport, TEAM_ARTIFACT};
use hetsim_engine::RunOutput;
use hetsim_msgs::mount_to_optical;
use hetsim_msgs::{wrap_angle, yaw_of, Pose};
use hetsim_physics::Physics;
use hetsim_scene::Scenario;
use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};
use serde_json::json;

/// The parent's report and who made it.
#[derive(Clone, Debug, PartialEq)]
pub struct TeamOutcome {
    /// The parent robot.
    pub parent: String,
    /// What it reported.
    pub report: TeamReport,
}

impl TeamOutcome {
    /// The coverage parent's report among a run's artifacts, if the run had a coverage parent.
    pub fn of(output: &RunOutput) -> Option<Self> {
        output
            .artifacts_named(TEAM_ARTIFACT)
            .find_map(|(robot, a)| {
                Some(Self {
                    parent: robot.to_string(),
                    report: a.decode()?,
                })
            })
    }
}

/// What a coverage mission did (the figures of Section V.B), against ground truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TeamMetrics {
    /// Children in the team.
    pub children: usize,
    /// Free vertices |V|.
    pub vertices: usize,
    /// Parent vertices |V_p|.
    pub parent_vertices: usize,
    /// Distinct vertices of V \ V_p with an image in the database.
    pub imaged: usize,
    /// `imaged / |V \ V_p|`.
    pub imaged_fraction: f64,
    /// Vertices the plan could not image (uncoverable, unreached or unreachable).
    pub unplanned: Vec<(usize, usize)>,
    /// Goals a child could not reach (blocked), `(col, row)`.
    pub abandoned: Vec<(usize, usize)>,
    /// Whether the parent finished its plan within the run.
    pub finished: bool,
    /// Sim time when the plan was done (or the run's end), minutes. Seed: 38.4 ± 1.7 min
    /// for 84 vertices, 3 children, 7 parent vertices.
    pub mission_min: f64,
    /// Distance of the true grab position from its vertex, metres.
    pub position_error_m: MeanStd,
    /// Distance of the parent's tracked grab position from its vertex, metres (the seed's
    /// measure: 0.10 ± 0.05 m).
    pub tracked_position_error_m: MeanStd,
    /// Angle between the true heading at the grab and the direction of mapping, degrees.
    pub heading_error_deg: MeanStd,
    /// Angle between the compass heading at the grab and the direction of mapping, degrees
    /// (the seed measured 8.79 ± 9.99° with the parent's tracker).
    pub compass_heading_error_deg: MeanStd,
    /// Error of the parent's grab position estimate against truth, metres.
    pub estimate_error_m: MeanStd,
    /// Collisions of all robots (contact episodes).
    pub collisions: u32,
    /// Children stopped because the tracker lost them.
    pub tracking_losses: u32,
    /// Orders the parent sent again (radio losses).
    pub resent_orders: u32,
    /// Drives of a child back onto its vertex before a grab, the parent having seen it,
    /// where it believes it is, in the grabbing child's view.
    pub view_recentres: u32,
    /// Grabs the parent ordered while it still saw a robot, where it tracks it, in the
    /// grabbing child's view (its own estimate of the view rule; the truth's count is
    /// `images_with_robot_in_view` and `images_with_distant_robot_in_view`).
    pub grabs_with_tracked_robot_in_view: u32,
    /// Database images with another robot in the child camera's view within r_los, where
    /// the plan keeps robots out of the images (should be zero).
    pub images_with_robot_in_view: usize,
    /// The child sent on a new path after mapping (`[coverage] localize_steps` moves), its
    /// particle filters against this run's database, per feature, against its truth. Empty
    /// when no such run was made (or the child took no image).
    pub localization: Vec<crate::localize::PathRun>,
    /// That child, by name.
    pub localization_child: Option<String>,
    /// When the parent heard that child report its run done, minutes (absent while the run
    /// went on, or when the parent gave up on it).
    pub localized_min: Option<f64>,
    /// The parent gave up on the run: no report within a minute per move.
    pub localization_timed_out: bool,
    /// The encoders' scale that child was sent, metres travelled per metre counted, as the
    /// parent measured it from its tracks while mapping (1: too few hops seen).
    pub localization_odometry_scale: Option<f64>,
    /// The hops between two images the parent saw it take that the scale rests on.
    pub localization_odometry_hops: Option<usize>,
    /// The same hops measured on the child's true positions at the images' stamps: their
    /// median of true straight distance over counted distance. Its difference from the scale
    /// sent is the tracker's share of the calibration's error (absent with no hops).
    pub localization_odometry_scale_true: Option<f64>,
    /// Database images with another robot in view farther than r_los (the seed's planner
    /// does not consider robots beyond r_los; a 1.5 m parent is visible across a room).
    pub images_with_distant_robot_in_view: usize,
    /// The parent's laser localization against its truth (absent when it steered by the
    /// oracle pose).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parent_localization: Option<ParentLocalization>,
    /// The parent's fixes of the children (its tracked paths) against their truth.
    pub tracking: Tracking,
}

/// The parent's fixes of the children, placed on the map by its own pose, against the
/// children's true positions at the fixes' stamps: the tracker's accuracy (the seed's
/// 0.04 ± 0.02 m within r_los) with the parent's localization error added.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tracking {
    /// Fixes compared (the tracked paths keep at most one per child every 0.2 s).
    pub fixes: usize,
    /// Horizontal position error, metres.
    pub error_m: MeanStd,
    /// 95th percentile of the error, metres.
    pub error_p95_m: f64,
    /// Largest error, metres.
    pub error_max_m: f64,
}

/// The 95th percentile (nearest rank) and the largest of `v`; 0 for none.
fn p95_max(v: &[f64]) -> (f64, f64) {
    let mut sorted = v.to_vec();
    sorted.sort_by(f64::total_cmp);
    let p95 = sorted
        .get(((sorted.len() as f64 * 0.95).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(0.0);
    (p95, sorted.last().copied().unwrap_or(0.0))
}

impl Tracking {
    /// The report's tracked paths against the children's truth.
    fn of(scenario: &Scenario, report: &TeamReport, truth: &[Vec<(u64, Pose)>]) -> Self {
        let mut err = Vec::new();
        for (name, path) in &report.tracked_paths {
            let Some(i) = scenario.robots.iter().position(|r| r.spec.name == *name) else {
                continue;
            };
            for (stamp, xy) in path {
                let t = truth_at(&truth[i], *stamp).translation.vector;
                err.push((xy[0] - t.x).hypot(xy[1] - t.y));
            }
        }
        let (error_p95_m, error_max_m) = p95_max(&err);
        Self {
            fixes: err.len(),
            error_m: MeanStd::population(&err),
            error_p95_m,
            error_max_m,
        }
    }
}

/// The parent's Monte Carlo localization (its `mcl` trajectory, one pose per filter update)
/// against its true pose at the same stamps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParentLocalization {
    /// Estimates compared.
    pub estimates: usize,
    /// Horizontal position error, metres.
    pub position_error_m: MeanStd,
    /// 95th percentile of the position error, metres.
    pub position_error_p95_m: f64,
    /// Largest position error, metres.
    pub position_error_max_m: f64,
    /// Heading error, degrees.
    pub heading_error_deg: MeanStd,
    /// Largest heading error, degrees.
    pub heading_error_max_deg: f64,
}

impl ParentLocalization {
    /// The parent's `mcl` trajectory among the run's artifacts, against its truth.
    pub fn of(output: &RunOutput, parent: &str) -> Option<Self> {
        let (_, artifacts) = output.artifacts.iter().find(|(r, _)| r == parent)?;
        let poses = artifacts.iter().find_map(|a| match &a.data {
            hetsim_msgs::ArtifactData::Trajectory(p) if a.name == "mcl" => Some(p),
            _ => None,
        })?;
        let truth = output.truth_of(parent)?;
        let (mut pos, mut head) = (Vec::new(), Vec::new());
        for (stamp, est) in poses {
            let t = truth_at(truth, *stamp);
            let (a, b) = (est.translation.vector, t.translation.vector);
            pos.push((a.x - b.x).hypot(a.y - b.y));
            head.push(wrap_angle(yaw_of(est) - yaw_of(&t)).abs().to_degrees());
        }
        let (p95, max) = p95_max(&pos);
        Some(Self {
            estimates: pos.len(),
            position_error_m: MeanStd::population(&pos),
            position_error_p95_m: p95,
            position_error_max_m: max,
            heading_error_deg: MeanStd::population(&head),
            heading_error_max_deg: p95_max(&head).1,
        })
    }
}

/// The distance to the nearest other robot that appears in the image child `robot` took at
/// `stamp_ns` (any of its footprint centre and corners, at half its height, projects inside
/// the image with nothing static in between), metres between the robots' centres.
fn robot_in_view(
    scenario: &Scenario,
    physics: &Physics,
    truth: &[Vec<(u64, Pose)>],
    robot: usize,
    stamp_ns: u64,
) -> Option<f64> {
    let (mount, k, _) = camera_of(&scenario.robots[robot])?;
    let body = truth_at(&truth[robot], stamp_ns);
    let cam = body * mount;
    let optical = Isometry3::from_parts(cam.translation, cam.rotation * mount_to_optical());
    let all: Vec<usize> = (0..truth.len()).collect();
    let seen = (0..truth.len()).filter(|&j| j != robot).filter(|&j| {
        let other = truth_at(&truth[j], stamp_ns);
        let b = &scenario.robots[j].model.body;
        let (hl, hw, hh) = (b.length_m / 2.0, b.width_m / 2.0, b.height_m / 2.0);
        [(0.0, 0.0), (hl, hw), (hl, -hw), (-hl, hw), (-hl, -hw)]
            .iter()
            .any(|&(x, y)| {
                let world = other * Point3::new(x, y, hh);
                let p = optical.inverse_transform_point(&world);
                if p.z <= 0.01 {
                    return false;
                }
                let u = k.k.alpha_u * p.x / p.z + k.k.u0;
                let v = k.k.alpha_v * p.y / p.z + k.k.v0;
                let inside = u >= -0.5
                    && v >= -0.5
                    && u <= k.width as f64 - 0.5
                    && v <= k.height as f64 - 0.5;
                let from = cam.translation.vector;
                inside
                    && physics.clear_line(
                        [from.x, from.y, from.z],
                        [world.x, world.y, world.z],
                        &all,
                    )
            })
    });
    let here = body.translation.vector;
    seen.map(|j| {
        let t = truth_at(&truth[j], stamp_ns).translation.vector;
        (t.x - here.x).hypot(t.y - here.y)
    })
    .min_by(f64::total_cmp)
}

impl TeamMetrics {
    /// The figures of a mission from its parent's report, ground truth and the robots'
    /// metrics.
    pub fn compute(scenario: &Scenario, outcome: &TeamOutcome, output: &RunOutput) -> Self {
        // Line of sight through the static world only (robots are ignored), so a fresh
        // physics world of the scenario answers as the run's would.
        let physics = Physics::for_scenario(scenario, &hetsim_core::Streams::new(scenario.seed));
        let physics = &physics;
        let truth: Vec<Vec<(u64, Pose)>> = output.truth.iter().map(|(_, t)| t.clone()).collect();
        let truth = &truth[..];
        let r = &outcome.report;
        let grid = &scenario
            .world
            .grid
            .as_ref()
            .expect("coverage missions run in indoor worlds")
            .grid;
        let mapping = direction_rad(scenario);
        let index = |name: &str| scenario.robots.iter().position(|x| x.spec.name == name);
        let mut imaged: Vec<(usize, usize)> = r.database.iter().map(|d| d.vertex).collect();
        imaged.sort_unstable();
        imaged.dedup();
        let (mut pos, mut tracked, mut head, mut compass, mut est) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut in_view, mut distant) = (0, 0);
        let r_los = hetsim_scene::coverage_params(scenario).r_los_m;
        for d in &r.database {
            let Some(i) = index(&d.child) else { continue };
            let centre = grid.centre_of(d.vertex.0, d.vertex.1);
            let pose = truth_at(&truth[i], d.image.stamp_ns);
            let t = pose.translation.vector;
            pos.push((t.x - centre[0]).hypot(t.y - centre[1]));
            tracked.push((d.estimated_xy[0] - centre[0]).hypot(d.estimated_xy[1] - centre[1]));
            est.push((d.estimated_xy[0] - t.x).hypot(d.estimated_xy[1] - t.y));
            head.push(wrap_angle(yaw_of(&pose) - mapping).abs().to_degrees());
            compass.push(
                wrap_angle(d.estimated_heading_rad - mapping)
                    .abs()
                    .to_degrees(),
            );
            match robot_in_view(scenario, physics, truth, i, d.image.stamp_ns) {
                Some(m) if m <= r_los => in_view += 1,
                Some(_) => distant += 1,
                None => {}
            }
        }
        let target = r.vertices.saturating_sub(r.parent_vertices.len());
        let end_ns = r
            .finished_ns
            .unwrap_or_else(|| truth.first().and_then(|t| t.last()).map_or(0, |p| p.0));
        Self {
            children: scenario
                .robots
                .iter()
                .filter(|x| matches!(x.spec.mission, hetsim_scene::MissionSpec::CoverageChild))
                .count(),
            vertices: r.vertices,
            parent_vertices: r.parent_vertices.len(),
            imaged: imaged.len(),
            imaged_fraction: if target == 0 {
                1.0
            } else {
                imaged.len() as f64 / target as f64
            },
            unplanned: r.unplanned.clone(),
            abandoned: r.abandoned.clone(),
            finished: r.finished_ns.is_some(),
            mission_min: end_ns as f64 / 60e9,
            position_error_m: MeanStd::population(&pos),
            tracked_position_error_m: MeanStd::population(&tracked),
            heading_error_deg: MeanStd::population(&head),
            compass_heading_error_deg: MeanStd::population(&compass),
            estimate_error_m: MeanStd::population(&est),
            collisions: output.robots.iter().map(|m| m.collisions).sum(),
            tracking_losses: r.tracking_losses,
            resent_orders: r.resent_orders,
            view_recentres: r.view_recentres,
            grabs_with_tracked_robot_in_view: r.grabs_with_tracked_robot_in_view,
            images_with_robot_in_view: in_view,
            images_with_distant_robot_in_view: distant,
            localization: crate::localize::in_lockstep(r, output),
            localization_child: r.tour.as_ref().map(|t| t.child.clone()),
            localized_min: r
                .tour
                .as_ref()
                .filter(|t| !t.timed_out)
                .and_then(|t| t.over_ns)
                .map(|ns| ns as f64 / 60e9),
            localization_timed_out: r.tour.as_ref().is_some_and(|t| t.timed_out),
            localization_odometry_scale: r.tour.as_ref().map(|t| t.odometry_scale),
            localization_odometry_hops: r.tour.as_ref().map(|t| t.odometry_hops.len()),
            localization_odometry_scale_true: r.tour.as_ref().and_then(|t| {
                let truth = output.truth_of(&t.child).filter(|tr| !tr.is_empty())?;
                let at = |ns: u64| truth_at(truth, ns).translation.vector;
                hetsim_coverage::median(
                    t.odometry_hops
                        .iter()
                        .map(|h| (at(h.to_ns) - at(h.from_ns)).xy().norm() / h.counted_m)
                        .collect(),
                )
            }),
            parent_localization: ParentLocalization::of(output, &outcome.parent),
            tracking: Tracking::of(scenario, r, truth),
        }
    }
}

/// The mission's files: the database (`coverage/images/<col>_<row>.png` and
/// `coverage/database.json` with the parent's estimate and the true pose of every grab, and
/// its features: the 128 WGOH values and the 15 x 11 thumbnail), and
/// the plots `plots/coverage-plan.png` (Fig. 5a) and `plots/coverage-paths.png` (Fig. 5b).
pub fn files(
    scenario: &Scenario,
    outcome: &TeamOutcome,
    truth: &[(String, Vec<(u64, Pose)>)],
) -> Vec<(String, Vec<u8>)> {
    let Some(g) = scenario.world.grid.as_ref() else {
        return Vec::new();
    };
    let grid = &g.grid;
    let r = &outcome.report;
    let png = |img: image::RgbImage| crate::charts::png(&img);
    let mut out = Vec::new();
    let mut entries = Vec::new();
    for d in &r.database {
        let name = format!("coverage/images/{}_{}.png", d.vertex.0, d.vertex.1);
        if let Some(img) =
            image::RgbImage::from_raw(d.image.width, d.image.height, d.image.to_rgb().into_owned())
        {
            out.push((name.clone(), png(img)));
        }
        let pose = truth
            .iter()
            .find(|(n, _)| *n == d.child)
            .map(|(_, t)| truth_at(t, d.image.stamp_ns));
        let gray = hetsim_vision::Gray::from_image(&d.image)
            .expect("the child's stack accepted the image: its bytes are its size");
        let features = hetsim_vision::appearance::Features::of(&gray);
        entries.push(json!({
            "wgoh": features.wgoh.0,
            "thumbnail_15x11": features.thumbnail.data,
            "vertex": [d.vertex.0, d.vertex.1],
            "vertex_xy_m": grid.centre_of(d.vertex.0, d.vertex.1),
            "child": d.child,
            "stamp_ns": d.image.stamp_ns,
            "image": name.trim_start_matches("coverage/"),
            "estimated_xy_m": d.estimated_xy,
            "estimated_heading_rad": d.estimated_heading_rad,
            "true_xy_m": pose.map(|p| [p.translation.vector.x, p.translation.vector.y]),
            "true_heading_rad": pose.map(|p| yaw_of(&p)),
        }));
    }
    let database = json!({
        "direction_rad": direction_rad(scenario),
        "grid": {"origin_m": [grid.origin_x, grid.origin_y], "cell_m": grid.cell_m, "cols": grid.cols, "rows": grid.rows},
        "parent_vertices": r.parent_vertices,
        "images": entries,
    });
    out.push((
        "coverage/database.json".into(),
        serde_json::to_vec_pretty(&database).expect("serializes"),
    ));
    let parent_xy: Vec<[f64; 2]> = r
        .parent_vertices
        .iter()
        .map(|(c, rw)| grid.centre_of(*c, *rw))
        .collect();
    let start = truth
        .iter()
        .find(|(n, _)| *n == outcome.parent)
        .and_then(|(_, t)| t.first())
        .map_or([0.0, 0.0], |(_, p)| {
            [p.translation.vector.x, p.translation.vector.y]
        });
    let plan = crate::charts::CoverageMap {
        title: "coverage plan: parent vertices and the parent's tour (Fig. 5a)",
        start,
        parent_vertices: &parent_xy,
        tour: true,
        paths: &[],
        grabs: &[],
    };
    out.push((
        "plots/coverage-plan.png".into(),
        crate::charts::coverage_map_png(grid, &plan),
    ));
    let paths: Vec<(String, Vec<[f64; 2]>)> = r
        .tracked_paths
        .iter()
        .map(|(name, p)| (name.clone(), p.iter().map(|(_, xy)| *xy).collect()))
        .collect();
    let grabs: Vec<[f64; 2]> = r.database.iter().map(|d| d.estimated_xy).collect();
    let mission = crate::charts::CoverageMap {
        title: "the children's tracked paths and their grabs (Fig. 5b)",
        start,
        parent_vertices: &parent_xy,
        tour: false,
        paths: &paths,
        grabs: &grabs,
    };
    out.push((
        "plots/coverage-paths.png".into(),
        crate::charts::coverage_map_png(grid, &mission),
    ));
    out
}
