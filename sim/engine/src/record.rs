//! Recording every message, command and ground-truth pose of a run to MCAP.
//!
//! Messages are JSON with JSON-schema schemas. Where Foxglove defines a schema the message
//! follows it and carries its name, so Foxglove Studio shows it natively:
//! `foxglove.PoseInFrame` (ground truth, `/<robot>/truth`), `foxglove.FrameTransform`
//! (`/tf`: `world` -> `<robot>/base_link`), `foxglove.LocationFix` (GPS) and
//! `foxglove.LaserScan`, `foxglove.CompressedImage` (PNG). The others (commands, compass, wheel odometry, IMU, child tracks,
//! rendezvous, radio) use `hetsim.*` schemas written here.
//!
//! Frames follow ROS REP-103: `world` is x east, y north, z up; `<robot>/base_link` is
//! x forward, y left, z up. GPS fixes are converted from the local east-north-up frame to
//! WGS-84 latitude/longitude around [`GEO_ORIGIN`] with a local flat-earth approximation
//! (error under a millimetre over the village's 800 m).
//!
//! The file is written under a temporary name and renamed when finished.

use hetsim_msgs::{Command, Pose, SensorMsg};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Latitude and longitude (degrees) and altitude (metres) of the world origin: LAAS-CNRS,
/// Toulouse. Any origin would do; this one is documented so positions can be reproduced.
pub const GEO_ORIGIN: (f64, f64, f64) = (43.5628, 1.4767, 150.0);

const EARTH_RADIUS_M: f64 = 6_378_137.0;

fn stamp(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn pose_json(p: &Pose) -> Value {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    json!({"position": {"x": t.x, "y": t.y, "z": t.z}, "orientation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}})
}

fn schema_for(name: &str) -> Value {
    let time = json!({"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}});
    let vec3 = json!({"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}});
    let quat = json!({"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}});
    let pose = json!({"type": "object", "properties": {"position": vec3, "orientation": quat}});
    let number = json!({"type": "number"});
    let string = json!({"type": "string"});
    let properties = match name {
        "foxglove.PoseInFrame" => json!({"timestamp": time, "frame_id": string, "pose": pose}),
        "foxglove.FrameTransform" => {
            json!({"timestamp": time, "parent_frame_id": string, "child_frame_id": string, "translation": vec3, "rotation": quat})
        }
        "foxglove.LocationFix" => {
            json!({"timestamp": time, "frame_id": string, "latitude": number, "longitude": number, "altitude": number, "position_covariance": {"type": "array", "items": number}, "position_covariance_type": {"type": "integer"}})
        }
        "foxglove.LaserScan" => {
            json!({"timestamp": time, "frame_id": string, "pose": pose, "start_angle": number, "end_angle": number, "ranges": {"type": "array", "items": number}, "intensities": {"type": "array", "items": number}})
        }
        "hetsim.Command" => {
            json!({"timestamp": time, "kind": string, "left_mps": number, "right_mps": number, "roll_rad": number, "pitch_rad": number, "yaw_rate_radps": number, "climb_rate_mps": number})
        }
        "hetsim.Compass" => json!({"timestamp": time, "frame_id": string, "heading_rad": number}),
        "hetsim.WheelOdometry" => {
            json!({"timestamp": time, "frame_id": string, "left_m": number, "right_m": number})
        }
        "hetsim.Imu" => {
            json!({"timestamp": time, "frame_id": string, "angular_velocity": vec3, "linear_acceleration": vec3})
        }
        "hetsim.ChildTracks" => {
            json!({"timestamp": time, "frame_id": string, "tracks": {"type": "array", "items": {"type": "object", "properties": {"child": string, "x": number, "y": number}}}})
        }
        "hetsim.Rendezvous" => {
            json!({"timestamp": time, "frame_id": string, "other": string, "pose": pose, "sigma_m": number, "sigma_rad": number})
        }
        "hetsim.ImageMatch" => {
            json!({"timestamp": time, "frame_id": string, "other": string, "other_stamp": time, "pose": pose, "sigma_m": number, "sigma_rad": number})
        }
        "foxglove.CompressedImage" => {
            json!({"timestamp": time, "frame_id": string, "data": {"type": "string", "contentEncoding": "base64"}, "format": string})
        }
        "hetsim.Comms" => {
            json!({"timestamp": time, "from": string, "to": string, "topic": string, "sent": time, "bytes": {"type": "integer"}})
        }
        _ => json!({}),
    };
    json!({"title": name, "type": "object", "properties": properties})
}

/// Standard base64 (RFC 4648) with padding.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let n = (chunk[0] as u32) << 16
            | (*chunk.get(1).unwrap_or(&0) as u32) << 8
            | *chunk.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
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
}

/// Writes an MCAP file during a run.
pub struct Recorder {
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    schemas: BTreeMap<String, u16>,
    channels: BTreeMap<String, u16>,
    counts: BTreeMap<String, u64>,
    sequence: u32,
    tmp: PathBuf,
    path: PathBuf,
}

impl Recorder {
    /// Starts a recording that will be at `path` once [`Recorder::finish`] succeeds.
    pub fn create(path: &Path) -> Result<Self, RecordError> {
        use hetsim_core::files::FileError;
        let tmp = Self::partial_path(path);
        if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(FileError::at(dir))?;
        }
        let file = std::fs::File::create(&tmp).map_err(FileError::at(&tmp))?;
        let writer =
            mcap::Writer::new(BufWriter::new(file)).map_err(|source| RecordError::Mcap {
                path: tmp.clone(),
                source,
            })?;
        Ok(Self {
            writer,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            counts: BTreeMap::new(),
            sequence: 0,
            tmp,
            path: path.to_path_buf(),
        })
    }

    fn write(&mut self, topic: &str, schema: &str, stamp_ns: u64, message: &Value) {
        let channel = match self.channels.get(topic) {
            Some(c) => *c,
            None => {
                let schema_id = match self.schemas.get(schema) {
                    Some(s) => *s,
                    None => {
                        let data =
                            serde_json::to_vec(&schema_for(schema)).expect("schemas serialize");
                        let id = self
                            .writer
                            .add_schema(schema, "jsonschema", &data)
                            .expect("schema registers");
                        self.schemas.insert(schema.to_string(), id);
                        id
                    }
                };
                let c = self
                    .writer
                    .add_channel(schema_id, topic, "json", &BTreeMap::new())
                    .expect("channel registers");
                self.channels.insert(topic.to_string(), c);
                c
            }
        };
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: stamp_ns,
            publish_time: stamp_ns,
        };
        let data = serde_json::to_vec(message).expect("messages serialize");
        // A failing disk surfaces at finish(), which reports it; the run goes on meanwhile.
        let _ = self.writer.write_to_known_channel(&header, &data);
        *self.counts.entry(topic.to_string()).or_default() += 1;
    }

    /// Ground truth of a robot: its pose and the `world` -> `<robot>/base_link` transform.
    pub fn truth(&mut self, robot: &str, stamp_ns: u64, pose: &Pose) {
        self.write(
            &format!("/{robot}/truth"),
            "foxglove.PoseInFrame",
            stamp_ns,
            &json!({"timestamp": stamp(stamp_ns), "frame_id": "world", "pose": pose_json(pose)}),
        );
        let p = pose_json(pose);
        self.write("/tf", "foxglove.FrameTransform", stamp_ns, &json!({"timestamp": stamp(stamp_ns), "parent_frame_id": "world", "child_frame_id": format!("{robot}/base_link"), "translation": p["position"], "rotation": p["orientation"]}));
    }

    /// A robot's actuator command.
    pub fn command(&mut self, robot: &str, stamp_ns: u64, cmd: &Command) {
        let body = match *cmd {
            Command::Wheels {
                left_mps,
                right_mps,
            } => json!({"kind": "wheels", "left_mps": left_mps, "right_mps": right_mps}),
            Command::Helicopter {
                roll_rad,
                pitch_rad,
                yaw_rate_radps,
                climb_rate_mps,
            } => {
                json!({"kind": "helicopter", "roll_rad": roll_rad, "pitch_rad": pitch_rad, "yaw_rate_radps": yaw_rate_radps, "climb_rate_mps": climb_rate_mps})
            }
            Command::Stop => json!({"kind": "stop"}),
        };
        let mut msg = body;
        msg["timestamp"] = stamp(stamp_ns);
        self.write(&format!("/{robot}/cmd"), "hetsim.Command", stamp_ns, &msg);
    }

    /// A sensor message or a radio delivery for `robot`, on `/<topic>`.
    pub fn sensor(
        &mut self,
        robot: &str,
        topic: &str,
        body_from_sensor: Option<&Pose>,
        msg: &SensorMsg,
    ) {
        let t = msg.stamp_ns();
        let frame = format!("{robot}/base_link");
        let topic = format!("/{topic}");
        match msg {
            // The engine records every robot's truth itself, oracle or not.
            SensorMsg::TruthPose(_) => {}
            SensorMsg::Compass(m) => self.write(&topic, "hetsim.Compass", t, &json!({"timestamp": stamp(t), "frame_id": frame, "heading_rad": m.heading_rad})),
            SensorMsg::Gps(m) => {
                let (lat0, lon0, alt0) = GEO_ORIGIN;
                let lat = lat0 + (m.position_m[1] / EARTH_RADIUS_M).to_degrees();
                let lon = lon0 + (m.position_m[0] / (EARTH_RADIUS_M * lat0.to_radians().cos())).to_degrees();
                let var = m.sigma_m * m.sigma_m;
                self.write(&topic, "foxglove.LocationFix", t, &json!({"timestamp": stamp(t), "frame_id": frame, "latitude": lat, "longitude": lon, "altitude": alt0 + m.position_m[2], "position_covariance": [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var], "position_covariance_type": 2}));
            }
            SensorMsg::WheelOdometry(m) => self.write(&topic, "hetsim.WheelOdometry", t, &json!({"timestamp": stamp(t), "frame_id": frame, "left_m": m.left_m, "right_m": m.right_m})),
            SensorMsg::Imu(m) => {
                let [wx, wy, wz] = m.angular_rate_radps;
                let [ax, ay, az] = m.accel_mps2;
                self.write(&topic, "hetsim.Imu", t, &json!({"timestamp": stamp(t), "frame_id": frame, "angular_velocity": {"x": wx, "y": wy, "z": wz}, "linear_acceleration": {"x": ax, "y": ay, "z": az}}));
            }
            SensorMsg::LaserScan(m) => {
                let end = m.angle_min_rad + m.angle_increment_rad * (m.ranges_m.len().max(1) - 1) as f64;
                // JSON has no infinity: beams without a return are written as range_max + 1.
                let ranges: Vec<f64> = m.ranges_m.iter().map(|r| if r.is_finite() { *r as f64 } else { m.range_max_m + 1.0 }).collect();
                let pose = body_from_sensor.map_or_else(|| pose_json(&Pose::identity()), pose_json);
                self.write(&topic, "foxglove.LaserScan", t, &json!({"timestamp": stamp(t), "frame_id": frame, "pose": pose, "start_angle": m.angle_min_rad, "end_angle": end, "ranges": ranges, "intensities": []}));
            }
            SensorMsg::ChildTracks(m) => {
                let tracks: Vec<Value> = m.tracks.iter().map(|k| json!({"child": k.child, "x": k.position_m[0], "y": k.position_m[1]})).collect();
                self.write(&topic, "hetsim.ChildTracks", t, &json!({"timestamp": stamp(t), "frame_id": "world", "tracks": tracks}));
            }
            SensorMsg::Rendezvous(m) => self.write(&topic, "hetsim.Rendezvous", t, &json!({"timestamp": stamp(t), "frame_id": frame, "other": m.other, "pose": pose_json(&m.relative), "sigma_m": m.sigma_m, "sigma_rad": m.sigma_rad})),
            SensorMsg::ImageMatch(m) => self.write(&topic, "hetsim.ImageMatch", t, &json!({"timestamp": stamp(t), "frame_id": frame, "other": m.other, "other_stamp": stamp(m.other_stamp_ns), "pose": pose_json(&m.relative), "sigma_m": m.sigma_m, "sigma_rad": m.sigma_rad})),
            SensorMsg::Image(m) => {
                let mut png = Vec::new();
                let img = image::RgbImage::from_raw(m.width, m.height, m.rgb.clone()).expect("image size matches its pixels");
                img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("PNG encodes in memory");
                self.write(&topic, "foxglove.CompressedImage", t, &json!({"timestamp": stamp(t), "frame_id": format!("{robot}/{}", m.sensor.replace('/', "_")), "data": base64(&png), "format": "png"}));
            }
            SensorMsg::Comms(m) => self.write(&format!("/{robot}/radio"), "hetsim.Comms", t, &json!({"timestamp": stamp(t), "from": m.from, "to": robot, "topic": m.topic, "sent": stamp(m.sent_ns), "bytes": m.payload.len()})),
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

    /// Finishes the file and moves it into place.
    pub fn finish(mut self) -> Result<PathBuf, RecordError> {
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

#[cfg(test)]
mod tests {
    #[test]
    fn base64_matches_rfc_4648_vectors() {
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(super::base64(plain.as_bytes()), coded);
        }
    }
}
