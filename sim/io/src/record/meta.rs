//! What a recording says about its run, as MCAP metadata records, so that `hetsim replay`
//! needs nothing but the file: the scenario and robot files as they were read, the seed and
//! duration in force (`hetsim.run`, written first), and what only the physics knew at the end
//! (`hetsim.outcome`: distance driven and collisions per robot, written last).

use super::{RecordError, Recorder};
use hetsim_engine::RecordedOutcome;
use hetsim_scene::Scenario;
use std::collections::BTreeMap;

/// Name of the metadata record describing the run.
pub const RUN_METADATA: &str = "hetsim.run";
/// Name of the metadata record with the physics' outcome per robot.
pub const OUTCOME_METADATA: &str = "hetsim.outcome";

impl Recorder {
    /// Writes the run's description: scenario file text and path, every robot file's text
    /// (key `robot_file/<model>`), seed, duration, tick length, open loop, and whether the
    /// cameras were rendered.
    pub fn describe(&mut self, scenario: &Scenario, rendered: bool) -> Result<(), RecordError> {
        let mut metadata = BTreeMap::new();
        metadata.insert("hetsim_version".into(), env!("CARGO_PKG_VERSION").into());
        metadata.insert("scenario_path".into(), scenario.path.display().to_string());
        metadata.insert("scenario".into(), scenario.text.clone());
        metadata.insert("seed".into(), scenario.seed.to_string());
        metadata.insert(
            "duration_secs".into(),
            format!("{:?}", scenario.duration_secs),
        );
        metadata.insert("dt_ns".into(), scenario.clock.dt_ns().to_string());
        metadata.insert("open_loop".into(), self.open_loop.to_string());
        metadata.insert("rendered".into(), rendered.to_string());
        metadata.insert(
            "camera_profile".into(),
            format!("{:?}", scenario.file.camera_profile).to_lowercase(),
        );
        for r in &scenario.robots {
            metadata.insert(format!("robot_file/{}", r.spec.model), r.model_text.clone());
            for s in &r.model.sensors {
                let Some((w, h, k, d)) = s.given_geometry() else {
                    continue;
                };
                let base = format!("{}/{}", r.spec.name, s.name());
                match s {
                    hetsim_scene::Sensor::StereoCamera { baseline_m, .. } => {
                        self.camera_info
                            .insert(format!("{base}/left"), (w, h, k, d, 0.0));
                        self.camera_info
                            .insert(format!("{base}/right"), (w, h, k, d, -baseline_m));
                    }
                    _ => {
                        self.camera_info.insert(base, (w, h, k, d, 0.0));
                    }
                }
            }
        }
        self.metadata(RUN_METADATA, metadata)
    }

    /// Records that the run's SLAM stacks are open loop (`hetsim run --open-loop`), so that a
    /// replay builds them the same way. Call before the run.
    pub fn set_open_loop(&mut self, open_loop: bool) {
        self.open_loop = open_loop;
    }

    /// Writes what the physics measured of each robot, and the ticks run: keys
    /// `<robot>/distance_m` (Rust's shortest round-trip decimal, so the bits come back) and
    /// `<robot>/collisions`.
    pub fn outcome(&mut self, ticks: u64, robots: &[RecordedOutcome]) -> Result<(), RecordError> {
        let mut metadata = BTreeMap::new();
        metadata.insert("ticks".into(), ticks.to_string());
        for r in robots {
            metadata.insert(
                format!("{}/distance_m", r.name),
                format!("{:?}", r.distance_m),
            );
            metadata.insert(format!("{}/collisions", r.name), r.collisions.to_string());
        }
        self.metadata(OUTCOME_METADATA, metadata)
    }

    /// The outcomes written by [`Recorder::outcome`], or which key is missing or bad.
    pub fn read_outcome(
        metadata: &BTreeMap<String, String>,
    ) -> Result<(u64, Vec<RecordedOutcome>), OutcomeError> {
        let get = |key: &str| {
            metadata
                .get(key)
                .ok_or_else(|| OutcomeError::Missing(key.to_string()))
        };
        let bad = |key: &str, value: &str| OutcomeError::NotANumber {
            key: key.to_string(),
            value: value.to_string(),
        };
        let ticks = get("ticks")?;
        let ticks = ticks.parse().map_err(|_| bad("ticks", ticks))?;
        let mut robots = Vec::new();
        for (key, value) in metadata {
            let Some(name) = key.strip_suffix("/distance_m") else {
                continue;
            };
            let key_c = format!("{name}/collisions");
            let collisions = get(&key_c)?;
            robots.push(RecordedOutcome {
                name: name.to_string(),
                distance_m: value.parse().map_err(|_| bad(key, value))?,
                collisions: collisions.parse().map_err(|_| bad(&key_c, collisions))?,
            });
        }
        Ok((ticks, robots))
    }

    fn metadata(
        &mut self,
        name: &str,
        metadata: BTreeMap<String, String>,
    ) -> Result<(), RecordError> {
        if !self.broken {
            if let Err(e) = self.writer.write_metadata(&mcap::records::Metadata {
                name: name.into(),
                metadata,
            }) {
                self.fail(e);
            }
        }
        self.first_failure()
    }
}

/// Why a recording's outcome metadata cannot be read back.
#[derive(Debug, thiserror::Error)]
pub enum OutcomeError {
    /// A key the outcome needs is absent.
    #[error("no \"{0}\"")]
    Missing(String),
    /// A value that is not a number.
    #[error("\"{key}\" = \"{value}\" is not a number")]
    NotANumber {
        /// The key.
        key: String,
        /// Its value.
        value: String,
    },
}
