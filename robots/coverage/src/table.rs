//! The `[coverage]` table of a scenario: the team's mapping parameters (seed 002). This crate
//! owns its fields, their defaults and what each may be ([`CoverageTable::rules`]); the
//! scenario loader reads the table into [`CoverageTable`] and checks it against those rules,
//! and [`CoverageTable::params`] makes the planner's [`CoverageParams`] of it and of the team
//! the scenario fields.

use crate::{CoverageParams, Direction, Reading, ViewRule};
use hetsim_msgs::params::Rule;
use serde::{Deserialize, Serialize};

/// The `[coverage]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CoverageTable {
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
    /// shipped one) or another of [`Reading`]'s names, each changing one decision (grid
    /// planning only: refused in a mission the simulator runs).
    pub reading: String,
    /// After mapping, the first child localizes from the database on a new path of this many
    /// grid moves, in lockstep (0: none). 20 by default.
    pub localize_steps: usize,
}

impl Default for CoverageTable {
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

/// The team a [`CoverageTable`] plans for, as the scenario's robot files declare it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannedTeam {
    /// Radius of the parent's footprint, metres.
    pub parent_radius_m: f64,
    /// Radius of a child's footprint, metres.
    pub child_radius_m: f64,
    /// The scenario's children (robots wearing a hat).
    pub children: usize,
}

fn direction(name: &str) -> Option<Direction> {
    match name {
        "east" => Some(Direction::East),
        "north" => Some(Direction::North),
        "west" => Some(Direction::West),
        "south" => Some(Direction::South),
        _ => None,
    }
}

fn view_rule(name: &str) -> Option<ViewRule> {
    match name {
        "every_grab" => Some(ViewRule::EveryGrab),
        "start_points" => Some(ViewRule::StartPoints),
        _ => None,
    }
}

impl CoverageTable {
    /// What each value must be. `mission_parent` names the scenario's robot that runs the
    /// mission, if one does: its images are rendered and its planner is the shipped one, so
    /// the relaxed view rule and the other readings are for grid planning only.
    pub fn rules(&self, mission_parent: Option<&str>) -> Vec<Rule> {
        let mut rules = vec![
            Rule::range("r_los_m", self.r_los_m, 0.1, 100.0),
            Rule::range("child_fov_deg", self.child_fov_deg, 1.0, 179.0),
            Rule::range("view_margin_deg", self.view_margin_deg, 0.0, 45.0),
            Rule::range("view_margin_m", self.view_margin_m, 0.0, 0.5),
            Rule::range("f_factor", self.f_factor, 0.5, 10.0),
        ];
        if direction(&self.direction).is_none() {
            rules.push(Rule::refused(
                "direction",
                format!("\"{}\"", self.direction),
                "one of \"east\", \"north\", \"west\", \"south\"",
            ));
        }
        if let Some(n) = self.children {
            rules.push(Rule::range("children", n as f64, 1.0, 32.0));
        }
        rules.push(Rule::range(
            "localize_steps",
            self.localize_steps as f64,
            0.0,
            1000.0,
        ));
        let only = "in a scenario whose parent runs the mission";
        match (view_rule(&self.views), mission_parent) {
            (Some(ViewRule::EveryGrab), _) | (Some(ViewRule::StartPoints), None) => {}
            (Some(ViewRule::StartPoints), Some(name)) => rules.push(Rule::refused(
                "views",
                format!("\"start_points\" (robot {name} runs the mission, and its images are rendered)"),
                format!("\"every_grab\" {only}; \"start_points\" only for grid planning (sweeps, `hetsim regress`)"),
            )),
            (None, _) => rules.push(Rule::refused(
                "views",
                format!("\"{}\"", self.views),
                "\"every_grab\" or \"start_points\"",
            )),
        }
        match (Reading::from_name(&self.reading), mission_parent) {
            (Some(Reading::Ours), _) | (Some(_), None) => {}
            (Some(_), Some(name)) => rules.push(Rule::refused(
                "reading",
                format!("\"{}\" (robot {name} runs the mission)", self.reading),
                format!("\"ours\" {only}; the other readings only for grid planning (sweeps, `hetsim regress`)"),
            )),
            (None, _) => {
                let allowed = Reading::ALL
                    .iter()
                    .map(|r| format!("\"{}\"", r.name()))
                    .collect::<Vec<_>>()
                    .join(", ");
                rules.push(Rule::refused(
                    "reading",
                    format!("\"{}\"", self.reading),
                    format!("one of {allowed}"),
                ));
            }
        }
        rules
    }

    /// The planner's parameters for `team`: the table's, with the team's footprints, and its
    /// children where the table does not count them. Names are read as [`Self::rules`]
    /// checked them (an unchecked table's unknown name takes the default).
    pub fn params(&self, team: PlannedTeam) -> CoverageParams {
        CoverageParams {
            r_los_m: self.r_los_m,
            direction: direction(&self.direction).unwrap_or(Direction::East),
            child_fov_deg: self.child_fov_deg,
            view_margin_deg: self.view_margin_deg,
            view_margin_m: self.view_margin_m,
            parent_radius_m: team.parent_radius_m,
            child_radius_m: team.child_radius_m,
            children: self.children.unwrap_or(team.children).max(1),
            f_factor: self.f_factor,
            views: view_rule(&self.views).unwrap_or_default(),
            reading: Reading::from_name(&self.reading).unwrap_or_default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_table_holds_and_plans_the_seed_s_team() {
        let t = CoverageTable::default();
        assert!(t.rules(Some("parent")).iter().all(Rule::holds));
        let team = PlannedTeam {
            parent_radius_m: 0.14,
            child_radius_m: 0.06,
            children: 4,
        };
        let p = t.params(team);
        assert_eq!((p.r_los_m, p.children, p.f_factor), (2.0, 4, 2.0));
        assert_eq!(
            (p.direction, p.views, p.reading),
            (Direction::East, ViewRule::EveryGrab, Reading::Ours)
        );
    }

    #[test]
    fn grid_planning_settings_are_refused_only_where_the_mission_runs() {
        let relaxed = CoverageTable {
            views: "start_points".into(),
            reading: Reading::ALL[1].name().into(),
            ..CoverageTable::default()
        };
        assert!(relaxed.rules(None).iter().all(Rule::holds));
        let refused: Vec<_> = relaxed
            .rules(Some("parent"))
            .into_iter()
            .filter(|r| !r.holds())
            .collect();
        let fields: Vec<_> = refused.iter().map(|r| r.field()[0].as_str()).collect();
        assert_eq!(fields, ["views", "reading"]);
        let wrong = CoverageTable {
            direction: "up".into(),
            ..CoverageTable::default()
        };
        assert_eq!(wrong.rules(None).iter().filter(|r| !r.holds()).count(), 1);
    }
}
