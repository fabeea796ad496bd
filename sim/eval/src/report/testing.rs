//! Helpers for the report's unit tests.

use crate::sweep::{Stat, SummaryCell};

/// A sweep cell for the report's unit tests: one axis value and one metric's samples (the
/// mean and spread left unset: the report reads the samples).
pub(super) fn test_cell(value: &str, metric: &str, samples: &[f64], missing: usize) -> SummaryCell {
    SummaryCell {
        values: vec![value.to_string()],
        metrics: vec![metric.to_string()],
        stats: vec![Stat {
            mean: f64::NAN,
            std: f64::NAN,
            samples: samples.to_vec(),
            missing,
        }],
        runs: samples.len() + missing,
    }
}
