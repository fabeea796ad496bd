//! `hetsim bench --replay`: a scenario run live with its recording, then the recording
//! replayed, back to back in one process: both speeds, the ratio, the recording's size, the
//! peak resident memory of each, and whether the replay reproduced the live run's digest.
//! With `--out DIR`, each phase's resident memory against sim time as `memory.csv` and
//! `memory.png`.

use super::Figures;
use crate::exec::{Job, MemoryTrace};
use crate::replay::ReplayArgs;
use anyhow::{Context, Result};
use serde_json::json;
use std::path::Path;

/// One phase's figures: wall seconds, the trace, and the digest.
struct Phase {
    wall: f64,
    trace: Vec<(f64, f64)>,
    digest: String,
}

fn timed(f: impl FnOnce(&MemoryTrace) -> Result<String>) -> Result<Phase> {
    let trace = MemoryTrace::default();
    let start = super::wall_clock();
    let digest = f(&trace)?;
    let wall = start.elapsed().as_secs_f64();
    Ok(Phase {
        wall,
        trace: trace.into_inner().expect("memory trace lock"),
        digest,
    })
}

/// Runs `scenario` for `sim_secs` rendered and recorded, then replays the recording.
pub fn replay(scenario: &Path, sim_secs: f64, out: Option<&Path>) -> Result<Figures> {
    let loaded = super::load_for(scenario, sim_secs)?;
    let tmp = tempfile::tempdir().context("a temporary folder for the recording")?;
    let rec = tmp.path().join("run.mcap");
    let live = timed(|memory| {
        let files = crate::exec::run_scenario(
            &loaded,
            &Job {
                out: Some(&tmp.path().join("live")),
                record: Some((&rec, hetsim_engine::record::RecordEncoding::Ros2)),
                render: Some(hetsim_render::RenderOptions::default()),
                dump: None,
                open_loop: false,
                quiet: false,
                memory: Some(memory),
            },
        )?;
        Ok(files.digest)
    })?;
    let bytes = std::fs::metadata(&rec)
        .with_context(|| format!("{}", rec.display()))?
        .len();
    let replayed = timed(|memory| {
        let files = crate::replay::replay(&ReplayArgs {
            source: rec.clone(),
            robots: Vec::new(),
            out: Some(tmp.path().join("replay")),
            set: Vec::new(),
            scenario: None,
            duration: None,
            quiet: false,
            memory: Some(memory),
        })?;
        Ok(files.digest)
    })?;
    let mut f = Figures::new(
        "replay",
        &[
            ("phase", "phase"),
            ("sim_s", "sim s"),
            ("wall_s", "wall s"),
            ("realtime", "x real time"),
            ("peak_rss_mib", "peak RSS MiB"),
        ],
    );
    let peak = |t: &[(f64, f64)]| t.iter().map(|p| p.1).fold(0.0, f64::max);
    for (name, p) in [
        ("live, rendering and recording", &live),
        ("replay", &replayed),
    ] {
        f.row(vec![
            json!(name),
            json!(sim_secs),
            json!(p.wall),
            json!(sim_secs / p.wall.max(1e-9)),
            json!(peak(&p.trace)),
        ]);
    }
    let mb = bytes as f64 / 1e6;
    f.about
        .insert("scenario".into(), json!(scenario.display().to_string()));
    f.about
        .insert("threads".into(), json!(crate::exec::rayon_threads()));
    f.about.insert(
        "replay_speedup".into(),
        json!(live.wall / replayed.wall.max(1e-9)),
    );
    f.about.insert("recording_mb".into(), json!(mb));
    f.about.insert(
        "recording_mb_per_sim_minute".into(),
        json!(mb * 60.0 / sim_secs),
    );
    f.about
        .insert("same_digest".into(), json!(live.digest == replayed.digest));
    f.about.insert("digest".into(), json!(live.digest));
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
        let mut csv = String::from("phase,sim_s,rss_mib\n");
        for (name, p) in [("live", &live), ("replay", &replayed)] {
            for (t, m) in &p.trace {
                csv.push_str(&format!("{name},{t:.2},{m:.1}\n"));
            }
        }
        hetsim_core::files::write_atomic(&dir.join("memory.csv"), csv.as_bytes())?;
        let png = hetsim_eval::charts::lines_png(
            &format!("{}: resident memory against sim time", loaded.file.name),
            "sim time [s]",
            "resident memory [MiB]",
            &[
                (
                    "live run, rendering and recording".into(),
                    live.trace.clone(),
                ),
                ("replay of its recording".into(), replayed.trace.clone()),
            ],
        );
        hetsim_core::files::write_atomic(&dir.join("memory.png"), &png)?;
    }
    Ok(f)
}
