//! Grid-level coverage planning of a scenario's parent/child team (seed 002, Section V.A).

use crate::EvalError;
use hetsim_coverage::{plan, CoverageParams, Map, Plan, Vertex};
use hetsim_scene::Scenario;
use serde::{Deserialize, Serialize};

/// The figures of Tables I and II and Figs. 3 and 4, for one plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoverageMetrics {
    /// |V|.
    pub vertices: usize,
    /// |V_p| = Q.
    pub parent_vertices: usize,
    /// Following behaviours executed.
    pub following: usize,
    /// Of `following`, those in which H held at least N vertices but the children could not
    /// all get to them within the parent's line of sight (ours; the rest are the paper's
    /// |H| < N).
    pub following_out_of_reach: usize,
    /// Mapping timesteps.
    pub mapping_timesteps: usize,
    /// Coordination timesteps.
    pub coordination_timesteps: usize,
    /// Mapping plus coordination.
    pub total_timesteps: usize,
    /// Imaged fraction of V \ V_p.
    pub coverage: f64,
    /// Imaged fraction of the vertices some vertex sees freely (V \ V_p without the
    /// uncoverable ones): 1 unless the team failed to get somewhere it could have imaged
    /// (Eq. 4's promise where its assumption holds).
    pub coverable_coverage: f64,
    /// Stages the team could not be moved to (0 expected).
    pub skipped_stages: usize,
    /// Vertices imaged after the tour from another vertex that sees them freely.
    pub revisited: usize,
    /// Vertices no vertex the parent can reach sees freely.
    pub uncoverable: usize,
    /// Visible vertices the team could not reach.
    pub unreached: usize,
    /// Unit steps of all robots.
    pub robot_steps: usize,
}

impl CoverageMetrics {
    /// The metrics of a plan.
    pub fn of(plan: &Plan) -> Self {
        Self {
            vertices: plan.vertices,
            parent_vertices: plan.parent_vertices.len(),
            following: plan.following_behaviours,
            following_out_of_reach: plan.following_out_of_reach,
            mapping_timesteps: plan.mapping_timesteps,
            coordination_timesteps: plan.coordination_timesteps,
            total_timesteps: plan.mapping_timesteps + plan.coordination_timesteps,
            coverage: plan.coverage(),
            coverable_coverage: plan.coverable_coverage(),
            skipped_stages: plan.skipped_stages.len(),
            revisited: plan.revisited.len(),
            uncoverable: plan.uncoverable.len(),
            unreached: plan.unreached.len(),
            robot_steps: plan.robot_steps,
        }
    }
}

/// Plans the coverage mission of an indoor scenario on its ground-truth grid. The parent
/// starts on the vertex under the scenario's `parent` robot (or the first robot); the
/// children on their robots' vertices when the scenario places exactly N of them, else next
/// to the parent.
pub fn plan_scenario(scenario: &Scenario) -> Result<(Map, CoverageParams, Plan), EvalError> {
    plan_scenario_with(scenario, None)
}

/// [`plan_scenario`] with `children` children instead of the scenario's number (they then
/// start next to the parent unless the scenario places exactly that many).
pub fn plan_scenario_with(
    scenario: &Scenario,
    children: Option<usize>,
) -> Result<(Map, CoverageParams, Plan), EvalError> {
    let grid = &scenario
        .world
        .grid
        .as_ref()
        .ok_or_else(|| EvalError::Plan("needs an indoor_grid world".into()))?
        .grid;
    let map = Map::from_grid(grid);
    let mut params = hetsim_scene::coverage_params(scenario);
    if let Some(n) = children {
        params.children = n;
    }
    let vertex_of =
        |x: f64, y: f64| -> Option<Vertex> { grid.cell_of(x, y).map(|(c, r)| r * grid.cols + c) };
    let parent = scenario
        .robots
        .iter()
        .find(|r| r.model.has_laser())
        .or(scenario.robots.first())
        .ok_or_else(|| EvalError::Plan("no robots".into()))?;
    let parent_start = vertex_of(parent.spec.start.x, parent.spec.start.y)
        .ok_or_else(|| EvalError::Plan("the parent starts outside the grid".into()))?;
    let kids: Vec<Vertex> = scenario
        .robots
        .iter()
        .filter(|r| r.model.is_tracked_child())
        .filter_map(|r| vertex_of(r.spec.start.x, r.spec.start.y))
        .collect();
    let child_starts = if kids.len() == params.children {
        kids
    } else {
        Vec::new()
    };
    let plan = plan(&map, &params, parent_start, &child_starts)
        .map_err(|e| EvalError::Plan(e.to_string()))?;
    Ok((map, params, plan))
}
