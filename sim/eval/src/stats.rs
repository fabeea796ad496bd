//! The one statistics helper: mean and standard deviation of a sample, with the divisor
//! named at the call site.
//!
//! Two conventions are in use, on purpose:
//! * [`MeanStd::population`] (divide by n) describes the values themselves, e.g. the spread
//!   of one mission's grab errors, as the seed's Section V.B reports them;
//! * [`MeanStd::sample`] (divide by n - 1, Bessel) estimates the spread of the process the
//!   values were drawn from, e.g. over the seeds of a sweep cell, as the seed's tables report.

use serde::{Deserialize, Serialize};

/// An `f64` that metrics.json may hold as `null`: JSON has no NaN, so serde_json writes a NaN
/// (a figure a run does not have) as `null`; this reads it back as NaN.
pub fn f64_or_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// Mean and standard deviation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    /// Mean.
    pub mean: f64,
    /// Standard deviation (see the constructor for the divisor).
    pub std: f64,
}

impl MeanStd {
    /// Mean and population standard deviation (divisor n); zeros when there are no values.
    pub fn population(values: &[f64]) -> Self {
        Self::with_divisor(values, values.len() as f64)
    }

    /// Mean and sample standard deviation (divisor n - 1); the standard deviation is 0 for
    /// fewer than two values.
    pub fn sample(values: &[f64]) -> Self {
        if values.len() < 2 {
            return Self {
                std: 0.0,
                ..Self::population(values)
            };
        }
        Self::with_divisor(values, values.len() as f64 - 1.0)
    }

    fn with_divisor(values: &[f64], divisor: f64) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / divisor;
        Self {
            mean,
            std: var.sqrt(),
        }
    }

    /// The mean and population standard deviation of the union of groups, each given by its
    /// own mean and population standard deviation (equal weights).
    pub fn pooled(groups: &[MeanStd]) -> Self {
        let n = groups.len().max(1) as f64;
        let mean = groups.iter().map(|s| s.mean).sum::<f64>() / n;
        let second = groups
            .iter()
            .map(|s| s.std * s.std + s.mean * s.mean)
            .sum::<f64>()
            / n;
        Self {
            mean,
            std: (second - mean * mean).max(0.0).sqrt(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn population_and_sample_divisors() {
        // 2, 4, 4, 4, 5, 5, 7, 9: mean 5, population variance 4, sample variance 32/7.
        let v = [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0];
        let p = MeanStd::population(&v);
        assert_eq!((p.mean, p.std), (5.0, 2.0));
        let s = MeanStd::sample(&v);
        assert!((s.std - (32.0f64 / 7.0).sqrt()).abs() < 1e-12);
        assert_eq!(
            MeanStd::sample(&[3.0]),
            MeanStd {
                mean: 3.0,
                std: 0.0
            }
        );
        assert_eq!(MeanStd::population(&[]), MeanStd::default());
    }

    #[test]
    fn pooling_two_halves_gives_the_whole() {
        let a = [1.0, 2.0, 3.0];
        let b = [7.0, 8.0, 9.0];
        let all = [a, b].concat();
        let pooled = MeanStd::pooled(&[MeanStd::population(&a), MeanStd::population(&b)]);
        let whole = MeanStd::population(&all);
        assert!((pooled.mean - whole.mean).abs() < 1e-12);
        assert!((pooled.std - whole.std).abs() < 1e-12);
    }
}
