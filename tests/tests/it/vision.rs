//! The vision front-end on rendered frames, against the renderer's ground truth.

use hetsim_msgs::Pinhole;
use hetsim_msgs::{mount_to_optical, CameraGeometry};
use hetsim_msgs::{pose_from_xyz_rpy, Pose};
use hetsim_render::{CameraView, RenderOptions, Renderer};
use hetsim_scene::world::SolidKind;
use hetsim_scene::{load_scenario, LoadOptions, Scenario};
use hetsim_tests::repo;
use hetsim_vision::harris::{detect, select_new};
use hetsim_vision::segments::{
    detect as detect_segments, project_segment, track, DetectParams, Segment, TrackParams,
};
use hetsim_vision::stereo::{match_stereo, Bench};
use hetsim_vision::vo::StereoVo;
use hetsim_vision::Gray;
use nalgebra::{Isometry3, Point3, Vector3};
use rand::SeedableRng;

fn village() -> Scenario {
    load_scenario(
        &repo().join("scenarios/village.toml"),
        &LoadOptions::default(),
    )
    .unwrap()
}

const K: CameraGeometry = hetsim_tests::TEST_INTRINSICS;
const CAM: Pinhole = K.k;

/// Left and right views of a bench whose left camera mount is `mount` (body convention).
fn bench_views(mount: &Pose, baseline: f64) -> [CameraView; 2] {
    let right = mount * pose_from_xyz_rpy([0.0, -baseline, 0.0], [0.0; 3]);
    [mount, &right].map(|m| CameraView::from_mount(K, m, [0.05, 3000.0]).with_depth())
}

fn gray(f: &hetsim_render::Frame) -> Gray {
    Gray::from_rgb(f.width as usize, f.height as usize, &f.rgb()).expect("w x h x 3")
}

/// The rover's bench at the entry of the north-west village, looking into it.
fn rover_mount(s: &Scenario, forward_m: f64, yaw_offset: f64) -> Pose {
    let d = &s.robots[0].spec.start;
    let yaw = d.yaw_deg.to_radians() + yaw_offset;
    let (x, y) = (d.x + forward_m * yaw.cos(), d.y + forward_m * yaw.sin());
    pose_from_xyz_rpy(
        [x, y, s.world.ground_z(x, y) + 1.4],
        [0.0, 8f64.to_radians(), yaw],
    )
}

#[test]
fn stereo_depth_matches_the_depth_buffer() {
    let s = village();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let frames = r.render(&bench_views(&rover_mount(&s, 0.0, 0.0), 0.35));
    let (l, rt) = (gray(&frames[0]), gray(&frames[1]));
    let corners = detect(&l, 0.005, 8);
    let chosen = select_new(&corners, l.width, l.height, &[], 30, 6.0);
    let points = match_stereo(
        &l,
        &rt,
        &Bench {
            camera: CAM,
            baseline_m: 0.35,
        },
        &chosen,
        [1.0, 60.0],
        0.85,
    );
    assert!(points.len() >= 60, "{} stereo points", points.len());
    let mut rel: Vec<f64> = points
        .iter()
        .filter_map(|p| {
            // Corners sit on depth edges: compare with the surfaces in the pixel's 3 x 3
            // neighbourhood and keep the closest.
            let (x, y) = (p.left[0] as i64, p.left[1] as i64);
            (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)))
                .map(|(xx, yy)| {
                    frames[0].depth()[yy as usize * K.width as usize + xx as usize] as f64
                })
                .filter(|t| *t > 0.0)
                .map(|t| (p.disparity - CAM.alpha_u * 0.35 / t).abs())
                .min_by(f64::total_cmp)
        })
        .collect();
    rel.sort_by(f64::total_cmp);
    let median = rel[rel.len() / 2];
    let p90 = rel[rel.len() * 9 / 10];
    // Stated bound, in disparity (depth error is Z^2 / (f b) times it: a quarter pixel is
    // 10 % of depth at 60 m): median error under 0.2 px, 90th percentile under 0.5 px.
    assert!(
        median < 0.2 && p90 < 0.5,
        "median {median:.4}, 90th percentile {p90:.4} over {} points",
        rel.len()
    );
}

#[test]
fn harris_points_repeat_under_small_camera_motion() {
    let s = village();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let (a, b) = (
        rover_mount(&s, 0.0, 0.0),
        rover_mount(&s, 0.3, 1f64.to_radians()),
    );
    let frames = r.render(&[
        bench_views(&a, 0.35)[0].clone(),
        bench_views(&b, 0.35)[0].clone(),
    ]);
    let ca = detect(&gray(&frames[0]), 0.01, 10);
    let cb = detect(&gray(&frames[1]), 0.01, 10);
    let b_from_a = optical(&b).inverse() * optical(&a);
    let (mut visible, mut repeated) = (0, 0);
    for c in ca.iter().take(300) {
        let z = frames[0].depth()[c.y * K.width as usize + c.x] as f64;
        if z <= 0.0 {
            continue;
        }
        let p = b_from_a * Point3::from(CAM.back_project(c.x as f64, c.y as f64, z));
        let Some([u, v]) = CAM.project(&p.coords) else {
            continue;
        };
        if u < 12.0 || v < 12.0 || u > K.width as f64 - 12.0 || v > K.height as f64 - 12.0 {
            continue;
        }
        visible += 1;
        if cb
            .iter()
            .any(|d| (d.x as f64 - u).hypot(d.y as f64 - v) <= 2.0)
        {
            repeated += 1;
        }
    }
    let rate = repeated as f64 / visible.max(1) as f64;
    // Stated bound: at least 60 % of the strongest corners are found again within 2 px
    // after 0.3 m forward and 1 deg of yaw.
    assert!(
        visible > 100 && rate > 0.6,
        "{repeated} of {visible} repeated ({rate:.2})"
    );
}

/// What stereo VO made of a rendered sequence.
struct VoRun {
    /// Frames with a motion estimate.
    tracked: usize,
    /// Position error at the end, metres.
    drift: f64,
    /// Rotation error at the end, degrees.
    rotation: f64,
    /// Per tracked frame: estimated over true translation length.
    ratios: Vec<f64>,
}

impl VoRun {
    fn median_ratio(&self) -> f64 {
        let mut r = self.ratios.clone();
        if r.is_empty() {
            return f64::NAN;
        }
        r.sort_by(f64::total_cmp);
        r[r.len() / 2]
    }
}

/// Runs stereo VO over the bench views of `mounts`.
fn vo_over(s: &Scenario, mounts: &[Pose], baseline: f64) -> VoRun {
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let mut vo = StereoVo::new(Bench {
        camera: CAM,
        baseline_m: baseline,
    });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut estimate = optical(&mounts[0]);
    let (mut tracked, mut ratios) = (0, Vec::new());
    for (k, m) in mounts.iter().enumerate() {
        let f = r.render(&bench_views(m, baseline));
        if let Some(motion) = vo.process(&gray(&f[0]), &gray(&f[1]), &mut rng) {
            estimate *= motion.current_from_previous.inverse();
            tracked += 1;
            if k > 0 {
                let step = optical(m).inverse() * optical(&mounts[k - 1]);
                let (est, truth) = (
                    motion.current_from_previous.translation.vector.norm(),
                    step.translation.vector.norm(),
                );
                ratios.push(est / truth);
            }
        }
    }
    let truth = optical(mounts.last().unwrap());
    let run = VoRun {
        tracked,
        drift: (estimate.translation.vector - truth.translation.vector).norm(),
        rotation: estimate.rotation.angle_to(&truth.rotation).to_degrees(),
        ratios,
    };
    println!(
        "VO: {} frames tracked, drift {:.3} m, rotation {:.2} deg, median estimated/true translation {:.4}",
        run.tracked,
        run.drift,
        run.rotation,
        run.median_ratio()
    );
    run
}

#[test]
fn visual_odometry_drift_on_a_rendered_rover_sequence() {
    let s = village();
    // 0.06 m per frame (0.6 m/s at 10 Hz) with a gentle turn, 60 frames: 3.6 m.
    let steps = 60;
    let mounts: Vec<Pose> = (0..=steps)
        .map(|k| rover_mount(&s, 0.06 * k as f64, 0.002 * k as f64))
        .collect();
    let VoRun {
        tracked,
        drift,
        rotation,
        ..
    } = vo_over(&s, &mounts, 0.35);
    assert_eq!(tracked, steps, "every frame tracked");
    let travelled = 0.06 * steps as f64;
    // Stated bound: under 5 % of the distance travelled (5 m per 100 m); measured 3.7 % when
    // this bound was set (0.134 m over 3.6 m). A short rendered sequence: 100 m of rendered
    // frames would take minutes on a CPU rasterizer.
    assert!(
        drift < 0.05 * travelled,
        "drift {drift:.3} m over {travelled:.1} m"
    );
    assert!(rotation < 1.0, "rotation error {rotation:.2} deg");
}

#[test]
fn visual_odometry_drift_on_a_rendered_helicopter_sequence() {
    let s = village();
    // Ressac's bench (0.9 m baseline) looking straight down from 40 m above the start,
    // flying 0.6 m per frame (6 m/s at 10 Hz) over the north-west group, climbing gently.
    let d = &s.robots[1].spec.start;
    let yaw = d.yaw_deg.to_radians();
    let steps = 40;
    let mounts: Vec<Pose> = (0..=steps)
        .map(|k| {
            let t = 0.6 * k as f64;
            pose_from_xyz_rpy(
                [d.x + t * yaw.cos(), d.y + t * yaw.sin(), 40.0 + 0.02 * t],
                [0.0, 90f64.to_radians(), yaw + 0.003 * k as f64],
            )
        })
        .collect();
    let VoRun {
        tracked,
        drift,
        rotation,
        ..
    } = vo_over(&s, &mounts, 0.9);
    assert_eq!(tracked, steps, "every frame tracked");
    let travelled = 0.6 * steps as f64;
    // Stated bound: under 3 % of the distance travelled (3 m per 100 m); measured 1.0 % when
    // this bound was set (0.244 m over 24 m, 0.3 deg). Depth from a 0.9 m baseline at 40 m is
    // coarse (10 px of disparity), so the bound is per distance, not per altitude.
    assert!(
        drift < 0.03 * travelled,
        "drift {drift:.3} m over {travelled:.1} m"
    );
    assert!(rotation < 1.0, "rotation error {rotation:.2} deg");
}

/// The 3D lines of a building: its box's 12 edges, and where its walls meet the ground.
fn building_lines(s: &Scenario) -> Vec<[Point3<f64>; 2]> {
    let mut lines = Vec::new();
    for b in s
        .world
        .solids
        .iter()
        .filter(|b| b.kind == SolidKind::Building)
    {
        let (sn, cs) = b.yaw_rad.sin_cos();
        let h = b.half_extents;
        let corner = |i: usize, z: f64| {
            let (lx, ly) = (
                if i == 1 || i == 2 { h[0] } else { -h[0] },
                if i >= 2 { h[1] } else { -h[1] },
            );
            Point3::new(
                b.centre[0] + cs * lx - sn * ly,
                b.centre[1] + sn * lx + cs * ly,
                z,
            )
        };
        let (bottom, top) = (b.centre[2] - h[2], b.centre[2] + h[2]);
        for i in 0..4 {
            let j = (i + 1) % 4;
            lines.push([corner(i, bottom), corner(j, bottom)]);
            lines.push([corner(i, top), corner(j, top)]);
            lines.push([corner(i, bottom), corner(i, top)]);
            let ground = |k: usize| {
                let p = corner(k, 0.0);
                Point3::new(p.x, p.y, s.world.ground_z(p.x, p.y))
            };
            lines.push([ground(i), ground(j)]);
        }
    }
    lines
}

fn optical(m: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(m.translation, m.rotation * mount_to_optical())
}

/// A segment found on a building in a rendered frame: its distance to the nearest projected
/// building edge it overlaps (the larger of its endpoints' distances, pixels) and that edge's 3D
/// line.
struct OnBuilding {
    segment: Segment,
    distance: f64,
    edge: [Point3<f64>; 2],
}

/// Segments detected in `frame` (seen from `mount`) with a building on at least one side: a
/// pixel 3 px either side of their middle whose depth-buffer point lies on a building.
fn segments_on_buildings(
    s: &Scenario,
    lines: &[[Point3<f64>; 2]],
    frame: &hetsim_render::Frame,
    mount: &Pose,
) -> Vec<OnBuilding> {
    let w2c = optical(mount);
    let on_building = |p: [f64; 2]| {
        let (x, y) = (p[0].round() as i64, p[1].round() as i64);
        if x < 0 || y < 0 || x >= K.width as i64 || y >= K.height as i64 {
            return false;
        }
        let z = frame.depth()[y as usize * K.width as usize + x as usize] as f64;
        let w = w2c * Point3::from(CAM.back_project(x as f64, y as f64, z));
        s.world.solids.iter().any(|b| {
            let (sn, cs) = b.yaw_rad.sin_cos();
            let (dx, dy, dz) = (w.x - b.centre[0], w.y - b.centre[1], w.z - b.centre[2]);
            let local = [cs * dx + sn * dy, -sn * dx + cs * dy, dz];
            b.kind == SolidKind::Building
                && (0..3).all(|k| local[k].abs() <= b.half_extents[k] + 0.05)
        })
    };
    let projected: Vec<(Segment, [Point3<f64>; 2])> = lines
        .iter()
        .filter_map(|l| project_segment(&CAM, &w2c, &l[0], &l[1], 0.1).map(|e| (e, *l)))
        .collect();
    detect_segments(&gray(frame), &DetectParams::default())
        .into_iter()
        .filter(|sg| {
            let m = sg.at(sg.length() / 2.0);
            let n = [sg.direction().y * 3.0, -sg.direction().x * 3.0];
            on_building([m[0] + n[0], m[1] + n[1]]) || on_building([m[0] - n[0], m[1] - n[1]])
        })
        .map(|segment| {
            let (distance, edge) = projected
                .iter()
                .filter(|(e, _)| {
                    // The detection must overlap the edge's extent, not just its line.
                    let (s0, s1) = (e.abscissa(segment.a), e.abscissa(segment.b));
                    s0.max(s1) > 0.0 && s0.min(s1) < e.length()
                })
                .map(|(e, l)| {
                    let d = e.line_distance(segment.a).abs();
                    (d.max(e.line_distance(segment.b).abs()), *l)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .unwrap_or((f64::MAX, lines[0]));
            OnBuilding {
                segment,
                distance,
                edge,
            }
        })
        .collect()
}

/// Three rover views into the north-west group and two helicopter views looking down on it.
fn building_views(s: &Scenario) -> Vec<Pose> {
    let d = &s.robots[0].spec.start;
    let heli = |dx: f64, dy: f64, z: f64| {
        pose_from_xyz_rpy([d.x + dx, d.y + dy, z], [0.0, 90f64.to_radians(), 0.3])
    };
    vec![
        rover_mount(s, 0.0, 0.0),
        rover_mount(s, 8.0, 0.3),
        rover_mount(s, 15.0, -0.4),
        heli(-25.0, 25.0, 40.0),
        heli(-40.0, 10.0, 30.0),
    ]
}

#[test]
fn detected_segments_lie_on_projected_building_edges() {
    let s = village();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let lines = building_lines(&s);
    let mut found = Vec::new();
    for mount in building_views(&s) {
        let f = r.render(&[bench_views(&mount, 0.35)[0].clone()]);
        found.extend(segments_on_buildings(&s, &lines, &f[0], &mount));
    }
    let distances: Vec<f64> = found.iter().map(|o| o.distance).collect();
    let on = distances.iter().filter(|d| **d <= 2.0).count();
    // Stated bound: at least 12 segments of 60 px or more on buildings over the five views,
    // and 90 % of them with both endpoints within 2 px of a projected building edge
    // (measured when set: 14 of 14, the worst 1.7 px).
    assert!(
        found.len() >= 12 && on as f64 >= 0.9 * found.len() as f64,
        "{on} of {} within 2 px: {distances:.2?}",
        found.len()
    );
}

#[test]
fn segments_are_tracked_from_a_predicted_3d_segment() {
    let s = village();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let lines = building_lines(&s);
    let (mut tried, mut good) = (0, 0);
    let mut errors = Vec::new();
    for mount in building_views(&s) {
        // The next frame: 0.3 m along the optical axis and 1 deg of yaw; the prediction is
        // made from a pose 5 cm and 0.5 deg off the truth, as a filter's would be.
        let next = mount * pose_from_xyz_rpy([0.3, 0.05, 0.0], [0.0, 0.0, 1f64.to_radians()]);
        let predicted_pose =
            next * pose_from_xyz_rpy([0.03, -0.04, 0.0], [0.0, 0.0, 0.5f64.to_radians()]);
        let f = r.render(&[
            bench_views(&mount, 0.35)[0].clone(),
            bench_views(&next, 0.35)[0].clone(),
        ]);
        for o in segments_on_buildings(&s, &lines, &f[0], &mount) {
            if o.distance > 2.0 {
                continue;
            }
            // The segment's 3D estimate: the edge's points nearest the rays through its ends.
            let c = optical(&mount);
            let [p, q] = [o.segment.a, o.segment.b].map(|e| {
                let ray = c.rotation * CAM.back_project(e[0], e[1], 1.0).normalize();
                nearest_on_line(&o.edge, &Point3::from(c.translation.vector), &ray)
            });
            let Some(prediction) = project_segment(&CAM, &optical(&predicted_pose), &p, &q, 0.1)
            else {
                continue;
            };
            tried += 1;
            let Some(t) = track(&gray(&f[1]), &prediction, &TrackParams::default()) else {
                continue;
            };
            let truth = project_segment(&CAM, &optical(&next), &o.edge[0], &o.edge[1], 0.1)
                .expect("in front");
            let e = truth
                .line_distance(t.a)
                .abs()
                .max(truth.line_distance(t.b).abs());
            errors.push(e);
            if e <= 2.0 && t.length() >= 0.8 * prediction.length() {
                good += 1;
            }
        }
    }
    // Stated bound: 80 % of the segments are tracked onto the true edge within 2 px and to at
    // least 80 % of the predicted length (measured when set: 12 of 14).
    assert!(
        tried >= 10 && good as f64 >= 0.8 * tried as f64,
        "{good} of {tried} tracked within 2 px: {errors:.2?}"
    );
}

/// The point of the 3D line `l` nearest the ray from `o` along unit `d`.
fn nearest_on_line(l: &[Point3<f64>; 2], o: &Point3<f64>, d: &Vector3<f64>) -> Point3<f64> {
    let u = (l[1] - l[0]).normalize();
    let w0 = l[0] - o;
    let (b, dd, e) = (u.dot(d), u.dot(&w0), d.dot(&w0));
    let denom = 1.0 - b * b;
    let s = if denom.abs() < 1e-12 {
        0.0
    } else {
        (b * e - dd) / denom
    };
    l[0] + u * s
}
