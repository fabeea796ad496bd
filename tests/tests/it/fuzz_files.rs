//! Seeded mutation fuzzing of scenario and robot files: field values, types, deleted and
//! duplicated lines, swapped lines and stray bytes, applied to the shipped files. Every case is
//! loaded in-process (parse, validate, generate the world, place the robots) and, when
//! accepted, run for 0.3 s of sim time without cameras (physics, sensors, the robot software)
//! and evaluated;
//! every 20th case also goes through `hetsim run` to check the process: a refused file exits
//! non-zero with a message naming the file and leaves no results folder and nothing
//! half-written behind.
//!
//! The bar: no panic, no hang (a case not done in 20 s counts as one: a liveness bound, not
//! a speed target), no partial output. `HETSIM_FUZZ_CASES` sets the number of cases (default
//! 2,000, CI's); `tests/fuzz/files.sh` runs 100,000 with a release build and reports the
//! slowest refusal. `HETSIM_FUZZ_SEED` replays another seed.

use hetsim_scene::{load_scenario, LoadOptions};
use hetsim_tests::{hetsim_bin, repo};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// The scenarios fuzzed, and which robot files each reads.
const SCENARIOS: [(&str, &[&str]); 4] = [
    ("lab", &["parent", "ctbot"]),
    ("indoor-team", &["parent", "ctbot"]),
    ("village-short", &["dala", "ressac"]),
    ("indoor-grid-20", &["ctbot"]),
];

/// A copy of the repository's scenarios and robot files in a temporary folder.
fn layout() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for sub in ["scenarios", "robots/models"] {
        std::fs::create_dir_all(dir.path().join(sub)).unwrap();
        for e in std::fs::read_dir(repo().join(sub)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                std::fs::copy(&p, dir.path().join(sub).join(p.file_name().unwrap())).unwrap();
            }
        }
    }
    dir
}

/// A replacement value: numbers at and beyond every limit, other types, broken syntax.
fn value(rng: &mut ChaCha8Rng, old: &str) -> String {
    let number = old.trim().parse::<f64>().ok();
    match rng.random_range(0..16) {
        0 => "0".into(),
        1 => "-1".into(),
        2 => "1e9".into(),
        3 => "1e300".into(),
        4 => "-1e300".into(),
        5 => ["nan", "inf", "-inf", "+inf"][rng.random_range(0..4)].into(),
        6 => "9223372036854775807".into(),
        7 => "\"text\"".into(),
        8 => ["true", "[]", "[1, 2]", "{ a = 1 }", "[[0.0, 1.0]]"][rng.random_range(0..5)].into(),
        9 => "1e-300".into(),
        10 => "".into(),
        11 => "[".into(),
        _ => match number {
            // A number scaled by a power of ten, or negated.
            Some(v) => {
                let k = rng.random_range(-6..10);
                let scaled = if rng.random_range(0..4) == 0 {
                    -v
                } else {
                    v * 10f64.powi(k)
                };
                if old.contains('.') || old.contains('e') || scaled.fract() != 0.0 {
                    format!("{scaled:?}")
                } else {
                    format!("{}", scaled as i64)
                }
            }
            None => format!("{}", rng.random_range(-1000..1000)),
        },
    }
}

/// One to three mutations of a file's text.
fn mutate(rng: &mut ChaCha8Rng, text: &str) -> Vec<u8> {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for _ in 0..rng.random_range(1..4) {
        if lines.is_empty() {
            break;
        }
        let i = rng.random_range(0..lines.len());
        match rng.random_range(0..10) {
            0 => {
                lines.remove(i);
            }
            1 => {
                let l = lines[i].clone();
                lines.insert(i, l);
            }
            2 => {
                let j = rng.random_range(0..lines.len());
                lines.swap(i, j);
            }
            _ => {
                // A value: after `=` on a `key = value` line, or an element of an inline list.
                let with_value: Vec<usize> = (0..lines.len())
                    .filter(|&k| lines[k].contains('=') && !lines[k].trim_start().starts_with('#'))
                    .collect();
                if with_value.is_empty() {
                    continue;
                }
                let k = with_value[rng.random_range(0..with_value.len())];
                let line = lines[k].clone();
                let eq = line.find('=').unwrap();
                let rest = &line[eq + 1..];
                // Numbers inside the value (inline tables and lists): replace one of them.
                let spans: Vec<(usize, usize)> = number_spans(rest);
                if !spans.is_empty() && rng.random_range(0..2) == 0 {
                    let (a, b) = spans[rng.random_range(0..spans.len())];
                    let new = value(rng, &rest[a..b]);
                    lines[k] = format!("{}{}{}{}", &line[..eq + 1], &rest[..a], new, &rest[b..]);
                } else {
                    let new = value(rng, rest);
                    lines[k] = format!("{} {new}", &line[..eq + 1]);
                }
            }
        }
    }
    let mut bytes = (lines.join("\n") + "\n").into_bytes();
    if rng.random_range(0..8) == 0 {
        // Stray bytes: invalid UTF-8, NUL, control characters.
        let at = rng.random_range(0..=bytes.len());
        let stray: Vec<u8> = (0..rng.random_range(1..4))
            .map(|_| [0xff, 0x00, 0xc3, 0x1b, b'"', b'['][rng.random_range(0..6)])
            .collect();
        bytes.splice(at..at, stray);
    }
    bytes
}

/// Byte ranges of the numbers in `s` (digits with sign, point and exponent).
fn number_spans(s: &str) -> Vec<(usize, usize)> {
    let b = s.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if b[i].is_ascii_digit()
            || ((b[i] == b'-' || b[i] == b'+') && b.get(i + 1).is_some_and(u8::is_ascii_digit))
        {
            let start = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit()
                    || b[i] == b'.'
                    || b[i] == b'e'
                    || b[i] == b'E'
                    || ((b[i] == b'-' || b[i] == b'+') && (b[i - 1] == b'e' || b[i - 1] == b'E')))
            {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// Loads and, when accepted, runs a scenario for 0.3 s: Ok(true) accepted, Ok(false) refused
/// with an error naming `mutated` (or the scenario, for a robot file's field it overrides).
fn load_and_run(path: &Path, mutated: &str) -> Result<bool, String> {
    let options = LoadOptions {
        robot_files: None,
        seed: None,
        duration_secs: Some(0.3),
    };
    match load_scenario(path, &options) {
        Ok(s) => {
            let stacks = hetsim_stacks::build_stacks(&s, false);
            let output = hetsim_engine::run(&s, stacks, |_, _| {}, Default::default())
                .map_err(|e| format!("an accepted scenario failed to run: {e}"))?;
            // And evaluated, as `hetsim run` does (indoor scenarios plan their coverage).
            hetsim_eval::Metrics::compute(&s, &output)
                .map_err(|e| format!("an accepted scenario's run failed to evaluate: {e}"))?;
            Ok(true)
        }
        Err(e) => {
            let text = e.to_string();
            if !names_file(&text, path, mutated) {
                return Err(format!(
                    "a refusal that names neither {mutated} nor the scenario: {text}"
                ));
            }
            Ok(false)
        }
    }
}

/// Whether an error message names the mutated file, or the scenario that reads it (a
/// robot file's field the scenario overrides is reported at the override).
fn names_file(text: &str, scenario: &Path, mutated: &str) -> bool {
    let scenario = scenario.file_name().unwrap().to_string_lossy();
    text.contains(&format!("{mutated}:")) || text.contains(&format!("{scenario}:"))
}

/// Runs one case on a worker thread with a liveness bound.
fn bounded(path: PathBuf, mutated: String) -> Result<bool, String> {
    let (tx, rx) = mpsc::channel();
    let worker = std::thread::spawn(move || {
        let _ = tx.send(load_and_run(&path, &mutated));
    });
    match rx.recv_timeout(Duration::from_secs(20)) {
        Ok(r) => {
            // A panic on the worker drops the sender before sending: recv fails instead.
            worker.join().map_err(|_| "panicked".to_string())?;
            r
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => {
            let panic = worker.join().err().and_then(|p| {
                p.downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            });
            Err(format!("panicked: {}", panic.unwrap_or_default()))
        }
        Err(mpsc::RecvTimeoutError::Timeout) => Err("no answer in 20 s (a hang)".into()),
    }
}

/// `hetsim run` on the mutated scenario: the same outcome as in-process (`accepted`), a
/// message naming the file, no results folder and nothing partial beside it when refused.
fn through_cli(path: &Path, root: &Path, mutated: &str, accepted: bool) -> Result<(), String> {
    let out = root.join("out");
    let _ = std::fs::remove_dir_all(&out);
    let run = std::process::Command::new(hetsim_bin())
        .args([
            "run",
            path.to_str().unwrap(),
            "--duration",
            "0.3",
            "--no-render",
            "--out",
        ])
        .arg(&out)
        .current_dir(root)
        .output()
        .map_err(|e| e.to_string())?;
    let stderr = String::from_utf8_lossy(&run.stderr);
    if stderr.contains("panicked") {
        return Err(format!("hetsim run panicked: {stderr}"));
    }
    let leftovers: Vec<String> = std::fs::read_dir(root)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.contains("partial") || n.starts_with(".frames"))
        .collect();
    if !leftovers.is_empty() {
        return Err(format!("left behind: {leftovers:?}"));
    }
    if run.status.success() != accepted {
        return Err(format!(
            "in-process {}, but hetsim run exited {:?}: {stderr}",
            if accepted { "accepted" } else { "refused" },
            run.status.code()
        ));
    }
    if run.status.success() {
        if !out.join("manifest.json").is_file() {
            return Err("exit 0 without a results folder".into());
        }
        std::fs::remove_dir_all(&out).unwrap();
    } else if out.exists() || !names_file(&stderr, path, mutated) {
        return Err(format!(
            "refused (exit {:?}) but: results folder {}, message {stderr:?}",
            run.status.code(),
            out.exists()
        ));
    }
    Ok(())
}

#[test]
fn mutated_scenario_and_robot_files_never_panic_hang_or_leave_partial_outputs() {
    let cases: usize = std::env::var("HETSIM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2_000);
    let seed: u64 = std::env::var("HETSIM_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let dir = layout();
    let root = dir.path();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut accepted, mut refused, mut failures) = (0usize, 0usize, Vec::new());
    let mut slowest = (0.0f64, 0usize);
    for case in 0..cases {
        let (scenario, models) = SCENARIOS[rng.random_range(0..SCENARIOS.len())];
        // Half the cases mutate the scenario, half one of the robot files it reads.
        let target = if rng.random_range(0..2) == 0 {
            root.join(format!("scenarios/{scenario}.toml"))
        } else {
            root.join(format!(
                "robots/models/{}.toml",
                models[rng.random_range(0..models.len())]
            ))
        };
        let original = std::fs::read(&target).unwrap();
        let mutated = mutate(&mut rng, &String::from_utf8_lossy(&original));
        std::fs::write(&target, &mutated).unwrap();
        // The case under way, for a process that dies (an abort on allocation failure).
        std::fs::write(
            std::env::temp_dir().join(format!("hetsim-fuzz-current-seed{seed}.txt")),
            format!("case {case}: {}\n", target.display())
                .into_bytes()
                .into_iter()
                .chain(mutated.iter().copied())
                .collect::<Vec<u8>>(),
        )
        .unwrap();
        let path = root.join(format!("scenarios/{scenario}.toml"));
        // Wall time, measured and printed, never asserted (the bound above is a liveness
        // bound): how long the slowest refusal took.
        #[allow(clippy::disallowed_methods)]
        let started = std::time::Instant::now();
        let mutated_name = target.file_name().unwrap().to_string_lossy().to_string();
        let mut outcome = bounded(path.clone(), mutated_name.clone());
        if matches!(outcome, Ok(false)) {
            let secs = started.elapsed().as_secs_f64();
            if secs > slowest.0 {
                slowest = (secs, case);
            }
        }
        if let (Ok(accepted), 0) = (&outcome, case % 20) {
            if let Err(e) = through_cli(&path, root, &mutated_name, *accepted) {
                outcome = Err(e);
            }
        }
        match outcome {
            Ok(true) => accepted += 1,
            Ok(false) => refused += 1,
            Err(e) => {
                let kept =
                    std::env::temp_dir().join(format!("hetsim-fuzz-seed{seed}-case{case}.toml"));
                std::fs::copy(&target, &kept).unwrap();
                failures.push(format!(
                    "case {case} ({}, kept as {}): {e}",
                    target.display(),
                    kept.display()
                ));
            }
        }
        std::fs::write(&target, &original).unwrap();
    }
    eprintln!(
        "{cases} cases (seed {seed}): {accepted} accepted and run, {refused} refused, {} failures; slowest refusal {:.3} s (case {})",
        failures.len(),
        slowest.0,
        slowest.1
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // Both outcomes occur: the mutations reach the validation and get past it.
    assert!(
        accepted > cases / 50 && refused > cases / 5,
        "{accepted} accepted, {refused} refused"
    );
}
