//! Messages the simulator delivers to a robot stack.

use crate::Pose;
use serde::{Deserialize, Serialize};

/// A pose at a sim time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Sim time of the measurement, nanoseconds.
    pub stamp_ns: u64,
    /// `world_from_body`.
    pub pose: Pose,
}

/// A 2D occupancy grid in the world's xy plane, row-major from the south-west corner.
///
/// Cell `(col, row)` covers `[origin_x + col * cell_m, origin_x + (col+1) * cell_m) x
/// [origin_y + row * cell_m, origin_y + (row+1) * cell_m)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OccupancyGrid {
    /// World x of the grid's west edge, metres.
    pub origin_x: f64,
    /// World y of the grid's south edge, metres.
    pub origin_y: f64,
    /// Cell size, metres.
    pub cell_m: f64,
    /// Number of columns (x).
    pub cols: usize,
    /// Number of rows (y).
    pub rows: usize,
    /// `true` where the cell is occupied; index `row * cols + col`.
    pub occupied: Vec<bool>,
}

impl OccupancyGrid {
    /// Whether `(col, row)` lies in the grid and is free.
    pub fn is_free(&self, col: i64, row: i64) -> bool {
        col >= 0
            && row >= 0
            && (col as usize) < self.cols
            && (row as usize) < self.rows
            && !self.occupied[row as usize * self.cols + col as usize]
    }

    /// The cell that contains a world point, if inside the grid.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let col = ((x - self.origin_x) / self.cell_m).floor();
        let row = ((y - self.origin_y) / self.cell_m).floor();
        (col >= 0.0 && row >= 0.0 && (col as usize) < self.cols && (row as usize) < self.rows)
            .then_some((col as usize, row as usize))
    }

    /// World coordinates of a cell's centre.
    pub fn centre_of(&self, col: usize, row: usize) -> [f64; 2] {
        [
            self.origin_x + (col as f64 + 0.5) * self.cell_m,
            self.origin_y + (row as f64 + 0.5) * self.cell_m,
        ]
    }

    /// Number of free cells.
    pub fn free_count(&self) -> usize {
        self.occupied.iter().filter(|o| !**o).count()
    }
}

/// What a robot is asked to do, given once at the start of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Mission {
    /// Visit these world points in order (z ignored by ground robots).
    Waypoints(Vec<[f64; 3]>),
    /// Visit these grid cells in order, moving only up/down/left/right between free cells.
    GridGoals {
        /// The map the robot may use.
        grid: OccupancyGrid,
        /// Cells `(col, row)` to visit in order.
        goals: Vec<(usize, usize)>,
    },
    /// Stay where it is.
    Idle,
    /// Lead a cooperative coverage mapping mission (seed 002): plan on the map, drive the
    /// tour, track and teleoperate the children, store their images.
    CoverageParent(CoverageMission),
    /// Be a child of a coverage mission: obey the parent's orders received by radio.
    Teleoperated {
        /// The parent robot's name.
        parent: String,
    },
}

/// What a coverage parent is given (seed 002, Sections III-IV): the range map the paper
/// assumes exists before the mission, the team, and the mapping parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoverageMission {
    /// The occupancy map at the grid resolution d.
    pub grid: OccupancyGrid,
    /// The children, by name, and their start cells `(col, row)`.
    pub children: Vec<(String, (usize, usize))>,
    /// Line-of-sight radius r_los, metres.
    pub r_los_m: f64,
    /// Direction of mapping: "east", "north", "west" or "south".
    pub direction: String,
    /// The children's camera opening angle, degrees.
    pub child_fov_deg: f64,
    /// Extra angle on each side of a child's view when keeping robots out of images, degrees.
    pub view_margin_deg: f64,
    /// Extra distance around a robot's footprint when keeping robots out of images, metres.
    #[serde(default)]
    pub view_margin_m: f64,
    /// Radius of the parent's footprint, metres.
    pub parent_radius_m: f64,
    /// Radius of a child's footprint, metres.
    pub child_radius_m: f64,
    /// Candidate distance factor f (Eq. 6).
    pub f_factor: f64,
    /// Children's driving speed, metres per second (0.15 in the seed).
    pub child_speed_mps: f64,
    /// The parent's start pose `[x, y, heading]` (metres, radians) as the operator gives it:
    /// the prior of its laser localization, as one sets a ROS `amcl` initial pose.
    #[serde(default)]
    pub parent_start: [f64; 3],
    /// After mapping, the first child is sent the database by radio and drives this many
    /// grid moves on its own, localizing from its images (0: no localization run).
    #[serde(default)]
    pub localize_steps: usize,
}

/// A compass heading.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompassReading {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// Heading of the body x axis, counter-clockwise from east, radians in (-pi, pi].
    pub heading_rad: f64,
}

/// A GPS position fix in the local world frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GpsFix {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// Antenna position (east, north, up), metres.
    pub position_m: [f64; 3],
    /// Standard deviation of each coordinate, metres.
    pub sigma_m: f64,
}

/// Wheel encoder distances travelled since the previous reading.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WheelOdometry {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// Left wheel surface distance, metres.
    pub left_m: f64,
    /// Right wheel surface distance, metres.
    pub right_m: f64,
}

/// An inertial measurement in the sensor frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImuSample {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// Angular rate, radians per second.
    pub angular_rate_radps: [f64; 3],
    /// Specific force (acceleration minus gravity), metres per second squared.
    pub accel_mps2: [f64; 3],
}

/// A planar laser scan in the sensor frame (angles counter-clockwise from the sensor's x).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// Angle of the first beam, radians.
    pub angle_min_rad: f64,
    /// Angle between beams, radians.
    pub angle_increment_rad: f64,
    /// Longest range, metres; a beam with no return reads `f32::INFINITY`.
    pub range_max_m: f64,
    /// Ranges, metres.
    pub ranges_m: Vec<f32>,
}

/// One tracked child.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// The child robot's name.
    pub child: String,
    /// Its measured position on the floor in the parent's body frame (x forward, y left),
    /// metres: the tracker knows where the hat is relative to the camera, not in the world.
    pub position_m: [f64; 2],
}

/// The parent's tracker output: every child it sees.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChildTracks {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// Children seen, by name.
    pub tracks: Vec<Track>,
}

/// A noisy relative pose of another robot seen by this one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rendezvous {
    /// Sim time, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// The robot seen.
    pub other: String,
    /// `self_from_other`: the other robot's body pose in this robot's body frame.
    pub relative: Pose,
    /// Standard deviation of the relative position, metres (each axis).
    pub sigma_m: f64,
    /// Standard deviation of the relative attitude, radians (each axis).
    pub sigma_rad: f64,
}

/// The emulated image-to-image matching event of the seed (Section V): the relative pose
/// between this robot's current frame and a past key frame (a sub-map origin) of another
/// robot, recovered by matching the two frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ImageMatch {
    /// Sim time of this robot's frame, nanoseconds.
    pub stamp_ns: u64,
    /// Sensor name on the robot.
    pub sensor: String,
    /// The robot whose key frame matched.
    pub other: String,
    /// Stamp of the other robot's key frame, nanoseconds.
    pub other_stamp_ns: u64,
    /// `self_from_other`: the other robot's body pose at its key frame in this robot's body
    /// frame now.
    pub relative: Pose,
    /// Standard deviation of the relative position, metres (each axis).
    pub sigma_m: f64,
    /// Standard deviation of the relative attitude, radians (each axis).
    pub sigma_rad: f64,
}

/// A camera image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Sim time of exposure, nanoseconds.
    pub stamp_ns: u64,
    /// Camera name on the robot; a stereo bench's cameras are `<name>/left`, `<name>/right`.
    pub sensor: String,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// How the pixels are stored: RGB or grey, 8 bits per channel.
    pub encoding: PixelEncoding,
    /// The pixels, `width x height x channels` bytes, row-major from the top-left pixel.
    /// Encoded as bytes: the same postcard encoding as a sequence of `u8`, written in one copy
    /// rather than one serializer call per byte.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// The pixel format of an [`Image`], with its ROS name (`sensor_msgs/Image.encoding`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PixelEncoding {
    /// Red, green, blue; 8 bits each.
    #[default]
    Rgb8,
    /// Grey (luminance, ITU-R BT.601 weights of the rendered RGB, rounded); 8 bits.
    Mono8,
}

impl PixelEncoding {
    /// Bytes per pixel.
    pub fn channels(self) -> u32 {
        match self {
            PixelEncoding::Rgb8 => 3,
            PixelEncoding::Mono8 => 1,
        }
    }

    /// The ROS name (`rgb8`, `mono8`).
    pub fn ros_name(self) -> &'static str {
        match self {
            PixelEncoding::Rgb8 => "rgb8",
            PixelEncoding::Mono8 => "mono8",
        }
    }

    /// The encoding of a ROS name, if hetsim knows it.
    pub fn from_ros_name(name: &str) -> Option<Self> {
        match name {
            "rgb8" => Some(PixelEncoding::Rgb8),
            "mono8" => Some(PixelEncoding::Mono8),
            _ => None,
        }
    }

    /// The grey level of an RGB pixel (BT.601), rounded half away from zero: what a mono8
    /// camera delivers. Called once per pixel of every grey frame: `f32::round` is a libm
    /// call on baseline x86-64, so the rounding is done on the truncated integer instead
    /// (exact: `y` lies in [0, 256), where `y - trunc(y)` has no rounding error).
    #[inline]
    pub fn luminance(rgb: [u8; 3]) -> u8 {
        let y = 0.299 * rgb[0] as f32 + 0.587 * rgb[1] as f32 + 0.114 * rgb[2] as f32;
        let t = y as u32;
        let r = if y - t as f32 >= 0.5 { t + 1 } else { t };
        r.min(255) as u8
    }
}

impl Image {
    /// The RGB pixels (grey ones repeated on the three channels).
    pub fn to_rgb(&self) -> std::borrow::Cow<'_, [u8]> {
        match self.encoding {
            PixelEncoding::Rgb8 => std::borrow::Cow::Borrowed(&self.data),
            PixelEncoding::Mono8 => {
                std::borrow::Cow::Owned(self.data.iter().flat_map(|&g| [g, g, g]).collect())
            }
        }
    }
}

/// A message from another robot, delivered by the radio.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Delivered {
    /// The sending robot.
    pub from: String,
    /// What it is about (the sender's choice).
    pub topic: String,
    /// When it was sent, nanoseconds.
    pub sent_ns: u64,
    /// When it arrived, nanoseconds.
    pub stamp_ns: u64,
    /// The bytes sent.
    pub payload: Vec<u8>,
}

/// A message a stack asks the radio to send.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outgoing {
    /// The receiving robot's name.
    pub to: String,
    /// What it is about.
    pub topic: String,
    /// The bytes to send.
    pub payload: Vec<u8>,
}

/// A message delivered to a robot stack.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SensorMsg {
    /// **Oracle**: the robot's exact ground-truth pose, delivered only by an `oracle_pose`
    /// sensor its robot file declares and enables (the manifest lists them). For waypoint
    /// pilots and the seed's parent ("accurate localization"); estimators must not read it.
    TruthPose(PoseStamped),
    /// Compass.
    Compass(CompassReading),
    /// GPS.
    Gps(GpsFix),
    /// Wheel encoders.
    WheelOdometry(WheelOdometry),
    /// Inertial measurement unit.
    Imu(ImuSample),
    /// Laser scanner.
    LaserScan(LaserScan),
    /// Child tracker.
    ChildTracks(ChildTracks),
    /// Rendezvous sensor.
    Rendezvous(Rendezvous),
    /// Image-to-image matching against another robot's key frames.
    ImageMatch(ImageMatch),
    /// Radio.
    Comms(Delivered),
    /// Camera.
    Image(Image),
}

impl SensorMsg {
    /// Sim time of the message, nanoseconds.
    pub fn stamp_ns(&self) -> u64 {
        match self {
            SensorMsg::TruthPose(m) => m.stamp_ns,
            SensorMsg::Compass(m) => m.stamp_ns,
            SensorMsg::Gps(m) => m.stamp_ns,
            SensorMsg::WheelOdometry(m) => m.stamp_ns,
            SensorMsg::Imu(m) => m.stamp_ns,
            SensorMsg::LaserScan(m) => m.stamp_ns,
            SensorMsg::ChildTracks(m) => m.stamp_ns,
            SensorMsg::Rendezvous(m) => m.stamp_ns,
            SensorMsg::ImageMatch(m) => m.stamp_ns,
            SensorMsg::Comms(m) => m.stamp_ns,
            SensorMsg::Image(m) => m.stamp_ns,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_and_centres_agree() {
        let grid = OccupancyGrid {
            origin_x: -1.0,
            origin_y: 2.0,
            cell_m: 0.5,
            cols: 4,
            rows: 3,
            occupied: vec![false; 12],
        };
        for row in 0..3 {
            for col in 0..4 {
                let [x, y] = grid.centre_of(col, row);
                assert_eq!(grid.cell_of(x, y), Some((col, row)));
            }
        }
        assert_eq!(grid.cell_of(-1.1, 2.1), None);
        assert!(!grid.is_free(-1, 0));
        assert!(grid.is_free(3, 2));
        assert!(!grid.is_free(4, 2));
    }

    #[test]
    fn luminance_rounds_as_f32_round_for_every_rgb_triple() {
        for r in 0..=255u8 {
            for g in 0..=255u8 {
                for b in 0..=255u8 {
                    let y = 0.299 * r as f32 + 0.587 * g as f32 + 0.114 * b as f32;
                    let reference = y.round().clamp(0.0, 255.0) as u8;
                    assert_eq!(
                        PixelEncoding::luminance([r, g, b]),
                        reference,
                        "{r} {g} {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn images_encode_their_bytes_as_a_sequence_of_u8_would() {
        // The run digest hashes postcard encodings: `serde_bytes` must not change them.
        #[derive(Serialize)]
        struct Plain {
            stamp_ns: u64,
            sensor: String,
            width: u32,
            height: u32,
            encoding: PixelEncoding,
            data: Vec<u8>,
        }
        let data: Vec<u8> = (0..300u32).map(|i| (i * 7 % 256) as u8).collect();
        let image = Image {
            stamp_ns: 12,
            sensor: "cam".into(),
            width: 10,
            height: 10,
            encoding: PixelEncoding::Rgb8,
            data: data.clone(),
        };
        let plain = Plain {
            stamp_ns: 12,
            sensor: "cam".into(),
            width: 10,
            height: 10,
            encoding: PixelEncoding::Rgb8,
            data,
        };
        let encoded = postcard::to_stdvec(&image).unwrap();
        assert_eq!(encoded, postcard::to_stdvec(&plain).unwrap());
        assert_eq!(postcard::from_bytes::<Image>(&encoded).unwrap(), image);
    }
}
