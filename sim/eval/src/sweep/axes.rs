//! A run's scenario: the base scenario with the run's axis values written in.
//!
//! `robots.<robot>.<field>` and `models.<model>.<field>` become entries of the robots'
//! `overrides` tables (so the scenario loader checks them against the robot file, with its
//! errors), anything else is a dotted path into the scenario itself.

use super::{Sweep, SweepError, SweepRun};

/// Why a setting could not be written into a scenario.
#[derive(Debug, thiserror::Error)]
pub enum SettingError {
    /// The base scenario is not TOML.
    #[error("{0}")]
    Parse(#[from] toml::de::Error),
    /// The scenario with the settings could not be written back as TOML.
    #[error("{0}")]
    Write(#[from] toml::ser::Error),
    /// An empty setting name.
    #[error("empty axis name")]
    EmptyKey,
    /// A segment of the dotted path is a value, not a table.
    #[error("axis {key}: {segment} is not a table in the base scenario")]
    NotATable {
        /// The setting.
        key: String,
        /// The segment that is not a table.
        segment: String,
    },
    /// A robot setting where the scenario has no robots.
    #[error("axis {key}: the base scenario has no [[robots]]")]
    NoRobots {
        /// The setting.
        key: String,
    },
    /// A robot whose `overrides` is not a table.
    #[error("axis {key}: a robot's overrides is not a table")]
    OverridesNotATable {
        /// The setting.
        key: String,
    },
    /// A robot setting that selects no robot.
    #[error("axis {key}: no robot matches in the base scenario (robots: {}); use robots.<robot name>.<field> or models.<model>.<field>", robots.join(", "))]
    NoRobotMatches {
        /// The setting.
        key: String,
        /// The scenario's robots, as `name (model m)`.
        robots: Vec<String>,
    },
}

impl Sweep {
    /// The base scenario with a run's axis values written in.
    pub fn scenario_text(&self, run: &SweepRun) -> Result<String, SweepError> {
        let axes = self.axes();
        let settings: Vec<(&str, &toml::Value)> =
            axes.iter().map(String::as_str).zip(&run.values).collect();
        apply_settings(&self.base_text, &settings).map_err(|e| self.run_error(run, e.to_string()))
    }
}

/// A scenario's text with settings written in: `robots.<robot>.<field>` and
/// `models.<model>.<field>` into the robots' `overrides`, anything else at its dotted path
/// (sweep axes, `hetsim replay --set`).
pub fn apply_settings(
    base: &str,
    settings: &[(&str, &toml::Value)],
) -> Result<String, SettingError> {
    let mut table: toml::Table = toml::from_str(base)?;
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
    Ok(toml::to_string(&table)?)
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
) -> Result<(), SettingError> {
    let (last, parents) = segments.split_last().ok_or(SettingError::EmptyKey)?;
    let mut at = table;
    for seg in parents {
        at = at
            .entry(seg.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| SettingError::NotATable {
                key: key.to_string(),
                segment: seg.to_string(),
            })?;
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
) -> Result<(), SettingError> {
    let robots = table
        .get_mut("robots")
        .and_then(|r| r.as_array_mut())
        .ok_or_else(|| SettingError::NoRobots {
            key: key.to_string(),
        })?;
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
            .ok_or_else(|| SettingError::OverridesNotATable {
                key: key.to_string(),
            })?;
        overrides.insert(field.join("."), value.clone());
    }
    if hit == 0 {
        return Err(SettingError::NoRobotMatches {
            key: key.to_string(),
            robots: names,
        });
    }
    Ok(())
}
