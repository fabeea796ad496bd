//! Golden digests of whole runs: what a run produces must not change when code is moved.
//!
//! A digest covers every message, command and output file of a run. Non-rendered runs are
//! bit-exact on any machine with this toolchain; rendered runs depend on the adapter, so their
//! digests are kept per adapter (backend and driver as the manifest records them), and each
//! rendered run is made on both backends, Vulkan and GL. A backend with no adapter on this
//! machine is skipped with a note; a run on an adapter without a recorded digest (a real GPU,
//! another Mesa) is reported and not compared. At least one rendered comparison must happen.
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

/// Runs `args` on each backend and compares with `golden`; at least one must compare.
fn check_backends(name: &str, args: &[&str], golden: PerAdapter) {
    let mut compared = 0;
    for backend in ["vulkan", "gl"] {
        let mut all = args.to_vec();
        all.extend(["--backend", backend]);
        compared += usize::from(check(&format!("{name}-{backend}"), &all, golden));
    }
    assert!(
        compared >= 1,
        "{name}: no backend had an adapter with a recorded digest"
    );
}

/// Runs `args` once; compares its digest with `golden` for the adapter it ran on. Returns
/// whether it compared; `false` when the backend has no adapter here or the adapter has no
/// recorded digest.
fn check(name: &str, args: &[&str], golden: PerAdapter) -> bool {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(name);
    let mut all = args.to_vec();
    all.extend(["--out", out.to_str().unwrap()]);
    let output = hetsim(&all, &[]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    if !output.status.success() && stderr.contains("no usable graphics adapter") {
        eprintln!("{name}: skipped, no adapter for this backend here: {stderr}");
        return false;
    }
    let digest = printed_digest(&output);
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
        Some((_, _, expected)) => {
            assert_eq!(
                digest, *expected,
                "{name} on {backend} / {driver}: the run's digest moved"
            );
            true
        }
        None => {
            eprintln!(
                "{name}: no golden digest for adapter {backend} / {driver}; digest {digest} not compared"
            );
            false
        }
    }
}

// The lab and indoor-team digests moved once, in the commit that made truth an oracle: the
// children (ctbot, no oracle) no longer receive `<child>/truth` messages, which the digest
// covered; every stack's commands and radio messages stayed the same bytes (the manifest's
// `stacks` digests, and tests/tests/oracle.rs). Before: lab 83596783 / d09f1e30, indoor-team
// cfb9f93a / e89fe768 (lavapipe / llvmpipe-GL).

#[test]
fn golden_lab_mission() {
    check_backends(
        "lab",
        &["run", "scenarios/lab.toml"],
        &[
            (
                LAVAPIPE.0,
                LAVAPIPE.1,
                "8dc54d1f9b937ee28858145a2055a7917210912ead831c877582c4118e83745a",
            ),
            (
                LLVMPIPE_GL.0,
                LLVMPIPE_GL.1,
                "a53034e3b83cb57c63cf8fead188ae930c2a18c2634edc6a8c978d69211e9d31",
            ),
        ],
    );
}

#[test]
fn golden_indoor_team_mission() {
    check_backends(
        "indoor-team",
        &["run", "scenarios/indoor-team.toml"],
        &[
            (
                LAVAPIPE.0,
                LAVAPIPE.1,
                "eb213b02550b61c4a5ed644885c39e15d9ab1c00c421544457db620ded614741",
            ),
            (
                LLVMPIPE_GL.0,
                LLVMPIPE_GL.1,
                "8d302ca62b50f5c9514bec5abd69c5110b207027e0e085f93ce8690691658773",
            ),
        ],
    );
}

#[test]
fn golden_indoor_grid_20_without_cameras() {
    assert!(check(
        "indoor-grid-20",
        &["run", "scenarios/indoor-grid-20.toml", "--no-render"],
        &[(
            "none",
            "none",
            "0a8ff85fe6efea20af64bca0aede7b8b37c241b750d8ae517a98c0fea570db62",
        )],
    ));
}

#[test]
fn golden_rendered_village_short() {
    check_backends(
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
