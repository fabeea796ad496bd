//! Loading a scenario with its robots and building its world.

use crate::check::Checker;
use crate::robot::{DriveKind, RobotModel};
use crate::scenario::{MissionSpec, RobotSpec, ScenarioFile, WorldKind};
use crate::source::Source;
use crate::world::{generate_indoor, generate_village, KeepClear, World};
use crate::SceneError;
use hetsim_core::{SimClock, Streams};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Values the command line may override.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Replaces the scenario's `seed`.
    pub seed: Option<u64>,
    /// Replaces the scenario's `duration_secs`.
    pub duration_secs: Option<f64>,
    /// Robot files' texts by model, used instead of reading them from `models_dir` (replay
    /// uses the robot files a recording carries).
    pub robot_files: Option<BTreeMap<String, String>>,
}

/// A robot with its resolved model.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolvedRobot {
    /// How the scenario places it.
    pub spec: RobotSpec,
    /// Its robot file with the scenario's overrides applied.
    pub model: RobotModel,
    /// The robot file.
    pub model_path: PathBuf,
    /// The robot file's text as read (before the scenario's overrides).
    pub model_text: String,
}

/// A loaded, validated scenario and its world.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The scenario file.
    pub path: PathBuf,
    /// What the file says.
    pub file: ScenarioFile,
    /// The master seed in force.
    pub seed: u64,
    /// The sim time to run, seconds.
    pub duration_secs: f64,
    /// The clock.
    pub clock: SimClock,
    /// Robots in creation order.
    pub robots: Vec<ResolvedRobot>,
    /// The world built from the file and the seed.
    pub world: World,
    /// SHA-256 of every file read, keyed by its path as given.
    pub file_hashes: BTreeMap<String, String>,
    /// The scenario file's text as read (recordings carry it, so replay needs no files).
    pub text: String,
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Loads a robot file on its own (for `hetsim validate` and tests), checking sensor rates
/// against a tick of `dt_secs`.
pub fn load_robot_model(path: &Path, dt_secs: f64) -> Result<RobotModel, SceneError> {
    let source = Source::read(path)?;
    let model: RobotModel = source.parse()?;
    check_model_name(&source, &model)?;
    model.validate(&Checker::new(&source), dt_secs)?;
    Ok(model)
}

fn check_model_name(source: &Source, model: &RobotModel) -> Result<(), SceneError> {
    let stem = source
        .path()
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("");
    if model.name != stem {
        return Err(Checker::new(source).error_at(
            &["name"],
            format!("\"{}\"", model.name),
            format!("\"{stem}\", the file's name without .toml"),
        ));
    }
    Ok(())
}

/// Loads, validates and builds a scenario.
pub fn load_scenario(path: &Path, options: &LoadOptions) -> Result<Scenario, SceneError> {
    load_source(Source::read(path)?, options)
}

/// Loads a scenario from `text` as if it were the file at `path` (relative paths resolve
/// against `path`'s folder). Sweeps use it to apply their axes to a base scenario.
pub fn load_scenario_text(
    path: &Path,
    text: String,
    options: &LoadOptions,
) -> Result<Scenario, SceneError> {
    load_source(Source::from_text(path, text)?, options)
}

fn load_source(source: Source, options: &LoadOptions) -> Result<Scenario, SceneError> {
    let path = source.path().to_path_buf();
    let path = path.as_path();
    let file: ScenarioFile = source.parse()?;
    let c = Checker::new(&source);
    file.validate(&c)?;
    if let Some(d) = options.duration_secs {
        if !(d.is_finite() && d > 0.0) {
            return Err(SceneError::field(
                path,
                None,
                "--duration",
                d,
                "a finite number of seconds > 0",
            ));
        }
    }
    let clock = SimClock::from_dt_secs(file.dt_secs)
        .map_err(|e| c.error_at(&["dt_secs"], file.dt_secs, e.to_string()))?;
    let mut file_hashes = BTreeMap::new();
    file_hashes.insert(
        path.display().to_string(),
        sha256_hex(source.text().as_bytes()),
    );

    let models_dir = path
        .parent()
        .unwrap_or(Path::new("."))
        .join(&file.models_dir);
    let mut robots = Vec::new();
    for (i, spec) in file.robots.iter().enumerate() {
        let model_path = models_dir.join(format!("{}.toml", spec.model));
        let given = options
            .robot_files
            .as_ref()
            .map(|files| files.get(&spec.model).cloned());
        if given == Some(None) {
            let known: Vec<&str> = options
                .robot_files
                .iter()
                .flat_map(|f| f.keys().map(String::as_str))
                .collect();
            return Err(c.error_at(
                &["robots", &i.to_string(), "model"],
                format!("\"{}\"", spec.model),
                format!("one of the robot files given: {}", known.join(", ")),
            ));
        }
        let given = given.flatten();
        if given.is_none() && !model_path.is_file() {
            let known = list_models(&models_dir);
            return Err(c.error_at(
                &["robots", &i.to_string(), "model"],
                format!("\"{}\"", spec.model),
                format!("a robot file in {}: one of {known}", models_dir.display()),
            ));
        }
        let source = match &given {
            Some(text) => Source::from_text(&model_path, text.clone())?,
            None => Source::read(&model_path)?,
        };
        let text = source.text().as_bytes().to_vec();
        let model = load_with_overrides(&c, i, spec, source, file.dt_secs)?;
        file_hashes.insert(model_path.display().to_string(), sha256_hex(&text));
        robots.push(ResolvedRobot {
            spec: spec.clone(),
            model,
            model_path,
            model_text: String::from_utf8_lossy(&text).into_owned(),
        });
    }
    check_missions(&c, &file, &robots)?;

    check_world_fits(&c, &file)?;
    let seed = options.seed.unwrap_or(file.seed);
    let streams = Streams::new(seed);
    let keep = keep_clear(&file, &robots);
    let world = match file.world.kind {
        WorldKind::Village => generate_village(&file.village(), &streams, &keep),
        WorldKind::IndoorGrid => generate_indoor(&file.indoor(), &streams, &keep),
    };
    check_placement(&c, &robots, &world, file.coverage.is_some())?;
    Ok(Scenario {
        path: path.to_path_buf(),
        duration_secs: options.duration_secs.unwrap_or(file.duration_secs),
        file,
        seed,
        clock,
        robots,
        world,
        file_hashes,
        text: source.text().to_string(),
    })
}

fn list_models(dir: &Path) -> String {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .filter_map(|e| {
                    e.path()
                        .file_stem()
                        .and_then(|s| s.to_str())
                        .map(str::to_string)
                        .filter(|_| e.path().extension().is_some_and(|x| x == "toml"))
                })
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    if names.is_empty() {
        "(none found)".to_string()
    } else {
        names.join(", ")
    }
}

/// Reads a robot file, applies the scenario's overrides for this robot, parses and validates.
fn load_with_overrides(
    c: &Checker,
    index: usize,
    spec: &RobotSpec,
    source: Source,
    dt_secs: f64,
) -> Result<RobotModel, SceneError> {
    let model_path = &source.path().to_path_buf();
    // The file must be valid on its own, so that its own errors point at its own lines.
    let model: RobotModel = source.parse()?;
    check_model_name(&source, &model)?;
    model.validate(&Checker::new(&source), dt_secs)?;
    if spec.overrides.is_empty() {
        return Ok(model);
    }
    let idx = index.to_string();
    let mut table: toml::Table = toml::from_str(source.text())
        .map_err(|e| SceneError::field(model_path, None, "(file)", "", e.to_string()))?;
    for (key, value) in &spec.overrides {
        let at = ["robots", idx.as_str(), "overrides", key.as_str()];
        let slot = lookup_mut(&mut table, key).ok_or_else(|| {
            c.error(&at, &format!("robots[{index}].overrides.\"{key}\""), value, format!("a dotted path to an existing field of {} (sensors by name, e.g. \"sensors.stereo.rate_hz\")", model_path.display()))
        })?;
        *slot = value.clone();
    }
    let text = toml::to_string(&table)
        .map_err(|e| SceneError::field(model_path, None, "(file)", "", e.to_string()))?;
    let merged = Source::from_text(model_path, text)?;
    let reword = |e: SceneError| match e {
        SceneError::Field(f) => c.error(
            &["robots", idx.as_str(), "overrides"],
            &format!("robots[{index}].overrides -> {}", f.field),
            f.value,
            f.allowed,
        ),
        other => other,
    };
    let model: RobotModel = merged.parse().map_err(reword)?;
    model
        .validate(&Checker::new(&merged), dt_secs)
        .map_err(reword)?;
    Ok(model)
}

/// Finds a field by dotted path; an array of tables is indexed by its elements' `name`. A
/// missing last segment is created in an existing table (a field the file leaves at its
/// default); whether it is a real field is then decided by parsing, which refuses unknown
/// fields.
fn lookup_mut<'a>(table: &'a mut toml::Table, dotted: &str) -> Option<&'a mut toml::Value> {
    fn child<'b>(v: &'b mut toml::Value, seg: &str, create: bool) -> Option<&'b mut toml::Value> {
        match v {
            toml::Value::Table(t) => {
                if create && !t.contains_key(seg) {
                    t.insert(seg.to_string(), toml::Value::Boolean(false));
                }
                t.get_mut(seg)
            }
            toml::Value::Array(items) => items
                .iter_mut()
                .find(|i| i.get("name").and_then(|n| n.as_str()) == Some(seg)),
            _ => None,
        }
    }
    let segments: Vec<&str> = dotted.split('.').collect();
    let (first, rest) = segments.split_first()?;
    if rest.is_empty() {
        return table.get_mut(*first);
    }
    // `[slam]` is the one table a robot file may leave out whose fields may be overridden,
    // and its nested tables (`edge_drift`, `matching`, `line_prior`) too: they are made on
    // the way, and whether the field exists is decided by the SLAM's own parsing.
    if *first == "slam" {
        let mut at = table
            .entry("slam")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        for seg in &rest[..rest.len() - 1] {
            at = at
                .as_table_mut()?
                .entry(*seg)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        }
        let last = rest[rest.len() - 1];
        return Some(
            at.as_table_mut()?
                .entry(last)
                .or_insert(toml::Value::Boolean(false)),
        );
    }
    let mut current = table.get_mut(*first)?;
    for (k, seg) in rest.iter().enumerate() {
        current = child(current, seg, k + 1 == rest.len())?;
    }
    Some(current)
}

/// Refuses, before it is built, a village whose terrain alone needs more memory than the
/// bound ([`crate::budget`]).
fn check_world_fits(c: &Checker, file: &ScenarioFile) -> Result<(), SceneError> {
    use crate::budget::{memory_bound, terrain_samples, village_bytes};
    use hetsim_core::files::human_bytes;
    if file.world.kind != WorldKind::Village {
        return Ok(());
    }
    let v = file.village();
    let need = village_bytes(v.size_m, v.terrain_cell_m);
    match memory_bound() {
        Some((bound, from)) if need > bound as f64 => Err(c.error_at(
            &["world", "village", "terrain_cell_m"],
            v.terrain_cell_m,
            format!(
                "a terrain that fits in memory: size_m = {} at terrain_cell_m = {} is {:.2e} \
                 height samples, about {} at {} bytes each, and {} is {} (a larger \
                 terrain_cell_m or a smaller size_m; --max-memory to declare another bound)",
                v.size_m,
                v.terrain_cell_m,
                terrain_samples(v.size_m, v.terrain_cell_m),
                human_bytes(need as u64),
                crate::budget::TERRAIN_BYTES_PER_SAMPLE,
                from,
                human_bytes(bound)
            ),
        )),
        _ => Ok(()),
    }
}

fn check_missions(
    c: &Checker,
    file: &ScenarioFile,
    robots: &[ResolvedRobot],
) -> Result<(), SceneError> {
    for (i, r) in robots.iter().enumerate() {
        let idx = i.to_string();
        let heli = r.model.body.drive == DriveKind::Helicopter;
        if matches!(r.spec.mission, MissionSpec::Lawnmower { .. }) && !heli {
            return Err(c.error_at(&["robots", &idx, "mission", "kind"], "\"lawnmower\"", format!("idle, waypoints or grid_goals for {} (a {:?} robot); lawnmower is for helicopters", r.spec.model, r.model.body.drive)));
        }
        if heli && matches!(r.spec.mission, MissionSpec::GridGoals { .. }) {
            return Err(c.error_at(
                &["robots", &idx, "mission", "kind"],
                "\"grid_goals\"",
                "idle, waypoints or lawnmower for a helicopter",
            ));
        }
        if heli && r.spec.start.z <= 0.0 {
            return Err(c.error_at(
                &["robots", &idx, "start", "z"],
                r.spec.start.z,
                "a height above the ground > 0 metres for a helicopter",
            ));
        }
        let coverage = matches!(
            r.spec.mission,
            MissionSpec::CoverageParent | MissionSpec::CoverageChild
        );
        if heli && coverage {
            return Err(c.error_at(
                &["robots", &idx, "mission", "kind"],
                format!("{:?}", r.spec.mission),
                "idle, waypoints or lawnmower for a helicopter",
            ));
        }
        let has = |kind: &str| r.model.sensors.iter().any(|s| s.kind() == kind);
        if matches!(r.spec.mission, MissionSpec::CoverageParent)
            && !(has("omni_camera") || has("child_tracker"))
        {
            return Err(c.error_at(
                &["robots", &idx, "mission", "kind"],
                "\"coverage_parent\"",
                format!(
                    "a robot with an omni_camera (its hat tracker's) or a child_tracker sensor \
                     ({} has neither)",
                    r.spec.model
                ),
            ));
        }
        if matches!(r.spec.mission, MissionSpec::CoverageChild)
            && !(has("compass") && has("camera") && has("wheel_odometry"))
        {
            return Err(c.error_at(
                &["robots", &idx, "mission", "kind"],
                "\"coverage_child\"",
                format!(
                    "a robot with a camera, a compass and wheel_odometry ({} lacks one)",
                    r.spec.model
                ),
            ));
        }
        if coverage && file.world.kind == WorldKind::IndoorGrid {
            // Coverage robots turn in place on vertices, the centres of free cells: a body
            // whose half-diagonal reaches half a cell touches an occupied neighbour even
            // when it stands exactly on its vertex.
            let b = &r.model.body;
            let reach = b.length_m.hypot(b.width_m) / 2.0;
            let half_cell = file.indoor().spacing_m / 2.0;
            if reach >= half_cell {
                return Err(c.error_at(
                    &["robots", &idx, "model"],
                    format!("\"{}\"", r.spec.model),
                    format!(
                        "a model whose footprint turns in place inside one grid cell: half its \
                         diagonal under half the spacing, {half_cell} m ({} is {} x {} m, \
                         half-diagonal {reach:.3} m)",
                        r.spec.model, b.length_m, b.width_m
                    ),
                ));
            }
        }
        if matches!(r.spec.mission, MissionSpec::CoverageChild) {
            let parents = robots
                .iter()
                .filter(|p| matches!(p.spec.mission, MissionSpec::CoverageParent))
                .count();
            if parents != 1 {
                return Err(c.error_at(
                    &["robots", &idx, "mission", "kind"],
                    "\"coverage_child\"",
                    format!("exactly one robot with mission coverage_parent in the scenario (found {parents})"),
                ));
            }
        }
        if let (MissionSpec::GridGoals { goals }, WorldKind::IndoorGrid) =
            (&r.spec.mission, file.world.kind)
        {
            let g = file.indoor();
            let (cols, rows) = (
                (g.width_m / g.spacing_m).round() as usize,
                (g.height_m / g.spacing_m).round() as usize,
            );
            for (k, goal) in goals.iter().enumerate() {
                if goal[0] >= cols || goal[1] >= rows {
                    return Err(c.error_at(
                        &["robots", &idx, "mission", "goals", &k.to_string()],
                        format!("{goal:?}"),
                        format!("a vertex [col, row] with col < {cols} and row < {rows}"),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Robot starts and ground routes that buildings and obstacles must leave free.
fn keep_clear(file: &ScenarioFile, robots: &[ResolvedRobot]) -> KeepClear {
    let mut keep = KeepClear::default();
    let g = file.indoor();
    for r in robots {
        let radius = r.model.body.length_m.hypot(r.model.body.width_m) / 2.0;
        let start = [r.spec.start.x, r.spec.start.y];
        if r.model.body.drive == DriveKind::Helicopter {
            continue;
        }
        let mut path = vec![start];
        match &r.spec.mission {
            MissionSpec::Waypoints { points } => path.extend(points.iter().map(|p| [p[0], p[1]])),
            MissionSpec::GridGoals { goals } => {
                // Goal vertices stay free too (a point each, not a path through obstacles).
                for goal in goals {
                    let centre = [
                        -g.width_m / 2.0 + (goal[0] as f64 + 0.5) * g.spacing_m,
                        -g.height_m / 2.0 + (goal[1] as f64 + 0.5) * g.spacing_m,
                    ];
                    keep.paths.push((vec![centre], radius));
                }
            }
            _ => {}
        }
        keep.paths.push((path, radius + 4.0 * radius.min(1.0)));
    }
    keep
}

fn check_placement(
    c: &Checker,
    robots: &[ResolvedRobot],
    world: &World,
    coverage: bool,
) -> Result<(), SceneError> {
    check_robot_starts(c, robots, world)?;
    check_team_vertices(c, robots, world, coverage)
}

/// The robots of a coverage team (seed 002) each start on a vertex of their own: the
/// mission's schedule has one robot per vertex. With a `[coverage]` section every robot
/// counts (the grid-level plan takes them all as the team, whatever their missions).
fn check_team_vertices(
    c: &Checker,
    robots: &[ResolvedRobot],
    world: &World,
    coverage: bool,
) -> Result<(), SceneError> {
    let Some(indoor) = &world.grid else {
        return Ok(());
    };
    let mut taken: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    for (i, r) in robots.iter().enumerate() {
        let in_team = matches!(
            r.spec.mission,
            MissionSpec::CoverageParent | MissionSpec::CoverageChild
        );
        if !(coverage || in_team) {
            continue;
        }
        let (x, y) = (r.spec.start.x, r.spec.start.y);
        let Some(cell) = indoor.grid.cell_of(x, y) else {
            continue;
        };
        if let Some(j) = taken.insert(cell, i) {
            return Err(c.error_at(
                &["robots", &i.to_string(), "start"],
                format!("x = {x}, y = {y} (vertex {cell:?})"),
                format!(
                    "a vertex no other robot of the coverage team starts on ({} starts on it)",
                    robots[j].spec.name
                ),
            ));
        }
    }
    Ok(())
}

fn check_robot_starts(
    c: &Checker,
    robots: &[ResolvedRobot],
    world: &World,
) -> Result<(), SceneError> {
    let [hx, hy] = world.half_extent;
    for (i, r) in robots.iter().enumerate() {
        let idx = i.to_string();
        let radius = r.model.body.length_m.max(r.model.body.width_m) / 2.0;
        let (x, y) = (r.spec.start.x, r.spec.start.y);
        if x.abs() > hx - radius || y.abs() > hy - radius {
            return Err(c.error_at(
                &["robots", &idx, "start"],
                format!("x = {x}, y = {y}"),
                format!(
                    "a start inside the world: |x| <= {}, |y| <= {} for this robot's size",
                    hx - radius,
                    hy - radius
                ),
            ));
        }
        let z = world.ground_z(x, y) + r.spec.start.z;
        if let Some(s) = world.solid_at(x, y, radius, z) {
            return Err(c.error_at(&["robots", &idx, "start"], format!("x = {x}, y = {y}"), format!("a start outside every obstacle: the robot would stand inside the {} centred at ({:.2}, {:.2})", format!("{:?}", s.kind).to_lowercase(), s.centre[0], s.centre[1])));
        }
        if let MissionSpec::Waypoints { points } = &r.spec.mission {
            for (k, p) in points.iter().enumerate() {
                if p[0].abs() > hx || p[1].abs() > hy {
                    return Err(c.error_at(
                        &["robots", &idx, "mission", "points", &k.to_string()],
                        format!("{p:?}"),
                        format!("a point inside the world: |x| <= {hx}, |y| <= {hy}"),
                    ));
                }
            }
        }
    }
    Ok(())
}
