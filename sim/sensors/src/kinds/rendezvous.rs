//! The emulated rendezvous: the true pose of every other robot within range, in the sensor's
//! cone and in sight, relative to this body, with announced Gaussian noise (an oracle of
//! relative pose; see the manifest's oracles).

use super::{At, Model};
use crate::relative::noisy_relative;
use crate::ros2::{self, from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, POINT, POSE, QUATERNION, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{Rendezvous as Seen, SensorMsg};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub(crate) struct Rendezvous {
    pub range_m: f64,
    pub fov_deg: f64,
    pub sigma_m: f64,
    pub sigma_deg: f64,
}

impl Model for Rendezvous {
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let origin = at.world_from_sensor.translation.vector;
        let team = at.team;
        // One message per robot seen, in robot order.
        let mut seen = Vec::new();
        for other in 0..team.names.len() {
            if other == at.robot {
                continue;
            }
            let other_pose = at.physics.pose(other);
            let centre =
                other_pose.translation.vector + Vector3::new(0.0, 0.0, team.heights[other] / 2.0);
            let v = centre - origin;
            let distance = v.norm();
            let axis = at.world_from_sensor.rotation * Vector3::x();
            let angle = (v.dot(&axis) / distance.max(1e-12)).clamp(-1.0, 1.0).acos();
            if distance > self.range_m || angle > self.fov_deg.to_radians() / 2.0 {
                continue;
            }
            if !at.physics.clear_line(
                [origin.x, origin.y, origin.z],
                [centre.x, centre.y, centre.z],
                &[at.robot, other],
            ) {
                continue;
            }
            let truth = at.world_from_body.inverse() * other_pose;
            let sr = self.sigma_deg.to_radians();
            let relative = noisy_relative(&truth, self.sigma_m, sr, rng);
            seen.push(Seen {
                stamp_ns: at.stamp_ns,
                sensor: at.sensor.clone(),
                other: team.names[other].clone(),
                relative,
                sigma_m: self.sigma_m,
                sigma_rad: sr,
            });
        }
        seen.into_iter().map(SensorMsg::Rendezvous).collect()
    }
}

/// `hetsim_msgs/msg/Rendezvous`.
#[derive(Serialize, Deserialize)]
struct Ros2Rendezvous {
    header: Header,
    other: String,
    pose: ros2::Pose,
    sigma_m: f64,
    sigma_rad: f64,
}

impl Ros2Message for Seen {
    const SCHEMA: &'static str = "hetsim_msgs/msg/Rendezvous";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "# The other robot's pose in this robot's body frame, with the noise it was drawn with.\nstd_msgs/Header header\nstring other\ngeometry_msgs/Pose pose\nfloat64 sigma_m\nfloat64 sigma_rad\n",
                &[HEADER, TIME, POSE, POINT, QUATERNION],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let m = Ros2Rendezvous {
            header: frames.in_sensor(),
            other: self.other.clone(),
            pose: ros2::Pose::of(&self.relative),
            sigma_m: self.sigma_m,
            sigma_rad: self.sigma_rad,
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2Rendezvous = from_cdr(data)?;
        Ok(SensorMsg::Rendezvous(Seen {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            other: m.other,
            relative: m.pose.pose(),
            sigma_m: m.sigma_m,
            sigma_rad: m.sigma_rad,
        }))
    }
}
