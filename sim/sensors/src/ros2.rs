//! The ROS 2 form of the sensors' messages, as a recording holds them: each kind's
//! `ros2msg` definition, its CDR encoding (little-endian, with the 4-byte encapsulation
//! header, by the `cdr` crate) and its decoding back into the message the robot received,
//! bit for bit where the ROS type keeps the bits. Each kind implements [`Ros2Message`] in its
//! own module (`kinds/*.rs`, the camera's image in `camera.rs`); [`KINDS`] and [`encode`]
//! list them (this module names the message types only, never the kind modules, so the
//! kinds depend on it and not the other way). The recorder and replay (`hetsim-io`) add the topics that are not a sensor's:
//! truth, `/tf`, commands and the radio.
//!
//! Standard types are the ROS 2 (Humble onwards) definitions (`sensor_msgs/msg/Image`,
//! `NavSatFix`, `LaserScan`, `Imu`); hetsim's own use `hetsim_msgs/msg/*`, defined in the
//! same syntax, so any ROS 2 tool that reads definitions from the file (Foxglove,
//! `mcap-ros2-support`, rosbags) decodes them without a package installed.

use hetsim_msgs::SensorMsg;
use serde::{Deserialize, Serialize};

/// A definition with its dependencies, in rosbag2's layout: the type's own fields, then per
/// dependency a line of 80 `=`, `MSG: pkg/Type` and its fields.
pub fn with_deps(own: &str, deps: &[(&str, &str)]) -> String {
    let mut text = own.to_string();
    for (name, body) in deps {
        text.push_str(&format!("{}\nMSG: {name}\n{body}", "=".repeat(80)));
    }
    text
}

/// `builtin_interfaces/Time`'s definition.
pub const TIME: (&str, &str) = ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n");
/// `std_msgs/Header`'s definition.
pub const HEADER: (&str, &str) = (
    "std_msgs/Header",
    "builtin_interfaces/Time stamp\nstring frame_id\n",
);
/// `geometry_msgs/Vector3`'s definition.
pub const VECTOR3: (&str, &str) = ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n");
/// `geometry_msgs/Point`'s definition.
pub const POINT: (&str, &str) = ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n");
/// `geometry_msgs/Quaternion`'s definition.
pub const QUATERNION: (&str, &str) = (
    "geometry_msgs/Quaternion",
    "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
);
/// `geometry_msgs/Pose`'s definition.
pub const POSE: (&str, &str) = (
    "geometry_msgs/Pose",
    "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
);

/// `builtin_interfaces/Time`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// Sim time in nanoseconds (runs are far shorter than the 68 years `sec` holds).
    pub fn of(ns: u64) -> Self {
        Self {
            sec: (ns / 1_000_000_000).min(i32::MAX as u64) as i32,
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Back to nanoseconds, refusing a time before 0 or nanoseconds of a second or more.
    pub fn ns(&self) -> Result<u64, DecodeError> {
        if self.sec < 0 || self.nanosec >= 1_000_000_000 {
            return Err(DecodeError::Stamp {
                sec: self.sec,
                nanosec: self.nanosec,
            });
        }
        Ok(self.sec as u64 * 1_000_000_000 + self.nanosec as u64)
    }
}

/// `std_msgs/Header`.
#[derive(Serialize, Deserialize)]
pub struct Header {
    /// The message's sim time.
    pub stamp: Time,
    /// Its frame.
    pub frame_id: String,
}

/// `geometry_msgs/Vector3` and `Point`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Quaternion {
    /// i.
    pub x: f64,
    /// j.
    pub y: f64,
    /// k.
    pub z: f64,
    /// The real part.
    pub w: f64,
}

/// `geometry_msgs/Pose` (and `Transform`: the same layout).
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Pose {
    /// Translation.
    pub position: Vector3,
    /// Rotation.
    pub orientation: Quaternion,
}

impl Pose {
    /// The ROS form of a pose.
    pub fn of(p: &hetsim_msgs::Pose) -> Self {
        let t = p.translation.vector;
        let q = p.rotation.quaternion();
        Self {
            position: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            orientation: Quaternion {
                x: q.i,
                y: q.j,
                z: q.k,
                w: q.w,
            },
        }
    }

    /// The recorded components as they are: no renormalization, so the bits come back.
    pub fn pose(&self) -> hetsim_msgs::Pose {
        let q = nalgebra::Quaternion::new(
            self.orientation.w,
            self.orientation.x,
            self.orientation.y,
            self.orientation.z,
        );
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(self.position.x, self.position.y, self.position.z),
            nalgebra::UnitQuaternion::new_unchecked(q),
        )
    }
}

/// Latitude and longitude (degrees) and altitude (metres) of the world origin: LAAS-CNRS,
/// Toulouse. Any origin would do; this one is documented so positions can be reproduced.
pub const GEO_ORIGIN: (f64, f64, f64) = (43.5628, 1.4767, 150.0);

const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// Latitude, longitude (degrees) and altitude of a point of the world frame (east, north,
/// up), around [`GEO_ORIGIN`] with a local flat-earth approximation (error under a
/// millimetre over the village's 800 m).
pub fn geo(position_m: [f64; 3]) -> (f64, f64, f64) {
    let (lat0, lon0, alt0) = GEO_ORIGIN;
    let lat = lat0 + (position_m[1] / EARTH_RADIUS_M).to_degrees();
    let lon = lon0 + (position_m[0] / (EARTH_RADIUS_M * lat0.to_radians().cos())).to_degrees();
    (lat, lon, alt0 + position_m[2])
}

/// CDR (little endian, with its encapsulation header) of a message.
pub fn cdr_bytes<T: Serialize>(message: &T) -> Vec<u8> {
    // Serializing plain structs into memory fails only on a type CDR cannot hold (an
    // Option, an unsized sequence): a defect of the structs in this crate and hetsim-io,
    // not an input.
    cdr::serialize::<_, _, cdr::CdrLe>(message, cdr::Infinite)
        .unwrap_or_else(|e| panic!("CDR encoding of a recorded message: {e}"))
}

/// A CDR message (4-byte encapsulation header, then the data). Decoded with RustDDS's
/// `cdr-encoding`, which checks every length against the bytes left before it allocates, so
/// a corrupt length cannot make it reserve gigabytes.
pub fn from_cdr<'de, T: Deserialize<'de>>(data: &'de [u8]) -> Result<T, DecodeError> {
    let (decoded, len) = match data {
        [0, 1, _, _, rest @ ..] => (
            cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(rest),
            rest.len(),
        ),
        [0, 0, _, _, rest @ ..] => (
            cdr_encoding::from_bytes::<T, byteorder::BigEndian>(rest),
            rest.len(),
        ),
        _ => return Err(DecodeError::NotCdr(data[..data.len().min(4)].to_vec())),
    };
    match decoded {
        Ok((value, used)) if used == len => Ok(value),
        Ok((_, used)) => Err(DecodeError::Trailing { used, len }),
        Err(e) => Err(DecodeError::Decode(e.to_string())),
    }
}

/// Why a recorded message does not decode.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
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
}

/// The frames a message's header may name, as the recorder knows them.
pub struct Frames<'a> {
    /// The message's stamp.
    pub stamp_ns: u64,
    /// The sensor's own frame (`<robot>/<sensor>`; the recorder writes its mount to
    /// `/tf_static` the first time it is named), or the body's where it has no mount.
    pub sensor: &'a mut dyn FnMut() -> String,
    /// `<robot>/base_link`.
    pub body: String,
}

impl Frames<'_> {
    /// A header stamped with the message's time in `frame`.
    pub fn header(&self, frame: String) -> Header {
        Header {
            stamp: Time::of(self.stamp_ns),
            frame_id: frame,
        }
    }

    /// A header in the sensor's frame.
    pub fn in_sensor(&mut self) -> Header {
        let frame = (self.sensor)();
        self.header(frame)
    }
}

/// One recorded message of a sensor's: on the sensor's topic with `suffix` appended.
pub struct Encoded {
    /// Appended to the sensor's topic (empty, or e.g. `/local`).
    pub suffix: &'static str,
    /// Its `ros2msg` schema.
    pub schema: &'static str,
    /// Its CDR bytes.
    pub data: Vec<u8>,
}

impl Encoded {
    /// `message` on the sensor's own topic.
    pub fn on_topic<T: Serialize>(schema: &'static str, message: &T) -> Self {
        Self {
            suffix: "",
            schema,
            data: cdr_bytes(message),
        }
    }
}

/// A sensor message's ROS 2 form.
pub trait Ros2Message {
    /// The schema replay decodes the message from.
    const SCHEMA: &'static str;

    /// The `ros2msg` definition of every schema [`Ros2Message::encode`] writes.
    fn definitions() -> Vec<(&'static str, String)>;

    /// The message as the recorder writes it: one or more ROS 2 messages.
    fn encode(&self, frames: &mut Frames) -> Vec<Encoded>;

    /// The message the robot received, from the bytes of its [`Ros2Message::SCHEMA`]
    /// message; `sensor` is its sensor's name.
    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError>;
}

/// A sensor kind as replay and the recorder's schemas see it.
pub struct Kind {
    /// The schema its messages are replayed from.
    pub schema: &'static str,
    /// Its definitions.
    pub definitions: fn() -> Vec<(&'static str, String)>,
    /// Its decoder.
    pub decode: fn(&[u8], String) -> Result<SensorMsg, DecodeError>,
}

impl Kind {
    /// The kind of messages of type `M`.
    pub const fn of<M: Ros2Message>() -> Self {
        Self {
            schema: M::SCHEMA,
            definitions: M::definitions,
            decode: M::decode,
        }
    }
}

/// Every sensor kind's ROS 2 form, for replay and the recording's schemas (adding a kind:
/// its line here and in [`encode`]).
pub const KINDS: [Kind; 9] = [
    Kind::of::<hetsim_msgs::Image>(),
    Kind::of::<hetsim_msgs::LaserScan>(),
    Kind::of::<hetsim_msgs::ImuSample>(),
    Kind::of::<hetsim_msgs::GpsFix>(),
    Kind::of::<hetsim_msgs::CompassReading>(),
    Kind::of::<hetsim_msgs::WheelOdometry>(),
    Kind::of::<hetsim_msgs::ChildTracks>(),
    Kind::of::<hetsim_msgs::Rendezvous>(),
    Kind::of::<hetsim_msgs::ImageMatch>(),
];

/// A sensor's message as the recorder writes it; `None` for what is not a sensor's (the
/// truth of an oracle, which the recorder writes for every robot itself, and the radio).
pub fn encode(msg: &SensorMsg, frames: &mut Frames) -> Option<Vec<Encoded>> {
    Some(match msg {
        SensorMsg::TruthPose(_) | SensorMsg::Comms(_) => return None,
        SensorMsg::Image(m) => m.encode(frames),
        SensorMsg::Gps(m) => m.encode(frames),
        SensorMsg::LaserScan(m) => m.encode(frames),
        SensorMsg::Imu(m) => m.encode(frames),
        SensorMsg::Compass(m) => m.encode(frames),
        SensorMsg::WheelOdometry(m) => m.encode(frames),
        SensorMsg::ChildTracks(m) => m.encode(frames),
        SensorMsg::Rendezvous(m) => m.encode(frames),
        SensorMsg::ImageMatch(m) => m.encode(frames),
    })
}

/// The definition of a sensor kind's schema.
pub fn definition(schema: &str) -> Option<String> {
    KINDS
        .iter()
        .flat_map(|k| (k.definitions)())
        .find(|(name, _)| *name == schema)
        .map(|(_, text)| text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_msgs::{
        ChildTracks, CompassReading, GpsFix, Image, ImageMatch, ImuSample, LaserScan,
        PixelEncoding, Rendezvous, Track, WheelOdometry,
    };
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    /// One message of every sensor kind, with values that need every bit of their fields
    /// (a laser scan's angles in `float32`, which the ROS type holds).
    fn one_of_each() -> Vec<SensorMsg> {
        let stamp_ns = 12_345_678_901;
        let sensor = || "s".to_string();
        let relative = Isometry3::from_parts(
            Translation3::new(1.0 / 3.0, -2.5, 0.1),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        );
        vec![
            SensorMsg::Image(Image {
                stamp_ns,
                sensor: sensor(),
                width: 3,
                height: 2,
                encoding: PixelEncoding::Mono8,
                data: vec![0, 1, 2, 253, 254, 255],
            }),
            SensorMsg::LaserScan(LaserScan {
                stamp_ns,
                sensor: sensor(),
                angle_min_rad: -1.5,
                angle_increment_rad: 0.25,
                range_max_m: 30.0,
                ranges_m: vec![1.0 / 3.0, f32::INFINITY, 7.25],
            }),
            SensorMsg::Imu(ImuSample {
                stamp_ns,
                sensor: sensor(),
                angular_rate_radps: [0.1, -0.2, 1.0 / 7.0],
                accel_mps2: [0.3, 9.81, -1e-9],
            }),
            SensorMsg::Gps(GpsFix {
                stamp_ns,
                sensor: sensor(),
                position_m: [123.456, -78.9, 40.0 / 3.0],
                sigma_m: 0.5,
            }),
            SensorMsg::Compass(CompassReading {
                stamp_ns,
                sensor: sensor(),
                heading_rad: -3.0,
            }),
            SensorMsg::WheelOdometry(WheelOdometry {
                stamp_ns,
                sensor: sensor(),
                left_m: 0.01,
                right_m: -1.0 / 9.0,
            }),
            SensorMsg::ChildTracks(ChildTracks {
                stamp_ns,
                sensor: sensor(),
                tracks: vec![Track {
                    child: "ctbot1".into(),
                    position_m: [0.7, -1.0 / 3.0],
                }],
            }),
            SensorMsg::Rendezvous(Rendezvous {
                stamp_ns,
                sensor: sensor(),
                other: "ressac".into(),
                relative,
                sigma_m: 0.5,
                sigma_rad: 0.03,
            }),
            SensorMsg::ImageMatch(ImageMatch {
                stamp_ns,
                sensor: sensor(),
                other: "dala".into(),
                other_stamp_ns: 2_000_000_001,
                relative,
                sigma_m: 0.2,
                sigma_rad: 0.01,
            }),
        ]
    }

    #[test]
    fn every_kind_decodes_to_the_message_it_encoded_bit_for_bit() {
        let messages = one_of_each();
        assert_eq!(
            messages.len(),
            KINDS.len(),
            "one message per registered kind"
        );
        for msg in messages {
            let mut named = 0;
            let mut sensor_frame = || {
                named += 1;
                "r/s".to_string()
            };
            let mut frames = Frames {
                stamp_ns: msg.stamp_ns(),
                sensor: &mut sensor_frame,
                body: "r/base_link".into(),
            };
            let encoded = encode(&msg, &mut frames).expect("a sensor's message");
            assert!(named <= 1, "{msg:?}: the sensor frame named {named} times");
            let kind = KINDS
                .iter()
                .find(|k| encoded.iter().any(|e| e.schema == k.schema))
                .unwrap_or_else(|| panic!("{msg:?}: no registered kind decodes it"));
            let replayed = encoded.iter().find(|e| e.schema == kind.schema).unwrap();
            let back = (kind.decode)(&replayed.data, "s".into()).unwrap();
            assert_eq!(back, msg);
            for e in &encoded {
                assert!(
                    definition(e.schema).is_some(),
                    "{}: no definition",
                    e.schema
                );
            }
        }
    }

    #[test]
    fn a_truncated_or_foreign_message_is_refused_not_misread() {
        let msg = &one_of_each()[4];
        let mut frame = || "r/s".to_string();
        let mut frames = Frames {
            stamp_ns: 1,
            sensor: &mut frame,
            body: "r/base_link".into(),
        };
        let bytes = &encode(msg, &mut frames).unwrap()[0].data;
        let decode = KINDS
            .iter()
            .find(|k| k.schema == CompassReading::SCHEMA)
            .unwrap()
            .decode;
        assert!(matches!(
            decode(&bytes[..bytes.len() - 1], "s".into()),
            Err(DecodeError::Decode(_))
        ));
        assert!(matches!(
            decode(&[9, 9, 0, 0, 1, 2], "s".into()),
            Err(DecodeError::NotCdr(_))
        ));
        let mut longer = bytes.clone();
        longer.extend_from_slice(&[0; 8]);
        assert!(matches!(
            decode(&longer, "s".into()),
            Err(DecodeError::Trailing { .. })
        ));
    }
}
