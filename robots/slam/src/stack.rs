//! A robot stack running the local level of the hierarchical SLAM beside another stack (the
//! waypoint pilot): stereo VO for the motion prediction, monocular point and line-segment
//! observations from the bench's left camera, and a new sub-map every `max_landmarks`
//! landmarks (seed Sections II, IV and V).
//!
//! Per stereo pair:
//! 1. stereo VO gives the left camera's motion and covariance; it is turned into the body's
//!    motion (`B M⁻¹ B⁻¹`, covariance through the adjoint of `B = body_from_camera`) and
//!    predicts the local map;
//! 2. every point is predicted into the left image with its innovation covariance `S`, and
//!    searched there by ZNCC of the patch taken when it was initialized, inside the 99 %
//!    ellipse of `S` (when `S` is small enough to search); a match updates the map unless the
//!    Mahalanobis gate rejects it;
//! 3. then the lines (seed Section V: the points' updated pose serves the segment tracker):
//!    each line's segment is predicted into the image from its 3D endpoints, clipped to the
//!    image, and tracked there ([`hetsim_vision::segments::track`], searching 3σ of the
//!    innovation along its normal); the tracked segment updates the line unless the gate
//!    rejects it, and extends its endpoints ([`crate::lines`]);
//! 4. the deletion policy of [`crate::ekf`] removes unreliable points and lines;
//! 5. new points are initialized (undelayed, inverse depth) from Harris corners so that each
//!    region of a regular 3 x 3 partition of the image has at least `per_region` points;
//!    new lines from LSD segments longer than `min_line_px` (seed: 60 px at 1024 px wide,
//!    scaled with the image width) that no mapped line already covers, while fewer than
//!    `max_visible_lines` are tracked (detection runs every `line_detect_period` frames: it
//!    is the costliest step);
//! 6. when the map holds `max_landmarks` landmarks (points and lines together), it is
//!    closed: the robot pose in it (mean and covariance) becomes the relative transform to
//!    the next sub-map, whose origin is that pose.
//!
//! 7. events (seed Section III) start a new sub-map at the frame they happen, link its origin,
//!    and the team's graph ([`crate::global`]) is optimized:
//!    * a rendezvous (this robot's rendezvous sensor sees another robot; once per robot per
//!      `rendezvous_period_s`) links the origin to the other robot's origin made at the same
//!      stamp: both robots see each other and both start a sub-map then (a full rendezvous);
//!    * an image match (the emulated matcher found one of another robot's key frames, i.e.
//!      sub-map origins, under this robot; once per robot per `image_match_period_s`, so
//!      that one pass over the other robot's path gives one link, not one per nearby origin)
//!      links the origin to that past origin.
//! 8. the robot's part of the graph goes to every robot it has met, over the radio, after each
//!    event and every `share_period_s`; parts received are merged and the graph optimized.
//!
//! Frames: the first sub-map's origin is the identity of the robot's own frame, its pose at
//! the first pair; the robot reads no truth. The scenario's first robot (`reference_robot`,
//! Dala in the village) is the team's frame, as in the seed; another robot's estimates move
//! into it once an event links the two ([`crate::global`]). GPS fixes are not events: they
//! are world positions, and no robot knows where its frame lies in the world (that would take
//! a world-frame node in the graph; see docs/known-gaps.md). Every frame is kept as
//! (sub-map, pose in it, its covariance), and written through the graph's optimized origins
//! (`slam/<robot>.tum`) and through the origins compounded without events
//! (`slam-open/<robot>.tum`, the open-loop estimate); the chained VO alone is
//! `vo/<robot>.tum`. With `cooperative` off there are no events and no radio.

use crate::ekf::{LocalMap, Update};
use crate::global::{relative_info, Anchor, Global, Link, Share};
use crate::idp::Sensor;
use crate::report::{EventLink, SlamEvent, SlamReport, REPORT_ARTIFACT};
use hetsim_msgs::{
    Artifact, ArtifactData, Delivered, Image, ImageMatch, Outgoing, Pose, Rendezvous, SensorMsg,
};
use hetsim_vision::harris::{select_new, Corner};
use hetsim_vision::matching::{search_pyramid, Template};
use hetsim_vision::segments::{self, Segment};
use hetsim_vision::stereo::Bench;
use hetsim_vision::vo::StereoVo;
use hetsim_vision::Gray;
use nalgebra::{Matrix6, Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

mod landmarks;

mod pipeline;
pub use pipeline::SlamStack;

mod events;

mod params;
pub use params::{EdgeDrift, SlamParams};

mod table;
pub use table::{SlamTable, SlamTableError};

mod places;
pub use places::PLACE_TOPIC;

/// The radio topic of a robot's part of the graph.
pub const SHARE_TOPIC: &str = "slam/graph";

/// Pilot + stereo VO + local EKF sub-maps + the team's graph.
pub struct SlamCore {
    robot: String,
    params: SlamParams,
    bench: Bench,
    vo: StereoVo,
    sensor: Sensor,
    body_from_camera: Pose,
    map: LocalMap,
    /// Each point's patch, by id.
    patches: BTreeMap<u64, Template>,
    next_id: u64,
    /// The team's graph (from the first pair on); this robot's origins first.
    global: Option<Global>,
    /// This robot's origins compounded without events (open loop).
    open_origins: Vec<Pose>,
    /// A rendezvous and an image match waiting for their frame.
    pending_rendezvous: Option<Rendezvous>,
    pending_match: Option<ImageMatch>,
    /// When the last event happened, nanoseconds.
    last_event_ns: u64,
    /// The last link event of each kind with each robot, nanoseconds.
    last_link: BTreeMap<(&'static str, String), u64>,
    /// Robots met (by an event or a part received): the radio's addressees.
    peers: std::collections::BTreeSet<String>,
    /// When this robot's part was last sent, nanoseconds.
    last_share_ns: Option<u64>,
    outgoing: Vec<Outgoing>,
    /// Events so far.
    events: Vec<SlamEvent>,
    counters: BTreeMap<String, u64>,
    last_motion: (Pose, Matrix6<f64>),
    vo_pose: Option<Pose>,
    vo_trajectory: Vec<(u64, Pose)>,
    /// Points of the closed sub-maps: `(sub-map, point in its frame)`.
    closed_points: Vec<(usize, Vector3<f64>)>,
    /// Segments of the closed sub-maps: `(sub-map, endpoints in its frame)`.
    closed_segments: Vec<(usize, [Vector3<f64>; 2])>,
    /// The lines' segments in the current frame, tracked or predicted (where new ones must
    /// not be added).
    seen_segments: Vec<Segment>,
    /// `(stamp, sub-map, pose in the sub-map, its covariance)` of every frame.
    trajectory: Vec<(u64, usize, Pose, Matrix6<f64>)>,
    /// RANSAC's generator for the VO, seeded by the caller.
    rng: ChaCha8Rng,
    /// Key frames: this robot's (one per origin) and those received.
    places: Vec<places::Place>,
    /// How many of this robot's key frames each robot met has been sent.
    places_sent: BTreeMap<String, usize>,
    /// When image matching was last tried, nanoseconds.
    last_match_attempt_ns: Option<u64>,
    /// The graph's joint covariance and the graph version it is of.
    covariance: Option<(u64, crate::graph::Covariance)>,
    /// RANSAC's generator for image matching, a stream of its own so that trying a match
    /// does not move the VO's draws.
    match_rng: ChaCha8Rng,
    /// Observations used, and rejected by the gate.
    pub updates: (u64, u64),
    /// The robot whose first origin this robot's estimates moved into at the last change of
    /// frame, and this robot's first origin in it as the graph had it right then (see
    /// [`SlamReport::own_origin_at_link`]).
    origin_at_link: Option<(String, Pose)>,
}

/// A point of a sub-map in the world frame, given the sub-map's origin.
fn to_world(origin: &Pose, p: &Vector3<f64>) -> [f64; 3] {
    let w = origin * nalgebra::Point3::from(*p);
    [w.x, w.y, w.z]
}

/// Whether the tracked segment `t` already covers the detected `d`: nearly parallel (10
/// degrees), `d`'s midpoint within 6 pixels of `t`'s line, and overlapping along it.
fn covers(t: &Segment, d: &Segment) -> bool {
    let mid = [(d.a[0] + d.b[0]) / 2.0, (d.a[1] + d.b[1]) / 2.0];
    let (s0, s1) = (t.abscissa(d.a), t.abscissa(d.b));
    t.direction().dot(&d.direction()).abs() > 10f64.to_radians().cos()
        && t.line_distance(mid).abs() < 6.0
        && s0.max(s1) > 0.0
        && s0.min(s1) < t.length()
}

impl SlamCore {
    /// SLAM for robot `robot` on a stereo bench whose left optical frame is at
    /// `body_from_camera`.
    pub fn new(
        robot: &str,
        bench: Bench,
        body_from_camera: Pose,
        params: SlamParams,
        seed: u64,
    ) -> Self {
        Self {
            robot: robot.to_string(),
            params,
            bench,
            vo: StereoVo::new(bench),
            sensor: Sensor::new(bench.camera, &body_from_camera),
            body_from_camera,
            map: LocalMap::new(),
            patches: BTreeMap::new(),
            next_id: 0,
            global: None,
            closed_points: Vec::new(),
            closed_segments: Vec::new(),
            seen_segments: Vec::new(),
            open_origins: Vec::new(),
            pending_rendezvous: None,
            pending_match: None,
            last_event_ns: 0,
            last_link: BTreeMap::new(),
            peers: Default::default(),
            last_share_ns: None,
            outgoing: Vec::new(),
            events: Vec::new(),
            counters: BTreeMap::new(),
            last_motion: (Pose::identity(), Matrix6::identity() * 1e-4),
            vo_pose: None,
            vo_trajectory: Vec::new(),
            trajectory: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            places: Vec::new(),
            places_sent: BTreeMap::new(),
            last_match_attempt_ns: None,
            covariance: None,
            match_rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5bd1_e995_9e37_79b9),
            updates: (0, 0),
            origin_at_link: None,
        }
    }

    /// Number of sub-maps so far (the current one included).
    pub fn submaps(&self) -> usize {
        self.global.as_ref().map_or(0, Global::len)
    }

    /// Events of a kind so far.
    pub fn events_of(&self, kind: &str) -> usize {
        self.events.iter().filter(|e| e.kind == kind).count()
    }

    fn count(&mut self, what: &str, n: u64) {
        *self.counters.entry(what.to_string()).or_default() += n;
    }

    /// The robot whose first origin is the frame of the pose estimates ([`Global::frame`]).
    fn frame(&self) -> &str {
        self.global.as_ref().map_or(&self.robot, |g| g.frame())
    }

    /// The current pose estimate in [`SlamCore::frame`]: the current origin and the pose in
    /// its map.
    fn world_pose(&self) -> Pose {
        let g = self
            .global
            .as_ref()
            .expect("events come after the first pair");
        g.origin(g.len() - 1) * self.map.pose()
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
        // The inbox guard and the bench's own check refused any image whose bytes are not its
        // size, so both convert; a pair that did not would be skipped, not read past its end.
        let (Some(l), Some(r)) = (Gray::from_image(left), Gray::from_image(right)) else {
            return;
        };
        let motion = self.vo.process(&l, &r, &mut self.rng);
        let stamp = left.stamp_ns;
        if self.global.is_none() {
            // The first pair: the first sub-map's origin is the identity of the robot's own
            // frame (seed Section V); only an event places it in another robot's.
            let reference = self
                .params
                .reference_robot
                .as_deref()
                .unwrap_or(&self.robot);
            self.global = Some(Global::new(&self.robot, reference, stamp));
            self.open_origins.push(Pose::identity());
            self.vo_pose = Some(Pose::identity());
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
            self.map
                .predict(&d, &(cov * self.params.vo_covariance_scale));
            if let Some(v) = self.vo_pose.as_mut() {
                *v *= d;
            }
            self.observe(&l);
        }
        if let Some(r) = self.pending_rendezvous.take_if(|r| r.stamp_ns <= stamp) {
            let info = relative_info(r.sigma_m, r.sigma_rad);
            self.link_event(
                "rendezvous",
                (&r.other, r.stamp_ns),
                r.relative,
                info,
                stamp,
            );
            self.last_link.insert(("rendezvous", r.other), r.stamp_ns);
        }
        if let Some(m) = self.pending_match.take_if(|m| m.stamp_ns <= stamp) {
            // The emulated matcher of the robot file's `image_match` oracle (ablations only).
            let info = relative_info(m.sigma_m, m.sigma_rad);
            let link = (m.other.as_str(), m.other_stamp_ns);
            self.link_event("image_match", link, m.relative, info, stamp);
            self.last_link.insert(("image_match", m.other), m.stamp_ns);
        }
        if let Some(f) = self.try_match(&l, stamp) {
            let cov = f.cov;
            let info = cov.try_inverse().unwrap_or_else(Matrix6::identity);
            self.link_event("image_match", (&f.robot, f.stamp_ns), f.z, info, stamp);
            if let Some(e) = self.events.last_mut() {
                if let Some(link) = e.link.as_mut() {
                    link.inliers = Some(f.inliers);
                    link.mahalanobis2 = Some(f.mahalanobis2);
                }
            }
            self.last_link.insert(("image_match", f.robot), stamp);
        }
        self.add_points(&l);
        if self.params.lines {
            self.add_lines(&l);
        }
        if self.map.landmarks() >= self.params.max_landmarks {
            self.new_submap(stamp);
        }
        self.keep_place(&l, stamp);
        self.trajectory.push((
            stamp,
            self.submaps() - 1,
            self.map.pose(),
            self.map.pose_covariance(),
        ));
        self.vo_trajectory
            .push((left.stamp_ns, self.vo_pose.expect("set above")));
    }

    /// World poses of the frames through the graph's origins (`optimized`) or the open-loop
    /// ones.
    fn world_trajectory(&self, optimized: bool) -> Vec<(u64, Pose)> {
        let Some(g) = self.global.as_ref() else {
            return Vec::new();
        };
        self.trajectory
            .iter()
            .map(|(t, node, local, _)| {
                let origin = if optimized {
                    g.origin(*node)
                } else {
                    self.open_origins[*node]
                };
                (*t, origin * local)
            })
            .collect()
    }
}

/// What the SLAM core is given, in the order the robot received it.
pub(crate) enum Event {
    /// A message other than the stereo images.
    Msg(SensorMsg),
    /// A stereo pair (left, right) with the same stamp.
    Pair(Box<(Image, Image)>),
    /// The end of a step at this time (when the graph may be shared).
    Tick(u64),
}

impl SlamCore {
    /// Processes one event, exactly as the stack's step met it.
    pub(crate) fn handle(&mut self, event: Event) {
        match event {
            Event::Pair(pair) => self.on_pair(&pair.0, &pair.1),
            Event::Tick(now_ns) => {
                let period = (self.params.share_period_s * 1e9) as u64;
                if self.last_share_ns.is_none_or(|t| now_ns >= t + period) {
                    // Nothing goes out before a robot has been met.
                    self.share(now_ns);
                }
            }
            Event::Msg(msg) => self.on_message(&msg),
        }
        self.note_frame_change();
    }

    /// Keeps this robot's first origin in the frame its estimates have just moved into, as
    /// the graph has it once optimized with the link that moved them: where that link put
    /// the robot, before any later event refined it. A robot's frame changes once at most
    /// (from its own to the component's gauge, the reference robot's where present:
    /// [`Global::frame`]), so the first change is the one kept.
    fn note_frame_change(&mut self) {
        if self.origin_at_link.is_some() {
            return;
        }
        if let Some(g) = self.global.as_ref().filter(|g| g.frame() != self.robot) {
            self.origin_at_link = Some((g.frame().to_string(), g.origin(0)));
        }
    }

    fn on_message(&mut self, msg: &SensorMsg) {
        match msg {
            // Events need the first origin (made at the first stereo pair); open loop uses
            // none.
            _ if self.global.is_none() || !self.params.cooperative => {}
            SensorMsg::Rendezvous(r) => {
                let period = self.params.rendezvous_period_s;
                if self.pending_rendezvous.is_none()
                    && self.link_due("rendezvous", &r.other, r.stamp_ns, period)
                {
                    self.pending_rendezvous = Some(r.clone());
                }
            }
            SensorMsg::ImageMatch(m) => {
                let period = self.params.image_match_period_s;
                if self.pending_match.is_none()
                    && self.link_due("image_match", &m.other, m.stamp_ns, period)
                {
                    self.pending_match = Some(m.clone());
                }
            }
            SensorMsg::Comms(d) if d.topic == SHARE_TOPIC => self.receive(d),
            SensorMsg::Comms(d) if d.topic == PLACE_TOPIC => self.receive_place(d),
            _ => {}
        }
    }

    /// The radio messages produced since the last call.
    pub(crate) fn take_outgoing(&mut self) -> Vec<Outgoing> {
        std::mem::take(&mut self.outgoing)
    }

    /// The stamps of the key frames (sub-map origins) so far.
    pub(crate) fn keyframes(&self) -> &[u64] {
        self.global.as_ref().map_or(&[], |g| &g.own.stamps)
    }

    /// What the core publishes at the end (the pilot's artifacts come from the shell).
    pub(crate) fn artifacts(&self) -> Vec<Artifact> {
        let mut out = vec![
            Artifact::trajectory("vo", self.vo_trajectory.clone()),
            Artifact::trajectory("slam", self.world_trajectory(true)),
            Artifact::trajectory("slam-open", self.world_trajectory(false)),
            Artifact {
                name: "map".into(),
                data: ArtifactData::Map {
                    points: self.map_points(),
                    segments: self.map_segments(),
                },
            },
        ];
        if let Some(report) = self.report() {
            out.push(Artifact::report(REPORT_ARTIFACT, &report));
        }
        out
    }
}

impl SlamCore {
    /// The global level's report for evaluation: origins with marginal covariance, the
    /// covariance of every pose of the `slam` trajectory, events, counters.
    pub fn report(&self) -> Option<SlamReport> {
        let g = self.global.as_ref()?;
        let marginals = g.own_covariances();
        let origins = (0..g.len())
            .map(|k| {
                (
                    g.own.stamps[k],
                    g.origin(k),
                    marginals[k].as_slice().to_vec(),
                )
            })
            .collect();
        // A frame's world pose is its origin compounded with its pose in the sub-map.
        let covariances = self
            .trajectory
            .iter()
            .map(|(_, node, local, cov)| {
                let (_, c) =
                    crate::graph::compound(&g.origin(*node), &marginals[*node], local, cov);
                c.as_slice().to_vec()
            })
            .collect();
        let mut counters = self.counters.clone();
        counters.insert("observations_used".into(), self.updates.0);
        counters.insert("observations_gated".into(), self.updates.1);
        counters.insert("unresolved_links".into(), g.unresolved as u64);
        counters.insert("submaps".into(), g.len() as u64);
        Some(SlamReport {
            frame: g.frame().to_string(),
            own_origin_at_link: self.origin_at_link.clone(),
            frame_start_ns: if g.frame() == self.robot {
                g.own.stamps.first().copied()
            } else {
                g.others
                    .get(g.frame())
                    .and_then(|s| s.stamps.first().copied())
            },
            origins,
            covariances,
            events: self.events.clone(),
            counters,
            keyframes: self
                .places
                .iter()
                .filter(|p| p.robot == self.robot)
                .map(|p| (p.stamp_ns, p.frame.median_depth()))
                .collect(),
        })
    }

    /// Mapped points in the world frame, with their sub-map.
    pub fn map_points(&self) -> Vec<(usize, [f64; 3])> {
        let current = self.map.euclidean_points().into_iter().map(|(_, p)| p);
        self.in_world(&self.closed_points, current, |origin, p| {
            to_world(origin, &p)
        })
    }

    /// Mapped segments in the world frame, with their sub-map.
    pub fn map_segments(&self) -> Vec<(usize, [[f64; 3]; 2])> {
        let current = self
            .map
            .euclidean_segments(self.params.line_output_spread)
            .into_iter()
            .map(|(_, e)| e);
        self.in_world(&self.closed_segments, current, |origin, e| {
            e.map(|p| to_world(origin, &p))
        })
    }
}
