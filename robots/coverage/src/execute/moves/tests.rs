//! Tests of the moves: robots get past each other, and every step is legal.

use super::*;

/// A run with robots placed by letter on a text map (`P` the parent, `k` children).
pub(in crate::execute) fn run_on<'a>(
    map: &'a Map,
    params: &'a CoverageParams,
    vis: &'a Visibility,
    rows: &[&str],
) -> Run<'a> {
    let mut parent = None;
    let mut kids = Vec::new();
    for (i, line) in rows.iter().enumerate() {
        let r = (rows.len() - 1 - i) as i64;
        for (c, ch) in line.chars().enumerate() {
            let v = map.at(c as i64, r).unwrap();
            match ch {
                'P' => parent = Some(v),
                'k' => kids.push(v),
                _ => {}
            }
        }
    }
    let mut pos = vec![parent.expect("a parent")];
    pos.extend(kids);
    Run {
        map,
        params,
        vis,
        pos,
        frames: Vec::new(),
        imaged: vec![false; map.len()],
        robot_steps: 0,
        stage: 0,
        backing_off: 0,
    }
}

/// Every frame moves exactly one robot one step onto a free vertex, and no two robots
/// ever share a vertex.
fn assert_legal(map: &Map, start: &[Vertex], frames: &[Frame]) {
    let mut prev = start.to_vec();
    for (t, f) in frames.iter().enumerate() {
        let moved: Vec<usize> = (0..prev.len())
            .filter(|&k| prev[k] != f.positions[k])
            .collect();
        assert_eq!(moved.len(), 1, "frame {t}: robots {moved:?} moved");
        let k = moved[0];
        assert!(map.adjacent(prev[k], f.positions[k]), "frame {t}: a jump");
        assert!(map.is_free(f.positions[k]));
        let mut sorted = f.positions.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(
            sorted.len(),
            f.positions.len(),
            "frame {t}: robots share a vertex"
        );
        prev = f.positions.clone();
    }
}

#[test]
fn the_parent_gets_to_the_end_of_a_dead_end_full_of_children() {
    // A one-cell corridor off a room, every vertex of it taken by a child; the parent
    // must stand at its far end.
    let rows = ["####.....", "kkkP.....", "####....."];
    let map = Map::from_text(&rows, 0.5);
    let params = CoverageParams::default();
    let vis = Visibility::compute(&map, &params);
    let mut run = run_on(&map, &params, &vis, &rows);
    let start = run.pos.clone();
    let end = map.at(0, 1).unwrap();
    run.drive_parent(end, Phase::Coordination, &|_| false)
        .unwrap();
    assert_eq!(run.pos[0], end);
    assert_legal(&map, &start, &run.frames);
}

#[test]
fn the_parent_stands_aside_to_let_a_dead_ends_child_out() {
    // The parent must stand on the tip of a one-vertex-wide dead end that holds a child.
    // The nearest vertex to back off to is the corridor's mouth, on the corridor itself:
    // the child could not get out past it. The parent must stand off the corridor and let
    // the child by.
    let rows = ["###.####", "#k.P....", "###.####"];
    let map = Map::from_text(&rows, 0.5);
    let params = CoverageParams::default();
    let vis = Visibility::compute(&map, &params);
    let mut run = run_on(&map, &params, &vis, &rows);
    let start = run.pos.clone();
    let tip = map.at(1, 1).unwrap();
    run.drive_parent(tip, Phase::Coordination, &|_| false)
        .unwrap();
    assert_eq!(run.pos[0], tip);
    assert_legal(&map, &start, &run.frames);
}

#[test]
fn a_child_gets_behind_a_parent_that_closes_a_dead_end() {
    // The parent stands in the mouth of a dead end; the vertex at its end can be reached
    // only through the parent's vertex. A child is let through, and the parent stands
    // where it was.
    let rows = ["#####....", "....P..k.", "#####...."];
    let map = Map::from_text(&rows, 0.5);
    let params = CoverageParams::default();
    let vis = Visibility::compute(&map, &params);
    let mut run = run_on(&map, &params, &vis, &rows);
    let start = run.pos.clone();
    let home = run.pos[0];
    let goal = map.at(1, 1).unwrap();
    let j = run
        .bring_child(Phase::Mapping, &|v| v == goal, &|_| true)
        .unwrap()
        .expect("a child gets there");
    assert_eq!(run.pos[j], goal);
    assert_eq!(run.pos[0], home);
    assert_legal(&map, &start, &run.frames);
}

#[test]
fn a_child_in_the_dead_end_behind_the_parent_comes_round_to_the_vertex_before_it() {
    // The child stands in the dead end behind the parent, and must get to the vertex just
    // east of the parent, which is on the parent's only way out and back: no stand lets
    // the child through and the parent back without crossing that vertex. The two trade
    // places out in the room at the corridor's far end, the parent comes back first, and
    // the child follows it in.
    let rows = ["#########...", "kP..........", "#########..."];
    let map = Map::from_text(&rows, 0.5);
    let params = CoverageParams {
        children: 1,
        ..CoverageParams::default()
    };
    let vis = Visibility::compute(&map, &params);
    let mut run = run_on(&map, &params, &vis, &rows);
    let start = run.pos.clone();
    let home = run.pos[0];
    let goal = map.at(2, 1).unwrap();
    let j = run
        .bring_child(Phase::Mapping, &|v| v == goal, &|_| true)
        .unwrap()
        .expect("the child gets there");
    assert_eq!(run.pos[j], goal);
    assert_eq!(run.pos[0], home);
    assert_legal(&map, &start, &run.frames);
    // In the corridor the two keep their order, so both must get off its line in the room:
    // the parent at least 9 steps out to a vertex beside the junction (9, 1) or beyond it,
    // the child 10 to another such vertex, then the parent 9 back and the child 8 to the
    // goal. 36 is the fewest steps that can do it, and the schedule takes no more.
    assert_eq!(run.frames.len(), 36);
}

#[test]
fn a_vertex_is_imaged_from_a_stand_that_sees_it_freely() {
    // The tip of a dead end, imaged looking north: the corridor's vertices see it freely
    // (a parent to the east is outside a north-looking view), the room's do not see it.
    // The parent drives to the nearest such stand and lets the child in past it.
    let rows = ["###......", "........P", "###...k.."];
    let map = Map::from_text(&rows, 0.5);
    let params = CoverageParams {
        children: 1,
        direction: crate::Direction::North,
        ..CoverageParams::default()
    };
    let vis = Visibility::compute(&map, &params);
    let mut run = run_on(&map, &params, &vis, &rows);
    let start = run.pos.clone();
    let tip = map.at(0, 1).unwrap();
    let j = run
        .bring_child_from_stand(Phase::Mapping, tip)
        .unwrap()
        .expect("a child gets there");
    assert_eq!(run.pos[j], tip);
    assert!(vis.los_free[run.pos[0]].binary_search(&tip).is_ok());
    assert_legal(&map, &start, &run.frames);
}
