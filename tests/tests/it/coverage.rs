//! Coverage-planning invariants on hundreds of seeded random maps from the indoor generator.

use hetsim_core::Streams;
use hetsim_coverage::select::select_parent_vertices;
use hetsim_coverage::{plan, validate, CoverageParams, Map, Plan, Reading, ViewRule, Visibility};
use hetsim_eval::coverage::plan_scenario;
use hetsim_eval::sweep::load_sweep;
use hetsim_scene::world::{generate_indoor, KeepClear};
use hetsim_scene::IndoorSpec;
use hetsim_tests::repo;

/// A random map from the indoor generator; `overlap`: obstacles may lie over each other.
fn random_map(size_m: f64, ratio: f64, overlap: bool, seed: u64) -> Map {
    let spec = IndoorSpec {
        width_m: size_m,
        height_m: size_m,
        obstruction_ratio: ratio,
        obstacles_overlap: overlap,
        ..IndoorSpec::default()
    };
    let world = generate_indoor(&spec, &Streams::new(seed), &KeepClear::default());
    Map::from_grid(&world.grid.unwrap().grid)
}

/// Fig. 3's 0 % map: 30 x 30 m with nothing on it, d = 0.5 m.
fn open_map() -> Map {
    let rows: Vec<String> = (0..60).map(|_| ".".repeat(60)).collect();
    let refs: Vec<&str> = rows.iter().map(String::as_str).collect();
    Map::from_text(&refs, 0.5)
}

/// The plan for `children` on the open map from its centre, validated and complete.
fn open_map_plan(children: usize, views: ViewRule) -> Plan {
    open_map_plan_reading(children, views, Reading::Ours)
}

/// [`open_map_plan`] under another reading of Section IV's open points.
fn open_map_plan_reading(children: usize, views: ViewRule, reading: Reading) -> Plan {
    let map = open_map();
    let params = CoverageParams {
        children,
        views,
        reading,
        ..CoverageParams::default()
    };
    let p = plan(&map, &params, centre_vertex(&map), &[]).unwrap();
    validate(&map, &params, &p).unwrap();
    assert_eq!(p.coverage(), 1.0);
    p
}

fn centre_vertex(map: &Map) -> usize {
    let (cc, cr) = (map.cols as f64 / 2.0, map.rows as f64 / 2.0);
    map.vertices()
        .into_iter()
        .min_by(|&a, &b| {
            let d = |v: usize| {
                let (c, r) = map.cell(v);
                (c as f64 - cc).hypot(r as f64 - cr)
            };
            d(a).total_cmp(&d(b)).then(a.cmp(&b))
        })
        .unwrap()
}

#[test]
fn invariants_hold_on_hundreds_of_random_maps() {
    let (mut maps, mut unreached, mut target, mut skipped) = (0, 0, 0, 0);
    let mut short = Vec::new();
    for seed in 0..100 {
        // The generator's obstacles apart, and at 40 % also merged over each other.
        for (ratio, overlap) in [(0.0, false), (0.2, false), (0.4, false), (0.4, true)] {
            let map = random_map(8.0, ratio, overlap, seed);
            let children = 1 + (seed as usize % 4);
            // Both view rules, each with every team size (children follow seed % 4).
            let views = if (seed / 4) % 2 == 0 {
                ViewRule::EveryGrab
            } else {
                ViewRule::StartPoints
            };
            let params = CoverageParams {
                children,
                views,
                ..CoverageParams::default()
            };
            let p = plan(&map, &params, centre_vertex(&map), &[]).unwrap_or_else(|e| {
                let rows: Vec<String> = (0..map.rows)
                    .rev()
                    .map(|r| {
                        (0..map.cols)
                            .map(|c| {
                                if map.is_free(map.at(c as i64, r as i64).unwrap()) {
                                    '.'
                                } else {
                                    '#'
                                }
                            })
                            .collect()
                    })
                    .collect();
                panic!(
                    "seed {seed} ratio {ratio} overlap {overlap} children {children} parent at {:?}: {e}\n{}",
                    map.cell(centre_vertex(&map)),
                    rows.join("\n")
                )
            });
            validate(&map, &params, &p).unwrap_or_else(|e| {
                panic!("seed {seed} ratio {ratio} overlap {overlap} children {children}: {e}")
            });
            // Whatever is reported uncoverable is so because no vertex sees it freely.
            let vis = Visibility::compute(&map, &params);
            for &u in &p.uncoverable {
                let seen = map
                    .vertices()
                    .iter()
                    .any(|&v| vis.los_free[v].binary_search(&u).is_ok());
                assert!(
                    !seen,
                    "seed {seed} ratio {ratio} overlap {overlap}: {:?} is visible yet was not imaged",
                    map.cell(u)
                );
            }
            if !p.unreached.is_empty() {
                short.push(format!(
                    "seed {seed} ratio {ratio} overlap {overlap} children {children}: {:?}",
                    p.unreached.iter().map(|&u| map.cell(u)).collect::<Vec<_>>()
                ));
            }
            unreached += p.unreached.len();
            skipped += p.skipped_stages.len();
            target += p.vertices - p.parent_vertices.len();
            maps += 1;
        }
    }
    assert_eq!(maps, 400);
    // Eq. 4 of seed 002 promises every vertex some reachable vertex sees freely, and
    // Section IV a stage at every parent vertex: on these cramped 8 x 8 m maps too (one-cell
    // corridors and dead ends at 40 %). Robots that could not pass each other left 416 of
    // 55816 vertices; the moves of `execute/moves.rs` left 4 (one map: a child in a dead
    // end had to come round the parent through the room beyond the corridor) until the
    // parent learned to let children out from behind it. With the obstacles merged, 1 (seed
    // 43, 4 children: children walled in a dead-end pocket ahead of a grabbing child) until
    // a failed after-tour try was made again once another vertex was imaged.
    eprintln!("{unreached} of {target} vertices unreached, {skipped} stages skipped");
    assert_eq!(skipped, 0, "stages skipped");
    assert_eq!(
        unreached,
        0,
        "{unreached} of {target} vertices unreached:\n{}",
        short.join("\n")
    );
}

/// An 8 x 8 m map at 40 % with merged obstacles (seed 43, 4 children). The last stage's
/// parent vertex (12, 15) stands at the mouth of a dead-end pocket and is the only vertex
/// that sees the pocket's first vertex (13, 15) freely; the children the parent pushed into
/// the pocket ahead of it stand in that vertex's view, walled in. Its first try after the
/// tour fails; the next vertex's try lets the children out and brings one in alone, and
/// the second try then images it. (Tried once only, it was left unreached.)
#[test]
fn a_vertex_whose_try_failed_is_tried_again_when_the_team_stands_otherwise() {
    let map = random_map(8.0, 0.4, true, 43);
    let params = CoverageParams {
        children: 4,
        ..CoverageParams::default()
    };
    let vis = Visibility::compute(&map, &params);
    let c = map.at(13, 15).unwrap();
    let stands: Vec<(usize, usize)> = map
        .vertices()
        .into_iter()
        .filter(|&w| vis.los_free[w].binary_search(&c).is_ok())
        .map(|w| map.cell(w))
        .collect();
    assert_eq!(stands, vec![(12, 15)], "the map this test was written for");
    let p = plan(&map, &params, centre_vertex(&map), &[]).unwrap();
    validate(&map, &params, &p).unwrap();
    assert!(p.revisited.contains(&c), "{:?}", map.cell(c));
    assert_eq!(p.unreached, Vec::<usize>::new());
}

/// Table I's 40 % maps with 2 and 3 children (`scenarios/sweeps/table1.toml`'s cells),
/// where five stages of four runs were once skipped: the parent could not get past a child
/// standing in a one-vertex-wide dead end. Section IV promises a stage at every parent
/// vertex, and Eq. 4 every vertex some vertex sees freely.
#[test]
fn no_stage_is_skipped_on_table_one_s_most_obstructed_maps() {
    // The committed sweep itself, its cells at 40 % with 2 and 3 children.
    let sweep = load_sweep(&repo().join("scenarios/sweeps/table1.toml")).unwrap();
    let axis = |name: &str| sweep.file.axes.keys().position(|k| k == name).unwrap();
    let (ratio, children) = (
        axis("world.indoor.obstruction_ratio"),
        axis("coverage.children"),
    );
    let crowded: Vec<_> = sweep
        .runs
        .iter()
        .filter(|run| {
            run.values[ratio].as_float() == Some(0.4)
                && matches!(run.values[children].as_integer(), Some(2 | 3))
        })
        .collect();
    assert_eq!(crowded.len(), 20);
    for run in crowded {
        let scenario = sweep.scenario(run).unwrap();
        let (_, params, plan) = plan_scenario(&scenario).unwrap();
        let what = format!("seed {}, {} children", run.seed, params.children);
        assert_eq!(plan.skipped_stages, Vec::<usize>::new(), "{what}");
        assert_eq!(plan.coverable_coverage(), 1.0, "{what}");
    }
}

/// Table II's seed 7 at r_los = 1 m: with the team moving around the parent (2026-11-28),
/// five to eight children ended the tour with two of them walled into a pocket in the view
/// of the last vertex to revisit, by the parent's stand and the grabbing child; the next
/// stand lets them out, and every vertex some vertex sees freely is imaged.
#[test]
fn a_view_walled_in_by_the_parent_s_stand_is_cleared_from_another_stand() {
    let sweep = load_sweep(&repo().join("scenarios/sweeps/table2.toml")).unwrap();
    let axis = |name: &str| sweep.file.axes.keys().position(|k| k == name).unwrap();
    let (r_los, children) = (axis("coverage.r_los_m"), axis("coverage.children"));
    let runs: Vec<_> = sweep
        .runs
        .iter()
        .filter(|run| {
            run.seed == 7
                && run.values[r_los].as_float() == Some(1.0)
                && matches!(run.values[children].as_integer(), Some(5..=8))
        })
        .collect();
    assert_eq!(runs.len(), 4);
    for run in runs {
        let scenario = sweep.scenario(run).unwrap();
        let (_, params, plan) = plan_scenario(&scenario).unwrap();
        let what = format!("{} children", params.children);
        assert_eq!(plan.skipped_stages, Vec::<usize>::new(), "{what}");
        assert_eq!(plan.unreached, Vec::<usize>::new(), "{what}");
        assert_eq!(plan.coverable_coverage(), 1.0, "{what}");
    }
}

#[test]
fn a_full_size_map_is_covered_and_the_plan_is_reproducible() {
    let map = random_map(30.0, 0.2, false, 11);
    let params = CoverageParams::default();
    let a = plan(&map, &params, centre_vertex(&map), &[]).unwrap();
    validate(&map, &params, &a).unwrap();
    assert!(a.coverage() > 0.99, "coverage {}", a.coverage());
    let b = plan(&map, &params, centre_vertex(&map), &[]).unwrap();
    assert_eq!(a, b);
    eprintln!(
        "|V| {} |V_p| {} mapping {} coordination {} following {}",
        a.vertices,
        a.parent_vertices.len(),
        a.mapping_timesteps,
        a.coordination_timesteps,
        a.following_behaviours
    );
}

/// Fig. 3 of seed 002 on its open 30 x 30 m map with only the starting points kept out of
/// each other's views (`views = "start_points"`, Section IV.C's rule for them): with no
/// waits for clear views at the grabs, the children's parallel walks share every stage, so
/// each child added lowers the mapping timesteps, as the paper says they "generally
/// decrease due to the parallel task execution", from 1 to 8 children.
#[test]
fn with_only_the_starting_points_checked_every_child_added_maps_faster() {
    let mapping: Vec<usize> = (1..=8)
        .map(|children| open_map_plan(children, ViewRule::StartPoints).mapping_timesteps)
        .collect();
    eprintln!("mapping timesteps for 1..=8 children: {mapping:?}");
    assert!(mapping.windows(2).all(|w| w[1] < w[0]), "{mapping:?}");
}

/// Fig. 3 of seed 002, its open 30 x 30 m map (the 0 % panel, the one map the paper and we
/// share): "by deploying more child robots, the mapping timesteps generally decrease due to
/// the parallel task execution. By contrast, the coordination timesteps grow". Under the
/// paper's view rule (no robot in view at any grab), mapping falls from 1 to 2 to 4
/// children (with 8 it rises again: `results/coverage-tables.md`), coordination grows from
/// 1 to 8, and more than one child gives the shortest mission.
#[test]
fn up_to_four_children_map_faster_and_eight_take_longer_to_coordinate() {
    let runs: Vec<(usize, usize, usize)> = [1, 2, 4, 8]
        .into_iter()
        .map(|children| {
            let p = open_map_plan(children, ViewRule::EveryGrab);
            (children, p.mapping_timesteps, p.coordination_timesteps)
        })
        .collect();
    eprintln!("(children, mapping, coordination): {runs:?}");
    let (mapping, coordination): (Vec<usize>, Vec<usize>) =
        runs.iter().map(|&(_, m, c)| (m, c)).unzip();
    assert!(
        mapping[1] < mapping[0] && mapping[2] < mapping[1],
        "{runs:?}"
    );
    assert!(coordination[3] > coordination[0], "{runs:?}");
    let best = runs.iter().min_by_key(|&&(_, m, c)| m + c).unwrap().0;
    assert!(best > 1, "{runs:?}");
}

/// Each reading's name gives the reading back: `[coverage] reading` is checked with these names.
#[test]
fn each_reading_is_found_by_its_name() {
    // The shipped reading first: reports take the others as `Reading::ALL[1..]`.
    assert_eq!(Reading::ALL[0], Reading::Ours);
    for r in Reading::ALL {
        assert_eq!(Reading::from_name(r.name()), Some(r));
    }
}

/// H from LOS_free (`h_from_los_free`) is a subset of Eq. 8's H, since LOS_free(v) is a
/// subset of LOS(v): a transition with fewer than N vertices in Eq. 8's H has fewer in it
/// too, so on the open map (where no child is ever unable to get to H, docs/coverage-planning.md) it makes at
/// least as many following behaviours for every N. The tour does not depend on N or on H.
/// With 8 children, strictly more (a check that the reading is wired in): a transition east
/// loses from H the vertices in the 80 deg wedge west of v_p^(t+1), up to 10 of them (the
/// visibility test), which lie between the two parent vertices.
#[test]
fn h_from_los_free_follows_at_least_as_often_as_eq_8() {
    for children in [1, 4, 8] {
        let ours = open_map_plan(children, ViewRule::EveryGrab);
        let free = open_map_plan_reading(children, ViewRule::EveryGrab, Reading::HFromLosFree);
        assert_eq!(ours.parent_vertices, free.parent_vertices);
        assert_eq!(ours.following_out_of_reach, 0);
        assert!(
            free.following_behaviours >= ours.following_behaviours,
            "{children} children: {} against {}",
            free.following_behaviours,
            ours.following_behaviours
        );
        if children == 8 {
            assert!(free.following_behaviours > ours.following_behaviours);
        }
    }
}

/// The readings of Eq. 6 and of the ties change the greedy choice itself (on the open map,
/// where every score ties with its mirror images), and the choice still covers every vertex.
#[test]
fn the_readings_of_eq_6_and_of_the_ties_change_the_choice() {
    let map = open_map();
    let choose = |reading| {
        let params = CoverageParams {
            reading,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let sel = select_parent_vertices(&map, &vis, &params);
        assert!(sel.uncoverable.is_empty(), "{reading:?}");
        sel.chosen
    };
    let ours = choose(Reading::Ours);
    for reading in [
        Reading::Eq6LastChoice,
        Reading::Eq6EveryChoice,
        Reading::TiesNearestLast,
        Reading::TiesNearestAny,
    ] {
        assert_ne!(choose(reading), ours, "{reading:?}");
    }
}

/// Under `tour_8_connected` the tour visits the same parent vertices in another order (a
/// wiring check), and each step, the first from the parent's start included, goes to a
/// nearest remaining parent vertex by the open map's 8-neighbour distance, which there is
/// the chessboard distance max(|dx|, |dy|).
#[test]
fn the_8_connected_tour_steps_to_a_nearest_vertex_by_chessboard_distance() {
    let ours = open_map_plan(1, ViewRule::EveryGrab);
    let eight = open_map_plan_reading(1, ViewRule::EveryGrab, Reading::Tour8Connected);
    let (mut a, mut b) = (ours.parent_vertices.clone(), eight.parent_vertices.clone());
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b);
    assert_ne!(ours.parent_vertices, eight.parent_vertices);
    let map = open_map();
    let chessboard = |u: usize, v: usize| {
        let ((uc, ur), (vc, vr)) = (map.cell(u), map.cell(v));
        uc.abs_diff(vc).max(ur.abs_diff(vr))
    };
    let order = &eight.parent_vertices;
    for k in 0..order.len() {
        let from = if k == 0 {
            centre_vertex(&map)
        } else {
            order[k - 1]
        };
        let nearest = order[k..].iter().map(|&v| chessboard(from, v)).min();
        assert_eq!(Some(chessboard(from, order[k])), nearest, "step {k}");
    }
}
