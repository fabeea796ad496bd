//! The `[coverage]` table of a scenario and its view rule's check.

use crate::check::Checker;
use crate::SceneError;
use hetsim_coverage::Reading;
use serde::{Deserialize, Serialize};

/// The `[coverage]` table: the parent/child team's mapping parameters (seed 002).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CoverageSpec {
    /// The parent's line-of-sight radius r_los, metres.
    pub r_los_m: f64,
    /// Direction of mapping: "east", "north", "west" or "south".
    pub direction: String,
    /// The children's camera opening angle, degrees.
    pub child_fov_deg: f64,
    /// Extra angle on each side of the children's view when checking that no robot is in an
    /// image, degrees (0 in the seed's model; covers the children's heading error when the
    /// mission runs in the simulator).
    pub view_margin_deg: f64,
    /// Extra distance around a robot's footprint when checking that it is not in an image,
    /// metres (0 in the seed's model; covers how far a robot stands off its vertex, by the
    /// drive's and the tracker's errors, when the mission runs in the simulator).
    pub view_margin_m: f64,
    /// Number of children N; `None` counts the scenario's robots that wear a hat (the
    /// children, as their robot files declare).
    pub children: Option<usize>,
    /// Candidate distance f as a multiple of r_los (Eq. 6).
    pub f_factor: f64,
    /// Where the planner keeps robots out of the children's images: "every_grab" (the paper's
    /// rule: no robot the camera could see, at any distance, at any grab) or "start_points"
    /// (a relaxation for comparison: only a stage's starting points; refused in a mission the
    /// simulator runs, whose images are rendered).
    pub views: String,
    /// Which reading of the points Section IV leaves open the planner takes: "ours" (the
    /// shipped one) or another of [`hetsim_coverage::Reading`]'s names, each changing one decision (grid planning
    /// only: refused in a mission the simulator runs).
    pub reading: String,
    /// After mapping, the first child localizes from the database on a new path of this many
    /// grid moves, in lockstep (0: none). 20 by default.
    pub localize_steps: usize,
}

impl Default for CoverageSpec {
    fn default() -> Self {
        Self {
            r_los_m: 2.0,
            direction: "east".to_string(),
            child_fov_deg: 80.0,
            view_margin_deg: 0.0,
            view_margin_m: 0.0,
            children: None,
            f_factor: 2.0,
            views: "every_grab".to_string(),
            reading: "ours".to_string(),
            localize_steps: 20,
        }
    }
}

impl CoverageSpec {
    /// `reading` names a [`hetsim_coverage::Reading`], and only "ours" in a scenario whose parent
    /// (`mission_parent`, by name) runs the mission.
    pub(crate) fn check_reading(
        &self,
        c: &Checker,
        mission_parent: Option<&str>,
    ) -> Result<(), SceneError> {
        let at = ["coverage", "reading"];
        let allowed = Reading::ALL
            .iter()
            .map(|r| format!("\"{}\"", r.name()))
            .collect::<Vec<_>>()
            .join(", ");
        match (self.reading.as_str(), mission_parent) {
            ("ours", _) => Ok(()),
            (other, None) if Reading::from_name(other).is_some() => Ok(()),
            (other, Some(name)) if Reading::from_name(other).is_some() => Err(c.error_at(
                &at,
                format!("\"{other}\" (robot {name} runs the mission)"),
                "\"ours\" in a scenario whose parent runs the mission; the other readings only for grid planning (sweeps, `hetsim regress`)",
            )),
            (other, _) => Err(c.error_at(&at, format!("\"{other}\""), format!("one of {allowed}"))),
        }
    }

    /// `views` is one of the two rules, and `start_points` (which checks no grab) is not
    /// asked of a scenario whose parent (`mission_parent`, by name) runs the mission.
    pub(crate) fn check_views(
        &self,
        c: &Checker,
        mission_parent: Option<&str>,
    ) -> Result<(), SceneError> {
        let at = ["coverage", "views"];
        match (self.views.as_str(), mission_parent) {
            ("every_grab", _) | ("start_points", None) => Ok(()),
            ("start_points", Some(name)) => Err(c.error_at(
                &at,
                format!("\"start_points\" (robot {name} runs the mission, and its images are rendered)"),
                "\"every_grab\" in a scenario whose parent runs the mission; \"start_points\" only for grid planning (sweeps, `hetsim regress`)",
            )),
            (other, _) => Err(c.error_at(
                &at,
                format!("\"{other}\""),
                "\"every_grab\" or \"start_points\"",
            )),
        }
    }
}
