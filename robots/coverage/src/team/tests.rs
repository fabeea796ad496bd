//! The child stack against hand-made orders, compass readings, encoders and images.

use super::*;
use hetsim_msgs::{CompassReading, Delivered, WheelOdometry};

fn child() -> ChildStack {
    ChildStack::new(
        ChildParams {
            track_m: 0.1,
            speed_mps: 0.15,
            max_turn_radps: 1.0,
            aim_tolerance_rad: 0.05,
            settle_ns: 200_000_000,
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
    assert_eq!(step(&mut c, 1, &[compass(0.99)]), Command::Stop);
    let odo = |m: f64| {
        SensorMsg::WheelOdometry(WheelOdometry {
            stamp_ns: 0,
            sensor: "e".into(),
            left_m: m,
            right_m: m,
        })
    };
    // Straight on, holding the heading by compass: 0.01 rad to the right of the target
    // turns it left a little (right wheel faster), 0.01 rad to the left turns it right.
    let Command::Wheels {
        left_mps,
        right_mps,
    } = step(&mut c, 2, &[odo(0.1)])
    else {
        panic!()
    };
    assert!((left_mps + right_mps - 0.3).abs() < 1e-12 && left_mps < right_mps);
    let Command::Wheels {
        left_mps,
        right_mps,
    } = step(&mut c, 3, &[odo(0.15), compass(1.01)])
    else {
        panic!()
    };
    assert!((left_mps + right_mps - 0.3).abs() < 1e-12 && left_mps > right_mps);
    assert_eq!(step(&mut c, 4, &[odo(0.06)]), Command::Stop);
    let r = replies(&mut c);
    assert!(
        matches!(r[..], [TeamMsg::Done { seq: 1, driven_m, heading_rad }] if (driven_m - 0.31).abs() < 1e-9 && (heading_rad - 1.01).abs() < 1e-9),
        "{r:?}"
    );
    // The order again (the parent missed the reply): acknowledged and answered again,
    // not driven again.
    assert_eq!(
        step(
            &mut c,
            5,
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
        6,
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
