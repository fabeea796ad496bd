//! Every shipped file loads; the worlds they describe have the properties DESIGN.md asks for.

use hetsim_engine::RunOptions;
use hetsim_scene::world::SolidKind;
use hetsim_scene::{load_robot_model, load_scenario, LoadOptions, Sensor};
use hetsim_tests::repo;

fn files_in(dir: &str) -> Vec<std::path::PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(repo().join(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
}

#[test]
fn every_scenario_and_robot_file_loads() {
    let scenarios = files_in("scenarios");
    assert!(scenarios.len() >= 5, "{scenarios:?}");
    for s in scenarios {
        load_scenario(&s, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    }
    let models = files_in("robots/models");
    assert_eq!(models.len(), 4);
    for m in models {
        load_robot_model(&m, 1e-3).unwrap_or_else(|e| panic!("{e}"));
    }
    // The shipped sweeps: each loads, and every combination of its axes makes a valid
    // scenario (load_sweep checks the first seed of each); the village and lab examples are
    // whole-run sweeps.
    let sweeps = files_in("scenarios/sweeps");
    let mut kinds = Vec::new();
    for s in &sweeps {
        let text = std::fs::read_to_string(s).unwrap();
        let sweep = match hetsim_eval::sweep::load_sweep(s) {
            Ok(sweep) => sweep,
            // A sweep over a recording needs the recording, which is made, not shipped (its
            // header says how): without it, a clear refusal naming the field.
            Err(e) if text.contains("\nrecording = ") => {
                let e = e.to_string();
                assert!(
                    e.contains("field `recording`") && e.contains("--record FILE"),
                    "{e}"
                );
                continue;
            }
            Err(e) => panic!("{e}"),
        };
        kinds.push((sweep.file.name.clone(), sweep.file.kind));
    }
    use hetsim_eval::sweep::SweepKind::{Plan, Run};
    for (name, kind) in [
        ("table1", Plan),
        ("table2", Plan),
        ("village-noise", Run),
        ("lab-compass", Run),
    ] {
        assert!(
            kinds.contains(&(name.to_string(), kind)),
            "{name}: {kinds:?}"
        );
    }
}

#[test]
fn robot_files_carry_the_seed_figures() {
    let model =
        |n: &str| load_robot_model(&repo().join(format!("robots/models/{n}.toml")), 1e-3).unwrap();
    let stereo = |m: &hetsim_scene::RobotModel| {
        m.sensors.iter().find_map(|s| match s {
            Sensor::StereoCamera {
                width_px,
                height_px,
                baseline_m,
                ..
            } => Some((*width_px, *height_px, *baseline_m)),
            _ => None,
        })
    };
    assert_eq!(stereo(&model("dala")), Some((1024, 768, 0.35)));
    assert_eq!(stereo(&model("ressac")), Some((1024, 768, 0.9)));
    let ctbot = model("ctbot");
    assert!((ctbot.body.length_m - 0.12).abs() < 1e-12);
    assert!((ctbot.pilot.cruise_mps - 0.15).abs() < 1e-12);
    assert_eq!(ctbot.pilot.reaim_m, Some(0.2));
    assert!(ctbot.sensors.iter().any(|s| matches!(s, Sensor::Camera { width_px: 120, height_px: 88, hfov_deg: Some(f), .. } if (*f - 80.0).abs() < 1e-12)));
    let parent = model("parent");
    // The parent tracks its children by image (its panoramas), not with the emulated tracker.
    assert!(!parent
        .sensors
        .iter()
        .any(|s| matches!(s, Sensor::ChildTracker { .. })));
    assert!(parent.sensors.iter().any(|s| matches!(
        s,
        Sensor::OmniCamera {
            width_px: 780,
            height_px: 580,
            ..
        }
    )));
}

#[test]
fn indoor_grids_reach_their_obstruction_ratio_and_stay_connected() {
    for (file, ratio) in [
        ("indoor-grid-0", 0.0),
        ("indoor-grid-20", 0.2),
        ("indoor-grid-40", 0.4),
    ] {
        for seed in 0..5 {
            let s = load_scenario(
                &repo().join(format!("scenarios/{file}.toml")),
                &LoadOptions {
                    robot_files: None,
                    seed: Some(seed),
                    duration_secs: None,
                },
            )
            .unwrap();
            let g = s.world.grid.as_ref().unwrap();
            assert_eq!((g.grid.cols, g.grid.rows), (60, 60));
            assert!(
                (g.realised_ratio - ratio).abs() < 0.01,
                "{file} seed {seed}: realised {}",
                g.realised_ratio
            );
            assert!(
                g.unreachable.is_empty(),
                "{file} seed {seed}: {:?}",
                g.unreachable
            );
            // Obstacles are taller than every sensor of every robot in the scenario.
            let highest_sensor = s
                .robots
                .iter()
                .flat_map(|r| r.model.sensors.iter().map(|x| x.mount().xyz_m[2]))
                .fold(0.0, f64::max);
            for o in s
                .world
                .solids
                .iter()
                .filter(|o| o.kind == SolidKind::Obstacle)
            {
                assert!(
                    o.top_z() > highest_sensor,
                    "obstacle {} m <= sensor {highest_sensor} m",
                    o.top_z()
                );
            }
        }
    }
}

#[test]
fn different_seeds_make_different_indoor_maps() {
    let path = repo().join("scenarios/indoor-grid-20.toml");
    let a = load_scenario(
        &path,
        &LoadOptions {
            robot_files: None,
            seed: Some(1),
            duration_secs: None,
        },
    )
    .unwrap();
    let b = load_scenario(
        &path,
        &LoadOptions {
            robot_files: None,
            seed: Some(2),
            duration_secs: None,
        },
    )
    .unwrap();
    let c = load_scenario(
        &path,
        &LoadOptions {
            robot_files: None,
            seed: Some(1),
            duration_secs: None,
        },
    )
    .unwrap();
    assert_ne!(a.world.grid, b.world.grid);
    assert_eq!(a.world.grid, c.world.grid);
}

#[test]
fn the_lab_has_84_free_vertices_all_connected() {
    let s = load_scenario(&repo().join("scenarios/lab.toml"), &LoadOptions::default()).unwrap();
    let g = s.world.grid.as_ref().unwrap();
    assert_eq!(g.grid.free_count(), 84);
    assert!(g.unreachable.is_empty());
    let area = g.grid.cols as f64 * g.grid.rows as f64 * g.grid.cell_m * g.grid.cell_m;
    assert!((area - 32.0).abs() < 1.0, "room area {area} m^2");
}

#[test]
fn the_village_has_two_building_groups_and_the_rover_starts_in_the_north_west_one() {
    let s = load_scenario(
        &repo().join("scenarios/village.toml"),
        &LoadOptions::default(),
    )
    .unwrap();
    let buildings: Vec<_> = s
        .world
        .solids
        .iter()
        .filter(|b| b.kind == SolidKind::Building)
        .collect();
    let nw = buildings
        .iter()
        .filter(|b| b.centre[0] < 0.0 && b.centre[1] > 0.0)
        .count();
    let se = buildings
        .iter()
        .filter(|b| b.centre[0] > 0.0 && b.centre[1] < 0.0)
        .count();
    assert!(nw >= 8 && se >= 8, "nw {nw} se {se}");
    assert_eq!(nw + se, buildings.len());
    let terrain = s.world.terrain.as_ref().unwrap();
    let (lo, hi) = terrain
        .heights
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), h| (a.min(*h), b.max(*h)));
    assert!(hi - lo > 2.0, "terrain has relief: {lo}..{hi}");
    let dala = &s.robots[0].spec.start;
    let near = buildings
        .iter()
        .filter(|b| (b.centre[0] - dala.x).hypot(b.centre[1] - dala.y) < 80.0)
        .count();
    assert!(
        near >= 5,
        "the rover starts among buildings ({near} within 80 m)"
    );
    for b in &buildings {
        assert!(!b.footprint_overlaps(dala.x, dala.y, 1.0));
    }
}

#[test]
fn in_the_village_the_rover_rides_the_terrain_and_the_helicopter_holds_40_m() {
    let s = load_scenario(
        &repo().join("scenarios/village.toml"),
        &LoadOptions {
            robot_files: None,
            seed: None,
            duration_secs: Some(120.0),
        },
    )
    .unwrap();
    let result = hetsim_tests::run_scenario(&s, RunOptions::default());
    let terrain = s.world.terrain.as_ref().unwrap();
    let (_, dala) = &result.truth[0];
    let (_, ressac) = &result.truth[1];
    for (_, pose) in dala {
        let t = pose.translation.vector;
        // Seated by rays on the heightfield's triangles vs. bilinear interpolation here: close.
        assert!(
            (t.z - terrain.height_at(t.x, t.y)).abs() < 0.3,
            "rover at {t:?}"
        );
    }
    let start_ground = terrain.height_at(-110.0, 110.0);
    assert!((ressac[0].1.translation.z - (start_ground + 40.0)).abs() < 1e-9);
    for (stamp, pose) in ressac.iter().filter(|(t, _)| *t > 30_000_000_000) {
        let z = pose.translation.z;
        assert!((z - 40.0).abs() < 3.0, "helicopter at {z} m at {stamp} ns");
    }
    let travelled = result.robots[1].distance_m;
    // Cruise is 6 m/s; accelerating and turning at the leg ends costs some of that.
    assert!(travelled > 400.0, "helicopter flew {travelled} m in 120 s");
    assert_eq!(result.robots.iter().map(|r| r.collisions).sum::<u32>(), 0);
}
