//! `manifest.json` and `timing.json`: what ran, on what, with which digest, and how long it
//! took, as the typed structs a results folder is written from and read back into.
//!
//! Fields are declared in alphabetical order: the manifest's bytes are the same as those of
//! the `serde_json` object it used to be built as (whose keys are sorted).

use crate::EvalError;
use hetsim_engine::cameras::Calibration;
use hetsim_engine::RunOutput;
use hetsim_scene::{Scenario, Sensor};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// `manifest.json`: what ran, on what, and the digest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// The renderer's adapter (`None` for an unrendered run).
    pub adapter: Option<Adapter>,
    /// SHA-256 of the executable that made the run ([`build_sha256`]); empty
    /// for a run from before manifests named it.
    #[serde(default)]
    pub build_sha256: String,
    /// Every camera's given and true calibration, in camera order: the true one is only
    /// here (a frame dump's `sensor.yaml` and a recording's camera info carry the given).
    #[serde(default)]
    pub cameras: Vec<CameraRecord>,
    /// The run digest (hex).
    pub digest: String,
    /// The tick, seconds.
    pub dt_secs: f64,
    /// The simulated duration, seconds.
    pub duration_secs: f64,
    /// SHA-256 of every file the scenario was loaded from, by path.
    pub files_sha256: BTreeMap<String, String>,
    /// The version of hetsim that made the run.
    pub hetsim_version: String,
    /// Every place where the simulator's truth reached robot software.
    pub oracles: Vec<Oracle>,
    /// Records in the digest.
    pub records: u64,
    /// The scenario and robot models as resolved (defaults and overrides applied), for the
    /// reader: the scenario's files, hashed above, are what a run is made from.
    pub resolved: serde_json::Value,
    /// The scenario file's path.
    pub scenario: String,
    /// The run's seed.
    pub seed: u64,
    /// The digest of each robot's stack, in robot order.
    pub stacks: Vec<StackDigest>,
}

/// One camera's calibrations, as the manifest records them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraRecord {
    /// What the robot software was given (its robot file's values).
    pub given: Calibration,
    /// The true mid-exposure minus the image's stamp, milliseconds.
    pub time_offset_ms: f64,
    /// `<robot>/<camera>[/<left|right>]`.
    pub topic: String,
    /// What the simulator rendered with.
    pub truth: Calibration,
}

/// The adapter a run rendered on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Adapter {
    /// `Vulkan` or `Gl`.
    pub backend: String,
    /// Driver and its version.
    pub driver: String,
    /// Adapter name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
}

/// A place where the simulator's truth reaches robot software.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Oracle {
    /// What it gives, in words.
    pub gives: String,
    /// `oracle_pose` or `image_match`.
    pub kind: String,
    /// How often (the `oracle_pose` sensor's rate), hertz.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_hz: Option<f64>,
    /// The robot it reaches.
    pub robot: String,
    /// The sensor it comes through.
    pub sensor: String,
}

/// The digest of one robot's stack.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StackDigest {
    /// The stack's digest (hex).
    pub digest: String,
    /// The robot.
    pub robot: String,
}

impl Manifest {
    /// The manifest of `scenario`'s run `result`, whose final digest is `digest`.
    pub fn of(scenario: &Scenario, result: &RunOutput, digest: &str) -> Self {
        Self {
            adapter: result.adapter.as_ref().map(|a| Adapter {
                backend: a.backend.clone(),
                driver: a.driver.clone(),
                name: a.name.clone(),
            }),
            build_sha256: build_sha256().to_string(),
            cameras: result
                .cameras
                .iter()
                .map(|(topic, c)| CameraRecord {
                    given: c.given,
                    time_offset_ms: c.time_offset_s * 1e3,
                    topic: topic.clone(),
                    truth: c.truth,
                })
                .collect(),
            digest: digest.to_string(),
            dt_secs: scenario.clock.dt_secs(),
            duration_secs: scenario.duration_secs,
            files_sha256: scenario.file_hashes.clone(),
            hetsim_version: env!("CARGO_PKG_VERSION").to_string(),
            oracles: oracles(scenario),
            records: result.digest.records(),
            resolved: resolved(scenario),
            scenario: scenario.path.display().to_string(),
            seed: scenario.seed,
            stacks: result
                .robots
                .iter()
                .map(|r| StackDigest {
                    digest: r.stack_digest.clone(),
                    robot: r.name.clone(),
                })
                .collect(),
        }
    }

    /// What differs between the run this manifest describes and a run of `scenario` by this
    /// build (`seed`, `duration`, `tick`, `files`, `settings`, `build`); `None`: the same run
    /// (the same files by content, resolved settings, seed, duration, tick and build), which
    /// computes the same bytes and may be written again.
    pub fn differs_from(&self, scenario: &Scenario) -> Option<&'static str> {
        if self.seed != scenario.seed {
            Some("seed")
        } else if self.duration_secs != scenario.duration_secs {
            Some("duration")
        } else if self.dt_secs != scenario.clock.dt_secs() {
            Some("tick")
        } else if !same_contents(&self.files_sha256, &scenario.file_hashes) {
            Some("files")
        } else if self.resolved != written_back(resolved(scenario)) {
            Some("settings")
        } else if self.build_sha256 != build_sha256() {
            Some("build")
        } else {
            None
        }
    }

    /// The manifest of the results folder `results`.
    pub fn read(results: &Path) -> Result<Self, EvalError> {
        crate::json::read(&results.join("manifest.json"))
    }

    /// Whether the run's robots were given the emulated image matcher (an oracle).
    pub fn has_image_match_oracle(&self) -> bool {
        self.oracles.iter().any(|o| o.kind == "image_match")
    }
}

/// Every place where the simulator's truth reaches robot software, for the manifest: the
/// enabled `oracle_pose` sensors, and the emulated `image_match` sensors, which pair the key
/// frames SLAM stacks report with the truth.
fn oracles(scenario: &Scenario) -> Vec<Oracle> {
    let mut out = Vec::new();
    for r in &scenario.robots {
        for s in &r.model.sensors {
            match s {
                Sensor::OraclePose {
                    name,
                    rate_hz,
                    enabled: true,
                    ..
                } => out.push(Oracle {
                    gives: "the robot's exact world_from_body".into(),
                    kind: "oracle_pose".into(),
                    rate_hz: Some(*rate_hz),
                    robot: r.spec.name.clone(),
                    sensor: name.clone(),
                }),
                Sensor::ImageMatch { name, .. } => out.push(Oracle {
                    gives: "the relative pose to another robot's key frame, chosen and measured from the truth at the key frames SLAM stacks report (RobotStack::oracle_keyframes), plus noise".into(),
                    kind: "image_match".into(),
                    rate_hz: None,
                    robot: r.spec.name.clone(),
                    sensor: name.clone(),
                }),
                _ => {}
            }
        }
    }
    out
}

/// `timing.json`: how long a run took on this machine (outside the digest).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Camera frames dumped (`hetsim run --frames`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames_written: Option<u64>,
    /// Simulated seconds per wall-clock second.
    pub realtime_factor: f64,
    /// The recording a replay read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replay_of: Option<String>,
    /// Simulated seconds.
    pub sim_secs: f64,
    /// rayon's threads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threads: Option<usize>,
    /// Wall-clock seconds, from start to the results computed.
    pub wall_secs: f64,
}

impl Timing {
    /// The timing of the results folder `results`; `None` where it has no `timing.json` (a
    /// run still reports without it; one whose file is there and unreadable is refused).
    pub fn read(results: &Path) -> Result<Option<Self>, EvalError> {
        let path = results.join("timing.json");
        if !path.exists() {
            return Ok(None);
        }
        crate::json::read(&path).map(Some)
    }
}

/// The running executable's SHA-256, hex (`"unknown"` where it cannot be read): which build
/// made a run, in its manifest as `build_sha256`. Hashed once per process (about half a
/// second for a release `hetsim`). `hetsim localize` runs a seed again rather than mix a run
/// of another build into its study.
pub fn build_sha256() -> &'static str {
    static BUILD: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    BUILD.get_or_init(|| {
        use sha2::{Digest, Sha256};
        let hash = || -> std::io::Result<String> {
            use std::io::Read;
            // The running file itself (on Linux, even once a rebuild has replaced it).
            let mut file = std::fs::File::open("/proc/self/exe")
                .or_else(|_| std::fs::File::open(std::env::current_exe()?))?;
            let mut hasher = Sha256::new();
            let mut buf = vec![0u8; 1 << 20];
            loop {
                let n = file.read(&mut buf)?;
                if n == 0 {
                    break;
                }
                hasher.update(&buf[..n]);
            }
            Ok(hasher
                .finalize()
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect())
        };
        hash().unwrap_or_else(|_| "unknown".into())
    })
}

/// The scenario as the run resolved it (its file with overrides and settings applied, and
/// each robot's model), as the manifest records it.
fn resolved(scenario: &Scenario) -> serde_json::Value {
    serde_json::json!({
        "scenario": scenario.file,
        "robots": scenario.robots.iter().map(|r| serde_json::json!({"name": r.spec.name, "model": r.model})).collect::<Vec<_>>(),
    })
}

/// Whether two runs read files of the same contents (the keys are paths as typed, which
/// differ between `./scenarios/lab.toml` and `scenarios/lab.toml`).
fn same_contents(a: &BTreeMap<String, String>, b: &BTreeMap<String, String>) -> bool {
    let hashes = |m: &BTreeMap<String, String>| {
        let mut v: Vec<String> = m.values().cloned().collect();
        v.sort();
        v
    };
    hashes(a) == hashes(b)
}

/// `value` as a manifest read back from its bytes holds it (so that a float compares as the
/// parser reads it, not as it was computed).
fn written_back(value: serde_json::Value) -> serde_json::Value {
    serde_json::to_vec(&value)
        .ok()
        .and_then(|bytes| serde_json::from_slice(&bytes).ok())
        .unwrap_or(value)
}
