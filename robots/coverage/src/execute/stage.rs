//! One stage of the mission at the grid level: the children ordered by distance, the stage's roadmaps driven timestep by timestep, and the mop-up of vertices a stage left.

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

    /// Walks the stage's roadmaps in parallel, then mops up deferred vertices.
    pub(super) fn map_stage(&mut self, child_set: &[Vertex]) -> Result<Vec<Vertex>, PlanError> {
        let parent = self.pos[0];
        let mut los_parent = vec![false; self.map.len()];
        for &v in &self.vis.los[parent] {
            los_parent[v] = true;
        }
        let mut in_set = vec![false; self.map.len()];
        for &c in child_set {
            in_set[c] = true;
        }
        let children: Vec<Vertex> = self.pos[1..].to_vec();
        let roadmaps = stage_roadmaps(
            self.map,
            self.params,
            &los_parent,
            parent,
            &children,
            child_set,
        );
        let mut walks = roadmaps.walks;
        let n = walks.len();
        let mut idx = vec![0usize; n];
        let mut pending = vec![false; n];
        let mut deferred: Vec<Vertex> = Vec::new();
        let mut imaged_here = Vec::new();
        loop {
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
                let next = walks[j][idx[j] + 1];
                if !self.occupied_by_other(robot, next) {
                    self.pos[robot] = next;
                    idx[j] += 1;
                    self.robot_steps += 1;
                    moved = true;
                }
            }
            let mut grabs = Vec::new();
            for (j, waiting) in pending.iter_mut().enumerate() {
                let (robot, at) = (j + 1, self.pos[j + 1]);
                *waiting = false;
                if in_set[at] && !self.imaged[at] {
                    if self.view_blocked(robot, at) {
                        *waiting = true;
                    } else {
                        self.imaged[at] = true;
                        imaged_here.push(at);
                        grabs.push((j, at));
                    }
                }
            }
            if moved || !grabs.is_empty() {
                self.push(Phase::Mapping, grabs);
                continue;
            }
            // Nobody could do anything: defer one blocked grab, or re-route one blocked walk.
            if let Some(j) = (0..n).find(|&j| pending[j]) {
                pending[j] = false;
                deferred.push(self.pos[j + 1]);
                // Mark as handled for this walk; the mop-up grabs it.
                in_set[self.pos[j + 1]] = false;
                continue;
            }
            let j = (0..n)
                .find(|&j| idx[j] + 1 < walks[j].len())
                .expect("an active child exists");
            let robot = j + 1;
            let rest: Vec<Vertex> = walks[j][idx[j] + 1..].to_vec();
            let reroute = rest.iter().enumerate().find_map(|(k, &target)| {
                if self.occupied_by_other(robot, target) {
                    return None;
                }
                self.map
                    .path_to(
                        self.pos[robot],
                        |v| v == target,
                        |v| v != parent && !self.occupied_by_other(robot, v),
                    )
                    .map(|p| (k, p))
            });
            match reroute {
                Some((k, p)) => {
                    let mut walk = walks[j][..=idx[j]].to_vec();
                    walk.extend(p.into_iter().skip(1));
                    walk.extend(rest.into_iter().skip(k + 1));
                    walks[j] = walk;
                }
                None => {
                    deferred.extend(
                        rest.iter()
                            .copied()
                            .filter(|&v| in_set[v] && !self.imaged[v]),
                    );
                    walks[j].truncate(idx[j] + 1);
                }
            }
        }
        // Mop-up, one vertex at a time.
        deferred.extend(roadmaps.unreachable);
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

    /// Everyone else leaves the view of child `robot` on `c`; whether its view is clear.
    fn clear_view(&mut self, robot: usize, c: Vertex) -> bool {
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
