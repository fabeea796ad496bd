//! The JSON encoding of a recording (`--record-encoding json`): JSON messages with JSON-schema
//! schemas. Where Foxglove defines a schema the message follows it and carries its name:
//! `foxglove.PoseInFrame` (ground truth), `foxglove.FrameTransform` (`/tf`),
//! `foxglove.LocationFix` (GPS), `foxglove.LaserScan`, `foxglove.CompressedImage` (PNG in
//! base64). The others use `hetsim.*` schemas written here. Foxglove opens it; ROS 2 tools
//! read only CDR, which is the default encoding (see `record.rs`).

use super::Recorder;
use hetsim_msgs::{Command, Pose, SensorMsg};
use hetsim_sensors::ros2::geo;
use serde_json::{json, Value};

fn stamp(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn pose_json(p: &Pose) -> Value {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    json!({"position": {"x": t.x, "y": t.y, "z": t.z}, "orientation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}})
}

/// The JSON schema of a schema name.
pub(super) fn schema_for(name: &str) -> Value {
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

impl Recorder {
    pub(super) fn json_truth(&mut self, robot: &str, stamp_ns: u64, pose: &Pose) {
        self.write_json(
            &format!("/{robot}/truth"),
            "foxglove.PoseInFrame",
            stamp_ns,
            &json!({"timestamp": stamp(stamp_ns), "frame_id": "world", "pose": pose_json(pose)}),
        );
        let p = pose_json(pose);
        self.write_json("/tf", "foxglove.FrameTransform", stamp_ns, &json!({"timestamp": stamp(stamp_ns), "parent_frame_id": "world", "child_frame_id": format!("{robot}/base_link"), "translation": p["position"], "rotation": p["orientation"]}));
    }

    pub(super) fn json_command(&mut self, robot: &str, stamp_ns: u64, cmd: &Command) {
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
        self.write_json(&format!("/{robot}/cmd"), "hetsim.Command", stamp_ns, &msg);
    }

    pub(super) fn json_sensor(
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
            SensorMsg::Compass(m) => self.write_json(&topic, "hetsim.Compass", t, &json!({"timestamp": stamp(t), "frame_id": frame, "heading_rad": m.heading_rad})),
            SensorMsg::Gps(m) => {
                let (lat, lon, alt) = geo(m.position_m);
                let var = m.sigma_m * m.sigma_m;
                self.write_json(&topic, "foxglove.LocationFix", t, &json!({"timestamp": stamp(t), "frame_id": frame, "latitude": lat, "longitude": lon, "altitude": alt, "position_covariance": [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var], "position_covariance_type": 2}));
            }
            SensorMsg::WheelOdometry(m) => self.write_json(&topic, "hetsim.WheelOdometry", t, &json!({"timestamp": stamp(t), "frame_id": frame, "left_m": m.left_m, "right_m": m.right_m})),
            SensorMsg::Imu(m) => {
                let [wx, wy, wz] = m.angular_rate_radps;
                let [ax, ay, az] = m.accel_mps2;
                self.write_json(&topic, "hetsim.Imu", t, &json!({"timestamp": stamp(t), "frame_id": frame, "angular_velocity": {"x": wx, "y": wy, "z": wz}, "linear_acceleration": {"x": ax, "y": ay, "z": az}}));
            }
            SensorMsg::LaserScan(m) => {
                let end = m.angle_min_rad + m.angle_increment_rad * (m.ranges_m.len().max(1) - 1) as f64;
                // JSON has no infinity: beams without a return are written as range_max + 1.
                let ranges: Vec<f64> = m.ranges_m.iter().map(|r| if r.is_finite() { *r as f64 } else { m.range_max_m + 1.0 }).collect();
                let pose = body_from_sensor.map_or_else(|| pose_json(&Pose::identity()), pose_json);
                self.write_json(&topic, "foxglove.LaserScan", t, &json!({"timestamp": stamp(t), "frame_id": frame, "pose": pose, "start_angle": m.angle_min_rad, "end_angle": end, "ranges": ranges, "intensities": []}));
            }
            SensorMsg::ChildTracks(m) => {
                let tracks: Vec<Value> = m.tracks.iter().map(|k| json!({"child": k.child, "x": k.position_m[0], "y": k.position_m[1]})).collect();
                self.write_json(&topic, "hetsim.ChildTracks", t, &json!({"timestamp": stamp(t), "frame_id": "world", "tracks": tracks}));
            }
            SensorMsg::Rendezvous(m) => self.write_json(&topic, "hetsim.Rendezvous", t, &json!({"timestamp": stamp(t), "frame_id": frame, "other": m.other, "pose": pose_json(&m.relative), "sigma_m": m.sigma_m, "sigma_rad": m.sigma_rad})),
            SensorMsg::ImageMatch(m) => self.write_json(&topic, "hetsim.ImageMatch", t, &json!({"timestamp": stamp(t), "frame_id": frame, "other": m.other, "other_stamp": stamp(m.other_stamp_ns), "pose": pose_json(&m.relative), "sigma_m": m.sigma_m, "sigma_rad": m.sigma_rad})),
            SensorMsg::Image(m) => {
                let mut png = Vec::new();
                let img = image::RgbImage::from_raw(m.width, m.height, m.to_rgb().into_owned()).expect("image size matches its pixels");
                img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png).expect("PNG encodes in memory");
                self.write_json(&topic, "foxglove.CompressedImage", t, &json!({"timestamp": stamp(t), "frame_id": format!("{robot}/{}", m.sensor.replace('/', "_")), "data": base64(&png), "format": "png"}));
            }
            SensorMsg::Comms(m) => self.write_json(&format!("/{robot}/radio"), "hetsim.Comms", t, &json!({"timestamp": stamp(t), "from": m.from, "to": robot, "topic": m.topic, "sent": stamp(m.sent_ns), "bytes": m.payload.len()})),
        }
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
