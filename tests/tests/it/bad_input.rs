//! Broken scenario and robot files are refused with the file, line, field, value and what is
//! allowed; the CLI exits non-zero and writes no results.

use hetsim_scene::{load_scenario, LoadOptions, SceneError};
use hetsim_tests::{hetsim, repo};
use std::path::PathBuf;

const SCENARIO: &str = r#"schema_version = 1
name = "broken"
seed = 3
dt_secs = 0.01
duration_secs = 1.0
models_dir = "models"

[world]
kind = "indoor_grid"

[world.indoor]
width_m = 4.0
height_m = 3.0
spacing_m = 0.5
obstruction_ratio = 0.1
obstacles = [ { centre = [1.0, 1.0], size_m = [1.0, 1.0], height_m = 2.0 } ]

[[robots]]
name = "child1"
model = "ctbot"
start = { x = -1.25, y = -0.75, yaw_deg = 0.0 }
mission = { kind = "grid_goals", goals = [[1, 1]] }
"#;

/// Writes a scenario (and a models folder with the shipped robots, `ctbot.toml` replaced by
/// `ctbot` when given) and loads it.
fn load(scenario: &str, ctbot: Option<&str>) -> (PathBuf, SceneError, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir(&models).unwrap();
    for m in ["ctbot", "parent", "dala", "ressac"] {
        std::fs::copy(
            repo().join(format!("robots/models/{m}.toml")),
            models.join(format!("{m}.toml")),
        )
        .unwrap();
    }
    if let Some(text) = ctbot {
        std::fs::write(models.join("ctbot.toml"), text).unwrap();
    }
    let path = dir.path().join("broken.toml");
    std::fs::write(&path, scenario).unwrap();
    let err = load_scenario(&path, &LoadOptions::default()).expect_err("must be refused");
    (path, err, dir)
}

fn ctbot() -> String {
    std::fs::read_to_string(repo().join("robots/models/ctbot.toml")).unwrap()
}

/// Asserts the message names the file, the line, the field, the value, and what is allowed.
fn assert_names(
    err: &SceneError,
    file_end: &str,
    line: usize,
    field: &str,
    value: &str,
    allowed: &str,
) {
    let f = err
        .as_field()
        .unwrap_or_else(|| panic!("not a field error: {err}"));
    let msg = err.to_string();
    assert!(f.file.ends_with(file_end), "file {:?} in {msg}", f.file);
    assert_eq!(f.line, Some(line), "line in {msg}");
    assert!(f.field.contains(field), "field {field:?} in {msg}");
    assert!(f.value.contains(value), "value {value:?} in {msg}");
    assert!(f.allowed.contains(allowed), "allowed {allowed:?} in {msg}");
    assert!(msg.contains(&format!(":{line}:")), "{msg}");
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .unwrap_or_else(|| panic!("{needle} not in text"))
        + 1
}

#[test]
fn the_base_file_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir(&models).unwrap();
    std::fs::copy(
        repo().join("robots/models/ctbot.toml"),
        models.join("ctbot.toml"),
    )
    .unwrap();
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, SCENARIO).unwrap();
    load_scenario(&path, &LoadOptions::default()).unwrap();
}

#[test]
fn syntax_error() {
    let text = SCENARIO.replace("seed = 3", "seed = = 3");
    let (_, e, _d) = load(&text, None);
    assert_names(&e, "broken.toml", 3, "(syntax)", "seed = = 3", "valid TOML");
}

#[test]
fn unknown_scenario_field() {
    let text = SCENARIO.replace("seed = 3", "seed = 3\nsped = 4");
    let (_, e, _d) = load(&text, None);
    assert_names(&e, "broken.toml", 4, "sped", "sped = 4", "unknown field");
}

#[test]
fn unknown_robot_file_field() {
    let robot = ctbot().replace("mass_kg = 0.6", "mass_kg = 0.6\nmass_lb = 1.3");
    let (_, e, _d) = load(SCENARIO, Some(&robot));
    assert_names(
        &e,
        "models/ctbot.toml",
        line_of(&robot, "mass_lb"),
        "mass_lb",
        "mass_lb = 1.3",
        "expected one of",
    );
}

#[test]
fn wrong_schema_version() {
    let text = SCENARIO.replace("schema_version = 1", "schema_version = 7");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        1,
        "schema_version",
        "7",
        "schema_version = 1",
    );
}

#[test]
fn missing_required_field() {
    let text = SCENARIO.replace("dt_secs = 0.01\n", "");
    let (_, e, _d) = load(&text, None);
    let msg = e.to_string();
    assert!(
        msg.contains("broken.toml:") && msg.contains("dt_secs"),
        "{msg}"
    );
}

#[test]
fn missing_robot_model() {
    let text = SCENARIO.replace("model = \"ctbot\"", "model = \"ctbot9\"");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "ctbot9"),
        "robots[0].model",
        "ctbot9",
        "one of ctbot, dala, parent, ressac",
    );
}

#[test]
fn zero_sensor_rate() {
    let robot = ctbot().replace("rate_hz = 2.0", "rate_hz = 0.0");
    let (_, e, _d) = load(SCENARIO, Some(&robot));
    assert_names(
        &e,
        "models/ctbot.toml",
        line_of(&robot, "rate_hz = 0.0"),
        "sensors[0].rate_hz",
        "0",
        "a rate > 0",
    );
}

#[test]
fn negative_sensor_rate() {
    let robot = ctbot().replace("rate_hz = 10.0", "rate_hz = -10.0");
    let (_, e, _d) = load(SCENARIO, Some(&robot));
    assert_names(
        &e,
        "models/ctbot.toml",
        line_of(&robot, "rate_hz = -10.0"),
        "sensors[1].rate_hz",
        "-10",
        "a rate > 0",
    );
}

#[test]
fn slam_table_unknown_field_and_value_out_of_range() {
    // The [slam] table's fields are the SLAM's own parameters: a misspelt one is refused
    // with the fields that exist, a value out of its range with the range.
    let robot = format!(
        "{}\n[slam]\nsigma_px = 0.8\n[slam.matching]\nmin_inlier = 5\n",
        ctbot()
    );
    let (_, e, _d) = load(SCENARIO, Some(&robot));
    assert_names(
        &e,
        "models/ctbot.toml",
        line_of(&robot, "min_inlier = 5"),
        "slam.matching.min_inlier",
        "5",
        "`min_inliers`",
    );
    let robot = format!("{}\n[slam]\nmatching = {{ ratio = 1.5 }}\n", ctbot());
    let (_, e, _d) = load(SCENARIO, Some(&robot));
    assert_names(
        &e,
        "models/ctbot.toml",
        line_of(&robot, "matching = "),
        "slam.matching.ratio",
        "1.5",
        "[0.01, 1]",
    );
}

#[test]
fn sensor_faster_than_the_tick() {
    let robot = ctbot().replace("rate_hz = 10.0", "rate_hz = 500.0");
    let (_, e, _d) = load(SCENARIO, Some(&robot));
    assert_names(
        &e,
        "models/ctbot.toml",
        line_of(&robot, "rate_hz = 500.0"),
        "sensors[1].rate_hz",
        "500",
        "tick rate 100 Hz",
    );
}

#[test]
fn non_positive_dt() {
    let text = SCENARIO.replace("dt_secs = 0.01", "dt_secs = 0.0");
    let (_, e, _d) = load(&text, None);
    assert_names(&e, "broken.toml", 4, "dt_secs", "0", "[0.000001, 1]");
}

#[test]
fn obstruction_ratio_out_of_range() {
    let text = SCENARIO.replace("obstruction_ratio = 0.1", "obstruction_ratio = 0.95");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "obstruction_ratio"),
        "world.indoor.obstruction_ratio",
        "0.95",
        "[0, 0.6]",
    );
}

#[test]
fn robot_inside_an_obstacle() {
    let text = SCENARIO.replace("x = -1.25, y = -0.75", "x = 0.75, y = 0.75");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "start ="),
        "robots[0].start",
        "x = 0.75, y = 0.75",
        "outside every obstacle",
    );
}

#[test]
fn robot_outside_the_world() {
    let text = SCENARIO.replace("x = -1.25, y = -0.75", "x = -9.0, y = -0.75");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "start ="),
        "robots[0].start",
        "x = -9",
        "inside the world",
    );
}

#[test]
fn duplicate_robot_names() {
    let text = format!("{SCENARIO}\n[[robots]]\nname = \"child1\"\nmodel = \"ctbot\"\nstart = {{ x = 1.25, y = -0.75 }}\nmission = {{ kind = \"idle\" }}\n");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        text.lines()
            .collect::<Vec<_>>()
            .iter()
            .rposition(|l| *l == "name = \"child1\"")
            .unwrap()
            + 1,
        "robots[1].name",
        "child1",
        "not used by another robot",
    );
}

#[test]
fn wrong_value_type() {
    let text = SCENARIO.replace("duration_secs = 1.0", "duration_secs = \"long\"");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        5,
        "duration_secs",
        "\"long\"",
        "invalid type",
    );
}

#[test]
fn extent_not_a_multiple_of_the_spacing() {
    let text = SCENARIO.replace("width_m = 4.0", "width_m = 4.2");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "width_m = 4.2"),
        "world.indoor.width_m",
        "4.2",
        "multiple of spacing_m",
    );
}

#[test]
fn grid_goal_outside_the_grid() {
    let text = SCENARIO.replace("goals = [[1, 1]]", "goals = [[1, 1], [8, 1]]");
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "goals ="),
        "robots[0].mission.goals[1]",
        "[8, 1]",
        "col < 8",
    );
}

#[test]
fn unknown_override_path() {
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\"",
        "overrides = { \"body.top_speed\" = 1.0 }\nmission = { kind = \"grid_goals\"",
    );
    let (_, e, _d) = load(&text, None);
    assert_names(
        // The key is written into the robot file's [body] table, whose parser refuses it and
        // lists the fields it accepts.
        &e,
        "broken.toml",
        line_of(&text, "overrides"),
        "top_speed",
        "1.0",
        "expected one of `drive`",
    );
}

#[test]
fn override_with_a_bad_value() {
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\"",
        "overrides = { \"sensors.compass.sigma_deg\" = -2.0 }\nmission = { kind = \"grid_goals\"",
    );
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "overrides"),
        "sensors[1].sigma_deg",
        "-2",
        "[0, 90]",
    );
}

#[test]
fn lawnmower_for_a_ground_robot() {
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\", goals = [[1, 1]] }",
        "mission = { kind = \"lawnmower\", from = [0.0, 0.0], to = [1.0, 0.0], width_m = 1.0, spacing_m = 0.5, altitude_m = 5.0 }",
    );
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "lawnmower"),
        "robots[0].mission.kind",
        "lawnmower",
        "for helicopters",
    );
}

#[test]
fn a_refused_run_exits_non_zero_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let models = dir.path().join("models");
    std::fs::create_dir(&models).unwrap();
    std::fs::copy(
        repo().join("robots/models/ctbot.toml"),
        models.join("ctbot.toml"),
    )
    .unwrap();
    let path = dir.path().join("broken.toml");
    std::fs::write(
        &path,
        SCENARIO.replace("x = -1.25, y = -0.75", "x = 0.75, y = 0.75"),
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = hetsim(
        &[
            "run",
            path.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("broken.toml:21: field `robots[0].start`"),
        "{stderr}"
    );
    assert!(!out_dir.exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        leftovers.len(),
        2,
        "only the scenario and models/: {leftovers:?}"
    );
}

#[test]
fn override_into_a_missing_table() {
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\"",
        "overrides = { \"wings.span_m\" = 2.0 }\nmission = { kind = \"grid_goals\"",
    );
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "overrides"),
        "wings.span_m",
        "2.0",
        "existing field",
    );
}

#[test]
fn coverage_child_without_a_parent() {
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\", goals = [[1, 1]] }",
        "mission = { kind = \"coverage_child\" }",
    );
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "coverage_child"),
        "robots[0].mission.kind",
        "coverage_child",
        "exactly one robot with mission coverage_parent",
    );
}

/// The base scenario with its robot made a parent running the coverage mission.
fn parent_scenario() -> String {
    SCENARIO
        .replace("model = \"ctbot\"", "model = \"parent\"")
        .replace(
            "mission = { kind = \"grid_goals\", goals = [[1, 1]] }",
            "mission = { kind = \"coverage_parent\" }",
        )
}

/// `line` in a `[coverage]` table appended to `base` is refused, naming its line, field and
/// value and what is allowed.
fn assert_coverage_refused(base: &str, line: &str, allowed: &str) {
    let text = format!("{base}\n[coverage]\n{line}\n");
    let (_, e, _d) = load(&text, None);
    let (field, value) = line.split_once(" = ").unwrap();
    let at = format!("coverage.{field}");
    let value = value.trim_matches('"');
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, field),
        &at,
        value,
        allowed,
    );
}

#[test]
fn coverage_values_out_of_range() {
    assert_coverage_refused(SCENARIO, "views = \"some_grabs\"", "\"every_grab\" or");
    assert_coverage_refused(SCENARIO, "localize_steps = 5000", "a number in [0, 1000]");
    assert_coverage_refused(SCENARIO, "view_margin_m = 0.75", "a number in [0, 0.5]");
    let one_of = "one of \"ours\", \"parent_a_point\"";
    assert_coverage_refused(SCENARIO, "reading = \"eq6_some_choice\"", one_of);
}

/// A mission the simulator runs renders its images and is the shipped planner: "start_points"
/// (which checks no grab) and the other readings of the open points are for grid plans only.
#[test]
fn grid_planning_settings_in_a_mission_the_simulator_runs() {
    let parent = parent_scenario();
    let only = "in a scenario whose parent runs the mission";
    let views = format!("\"every_grab\" {only}");
    assert_coverage_refused(&parent, "views = \"start_points\"", &views);
    assert_coverage_refused(
        &parent,
        "reading = \"los_strict\"",
        &format!("\"ours\" {only}"),
    );
}

#[test]
fn coverage_parent_without_a_coverage_table() {
    let text = parent_scenario();
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "coverage_parent"),
        "robots[0].mission.kind",
        "coverage_parent",
        "a [coverage] table",
    );
}

#[test]
fn coverage_child_without_a_compass() {
    let robot = ctbot()
        .replace("kind = \"compass\"", "kind = \"gps\"")
        .replace("sigma_deg = 3.5", "sigma_m = 2.0");
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\", goals = [[1, 1]] }",
        "mission = { kind = \"coverage_child\" }",
    );
    let (_, e, _d) = load(&text, Some(&robot));
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "coverage_child"),
        "robots[0].mission.kind",
        "coverage_child",
        "a camera, a compass and wheel_odometry",
    );
}

#[test]
fn rendezvous_with_a_negative_range() {
    let text = std::fs::read_to_string(repo().join("scenarios/village-short.toml"))
        .unwrap()
        .replace(
            "duration_secs = 45.0",
            "duration_secs = 45.0\nmodels_dir = \"models\"",
        )
        .replacen(
            "\"sensors.gps.outages_s\" = [[0.0, 100000.0]] }",
            "\"sensors.gps.outages_s\" = [[0.0, 100000.0]], \"sensors.rendezvous.range_m\" = -3.0 }",
            1,
        );
    let (_, e, _d) = load(&text, None);
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "rendezvous.range_m"),
        "range_m",
        "-3",
        "> 0",
    );
}

#[test]
fn coverage_robot_too_big_to_turn_in_its_cell() {
    // A 0.36 m square reaches 0.255 m from its centre turning in place: past the 0.25 m to
    // the side of its 0.5 m cell.
    let robot = ctbot()
        .replace("length_m = 0.12", "length_m = 0.36")
        .replace("width_m = 0.12", "width_m = 0.36");
    let text = SCENARIO.replace(
        "mission = { kind = \"grid_goals\", goals = [[1, 1]] }",
        "mission = { kind = \"coverage_child\" }",
    );
    let (_, e, _d) = load(&text, Some(&robot));
    assert_names(
        &e,
        "broken.toml",
        line_of(&text, "model = \"ctbot\""),
        "robots[0].model",
        "ctbot",
        "half-diagonal 0.255 m",
    );
}
