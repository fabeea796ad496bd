//! Scenario and robot files: schema, parsing, validation, and the procedural worlds.
//!
//! Loading is parse, then validate, then build: [`load_scenario`] reads the scenario, checks
//! its schema version, deserializes it refusing unknown fields, checks every value against its
//! allowed range, reads each referenced robot file the same way (applying the scenario's
//! per-robot overrides), builds the world from the seed, and finally checks that every robot
//! starts inside the world and outside every obstacle. Every refusal names the file, the line,
//! the field, the bad value and what is allowed; nothing is run on a refused scenario.

pub mod budget;
mod check;
mod error;
mod given;
mod load;
mod params;
mod robot;
mod scenario;
mod source;
pub mod world;

pub use check::{field_name, Checker};
pub use error::{FieldError, SceneError};
pub use given::{coverage_params, stereo_bench, StereoBench};
pub use load::{
    load_robot_model, load_scenario, load_scenario_text, LoadOptions, ResolvedRobot, Scenario,
};
pub use robot::{
    camera_geometry, Body, CalibrationError, CameraProfile, DriveKind, Exposure, Helicopter, Mount,
    PilotTable, RobotModel, Sensor, Shutter, SlamTable, SteeringKind, Wheels, HAT_SCALE,
    HAT_THICKNESS_M, TRUNCATION_SIGMAS,
};
pub use scenario::{
    BoxSpec, CommsSpec, CoverageTable, IndoorSpec, MissionSpec, RobotSpec, ScenarioFile, Start,
    VillageSpec, WorldKind, WorldSpec,
};
pub use source::{Source, SCHEMA_VERSION};
