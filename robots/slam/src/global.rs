//! The multi-robot global level (seed Section III): each robot keeps the graph of sub-map
//! origins of the whole team, built from its own part and the parts the others sent it.
//!
//! A robot's part ([`Share`]) is what the seed says is exchanged: its sub-map origins (stamp
//! and current estimate), the relative transforms between consecutive ones, its GPS fixes,
//! and the event links it measured (rendezvous, image matching) from one of its origins to
//! another robot's origin, named by that robot and the origin's stamp. The local maps never
//! travel. A robot rebuilds its joint [`Graph`] when its part changes or a part arrives, and
//! optimizes it (Gauss-Newton over the whole graph: the team's graphs are small).
//!
//! Gauge: every robot's first origin is its start pose, held fixed (the seed takes Dala's first
//! map as the world frame and Ressac starts above Dala; here each robot is given its start
//! pose, and the events correct the drift after it).

pub use crate::graph::relative_info;
use crate::graph::{Edge, Graph, Prior};
use nalgebra::{Isometry3, Matrix3, Matrix6, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// An event link measured by the robot that owns the share.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Link {
    /// What produced it: `"rendezvous"` or `"image_match"`.
    pub kind: String,
    /// The owner's origin (index in its part).
    pub node: usize,
    /// The other robot.
    pub other: String,
    /// The stamp of the other robot's origin, nanoseconds.
    pub other_stamp_ns: u64,
    /// Measured `T_node⁻¹ T_other` (`self_from_other`).
    pub z: Isometry3<f64>,
    /// Its information (right perturbation).
    pub info: Matrix6<f64>,
}

/// A GPS fix on one of the owner's origins.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fix {
    /// The owner's origin.
    pub node: usize,
    /// The antenna in the body frame.
    pub offset: Vector3<f64>,
    /// The measured antenna position.
    pub position: Vector3<f64>,
    /// Its information.
    pub info: Matrix3<f64>,
}

/// One robot's part of the global graph, as sent over the radio.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Share {
    /// The owner.
    pub robot: String,
    /// Stamps of its origins, nanoseconds.
    pub stamps: Vec<u64>,
    /// Its current estimates of its origins (initial values for the receiver).
    pub poses: Vec<Isometry3<f64>>,
    /// `chain[k]`: measured origin `k` to origin `k + 1`, with information.
    pub chain: Vec<(Isometry3<f64>, Matrix6<f64>)>,
    /// GPS fixes.
    pub fixes: Vec<Fix>,
    /// Event links.
    pub links: Vec<Link>,
}

impl Share {
    /// Whether `other` carries the same origins and constraints (its pose estimates aside).
    fn same_constraints(&self, other: &Share) -> bool {
        self.stamps == other.stamps
            && self.chain == other.chain
            && self.fixes == other.fixes
            && self.links == other.links
    }
}

/// A robot's view of the team's graph.
#[derive(Clone, Debug, Default)]
pub struct Global {
    /// This robot's part.
    pub own: Share,
    /// The latest part received from each other robot.
    pub others: BTreeMap<String, Share>,
    /// The joint graph (this robot's origins first, in order).
    pub graph: Graph,
    /// `(robot, origin)` of each graph node.
    keys: Vec<(String, usize)>,
    /// Event links whose other origin is not known here yet.
    pub unresolved: usize,
}

impl Global {
    /// The global level of robot `robot`, whose first origin is `start` at `stamp_ns`.
    pub fn new(robot: &str, start: Isometry3<f64>, stamp_ns: u64) -> Self {
        let mut g = Self {
            own: Share {
                robot: robot.to_string(),
                ..Share::default()
            },
            ..Self::default()
        };
        g.own.stamps.push(stamp_ns);
        g.own.poses.push(start);
        g.rebuild();
        g
    }

    /// Number of this robot's origins.
    pub fn len(&self) -> usize {
        self.own.stamps.len()
    }

    /// Whether there are none (never: the first exists from the start).
    pub fn is_empty(&self) -> bool {
        self.own.stamps.is_empty()
    }

    /// The current estimate of this robot's origin `k`.
    pub fn origin(&self, k: usize) -> Isometry3<f64> {
        self.graph.nodes[k]
    }

    /// A new origin at `stamp_ns`, `z` from the last one with information `info`; returns its
    /// index.
    pub fn push(&mut self, stamp_ns: u64, z: Isometry3<f64>, info: Matrix6<f64>) -> usize {
        let last = self.len() - 1;
        let pose = self.origin(last) * z;
        self.own.stamps.push(stamp_ns);
        self.own.poses.push(pose);
        self.own.chain.push((z, info));
        // Appended in place (own origins come first in the joint graph, so the others' keys
        // shift by one; rebuilding keeps it simple and exact).
        self.rebuild();
        self.len() - 1
    }

    /// A GPS fix on origin `node`.
    pub fn fix(&mut self, fix: Fix) {
        self.own.fixes.push(fix);
        self.rebuild();
    }

    /// An event link from one of this robot's origins.
    pub fn link(&mut self, link: Link) {
        self.own.links.push(link);
        self.rebuild();
    }

    /// Another robot's part arrived (a newer one replaces the older).
    /// Returns whether the graph changed: a part with the constraints already known (the
    /// periodic re-sending) changes nothing and needs no optimization.
    pub fn receive(&mut self, share: Share) -> bool {
        if share.robot == self.own.robot {
            return false;
        }
        let changed = self.others.get(&share.robot).is_none_or(|old| {
            share.stamps.len() >= old.stamps.len() && !old.same_constraints(&share)
        });
        if changed {
            self.others.insert(share.robot.clone(), share);
            self.rebuild();
        }
        changed
    }

    /// Optimizes the joint graph; returns the final cost.
    pub fn optimize(&mut self) -> f64 {
        let cost = self.graph.optimize(10);
        for (i, (robot, k)) in self.keys.iter().enumerate() {
            if *robot == self.own.robot {
                self.own.poses[*k] = self.graph.nodes[i];
            }
        }
        cost
    }

    /// Marginal covariances of this robot's origins.
    pub fn own_covariances(&self) -> Vec<Matrix6<f64>> {
        let m = self.graph.marginals();
        m[..self.len()].to_vec()
    }

    /// Rebuilds the joint graph from the parts, starting from the current estimates.
    fn rebuild(&mut self) {
        let current: BTreeMap<(String, usize), Isometry3<f64>> = self
            .keys
            .iter()
            .cloned()
            .zip(self.graph.nodes.iter().copied())
            .collect();
        let mut graph = Graph::default();
        let mut keys = Vec::new();
        let mut index = BTreeMap::new();
        let parts: Vec<&Share> = std::iter::once(&self.own)
            .chain(self.others.values())
            .collect();
        for part in &parts {
            for (k, pose) in part.poses.iter().enumerate() {
                let key = (part.robot.clone(), k);
                let at = *current.get(&key).unwrap_or(pose);
                index.insert(key.clone(), graph.add_node(at));
                keys.push(key);
            }
            graph.anchors.push(index[&(part.robot.clone(), 0)]);
        }
        let mut unresolved = 0;
        for part in &parts {
            let node = |k: usize| index[&(part.robot.clone(), k)];
            for (k, (z, info)) in part.chain.iter().enumerate() {
                graph.edges.push(Edge {
                    from: node(k),
                    to: node(k + 1),
                    z: *z,
                    info: *info,
                });
            }
            for f in &part.fixes {
                graph.priors.push(Prior {
                    node: node(f.node),
                    offset: f.offset,
                    position: f.position,
                    info: f.info,
                });
            }
            for l in &part.links {
                let other = parts
                    .iter()
                    .find(|p| p.robot == l.other)
                    .and_then(|p| p.stamps.iter().position(|t| *t == l.other_stamp_ns));
                match other {
                    Some(j) => graph.edges.push(Edge {
                        from: node(l.node),
                        to: index[&(l.other.clone(), j)],
                        z: l.z,
                        info: l.info,
                    }),
                    None => unresolved += 1,
                }
            }
        }
        self.graph = graph;
        self.keys = keys;
        self.unresolved = unresolved;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::exp;
    use nalgebra::{Translation3, UnitQuaternion, Vector6};

    fn step(x: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        )
    }

    /// Two robots drive; B's chain has a biased odometry. A link from B's last origin to A's
    /// origin, sent to A over the "radio" (a serialized share) and known to B, pulls B's end
    /// back on both robots' graphs, which agree.
    #[test]
    fn a_link_between_two_robots_corrects_the_drifting_one_on_both_sides() {
        let start_a = Isometry3::identity();
        let start_b = step(0.0, 0.3);
        let mut a = Global::new("a", start_a, 0);
        let mut b = Global::new("b", start_b, 0);
        let mut truth_b = start_b;
        let mut truth_a = vec![start_a];
        for k in 1..=10u64 {
            let z = step(2.0, 0.05);
            a.push(k * 1000, z, relative_info(0.01, 0.001));
            truth_a.push(truth_a.last().unwrap() * z);
            truth_b *= z;
            // B's odometry overestimates the distance by 5 % and turns 0.01 rad too much.
            let biased = step(2.1, 0.06);
            b.push(k * 1000, biased, relative_info(0.1, 0.01));
        }
        let before = (b.origin(10).translation.vector - truth_b.translation.vector).norm();
        let open_cov = b.own_covariances()[10];
        // B sees A's origin 4 from its last origin.
        let z =
            truth_b.inverse() * truth_a[4] * exp(&Vector6::new(0.01, -0.01, 0.0, 0.0, 0.0, 0.001));
        b.link(Link {
            kind: "image_match".into(),
            node: 10,
            other: "a".into(),
            other_stamp_ns: 4000,
            z,
            info: relative_info(0.05, 0.005),
        });
        assert_eq!(b.unresolved, 1, "A's origins are not known to B yet");
        let wire = serde_json::to_vec(&a.own).unwrap();
        b.receive(serde_json::from_slice(&wire).unwrap());
        assert_eq!(b.unresolved, 0);
        b.optimize();
        let after = (b.origin(10).translation.vector - truth_b.translation.vector).norm();
        assert!(
            after < before / 4.0,
            "B's end error {before:.3} -> {after:.3} m"
        );
        a.receive(serde_json::from_slice(&serde_json::to_vec(&b.own).unwrap()).unwrap());
        a.optimize();
        let b_on_a = a.graph.nodes[a.len() + 10];
        assert!((b_on_a.translation.vector - b.origin(10).translation.vector).norm() < 1e-3);
        // A's own origins barely move (its chain is ten times more certain).
        assert!((a.origin(10).translation.vector - truth_a[10].translation.vector).norm() < 0.1);
        // The marginal of B's last origin shrank below its open-loop one.
        let c = b.own_covariances()[10];
        assert!(
            c[(0, 0)] + c[(1, 1)] < 0.1 * (open_cov[(0, 0)] + open_cov[(1, 1)]),
            "{c}\n{open_cov}"
        );
    }

    /// A link to an origin the other robot never made stays unresolved instead of breaking
    /// the graph.
    #[test]
    fn a_link_to_an_unknown_origin_is_kept_unresolved() {
        let mut a = Global::new("a", Isometry3::identity(), 0);
        a.push(100, step(1.0, 0.0), relative_info(0.1, 0.01));
        let mut b = Global::new("b", step(5.0, 0.0), 0);
        b.link(Link {
            kind: "rendezvous".into(),
            node: 0,
            other: "a".into(),
            other_stamp_ns: 77,
            z: step(-5.0, 0.0),
            info: relative_info(0.1, 0.01),
        });
        b.receive(a.own.clone());
        assert_eq!(b.unresolved, 1);
        assert_eq!(b.graph.edges.len(), 1, "A's chain only");
        b.optimize();
    }
}
