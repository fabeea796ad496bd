//! A results folder is never silently replaced: `--out` naming another run's results is
//! refused before the run starts, saying what is there and how to replace it; the same run
//! is rewritten; a folder another live process is writing is refused, naming the process; a
//! recording that cannot fit is refused before the run, and one that fills the disk says so.

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

/// A tmpfs of `size` mounted on a fresh folder, unmounted when dropped (the suite runs as
/// root, as CI does: mounting needs it).
struct SmallDisk {
    dir: tempfile::TempDir,
}

impl SmallDisk {
    fn new(size: &str) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let mounted = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .status()
            .expect("mount runs");
        assert!(mounted.success(), "mounting a {size} tmpfs needs root");
        Self { dir }
    }
    fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .arg(self.dir.path())
            .status();
    }
}

#[test]
fn a_recording_that_cannot_fit_is_refused_first_and_a_full_disk_is_named_with_its_cause() {
    let disk = SmallDisk::new("64k");
    let results = tempfile::tempdir().unwrap();
    let out = results.path().join("run");
    let rec = disk.path().join("lab.mcap");
    let record = |duration: &str, extra: &[&str]| {
        let mut args = vec![
            "run",
            "scenarios/lab.toml",
            "--duration",
            duration,
            "--record",
            rec.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        hetsim(&args, &[])
    };
    // Rendered, the lab's cameras need far more than 64 kB: refused before the run.
    let refused = record("20", &[]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    for said in [
        "lab.mcap",
        "the recording needs about",
        "free there",
        "--force",
    ] {
        assert!(err.contains(said), "{said:?} in: {err}");
    }
    // Not rendered, it holds no images and starts, then fills the disk: the cause and the
    // path, not the writer's later refusals, and nothing left behind.
    let full = record("60", &["--no-render"]);
    let err = String::from_utf8_lossy(&full.stderr);
    assert!(!full.status.success());
    for said in [
        "lab.mcap.partial",
        "No space left on device",
        "free there now",
    ] {
        assert!(err.contains(said), "{said:?} in: {err}");
    }
    assert!(!err.contains("attempted another write"), "{err}");
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    assert!(entries(disk.path()).is_empty(), "no partial recording");
    assert!(entries(results.path()).is_empty(), "no results, no lock");
}

#[test]
fn a_village_beyond_the_memory_bound_is_refused_before_it_is_built() {
    // 5000 m at 0.5 m cells: 1e8 height samples, about 1.7 GB (the largest village the
    // ranges allow), refused under a declared 1 GB bound before the terrain
    // is generated (the loader checks the estimate first: `sim/scene/src/load.rs`).
    let dir = tempfile::tempdir().unwrap();
    let models = hetsim_tests::repo().join("robots/models");
    let text = std::fs::read_to_string(hetsim_tests::repo().join("scenarios/village.toml"))
        .unwrap()
        .replace("size_m = 800.0", "size_m = 5000.0")
        .replace("terrain_cell_m = 4.0", "terrain_cell_m = 0.5")
        .replacen(
            "schema_version = 1\n",
            &format!(
                "schema_version = 1\nmodels_dir = {:?}\n",
                models.display().to_string()
            ),
            1,
        );
    let path = dir.path().join("big.toml");
    std::fs::write(&path, text).unwrap();
    let refused = hetsim(
        &["validate", path.to_str().unwrap(), "--max-memory", "1G"],
        &[],
    );
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "{err}");
    for said in [
        "big.toml:",
        "world.village.terrain_cell_m",
        "1.00e8 height samples",
        "1.7 GB",
        "--max-memory is 1.0 GB",
    ] {
        assert!(err.contains(said), "{said:?} in: {err}");
    }
}

#[test]
fn a_run_option_that_changes_the_bytes_is_another_run_too() {
    // The same scenario, seed and duration, rendered once and not the next time: the
    // scenario matches, the digest does not, so the second is refused when it would write.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let lab = |extra: &[&str]| {
        let mut args = vec![
            "run",
            "scenarios/lab.toml",
            "--duration",
            "2",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        hetsim(&args, &[])
    };
    assert!(lab(&["--no-render"]).status.success());
    let first = std::fs::read(out.join("manifest.json")).unwrap();
    let refused = lab(&[]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "{err}");
    assert!(
        err.contains("holds the results of another run") && err.contains("digest"),
        "{err}"
    );
    assert_eq!(std::fs::read(out.join("manifest.json")).unwrap(), first);
    assert_eq!(entries(tmp.path()), ["run"], "nothing else left behind");
}

#[test]
fn results_and_frames_that_fill_the_disk_say_so_once_and_leave_nothing() {
    // Each kind of output on a disk too small for it: the cause and the path, in one line,
    // and no partial folder (a recording's own case is above).
    for (size, args) in [
        (
            "8k",
            vec![
                "run",
                "scenarios/indoor-grid-20.toml",
                "--duration",
                "30",
                "--no-render",
            ],
        ),
        (
            "1m",
            vec!["frames", "scenarios/lab.toml", "--from", "0", "--to", "3"],
        ),
    ] {
        let disk = SmallDisk::new(size);
        let out = disk.path().join("out");
        let mut args = args.clone();
        args.extend(["--out", out.to_str().unwrap()]);
        let full = hetsim(&args, &[]);
        let err = String::from_utf8_lossy(&full.stderr);
        assert!(!full.status.success(), "{args:?}: {err}");
        assert!(err.contains(disk.path().to_str().unwrap()), "{err}");
        assert_eq!(
            err.matches("No space left on device").count(),
            1,
            "the cause once: {err}"
        );
        assert!(
            entries(disk.path()).is_empty(),
            "{args:?} left {:?}",
            entries(disk.path())
        );
    }
}
