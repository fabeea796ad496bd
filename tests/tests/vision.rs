//! The vision front-end on rendered frames, against the renderer's ground truth.

use hetsim_msgs::{pose_from_xyz_rpy, Pose};
use hetsim_render::{mount_to_optical, CameraView, Intrinsics, RenderOptions, Renderer};
use hetsim_scene::{load_scenario, LoadOptions, Scenario};
use hetsim_tests::repo;
use hetsim_vision::harris::{detect, select_new};
use hetsim_vision::stereo::{match_stereo, Bench};
use hetsim_vision::vo::StereoVo;
use hetsim_vision::{Camera, Gray};
use nalgebra::{Isometry3, Point3};
use rand::SeedableRng;

fn village() -> Scenario {
    load_scenario(
        &repo().join("scenarios/village.toml"),
        &LoadOptions::default(),
    )
    .unwrap()
}

const K: Intrinsics = Intrinsics {
    width: 512,
    height: 384,
    alpha_u: 443.4,
    alpha_v: 443.4,
    u0: 255.5,
    v0: 191.5,
};
const CAM: Camera = Camera {
    alpha_u: 443.4,
    alpha_v: 443.4,
    u0: 255.5,
    v0: 191.5,
};

/// Left and right views of a bench whose left camera mount is `mount` (body convention).
fn bench_views(mount: &Pose, baseline: f64) -> [CameraView; 2] {
    let right = mount * pose_from_xyz_rpy([0.0, -baseline, 0.0], [0.0; 3]);
    [mount, &right].map(|m| CameraView::from_mount(K, m, [0.05, 3000.0]))
}

fn gray(f: &hetsim_render::Frame) -> Gray {
    Gray::from_rgb(f.width as usize, f.height as usize, &f.rgb)
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
                    frames[0].depth_m[yy as usize * K.width as usize + xx as usize] as f64
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
    let optical = |m: &Pose| Isometry3::from_parts(m.translation, m.rotation * mount_to_optical());
    let b_from_a = optical(&b).inverse() * optical(&a);
    let (mut visible, mut repeated) = (0, 0);
    for c in ca.iter().take(300) {
        let z = frames[0].depth_m[c.y * K.width as usize + c.x] as f64;
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

#[test]
fn visual_odometry_drift_on_a_rendered_rover_sequence() {
    let s = village();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let mut vo = StereoVo::new(Bench {
        camera: CAM,
        baseline_m: 0.35,
    });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let optical = |m: &Pose| Isometry3::from_parts(m.translation, m.rotation * mount_to_optical());
    // 0.06 m per frame (0.6 m/s at 10 Hz) with a gentle turn, 60 frames: 3.6 m.
    let steps = 60;
    let mounts: Vec<Pose> = (0..=steps)
        .map(|k| rover_mount(&s, 0.06 * k as f64, 0.002 * k as f64))
        .collect();
    let mut estimate = optical(&mounts[0]);
    let mut tracked = 0;
    for m in &mounts {
        let f = r.render(&bench_views(m, 0.35));
        if let Some(motion) = vo.process(&gray(&f[0]), &gray(&f[1]), &mut rng) {
            estimate *= motion.current_from_previous.inverse();
            tracked += 1;
        }
    }
    assert_eq!(tracked, steps, "every frame tracked");
    let truth = optical(&mounts[steps]);
    let travelled = 0.06 * steps as f64;
    let drift = (estimate.translation.vector - truth.translation.vector).norm();
    // Stated bound: under 5 % of the distance travelled (5 m per 100 m); measured 3.7 % when
    // this bound was set (0.134 m over 3.6 m). Rover only, on a short rendered sequence:
    // 100 m of rendered frames would take minutes on a CPU rasterizer.
    assert!(
        drift < 0.05 * travelled,
        "drift {drift:.3} m over {travelled:.1} m"
    );
    assert!(estimate.rotation.angle_to(&truth.rotation).to_degrees() < 1.0);
}
