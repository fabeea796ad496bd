//! The grab-time view check: the point version of the view test against the planner's, and
//! the parent driving a child back onto its vertex before a grab that would show it.

use super::super::{dist, Task};
use super::*;
use crate::visibility::in_view;
use crate::Direction;
use hetsim_msgs::pose_from_xyz_rpy;

fn params() -> CoverageParams {
    CoverageParams {
        r_los_m: 2.0,
        direction: Direction::East,
        child_fov_deg: 80.0,
        view_margin_deg: 10.0,
        view_margin_m: 0.04,
        parent_radius_m: 0.2,
        child_radius_m: 0.06,
        children: 2,
        f_factor: 2.0,
        views: crate::ViewRule::EveryGrab,
        reading: crate::Reading::Ours,
    }
}

/// At the vertices' centres, with the planner's disc, the two tests are one: the planner's
/// integer geometry is the point test's special case (every pair of free vertices on 30
/// random 12 x 12 maps, a quarter occupied, both robot sizes).
#[test]
fn at_vertex_centres_the_point_test_is_the_planner_s() {
    use rand::SeedableRng;
    let p = params();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let (mut shown, mut pairs) = (0, 0);
    for _ in 0..30 {
        let m = crate::map::random_map(&mut rng, 12, 0.25);
        let centre = |v: Vertex| {
            let (c, r) = m.cell(v);
            [c as f64 + 0.5, r as f64 + 0.5]
        };
        for &w in &m.vertices() {
            for &u in &m.vertices() {
                for radius in [p.child_radius_m, p.parent_radius_m] {
                    let disc = radius * std::f64::consts::SQRT_2 + p.view_margin_m;
                    let planner = in_view(&m, &p, w, u, radius);
                    let points = in_view_at(&m, &p, centre(w), centre(u), radius, disc);
                    assert_eq!(
                        planner,
                        points,
                        "{:?} sees {:?}, radius {radius}",
                        m.cell(w),
                        m.cell(u)
                    );
                    shown += usize::from(planner);
                    pairs += 1;
                }
            }
        }
    }
    // Both answers occur: the comparison is not between two constants.
    assert!(
        shown > pairs / 20 && shown < pairs / 2,
        "{shown} of {pairs} in view"
    );
}

/// A parent with two children on a free 5 x 3 m room of 0.5 m cells, planned.
fn planned_parent() -> ParentStack {
    let children = [("child1", (0, 0)), ("child2", (0, 5))];
    let mission = super::super::test_mission([10, 6], &[], &children, [0.25, 1.25, 0.0]);
    super::super::planned_test_parent(mission)
}

/// Timestep `t`'s grabs next: everyone on the vertices the plan has them on then, and the
/// timestep's moves done. Returns the first grabbing child and the other child.
fn before_grab(p: &mut ParentStack, t: usize) -> (usize, usize) {
    let plan = p.plan.as_ref().expect("planned");
    let positions = plan.frames[t].positions.clone();
    let grabber = plan.frames[t].grabs[0].0;
    p.step_index = t;
    p.moves_started = true;
    p.grabbing = false;
    p.recentres = 0;
    for (k, &v) in positions[1..].iter().enumerate() {
        let at = p.centre(v);
        p.children[k].planned = at;
        p.children[k].estimate = at;
    }
    let at = p.centre(positions[0]);
    p.pose = Some(pose_from_xyz_rpy([at[0], at[1], 0.0], [0.0; 3]));
    (grabber, 1 - grabber)
}

/// Where, 0.1 m from its vertex, the other child shows in the grabbing child's view (one
/// of eight directions).
fn into_view(p: &ParentStack, grabber: usize, other: usize) -> Option<[f64; 2]> {
    let home = p.children[other].planned;
    (0..8)
        .map(|k| k as f64 * std::f64::consts::FRAC_PI_4)
        .find_map(|a| {
            let at = [home[0] + 0.1 * a.cos(), home[1] + 0.1 * a.sin()];
            p.seen_in_view(p.children[grabber].estimate, at, p.mission.child_radius_m)
                .then_some(at)
        })
}

/// The plan's first grab where a 0.1 m offset of the other child enters the grabbing
/// child's view, set up as [`before_grab`]; returns the two children and that offset.
fn a_grab_a_small_offset_spoils(p: &mut ParentStack) -> (usize, usize, [f64; 2]) {
    let frames = p.plan.as_ref().expect("planned").frames.len();
    for t in 0..frames {
        if p.plan.as_ref().unwrap().frames[t].grabs.is_empty() {
            continue;
        }
        let (grabber, other) = before_grab(p, t);
        // On their vertices, the plan's views are clear.
        let grabs = p.plan.as_ref().unwrap().frames[t].grabs.clone();
        assert_eq!(p.views_to_clear(&grabs), (vec![], 0), "timestep {t}");
        if let Some(at) = into_view(p, grabber, other) {
            return (grabber, other, at);
        }
    }
    panic!("no grab of the plan is spoiled by a 0.1 m offset of the other child");
}

#[test]
fn a_child_off_its_vertex_in_a_grabbing_child_s_view_is_driven_back_before_the_grab() {
    let mut p = planned_parent();
    let (grabber, other, at) = a_grab_a_small_offset_spoils(&mut p);
    let grabs = p.plan.as_ref().unwrap().frames[p.step_index].grabs.clone();
    let home = p.children[other].planned;
    p.children[other].estimate = at;
    assert_eq!(p.views_to_clear(&grabs), (vec![other], 1));
    p.advance();
    // The other child is driven back to its vertex, and no grab is ordered yet.
    let Task::Move { goal, .. } = p.children[other].task else {
        panic!("{:?}", p.children[other].task)
    };
    assert!(dist(goal, home) < 1e-9, "driven to {goal:?}, not {home:?}");
    assert_eq!(p.children[grabber].task, Task::Idle);
    assert_eq!(p.report.view_recentres, 1);
    // Back on its vertex: the grab goes ahead, with nothing in view.
    p.children[other].estimate = p.children[other].planned;
    p.children[other].task = Task::Idle;
    p.children[other].acked = true;
    p.advance();
    assert!(matches!(p.children[grabber].task, Task::Grab { .. }));
    assert_eq!(p.report.grabs_with_tracked_robot_in_view, 0);
}

#[test]
fn a_child_that_stays_in_view_is_counted_and_the_grab_goes_ahead() {
    let mut p = planned_parent();
    let (grabber, other, at) = a_grab_a_small_offset_spoils(&mut p);
    p.children[other].estimate = at;
    // It never gets back: each round of driving ends with it where it was.
    for round in 0..RECENTRES {
        p.advance();
        assert!(
            matches!(p.children[other].task, Task::Move { .. }),
            "round {round}"
        );
        p.children[other].task = Task::Idle;
        p.children[other].acked = true;
    }
    p.advance();
    assert!(matches!(p.children[grabber].task, Task::Grab { .. }));
    assert_eq!(p.report.view_recentres, RECENTRES);
    assert_eq!(p.report.grabs_with_tracked_robot_in_view, 1);
}

/// The plan's first timestep with one grab, whose child has a free vertex two cells ahead of
/// it (east) that no robot stands on, set up as [`before_grab`]; returns the two children
/// and that vertex.
fn a_grab_with_a_free_vertex_ahead(p: &mut ParentStack) -> (usize, usize, Vertex) {
    let frames = p.plan.as_ref().expect("planned").frames.len();
    for t in 0..frames {
        let frame = &p.plan.as_ref().unwrap().frames[t];
        let &[(grabber, v)] = frame.grabs.as_slice() else {
            continue;
        };
        let positions = frame.positions.clone();
        let (c, r) = p.map.cell(v);
        let Some(ahead) = p.map.at(c as i64 + 2, r as i64) else {
            continue;
        };
        if !positions.contains(&ahead) {
            before_grab(p, t);
            return (grabber, 1 - grabber, ahead);
        }
    }
    panic!("no lone grab of the plan has a free vertex two cells ahead");
}

#[test]
fn a_child_in_view_on_its_vertex_too_is_counted_not_driven() {
    let mut p = planned_parent();
    let (grabber, other, ahead) = a_grab_with_a_free_vertex_ahead(&mut p);
    let grabs = p.plan.as_ref().unwrap().frames[p.step_index].grabs.clone();
    // The other child's vertex is 1 m straight ahead of the grabbing child's, so it is in
    // view on its vertex too (only the planner's margins could allow that); it stands 0.1 m
    // off it, still in view. Driving it back would not clear the view.
    let home = p.centre(ahead);
    p.children[other].planned = home;
    p.children[other].estimate = [home[0], home[1] + 0.1];
    assert!(p.seen_in_view(p.children[grabber].planned, home, p.mission.child_radius_m));
    assert_eq!(p.views_to_clear(&grabs), (vec![], 1));
    p.advance();
    assert!(matches!(p.children[grabber].task, Task::Grab { .. }));
    assert_eq!(p.children[other].task, Task::Idle);
    assert_eq!(p.report.view_recentres, 0);
    assert_eq!(p.report.grabs_with_tracked_robot_in_view, 1);
}

#[test]
fn the_parent_in_view_is_counted() {
    let mut p = planned_parent();
    let (grabber, _, ahead) = a_grab_with_a_free_vertex_ahead(&mut p);
    let grabs = p.plan.as_ref().unwrap().frames[p.step_index].grabs.clone();
    let from = p.children[grabber].estimate;
    // Where the plan has it, the parent is out of every grabbing child's view.
    assert_eq!(p.views_to_clear(&grabs), (vec![], 0));
    // The parent 1 m straight ahead of the grabbing child is counted (the children are
    // where the plan has them).
    let put_parent = |p: &mut ParentStack, at: [f64; 2]| {
        p.pose = Some(pose_from_xyz_rpy([at[0], at[1], 0.0], [0.0; 3]));
    };
    let in_front = p.centre(ahead);
    put_parent(&mut p, in_front);
    assert_eq!(p.views_to_clear(&grabs), (vec![], 1));
    // 1 m behind it (west), the camera looks away from it.
    put_parent(&mut p, [from[0] - 1.0, from[1]]);
    assert_eq!(p.views_to_clear(&grabs), (vec![], 0));
    // Ahead again: the grab is ordered at once, and counted.
    put_parent(&mut p, in_front);
    p.advance();
    assert!(matches!(p.children[grabber].task, Task::Grab { .. }));
    assert_eq!(p.report.view_recentres, 0);
    assert_eq!(p.report.grabs_with_tracked_robot_in_view, 1);
}
