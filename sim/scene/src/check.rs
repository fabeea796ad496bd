//! Range checks that produce errors pointing at the file, line and field.

use crate::source::Source;
use crate::{FieldError, SceneError};
use std::fmt::Display;

/// Checks values parsed from one [`Source`].
pub struct Checker<'a> {
    source: &'a Source,
}

/// `["sensors", "0", "rate_hz"]` -> `sensors[0].rate_hz`.
pub fn field_name(path: &[&str]) -> String {
    let mut out = String::new();
    for seg in path {
        if seg.parse::<usize>().is_ok() {
            out.push_str(&format!("[{seg}]"));
        } else {
            if !out.is_empty() {
                out.push('.');
            }
            out.push_str(seg);
        }
    }
    out
}

impl<'a> Checker<'a> {
    /// A checker for values parsed from `source`.
    pub fn new(source: &'a Source) -> Self {
        Self { source }
    }

    /// The source being checked.
    pub fn source(&self) -> &Source {
        self.source
    }

    /// An error at `path` (for the line) about `field`.
    pub fn error(
        &self,
        path: &[&str],
        field: &str,
        value: impl Display,
        allowed: impl Into<String>,
    ) -> SceneError {
        SceneError::field(
            self.source.path(),
            self.source.line(path),
            field,
            value,
            allowed,
        )
    }

    /// An error at `path`, naming the field after the path.
    pub fn error_at(
        &self,
        path: &[&str],
        value: impl Display,
        allowed: impl Into<String>,
    ) -> SceneError {
        self.error(path, &field_name(path), value, allowed)
    }

    /// `value` must be finite and > 0.
    pub fn positive(&self, path: &[&str], value: f64) -> Result<(), SceneError> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(self.error_at(path, number(value), "a finite number > 0"))
        }
    }

    /// `value` must be finite and in `[lo, hi]`.
    pub fn range(&self, path: &[&str], value: f64, lo: f64, hi: f64) -> Result<(), SceneError> {
        if value.is_finite() && value >= lo && value <= hi {
            Ok(())
        } else {
            Err(self.error_at(path, number(value), format!("a number in [{lo}, {hi}]")))
        }
    }

    /// Replaces the "allowed" text of a field error.
    pub fn reword(&self, error: SceneError, allowed: &str) -> SceneError {
        match error {
            SceneError::Field(e) => SceneError::Field(FieldError {
                allowed: allowed.to_string(),
                ..e
            }),
            other => other,
        }
    }
}

/// A number as an error message shows it: as written for ordinary magnitudes, in exponent
/// form where the plain decimal would run to hundreds of digits (`1e300`, not 301 of them).
pub fn number(value: f64) -> String {
    if value != 0.0 && value.is_finite() && !(1e-6..1e15).contains(&value.abs()) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn numbers_in_messages_stay_short_at_any_magnitude() {
        assert_eq!(super::number(1e300), "1e300");
        assert_eq!(super::number(-2.5e-9), "-2.5e-9");
        assert_eq!(super::number(10_000_000.0), "10000000");
        assert_eq!(super::number(0.9), "0.9");
        assert_eq!(super::number(0.0), "0");
        assert_eq!(super::number(f64::NAN), "NaN");
    }
}
