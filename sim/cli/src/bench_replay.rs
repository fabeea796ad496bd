//! `hetsim bench --replay`: a scenario run live with its recording, then the recording
//! replayed in a process of its own, back to back: both speeds, the ratio, the recording's
//! size, the peak resident memory of each, and whether the replay reproduced the live run's
//! digest.
//! With `--out DIR`, each phase's resident memory against sim time as `memory.csv` and
//! `memory.png`.

use crate::bench::Figures;
use crate::exec::{Job, MemoryTrace};
use anyhow::{Context, Result};
use serde_json::json;
use std::path::Path;

/// One phase's figures: wall seconds, resident memory against sim time, the peak, and the
/// digest.
struct Phase {
    wall: f64,
    trace: Vec<(f64, f64)>,
    peak: f64,
    digest: String,
}

/// Runs `scenario` for `sim_secs` rendered and recorded (in this process), then replays
/// the recording in a process of its own, so that neither phase's memory holds the other's.
/// The live run's results folder is kept in `results/runs/bench-replay-<name>`.
pub fn replay(scenario: &Path, sim_secs: f64, out: Option<&Path>) -> Result<Figures> {
    let loaded = crate::bench::load_for(scenario, sim_secs)?;
    let tmp = tempfile::tempdir().context("a temporary folder for the recording")?;
    let rec = tmp.path().join("run.mcap");
    let kept = Path::new("results/runs").join(format!("bench-replay-{}", loaded.file.name));
    let trace = MemoryTrace::default();
    let start = crate::bench::wall_clock();
    let files = crate::exec::run_scenario(
        &loaded,
        &Job {
            out: Some(&kept),
            record: Some((&rec, hetsim_io::RecordEncoding::Ros2)),
            render: Some(hetsim_render::RenderOptions::default()),
            dump: None,
            open_loop: false,
            quiet: false,
            memory: Some(&trace),
            // The benchmark's own folder, remade by each benchmark run.
            replace: true,
            record_anyway: false,
        },
    )?;
    let live = Phase {
        wall: start.elapsed().as_secs_f64(),
        trace: trace.into_inner().expect("memory trace lock"),
        peak: crate::exec::peak_resident_mib().unwrap_or(f64::NAN),
        digest: files.digest,
    };
    let bytes = std::fs::metadata(&rec)
        .with_context(|| format!("{}", rec.display()))?
        .len();
    // The replay in a fresh process: `hetsim replay REC --memory-trace FILE`.
    let memory = tmp.path().join("replay-memory.csv");
    let exe = std::env::current_exe().context("this executable's path")?;
    let start = crate::bench::wall_clock();
    let child = std::process::Command::new(exe)
        .arg("replay")
        .arg(&rec)
        .arg("--out")
        .arg(tmp.path().join("replay"))
        .arg("--memory-trace")
        .arg(&memory)
        .stderr(std::process::Stdio::inherit())
        .output()
        .context("running hetsim replay")?;
    let wall = start.elapsed().as_secs_f64();
    let stdout = String::from_utf8_lossy(&child.stdout);
    anyhow::ensure!(child.status.success(), "hetsim replay failed: {stdout}");
    let digest = stdout
        .lines()
        .find_map(|l| l.strip_prefix("digest: "))
        .context("hetsim replay printed no digest")?
        .to_string();
    let (mut trace, mut peak) = (Vec::new(), f64::NAN);
    for line in std::fs::read_to_string(&memory)?.lines().skip(1) {
        let (a, b) = line.split_once(',').context("a memory trace row")?;
        let mib: f64 = b.parse()?;
        match a {
            "peak" => peak = mib,
            t => trace.push((t.parse()?, mib)),
        }
    }
    let replayed = Phase {
        wall,
        trace,
        peak,
        digest,
    };
    let mut f = Figures::new(
        "replay",
        &[
            ("phase", "phase"),
            ("sim_s", "sim s"),
            ("wall_s", "wall s"),
            ("realtime", "x real time"),
            ("peak_rss_mib", "peak RSS MiB (VmHWM)"),
        ],
    );
    for (name, p) in [
        ("live, rendering and recording", &live),
        ("replay", &replayed),
    ] {
        f.row(vec![
            json!(name),
            json!(sim_secs),
            json!(p.wall),
            json!(sim_secs / p.wall.max(1e-9)),
            json!(p.peak),
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
    f.about
        .insert("live_results".into(), json!(kept.display().to_string()));
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
