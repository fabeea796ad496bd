//! A results folder is never silently replaced: `--out` naming another run's results is
//! refused before the run starts, saying what is there and how to replace it; the same run
//! is rewritten; a folder another live process is writing is refused, naming the process.

use hetsim_tests::hetsim;
use std::path::Path;

/// `hetsim run` of a two-second indoor grid without cameras into `out`.
fn run(out: &Path, seed: &str, extra: &[&str]) -> std::process::Output {
    let out = out.to_str().unwrap();
    let mut args = vec![
        "run",
        "scenarios/indoor-grid-20.toml",
        "--seed",
        seed,
        "--duration",
        "2",
        "--no-render",
        "--out",
        out,
    ];
    args.extend(extra);
    hetsim(&args, &[])
}

fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    names.sort();
    names
}

fn manifest(out: &Path) -> hetsim_eval::manifest::Manifest {
    hetsim_eval::manifest::Manifest::read(out).unwrap()
}

#[test]
fn another_runs_results_are_refused_the_same_run_is_rewritten_and_force_replaces() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    assert!(run(&out, "1", &[]).status.success());
    let first = std::fs::read(out.join("manifest.json")).unwrap();
    let digest = manifest(&out).digest;

    let refused = run(&out, "2", &[]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    for said in [
        "holds the results of another run",
        "indoor-grid-20.toml",
        "seed 1",
        &digest[..16],
        "this run differs in its seed",
        "--force",
    ] {
        assert!(err.contains(said), "{said:?} in: {err}");
    }
    assert_eq!(
        std::fs::read(out.join("manifest.json")).unwrap(),
        first,
        "the earlier results are kept"
    );
    assert_eq!(entries(tmp.path()), ["run"], "nothing else left behind");

    // The same run (same files, settings, seed, duration, build) is rewritten, to the
    // same digest: a resumed study reuses its folders.
    let again = run(&out, "1", &[]);
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    assert_eq!(manifest(&out).digest, digest);

    let forced = run(&out, "2", &["--force"]);
    assert!(
        forced.status.success(),
        "{}",
        String::from_utf8_lossy(&forced.stderr)
    );
    assert_eq!(manifest(&out).seed, 2);
    assert_eq!(entries(tmp.path()), ["run"], "the lock is released");
}

#[test]
fn a_folder_another_live_process_writes_is_refused_and_a_stale_claim_is_taken_over() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let lock = tmp.path().join("run.lock");
    let host = hetsim_core::lock::host_name();
    // This test's own process: alive, on this host.
    std::fs::write(&lock, format!("{} {host}\n", std::process::id())).unwrap();
    let refused = run(&out, "1", &[]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    let holder = format!("being written by process {} on {host}", std::process::id());
    assert!(err.contains(&holder), "{err}");
    assert!(!out.exists(), "nothing written");
    assert!(lock.exists(), "the holder's claim stays");

    // A claim left by a process that is gone (Linux's pid_max is at most 2^22).
    std::fs::write(&lock, format!("4194304 {host}\n")).unwrap();
    let taken = run(&out, "1", &[]);
    assert!(
        taken.status.success(),
        "{}",
        String::from_utf8_lossy(&taken.stderr)
    );
    assert!(out.join("manifest.json").is_file());
    assert!(!lock.exists(), "released at the end");
}
