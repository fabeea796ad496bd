//! The cooperative mapping mission of seed 002 run in lockstep, in a small room: unreachable
//! vertices and a lossy radio. The lab mission's own checks run with its golden digest
//! (`tests/golden.rs`), on both backends.

use hetsim_eval::Metrics;
use hetsim_tests::{hetsim, printed_digest, repo};
use std::path::Path;

/// A results folder's metrics.json, typed.
fn metrics(dir: &Path) -> Metrics {
    Metrics::read(dir).unwrap_or_else(|e| panic!("{e}"))
}

/// A small room (3 x 2 m, d = 0.5 m) whose south-east corner cell is walled off by two
/// cupboards, with a parent and two children; `extra` is appended (e.g. a `[comms]` table).
fn small_room(dir: &Path, extra: &str) -> std::path::PathBuf {
    let text = format!(
        r#"schema_version = 1
name = "small-room"
models_dir = "{models}"
seed = 3
dt_secs = 0.01
duration_secs = 3600.0

[world]
kind = "indoor_grid"

[world.indoor]
width_m = 3.0
height_m = 2.0
spacing_m = 0.5
obstruction_ratio = 0.0
wall_height_m = 2.5
obstacles = [
    {{ centre = [0.75, -0.75], size_m = [0.5, 0.5], height_m = 2.0 }},
    {{ centre = [1.25, -0.25], size_m = [0.5, 0.5], height_m = 2.0 }},
]

[[robots]]
name = "parent"
model = "parent"
start = {{ x = -0.75, y = 0.25 }}
mission = {{ kind = "coverage_parent" }}

[[robots]]
name = "child1"
model = "ctbot"
start = {{ x = -1.25, y = 0.25 }}
mission = {{ kind = "coverage_child" }}

[[robots]]
name = "child2"
model = "ctbot"
start = {{ x = -0.75, y = 0.75 }}
mission = {{ kind = "coverage_child" }}

[coverage]
r_los_m = 2.0
direction = "east"
view_margin_deg = 10.0
{extra}
"#,
        models = repo().join("robots/models").display()
    );
    let path = dir.join("small-room.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn an_unreachable_vertex_is_reported_not_looped_on() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = small_room(dir.path(), "");
    let out = dir.path().join("run");
    let o = hetsim(
        &[
            "run",
            scenario.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    printed_digest(&o);
    let m = metrics(&out);
    assert_eq!(m.unreachable_vertices, Some(vec![(5, 0)]));
    let t = m.team.as_ref().expect("metrics.json has a team section");
    assert!(t.finished, "{t:?}");
    let unplanned = &t.unplanned;
    assert!(unplanned.contains(&(5, 0)), "{t:?}");
    // Everything else is imaged, and the mission ended long before the scenario's hour.
    let target = t.vertices - t.parent_vertices - unplanned.len();
    assert_eq!(t.imaged, target, "{t:?}");
    assert!(m.sim_secs < 1200.0, "{}", m.sim_secs);
}

#[test]
fn the_mission_completes_with_ten_percent_comms_loss() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = small_room(dir.path(), "\n[comms]\nloss = 0.1\n");
    let out = dir.path().join("run");
    printed_digest(&hetsim(
        &[
            "run",
            scenario.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    ));
    let m = metrics(&out);
    let t = m.team.as_ref().expect("metrics.json has a team section");
    assert!(t.finished, "{t:?}");
    assert!(m.comms.dropped_loss > 0, "{:?}", m.comms);
    assert!(t.resent_orders > 0, "{t:?}");
    let target = t.vertices - t.parent_vertices - t.unplanned.len();
    assert_eq!(t.imaged, target, "{t:?}");
    // Nobody touched anything, the child's localization run after mapping included.
    assert_eq!(t.collisions, 0, "{t:?}");
    // The database reached the first child by the lossy radio, it drove its 20 moves and
    // its report came back: the mission ended with it, long before the scenario's hour.
    let localized = t.localized_min.expect("the localization run ended");
    assert!(m.sim_secs < localized * 60.0 + 3.0, "{m:?}");
    let runs = &t.localization;
    assert_eq!(runs.len(), 2, "{t:?}");
    for run in runs {
        assert_eq!(run.steps, 21, "{run:?}");
    }
}
