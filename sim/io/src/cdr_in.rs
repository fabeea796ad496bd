//! Decoding a recording's ROS 2 (CDR) messages back into what the robots received: the
//! inverse of `record.rs`, bit for bit where the recording keeps the bits (every field but a
//! laser scan's angles, which `sensor_msgs/LaserScan` holds as `float32`: replay takes them
//! from the robot file, see `replay.rs`).

use crate::record::ros2::{self, Header, PoseStamped, Time};
use hetsim_engine::replay::Event;
use hetsim_msgs::{Command, Delivered, GpsFix, SensorMsg};
use hetsim_sensors::ros2::{from_cdr, DecodeError, Ros2Message, KINDS};
use serde::Deserialize;

/// What a channel carries, from its topic and schema.
pub struct Channel {
    /// The topic.
    pub topic: String,
    kind: Kind,
}

enum Kind {
    /// Not replayed: `/tf`, `/tf_static`, the WGS-84 copy of a GPS fix, cameras' calibrations
    /// (the robot files the recording carries give them).
    Skip,
    /// `/<robot>/truth`.
    Truth(String),
    /// `/<robot>/cmd`.
    Command(String),
    /// A sensor's message for a robot: robot, sensor name, the kind's decoder.
    Sensor(String, String, Decoder),
    /// A radio delivery to a robot: robot, topic's sensor part.
    Radio(String, String),
}

type Decoder = fn(&[u8], String) -> Result<SensorMsg, DecodeError>;

/// Why a recorded channel or message cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum CdrError {
    /// Not ROS 2's encodings.
    #[error("schema encoding \"{schema_encoding}\", message encoding \"{message_encoding}\": hetsim replays ROS 2 recordings (ros2msg schemas, cdr messages), the default of hetsim run --record")]
    Encoding {
        /// The channel's schema encoding.
        schema_encoding: String,
        /// The channel's message encoding.
        message_encoding: String,
    },
    /// A topic not of the form hetsim records.
    #[error("not a /<robot>/<sensor> topic hetsim records")]
    Topic,
    /// A schema on a channel hetsim does not record (`known` lists those it does).
    #[error("schema \"{schema}\" is not one hetsim replays{known}")]
    Schema {
        /// The schema's name.
        schema: String,
        /// ` (known: ...)` where the channel is being opened, empty for a message.
        known: String,
    },
    /// A command of an unknown kind.
    #[error("command kind \"{0}\": one of wheels, helicopter, stop")]
    CommandKind(String),
    /// A message that does not decode ([`hetsim_sensors::ros2`]).
    #[error(transparent)]
    Message(#[from] DecodeError),
    /// A radio delivery on another robot's topic.
    #[error("a radio delivery to \"{to}\" on {robot}'s topic")]
    Delivery {
        /// The addressee.
        to: String,
        /// The topic's robot.
        robot: String,
    },
}

/// A decoded message.
pub enum Decoded {
    /// Something replay does not feed.
    Skip,
    /// Truth, a command or a robot's message.
    Event(Event),
}

impl Channel {
    /// The channel of `topic` with schema `schema`, or why hetsim cannot replay it.
    pub fn of(
        topic: &str,
        schema: &str,
        schema_encoding: &str,
        message_encoding: &str,
    ) -> Result<Self, CdrError> {
        let channel = |kind| {
            Ok(Self {
                topic: topic.to_string(),
                kind,
            })
        };
        if matches!(topic, "/tf" | "/tf_static")
            || matches!(
                schema,
                "sensor_msgs/msg/NavSatFix" | "sensor_msgs/msg/CameraInfo"
            )
        {
            return channel(Kind::Skip);
        }
        if schema_encoding != "ros2msg" || message_encoding != "cdr" {
            return Err(CdrError::Encoding {
                schema_encoding: schema_encoding.to_string(),
                message_encoding: message_encoding.to_string(),
            });
        }
        let Some((robot, sensor)) = topic.strip_prefix('/').and_then(|t| t.split_once('/')) else {
            return Err(CdrError::Topic);
        };
        let (robot, sensor) = (robot.to_string(), sensor.to_string());
        match (sensor.as_str(), schema) {
            ("truth", "geometry_msgs/msg/PoseStamped") => channel(Kind::Truth(robot)),
            ("cmd", "hetsim_msgs/msg/Command") => channel(Kind::Command(robot)),
            _ if schema == ros2::COMMS => channel(Kind::Radio(robot, sensor)),
            _ => match KINDS.iter().find(|k| k.schema == schema) {
                Some(k) => {
                    // A GPS fix's local copy is on `<gps>/local`; the robot knows it as `<gps>`.
                    let sensor = match sensor.strip_suffix("/local") {
                        Some(gps) if k.schema == GpsFix::SCHEMA => gps.to_string(),
                        _ => sensor,
                    };
                    channel(Kind::Sensor(robot, sensor, k.decode))
                }
                None => Err(CdrError::Schema {
                    schema: schema.to_string(),
                    known: format!(
                        " (known: geometry_msgs/msg/PoseStamped on /<robot>/truth, hetsim_msgs/msg/Command on /<robot>/cmd, {}, {})",
                        KINDS.map(|k| k.schema).join(", "),
                        ros2::COMMS
                    ),
                }),
            },
        }
    }

    /// Decodes one message of this channel.
    pub fn decode(&self, data: &[u8]) -> Result<Decoded, CdrError> {
        let event = match &self.kind {
            Kind::Skip => return Ok(Decoded::Skip),
            Kind::Truth(robot) => {
                let m: PoseStamped = cdr(data)?;
                Event::Truth {
                    robot: robot.clone(),
                    stamp_ns: ns(&m.header.stamp)?,
                    pose: m.pose.pose(),
                }
            }
            Kind::Command(robot) => {
                let m: CommandIn = cdr(data)?;
                let cmd = match m.kind.as_str() {
                    "wheels" => Command::Wheels {
                        left_mps: m.left_mps,
                        right_mps: m.right_mps,
                    },
                    "helicopter" => Command::Helicopter {
                        roll_rad: m.roll_rad,
                        pitch_rad: m.pitch_rad,
                        yaw_rate_radps: m.yaw_rate_radps,
                        climb_rate_mps: m.climb_rate_mps,
                    },
                    "stop" => Command::Stop,
                    other => return Err(CdrError::CommandKind(other.to_string())),
                };
                Event::Command {
                    robot: robot.clone(),
                    stamp_ns: ns(&m.header.stamp)?,
                    cmd,
                }
            }
            Kind::Sensor(robot, sensor, decode) => Event::Sensor {
                robot: robot.clone(),
                topic: format!("{robot}/{sensor}"),
                msg: decode(data, sensor.clone())?,
            },
            Kind::Radio(robot, sensor) => Event::Sensor {
                robot: robot.clone(),
                topic: format!("{robot}/{sensor}"),
                msg: radio(robot, data)?,
            },
        };
        Ok(Decoded::Event(event))
    }
}

fn cdr<'de, T: Deserialize<'de>>(data: &'de [u8]) -> Result<T, CdrError> {
    Ok(from_cdr(data)?)
}

fn ns(t: &Time) -> Result<u64, CdrError> {
    Ok(t.ns()?)
}

/// A radio delivery, refused on another robot's topic.
fn radio(robot: &str, data: &[u8]) -> Result<SensorMsg, CdrError> {
    let m: CommsIn = cdr(data)?;
    if m.to != robot {
        return Err(CdrError::Delivery {
            to: m.to.clone(),
            robot: robot.to_string(),
        });
    }
    Ok(SensorMsg::Comms(Delivered {
        from: m.from,
        topic: m.topic,
        sent_ns: ns(&m.sent)?,
        stamp_ns: ns(&m.header.stamp)?,
        payload: m.payload.into_vec(),
    }))
}

#[derive(Deserialize)]
struct CommandIn {
    header: Header,
    kind: String,
    left_mps: f64,
    right_mps: f64,
    roll_rad: f64,
    pitch_rad: f64,
    yaw_rate_radps: f64,
    climb_rate_mps: f64,
}

#[derive(Deserialize)]
struct CommsIn {
    header: Header,
    from: String,
    to: String,
    topic: String,
    sent: Time,
    _bytes: u32,
    payload: serde_bytes::ByteBuf,
}
