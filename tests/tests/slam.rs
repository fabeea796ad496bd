//! The local level of the hierarchical SLAM on rendered frames, against ground truth.

use hetsim_msgs::{pose_from_xyz_rpy, Image, Pose, PoseStamped, RobotStack, SensorMsg};
use hetsim_render::{mount_to_optical, CameraView, Intrinsics, RenderOptions, Renderer};
use hetsim_scene::{load_scenario, LoadOptions};
use hetsim_slam::stack::{SlamParams, SlamStack};
use hetsim_tests::repo;
use hetsim_vision::stereo::Bench;
use hetsim_vision::Camera;
use nalgebra::Isometry3;

const K: Intrinsics = hetsim_tests::TEST_INTRINSICS;

/// A stack that does nothing: the SLAM's inner pilot.
struct Still;

impl RobotStack for Still {
    fn step(&mut self, _: u64, _: &[SensorMsg]) -> hetsim_msgs::Command {
        hetsim_msgs::Command::Stop
    }
    fn status(&self) -> hetsim_msgs::StackStatus {
        hetsim_msgs::StackStatus::default()
    }
}

/// Final position error of each of the stack's trajectories over a rendered rover sequence.
fn run_sequence(frames: usize) -> (f64, f64, f64, usize) {
    let s = load_scenario(
        &repo().join("scenarios/village.toml"),
        &LoadOptions::default(),
    )
    .unwrap();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let d = &s.robots[0].spec.start;
    // The rover's body, and its bench 1.4 m up, pitched 8 degrees down, 0.35 m baseline.
    let body = |k: usize| {
        let yaw = d.yaw_deg.to_radians() + 0.002 * k as f64;
        let t = 0.06 * k as f64;
        let (x, y) = (d.x + t * yaw.cos(), d.y + t * yaw.sin());
        pose_from_xyz_rpy([x, y, s.world.ground_z(x, y)], [0.0, 0.0, yaw])
    };
    let mount = pose_from_xyz_rpy([0.0, 0.0, 1.4], [0.0, 8f64.to_radians(), 0.0]);
    let right = mount * pose_from_xyz_rpy([0.0, -0.35, 0.0], [0.0; 3]);
    let body_from_camera =
        Isometry3::from_parts(mount.translation, mount.rotation * mount_to_optical());
    let camera = Camera {
        alpha_u: K.alpha_u,
        alpha_v: K.alpha_v,
        u0: K.u0,
        v0: K.v0,
    };
    let mut stack = SlamStack::new(
        Box::new(Still),
        "stereo",
        Bench {
            camera,
            baseline_m: 0.35,
        },
        body_from_camera,
        SlamParams::ground(),
        7,
    );
    for k in 0..=frames {
        let b: Pose = body(k);
        let views = [mount, right].map(|m| CameraView::from_mount(K, &(b * m), [0.05, 3000.0]));
        let f = r.render(&views);
        let stamp_ns = k as u64 * 100_000_000;
        let img = |i: usize, side: &str| {
            SensorMsg::Image(Image {
                stamp_ns,
                sensor: format!("stereo/{side}"),
                width: K.width,
                height: K.height,
                rgb: f[i].rgb.clone(),
            })
        };
        let mut inbox = vec![img(0, "left"), img(1, "right")];
        if k == 0 {
            inbox.insert(0, SensorMsg::TruthPose(PoseStamped { stamp_ns, pose: b }));
        }
        stack.step(stamp_ns, &inbox);
    }
    let truth = body(frames).translation.vector;
    let points = stack.map_points();
    assert!(points.len() >= 18, "{} mapped points", points.len());
    assert!(points.iter().all(|(_, p)| p.iter().all(|v| v.is_finite())));
    let t = stack.trajectories();
    let end = |kind: &str| {
        let poses = &t.iter().find(|(k, _)| k == kind).unwrap().1;
        assert_eq!(poses.len(), frames + 1, "{kind}: a pose per frame");
        (poses.last().unwrap().1.translation.vector - truth).norm()
    };
    (
        end("vo"),
        end("slam"),
        0.06 * frames as f64,
        stack.submaps(),
    )
}

#[test]
fn local_slam_tracks_a_rendered_rover_sequence_no_worse_than_vo() {
    let (vo, slam, travelled, submaps) = run_sequence(60);
    assert_eq!(submaps, 1, "fewer than 100 points in 60 frames");
    // Stated bounds: the SLAM's final error under 5 % of the distance, and no more than the
    // VO's it is predicted with (the points it maps correct the VO's drift). Measured when
    // set: SLAM 0.110 m, VO 0.136 m over 3.6 m.
    assert!(
        slam < 0.05 * travelled,
        "slam {slam:.3} m over {travelled:.1} m"
    );
    assert!(slam <= vo * 1.05, "slam {slam:.3} vs vo {vo:.3}");
}
