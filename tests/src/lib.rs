//! Helpers shared by the end-to-end tests: paths into the repository and the `hetsim` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// `hetsim` of the `release` profile or of the test's own, built (or brought up to date) at
/// most once per profile and test process: `cargo test -p hetsim-tests` alone does not build
/// other packages' binaries, and a stale binary would test old code.
fn built_hetsim(release: bool) -> PathBuf {
    static BUILD: [std::sync::Once; 2] = [std::sync::Once::new(), std::sync::Once::new()];
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test> -> target/<profile>
    let profile_dir = exe
        .parent()
        .and_then(Path::parent)
        .expect("target/<profile>")
        .to_path_buf();
    let release = release || profile_dir.file_name().is_some_and(|n| n == "release");
    BUILD[release as usize].call_once(|| {
        let mut cmd = Command::new(env!("CARGO"));
        cmd.args(["build", "-q", "-p", "hetsim-cli"])
            .current_dir(repo());
        if release {
            cmd.arg("--release");
        }
        assert!(
            cmd.status().expect("cargo runs").success(),
            "building hetsim-cli failed"
        );
    });
    let dir = if release {
        profile_dir.with_file_name("release")
    } else {
        profile_dir
    };
    dir.join(format!("hetsim{}", std::env::consts::EXE_SUFFIX))
}

/// The `hetsim` binary of this build.
pub fn hetsim_bin() -> PathBuf {
    built_hetsim(false)
}

/// The release build of `hetsim`: for the runs too long for the test profile's optimisation
/// (the full 600 s village, the golden missions, the whole-lab recording). `.ci/run` builds it
/// before the tests, so there it costs nothing; elsewhere the first such test builds it.
pub fn hetsim_release_bin() -> PathBuf {
    built_hetsim(true)
}

/// Runs `hetsim` with arguments and extra environment, in the repository root.
pub fn hetsim(args: &[&str], env: &[(&str, &str)]) -> Output {
    run_hetsim(hetsim_bin(), args, env)
}

/// [`hetsim`] with the release build: for whole missions, which it runs about a fifth faster
/// than the test profile (whose own crates are at opt-level 1), to the same digest.
pub fn hetsim_release(args: &[&str], env: &[(&str, &str)]) -> Output {
    run_hetsim(hetsim_release_bin(), args, env)
}

/// [`hetsim`] with these variables taken out of the environment it inherits: a machine
/// that does not set them.
pub fn hetsim_without(args: &[&str], removed: &[&str]) -> Output {
    let mut cmd = Command::new(hetsim_bin());
    cmd.args(args).current_dir(repo());
    for k in removed {
        cmd.env_remove(k);
    }
    cmd.output().expect("hetsim starts")
}

fn run_hetsim(bin: PathBuf, args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(bin);
    cmd.args(args).current_dir(repo());
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("hetsim starts")
}

/// Runs a scenario in-process with the robot software its robots declare (no cameras unless
/// `options` asks for them).
pub fn run_scenario(
    scenario: &hetsim_scene::Scenario,
    options: hetsim_engine::RunOptions<'_>,
) -> hetsim_engine::RunOutput {
    let stacks = hetsim_stacks::build_stacks(scenario, false);
    hetsim_engine::run(scenario, stacks, |_, _| {}, options).expect("the run completes")
}

/// The `digest: <hex>` line a successful run prints last.
pub fn printed_digest(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "hetsim failed: {}\n{}",
        stdout,
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<&str> = stdout.lines().collect();
    assert!(
        lines.len() >= 2,
        "expected results and digest lines, got {stdout:?}"
    );
    assert!(lines[lines.len() - 2].starts_with("results: "), "{stdout}");
    lines[lines.len() - 1]
        .strip_prefix("digest: ")
        .expect("last line is the digest")
        .to_string()
}

/// The 512 x 384 pinhole (60° horizontal field of view) the rendered vision tests use.
pub const TEST_INTRINSICS: hetsim_msgs::CameraGeometry = hetsim_msgs::CameraGeometry {
    width: 512,
    height: 384,
    k: hetsim_msgs::Pinhole {
        alpha_u: 443.4,
        alpha_v: 443.4,
        u0: 255.5,
        v0: 191.5,
    },
};

/// Every file of a sweep's folder by relative path, but what differs by design between two
/// folders of one sweep: the runs' wall-time `timing.json`, and the `shards/` and `slurm/`
/// that only a Slurm sweep's folder has.
pub fn sweep_folder_files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, at: &Path, files: &mut Vec<(String, Vec<u8>)>) {
        let mut entries: Vec<_> = std::fs::read_dir(at)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for p in entries {
            let rel = p.strip_prefix(root).unwrap().display().to_string();
            if p.is_dir() {
                if rel != "shards" && rel != "slurm" {
                    walk(root, &p, files);
                }
            } else if p.file_name().is_some_and(|n| n != "timing.json") {
                files.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut files = Vec::new();
    walk(dir, dir, &mut files);
    files
}

/// Two sweep folders hold the same files with the same bytes ([`sweep_folder_files`]).
pub fn assert_same_sweep_folders(a: &Path, b: &Path) {
    let (ta, tb) = (sweep_folder_files(a), sweep_folder_files(b));
    let names = |t: &[(String, Vec<u8>)]| t.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    assert_eq!(names(&ta), names(&tb), "{} vs {}", a.display(), b.display());
    for ((name, x), (_, y)) in ta.iter().zip(&tb) {
        assert!(
            x == y,
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}
