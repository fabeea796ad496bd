//! Camera frames written to disk in the EuRoC MAV dataset layout.
//!
//! ```text
//! frames/<robot>/<camera>/data/<t_ns>.png    the image as the robot received it
//! frames/<robot>/<camera>/depth/<t_ns>.png   ground-truth depth, 16-bit, millimetres (0 = none)
//! frames/<robot>/<camera>/data.csv           #timestamp [ns],filename
//! frames/<robot>/<camera>/sensor.yaml        intrinsics, distortion, resolution, rate, T_BS
//! frames/<robot>/<camera>.tum                world_from_optical at each frame (TUM)
//! ```
//! A stereo bench's cameras are `<camera>_left` and `<camera>_right`. `T_BS` is
//! `body_from_optical` (row-major 4 x 4), the body being the robot's `base_link`.

use crate::cameras::Shot;
use crate::output::tum_line;
use hetsim_core::files::FileError;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why a frame could not be written.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// A file could not be written.
    #[error(transparent)]
    Io(#[from] FileError),
    /// An image could not be encoded.
    #[error("{path}: {source}")]
    Encode {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: image::ImageError,
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

/// Which frames to write, and where.
pub struct FrameDump {
    root: PathBuf,
    window_ns: Option<(u64, u64)>,
    cameras: Option<Vec<String>>,
    csv: BTreeMap<String, String>,
    tum: BTreeMap<String, String>,
    rates: BTreeMap<String, f64>,
    written: u64,
}

fn folder(topic: &str) -> (String, String) {
    let mut parts = topic.splitn(2, '/');
    let robot = parts.next().unwrap_or("robot").to_string();
    let camera = parts.next().unwrap_or("camera").replace('/', "_");
    (robot, camera)
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
            csv: BTreeMap::new(),
            tum: BTreeMap::new(),
            rates: BTreeMap::new(),
            written: 0,
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

    /// Writes one frame (image, depth, CSV and TUM lines; `sensor.yaml` the first time).
    pub fn write(&mut self, shot: &Shot) -> Result<(), FrameError> {
        let rate_hz = shot.rate_hz;
        let (robot, camera) = folder(&shot.topic);
        let dir = self.root.join(&robot).join(&camera);
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
            move |source| FrameError::Encode { path, source }
        };
        if !self.csv.contains_key(&shot.topic) {
            for sub in ["data", "depth"] {
                let d = dir.join(sub);
                std::fs::create_dir_all(&d).map_err(FileError::at(&d))?;
            }
            let yaml = sensor_yaml(shot, rate_hz);
            let path = dir.join("sensor.yaml");
            std::fs::write(&path, yaml).map_err(FileError::at(&path))?;
            self.csv
                .insert(shot.topic.clone(), "#timestamp [ns],filename\n".to_string());
            self.rates.insert(shot.topic.clone(), rate_hz);
        }
        let name = format!("{ns}.png");
        let img = image::RgbImage::from_raw(width, height, shot.image.rgb.clone())
            .ok_or_else(|| size("image", shot.image.rgb.len()))?;
        let path = dir.join("data").join(&name);
        img.save_with_format(&path, image::ImageFormat::Png)
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
        self.csv
            .get_mut(&shot.topic)
            .expect("created above")
            .push_str(&format!("{ns},{name}\n"));
        self.tum
            .entry(shot.topic.clone())
            .or_default()
            .push_str(&tum_line(ns, &shot.world_from_optical));
        self.written += 1;
        Ok(())
    }

    /// Writes each camera's `data.csv` and TUM file.
    pub fn finish(&self) -> Result<(), FrameError> {
        for (topic, csv) in &self.csv {
            let (robot, camera) = folder(topic);
            let path = self.root.join(&robot).join(&camera).join("data.csv");
            std::fs::write(&path, csv).map_err(FileError::at(&path))?;
            let tum = self.root.join(&robot).join(format!("{camera}.tum"));
            std::fs::write(&tum, &self.tum[topic]).map_err(FileError::at(&tum))?;
        }
        Ok(())
    }
}

fn sensor_yaml(shot: &Shot, rate_hz: f64) -> String {
    let k = &shot.intrinsics;
    let t = shot.body_from_optical.to_homogeneous();
    let rows: Vec<String> = (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:.9}", t[(r, c)]))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    let (model, intrinsics) = if k.alpha_u > 0.0 {
        (
            "pinhole",
            format!("[{}, {}, {}, {}]", k.alpha_u, k.alpha_v, k.u0, k.v0),
        )
    } else {
        ("equirectangular", "[]".to_string())
    };
    format!(
        "# hetsim camera {topic}; EuRoC sensor.yaml layout\nsensor_type: camera\ncomment: {topic}\nT_BS:\n  cols: 4\n  rows: 4\n  data: [{}]\nrate_hz: {rate_hz}\nresolution: [{}, {}]\ncamera_model: {model}\nintrinsics: {intrinsics}\ndistortion_model: radial-tangential\ndistortion_coefficients: [{}, {}, 0.0, 0.0]\n",
        rows.join(",\n         "),
        k.width,
        k.height,
        shot.distortion[0],
        shot.distortion[1],
        topic = shot.topic
    )
}
