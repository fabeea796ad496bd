//! The plan's execution, timestep by timestep: planning from the start, each timestep's
//! moves (a robot moving onto a vertex another leaves waits until that one has arrived),
//! then its grabs, then the next timestep (see the parent's module notes, "Execution").

use super::*;

impl ParentStack {
    fn idle(&self) -> bool {
        self.waiting.is_empty()
            && self.pilot.is_none()
            && self.children.iter().all(|c| c.task == Task::Idle)
    }

    /// Starts the next timestep's moves or grabs when everything is idle.
    pub(super) fn advance(&mut self) {
        let Some(plan) = self.plan.as_ref() else {
            return;
        };
        let total = plan.frames.len();
        // Each timestep: its moves, then (all robots arrived) its grabs, then (all images
        // in) the next timestep.
        while self.idle() && self.report.finished_ns.is_none() {
            if self.step_index >= total {
                self.report.finished_ns = Some(self.now_ns);
                return;
            }
            let plan = self.plan.as_ref().expect("planned");
            if !self.moves_started {
                self.moves_started = true;
                let previous = if self.step_index == 0 {
                    plan.start.clone()
                } else {
                    plan.frames[self.step_index - 1].positions.clone()
                };
                let next = plan.frames[self.step_index].positions.clone();
                // A robot moving onto a vertex another robot leaves in the same timestep (a
                // train) waits until that robot has arrived at its own target.
                for r in 0..next.len() {
                    if next[r] == previous[r] {
                        continue;
                    }
                    let blocker = (0..next.len())
                        .find(|&q| q != r && previous[q] == next[r] && next[q] != previous[q]);
                    self.waiting.push((r, next[r], blocker));
                }
                self.release_waiting();
            } else if !self.grabbing {
                let grabs = plan.frames[self.step_index].grabs.clone();
                // The grabbing children's views where the parent tracks the robots: a child
                // off its vertex in one is driven back onto it first (`parent/views.rs`).
                let (movers, seen) = self.views_to_clear(&grabs);
                if !movers.is_empty() && self.recentres < views::RECENTRES {
                    self.recentres += 1;
                    self.report.view_recentres += movers.len() as u32;
                    for k in movers {
                        let goal = self.children[k].planned;
                        self.start_move(k, goal, 0);
                    }
                    continue;
                }
                self.report.grabs_with_tracked_robot_in_view += seen;
                self.grabbing = true;
                let heading = {
                    let (x, y) = self.coverage.direction.unit();
                    y.atan2(x)
                };
                for (child, v) in grabs {
                    let cell = self.map.cell(v);
                    self.order(
                        child,
                        Order::Grab {
                            heading_rad: heading,
                            vertex: cell,
                        },
                    );
                    self.children[child].task = Task::Grab {
                        vertex: cell,
                        sent_ns: self.now_ns,
                        fixes: ([0.0; 2], 0),
                    };
                }
            } else {
                self.step_index += 1;
                self.report.steps_done = self.step_index;
                self.moves_started = false;
                self.grabbing = false;
                self.recentres = 0;
            }
        }
    }

    /// Starts the moves of the timestep whose way is clear.
    pub(super) fn release_waiting(&mut self) {
        let mut still = Vec::new();
        let waiting = std::mem::take(&mut self.waiting);
        // Robots whose own move has not finished yet: their start or their move is pending.
        let busy = |s: &Self, q: usize| {
            waiting.iter().any(|w| w.0 == q)
                || if q == 0 {
                    s.pilot.is_some()
                } else {
                    s.children[q - 1].task != Task::Idle
                }
        };
        let mut started = Vec::new();
        for &(r, target, blocker) in &waiting {
            if blocker.is_some_and(|q| busy(self, q)) {
                still.push((r, target, blocker));
                continue;
            }
            started.push(r);
        }
        for &(r, target, _) in waiting.iter().filter(|w| started.contains(&w.0)) {
            let goal = self.centre(target);
            if r == 0 {
                self.pilot = Some(GroundPilot::new(
                    self.params.pilot,
                    Mission::Waypoints(vec![[goal[0], goal[1], 0.0]]),
                ));
            } else {
                self.start_move(r - 1, goal, 0);
            }
        }
        self.waiting = still;
    }

    /// Plans the mission from where the parent stands and the children's start vertices;
    /// a mission without a plan is over at once.
    pub(super) fn make_plan(&mut self, pose: &Pose) {
        let here = [pose.translation.vector.x, pose.translation.vector.y];
        let starts: Option<Vec<Vertex>> = self
            .mission
            .children
            .iter()
            .map(|(_, (c, r))| self.map.at(*c as i64, *r as i64))
            .collect();
        let result = match (self.vertex_at(here), starts) {
            (Some(p), Some(kids)) => plan(&self.map, &self.coverage, p, &kids).ok(),
            _ => None,
        };
        match result {
            Some(p) => {
                self.report.vertices = p.vertices;
                self.report.parent_vertices = p
                    .parent_vertices
                    .iter()
                    .map(|v| self.map.cell(*v))
                    .collect();
                self.report.unplanned = p
                    .uncoverable
                    .iter()
                    .chain(&p.unreached)
                    .map(|v| self.map.cell(*v))
                    .collect();
                self.report.steps_total = p.frames.len();
                self.plan = Some(p);
            }
            None => {
                self.plan_failed = true;
                self.report.finished_ns = Some(self.now_ns);
            }
        }
    }
}
