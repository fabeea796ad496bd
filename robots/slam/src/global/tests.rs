//! Tests of the team's global level: links, frames, partial rendezvous through anchors.

use super::*;
use crate::graph::exp;
use nalgebra::{Translation3, UnitQuaternion, Vector6};

fn step(x: f64, yaw: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

/// Two robots drive, each in its own frame; B's chain has a biased odometry, and B starts
/// turned by 172 degrees from A. A link from B's last origin to A's origin, known to B
/// and sent to A over the "radio" (a serialized share), places B in A's frame on both
/// robots' graphs and pulls B's end back; both graphs agree.
#[test]
fn a_link_places_the_other_robot_in_the_references_frame_and_corrects_its_drift() {
    let start_a = Isometry3::identity();
    let start_b = Isometry3::from_parts(
        Translation3::new(3.0, -2.0, 0.5),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 3.0),
    );
    let mut a = Global::new("a", "a", 0);
    let mut b = Global::new("b", "a", 0);
    let mut truth_b = start_b;
    let mut truth_a = vec![start_a];
    for k in 1..=10u64 {
        let z = step(2.0, 0.05);
        a.push(k * 1000, z, relative_info(0.01, 0.001));
        truth_a.push(truth_a.last().unwrap() * z);
        truth_b *= z;
        // B's odometry overestimates the distance by 5 % and turns 0.01 rad too much.
        let biased = step(2.1, 0.06);
        b.push(k * 1000, biased, relative_info(0.1, 0.01));
    }
    // Before any event B knows only its own frame: its first origin is the identity.
    assert_eq!(b.frame(), "b");
    assert_eq!(b.origin(0), Isometry3::identity());
    let in_b = start_b.inverse() * truth_b;
    let drift = (b.origin(10).translation.vector - in_b.translation.vector).norm();
    assert!(drift > 1.0, "B drifted {drift} m in its own frame");
    let own_chain = b.origin(0).inverse() * b.origin(10);
    let open_cov = b.own_covariances()[10];
    // B sees A's origin 4 from its last origin.
    let z = truth_b.inverse() * truth_a[4] * exp(&Vector6::new(0.01, -0.01, 0.0, 0.0, 0.0, 0.001));
    b.link(Link {
        kind: "image_match".into(),
        node: 10,
        other: "a".into(),
        other_stamp_ns: 4000,
        z,
        info: relative_info(0.05, 0.005),
    });
    assert_eq!(b.unresolved, 1, "A's origins are not known to B yet");
    assert_eq!(b.frame(), "b");
    // A hears of the link first: B's part arrives in B's frame and is moved into A's.
    a.receive(serde_json::from_slice(&serde_json::to_vec(&b.own).unwrap()).unwrap());
    a.optimize();
    let wire = serde_json::to_vec(&a.own).unwrap();
    b.receive(serde_json::from_slice(&wire).unwrap());
    assert_eq!(b.unresolved, 0);
    b.optimize();
    assert_eq!(b.frame(), "a");
    let after = (b.origin(10).translation.vector - truth_b.translation.vector).norm();
    assert!(
        after < drift / 4.0,
        "B's end error {drift:.3} -> {after:.3} m"
    );
    // B's start is found in A's frame, 172 degrees of yaw included, off by no more than
    // its chain's drift (one link closes no loop): 10 x 0.01 rad of yaw, and over its
    // 20 m at most 5 % + 0.1 rad of relative error, 3 m; and B's chain moved rigidly.
    let start = b.origin(0).inverse() * start_b;
    assert!(start.translation.vector.norm() < 3.0, "{start}");
    assert!(start.rotation.angle() < 0.12, "{start}");
    let chain = b.origin(0).inverse() * b.origin(10);
    assert!((chain.translation.vector - own_chain.translation.vector).norm() < 1e-3);
    let b_on_a = a.graph.nodes[a.len() + 10];
    assert!((b_on_a.translation.vector - b.origin(10).translation.vector).norm() < 1e-3);
    // A's own origins barely move (its chain is ten times more certain) and stay in its
    // own frame.
    assert_eq!(a.frame(), "a");
    assert_eq!(a.origin(0), Isometry3::identity());
    assert!((a.origin(10).translation.vector - truth_a[10].translation.vector).norm() < 0.1);
    // B's first origin is free now, and the marginal of its last shrank below the
    // open-loop one.
    let c = b.own_covariances();
    assert!(c[0][(0, 0)] > 0.0, "B's first origin is estimated");
    assert!(
        c[10][(0, 0)] + c[10][(1, 1)] < 0.1 * (open_cov[(0, 0)] + open_cov[(1, 1)]),
        "{}\n{open_cov}",
        c[10]
    );
}

/// A link to an origin the other robot never made stays unresolved instead of breaking
/// the graph.
#[test]
fn a_link_to_an_unknown_origin_is_kept_unresolved() {
    let mut a = Global::new("a", "a", 0);
    a.push(100, step(1.0, 0.0), relative_info(0.1, 0.01));
    let mut b = Global::new("b", "a", 0);
    b.link(Link {
        kind: "rendezvous".into(),
        node: 0,
        other: "a".into(),
        other_stamp_ns: 77,
        z: step(-5.0, 0.0),
        info: relative_info(0.1, 0.01),
    });
    b.receive(a.own.clone());
    assert_eq!(b.unresolved, 1);
    assert_eq!(b.graph.edges.len(), 1, "A's chain only");
    b.optimize();
    // Two components, each held at its own first origin; B stays in its own frame.
    assert_eq!(b.graph.anchors, vec![0, 1]);
    assert_eq!(b.frame(), "b");
    assert_eq!(b.origin(0), Isometry3::identity());
}

/// A partial rendezvous: A sees B at a frame where B started no sub-map. A's link names
/// B's frame at that stamp, which B does not hold as an origin, so it cannot resolve
/// until B, hearing of it, publishes that frame as an anchor (its pose in its sub-map);
/// then the link holds on both graphs and pulls B's drifted chain back.
#[test]
fn a_partial_rendezvous_resolves_through_the_seen_robots_anchor() {
    let start_b = Isometry3::from_parts(
        Translation3::new(1.0, 1.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
    );
    let mut a = Global::new("a", "a", 0);
    let mut b = Global::new("b", "a", 0);
    // The start: a full rendezvous at stamp 0 links the first origins.
    let z0 = start_b;
    a.link(Link {
        kind: "rendezvous".into(),
        node: 0,
        other: "b".into(),
        other_stamp_ns: 0,
        z: z0,
        info: relative_info(0.05, 0.005),
    });
    // B drives 10 sub-maps of 4 m with biased odometry (5 % long, 0.02 rad too much
    // turning); its frames between origins are kept as (origin, pose in it, covariance).
    let mut truth_b = start_b;
    let mut frames = Vec::new();
    for k in 1..=10u64 {
        let z = step(4.0, 0.1);
        let biased = step(4.2, 0.12);
        // A frame halfway through the sub-map, at stamp k * 1000 - 500.
        let half_true = truth_b * step(2.0, 0.05);
        let half_est = step(2.1, 0.06);
        frames.push((k * 1000 - 500, k as usize - 1, half_est, half_true));
        truth_b *= z;
        b.push(k * 1000, biased, relative_info(0.2, 0.02));
    }
    // A, at its origin, sees B at its frame of stamp 9500 (no origin of B's).
    let (stamp, node, half_est, half_true) = frames[9];
    let z = half_true;
    a.link(Link {
        kind: "rendezvous".into(),
        node: 0,
        other: "b".into(),
        other_stamp_ns: stamp,
        z,
        info: relative_info(0.05, 0.005),
    });
    let wire = |g: &Global| serde_json::from_slice(&serde_json::to_vec(&g.own).unwrap());
    b.receive(wire(&a).unwrap());
    b.optimize();
    assert_eq!(b.unresolved, 1, "B holds no origin at {stamp}");
    let at_frame = |g: &Global| g.origin(node) * half_est;
    let before = (at_frame(&b).translation.vector - half_true.translation.vector).norm();
    assert!(before > 1.0, "B drifted {before} m");
    assert_eq!(b.wanted_anchors(), vec![stamp]);
    b.anchor(Anchor {
        stamp_ns: stamp,
        node,
        pose: half_est,
        cov: Matrix6::from_diagonal_element(1e-4),
    });
    b.optimize();
    assert_eq!(b.unresolved, 0);
    assert!(b.wanted_anchors().is_empty());
    let after = (at_frame(&b).translation.vector - half_true.translation.vector).norm();
    assert!(
        after < 0.2,
        "B at the rendezvous frame: {before:.3} -> {after:.3} m"
    );
    // A resolves its link once B's part with the anchor arrives, and agrees.
    a.receive(wire(&b).unwrap());
    a.optimize();
    assert_eq!(a.unresolved, 0);
    let on_a = a.graph.nodes[a.len() + node] * half_est;
    assert!((on_a.translation.vector - at_frame(&b).translation.vector).norm() < 1e-3);
    // A part of an older version, without the anchors field, still reads.
    let mut old = serde_json::to_value(&a.own).unwrap();
    old.as_object_mut().unwrap().remove("anchors");
    let parsed: Share = serde_json::from_value(old).unwrap();
    assert!(parsed.anchors.is_empty() && parsed.links == a.own.links);
}

/// `through` composes the measurement and its covariance as a sampled check does.
#[test]
fn a_link_through_an_anchor_has_the_sampled_covariance() {
    use rand::{RngExt, SeedableRng};
    let z = Isometry3::from_parts(
        Translation3::new(2.0, -1.0, 0.5),
        UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
    );
    let a = Isometry3::from_parts(
        Translation3::new(-3.0, 4.0, 1.0),
        UnitQuaternion::from_euler_angles(0.0, 0.1, -1.2),
    );
    let cov_z = Matrix6::from_diagonal(&Vector6::new(0.04, 0.01, 0.02, 1e-4, 4e-4, 1e-4));
    let cov_a = Matrix6::from_diagonal(&Vector6::new(0.01, 0.03, 0.01, 2e-4, 1e-4, 3e-4));
    let (out, cov) = crate::graph::through(&z, &cov_z, &a, &cov_a);
    assert!((out.to_homogeneous() - (z * a.inverse()).to_homogeneous()).amax() < 1e-12);
    // Monte Carlo: 20000 draws of both perturbations, the empirical covariance of the
    // result's perturbation. Its sampling error is about sqrt(2 / N) = 1 % of each
    // variance; 5 % of the largest variance bounds every entry.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let lz = cov_z.cholesky().unwrap().l();
    let la = cov_a.cholesky().unwrap().l();
    let n = 20000;
    let mut acc = Matrix6::zeros();
    for _ in 0..n {
        let mut g = || {
            Vector6::from_fn(|_, _| {
                let (u, v): (f64, f64) = (rng.random(), rng.random());
                (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
            })
        };
        let (dz, da) = (lz * g(), la * g());
        let sample = z * exp(&dz) * (a * exp(&da)).inverse();
        let e = crate::graph::log(&(out.inverse() * sample));
        acc += e * e.transpose();
    }
    let empirical = acc / n as f64;
    let scale = cov.diagonal().amax();
    assert!(
        (empirical - cov).amax() < 0.05 * scale,
        "{empirical}\nvs\n{cov}"
    );
}
