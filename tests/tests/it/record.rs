//! `--record` writes ROS 2 MCAP: profile `ros2`, `ros2msg` schemas, CDR messages. Read back
//! with the `mcap` crate and decoded by an independent CDR implementation (`cdr-encoding`,
//! RustDDS's; the recorder encodes with the `cdr` crate) into the ROS 2 message layouts
//! written out below, every message consumed to its last byte; exact per-topic counts and
//! values checked against the run.

// The structs mirror the wire layout field by field: every field is decoded (and so checked
// for position and size), also those no assertion reads.
#![allow(dead_code)]

use byteorder::LittleEndian;
use hetsim_engine::RunOptions;
use hetsim_io::record::{RecordEncoding, Recorder};
use hetsim_scene::{load_scenario, load_scenario_text, LoadOptions, Scenario};
use hetsim_tests::repo;
use serde::Deserialize;
use std::collections::BTreeMap;

#[derive(Deserialize, Debug)]
struct Time {
    sec: i32,
    nanosec: u32,
}
#[derive(Deserialize, Debug)]
struct Header {
    stamp: Time,
    frame_id: String,
}
#[derive(Deserialize, Debug, Clone, Copy)]
struct Vector3 {
    x: f64,
    y: f64,
    z: f64,
}
#[derive(Deserialize, Debug, Clone, Copy)]
struct Quaternion {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}
#[derive(Deserialize, Debug, Clone, Copy)]
struct Pose {
    position: Vector3,
    orientation: Quaternion,
}
#[derive(Deserialize, Debug)]
struct Image {
    header: Header,
    height: u32,
    width: u32,
    encoding: String,
    is_bigendian: u8,
    step: u32,
    #[serde(with = "serde_bytes")]
    data: Vec<u8>,
}
#[derive(Deserialize, Debug)]
struct NavSatStatus {
    status: i8,
    service: u16,
}
#[derive(Deserialize, Debug)]
struct NavSatFix {
    header: Header,
    status: NavSatStatus,
    latitude: f64,
    longitude: f64,
    altitude: f64,
    position_covariance: [f64; 9],
    position_covariance_type: u8,
}
#[derive(Deserialize, Debug)]
struct LaserScan {
    header: Header,
    angle_min: f32,
    angle_max: f32,
    angle_increment: f32,
    time_increment: f32,
    scan_time: f32,
    range_min: f32,
    range_max: f32,
    ranges: Vec<f32>,
    intensities: Vec<f32>,
}
#[derive(Deserialize, Debug)]
struct Imu {
    header: Header,
    orientation: Quaternion,
    orientation_covariance: [f64; 9],
    angular_velocity: Vector3,
    angular_velocity_covariance: [f64; 9],
    linear_acceleration: Vector3,
    linear_acceleration_covariance: [f64; 9],
}
#[derive(Deserialize, Debug)]
struct PoseStamped {
    header: Header,
    pose: Pose,
}
#[derive(Deserialize, Debug)]
struct TransformStamped {
    header: Header,
    child_frame_id: String,
    transform: Pose,
}
#[derive(Deserialize, Debug)]
struct TfMessage {
    transforms: Vec<TransformStamped>,
}
#[derive(Deserialize, Debug)]
struct Command {
    header: Header,
    kind: String,
    left_mps: f64,
    right_mps: f64,
    roll_rad: f64,
    pitch_rad: f64,
    yaw_rate_radps: f64,
    climb_rate_mps: f64,
}
#[derive(Deserialize, Debug)]
struct Compass {
    header: Header,
    heading_rad: f64,
}
#[derive(Deserialize, Debug)]
struct WheelOdometry {
    header: Header,
    left_m: f64,
    right_m: f64,
}
#[derive(Deserialize, Debug)]
struct Rendezvous {
    header: Header,
    other: String,
    pose: Pose,
    sigma_m: f64,
    sigma_rad: f64,
}
#[derive(Deserialize, Debug)]
struct Comms {
    header: Header,
    from: String,
    to: String,
    topic: String,
    sent: Time,
    bytes: u32,
    payload: Vec<u8>,
}

/// Decodes a CDR message (encapsulation CDR_LE) and checks it used every byte but the final
/// alignment padding.
fn decode<T: for<'de> Deserialize<'de>>(topic: &str, data: &[u8]) -> T {
    assert_eq!(&data[..4], &[0, 1, 0, 0], "{topic}: CDR_LE encapsulation");
    let (value, used) = cdr_encoding::from_bytes::<T, LittleEndian>(&data[4..])
        .unwrap_or_else(|e| panic!("{topic}: {e}"));
    assert_eq!(used, data.len() - 4, "{topic}: every byte is a field");
    value
}

/// A topic's schema name, schema encoding, message encoding and messages (log time, data).
type Topic = (String, String, String, Vec<(u64, Vec<u8>)>);

struct Recorded {
    profile: String,
    topics: BTreeMap<String, Topic>,
    /// Each topic's `offered_qos_profiles` channel metadata.
    qos: BTreeMap<String, String>,
}

fn record(scenario: &Scenario, render: bool) -> (Recorded, hetsim_engine::RunOutput) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let mut rec = Recorder::create(&path, RecordEncoding::Ros2).unwrap();
    let result = hetsim_tests::run_scenario(
        scenario,
        RunOptions {
            recorder: Some(&mut rec),
            render: render.then(hetsim_render::RenderOptions::default),
            ..RunOptions::default()
        },
    );
    rec.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let header = mcap::read::LinearReader::new(&bytes)
        .unwrap()
        .find_map(|r| match r.unwrap() {
            mcap::records::Record::Header(h) => Some(h),
            _ => None,
        })
        .unwrap();
    let mut topics: BTreeMap<String, Topic> = BTreeMap::new();
    let mut qos = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        let schema = m
            .channel
            .schema
            .as_ref()
            .expect("every channel has a schema");
        let entry = topics.entry(m.channel.topic.clone()).or_insert_with(|| {
            (
                schema.name.clone(),
                schema.encoding.clone(),
                m.channel.message_encoding.clone(),
                Vec::new(),
            )
        });
        entry.3.push((m.log_time, m.data.to_vec()));
        if let Some(q) = m.channel.metadata.get("offered_qos_profiles") {
            qos.insert(m.channel.topic.clone(), q.clone());
        }
    }
    (
        Recorded {
            profile: header.profile,
            topics,
            qos,
        },
        result,
    )
}

/// Messages of a topic, with their schema checked.
fn of<'a>(r: &'a Recorded, topic: &str, schema: &str) -> &'a [(u64, Vec<u8>)] {
    let (name, schema_encoding, encoding, messages) = r
        .topics
        .get(topic)
        .unwrap_or_else(|| panic!("no {topic} in {:?}", r.topics.keys().collect::<Vec<_>>()));
    assert_eq!(
        (name.as_str(), schema_encoding.as_str(), encoding.as_str()),
        (schema, "ros2msg", "cdr"),
        "{topic}"
    );
    messages
}

fn stamp_ns(h: &Header) -> u64 {
    h.stamp.sec as u64 * 1_000_000_000 + h.stamp.nanosec as u64
}

#[test]
fn a_ros2_recording_of_the_lab_decodes_with_exact_counts() {
    let s = load_scenario(
        &repo().join("scenarios/lab.toml"),
        &LoadOptions {
            robot_files: None,
            seed: None,
            duration_secs: Some(10.0),
        },
    )
    .unwrap();
    let (r, result) = record(&s, false);
    assert_eq!(r.profile, "ros2");
    // The ROS 2 profile's required channel metadata: every topic offers its QoS, /tf_static
    // latched (durability 1, transient local) and the rest volatile (2), all reliable.
    assert_eq!(r.qos.len(), r.topics.len());
    for (topic, q) in &r.qos {
        let durability = if topic == "/tf_static" {
            "durability: 1"
        } else {
            "durability: 2"
        };
        assert!(
            q.contains(durability) && q.contains("reliability: 1"),
            "{topic}: {q}"
        );
    }
    // Every message the robots received is recorded once on its topic.
    for (topic, n) in &result.messages {
        if !topic.ends_with("/truth") && !topic.ends_with("/radio") {
            assert_eq!(r.topics[&format!("/{topic}")].3.len() as u64, *n, "{topic}");
        }
    }
    // Truth at every 10 ms tick for 10 s plus the initial pose (replay's radio needs the
    // positions the live radio saw), a /tf per truth sample and robot; the run keeps 50 Hz.
    let truth = of(&r, "/parent/truth", "geometry_msgs/msg/PoseStamped");
    assert_eq!(truth.len(), 1001);
    assert_eq!(of(&r, "/tf", "tf2_msgs/msg/TFMessage").len(), 4 * 1001);
    let true_poses = result.truth_of("parent").unwrap();
    assert_eq!(true_poses.len(), 501);
    let kept = truth.iter().filter(|(t, _)| t % 20_000_000 == 0);
    for ((t, data), (stamp, pose)) in kept.zip(true_poses) {
        let m: PoseStamped = decode("/parent/truth", data);
        assert_eq!(
            (*t, stamp_ns(&m.header), m.header.frame_id.as_str()),
            (*stamp, *stamp, "world")
        );
        let p = pose.translation.vector;
        assert_eq!(
            [m.pose.position.x, m.pose.position.y, m.pose.position.z],
            [p.x, p.y, p.z],
            "bit for bit"
        );
        assert_eq!(m.pose.orientation.w, pose.rotation.quaternion().w);
    }
    for (_, data) in of(&r, "/tf", "tf2_msgs/msg/TFMessage") {
        let m: TfMessage = decode("/tf", data);
        assert_eq!(m.transforms.len(), 1);
        assert_eq!(m.transforms[0].header.frame_id, "world");
        assert!(m.transforms[0].child_frame_id.ends_with("/base_link"));
    }
    // The laser: 240 deg at 0.5 deg is 481 beams in the laser's own frame, placed by /tf_static.
    let scans = of(&r, "/parent/laser", "sensor_msgs/msg/LaserScan");
    assert_eq!(scans.len(), 100, "10 Hz for 10 s");
    for (_, data) in scans {
        let m: LaserScan = decode("/parent/laser", data);
        assert_eq!(m.ranges.len(), 481);
        assert_eq!(m.header.frame_id, "parent/laser");
        assert!(((m.angle_max - m.angle_min) - 480.0 * m.angle_increment).abs() < 1e-4);
        assert!((m.angle_max - m.angle_min - 240f32.to_radians()).abs() < 1e-4);
        assert_eq!(m.range_max, 20.0);
        assert!(
            m.intensities.is_empty()
                && m.range_min == 0.0
                && m.time_increment == 0.0
                && m.scan_time == 0.0
        );
        assert!(
            m.ranges
                .iter()
                .all(|d| d.is_infinite() || (0.0..=20.5).contains(d)),
            "metres, +inf for no return"
        );
    }
    let statics: Vec<TfMessage> = of(&r, "/tf_static", "tf2_msgs/msg/TFMessage")
        .iter()
        .map(|(_, d)| decode("/tf_static", d))
        .collect();
    let laser = statics
        .iter()
        .flat_map(|m| &m.transforms)
        .find(|t| t.child_frame_id == "parent/laser")
        .expect("the laser's mount on /tf_static");
    assert_eq!(laser.header.frame_id, "parent/base_link");
    let mount = s
        .robots
        .iter()
        .find(|r| r.spec.name == "parent")
        .and_then(|r| r.model.sensors.iter().find(|x| x.name() == "laser"))
        .expect("the lab's parent has a laser")
        .mount()
        .xyz_m;
    assert_eq!(
        [laser.transform.position.x, laser.transform.position.z],
        [mount[0], mount[2]],
        "the robot file's mount"
    );
    for (_, data) in of(&r, "/child1/compass", "hetsim_msgs/msg/Compass") {
        let m: Compass = decode("/child1/compass", data);
        assert!(m.heading_rad.abs() <= std::f64::consts::PI * 2.0);
    }
    for (_, data) in of(&r, "/child1/encoders", "hetsim_msgs/msg/WheelOdometry") {
        let m: WheelOdometry = decode("/child1/encoders", data);
        assert!(
            m.left_m.abs() < 0.1 && m.right_m.abs() < 0.1,
            "a c't-Bot rolls at most 0.15 m/s"
        );
    }
    // Recorded without rendering: no panoramas, and no emulated tracker either (the parent
    // tracks its children by the hats in its panoramas).
    assert!(!r.topics.contains_key("/parent/omni") && !r.topics.contains_key("/parent/tracker"));
    let mut kinds = BTreeMap::<String, usize>::new();
    for (t, data) in of(&r, "/child2/cmd", "hetsim_msgs/msg/Command") {
        let m: Command = decode("/child2/cmd", data);
        assert_eq!(stamp_ns(&m.header), *t);
        assert!(
            m.roll_rad == 0.0
                && m.pitch_rad == 0.0
                && m.yaw_rate_radps == 0.0
                && m.climb_rate_mps == 0.0
        );
        assert!(m.left_mps.abs() <= 0.5 && m.right_mps.abs() <= 0.5);
        *kinds.entry(m.kind).or_default() += 1;
    }
    assert_eq!(kinds.values().sum::<usize>(), 1000, "a command per tick");
    assert!(
        kinds.keys().all(|k| k == "wheels" || k == "stop"),
        "{kinds:?}"
    );
    let radio: usize = r
        .topics
        .iter()
        .filter(|(t, _)| t.ends_with("/radio"))
        .map(|(t, (.., msgs))| {
            for (_, data) in msgs {
                let m: Comms = decode(t, data);
                assert!(t.contains(&m.to) && m.from != m.to && m.bytes > 0 && !m.topic.is_empty());
                assert_eq!(
                    m.payload.len(),
                    m.bytes as usize,
                    "the bytes sent are recorded"
                );
                assert!(
                    stamp_ns(&m.header)
                        >= m.sent.sec as u64 * 1_000_000_000 + m.sent.nanosec as u64
                );
            }
            msgs.len()
        })
        .sum();
    assert_eq!(
        radio as u64,
        result
            .messages
            .iter()
            .filter(|(t, _)| t.ends_with("/radio"))
            .map(|(_, n)| n)
            .sum::<u64>()
    );
}

#[test]
fn a_ros2_recording_of_the_village_carries_raw_images_imu_gps_and_rendezvous() {
    // The short village with GPS on (its scenario turns it off), two rendered seconds.
    let path = repo().join("scenarios/village-short.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(", \"sensors.gps.outages_s\" = [[0.0, 100000.0]]", "")
        .replace(
            "overrides = { \"sensors.gps.outages_s\" = [[0.0, 100000.0]] }",
            "",
        );
    assert!(
        !text.contains("outages_s"),
        "GPS outages removed from the scenario"
    );
    let s = load_scenario_text(
        &path,
        text,
        &LoadOptions {
            robot_files: None,
            seed: None,
            duration_secs: Some(2.0),
        },
    )
    .unwrap();
    let (r, result) = record(&s, true);
    for (topic, n) in &result.messages {
        if !topic.ends_with("/truth") && !topic.ends_with("/radio") {
            assert_eq!(r.topics[&format!("/{topic}")].3.len() as u64, *n, "{topic}");
        }
    }
    // Images: raw mono8 (the benches deliver grey), 10 Hz, the resolved resolution (the
    // scenario halves both benches).
    for side in ["left", "right"] {
        let topic = format!("/ressac/stereo/{side}");
        let images = of(&r, &topic, "sensor_msgs/msg/Image");
        assert_eq!(images.len(), 20, "10 Hz for 2 s");
        for (t, data) in images {
            let m: Image = decode(&topic, data);
            assert_eq!(
                (m.width, m.height, m.encoding.as_str(), m.is_bigendian),
                (512, 384, "mono8", 0)
            );
            assert_eq!(m.step, m.width);
            assert_eq!(m.data.len(), (m.step * m.height) as usize);
            assert_eq!(stamp_ns(&m.header), *t);
            assert_eq!(m.header.frame_id, format!("ressac/stereo_{side}"));
        }
    }
    // The bench's optical frames on /tf_static: 0.9 m apart (Ressac's baseline).
    let statics: Vec<TfMessage> = of(&r, "/tf_static", "tf2_msgs/msg/TFMessage")
        .iter()
        .map(|(_, d)| decode("/tf_static", d))
        .collect();
    let find = |frame: &str| {
        statics
            .iter()
            .flat_map(|m| &m.transforms)
            .find(|t| t.child_frame_id == frame)
            .unwrap_or_else(|| panic!("{frame} on /tf_static"))
            .transform
            .position
    };
    let (l, rt) = (find("ressac/stereo_left"), find("ressac/stereo_right"));
    let baseline = ((l.x - rt.x).powi(2) + (l.y - rt.y).powi(2) + (l.z - rt.z).powi(2)).sqrt();
    assert!((baseline - 0.9).abs() < 1e-9, "{baseline}");
    // IMU at 100 Hz, no orientation (covariance[0] = -1 as sensor_msgs says), about +g up.
    let imu = of(&r, "/ressac/imu", "sensor_msgs/msg/Imu");
    assert_eq!(imu.len(), 200);
    let mut az = 0.0;
    for (_, data) in imu {
        let m: Imu = decode("/ressac/imu", data);
        assert_eq!(m.orientation_covariance[0], -1.0);
        assert_eq!([m.orientation.x, m.orientation.w], [0.0, 1.0]);
        assert!(
            m.angular_velocity.x.is_finite()
                && m.angular_velocity_covariance == [0.0; 9]
                && m.linear_acceleration_covariance == [0.0; 9]
        );
        az += m.linear_acceleration.z / 200.0;
    }
    assert!((az - 9.81).abs() < 1.0, "{az}");
    // GPS: WGS-84 near the documented origin (43.5628 N, 1.4767 E, 150 m), 1 Hz on both
    // robots, the variance of the resolved sigma on the diagonal.
    let mut fixes = 0;
    for robot in ["dala", "ressac"] {
        let topic = format!("/{robot}/gps");
        let truth = result.truth_of(robot).unwrap();
        for (t, data) in of(&r, &topic, "sensor_msgs/msg/NavSatFix") {
            let m: NavSatFix = decode(&topic, data);
            fixes += 1;
            assert_eq!(
                (
                    m.status.status,
                    m.status.service,
                    m.position_covariance_type
                ),
                (0, 1, 2)
            );
            let (_, pose) = truth.iter().min_by_key(|(s, _)| s.abs_diff(*t)).unwrap();
            let p = pose.translation.vector;
            // Back to metres east/north of the origin (flat earth), within the fix's noise.
            let north = (m.latitude - 43.5628).to_radians() * 6_378_137.0;
            let east =
                (m.longitude - 1.4767).to_radians() * 6_378_137.0 * 43.5628f64.to_radians().cos();
            let sigma = m.position_covariance[0].sqrt();
            assert!(
                sigma > 0.0
                    && m.position_covariance[4] == m.position_covariance[0]
                    && m.position_covariance[1] == 0.0
            );
            assert!(
                (east - p.x).abs() < 6.0 * sigma + 1.0 && (north - p.y).abs() < 6.0 * sigma + 1.0,
                "{east} {north} vs {p:?}"
            );
            assert!((m.altitude - 150.0 - p.z).abs() < 6.0 * sigma + 1.0);
        }
    }
    assert_eq!(fixes, 4, "1 Hz on two robots over 2 s");
    // The same fixes in the local frame, as the robots received them (replay reads these).
    let local: usize = ["dala", "ressac"]
        .iter()
        .map(|robot| {
            let topic = format!("/{robot}/gps/local");
            of(&r, &topic, "hetsim_msgs/msg/GpsLocal").len()
        })
        .sum();
    assert_eq!(local, fixes);
    // The rendezvous right at the start: Ressac sees Dala 40 m below.
    let mut seen = 0;
    for robot in ["dala", "ressac"] {
        let topic = format!("/{robot}/rendezvous");
        if let Some((_, _, _, msgs)) = r.topics.get(&topic) {
            for (_, data) in msgs {
                let m: Rendezvous = decode(&topic, data);
                seen += 1;
                assert!(m.sigma_m > 0.0 && m.sigma_rad > 0.0 && m.other != robot);
                let d = (m.pose.position.x.powi(2)
                    + m.pose.position.y.powi(2)
                    + m.pose.position.z.powi(2))
                .sqrt();
                assert!((30.0..50.0).contains(&d), "{d} m between the robots");
            }
        }
    }
    assert!(seen > 0, "a rendezvous in the first two seconds");
    for robot in ["dala", "ressac"] {
        let topic = format!("/{robot}/cmd");
        for (_, data) in of(&r, &topic, "hetsim_msgs/msg/Command") {
            let m: Command = decode(&topic, data);
            assert!(
                m.kind
                    == if robot == "dala" {
                        "wheels"
                    } else {
                        "helicopter"
                    }
                    || m.kind == "stop",
                "{}",
                m.kind
            );
        }
    }
}
