//! The robot software never depends on the simulator.

use hetsim_tests::repo;
use std::collections::BTreeMap;

#[test]
fn robots_crates_never_depend_on_sim_crates() {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(repo())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let root = repo().canonicalize().unwrap();
    // package name -> folder relative to the repository
    let mut folder: BTreeMap<String, String> = BTreeMap::new();
    for p in meta["packages"].as_array().unwrap() {
        let manifest = std::path::Path::new(p["manifest_path"].as_str().unwrap())
            .canonicalize()
            .unwrap();
        let rel = manifest
            .parent()
            .unwrap()
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .to_string();
        folder.insert(p["name"].as_str().unwrap().to_string(), rel);
    }
    let robots: Vec<_> = folder
        .iter()
        .filter(|(_, f)| f.starts_with("robots/"))
        .map(|(n, _)| n.clone())
        .collect();
    assert!(robots.len() >= 2, "{folder:?}");
    for p in meta["packages"].as_array().unwrap() {
        let name = p["name"].as_str().unwrap();
        if !robots.iter().any(|r| r == name) {
            continue;
        }
        for dep in p["dependencies"].as_array().unwrap() {
            let dep_name = dep["name"].as_str().unwrap();
            if let Some(f) = folder.get(dep_name) {
                assert!(
                    !f.starts_with("sim/"),
                    "{name} ({}) depends on {dep_name} ({f})",
                    folder[name]
                );
            }
        }
    }
}
