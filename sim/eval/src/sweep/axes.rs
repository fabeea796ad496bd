//! A run's scenario: the base scenario with the run's axis values written in.
//!
//! `robots.<robot>.<field>` and `models.<model>.<field>` become entries of the robots'
//! `overrides` tables (so the scenario loader checks them against the robot file, with its
//! errors), anything else is a dotted path into the scenario itself.

use super::{Sweep, SweepError, SweepRun};

impl Sweep {
    /// The base scenario with a run's axis values written in.
    pub fn scenario_text(&self, run: &SweepRun) -> Result<String, SweepError> {
        let axes = self.axes();
        let settings: Vec<(&str, &toml::Value)> =
            axes.iter().map(String::as_str).zip(&run.values).collect();
        apply_settings(&self.base_text, &settings).map_err(|e| self.run_error(run, e))
    }
}

/// A scenario's text with settings written in: `robots.<robot>.<field>` and
/// `models.<model>.<field>` into the robots' `overrides`, anything else at its dotted path
/// (sweep axes, `hetsim replay --set`).
pub fn apply_settings(base: &str, settings: &[(&str, &toml::Value)]) -> Result<String, String> {
    let mut table: toml::Table = toml::from_str(base).map_err(|e| e.to_string())?;
    for &(key, value) in settings {
        let segments: Vec<&str> = key.split('.').collect();
        match segments.as_slice() {
            ["robots", who, field @ ..] if !field.is_empty() => {
                set_override(&mut table, key, |r| name_of(r) == Some(who), field, value)?
            }
            ["models", model, field @ ..] if !field.is_empty() => set_override(
                &mut table,
                key,
                |r| r.get("model").and_then(|m| m.as_str()) == Some(model),
                field,
                value,
            )?,
            _ => set_path(&mut table, key, &segments, value)?,
        }
    }
    toml::to_string(&table).map_err(|e| e.to_string())
}

fn name_of(robot: &toml::Table) -> Option<&str> {
    robot.get("name").and_then(|n| n.as_str())
}

/// Writes `value` at a dotted path of the scenario, creating tables on the way.
fn set_path(
    table: &mut toml::Table,
    key: &str,
    segments: &[&str],
    value: &toml::Value,
) -> Result<(), String> {
    let (last, parents) = segments
        .split_last()
        .ok_or_else(|| "empty axis name".to_string())?;
    let mut at = table;
    for seg in parents {
        at = at
            .entry(seg.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| format!("axis {key}: {seg} is not a table in the base scenario"))?;
    }
    at.insert(last.to_string(), value.clone());
    Ok(())
}

/// Writes `"field" = value` into the `overrides` of every robot `pick` selects.
fn set_override(
    table: &mut toml::Table,
    key: &str,
    pick: impl Fn(&toml::Table) -> bool,
    field: &[&str],
    value: &toml::Value,
) -> Result<(), String> {
    let robots = table
        .get_mut("robots")
        .and_then(|r| r.as_array_mut())
        .ok_or_else(|| format!("axis {key}: the base scenario has no [[robots]]"))?;
    let mut names = Vec::new();
    let mut hit = 0;
    for robot in robots.iter_mut() {
        let Some(robot) = robot.as_table_mut() else {
            continue;
        };
        names.push(format!(
            "{} (model {})",
            name_of(robot).unwrap_or("?"),
            robot.get("model").and_then(|m| m.as_str()).unwrap_or("?")
        ));
        if !pick(robot) {
            continue;
        }
        hit += 1;
        let overrides = robot
            .entry("overrides".to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| format!("axis {key}: a robot's overrides is not a table"))?;
        overrides.insert(field.join("."), value.clone());
    }
    if hit == 0 {
        return Err(format!(
            "axis {key}: no robot matches in the base scenario (robots: {}); use robots.<robot name>.<field> or models.<model>.<field>",
            names.join(", ")
        ));
    }
    Ok(())
}
