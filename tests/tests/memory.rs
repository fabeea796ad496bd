//! Per-tick state does not accumulate: over a long run, the heap grows by what the run is
//! meant to keep (the ground truth at the truth rate, and what the robots keep) and by
//! nothing per tick. The heap's bytes in use are counted by an instrumented global allocator
//! at every sim second.

use hetsim_scene::{load_scenario, LoadOptions};
use stats_alloc::{StatsAlloc, INSTRUMENTED_SYSTEM};
use std::sync::Mutex;

#[global_allocator]
static GLOBAL: &StatsAlloc<std::alloc::System> = &INSTRUMENTED_SYSTEM;

/// Heap bytes in use now.
fn heap() -> i64 {
    let s = GLOBAL.stats();
    // A reallocation is already counted in both totals (its growth or its shrinking).
    s.bytes_allocated as i64 - s.bytes_deallocated as i64
}

/// The heap in use at each sim second of a run of `scenario` for `secs`, without cameras.
fn heap_over_time(scenario: &str, secs: f64) -> (Vec<(f64, i64)>, i64) {
    // The allocator counts every thread: one measured run at a time.
    static ONE: Mutex<()> = Mutex::new(());
    let _one = ONE.lock().unwrap_or_else(|e| e.into_inner());
    let s = load_scenario(
        &hetsim_tests::repo().join(scenario),
        &LoadOptions {
            duration_secs: Some(secs),
            ..LoadOptions::default()
        },
    )
    .unwrap();
    let samples = Mutex::new(Vec::with_capacity(secs as usize + 8));
    let clock = s.clock;
    let stacks = hetsim_stacks::build_stacks(&s, false);
    let output = hetsim_engine::run(
        &s,
        stacks,
        |tick, _| {
            let h = heap();
            samples.lock().unwrap().push((clock.time_secs(tick), h));
        },
        hetsim_engine::RunOptions::default(),
    )
    .unwrap();
    let kept = kept_bytes(&output);
    drop(output);
    (samples.into_inner().unwrap(), kept)
}

/// What the robots keep, as their artifacts hold it: poses of trajectories, map landmarks,
/// reports' encoded bytes (postcard: a number takes at most its size in memory).
fn kept_bytes(output: &hetsim_engine::RunOutput) -> i64 {
    use hetsim_msgs::ArtifactData;
    let pose = std::mem::size_of::<(u64, hetsim_msgs::Pose)>();
    output
        .artifacts
        .iter()
        .flat_map(|(_, list)| list)
        .map(|a| match &a.data {
            ArtifactData::Trajectory(t) => t.len() * pose,
            ArtifactData::Map { points, segments } => points.len() * 32 + segments.len() * 56,
            ArtifactData::Report(bytes) => bytes.len(),
        } as i64)
        .sum()
}

/// The heap at the first sample at or after `t` seconds.
fn at(samples: &[(f64, i64)], t: f64) -> i64 {
    samples.iter().find(|(s, _)| *s >= t).unwrap().1
}

/// Heap growth from `from` to the end of a `secs` run of `scenario`, with the samples.
fn growth(scenario: &str, from: f64, secs: f64) -> (i64, Vec<(f64, i64)>, i64) {
    let (samples, kept) = heap_over_time(scenario, secs);
    (at(&samples, secs) - at(&samples, from), samples, kept)
}

/// The run reserves its ground truth for its whole length up front, so from the first
/// seconds on the heap grows only by what the robots keep. Waypoint pilots keep nothing that
/// grows; a few KiB of slack cover allocator-visible noise (a BTreeMap node, a Vec of
/// messages that a busier tick widens).
#[test]
fn a_long_run_keeps_no_per_tick_state() {
    let (grown, samples, kept) = growth("scenarios/indoor-grid-20.toml", 20.0, 240.0);
    assert_eq!(kept, 0, "waypoint pilots publish nothing");
    println!("indoor-grid-20: the heap grew by {grown} bytes from 20 s to 240 s");
    assert!(
        grown <= 64 * 1024,
        "indoor-grid-20: the heap grew by {grown} bytes from 20 s to 240 s (22,000 ticks): per-tick state accumulates ({:?})",
        samples.iter().step_by(20).collect::<Vec<_>>()
    );
}

/// The coverage team without cameras (laser, compass, encoders, orders over the radio; no
/// panoramas, so no hat fixes: the parent drives its children by dead reckoning): the heap
/// grows by what the robots keep (the parent's record of each child's tracked path) and no
/// more, however long a child waits for an image that never comes (without cameras, none
/// does).
#[test]
fn a_long_coverage_mission_keeps_no_per_tick_state() {
    let (grown, samples, kept) = growth("scenarios/lab.toml", 20.0, 300.0);
    println!("lab: the heap grew by {grown} bytes from 20 s to 300 s; the robots keep {kept}");
    // What the robots keep (no tracked paths here: no panoramas, no fixes) is in Vecs whose
    // capacity is at most twice their length.
    assert!(
        grown <= 2 * kept + 16 * 1024,
        "lab: the heap grew by {grown} bytes from 20 s to 300 s, the robots keep {kept}: per-tick state accumulates ({:?})",
        samples.iter().step_by(10).collect::<Vec<_>>()
    );
}

/// On demand (`HETSIM_RECORDING=village.mcap cargo test --release -p hetsim-tests --test
/// memory -- --ignored --nocapture`): the robot software's heap, replaying a recording, at
/// every 10 sim seconds, and what its artifacts hold at the end. How `results/replay/README.md`
/// attributes the full village's memory growth.
#[test]
#[ignore = "needs a recording; a measurement, not a check"]
fn robot_software_heap_over_a_recording() {
    let path = std::path::PathBuf::from(
        std::env::var("HETSIM_RECORDING").expect("HETSIM_RECORDING=<a recording>"),
    );
    static ONE: Mutex<()> = Mutex::new(());
    let _one = ONE.lock().unwrap();
    let mut rec = hetsim_io::McapRecording::open(&path).unwrap();
    let run = rec.run.clone();
    let s = hetsim_scene::load_scenario_text(
        &run.scenario_path,
        run.scenario_text.clone(),
        &LoadOptions {
            seed: Some(run.seed),
            duration_secs: Some(run.duration_secs),
            robot_files: Some(run.robot_files.clone()),
        },
    )
    .unwrap();
    let stacks = hetsim_stacks::build_stacks(&s, false)
        .into_iter()
        .map(Some)
        .collect();
    let clock = s.clock;
    let samples = Mutex::new(Vec::with_capacity(10_000));
    let output = hetsim_engine::replay(&s, stacks, &mut rec, |tick, _| {
        let h = heap();
        samples.lock().unwrap().push((clock.time_secs(tick), h));
    })
    .unwrap();
    for (t, h) in samples
        .lock()
        .unwrap()
        .iter()
        .filter(|(t, _)| (t % 10.0).abs() < 1e-9)
    {
        println!("{t:6.0} s: heap {:8.2} MiB", *h as f64 / 1048576.0);
    }
    // Least-squares slope of the heap from 20 s on, every sim second.
    let pts: Vec<(f64, f64)> = samples
        .lock()
        .unwrap()
        .iter()
        .filter(|(t, _)| *t >= 20.0)
        .map(|(t, h)| (*t, *h as f64))
        .collect();
    let n = pts.len() as f64;
    let (mt, mh) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let slope = pts.iter().map(|p| (p.0 - mt) * (p.1 - mh)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mt).powi(2)).sum::<f64>();
    println!(
        "heap slope from 20 s: {:.1} KiB per sim second",
        slope / 1024.0
    );
    println!(
        "artifacts: {:.2} MiB",
        kept_bytes(&output) as f64 / 1048576.0
    );
}
