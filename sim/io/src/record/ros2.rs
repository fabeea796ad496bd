//! The ROS 2 side of a recording that is not a sensor's: truth (`PoseStamped`), `/tf` and
//! `/tf_static` (`tf2_msgs/msg/TFMessage`), commands and the radio (`hetsim_msgs/msg/*`,
//! defined here in `ros2msg` syntax), and each channel's QoS metadata. Each sensor kind's
//! messages are its module's in `hetsim_sensors` ([`hetsim_sensors::ros2`]), with the
//! common types re-exported here.

pub use hetsim_sensors::ros2::{cdr_bytes as encode, Header, Pose, Time};
use hetsim_sensors::ros2::{with_deps, HEADER, POINT, POSE, QUATERNION, TIME, VECTOR3};
use serde::{Deserialize, Serialize};

const TRANSFORM: (&str, &str) = (
    "geometry_msgs/Transform",
    "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
);
const TRANSFORM_STAMPED: (&str, &str) = (
    "geometry_msgs/TransformStamped",
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n",
);

/// Truth's schema.
pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
/// `/tf`'s and `/tf_static`'s schema.
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
/// Commands' schema.
pub const COMMAND: &str = "hetsim_msgs/msg/Command";
/// The radio's schema.
pub const COMMS: &str = "hetsim_msgs/msg/Comms";
/// A camera's calibration's schema (`<camera topic>/camera_info`).
pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";

const REGION_OF_INTEREST: (&str, &str) = (
    "sensor_msgs/RegionOfInterest",
    "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
);

/// The `ros2msg` definition of a schema name used in recordings.
pub fn definition(schema: &str) -> Option<String> {
    let header_deps = [HEADER, TIME];
    Some(match schema {
        POSE_STAMPED => with_deps(
            "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
            &[HEADER, TIME, POSE, POINT, QUATERNION],
        ),
        TF_MESSAGE => with_deps(
            "geometry_msgs/TransformStamped[] transforms\n",
            &[TRANSFORM_STAMPED, HEADER, TIME, TRANSFORM, VECTOR3, QUATERNION],
        ),
        COMMAND => with_deps(
            "# A robot's actuator command; kind is wheels, helicopter or stop, and only its fields are set.\nstd_msgs/Header header\nstring kind\nfloat64 left_mps\nfloat64 right_mps\nfloat64 roll_rad\nfloat64 pitch_rad\nfloat64 yaw_rate_radps\nfloat64 climb_rate_mps\n",
            &header_deps,
        ),
        COMMS => with_deps(
            "# A radio delivery to this robot: sender, topic, when it was sent, its size and its bytes.\nstd_msgs/Header header\nstring from\nstring to\nstring topic\nbuiltin_interfaces/Time sent\nuint32 bytes\nuint8[] payload\n",
            &header_deps,
        ),
        CAMERA_INFO => with_deps(
            "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi\n",
            &[HEADER, TIME, REGION_OF_INTEREST],
        ),
        _ => return hetsim_sensors::ros2::definition(schema),
    })
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

/// `sensor_msgs/msg/RegionOfInterest` (the whole image: all zeros).
#[derive(Clone, Default, Serialize)]
pub struct RegionOfInterest {
    pub x_offset: u32,
    pub y_offset: u32,
    pub height: u32,
    pub width: u32,
    pub do_rectify: bool,
}

/// `sensor_msgs/msg/CameraInfo`: a camera's calibration as ROS carries it beside each image.
#[derive(Serialize)]
pub struct CameraInfo {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    pub d: Vec<f64>,
    pub k: [f64; 9],
    pub r: [f64; 9],
    pub p: [f64; 12],
    pub binning_x: u32,
    pub binning_y: u32,
    pub roi: RegionOfInterest,
}

impl CameraInfo {
    /// The `plumb_bob` calibration of a `width x height` pinhole `k` with radial distortion
    /// `[k1, k2]`; `tx_m`: for a bench's right camera, its position along the left camera's x
    /// (`-baseline`), which ROS puts in the projection matrix as `Tx = fx * tx_m`; 0 otherwise.
    pub fn of(
        width: u32,
        height: u32,
        k: &hetsim_msgs::Pinhole,
        [k1, k2]: [f64; 2],
        tx_m: f64,
    ) -> Self {
        let (fx, fy, cx, cy) = (k.alpha_u, k.alpha_v, k.u0, k.v0);
        Self {
            header: Header {
                stamp: Time::of(0),
                frame_id: String::new(),
            },
            height,
            width,
            distortion_model: "plumb_bob".into(),
            d: vec![k1, k2, 0.0, 0.0, 0.0],
            k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, fx * tx_m, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            binning_x: 0,
            binning_y: 0,
            roi: RegionOfInterest::default(),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_aligns_after_the_encapsulation_header() {
        // Header: sec (4) nanosec (4) frame_id len (4) "ab\0" (3); then a float64 aligned to 8
        // counting from after the 4-byte encapsulation header: 15 -> 16.
        #[derive(Serialize)]
        struct Compass {
            header: Header,
            heading_rad: f64,
        }
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
        let sensors = hetsim_sensors::ros2::KINDS
            .iter()
            .flat_map(|k| (k.definitions)())
            .map(|(schema, _)| schema);
        let schemas: Vec<&str> = [POSE_STAMPED, TF_MESSAGE, COMMAND, COMMS]
            .into_iter()
            .chain(sensors)
            .collect();
        for schema in schemas {
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
