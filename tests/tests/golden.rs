//! Golden digests of whole runs: what a run produces must not change when code is moved.
//!
//! A digest covers every message, command and output file of a run. Non-rendered runs are
//! bit-exact on any machine with this toolchain; rendered runs depend on the adapter, so their
//! digests are kept per adapter (backend and driver as the manifest records them). A run on an
//! adapter without a recorded digest (a real GPU, another Mesa) is reported and not compared.
//!
//! Regenerating a value is legitimate only in a commit of its own that says which change moved
//! it and why the new value is right (DESIGN.md, determinism contract); never to make a
//! refactor pass.

use hetsim_tests::{hetsim, printed_digest};

/// `(backend, driver)` of the manifest -> digest.
type PerAdapter = &'static [(&'static str, &'static str, &'static str)];

/// Mesa 22.3.6's lavapipe (Vulkan) and llvmpipe (GL), as Debian 12 ships them.
const LAVAPIPE: (&str, &str) = ("Vulkan", "llvmpipe Mesa 22.3.6 (LLVM 15.0.6)");
const LLVMPIPE_GL: (&str, &str) = ("Gl", "4.5 (Core Profile) Mesa 22.3.6");

fn check(name: &str, args: &[&str], golden: PerAdapter) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(name);
    let mut all = args.to_vec();
    all.extend(["--out", out.to_str().unwrap()]);
    let digest = printed_digest(&hetsim(&all, &[]));
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let adapter = &manifest["adapter"];
    let (backend, driver) = (
        adapter["backend"].as_str().unwrap_or("none"),
        adapter["driver"].as_str().unwrap_or("none"),
    );
    match golden
        .iter()
        .find(|(b, d, _)| *b == backend && *d == driver)
    {
        Some((_, _, expected)) => assert_eq!(
            digest, *expected,
            "{name} on {backend} / {driver}: the run's digest moved"
        ),
        None => eprintln!(
            "{name}: no golden digest for adapter {backend} / {driver}; digest {digest} not compared"
        ),
    }
}

#[test]
fn golden_lab_mission() {
    check(
        "lab",
        &["run", "scenarios/lab.toml"],
        &[
            (
                LAVAPIPE.0,
                LAVAPIPE.1,
                "83596783a5e40cf7085ab44020bda1136a11dff94f0ed6c6b5a5d3b9ffc60d09",
            ),
            (
                LLVMPIPE_GL.0,
                LLVMPIPE_GL.1,
                "d09f1e30f2f5014e5fcd07e7b68956db952fcfb9b65b932da4483dd3e19509b4",
            ),
        ],
    );
}

#[test]
fn golden_indoor_team_mission() {
    check(
        "indoor-team",
        &["run", "scenarios/indoor-team.toml"],
        &[
            (
                LAVAPIPE.0,
                LAVAPIPE.1,
                "cfb9f93af3cc7bcc04eea4c3b5a11f2c7037bfd7fe7032588142990380e75225",
            ),
            (
                LLVMPIPE_GL.0,
                LLVMPIPE_GL.1,
                "e89fe7688af1499cdbf31b3f024100f2e35b0f0f77134f79c885ebb01571aa52",
            ),
        ],
    );
}

#[test]
fn golden_indoor_grid_20_without_cameras() {
    check(
        "indoor-grid-20",
        &["run", "scenarios/indoor-grid-20.toml", "--no-render"],
        &[(
            "none",
            "none",
            "0a8ff85fe6efea20af64bca0aede7b8b37c241b750d8ae517a98c0fea570db62",
        )],
    );
}

#[test]
fn golden_rendered_village_short() {
    check(
        "village-short",
        &["run", "scenarios/village-short.toml"],
        &[
            (
                LAVAPIPE.0,
                LAVAPIPE.1,
                "5baa20c66cd98c3d612da4fc862496d2a36ee7763001867906d3f8d8b2755025",
            ),
            (
                LLVMPIPE_GL.0,
                LLVMPIPE_GL.1,
                "fdbb678eed2a59a28fafe01f167552b6e768cbf05ff7eb2b7a80b475a69162fc",
            ),
        ],
    );
}
