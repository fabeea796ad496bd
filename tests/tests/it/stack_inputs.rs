//! Robot software never panics on what it is fed: every kind of message, mutated, at every
//! kind of stack (the rover's and the helicopter's SLAM around their pilots, the coverage
//! parent, a c't-Bot child), at least 1,000 messages of each kind at each stack. A message
//! the boundary refuses names its sensor, field and value; one it accepts is computed on,
//! and that must not panic either (the SLAM's worker thread included: its artifacts are
//! collected at the end, which joins it). Mutations are drawn from a seeded ChaCha stream,
//! so a failure is reproduced by its seed and index.

use hetsim_msgs::{
    pose_from_xyz_rpy, ChildTracks, CompassReading, Delivered, GpsFix, Image, ImageMatch,
    ImuSample, LaserScan, Outgoing, PoseStamped, Rendezvous, RobotStack, SensorMsg, StackStatus,
    Track, WheelOdometry,
};
use hetsim_scene::{load_scenario, LoadOptions};
use hetsim_tests::repo;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::{Arc, Mutex};

/// Messages per kind per stack.
const CASES: usize = 1_000;

/// A stack that copies what its inner stack sends, to mutate real payloads later.
struct Tap {
    inner: Box<dyn RobotStack>,
    sent: Arc<Mutex<Vec<Outgoing>>>,
}

impl RobotStack for Tap {
    fn step(
        &mut self,
        now_ns: u64,
        inbox: &[SensorMsg],
    ) -> Result<hetsim_msgs::Command, hetsim_msgs::InputError> {
        self.inner.step(now_ns, inbox)
    }
    fn status(&self) -> StackStatus {
        self.inner.status()
    }
    fn outbox(&mut self) -> Vec<Outgoing> {
        let out = self.inner.outbox();
        self.sent.lock().unwrap().extend(out.iter().cloned());
        out
    }
}

/// Real radio payloads (graph shares, key frames, team orders and replies) from short runs.
fn real_payloads() -> Vec<Outgoing> {
    let sent = Arc::new(Mutex::new(Vec::new()));
    for (file, secs, render) in [("village-short", 3.0, true), ("lab", 60.0, true)] {
        let s = load_scenario(
            &repo().join(format!("scenarios/{file}.toml")),
            &LoadOptions {
                robot_files: None,
                seed: None,
                duration_secs: Some(secs),
            },
        )
        .unwrap();
        let stacks: Vec<Box<dyn RobotStack>> = hetsim_stacks::build_stacks(&s, false)
            .into_iter()
            .map(|inner| {
                Box::new(Tap {
                    inner,
                    sent: sent.clone(),
                }) as Box<dyn RobotStack>
            })
            .collect();
        hetsim_engine::run(
            &s,
            stacks,
            |_, _| {},
            hetsim_engine::RunOptions {
                render: render.then(hetsim_render::RenderOptions::default),
                ..Default::default()
            },
        )
        .unwrap();
    }
    let out = sent.lock().unwrap().clone();
    out
}

/// A number: mostly plausible, sometimes an edge (NaN, infinities, zero, huge, tiny).
fn number(rng: &mut ChaCha8Rng, scale: f64) -> f64 {
    match rng.random_range(0..10) {
        0 => [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            1e300,
            -1e300,
            1e-300,
            f64::MAX,
            f64::MIN_POSITIVE,
        ][rng.random_range(0..10)],
        1 => -scale * rng.random::<f64>(),
        _ => scale * (rng.random::<f64>() * 2.0 - 1.0),
    }
}

fn stamp(rng: &mut ChaCha8Rng, now: u64) -> u64 {
    match rng.random_range(0..20) {
        0 => u64::MAX,
        1 => now + rng.random_range(1..1_000_000_000),
        2 => now.saturating_sub(rng.random_range(1..10_000_000_000)),
        _ => now,
    }
}

fn pose(rng: &mut ChaCha8Rng) -> hetsim_msgs::Pose {
    if rng.random_range(0..8) == 0 {
        // A quaternion that is not a rotation (nalgebra's unchecked constructor, as a
        // deserializer builds one).
        let q = Quaternion::new(
            number(rng, 2.0),
            number(rng, 2.0),
            number(rng, 2.0),
            number(rng, 2.0),
        );
        return hetsim_msgs::Pose::from_parts(
            Translation3::new(number(rng, 100.0), number(rng, 100.0), number(rng, 100.0)),
            UnitQuaternion::new_unchecked(q),
        );
    }
    pose_from_xyz_rpy(
        [number(rng, 200.0), number(rng, 200.0), number(rng, 50.0)],
        [number(rng, 3.2), number(rng, 3.2), number(rng, 3.2)],
    )
}

fn name(rng: &mut ChaCha8Rng, known: &[&str]) -> String {
    match rng.random_range(0..6) {
        0 => String::new(),
        1 => "\u{0}\u{ff}zz/..".to_string(),
        _ => known[rng.random_range(0..known.len())].to_string(),
    }
}

/// A mutated message of kind `kind` (0..11) for a stack at `now`.
fn message(
    rng: &mut ChaCha8Rng,
    kind: usize,
    now: u64,
    sensors: &[&str],
    payloads: &[Outgoing],
    size: (u32, u32),
) -> SensorMsg {
    let t = stamp(rng, now);
    let sensor = name(rng, sensors);
    match kind {
        0 => SensorMsg::TruthPose(PoseStamped {
            stamp_ns: t,
            pose: pose(rng),
        }),
        1 => SensorMsg::Compass(CompassReading {
            stamp_ns: t,
            sensor,
            heading_rad: number(rng, 7.0),
        }),
        2 => SensorMsg::Gps(GpsFix {
            stamp_ns: t,
            sensor,
            position_m: [number(rng, 300.0), number(rng, 300.0), number(rng, 50.0)],
            sigma_m: number(rng, 5.0),
        }),
        3 => SensorMsg::WheelOdometry(WheelOdometry {
            stamp_ns: t,
            sensor,
            left_m: number(rng, 0.1),
            right_m: number(rng, 0.1),
        }),
        4 => SensorMsg::Imu(ImuSample {
            stamp_ns: t,
            sensor,
            angular_rate_radps: [number(rng, 1.0), number(rng, 1.0), number(rng, 1.0)],
            accel_mps2: [number(rng, 12.0), number(rng, 12.0), number(rng, 12.0)],
        }),
        5 => {
            let beams = [0, 1, 2, 481, 5000][rng.random_range(0..5)];
            SensorMsg::LaserScan(LaserScan {
                stamp_ns: t,
                sensor,
                angle_min_rad: number(rng, 3.2),
                angle_increment_rad: number(rng, 0.02),
                range_max_m: number(rng, 30.0),
                ranges_m: (0..beams).map(|_| number(rng, 20.0) as f32).collect(),
            })
        }
        6 => SensorMsg::ChildTracks(ChildTracks {
            stamp_ns: t,
            sensor,
            tracks: (0..rng.random_range(0..5))
                .map(|_| Track {
                    child: name(rng, &["child1", "child2", "child3", "parent"]),
                    position_m: [number(rng, 5.0), number(rng, 5.0)],
                })
                .collect(),
        }),
        7 => SensorMsg::Rendezvous(Rendezvous {
            stamp_ns: t,
            sensor,
            other: name(rng, &["dala", "ressac", "parent"]),
            relative: pose(rng),
            sigma_m: number(rng, 1.0),
            sigma_rad: number(rng, 0.1),
        }),
        8 => SensorMsg::ImageMatch(ImageMatch {
            stamp_ns: t,
            sensor,
            other: name(rng, &["dala", "ressac"]),
            other_stamp_ns: stamp(rng, now / 2),
            relative: pose(rng),
            sigma_m: number(rng, 1.0),
            sigma_rad: number(rng, 0.1),
        }),
        9 => {
            // A real payload, mutated: bytes flipped, cut short, lengthened, or random.
            let real = &payloads[rng.random_range(0..payloads.len())];
            let mut payload = real.payload.clone();
            match rng.random_range(0..5) {
                0 => payload = (0..rng.random_range(0..64)).map(|_| rng.random()).collect(),
                1 => payload.truncate(rng.random_range(0..=payload.len())),
                2 => payload.extend((0..rng.random_range(1..32)).map(|_| rng.random::<u8>())),
                _ => {
                    for _ in 0..rng.random_range(1..8) {
                        if !payload.is_empty() {
                            let i = rng.random_range(0..payload.len());
                            payload[i] ^= 1 << rng.random_range(0..8);
                        }
                    }
                }
            }
            SensorMsg::Comms(Delivered {
                from: name(rng, &["dala", "ressac", "parent", "child1", "child2"]),
                topic: if rng.random_range(0..8) == 0 {
                    "nope".into()
                } else {
                    real.topic.clone()
                },
                sent_ns: stamp(rng, now),
                stamp_ns: t,
                payload,
            })
        }
        _ => {
            // Mostly the stack's own size with the right bytes (the VO and the features run
            // on noise), else any size with any number of bytes.
            let (width, height) = if rng.random_range(0..2) == 0 {
                size
            } else {
                (rng.random_range(0..300), rng.random_range(0..300))
            };
            let encoding = if rng.random_range(0..2) == 0 {
                hetsim_msgs::PixelEncoding::Rgb8
            } else {
                hetsim_msgs::PixelEncoding::Mono8
            };
            let n = if rng.random_range(0..4) == 0 {
                rng.random_range(0..1000)
            } else {
                (width * height * encoding.channels()) as usize
            };
            SensorMsg::Image(Image {
                stamp_ns: t,
                sensor,
                width,
                height,
                encoding,
                data: (0..n).map(|_| rng.random()).collect(),
            })
        }
    }
}

/// Throws `CASES` mutated messages of every kind at each stack of `scenario`, in a few
/// valid steps' company (the truth for pilots, stereo pairs for the SLAM).
fn throw(
    scenario: &str,
    sensors: &[&str],
    payloads: &[Outgoing],
    size: (u32, u32),
    seed: u64,
) -> (usize, usize) {
    let s = load_scenario(
        &repo().join(format!("scenarios/{scenario}.toml")),
        &LoadOptions::default(),
    )
    .unwrap();
    let (mut accepted, mut refused) = (0, 0);
    // Per robot: messages accepted and refused over every kind.
    let mut per_robot: Vec<(usize, usize)> = vec![(0, 0); s.robots.len()];
    for kind in 0..11 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed * 100 + kind as u64);
        let mut stacks = hetsim_stacks::build_stacks(&s, false);
        for (r, stack) in stacks.iter_mut().enumerate() {
            let mut now = 0u64;
            for case in 0..CASES {
                now += 10_000_000;
                let mut msg = message(&mut rng, kind, now, sensors, payloads, size);
                // A stereo pair now and then: the right image with the left's stamp.
                let mut inbox = vec![msg.clone()];
                if let SensorMsg::Image(img) = &mut msg {
                    if img.sensor.ends_with("/left") && rng.random_range(0..2) == 0 {
                        img.sensor = img.sensor.replace("/left", "/right");
                        inbox.push(msg);
                    }
                }
                match stack.step(now, &inbox) {
                    Ok(_) => {
                        accepted += 1;
                        per_robot[r].0 += 1;
                    }
                    Err(e) => {
                        refused += 1;
                        per_robot[r].1 += 1;
                        // The refusal names its field, the value and what is allowed, and
                        // comes from a message of this step.
                        assert!(
                            !e.field.is_empty() && !e.value.is_empty() && !e.allowed.is_empty(),
                            "{scenario} robot {r} kind {kind} case {case}: {e}"
                        );
                        assert!(
                            inbox.iter().any(|m| m.stamp_ns() == e.stamp_ns
                                && hetsim_msgs::sensor_of(m) == e.sensor),
                            "{scenario} robot {r} kind {kind} case {case}: {e} names no message of the step"
                        );
                    }
                }
                let _ = stack.outbox();
                let _ = stack.status();
            }
            // Joins the SLAM's worker: a panic there surfaces here.
            let _ = stack.artifacts();
        }
        eprintln!("{scenario} kind {kind}: {accepted} accepted, {refused} refused so far");
    }
    // Every stack both computed on messages and refused some: the mutations reach past the
    // boundary and are caught by it, at each stack.
    for (r, (a, f)) in per_robot.iter().enumerate() {
        assert!(
            *a > 0 && *f > 0,
            "{scenario} robot {r}: {a} accepted, {f} refused"
        );
    }
    (accepted, refused)
}

#[test]
fn no_stack_panics_on_mutated_messages_of_any_kind() {
    let payloads = real_payloads();
    for topic in ["slam/graph", "slam/keyframe", "team"] {
        assert!(
            payloads.iter().any(|p| p.topic == topic),
            "a real {topic} payload to mutate"
        );
    }
    // The village: Dala's and Ressac's SLAM around their pilots.
    let sensors = [
        "stereo/left",
        "stereo/right",
        "gps",
        "imu",
        "rendezvous",
        "truth",
        "image_match",
    ];
    let (a, r) = throw("village-short", &sensors, &payloads, (128, 96), 1);
    assert!(a > 0 && r > 0, "some accepted ({a}) and some refused ({r})");
    // The lab: the parent and three children.
    let sensors = [
        "camera", "compass", "encoders", "laser", "tracker", "omni", "truth",
    ];
    let (a, r) = throw("lab", &sensors, &payloads, (120, 88), 2);
    assert!(a > 0 && r > 0, "some accepted ({a}) and some refused ({r})");
}
