//! The `[slam]` table of a robot file: tuning of the robot's SLAM software (seed 001), each
//! field optional; an absent field keeps the seed's value for the robot's kind. It is what a
//! parameter study changes, in a scenario's `overrides`, a sweep's axes or
//! `hetsim replay --set`.

use crate::check::Checker;
use crate::SceneError;
use serde::{Deserialize, Serialize};

/// Tuning of the SLAM software.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlamTuning {
    /// Pixel noise of an observation in the local EKF, pixels.
    #[serde(default)]
    pub sigma_px: Option<f64>,
    /// Points per sub-map before a new one starts (seed: 100).
    #[serde(default)]
    pub max_landmarks: Option<u32>,
    /// Points kept in each region of the 3 x 3 image partition (seed: 2).
    #[serde(default)]
    pub per_region: Option<u32>,
    /// Lines on (`false`: points only).
    #[serde(default)]
    pub lines: Option<bool>,
    /// New lines from segments longer than this in a 1024-pixel-wide image, pixels (seed: 60).
    #[serde(default)]
    pub min_line_px: Option<f64>,
    /// Image matches are accepted within this chi-square (6 degrees of freedom) of the graph's
    /// prediction.
    #[serde(default)]
    pub match_gate_chi2: Option<f64>,
    /// The drift of a sub-map's relative transform that VO's covariance does not hold, as a
    /// fraction of the sub-map's length, on the body's x, y and z axes.
    #[serde(default)]
    pub edge_drift_translation: Option<[f64; 3]>,
    /// The same drift on roll, pitch and yaw, degrees per metre.
    #[serde(default)]
    pub edge_drift_rotation_deg_per_m: Option<[f64; 3]>,
    /// VO's motion covariance is multiplied by this in the local map's prediction.
    #[serde(default)]
    pub vo_covariance_scale: Option<f64>,
}

impl SlamTuning {
    /// Checks every value given against its allowed range.
    pub fn validate(&self, c: &Checker) -> Result<(), SceneError> {
        if let Some(v) = self.sigma_px {
            c.range(&["slam", "sigma_px"], v, 0.01, 100.0)?;
        }
        if let Some(v) = self.max_landmarks {
            c.range(&["slam", "max_landmarks"], v as f64, 1.0, 10_000.0)?;
        }
        if let Some(v) = self.per_region {
            c.range(&["slam", "per_region"], v as f64, 1.0, 1_000.0)?;
        }
        if let Some(v) = self.min_line_px {
            c.range(&["slam", "min_line_px"], v, 1.0, 10_000.0)?;
        }
        if let Some(v) = self.match_gate_chi2 {
            c.range(&["slam", "match_gate_chi2"], v, 0.01, 1e6)?;
        }
        if let Some(v) = self.vo_covariance_scale {
            c.range(&["slam", "vo_covariance_scale"], v, 0.01, 1e6)?;
        }
        for (field, values, hi) in [
            ("edge_drift_translation", self.edge_drift_translation, 1.0),
            (
                "edge_drift_rotation_deg_per_m",
                self.edge_drift_rotation_deg_per_m,
                10.0,
            ),
        ] {
            for (i, v) in values.iter().flatten().enumerate() {
                let index = i.to_string();
                c.range(&["slam", field, &index], *v, 0.0, hi)?;
            }
        }
        Ok(())
    }
}
