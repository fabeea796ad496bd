//! Sweeps give the same files whatever the job count, sharding or interruption; regression
//! catches moved metrics.

use hetsim_eval::regress::{regress, Baseline};
use hetsim_eval::sweep::{load_sweep, merge, run_sweep, METRICS};
use hetsim_tests::{hetsim, repo};
use std::path::Path;

/// Columns of the small sweep's `runs.csv`: the run's index, its two axes, its seed and the
/// planner's metrics.
const COLUMNS: usize = 4 + METRICS.len();

fn sweep_file(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("small.toml");
    let base = repo().join("scenarios/lab.toml");
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"small\"\nbase = \"{}\"\nseeds = 3\n\n[axes]\n\"world.indoor.obstruction_ratio\" = [0.0, 0.1]\n\"coverage.children\" = [1, 2]\n",
            base.display()
        ),
    )
    .unwrap();
    path
}

fn outputs(dir: &Path) -> Vec<String> {
    ["runs.csv", "summary.csv", "summary.md"]
        .iter()
        .map(|f| std::fs::read_to_string(dir.join(f)).unwrap())
        .collect()
}

#[test]
fn jobs_shards_and_resuming_give_the_same_files() {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = load_sweep(&sweep_file(tmp.path())).unwrap();
    assert_eq!(sweep.runs.len(), 2 * 2 * 3);
    let none = |_: usize, _: usize| {};
    let one = tmp.path().join("jobs1");
    let two = tmp.path().join("jobs2");
    let s1 = run_sweep(&sweep, &one, 1, (1, 1), &none).unwrap();
    run_sweep(&sweep, &two, 2, (1, 1), &none).unwrap();
    assert_eq!(s1.finished, 12);
    assert_eq!(outputs(&one), outputs(&two));
    assert_eq!(
        outputs(&one)[0].lines().count(),
        13,
        "header and one row per run"
    );

    let (a, b, merged) = (
        tmp.path().join("shard1"),
        tmp.path().join("shard2"),
        tmp.path().join("merged"),
    );
    let part = run_sweep(&sweep, &a, 2, (1, 2), &none).unwrap();
    assert_eq!(part.finished, 6);
    run_sweep(&sweep, &b, 2, (2, 2), &none).unwrap();
    merge(&sweep, &merged, &[a.clone(), b]).unwrap();
    assert_eq!(outputs(&one), outputs(&merged));

    // Resume: the first shard's rows are kept as they are (a doctored one proves it), the
    // rest are run; a half-written temporary file left by a crash is ignored.
    let row0 = a.join("rows/000000.csv");
    let original = std::fs::read_to_string(&row0).unwrap();
    let mut fields: Vec<String> = original.trim_end().split(',').map(str::to_string).collect();
    let last = fields.len() - 1;
    fields[last] = "123456".to_string();
    std::fs::write(&row0, fields.join(",") + "\n").unwrap();
    std::fs::write(a.join("rows/000001.tmp-99"), "half a ro").unwrap();
    run_sweep(&sweep, &a, 2, (1, 1), &none).unwrap();
    let resumed = outputs(&a);
    assert!(
        resumed[0].contains("123456"),
        "finished rows are not redone"
    );
    std::fs::write(&row0, original).unwrap();
    hetsim_eval::sweep::summarize(&sweep, &a).unwrap();
    assert_eq!(outputs(&one), outputs(&a));
}

#[test]
fn more_children_on_an_open_map_change_the_timesteps_and_cover_everything() {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = load_sweep(&sweep_file(tmp.path())).unwrap();
    let out = tmp.path().join("o");
    let summary = run_sweep(&sweep, &out, 2, (1, 1), &|_, _| {}).unwrap();
    for cell in &summary.cells {
        let coverage = cell.stat("coverage").mean;
        assert!(coverage > 0.95, "{:?}: coverage {coverage}", cell.values);
        assert!(
            cell.stat("parent_vertices").mean >= 1.0,
            "{:?}: at least one parent vertex",
            cell.values
        );
    }
}

#[test]
fn bad_sweep_files_are_refused_with_the_place() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("bad.toml");
    std::fs::write(
        &path,
        "schema_version = 1\nname = \"x\"\nbase = \"nope.toml\"\nseeds = 2\n[axes]\n",
    )
    .unwrap();
    let e = load_sweep(&path).unwrap_err().to_string();
    assert!(
        e.contains("bad.toml") && e.contains("base") && e.contains("nope.toml"),
        "{e}"
    );
    std::fs::write(&path, format!("schema_version = 1\nname = \"x\"\nbase = \"{}\"\nseeds = 2\n[axes]\n\"world.indoor.obstruction_ratio\" = [0.9]\n", repo().join("scenarios/lab.toml").display())).unwrap();
    let e = load_sweep(&path).unwrap_err().to_string();
    assert!(
        e.contains("obstruction_ratio") && e.contains("0.9") && e.contains("[0, 0.6]"),
        "{e}"
    );
    std::fs::write(
        &path,
        "schema_version = 1\nname = \"x\"\nbase = \"a.toml\"\nseedz = 2\n[axes]\n",
    )
    .unwrap();
    let e = load_sweep(&path).unwrap_err().to_string();
    assert!(e.contains("bad.toml:4") && e.contains("seedz"), "{e}");
}

#[test]
fn regression_passes_on_the_committed_baselines_and_catches_a_moved_metric() {
    let rows = regress(
        &repo(),
        &["scenarios/indoor-grid-20.toml".to_string()],
        false,
    )
    .unwrap();
    // Five baseline metrics, and full coverage and no skipped stage with 1 to 8 children
    // (requirements).
    assert_eq!(rows.iter().filter(|r| !r.required).count(), 5);
    assert_eq!(rows.iter().filter(|r| r.required).count(), 16);
    assert!(rows.iter().all(|r| !r.moved()), "{rows:?}");

    // A copy of the repository's inputs with a doctored baseline.
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    copy_inputs(root);
    let text =
        std::fs::read_to_string(repo().join("results/baselines/indoor-grid-20.json")).unwrap();
    let mut b: Baseline = serde_json::from_str(&text).unwrap();
    *b.metrics.get_mut("parent_vertices").unwrap() += 50.0;
    std::fs::write(
        root.join("results/baselines/indoor-grid-20.json"),
        serde_json::to_string(&b).unwrap(),
    )
    .unwrap();
    let rows = regress(root, &["scenarios/indoor-grid-20.toml".to_string()], false).unwrap();
    let moved: Vec<_> = rows
        .iter()
        .filter(|r| r.moved())
        .map(|r| r.metric.as_str())
        .collect();
    assert_eq!(moved, vec!["parent_vertices"]);
}

/// Copies the repository's scenarios and robot models into `root`, and makes its
/// `results/baselines`.
fn copy_inputs(root: &Path) {
    for dir in ["scenarios", "robots/models"] {
        std::fs::create_dir_all(root.join(dir)).unwrap();
        for e in std::fs::read_dir(repo().join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.is_file() {
                std::fs::copy(&p, root.join(dir).join(p.file_name().unwrap())).unwrap();
            }
        }
    }
    std::fs::create_dir_all(root.join("results/baselines")).unwrap();
}

/// `hetsim regress` fails, naming the requirement, when a plan of its map leaves unimaged a
/// vertex that some vertex sees freely (Eq. 4's promise), and `--update` then keeps the
/// baseline. The premise: on indoor-grid-20's map (seed 1) at r_los = 1 m, Eq. 6 read as
/// written (`eq6_every_choice`, which shrinks the candidates to those within f of every
/// choice so far) leaves such vertices with 7 and 8 children (`readings-table2`).
#[test]
fn regress_fails_when_a_plan_leaves_a_coverable_vertex_unimaged() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    copy_inputs(root);
    let base = std::fs::read_to_string(repo().join("scenarios/indoor-grid-20.toml")).unwrap();
    let short = base.replace(
        "r_los_m = 2.0",
        "r_los_m = 1.0\nreading = \"eq6_every_choice\"",
    );
    assert_ne!(short, base);
    std::fs::write(root.join("scenarios/short.toml"), short).unwrap();
    // A baseline to compare with: indoor-grid-20's (the same seed).
    let baseline = root.join("results/baselines/short.json");
    std::fs::copy(
        repo().join("results/baselines/indoor-grid-20.json"),
        &baseline,
    )
    .unwrap();
    let before = std::fs::read(&baseline).unwrap();
    for args in [
        &["regress", "scenarios/short.toml"][..],
        &["regress", "--update", "scenarios/short.toml"],
    ] {
        let out = std::process::Command::new(hetsim_tests::hetsim_bin())
            .args(args)
            .current_dir(root)
            .output()
            .unwrap();
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert!(!out.status.success(), "{args:?}: {stdout}{stderr}");
        assert!(
            stderr.contains("requirement(s) failed"),
            "{args:?}: {stderr}"
        );
        let failed: Vec<&str> = stdout
            .lines()
            .filter(|l| l.ends_with("| REQUIREMENT FAILED |"))
            .collect();
        assert!(
            !failed.is_empty()
                && failed
                    .iter()
                    .all(|l| l.contains("| coverable_coverage (children = ")),
            "{args:?}: {stdout}"
        );
        assert_eq!(std::fs::read(&baseline).unwrap(), before, "{args:?}");
    }
}

#[test]
fn the_regress_command_exits_zero_on_the_committed_baselines() {
    let out = hetsim(&["regress"], &[]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("regress: 63 metrics within tolerance"),
        "{stdout}"
    );
}

#[test]
fn a_killed_sweep_leaves_only_whole_rows_and_resumes_to_the_same_files() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("kill.toml");
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"kill\"\nbase = \"{}\"\nseeds = 6\n\n[axes]\n\"world.indoor.obstruction_ratio\" = [0.0, 0.2]\n\"coverage.children\" = [1, 3]\n",
            repo().join("scenarios/indoor-grid-20.toml").display()
        ),
    )
    .unwrap();
    let killed = tmp.path().join("killed");
    let mut child = std::process::Command::new(hetsim_tests::hetsim_bin())
        .args([
            "sweep",
            path.to_str().unwrap(),
            "--jobs",
            "2",
            "--out",
            killed.to_str().unwrap(),
        ])
        .current_dir(repo())
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Kill it once some, but not all, rows exist.
    let rows = killed.join("rows");
    for _ in 0..600 {
        let n = std::fs::read_dir(&rows)
            .map(|d| {
                d.filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .path()
                        .extension()
                        .is_some_and(|x| x == "csv")
                })
                .count()
            })
            .unwrap_or(0);
        if n >= 3 || child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.kill().ok();
    child.wait().unwrap();
    let finished: Vec<_> = std::fs::read_dir(&rows)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "csv"))
        .collect();
    assert!(
        !finished.is_empty() && finished.len() < 24,
        "{} rows after the kill",
        finished.len()
    );
    for row in &finished {
        let text = std::fs::read_to_string(row).unwrap();
        assert!(
            text.ends_with('\n') && text.trim_end().split(',').count() == COLUMNS,
            "whole row in {}: {text:?}",
            row.display()
        );
    }
    let resumed = hetsim(
        &[
            "sweep",
            path.to_str().unwrap(),
            "--out",
            killed.to_str().unwrap(),
        ],
        &[],
    );
    assert!(resumed.status.success());
    let fresh = tmp.path().join("fresh");
    let whole = hetsim(
        &[
            "sweep",
            path.to_str().unwrap(),
            "--jobs",
            "1",
            "--out",
            fresh.to_str().unwrap(),
        ],
        &[],
    );
    assert!(whole.status.success());
    assert_eq!(outputs(&killed), outputs(&fresh));
}

#[test]
fn a_short_or_mangled_row_file_is_an_error_naming_the_file_not_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = load_sweep(&sweep_file(tmp.path())).unwrap();
    let out = tmp.path().join("o");
    run_sweep(&sweep, &out, 2, (1, 1), &|_, _| {}).unwrap();
    let row = out.join("rows/000003.csv");
    let original = std::fs::read_to_string(&row).unwrap();
    // Cut after the seed: the metrics are missing.
    let short: Vec<&str> = original.trim_end().split(',').take(4).collect();
    std::fs::write(&row, short.join(",") + "\n").unwrap();
    let e = hetsim_eval::sweep::summarize(&sweep, &out)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("000003.csv")
            && e.contains("4 fields")
            && e.contains(&format!("{COLUMNS} columns")),
        "{e}"
    );
    // A metric that is not a number names its column.
    let mut fields: Vec<String> = original.trim_end().split(',').map(String::from).collect();
    fields[5] = "many".into();
    std::fs::write(&row, fields.join(",") + "\n").unwrap();
    let e = hetsim_eval::sweep::summarize(&sweep, &out)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("000003.csv") && e.contains("many") && e.contains("parent_vertices"),
        "{e}"
    );
}

#[test]
fn the_reports_sweep_folders_of_another_build_are_run_afresh() {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = load_sweep(&sweep_file(tmp.path())).unwrap();
    let none = |_: usize, _: usize| {};
    let dir = tmp.path().join("cached");
    run_sweep(&sweep, &dir, 2, (1, 1), &none).unwrap();
    let want = outputs(&dir);
    // The folder as another build left it: its identity names another executable, and its
    // first row is not what this build computes.
    let identity = dir.join("identity.json");
    let ours = std::fs::read_to_string(&identity).unwrap();
    let build = hetsim_eval::manifest::build_sha256();
    assert!(ours.contains(build), "{ours}");
    std::fs::write(&identity, ours.replace(build, &"0".repeat(64))).unwrap();
    let rows = dir.join("rows");
    std::fs::copy(rows.join("000001.csv"), rows.join("000000.csv")).unwrap();
    let s = hetsim_eval::report::run_cached(&sweep, &dir, 2, &none).unwrap();
    assert_eq!(s.finished, 12);
    assert_eq!(outputs(&dir), want, "every row recomputed");
    assert_eq!(std::fs::read_to_string(&identity).unwrap(), ours);
}
