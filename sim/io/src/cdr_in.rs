//! Decoding a recording's ROS 2 (CDR) messages back into what the robots received: the
//! inverse of `record.rs`, bit for bit where the recording keeps the bits (every field but a
//! laser scan's angles, which `sensor_msgs/LaserScan` holds as `float32`: replay takes them
//! from the robot file, see `replay.rs`).

use crate::record::ros2::{Compass, GpsLocal, Header, Imu, Pose, PoseStamped, Time, WheelOdometry};
use hetsim_engine::replay::Event;
use hetsim_msgs::{
    ChildTracks, Command, CompassReading, Delivered, GpsFix, Image, ImageMatch, ImuSample,
    LaserScan, PixelEncoding, Rendezvous, SensorMsg, Track,
};
use serde::Deserialize;

/// What a channel carries, from its topic and schema.
pub struct Channel {
    /// The topic.
    pub topic: String,
    kind: Kind,
}

enum Kind {
    /// Not replayed: `/tf`, `/tf_static`, the WGS-84 copy of a GPS fix.
    Skip,
    /// `/<robot>/truth`.
    Truth(String),
    /// `/<robot>/cmd`.
    Command(String),
    /// A message for a robot: robot, sensor name, schema.
    Sensor(String, String, &'static str),
}

/// The schemas a robot's topics may have, as the recorder writes them.
const SENSOR_SCHEMAS: [&str; 10] = [
    "sensor_msgs/msg/Image",
    "sensor_msgs/msg/LaserScan",
    "sensor_msgs/msg/Imu",
    "hetsim_msgs/msg/GpsLocal",
    "hetsim_msgs/msg/Compass",
    "hetsim_msgs/msg/WheelOdometry",
    "hetsim_msgs/msg/ChildTracks",
    "hetsim_msgs/msg/Rendezvous",
    "hetsim_msgs/msg/ImageMatch",
    "hetsim_msgs/msg/Comms",
];

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
    /// A message without CDR's encapsulation header.
    #[error(
        "not CDR: its encapsulation header is {0:02x?}, expected 00 01 (little-endian) or 00 00"
    )]
    NotCdr(Vec<u8>),
    /// A message that decodes from fewer bytes than it has.
    #[error("CDR decodes from {used} of its {len} bytes (a message of another layout?)")]
    Trailing {
        /// Bytes decoded.
        used: usize,
        /// Bytes in the message.
        len: usize,
    },
    /// A message CDR cannot decode.
    #[error("CDR does not decode: {0}")]
    Decode(String),
    /// A stamp before 0 or with nanoseconds of a second or more.
    #[error("stamp {sec} s {nanosec} ns: a time from 0 on with nanoseconds below 1e9")]
    Stamp {
        /// Seconds.
        sec: i32,
        /// Nanoseconds.
        nanosec: u32,
    },
    /// An image encoding hetsim does not read.
    #[error("image encoding \"{0}\": hetsim reads rgb8 and mono8")]
    ImageEncoding(String),
    /// Padded image rows.
    #[error("image step {step} for width {width} in {encoding}: hetsim reads unpadded rows")]
    ImageStep {
        /// Bytes per row.
        step: u32,
        /// Pixels per row.
        width: u32,
        /// Its encoding.
        encoding: String,
    },
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
        if matches!(topic, "/tf" | "/tf_static") || schema == "sensor_msgs/msg/NavSatFix" {
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
            _ => match SENSOR_SCHEMAS.iter().find(|s| **s == schema) {
                Some(s) => {
                    // A GPS fix's local copy is on `<gps>/local`; the robot knows it as `<gps>`.
                    let sensor = match sensor.strip_suffix("/local") {
                        Some(gps) if *s == "hetsim_msgs/msg/GpsLocal" => gps.to_string(),
                        _ => sensor,
                    };
                    channel(Kind::Sensor(robot, sensor, s))
                }
                None => Err(CdrError::Schema {
                    schema: schema.to_string(),
                    known: format!(
                        " (known: geometry_msgs/msg/PoseStamped on /<robot>/truth, hetsim_msgs/msg/Command on /<robot>/cmd, {})",
                        SENSOR_SCHEMAS.join(", ")
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
                    pose: pose(&m.pose),
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
            Kind::Sensor(robot, sensor, schema) => Event::Sensor {
                robot: robot.clone(),
                topic: format!("{robot}/{sensor}"),
                msg: sensor_msg(robot, sensor, schema, data)?,
            },
        };
        Ok(Decoded::Event(event))
    }
}

/// A CDR message (4-byte encapsulation header, then the data). Decoded with RustDDS's
/// `cdr-encoding`, which checks every length against the bytes left before it allocates, so
/// a corrupt length cannot make it reserve gigabytes.
fn cdr<'de, T: Deserialize<'de>>(data: &'de [u8]) -> Result<T, CdrError> {
    let (decoded, len) = match data {
        [0, 1, _, _, rest @ ..] => (
            cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(rest),
            rest.len(),
        ),
        [0, 0, _, _, rest @ ..] => (
            cdr_encoding::from_bytes::<T, byteorder::BigEndian>(rest),
            rest.len(),
        ),
        _ => return Err(CdrError::NotCdr(data[..data.len().min(4)].to_vec())),
    };
    match decoded {
        Ok((value, used)) if used == len => Ok(value),
        Ok((_, used)) => Err(CdrError::Trailing { used, len }),
        Err(e) => Err(CdrError::Decode(e.to_string())),
    }
}

fn ns(t: &Time) -> Result<u64, CdrError> {
    if t.sec < 0 || t.nanosec >= 1_000_000_000 {
        return Err(CdrError::Stamp {
            sec: t.sec,
            nanosec: t.nanosec,
        });
    }
    Ok(t.sec as u64 * 1_000_000_000 + t.nanosec as u64)
}

fn pose(p: &Pose) -> hetsim_msgs::Pose {
    // The recorded components as they are: no renormalization, so the bits come back.
    let q = nalgebra::Quaternion::new(
        p.orientation.w,
        p.orientation.x,
        p.orientation.y,
        p.orientation.z,
    );
    nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(p.position.x, p.position.y, p.position.z),
        nalgebra::UnitQuaternion::new_unchecked(q),
    )
}

fn sensor_msg(robot: &str, sensor: &str, schema: &str, data: &[u8]) -> Result<SensorMsg, CdrError> {
    let sensor = sensor.to_string();
    Ok(match schema {
        "sensor_msgs/msg/Image" => {
            let m: ImageIn = cdr(data)?;
            let encoding = PixelEncoding::from_ros_name(&m.encoding)
                .ok_or_else(|| CdrError::ImageEncoding(m.encoding.clone()))?;
            if m.step != m.width.saturating_mul(encoding.channels()) {
                return Err(CdrError::ImageStep {
                    step: m.step,
                    width: m.width,
                    encoding: m.encoding.clone(),
                });
            }
            SensorMsg::Image(Image {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                width: m.width,
                height: m.height,
                encoding,
                data: m.data.into_vec(),
            })
        }
        "sensor_msgs/msg/LaserScan" => {
            let m: LaserScanIn = cdr(data)?;
            SensorMsg::LaserScan(LaserScan {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                angle_min_rad: m.angle_min as f64,
                angle_increment_rad: m.angle_increment as f64,
                range_max_m: m.range_max as f64,
                ranges_m: m.ranges,
            })
        }
        "sensor_msgs/msg/Imu" => {
            let m: Imu = cdr(data)?;
            let v = |v: crate::record::ros2::Vector3| [v.x, v.y, v.z];
            SensorMsg::Imu(ImuSample {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                angular_rate_radps: v(m.angular_velocity),
                accel_mps2: v(m.linear_acceleration),
            })
        }
        "hetsim_msgs/msg/GpsLocal" => {
            let m: GpsLocal = cdr(data)?;
            SensorMsg::Gps(GpsFix {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                position_m: [m.position.x, m.position.y, m.position.z],
                sigma_m: m.sigma_m,
            })
        }
        "hetsim_msgs/msg/Compass" => {
            let m: Compass = cdr(data)?;
            SensorMsg::Compass(CompassReading {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                heading_rad: m.heading_rad,
            })
        }
        "hetsim_msgs/msg/WheelOdometry" => {
            let m: WheelOdometry = cdr(data)?;
            SensorMsg::WheelOdometry(hetsim_msgs::WheelOdometry {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                left_m: m.left_m,
                right_m: m.right_m,
            })
        }
        "hetsim_msgs/msg/ChildTracks" => {
            let m: ChildTracksIn = cdr(data)?;
            SensorMsg::ChildTracks(ChildTracks {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                tracks: m
                    .tracks
                    .into_iter()
                    .map(|t| Track {
                        child: t.child,
                        position_m: [t.x, t.y],
                    })
                    .collect(),
            })
        }
        "hetsim_msgs/msg/Rendezvous" => {
            let m: RendezvousIn = cdr(data)?;
            SensorMsg::Rendezvous(Rendezvous {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                other: m.other,
                relative: pose(&m.pose),
                sigma_m: m.sigma_m,
                sigma_rad: m.sigma_rad,
            })
        }
        "hetsim_msgs/msg/ImageMatch" => {
            let m: ImageMatchIn = cdr(data)?;
            SensorMsg::ImageMatch(ImageMatch {
                stamp_ns: ns(&m.header.stamp)?,
                sensor,
                other: m.other,
                other_stamp_ns: ns(&m.other_stamp)?,
                relative: pose(&m.pose),
                sigma_m: m.sigma_m,
                sigma_rad: m.sigma_rad,
            })
        }
        "hetsim_msgs/msg/Comms" => {
            let m: CommsIn = cdr(data)?;
            if m.to != robot {
                return Err(CdrError::Delivery {
                    to: m.to.clone(),
                    robot: robot.to_string(),
                });
            }
            SensorMsg::Comms(Delivered {
                from: m.from,
                topic: m.topic,
                sent_ns: ns(&m.sent)?,
                stamp_ns: ns(&m.header.stamp)?,
                payload: m.payload.into_vec(),
            })
        }
        other => {
            return Err(CdrError::Schema {
                schema: other.to_string(),
                known: String::new(),
            })
        }
    })
}

#[derive(Deserialize)]
struct ImageIn {
    header: Header,
    height: u32,
    width: u32,
    encoding: String,
    _is_bigendian: u8,
    step: u32,
    data: serde_bytes::ByteBuf,
}

#[derive(Deserialize)]
struct LaserScanIn {
    header: Header,
    angle_min: f32,
    _angle_max: f32,
    angle_increment: f32,
    _time_increment: f32,
    _scan_time: f32,
    _range_min: f32,
    range_max: f32,
    ranges: Vec<f32>,
    _intensities: Vec<f32>,
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
struct ChildTrackIn {
    child: String,
    x: f64,
    y: f64,
}

#[derive(Deserialize)]
struct ChildTracksIn {
    header: Header,
    tracks: Vec<ChildTrackIn>,
}

#[derive(Deserialize)]
struct RendezvousIn {
    header: Header,
    other: String,
    pose: Pose,
    sigma_m: f64,
    sigma_rad: f64,
}

#[derive(Deserialize)]
struct ImageMatchIn {
    header: Header,
    other: String,
    other_stamp: Time,
    pose: Pose,
    sigma_m: f64,
    sigma_rad: f64,
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
