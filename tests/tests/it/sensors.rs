//! Non-visual sensors against ground truth and their configured noise; the MCAP recording.

use hetsim_core::Streams;
use hetsim_engine::RunOptions;
use hetsim_io::Recorder;
use hetsim_msgs::{yaw_of, SensorMsg};
use hetsim_physics::Physics;
use hetsim_scene::{load_scenario_text, LoadOptions, Scenario};
use hetsim_sensors::SensorSuite;
use hetsim_tests::repo;

/// An indoor scenario from a `[[robots]]` and `[world.indoor]` body, loaded as if it lived in
/// `scenarios/`.
fn scenario(indoor: &str, robots: &str) -> Scenario {
    scenario_with(indoor, robots, "")
}

/// [`scenario`] with top-level lines `head` (e.g. a `models_dir`).
fn scenario_with(indoor: &str, robots: &str, head: &str) -> Scenario {
    let text = format!(
        "schema_version = 1\nname = \"t\"\n{head}\nseed = 4\ndt_secs = 0.01\nduration_secs = 10.0\n[world]\nkind = \"indoor_grid\"\n[world.indoor]\n{indoor}\n{robots}"
    );
    load_scenario_text(
        &repo().join("scenarios/test.toml"),
        text,
        &LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// A models directory with the c't-Bot and a parent whose children are tracked by the
/// emulated `child_tracker` (the seed's figures: 23 Hz, 0.04 ± 0.02 m within 2 m) instead of
/// the hat tracker on its panoramas; the scenario line that points at it.
fn emulated_tracker_models(dir: &std::path::Path) -> String {
    let models = repo().join("robots/models");
    std::fs::copy(models.join("ctbot.toml"), dir.join("ctbot.toml")).unwrap();
    let parent = std::fs::read_to_string(models.join("parent.toml"))
        .unwrap()
        .replace("name = \"parent\"", "name = \"tracker_parent\"");
    std::fs::write(
        dir.join("tracker_parent.toml"),
        format!(
            "{parent}\n[[sensors]]\nkind = \"child_tracker\"\nname = \"tracker\"\nrate_hz = 23.0\nmount = {{ xyz_m = [0.0, 0.0, 1.45], rpy_deg = [0.0, 0.0, 0.0] }}\nrange_m = 2.0\nerror_mean_m = 0.04\nerror_std_m = 0.02\n"
        ),
    )
    .unwrap();
    format!("models_dir = \"{}\"", dir.display())
}

fn physics_for(s: &Scenario) -> Physics {
    Physics::for_scenario(s, &Streams::new(s.seed))
}

/// Samples every sensor for `ticks` ticks of a world where nothing moves.
fn sample_still(s: &Scenario, ticks: u64) -> Vec<SensorMsg> {
    sample_still_by_robot(s, ticks)
        .into_iter()
        .map(|(_, m)| m)
        .collect()
}

/// [`sample_still`] with the index of the robot each message is for.
fn sample_still_by_robot(s: &Scenario, ticks: u64) -> Vec<(usize, SensorMsg)> {
    let physics = physics_for(s);
    let mut suite = SensorSuite::new(s, &Streams::new(s.seed));
    (0..ticks)
        .flat_map(|t| suite.sample(&physics, t))
        .map(|x| (x.robot, x.msg))
        .collect()
}

fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (
        m,
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt(),
    )
}

/// Checks a sample mean and standard deviation against the configured values: the mean within
/// 4 standard errors, the standard deviation within 4 of its standard errors (σ / sqrt(2n)).
fn assert_stats(v: &[f64], mean: f64, sigma: f64, what: &str) {
    let n = v.len() as f64;
    let (m, s) = mean_std(v);
    assert!(
        (m - mean).abs() < 4.0 * sigma / n.sqrt(),
        "{what}: mean {m} vs {mean} (n = {n})"
    );
    assert!(
        (s - sigma).abs() < 4.0 * sigma / (2.0 * n).sqrt(),
        "{what}: std {s} vs {sigma} (n = {n})"
    );
}

const ROOM: &str = "width_m = 10.0\nheight_m = 8.0\nspacing_m = 0.5";

#[test]
fn compass_noise_and_bias_match_the_robot_file() {
    let s = scenario(ROOM, "[[robots]]\nname = \"c\"\nmodel = \"ctbot\"\nstart = { x = 0.25, y = 0.25, yaw_deg = 30.0 }\nmission = { kind = \"idle\" }\noverrides = { \"sensors.compass.bias_deg\" = 5.0 }\n");
    let headings: Vec<f64> = sample_still(&s, 50_000)
        .into_iter()
        .filter_map(|m| {
            if let SensorMsg::Compass(c) = m {
                Some((c.heading_rad - 30f64.to_radians()).to_degrees())
            } else {
                None
            }
        })
        .collect();
    assert_eq!(headings.len(), 5000, "10 Hz for 500 s");
    assert_stats(&headings, 5.0, 3.5, "compass");
}

#[test]
fn gps_and_imu_noise_match_the_robot_files() {
    let s = scenario(
        "width_m = 40.0\nheight_m = 40.0\nspacing_m = 0.5",
        "[[robots]]\nname = \"d\"\nmodel = \"dala\"\nstart = { x = 0.0, y = 0.0 }\nmission = { kind = \"idle\" }\n[[robots]]\nname = \"r\"\nmodel = \"ressac\"\nstart = { x = 10.0, y = 10.0, z = 5.0 }\nmission = { kind = \"idle\" }\n",
    );
    let by_robot = sample_still_by_robot(&s, 200_000);
    let msgs: Vec<SensorMsg> = by_robot.iter().map(|(_, m)| m.clone()).collect();
    // Both robots carry a GPS; dala's antenna is at (0, 0, 1.5), sigma 1.5 m.
    let dala: Vec<[f64; 3]> = by_robot
        .iter()
        .filter_map(|(r, m)| {
            if let (0, SensorMsg::Gps(g)) = (r, m) {
                Some(g.position_m)
            } else {
                None
            }
        })
        .collect();
    assert!(dala.len() > 1500);
    for (axis, truth) in [(0, 0.0), (1, 0.0), (2, 1.5)] {
        assert_stats(
            &dala.iter().map(|p| p[axis]).collect::<Vec<_>>(),
            truth,
            1.5,
            "gps",
        );
    }
    // A helicopter standing still: gyro reads its bias, accelerometer gravity plus its bias.
    let imu: Vec<([f64; 3], [f64; 3])> = msgs
        .iter()
        .filter_map(|m| {
            if let SensorMsg::Imu(i) = m {
                Some((i.angular_rate_radps, i.accel_mps2))
            } else {
                None
            }
        })
        .skip(3)
        .collect();
    assert!(imu.len() > 19_000);
    let (gx, gz) = (
        mean_std(&imu.iter().map(|s| s.0[0]).collect::<Vec<_>>()),
        mean_std(&imu.iter().map(|s| s.1[2]).collect::<Vec<_>>()),
    );
    assert!((gx.1 - 0.002).abs() < 0.0002, "gyro std {}", gx.1);
    assert!(
        gx.0.abs() < 4.0 * 0.0005,
        "gyro bias {} is drawn from N(0, 0.0005)",
        gx.0
    );
    assert!(
        (gz.0 - 9.81).abs() < 4.0 * 0.02,
        "specific force z {} = g + bias",
        gz.0
    );
    assert!((gz.1 - 0.05).abs() < 0.005, "accel std {}", gz.1);
}

#[test]
fn laser_ranges_equal_the_distance_to_the_walls() {
    let s = scenario(ROOM, "[[robots]]\nname = \"p\"\nmodel = \"parent\"\nstart = { x = 0.25, y = -0.25, yaw_deg = 0.0 }\nmission = { kind = \"idle\" }\noverrides = { \"sensors.laser.range_sigma_m\" = 0.0 }\n");
    let scan = sample_still(&s, 10)
        .into_iter()
        .find_map(|m| {
            if let SensorMsg::LaserScan(l) = m {
                Some(l)
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(scan.ranges_m.len(), 481, "240 deg at 0.5 deg");
    // Sensor at (0.25 + its mount's x, -0.25) (the robot faces east) in a 10 x 8 m room;
    // walls' inner faces at x = +-5, y = +-4.
    let mount = s.robots[0]
        .model
        .sensors
        .iter()
        .find(|x| x.name() == "laser")
        .unwrap()
        .mount()
        .xyz_m;
    assert_eq!(mount[1], 0.0, "on the robot's axis");
    let (ox, oy) = (0.25 + mount[0], -0.25);
    for (k, r) in scan.ranges_m.iter().enumerate() {
        let a = scan.angle_min_rad + k as f64 * scan.angle_increment_rad;
        let (c, s) = (a.cos(), a.sin());
        let tx = if c > 1e-12 {
            (5.0 - ox) / c
        } else if c < -1e-12 {
            (-5.0 - ox) / c
        } else {
            f64::INFINITY
        };
        let ty = if s > 1e-12 {
            (4.0 - oy) / s
        } else if s < -1e-12 {
            (-4.0 - oy) / s
        } else {
            f64::INFINITY
        };
        let expected = tx.min(ty);
        assert!(
            (*r as f64 - expected).abs() < 1e-4,
            "beam {k} at {a}: {r} vs {expected}"
        );
    }
}

#[test]
fn the_emulated_tracker_sees_children_within_2_m_only_in_line_of_sight() {
    let robots = "[[robots]]\nname = \"p\"\nmodel = \"parent\"\nstart = { x = -2.75, y = 0.25 }\nmission = { kind = \"idle\" }\n[[robots]]\nname = \"near\"\nmodel = \"ctbot\"\nstart = { x = -1.25, y = 0.25 }\nmission = { kind = \"idle\" }\n[[robots]]\nname = \"far\"\nmodel = \"ctbot\"\nstart = { x = -2.75, y = 2.75 }\nmission = { kind = \"idle\" }\n[[robots]]\nname = \"hidden\"\nmodel = \"ctbot\"\nstart = { x = -2.75, y = -1.25 }\nmission = { kind = \"idle\" }\n";
    let wall = "obstacles = [ { centre = [-2.75, -0.5], size_m = [1.0, 0.5], height_m = 2.0 } ]";
    let dir = tempfile::tempdir().unwrap();
    let robots = robots.replace("model = \"parent\"", "model = \"tracker_parent\"");
    let s = scenario_with(
        &format!("{ROOM}\n{wall}"),
        &robots,
        &emulated_tracker_models(dir.path()),
    );
    let tracks: Vec<_> = sample_still(&s, 100_000)
        .into_iter()
        .filter_map(|m| {
            if let SensorMsg::ChildTracks(t) = m {
                Some(t)
            } else {
                None
            }
        })
        .collect();
    assert!(tracks.len() > 20_000);
    let mut errors = Vec::new();
    for t in &tracks {
        let names: Vec<&str> = t.tracks.iter().map(|k| k.child.as_str()).collect();
        assert_eq!(
            names,
            vec!["near"],
            "1.5 m away and visible; 'far' is 2.5 m away, 'hidden' behind a cabinet"
        );
        // In the parent's body frame (it faces east): 1.5 m straight ahead.
        errors.push((t.tracks[0].position_m[0] - 1.5).hypot(t.tracks[0].position_m[1]));
    }
    // |N(0.04, 0.02)|: mean 0.0403 (the fold adds 0.3 mm), std about 0.0195.
    let (m, sd) = mean_std(&errors);
    assert!((m - 0.0403).abs() < 0.0005, "error mean {m}");
    assert!((sd - 0.0195).abs() < 0.001, "error std {sd}");
}

/// The emulated tracker's fixes turn with the parent: facing north, a child 1.5 m to its east is
/// 1.5 m to its right (body y = -1.5).
#[test]
fn the_emulated_tracker_measures_in_the_parents_body_frame() {
    let robots = "[[robots]]\nname = \"p\"\nmodel = \"parent\"\nstart = { x = -2.75, y = 0.25, yaw_deg = 90.0 }\nmission = { kind = \"idle\" }\n[[robots]]\nname = \"near\"\nmodel = \"ctbot\"\nstart = { x = -1.25, y = 0.25 }\nmission = { kind = \"idle\" }\n";
    let dir = tempfile::tempdir().unwrap();
    let robots = robots.replace("model = \"parent\"", "model = \"tracker_parent\"");
    let s = scenario_with(ROOM, &robots, &emulated_tracker_models(dir.path()));
    let mut sum = [0.0; 2];
    let mut n = 0.0;
    for m in sample_still(&s, 20_000) {
        if let SensorMsg::ChildTracks(t) = m {
            for k in &t.tracks {
                sum[0] += k.position_m[0];
                sum[1] += k.position_m[1];
                n += 1.0;
            }
        }
    }
    assert!(n > 1000.0, "{n} fixes");
    // The error's direction is uniform, so the mean fix is the true position to within
    // 0.04 m / sqrt(n).
    let mean = [sum[0] / n, sum[1] / n];
    assert!(
        mean[0].abs() < 0.01 && (mean[1] + 1.5).abs() < 0.01,
        "{mean:?}"
    );
}

#[test]
fn rendezvous_fires_only_with_line_of_sight() {
    let robots = "[[robots]]\nname = \"d\"\nmodel = \"dala\"\nstart = { x = -1.5, y = 0.0 }\nmission = { kind = \"idle\" }\n[[robots]]\nname = \"r\"\nmodel = \"ressac\"\nstart = { x = 3.0, y = 0.0, z = 25.0 }\nmission = { kind = \"idle\" }\n";
    let room = "width_m = 40.0\nheight_m = 40.0\nspacing_m = 0.5";
    let count = |s: &Scenario| {
        sample_still(s, 1000)
            .iter()
            .filter(|m| matches!(m, SensorMsg::Rendezvous(_)))
            .count()
    };
    let open = scenario(room, robots);
    // 2 Hz on each robot for 10 s: dala looks up at ressac and ressac down at dala.
    assert_eq!(count(&open), 40);
    let rel = sample_still(&open, 100)
        .into_iter()
        .find_map(|m| {
            if let SensorMsg::Rendezvous(r) = m {
                Some(r)
            } else {
                None
            }
        })
        .unwrap();
    assert_eq!(rel.other, "r");
    assert!(
        (rel.relative.translation.x - 4.5).abs() < 3.0
            && (rel.relative.translation.z - 25.0).abs() < 3.0,
        "{:?}",
        rel.relative.translation
    );
    // A tall tower between them blocks the line of sight both ways.
    let tower = format!(
        "{room}\nobstacles = [ {{ centre = [0.0, 0.0], size_m = [0.5, 2.0], height_m = 40.0 }} ]"
    );
    assert_eq!(count(&scenario(&tower, robots)), 0);
}

#[test]
fn wheel_odometry_overestimates_distance_by_the_slip() {
    let s = scenario(
        "width_m = 20.0\nheight_m = 4.0\nspacing_m = 0.5",
        "[[robots]]\nname = \"c\"\nmodel = \"ctbot\"\nstart = { x = -9.25, y = 0.25 }\nmission = { kind = \"waypoints\", points = [[8.0, 0.25]] }\noverrides = { \"sensors.encoders.scale_sigma\" = 0.0, \"sensors.encoders.noise_per_m\" = 0.0, \"body.wheels.speed_noise\" = 0.0, \"sensors.truth.enabled\" = true }\n",
    );
    let result = hetsim_tests::run_scenario(&s, RunOptions::default());
    let truth = &result.truth[0].1;
    let travelled: f64 = truth
        .windows(2)
        .map(|w| (w[1].1.translation.vector - w[0].1.translation.vector).norm())
        .sum();
    assert!(travelled > 1.2, "drove {travelled} m");
    // The run's own odometry is in the digest only; sample it again the same way.
    let mut physics = physics_for(&s);
    let mut suite = SensorSuite::new(&s, &Streams::new(s.seed));
    let mut odo = 0.0;
    let mut truth_m = 0.0;
    let mut last = physics.pose(0).translation.vector;
    for t in 0..500 {
        physics.command(
            0,
            &hetsim_msgs::Command::Wheels {
                left_mps: 0.15,
                right_mps: 0.15,
            },
        );
        physics.step();
        let now = physics.pose(0).translation.vector;
        truth_m += (now - last).norm();
        last = now;
        for x in suite.sample(&physics, t) {
            if let SensorMsg::WheelOdometry(w) = x.msg {
                odo += (w.left_m + w.right_m) / 2.0;
            }
        }
    }
    // ctbot: longitudinal_slip 0.02, so the wheels turn 1 / 0.98 times the distance covered.
    assert!(
        (odo / truth_m - 1.0 / 0.98).abs() < 1e-6,
        "odometry {odo} vs truth {truth_m}"
    );
    assert!((yaw_of(&physics.pose(0))).abs() < 1e-9);
}

#[test]
fn a_json_recording_reads_back_with_the_expected_topics_and_counts() {
    let s = hetsim_scene::load_scenario(
        &repo().join("scenarios/lab.toml"),
        &LoadOptions {
            robot_files: None,
            seed: None,
            duration_secs: Some(10.0),
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lab.mcap");
    let mut rec = Recorder::create(&path, hetsim_io::RecordEncoding::Json).unwrap();
    let result = hetsim_tests::run_scenario(
        &s,
        RunOptions {
            recorder: Some(&mut rec),
            ..RunOptions::default()
        },
    );
    rec.finish().unwrap();
    assert!(!dir.path().join("lab.mcap.partial").exists());
    let bytes = std::fs::read(&path).unwrap();
    let mut counts: std::collections::BTreeMap<String, u64> = Default::default();
    let mut schemas: std::collections::BTreeMap<String, String> = Default::default();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        *counts.entry(m.channel.topic.clone()).or_default() += 1;
        if let Some(s) = &m.channel.schema {
            schemas.insert(m.channel.topic.clone(), s.name.clone());
        }
        let _: serde_json::Value = serde_json::from_slice(&m.data).expect("every message is JSON");
    }
    // Truth at every 10 ms tick for 10 s plus the initial pose (replay's radio needs the
    // positions the live radio saw); one /tf per truth message per robot.
    assert_eq!(counts["/parent/truth"], 1001);
    assert_eq!(counts["/tf"], 4 * 1001);
    assert_eq!(counts["/parent/laser"], 100);
    assert_eq!(counts["/child1/compass"], 100);
    // Not rendered: no panoramas, and no emulated tracker (the parent tracks its children by
    // the hats in its panoramas).
    assert!(!counts.contains_key("/parent/omni") && !counts.contains_key("/parent/tracker"));
    assert_eq!(counts["/child2/cmd"], 1000);
    for (topic, n) in &result.messages {
        if !topic.ends_with("/truth") {
            assert_eq!(counts[&format!("/{topic}")], *n, "{topic}");
        }
    }
    assert_eq!(schemas["/parent/laser"], "foxglove.LaserScan");
    assert_eq!(schemas["/parent/truth"], "foxglove.PoseInFrame");
    assert_eq!(schemas["/tf"], "foxglove.FrameTransform");
}
