//! Child roadmap graphs of one stage (Section IV.C, Fig. 2).
//!
//! For the child vertices C of a stage, with the parent standing on `v_p`:
//! * **Start points** are taken from C against the direction of mapping (sorted by their
//!   coordinate along it, then across it), skipping any candidate that would be in the view
//!   of an accepted start or have one in its own view, so that no start obstructs another.
//! * **Goal points** lie in C no further back than their start along the direction of
//!   mapping; the first is the most advanced, each next one maximises its smallest distance
//!   to the goals already chosen (spread). The goals are then paired with the starts in the
//!   same order across the direction of mapping (where each stays ahead of its start): the
//!   spread puts the second goal far from the first, often across the stage from its start,
//!   and paths that swap sides cross, putting the children in each other's way and views.
//!   Pairing in order removes such crossings, though paths can still cross (a start far
//!   behind another, obstacles). Measured effect: docs/coverage-planning.md, "Mapping with many children".
//! * **Paths** are shortest 4-connected paths from start to goal through the parent's line
//!   of sight LOS(v_p) (where the parent can track a child), never through `v_p`; through
//!   any free vertex only if LOS(v_p) does not connect them.
//! * **Extension** until C is covered, the graphs growing in parallel in time: each step
//!   grows the graph of the child whose walk (the way from where it stands to its start,
//!   then its graph) is shortest among those that can grow, so that a child with a long way
//!   to its start takes fewer vertices (a graph hemmed in by others' cannot grow, so the
//!   walks need not end together; the executor ends a round when the first child is idle
//!   and builds new roadmaps for the rest). The graph grown *hills* if it can: an edge `a -> b`
//!   becomes `a -> a' -> b' -> b` where `a'`, `b'` are uncovered child vertices beside it;
//!   otherwise it *branches out* to an uncovered neighbour `c` of a vertex `u` of its graph
//!   (`u -> c -> u`), which later hilling widens. When no graph can grow, the first
//!   uncovered child vertex (in the order C is given) is reached by the shortest detour out
//!   and back from the nearest graph vertex, through LOS(v_p); one no detour reaches is
//!   `unreachable`. (Before 2026-11-27 every graph that could hill did so once per turn,
//!   whatever its length, and a graph branched out only when no graph could hill; in
//!   commit d43f3dd the shortest graph that could hill did. Measured effects: docs/coverage-planning.md,
//!   "Mapping with many children".)
//! * Children not given a start point (fewer starts than children) stay where they are.
//! * A child's walk begins where it stands, goes to its start point, then follows its graph.

use crate::map::{Map, Vertex};
use crate::visibility::in_view;
use crate::CoverageParams;

/// The walks of all children for one stage, and the child vertices no walk can reach.
#[derive(Clone, Debug, PartialEq)]
pub struct StageRoadmaps {
    /// `walks[j]` starts at child `j`'s position; consecutive vertices are adjacent.
    pub walks: Vec<Vec<Vertex>>,
    /// Child vertices no walk reaches.
    pub unreachable: Vec<Vertex>,
}

fn along(map: &Map, params: &CoverageParams, v: Vertex) -> (i64, i64) {
    let (c, r) = map.cell(v);
    let (dx, dy) = params.direction.step();
    (
        dx * c as i64 + dy * r as i64,
        -dy * c as i64 + dx * r as i64,
    )
}

/// Builds the walks of one stage.
pub fn stage_roadmaps(
    map: &Map,
    params: &CoverageParams,
    los_parent: &[bool],
    parent: Vertex,
    children: &[Vertex],
    child_set: &[Vertex],
) -> StageRoadmaps {
    let stage = Stage::new(map, params, los_parent, parent, children, child_set);
    let starts = stage.start_points();
    let owner = stage.assign_starts(&starts);
    let goals = stage.spread_goals(&starts);
    let goals = pair_across(map, params, &starts, goals);
    let (mut routes, mut covered) = stage.initial_routes(&starts, &goals);
    // Steps each child needs to get to its start point: the graphs grow "in parallel" in
    // time, so the child whose walk (approach and graph) is shortest grows first.
    // Each owned start's way from its child, found once: it orders the growth and begins
    // the child's walk.
    let approaches = stage.approaches(&starts, &owner);
    let approach: Vec<usize> = approaches
        .iter()
        .map(|p| p.as_ref().map_or(usize::MAX / 2, |p| p.len() - 1))
        .collect();
    let mut unreachable = stage.extend(&mut routes, &approach, &mut covered);
    let walks = stage.walks(routes, &owner, approaches);
    stage.add_untouched(&walks, &mut unreachable);
    unreachable.sort_unstable();
    StageRoadmaps { walks, unreachable }
}

/// One stage's child vertices, the children and the parent standing among them: what its
/// walks are built from.
struct Stage<'a> {
    map: &'a Map,
    params: &'a CoverageParams,
    /// `los_parent[v]`: the parent standing on `parent` has `v` in its line of sight.
    los_parent: &'a [bool],
    parent: Vertex,
    /// Where the children stand.
    children: &'a [Vertex],
    /// The child vertices C.
    child_set: &'a [Vertex],
    /// `in_set[v]`: `v` is in `child_set`.
    in_set: Vec<bool>,
}

impl<'a> Stage<'a> {
    /// The stage of [`stage_roadmaps`]' arguments, with its child set marked.
    fn new(
        map: &'a Map,
        params: &'a CoverageParams,
        los_parent: &'a [bool],
        parent: Vertex,
        children: &'a [Vertex],
        child_set: &'a [Vertex],
    ) -> Self {
        let in_set = {
            let mut s = vec![false; map.len()];
            for &c in child_set {
                s[c] = true;
            }
            s
        };
        Self {
            map,
            params,
            los_parent,
            parent,
            children,
            child_set,
            in_set,
        }
    }

    /// Whether a path may go through `v` where the parent can track it: in its line of
    /// sight, never its vertex.
    fn region(&self, v: Vertex) -> bool {
        v != self.parent && self.los_parent[v]
    }

    /// Whether a path may go through `v` at all: anywhere but the parent's vertex.
    fn anywhere(&self, v: Vertex) -> bool {
        v != self.parent
    }

    /// A shortest path from `from` to `to` through [`Self::region`], else through
    /// [`Self::anywhere`].
    fn path(&self, from: Vertex, to: Vertex) -> Option<Vec<Vertex>> {
        self.map
            .path_to(from, |v| v == to, |v| self.region(v))
            .or_else(|| self.map.path_to(from, |v| v == to, |v| self.anywhere(v)))
    }

    /// Whether some child vertex is not covered yet.
    fn uncovered(&self, covered: &[bool]) -> bool {
        self.child_set.iter().any(|&c| !covered[c])
    }

    /// Whether a graph may grow onto `v`: an uncovered child vertex, not the parent's.
    fn open(&self, v: Vertex, covered: &[bool]) -> bool {
        self.in_set[v] && !covered[v] && v != self.parent
    }

    /// Picks the start points: one per child at most, none in another's view.
    fn start_points(&self) -> Vec<Vertex> {
        let (map, params, children) = (self.map, self.params, self.children);
        // Start points, against the direction of mapping.
        let mut candidates = self.child_set.to_vec();
        candidates.sort_by_key(|&v| (along(map, params, v), v));
        let mut starts: Vec<Vertex> = Vec::new();
        for &s in &candidates {
            if starts.len() == params.children.min(children.len()) {
                break;
            }
            let clear = starts.iter().all(|&o| {
                !in_view(map, params, s, o, params.child_radius_m)
                    && !in_view(map, params, o, s, params.child_radius_m)
            });
            if clear {
                starts.push(s);
            }
        }
        starts
    }

    /// The child owning each start (`None`: no child was left for it).
    fn assign_starts(&self, starts: &[Vertex]) -> Vec<Option<usize>> {
        let (map, children) = (self.map, self.children);
        // Assign starts to children: each start, in order, to the nearest free child.
        let mut owner: Vec<Option<usize>> = vec![None; starts.len()];
        let mut taken = vec![false; children.len()];
        for (k, &s) in starts.iter().enumerate() {
            let dist = map.distances_until(s, |v| self.anywhere(v), children);
            if let Some(j) = (0..children.len())
                .filter(|&j| !taken[j])
                .min_by_key(|&j| (dist[children[j]], j))
            {
                taken[j] = true;
                owner[k] = Some(j);
            }
        }
        owner
    }

    /// Picks a goal for each start, ahead of it and spread out (not yet paired across).
    fn spread_goals(&self, starts: &[Vertex]) -> Vec<Vertex> {
        let (map, params, child_set) = (self.map, self.params, self.child_set);
        // Goals, in the direction of mapping, spread out.
        let mut goals: Vec<Vertex> = Vec::new();
        for &s in starts {
            let ahead: Vec<Vertex> = child_set
                .iter()
                .copied()
                .filter(|&g| {
                    along(map, params, g).0 >= along(map, params, s).0 && !goals.contains(&g)
                })
                .collect();
            let goal = if goals.is_empty() {
                ahead
                    .iter()
                    .copied()
                    .max_by_key(|&g| (along(map, params, g).0, std::cmp::Reverse(g)))
            } else {
                ahead.iter().copied().max_by(|&a, &b| {
                    let spread = |g: Vertex| {
                        goals
                            .iter()
                            .map(|&o| map.distance_m(g, o))
                            .fold(f64::INFINITY, f64::min)
                    };
                    spread(a).total_cmp(&spread(b)).then(b.cmp(&a))
                })
            };
            goals.push(goal.unwrap_or(s));
        }
        goals
    }

    /// The initial graphs, start -> goal, and the vertices they cover.
    fn initial_routes(&self, starts: &[Vertex], goals: &[Vertex]) -> (Vec<Vec<Vertex>>, Vec<bool>) {
        // Initial graphs: start -> goal.
        let mut covered = vec![false; self.map.len()];
        let mut routes: Vec<Vec<Vertex>> = Vec::new();
        for (k, &s) in starts.iter().enumerate() {
            let route = self.path(s, goals[k]).unwrap_or_else(|| vec![s]);
            for &v in &route {
                covered[v] = true;
            }
            routes.push(route);
        }
        (routes, covered)
    }

    /// Each start's way from the child owning it (`None`: no owner, or no way).
    fn approaches(&self, starts: &[Vertex], owner: &[Option<usize>]) -> Vec<Option<Vec<Vertex>>> {
        starts
            .iter()
            .enumerate()
            .map(|(k, &s)| owner[k].and_then(|j| self.path(self.children[j], s)))
            .collect()
    }

    /// Extends the graphs until the child set is covered, one growth or detour at a time;
    /// returns the child vertices no detour reaches.
    fn extend(
        &self,
        routes: &mut [Vec<Vertex>],
        approach: &[usize],
        covered: &mut [bool],
    ) -> Vec<Vertex> {
        let mut unreachable = Vec::new();
        while !routes.is_empty() && self.uncovered(covered) {
            if let Some((k, i, new)) = self.growth(routes, approach, covered) {
                for &v in &new {
                    covered[v] = true;
                }
                routes[k].splice(i + 1..i + 1, new);
                continue;
            }
            self.detour(routes, covered, &mut unreachable);
        }
        unreachable
    }

    /// The growth of the shortest walk that can grow: the route, the index of the vertex
    /// to insert after and the vertices to insert.
    fn growth(
        &self,
        routes: &[Vec<Vertex>],
        approach: &[usize],
        covered: &[bool],
    ) -> Option<(usize, usize, Vec<Vertex>)> {
        let map = self.map;
        let mut order: Vec<usize> = (0..routes.len()).collect();
        order.sort_by_key(|&k| (approach[k] + routes[k].len(), k));
        // The shortest walk that can grow hills if it can, else branches out to a
        // neighbour.
        order.iter().find_map(|&k| {
            if let Some((i, a2, b2)) = hill(map, &routes[k], |v| self.open(v, covered)) {
                return Some((k, i, vec![a2, b2]));
            }
            routes[k].iter().enumerate().find_map(|(i, &u)| {
                map.neighbours(u)
                    .find(|&c| self.open(c, covered))
                    .map(|c| (k, i, vec![c, u]))
            })
        })
    }

    /// Covers the first uncovered child vertex by a detour out and back from the nearest
    /// graph vertex, or adds it to `unreachable` if no detour reaches it.
    fn detour(
        &self,
        routes: &mut [Vec<Vertex>],
        covered: &mut [bool],
        unreachable: &mut Vec<Vertex>,
    ) {
        let map = self.map;
        let region = |v: Vertex| self.region(v);
        // A detour out and back to the first uncovered child vertex, from the nearest
        // graph vertex.
        let target = self
            .child_set
            .iter()
            .copied()
            .find(|&c| !covered[c])
            .expect("some vertex is uncovered");
        let dist = map.distances(target, region);
        let best = routes
            .iter()
            .enumerate()
            .flat_map(|(k, r)| r.iter().enumerate().map(move |(i, &u)| (k, i, u)))
            .filter(|&(_, _, u)| dist[u] != usize::MAX)
            .min_by_key(|&(k, i, u)| (dist[u], k, i));
        match best.and_then(|(k, i, u)| map.path_to(u, |v| v == target, region).map(|p| (k, i, p)))
        {
            Some((k, i, p)) => {
                let mut detour: Vec<Vertex> = p[1..].to_vec();
                detour.extend(p[..p.len() - 1].iter().rev());
                for &v in &detour {
                    covered[v] = true;
                }
                routes[k].splice(i + 1..i + 1, detour);
            }
            None => {
                covered[target] = true;
                unreachable.push(target);
            }
        }
    }

    /// Each child's walk: its way to its start point, then its graph; a child with neither
    /// stays where it is.
    fn walks(
        &self,
        routes: Vec<Vec<Vertex>>,
        owner: &[Option<usize>],
        mut approaches: Vec<Option<Vec<Vertex>>>,
    ) -> Vec<Vec<Vertex>> {
        let mut walks: Vec<Vec<Vertex>> = self.children.iter().map(|&c| vec![c]).collect();
        for (k, route) in routes.into_iter().enumerate() {
            // A child cut off from its start point (the parent stands in the way) gets no graph;
            // the vertices only that graph touched are left to the mop-up.
            // (Growth inserts after a route's first vertex, so route[0] is still its start.)
            if let (Some(j), Some(mut walk)) = (owner[k], approaches[k].take()) {
                walk.extend(route.into_iter().skip(1));
                walks[j] = walk;
            }
        }
        walks
    }

    /// Adds to `unreachable` the child vertices no walk touches.
    fn add_untouched(&self, walks: &[Vec<Vertex>], unreachable: &mut Vec<Vertex>) {
        // Anything in C left untouched by every walk (no start could be placed) is unreachable.
        let mut touched = vec![false; self.map.len()];
        for w in walks {
            for &v in w {
                touched[v] = true;
            }
        }
        for &c in self.child_set {
            if !touched[c] && !unreachable.contains(&c) {
                unreachable.push(c);
            }
        }
    }
}

/// `goals` (one per start) paired with `starts` in the same order across the direction of
/// mapping, so that no two paths swap sides; `goals` as given if that would put a goal
/// behind its start along the direction of mapping.
fn pair_across(
    map: &Map,
    params: &CoverageParams,
    starts: &[Vertex],
    goals: Vec<Vertex>,
) -> Vec<Vertex> {
    debug_assert_eq!(starts.len(), goals.len());
    let mut starts_across: Vec<usize> = (0..starts.len()).collect();
    starts_across.sort_by_key(|&k| (along(map, params, starts[k]).1, k));
    let mut goals_across = goals.clone();
    goals_across.sort_by_key(|&g| (along(map, params, g).1, g));
    let mut paired = goals.clone();
    for (&k, &g) in starts_across.iter().zip(&goals_across) {
        paired[k] = g;
    }
    let ahead = |k: usize| along(map, params, paired[k]).0 >= along(map, params, starts[k]).0;
    if (0..starts.len()).all(ahead) {
        paired
    } else {
        goals
    }
}

/// The first edge `a -> b` of `route` with two open vertices `a'`, `b'` beside it (left
/// side first): returns the edge's index and `a'`, `b'`.
fn hill(
    map: &Map,
    route: &[Vertex],
    open: impl Fn(Vertex) -> bool,
) -> Option<(usize, Vertex, Vertex)> {
    for i in 0..route.len().saturating_sub(1) {
        let (a, b) = (route[i], route[i + 1]);
        let ((ac, ar), (bc, br)) = (map.cell(a), map.cell(b));
        let (dc, dr) = (bc as i64 - ac as i64, br as i64 - ar as i64);
        for (sc, sr) in [(-dr, dc), (dr, -dc)] {
            let a2 = map.at(ac as i64 + sc, ar as i64 + sr);
            let b2 = map.at(bc as i64 + sc, br as i64 + sr);
            if let (Some(a2), Some(b2)) = (a2, b2) {
                if map.is_free(a2) && map.is_free(b2) && open(a2) && open(b2) {
                    return Some((i, a2, b2));
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn goals_are_paired_with_starts_so_that_paths_do_not_cross() {
        let map = Map::from_text(&["........"; 6], 0.5);
        let params = CoverageParams::default();
        let v = |c: i64, r: i64| map.at(c, r).unwrap();
        // Mapping east: the northern start gets the northern goal, whatever the order.
        let starts = [v(0, 1), v(0, 4)];
        assert_eq!(
            pair_across(&map, &params, &starts, vec![v(7, 5), v(6, 0)]),
            vec![v(6, 0), v(7, 5)]
        );
        assert_eq!(
            pair_across(&map, &params, &starts, vec![v(6, 0), v(7, 5)]),
            vec![v(6, 0), v(7, 5)]
        );
        // Pairing across would put the goal (1, 0) behind the start (3, 1): kept as given.
        let starts = [v(3, 1), v(0, 4)];
        let goals = vec![v(7, 5), v(1, 0)];
        assert_eq!(pair_across(&map, &params, &starts, goals.clone()), goals);
    }

    #[test]
    fn a_child_far_from_its_start_gets_less_of_the_stage() {
        // Two children map an open block (columns 15-21, rows 0-11) whose only western
        // vertices are its two corners (14, 0) and (14, 11): those are the start points. The
        // near child stands next to the southern start, the far one 13 steps west of the
        // northern, whose graph is a single vertex at first and can only branch out. Each
        // step grows the shortest walk (way to the start included) that can grow: the near
        // graph grows first, then both, from the south and the north edges towards each
        // other. (Until 2026-11 any graph that could hill did before any branched out, so
        // the near child hilled over the whole block and the far child imaged only its start
        // point: walks of 87 and 14 vertices.)
        let rows = vec![".".repeat(22); 12];
        let refs: Vec<&str> = rows.iter().map(String::as_str).collect();
        let map = Map::from_text(&refs, 0.5);
        let params = CoverageParams {
            children: 2,
            ..CoverageParams::default()
        };
        let v = |c: i64, r: i64| map.at(c, r).unwrap();
        let parent = v(13, 6);
        let mut set: Vec<Vertex> = (15..22)
            .flat_map(|c| (0..12).map(move |r| v(c, r)))
            .collect();
        set.extend([v(14, 0), v(14, 11)]);
        let los = vec![true; map.len()];
        let (near, far) = (v(13, 0), v(1, 11));
        let r = stage_roadmaps(&map, &params, &los, parent, &[near, far], &set);
        assert!(r.unreachable.is_empty());
        let (near_walk, far_walk) = (&r.walks[0], &r.walks[1]);
        assert_eq!(
            (near_walk[1], far_walk[13]),
            (v(14, 0), v(14, 11)),
            "the starts"
        );
        for &c in &set {
            assert!(near_walk.contains(&c) || far_walk.contains(&c), "{c}");
        }
        let in_set = |w: &Vec<Vertex>| {
            let mut seen: Vec<Vertex> = w.iter().copied().filter(|u| set.contains(u)).collect();
            seen.sort_unstable();
            seen.dedup();
            seen.len()
        };
        // Alone, the near child would walk at least the whole block (|C| + 1 vertices with
        // its step to the start). Shared, the stage takes at most three quarters of that,
        // and the far child, for all its way to the start, images a quarter of the block
        // (distinct vertices). These are margins, not the balance the rule aims at (walks
        // of about 52 each): a graph hemmed in by the other's stops growing.
        let longest = near_walk.len().max(far_walk.len());
        assert!(
            4 * longest <= 3 * (set.len() + 1),
            "walks of {} and {} vertices for {} child vertices",
            near_walk.len(),
            far_walk.len(),
            set.len()
        );
        assert!(4 * in_set(far_walk) >= set.len(), "{}", in_set(far_walk));
        assert!(in_set(far_walk) < in_set(near_walk));
    }

    #[test]
    fn hilling_winds_a_path_over_a_block() {
        let map = Map::from_text(&["....", "....", "...."], 0.5);
        let params = CoverageParams {
            children: 1,
            ..CoverageParams::default()
        };
        let all: Vec<Vertex> = map.vertices();
        let los = vec![true; map.len()];
        // Parent off the map's vertex set: use a vertex that is not in C.
        let parent = map.at(3, 2).unwrap();
        let set: Vec<Vertex> = all.iter().copied().filter(|&v| v != parent).collect();
        let r = stage_roadmaps(&map, &params, &los, parent, &[map.at(0, 0).unwrap()], &set);
        assert!(r.unreachable.is_empty());
        let walk = &r.walks[0];
        for w in walk.windows(2) {
            assert!(map.adjacent(w[0], w[1]));
            assert_ne!(w[1], parent);
        }
        for &c in &set {
            assert!(walk.contains(&c), "{c} not covered");
        }
        // 11 child vertices; hilling keeps revisits low.
        assert!(walk.len() <= 16, "walk of {} vertices", walk.len());
    }
}
