//! A robot stack running the local level of the hierarchical SLAM beside another stack (the
//! waypoint pilot): stereo VO for the motion prediction, monocular point observations from
//! the bench's left camera, and a new sub-map every `max_landmarks` points (seed Sections II
//! and V).
//!
//! Per stereo pair:
//! 1. stereo VO gives the left camera's motion and covariance; it is turned into the body's
//!    motion (`B M⁻¹ B⁻¹`, covariance through the adjoint of `B = body_from_camera`) and
//!    predicts the local map;
//! 2. every point is predicted into the left image with its innovation covariance `S`, and
//!    searched there by ZNCC of the patch taken when it was initialized, inside the 99 %
//!    ellipse of `S` (when `S` is small enough to search); a match updates the map unless the
//!    Mahalanobis gate rejects it;
//! 3. the deletion policy of [`crate::ekf`] removes unreliable points;
//! 4. new points are initialized (undelayed, inverse depth) from Harris corners so that each
//!    region of a regular 3 x 3 partition of the image has at least `per_region` points;
//! 5. when the map holds `max_landmarks` points, it is closed: the robot pose in it (mean and
//!    covariance) becomes the relative transform to the next sub-map, whose origin is that
//!    pose.
//!
//! 6. a GPS fix, once `gps_event_period_s` has passed since the last event, is an event: a new
//!    sub-map starts, the fix constrains its origin, and the global graph
//!    ([`crate::graph`]) is optimized.
//!
//! The first sub-map's origin is the true pose at the first pair (the seed's first map is its
//! world frame). Every frame is kept as (sub-map, pose in it), and written through the
//! graph's optimized origins (`slam/<robot>.tum`) and through the origins compounded without
//! events (`slam-open/<robot>.tum`, the open-loop estimate); the chained VO alone is
//! `vo/<robot>.tum`. Rendezvous and image-matching events are not wired yet.

use crate::ekf::{LocalMap, Update};
use crate::graph::{Edge, Graph, Prior};
use crate::idp::Sensor;
use hetsim_msgs::{Command, Image, Outgoing, Pose, RobotStack, SensorMsg, StackStatus};
use hetsim_vision::harris::{detect, select_new, Corner};
use hetsim_vision::matching::{search_ellipse, Patch};
use hetsim_vision::stereo::Bench;
use hetsim_vision::vo::StereoVo;
use hetsim_vision::Gray;
use nalgebra::{Matrix3, Matrix6, Vector2, Vector3};
use std::collections::BTreeMap;

/// Tuning of the local level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlamParams {
    /// Initial inverse depth of a new point, m⁻¹ (seed: Dala 0.1, Ressac 0.025).
    pub rho_init: f64,
    /// Its standard deviation, m⁻¹ (seed: Dala 0.2, Ressac 0.0125).
    pub sigma_rho: f64,
    /// Points per sub-map before a new one starts (seed: 100).
    pub max_landmarks: usize,
    /// Points kept in each region of the 3 x 3 partition (seed: 2).
    pub per_region: usize,
    /// Pixel noise of an observation, pixels.
    pub sigma_px: f64,
    /// A point whose 1σ search ellipse is wider than this is not searched, pixels.
    pub max_search_px: f64,
    /// Deletion: searched at least this often and found in fewer than half.
    pub min_searches: u32,
    /// A GPS fix becomes an event when this long has passed since the last event, seconds
    /// (`None`: GPS unused).
    pub gps_event_period_s: Option<f64>,
    /// The GPS antenna in the body frame, metres.
    pub gps_offset: Vector3<f64>,
    /// Drift of a sub-map's relative transform as a fraction of its length (1σ per axis).
    pub edge_drift: f64,
}

impl SlamParams {
    /// The seed's values for a ground robot (Dala).
    pub fn ground() -> Self {
        Self {
            rho_init: 0.1,
            sigma_rho: 0.2,
            ..Self::common()
        }
    }

    /// The seed's values for the helicopter (Ressac): points start at 40 m.
    pub fn aerial() -> Self {
        Self {
            rho_init: 0.025,
            sigma_rho: 0.0125,
            ..Self::common()
        }
    }

    fn common() -> Self {
        Self {
            rho_init: 0.1,
            sigma_rho: 0.2,
            max_landmarks: 100,
            per_region: 2,
            sigma_px: 1.0,
            max_search_px: 10.0,
            min_searches: 6,
            gps_event_period_s: Some(30.0),
            gps_offset: Vector3::zeros(),
            edge_drift: 0.03,
        }
    }
}

/// Pilot + stereo VO + local EKF sub-maps.
pub struct SlamStack {
    inner: Box<dyn RobotStack>,
    params: SlamParams,
    vo: StereoVo,
    stereo: String,
    sensor: Sensor,
    body_from_camera: Pose,
    map: LocalMap,
    /// Each point's patch, by id.
    patches: BTreeMap<u64, Patch>,
    next_id: u64,
    /// The global level: one node per sub-map origin (the current one last).
    graph: Graph,
    /// The same origins compounded without events (open loop).
    open_origins: Vec<Pose>,
    /// A GPS fix waiting to become an event at the next frame.
    pending_fix: Option<hetsim_msgs::GpsFix>,
    /// When the last event happened, nanoseconds.
    last_event_ns: u64,
    /// GPS events so far.
    pub gps_events: usize,
    pending_left: Option<Image>,
    last_motion: (Pose, Matrix6<f64>),
    vo_pose: Option<Pose>,
    vo_trajectory: Vec<(u64, Pose)>,
    /// Points of the closed sub-maps: `(sub-map, point in its frame)`.
    closed_points: Vec<(usize, Vector3<f64>)>,
    /// `(stamp, sub-map, pose in the sub-map)` of every frame.
    trajectory: Vec<(u64, usize, Pose)>,
    rng: Lcg,
    truth: Option<Pose>,
    /// Observations used, and rejected by the gate.
    pub updates: (u64, u64),
}

/// A small deterministic generator for RANSAC, seeded by the caller.
struct Lcg(u64);

impl rand::TryRng for Lcg {
    type Error = core::convert::Infallible;
    fn try_next_u32(&mut self) -> Result<u32, Self::Error> {
        Ok((self.try_next_u64()? >> 32) as u32)
    }
    fn try_next_u64(&mut self) -> Result<u64, Self::Error> {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut x = self.0;
        x ^= x >> 33;
        Ok(x)
    }
    fn try_fill_bytes(&mut self, dst: &mut [u8]) -> Result<(), Self::Error> {
        for chunk in dst.chunks_mut(8) {
            let v = self.try_next_u64()?.to_le_bytes();
            chunk.copy_from_slice(&v[..chunk.len()]);
        }
        Ok(())
    }
}

impl SlamStack {
    /// SLAM on the stereo camera named `stereo`, whose left optical frame is at
    /// `body_from_camera`, around `inner`.
    pub fn new(
        inner: Box<dyn RobotStack>,
        stereo: &str,
        bench: Bench,
        body_from_camera: Pose,
        params: SlamParams,
        seed: u64,
    ) -> Self {
        Self {
            inner,
            params,
            vo: StereoVo::new(bench),
            stereo: stereo.to_string(),
            sensor: Sensor::new(bench.camera, &body_from_camera),
            body_from_camera,
            map: LocalMap::new(),
            patches: BTreeMap::new(),
            next_id: 0,
            graph: Graph::default(),
            closed_points: Vec::new(),
            open_origins: Vec::new(),
            pending_fix: None,
            last_event_ns: 0,
            gps_events: 0,
            pending_left: None,
            last_motion: (Pose::identity(), Matrix6::identity() * 1e-4),
            vo_pose: None,
            vo_trajectory: Vec::new(),
            trajectory: Vec::new(),
            rng: Lcg(seed),
            truth: None,
            updates: (0, 0),
        }
    }

    /// Number of sub-maps so far (the current one included).
    pub fn submaps(&self) -> usize {
        self.graph.nodes.len()
    }

    /// The body motion `previous_from_current` and its covariance on `(Δp, δθ)`, from the
    /// camera's `current_from_previous` and its left-perturbation covariance.
    fn body_motion(&self, m: &Pose, cov: &Matrix6<f64>) -> (Pose, Matrix6<f64>) {
        let b = self.body_from_camera;
        let d = b * m.inverse() * b.inverse();
        // δ_body = -Ad_B ξ; Ad_B = [[R, [t]x R], [0, R]].
        let r = b.rotation.to_rotation_matrix().into_inner();
        let mut ad = Matrix6::zeros();
        ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        ad.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(crate::quat::skew(&b.translation.vector) * r));
        ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
        // Right perturbation to additive (Δp, δθ): Δp moves by R_D δρ.
        let mut t = Matrix6::identity();
        t.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&d.rotation.to_rotation_matrix().into_inner());
        let c = t * ad * cov * ad.transpose() * t.transpose();
        // A floor against VO's optimism: 1 mm and 0.05 degree per frame.
        let floor = Matrix6::from_diagonal(&nalgebra::Vector6::new(
            1e-6, 1e-6, 1e-6, 7.6e-7, 7.6e-7, 7.6e-7,
        ));
        (d, (c + c.transpose()) * 0.5 + floor)
    }

    fn on_pair(&mut self, left: &Image, right: &Image) {
        let (l, r) = (
            Gray::from_rgb(left.width as usize, left.height as usize, &left.rgb),
            Gray::from_rgb(right.width as usize, right.height as usize, &right.rgb),
        );
        let motion = self.vo.process(&l, &r, &mut self.rng);
        let Some(truth) = self.truth else {
            return;
        };
        if self.graph.nodes.is_empty() {
            // The first pair: the first sub-map's origin is the robot's pose.
            self.graph.add_node(truth);
            self.open_origins.push(truth);
            self.vo_pose = Some(truth);
        } else {
            let (d, cov) = match &motion {
                Some(m) => {
                    let dm = self.body_motion(&m.current_from_previous, &m.covariance);
                    self.last_motion = dm;
                    dm
                }
                // Lost: constant velocity, with ten times the uncertainty.
                None => (self.last_motion.0, self.last_motion.1 * 10.0),
            };
            self.map.predict(&d, &cov);
            if let Some(v) = self.vo_pose.as_mut() {
                *v *= d;
            }
            self.observe(&l);
        }
        if let Some(fix) = self.pending_fix.take() {
            self.gps_event(&fix, left.stamp_ns);
        }
        self.add_points(&l);
        if self.map.points.len() >= self.params.max_landmarks {
            self.new_submap();
        }
        self.trajectory
            .push((left.stamp_ns, self.graph.nodes.len() - 1, self.map.pose()));
        self.vo_trajectory
            .push((left.stamp_ns, self.vo_pose.expect("set above")));
    }

    fn observe(&mut self, img: &Gray) {
        let sigma = self.params.sigma_px;
        let mut k = 0;
        while k < self.map.points.len() {
            let Some((pr, s)) = self.map.predict_point(&self.sensor, k, sigma) else {
                k += 1;
                continue;
            };
            let inside = pr.pixel.x >= 6.0
                && pr.pixel.y >= 6.0
                && pr.pixel.x < img.width as f64 - 7.0
                && pr.pixel.y < img.height as f64 - 7.0;
            if !inside || s[(0, 0)].max(s[(1, 1)]).sqrt() > self.params.max_search_px {
                k += 1;
                continue;
            }
            self.map.points[k].searched += 1;
            let found = search_ellipse(
                img,
                &self.patches[&self.map.points[k].id],
                [pr.pixel.x, pr.pixel.y],
                [[s[(0, 0)], s[(0, 1)]], [s[(1, 0)], s[(1, 1)]]],
                9.21,
                0.8,
            );
            if let Some(m) = found {
                match self
                    .map
                    .update(&self.sensor, k, &Vector2::new(m.x, m.y), sigma, 9.21)
                {
                    Some(Update::Accepted) => {
                        self.map.points[k].found += 1;
                        self.updates.0 += 1;
                    }
                    Some(Update::Gated(_)) => self.updates.1 += 1,
                    None => {}
                }
            }
            k += 1;
        }
        self.map.symmetrize();
        for id in self.map.prune(self.params.min_searches) {
            self.patches.remove(&id);
        }
    }

    fn add_points(&mut self, img: &Gray) {
        // Where the current points are seen, for the 3 x 3 partition.
        let tracked: Vec<[f64; 2]> = (0..self.map.points.len())
            .filter_map(|k| {
                crate::idp::project(
                    &self.sensor,
                    &self.map.position(),
                    &self.map.quaternion(),
                    &self.map.point(k),
                )
                .map(|p| [p.pixel.x, p.pixel.y])
            })
            .filter(|p| {
                p[0] >= 0.0 && p[1] >= 0.0 && p[0] < img.width as f64 && p[1] < img.height as f64
            })
            .collect();
        let corners: Vec<Corner> = detect(img, 0.01, 8);
        let chosen = select_new(
            &corners,
            img.width,
            img.height,
            &tracked,
            self.params.per_region,
            15.0,
        );
        for c in chosen {
            if self.map.points.len() >= self.params.max_landmarks {
                break;
            }
            let Some(patch) = Patch::at(img, c.x, c.y) else {
                continue;
            };
            let id = self.next_id;
            self.next_id += 1;
            self.map.add_point(
                &self.sensor,
                &Vector2::new(c.x as f64, c.y as f64),
                self.params.sigma_px,
                self.params.rho_init,
                self.params.sigma_rho,
                id,
            );
            self.patches.insert(id, patch);
        }
    }

    /// Closes the current sub-map: the robot pose in it becomes the relative transform to a
    /// new node, and a new local map starts there.
    fn new_submap(&mut self) {
        let relative = self.map.pose();
        // Information of the relative transform. The filter's own covariance comes from
        // VO's, which only knows its random errors; the drift VO shows against the truth
        // (1 to 6 % of the distance in the village) is systematic. The edge therefore gets a
        // drift term of `edge_drift` of the distance travelled in the sub-map (each axis) and
        // 0.1 degree per metre, so that GPS events can pull the origins back.
        let d = relative.translation.vector.norm();
        let (st, sr) = (
            self.params.edge_drift * d + 1e-3,
            (0.1f64.to_radians() * d).max(1e-4),
        );
        let cov = self.map.pose_covariance()
            + Matrix6::from_diagonal(&nalgebra::Vector6::new(
                st * st,
                st * st,
                st * st,
                sr * sr,
                sr * sr,
                sr * sr,
            ));
        let info = cov.try_inverse().unwrap_or_else(Matrix6::identity);
        let last = self.graph.nodes.len() - 1;
        self.closed_points.extend(
            self.map
                .euclidean_points()
                .into_iter()
                .map(|(_, p)| (last, p)),
        );
        let node = self.graph.add_node(self.graph.nodes[last] * relative);
        self.graph.edges.push(Edge {
            from: last,
            to: node,
            z: relative,
            info,
        });
        let open = self.open_origins[last] * relative;
        self.open_origins.push(open);
        self.map = LocalMap::new();
        self.patches.clear();
    }

    /// A GPS fix as an event (seed Section III): a new sub-map starts at the robot's pose, the
    /// fix constrains its origin, and the graph is optimized.
    fn gps_event(&mut self, fix: &hetsim_msgs::GpsFix, stamp_ns: u64) {
        self.new_submap();
        let node = self.graph.nodes.len() - 1;
        let s2 = fix.sigma_m * fix.sigma_m;
        self.graph.priors.push(Prior {
            node,
            offset: self.params.gps_offset,
            position: Vector3::from(fix.position_m),
            info: Matrix3::identity() / s2,
        });
        self.graph.optimize(10);
        self.last_event_ns = stamp_ns;
        self.gps_events += 1;
    }

    /// World poses of the frames through the graph's origins (`optimized`) or the open-loop
    /// ones.
    fn world_trajectory(&self, optimized: bool) -> Vec<(u64, Pose)> {
        self.trajectory
            .iter()
            .map(|(t, node, local)| {
                let origin = if optimized {
                    self.graph.nodes[*node]
                } else {
                    self.open_origins[*node]
                };
                (*t, origin * local)
            })
            .collect()
    }
}

impl RobotStack for SlamStack {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Command {
        for msg in inbox {
            match msg {
                // The latest true pose until the first stereo pair anchors the estimate.
                SensorMsg::TruthPose(p) if self.graph.nodes.is_empty() => self.truth = Some(p.pose),
                SensorMsg::Gps(fix) => {
                    let due = self.params.gps_event_period_s.is_some_and(|period| {
                        fix.stamp_ns >= self.last_event_ns + (period * 1e9) as u64
                    });
                    if due && !self.graph.nodes.is_empty() {
                        self.pending_fix = Some(fix.clone());
                    }
                }
                SensorMsg::Image(img) if img.sensor == format!("{}/left", self.stereo) => {
                    self.pending_left = Some(img.clone())
                }
                SensorMsg::Image(img) if img.sensor == format!("{}/right", self.stereo) => {
                    if let Some(left) = self
                        .pending_left
                        .take()
                        .filter(|l| l.stamp_ns == img.stamp_ns)
                    {
                        self.on_pair(&left, img);
                    }
                }
                _ => {}
            }
        }
        self.inner.step(now_ns, inbox)
    }

    fn status(&self) -> StackStatus {
        self.inner.status()
    }

    fn outbox(&mut self) -> Vec<Outgoing> {
        self.inner.outbox()
    }

    fn map_points(&self) -> Vec<(usize, [f64; 3])> {
        let current = self.graph.nodes.len().saturating_sub(1);
        self.closed_points
            .iter()
            .copied()
            .chain(
                self.map
                    .euclidean_points()
                    .into_iter()
                    .map(|(_, p)| (current, p)),
            )
            .filter_map(|(node, p)| {
                let w = self.graph.nodes.get(node)? * nalgebra::Point3::from(p);
                Some((node, [w.x, w.y, w.z]))
            })
            .collect()
    }

    fn trajectories(&self) -> Vec<(String, Vec<(u64, Pose)>)> {
        let mut t = self.inner.trajectories();
        t.push(("vo".to_string(), self.vo_trajectory.clone()));
        t.push(("slam".to_string(), self.world_trajectory(true)));
        t.push(("slam-open".to_string(), self.world_trajectory(false)));
        t
    }
}
