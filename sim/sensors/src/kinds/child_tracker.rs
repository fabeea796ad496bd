//! A parent's child tracker (seed 002's hat tracking, emulated): the floor position of every
//! robot wearing the orange hat (`body.hat`) within range and in sight, with an error of random direction and a normally
//! distributed size, in the parent's heading frame.

use super::{At, Model};
use crate::ros2::{from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{yaw_of, ChildTracks, SensorMsg, Track};
use rand::RngExt;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

pub(crate) struct ChildTracker {
    pub range_m: f64,
    pub error_mean_m: f64,
    pub error_std_m: f64,
}

impl Model for ChildTracker {
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let origin = at.world_from_sensor.translation.vector;
        let team = at.team;
        let mut tracks = Vec::new();
        let error = Normal::new(self.error_mean_m, self.error_std_m).expect("validated std >= 0");
        for other in 0..team.names.len() {
            if other == at.robot || !team.hats[other] {
                continue;
            }
            let p = at.physics.pose(other).translation.vector;
            let hat = [p.x, p.y, p.z + team.heights[other]];
            let horizontal = (hat[0] - origin.x).hypot(hat[1] - origin.y);
            if horizontal > self.range_m
                || !at
                    .physics
                    .clear_line([origin.x, origin.y, origin.z], hat, &[at.robot, other])
            {
                continue;
            }
            let magnitude = error.sample(rng).abs();
            let angle = rng.random_range(0.0..std::f64::consts::TAU);
            // The measured floor position, in the parent's body frame (its heading only: the
            // floor position of a child, however the body tilts).
            let here = at.world_from_body.translation.vector;
            let (dx, dy) = (
                p.x + magnitude * angle.cos() - here.x,
                p.y + magnitude * angle.sin() - here.y,
            );
            let (sin, cos) = yaw_of(&at.world_from_body).sin_cos();
            tracks.push(Track {
                child: team.names[other].clone(),
                position_m: [cos * dx + sin * dy, -sin * dx + cos * dy],
            });
        }
        vec![SensorMsg::ChildTracks(ChildTracks {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            tracks,
        })]
    }
}

const CHILD_TRACK: (&str, &str) = (
    "hetsim_msgs/ChildTrack",
    "# A child's position on the floor as the parent's tracker measured it, in the parent's body frame (x forward, y left).\nstring child\nfloat64 x\nfloat64 y\n",
);

/// `hetsim_msgs/ChildTrack`.
#[derive(Serialize, Deserialize)]
struct Ros2ChildTrack {
    child: String,
    x: f64,
    y: f64,
}

/// `hetsim_msgs/msg/ChildTracks`.
#[derive(Serialize, Deserialize)]
struct Ros2ChildTracks {
    header: Header,
    tracks: Vec<Ros2ChildTrack>,
}

impl Ros2Message for ChildTracks {
    const SCHEMA: &'static str = "hetsim_msgs/msg/ChildTracks";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "std_msgs/Header header\nhetsim_msgs/ChildTrack[] tracks\n",
                &[HEADER, TIME, CHILD_TRACK],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let m = Ros2ChildTracks {
            header: frames.header("world".into()),
            tracks: self
                .tracks
                .iter()
                .map(|k| Ros2ChildTrack {
                    child: k.child.clone(),
                    x: k.position_m[0],
                    y: k.position_m[1],
                })
                .collect(),
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2ChildTracks = from_cdr(data)?;
        Ok(SensorMsg::ChildTracks(ChildTracks {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            tracks: m
                .tracks
                .into_iter()
                .map(|t| Track {
                    child: t.child,
                    position_m: [t.x, t.y],
                })
                .collect(),
        }))
    }
}
