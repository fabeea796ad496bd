//! What a recording says about its run, as MCAP metadata records, so that `hetsim replay`
//! needs nothing but the file: the scenario and robot files as they were read, the seed and
//! duration in force (`hetsim.run`, written first), and what only the physics knew at the end
//! (`hetsim.outcome`: distance driven and collisions per robot, written last).

use super::{RecordError, Recorder};
use hetsim_scene::Scenario;
use std::collections::BTreeMap;

/// Name of the metadata record describing the run.
pub const RUN_METADATA: &str = "hetsim.run";
/// Name of the metadata record with the physics' outcome per robot.
pub const OUTCOME_METADATA: &str = "hetsim.outcome";

/// What the physics measured of one robot, kept in the recording (replay has no physics).
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedOutcome {
    /// The robot.
    pub name: String,
    /// Distance travelled in the xy plane, metres.
    pub distance_m: f64,
    /// Collisions (contact episodes).
    pub collisions: u32,
}

impl Recorder {
    /// Writes the run's description: scenario file text and path, every robot file's text
    /// (key `robot_file/<model>`), seed, duration and tick length.
    pub fn describe(&mut self, scenario: &Scenario) -> Result<(), RecordError> {
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
        for r in &scenario.robots {
            metadata.insert(format!("robot_file/{}", r.spec.model), r.model_text.clone());
        }
        self.metadata(RUN_METADATA, metadata)
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

    /// The outcomes written by [`Recorder::outcome`], if the metadata holds them.
    pub fn read_outcome(
        metadata: &BTreeMap<String, String>,
    ) -> Option<(u64, Vec<RecordedOutcome>)> {
        let ticks = metadata.get("ticks")?.parse().ok()?;
        let mut robots = Vec::new();
        for (key, value) in metadata {
            let Some(name) = key.strip_suffix("/distance_m") else {
                continue;
            };
            robots.push(RecordedOutcome {
                name: name.to_string(),
                distance_m: value.parse().ok()?,
                collisions: metadata.get(&format!("{name}/collisions"))?.parse().ok()?,
            });
        }
        Some((ticks, robots))
    }

    fn metadata(
        &mut self,
        name: &str,
        metadata: BTreeMap<String, String>,
    ) -> Result<(), RecordError> {
        self.writer
            .write_metadata(&mcap::records::Metadata {
                name: name.into(),
                metadata,
            })
            .map_err(|source| RecordError::Mcap {
                path: self.tmp.clone(),
                source,
            })
    }
}
