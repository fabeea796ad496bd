//! Stage transitions with the team moving together (Sections IV.C-D).
//!
//! The parent tracks and teleoperates every child at once, so in a transition all robots
//! that have somewhere to go step in the same timestep, as in the behaviour-based
//! formations of the paper's [17] (each robot steers towards its own target; the team's
//! shape follows from the targets):
//! * **Through H (Eq. 8).** Each child, nearest to H first, takes the nearest vertex of H
//!   no other child took; they all step towards their vertices at once; then the parent
//!   drives.
//! * **Following behaviour.** Children on the parent's path step off it together. The
//!   parent drives with the children in file behind it: each timestep the parent steps on,
//!   then the k-th child (nearest the parent first) steps towards the vertex the parent held
//!   k timesteps before. When the parent has arrived, the children outside its line of
//!   sight spread into it together, as many as it has free vertices for, the nearest child
//!   to the deepest of the vertices chosen (they arrive in file: docs/coverage-planning.md, "Coverage planning
//!   decisions", for the measured effect).
//! * Ways are planned around the robots that stay where they are (the parent above all).
//!
//! In a timestep the robots step in a fixed order onto vertices nobody holds at that moment,
//! so a robot may enter the vertex another left in the same timestep (a train, which the
//! lockstep parent releases only once the robot ahead has arrived) but two robots never
//! share or swap a vertex. Where moving together gets stuck (a corridor where robots must
//! pass each other), the rest is done one robot at a time with the moves of [`super::moves`].

use super::*;

impl Run<'_> {
    /// Distinct targets among the vertices where `goal` holds for `robots`, in the order
    /// given: each takes the nearest one not yet taken (geodesic through `within`, or
    /// through anything for a robot already outside it, and never through a robot outside
    /// `robots`, which stays where it is). Robots with no such target are left out.
    ///
    /// `deepest_first` then hands the same targets out again, the farthest from the first
    /// robot that got one to it, the next farthest to the second, and so on: for robots
    /// arriving one behind the other through one way in, so that the first goes deepest and
    /// none stops in the way of those behind it. Distances are geodesic through vertices no
    /// robot outside `robots` holds (`within` is not consulted: the one caller lets the
    /// children go anywhere); where a target or a robot is not reachable that way from the
    /// first robot, the targets stay as handed out. (Nearest-first pairing stopped the first
    /// robot at the way in, and the rest had to be moved one at a time: README, "Coverage
    /// planning decisions", Timesteps.)
    fn assign(
        &self,
        robots: &[usize],
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
        deepest_first: bool,
    ) -> Vec<(usize, Vertex)> {
        let mut taken = vec![false; self.map.len()];
        for (q, &p) in self.pos.iter().enumerate() {
            if !robots.contains(&q) {
                taken[p] = true;
            }
        }
        let standing = taken.clone();
        let mut goals = Vec::with_capacity(robots.len());
        for &k in robots {
            // A child already out of the region may cross anything to get back.
            let roam = !within(self.pos[k]);
            let target = self
                .map
                .path_to(
                    self.pos[k],
                    |v| goal(v) && !taken[v],
                    |v| !standing[v] && (roam || within(v) || goal(v)),
                )
                .and_then(|path| path.last().copied());
            if let Some(t) = target {
                taken[t] = true;
                goals.push((k, t));
            }
        }
        if deepest_first && goals.len() > 1 {
            let dist = self.map.distances(self.pos[goals[0].0], |v| !standing[v]);
            let connected = goals
                .iter()
                .all(|&(k, t)| dist[t] != usize::MAX && dist[self.pos[k]] != usize::MAX);
            if !connected {
                return goals;
            }
            let mut targets: Vec<Vertex> = goals.iter().map(|&(_, t)| t).collect();
            targets.sort_by_key(|&t| (std::cmp::Reverse(dist[t]), t));
            for (g, t) in goals.iter_mut().zip(targets) {
                g.1 = t;
            }
        }
        goals
    }

    /// One step of `robot` towards the target whose distances are `field`: onto the free
    /// neighbour nearest the target, if it is nearer than where the robot stands and not
    /// `barred`. Returns whether it moved.
    fn step_towards(
        &mut self,
        robot: usize,
        field: &[usize],
        barred: &dyn Fn(Vertex) -> bool,
    ) -> bool {
        let here = self.pos[robot];
        let next = self
            .map
            .neighbours(here)
            .filter(|&u| field[u] < field[here] && !barred(u) && !self.occupied_by_other(robot, u))
            .min_by_key(|&u| field[u]);
        if let Some(u) = next {
            self.pos[robot] = u;
            self.robot_steps += 1;
        }
        next.is_some()
    }

    /// Moves every robot of `goals` to its target together, one step each per timestep
    /// (geodesic through `within`, or through anything for a robot that starts outside
    /// it). Returns whether all arrived; when a timestep moves nobody, the robots stay
    /// where they got to.
    ///
    /// The robots not in `goals` stay where they are, so the ways are planned around them;
    /// a robot whose target lies only beyond one heads there all the same (and where it
    /// gets stuck the one-at-a-time moves take over). Until 2026-11-28 the ways went
    /// through them, and a robot whose way led across the parent stopped beside it.
    fn move_together(
        &mut self,
        goals: &[(usize, Vertex)],
        phase: Phase,
        within: &dyn Fn(Vertex) -> bool,
    ) -> bool {
        let mut standing = vec![false; self.map.len()];
        for (q, &p) in self.pos.iter().enumerate() {
            if !goals.iter().any(|&(k, _)| k == q) {
                standing[p] = true;
            }
        }
        let fields: Vec<Vec<usize>> = goals
            .iter()
            .map(|&(k, t)| {
                let roam = !within(self.pos[k]);
                let around = self.map.distances_until(
                    t,
                    |v| !standing[v] && (roam || within(v)),
                    &[self.pos[k]],
                );
                if around[self.pos[k]] != usize::MAX {
                    around
                } else {
                    self.map
                        .distances_until(t, |v| roam || within(v), &[self.pos[k]])
                }
            })
            .collect();
        loop {
            if goals.iter().all(|&(k, t)| self.pos[k] == t) {
                return true;
            }
            let mut moved = false;
            for (g, &(k, t)) in goals.iter().enumerate() {
                if self.pos[k] != t {
                    moved |= self.step_towards(k, &fields[g], &|_| false);
                }
            }
            if !moved {
                return false;
            }
            self.push(phase, Vec::new());
        }
    }

    /// Children `robots` to distinct vertices where `goal` holds, together; those that could
    /// not get there together walk one at a time (pushing others aside). Returns whether
    /// every one of them stands on a `goal` vertex.
    fn gather(
        &mut self,
        robots: &[usize],
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
        deepest_first: bool,
    ) -> bool {
        let goals = self.assign(robots, goal, within, deepest_first);
        self.move_together(&goals, Phase::Coordination, within);
        let mut all = true;
        for &j in robots {
            if !goal(self.pos[j]) {
                let roam = !within(self.pos[j]);
                let r = self.walk_alone(j, Phase::Coordination, goal, |v| {
                    roam || within(v) || goal(v)
                });
                all &= r.is_ok();
            }
        }
        all
    }

    /// The parent drives a shortest path to `to` with the children in file behind it;
    /// from where formation driving gets stuck, the parent drives on alone, moving children
    /// out of its way. The k-th child (nearest the parent first) heads for the vertex the
    /// parent held k timesteps before, never onto the part of the path still ahead.
    fn drive_in_formation(&mut self, to: Vertex) -> Result<(), PlanError> {
        // From where the parent stands now (a child stepping off its path may have pushed
        // it aside).
        let Some(path) = self.map.path_to(self.pos[0], |v| v == to, |_| true) else {
            return self.drive_parent(to, Phase::Coordination, &|_| false);
        };
        let file = self.nearest_first(|v| v == path[0]);
        let mut index_on_path = vec![usize::MAX; self.map.len()];
        for (i, &v) in path.iter().enumerate() {
            index_on_path[v] = i;
        }
        let mut i = 0;
        while i + 1 < path.len() && !self.occupied_by_other(0, path[i + 1]) {
            i += 1;
            self.pos[0] = path[i];
            self.robot_steps += 1;
            let ahead = |u: Vertex| index_on_path[u] != usize::MAX && index_on_path[u] > i;
            for (k, &j) in file.iter().enumerate() {
                let slot = path[i.saturating_sub(k + 1)];
                if self.pos[j] != slot {
                    let field = self.map.distances_until(slot, |_| true, &[self.pos[j]]);
                    self.step_towards(j, &field, &ahead);
                }
            }
            self.push(Phase::Coordination, Vec::new());
        }
        self.drive_parent(to, Phase::Coordination, &|_| false)
    }

    /// Moves the team from the parent's vertex to `to`: through H, or by the following
    /// behaviour (returns why then).
    pub(super) fn transition(&mut self, to: Vertex) -> Result<Option<Following>, PlanError> {
        let from = self.pos[0];
        if from == to {
            return Ok(None);
        }
        let n = self.pos.len() - 1;
        let stuck = PlanError::Stuck {
            stage: self.stage,
            robot: 0,
            target: Some(to),
        };
        let parent_path = self.map.path_to(from, |v| v == to, |_| true).ok_or(stuck)?;
        let mut on_path = vec![false; self.map.len()];
        for &v in &parent_path {
            on_path[v] = true;
        }
        // H (Eq. 8; from LOS_free under `Reading::HFromLosFree`) decides between the two;
        // the children prefer its vertices off the parent's path, and stand on the path only
        // where H off it is too small (the parent then moves them aside as it drives).
        let mut in_h = vec![false; self.map.len()];
        let mut h_count = 0;
        let mut off_path = 0;
        let (here, next) = match self.params.reading {
            Reading::HFromLosFree => (&self.vis.los_free[from], &self.vis.los_free[to]),
            _ => (&self.vis.los[from], &self.vis.los[to]),
        };
        for &v in here {
            if v != to && next.binary_search(&v).is_ok() {
                in_h[v] = true;
                h_count += 1;
                off_path += usize::from(!on_path[v]);
            }
        }
        if off_path >= n {
            for v in 0..self.map.len() {
                in_h[v] &= !on_path[v];
            }
        }
        let mut following = (h_count < n).then_some(Following::FewInH);
        if following.is_none() {
            // Children to distinct vertices of H, staying in the parent's sight.
            let mut los_from = vec![false; self.map.len()];
            for &v in &self.vis.los[from] {
                los_from[v] = true;
            }
            let order = self.nearest_first(|v| in_h[v]);
            let saved = self.snapshot();
            if !self.gather(&order, &|v| in_h[v], &|v| los_from[v] || in_h[v], false) {
                // Undo and fall back to following.
                self.restore(saved);
                following = Some(Following::HOutOfReach);
            }
        }
        let Some(cause) = following else {
            // The parent drives, children in its way making way.
            self.drive_parent(to, Phase::Coordination, &|_| false)?;
            return Ok(None);
        };
        // Children on the parent's path step off it (one that cannot is moved ahead of the
        // parent as it drives), then follow it in file.
        let on: Vec<usize> = (1..=n).filter(|&j| on_path[self.pos[j]]).collect();
        let _ = self.gather(&on, &|v| !on_path[v], &|_| true, false);
        self.drive_in_formation(to)?;
        let mut around = vec![false; self.map.len()];
        for &v in &self.vis.los[to] {
            around[v] = true;
        }
        // A child that cannot get into LOS(to) (the parent's vertex cuts it off), or for
        // which LOS(to) has no room left (its free vertices nobody holds), stays where it
        // is; the stage's roadmaps start from wherever the children stand. The children
        // arrive in file, the nearest going deepest.
        let room = self.vis.los[to]
            .iter()
            .filter(|&&v| v != to && !self.pos.contains(&v))
            .count();
        let outside: Vec<usize> = self
            .nearest_first(|v| around[v])
            .into_iter()
            .filter(|&j| !around[self.pos[j]])
            .take(room)
            .collect();
        let _ = self.gather(&outside, &|v| around[v], &|_| true, true);
        Ok(Some(cause))
    }
}

#[cfg(test)]
mod tests {
    use super::super::moves::tests::run_on;
    use super::*;

    /// Every robot moves at most one step per frame onto a free vertex; no two share or
    /// swap a vertex. Returns the frames in which more than one robot moved.
    fn frames_moving_several(map: &Map, start: &[Vertex], frames: &[Frame]) -> usize {
        let mut prev = start.to_vec();
        let mut several = 0;
        for (t, f) in frames.iter().enumerate() {
            let pos = &f.positions;
            let moved = (0..pos.len()).filter(|&k| prev[k] != pos[k]).count();
            assert!(moved >= 1, "frame {t}: nobody moved");
            several += usize::from(moved > 1);
            for k in 0..pos.len() {
                assert!(
                    prev[k] == pos[k] || map.adjacent(prev[k], pos[k]),
                    "frame {t}: a jump"
                );
                assert!(map.is_free(pos[k]));
                for q in k + 1..pos.len() {
                    assert_ne!(
                        pos[k], pos[q],
                        "frame {t}: robots {k} and {q} share a vertex"
                    );
                    assert!(
                        !(pos[k] == prev[q] && pos[q] == prev[k]),
                        "frame {t}: robots {k} and {q} swapped"
                    );
                }
            }
            prev = pos.clone();
        }
        several
    }

    #[test]
    fn children_move_into_h_together() {
        // An open room; the next parent vertex is 2 m east. Four children west of the parent
        // each have a few steps to H: together they need the longest of their walks, not
        // the sum.
        let rows = [
            "..............",
            "k.............",
            "k...P.........",
            "k.............",
            "k.............",
        ];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            children: 4,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let start = run.pos.clone();
        let to = map.at(8, 2).unwrap();
        let following = run.transition(to).unwrap();
        assert_eq!(following, None, "H is large in an open room");
        assert_eq!(run.pos[0], to);
        frames_moving_several(&map, &start, &run.frames);
        // The children's part is the frames before the parent's first step. Each child walks
        // at least 4 steps east (H lies within 2 m of both parent vertices, the children
        // stand 2 m west of the first): one at a time that is at least one frame per step;
        // together, at least two steps per frame.
        let first_parent_step = run
            .frames
            .iter()
            .position(|f| f.positions[0] != start[0])
            .unwrap();
        let child_steps = run.robot_steps - 4;
        assert!(child_steps >= 16, "{child_steps}");
        assert!(
            2 * first_parent_step <= child_steps,
            "{first_parent_step} frames for {child_steps} child steps"
        );
    }

    #[test]
    fn children_follow_the_parent_in_file_through_a_corridor() {
        // Two rooms joined by a one-cell corridor 6 m long: the parent's line of sight at the
        // two ends does not overlap, so the team follows it (Section IV.D). The children walk
        // behind it in the same timesteps, so the transition takes little more than the
        // parent's own path.
        let rows = [
            "....#############....",
            ".k..#############....",
            "..P..................",
            ".kk.#############....",
            "....#############....",
        ];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            children: 3,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let start = run.pos.clone();
        let to = map.at(19, 2).unwrap();
        let path = map.path_to(start[0], |v| v == to, |_| true).unwrap().len() - 1;
        // H is empty: a following behaviour by the paper's own test.
        assert_eq!(run.transition(to).unwrap(), Some(Following::FewInH));
        assert_eq!(run.pos[0], to);
        let several = frames_moving_several(&map, &start, &run.frames);
        assert!(
            several * 2 > path,
            "{several} of {} frames",
            run.frames.len()
        );
        // In file, the children stay a few vertices behind: the whole transition is little
        // more than the parent's path. One at a time, each child would walk the corridor
        // after the parent, more than twice the path in all.
        assert!(run.frames.len() < 2 * path, "{} frames", run.frames.len());
        // They all got into the parent's line of sight at the far end.
        for &c in &run.pos[1..] {
            assert!(vis.los[to].binary_search(&c).is_ok(), "{:?}", map.cell(c));
        }
    }

    #[test]
    fn a_robot_moving_together_goes_around_the_parent_not_into_it() {
        // The child's target lies two cells east of the parent, which stands still between
        // them. The way around it is 6 steps; a way planned through the parent stops the
        // child beside it (every step left would lead away from the target), and moving
        // together reports failure.
        let rows = [".....", "k.P..", "....."];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            children: 1,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let start = run.pos.clone();
        let target = map.at(4, 1).unwrap();
        assert!(run.move_together(&[(1, target)], Phase::Coordination, &|_| true));
        frames_moving_several(&map, &start, &run.frames);
        assert_eq!(run.pos, vec![start[0], target]);
        assert_eq!(run.frames.len(), 6);
    }

    #[test]
    fn children_on_both_sides_of_the_parent_keep_targets_on_their_own_side() {
        // A one-cell corridor, r_los = 1 m: the parent stands in it, one child four cells
        // west and one four cells east, both outside LOS(to) (two cells either side). Each
        // takes the nearest vertex of LOS(to), on its own side, two steps away. The parent
        // cuts the corridor in two, so handing the targets out again deepest first (from the
        // first child) must leave them as they are: two timesteps, both in LOS(to).
        let rows = ["#########", "k...P...k", "#########"];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            r_los_m: 1.0,
            children: 2,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let start = run.pos.clone();
        let to = start[0];
        let mut around = vec![false; map.len()];
        for &v in &vis.los[to] {
            around[v] = true;
        }
        assert!(run.gather(&[1, 2], &|v| around[v], &|_| true, true));
        frames_moving_several(&map, &start, &run.frames);
        assert_eq!(run.pos[1..], [map.at(2, 1).unwrap(), map.at(6, 1).unwrap()]);
        assert_eq!(run.frames.len(), 2);
    }

    #[test]
    fn children_arriving_in_file_fill_a_small_line_of_sight_together() {
        // r_los = 1 m: LOS(to) is the 12 vertices within two cells of the parent, in a
        // 5 x 5 room. Six children stand in file in the corridor that enters the room on the
        // parent's row, all outside LOS(to), as a following behaviour leaves them. The six
        // vertices of LOS(to) nearest the file are the mouth (6, 2), (7, 2), (7, 1), (7, 3),
        // (8, 1) and (8, 3); the nearest child goes deepest, to (8, 1) beside the parent (4
        // steps from it around the parent; (8, 3) is as deep and comes later in vertex
        // order), the rest fill in behind it, and the mouth is taken last. In a train the
        // k-th child starts k steps behind the first and its target is no deeper, so the
        // gather takes at most 4 + 5 timesteps. (Handing out the nearest vertex first, the
        // first child stopped in the mouth, the rest were moved one at a time, pushing each
        // other about, and one ended outside LOS(to).)
        let rows = [
            "######.....",
            "######.....",
            "kkkkkk..P..",
            "######.....",
            "######.....",
        ];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            r_los_m: 1.0,
            children: 6,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let start = run.pos.clone();
        let to = start[0];
        assert_eq!(vis.los[to].len(), 12);
        let mut around = vec![false; map.len()];
        for &v in &vis.los[to] {
            around[v] = true;
        }
        let file = run.nearest_first(|v| around[v]);
        assert!(file.iter().all(|&j| !around[start[j]]), "all outside");
        assert!(run.gather(&file, &|v| around[v], &|_| true, true));
        frames_moving_several(&map, &start, &run.frames);
        assert_eq!(run.pos[0], to, "the parent stays");
        for &c in &run.pos[1..] {
            assert!(around[c], "{:?}", map.cell(c));
        }
        assert_eq!(
            run.pos[file[0]],
            map.at(8, 1).unwrap(),
            "the nearest went deepest"
        );
        assert!(run.frames.len() <= 4 + 5, "{} timesteps", run.frames.len());
    }

    #[test]
    fn children_cut_off_from_h_by_the_parent_make_a_following_behaviour_of_our_kind() {
        // A one-cell corridor: three children stand west of the parent, the next parent
        // vertex is 2 m east. H (Eq. 8) holds the three cells between the two parent
        // vertices, so |H| = N and the paper's test asks for no following behaviour (it
        // would with one child more); but the children's part of LOS(v_p^t) meets H only
        // through the parent's own vertex, which is in neither set (v is not in LOS(v)). The
        // transition is a following behaviour of the second kind, and the children still end
        // in the parent's line of sight at `to`.
        let rows = ["############", "kkkP........", "############"];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            children: 3,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let start = run.pos.clone();
        let to = map.at(7, 1).unwrap();
        let h = vis.los[start[0]]
            .iter()
            .filter(|&&v| v != to && vis.los[to].binary_search(&v).is_ok())
            .count();
        assert_eq!(h, 3, "H: the cells between the two parent vertices");
        assert_eq!(run.transition(to).unwrap(), Some(Following::HOutOfReach));
        assert_eq!(run.pos[0], to);
        frames_moving_several(&map, &start, &run.frames);
        for &c in &run.pos[1..] {
            assert!(vis.los[to].binary_search(&c).is_ok(), "{:?}", map.cell(c));
        }
    }
}
