//! What every robot stack checks at its boundary, before it uses a message: the checks that
//! need no knowledge of the robot (sizes against bytes, finite numbers, valid rotations,
//! non-decreasing stamps per sensor, nothing from the future). A stack adds what only it
//! knows (its cameras' sizes, for one). A message that fails is refused with an
//! [`InputError`] naming the sensor, stamp, field, value and what is allowed; the caller (the
//! engine, a replay) stops there, so no stack ever computes on it.

use crate::{Pose, SensorMsg};
use std::collections::BTreeMap;

/// A message a stack refused.
#[derive(Clone, Debug, PartialEq)]
pub struct InputError {
    /// The sensor (its name on the robot), or `radio` for a radio delivery.
    pub sensor: String,
    /// The message's stamp, nanoseconds.
    pub stamp_ns: u64,
    /// The field refused.
    pub field: String,
    /// Its value.
    pub value: String,
    /// What is allowed.
    pub allowed: String,
}

impl std::fmt::Display for InputError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} at {} ns: field `{}` = {}: {}",
            self.sensor, self.stamp_ns, self.field, self.value, self.allowed
        )
    }
}

impl std::error::Error for InputError {}

impl InputError {
    /// An error about `msg`'s `field`.
    pub fn of(msg: &SensorMsg, field: &str, value: impl std::fmt::Display, allowed: &str) -> Self {
        Self {
            sensor: sensor_of(msg).to_string(),
            stamp_ns: msg.stamp_ns(),
            field: field.to_string(),
            value: value.to_string(),
            allowed: allowed.to_string(),
        }
    }
}

/// The sensor a message comes from (`radio` for a delivery, `truth` for the oracle).
pub fn sensor_of(msg: &SensorMsg) -> &str {
    match msg {
        SensorMsg::TruthPose(_) => "truth",
        SensorMsg::Compass(m) => &m.sensor,
        SensorMsg::Gps(m) => &m.sensor,
        SensorMsg::WheelOdometry(m) => &m.sensor,
        SensorMsg::Imu(m) => &m.sensor,
        SensorMsg::LaserScan(m) => &m.sensor,
        SensorMsg::ChildTracks(m) => &m.sensor,
        SensorMsg::Rendezvous(m) => &m.sensor,
        SensorMsg::ImageMatch(m) => &m.sensor,
        SensorMsg::Comms(_) => "radio",
        SensorMsg::Image(m) => &m.sensor,
    }
}

const FINITE: &str = "a finite number";

fn finite(msg: &SensorMsg, field: &str, v: f64) -> Result<(), InputError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(InputError::of(msg, field, v, FINITE))
    }
}

fn positive(msg: &SensorMsg, field: &str, v: f64) -> Result<(), InputError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(InputError::of(msg, field, v, "a finite number above 0"))
    }
}

/// A standard deviation: 0 for a noise-free sensor, as robot files allow.
fn sigma(msg: &SensorMsg, field: &str, v: f64) -> Result<(), InputError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(InputError::of(
            msg,
            field,
            v,
            "a finite number of 0 or more",
        ))
    }
}

/// A pose: finite translation, a rotation quaternion of unit norm (within 1e-6).
fn pose(msg: &SensorMsg, field: &str, p: &Pose) -> Result<(), InputError> {
    let t = p.translation.vector;
    for (axis, v) in ["x", "y", "z"].iter().zip(t.iter()) {
        finite(msg, &format!("{field}.translation.{axis}"), *v)?;
    }
    let q = p.rotation.quaternion();
    let norm = q.norm();
    if !(norm.is_finite() && (norm - 1.0).abs() < 1e-6) {
        return Err(InputError::of(
            msg,
            &format!("{field}.rotation"),
            format!("a quaternion of norm {norm}"),
            "a unit quaternion",
        ));
    }
    Ok(())
}

/// The checks of a single message that need no knowledge of the robot.
pub fn check_message(msg: &SensorMsg) -> Result<(), InputError> {
    match msg {
        SensorMsg::TruthPose(m) => pose(msg, "pose", &m.pose),
        SensorMsg::Compass(m) => finite(msg, "heading_rad", m.heading_rad),
        SensorMsg::Gps(m) => {
            for (axis, v) in ["x", "y", "z"].iter().zip(m.position_m) {
                finite(msg, &format!("position_m.{axis}"), v)?;
            }
            sigma(msg, "sigma_m", m.sigma_m)
        }
        SensorMsg::WheelOdometry(m) => {
            finite(msg, "left_m", m.left_m)?;
            finite(msg, "right_m", m.right_m)
        }
        SensorMsg::Imu(m) => {
            for (axis, v) in ["x", "y", "z"].iter().zip(m.angular_rate_radps) {
                finite(msg, &format!("angular_rate_radps.{axis}"), v)?;
            }
            for (axis, v) in ["x", "y", "z"].iter().zip(m.accel_mps2) {
                finite(msg, &format!("accel_mps2.{axis}"), v)?;
            }
            Ok(())
        }
        SensorMsg::LaserScan(m) => {
            finite(msg, "angle_min_rad", m.angle_min_rad)?;
            positive(msg, "angle_increment_rad", m.angle_increment_rad)?;
            positive(msg, "range_max_m", m.range_max_m)?;
            if m.ranges_m.is_empty() || m.ranges_m.len() > 100_000 {
                return Err(InputError::of(
                    msg,
                    "ranges_m",
                    format!("{} beams", m.ranges_m.len()),
                    "1 to 100000 beams",
                ));
            }
            let sweep = m.angle_increment_rad * (m.ranges_m.len() - 1) as f64;
            if sweep > std::f64::consts::TAU + 1e-9 {
                return Err(InputError::of(
                    msg,
                    "ranges_m",
                    format!(
                        "{} beams of {} rad",
                        m.ranges_m.len(),
                        m.angle_increment_rad
                    ),
                    "beams that sweep at most a full turn",
                ));
            }
            match m
                .ranges_m
                .iter()
                .enumerate()
                .find(|(_, r)| r.is_nan() || **r < 0.0 || **r == f32::NEG_INFINITY)
            {
                Some((i, r)) => Err(InputError::of(
                    msg,
                    &format!("ranges_m[{i}]"),
                    r,
                    "a range of 0 or more metres, or +inf for no return",
                )),
                None => Ok(()),
            }
        }
        SensorMsg::ChildTracks(m) => {
            for (i, t) in m.tracks.iter().enumerate() {
                finite(msg, &format!("tracks[{i}].position_m.x"), t.position_m[0])?;
                finite(msg, &format!("tracks[{i}].position_m.y"), t.position_m[1])?;
            }
            Ok(())
        }
        SensorMsg::Rendezvous(m) => {
            pose(msg, "relative", &m.relative)?;
            sigma(msg, "sigma_m", m.sigma_m)?;
            sigma(msg, "sigma_rad", m.sigma_rad)
        }
        SensorMsg::ImageMatch(m) => {
            pose(msg, "relative", &m.relative)?;
            sigma(msg, "sigma_m", m.sigma_m)?;
            sigma(msg, "sigma_rad", m.sigma_rad)?;
            if m.other_stamp_ns > m.stamp_ns {
                return Err(InputError::of(
                    msg,
                    "other_stamp_ns",
                    m.other_stamp_ns,
                    "a stamp no later than the message's",
                ));
            }
            Ok(())
        }
        SensorMsg::Comms(m) => {
            if m.sent_ns > m.stamp_ns {
                return Err(InputError::of(
                    msg,
                    "sent_ns",
                    m.sent_ns,
                    "a send time no later than the delivery",
                ));
            }
            Ok(())
        }
        SensorMsg::Image(m) => {
            let want = (m.width as u64) * (m.height as u64) * m.encoding.channels() as u64;
            if m.width == 0 || m.height == 0 || m.width > 16_384 || m.height > 16_384 {
                return Err(InputError::of(
                    msg,
                    "width x height",
                    format!("{} x {}", m.width, m.height),
                    "1 to 16384 pixels each way",
                ));
            }
            if m.data.len() as u64 != want {
                return Err(InputError::of(
                    msg,
                    "data",
                    format!("{} bytes", m.data.len()),
                    &format!(
                        "width x height x {} = {want} bytes ({})",
                        m.encoding.channels(),
                        m.encoding.ros_name()
                    ),
                ));
            }
            Ok(())
        }
    }
}

/// A stack's guard at its boundary: every message checked ([`check_message`]), stamps no
/// later than the step's time, and non-decreasing per sensor.
#[derive(Clone, Debug, Default)]
pub struct InboxGuard {
    last: BTreeMap<String, u64>,
}

impl InboxGuard {
    /// A guard that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Checks the messages of one step at `now_ns`, in order.
    pub fn check(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<(), InputError> {
        for msg in inbox {
            check_message(msg)?;
            let stamp = msg.stamp_ns();
            if stamp > now_ns {
                return Err(InputError::of(
                    msg,
                    "stamp_ns",
                    stamp,
                    &format!("a stamp no later than the step's time, {now_ns} ns"),
                ));
            }
            let sensor = sensor_of(msg);
            // Radio deliveries come from several senders, each in order; by sender.
            let key = match msg {
                SensorMsg::Comms(m) => format!("radio/{}/{}", m.from, m.topic),
                _ => sensor.to_string(),
            };
            if let Some(last) = self.last.get(&key) {
                if stamp < *last {
                    return Err(InputError::of(
                        msg,
                        "stamp_ns",
                        stamp,
                        &format!("non-decreasing stamps per sensor (the last was {last} ns)"),
                    ));
                }
            }
            self.last.insert(key, stamp);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CompassReading, Image, LaserScan};

    fn image(width: u32, height: u32, bytes: usize) -> SensorMsg {
        SensorMsg::Image(Image {
            stamp_ns: 5,
            sensor: "stereo/left".into(),
            width,
            height,
            encoding: crate::PixelEncoding::Rgb8,
            data: vec![0; bytes],
        })
    }

    fn compass(stamp_ns: u64, heading_rad: f64) -> SensorMsg {
        SensorMsg::Compass(CompassReading {
            stamp_ns,
            sensor: "compass".into(),
            heading_rad,
        })
    }

    #[test]
    fn a_refusal_names_sensor_stamp_field_value_and_what_is_allowed() {
        let e = check_message(&image(4, 3, 35)).unwrap_err();
        assert_eq!(
            (e.sensor.as_str(), e.stamp_ns, e.field.as_str()),
            ("stereo/left", 5, "data")
        );
        assert_eq!(e.value, "35 bytes");
        assert!(e.allowed.contains("36 bytes"), "{e}");
        assert!(check_message(&image(4, 3, 36)).is_ok());
        // Sizes whose product overflows 32 bits are refused by their size, not by a wrapped
        // product that happens to match the bytes.
        let e = check_message(&image(65_536, 65_536, 0)).unwrap_err();
        assert_eq!(e.field, "width x height");
        let e = check_message(&compass(1, f64::NAN)).unwrap_err();
        assert_eq!((e.field.as_str(), e.value.as_str()), ("heading_rad", "NaN"));
        let scan = |ranges_m: Vec<f32>| {
            SensorMsg::LaserScan(LaserScan {
                stamp_ns: 1,
                sensor: "laser".into(),
                angle_min_rad: -1.0,
                angle_increment_rad: 0.01,
                range_max_m: 20.0,
                ranges_m,
            })
        };
        assert!(check_message(&scan(vec![1.0, f32::INFINITY, 0.0])).is_ok());
        let e = check_message(&scan(vec![1.0, -0.5])).unwrap_err();
        assert_eq!(e.field, "ranges_m[1]");
    }

    #[test]
    fn stamps_go_forward_per_sensor_and_never_past_the_step() {
        let mut guard = InboxGuard::new();
        guard
            .check(10, &[compass(5, 0.0), compass(10, 0.1)])
            .unwrap();
        let e = guard.check(20, &[compass(9, 0.0)]).unwrap_err();
        assert_eq!((e.field.as_str(), e.value.as_str()), ("stamp_ns", "9"));
        assert!(e.allowed.contains("10 ns"), "{e}");
        let e = guard.check(20, &[compass(21, 0.0)]).unwrap_err();
        assert!(e.allowed.contains("20 ns"), "{e}");
        // A refused message leaves the guard as it was.
        guard.check(20, &[compass(10, 0.0)]).unwrap();
    }
}
