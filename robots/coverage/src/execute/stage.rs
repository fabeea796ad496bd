//! One stage of the mission at the grid level: the children ordered by distance, the
//! stage's roadmaps driven timestep by timestep, and the mop-up of vertices a stage left.

use super::*;

impl Run<'_> {
    /// Children ordered by geodesic distance to the nearest vertex satisfying `goal`.
    pub(super) fn nearest_first(&self, goal: impl Fn(Vertex) -> bool) -> Vec<usize> {
        let n = self.pos.len() - 1;
        let mut order: Vec<(usize, usize)> = (1..=n)
            .map(|j| {
                let d = self
                    .map
                    .path_to(self.pos[j], &goal, |_| true)
                    .map_or(usize::MAX, |p| p.len());
                (d, j)
            })
            .collect();
        order.sort_unstable();
        order.into_iter().map(|(_, j)| j).collect()
    }

    /// Walks the stage's roadmaps in parallel, in rounds, then mops up what is left one
    /// vertex at a time.
    ///
    /// A round builds roadmaps for the child vertices still to be imaged from wherever the
    /// children stand and walks them in parallel until the first child is idle (once it
    /// has imaged something, with nobody waiting to grab); what it has not imaged (not
    /// reached yet, or a view it could not clear) goes to the next round.
    /// Rounds go on while each images something; the rest is mopped up.
    pub(super) fn map_stage(&mut self, child_set: &[Vertex]) -> Result<Vec<Vertex>, PlanError> {
        let parent = self.pos[0];
        let mut los_parent = vec![false; self.map.len()];
        for &v in &self.vis.los[parent] {
            los_parent[v] = true;
        }
        let n = self.pos.len() - 1;
        let mut imaged_here = Vec::new();
        let mut left: Vec<Vertex> = child_set.to_vec();
        let mut unreachable = Vec::new();
        while !left.is_empty() && n > 0 {
            let children: Vec<Vertex> = self.pos[1..].to_vec();
            let roadmaps =
                stage_roadmaps(self.map, self.params, &los_parent, parent, &children, &left);
            unreachable.extend(roadmaps.unreachable);
            let before = imaged_here.len();
            self.walk_roadmaps(roadmaps.walks, &left, &mut imaged_here);
            if imaged_here.len() == before {
                break;
            }
            left.retain(|&c| !self.imaged[c] && !unreachable.contains(&c));
        }
        let mut deferred = unreachable;
        // Mop-up, one vertex at a time.
        deferred.extend(child_set.iter().copied().filter(|&c| !self.imaged[c]));
        deferred.sort_unstable();
        deferred.dedup();
        for c in deferred {
            if self.imaged[c] || n == 0 {
                continue;
            }
            if let Some(j) = self.mop_up(parent, c)? {
                self.imaged[c] = true;
                imaged_here.push(c);
                if let Some(last) = self.frames.last_mut() {
                    last.grabs.push((j, c));
                }
            }
        }
        Ok(imaged_here)
    }

    /// One round: the children walk `walks` in parallel, one step each per timestep (a
    /// child whose next vertex is taken waits), and grab on every vertex of `set` they
    /// reach whose view is clear, until a child is idle while another still walks and
    /// nobody waits to grab (once the round has imaged something; the caller re-plans the
    /// rest from there). A child whose view holds a robot that is walking waits for it to
    /// pass, and a child done with its walk that stands in the view steps out of
    /// it (its walk is extended to the nearest vertex outside the view) while the grabbing
    /// child waits. One whose view holds the parent or a child itself waiting to grab, or a
    /// done child with no way out or already stepped aside 2N times this round, leaves the
    /// vertex to the next round and walks on. When nobody can move, one blocked walk is
    /// re-routed or cut short.
    fn walk_roadmaps(
        &mut self,
        mut walks: Vec<Vec<Vertex>>,
        set: &[Vertex],
        imaged_here: &mut Vec<Vertex>,
    ) {
        let parent = self.pos[0];
        let mut in_set = vec![false; self.map.len()];
        for &c in set {
            in_set[c] = true;
        }
        let n = walks.len();
        let mut idx = vec![0usize; n];
        let mut pending = vec![false; n];
        let mut evictions = vec![0usize; n];
        let imaged_before = imaged_here.len();
        loop {
            // The round ends as soon as a child is idle (its walk done, or none given) while
            // another still walks and nobody waits to grab, once it has imaged something:
            // the stage's remaining vertices then get new roadmaps from where everyone
            // stands, so the idle child takes a share of the rest instead of waiting for the
            // longest walk to end. (Each round images something, so the rounds end.)
            let done = |j: usize| idx[j] + 1 >= walks[j].len();
            if imaged_here.len() > imaged_before
                && !pending.contains(&true)
                && (0..n).any(done)
                && !(0..n).all(done)
            {
                break;
            }
            let active = (0..n).any(|j| pending[j] || idx[j] + 1 < walks[j].len());
            if !active {
                break;
            }
            let mut moved = false;
            for j in 0..n {
                let robot = j + 1;
                if pending[j] || idx[j] + 1 >= walks[j].len() {
                    continue;
                }
                let mut next = walks[j][idx[j] + 1];
                // A robot that will not move this round (the parent, a child done or
                // waiting to grab) is walked around at once.
                let settled =
                    |q: usize| q == 0 || pending[q - 1] || idx[q - 1] + 1 >= walks[q - 1].len();
                if (0..self.pos.len()).any(|q| q != robot && self.pos[q] == next && settled(q)) {
                    if let Some(walk) = self.reroute(robot, &walks[j], idx[j], parent) {
                        walks[j] = walk;
                        next = walks[j][idx[j] + 1];
                    }
                }
                if !self.occupied_by_other(robot, next) {
                    self.pos[robot] = next;
                    idx[j] += 1;
                    self.robot_steps += 1;
                    moved = true;
                }
            }
            let mut grabs = Vec::new();
            let was_pending = std::mem::replace(&mut pending, vec![false; n]);
            for (j, waiting) in pending.iter_mut().enumerate() {
                let (robot, at) = (j + 1, self.pos[j + 1]);
                if !in_set[at] || self.imaged[at] {
                    continue;
                }
                let in_my_view: Vec<usize> = (0..self.pos.len())
                    .filter(|&k| {
                        self.params.views == ViewRule::EveryGrab
                            && k != robot
                            && in_view(self.map, self.params, at, self.pos[k], self.radius(k))
                    })
                    .collect();
                if in_my_view.is_empty() {
                    self.imaged[at] = true;
                    imaged_here.push(at);
                    grabs.push((j, at));
                } else if in_my_view.iter().all(|&k| k > 0 && !was_pending[k - 1]) {
                    // Walking robots pass; a child done with its walk steps out of the view.
                    let done = |k: usize| idx[k - 1] + 1 >= walks[k - 1].len();
                    let ways_out: Option<Vec<(usize, Vec<Vertex>)>> = in_my_view
                        .iter()
                        .filter(|&&k| done(k))
                        .map(|&k| {
                            // At most 2N times a round, so that two grabs cannot send a
                            // child back and forth for ever.
                            (evictions[k - 1] < 2 * n)
                                .then(|| self.out_of_view(k, at, parent))
                                .flatten()
                                .map(|path| (k, path))
                        })
                        .collect();
                    match ways_out {
                        Some(ways_out) => {
                            for (k, path) in ways_out {
                                evictions[k - 1] += 1;
                                walks[k - 1].extend(path.into_iter().skip(1));
                            }
                            *waiting = true;
                        }
                        None => in_set[at] = false,
                    }
                } else {
                    // Left for the next round.
                    in_set[at] = false;
                }
            }
            if moved || !grabs.is_empty() {
                self.push(Phase::Mapping, grabs);
                continue;
            }
            // Nobody could do anything: give up one blocked grab, or re-route one walk.
            if let Some(j) = (0..n).find(|&j| pending[j]) {
                pending[j] = false;
                in_set[self.pos[j + 1]] = false;
                continue;
            }
            let j = (0..n)
                .find(|&j| idx[j] + 1 < walks[j].len())
                .expect("an active child exists");
            let robot = j + 1;
            match self.reroute(robot, &walks[j], idx[j], parent) {
                Some(walk) => walks[j] = walk,
                None => walks[j].truncate(idx[j] + 1),
            }
        }
    }

    /// The shortest way for child `robot` to the nearest vertex outside the view of a child
    /// grabbing at `at`, through vertices nobody holds and never the parent's `parent`.
    fn out_of_view(&self, robot: usize, at: Vertex, parent: Vertex) -> Option<Vec<Vertex>> {
        let (map, params) = (self.map, self.params);
        self.map.path_to(
            self.pos[robot],
            |v| v != parent && !in_view(map, params, at, v, params.child_radius_m),
            |v| v != parent && !self.occupied_by_other(robot, v),
        )
    }

    /// `walk` (child `robot` stands on `walk[at]`) re-routed around the other robots: to the
    /// first vertex still ahead on it that no robot holds, by a shortest path through free
    /// vertices (never the parent's), then on as before. `None` if there is no such path.
    fn reroute(
        &self,
        robot: usize,
        walk: &[Vertex],
        at: usize,
        parent: Vertex,
    ) -> Option<Vec<Vertex>> {
        let rest = &walk[at + 1..];
        rest.iter().enumerate().find_map(|(k, &target)| {
            if target == self.pos[robot] || self.occupied_by_other(robot, target) {
                return None;
            }
            let path = self.map.path_to(
                self.pos[robot],
                |v| v == target,
                |v| v != parent && !self.occupied_by_other(robot, v),
            )?;
            let mut new = walk[..=at].to_vec();
            new.extend(path.into_iter().skip(1));
            new.extend(rest.iter().skip(k + 1));
            Some(new)
        })
    }

    /// Brings the nearest child to `c`, clears its view, and returns the child's index if it
    /// can grab there.
    pub(super) fn mop_up(&mut self, parent: Vertex, c: Vertex) -> Result<Option<usize>, PlanError> {
        if self.pos[0] == c {
            return Ok(None);
        }
        // The parent stands on the stage's parent vertex again if an earlier grab moved it.
        if self.pos[0] != parent
            && self
                .drive_parent(parent, Phase::Mapping, &|_| false)
                .is_err()
        {
            return Ok(None);
        }
        // Whichever child is nearest; the parent lets it through if its vertex cuts c off,
        // or, where it could not come back without crossing c, watches from another vertex
        // that has c in its LOS_free.
        let robot = match self.bring_child(Phase::Mapping, &|v| v == c, &|_| true)? {
            Some(robot) => robot,
            None => match self.bring_child_from_stand(Phase::Mapping, c)? {
                Some(robot) => robot,
                None => return Ok(None),
            },
        };
        if !self.clear_view(robot, c) {
            return Ok(None);
        }
        if self.frames.last().is_none_or(|f| f.positions != self.pos) {
            self.push(Phase::Mapping, Vec::new());
        }
        Ok(Some(robot - 1))
    }

    /// Everyone else leaves the view of child `robot` on `c`; whether its view is clear
    /// (always, under [`ViewRule::StartPoints`], which does not check grabs).
    pub(super) fn clear_view(&mut self, robot: usize, c: Vertex) -> bool {
        if self.params.views == ViewRule::StartPoints {
            return self.pos[robot] == c;
        }
        let n = self.pos.len() - 1;
        let watcher = self.pos[0];
        // Robots in its view step out of it (a step aside can bring another one in, so
        // this is repeated until the view is clear or nobody can move).
        let (map, params) = (self.map, self.params);
        let out_of_view = |v: Vertex| !in_view(map, params, c, v, params.child_radius_m) && v != c;
        for _ in 0..8 * n {
            let Some(other) = (1..=n).find(|&k| {
                k != robot && in_view(map, params, c, self.pos[k], params.child_radius_m)
            }) else {
                break;
            };
            let pinned = |v: Vertex| v == c || v == watcher;
            if !self.make_way(self.pos[other], Phase::Mapping, &pinned, &out_of_view)
                && self
                    .walk_alone(other, Phase::Mapping, out_of_view, |v| {
                        v != watcher && v != c
                    })
                    .is_err()
            {
                return false;
            }
        }
        // A robot pushed aside may have pushed the grabbing child off c.
        self.pos[robot] == c && !self.view_blocked(robot, c)
    }

    /// Images `c` after the tour ([`Plan::revisited`]): the parent drives to a vertex that
    /// sees `c` freely, a child is brought there and the view is cleared. The child, if it
    /// grabbed.
    pub(super) fn revisit(&mut self, c: Vertex) -> Result<Option<usize>, PlanError> {
        if self.pos.len() < 2 {
            return Ok(None);
        }
        let Some(robot) = self.bring_child_from_stand(Phase::Mapping, c)? else {
            return Ok(None);
        };
        if !self.clear_view(robot, c) {
            return Ok(None);
        }
        if self.frames.last().is_none_or(|f| f.positions != self.pos) {
            self.push(Phase::Mapping, Vec::new());
        }
        Ok(Some(robot - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::super::moves::tests::run_on;
    use super::*;

    #[test]
    fn a_child_done_with_its_walk_steps_out_of_a_grabbing_childs_view() {
        // Child 2 (row 4, column 7) has finished its walk and stands due east of the vertex
        // child 1 walks to, in the middle of its camera's view. The grab is made in the same
        // round: child 2 steps out of the view and child 1 waits for it, instead of leaving
        // the vertex to a later round.
        let rows = [
            "..........",
            "..........",
            "..........",
            "..........",
            "P.k....k..",
            "..........",
            "..........",
            "..........",
            "..........",
        ];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            children: 2,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let at = |c: i64| map.at(c, 4).unwrap();
        let (first, second) = (run.pos[1], run.pos[2]);
        assert_eq!((first, second), (at(2), at(7)), "children in scan order");
        let target = at(4);
        assert!(in_view(
            &map,
            &params,
            target,
            second,
            params.child_radius_m
        ));
        let walks = vec![vec![at(2), at(3), target], vec![second]];
        let mut imaged = Vec::new();
        run.walk_roadmaps(walks, &[target], &mut imaged);
        assert_eq!(imaged, vec![target], "the grab is made in the round");
        let grab = run
            .frames
            .iter()
            .find(|f| !f.grabs.is_empty())
            .expect("a frame with the grab");
        assert_eq!(grab.grabs, vec![(0, target)]);
        // At the grab the child that was done stands outside the grabbing child's view.
        assert_eq!(grab.positions[1], target);
        assert!(!in_view(
            &map,
            &params,
            target,
            grab.positions[2],
            params.child_radius_m
        ));
    }

    #[test]
    fn a_round_ends_when_a_child_is_idle_while_another_still_walks() {
        // Child 1's walk is one step, child 2's four. Grabs are not checked here, so no
        // child waits: after the first timestep child 1 is done and the round ends with child
        // 2 on its second vertex, for the caller to re-plan the rest.
        let rows = [
            "..........",
            "..k...k...",
            "..........",
            "..........",
            "P.........",
            "..........",
            "..........",
        ];
        let map = Map::from_text(&rows, 0.5);
        let params = CoverageParams {
            children: 2,
            views: ViewRule::StartPoints,
            ..CoverageParams::default()
        };
        let vis = Visibility::compute(&map, &params);
        let mut run = run_on(&map, &params, &vis, &rows);
        let at = |c: i64, r: i64| map.at(c, r).unwrap();
        assert_eq!(
            (run.pos[1], run.pos[2]),
            (at(2, 5), at(6, 5)),
            "text row 1 is r = 5"
        );
        let short = vec![at(2, 5), at(2, 4)];
        let long: Vec<Vertex> = (1..=5).rev().map(|r| at(6, r)).collect();
        let set: Vec<Vertex> = short[1..].iter().chain(&long[1..]).copied().collect();
        let frames_before = run.frames.len();
        let mut imaged = Vec::new();
        run.walk_roadmaps(vec![short, long], &set, &mut imaged);
        assert_eq!(run.frames.len(), frames_before + 1, "one timestep");
        assert_eq!(imaged, vec![at(2, 4), at(6, 4)]);
        assert_eq!((run.pos[1], run.pos[2]), (at(2, 4), at(6, 4)));
        // The rest of child 2's walk is left for the next round's roadmaps.
        assert!([at(6, 3), at(6, 2), at(6, 1)]
            .iter()
            .all(|&v| !run.imaged[v]));
    }
}
