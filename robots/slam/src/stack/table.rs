//! The `[slam]` table of a robot file: tuning of the robot's SLAM software (seed 001), each
//! field optional; an absent field keeps the seed's value for the robot's kind
//! ([`SlamParams::ground`], [`SlamParams::aerial`]). It is what a parameter study changes, in
//! a scenario's `overrides`, a sweep's axes or `hetsim replay --set`. This crate owns the
//! fields, what each may be and how each sets [`SlamParams`]; the scenario loader reads the
//! table into this struct and checks it with [`SlamTuning::rules`].

use super::SlamParams;
use hetsim_msgs::params::Rule;
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
    /// Every value given, each with its allowed range (`lines`, a switch, has none).
    pub fn rules(&self) -> Vec<Rule> {
        let one = |field: &str, value: Option<f64>, lo: f64, hi: f64| {
            value.map(|value| Rule::range(field, value, lo, hi))
        };
        let mut out: Vec<Rule> = [
            one("sigma_px", self.sigma_px, 0.01, 100.0),
            one(
                "max_landmarks",
                self.max_landmarks.map(f64::from),
                1.0,
                10_000.0,
            ),
            one("per_region", self.per_region.map(f64::from), 1.0, 1_000.0),
            one("min_line_px", self.min_line_px, 1.0, 10_000.0),
            one("match_gate_chi2", self.match_gate_chi2, 0.01, 1e6),
            one("vo_covariance_scale", self.vo_covariance_scale, 0.01, 1e6),
        ]
        .into_iter()
        .flatten()
        .collect();
        for (field, values, hi) in [
            ("edge_drift_translation", self.edge_drift_translation, 1.0),
            (
                "edge_drift_rotation_deg_per_m",
                self.edge_drift_rotation_deg_per_m,
                10.0,
            ),
        ] {
            for (i, v) in values.iter().flatten().enumerate() {
                out.push(Rule::Range {
                    field: vec![field.to_string(), i.to_string()],
                    value: *v,
                    lo: 0.0,
                    hi,
                });
            }
        }
        out
    }

    /// The given values over `params` (the seed's for the robot's kind).
    pub fn apply(&self, params: &mut SlamParams) {
        if let Some(v) = self.sigma_px {
            params.sigma_px = v;
        }
        if let Some(v) = self.max_landmarks {
            params.max_landmarks = v as usize;
        }
        if let Some(v) = self.per_region {
            params.per_region = v as usize;
        }
        if let Some(v) = self.lines {
            params.lines = v;
        }
        if let Some(v) = self.min_line_px {
            params.min_line_px = v;
        }
        if let Some(v) = self.match_gate_chi2 {
            params.match_gate_chi2 = v;
        }
        if let Some(v) = self.vo_covariance_scale {
            params.vo_covariance_scale = v;
        }
        if let Some(v) = self.edge_drift_translation {
            params.edge_drift.translation = v;
        }
        if let Some(v) = self.edge_drift_rotation_deg_per_m {
            params.edge_drift.rotation_deg_per_m = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_table_keeps_the_seeds_values_and_each_field_sets_its_own() {
        let seed = SlamParams::ground();
        let mut p = seed.clone();
        SlamTuning::default().apply(&mut p);
        assert_eq!(p, seed);
        assert!(SlamTuning::default().rules().is_empty());
        let t: SlamTuning =
            serde_json::from_str(r#"{"sigma_px": 0.7, "edge_drift_translation": [0.1, 0.2, 0.3]}"#)
                .unwrap();
        t.apply(&mut p);
        assert_eq!(p.sigma_px, 0.7);
        assert_eq!(p.edge_drift.translation, [0.1, 0.2, 0.3]);
        assert_eq!(p.max_landmarks, seed.max_landmarks);
        let fields: Vec<Vec<String>> = t.rules().iter().map(|r| r.field().to_vec()).collect();
        assert_eq!(fields[0], ["sigma_px"]);
        assert_eq!(fields[3], ["edge_drift_translation", "2"]);
        assert!(
            serde_json::from_str::<SlamTuning>(r#"{"sigma": 1.0}"#).is_err(),
            "unknown fields are refused"
        );
    }
}
