//! The ROS 2 side of a recording: message definitions (`ros2msg`, as rosbag2 stores them in
//! MCAP) and the CDR layout of each message as serde structs, encoded by the `cdr` crate
//! (little-endian, with the 4-byte encapsulation header).
//!
//! Standard types are the ROS 2 (Humble onwards) definitions: `sensor_msgs/msg/Image`,
//! `NavSatFix`, `LaserScan`, `Imu`, `geometry_msgs/msg/PoseStamped`, `tf2_msgs/msg/TFMessage`.
//! hetsim's own topics use `hetsim_msgs/msg/*`, defined here in the same syntax, so any
//! ROS 2 tool that reads definitions from the file (Foxglove, `mcap-ros2-support`, rosbags)
//! decodes them without a package installed.

use serde::{Deserialize, Serialize};

/// A definition with its dependencies, in rosbag2's layout: the type's own fields, then per
/// dependency a line of 80 `=`, `MSG: pkg/Type` and its fields.
fn with_deps(own: &str, deps: &[(&str, &str)]) -> String {
    let mut text = own.to_string();
    for (name, body) in deps {
        text.push_str(&format!("{}\nMSG: {name}\n{body}", "=".repeat(80)));
    }
    text
}

const TIME: (&str, &str) = ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n");
const HEADER: (&str, &str) = (
    "std_msgs/Header",
    "builtin_interfaces/Time stamp\nstring frame_id\n",
);
const VECTOR3: (&str, &str) = ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n");
const POINT: (&str, &str) = ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n");
const QUATERNION: (&str, &str) = (
    "geometry_msgs/Quaternion",
    "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
);
const POSE: (&str, &str) = (
    "geometry_msgs/Pose",
    "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
);
const TRANSFORM: (&str, &str) = (
    "geometry_msgs/Transform",
    "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
);
const TRANSFORM_STAMPED: (&str, &str) = (
    "geometry_msgs/TransformStamped",
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
);
const NAV_SAT_STATUS: (&str, &str) = (
    "sensor_msgs/NavSatStatus",
    "int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\nint8 STATUS_GBAS_FIX=2\nint8 status\nuint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\nuint16 SERVICE_GALILEO=8\nuint16 service\n",
);
const CHILD_TRACK: (&str, &str) = (
    "hetsim_msgs/ChildTrack",
    "# A child's position on the floor as the parent's tracker measured it, in the parent's body frame (x forward, y left).\nstring child\nfloat64 x\nfloat64 y\n",
);

/// The `ros2msg` definition of a schema name used in recordings.
pub fn definition(schema: &str) -> Option<String> {
    let header_deps = [HEADER, TIME];
    Some(match schema {
        "sensor_msgs/msg/Image" => with_deps(
            "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
            &header_deps,
        ),
        "sensor_msgs/msg/NavSatFix" => with_deps(
            "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\nuint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\nstd_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\nfloat64 altitude\nfloat64[9] position_covariance\nuint8 position_covariance_type\n",
            &[HEADER, TIME, NAV_SAT_STATUS],
        ),
        "sensor_msgs/msg/LaserScan" => with_deps(
            "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n",
            &header_deps,
        ),
        "sensor_msgs/msg/Imu" => with_deps(
            "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\ngeometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
            &[HEADER, TIME, QUATERNION, VECTOR3],
        ),
        "geometry_msgs/msg/PoseStamped" => with_deps(
            "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
            &[HEADER, TIME, POSE, POINT, QUATERNION],
        ),
        "tf2_msgs/msg/TFMessage" => with_deps(
            "geometry_msgs/TransformStamped[] transforms\n",
            &[TRANSFORM_STAMPED, HEADER, TIME, TRANSFORM, VECTOR3, QUATERNION],
        ),
        "hetsim_msgs/msg/Command" => with_deps(
            "# A robot's actuator command; kind is wheels, helicopter or stop, and only its fields are set.\nstd_msgs/Header header\nstring kind\nfloat64 left_mps\nfloat64 right_mps\nfloat64 roll_rad\nfloat64 pitch_rad\nfloat64 yaw_rate_radps\nfloat64 climb_rate_mps\n",
            &header_deps,
        ),
        "hetsim_msgs/msg/Compass" => with_deps(
            "# Heading, radians counter-clockwise from east.\nstd_msgs/Header header\nfloat64 heading_rad\n",
            &header_deps,
        ),
        "hetsim_msgs/msg/WheelOdometry" => with_deps(
            "# Distance each wheel rolled since the last message, metres.\nstd_msgs/Header header\nfloat64 left_m\nfloat64 right_m\n",
            &header_deps,
        ),
        "hetsim_msgs/msg/ChildTracks" => with_deps(
            "std_msgs/Header header\nhetsim_msgs/ChildTrack[] tracks\n",
            &[HEADER, TIME, CHILD_TRACK],
        ),
        "hetsim_msgs/msg/Rendezvous" => with_deps(
            "# The other robot's pose in this robot's body frame, with the noise it was drawn with.\nstd_msgs/Header header\nstring other\ngeometry_msgs/Pose pose\nfloat64 sigma_m\nfloat64 sigma_rad\n",
            &[HEADER, TIME, POSE, POINT, QUATERNION],
        ),
        "hetsim_msgs/msg/ImageMatch" => with_deps(
            "# Oracle (ablations only): the pose relative to another robot's key frame at other_stamp.\nstd_msgs/Header header\nstring other\nbuiltin_interfaces/Time other_stamp\ngeometry_msgs/Pose pose\nfloat64 sigma_m\nfloat64 sigma_rad\n",
            &[HEADER, TIME, POSE, POINT, QUATERNION],
        ),
        "hetsim_msgs/msg/Comms" => with_deps(
            "# A radio delivery to this robot: sender, topic, when it was sent, its size and its bytes.\nstd_msgs/Header header\nstring from\nstring to\nstring topic\nbuiltin_interfaces/Time sent\nuint32 bytes\nuint8[] payload\n",
            &header_deps,
        ),
        "hetsim_msgs/msg/GpsLocal" => with_deps(
            "# A GPS fix in the local world frame (east, north, up), metres, exactly as the robot received it; the NavSatFix beside it carries the same fix in WGS-84.\nstd_msgs/Header header\ngeometry_msgs/Point position\nfloat64 sigma_m\n",
            &[HEADER, TIME, POINT],
        ),
        _ => return None,
    })
}

/// `builtin_interfaces/Time`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
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
}

/// `std_msgs/Header`.
#[derive(Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `geometry_msgs/Vector3` and `Point`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

/// `geometry_msgs/Pose` (and `Transform`: the same layout).
#[derive(Clone, Copy, Serialize, Deserialize)]
pub struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

impl Pose {
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
}

/// `sensor_msgs/msg/Image`.
#[derive(Serialize)]
pub struct Image<'a> {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: &'a str,
    pub is_bigendian: u8,
    pub step: u32,
    #[serde(with = "serde_bytes")]
    pub data: &'a [u8],
}

/// `sensor_msgs/msg/NavSatStatus`.
#[derive(Serialize)]
pub struct NavSatStatus {
    pub status: i8,
    pub service: u16,
}

/// `sensor_msgs/msg/NavSatFix`.
#[derive(Serialize)]
pub struct NavSatFix {
    pub header: Header,
    pub status: NavSatStatus,
    pub latitude: f64,
    pub longitude: f64,
    pub altitude: f64,
    pub position_covariance: [f64; 9],
    pub position_covariance_type: u8,
}

/// `sensor_msgs/msg/LaserScan`.
#[derive(Serialize)]
pub struct LaserScan<'a> {
    pub header: Header,
    pub angle_min: f32,
    pub angle_max: f32,
    pub angle_increment: f32,
    pub time_increment: f32,
    pub scan_time: f32,
    pub range_min: f32,
    pub range_max: f32,
    pub ranges: &'a [f32],
    pub intensities: &'a [f32],
}

/// `sensor_msgs/msg/Imu`.
#[derive(Serialize, Deserialize)]
pub struct Imu {
    pub header: Header,
    pub orientation: Quaternion,
    pub orientation_covariance: [f64; 9],
    pub angular_velocity: Vector3,
    pub angular_velocity_covariance: [f64; 9],
    pub linear_acceleration: Vector3,
    pub linear_acceleration_covariance: [f64; 9],
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Serialize, Deserialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}

/// `geometry_msgs/msg/TransformStamped` (a `Transform` has `Pose`'s layout: translation,
/// rotation).
#[derive(Serialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Pose,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Serialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}

/// `hetsim_msgs/msg/Command`.
#[derive(Serialize)]
pub struct Command<'a> {
    pub header: Header,
    pub kind: &'a str,
    pub left_mps: f64,
    pub right_mps: f64,
    pub roll_rad: f64,
    pub pitch_rad: f64,
    pub yaw_rate_radps: f64,
    pub climb_rate_mps: f64,
}

/// `hetsim_msgs/msg/Compass`.
#[derive(Serialize, Deserialize)]
pub struct Compass {
    pub header: Header,
    pub heading_rad: f64,
}

/// `hetsim_msgs/msg/WheelOdometry`.
#[derive(Serialize, Deserialize)]
pub struct WheelOdometry {
    pub header: Header,
    pub left_m: f64,
    pub right_m: f64,
}

/// `hetsim_msgs/ChildTrack`.
#[derive(Serialize)]
pub struct ChildTrack<'a> {
    pub child: &'a str,
    pub x: f64,
    pub y: f64,
}

/// `hetsim_msgs/msg/ChildTracks`.
#[derive(Serialize)]
pub struct ChildTracks<'a> {
    pub header: Header,
    pub tracks: Vec<ChildTrack<'a>>,
}

/// `hetsim_msgs/msg/Rendezvous`.
#[derive(Serialize)]
pub struct Rendezvous<'a> {
    pub header: Header,
    pub other: &'a str,
    pub pose: Pose,
    pub sigma_m: f64,
    pub sigma_rad: f64,
}

/// `hetsim_msgs/msg/ImageMatch`.
#[derive(Serialize)]
pub struct ImageMatch<'a> {
    pub header: Header,
    pub other: &'a str,
    pub other_stamp: Time,
    pub pose: Pose,
    pub sigma_m: f64,
    pub sigma_rad: f64,
}

/// `hetsim_msgs/msg/Comms`.
#[derive(Serialize)]
pub struct Comms<'a> {
    pub header: Header,
    pub from: &'a str,
    pub to: &'a str,
    pub topic: &'a str,
    pub sent: Time,
    pub bytes: u32,
    #[serde(with = "serde_bytes")]
    pub payload: &'a [u8],
}

/// `hetsim_msgs/msg/GpsLocal`.
#[derive(Serialize, Deserialize)]
pub struct GpsLocal {
    pub header: Header,
    pub position: Vector3,
    pub sigma_m: f64,
}

/// The channel's `offered_qos_profiles` metadata, in rosbag2's YAML: reliable and volatile,
/// but transient-local (latched) for `/tf_static`; history, deadline, lifespan and lease left
/// at rosbag2's "unknown"/infinite values.
pub fn qos_profiles(topic: &str) -> String {
    let durability = if topic == "/tf_static" { 1 } else { 2 };
    let infinite = "\n    sec: 9223372036\n    nsec: 854775807";
    format!(
        "- history: 3\n  depth: 0\n  reliability: 1\n  durability: {durability}\n  deadline:{infinite}\n  lifespan:{infinite}\n  liveliness: 1\n  liveliness_lease_duration:{infinite}\n  avoid_ros_namespace_conventions: false"
    )
}

/// CDR (little endian, with its encapsulation header) of a message.
pub fn encode<T: Serialize>(message: &T) -> Vec<u8> {
    // Serializing plain structs into memory fails only on a type CDR cannot hold (an
    // Option, an unsized sequence): a defect of the structs above, not an input.
    cdr::serialize::<_, _, cdr::CdrLe>(message, cdr::Infinite)
        .unwrap_or_else(|e| panic!("CDR encoding of a recorded message: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_after_the_encapsulation_header() {
        // Header: sec (4) nanosec (4) frame_id len (4) "ab\0" (3); then a float64 aligned to 8
        // counting from after the 4-byte encapsulation header: 15 -> 16.
        let bytes = encode(&Compass {
            header: Header {
                stamp: Time::of(1_500_000_000),
                frame_id: "ab".into(),
            },
            heading_rad: 1.0,
        });
        assert_eq!(&bytes[..4], &[0, 1, 0, 0], "CDR_LE");
        assert_eq!(&bytes[4..8], &1i32.to_le_bytes());
        assert_eq!(&bytes[8..12], &500_000_000u32.to_le_bytes());
        assert_eq!(&bytes[12..16], &3u32.to_le_bytes());
        assert_eq!(&bytes[16..19], b"ab\0");
        assert_eq!(&bytes[20..28], &1.0f64.to_le_bytes());
        assert_eq!(bytes.len(), 28);
    }

    #[test]
    fn every_definition_names_only_defined_types() {
        for schema in [
            "sensor_msgs/msg/Image",
            "sensor_msgs/msg/NavSatFix",
            "sensor_msgs/msg/LaserScan",
            "sensor_msgs/msg/Imu",
            "geometry_msgs/msg/PoseStamped",
            "tf2_msgs/msg/TFMessage",
            "hetsim_msgs/msg/Command",
            "hetsim_msgs/msg/Compass",
            "hetsim_msgs/msg/WheelOdometry",
            "hetsim_msgs/msg/ChildTracks",
            "hetsim_msgs/msg/Rendezvous",
            "hetsim_msgs/msg/ImageMatch",
            "hetsim_msgs/msg/Comms",
            "hetsim_msgs/msg/GpsLocal",
        ] {
            let text = definition(schema).unwrap();
            let defined: Vec<&str> = text
                .lines()
                .filter_map(|l| l.strip_prefix("MSG: "))
                .collect();
            for line in text
                .lines()
                .filter(|l| !l.starts_with('#') && !l.starts_with("MSG") && !l.starts_with('='))
            {
                let ty = line.split_whitespace().next().unwrap_or("");
                let base = ty.split('[').next().unwrap();
                if base.contains('/') {
                    assert!(
                        defined.contains(&base),
                        "{schema}: {base} is used but not defined"
                    );
                }
            }
        }
    }
}
