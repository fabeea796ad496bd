//! The SLAM stack's global level: sub-maps closed at their origins, rendezvous and image-match events, the team's graph exchanged over the radio.

use super::*;

impl SlamCore {
    /// Closes the current sub-map at the frame `stamp`: the robot pose in it becomes the
    /// relative transform to a new node, and a new local map starts there.
    pub(super) fn new_submap(&mut self, stamp: u64) {
        let relative = self.map.pose();
        // Information of the relative transform: the filter's own covariance, which comes
        // from VO's random errors, and the drift VO shows against the truth, which is
        // systematic (`EdgeDrift`), so that events can pull the origins back.
        let d = relative.translation.vector.norm();
        let cov = self.map.pose_covariance() + self.params.edge_drift.covariance(d);
        let info = cov.try_inverse().unwrap_or_else(Matrix6::identity);
        let last = self.submaps() - 1;
        self.closed_points.extend(
            self.map
                .euclidean_points()
                .into_iter()
                .map(|(_, p)| (last, p)),
        );
        self.closed_segments.extend(
            self.map
                .euclidean_segments(self.params.line_output_spread)
                .into_iter()
                .map(|(_, e)| (last, e)),
        );
        self.global
            .as_mut()
            .expect("a sub-map closes after the first pair")
            .push(stamp, relative, info);
        let open = self.open_origins[last] * relative;
        self.open_origins.push(open);
        self.map = LocalMap::new();
        self.patches.clear();
    }

    /// The origin for an event at frame `stamp`: a new sub-map starts there (the seed starts
    /// one after every event), unless one already started at this frame.
    pub(super) fn event_node(&mut self, stamp: u64) -> usize {
        let g = self
            .global
            .as_ref()
            .expect("events come after the first pair");
        if g.own.stamps.last() != Some(&stamp) {
            self.new_submap(stamp);
        }
        self.submaps() - 1
    }

    /// Optimizes the team's graph after an event and logs it; the part goes to the peers.
    /// `before` is the robot's pose estimate before the event, in the frame of `frame_before`.
    pub(super) fn after_event(
        &mut self,
        kind: &str,
        other: &str,
        stamp: u64,
        (before, frame_before): (Pose, String),
        link: Option<EventLink>,
    ) {
        let g = self
            .global
            .as_mut()
            .expect("events come after the first pair");
        g.optimize();
        let frame_after = g.frame().to_string();
        let after = self.world_pose();
        self.events.push(SlamEvent {
            kind: kind.to_string(),
            stamp_ns: stamp,
            other: other.to_string(),
            before,
            after,
            frame_before,
            frame_after,
            link,
        });
        self.last_event_ns = stamp;
        self.share(stamp);
    }

    /// A link event (seed Sections III and V): the origin made now is linked to the other
    /// robot's origin of stamp `link.1` by the measured `self_from_other` `z`, whose position
    /// information is `info`. For a rendezvous that is the origin the other
    /// robot made at the same frame (it saw this robot too); for an image match, the past
    /// origin whose frame matched.
    pub(super) fn link_event(
        &mut self,
        kind: &str,
        link: (&str, u64),
        z: Pose,
        info: Matrix6<f64>,
        stamp: u64,
    ) {
        let (other, other_stamp_ns) = link;
        let before = (self.world_pose(), self.frame().to_string());
        let node = self.event_node(stamp);
        self.global
            .as_mut()
            .expect("after the first pair")
            .link(Link {
                kind: kind.to_string(),
                node,
                other: other.to_string(),
                other_stamp_ns,
                z,
                info,
            });
        self.peers.insert(other.to_string());
        let cov = info.try_inverse().unwrap_or_else(Matrix6::zeros);
        let link = EventLink {
            other_stamp_ns,
            z,
            covariance: cov.as_slice().to_vec(),
            inliers: None,
            mahalanobis2: None,
        };
        self.after_event(kind, other, stamp, before, Some(link));
    }

    /// Whether a link event of `kind` with `other` at `stamp_ns` is due: none with that
    /// robot in the last `period_s`.
    pub(super) fn link_due(
        &self,
        kind: &'static str,
        other: &str,
        stamp_ns: u64,
        period_s: f64,
    ) -> bool {
        self.last_link
            .get(&(kind, other.to_string()))
            .is_none_or(|t| stamp_ns >= t + (period_s * 1e9) as u64)
    }

    /// The closed sub-maps' landmarks and the current map's, with their sub-maps, through the
    /// graph's origins by `place` (nothing before the first pair).
    pub(super) fn in_world<T: Copy, W>(
        &self,
        closed: &[(usize, T)],
        current: impl Iterator<Item = T>,
        place: impl Fn(&Pose, T) -> W,
    ) -> Vec<(usize, W)> {
        let Some(g) = self.global.as_ref() else {
            return Vec::new();
        };
        let node = g.len() - 1;
        closed
            .iter()
            .copied()
            .chain(current.map(|x| (node, x)))
            .map(|(k, x)| (k, place(&g.origin(k), x)))
            .collect()
    }

    /// Sends this robot's part of the graph to every robot met.
    pub(super) fn share(&mut self, now_ns: u64) {
        let Some(g) = self.global.as_ref() else {
            return;
        };
        if !self.params.cooperative || self.peers.is_empty() {
            return;
        }
        let payload = serde_json::to_vec(&g.own).expect("a share serializes");
        for to in &self.peers {
            self.outgoing.push(Outgoing {
                to: to.clone(),
                topic: SHARE_TOPIC.to_string(),
                payload: payload.clone(),
            });
        }
        self.count("shares_sent", self.peers.len() as u64);
        self.last_share_ns = Some(now_ns);
        self.send_places();
    }

    /// Another robot's part arrived. If its links name frames of this robot that are not
    /// origins (the other robot saw this one, which did not see it then: a partial
    /// rendezvous), this robot publishes those frames as anchors, which resolves the links:
    /// for this robot that is the event, logged with the error before and after it.
    pub(super) fn receive(&mut self, d: &Delivered) {
        let Ok(share) = serde_json::from_slice::<Share>(&d.payload) else {
            self.count("shares_malformed", 1);
            return;
        };
        if self.global.is_none() {
            return;
        }
        let before = (self.world_pose(), self.frame().to_string());
        let sender = share.robot.clone();
        let kinds: BTreeMap<u64, String> = share
            .links
            .iter()
            .map(|l| (l.other_stamp_ns, l.kind.clone()))
            .collect();
        let g = self.global.as_mut().expect("checked above");
        self.peers.insert(sender.clone());
        let changed = g.receive(share);
        let mut anchored = None;
        for stamp in g.wanted_anchors() {
            // The frame at that stamp (frames are in stamp order); a stamp of no frame (before
            // the first pair, or between frames) cannot be anchored and stays unresolved.
            let Ok(i) = self.trajectory.binary_search_by_key(&stamp, |f| f.0) else {
                continue;
            };
            let (_, node, pose, cov) = self.trajectory[i];
            g.anchor(Anchor {
                stamp_ns: stamp,
                node,
                pose,
                cov,
            });
            anchored = Some(stamp);
        }
        match anchored {
            Some(stamp) => {
                let kind = kinds
                    .get(&stamp)
                    .cloned()
                    .unwrap_or_else(|| "rendezvous".into());
                let at = self.trajectory.last().map_or(stamp, |f| f.0);
                self.count("anchors", 1);
                self.after_event(&kind, &sender, at, before, None);
            }
            None if changed => {
                g.optimize();
            }
            None => {}
        }
        self.count("shares_received", 1);
    }
}
