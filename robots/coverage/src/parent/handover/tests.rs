//! The parent's side of the handover against hand-made replies: the database is repeated
//! until the child acknowledges it, then small polls until the child's report comes, which
//! the radio may lose; a child that never answers is given up at the deadline.

use super::super::dist;
use super::*;
use crate::report::DatabaseImage;
use hetsim_msgs::{CoverageMission, RobotStack};

const S: u64 = 1_000_000_000;
const STEPS: usize = 3;

/// A parent whose mapping of a free 4 x 3 room of 0.5 m cells (8 x 6) is done: it stands on
/// (1, 0), beside its one child at (0, 0); one image in the database.
fn mapped_parent() -> ParentStack {
    let mission = CoverageMission {
        view_margin_deg: 0.0,
        view_margin_m: 0.0,
        localize_steps: STEPS,
        ..super::super::test_mission([8, 6], &[], &[("child1", (0, 0))], [0.75, 0.25, 0.0])
    };
    let mut p = super::super::planned_test_parent(mission);
    p.report.database.push(DatabaseImage {
        vertex: (0, 0),
        child: "child1".into(),
        estimated_xy: [0.25, 0.25],
        estimated_heading_rad: 0.0,
        image: crate::localize::tests::room_view(S, 0.25, 0.25),
    });
    p.report.finished_ns = Some(10 * S);
    p
}

/// The parent's handover step at `now_ns`, and what it sent.
fn at(p: &mut ParentStack, now_ns: u64) -> Vec<TeamMsg> {
    p.now_ns = now_ns;
    p.hand_over();
    p.outbox()
        .iter()
        .inspect(|o| assert_eq!(o.to, "child1"))
        .map(|o| postcard::from_bytes(&o.payload).unwrap())
        .collect()
}

fn is_database(m: &TeamMsg) -> bool {
    matches!(m, TeamMsg::Localize { .. })
}

/// The documented rhythm (every ten `resend_ns`), the switch from the database to polls
/// once acknowledged, and a lost report: the parent polls on, and the mission ends only when
/// a report reaches it.
#[test]
fn the_parent_repeats_the_database_then_polls_until_the_report_comes() {
    let mut p = mapped_parent();
    let every = 10 * p.params.resend_ns;
    let t0 = 10 * S;
    let sent = at(&mut p, t0);
    assert_eq!(sent.len(), 1);
    let TeamMsg::Localize {
        seq, path, places, ..
    } = &sent[0]
    else {
        panic!("the database first, got {:?}", sent[0]);
    };
    let seq = *seq;
    assert_eq!(places.len(), 1, "the database's one image");
    assert_eq!(
        path.len(),
        STEPS + 1,
        "the child's vertex, then a move per step"
    );
    assert_eq!(
        path[0],
        [0.25, 0.25],
        "from where the parent last had the child"
    );
    // Every move is one grid step, and none onto the parent's vertex: the first can only be
    // north, (1, 0) being the parent's.
    assert_eq!(path[1], [0.25, 0.75]);
    for w in path.windows(2) {
        let d = dist(w[0], w[1]);
        assert!((d - 0.5).abs() < 1e-9, "a move of {d} m");
        assert_ne!(w[1], [0.75, 0.25], "onto the parent");
    }
    assert!(!p.status().mission_over);

    // Not heard: nothing until ten resend_ns have passed, then the database again.
    assert!(at(&mut p, t0 + every - 1).is_empty());
    let again = at(&mut p, t0 + every);
    assert!(again.len() == 1 && is_database(&again[0]), "{again:?}");
    assert_eq!(p.report.resent_orders, 1);

    // An acknowledgement of another message is not this one's.
    assert!(!p.handover_reply(0, &TeamMsg::Ack { seq: seq + 1 }));
    // Nor is another child's.
    assert!(!p.handover_reply(1, &TeamMsg::Ack { seq }));
    assert!(p.handover_reply(0, &TeamMsg::Ack { seq }));
    // Heard: small polls from now on, never the database.
    let poll = at(&mut p, t0 + 2 * every);
    assert_eq!(poll, vec![TeamMsg::Poll { seq }]);
    assert_eq!(p.report.resent_orders, 1, "a poll is not a resent order");

    // The child's report is lost: the parent keeps polling, and the mission is not over.
    for k in 3..6 {
        assert_eq!(at(&mut p, t0 + k * every), vec![TeamMsg::Poll { seq }]);
        assert!(!p.status().mission_over);
    }
    // A report for another sequence number is not this run's.
    assert!(!p.handover_reply(0, &TeamMsg::Localized { seq: seq + 1 }));
    assert!(!p.status().mission_over);
    // The next report arrives.
    let heard = t0 + 5 * every + S;
    p.now_ns = heard;
    assert!(p.handover_reply(0, &TeamMsg::Localized { seq }));
    assert!(p.status().mission_over);
    assert!(
        at(&mut p, t0 + 40 * S).is_empty(),
        "nothing after the report"
    );
    let tour = p.team_report().tour.expect("the run is reported");
    assert_eq!(tour.child, "child1");
    assert_eq!(tour.path.len(), STEPS + 1);
    assert_eq!(tour.over_ns, Some(heard));
    assert!(!tour.timed_out);
    // A repeated report changes nothing.
    p.now_ns = t0 + 10 * every;
    assert!(p.handover_reply(0, &TeamMsg::Localized { seq }));
    assert_eq!(p.team_report().tour.unwrap().over_ns, Some(heard));
}

/// A child that never answers (stuck, or out of radio range) does not hold the run open:
/// the documented deadline is a minute per move, and the report says the run timed out.
#[test]
fn a_child_that_never_answers_is_given_up_at_the_deadline() {
    let mut p = mapped_parent();
    let every = 10 * p.params.resend_ns;
    let t0 = 10 * S;
    assert_eq!(at(&mut p, t0).len(), 1);
    let deadline = t0 + 60 * S * STEPS as u64;
    // Up to the deadline: the database at its rhythm, and the run still on.
    let mut t = t0;
    while t + every < deadline {
        t += every;
        let sent = at(&mut p, t);
        assert!(sent.len() == 1 && is_database(&sent[0]), "at {t}: {sent:?}");
    }
    at(&mut p, deadline - 1);
    assert!(!p.status().mission_over, "over before the deadline");
    at(&mut p, deadline);
    assert!(p.status().mission_over, "not over at the deadline");
    assert!(
        at(&mut p, deadline + 2 * every).is_empty(),
        "sent after giving up"
    );
    let tour = p.team_report().tour.unwrap();
    assert!(tour.timed_out);
    assert_eq!(tour.over_ns, Some(deadline));
}

/// A run asked for but impossible (the parent cannot place its child on a vertex, so no
/// path): tried once, nothing sent, and the mission over then, not before.
#[test]
fn a_run_that_is_impossible_sends_nothing_and_ends_the_mission() {
    let mut p = mapped_parent();
    p.children[0].planned = [-1.0, -1.0];
    assert!(
        !p.status().mission_over,
        "over before the handover was tried"
    );
    assert!(at(&mut p, 10 * S).is_empty());
    assert!(p.status().mission_over);
    assert!(at(&mut p, 100 * S).is_empty());
    assert_eq!(p.team_report().tour, None);
}

/// With no run asked for (`localize_steps = 0`), nothing is sent and the mission is over
/// with the mapping.
#[test]
fn no_run_asked_for_sends_nothing() {
    let mut p = mapped_parent();
    p.mission.localize_steps = 0;
    assert!(p.status().mission_over);
    assert!(at(&mut p, 10 * S).is_empty());
    assert!(at(&mut p, 100 * S).is_empty());
    assert!(p.status().mission_over);
    assert_eq!(p.team_report().tour, None);
}

/// Whatever the seed, the walk never steps onto the vertex where the parent stands: from
/// (0, 0), with the parent on (1, 0), the first move is always north.
#[test]
fn the_walk_never_steps_onto_the_parent() {
    let mut p = mapped_parent();
    let parent = p.map.at(1, 0).unwrap();
    let north = p.map.at(0, 1).unwrap();
    for seed in 0..16 {
        p.params.tour_seed = seed;
        let path = p.tour_path(0).expect("a free room has a walk");
        assert_eq!(path.len(), STEPS + 1);
        assert_eq!(path[1], north, "seed {seed}");
        assert!(!path.contains(&parent), "seed {seed}: {path:?}");
    }
}

/// The database's message carries the encoders' scale measured from the images the parent
/// saw the child take (`parent/odometry.rs`): uncalibrated (1) with no hop seen, the hops'
/// scale once enough were seen, in the message and in the report.
#[test]
fn the_database_carries_the_encoders_scale_from_the_hops_seen() {
    let scale_sent = |p: &mut ParentStack| match &at(p, 10 * S)[..] {
        [TeamMsg::Localize { odometry_scale, .. }] => *odometry_scale,
        other => panic!("the database first, got {other:?}"),
    };
    assert_eq!(scale_sent(&mut mapped_parent()), 1.0, "no hop seen");

    let mut p = mapped_parent();
    // Six hops east along row 0 and back, seen at each image, the encoders counting
    // 1 / 0.96 of each 0.5 m.
    let xs = [0.25, 0.75, 1.25, 1.75, 1.25, 0.75, 0.25];
    for (k, x) in xs.iter().enumerate() {
        p.children[0].seq += 1;
        let seq = p.children[0].seq;
        p.children[0].task = super::super::Task::Grab {
            vertex: (0, 0),
            sent_ns: 0,
            fixes: ([2.0 * x, 0.5], 2),
        };
        let image = crate::localize::tests::room_view(k as u64 * S, *x, 0.25);
        p.handle_reply(
            0,
            TeamMsg::Grabbed {
                seq,
                vertex: (0, 0),
                heading_rad: 0.0,
                image,
                odometer_m: k as f64 * 0.5 / 0.96,
            },
        );
    }
    assert!((scale_sent(&mut p) - 0.96).abs() < 1e-9);
    let tour = p.team_report().tour.expect("sent");
    assert_eq!(tour.odometry_hops.len(), 6);
    // Each hop between consecutive images, by their stamps (the evaluation finds the child's
    // true positions by them).
    for (k, h) in tour.odometry_hops.iter().enumerate() {
        assert_eq!((h.from_ns, h.to_ns), (k as u64 * S, (k as u64 + 1) * S));
    }
    assert!((tour.odometry_scale - 0.96).abs() < 1e-9);
}
