//! Robot description files (`robots/models/*.toml`): bodies, drives, pilots and sensors.
//!
//! Parsing refuses unknown fields; [`RobotModel::validate`] then checks every value against
//! its allowed range. Sensors are described here for every later stage (cameras, compass,
//! GPS, laser, tracker); which of them the simulator models is the engine's business.

use serde::{Deserialize, Serialize};

mod camera;
mod validate;

pub use camera::{CalibrationError, CameraProfile, Exposure, Shutter, TRUNCATION_SIGMAS};

pub use hetsim_pilot::{PilotTable, SteeringKind};
pub use hetsim_slam::stack::SlamTable;

/// A robot description.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotModel {
    /// Must be [`crate::SCHEMA_VERSION`].
    pub schema_version: i64,
    /// The model's name; must equal the file's stem.
    pub name: String,
    /// One line for people.
    #[serde(default)]
    pub description: String,
    /// Shape, mass and drive.
    pub body: Body,
    /// Parameters of the robot's waypoint follower.
    pub pilot: PilotTable,
    /// The robot's sensors.
    #[serde(default)]
    pub sensors: Vec<Sensor>,
    /// Tuning of its SLAM software, where it runs one (absent fields: the seed's values).
    #[serde(default)]
    pub slam: SlamTable,
}

impl RobotModel {
    /// The SLAM software's parameters: the seed's for the robot's kind (the helicopter's, or a
    /// ground robot's) with the robot file's `[slam]` table written over them.
    pub fn slam_params(
        &self,
    ) -> Result<hetsim_slam::stack::SlamParams, hetsim_slam::stack::SlamTableError> {
        let seed = match self.body.drive {
            DriveKind::Helicopter => hetsim_slam::stack::SlamParams::aerial(),
            _ => hetsim_slam::stack::SlamParams::ground(),
        };
        self.slam.over(&seed)
    }
}

/// How a robot moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriveKind {
    /// Skid-steer (tracks or four fixed wheels): the rover.
    SkidSteer,
    /// Two-wheel differential drive: the parent and the c't-Bots.
    Differential,
    /// Helicopter with an attitude/climb-rate autopilot inner loop.
    Helicopter,
}

/// The hat's thickness, metres: its top is this far above the body's top (`height_m`).
pub const HAT_THICKNESS_M: f64 = 0.024;

/// The hat's length and width as fractions of the body's.
pub const HAT_SCALE: f64 = 0.9;

/// Shape, mass and drive limits.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Body {
    /// Which drive model moves the body.
    pub drive: DriveKind,
    /// Extent along the body x axis, metres.
    pub length_m: f64,
    /// Extent along the body y axis, metres.
    pub width_m: f64,
    /// Extent along the body z axis, metres.
    pub height_m: f64,
    /// Mass, kilograms.
    pub mass_kg: f64,
    /// Top speed, metres per second.
    pub max_speed_mps: f64,
    /// Top yaw rate, degrees per second.
    pub max_yaw_rate_deg_s: f64,
    /// Wheel parameters (skid-steer and differential drives).
    #[serde(default)]
    pub wheels: Option<Wheels>,
    /// Rotor/autopilot parameters (helicopter).
    #[serde(default)]
    pub helicopter: Option<Helicopter>,
    /// Wears the orange hat that a parent's child tracker follows (seed 002's c't-Bots): the
    /// renderer draws it on top of the body, [`HAT_THICKNESS_M`] thick and [`HAT_SCALE`] of its
    /// footprint.
    #[serde(default)]
    pub hat: bool,
}

/// Wheel-ground parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wheels {
    /// Distance between left and right contact lines, metres.
    pub track_m: f64,
    /// First-order time constant of the wheel speed response, seconds.
    pub motor_time_constant_s: f64,
    /// Mean fraction of wheel surface speed lost to longitudinal slip, `[0, 0.5]`.
    pub longitudinal_slip: f64,
    /// Skid-steer instantaneous-centre-of-rotation expansion: the effective track is
    /// `track_m * icr_expansion` (1 for an ideal differential drive), `[1, 3]`.
    pub icr_expansion: f64,
    /// Standard deviation of the random relative wheel speed error per wheel, `[0, 0.5]`.
    pub speed_noise: f64,
}

/// Helicopter autopilot inner-loop parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Helicopter {
    /// Largest roll or pitch, degrees, `(0, 45]`.
    pub max_tilt_deg: f64,
    /// Largest climb or sink rate, metres per second.
    pub max_climb_mps: f64,
    /// First-order time constant of the attitude response, seconds.
    pub attitude_time_constant_s: f64,
    /// First-order time constant of the climb-rate response, seconds.
    pub climb_time_constant_s: f64,
}

fn unit_gain() -> f64 {
    1.0
}

/// Where a sensor sits on the body.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mount {
    /// Position in the body frame, metres.
    pub xyz_m: [f64; 3],
    /// Roll, pitch, yaw of the sensor frame in the body frame, degrees.
    pub rpy_deg: [f64; 3],
}

/// A camera's geometry: its `intrinsics` table where given, else square pixels centred in the
/// image with the horizontal opening angle `hfov_deg` (60 degrees where neither is given).
pub fn camera_geometry(
    width: u32,
    height: u32,
    hfov_deg: Option<f64>,
    k: Option<&hetsim_msgs::Pinhole>,
) -> hetsim_msgs::CameraGeometry {
    match k {
        Some(k) => hetsim_msgs::CameraGeometry {
            width,
            height,
            k: *k,
        },
        None => hetsim_msgs::CameraGeometry::from_hfov(width, height, hfov_deg.unwrap_or(60.0)),
    }
}

/// A sensor on a robot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Sensor {
    /// A pinhole camera.
    Camera {
        /// Unique on the robot.
        name: String,
        /// Frames per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Image width, pixels.
        width_px: u32,
        /// Image height, pixels.
        height_px: u32,
        /// Horizontal opening angle, degrees (used when `intrinsics` is absent).
        #[serde(default)]
        hfov_deg: Option<f64>,
        /// Intrinsics (override `hfov_deg`).
        #[serde(default)]
        intrinsics: Option<hetsim_msgs::Pinhole>,
        /// Gaussian pixel noise, grey levels (0-255).
        #[serde(default)]
        pixel_noise_sigma: f64,
        /// Radial distortion coefficients `[k1, k2]`.
        #[serde(default)]
        distortion: Option<[f64; 2]>,
        /// Exposure gain applied to the rendered intensities.
        #[serde(default = "unit_gain")]
        gain: f64,
        /// What the camera delivers: `"rgb8"` (the default) or `"mono8"` (grey).
        #[serde(default)]
        encoding: hetsim_msgs::PixelEncoding,
        /// How far the true calibration may lie from the one above (none by default).
        #[serde(default)]
        calibration_error: CalibrationError,
        /// Exposure time, shutter and vignetting (an instant by default).
        #[serde(default)]
        exposure: Exposure,
    },
    /// A rectified stereo bench: left camera at `mount`, right camera `baseline_m` to its right.
    StereoCamera {
        /// Unique on the robot.
        name: String,
        /// Frame pairs per second.
        rate_hz: f64,
        /// Mounting pose of the left camera.
        mount: Mount,
        /// Image width, pixels.
        width_px: u32,
        /// Image height, pixels.
        height_px: u32,
        /// Horizontal opening angle, degrees (used when `intrinsics` is absent).
        #[serde(default)]
        hfov_deg: Option<f64>,
        /// Intrinsics (override `hfov_deg`).
        #[serde(default)]
        intrinsics: Option<hetsim_msgs::Pinhole>,
        /// Distance between the optical centres, metres.
        baseline_m: f64,
        /// Gaussian pixel noise, grey levels (0-255).
        #[serde(default)]
        pixel_noise_sigma: f64,
        /// Radial distortion coefficients `[k1, k2]` (both cameras).
        #[serde(default)]
        distortion: Option<[f64; 2]>,
        /// Exposure gain applied to the rendered intensities.
        #[serde(default = "unit_gain")]
        gain: f64,
        /// What the cameras deliver: `"rgb8"` (the default) or `"mono8"` (grey).
        #[serde(default)]
        encoding: hetsim_msgs::PixelEncoding,
        /// How far the true calibration of both cameras and of the pair may lie from the one
        /// above (none by default).
        #[serde(default)]
        calibration_error: CalibrationError,
        /// Exposure time, shutter and vignetting of both cameras (an instant by default).
        #[serde(default)]
        exposure: Exposure,
    },
    /// An omnidirectional camera (the parent's tracker camera).
    OmniCamera {
        /// Unique on the robot.
        name: String,
        /// Frames per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Image width, pixels.
        width_px: u32,
        /// Image height, pixels.
        height_px: u32,
        /// Elevation range seen, degrees below/above the horizon: `[min, max]`.
        elevation_deg: [f64; 2],
    },
    /// A magnetic compass.
    Compass {
        /// Unique on the robot.
        name: String,
        /// Readings per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Standard deviation of the heading error, degrees.
        sigma_deg: f64,
        /// Constant heading bias, degrees.
        #[serde(default)]
        bias_deg: f64,
        /// Heading-dependent distortion (uncompensated hard iron): adds
        /// `distortion_deg * sin(heading)`, degrees.
        #[serde(default)]
        distortion_deg: f64,
    },
    /// A GPS receiver.
    Gps {
        /// Unique on the robot.
        name: String,
        /// Fixes per second when available.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Standard deviation of each position coordinate, metres.
        sigma_m: f64,
        /// Fix only at these sim times, seconds, instead of at `rate_hz` (the seed's
        /// occasional fixes). Each is delivered at the first tick at or after it.
        #[serde(default)]
        schedule_s: Vec<f64>,
        /// Intervals `[start, end]`, seconds, without any fix.
        #[serde(default)]
        outages_s: Vec<[f64; 2]>,
    },
    /// Wheel encoders.
    WheelOdometry {
        /// Unique on the robot.
        name: String,
        /// Readings per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Standard deviation of the constant per-wheel scale error (wheel radius error).
        scale_sigma: f64,
        /// Standard deviation of the distance noise per metre travelled, metres.
        noise_per_m: f64,
    },
    /// Inertial measurement unit.
    Imu {
        /// Unique on the robot.
        name: String,
        /// Samples per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Angular-rate white noise, radians per second.
        gyro_sigma_radps: f64,
        /// Constant gyro bias drawn once per run with this standard deviation, rad/s.
        gyro_bias_sigma_radps: f64,
        /// Acceleration white noise, metres per second squared.
        accel_sigma_mps2: f64,
        /// Constant accelerometer bias drawn once per run with this standard deviation.
        accel_bias_sigma_mps2: f64,
    },
    /// Detects other robots in view and measures their relative pose.
    Rendezvous {
        /// Unique on the robot.
        name: String,
        /// Measurements per second.
        rate_hz: f64,
        /// Mounting pose (the sensor looks along its x axis).
        mount: Mount,
        /// Largest detection distance, metres.
        range_m: f64,
        /// Full opening angle of the detection cone, degrees.
        fov_deg: f64,
        /// Relative position noise, metres.
        sigma_m: f64,
        /// Relative yaw noise, degrees.
        sigma_deg: f64,
    },
    /// Emulates the seed's image-to-image matching (Section V): when this robot's frame
    /// overlaps a key frame of another robot (its body within `range_m` horizontally of the
    /// key frame's position, the key frame at least `min_age_s` old), it measures the relative
    /// pose between them once per key frame.
    ImageMatch {
        /// Unique on the robot.
        name: String,
        /// Attempts per second.
        rate_hz: f64,
        /// Mounting pose (unused by the emulation; kept for the frame tree).
        mount: Mount,
        /// Largest horizontal distance to the key frame's position, metres.
        range_m: f64,
        /// Youngest key frame considered, seconds.
        min_age_s: f64,
        /// Relative position noise, metres (each axis).
        sigma_m: f64,
        /// Relative attitude noise, degrees (each axis).
        sigma_deg: f64,
    },
    /// **Oracle**: the robot's exact ground-truth pose (`world_from_body`), delivered at
    /// `rate_hz` as `SensorMsg::TruthPose` on `<robot>/<name>`. Only robot software that is not
    /// an estimator may rely on it (a waypoint pilot; the seed's parent, which "has an
    /// accurate localization"); the manifest lists every oracle of a run. A robot without an
    /// enabled oracle never receives its true pose.
    OraclePose {
        /// Unique on the robot.
        name: String,
        /// Poses per second.
        rate_hz: f64,
        /// Mounting pose (the pose given is the body's; kept for the frame tree).
        mount: Mount,
        /// Whether the robot receives it; a scenario may switch it by override (`"sensors.<name>.enabled"`).
        enabled: bool,
    },
    /// A planar laser scanner.
    Laser {
        /// Unique on the robot.
        name: String,
        /// Scans per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Field of view, degrees, `(0, 360]`.
        fov_deg: f64,
        /// Angle between beams, degrees.
        resolution_deg: f64,
        /// Longest range, metres.
        max_range_m: f64,
        /// Standard deviation of range noise, metres.
        range_sigma_m: f64,
    },
    /// The parent's tracker of the children's orange hats.
    ChildTracker {
        /// Unique on the robot.
        name: String,
        /// Measurements per second.
        rate_hz: f64,
        /// Mounting pose.
        mount: Mount,
        /// Largest tracking distance, metres (r_los = 2.0 m in the seed).
        range_m: f64,
        /// Mean position error, metres (0.04 in the seed).
        error_mean_m: f64,
        /// Standard deviation of the position error, metres (0.02 in the seed).
        error_std_m: f64,
    },
}

impl RobotModel {
    /// Whether it carries a laser scanner: in a coverage team, the parent, which maps with it
    /// (seed 002). Roles come from what a robot file declares, never from a model's name.
    pub fn has_laser(&self) -> bool {
        self.sensors
            .iter()
            .any(|s| matches!(s, Sensor::Laser { .. }))
    }

    /// Whether it wears a hat for a parent's tracker: in a coverage team, a child.
    pub fn is_tracked_child(&self) -> bool {
        self.body.hat
    }
}

impl Sensor {
    /// Whether this is an enabled oracle: a sensor that gives the robot ground truth.
    pub fn is_enabled_oracle(&self) -> bool {
        matches!(self, Sensor::OraclePose { enabled: true, .. })
    }

    /// The sensor's kind as written in robot files (`camera`, `compass`, ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Sensor::Camera { .. } => "camera",
            Sensor::StereoCamera { .. } => "stereo_camera",
            Sensor::OmniCamera { .. } => "omni_camera",
            Sensor::Compass { .. } => "compass",
            Sensor::Gps { .. } => "gps",
            Sensor::Laser { .. } => "laser",
            Sensor::ChildTracker { .. } => "child_tracker",
            Sensor::WheelOdometry { .. } => "wheel_odometry",
            Sensor::Imu { .. } => "imu",
            Sensor::Rendezvous { .. } => "rendezvous",
            Sensor::ImageMatch { .. } => "image_match",
            Sensor::OraclePose { .. } => "oracle_pose",
        }
    }

    /// A pinhole camera's or a stereo bench's calibration error and exposure.
    pub fn imperfections(&self) -> Option<(&CalibrationError, &Exposure)> {
        match self {
            Sensor::Camera {
                calibration_error,
                exposure,
                ..
            }
            | Sensor::StereoCamera {
                calibration_error,
                exposure,
                ..
            } => Some((calibration_error, exposure)),
            _ => None,
        }
    }

    /// A pinhole camera's or a stereo bench's given geometry: image size, intrinsics and
    /// distortion (zero where the file gives none).
    pub fn given_geometry(&self) -> Option<(u32, u32, hetsim_msgs::Pinhole, [f64; 2])> {
        match self {
            Sensor::Camera {
                width_px,
                height_px,
                hfov_deg,
                intrinsics,
                distortion,
                ..
            }
            | Sensor::StereoCamera {
                width_px,
                height_px,
                hfov_deg,
                intrinsics,
                distortion,
                ..
            } => Some((
                *width_px,
                *height_px,
                camera_geometry(*width_px, *height_px, *hfov_deg, intrinsics.as_ref()).k,
                distortion.unwrap_or([0.0, 0.0]),
            )),
            _ => None,
        }
    }

    /// The sensor's name.
    pub fn name(&self) -> &str {
        match self {
            Sensor::Camera { name, .. }
            | Sensor::StereoCamera { name, .. }
            | Sensor::OmniCamera { name, .. }
            | Sensor::Compass { name, .. }
            | Sensor::Gps { name, .. }
            | Sensor::Laser { name, .. }
            | Sensor::ChildTracker { name, .. }
            | Sensor::WheelOdometry { name, .. }
            | Sensor::Imu { name, .. }
            | Sensor::Rendezvous { name, .. }
            | Sensor::ImageMatch { name, .. }
            | Sensor::OraclePose { name, .. } => name,
        }
    }

    /// The sensor's rate.
    pub fn rate_hz(&self) -> f64 {
        match self {
            Sensor::Camera { rate_hz, .. }
            | Sensor::StereoCamera { rate_hz, .. }
            | Sensor::OmniCamera { rate_hz, .. }
            | Sensor::Compass { rate_hz, .. }
            | Sensor::Gps { rate_hz, .. }
            | Sensor::Laser { rate_hz, .. }
            | Sensor::ChildTracker { rate_hz, .. }
            | Sensor::WheelOdometry { rate_hz, .. }
            | Sensor::Imu { rate_hz, .. }
            | Sensor::Rendezvous { rate_hz, .. }
            | Sensor::ImageMatch { rate_hz, .. }
            | Sensor::OraclePose { rate_hz, .. } => *rate_hz,
        }
    }

    /// The sensor's mounting pose.
    pub fn mount(&self) -> &Mount {
        match self {
            Sensor::Camera { mount, .. }
            | Sensor::StereoCamera { mount, .. }
            | Sensor::OmniCamera { mount, .. }
            | Sensor::Compass { mount, .. }
            | Sensor::Gps { mount, .. }
            | Sensor::Laser { mount, .. }
            | Sensor::ChildTracker { mount, .. }
            | Sensor::WheelOdometry { mount, .. }
            | Sensor::Imu { mount, .. }
            | Sensor::Rendezvous { mount, .. }
            | Sensor::ImageMatch { mount, .. }
            | Sensor::OraclePose { mount, .. } => mount,
        }
    }
}
