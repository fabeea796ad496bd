//! The child stack against hand-made orders, compass readings, encoders and images.

use super::*;
use hetsim_msgs::{CompassReading, Delivered, WheelOdometry};
use hetsim_vision::appearance::{Feature, Features};

fn child() -> ChildStack {
    ChildStack::new(
        ChildParams {
            track_m: 0.1,
            speed_mps: 0.15,
            max_turn_radps: 1.0,
            aim_tolerance_rad: 0.05,
            settle_ns: 200_000_000,
            seed: 5,
        },
        &Mission::Teleoperated {
            parent: "parent".into(),
        },
    )
}

fn order(seq: u32, order: Order) -> SensorMsg {
    let out = TeamMsg::Order { seq, order }.to("child");
    SensorMsg::Comms(Delivered {
        from: "parent".into(),
        topic: out.topic,
        sent_ns: 0,
        stamp_ns: 0,
        payload: out.payload,
    })
}

fn compass(h: f64) -> SensorMsg {
    SensorMsg::Compass(CompassReading {
        stamp_ns: 0,
        sensor: "compass".into(),
        heading_rad: h,
    })
}

/// An encoder reading at `stamp_ns`: both wheels `m` metres.
fn odo(stamp_ns: u64, m: f64) -> SensorMsg {
    SensorMsg::WheelOdometry(WheelOdometry {
        stamp_ns,
        sensor: "e".into(),
        left_m: m,
        right_m: m,
    })
}

/// A step whose messages the boundary accepts.
fn step(c: &mut ChildStack, now_ns: u64, inbox: &[SensorMsg]) -> Command {
    c.step(now_ns, inbox).expect("valid messages")
}

fn replies(c: &mut ChildStack) -> Vec<TeamMsg> {
    c.outbox()
        .iter()
        .map(|o| postcard::from_bytes(&o.payload).unwrap())
        .collect()
}

#[test]
fn a_drive_turns_by_compass_then_stops_after_the_encoder_distance() {
    const T: u64 = 100_000_000;
    let mut c = child();
    let cmd = step(
        &mut c,
        0,
        &[
            compass(0.0),
            order(
                1,
                Order::Drive {
                    heading_rad: 1.0,
                    distance_m: 0.3,
                },
            ),
        ],
    );
    assert_eq!(replies(&mut c), vec![TeamMsg::Ack { seq: 1 }]);
    // Turning left (right wheel faster).
    let Command::Wheels {
        left_mps,
        right_mps,
    } = cmd
    else {
        panic!("{cmd:?}")
    };
    assert!(right_mps > 0.0 && left_mps < 0.0);
    // Aligned: stop once, then drive straight.
    assert_eq!(
        step(&mut c, T, &[compass(0.99), odo(T, 0.0)]),
        Command::Stop
    );
    // Straight on, holding the heading by compass: 0.01 rad to the right of the target
    // turns it left a little (right wheel faster), 0.01 rad to the left turns it right.
    let Command::Wheels {
        left_mps,
        right_mps,
    } = step(&mut c, 2 * T, &[odo(2 * T, 0.1)])
    else {
        panic!()
    };
    assert!((left_mps + right_mps - 0.3).abs() < 1e-12 && left_mps < right_mps);
    let Command::Wheels {
        left_mps,
        right_mps,
    } = step(&mut c, 3 * T, &[odo(3 * T, 0.15), compass(1.01)])
    else {
        panic!()
    };
    assert!((left_mps + right_mps - 0.3).abs() < 1e-12 && left_mps > right_mps);
    assert_eq!(step(&mut c, 4 * T, &[odo(4 * T, 0.06)]), Command::Stop);
    // Told to stop, it rolls on: counted, and reported once a reading shows it stands (under
    // 1 cm/s; a step with no reading is not standing).
    assert_eq!(step(&mut c, 5 * T, &[odo(5 * T, 0.008)]), Command::Stop);
    assert_eq!(step(&mut c, 5 * T + 1, &[compass(1.01)]), Command::Stop);
    // Half a millimetre in 10 ms is 5 cm/s: still rolling, however small the reading.
    let soon = 5 * T + T / 10;
    assert_eq!(step(&mut c, soon, &[odo(soon, 0.0005)]), Command::Stop);
    assert!(replies(&mut c).is_empty(), "reported while rolling");
    assert_eq!(step(&mut c, 6 * T, &[odo(6 * T, 0.0002)]), Command::Stop);
    let r = replies(&mut c);
    assert!(
        matches!(r[..], [TeamMsg::Done { seq: 1, driven_m, heading_rad }] if (driven_m - 0.3187).abs() < 1e-9 && (heading_rad - 1.01).abs() < 1e-9),
        "{r:?}"
    );
    // The order again (the parent missed the reply): acknowledged and answered again,
    // not driven again.
    assert_eq!(
        step(
            &mut c,
            7 * T,
            &[order(
                1,
                Order::Drive {
                    heading_rad: 1.0,
                    distance_m: 0.3
                }
            )]
        ),
        Command::Stop
    );
    assert_eq!(replies(&mut c).len(), 2);
    // An older order is ignored.
    step(
        &mut c,
        8 * T,
        &[order(
            0,
            Order::Drive {
                heading_rad: 2.0,
                distance_m: 1.0,
            },
        )],
    );
    assert!(replies(&mut c).is_empty());
}

#[test]
fn a_child_slower_than_the_turn_floor_turns_at_its_own_maximum() {
    // A robot file may allow less than the 0.25 rad/s floor (the file fuzzer found one
    // that made the clamp panic): the wheels then turn the robot at its maximum.
    let mut c = child();
    c.params.max_turn_radps = 0.1;
    let cmd = step(
        &mut c,
        0,
        &[
            compass(0.0),
            order(
                1,
                Order::Drive {
                    heading_rad: 1.0,
                    distance_m: 0.3,
                },
            ),
        ],
    );
    let Command::Wheels {
        left_mps,
        right_mps,
    } = cmd
    else {
        panic!("{cmd:?}")
    };
    let yaw_rate = (right_mps - left_mps) / c.params.track_m;
    assert!((yaw_rate - 0.1).abs() < 1e-9, "{yaw_rate} rad/s");
}

#[test]
fn a_grab_waits_for_an_image_taken_after_settling() {
    let mut c = child();
    step(
        &mut c,
        0,
        &[
            compass(0.02),
            order(
                3,
                Order::Grab {
                    heading_rad: 0.0,
                    vertex: (4, 2),
                },
            ),
        ],
    );
    assert!(!c.status().wants_images || c.phase != Phase::Idle);
    step(&mut c, 10, &[compass(0.01)]);
    assert!(c.status().wants_images);
    let img = |stamp_ns| {
        SensorMsg::Image(Image {
            stamp_ns,
            sensor: "camera".into(),
            width: 1,
            height: 1,
            encoding: hetsim_msgs::PixelEncoding::Rgb8,
            data: vec![1, 2, 3],
        })
    };
    step(&mut c, 100_000_000, &[img(100_000_000)]);
    assert!(replies(&mut c)
        .iter()
        .all(|m| matches!(m, TeamMsg::Ack { .. })));
    step(&mut c, 500_000_000, &[img(500_000_000)]);
    let r = replies(&mut c);
    assert!(
        matches!(&r[..], [TeamMsg::Grabbed { seq: 3, vertex: (4, 2), image, .. }] if image.stamp_ns == 500_000_000),
        "{r:?}"
    );
    assert!(!c.status().wants_images);
}

/// The localization run of [`a_child_sent_the_database_drives_its_path_and_localizes`]: the
/// database and the path, from (0.25, 0.25) five cells east, then two north past the
/// obstacle's east side (cells (3, 2) and (4, 2) are occupied); the child's encoders count
/// `counts_per_m` per metre travelled, and the message brings it `odometry_scale`.
struct TourRun {
    c: ChildStack,
    /// Where the robot really ended.
    at: [f64; 2],
    heard: Vec<TeamMsg>,
    delivered: SensorMsg,
    path: Vec<[f64; 2]>,
}

fn run_tour(odometry_scale: f64, counts_per_m: f64) -> TourRun {
    let grid = crate::localize::tests::grid();
    let places: Vec<([f64; 2], Features)> = (0..48)
        .filter(|i| !grid.occupied[*i])
        .map(|i| {
            let xy = grid.centre_of(i % 8, i / 8);
            let img = crate::localize::tests::room_view(0, xy[0], xy[1]);
            (
                xy,
                Features::of(&hetsim_vision::Gray::from_image(&img).unwrap()),
            )
        })
        .collect();
    let path: Vec<[f64; 2]> = [
        (0, 0),
        (1, 0),
        (2, 0),
        (3, 0),
        (4, 0),
        (5, 0),
        (5, 1),
        (5, 2),
    ]
    .iter()
    .map(|&(c, r)| [0.25 + 0.5 * c as f64, 0.25 + 0.5 * r as f64])
    .collect();
    let mut c = child();
    let msg = TeamMsg::Localize {
        seq: 9,
        grid,
        places,
        path: path.clone(),
        heading_rad: 0.0,
        odometry_scale,
    }
    .to("child");
    let delivered = SensorMsg::Comms(Delivered {
        from: "parent".into(),
        topic: msg.topic,
        sent_ns: 0,
        stamp_ns: 0,
        payload: msg.payload,
    });
    // The robot: unicycle kinematics from the wheel speeds, 50 ms ticks.
    let (mut x, mut y, mut yaw) = (0.25, 0.25, 0.0f64);
    let mut wheels = (0.0, 0.0);
    let dt = 0.05;
    let mut heard = Vec::new();
    for tick in 0..20_000u64 {
        let now = tick * 50_000_000;
        let (l, r) = wheels;
        let (left_m, right_m) = (l * dt, r * dt);
        let forward = (left_m + right_m) / 2.0;
        yaw += (right_m - left_m) / c.params.track_m;
        x += forward * yaw.cos();
        y += forward * yaw.sin();
        let mut inbox = vec![
            SensorMsg::Compass(CompassReading {
                stamp_ns: now,
                sensor: "compass".into(),
                heading_rad: hetsim_msgs::wrap_angle(yaw),
            }),
            SensorMsg::WheelOdometry(WheelOdometry {
                stamp_ns: now,
                sensor: "e".into(),
                left_m: left_m * counts_per_m,
                right_m: right_m * counts_per_m,
            }),
        ];
        if tick == 0 {
            inbox.push(delivered.clone());
        }
        if c.status().wants_images {
            inbox.push(SensorMsg::Image(crate::localize::tests::room_view(
                now, x, y,
            )));
        }
        wheels = match step(&mut c, now, &inbox) {
            Command::Wheels {
                left_mps,
                right_mps,
            } => (left_mps, right_mps),
            _ => (0.0, 0.0),
        };
        heard.extend(replies(&mut c));
        if heard.contains(&TeamMsg::Localized { seq: 9 }) {
            break;
        }
    }
    TourRun {
        c,
        at: [x, y],
        heard,
        delivered,
        path,
    }
}

/// After mapping, the database comes by radio with a path; the child drives it on its own
/// (kinematics below, true compass, encoders of its own wheels, images of where it really
/// is) and localizes: the run ends with `Localized`, and each feature's filter ends within
/// one grid spacing of the truth, from particles spread over the whole room.
#[test]
fn a_child_sent_the_database_drives_its_path_and_localizes() {
    let TourRun {
        mut c,
        at: [x, y],
        heard,
        delivered,
        path,
    } = run_tour(1.0, 1.0);
    assert!(heard.contains(&TeamMsg::Ack { seq: 9 }), "{heard:?}");
    assert!(heard.contains(&TeamMsg::Localized { seq: 9 }), "never done");
    // It drove the path itself: within a few centimetres of its end (2.75, 1.25).
    assert!(
        (x - 2.75).hypot(y - 1.25) < 0.1,
        "ended at ({x:.2}, {y:.2})"
    );
    let artifacts = c.artifacts();
    assert_eq!(artifacts.len(), Feature::ALL.len());
    for a in &artifacts {
        let hetsim_msgs::ArtifactData::Trajectory(track) = &a.data else {
            panic!("{} is not a trajectory", a.name)
        };
        // One estimate per image: one per vertex of the path.
        assert_eq!(track.len(), path.len(), "{}", a.name);
        let e = track.last().unwrap().1.translation.vector;
        let error = (e.x - x).hypot(e.y - y);
        assert!(error < 0.5, "{}: final error {error:.2} m", a.name);
    }
    // A poll, or the database again (its acknowledgement was lost), is answered with the
    // acknowledgement and the report, and starts nothing.
    step(&mut c, u64::MAX / 4, std::slice::from_ref(&delivered));
    let poll = TeamMsg::Poll { seq: 9 }.to("child");
    step(
        &mut c,
        u64::MAX / 4 + 1,
        &[SensorMsg::Comms(Delivered {
            from: "parent".into(),
            topic: poll.topic,
            sent_ns: 0,
            stamp_ns: 0,
            payload: poll.payload,
        })],
    );
    let again = vec![TeamMsg::Ack { seq: 9 }, TeamMsg::Localized { seq: 9 }];
    assert_eq!(replies(&mut c), [again.clone(), again].concat());
    assert_eq!(c.phase, Phase::Idle);
    // An order after the run is obeyed again and answered by radio; the estimates stay.
    step(&mut c, u64::MAX / 2, &[order(10, Order::Stop)]);
    assert_eq!(replies(&mut c), vec![TeamMsg::Ack { seq: 10 }]);
    assert_eq!(c.artifacts().len(), Feature::ALL.len());
}

/// Encoders that count 6 % more than the robot travels leave the uncalibrated child short
/// of its path's end (2.5 m east, then 1 m north) by (2.5, 1.0) x (1 - 1 / 1.06) = (0.14,
/// 0.06) m, 0.15 m (its own localization takes over only beyond 0.3 m). Sent the parent's
/// calibration, 1.3 % low as in the lab, it ends as close as with true encoders (the bound
/// of the test above; 1.3 % of the path is 0.05 m).
#[test]
fn a_calibrated_child_drives_its_path_with_encoders_that_overcount() {
    let gain = 1.06;
    let off = |r: &TourRun| (r.at[0] - 2.75).hypot(r.at[1] - 1.25);
    let blind = run_tour(1.0, gain);
    assert!(off(&blind) > 0.12, "uncalibrated, {:.3} m off", off(&blind));
    let calibrated = run_tour(0.987 / gain, gain);
    assert!(
        off(&calibrated) < 0.1,
        "calibrated, {:.3} m off",
        off(&calibrated)
    );
    assert!(calibrated.heard.contains(&TeamMsg::Localized { seq: 9 }));
}

/// A scale no wheel's slip or encoder error could give (a bad measurement) is not used: the
/// child drives as uncalibrated, to the same spot.
#[test]
fn an_implausible_scale_is_not_used() {
    let blind = run_tour(1.0, 1.0).at;
    for scale in [0.5, 1.3] {
        let at = run_tour(scale, 1.0).at;
        assert!(
            (at[0] - blind[0]).abs() < 1e-12 && (at[1] - blind[1]).abs() < 1e-12,
            "scale {scale}: {at:?} vs {blind:?}"
        );
    }
}

/// A drive whose encoders fall silent as it stops is reported a second after the stop: the
/// roll cannot be told from nothing, and the parent must not wait for ever.
#[test]
fn a_drive_with_silent_encoders_is_reported_a_second_after_the_stop() {
    const T: u64 = 100_000_000;
    let mut c = child();
    let drive = Order::Drive {
        heading_rad: 0.0,
        distance_m: 0.1,
    };
    step(&mut c, 0, &[compass(0.0), order(1, drive)]);
    step(&mut c, T, &[compass(0.0), odo(T, 0.0)]);
    assert_eq!(step(&mut c, 2 * T, &[odo(2 * T, 0.12)]), Command::Stop);
    replies(&mut c);
    assert_eq!(step(&mut c, 12 * T - 1, &[]), Command::Stop);
    assert!(replies(&mut c).is_empty(), "reported before the second");
    step(&mut c, 12 * T, &[]);
    let r = replies(&mut c);
    assert!(
        matches!(r[..], [TeamMsg::Done { seq: 1, driven_m, .. }] if (driven_m - 0.12).abs() < 1e-12),
        "{r:?}"
    );
}

/// The odometer sent with an image is everything the encoders counted, signed: forward
/// drives, the roll after them, a reverse reading, turns on the spot (the wheels opposite:
/// nothing), whatever the phase.
#[test]
fn an_image_carries_the_encoders_odometer() {
    const T: u64 = 100_000_000;
    let mut c = child();
    let turn = |t: u64, m: f64| {
        SensorMsg::WheelOdometry(WheelOdometry {
            stamp_ns: t,
            sensor: "e".into(),
            left_m: -m,
            right_m: m,
        })
    };
    let drive = Order::Drive {
        heading_rad: 0.0,
        distance_m: 0.2,
    };
    step(&mut c, 0, &[compass(0.0), order(1, drive)]);
    step(&mut c, T, &[compass(0.0), odo(T, 0.0)]);
    step(&mut c, 2 * T, &[odo(2 * T, 0.25)]);
    step(&mut c, 3 * T, &[odo(3 * T, 0.006)]);
    step(&mut c, 4 * T, &[odo(4 * T, -0.0005)]);
    let grab = Order::Grab {
        heading_rad: 1.0,
        vertex: (2, 3),
    };
    step(
        &mut c,
        5 * T,
        &[compass(0.0), order(2, grab), turn(5 * T, 0.03)],
    );
    step(&mut c, 6 * T, &[compass(1.0), turn(6 * T, 0.02)]);
    step(&mut c, 7 * T, &[compass(1.0)]);
    let img = |t: u64| {
        SensorMsg::Image(Image {
            stamp_ns: t,
            sensor: "camera".into(),
            width: 2,
            height: 2,
            encoding: hetsim_msgs::PixelEncoding::Rgb8,
            data: vec![0; 12],
        })
    };
    step(&mut c, 10 * T, &[img(10 * T)]);
    let r = replies(&mut c);
    let sent = r.iter().find_map(|m| match m {
        TeamMsg::Grabbed { odometer_m, .. } => Some(*odometer_m),
        _ => None,
    });
    let expected = 0.25 + 0.006 - 0.0005;
    assert!(
        sent.is_some_and(|o| (o - expected).abs() < 1e-12),
        "{sent:?} vs {expected} ({r:?})"
    );
}

/// A sure estimate (particle spread under 0.25 m) corrects the dead-reckoned position only
/// as far as its own error allows: a position 0.5 m from it moves along the line between them
/// to 0.3 m (`TRUST_M`) from it; one within 0.3 m stays; an unsure estimate moves nothing.
#[test]
fn a_sure_estimate_pulls_the_position_to_within_its_error_not_onto_itself() {
    let (e, far, near) = ([1.0, -0.5], [1.3, -0.1], [1.1, -0.3]);
    let moved = tour::corrected(far, e, 0.1);
    assert!(
        (moved[0] - 1.18).abs() < 1e-12 && (moved[1] + 0.26).abs() < 1e-12,
        "{moved:?}"
    );
    assert_eq!(tour::corrected(near, e, 0.1), near);
    assert_eq!(tour::corrected(far, e, 0.3), far, "unsure");
}
