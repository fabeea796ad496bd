//! Re-checks a plan's invariants from its schedule alone.

use crate::execute::Plan;
use crate::map::{Map, Vertex};
use crate::visibility::{in_view, Visibility};
use crate::{CoverageParams, ViewRule};

/// Checks, frame by frame: every move is one up/down/left/right step onto a free vertex; no
/// two robots share a vertex and no two swap; every grab is by a child standing on that
/// vertex, in the parent's LOS_free, with no other robot in view (under
/// [`ViewRule::EveryGrab`]), and each vertex is grabbed
/// once; children never stand on the parent's vertex; and the imaged vertices are exactly
/// V \ V_p minus the reported uncoverable and unreached ones. Returns the first violation.
pub fn validate(map: &Map, params: &CoverageParams, plan: &Plan) -> Result<(), Violation> {
    check(map, params, plan)
}

/// The first invariant a plan breaks, with the timestep and the robots involved.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Violation(pub String);

fn check(map: &Map, params: &CoverageParams, plan: &Plan) -> Result<(), Violation> {
    let vis = Visibility::compute(map, params);
    let mut prev = plan.start.clone();
    let mut grabbed = vec![false; map.len()];
    let radius = |k: usize| {
        if k == 0 {
            params.parent_radius_m
        } else {
            params.child_radius_m
        }
    };
    for (t, frame) in plan.frames.iter().enumerate() {
        let pos = &frame.positions;
        if pos.len() != prev.len() {
            return Err(Violation(format!("timestep {t}: robot count changed")));
        }
        for (k, (&a, &b)) in prev.iter().zip(pos).enumerate() {
            if a != b && !map.adjacent(a, b) {
                return Err(Violation(format!(
                    "timestep {t} ({:?}, stage {}): robot {k} jumped from {:?} to {:?}",
                    frame.phase,
                    frame.stage,
                    map.cell(a),
                    map.cell(b)
                )));
            }
            if !map.is_free(b) {
                return Err(Violation(format!(
                    "timestep {t}: robot {k} on an occupied cell {:?}",
                    map.cell(b)
                )));
            }
        }
        for i in 0..pos.len() {
            for j in i + 1..pos.len() {
                if pos[i] == pos[j] {
                    return Err(Violation(format!(
                        "timestep {t}: robots {i} and {j} share {:?}",
                        map.cell(pos[i])
                    )));
                }
                if pos[i] == prev[j] && pos[j] == prev[i] {
                    return Err(Violation(format!(
                        "timestep {t}: robots {i} and {j} swapped places"
                    )));
                }
            }
        }
        for &(child, v) in &frame.grabs {
            let robot = child + 1;
            if pos[robot] != v {
                return Err(Violation(format!(
                    "timestep {t}: child {child} grabbed at {:?} standing on {:?}",
                    map.cell(v),
                    map.cell(pos[robot])
                )));
            }
            if grabbed[v] {
                return Err(Violation(format!(
                    "timestep {t}: {:?} grabbed twice",
                    map.cell(v)
                )));
            }
            grabbed[v] = true;
            if vis.los_free[pos[0]].binary_search(&v).is_err() {
                return Err(Violation(format!(
                    "timestep {t}: {:?} is not in LOS_free of the parent at {:?}",
                    map.cell(v),
                    map.cell(pos[0])
                )));
            }
            for (k, &u) in pos.iter().enumerate() {
                if params.views == ViewRule::EveryGrab
                    && k != robot
                    && in_view(map, params, v, u, radius(k))
                {
                    return Err(Violation(format!("timestep {t}: robot {k} at {:?} is in the view of child {child} grabbing at {:?}", map.cell(u), map.cell(v))));
                }
            }
        }
        prev = pos.clone();
    }
    let mut expected: Vec<Vertex> = map.vertices();
    expected.retain(|v| {
        !plan.parent_vertices.contains(v)
            && !plan.uncoverable.contains(v)
            && !plan.unreached.contains(v)
    });
    let got: Vec<Vertex> = (0..map.len()).filter(|&v| grabbed[v]).collect();
    if got != expected {
        let missing: Vec<_> = expected
            .iter()
            .filter(|v| !grabbed[**v])
            .map(|&v| map.cell(v))
            .take(5)
            .collect();
        return Err(Violation(format!(
            "imaged {} vertices, expected {}; missing e.g. {missing:?}",
            got.len(),
            expected.len()
        )));
    }
    let mut from_sets: Vec<Vertex> = plan
        .child_sets
        .iter()
        .flatten()
        .chain(&plan.revisited)
        .copied()
        .collect();
    from_sets.sort_unstable();
    if from_sets != got {
        return Err(Violation(
            "the child sets C(t) do not match the grabs".to_string(),
        ));
    }
    Ok(())
}
