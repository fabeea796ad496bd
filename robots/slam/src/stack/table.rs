//! The `[slam]` table of a robot file: any field of [`SlamParams`] (nested tables for
//! `edge_drift`, `matching` and `line_prior`), written over the seed's values for the robot's
//! kind ([`SlamParams::ground`], [`SlamParams::aerial`]); a field the table leaves out keeps
//! the seed's value. It is what a parameter study changes, in a scenario's `overrides`, a
//! sweep's axes or `hetsim replay --set` (`robots.dala.slam.sigma_px=1.5`,
//! `models.ressac.slam.edge_drift.translation=[0.01, 0.01, 0.005]`).
//!
//! The fields are [`SlamParams`]' own (it derives `Deserialize`, refusing unknown fields):
//! no second list of them exists. What each may be is [`SlamParams::rules`]; the scenario
//! loader checks a table with both and names the file, line and field of the first that
//! fails.

use super::SlamParams;
use hetsim_msgs::params::Rule;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// A robot file's `[slam]` table as written: the values it gives, nothing else.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct SlamTable(pub Map<String, Value>);

/// A `[slam]` table that is not a [`SlamParams`]: a field that does not exist, or a value of
/// the wrong type.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("slam.{}: {message}", path.join("."))]
pub struct SlamTableError {
    /// Where in the table, one segment per table, field or array index.
    pub path: Vec<String>,
    /// The value the table gives there, as JSON (`None`: the table gives none there).
    pub given: Option<String>,
    /// What is wrong, as serde says it (it lists the allowed fields of an unknown one).
    pub message: String,
}

impl SlamTable {
    /// `base` (the seed's values for the robot's kind) with the table's values written over
    /// it: a value replaces the base's, a nested table is written over the base's field by
    /// field. The settings a scenario decides (`cooperative`, `reference_robot`) are not the
    /// table's and stay as `base` has them.
    pub fn over(&self, base: &SlamParams) -> Result<SlamParams, SlamTableError> {
        let mut merged = serde_json::to_value(base).expect("SlamParams serializes to JSON");
        write_over(&mut merged, &Value::Object(self.0.clone()));
        let mut params: SlamParams =
            serde_path_to_error::deserialize(merged).map_err(|e| self.error(e))?;
        params.cooperative = base.cooperative;
        params.reference_robot = base.reference_robot.clone();
        Ok(params)
    }

    fn error(&self, e: serde_path_to_error::Error<serde_json::Error>) -> SlamTableError {
        use serde_path_to_error::Segment;
        let mut path: Vec<String> = e
            .path()
            .iter()
            .filter_map(|s| match s {
                Segment::Map { key } => Some(key.clone()),
                Segment::Seq { index } => Some(index.to_string()),
                Segment::Enum { variant } => Some(variant.clone()),
                Segment::Unknown => None,
            })
            .collect();
        let message = e.into_inner().to_string();
        // serde names an unknown field in its message; the path may stop at its table.
        if let Some(name) = message
            .strip_prefix("unknown field `")
            .and_then(|rest| rest.split('`').next())
        {
            if path.last().map(String::as_str) != Some(name) {
                path.push(name.to_string());
            }
        }
        let root = Value::Object(self.0.clone());
        let given = path
            .iter()
            .try_fold(&root, |at, seg| match at {
                Value::Object(m) => m.get(seg),
                Value::Array(a) => seg.parse::<usize>().ok().and_then(|i| a.get(i)),
                _ => None,
            })
            .map(Value::to_string);
        SlamTableError {
            path,
            given,
            message,
        }
    }
}

/// Writes `over` onto `base`: tables field by field, anything else replaced.
fn write_over(base: &mut Value, over: &Value) {
    match (base, over) {
        (Value::Object(b), Value::Object(o)) => {
            for (key, value) in o {
                match b.get_mut(key) {
                    Some(slot) if slot.is_object() && value.is_object() => write_over(slot, value),
                    _ => {
                        b.insert(key.clone(), value.clone());
                    }
                }
            }
        }
        (b, o) => *b = o.clone(),
    }
}

impl SlamParams {
    /// What each value may be: wide bounds that keep the filter defined (a positive noise, a
    /// probability in (0, 1], an angle within a half turn), not the seed's values.
    pub fn rules(&self) -> Vec<Rule> {
        let mut out = vec![
            Rule::range("rho_init", self.rho_init, 0.0, 10.0),
            Rule::range("sigma_rho", self.sigma_rho, 1e-6, 10.0),
            Rule::range("max_landmarks", self.max_landmarks as f64, 1.0, 10_000.0),
            Rule::range("per_region", self.per_region as f64, 1.0, 1_000.0),
            Rule::range("sigma_px", self.sigma_px, 0.01, 100.0),
            Rule::range("vo_covariance_scale", self.vo_covariance_scale, 0.01, 1e6),
            Rule::range("max_search_px", self.max_search_px, 1.0, 10_000.0),
            Rule::range("min_searches", f64::from(self.min_searches), 1.0, 1_000.0),
            Rule::range("rendezvous_period_s", self.rendezvous_period_s, 0.0, 1e6),
            Rule::range("image_match_period_s", self.image_match_period_s, 0.0, 1e6),
            Rule::range("match_period_s", self.match_period_s, 0.01, 1e6),
            Rule::range("max_view_angle_deg", self.max_view_angle_deg, 0.0, 180.0),
            Rule::range(
                "max_match_candidates",
                self.max_match_candidates as f64,
                1.0,
                100.0,
            ),
            Rule::range("match_gate_chi2", self.match_gate_chi2, 0.01, 1e6),
            Rule::range("share_period_s", self.share_period_s, 0.01, 1e6),
            Rule::range("min_line_px", self.min_line_px, 1.0, 10_000.0),
            Rule::range(
                "max_visible_lines",
                self.max_visible_lines as f64,
                0.0,
                1_000.0,
            ),
            Rule::range(
                "line_detect_period",
                f64::from(self.line_detect_period),
                1.0,
                1_000.0,
            ),
            Rule::range("line_detect_scale", self.line_detect_scale, 0.05, 1.0),
            Rule::range("line_output_spread", self.line_output_spread, 1e-3, 10.0),
        ];
        let m = &self.matching;
        let nested = |table: &str, field: &str, value: f64, lo: f64, hi: f64| Rule::Range {
            field: vec![table.to_string(), field.to_string()],
            value,
            lo,
            hi,
        };
        out.extend([
            nested(
                "matching",
                "max_distance",
                f64::from(m.max_distance),
                0.0,
                256.0,
            ),
            nested("matching", "ratio", m.ratio, 0.01, 1.0),
            nested("matching", "iterations", m.iterations as f64, 1.0, 1e6),
            nested("matching", "inlier_px", m.inlier_px, 0.01, 100.0),
            // A relative pose from 3D-2D matches needs at least 3 points.
            nested(
                "matching",
                "min_inliers",
                m.min_inliers as f64,
                3.0,
                10_000.0,
            ),
            nested("matching", "sigma_px", m.sigma_px, 0.01, 100.0),
            nested(
                "matching",
                "sigma_disparity_px",
                m.sigma_disparity_px,
                0.01,
                100.0,
            ),
        ]);
        let element =
            |table: &str, field: &str, i: usize, value: f64, lo: f64, hi: f64| Rule::Range {
                field: vec![table.to_string(), field.to_string(), i.to_string()],
                value,
                lo,
                hi,
            };
        for i in 0..3 {
            let d = &self.edge_drift;
            out.push(element(
                "edge_drift",
                "translation",
                i,
                d.translation[i],
                0.0,
                1.0,
            ));
            out.push(element(
                "edge_drift",
                "rotation_deg_per_m",
                i,
                d.rotation_deg_per_m[i],
                0.0,
                10.0,
            ));
        }
        for i in 0..2 {
            let p = &self.line_prior;
            out.push(element("line_prior", "beta", i, p.beta[i], -10.0, 10.0));
            out.push(element(
                "line_prior",
                "sigma_beta",
                i,
                p.sigma_beta[i],
                1e-6,
                10.0,
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(json: &str) -> SlamTable {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn an_empty_table_keeps_the_seeds_values_and_each_field_sets_its_own() {
        for seed in [SlamParams::ground(), SlamParams::aerial()] {
            let mut base = seed.clone();
            base.cooperative = false;
            base.reference_robot = Some("dala".into());
            assert_eq!(SlamTable::default().over(&base).unwrap(), base);
            assert!(
                seed.rules().iter().all(Rule::holds),
                "the seed's values hold their own rules"
            );
        }
        let seed = SlamParams::aerial();
        let p = table(
            r#"{"sigma_px": 0.7, "vo_covariance_scale": 10,
                "edge_drift": {"translation": [0.1, 0.2, 0.3]}, "matching": {"ratio": 0.6}}"#,
        )
        .over(&seed)
        .unwrap();
        assert_eq!(p.sigma_px, 0.7);
        assert_eq!(p.vo_covariance_scale, 10.0, "an integer is a number");
        assert_eq!(p.edge_drift.translation, [0.1, 0.2, 0.3]);
        assert_eq!(
            p.edge_drift.rotation_deg_per_m, seed.edge_drift.rotation_deg_per_m,
            "a nested table is written over field by field"
        );
        assert_eq!(p.matching.ratio, 0.6);
        assert_eq!(p.matching.iterations, seed.matching.iterations);
        assert_eq!(p.max_landmarks, seed.max_landmarks);
    }

    #[test]
    fn an_unknown_field_or_a_wrong_type_is_named_with_its_place() {
        let seed = SlamParams::ground();
        let e = table(r#"{"sigma": 1.0}"#).over(&seed).unwrap_err();
        assert_eq!(e.path, ["sigma"]);
        assert_eq!(e.given.as_deref(), Some("1.0"));
        assert!(e.message.contains("sigma_px"), "lists the fields: {e}");
        let e = table(r#"{"matching": {"min_inlier": 5}}"#)
            .over(&seed)
            .unwrap_err();
        assert_eq!(e.path, ["matching", "min_inlier"]);
        let e = table(r#"{"max_landmarks": 1.5}"#).over(&seed).unwrap_err();
        assert_eq!(e.path, ["max_landmarks"]);
        let e = table(r#"{"cooperative": false}"#).over(&seed).unwrap_err();
        assert_eq!(
            e.path,
            ["cooperative"],
            "the scenario's settings are not the table's"
        );
        let bad = table(r#"{"edge_drift": {"translation": [0.01, -1, 0.01]}}"#)
            .over(&seed)
            .unwrap();
        let failed: Vec<_> = bad.rules().into_iter().filter(|r| !r.holds()).collect();
        assert_eq!(failed.len(), 1);
        assert_eq!(failed[0].field(), ["edge_drift", "translation", "1"]);
    }
}
