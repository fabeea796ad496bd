//! The emulated image matcher: the nearest unmatched key frame of another robot under this
//! one, old enough, as the true relative pose with announced Gaussian noise (an oracle; see
//! the manifest's oracles).

use super::{At, Model};
use crate::relative::noisy_relative;
use crate::ros2::{self, from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{Time, HEADER, POINT, POSE, QUATERNION, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{ImageMatch as Matched, SensorMsg};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

pub(crate) struct ImageMatch {
    pub range_m: f64,
    pub min_age_s: f64,
    pub sigma_m: f64,
    pub sigma_deg: f64,
    /// Key frames already matched: `(robot, stamp)`.
    pub used: BTreeSet<(usize, u64)>,
}

impl Model for ImageMatch {
    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let here = at.world_from_body.translation.vector;
        let min_age_ns = (self.min_age_s * 1e9) as u64;
        let best = at
            .keyframes
            .iter()
            .filter(|(r, t, _)| {
                *r != at.robot
                    && t.saturating_add(min_age_ns) <= at.stamp_ns
                    && !self.used.contains(&(*r, *t))
            })
            .map(|(r, t, p)| {
                let d = (p.translation.vector - here).xy().norm();
                (d, *r, *t, *p)
            })
            .filter(|(d, ..)| *d <= self.range_m)
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, other, other_stamp_ns, kf)) = best else {
            return Vec::new();
        };
        self.used.insert((other, other_stamp_ns));
        let truth = at.world_from_body.inverse() * kf;
        let sr = self.sigma_deg.to_radians();
        let relative = noisy_relative(&truth, self.sigma_m, sr, rng);
        vec![SensorMsg::ImageMatch(Matched {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            other: at.team.names[other].clone(),
            other_stamp_ns,
            relative,
            sigma_m: self.sigma_m,
            sigma_rad: sr,
        })]
    }
}

/// `hetsim_msgs/msg/ImageMatch`.
#[derive(Serialize, Deserialize)]
struct Ros2ImageMatch {
    header: Header,
    other: String,
    other_stamp: Time,
    pose: ros2::Pose,
    sigma_m: f64,
    sigma_rad: f64,
}

/// In the body's frame (the match relates body poses).
impl Ros2Message for Matched {
    const SCHEMA: &'static str = "hetsim_msgs/msg/ImageMatch";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "# Oracle (ablations only): the pose relative to another robot's key frame at other_stamp.\nstd_msgs/Header header\nstring other\nbuiltin_interfaces/Time other_stamp\ngeometry_msgs/Pose pose\nfloat64 sigma_m\nfloat64 sigma_rad\n",
                &[HEADER, TIME, POSE, POINT, QUATERNION],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let m = Ros2ImageMatch {
            header: frames.header(frames.body.clone()),
            other: self.other.clone(),
            other_stamp: Time::of(self.other_stamp_ns),
            pose: ros2::Pose::of(&self.relative),
            sigma_m: self.sigma_m,
            sigma_rad: self.sigma_rad,
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2ImageMatch = from_cdr(data)?;
        Ok(SensorMsg::ImageMatch(Matched {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            other: m.other,
            other_stamp_ns: m.other_stamp.ns()?,
            relative: m.pose.pose(),
            sigma_m: m.sigma_m,
            sigma_rad: m.sigma_rad,
        }))
    }
}
