//! Camera frames, IMU samples and ground truth written as EuRoC MAV datasets, one per robot.
//!
//! ```text
//! frames/<robot>/mav0/body.yaml                          the body frame (base_link)
//! frames/<robot>/mav0/cam<k>/data/<t_ns>.png             the image as the robot received it
//! frames/<robot>/mav0/cam<k>/data.csv                    #timestamp [ns],filename
//! frames/<robot>/mav0/cam<k>/sensor.yaml                 intrinsics, distortion, resolution,
//!                                                        rate, T_BS (body_from_optical)
//! frames/<robot>/mav0/cam<k>/depth/<t_ns>.png            ground-truth depth, 16-bit mm (0 =
//!                                                        none); not in EuRoC, loaders skip it
//! frames/<robot>/mav0/cam<k>/world_from_optical.tum      the camera's true pose per frame
//! frames/<robot>/mav0/imu<k>/data.csv                    #timestamp [ns],w_RS_S_x [rad s^-1],..
//! frames/<robot>/mav0/imu<k>/sensor.yaml                 T_BS, rate, noise densities
//! frames/<robot>/mav0/state_groundtruth_estimate0/data.csv   EuRoC's 17 columns: the body's
//!                                                        true pose, velocity and IMU biases
//! frames/<robot>/mav0/state_groundtruth_estimate0/sensor.yaml
//! ```
//!
//! A robot's dumped cameras are numbered in the order of its robot file, a stereo bench's
//! left camera before its right, so a bench alone is `cam0` (left) and `cam1` (right) as
//! EuRoC and the stereo loaders that read it expect. Only cameras the dump wants are numbered.
//! A robot's IMUs and ground truth are written when at least one of its cameras is dumped,
//! within the same time window. Frames: the world is x east, y north, z up (REP-103; EuRoC's
//! `R`); the body `B` is the robot's `base_link`; each sensor's `T_BS` is `body_from_sensor`.

use hetsim_core::files::FileError;
use hetsim_engine::cameras::Shot;
use hetsim_engine::{tum_line, FrameSink, ImuSpec, SinkError};
use hetsim_msgs::{ImuSample, PixelEncoding, Pose};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod euroc;

/// Why a frame could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// A file could not be written.
    #[error(transparent)]
    Io(#[from] FileError),
    /// An image could not be encoded or written. The message holds the cause, which is
    /// therefore not also the error's source (a chain would say it twice).
    #[error("{path}: {error}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// What failed.
        error: image::ImageError,
    },
    /// An image's bytes do not match its size.
    #[error("{topic}: {what} of {width} x {height} does not match its {bytes} values")]
    Size {
        /// The camera.
        topic: String,
        /// `image` or `depth`.
        what: &'static str,
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
        /// Values given.
        bytes: usize,
    },
}

struct CamSlot {
    robot: String,
    folder: String,
    csv: String,
    tum: String,
}

struct ImuSlot {
    spec: ImuSpec,
    robot: String,
    folder: String,
    csv: String,
}

/// Which frames to write, and where.
pub struct FrameDump {
    root: PathBuf,
    window_ns: Option<(u64, u64)>,
    cameras: Option<Vec<String>>,
    cams: BTreeMap<String, CamSlot>,
    imus: BTreeMap<String, ImuSlot>,
    written: u64,
}

fn robot_of(topic: &str) -> &str {
    topic.split('/').next().unwrap_or("robot")
}

impl FrameDump {
    /// Frames go under `root` (the `frames/` folder); only those stamped within `window`
    /// (seconds, inclusive) and of cameras named in `cameras` (`robot/camera`, or `robot` for
    /// all of a robot's cameras) when given.
    pub fn new(root: &Path, window_s: Option<(f64, f64)>, cameras: Option<Vec<String>>) -> Self {
        Self {
            root: root.to_path_buf(),
            window_ns: window_s.map(|(a, b)| ((a * 1e9).round() as u64, (b * 1e9).round() as u64)),
            cameras,
            cams: BTreeMap::new(),
            imus: BTreeMap::new(),
            written: 0,
        }
    }

    /// Numbers the wanted cameras per robot (`camera_topics` in robot-file order) and notes
    /// the IMUs of robots with a wanted camera. Called once, before the first frame.
    pub fn begin(&mut self, camera_topics: &[String], imus: &[ImuSpec]) {
        let mut next: BTreeMap<String, usize> = BTreeMap::new();
        let wanted: Vec<&String> = camera_topics.iter().filter(|t| self.wants(t)).collect();
        for topic in wanted {
            let robot = robot_of(topic).to_string();
            let k = next.entry(robot.clone()).or_default();
            self.cams.insert(
                topic.clone(),
                CamSlot {
                    robot,
                    folder: format!("cam{k}"),
                    csv: "#timestamp [ns],filename\n".to_string(),
                    tum: String::new(),
                },
            );
            *k += 1;
        }
        let mut next: BTreeMap<String, usize> = BTreeMap::new();
        for spec in imus {
            let robot = robot_of(&spec.topic).to_string();
            if !self.cams.values().any(|c| c.robot == robot) {
                continue;
            }
            let k = next.entry(robot.clone()).or_default();
            self.imus.insert(
                spec.topic.clone(),
                ImuSlot {
                    spec: spec.clone(),
                    robot,
                    folder: format!("imu{k}"),
                    csv: "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n".to_string(),
                },
            );
            *k += 1;
        }
    }

    /// Whether a camera's frames are wanted at all.
    pub fn wants(&self, topic: &str) -> bool {
        self.cameras.as_ref().is_none_or(|list| {
            list.iter()
                .any(|c| topic == c || topic.starts_with(&format!("{c}/")))
        })
    }

    /// Whether a frame at this time is wanted.
    pub fn in_window(&self, stamp_ns: u64) -> bool {
        self.window_ns
            .is_none_or(|(a, b)| stamp_ns >= a && stamp_ns <= b)
    }

    /// Frames written so far.
    pub fn written(&self) -> u64 {
        self.written
    }

    fn mav0(&self, robot: &str) -> PathBuf {
        self.root.join(robot).join("mav0")
    }

    /// Writes one frame (image, depth, its CSV and TUM lines; `sensor.yaml` the first time).
    pub fn write(&mut self, shot: &Shot) -> Result<(), FrameError> {
        let Some(slot) = self.cams.get(&shot.topic) else {
            return Ok(());
        };
        let dir = self.mav0(&slot.robot).join(&slot.folder);
        let first = slot.tum.is_empty();
        let ns = shot.image.stamp_ns;
        let (width, height) = (shot.image.width, shot.image.height);
        let size = |what, bytes| FrameError::Size {
            topic: shot.topic.clone(),
            what,
            width,
            height,
            bytes,
        };
        let encode = |path: &Path| {
            let path = path.to_path_buf();
            move |error| FrameError::Encode { path, error }
        };
        if first {
            for sub in ["data", "depth"] {
                let d = dir.join(sub);
                std::fs::create_dir_all(&d).map_err(FileError::at(&d))?;
            }
            let path = dir.join("sensor.yaml");
            std::fs::write(&path, euroc::camera_yaml(shot)).map_err(FileError::at(&path))?;
        }
        let name = format!("{ns}.png");
        let path = dir.join("data").join(&name);
        let data = shot.image.data.clone();
        let len = data.len();
        match shot.image.encoding {
            PixelEncoding::Rgb8 => image::RgbImage::from_raw(width, height, data)
                .ok_or_else(|| size("image", len))?
                .save_with_format(&path, image::ImageFormat::Png),
            PixelEncoding::Mono8 => image::GrayImage::from_raw(width, height, data)
                .ok_or_else(|| size("image", len))?
                .save_with_format(&path, image::ImageFormat::Png),
        }
        .map_err(encode(&path))?;
        if let Some(depth_m) = &shot.depth_m {
            let mm: Vec<u16> = depth_m
                .iter()
                .map(|d| (*d as f64 * 1000.0).round().clamp(0.0, 65535.0) as u16)
                .collect();
            let values = mm.len();
            let depth =
                image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width, height, mm)
                    .ok_or_else(|| size("depth", values))?;
            let path = dir.join("depth").join(&name);
            depth
                .save_with_format(&path, image::ImageFormat::Png)
                .map_err(encode(&path))?;
        }
        let slot = self.cams.get_mut(&shot.topic).expect("looked up above");
        slot.csv.push_str(&format!("{ns},{name}\n"));
        slot.tum.push_str(&tum_line(ns, &shot.world_from_optical));
        self.written += 1;
        Ok(())
    }

    /// Notes one IMU sample of a robot whose cameras are dumped (inside the window).
    pub fn imu(&mut self, topic: &str, sample: &ImuSample) {
        if !self.in_window(sample.stamp_ns) {
            return;
        }
        if let Some(slot) = self.imus.get_mut(topic) {
            let [wx, wy, wz] = sample.angular_rate_radps;
            let [ax, ay, az] = sample.accel_mps2;
            slot.csv.push_str(&format!(
                "{},{wx},{wy},{wz},{ax},{ay},{az}\n",
                sample.stamp_ns
            ));
        }
    }

    /// Writes each camera's `data.csv` and poses, each IMU's `data.csv` and `sensor.yaml`,
    /// and for every robot with a dumped camera its `body.yaml` and ground truth
    /// (`truth`: each robot's name and `world_from_body` samples in time order).
    pub fn finish(&self, truth: &[(&str, &[(u64, Pose)])]) -> Result<(), FrameError> {
        let write = |path: PathBuf, text: &str| -> Result<(), FrameError> {
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir).map_err(FileError::at(dir))?;
            }
            std::fs::write(&path, text).map_err(FileError::at(&path))?;
            Ok(())
        };
        let mut robots: Vec<&str> = Vec::new();
        for slot in self.cams.values().filter(|s| !s.tum.is_empty()) {
            let dir = self.mav0(&slot.robot).join(&slot.folder);
            write(dir.join("data.csv"), &slot.csv)?;
            write(dir.join("world_from_optical.tum"), &slot.tum)?;
            if !robots.contains(&slot.robot.as_str()) {
                robots.push(&slot.robot);
            }
        }
        for slot in self.imus.values() {
            if !robots.contains(&slot.robot.as_str()) {
                continue;
            }
            let dir = self.mav0(&slot.robot).join(&slot.folder);
            write(dir.join("data.csv"), &slot.csv)?;
            write(dir.join("sensor.yaml"), &euroc::imu_yaml(&slot.spec))?;
        }
        for robot in robots {
            let mav0 = self.mav0(robot);
            write(mav0.join("body.yaml"), &euroc::body_yaml(robot))?;
            let samples = truth
                .iter()
                .find(|(name, _)| *name == robot)
                .map_or(&[][..], |(_, s)| *s);
            // The biases of the robot's first IMU (EuRoC's b_w, b_a are imu0's), else none.
            let bias = self
                .imus
                .values()
                .find(|s| s.robot == robot && s.folder == "imu0")
                .map_or(([0.0; 3], [0.0; 3]), |s| s.spec.bias);
            let dir = mav0.join("state_groundtruth_estimate0");
            write(
                dir.join("data.csv"),
                &euroc::groundtruth_csv(samples, self.window_ns, bias),
            )?;
            write(dir.join("sensor.yaml"), euroc::GROUNDTRUTH_YAML)?;
        }
        Ok(())
    }
}

impl FrameSink for FrameDump {
    fn begin(&mut self, camera_topics: &[String], imus: &[ImuSpec]) {
        FrameDump::begin(self, camera_topics, imus);
    }
    fn wants_frame(&self, topic: &str, stamp_ns: u64) -> bool {
        self.wants(topic) && self.in_window(stamp_ns)
    }
    fn write(&mut self, shot: &Shot) -> Result<(), SinkError> {
        Ok(FrameDump::write(self, shot)?)
    }
    fn imu(&mut self, topic: &str, sample: &ImuSample) {
        FrameDump::imu(self, topic, sample);
    }
    fn finish(&self, truth: &[(&str, &[(u64, Pose)])]) -> Result<(), SinkError> {
        Ok(FrameDump::finish(self, truth)?)
    }
}
