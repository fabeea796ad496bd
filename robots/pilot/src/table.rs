//! The `[pilot]` table of a robot file: how the waypoint follower drives the robot. This
//! crate owns its fields, their defaults and what each may be ([`PilotTable::rules`]); the
//! scenario loader reads the table into [`PilotTable`] and checks it against those rules, and
//! the stacks turn it into the pilots' parameters with the body the robot file declares.

use crate::Steering;
use hetsim_msgs::params::Rule;
use serde::{Deserialize, Serialize};

/// Steering behaviour of the waypoint follower, as a robot file names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SteeringKind {
    /// Turn while driving.
    Smooth,
    /// Rotate in place, drive straight, re-aim near the goal (the c't-Bots).
    RotateThenDrive,
}

/// The `[pilot]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PilotTable {
    /// Speed when on course, metres per second.
    pub cruise_mps: f64,
    /// A waypoint counts as reached within this distance, metres.
    pub arrive_m: f64,
    /// Steering behaviour (ground robots).
    #[serde(default = "smooth")]
    pub steering: SteeringKind,
    /// Re-aim distance for `rotate_then_drive`, metres (0.2 m in the seed).
    #[serde(default)]
    pub reaim_m: Option<f64>,
    /// Heading error accepted before driving straight, degrees.
    #[serde(default)]
    pub aim_tolerance_deg: Option<f64>,
}

fn smooth() -> SteeringKind {
    SteeringKind::Smooth
}

/// Heading error a smooth-steering robot turns in place for before driving, degrees.
const TURN_IN_PLACE_DEG: f64 = 60.0;
/// Re-aim distance where a robot file gives none, metres (the seed's 0.2 m).
const DEFAULT_REAIM_M: f64 = 0.2;
/// Heading error accepted before driving straight where a robot file gives none, degrees.
const DEFAULT_AIM_TOLERANCE_DEG: f64 = 2.0;

impl PilotTable {
    /// What each value given must be, for a body whose top speed is `max_speed_mps`:
    /// rotate-then-drive steering needs its re-aim distance and aim tolerance.
    pub fn rules(&self, max_speed_mps: f64) -> Vec<Rule> {
        let mut rules = vec![
            Rule::range("cruise_mps", self.cruise_mps, 1e-3, max_speed_mps),
            Rule::positive("arrive_m", self.arrive_m),
        ];
        if self.steering == SteeringKind::RotateThenDrive {
            rules.push(match self.reaim_m {
                Some(v) => Rule::positive("reaim_m", v),
                None => Rule::refused(
                    "reaim_m",
                    "(missing)",
                    "a positive distance in metres for rotate_then_drive steering",
                ),
            });
            rules.push(match self.aim_tolerance_deg {
                Some(v) => Rule::range("aim_tolerance_deg", v, 1e-3, 45.0),
                None => Rule::refused(
                    "aim_tolerance_deg",
                    "(missing)",
                    "an angle in (0, 45] degrees for rotate_then_drive steering",
                ),
            });
        }
        rules
    }

    /// The ground pilot's steering.
    pub fn steering(&self) -> Steering {
        match self.steering {
            SteeringKind::Smooth => Steering::Smooth {
                turn_in_place_rad: TURN_IN_PLACE_DEG.to_radians(),
            },
            SteeringKind::RotateThenDrive => Steering::RotateThenDrive {
                reaim_m: self.reaim_m.unwrap_or(DEFAULT_REAIM_M),
                aim_tolerance_rad: self.aim_tolerance_rad(),
            },
        }
    }

    /// The heading error accepted before driving straight, radians.
    pub fn aim_tolerance_rad(&self) -> f64 {
        self.aim_tolerance_deg
            .unwrap_or(DEFAULT_AIM_TOLERANCE_DEG)
            .to_radians()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> PilotTable {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn rotate_then_drive_needs_its_reaim_distance_and_tolerance() {
        let smooth = table("cruise_mps = 0.5\narrive_m = 0.3\n");
        assert_eq!(smooth.steering, SteeringKind::Smooth);
        assert!(smooth.rules(1.0).iter().all(Rule::holds));
        assert!(
            !smooth.rules(0.4)[0].holds(),
            "cruise above the body's top speed"
        );
        let bare = table("cruise_mps = 0.15\narrive_m = 0.05\nsteering = \"rotate_then_drive\"\n");
        let refused: Vec<_> = bare.rules(0.3).into_iter().filter(|r| !r.holds()).collect();
        assert_eq!(refused.len(), 2, "{refused:?}");
        assert_eq!(refused[0].field(), ["reaim_m".to_string()]);
        let given = table(
            "cruise_mps = 0.15\narrive_m = 0.05\nsteering = \"rotate_then_drive\"\nreaim_m = 0.2\naim_tolerance_deg = 3.0\n",
        );
        assert!(given.rules(0.3).iter().all(Rule::holds));
        assert_eq!(
            given.steering(),
            Steering::RotateThenDrive {
                reaim_m: 0.2,
                aim_tolerance_rad: 3f64.to_radians()
            }
        );
    }
}
