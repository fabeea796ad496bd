//! Sweeps of whole lockstep runs: axes over scenario and robot-file fields, metrics read from
//! each run's metrics.json, the same files for any job count, sharding or resumption.

use hetsim_tests::{assert_same_sweep_folders as assert_same_tree, hetsim, repo};
use std::path::Path;

fn sweep(args: &[&str]) -> String {
    let out = hetsim(&[&["sweep"], args].concat(), &[]);
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "hetsim sweep {args:?}: {text}");
    text
}

/// `from`'s files and folders, copied to `to` (a new folder).
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let target = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_tree(&p, &target);
        } else {
            std::fs::copy(&p, &target).unwrap();
        }
    }
}

fn csv_rows(path: &Path) -> Vec<Vec<String>> {
    csv::Reader::from_path(path)
        .unwrap()
        .records()
        .map(|r| r.unwrap().iter().map(str::to_string).collect())
        .collect()
}

#[test]
fn a_whole_run_sweep_is_the_same_for_any_jobs_sharding_and_resumption() {
    let tmp = tempfile::tempdir().unwrap();
    // The whole sweep one run at a time (crate::shared, which the Slurm test reads too);
    // below, the same sweep in two shards, one of them two runs at a time, must give the
    // same folder.
    let (f, one) = (
        crate::shared::lab_sweep_file().to_str().unwrap(),
        crate::shared::lab_sweep_one_job(),
    );
    let at = |name: &str| tmp.path().join(name);

    // runs.csv: a row per run with its axis value, seed, digest and the four metrics; the
    // compass noise reached the robots (their resolved robot files in the manifest) and
    // changed the runs.
    let rows = csv_rows(&one.join("runs.csv"));
    assert_eq!(rows.len(), 4);
    let mut digests: Vec<&str> = rows.iter().map(|r| r[3].as_str()).collect();
    digests.sort();
    digests.dedup();
    assert_eq!(digests.len(), 4, "every run differs: {rows:?}");
    for row in &rows {
        assert_eq!(row.len(), 4 + 4, "{row:?}");
        let manifest: serde_json::Value = serde_json::from_slice(
            &std::fs::read(
                one.join("runs")
                    .join(format!("{:06}", row[0].parse::<usize>().unwrap()))
                    .join("manifest.json"),
            )
            .unwrap(),
        )
        .unwrap();
        assert_eq!(manifest["digest"], row[3].as_str());
        let sigma: f64 = row[1].parse().unwrap();
        let robots = manifest["resolved"]["robots"].as_array().unwrap();
        for r in robots.iter().filter(|r| r["model"]["name"] == "ctbot") {
            let compass = r["model"]["sensors"]
                .as_array()
                .unwrap()
                .iter()
                .find(|s| s["name"] == "compass")
                .unwrap();
            assert_eq!(compass["sigma_deg"].as_f64(), Some(sigma), "{}", r["name"]);
        }
        // The run's own figure, read back: the children's compass error grows with the noise
        // it was given. The figure is the mean heading error at the 8-9 grabs of 120 s: a
        // 1 deg compass (mean |error| 0.8 deg, its mean over 8 grabs within 0.6 deg of that at
        // three standard errors) cannot reach 3 deg, and a 16 deg one (12.8 deg) stays above it
        // even if the parent's steering averaged four readings per grab.
        let err: f64 = row[5].parse().unwrap();
        if sigma == 1.0 {
            assert!(err < 3.0, "compass error {err} deg with sigma 1 deg");
        } else {
            assert!(err > 3.0, "compass error {err} deg with sigma 16 deg");
        }
    }
    let md = std::fs::read_to_string(one.join("summary.md")).unwrap();
    assert!(
        md.contains("## `team.imaged`") && md.contains("4 of 4 runs"),
        "{md}"
    );
    assert!(one.join("boxplot.png").is_file());

    // Two shards and a merge: the same folder, run folders included, whether a shard runs
    // its two runs side by side (`--jobs 2`) or one after the other.
    let (s1, s2, merged) = (at("shard1"), at("shard2"), at("merged"));
    sweep(&[
        f,
        "--shard",
        "1/2",
        "--jobs",
        "2",
        "--out",
        s1.to_str().unwrap(),
    ]);
    sweep(&[
        f,
        "--shard",
        "2/2",
        "--jobs",
        "1",
        "--out",
        s2.to_str().unwrap(),
    ]);
    sweep(&[
        "merge",
        f,
        s1.to_str().unwrap(),
        s2.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert_same_tree(one, &merged);
    // A shard missing from the merge is refused, naming the first run it lacks.
    let partial = hetsim(
        &[
            "sweep",
            "merge",
            f,
            s1.to_str().unwrap(),
            "--out",
            at("partial").to_str().unwrap(),
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&partial.stderr);
    assert!(
        !partial.status.success()
            && err.contains("2 of 4 runs")
            && err.contains("first missing: run 1"),
        "{err}"
    );

    // Resumption: a run whose row was lost but whose results folder is whole is read back,
    // not run again (its timing.json is kept); a run with neither is run again. On a copy:
    // the shared folder stays as `--jobs 1` wrote it.
    let reference = one;
    let one = &at("resumed");
    copy_tree(reference, one);
    let timing = one.join("runs/000001/timing.json");
    let before = std::fs::read(&timing).unwrap();
    std::fs::remove_file(one.join("rows/000001.csv")).unwrap();
    std::fs::remove_file(one.join("rows/000002.csv")).unwrap();
    std::fs::remove_dir_all(one.join("runs/000002")).unwrap();
    std::fs::create_dir_all(one.join("runs/.000002.partial-1")).unwrap();
    let resumed = sweep(&[f, "--out", one.to_str().unwrap()]);
    assert!(resumed.contains("finished: 4 of 4 runs"), "{resumed}");
    assert_eq!(
        std::fs::read(&timing).unwrap(),
        before,
        "run 1 was not redone"
    );
    assert!(!one.join("runs/.000002.partial-1").exists());
    assert_same_tree(one, &merged);
}

#[test]
fn whole_run_sweeps_refuse_bad_metrics_and_axes_with_the_place() {
    let tmp = tempfile::tempdir().unwrap();
    // A metric path that is not in metrics.json names the key and what is there.
    let path = tmp.path().join("bad.toml");
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"bad\"\nkind = \"run\"\nbase = \"{}\"\nseeds = 1\nduration_secs = 1.0\nrender = false\nmetrics = [\"team.no_such_figure\"]\n[axes]\n\"coverage.r_los_m\" = [2.0]\n",
            repo().join("scenarios/lab.toml").display()
        ),
    )
    .unwrap();
    let out = hetsim(
        &[
            "sweep",
            path.to_str().unwrap(),
            "--out",
            tmp.path().join("o").to_str().unwrap(),
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("bad.toml")
            && err.contains("run 0")
            && err.contains("no_such_figure")
            && err.contains("imaged_fraction"),
        "{err}"
    );
    assert!(!tmp.path().join("o/rows/000000.csv").exists());

    // An axis naming a robot the scenario does not have lists the robots.
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"bad\"\nkind = \"run\"\nbase = \"{}\"\nseeds = 1\nmetrics = [\"comms.sent\"]\n[axes]\n\"robots.child9.sensors.compass.sigma_deg\" = [2.0]\n",
            repo().join("scenarios/lab.toml").display()
        ),
    )
    .unwrap();
    let e = hetsim_eval::sweep::load_sweep(&path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("child9") && e.contains("child1 (model ctbot)"),
        "{e}"
    );

    // A robot-file field that does not exist is refused by the scenario loader, by name.
    std::fs::write(
        &path,
        format!(
            "schema_version = 1\nname = \"bad\"\nkind = \"run\"\nbase = \"{}\"\nseeds = 1\nmetrics = [\"comms.sent\"]\n[axes]\n\"robots.child1.sensors.compass.sigma_dg\" = [2.0]\n",
            repo().join("scenarios/lab.toml").display()
        ),
    )
    .unwrap();
    let e = hetsim_eval::sweep::load_sweep(&path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sigma_dg") && e.contains("run 0"), "{e}");

    // Fields of the other kind, and a run sweep without metrics.
    for (body, field) in [
        ("kind = \"plan\"\nmetrics = [\"a\"]\n", "metrics"),
        ("kind = \"run\"\n", "metrics"),
        ("kind = \"run\"\nmetrics = [\"a..b\"]\n", "metrics[0]"),
        (
            "kind = \"run\"\nmetrics = [\"a\"]\nduration_secs = -1.0\n",
            "duration_secs",
        ),
    ] {
        std::fs::write(
            &path,
            format!(
                "schema_version = 1\nname = \"bad\"\nbase = \"{}\"\nseeds = 1\n{body}[axes]\n",
                repo().join("scenarios/lab.toml").display()
            ),
        )
        .unwrap();
        let e = hetsim_eval::sweep::load_sweep(&path)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.toml") && e.contains(&format!("`{field}`")),
            "{body}: {e}"
        );
    }
}

#[test]
fn a_folder_of_another_sweep_is_never_resumed_or_merged_into() {
    let tmp = tempfile::tempdir().unwrap();
    let write = |values: &str| {
        let path = tmp.path().join("s.toml");
        std::fs::write(
            &path,
            format!(
                "schema_version = 1\nname = \"s\"\nkind = \"run\"\nbase = \"{}\"\nseeds = 1\nduration_secs = 30.0\nrender = false\nmetrics = [\"comms.sent\"]\n[axes]\n\"models.ctbot.sensors.compass.sigma_deg\" = [{values}]\n",
                repo().join("scenarios/lab.toml").display()
            ),
        )
        .unwrap();
        path
    };
    let out = tmp.path().join("o");
    let file = write("2.0, 7.0");
    sweep(&[file.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let rows_before = std::fs::read(out.join("runs.csv")).unwrap();
    // The same file, but the folder made by another build of hetsim: its rows would come
    // from another planner.
    let identity = out.join("identity.json");
    let ours = std::fs::read_to_string(&identity).unwrap();
    let build = serde_json::from_str::<serde_json::Value>(&ours).unwrap()["build_sha256"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(build.len(), 64, "{ours}");
    std::fs::write(&identity, ours.replace(&build, &"0".repeat(64))).unwrap();
    let rebuilt = hetsim(
        &[
            "sweep",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&rebuilt.stderr);
    assert!(
        !rebuilt.status.success() && err.contains("build_sha256"),
        "{err}"
    );
    std::fs::write(&identity, ours).unwrap();
    // The same file with another axis value: its rows would be reported under the new labels.
    let file = write("2.0, 8.0");
    let again = hetsim(
        &[
            "sweep",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success(), "{err}");
    assert!(
        err.contains("another sweep") && err.contains("axes") && err.contains("s.toml"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(out.join("runs.csv")).unwrap(),
        rows_before,
        "nothing rewritten"
    );
    // Nor merged: the first sweep's folder as a shard of the second.
    let merged = tmp.path().join("m");
    let m = hetsim(
        &[
            "sweep",
            "merge",
            file.to_str().unwrap(),
            out.to_str().unwrap(),
            "--out",
            merged.to_str().unwrap(),
        ],
        &[],
    );
    let err = String::from_utf8_lossy(&m.stderr);
    assert!(
        !m.status.success() && err.contains("another sweep") && err.contains("axes"),
        "{err}"
    );
    assert!(!merged.join("runs.csv").exists());
}
