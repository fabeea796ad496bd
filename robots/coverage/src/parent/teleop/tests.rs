//! When the parent expects to see a child: a hat behind an obstacle's edge is not a lost
//! child.

use super::*;
use crate::visibility::line_of_sight;
use hetsim_msgs::pose_from_xyz_rpy;
use hetsim_vision::hats::{HatFinder, Panorama};

/// A 5 x 3 m room of 0.5 m cells with one occupied cell, (5, 2): x 2.5-3.0 m, y 1.0-1.5 m.
/// The parent stands at (3.75, 1.75) with the lab's hat tracker (0.108 m hats), one child
/// at `child`.
fn parent_with_child_at(child: [f64; 2]) -> ParentStack {
    let mission =
        super::super::test_mission([10, 6], &[(5, 2)], &[("child1", (0, 0))], [3.75, 1.75, 0.0]);
    let mut p = super::super::planned_test_parent(mission);
    p.params.hat_tracker = Some(HatTracker {
        camera: "omni".into(),
        mount: [0.0; 3],
        finder: HatFinder {
            panorama: Panorama {
                width: 780,
                height: 580,
                elevation_rad: [(-75f64).to_radians(), 15f64.to_radians()],
            },
            camera_height_m: 1.45,
            hat_height_m: 0.124,
            min_pixels: 4,
            hat_size_m: [0.108; 2],
            hat_thickness_m: 0.024,
        },
        range_m: 2.0,
        gate_m: 0.3,
    });
    p.pose = Some(pose_from_xyz_rpy([3.75, 1.75, 0.0], [0.0; 3]));
    p.children[0].estimate = child;
    p
}

#[test]
fn a_child_whose_hat_an_obstacle_may_cut_is_not_expected_in_view() {
    // On its vertex, 1.5 m west: the sight lines to its hat, and to where it may drive in
    // half a second (0.151 m across the sight line), pass 0.12 m or more above the
    // obstacle's top edge.
    assert!(parent_with_child_at([2.25, 1.75]).expected_in_view(0));
    // 0.2 m south of it, on its way to the vertex below: its cell and the parent's still see
    // each other centre to centre (what the parent tested until 2026-11-29). The line to
    // its hat's south edge clears the obstacle by about 2 cm, but where the child may have
    // driven in the half second it may go unseen (0.075 m further at 0.15 m/s), it crosses
    // the obstacle, which would cut the hat.
    let p = parent_with_child_at([2.25, 1.55]);
    let vertex = |x: f64, y: f64| p.vertex_at([x, y]).unwrap();
    assert!(line_of_sight(
        &p.map,
        vertex(3.75, 1.75),
        vertex(2.25, 1.55)
    ));
    assert!(!p.expected_in_view(0));
    // North of the parent, nothing between: in view up to r_los less 0.15 m.
    assert!(parent_with_child_at([3.75, 2.75]).expected_in_view(0));
    assert!(!parent_with_child_at([1.75, 1.75]).expected_in_view(0));
}

#[test]
fn a_driving_child_is_expected_in_view_only_where_it_may_have_got_to() {
    // Last seen on its vertex 1.5 m west of the parent, in plain view, driving south
    // towards (2.25, 0.75), which the obstacle hides from the parent.
    let driving = |unseen_s: f64| {
        let mut p = parent_with_child_at([2.25, 1.75]);
        p.now_ns = 100_000_000_000;
        p.children[0].last_fix_ns = Some(p.now_ns - (unseen_s * 1e9) as u64);
        p.children[0].task = Task::Move {
            goal: [2.25, 0.75],
            reaimed: false,
            corrections: 0,
            due_ns: p.now_ns + 10_000_000_000,
            from: [2.25, 1.75],
            blind: false,
        };
        p
    };
    let hidden = |p: &ParentStack, at: [f64; 2]| !p.whole_hat_in_sight([3.75, 1.75], at);
    // Unseen for 0.1 s it has driven 0.015 m at 0.15 m/s: still in plain view.
    assert!(driving(0.1).expected_in_view(0));
    // Unseen for 3 s it may be 0.45 m on, at (2.25, 1.30), where the obstacle hides it
    // (the sight line to it passes x = 3.0 m at y = 1.525 m, 0.025 m above the obstacle's
    // corner, and enters its top edge at x = 2.92 m). The points across the sight line
    // (the hat's half-diagonal and half a second's drive) are cut from about 0.15 m on,
    // about a second's drive.
    let p = driving(3.0);
    assert!(!hidden(&p, [2.25, 1.75]));
    assert!(hidden(&p, [2.25, 1.30]));
    assert!(!p.expected_in_view(0));
    assert!(driving(0.8).expected_in_view(0));
    assert!(!driving(1.2).expected_in_view(0));
}
