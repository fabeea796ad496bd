//! Truth reaches a robot only through an oracle its robot file declares, and the coverage
//! team (the parent, which localizes from its laser, and the children) does not depend on it:
//! with every truth message withheld from them they compute the same bytes.

use hetsim_eval::manifest::Manifest;
use hetsim_eval::Metrics;
use hetsim_tests::{hetsim, printed_digest, repo};
use std::path::Path;

/// Runs the lab mission's first two minutes, with every robot's oracle switched on or left as
/// the robot files declare it (off); returns the results folder and the digest.
fn lab(dir: &Path, oracle: bool) -> (std::path::PathBuf, String) {
    let mut text = std::fs::read_to_string(repo().join("scenarios/lab.toml")).unwrap();
    text = text.replacen(
        "schema_version = 1\n",
        &format!(
            "schema_version = 1\nmodels_dir = \"{}\"\n",
            repo().join("robots/models").display()
        ),
        1,
    );
    if oracle {
        for kind in ["coverage_child", "coverage_parent"] {
            let mission = format!("mission = {{ kind = \"{kind}\" }}");
            text = text.replace(
                &mission,
                &format!("{mission}\noverrides = {{ \"sensors.truth.enabled\" = true }}"),
            );
        }
    }
    let name = if oracle { "with" } else { "without" };
    let scenario = dir.join(format!("lab-{name}.toml"));
    std::fs::write(&scenario, text).unwrap();
    let out = dir.join(name);
    let o = hetsim(
        &[
            "run",
            scenario.to_str().unwrap(),
            "--duration",
            "120",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let digest = printed_digest(&o);
    (out, digest)
}

#[test]
fn the_coverage_team_computes_the_same_bytes_without_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (without, d_without) = lab(dir.path(), false);
    let (with, d_with) = lab(dir.path(), true);
    let (m_without, m_with) = (
        Manifest::read(&without).unwrap(),
        Manifest::read(&with).unwrap(),
    );
    // The manifest lists every oracle that is on: none as the robot files declare them.
    let oracle_robots = |m: &Manifest| -> Vec<String> {
        m.oracles
            .iter()
            .filter(|o| o.kind == "oracle_pose")
            .map(|o| o.robot.clone())
            .collect()
    };
    assert!(oracle_robots(&m_without).is_empty());
    assert_eq!(
        oracle_robots(&m_with),
        ["parent", "child1", "child2", "child3"]
    );
    // The truth really was delivered in one run and withheld in the other.
    let truth_count = |out: &Path, robot: &str| {
        Metrics::read(out)
            .unwrap()
            .messages
            .get(&format!("{robot}/truth"))
            .copied()
            .unwrap_or(0)
    };
    for robot in ["parent", "child1", "child2", "child3"] {
        assert_eq!(truth_count(&without, robot), 0, "{robot} got truth");
        assert!(truth_count(&with, robot) > 100, "{robot} got no truth");
    }
    assert_ne!(d_without, d_with, "the delivered truth is in the digest");
    // What every stack computed (commands and radio messages) is the same bytes.
    assert_eq!(m_without.stacks.len(), 4);
    assert_eq!(m_without.stacks, m_with.stacks);
    // And the mission got somewhere in those two minutes: images were taken.
    let imaged = Metrics::read(&without)
        .unwrap()
        .team
        .expect("a team")
        .imaged;
    assert!(imaged > 0, "no vertex imaged in two minutes");
}
