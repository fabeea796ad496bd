//! Checks a robot file's `[slam]` table, whose fields, ranges and meaning belong to the SLAM
//! software ([`hetsim_slam::stack::SlamTuning`]).

use crate::check::Checker;
use crate::SceneError;
use hetsim_slam::stack::SlamTuning;

/// Checks every value given against the range the SLAM software allows for it.
pub(super) fn validate(tuning: &SlamTuning, c: &Checker) -> Result<(), SceneError> {
    for b in tuning.bounds() {
        let mut path = vec!["slam"];
        path.extend(b.field.iter().map(String::as_str));
        c.range(&path, b.value, b.lo, b.hi)?;
    }
    Ok(())
}
