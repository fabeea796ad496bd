//! Image matching as the robot's own event (seed Section V): every sub-map origin keeps its key
//! frame ([`KeyFrame`]: the left image's stereo points with descriptors), key frames travel to
//! the robots met over the radio, and the robot looks for a past key frame (its own or another
//! robot's) under its current view, chosen from its own graph estimate, never from the truth.
//!
//! Candidates, every `match_period_s`:
//! * a key frame the robot has left since it was made or last matched (the looked-at points,
//!   by the robot's estimate, were once [`LEAVE`] footprint radii apart): a loop, not the
//!   sub-maps' chain, which the EKF already links;
//! * whose camera looks within `max_view_angle_deg` of the current one (interest points do not
//!   survive large viewpoint changes; the seed's remark on its points);
//! * whose looked-at point (its median depth along its optical axis) lies, by the graph's
//!   estimate, within half its footprint radius plus three standard deviations of the current
//!   looked-at point, the deviation from the joint covariance of the two origins and the
//!   current sub-map's pose covariance;
//!
//! nearest first (in those units), at most `max_match_candidates` per attempt. A match
//! ([`match_keyframes`]) is accepted only with enough inliers and if the measured relative pose
//! agrees with the predicted one: its Mahalanobis distance under the sum of both covariances
//! within `match_gate_chi2` (chi-square, 6 degrees of freedom). Rejected ones are counted.

use super::*;
use crate::graph::{compound, inverse_covariance, log, numeric, relative};
use hetsim_vision::place::{match_keyframes, KeyFrame};
use nalgebra::Isometry3;

/// A key frame is left once the looked-at points are this many footprint radii apart (more
/// than one: a helicopter's tilt swings its looked-at point by metres).
pub(crate) const LEAVE: f64 = 1.5;

/// The radio topic of key frames.
pub const PLACE_TOPIC: &str = "slam/keyframe";

/// A key frame at a sub-map origin.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Place {
    /// The robot whose origin it is.
    pub robot: String,
    /// The origin's stamp.
    pub stamp_ns: u64,
    /// That robot's left optical frame in its body frame.
    pub body_from_camera: Pose,
    /// The key frame.
    pub frame: KeyFrame,
    /// The robot's view has left this key frame's since it was made or last matched.
    pub left: bool,
}

impl Place {
    /// Bytes on the radio: the robot's name (u16 length, UTF-8), the stamp (u64), the camera
    /// pose (translation, then quaternion i, j, k, w: 7 f64), then [`KeyFrame::to_bytes`].
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(&(self.robot.len() as u16).to_le_bytes());
        out.extend_from_slice(self.robot.as_bytes());
        out.extend_from_slice(&self.stamp_ns.to_le_bytes());
        let (t, q) = (
            &self.body_from_camera.translation.vector,
            &self.body_from_camera.rotation,
        );
        for v in [t.x, t.y, t.z, q.i, q.j, q.k, q.w] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.frame.to_bytes());
        out
    }

    /// Reads [`Place::to_bytes`]; `None` for anything else.
    pub fn from_bytes(b: &[u8]) -> Option<Self> {
        let n = u16::from_le_bytes(b.get(0..2)?.try_into().ok()?) as usize;
        let robot = std::str::from_utf8(b.get(2..2 + n)?).ok()?.to_string();
        let at = 2 + n;
        let stamp_ns = u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?);
        let f = |k: usize| -> Option<f64> {
            let o = at + 8 + 8 * k;
            Some(f64::from_le_bytes(b.get(o..o + 8)?.try_into().ok()?))
        };
        let v: Vec<f64> = (0..7).map(f).collect::<Option<_>>()?;
        if !v.iter().all(|x| x.is_finite()) {
            return None;
        }
        let q = nalgebra::Quaternion::new(v[6], v[3], v[4], v[5]);
        if (q.norm() - 1.0).abs() > 1e-6 {
            return None;
        }
        let body_from_camera = Isometry3::from_parts(
            nalgebra::Translation3::new(v[0], v[1], v[2]),
            nalgebra::UnitQuaternion::from_quaternion(q),
        );
        let frame = KeyFrame::from_bytes(b.get(at + 64..)?)?;
        Some(Self {
            robot,
            stamp_ns,
            body_from_camera,
            frame,
            left: false,
        })
    }
}

/// An accepted image match: the link to make.
pub(crate) struct Found {
    pub robot: String,
    pub stamp_ns: u64,
    /// `current body from key-frame body`, as the graph's links measure it.
    pub z: Pose,
    pub cov: Matrix6<f64>,
    pub inliers: usize,
    pub mahalanobis2: f64,
}

/// The right perturbation's covariance of `B T Bk⁻¹` given a left perturbation `Exp(ξ) T`
/// of `T` with covariance `cov`.
fn link_covariance(b: &Pose, t: &Pose, bk: &Pose, cov: &Matrix6<f64>) -> Matrix6<f64> {
    let z = b * t * bk.inverse();
    let j = numeric(|xi| log(&(z.inverse() * b * crate::graph::exp(xi) * t * bk.inverse())));
    let c = j * cov * j.transpose();
    (c + c.transpose()) * 0.5
}

/// The looked-at point of a camera at `pose`: `depth` metres along its optical axis.
fn looked_at(pose: &Pose, depth: f64) -> Vector3<f64> {
    (pose * nalgebra::Point3::new(0.0, 0.0, depth)).coords
}

impl SlamCore {
    /// The key frame of an origin made at this frame (its left image and the VO's stereo
    /// points), kept and sent to the robots met.
    pub(super) fn keep_place(&mut self, left: &Gray, stamp: u64) {
        let Some(g) = self.global.as_ref() else {
            return;
        };
        if !self.params.cooperative || g.own.stamps.last() != Some(&stamp) {
            return;
        }
        if self
            .places
            .iter()
            .any(|p| p.robot == self.robot && p.stamp_ns == stamp)
        {
            return;
        }
        let frame = KeyFrame::new(
            left,
            self.bench.camera,
            self.bench.baseline_m,
            self.vo.points(),
        );
        self.places.push(Place {
            robot: self.robot.clone(),
            stamp_ns: stamp,
            body_from_camera: self.body_from_camera,
            frame,
            left: false,
        });
        self.count("keyframes", 1);
    }

    /// Sends each robot met the key frames of this robot it has not been sent yet.
    pub(super) fn send_places(&mut self) {
        let own: Vec<usize> = (0..self.places.len())
            .filter(|&i| self.places[i].robot == self.robot)
            .collect();
        for to in self.peers.clone() {
            let sent = self.places_sent.entry(to.clone()).or_default();
            let from = *sent;
            *sent = own.len();
            for &i in &own[from..] {
                let payload = self.places[i].to_bytes();
                self.count("keyframe_bytes_sent", payload.len() as u64);
                self.outgoing.push(Outgoing {
                    to: to.clone(),
                    topic: PLACE_TOPIC.to_string(),
                    payload,
                });
            }
        }
    }

    /// Another robot's key frame arrived.
    pub(super) fn receive_place(&mut self, d: &Delivered) {
        let Some(place) = Place::from_bytes(&d.payload) else {
            self.count("keyframes_malformed", 1);
            return;
        };
        let known = self
            .places
            .iter()
            .any(|p| p.robot == place.robot && p.stamp_ns == place.stamp_ns);
        if place.robot != self.robot && !known {
            self.places.push(place);
            self.count("keyframes_received", 1);
        }
    }

    /// The graph's joint covariance, recomputed when the graph changed.
    fn joint_covariance(&mut self) -> Option<&crate::graph::Covariance> {
        let g = self.global.as_ref()?;
        if self
            .covariance
            .as_ref()
            .is_none_or(|(v, _)| *v != g.version)
        {
            self.covariance = Some((g.version, g.graph.covariance()?));
        }
        self.covariance.as_ref().map(|(_, c)| c)
    }

    /// Looks for a past key frame under the current view (see the module's text); returns the
    /// accepted match, if any.
    pub(super) fn try_match(&mut self, left: &Gray, stamp: u64) -> Option<Found> {
        let period = (self.params.match_period_s * 1e9) as u64;
        if !self.params.cooperative
            || self.global.is_none()
            || self.places.is_empty()
            || self
                .last_match_attempt_ns
                .is_some_and(|t| stamp < t + period)
        {
            return None;
        }
        self.last_match_attempt_ns = Some(stamp);
        let mut z: Vec<f64> = self.vo.points().iter().map(|p| p.point.z).collect();
        z.sort_by(f64::total_cmp);
        let depth = z.get(z.len() / 2).copied().unwrap_or(0.0);
        if z.len() < self.params.matching.min_inliers || depth <= 0.0 {
            return None;
        }
        let cov = self.joint_covariance()?.clone();
        let g = self.global.as_ref().expect("checked above");
        let c = g.len() - 1;
        let (local, local_cov) = (self.map.pose(), self.map.pose_covariance());
        let b = self.body_from_camera;
        let max_angle = self.params.max_view_angle_deg.to_radians();
        // (score, place, predicted key-frame body from current body, its covariance)
        let mut candidates = Vec::new();
        for (i, p) in self.places.iter_mut().enumerate() {
            let Some(k) = g.index_of(&p.robot, p.stamp_ns) else {
                continue;
            };
            if p.robot == self.robot && k == c {
                continue;
            }
            let (u, su) = relative(
                (&g.graph.nodes[k], &cov.block(k, k)),
                (&g.graph.nodes[c], &cov.block(c, c)),
                &cov.block(k, c),
            );
            let (q, sq) = compound(&u, &su, &local, &local_cov);
            let kf_cam = p.body_from_camera;
            let cur_cam = q * b;
            let angle = (kf_cam.rotation * Vector3::z())
                .dot(&(cur_cam.rotation * Vector3::z()))
                .clamp(-1.0, 1.0)
                .acos();
            let kf_depth = p.frame.median_depth();
            let radius = kf_depth * (p.frame.camera.u0 + 0.5) / p.frame.camera.alpha_u;
            let distance = (looked_at(&kf_cam, kf_depth) - looked_at(&cur_cam, depth)).norm();
            if angle > max_angle || distance > LEAVE * radius {
                p.left = true;
            }
            if !p.left || angle > max_angle {
                continue;
            }
            // Where the current looked-at point lies is uncertain by the relative pose's
            // position and its rotation over the depth.
            let sp = sq
                .fixed_view::<3, 3>(0, 0)
                .symmetric_eigenvalues()
                .max()
                .max(0.0);
            let sr = sq
                .fixed_view::<3, 3>(3, 3)
                .symmetric_eigenvalues()
                .max()
                .max(0.0);
            let sigma = (sp + sr * depth * depth).sqrt();
            let reach = 0.5 * radius + 3.0 * sigma;
            if distance < reach {
                candidates.push((distance / reach, i, q, sq));
            }
        }
        if candidates.is_empty() {
            return None;
        }
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        let current = KeyFrame::new(
            left,
            self.bench.camera,
            self.bench.baseline_m,
            self.vo.points(),
        );
        let image_period = self.params.image_match_period_s;
        let mut tried = 0;
        for (_, i, q, sq) in candidates {
            if tried >= self.params.max_match_candidates {
                break;
            }
            let (robot, kf_stamp) = (self.places[i].robot.clone(), self.places[i].stamp_ns);
            if !self.link_due("image_match", &robot, stamp, image_period) {
                continue;
            }
            tried += 1;
            self.count("match_attempts", 1);
            let found = match_keyframes(
                &self.places[i].frame,
                &current,
                &self.params.matching,
                &mut self.match_rng,
            );
            let Ok(m) = found else {
                self.count("matches_too_few_inliers", 1);
                continue;
            };
            let bk = self.places[i].body_from_camera;
            let z = b * m.current_from_keyframe * bk.inverse();
            let sz = link_covariance(&b, &m.current_from_keyframe, &bk, &m.covariance);
            // The prediction of z is q⁻¹ (q: key-frame body from current body).
            let nu = log(&(z.inverse() * q.inverse()));
            let d2 = (sz + inverse_covariance(&q, &sq))
                .try_inverse()
                .map_or(f64::INFINITY, |s| (nu.transpose() * s * nu)[0]);
            // A distance that is not a number is refused too.
            if d2.is_nan() || d2 > self.params.match_gate_chi2 {
                self.count("matches_gated", 1);
                continue;
            }
            self.count("matches_accepted", 1);
            self.places[i].left = false;
            return Some(Found {
                robot,
                stamp_ns: kf_stamp,
                z,
                cov: sz,
                inliers: m.inliers,
                mahalanobis2: d2,
            });
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_vision::place::KeyPoint;

    #[test]
    fn a_key_frame_crosses_the_radio_bit_for_bit_and_damage_is_refused() {
        let place = Place {
            robot: "ressac".into(),
            stamp_ns: 380_500_000_000,
            body_from_camera: hetsim_msgs::pose_from_xyz_rpy([0.6, 0.45, -0.5], [0.1, 1.4, -0.3]),
            frame: KeyFrame {
                camera: hetsim_msgs::Pinhole {
                    alpha_u: 886.8,
                    alpha_v: 886.8,
                    u0: 511.5,
                    v0: 383.5,
                },
                baseline_m: 0.9,
                points: vec![KeyPoint {
                    pixel: [10.5, 20.25],
                    point: [1.0, -2.0, 39.5],
                    descriptor: [1, u64::MAX, 3, 1 << 63],
                }],
            },
            left: false,
        };
        let bytes = place.to_bytes();
        assert_eq!(Place::from_bytes(&bytes), Some(place.clone()));
        assert_eq!(Place::from_bytes(&bytes[..bytes.len() - 1]), None);
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(Place::from_bytes(&longer), None);
        let mut bad = bytes.clone();
        // The quaternion's w (the 7th f64 after name and stamp) no longer of unit norm.
        let w = 2 + 6 + 8 + 6 * 8;
        bad[w..w + 8].copy_from_slice(&3.0f64.to_le_bytes());
        assert_eq!(Place::from_bytes(&bad), None);
    }

    /// The link's covariance against sampling: `T` perturbed on the left by draws of its
    /// covariance, the residual `Log(ẑ⁻¹ B Exp(ξ) T Bk⁻¹)` sampled (20000 draws: 5 % is
    /// several times the sampling error of about 1 % per entry).
    #[test]
    fn the_link_covariance_matches_sampled_links() {
        use rand::{RngExt, SeedableRng};
        let b = hetsim_msgs::pose_from_xyz_rpy(
            [0.6, 0.45, -0.5],
            [0.0, std::f64::consts::FRAC_PI_2, 0.0],
        );
        let bk = hetsim_msgs::pose_from_xyz_rpy([0.35, 0.17, 1.4], [0.0, 0.14, 0.0]);
        let t = hetsim_msgs::pose_from_xyz_rpy([3.0, -1.0, 2.0], [0.2, -0.1, 2.9]);
        let l = nalgebra::Matrix6::from_fn(|i, j| match (i, j) {
            _ if i == j && i < 3 => 0.05,
            _ if i == j => 0.004,
            (4, 0) => 0.02,
            (5, 1) => -0.01,
            _ => 0.0,
        });
        let cov = l * l.transpose();
        let predicted = link_covariance(&b, &t, &bk, &cov);
        let z = b * t * bk.inverse();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut gauss = || -> f64 {
            let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        };
        let n = 20000;
        let mut sampled = nalgebra::Matrix6::zeros();
        for _ in 0..n {
            let xi = l * nalgebra::Vector6::from_fn(|_, _| gauss());
            let e = log(&(z.inverse() * b * crate::graph::exp(&xi) * t * bk.inverse()));
            sampled += e * e.transpose() / n as f64;
        }
        let rel = (sampled - predicted).abs().max() / predicted.abs().max();
        assert!(
            rel < 0.05,
            "sampled vs first order: {rel:.3}\n{sampled}\n{predicted}"
        );
    }
}
