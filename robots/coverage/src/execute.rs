//! Executing a mission at the grid level, one timestep at a time (Sections IV.C-D, V.A).
//!
//! Decisions:
//! * **Timestep.** A timestep is the time of one up/down/left/right step of a robot, and
//!   every robot may step in the same timestep. While mapping, the children walk their
//!   roadmaps in parallel (a child whose next vertex is taken waits, or walks around a
//!   robot that will not move). Stage transitions move the team together ([`together`]):
//!   the parent tracks and teleoperates all children at once, as in the behaviour-based
//!   formations of the paper's [17], so a transition costs about as many timesteps as its
//!   longest walk, and coordination grows with N only by the time to gather and spread
//!   (until 2026-11 coordination moved one robot at a time and grew linearly with N). Robots
//!   step in a fixed order onto vertices nobody holds at that moment: a train (a robot
//!   entering the vertex another leaves) is allowed, a shared vertex or a swap never.
//! * **Mapping vs coordination.** Timesteps of a stage's mapping (children walking their
//!   roadmaps and grabbing) are mapping timesteps; moving between stages, the following
//!   behaviour included, are coordination timesteps. Reaching a stage's start points is
//!   mapping (it happens inside the stage).
//! * **Image grabs** take no extra timestep. A child grabs when it stands on an unimaged
//!   child vertex of the stage and, under [`ViewRule::EveryGrab`], no other robot is in its
//!   view (the view cone of [`crate::visibility`], robots as discs, at any distance). A child
//!   with a walking robot in view waits for it to pass; a child done with its walk that
//!   stands in the view steps out of it to the nearest vertex outside it while the grabbing
//!   child waits; one whose view holds the parent or a child itself waiting (or a done
//!   child with no way out) leaves the vertex and walks on. (Until 2026-11 a child done
//!   with its walk stayed where it was and the vertex was left; measured effect: docs/coverage-planning.md,
//!   "Mapping with many children".) A stage runs in rounds: a round ends as soon as a
//!   child is idle (its walk done, or none given) while another still walks, and what is
//!   still to image gets new roadmaps from where the children stand, so that the idle child
//!   takes a share of it (before 2026-11-28 a round ran until every walk was done: on three
//!   20 % maps at r_los 8 m with 8 children, 44 % of the children's round timesteps were
//!   spent done with their walks, and mapping rose beyond 4 children; measured effect:
//!   docs/coverage-planning.md, "Mapping with many children"). Rounds go on while each images anything; the
//!   rest is mopped up one vertex at a time (the nearest child goes there, robots in its
//!   view step out of it, it grabs). Under [`ViewRule::StartPoints`] (a relaxation, for
//!   comparison with the paper) only the stages' starting points are kept out of each
//!   other's views.
//! * **C(t)** is LOS_free(v_p^t) minus V_p minus what is already imaged, so a vertex a stage
//!   could not image is tried again by later stages; what no stage images is reported.
//! * **Transitions (Eq. 8).** H = LOS(v_p^t) ∩ LOS(v_p^(t+1)) without the two parent
//!   vertices. If |H| >= N and the children can get to N distinct vertices of it (those off
//!   the parent's path when there are N of them), they move there together, then the parent
//!   drives its shortest path (children in its way make way). Otherwise a following
//!   behaviour is counted: children on the parent's path step off it, the parent drives with
//!   the children in file behind it, and they spread into LOS(v_p^(t+1)) together (as many
//!   as it has free vertices for, the nearest child going deepest).
//! * **Start.** The parent first drives from its start vertex to the first parent vertex in
//!   the same way. Children given no start vertices stand on the free vertices nearest the
//!   parent (breadth-first order) that are not dead ends.
//! * **Robots in each other's way** ([`moves`]). Moves are single steps between free
//!   vertices and robots never pass each other, so in a one-vertex-wide passage robots make
//!   way: children shift towards the nearest empty vertex, the parent backs off to let a
//!   pocket of children out, or steps aside to let one behind it. A vertex a stage still
//!   cannot image with the parent on its parent vertex is imaged from another vertex that
//!   sees it freely, in the stage or after the tour (`revisited`). A transition that fails
//!   all the same skips its stage (`skipped_stages`; none on the Table I-II sweeps), and what
//!   nothing images is `unreached`, apart from `uncoverable` (vertices no vertex the parent
//!   can reach sees freely).

use crate::map::{Map, Vertex};
use crate::roadmap::stage_roadmaps;
use crate::select::{select_parent_vertices, tour};
use crate::visibility::{in_view, Visibility};
use crate::{CoverageParams, Reading, ViewRule};
use serde::Serialize;

mod moves;
mod stage;
mod together;

/// How many times the after-tour loop tries a vertex the stages left. A try that fails
/// is made again after another vertex is imaged, since the team then stands otherwise: in
/// a dead-end pocket, a grabbing child with children walled in its view ahead of it fails,
/// and the next vertex's try lets them out and brings one child in alone (an 8 x 8 m map
/// at 40 % with merged obstacles, 4 children: `tests/tests/it/coverage.rs`'s invariants).
const REVISIT_TRIES: u8 = 2;

/// Why a stage transition was a following behaviour (Section IV.D).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Following {
    /// Fewer than N vertices in H (Eq. 8): the paper's test.
    FewInH,
    /// H holds at least N vertices (those off the parent's path where there are N of them),
    /// but the children cannot all get to them through LOS(v_p^t), where the parent can
    /// track them; ours, since the paper does not say what happens then (docs/coverage-planning.md,
    /// "Transitions and following behaviours").
    HOutOfReach,
}

/// Which part of the mission a timestep belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Children walking a stage's roadmaps and grabbing images.
    Mapping,
    /// Moving the team between parent vertices.
    Coordination,
}

/// The state after one timestep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Frame {
    /// Mapping or coordination.
    pub phase: Phase,
    /// Index of the stage (parent vertex in tour order) this timestep belongs to.
    pub stage: usize,
    /// Robot positions after the step: the parent first, then the children.
    pub positions: Vec<Vertex>,
    /// Images grabbed at the end of this timestep: (child index, vertex).
    pub grabs: Vec<(usize, Vertex)>,
}

/// A whole mission.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Plan {
    /// Number of vertices |V|.
    pub vertices: usize,
    /// V_p in visiting order.
    pub parent_vertices: Vec<Vertex>,
    /// C(t) as imaged, per stage.
    pub child_sets: Vec<Vec<Vertex>>,
    /// Vertices of V \ V_p that no vertex the parent can reach has in its LOS_free: no
    /// parent placement lets a child image them.
    pub uncoverable: Vec<Vertex>,
    /// Vertices some vertex the parent can reach sees freely, but that were not imaged
    /// because the team could not get there (none expected; see `skipped_stages`).
    pub unreached: Vec<Vertex>,
    /// Stages (indices into `parent_vertices`) skipped because the team could not be moved
    /// there (none on the Table I-II sweeps, and `hetsim regress` requires none: the moves of
    /// `execute/moves.rs` let robots by each other; the after-tour revisits image what a
    /// skipped stage would have).
    pub skipped_stages: Vec<usize>,
    /// Vertices imaged after the tour, with the parent on a vertex (not necessarily a
    /// parent vertex) that has them in its LOS_free: those the stages left (a view the team
    /// could not clear, a vertex the stand could not serve). Within a stage, a vertex the
    /// parent vertex cannot serve is imaged from such a stand too, and counted in that
    /// stage's `child_sets`.
    pub revisited: Vec<Vertex>,
    /// Positions at the start: the parent, then the children.
    pub start: Vec<Vertex>,
    /// The schedule.
    pub frames: Vec<Frame>,
    /// Timesteps spent mapping.
    pub mapping_timesteps: usize,
    /// Timesteps spent moving between stages.
    pub coordination_timesteps: usize,
    /// Stage transitions done by the following behaviour.
    pub following_behaviours: usize,
    /// Of `following_behaviours`, those in which H held at least N vertices but the children
    /// could not all get to them through LOS(v_p^t), where the parent can track them
    /// (ours: the paper does not say what happens then); the rest are the paper's |H| < N.
    pub following_out_of_reach: usize,
    /// Unit steps of all robots together.
    pub robot_steps: usize,
}

impl Plan {
    /// Images grabbed over V \ V_p.
    pub fn coverage(&self) -> f64 {
        self.imaged_fraction(self.vertices - self.parent_vertices.len())
    }

    /// Images grabbed over the vertices of V \ V_p that some vertex sees freely: Eq. 4
    /// promises 1 where every vertex is seen freely by some vertex, and the team's moves
    /// keep that promise on every vertex that is.
    pub fn coverable_coverage(&self) -> f64 {
        self.imaged_fraction(self.vertices - self.parent_vertices.len() - self.uncoverable.len())
    }

    /// Images grabbed (in the stages and after the tour) over `target` vertices.
    fn imaged_fraction(&self, target: usize) -> f64 {
        let imaged = self.child_sets.iter().map(Vec::len).sum::<usize>() + self.revisited.len();
        if target == 0 {
            1.0
        } else {
            imaged as f64 / target as f64
        }
    }
}

/// Why a plan could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A start vertex is occupied or outside the map.
    #[error("start vertex {0} is not a free vertex of the map")]
    BadStart(Vertex),
    /// Two robots start on the same vertex.
    #[error("two robots start on vertex {0}")]
    SharedStart(Vertex),
    /// A robot could not be moved without a collision.
    #[error("stage {stage}: robot {robot} cannot reach {target:?} without passing another robot")]
    Stuck {
        /// The stage.
        stage: usize,
        /// The robot (0 is the parent).
        robot: usize,
        /// Where it was going.
        target: Option<Vertex>,
    },
}

/// A point of a [`Run`] to go back to ([`Run::snapshot`]).
struct Snapshot {
    pos: Vec<Vertex>,
    frames: usize,
    robot_steps: usize,
}

struct Run<'a> {
    map: &'a Map,
    params: &'a CoverageParams,
    vis: &'a Visibility,
    pos: Vec<Vertex>,
    frames: Vec<Frame>,
    imaged: Vec<bool>,
    robot_steps: usize,
    stage: usize,
    /// Nesting of the parent's back-offs ([`moves`]).
    backing_off: usize,
}

impl Run<'_> {
    fn occupied_by_other(&self, robot: usize, v: Vertex) -> bool {
        self.pos
            .iter()
            .enumerate()
            .any(|(k, &p)| k != robot && p == v)
    }

    fn radius(&self, robot: usize) -> f64 {
        if robot == 0 {
            self.params.parent_radius_m
        } else {
            self.params.child_radius_m
        }
    }

    /// Whether child `robot` standing on `at` has another robot in view.
    fn view_blocked(&self, robot: usize, at: Vertex) -> bool {
        self.pos
            .iter()
            .enumerate()
            .any(|(k, &u)| k != robot && in_view(self.map, self.params, at, u, self.radius(k)))
    }

    /// Where the robots stand and how far the schedule got, to undo moves that led nowhere.
    fn snapshot(&self) -> Snapshot {
        Snapshot {
            pos: self.pos.clone(),
            frames: self.frames.len(),
            robot_steps: self.robot_steps,
        }
    }

    /// Undoes every move made since `saved` was taken.
    fn restore(&mut self, saved: Snapshot) {
        self.pos = saved.pos;
        self.frames.truncate(saved.frames);
        self.robot_steps = saved.robot_steps;
    }

    fn push(&mut self, phase: Phase, grabs: Vec<(usize, Vertex)>) {
        self.frames.push(Frame {
            phase,
            stage: self.stage,
            positions: self.pos.clone(),
            grabs,
        });
    }

    /// Moves one robot alone along a shortest path (avoiding the others) to the first vertex
    /// satisfying `goal`, one frame per step. When other children block every such path,
    /// the path is planned through them and each blocking child is first pushed off it to
    /// the nearest vertex that is not on it (recursively, at most one level per robot). While
    /// coordinating, the parent may be pushed aside too; while mapping, never. Returns where
    /// the robot ended.
    fn walk_alone(
        &mut self,
        robot: usize,
        phase: Phase,
        goal: impl Fn(Vertex) -> bool,
        within: impl Fn(Vertex) -> bool,
    ) -> Result<Vertex, PlanError> {
        self.walk_pushing(robot, phase, &goal, &within, 0)
    }

    fn walk_pushing(
        &mut self,
        robot: usize,
        phase: Phase,
        goal: &dyn Fn(Vertex) -> bool,
        within: &dyn Fn(Vertex) -> bool,
        depth: usize,
    ) -> Result<Vertex, PlanError> {
        let stuck = PlanError::Stuck {
            stage: self.stage,
            robot,
            target: None,
        };
        // While coordinating, the parent may step aside too; while mapping it holds its
        // parent vertex.
        let push_parent = phase == Phase::Coordination;
        for _attempt in 0..4 * self.pos.len() {
            if let Some(path) = self.map.path_to(self.pos[robot], goal, |v| {
                within(v) && !self.occupied_by_other(robot, v)
            }) {
                for &v in &path[1..] {
                    self.pos[robot] = v;
                    self.robot_steps += 1;
                    self.push(phase, Vec::new());
                }
                return Ok(self.pos[robot]);
            }
            if depth > self.pos.len() {
                return Err(stuck);
            }
            let parent_at = self.pos[0];
            let through = self
                .map
                .path_to(self.pos[robot], goal, |v| {
                    within(v) && (robot == 0 || push_parent || v != parent_at)
                })
                .ok_or(stuck.clone())?;
            let mut on_path = vec![false; self.map.len()];
            for &v in &through {
                on_path[v] = true;
            }
            let first = if push_parent { 0 } else { 1 };
            let blocker = through[1..]
                .iter()
                .find_map(|&v| (first..self.pos.len()).find(|&k| k != robot && self.pos[k] == v));
            let Some(b) = blocker else { return Err(stuck) };
            let me = self.pos[robot];
            let on_path = &on_path;
            let off = move |u: Vertex| !on_path[u] && u != me;
            // A pushed robot never plans through the robot pushing it (that would only push
            // the pusher back), nor, if it is a child, through the parent.
            let keep = move |u: Vertex| u != me && (b == 0 || u != parent_at);
            self.walk_pushing(b, phase, &off, &keep, depth + 1)?;
        }
        Err(stuck)
    }
}

/// Plans and executes the whole mission for a map, with the parent starting on
/// `parent_start` and the children on `child_starts` (or, if empty, on the free vertices
/// nearest the parent).
pub fn plan(
    map: &Map,
    params: &CoverageParams,
    parent_start: Vertex,
    child_starts: &[Vertex],
) -> Result<Plan, PlanError> {
    let vis = Visibility::compute(map, params);
    plan_with(map, params, &vis, parent_start, child_starts)
}

/// [`plan`] with precomputed visibility.
pub fn plan_with(
    map: &Map,
    params: &CoverageParams,
    vis: &Visibility,
    parent_start: Vertex,
    child_starts: &[Vertex],
) -> Result<Plan, PlanError> {
    if parent_start >= map.len() || !map.is_free(parent_start) {
        return Err(PlanError::BadStart(parent_start));
    }
    let start = start_positions(map, params, parent_start, child_starts);
    check_starts(map, &start)?;
    let selection = select_parent_vertices(map, vis, params);
    // Parent vertices the parent cannot reach (another free-space component) are dropped:
    // what only they could see is reported as uncoverable.
    let (order, _unreachable_parents) = tour(map, &selection.chosen, parent_start, params.reading);
    let mut is_parent = vec![false; map.len()];
    for &p in &order {
        is_parent[p] = true;
    }
    let mut run = Run {
        map,
        params,
        vis,
        pos: start.clone(),
        frames: Vec::new(),
        imaged: vec![false; map.len()],
        robot_steps: 0,
        stage: 0,
        backing_off: 0,
    };
    let stages = run.run_stages(&order, &is_parent)?;
    let seen = seen_freely(map, vis, parent_start);
    // What the stages left: one vertex at a time, nearest to the parent first, from
    // whichever vertex that sees it freely a child can get there.
    run.stage = order.len();
    let revisited = run.revisit_left(&seen, &is_parent)?;
    let (unreached, uncoverable): (Vec<Vertex>, Vec<Vertex>) = map
        .vertices()
        .into_iter()
        .filter(|&v| !is_parent[v] && !run.imaged[v])
        .partition(|&v| seen[v]);
    let mapping_timesteps = run
        .frames
        .iter()
        .filter(|f| f.phase == Phase::Mapping)
        .count();
    let coordination_timesteps = run.frames.len() - mapping_timesteps;
    Ok(Plan {
        vertices: map.vertices().len(),
        parent_vertices: order,
        child_sets: stages.child_sets,
        uncoverable,
        unreached,
        skipped_stages: stages.skipped_stages,
        revisited,
        start,
        mapping_timesteps,
        coordination_timesteps,
        following_behaviours: stages.following_behaviours,
        following_out_of_reach: stages.following_out_of_reach,
        robot_steps: run.robot_steps,
        frames: run.frames,
    })
}

/// Where the robots start: the parent on `parent_start`, the children on `child_starts`
/// or, if empty, on the free vertices nearest the parent.
fn start_positions(
    map: &Map,
    params: &CoverageParams,
    parent_start: Vertex,
    child_starts: &[Vertex],
) -> Vec<Vertex> {
    let mut start = vec![parent_start];
    if child_starts.is_empty() {
        let dist = map.distances(parent_start, |_| true);
        // Nearest first, but never in a dead end (a child there could be shut in by the
        // parent).
        let mut near: Vec<Vertex> = map
            .vertices()
            .into_iter()
            .filter(|&v| {
                v != parent_start && dist[v] != usize::MAX && map.neighbours(v).count() >= 2
            })
            .collect();
        near.sort_by_key(|&v| (dist[v], v));
        start.extend(near.into_iter().take(params.children));
    } else {
        start.extend_from_slice(child_starts);
    }
    start
}

/// Checks that every start is a free vertex of the map and no two robots share one.
fn check_starts(map: &Map, start: &[Vertex]) -> Result<(), PlanError> {
    for (k, &s) in start.iter().enumerate() {
        if s >= map.len() || !map.is_free(s) {
            return Err(PlanError::BadStart(s));
        }
        if start[..k].contains(&s) {
            return Err(PlanError::SharedStart(s));
        }
    }
    Ok(())
}

/// `seen[w]`: some vertex the parent can get to from `parent_start` has `w` in its
/// LOS_free.
fn seen_freely(map: &Map, vis: &Visibility, parent_start: Vertex) -> Vec<bool> {
    // Seen freely from a vertex the parent can get to (a free-space component of its own
    // is no parent placement's to see).
    let reachable = map.distances(parent_start, |_| true);
    let mut seen = vec![false; map.len()];
    for v in map.vertices() {
        if reachable[v] == usize::MAX {
            continue;
        }
        for &w in &vis.los_free[v] {
            seen[w] = true;
        }
    }
    seen
}

/// What the stages of the tour did, for the [`Plan`].
struct StagesDone {
    /// C(t) as imaged, per stage (empty for a skipped stage).
    child_sets: Vec<Vec<Vertex>>,
    /// Stage transitions done by the following behaviour.
    following_behaviours: usize,
    /// Of those, the ones where H was out of the children's reach.
    following_out_of_reach: usize,
    /// Stages the team could not be moved to.
    skipped_stages: Vec<usize>,
}

impl Run<'_> {
    /// Runs the stages of the tour `order`: each transition, then its mapping.
    fn run_stages(
        &mut self,
        order: &[Vertex],
        is_parent: &[bool],
    ) -> Result<StagesDone, PlanError> {
        let vis = self.vis;
        let mut child_sets = Vec::new();
        let mut following_behaviours = 0;
        let mut following_out_of_reach = 0;
        let mut skipped_stages = Vec::new();
        for (t, &vp) in order.iter().enumerate() {
            self.stage = t;
            match self.transition(vp) {
                Ok(Some(cause)) => {
                    following_behaviours += 1;
                    following_out_of_reach += usize::from(cause == Following::HOutOfReach);
                }
                Ok(None) => {}
                Err(_) => {
                    // Every step made so far was legal; the team simply stays where it got to
                    // and later stages pick up this stage's vertices.
                    skipped_stages.push(t);
                    child_sets.push(Vec::new());
                    continue;
                }
            }
            let set: Vec<Vertex> = vis.los_free[vp]
                .iter()
                .copied()
                .filter(|&v| !is_parent[v] && !self.imaged[v])
                .collect();
            child_sets.push(self.map_stage(&set)?);
        }
        Ok(StagesDone {
            child_sets,
            following_behaviours,
            following_out_of_reach,
            skipped_stages,
        })
    }

    /// Images what the stages left among the vertices `seen` freely, one vertex at a time;
    /// returns those imaged, in order.
    fn revisit_left(
        &mut self,
        seen: &[bool],
        is_parent: &[bool],
    ) -> Result<Vec<Vertex>, PlanError> {
        let mut revisited = Vec::new();
        // A vertex whose try failed is tried again only after another one was imaged (the
        // team then stands otherwise), at most REVISIT_TRIES times in all.
        let (mut tries, mut failed_after): (Vec<u8>, Vec<Option<usize>>) =
            (vec![0; self.map.len()], vec![None; self.map.len()]);
        while let Some(c) = self.next_left(seen, is_parent, &tries, &failed_after, revisited.len())
        {
            tries[c] += 1;
            match self.revisit(c)? {
                Some(j) => {
                    self.imaged[c] = true;
                    revisited.push(c);
                    if let Some(last) = self.frames.last_mut() {
                        last.grabs.push((j, c));
                    }
                }
                None => failed_after[c] = Some(revisited.len()),
            }
        }
        Ok(revisited)
    }

    /// The next vertex left to try: seen freely, not imaged, a try still due after
    /// `revisited` vertices were imaged, and the nearest one the parent can get to.
    fn next_left(
        &self,
        seen: &[bool],
        is_parent: &[bool],
        tries: &[u8],
        failed_after: &[Option<usize>],
        revisited: usize,
    ) -> Option<Vertex> {
        let map = self.map;
        let from_parent = map.distances(self.pos[0], |_| true);
        let eligible =
            |v: Vertex| tries[v] < REVISIT_TRIES && failed_after[v].is_none_or(|n| n < revisited);
        map.vertices()
            .into_iter()
            .filter(|&v| seen[v] && !is_parent[v] && !self.imaged[v] && eligible(v))
            .filter(|&v| from_parent[v] != usize::MAX)
            .min_by_key(|&v| (from_parent[v], v))
    }
}
