//! Moving robots past each other on a grid where two robots never share or swap a vertex.
//!
//! The children are interchangeable for the mission (any child can image any vertex, and any
//! child can stand in a following position), so a child in the way is never a reason to fail:
//! the robots between a vertex and the nearest empty one shift one step each along the path
//! between them (unlabelled pebble motion), which empties the vertex in as many single steps as
//! there are robots on that path. The parent is the one robot that must itself get somewhere.
//! It is blocked when the children ahead have no empty vertex to move to in the pocket beyond
//! its next step (the part of the map its own vertex cuts off; a pocket a back-off already
//! emptied is not refilled from outside): every vertex there holds a child. Then the parent
//! yields: it backs off to the nearest vertex from which the pocket's children can leave past
//! it, they leave, and it goes on. Where the only room they would find is on the parent's own
//! way back in (it backed off along a one-vertex-wide corridor), that back-off is undone and
//! the parent stands where its way back leaves them enough empty vertices (a side vertex at the
//! corridor's mouth). A child that must get behind the parent (to image a vertex the parent's
//! vertex cuts off) is let through the same way.

use super::*;

/// How many times [`Run::drive_parent`] may back off before it gives up (each back-off
/// empties a pocket of at most N children, so a handful is plenty; the bound only keeps a
/// bug from looping forever).
const MAX_BACK_OFFS: usize = 32;

impl Run<'_> {
    /// The child standing on `v`, if any.
    pub(super) fn child_at(&self, v: Vertex) -> Option<usize> {
        (1..self.pos.len()).find(|&k| self.pos[k] == v)
    }

    /// Empties vertex `v` by shifting the children on a shortest path from `v` to the nearest
    /// vertex with no robot where `hole_ok` holds, one step each, starting with the one
    /// nearest that vertex. The path avoids the parent and every vertex in `keep` (robots
    /// there do not move, and a kept `v` is not emptied). An empty vertex on the way where
    /// `hole_ok` is false is not the end of the path, but the shift can leave a child on it
    /// (and empty the vertex after it instead): `hole_ok` says where the chain may end, not
    /// which vertices stay empty. Returns whether `v` is now empty.
    pub(super) fn make_way(
        &mut self,
        v: Vertex,
        phase: Phase,
        keep: &dyn Fn(Vertex) -> bool,
        hole_ok: &dyn Fn(Vertex) -> bool,
    ) -> bool {
        if self.child_at(v).is_none() {
            return self.pos[0] != v;
        }
        if keep(v) {
            return false;
        }
        let parent = self.pos[0];
        let Some(path) = self.map.path_to(
            v,
            |u| hole_ok(u) && !self.occupied_by_other(usize::MAX, u),
            |u| u != parent && !keep(u),
        ) else {
            return false;
        };
        for k in (0..path.len() - 1).rev() {
            if let Some(j) = self.child_at(path[k]) {
                self.pos[j] = path[k + 1];
                self.robot_steps += 1;
                self.push(phase, Vec::new());
            }
        }
        true
    }

    /// Drives the parent to `to` along shortest paths, moving children out of its way
    /// ([`Self::make_way`]); children on vertices where `keep` holds are never moved and never
    /// passed. When the vertex ahead lies in a pocket full of children, the parent backs off
    /// and lets them out first.
    pub(super) fn drive_parent(
        &mut self,
        to: Vertex,
        phase: Phase,
        keep: &dyn Fn(Vertex) -> bool,
    ) -> Result<(), PlanError> {
        let stuck = PlanError::Stuck {
            stage: self.stage,
            robot: 0,
            target: Some(to),
        };
        // Vertices a back-off emptied: holes there are not refilled until the parent is in.
        let mut emptied = vec![false; self.map.len()];
        let mut back_offs = 0;
        while self.pos[0] != to {
            let here = self.pos[0];
            let path = self
                .map
                .path_to(here, |u| u == to, |u| !keep(u) || u == to)
                .ok_or(stuck.clone())?;
            if keep(to) && self.child_at(to).is_some() {
                return Err(stuck);
            }
            let next = path[1];
            if emptied[next] {
                emptied.iter_mut().for_each(|e| *e = false);
            }
            if self.child_at(next).is_some() {
                let mut rest = vec![false; self.map.len()];
                for &u in &path[1..] {
                    rest[u] = true;
                }
                let emptied_now = &emptied;
                // Prefer holes off the rest of the path (the children are then not met again).
                let cleared = self.make_way(next, phase, keep, &|u| !rest[u] && !emptied_now[u])
                    || self.make_way(next, phase, keep, &|u| !emptied_now[u]);
                if !cleared {
                    back_offs += 1;
                    if back_offs > MAX_BACK_OFFS {
                        return Err(stuck);
                    }
                    let pocket = self.back_off(next, phase, keep)?;
                    for u in pocket {
                        emptied[u] = true;
                    }
                    continue;
                }
            }
            self.pos[0] = next;
            self.robot_steps += 1;
            self.push(phase, Vec::new());
        }
        Ok(())
    }

    /// Empties the pocket beyond `next` (the vertices reachable from `next` without passing
    /// the parent or a kept vertex; [`Self::drive_parent`] calls this when it holds no empty
    /// vertex): the parent backs off to a stand outside it, and the pocket's children leave
    /// past it. Returns the pocket.
    ///
    /// First the quick rule of [`Self::back_off_from`]: the nearest stand past which the
    /// children can reach as many empty vertices as there are children, counting the
    /// parent's present vertex as one although they leave by it, not onto it. So it can pick
    /// a stand one vertex short (the mouth of a one-vertex-wide dead end: the child could
    /// only stop on the corridor the parent must come back by). Where the children cannot get
    /// out, that attempt is undone and the strict rule stands the parent where the empty
    /// vertices, not counting its own way back, are enough.
    fn back_off(
        &mut self,
        next: Vertex,
        phase: Phase,
        keep: &dyn Fn(Vertex) -> bool,
    ) -> Result<Vec<Vertex>, PlanError> {
        let here = self.pos[0];
        let stuck = PlanError::Stuck {
            stage: self.stage,
            robot: 0,
            target: Some(next),
        };
        // A back-off drives the parent, which may itself back off once more, never deeper.
        if self.backing_off >= 2 {
            return Err(stuck);
        }
        self.backing_off += 1;
        let saved = self.snapshot();
        let mut result = self.back_off_from(here, next, phase, keep, stuck.clone(), false);
        if result.is_err() {
            // The quick stand left the children no way out: undo, and use the strict rule.
            self.restore(saved);
            result = self.back_off_from(here, next, phase, keep, stuck, true);
        }
        self.backing_off -= 1;
        result
    }

    fn back_off_from(
        &mut self,
        here: Vertex,
        next: Vertex,
        phase: Phase,
        keep: &dyn Fn(Vertex) -> bool,
        stuck: PlanError,
        strict: bool,
    ) -> Result<Vec<Vertex>, PlanError> {
        let reach = self.map.distances(next, |u| u != here && !keep(u));
        let pocket: Vec<Vertex> = (0..self.map.len())
            .filter(|&u| reach[u] != usize::MAX)
            .collect();
        let mut in_pocket = vec![false; self.map.len()];
        for &u in &pocket {
            in_pocket[u] = true;
        }
        let leaving = pocket
            .iter()
            .filter(|&&u| self.child_at(u).is_some())
            .count();
        // Candidate stands, nearest first, outside the pocket.
        let from_here = self.map.distances(here, |u| !in_pocket[u] && !keep(u));
        let mut stands: Vec<Vertex> = (0..self.map.len())
            .filter(|&u| from_here[u] != usize::MAX && u != here)
            .collect();
        stands.sort_by_key(|&u| (from_here[u], u));
        if strict {
            // Each candidate costs two breadth-first searches; a stand further than this
            // many vertices away is no longer a back-off.
            stands.truncate(256);
        }
        // The parent's way from a stand back to `here` (strict: the children may not park
        // on it).
        let way_back = |w: Vertex| -> Vec<bool> {
            let mut on = vec![false; self.map.len()];
            if strict {
                let back = self
                    .map
                    .path_to(w, |u| u == here, |u| !in_pocket[u] && !keep(u));
                for u in back.into_iter().flatten() {
                    on[u] = true;
                }
            }
            on
        };
        let stand = stands
            .into_iter()
            .find(|&w| {
                // Empty vertices outside the pocket the children can reach past `w`.
                let out = self.map.distances(here, |u| u != w && !keep(u));
                let back = way_back(w);
                let holes = (0..self.map.len())
                    .filter(|&u| {
                        out[u] != usize::MAX
                            && !in_pocket[u]
                            && u != w
                            && u != here
                            && !back[u]
                            && !self.occupied_by_other(usize::MAX, u)
                    })
                    .count();
                // Quick rule: `here` itself becomes free too once the parent stands on `w`
                // (though the children then leave by it, not onto it).
                holes + usize::from(!strict) >= leaving
            })
            .ok_or(stuck.clone())?;
        let back = way_back(stand);
        // Back off without entering the pocket.
        let keep_out = |u: Vertex| keep(u) || in_pocket[u];
        self.drive_parent(stand, phase, &keep_out)?;
        // The pocket's children leave, nearest to the exit first.
        for _ in 0..leaving {
            let Some(&inside) = pocket
                .iter()
                .filter(|&&u| self.child_at(u).is_some())
                .min_by_key(|&&u| (reach[u], u))
            else {
                break;
            };
            let stand = self.pos[0];
            let exit = self.map.path_to(
                inside,
                // Not the vertex the parent just left: a child parked there would block
                // its way back in.
                |u| {
                    !in_pocket[u]
                        && u != stand
                        && u != here
                        && !back[u]
                        && !self.occupied_by_other(usize::MAX, u)
                },
                |u| u != stand && !keep(u),
            );
            let Some(exit) = exit else {
                return Err(stuck);
            };
            let j = self.child_at(inside).expect("a child stands there");
            // Children outside the pocket on the way step aside first.
            let pinned = |x: Vertex| keep(x) || in_pocket[x] || x == inside;
            let on_exit = |x: Vertex| exit.contains(&x);
            for _ in 0..exit.len() * self.pos.len() {
                let Some(&u) = exit[1..].iter().find(|&&u| self.child_at(u).is_some()) else {
                    break;
                };
                if !self.make_way(u, phase, &pinned, &|x| !on_exit(x)) {
                    return Err(stuck);
                }
            }
            if exit[1..].iter().any(|&u| self.occupied_by_other(j, u)) {
                return Err(stuck);
            }
            for &u in &exit[1..] {
                self.pos[j] = u;
                self.robot_steps += 1;
                self.push(phase, Vec::new());
            }
        }
        Ok(pocket)
    }

    /// Brings some child (whichever is nearest) onto a vertex satisfying `goal`, through
    /// vertices satisfying `within`, and returns it; `None` if no child can get there. A
    /// child cut off by the parent's vertex is let through: the parent steps aside and
    /// comes back (while mapping it must stand on its parent vertex again to track the
    /// child). Where no stand lets a child through and the parent back without crossing the
    /// goal, the last resort is [`Self::let_out_behind`].
    pub(super) fn bring_child(
        &mut self,
        phase: Phase,
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
    ) -> Result<Option<usize>, PlanError> {
        if let Some(j) = self.nearest_child_to(goal, within, self.pos[0]) {
            let at = self.walk_child(j, goal, within, phase);
            return Ok(goal(at).then_some(j));
        }
        // Nobody gets there past the parent: it steps to a stand that lets one through and
        // from which it can come back without crossing the goal. Driving there can push the
        // children it meant to let through (a corridor's children go ahead of the parent),
        // so the choice is made again from where it got to, a few times.
        let home = self.pos[0];
        for _round in 0..4 {
            let here = self.pos[0];
            let from_here = self.map.distances(here, |_| true);
            let mut stands: Vec<Vertex> = (0..self.map.len())
                .filter(|&u| from_here[u] != usize::MAX && u != here && !goal(u))
                .collect();
            stands.sort_by_key(|&u| (from_here[u], u));
            let stand = stands.into_iter().take(256).find(|&w| {
                self.nearest_child_to(goal, within, w).is_some()
                    && self.map.path_to(w, |u| u == home, |u| !goal(u)).is_some()
            });
            let Some(w) = stand else { break };
            if self.drive_parent(w, phase, &|_| false).is_err() {
                break;
            }
            if let Some(j) = self.nearest_child_to(goal, within, w) {
                let at = self.walk_child(j, goal, within, phase);
                let pinned = move |u: Vertex| u == at;
                // Every step made was legal; a parent that cannot get back leaves this
                // vertex unimaged (the next grab drives it back first).
                if self.drive_parent(home, phase, &pinned).is_err() {
                    return Ok(None);
                }
                return Ok(goal(at).then_some(j));
            }
        }
        if self.pos[0] != home {
            // Best effort, as above.
            let _ = self.drive_parent(home, phase, &|_| false);
        }
        if self.pos[0] == home {
            return Ok(self.let_out_behind(phase, goal, within));
        }
        Ok(None)
    }

    /// The last resort of [`Self::bring_child`], with the parent on its vertex `home`, for a
    /// child in a pocket behind it (beyond a neighbour of `home` that only `home` leads to,
    /// the goal outside it) when the goal lies on the parent's only way back from any stand
    /// that would let the child through (a one-vertex-wide corridor with the child in its
    /// dead end). For each such pocket in turn: all its children come out as from a pocket
    /// in the parent's way ([`Self::back_off`]), the parent drives back to `home`, and the
    /// nearest child walks to the goal. Undone, and the next pocket tried, where that does
    /// not get a child there.
    fn let_out_behind(
        &mut self,
        phase: Phase,
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
    ) -> Option<usize> {
        let home = self.pos[0];
        for n in self.map.neighbours(home) {
            if goal(n) {
                continue;
            }
            let reach = self.map.distances(n, |u| u != home);
            let holds_child = (1..self.pos.len()).any(|j| reach[self.pos[j]] != usize::MAX);
            let holds_goal = (0..self.map.len()).any(|u| reach[u] != usize::MAX && goal(u));
            if !holds_child || holds_goal {
                continue;
            }
            let saved = self.snapshot();
            if self.back_off(n, phase, &|_| false).is_ok()
                && self.drive_parent(home, phase, &|_| false).is_ok()
            {
                if let Some(j) = self.nearest_child_to(goal, within, home) {
                    let at = self.walk_child(j, goal, within, phase);
                    if goal(at) {
                        return Some(j);
                    }
                }
            }
            self.restore(saved);
        }
        None
    }

    /// The child with the shortest path to a `goal` vertex through `within` vertices if the
    /// parent stood on `parent_at` (other children on the way are not obstacles: the one
    /// nearest the goal along the way is the one chosen, and its path is free).
    fn nearest_child_to(
        &self,
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
        parent_at: Vertex,
    ) -> Option<usize> {
        // Breadth-first from the goal vertices back to the first child met.
        let starts: Vec<Vertex> = (0..self.map.len())
            .filter(|&v| self.map.is_free(v) && goal(v) && v != parent_at)
            .collect();
        if let Some(j) = starts.iter().find_map(|&v| self.child_at(v)) {
            return Some(j);
        }
        let mut seen = vec![false; self.map.len()];
        for &v in &starts {
            seen[v] = true;
        }
        let mut queue: std::collections::VecDeque<Vertex> = starts.into();
        while let Some(v) = queue.pop_front() {
            for n in self.map.neighbours(v) {
                if seen[n] || n == parent_at {
                    continue;
                }
                if let Some(j) = self.child_at(n) {
                    return Some(j);
                }
                seen[n] = true;
                if within(n) {
                    queue.push_back(n);
                }
            }
        }
        None
    }

    /// Walks child `j` along a shortest free path to a `goal` vertex (one exists: see
    /// [`Self::nearest_child_to`]); returns where it stopped.
    fn walk_child(
        &mut self,
        j: usize,
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
        phase: Phase,
    ) -> Vertex {
        let path = self.map.path_to(
            self.pos[j],
            |u| goal(u) && !self.occupied_by_other(j, u),
            |u| (within(u) || goal(u)) && !self.occupied_by_other(j, u),
        );
        if let Some(path) = path {
            for &u in &path[1..] {
                self.pos[j] = u;
                self.robot_steps += 1;
                self.push(phase, Vec::new());
            }
        }
        self.pos[j]
    }

    /// Brings a child onto `c` with the parent on another vertex that has `c` in its
    /// LOS_free, for a vertex the stage's parent vertex cannot let a child reach (the parent
    /// would have to leave through `c` itself, as at the end of a dead end): the parent
    /// drives to the nearest such stands in turn and lets a child through there, until the
    /// child's view there can be cleared too. (A stand can close the only way out of the
    /// view: on one 1 m map the parent's stand and the grabbing child walled two children
    /// into a pocket in its view; the next stand let them out.) The parent stays on the
    /// stand; the next grab or stage moves it on. Returns the child, on `c` with its view
    /// clear; `None` when no stand served, with the moves made at the stands tried kept
    /// (each legal, as a failed grab's always were).
    pub(super) fn bring_child_from_stand(
        &mut self,
        phase: Phase,
        c: Vertex,
    ) -> Result<Option<usize>, PlanError> {
        let from_here = self.map.distances(self.pos[0], |_| true);
        let mut stands: Vec<Vertex> = self.vis.los[c]
            .iter()
            .copied()
            .filter(|&w| {
                from_here[w] != usize::MAX && self.vis.los_free[w].binary_search(&c).is_ok()
            })
            .collect();
        stands.sort_by_key(|&w| (from_here[w], w));
        for w in stands.into_iter().take(8) {
            if self.drive_parent(w, phase, &|_| false).is_err() {
                continue;
            }
            if let Some(j) = self.bring_child(phase, &|v| v == c, &|_| true)? {
                if self.clear_view(j, c) {
                    return Ok(Some(j));
                }
            }
        }
        Ok(None)
    }
}

#[cfg(test)]
pub(super) mod tests;
