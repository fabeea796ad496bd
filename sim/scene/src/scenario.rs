//! Scenario files (`scenarios/*.toml`): the world, the robots placed in it and their missions.

use crate::check::Checker;
use crate::SceneError;
pub use hetsim_coverage::CoverageTable;
use serde::{Deserialize, Serialize};

/// A scenario as written in its file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Must be [`crate::SCHEMA_VERSION`].
    pub schema_version: i64,
    /// Name used in run ids.
    pub name: String,
    /// One line for people.
    #[serde(default)]
    pub description: String,
    /// Master seed (the CLI's `--seed` overrides it).
    #[serde(default)]
    pub seed: u64,
    /// Fixed physics and sensing step, seconds.
    pub dt_secs: f64,
    /// Sim time to run, seconds (the CLI's `--duration` overrides it).
    pub duration_secs: f64,
    /// Folder of robot files, relative to this file's folder.
    #[serde(default = "default_models_dir")]
    pub models_dir: String,
    /// Rate at which ground-truth poses are delivered and recorded, Hz.
    #[serde(default = "default_truth_rate")]
    pub truth_rate_hz: f64,
    /// The world.
    pub world: WorldSpec,
    /// The robots, created in this order.
    pub robots: Vec<RobotSpec>,
    /// Cooperative coverage mapping parameters (indoor worlds).
    #[serde(default)]
    pub coverage: Option<CoverageTable>,
    /// The radio between robots.
    #[serde(default)]
    pub comms: CommsSpec,
    /// `"realistic"` (the default): the cameras' calibration errors and exposures as their
    /// robot files declare them; `"perfect"`: none (the CLI's `--camera-profile` overrides it).
    #[serde(default)]
    pub camera_profile: crate::CameraProfile,
}

/// The `[comms]` table: the radio link model between every pair of robots.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommsSpec {
    /// Largest distance between sender and receiver at sending time, metres.
    pub range_m: f64,
    /// Propagation and processing delay, seconds (rounded to whole ticks).
    pub latency_s: f64,
    /// Link rate, bits per second; a message occupies its link for `8 * bytes / rate`.
    pub bandwidth_bps: f64,
    /// Probability that a message is lost, independently per message.
    pub loss: f64,
}

impl Default for CommsSpec {
    fn default() -> Self {
        Self {
            range_m: 200.0,
            latency_s: 0.02,
            bandwidth_bps: 1.0e6,
            loss: 0.0,
        }
    }
}

fn default_models_dir() -> String {
    "../robots/models".to_string()
}

fn default_truth_rate() -> f64 {
    50.0
}

/// Which generator builds the world.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WorldKind {
    /// Terrain with two groups of buildings.
    Village,
    /// A walled rectangular floor with obstacles on a vertex grid (indoor grids and the lab).
    IndoorGrid,
}

/// The `[world]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldSpec {
    /// Which generator.
    pub kind: WorldKind,
    /// Village parameters (`kind = "village"`).
    #[serde(default)]
    pub village: Option<VillageSpec>,
    /// Indoor parameters (`kind = "indoor_grid"`).
    #[serde(default)]
    pub indoor: Option<IndoorSpec>,
}

/// Village generator parameters. Defaults give the seed's experiment area.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VillageSpec {
    /// Side of the square world, metres.
    pub size_m: f64,
    /// Terrain height-sample spacing, metres.
    pub terrain_cell_m: f64,
    /// Peak-to-mean terrain relief, metres.
    pub relief_m: f64,
    /// Centre of the north-west building group, metres.
    pub north_west_centre: [f64; 2],
    /// Centre of the south-east building group, metres.
    pub south_east_centre: [f64; 2],
    /// Radius of each building group, metres.
    pub group_radius_m: f64,
    /// Buildings per group.
    pub buildings_per_group: u32,
    /// Fixed buildings placed before the random ones.
    pub buildings: Vec<BoxSpec>,
}

impl Default for VillageSpec {
    fn default() -> Self {
        Self {
            size_m: 800.0,
            terrain_cell_m: 4.0,
            relief_m: 6.0,
            north_west_centre: [-150.0, 150.0],
            south_east_centre: [150.0, -150.0],
            group_radius_m: 60.0,
            buildings_per_group: 12,
            buildings: Vec::new(),
        }
    }
}

/// Indoor generator parameters. Defaults give the seed's 30 x 30 m simulation maps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IndoorSpec {
    /// Extent along x (east), metres.
    pub width_m: f64,
    /// Extent along y (north), metres.
    pub height_m: f64,
    /// Vertex spacing d, metres.
    pub spacing_m: f64,
    /// Fraction of the floor the random obstacles should cover, `[0, 0.6]`.
    pub obstruction_ratio: f64,
    /// Random obstacles' side lengths, in cells: `[min, max]`.
    pub obstacle_cells: [u32; 2],
    /// Random obstacles' heights, metres: `[min, max]`.
    pub obstacle_height_m: [f64; 2],
    /// Whether a random obstacle may be placed over cells other obstacles occupy (only its
    /// new cells count towards `obstruction_ratio`), so that obstacles merge into larger
    /// ones; `false` refuses every placement that covers an occupied cell.
    pub obstacles_overlap: bool,
    /// Height of the border walls, metres.
    pub wall_height_m: f64,
    /// Fixed obstacles (furniture) placed before the random ones.
    pub obstacles: Vec<BoxSpec>,
}

impl Default for IndoorSpec {
    fn default() -> Self {
        Self {
            width_m: 30.0,
            height_m: 30.0,
            spacing_m: 0.5,
            obstruction_ratio: 0.0,
            obstacle_cells: [1, 6],
            obstacle_height_m: [1.8, 2.4],
            obstacles_overlap: false,
            wall_height_m: 2.5,
            obstacles: Vec::new(),
        }
    }
}

/// An axis-aligned (before `yaw_deg`) box standing on the ground.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Centre of the footprint, metres.
    pub centre: [f64; 2],
    /// Footprint size along x and y before rotation, metres.
    pub size_m: [f64; 2],
    /// Height, metres.
    pub height_m: f64,
    /// Rotation about z, degrees.
    #[serde(default)]
    pub yaw_deg: f64,
}

/// A robot placed in the scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    /// Unique name in the scenario; prefixes the robot's random streams.
    pub name: String,
    /// Robot file stem in `models_dir`.
    pub model: String,
    /// Start pose.
    pub start: Start,
    /// What the robot does.
    pub mission: MissionSpec,
    /// Values replacing robot-file fields for this robot: dotted paths into the robot file,
    /// sensors addressed by name (`"sensors.stereo.rate_hz" = 5`).
    #[serde(default)]
    pub overrides: toml::Table,
}

/// A start pose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Start {
    /// East, metres.
    pub x: f64,
    /// North, metres.
    pub y: f64,
    /// Height above the ground under the robot, metres (helicopters).
    #[serde(default)]
    pub z: f64,
    /// Heading, degrees counter-clockwise from east.
    #[serde(default)]
    pub yaw_deg: f64,
}

/// A mission as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum MissionSpec {
    /// Stay put.
    Idle,
    /// Visit world points in order; `z` is the height above the datum for helicopters.
    Waypoints {
        /// `[x, y]` or `[x, y, z]` points, metres.
        points: Vec<Vec<f64>>,
    },
    /// A helicopter lawnmower survey from `from` to `to`, then the `then` points.
    Lawnmower {
        /// Start of the survey's centre line, metres.
        from: [f64; 2],
        /// End of the survey's centre line, metres.
        to: [f64; 2],
        /// Survey width across the centre line, metres.
        width_m: f64,
        /// Distance between legs, metres.
        spacing_m: f64,
        /// Flight height above the datum z = 0, metres.
        altitude_m: f64,
        /// Points flown after the survey (for example back over the start area), metres.
        #[serde(default)]
        then: Vec<[f64; 2]>,
    },
    /// Visit grid vertices `[col, row]` in order, moving up/down/left/right (indoor worlds).
    GridGoals {
        /// Vertices, `[col, row]` from the south-west corner.
        goals: Vec<[usize; 2]>,
    },
    /// Lead the cooperative coverage mapping mission of the `[coverage]` table (seed 002):
    /// plan, drive the tour, track and teleoperate the `coverage_child` robots.
    CoverageParent,
    /// A child of the coverage mission, teleoperated by the `coverage_parent` robot.
    CoverageChild,
}

impl ScenarioFile {
    /// Checks scenario-level values (not the robots' files, not placement in the world).
    pub fn validate(&self, c: &Checker) -> Result<(), SceneError> {
        check_name(c, &["name"], &self.name)?;
        self.check_timing(c)?;
        check_world(c, &self.world)?;
        self.check_coverage(c)?;
        check_comms(c, &self.comms)?;
        self.check_robots(c)
    }

    /// Checks the tick `dt_secs`, the run length and the truth rate (at most one per tick).
    fn check_timing(&self, c: &Checker) -> Result<(), SceneError> {
        c.range(&["dt_secs"], self.dt_secs, 1e-6, 1.0)?;
        c.positive(&["duration_secs"], self.duration_secs)?;
        c.range(
            &["truth_rate_hz"],
            self.truth_rate_hz,
            1e-3,
            1.0 / self.dt_secs,
        )
        .map_err(|e| {
            c.reword(
                e,
                &format!("a rate > 0 and <= the tick rate {} Hz", 1.0 / self.dt_secs),
            )
        })
    }

    /// Checks the `[coverage]` table: only in an indoor grid, by the coverage crate's rules.
    fn check_coverage(&self, c: &Checker) -> Result<(), SceneError> {
        if let Some(cov) = &self.coverage {
            if self.world.kind != WorldKind::IndoorGrid {
                return Err(c.error_at(
                    &["coverage"],
                    "(table)",
                    "a [coverage] table only in an indoor_grid world",
                ));
            }
            let parent = self
                .robots
                .iter()
                .find(|r| matches!(r.mission, MissionSpec::CoverageParent));
            crate::params::check(c, &["coverage"], cov.rules(parent.map(|r| r.name.as_str())))?;
        }
        Ok(())
    }

    /// Checks the `[[robots]]` entries: at least one, each valid and named uniquely.
    fn check_robots(&self, c: &Checker) -> Result<(), SceneError> {
        if self.robots.is_empty() {
            return Err(c.error_at(&["robots"], "(none)", "at least one [[robots]] entry"));
        }
        let mut names = std::collections::BTreeSet::new();
        for (i, r) in self.robots.iter().enumerate() {
            let idx = i.to_string();
            if !names.insert(r.name.as_str()) {
                return Err(c.error_at(
                    &["robots", &idx, "name"],
                    format!("\"{}\"", r.name),
                    "a name not used by another robot in this scenario",
                ));
            }
            check_name(c, &["robots", &idx, "name"], &r.name)?;
            for (f, v) in [
                ("x", r.start.x),
                ("y", r.start.y),
                ("z", r.start.z),
                ("yaw_deg", r.start.yaw_deg),
            ] {
                if !v.is_finite() {
                    return Err(c.error_at(&["robots", &idx, "start", f], v, "a finite number"));
                }
            }
            self.check_mission(c, &idx, &r.mission)?;
        }
        Ok(())
    }

    /// Checks `robots[idx].mission`: its kind fits the world and the scenario, its values.
    fn check_mission(
        &self,
        c: &Checker,
        idx: &str,
        mission: &MissionSpec,
    ) -> Result<(), SceneError> {
        match (mission, self.world.kind) {
            (MissionSpec::GridGoals { .. }, WorldKind::Village) => {
                return Err(c.error_at(&["robots", idx, "mission", "kind"], "\"grid_goals\"", "idle, waypoints or lawnmower in a village (grid_goals needs an indoor_grid world)"));
            }
            (MissionSpec::CoverageParent | MissionSpec::CoverageChild, WorldKind::Village) => {
                return Err(c.error_at(&["robots", idx, "mission", "kind"], format!("{mission:?}"), "idle, waypoints or lawnmower in a village (coverage missions need an indoor_grid world)"));
            }
            (MissionSpec::CoverageParent, _) if self.coverage.is_none() => {
                return Err(c.error_at(
                    &["robots", idx, "mission", "kind"],
                    "\"coverage_parent\"",
                    "a mission other than coverage_parent, or a [coverage] table in the scenario",
                ));
            }
            (MissionSpec::Waypoints { points }, _) => {
                for (k, p) in points.iter().enumerate() {
                    if !(p.len() == 2 || p.len() == 3) || p.iter().any(|v| !v.is_finite()) {
                        return Err(c.error_at(
                            &["robots", idx, "mission", "points", &k.to_string()],
                            format!("{p:?}"),
                            "[x, y] or [x, y, z] finite metres",
                        ));
                    }
                }
            }
            (
                MissionSpec::Lawnmower {
                    width_m,
                    spacing_m,
                    altitude_m,
                    ..
                },
                _,
            ) => {
                c.range(
                    &["robots", idx, "mission", "width_m"],
                    *width_m,
                    0.0,
                    10_000.0,
                )?;
                c.positive(&["robots", idx, "mission", "spacing_m"], *spacing_m)?;
                c.range(
                    &["robots", idx, "mission", "altitude_m"],
                    *altitude_m,
                    1.0,
                    1000.0,
                )?;
            }
            _ => {}
        }
        Ok(())
    }

    /// The village parameters, defaults filled in.
    pub fn village(&self) -> VillageSpec {
        self.world.village.clone().unwrap_or_default()
    }

    /// The indoor parameters, defaults filled in.
    pub fn indoor(&self) -> IndoorSpec {
        self.world.indoor.clone().unwrap_or_default()
    }
}

/// Checks the `[world]` table: only its kind's generator table, each table's values.
fn check_world(c: &Checker, world: &WorldSpec) -> Result<(), SceneError> {
    match (world.kind, &world.village, &world.indoor) {
        (WorldKind::Village, _, Some(_)) => {
            return Err(c.error_at(
                &["world", "indoor"],
                "(table)",
                "no [world.indoor] table when world.kind = \"village\"",
            ))
        }
        (WorldKind::IndoorGrid, Some(_), _) => {
            return Err(c.error_at(
                &["world", "village"],
                "(table)",
                "no [world.village] table when world.kind = \"indoor_grid\"",
            ))
        }
        _ => {}
    }
    if let Some(v) = &world.village {
        check_village(c, v)?;
    }
    if let Some(g) = &world.indoor {
        check_indoor(c, g)?;
    }
    Ok(())
}

/// Checks the `[world.village]` table: sizes, building groups inside the world, buildings.
fn check_village(c: &Checker, v: &VillageSpec) -> Result<(), SceneError> {
    let at = |f: &'static str| ["world", "village", f];
    c.range(&at("size_m"), v.size_m, 50.0, 5000.0)?;
    c.range(&at("terrain_cell_m"), v.terrain_cell_m, 0.5, v.size_m / 4.0)?;
    c.range(&at("relief_m"), v.relief_m, 0.0, 100.0)?;
    c.range(&at("group_radius_m"), v.group_radius_m, 5.0, v.size_m / 2.0)?;
    c.range(
        &at("buildings_per_group"),
        v.buildings_per_group as f64,
        0.0,
        200.0,
    )?;
    for (name, centre) in [
        ("north_west_centre", v.north_west_centre),
        ("south_east_centre", v.south_east_centre),
    ] {
        let half = v.size_m / 2.0 - v.group_radius_m;
        if centre.iter().any(|c| !c.is_finite() || c.abs() > half) {
            return Err(c.error_at(
                &["world", "village", name],
                format!("{centre:?}"),
                format!("a centre with |x|, |y| <= {half} so the group fits in the world"),
            ));
        }
    }
    for (i, b) in v.buildings.iter().enumerate() {
        check_box(
            c,
            &["world", "village", "buildings"],
            i,
            b,
            v.size_m / 2.0,
            v.size_m / 2.0,
        )?;
    }
    Ok(())
}

/// Checks the `[world.indoor]` table: a floor the vertex grid fills, obstacle ranges, obstacles.
fn check_indoor(c: &Checker, g: &IndoorSpec) -> Result<(), SceneError> {
    let at = |f: &'static str| ["world", "indoor", f];
    c.range(&at("spacing_m"), g.spacing_m, 0.05, 5.0)?;
    for (name, extent) in [("width_m", g.width_m), ("height_m", g.height_m)] {
        c.range(&at(name), extent, 2.0 * g.spacing_m, 500.0)?;
        let cells = extent / g.spacing_m;
        if (cells - cells.round()).abs() > 1e-6 {
            return Err(c.error_at(
                &at(name),
                extent,
                format!(
                    "a multiple of spacing_m = {} (the vertex grid must fill the floor)",
                    g.spacing_m
                ),
            ));
        }
    }
    c.range(&at("obstruction_ratio"), g.obstruction_ratio, 0.0, 0.6)?;
    let [lo, hi] = g.obstacle_cells;
    if lo == 0 || lo > hi {
        return Err(c.error_at(
            &at("obstacle_cells"),
            format!("{:?}", g.obstacle_cells),
            "[min, max] cells with 1 <= min <= max",
        ));
    }
    let [hlo, hhi] = g.obstacle_height_m;
    if !(hlo.is_finite() && hhi.is_finite() && hlo > 0.0 && hlo <= hhi) {
        return Err(c.error_at(
            &at("obstacle_height_m"),
            format!("{:?}", g.obstacle_height_m),
            "[min, max] metres with 0 < min <= max",
        ));
    }
    c.range(&at("wall_height_m"), g.wall_height_m, 0.1, 20.0)?;
    for (i, b) in g.obstacles.iter().enumerate() {
        check_box(
            c,
            &["world", "indoor", "obstacles"],
            i,
            b,
            g.width_m / 2.0,
            g.height_m / 2.0,
        )?;
    }
    Ok(())
}

/// Checks the `[comms]` table: range, latency, bandwidth and loss probability.
fn check_comms(c: &Checker, comms: &CommsSpec) -> Result<(), SceneError> {
    let at = |f: &'static str| ["comms", f];
    c.positive(&at("range_m"), comms.range_m)?;
    c.range(&at("latency_s"), comms.latency_s, 0.0, 60.0)?;
    c.positive(&at("bandwidth_bps"), comms.bandwidth_bps)?;
    c.range(&at("loss"), comms.loss, 0.0, 1.0)
}

/// Checks a name at `path`: non-empty, of ASCII letters, digits, '-' and '_'.
fn check_name(c: &Checker, path: &[&str], name: &str) -> Result<(), SceneError> {
    if name.is_empty()
        || !name
            .chars()
            .all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_')
    {
        return Err(c.error_at(
            path,
            format!("\"{name}\""),
            "a non-empty name of letters, digits, '-' and '_'",
        ));
    }
    Ok(())
}

/// Checks `table[i]`, a box: sizes and height > 0, centre within `half_x` and `half_y`.
fn check_box(
    c: &Checker,
    table: &[&str; 3],
    i: usize,
    b: &BoxSpec,
    half_x: f64,
    half_y: f64,
) -> Result<(), SceneError> {
    let idx = i.to_string();
    let at = |f: &'static str| [table[0], table[1], table[2], idx.as_str(), f];
    for (k, s) in b.size_m.iter().enumerate() {
        if !(s.is_finite() && *s > 0.0) {
            return Err(c.error_at(
                &at("size_m"),
                format!("{:?}", b.size_m),
                format!("two sizes > 0 metres (entry {k} is not)"),
            ));
        }
    }
    c.positive(&at("height_m"), b.height_m)?;
    if b.centre.iter().any(|v| !v.is_finite())
        || b.centre[0].abs() > half_x
        || b.centre[1].abs() > half_y
    {
        return Err(c.error_at(
            &at("centre"),
            format!("{:?}", b.centre),
            format!("a centre inside the world: |x| <= {half_x}, |y| <= {half_y}"),
        ));
    }
    Ok(())
}
