//! Recording every message, command and ground-truth pose of a run to MCAP.
//!
//! The default encoding is ROS 2's (MCAP profile `ros2`, schemas `ros2msg`, messages CDR), so
//! `ros2 bag`, rosbags and Foxglove open a recording as it is:
//!
//! | topic | type |
//! |---|---|
//! | `/<robot>/truth` | `geometry_msgs/msg/PoseStamped` (frame `world`), every robot, at `truth_rate_hz` |
//! | `/tf` | `tf2_msgs/msg/TFMessage`: `world` -> `<robot>/base_link` with each truth sample |
//! | `/tf_static` | `base_link` -> each sensor's frame `<robot>/<sensor>` (cameras: the optical frame, z forward), once per sensor |
//! | `/<robot>/<camera>[/left\|right]` | `sensor_msgs/msg/Image`, `rgb8` or `mono8`, raw |
//! | `/<robot>/<camera>[/left\|right]/camera_info` | `sensor_msgs/msg/CameraInfo` with each image: the calibration the robot is **given** (its robot file's; the true one is only in the results' manifest) |
//! | `/<robot>/<gps>` | `sensor_msgs/msg/NavSatFix` (WGS-84 around [`GEO_ORIGIN`]) |
//! | `/<robot>/<laser>` | `sensor_msgs/msg/LaserScan` (no return: +inf, REP-117) |
//! | `/<robot>/<imu>` | `sensor_msgs/msg/Imu` (no orientation: `orientation_covariance[0] = -1`) |
//! | `/<robot>/cmd`, compass, wheel odometry, child tracks, rendezvous, image match, `/<robot>/radio` | `hetsim_msgs/msg/*`, defined in the file |
//!
//! Every channel carries `offered_qos_profiles` as rosbag2 writes it (reliable, volatile;
//! `/tf_static` transient-local, so a player latches it).
//!
//! `--record-encoding json` writes the earlier JSON encoding instead (Foxglove's JSON schemas,
//! images as base64 PNG; see `record/json.rs`).
//!
//! Frames follow ROS REP-103: `world` is x east, y north, z up; `<robot>/base_link` is
//! x forward, y left, z up. GPS fixes are converted from the local east-north-up frame to
//! WGS-84 latitude/longitude around [`GEO_ORIGIN`] with a local flat-earth approximation
//! (error under a millimetre over the village's 800 m).
//!
//! The file is written under a temporary name and renamed when finished.

use hetsim_engine::{RecordedOutcome, RunRecorder, SinkError};
use hetsim_msgs::{Command, Pose, SensorMsg};
use hetsim_scene::Scenario;
use std::collections::{BTreeMap, BTreeSet};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

mod json;
mod meta;
pub(crate) mod ros2;

pub use meta::{OUTCOME_METADATA, RUN_METADATA};

pub use hetsim_sensors::ros2::GEO_ORIGIN;

/// How a recording encodes its messages.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RecordEncoding {
    /// ROS 2: CDR messages with `ros2msg` schemas (the default).
    #[default]
    Ros2,
    /// JSON messages with JSON schemas (Foxglove's where it has one).
    Json,
}

/// Why a recording could not be written.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A file could not be created or moved.
    #[error(transparent)]
    Io(#[from] hetsim_core::files::FileError),
    /// The MCAP writer failed.
    #[error("{}: {source}", path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: mcap::McapError,
    },
    /// A message could not be written (a full disk): the first failure, not the writer's
    /// later refusals.
    #[error("{}: writing the recording failed after {} of messages, with {} free there now", path.display(), hetsim_core::files::human_bytes(*.written), .free.map_or("unknown".to_string(), hetsim_core::files::human_bytes))]
    Write {
        /// The file being written.
        path: PathBuf,
        /// Bytes of messages written before it failed.
        written: u64,
        /// Bytes free on its file system when the recording finished.
        free: Option<u64>,
        /// The first failure.
        source: mcap::McapError,
    },
}

/// What zstd leaves of the cameras' images in a ROS 2 recording: a village minute recorded
/// 1.42 GB of 1.89 GB of Mono8 images (four 1024x768 cameras at 10 Hz; pixel noise keeps
/// them from compressing further).
const IMAGE_COMPRESSION: f64 = 0.75;

/// About how many bytes a ROS 2 recording of `scenario` takes: its cameras' images (width x
/// height x bytes per pixel, at their rates, over the run) as zstd compresses them, which
/// is nearly all of it (the other messages are a few kB a second). An estimate from the
/// scenario, for refusing a recording that cannot fit before the run starts.
pub fn estimated_bytes(scenario: &Scenario) -> u64 {
    use hetsim_scene::Sensor;
    let per_second: f64 = scenario
        .robots
        .iter()
        .flat_map(|r| &r.model.sensors)
        .map(|s| match s {
            Sensor::Camera {
                width_px,
                height_px,
                rate_hz,
                encoding,
                ..
            } => f64::from(width_px * height_px * encoding.channels()) * rate_hz,
            Sensor::StereoCamera {
                width_px,
                height_px,
                rate_hz,
                encoding,
                ..
            } => 2.0 * f64::from(width_px * height_px * encoding.channels()) * rate_hz,
            // The panorama is delivered as RGB.
            Sensor::OmniCamera {
                width_px,
                height_px,
                rate_hz,
                ..
            } => f64::from(width_px * height_px * 3) * rate_hz,
            _ => 0.0,
        })
        .sum();
    (per_second * scenario.duration_secs * IMAGE_COMPRESSION) as u64
}

/// Writes an MCAP file during a run.
pub struct Recorder {
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    encoding: RecordEncoding,
    schemas: BTreeMap<String, u16>,
    channels: BTreeMap<String, u16>,
    counts: BTreeMap<String, u64>,
    /// Sensor frames whose `/tf_static` transform is written.
    static_frames: BTreeSet<String>,
    /// Each pinhole camera's given calibration by topic (`<robot>/<camera>[/<eye>]`): image
    /// size, pinhole, distortion and a bench's right camera's `-baseline`.
    camera_info: BTreeMap<String, (u32, u32, hetsim_msgs::Pinhole, [f64; 2], f64)>,
    sequence: u32,
    /// The delivery time of the sensor message being written, if it is one.
    received_ns: Option<u64>,
    /// Whether the run's SLAM stacks are open loop (written into `hetsim.run`).
    open_loop: bool,
    tmp: PathBuf,
    path: PathBuf,
    /// Bytes of messages written.
    written: u64,
    /// The first write that failed, until reported.
    failed: Option<mcap::McapError>,
    /// A write failed: nothing more is written.
    broken: bool,
}

impl Recorder {
    /// Starts a recording that will be at `path` once [`Recorder::finish`] succeeds.
    pub fn create(path: &Path, encoding: RecordEncoding) -> Result<Self, RecordError> {
        use hetsim_core::files::FileError;
        let tmp = Self::partial_path(path);
        if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(FileError::at(dir))?;
        }
        let file = std::fs::File::create(&tmp).map_err(FileError::at(&tmp))?;
        let profile = match encoding {
            RecordEncoding::Ros2 => "ros2",
            RecordEncoding::Json => "",
        };
        let writer = mcap::WriteOptions::new()
            .profile(profile)
            .library(concat!("hetsim ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(|source| RecordError::Mcap {
                path: tmp.clone(),
                source,
            })?;
        Ok(Self {
            writer,
            encoding,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            counts: BTreeMap::new(),
            static_frames: BTreeSet::new(),
            camera_info: BTreeMap::new(),
            sequence: 0,
            received_ns: None,
            open_loop: false,
            tmp,
            path: path.to_path_buf(),
            written: 0,
            failed: None,
            broken: false,
        })
    }

    /// The channel of a topic, registering it (and its schema) on first use.
    fn channel(&mut self, topic: &str, schema: &str) -> Result<u16, mcap::McapError> {
        if let Some(c) = self.channels.get(topic) {
            return Ok(*c);
        }
        let schema_id = match self.schemas.get(schema) {
            Some(s) => *s,
            None => {
                let (encoding, data) = match self.encoding {
                    RecordEncoding::Ros2 => (
                        "ros2msg",
                        ros2::definition(schema)
                            .unwrap_or_else(|| panic!("no ros2msg definition of {schema}"))
                            .into_bytes(),
                    ),
                    RecordEncoding::Json => (
                        "jsonschema",
                        serde_json::to_vec(&json::schema_for(schema)).expect("schemas serialize"),
                    ),
                };
                let id = self.writer.add_schema(schema, encoding, &data)?;
                self.schemas.insert(schema.to_string(), id);
                id
            }
        };
        let message_encoding = match self.encoding {
            RecordEncoding::Ros2 => "cdr",
            RecordEncoding::Json => "json",
        };
        let mut metadata = BTreeMap::new();
        if self.encoding == RecordEncoding::Ros2 {
            metadata.insert(
                "offered_qos_profiles".to_string(),
                ros2::qos_profiles(topic),
            );
        }
        let c = self
            .writer
            .add_channel(schema_id, topic, message_encoding, &metadata)?;
        self.channels.insert(topic.to_string(), c);
        Ok(c)
    }

    /// Writes a message stamped `stamp_ns` that its robot received at `self.received_ns`
    /// (MCAP's log time: replay feeds a message at the tick it was received).
    fn write_bytes(&mut self, topic: &str, schema: &str, stamp_ns: u64, data: &[u8]) {
        *self.counts.entry(topic.to_string()).or_default() += 1;
        if self.broken {
            return;
        }
        let channel = match self.channel(topic, schema) {
            Ok(c) => c,
            Err(e) => return self.fail(e),
        };
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: self.received_ns.unwrap_or(stamp_ns),
            publish_time: stamp_ns,
        };
        // A failing disk surfaces at finish(), which reports its first failure (the writer
        // refuses every later write with a message of its own); the run goes on meanwhile.
        match self.writer.write_to_known_channel(&header, data) {
            Ok(()) => self.written += data.len() as u64,
            Err(e) => self.fail(e),
        }
    }

    fn write_json(
        &mut self,
        topic: &str,
        schema: &str,
        stamp_ns: u64,
        message: &serde_json::Value,
    ) {
        let data = serde_json::to_vec(message).expect("messages serialize");
        self.write_bytes(topic, schema, stamp_ns, &data);
    }

    fn write_cdr<T: serde::Serialize>(
        &mut self,
        topic: &str,
        schema: &str,
        stamp_ns: u64,
        message: &T,
    ) {
        let data = ros2::encode(message);
        self.write_bytes(topic, schema, stamp_ns, &data);
    }

    /// Ground truth of a robot: its pose and the `world` -> `<robot>/base_link` transform.
    pub fn truth(&mut self, robot: &str, stamp_ns: u64, pose: &Pose) {
        if self.encoding == RecordEncoding::Json {
            return self.json_truth(robot, stamp_ns, pose);
        }
        let header = |frame: &str| ros2::Header {
            stamp: ros2::Time::of(stamp_ns),
            frame_id: frame.to_string(),
        };
        self.write_cdr(
            &format!("/{robot}/truth"),
            ros2::POSE_STAMPED,
            stamp_ns,
            &ros2::PoseStamped {
                header: header("world"),
                pose: ros2::Pose::of(pose),
            },
        );
        self.write_cdr(
            "/tf",
            ros2::TF_MESSAGE,
            stamp_ns,
            &ros2::TfMessage {
                transforms: vec![ros2::TransformStamped {
                    header: header("world"),
                    child_frame_id: format!("{robot}/base_link"),
                    transform: ros2::Pose::of(pose),
                }],
            },
        );
    }

    /// A robot's actuator command.
    pub fn command(&mut self, robot: &str, stamp_ns: u64, cmd: &Command) {
        if self.encoding == RecordEncoding::Json {
            return self.json_command(robot, stamp_ns, cmd);
        }
        let mut m = ros2::Command {
            header: ros2::Header {
                stamp: ros2::Time::of(stamp_ns),
                frame_id: format!("{robot}/base_link"),
            },
            kind: "stop",
            left_mps: 0.0,
            right_mps: 0.0,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rate_radps: 0.0,
            climb_rate_mps: 0.0,
        };
        match *cmd {
            Command::Wheels {
                left_mps,
                right_mps,
            } => (m.kind, m.left_mps, m.right_mps) = ("wheels", left_mps, right_mps),
            Command::Helicopter {
                roll_rad,
                pitch_rad,
                yaw_rate_radps,
                climb_rate_mps,
            } => {
                m.kind = "helicopter";
                (m.roll_rad, m.pitch_rad) = (roll_rad, pitch_rad);
                (m.yaw_rate_radps, m.climb_rate_mps) = (yaw_rate_radps, climb_rate_mps);
            }
            Command::Stop => {}
        }
        self.write_cdr(&format!("/{robot}/cmd"), ros2::COMMAND, stamp_ns, &m);
    }

    /// The frame of a robot's sensor, with its `/tf_static` transform written the first time.
    fn sensor_frame(
        &mut self,
        robot: &str,
        sensor: &str,
        body_from_sensor: Option<&Pose>,
        stamp_ns: u64,
    ) -> String {
        let Some(mount) = body_from_sensor else {
            return format!("{robot}/base_link");
        };
        let frame = format!("{robot}/{}", sensor.replace('/', "_"));
        if self.static_frames.insert(frame.clone()) {
            self.write_cdr(
                "/tf_static",
                ros2::TF_MESSAGE,
                stamp_ns,
                &ros2::TfMessage {
                    transforms: vec![ros2::TransformStamped {
                        header: ros2::Header {
                            stamp: ros2::Time::of(stamp_ns),
                            frame_id: format!("{robot}/base_link"),
                        },
                        child_frame_id: frame.clone(),
                        transform: ros2::Pose::of(mount),
                    }],
                },
            );
        }
        frame
    }

    /// A sensor message or a radio delivery for `robot`, on `/<topic>`, delivered to it at
    /// `received_ns` (the message's log time); `body_from_sensor` is the sensor's mount (a
    /// camera's optical frame), where it has one.
    pub fn sensor(
        &mut self,
        robot: &str,
        topic: &str,
        body_from_sensor: Option<&Pose>,
        msg: &SensorMsg,
        received_ns: u64,
    ) {
        self.received_ns = Some(received_ns);
        if self.encoding == RecordEncoding::Json {
            self.json_sensor(robot, topic, body_from_sensor, msg);
        } else {
            self.ros2_sensor(robot, topic, body_from_sensor, msg);
        }
        self.received_ns = None;
    }

    fn ros2_sensor(
        &mut self,
        robot: &str,
        topic: &str,
        body_from_sensor: Option<&Pose>,
        msg: &SensorMsg,
    ) {
        let t = msg.stamp_ns();
        let sensor = topic.split_once('/').map_or(topic, |(_, s)| s);
        let topic = format!("/{topic}");
        if let SensorMsg::Comms(m) = msg {
            return self.write_cdr(
                &format!("/{robot}/radio"),
                ros2::COMMS,
                t,
                &ros2::Comms {
                    header: ros2::Header {
                        stamp: ros2::Time::of(t),
                        frame_id: format!("{robot}/base_link"),
                    },
                    from: &m.from,
                    to: robot,
                    topic: &m.topic,
                    sent: ros2::Time::of(m.sent_ns),
                    bytes: m.payload.len().min(u32::MAX as usize) as u32,
                    payload: &m.payload,
                },
            );
        }
        // The sensor's frame, its mount written to /tf_static before the first message that
        // names it.
        let mut sensor_frame = || self.sensor_frame(robot, sensor, body_from_sensor, t);
        let mut frames = hetsim_sensors::ros2::Frames {
            stamp_ns: t,
            sensor: &mut sensor_frame,
            body: format!("{robot}/base_link"),
        };
        // The engine records every robot's truth itself, oracle or not.
        let Some(encoded) = hetsim_sensors::ros2::encode(msg, &mut frames) else {
            return;
        };
        for e in encoded {
            self.write_bytes(&format!("{topic}{}", e.suffix), e.schema, t, &e.data);
        }
        if let (SensorMsg::Image(_), Some(&(w, h, k, d, tx))) =
            (msg, self.camera_info.get(&topic[1..]))
        {
            let mut info = ros2::CameraInfo::of(w, h, &k, d, tx);
            info.header = ros2::Header {
                stamp: ros2::Time::of(t),
                frame_id: self.sensor_frame(robot, sensor, body_from_sensor, t),
            };
            self.write_cdr(&format!("{topic}/camera_info"), ros2::CAMERA_INFO, t, &info);
        }
    }

    /// Where the recording for `path` is written until [`Recorder::finish`] moves it into place
    /// (a run that fails removes it).
    pub fn partial_path(path: &Path) -> PathBuf {
        path.with_extension("mcap.partial")
    }

    /// Messages written per topic.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// Keeps the first failure; nothing is written after it.
    fn fail(&mut self, e: mcap::McapError) {
        if !self.broken {
            self.broken = true;
            self.failed = Some(e);
        }
    }

    /// The first write that failed, as the error to report (once: the writer refuses every
    /// later write, and those refusals say nothing of the cause).
    fn first_failure(&mut self) -> Result<(), RecordError> {
        match self.failed.take() {
            None if self.broken => Err(RecordError::Mcap {
                path: self.tmp.clone(),
                source: mcap::McapError::Io(std::io::Error::other(
                    "an earlier write failed (reported above)",
                )),
            }),
            None => Ok(()),
            Some(source) => Err(RecordError::Write {
                free: hetsim_core::files::free_bytes(&self.tmp),
                path: self.tmp.clone(),
                written: self.written,
                source,
            }),
        }
    }

    /// Finishes the file and moves it into place.
    pub fn finish(mut self) -> Result<PathBuf, RecordError> {
        self.first_failure()?;
        self.writer.finish().map_err(|source| RecordError::Mcap {
            path: self.tmp.clone(),
            source,
        })?;
        // Flushed and on disk before the rename makes it look complete.
        let file = self
            .writer
            .into_inner()
            .into_inner()
            .map_err(|e| hetsim_core::files::FileError::at(&self.tmp)(e.into_error()))?;
        file.sync_all()
            .map_err(hetsim_core::files::FileError::at(&self.tmp))?;
        std::fs::rename(&self.tmp, &self.path)
            .map_err(hetsim_core::files::FileError::at(&self.path))?;
        Ok(self.path)
    }
}

impl RunRecorder for Recorder {
    fn describe(&mut self, scenario: &Scenario, rendered: bool) -> Result<(), SinkError> {
        Ok(Recorder::describe(self, scenario, rendered)?)
    }
    fn truth(&mut self, robot: &str, stamp_ns: u64, pose: &Pose) {
        Recorder::truth(self, robot, stamp_ns, pose);
    }
    fn command(&mut self, robot: &str, stamp_ns: u64, cmd: &Command) {
        Recorder::command(self, robot, stamp_ns, cmd);
    }
    fn sensor(
        &mut self,
        robot: &str,
        topic: &str,
        mount: Option<&Pose>,
        msg: &SensorMsg,
        received_ns: u64,
    ) {
        Recorder::sensor(self, robot, topic, mount, msg, received_ns);
    }
    fn outcome(&mut self, ticks: u64, robots: &[RecordedOutcome]) -> Result<(), SinkError> {
        Ok(Recorder::outcome(self, ticks, robots)?)
    }
}
