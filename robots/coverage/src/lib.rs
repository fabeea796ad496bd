//! Cooperative coverage mapping by a parent robot and N child robots (seed
//! `002_4e4d2d7b10a09d98`, Section IV).
//!
//! From an occupancy grid: the vertex set V (centres of free `d x d` cells), line of sight
//! LOS and LOS_free (Eqs. 1-2, [`visibility`]), the greedy choice of parent vertices with
//! weights `(9 - n(v))^2` and scores (Eqs. 5-7) and their nearest-neighbour tour over
//! geodesic distances ([`select`]), the child roadmaps of each stage with start points, goal
//! points, paths, hilling and branching ([`roadmap`]), and the execution of the whole mission
//! at the grid level, timestep by timestep, with stage transitions through H (Eq. 8) or the
//! following behaviour ([`execute`]). [`validate`] re-checks a plan's invariants from its
//! schedule alone.
//!
//! Executed in the simulator, the mission runs as robot software: [`ParentStack`] plans,
//! drives its tour, tracks the children and teleoperates them by radio ([`team`]);
//! [`ChildStack`] obeys, grabs the images and sends them to the parent.
//!
//! Every decision the paper leaves open is stated in the module that makes it and listed in
//! docs/coverage-planning.md ("Coverage planning decisions").

pub mod execute;
pub mod localize;
pub mod map;
pub mod mcl;
pub mod parent;
pub mod report;
pub mod roadmap;
mod sampling;
pub mod select;
mod table;
pub mod team;
pub mod validate;
pub mod visibility;

pub use execute::{plan, plan_with, Frame, Phase, Plan, PlanError};
pub use map::{Map, Vertex};
pub use parent::{HatTracker, ParentParams, ParentStack};
pub use report::{
    median, DatabaseImage, OdometryHop, TeamReport, TourReport, TrackedPath, TEAM_ARTIFACT,
};
pub use table::{CoverageTable, PlannedTeam};
pub use team::{ChildParams, ChildStack};
pub use validate::validate;
pub use visibility::Visibility;

use serde::{Deserialize, Serialize};

/// The direction all images are taken in (the "direction of mapping").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// +x (the paper's choice).
    East,
    /// +y.
    North,
    /// -x.
    West,
    /// -y.
    South,
}

impl Direction {
    /// Unit vector in grid axes (columns east, rows north).
    pub fn unit(self) -> (f64, f64) {
        match self {
            Direction::East => (1.0, 0.0),
            Direction::North => (0.0, 1.0),
            Direction::West => (-1.0, 0.0),
            Direction::South => (0.0, -1.0),
        }
    }

    /// Integer unit vector in grid axes.
    pub fn step(self) -> (i64, i64) {
        match self {
            Direction::East => (1, 0),
            Direction::North => (0, 1),
            Direction::West => (-1, 0),
            Direction::South => (0, -1),
        }
    }
}

/// Where the planner keeps robots out of the children's images.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewRule {
    /// No robot the grabbing child's camera could see, at any distance, at every grab: the
    /// paper's rule ("no robot must stand in the field of view of another robot at the
    /// instance an image is grabbed", Section II), with the camera's reach.
    #[default]
    EveryGrab,
    /// A relaxation for comparison: only a stage's starting points are kept out of each
    /// other's views (Section IV.C's choice of them); grabs are not checked.
    StartPoints,
}

/// Which reading of the points Section IV leaves open the planner takes. `Ours` is the
/// reading decided and shipped (docs/coverage-planning.md, "Coverage planning decisions"); each other one
/// changes one decision, to measure its effect on Tables I-II (`hetsim report coverage`,
/// `scenarios/sweeps/readings-*.toml`). For grid planning only: a scenario whose parent runs
/// the mission is refused any but `Ours`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Reading {
    /// The shipped reading.
    #[default]
    Ours,
    /// LOS_free (Eq. 2) drops only the vertices whose view holds the parent's centre, not
    /// its disc.
    ParentAPoint,
    /// LOS (Eq. 1) holds the vertices strictly closer than r_los, not those at r_los.
    LosStrict,
    /// LOS (Eq. 1) is a sight line that crosses the inside of no occupied cell, as a
    /// camera's ([`crate::visibility::line_of_sight_open`]): it may graze an obstacle cell's
    /// corner or pass between two that meet at a corner, which the shipped LOS may not.
    LosOpen,
    /// Eq. 6's candidates are the vertices within f of the last parent vertex chosen, not of
    /// any.
    Eq6LastChoice,
    /// Eq. 6 as written: within f of every parent vertex chosen so far (the whole map where
    /// none of those covers anything new, as in `Ours`).
    Eq6EveryChoice,
    /// Ties in the score go to the vertex nearest the last choice (straight-line distance),
    /// then the lowest index.
    TiesNearestLast,
    /// Ties in the score go to the vertex nearest any choice (straight-line distance), then
    /// the lowest index.
    TiesNearestAny,
    /// H (Eq. 8) is LOS_free(v_p^t) ∩ LOS_free(v_p^(t+1)), not LOS ∩ LOS.
    HFromLosFree,
    /// The tour's distance transform (the paper's [16]) steps to the 8 cells around a vertex,
    /// each step costing 1 and none cutting an occupied cell's corner, not to the 4 the
    /// robots step to (Section IV states 4; measured to rule the tour's metric out).
    Tour8Connected,
    /// n(v) counts the free vertices around v still uncovered, not all free ones, so that a
    /// vertex's specific weight grows as its neighbours are covered (updated with the
    /// scores, step 4 of the selection).
    NUncovered,
}

impl Reading {
    /// Every reading, `Ours` first.
    pub const ALL: [Reading; 11] = [
        Reading::Ours,
        Reading::ParentAPoint,
        Reading::LosStrict,
        Reading::LosOpen,
        Reading::Eq6LastChoice,
        Reading::Eq6EveryChoice,
        Reading::TiesNearestLast,
        Reading::TiesNearestAny,
        Reading::HFromLosFree,
        Reading::Tour8Connected,
        Reading::NUncovered,
    ];

    /// The name a scenario's `[coverage] reading` gives it.
    pub fn name(self) -> &'static str {
        match self {
            Reading::Ours => "ours",
            Reading::ParentAPoint => "parent_a_point",
            Reading::LosStrict => "los_strict",
            Reading::LosOpen => "los_open",
            Reading::Eq6LastChoice => "eq6_last_choice",
            Reading::Eq6EveryChoice => "eq6_every_choice",
            Reading::TiesNearestLast => "ties_nearest_last",
            Reading::TiesNearestAny => "ties_nearest_any",
            Reading::HFromLosFree => "h_from_los_free",
            Reading::Tour8Connected => "tour_8_connected",
            Reading::NUncovered => "n_uncovered",
        }
    }

    /// The reading named `name`, if any.
    pub fn from_name(name: &str) -> Option<Reading> {
        Reading::ALL.into_iter().find(|r| r.name() == name)
    }
}

/// Parameters of the team and the mapping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoverageParams {
    /// The parent's line-of-sight radius r_los, metres (2.0 in the seed).
    pub r_los_m: f64,
    /// Direction of mapping.
    pub direction: Direction,
    /// The children's camera opening angle, degrees (80 in the seed).
    pub child_fov_deg: f64,
    /// Extra angle on each side of a child's view when checking that no robot is in an
    /// image, degrees (0 in the seed).
    pub view_margin_deg: f64,
    /// Extra distance around a robot's footprint when checking that it is not in an image,
    /// metres (0 in the seed: robots stand on their vertices).
    #[serde(default)]
    pub view_margin_m: f64,
    /// Radius of the parent's footprint, metres.
    pub parent_radius_m: f64,
    /// Radius of a child's footprint, metres (0.06 for a c't-Bot).
    pub child_radius_m: f64,
    /// Number of child robots N.
    pub children: usize,
    /// Candidate distance f as a multiple of r_los (Eq. 6; 2 in the seed).
    pub f_factor: f64,
    /// Where robots are kept out of the images.
    #[serde(default)]
    pub views: ViewRule,
    /// The reading of Section IV's open points.
    #[serde(default)]
    pub reading: Reading,
}

impl Default for CoverageParams {
    fn default() -> Self {
        Self {
            r_los_m: 2.0,
            direction: Direction::East,
            child_fov_deg: 80.0,
            view_margin_deg: 0.0,
            view_margin_m: 0.0,
            parent_radius_m: 0.225,
            child_radius_m: 0.06,
            children: 3,
            f_factor: 2.0,
            views: ViewRule::EveryGrab,
            reading: Reading::Ours,
        }
    }
}
