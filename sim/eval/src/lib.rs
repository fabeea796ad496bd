//! Everything computed from a run's outputs: trajectory metrics (ATE, RPE, NEES), SLAM
//! evaluation, the coverage team's figures, localization experiments, the coverage-planning
//! sweeps, regression, reports, plots, and the results folder of a run.
//!
//! Evaluation reads what a run produced ([`hetsim_engine::RunOutput`]: truth, the stacks'
//! artifacts, counts) and the scenario; it never reaches into the engine's loop. It may use
//! the truth freely: it runs after the robots, on what they published.

pub mod charts;
pub mod coverage;
pub mod drift;
pub mod frames;
pub mod json;
pub mod localize;
pub mod manifest;
pub mod matching;
pub mod metrics;
pub mod regress;
pub mod report;
pub mod results;
pub mod scene;
pub mod slam;
pub mod stats;
pub mod sweep;
pub mod team;
pub mod trajectory;
pub mod village;

pub use metrics::{Metrics, RobotMetrics};
pub use results::{write_run, RunFiles};
pub use trajectory::Estimate;

use std::path::PathBuf;

/// Why an evaluation could not be made or written.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A results file (`metrics.json`, `manifest.json`, ...) is not what this version writes.
    #[error("{}: not the file this hetsim writes there: {source}", path.display())]
    Parse {
        /// The file.
        path: std::path::PathBuf,
        /// The field's path in the document, and where and why it does not parse.
        #[source]
        source: serde_path_to_error::Error<serde_json::Error>,
    },
    /// A file could not be read or written.
    #[error(transparent)]
    File(#[from] hetsim_core::files::FileError),
    /// A scenario was refused.
    #[error(transparent)]
    Scene(#[from] hetsim_scene::SceneError),
    /// A sweep failed.
    #[error(transparent)]
    Sweep(#[from] sweep::SweepError),
    /// The renderer could not start.
    #[error(transparent)]
    Render(#[from] hetsim_engine::RenderError),
    /// Coverage planning is impossible for this scenario.
    #[error("coverage planning: {0}")]
    Plan(String),
    /// A file's content is not what was expected.
    #[error("{}: {message}", path.display())]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the place in the file where known.
        message: String,
    },
    /// The results folder already exists and is not a hetsim results folder.
    #[error("{}: exists and is not a hetsim results directory (no manifest.json); choose another --out or remove it", .0.display())]
    Occupied(PathBuf),
    /// The results folder holds the results of another run.
    #[error("{}: holds the results of another run ({scenario}, seed {seed}, digest {digest}; this run differs in its {differs}); give --force to replace them, or choose another --out", dir.display())]
    OtherRun {
        /// The folder.
        dir: PathBuf,
        /// The scenario file of the run it holds.
        scenario: String,
        /// That run's seed.
        seed: u64,
        /// That run's digest.
        digest: String,
        /// The first thing that differs (`seed`, `duration`, `tick`, `files`, `settings`,
        /// `build`).
        differs: &'static str,
    },
    /// Something the experiment needs is missing from the scenario.
    #[error("{0}")]
    Scenario(String),
}
