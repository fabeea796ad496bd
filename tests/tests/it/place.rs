//! Image matching of stereo key frames ([`hetsim_vision::place`]) on rendered village frames,
//! against the renderer's poses: Ressac's bench looking down from 40 m, over the same place
//! from other positions and headings (a half turn included), and over another place.

use hetsim_msgs::mount_to_optical;
use hetsim_msgs::Pinhole;
use hetsim_msgs::{pose_from_xyz_rpy, Pose};
use hetsim_render::{CameraView, RenderOptions, Renderer};
use hetsim_scene::{load_scenario, LoadOptions, Scenario};
use hetsim_tests::repo;
use hetsim_vision::harris::{detect, select_new};
use hetsim_vision::place::{match_keyframes, KeyFrame, MatchParams};
use hetsim_vision::stereo::{match_stereo, Bench};
use hetsim_vision::Gray;
use nalgebra::{Isometry3, Vector6};
use rand::SeedableRng;

const K: hetsim_msgs::CameraGeometry = hetsim_tests::TEST_INTRINSICS;
const CAM: Pinhole = K.k;
const BASELINE: f64 = 0.9;

fn village() -> Scenario {
    load_scenario(
        &repo().join("scenarios/village.toml"),
        &LoadOptions::default(),
    )
    .unwrap()
}

/// Ressac's left camera `east`, `north` metres from its start, at `altitude` metres, heading
/// `yaw_deg`, looking straight down.
fn mount(s: &Scenario, east: f64, north: f64, altitude: f64, yaw_deg: f64) -> Pose {
    let d = &s.robots[1].spec.start;
    pose_from_xyz_rpy(
        [d.x + east, d.y + north, altitude],
        [0.0, 90f64.to_radians(), yaw_deg.to_radians()],
    )
}

fn optical(m: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(m.translation, m.rotation * mount_to_optical())
}

/// The key frame of the bench at `m`, as the SLAM makes it: Harris corners in the 3 x 3
/// partition, triangulated with the right image.
fn keyframe(r: &mut Renderer, m: &Pose) -> KeyFrame {
    let right = m * pose_from_xyz_rpy([0.0, -BASELINE, 0.0], [0.0; 3]);
    let views = [m, &right].map(|m| CameraView::from_mount(K, m, [0.05, 3000.0]));
    let f = r.render(&views);
    let gray = |f: &hetsim_render::Frame| {
        Gray::from_rgb(f.width as usize, f.height as usize, &f.rgb()).expect("w x h x 3")
    };
    let (l, rt) = (gray(&f[0]), gray(&f[1]));
    let corners = detect(&l, 0.005, 8);
    let chosen = select_new(&corners, l.width, l.height, &[], 25, 8.0);
    let bench = Bench {
        camera: CAM,
        baseline_m: BASELINE,
    };
    let stereo = match_stereo(&l, &rt, &bench, &chosen, [0.5, 120.0], 0.85);
    KeyFrame::new(&l, CAM, BASELINE, &stereo)
}

/// The error of `current_from_keyframe` as a left perturbation, and its NEES.
fn judged(est: &Pose, truth: &Pose, cov: &nalgebra::Matrix6<f64>) -> (f64, f64, f64) {
    let e = truth * est.inverse();
    let r = e.rotation.scaled_axis();
    let v = Vector6::new(
        e.translation.x,
        e.translation.y,
        e.translation.z,
        r.x,
        r.y,
        r.z,
    );
    let nees = (v.transpose() * cov.try_inverse().unwrap() * v)[0];
    (e.translation.vector.norm(), r.norm().to_degrees(), nees)
}

#[test]
fn a_past_view_is_matched_from_other_positions_and_headings_and_another_place_is_not() {
    let s = village();
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let yaw0 = s.robots[1].spec.start.yaw_deg;
    let past = mount(&s, 0.0, 0.0, 40.0, yaw0);
    let kf = keyframe(&mut r, &past);
    assert!(
        kf.points.len() >= 60,
        "{} key-frame points",
        kf.points.len()
    );
    let params = MatchParams::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    // Same heading, a quarter turn, the way back (a half turn), and a half turn with a
    // different altitude, each a few metres off the key frame.
    let passes = [
        (4.0, -3.0, 40.0, yaw0),
        (-3.0, 5.0, 41.0, yaw0 + 90.0),
        (5.0, 2.0, 40.0, yaw0 + 180.0),
        (-2.0, -4.0, 37.0, yaw0 + 185.0),
    ];
    for (east, north, alt, yaw) in passes {
        let now = mount(&s, east, north, alt, yaw);
        let cur = keyframe(&mut r, &now);
        let m = match_keyframes(&kf, &cur, &params, &mut rng)
            .unwrap_or_else(|e| panic!("pass {east},{north},{alt},{yaw}: {e:?}"));
        let truth = optical(&now).inverse() * optical(&past);
        let (dt, dr, nees) = judged(&m.current_from_keyframe, &truth, &m.covariance);
        println!(
            "pass ({east}, {north}, {alt} m, {yaw} deg): {} matches, {} inliers, error {dt:.3} m {dr:.3} deg, NEES {nees:.2}",
            m.matches, m.inliers
        );
        // A true match: the relative pose within its own stated covariance (chi-square with
        // 6 degrees of freedom, 99.9 %: 22.46), and within 0.5 m and 1 degree (a false
        // association would be off by metres).
        assert!(nees < 22.46, "NEES {nees:.2}");
        assert!(dt < 0.5 && dr < 1.0, "error {dt:.3} m, {dr:.3} deg");
    }
    // Over another place, 150 m away: no pose with enough inliers.
    let elsewhere = keyframe(&mut r, &mount(&s, 110.0, -100.0, 40.0, yaw0));
    let got = match_keyframes(&kf, &elsewhere, &params, &mut rng);
    assert!(got.is_err(), "a wrong candidate matched: {got:?}");
}
