//! Choosing the parent vertices V_p (Eqs. 5-7) and the order they are visited in.
//!
//! Decisions:
//! * `n(v)` is the number of free vertices among the 8 cells around `v` (0..=8), so the
//!   specific weight `w_s(v) = (9 - n(v))^2` ranges over 1..=81.
//! * Scores count only vertices still to be covered: after each choice, every vertex that
//!   became covered (or became a parent vertex) has its `w_s` removed from the score of every
//!   `v` whose LOS_free contains it. Otherwise the greedy choice would keep picking the same
//!   crowded area.
//! * Eq. 6 reads "for all v_p"; taken literally the candidate set is empty as soon as two
//!   chosen vertices are more than f apart. We read it as "within f of some chosen parent
//!   vertex", which keeps the growing cover contiguous as the text intends. Only candidates
//!   that would cover something new are considered; when none lies within f (a gap closed
//!   off by obstacles), the whole map is searched.
//! * Ties in the score go to the lowest vertex index (south-west first, row by row).
//! * n(v) counts every free vertex around v, so w_s(v) is fixed; only the sum of Eq. 5
//!   changes as vertices are covered. [`Reading::NUncovered`] counts the uncovered ones only,
//!   so a vertex's own weight grows as the vertices around it are covered.
//! * [`Reading`] names the other readings of Eq. 6 and of the ties, measured against these
//!   in `results/coverage-tables.md`.
//! * Vertices that no vertex's LOS_free contains cannot be imaged by any parent placement.
//!   They are not turned into parent vertices to make the loop end; selection stops when no
//!   candidate covers anything new, and they are reported as uncoverable.
//! * The tour is nearest neighbour by geodesic (4-connected step) distance, computed by a
//!   breadth-first distance transform from each parent vertex, starting from the parent
//!   vertex nearest to where the parent robot stands; ties to the lowest index. The robots
//!   step up, down, left or right and the roadmap graphs' vertices have at most 4 edges
//!   (Section IV), so the distances do too; [`Reading::Tour8Connected`] takes them over 8
//!   neighbours instead, to measure what the metric does.

use crate::map::{Map, Vertex};
use crate::visibility::Visibility;
use crate::{CoverageParams, Reading};

/// The greedy selection, in the order vertices were chosen, and the vertices it cannot
/// cover.
#[derive(Clone, Debug, PartialEq)]
pub struct Selection {
    /// V_p in selection order.
    pub chosen: Vec<Vertex>,
    /// Vertices of V that are neither parent vertices nor in any parent vertex's LOS_free.
    pub uncoverable: Vec<Vertex>,
}

/// Runs the greedy choice of parent vertices.
pub fn select_parent_vertices(map: &Map, vis: &Visibility, params: &CoverageParams) -> Selection {
    let vertices = map.vertices();
    let reading = params.reading;
    // n(v), and w_s(v) = (9 - n(v))^2 (Eq. 5). Under `NUncovered`, n(v) falls as the
    // vertices around v are covered, and w_s(v) grows with it.
    let mut n: Vec<u64> = (0..map.len())
        .map(|v| map.free_8_neighbours(v) as u64)
        .collect();
    let mut specific: Vec<u64> = n.iter().map(|&k| (9 - k).pow(2)).collect();
    // reverse[l]: the vertices v whose LOS_free contains l.
    let mut reverse: Vec<Vec<Vertex>> = vec![Vec::new(); map.len()];
    for &v in &vertices {
        for &l in &vis.los_free[v] {
            reverse[l].push(v);
        }
    }
    let mut score: Vec<u64> = vec![0; map.len()];
    for &v in &vertices {
        score[v] = vis.los_free[v].iter().map(|&l| specific[l]).sum();
    }
    let mut done = vec![false; map.len()]; // covered, or a parent vertex
    let mut is_parent = vec![false; map.len()];
    // Eq. 6's candidates: within f of some chosen parent vertex (of the last, or of every
    // one, in the other readings), counted as how many chosen ones are that near.
    let mut near = vec![0usize; map.len()];
    // Ties: the distance to the nearest chosen vertex (the last one, or any).
    let mut tie_m = vec![0.0f64; map.len()];
    let f = params.f_factor * params.r_los_m;
    let mut remaining = vertices.len();
    let mut chosen = Vec::new();
    let mut retire =
        |l: Vertex, done: &mut Vec<bool>, score: &mut Vec<u64>, remaining: &mut usize| {
            if done[l] {
                return;
            }
            done[l] = true;
            *remaining -= 1;
            for &v in &reverse[l] {
                score[v] -= specific[l];
            }
            if reading == Reading::NUncovered {
                // Each vertex around l has one uncovered neighbour fewer; where it is still
                // uncovered itself, the scores that count it grow by its new weight's increase.
                for u in map.free_8_around(l) {
                    n[u] -= 1;
                    let grown = (9 - n[u]).pow(2) - specific[u];
                    specific[u] += grown;
                    if !done[u] {
                        for &v in &reverse[u] {
                            score[v] += grown;
                        }
                    }
                }
            }
        };
    while remaining > 0 {
        let candidate = |v: Vertex| match reading {
            Reading::Eq6LastChoice => chosen
                .last()
                .is_some_and(|&p| map.distance_m(v, p) <= f + 1e-9),
            Reading::Eq6EveryChoice => near[v] == chosen.len(),
            _ => near[v] > 0,
        };
        let best = |restrict: bool| {
            vertices
                .iter()
                .copied()
                .filter(|&v| !is_parent[v] && score[v] > 0 && (!restrict || candidate(v)))
                .max_by(|&a, &b| {
                    score[a]
                        .cmp(&score[b])
                        .then(tie_m[b].total_cmp(&tie_m[a]))
                        .then(b.cmp(&a))
                })
        };
        let Some(p) = best(!chosen.is_empty()).or_else(|| best(false)) else {
            break;
        };
        is_parent[p] = true;
        chosen.push(p);
        retire(p, &mut done, &mut score, &mut remaining);
        for &l in &vis.los_free[p] {
            retire(l, &mut done, &mut score, &mut remaining);
        }
        let reach = (f / map.cell_m).floor() as i64;
        let (pc, pr) = map.cell(p);
        for dr in -reach..=reach {
            for dc in -reach..=reach {
                if let Some(v) = map.at(pc as i64 + dc, pr as i64 + dr) {
                    if map.distance_m(v, p) <= f + 1e-9 {
                        near[v] += 1;
                    }
                }
            }
        }
        match reading {
            Reading::TiesNearestLast => {
                for &v in &vertices {
                    tie_m[v] = map.distance_m(v, p);
                }
            }
            Reading::TiesNearestAny => {
                for &v in &vertices {
                    let d = map.distance_m(v, p);
                    tie_m[v] = if chosen.len() == 1 {
                        d
                    } else {
                        tie_m[v].min(d)
                    };
                }
            }
            _ => {}
        }
    }
    let uncoverable = vertices.into_iter().filter(|&v| !done[v]).collect();
    Selection {
        chosen,
        uncoverable,
    }
}

/// Orders parent vertices into a nearest-neighbour tour from the one geodesically nearest
/// to `start` (over 4 neighbours, or 8 under [`Reading::Tour8Connected`]; the same vertices
/// are reachable either way). Parent vertices that cannot be reached from `start` are left
/// out and returned second.
pub fn tour(
    map: &Map,
    chosen: &[Vertex],
    start: Vertex,
    reading: Reading,
) -> (Vec<Vertex>, Vec<Vertex>) {
    let mut left: Vec<Vertex> = chosen.to_vec();
    left.sort_unstable();
    let mut order = Vec::with_capacity(left.len());
    let mut here = start;
    loop {
        let dist = match reading {
            Reading::Tour8Connected => map.distances_8(here),
            _ => map.distances(here, |_| true),
        };
        let next = left
            .iter()
            .enumerate()
            .filter(|(_, &v)| dist[v] != usize::MAX)
            .min_by_key(|(_, &v)| (dist[v], v))
            .map(|(i, _)| i);
        let Some(i) = next else { break };
        here = left.remove(i);
        order.push(here);
    }
    (order, left)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Direction;

    #[test]
    fn an_open_room_is_covered_and_the_tour_visits_every_parent_vertex() {
        let rows: Vec<String> = (0..12).map(|_| ".".repeat(16)).collect();
        let refs: Vec<&str> = rows.iter().map(String::as_str).collect();
        let map = Map::from_text(&refs, 0.5);
        let params = CoverageParams {
            direction: Direction::East,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let sel = select_parent_vertices(&map, &vis, &params);
        assert!(sel.uncoverable.is_empty());
        let mut covered = vec![false; map.len()];
        for &p in &sel.chosen {
            covered[p] = true;
            for &l in &vis.los_free[p] {
                covered[l] = true;
            }
        }
        assert!(map.vertices().iter().all(|&v| covered[v]));
        // Each choice added something new.
        assert!(
            sel.chosen.len() < map.vertices().len() / 10,
            "{} parent vertices",
            sel.chosen.len()
        );
        let (order, unreachable) = tour(&map, &sel.chosen, 0, Reading::Ours);
        assert!(unreachable.is_empty());
        let mut sorted = order.clone();
        sorted.sort_unstable();
        let mut expected = sel.chosen.clone();
        expected.sort_unstable();
        assert_eq!(sorted, expected);
    }

    /// Each choice has the highest score among Eq. 6's candidates (the lowest index among
    /// equals), the scores recomputed from Eq. 5 at every step from what is still uncovered,
    /// not kept up to date as the selection does: with n(v) all free vertices around v, and
    /// under `n_uncovered` the uncovered ones only.
    #[test]
    fn each_choice_has_the_best_score_recomputed_from_eq_5() {
        let small = Map::from_text(
            &[
                "................",
                "...##......#....",
                "...##......#....",
                "...........#....",
                "......###.......",
                "................",
                ".#..........##..",
                ".#..............",
                "........#.......",
                "................",
            ],
            0.5,
        );
        // A larger cluttered room: each cell occupied with probability 0.19.
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(18);
        let cluttered = crate::map::random_map(&mut rng, 24, 0.19);
        for (map, reading) in [
            (&small, Reading::Ours),
            (&small, Reading::NUncovered),
            (&cluttered, Reading::Ours),
            (&cluttered, Reading::NUncovered),
        ] {
            let params = CoverageParams {
                reading,
                ..CoverageParams::default()
            };
            let vis = Visibility::compute(map, &params);
            let sel = select_parent_vertices(map, &vis, &params);
            let f = params.f_factor * params.r_los_m;
            let mut done = vec![false; map.len()];
            let weight = |l: Vertex, done: &[bool]| {
                let n = map
                    .free_8_around(l)
                    .filter(|&u| reading == Reading::Ours || !done[u])
                    .count() as u64;
                (9 - n).pow(2)
            };
            for (k, &p) in sel.chosen.iter().enumerate() {
                let score = |v: Vertex| -> u64 {
                    let free = vis.los_free[v].iter().filter(|&&l| !done[l]);
                    free.map(|&l| weight(l, &done)).sum()
                };
                let open = |v: &Vertex| !sel.chosen[..k].contains(v) && score(*v) > 0;
                let near = |v: &Vertex| {
                    k == 0
                        || sel.chosen[..k]
                            .iter()
                            .any(|&c| map.distance_m(*v, c) <= f + 1e-9)
                };
                let mut candidates: Vec<Vertex> = map
                    .vertices()
                    .into_iter()
                    .filter(|v| open(v) && near(v))
                    .collect();
                if candidates.is_empty() {
                    candidates = map.vertices().into_iter().filter(open).collect();
                }
                let best = candidates.iter().map(|&v| score(v)).max().unwrap();
                let first = candidates.iter().find(|&&v| score(v) == best).unwrap();
                assert_eq!((p, score(p)), (*first, best), "{reading:?}, choice {k}");
                done[p] = true;
                for &l in &vis.los_free[p] {
                    done[l] = true;
                }
            }
            let left: Vec<Vertex> = map.vertices().into_iter().filter(|&v| !done[v]).collect();
            assert_eq!(left, sel.uncoverable, "{reading:?}");
        }
    }

    #[test]
    fn a_vertex_nobody_can_see_is_reported() {
        // (0,1) is walled in on every side: no vertex has it in line of sight.
        let map = Map::from_text(&["##....", ".#....", "##...."], 0.5);
        let params = CoverageParams::default();
        let vis = Visibility::compute(&map, &params);
        let sel = select_parent_vertices(&map, &vis, &params);
        assert_eq!(sel.uncoverable, vec![map.at(0, 1).unwrap()]);
    }
}
