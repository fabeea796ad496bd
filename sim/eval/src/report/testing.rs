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

/// A sweep cell for the report's unit tests with axis values `values` and one run's Q
/// (`parent_vertices`) and following behaviours.
pub(super) fn q_following_cell(values: &[&str], q: f64, following: f64) -> SummaryCell {
    let mut c = test_cell(values[0], "parent_vertices", &[q], 0);
    c.values = values.iter().map(|v| v.to_string()).collect();
    let f = test_cell("", "following", &[following], 0);
    c.metrics.extend(f.metrics);
    c.stats.extend(f.stats);
    c
}
