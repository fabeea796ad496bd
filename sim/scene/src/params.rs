//! Checks a settings table that robot software owns against the rules its crate states
//! ([`hetsim_msgs::params::Rule`]): a robot file's `[slam]` ([`hetsim_slam::stack::SlamParams::rules`])
//! and `[pilot]` ([`hetsim_pilot::PilotTable`]), a scenario's `[coverage]`
//! ([`hetsim_coverage::CoverageTable`]). The fields, their ranges and their meaning are the
//! robot software's; what is here is naming the file, line and field of the first that fails.

use crate::check::Checker;
use crate::SceneError;
use hetsim_msgs::params::Rule;

/// The first of `rules` that the table at `table` (its path in the file) fails, as an error.
pub(crate) fn check(c: &Checker, table: &[&str], rules: Vec<Rule>) -> Result<(), SceneError> {
    for rule in rules {
        let path: Vec<&str> = table
            .iter()
            .copied()
            .chain(rule.field().iter().map(String::as_str))
            .collect();
        match &rule {
            Rule::Range { value, lo, hi, .. } => c.range(&path, *value, *lo, *hi)?,
            Rule::Positive { value, .. } => c.positive(&path, *value)?,
            Rule::Refused { shown, allowed, .. } => {
                return Err(c.error_at(&path, shown, allowed.as_str()))
            }
        }
    }
    Ok(())
}
