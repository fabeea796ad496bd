//! The view rule at grab time, on the parent's own estimates.
//!
//! The plan keeps every robot out of each grabbing child's view with the robots on their
//! vertices, each grown by `view_margin_m` for how far it may stand off its vertex. The
//! teleoperation accepts a child within `arrive_m` of its goal, stops correcting after three
//! corrections wherever it is, and drives an idle child back in the tracker's view back only
//! when it is more than `2 arrive_m` (0.14 m) off: a child standing off its vertex can show
//! in another's image though the plan is clear (indoor-team with a 0.04 m margin,
//! 2026-11-28: one image with a child 2.3 m away that stood 0.10 m off its vertex).
//!
//! So before it orders a timestep's grabs, the parent looks at each grabbing child's view
//! with the robots where it believes they are (its hat tracker's estimates, dead reckoning
//! for a child out of the tracker's range, its own laser pose).
//! A child it finds in a view that would be clear with the two children on their vertices
//! is driven back onto its vertex first (and the grabbing child too, if it is off its own),
//! at most [`RECENTRES`] times a timestep. What is still in view after that, or in view
//! with everyone on their vertices (only the planner's margins can allow that), is counted
//! (`grabs_with_tracked_robot_in_view`) and the grab goes ahead: the check uses estimates,
//! and the grab must not wait forever on a tracker's error. A child out of the tracker's
//! range is where dead reckoning puts it, which can be a decimetre from the truth: for
//! those the planner's `view_margin_m` must do (indoor-team keeps 0.12 m for that).

use super::*;
use crate::visibility::{segment_open, ALONG, FINE};

/// Rounds of driving children back onto their vertices before one timestep's grabs.
pub(super) const RECENTRES: u32 = 2;

/// A child nearer its vertex than this is on it, metres (the hat tracker's error within
/// r_los: 0.012-0.016 m mean in the lab and indoor-team).
const ON_VERTEX_M: f64 = 0.03;

/// Whether a robot whose centre is at `at` is in the view of a camera at `from` that looks
/// along the direction of mapping. Positions are in cells of `map` (vertex `(c, r)`'s
/// centre is at `(c + 0.5, r + 0.5)`). The test is [`crate::visibility::in_view`]'s with
/// points for vertices: the disc of radius `radius_m` overlaps the cone (opening
/// `child_fov_deg`, widened by `view_margin_deg` on each side), and the robot's centre or
/// a point of the diameter across the sight line of the disc of radius `disc_m` around it
/// is in sight of `from` ([`segment_open`]), sampled every 1/16 cell or less.
pub(crate) fn in_view_at(
    map: &Map,
    params: &CoverageParams,
    from: [f64; 2],
    at: [f64; 2],
    radius_m: f64,
    disc_m: f64,
) -> bool {
    let (vx, vy) = (at[0] - from[0], at[1] - from[1]);
    let len = vx.hypot(vy);
    let d = len * map.cell_m;
    if d <= radius_m {
        return true;
    }
    let (dx, dy) = params.direction.unit();
    let angle = ((vx * dx + vy * dy) / len).clamp(-1.0, 1.0).acos();
    let half = (params.child_fov_deg / 2.0 + params.view_margin_deg).to_radians();
    let widen = (radius_m / d).min(1.0).asin();
    if angle > half + widen + 1e-12 {
        return false;
    }
    let apex = fine(from);
    across_sight(from, at, disc_m / map.cell_m).any(|p| segment_open(map, apex, p, FINE))
}

/// A position in cells on [`segment_open`]'s lattice of [`FINE`] points per cell.
pub(super) fn fine(p: [f64; 2]) -> (i64, i64) {
    let f = |x: f64| (x * FINE as f64).round() as i64;
    (f(p[0]), f(p[1]))
}

/// The points, on [`FINE`]'s lattice, of the diameter of the disc of radius `rho` (cells)
/// around `at` across the sight line from `from`: its centre first, then the diameter's
/// points from the ends inwards, every 1/16 cell or less. Where `at` is `from`, the centre.
pub(super) fn across_sight(
    from: [f64; 2],
    at: [f64; 2],
    rho: f64,
) -> impl Iterator<Item = (i64, i64)> {
    let (vx, vy) = (at[0] - from[0], at[1] - from[1]);
    let len = vx.hypot(vy);
    let (px, py) = if len > 0.0 {
        (-vy / len * rho, vx / len * rho)
    } else {
        (0.0, 0.0)
    };
    let steps = (rho * ALONG).ceil().max(1.0) as usize;
    std::iter::once(0.0)
        .chain((0..steps).map(move |k| 1.0 - k as f64 / steps as f64))
        .flat_map(|f| [f, -f])
        .map(move |f| fine([at[0] + f * px, at[1] + f * py]))
}

impl ParentStack {
    /// A position in metres in the map's cells.
    pub(super) fn in_cells(&self, p: [f64; 2]) -> [f64; 2] {
        let g = &self.mission.grid;
        [
            (p[0] - g.origin_x) / g.cell_m,
            (p[1] - g.origin_y) / g.cell_m,
        ]
    }

    /// Whether the parent sees robot `at` (metres, of `radius_m`) in the view of a child
    /// grabbing at `from` (metres); the disc grown by the tracker's error.
    fn seen_in_view(&self, from: [f64; 2], at: [f64; 2], radius_m: f64) -> bool {
        let disc_m = radius_m * std::f64::consts::SQRT_2 + ON_VERTEX_M;
        let (from, at) = (self.in_cells(from), self.in_cells(at));
        in_view_at(&self.map, &self.coverage, from, at, radius_m, disc_m)
    }

    /// The children to drive back onto their vertices before `grabs` (child, vertex), and
    /// how many grabs would still show a robot where the parent tracks them: a child in a
    /// grabbing child's view that would be out of it with both on their vertices is
    /// returned if it is off its vertex (and the grabbing child too, if it is off its own).
    pub(super) fn views_to_clear(&self, grabs: &[(usize, Vertex)]) -> (Vec<usize>, u32) {
        let r_child = self.mission.child_radius_m;
        let off =
            |k: usize| dist(self.children[k].estimate, self.children[k].planned) > ON_VERTEX_M;
        let mut movers = Vec::new();
        let mut seen = 0;
        for &(c, v) in grabs {
            let (from, vertex) = (self.children[c].estimate, self.centre(v));
            let mut shows = false;
            for k in (0..self.children.len()).filter(|&k| k != c) {
                if !self.seen_in_view(from, self.children[k].estimate, r_child) {
                    continue;
                }
                shows = true;
                if self.seen_in_view(vertex, self.children[k].planned, r_child) {
                    // In view on their vertices too: only the planner's margins allow
                    // that; moving does not help.
                    continue;
                }
                movers.extend([k, c].into_iter().filter(|&j| off(j)));
            }
            if let Some(pose) = self.pose {
                let here = [pose.translation.vector.x, pose.translation.vector.y];
                shows |= self.seen_in_view(from, here, self.mission.parent_radius_m);
            }
            seen += u32::from(shows);
        }
        movers.sort_unstable();
        movers.dedup();
        (movers, seen)
    }
}

#[cfg(test)]
mod tests;
