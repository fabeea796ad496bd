//! The local level of the hierarchical SLAM on rendered frames, against ground truth.

use hetsim_eval::slam::EventMetrics;
use hetsim_eval::Metrics;
use hetsim_msgs::{mount_to_optical, CameraGeometry};
use hetsim_msgs::{pose_from_xyz_rpy, Image, Pose, PoseStamped, RobotStack, SensorMsg};
use hetsim_render::{CameraView, RenderOptions, Renderer};
use hetsim_scene::{load_scenario, LoadOptions};
use hetsim_slam::stack::{SlamParams, SlamStack};
use hetsim_tests::repo;
use hetsim_vision::stereo::Bench;
use nalgebra::Isometry3;

const K: CameraGeometry = hetsim_tests::TEST_INTRINSICS;

/// A stack that does nothing: the SLAM's inner pilot.
struct Still;

impl RobotStack for Still {
    fn step(
        &mut self,
        _: u64,
        _: &[SensorMsg],
    ) -> Result<hetsim_msgs::Command, hetsim_msgs::InputError> {
        Ok(hetsim_msgs::Command::Stop)
    }
    fn status(&self) -> hetsim_msgs::StackStatus {
        hetsim_msgs::StackStatus::default()
    }
}

/// What a rendered rover sequence gave.
struct Sequence {
    /// Final position errors of VO and of the SLAM, metres.
    vo: f64,
    slam: f64,
    /// Distance travelled, metres.
    travelled: f64,
    submaps: usize,
    /// Mapped segments, and the relative depth errors of points sampled along them against
    /// the last frame's rendered depth (those in its view).
    segments: usize,
    segment_depth_errors: Vec<f64>,
    counters: std::collections::BTreeMap<String, u64>,
    /// Everything the stack published, serialized.
    bytes: Vec<u8>,
}

/// The SLAM stack over a rendered rover sequence of `frames` frames, with lines or not, and
/// with the true pose in every inbox or never (robot software must not read it).
fn run_sequence(frames: usize, lines: bool, truth_in_inbox: bool) -> Sequence {
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
    let camera = K.k;
    let mut stack = SlamStack::new(
        Box::new(Still),
        "dala",
        "stereo",
        Bench {
            camera,
            baseline_m: 0.35,
        },
        body_from_camera,
        SlamParams {
            lines,
            ..SlamParams::ground()
        },
        7,
    );
    let mut last_depth = Vec::new();
    for k in 0..=frames {
        let b: Pose = body(k);
        let views = [mount, right]
            .map(|m| CameraView::from_mount(K, &(b * m), [0.05, 3000.0]).with_depth());
        let f = r.render(&views);
        let stamp_ns = k as u64 * 100_000_000;
        let img = |i: usize, side: &str| {
            SensorMsg::Image(Image {
                stamp_ns,
                sensor: format!("stereo/{side}"),
                width: K.width,
                height: K.height,
                encoding: hetsim_msgs::PixelEncoding::Rgb8,
                data: f[i].rgb(),
            })
        };
        let mut inbox = vec![img(0, "left"), img(1, "right")];
        if truth_in_inbox {
            inbox.insert(0, SensorMsg::TruthPose(PoseStamped { stamp_ns, pose: b }));
        }
        stack.step(stamp_ns, &inbox).expect("valid rendered frames");
        last_depth = f[0].depth().to_vec();
    }
    // The stack estimates in its own frame, its pose at the first pair; the test places that
    // frame in the world as the evaluation does.
    let world_from_frame = body(0);
    let truth = (world_from_frame.inverse() * body(frames))
        .translation
        .vector;
    let points = stack.map_points();
    assert!(points.len() >= 18, "{} mapped points", points.len());
    assert!(points.iter().all(|(_, p)| p.iter().all(|v| v.is_finite())));
    // Points along each mapped segment against the rendered depth: the nearest surface in a
    // 7 x 7 window (a segment lies on an edge, where the depth jumps).
    let world_from_camera = world_from_frame.inverse() * body(frames) * body_from_camera;
    let segments = stack.map_segments();
    let mut segment_depth_errors = Vec::new();
    for (_, [a, b]) in &segments {
        for t in [0.1, 0.3, 0.5, 0.7, 0.9] {
            let w: nalgebra::Point3<f64> =
                nalgebra::Vector3::from_fn(|i, _| a[i] + t * (b[i] - a[i])).into();
            let c = world_from_camera.inverse_transform_point(&w);
            let Some([u, v]) = camera.project(&c.coords) else {
                continue;
            };
            let (u, v) = (u.round() as i64, v.round() as i64);
            let (w_px, h_px) = (K.width as i64, K.height as i64);
            if c.z < 0.5 || u < 3 || v < 3 || u >= w_px - 3 || v >= h_px - 3 {
                continue;
            }
            let nearest = (-3..=3)
                .flat_map(|dy| (-3..=3).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| last_depth[((v + dy) * w_px + u + dx) as usize] as f64)
                .filter(|d| *d > 0.0)
                .fold(f64::INFINITY, f64::min);
            if nearest.is_finite() {
                segment_depth_errors.push((c.z - nearest).abs() / nearest);
            }
        }
    }
    let t = stack.artifacts();
    let end = |kind: &str| {
        let poses = match &t.iter().find(|a| a.name == kind).unwrap().data {
            hetsim_msgs::ArtifactData::Trajectory(poses) => poses,
            other => panic!("{kind} is not a trajectory: {other:?}"),
        };
        assert_eq!(poses.len(), frames + 1, "{kind}: a pose per frame");
        (poses.last().unwrap().1.translation.vector - truth).norm()
    };
    Sequence {
        vo: end("vo"),
        slam: end("slam"),
        travelled: 0.06 * frames as f64,
        submaps: stack.submaps(),
        segments: segments.len(),
        segment_depth_errors,
        counters: stack.report().unwrap().counters,
        bytes: serde_json::to_vec(&stack.artifacts()).unwrap(),
    }
}

/// Robot software reads no truth: the SLAM stack publishes the same bytes whether or not
/// the true pose is in its inbox.
#[test]
fn the_slam_stack_computes_the_same_bytes_with_the_truth_withheld() {
    let with = run_sequence(12, true, true);
    let without = run_sequence(12, true, false);
    assert!(with.submaps >= 1 && with.bytes.len() > 1000);
    assert!(
        with.bytes == without.bytes,
        "the truth changed the SLAM's output"
    );
}

#[test]
fn local_slam_tracks_a_rendered_rover_sequence_no_worse_than_vo() {
    let q = run_sequence(60, true, false);
    let points_only = run_sequence(60, false, false);
    let mut errors = q.segment_depth_errors.clone();
    errors.sort_by(f64::total_cmp);
    eprintln!(
        "slam {:.3} m (points only {:.3} m), vo {:.3} m over {:.2} m; {} segments, depth errors {errors:.3?}; {:?}",
        q.slam, points_only.slam, q.vo, q.travelled, q.segments, q.counters
    );
    assert_eq!(q.submaps, 1, "fewer than 100 landmarks in 60 frames");
    // Stated bound: the SLAM's final error under 5 % of the distance.
    assert!(
        q.slam < 0.05 * q.travelled,
        "slam {:.3} m over {:.1} m",
        q.slam,
        q.travelled
    );
    // And no worse than the VO it is predicted with by more than 1 % of the distance: with
    // textured near-field views the VO itself drifts under 1 % here, so the landmarks have
    // little to correct (measured when set: SLAM 0.014 m, VO 0.007 m over 3.6 m; on the
    // earlier, barely textured ground SLAM 0.097 m and VO 0.136 m).
    assert!(
        q.slam <= q.vo + 0.01 * q.travelled,
        "slam {:.3} vs vo {:.3} over {:.1} m",
        q.slam,
        q.vo,
        q.travelled
    );
    // The lines: tracked and used, no harm to the estimate, and the segments whose depth is
    // known to 20 % lie on the rendered surfaces. Measured when set: 324 line observations,
    // 44 lines initialized, 3 segments output, median depth error 15 %.
    assert!(
        q.slam <= points_only.slam * 1.05,
        "with lines {:.3} m, points only {:.3} m",
        q.slam,
        points_only.slam
    );
    assert!(
        q.counters["line_observations_used"] >= 100,
        "{:?}",
        q.counters
    );
    assert_eq!(points_only.counters.get("line_observations_used"), None);
    assert!(
        q.segments >= 2 && errors.len() >= 5,
        "{} segments",
        q.segments
    );
    let median = errors[errors.len() / 2];
    assert!(median < 0.2, "median relative depth error {median:.3}");
}

/// A results folder's metrics.json, typed.
fn metrics(dir: &std::path::Path) -> Metrics {
    Metrics::read(dir).unwrap_or_else(|e| panic!("{e}"))
}

/// The short village in lockstep (Dala and Ressac rendered at 512 x 384): a rendezvous just
/// after the start on both robots; Ressac's own image matcher, with no truth, finds its first
/// key frames (tied to Dala's by the rendezvous) when it comes back over the start; the graphs
/// and key frames exchanged over the radio; Dala within 1 % of its path;
/// Ressac's image match true, within its covariance, and pulling its error down.
///
/// What a run of `scenarios/village-short.toml` must have done, on any backend: the golden
/// test of that run (`golden::golden_rendered_village_short`, on both rasterizers) asserts it
/// on its own runs, so the 45 s are not run again here.
pub(crate) fn cooperative_slam_corrects_ressac_and_keeps_dala_within_one_percent(
    out: &std::path::Path,
) {
    let m = metrics(out);
    let ate = |kind: &str, robot: &str| {
        m.estimates
            .get(&format!("{kind}/{robot}"))
            .unwrap_or_else(|| panic!("no {kind}/{robot} estimate"))
            .ate_m
    };
    // Ressac is corrected by its image match: the match pulls its error down when it fires
    // (asserted with the events below). Whether the cooperative estimate beats the open
    // loop over the whole run is not asserted on this one 45 s run: since the VO keeps its
    // pairs through turns (c6db860) Ressac's open loop drifts about a metre here, the size
    // of the rendezvous' and the 512 x 384 match's own errors, and VO, open loop and
    // cooperative ATE lie within 0.15 m of each other. The full village's 600 s over five
    // seeds carries that comparison (`results/village/`).
    // Dala's open loop is good to centimetres on textured ground, better than its events
    // (rendezvous 0.5 m): they may move it, but its estimate must stay a good SLAM's,
    // within 1 % of the distance it travelled (measured when set: 0.091 m over 25 m; after
    // the drift's recalibration, 1794a37: 0.06 m, open loop 0.06 m).
    let (coop, open) = (ate("slam", "dala"), ate("slam-open", "dala"));
    open_loop_and_vo_start_where_the_first_link_put_them(out);
    let length = m
        .estimates
        .get("slam/dala")
        .expect("a slam/dala estimate")
        .length_m;
    assert!(
        coop < 0.01 * length,
        "dala: cooperative ATE {coop:.3} m (open loop {open:.3} m) over {length:.1} m"
    );
    let slam = m.slam.as_ref().expect("metrics.json has a slam section");
    let robot_slam = |robot: &str| {
        slam.robots
            .get(robot)
            .unwrap_or_else(|| panic!("no SLAM figures of {robot}"))
    };
    let events = |robot: &str, kind: &str| -> Vec<EventMetrics> {
        robot_slam(robot)
            .events
            .iter()
            .filter(|e| e.kind == kind)
            .cloned()
            .collect()
    };
    // The rendezvous: both robots at the same frame, each linked to the other's origin.
    let (rd, rr) = (events("dala", "rendezvous"), events("ressac", "rendezvous"));
    assert_eq!((rd.len(), rr.len()), (1, 1), "{slam:?}");
    assert_eq!(rd[0].time_s, rr[0].time_s);
    assert!(rd[0].time_s < 2.0, "just after the start");
    // The image match is Ressac's, earned from its images (no image-match sensor in the
    // robot files any more), and a true one: within 2 m and 5 degrees of the true relative
    // pose (a wrong association lands metres or tens of degrees off), and within its own
    // covariance (chi-square with 6 degrees of freedom, 99.9 %: 22.46).
    assert!(
        !m.messages.keys().any(|k| k.contains("image_match")),
        "an image-match oracle fed the run: {:?}",
        m.messages
    );
    let matches = events("ressac", "image_match");
    assert!(!matches.is_empty(), "no image match: {slam:?}");
    let (before, after) = (matches[0].error_before_m, matches[0].error_after_m);
    assert!(
        after < before,
        "the match moved Ressac {before:.3} -> {after:.3} m"
    );
    let judged = robot_slam("ressac")
        .matching
        .as_ref()
        .expect("ressac's image matching judged against the truth (matching)");
    assert_eq!(judged.false_matches, 0, "{judged:?}");
    for link in &judged.links {
        assert!(link.nees < 22.46, "{link:?}");
    }
    for robot in ["dala", "ressac"] {
        let r = robot_slam(robot);
        let c = &r.counters;
        let counter = |name: &str| {
            c.get(name)
                .copied()
                .unwrap_or_else(|| panic!("{robot}: no counter {name}: {c:?}"))
        };
        assert!(counter("keyframe_bytes_sent") > 0, "{robot}: {c:?}");
        assert_eq!(c.get("unresolved_links"), Some(&0), "{robot}: {c:?}");
        assert!(counter("shares_received") >= 2, "{robot}: {c:?}");
        // Consistency on one run: a consistent filter's pose NEES is chi-square with 6
        // degrees of freedom, within [0.381, 22.46] (its 0.1 % and 99.9 % quantiles) but
        // for one sample in 500; the run's mean falls outside as rarely when its poses are
        // fully correlated in time, and more rarely still when they are not. (When issue 17
        // was filed, Dala's mean was 192 here and Ressac's 42; after the drift's
        // recalibration on the full village's 1024 x 768 benches, 16.4 and 12.3: at half
        // that resolution Dala's forward error is 11 times its variance; with Ressac's VO
        // covariance scaled by 4 in its sub-map EKF, 16.4 and 11.1.) The Monte Carlo
        // test over the full village is in `results/village/README.md`.
        let nees = r.nees_mean;
        assert!(
            (0.381..=22.46).contains(&nees),
            "{robot}: mean NEES {nees:.2} outside [0.381, 22.46]"
        );
        // Both robots map lines (measured when set: Dala 2358 line observations used,
        // Ressac 802; after the recalibration 2980 and 356; with Ressac's VO scale, 2980 and
        // 367).
        assert!(counter("line_observations_used") >= 100, "{robot}: {c:?}");
    }
    // map.ply: points, then the segments' endpoints joined by edges, all finite.
    let ply = std::fs::read_to_string(out.join("map.ply")).unwrap();
    let count = |what: &str| -> usize {
        ply.lines()
            .find_map(|l| l.strip_prefix(what))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (vertices, edges) = (count("element vertex "), count("element edge "));
    let body: Vec<&str> = ply.split("end_header\n").nth(1).unwrap().lines().collect();
    assert!(edges >= 5, "{edges} segments in map.ply");
    assert_eq!(body.len(), vertices + edges);
    for edge in &body[vertices..] {
        let v: Vec<usize> = edge
            .split(' ')
            .take(2)
            .map(|x| x.parse().unwrap())
            .collect();
        assert!(v[0] + 1 == v[1] && v[1] < vertices, "{edge}");
    }
    assert!(body[..vertices].iter().all(|l| l
        .split(' ')
        .take(3)
        .all(|x| x.parse::<f64>().unwrap().is_finite())));
    // One image match for the pass over its first origins (at most one per robot per 30 s).
    // Its altitude correction is not asserted here: with the VO keeping its pairs through
    // turns (c6db860), Ressac's altitude drifts about 0.5 m in this run, the size of the
    // 512 x 384 match's own error (about 1 m and 2 deg), so the match may leave it as it is.
    // The full village's 600 s carry that figure (`results/village/`).
    let im = events("ressac", "image_match");
    assert_eq!(im.len(), 1, "image matches: {slam:?}");
    // The graph with covariances, and the Fig. 7 plots.
    let graph: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("slam/ressac-graph.json")).unwrap())
            .unwrap();
    let origins = graph["origins"].as_array().unwrap();
    assert_eq!(origins.len(), robot_slam("ressac").submaps);
    assert_eq!(origins[1]["covariance"].as_array().unwrap().len(), 6);
    assert!(out.join("plots/fig7-ressac.png").exists());
}

/// The poses of a TUM file (world frame): stamp and position.
fn tum_positions(out: &std::path::Path, file: &str) -> Vec<(f64, [f64; 3])> {
    let text = std::fs::read_to_string(out.join(file)).unwrap();
    text.lines()
        .map(|l| {
            let v: Vec<f64> = l.split(' ').map(|x| x.parse().unwrap()).collect();
            (v[0], [v[1], v[2], v[3]])
        })
        .collect()
}

/// The first pose of robot `robot`'s estimate `kind`, and its true pose at that stamp.
fn first_and_truth(out: &std::path::Path, kind: &str, robot: &str) -> ([f64; 3], [f64; 3]) {
    let (t, p) = tum_positions(out, &format!("{kind}/{robot}.tum"))[0];
    let truth = tum_positions(out, &format!("truth/{robot}.tum"));
    let nearest = truth
        .iter()
        .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
        .unwrap();
    assert!((nearest.0 - t).abs() < 1e-6, "no truth at {t}");
    (p, nearest.1)
}

/// Without alignment, Ressac's open loop and VO are in Dala's frame where its own first link
/// (the rendezvous at 0.5 s) put its first origin, as its cooperative estimate starts: no
/// estimate is placed by the truth. Both start at that same pose, whose error is the
/// rendezvous' (σ 0.5 m on each axis: the norm of three is under 4.03 σ = 2.02 m but for
/// one draw in 1000, chi with 3 degrees of freedom, plus Dala's few millimetres; and above
/// 1 mm but for one in 10⁸). Dala, the team's frame, starts at its true pose.
fn open_loop_and_vo_start_where_the_first_link_put_them(out: &std::path::Path) {
    let dist = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    let (open, truth) = first_and_truth(out, "slam-open", "ressac");
    let (vo, _) = first_and_truth(out, "vo", "ressac");
    assert!(dist(open, vo) < 1e-9, "open loop {open:?}, VO {vo:?}");
    let e = dist(open, truth);
    assert!((1e-3..2.05).contains(&e), "Ressac's first-link error {e} m");
    let (dala, dala_truth) = first_and_truth(out, "slam-open", "dala");
    let dala = dist(dala, dala_truth);
    assert!(dala < 0.01, "Dala starts {dala} m from its true pose");
}

/// The same inputs give the same digest with the SLAM, its events and the radio on one and on
/// two threads; `--open-loop` runs without events or radio, so its SLAM is its open loop.
#[test]
fn slam_with_events_is_deterministic_and_open_loop_has_none() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, threads: &'static str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "run",
            "scenarios/village-short.toml",
            "--duration",
            "8",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        std::thread::spawn(move || {
            let a: Vec<&str> = args.iter().map(String::as_str).collect();
            let printed = hetsim_tests::hetsim(&a, &[("RAYON_NUM_THREADS", threads)]);
            (out, hetsim_tests::printed_digest(&printed))
        })
    };
    let (one, two) = (run("one", "1", &[]), run("two", "2", &[]));
    let (one, two) = (one.join().unwrap(), two.join().unwrap());
    assert_eq!(one.1, two.1, "digest depends on the thread count");
    let read = |out: &std::path::Path, f: &str| std::fs::read(out.join(f)).unwrap();
    assert_eq!(
        read(&one.0, "slam/ressac.tum"),
        read(&two.0, "slam/ressac.tum")
    );
    let one_m = metrics(&one.0);
    let one_slam = one_m
        .slam
        .as_ref()
        .expect("metrics.json has a slam section");
    assert!(!one_slam
        .robots
        .get("ressac")
        .expect("SLAM figures of ressac")
        .events
        .is_empty());
    let open = run("open", "2", &["--open-loop"]).join().unwrap();
    let m = metrics(&open.0);
    let slam = m.slam.as_ref().expect("metrics.json has a slam section");
    for robot in ["dala", "ressac"] {
        let r = slam
            .robots
            .get(robot)
            .unwrap_or_else(|| panic!("no SLAM figures of {robot}"));
        assert!(r.events.is_empty(), "{r:?}");
        assert!(!r.counters.contains_key("shares_sent"), "{r:?}");
        assert_eq!(
            read(&open.0, &format!("slam/{robot}.tum")),
            read(&open.0, &format!("slam-open/{robot}.tum"))
        );
    }
    assert_ne!(open.1, one.1);
}
