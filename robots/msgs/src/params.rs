//! Settings tables that robot software owns (a robot file's `[slam]` and `[pilot]`, a
//! scenario's `[coverage]`): the crate that reads a table says what each of its values may
//! be, as [`Rule`]s, and the simulator's loader checks the values a file gives against them
//! and names the file, the line and the field where one fails.

/// One thing a settings value must be, with the value given. `field` is the path inside the
/// table (`["edge_drift", "translation", "1"]` for an array's element).
#[derive(Clone, Debug, PartialEq)]
pub enum Rule {
    /// A finite number in the closed range `[lo, hi]`.
    Range {
        /// The field.
        field: Vec<String>,
        /// The value given.
        value: f64,
        /// Smallest allowed.
        lo: f64,
        /// Largest allowed.
        hi: f64,
    },
    /// A finite number > 0.
    Positive {
        /// The field.
        field: Vec<String>,
        /// The value given.
        value: f64,
    },
    /// A value refused for another reason (missing where another field needs it, a name that
    /// is not one of the allowed ones): as the error shows it, and what is allowed.
    Refused {
        /// The field.
        field: Vec<String>,
        /// The value as the error shows it (`"(missing)"`, `"\"west-ish\""`).
        shown: String,
        /// What is allowed.
        allowed: String,
    },
}

impl Rule {
    /// A [`Rule::Range`] on a top-level field.
    pub fn range(field: &str, value: f64, lo: f64, hi: f64) -> Self {
        Rule::Range {
            field: vec![field.to_string()],
            value,
            lo,
            hi,
        }
    }

    /// A [`Rule::Positive`] on a top-level field.
    pub fn positive(field: &str, value: f64) -> Self {
        Rule::Positive {
            field: vec![field.to_string()],
            value,
        }
    }

    /// A [`Rule::Refused`] on a top-level field.
    pub fn refused(field: &str, shown: impl Into<String>, allowed: impl Into<String>) -> Self {
        Rule::Refused {
            field: vec![field.to_string()],
            shown: shown.into(),
            allowed: allowed.into(),
        }
    }

    /// The field the rule is about.
    pub fn field(&self) -> &[String] {
        match self {
            Rule::Range { field, .. }
            | Rule::Positive { field, .. }
            | Rule::Refused { field, .. } => field,
        }
    }

    /// Whether the value given meets the rule.
    pub fn holds(&self) -> bool {
        match *self {
            Rule::Range { value, lo, hi, .. } => value.is_finite() && value >= lo && value <= hi,
            Rule::Positive { value, .. } => value.is_finite() && value > 0.0,
            Rule::Refused { .. } => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_is_closed_and_refuses_what_is_not_finite() {
        assert!(Rule::range("x", 1.0, 1.0, 2.0).holds());
        assert!(Rule::range("x", 2.0, 1.0, 2.0).holds());
        assert!(!Rule::range("x", 2.000_001, 1.0, 2.0).holds());
        assert!(!Rule::range("x", f64::NAN, f64::NEG_INFINITY, f64::INFINITY).holds());
        assert!(!Rule::range("x", f64::INFINITY, 0.0, f64::INFINITY).holds());
    }

    #[test]
    fn positive_excludes_zero_and_refused_never_holds() {
        assert!(Rule::positive("x", f64::MIN_POSITIVE).holds());
        assert!(!Rule::positive("x", 0.0).holds());
        assert!(!Rule::positive("x", f64::INFINITY).holds());
        assert!(!Rule::refused("x", "(missing)", "a number").holds());
        assert_eq!(Rule::refused("x", "", "").field(), ["x".to_string()]);
    }
}
