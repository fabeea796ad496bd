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
//! Frames and gauge (seed Section V: Dala's first map is the world frame). Every robot starts
//! in its own frame: its first origin is the identity. The team names a reference robot whose
//! first origin is the team's frame. The joint graph falls into connected components (parts
//! joined by resolved event links); each is held fixed at one first origin, the reference's
//! where the component holds it, else that of its first part (this robot's own, or the
//! earliest named). A robot therefore knows nothing of another's frame until an event links
//! them; when one does, the newly joined part's estimates are moved rigidly into the
//! component's frame through that link (they may be off by any rotation, 180 degrees of yaw
//! included) before Gauss-Newton refines them. [`Global::frame`] names the robot whose first
//! origin this robot's estimates are expressed in.

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

/// One of the owner's frames that is not an origin but that another robot's link names (a
/// partial rendezvous: the other robot saw this one when this one did not see it, so this one
/// started no sub-map then): the frame's pose in the sub-map it belongs to, with covariance.
/// A link to the frame's stamp resolves to an edge to that sub-map's origin through it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Anchor {
    /// The frame's stamp, nanoseconds.
    pub stamp_ns: u64,
    /// The owner's origin (sub-map) the frame belongs to.
    pub node: usize,
    /// The frame's pose in that sub-map.
    pub pose: Isometry3<f64>,
    /// Its covariance (right perturbation), from the local map.
    pub cov: Matrix6<f64>,
}

/// One robot's part of the global graph, as sent over the radio.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Share {
    /// The owner.
    pub robot: String,
    /// The robot whose first origin is the frame of `poses` (the owner's own until an event
    /// links it to the reference's component).
    pub frame: String,
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
    /// Frames other robots' links name that are not origins.
    #[serde(default)]
    pub anchors: Vec<Anchor>,
}

impl Share {
    /// Whether `other` carries the same origins and constraints (its pose estimates aside).
    fn same_constraints(&self, other: &Share) -> bool {
        self.stamps == other.stamps
            && self.chain == other.chain
            && self.fixes == other.fixes
            && self.links == other.links
            && self.anchors == other.anchors
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
    /// The team's reference robot (its first origin is the team's frame).
    reference: String,
    /// The frame each part's current node values are in, by robot.
    frames: BTreeMap<String, String>,
    /// Counts the changes of the graph (its nodes or constraints), for caches of what is
    /// computed from it.
    pub version: u64,
}

impl Global {
    /// The global level of robot `robot`, whose first origin (the identity of its own frame)
    /// is its pose at `stamp_ns`, in a team whose frame is `reference`'s first origin.
    pub fn new(robot: &str, reference: &str, stamp_ns: u64) -> Self {
        let mut g = Self {
            own: Share {
                robot: robot.to_string(),
                frame: robot.to_string(),
                ..Share::default()
            },
            reference: reference.to_string(),
            ..Self::default()
        };
        g.frames.insert(robot.to_string(), robot.to_string());
        g.own.stamps.push(stamp_ns);
        g.own.poses.push(Isometry3::identity());
        g.rebuild();
        g
    }

    /// The robot whose first origin is the frame of this robot's estimates: its own until an
    /// event joins it to another robot's component.
    pub fn frame(&self) -> &str {
        &self.own.frame
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

    /// A frame of this robot that other robots' links name (see [`Anchor`]).
    pub fn anchor(&mut self, anchor: Anchor) {
        self.own.anchors.push(anchor);
        self.rebuild();
    }

    /// The stamps of this robot's frames that the other parts' links name but that are
    /// neither origins nor anchored yet: the frames to publish as [`Anchor`]s, in order.
    pub fn wanted_anchors(&self) -> Vec<u64> {
        let me = &self.own.robot;
        let mut wanted: Vec<u64> = self
            .others
            .values()
            .flat_map(|p| p.links.iter())
            .filter(|l| &l.other == me)
            .map(|l| l.other_stamp_ns)
            .filter(|t| !self.own.stamps.contains(t))
            .filter(|t| !self.own.anchors.iter().any(|a| a.stamp_ns == *t))
            .collect();
        wanted.sort_unstable();
        wanted.dedup();
        wanted
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

    /// The joint graph's node of `robot`'s origin made at `stamp_ns`, if that part is here.
    pub fn index_of(&self, robot: &str, stamp_ns: u64) -> Option<usize> {
        let part = if robot == self.own.robot {
            &self.own
        } else {
            self.others.get(robot)?
        };
        let k = part.stamps.iter().position(|t| *t == stamp_ns)?;
        self.keys.iter().position(|(r, i)| r == robot && *i == k)
    }

    /// Optimizes the joint graph; returns the final cost.
    pub fn optimize(&mut self) -> f64 {
        self.version += 1;
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

    /// Rebuilds the joint graph from the parts, starting from the current estimates: a part
    /// already in the graph keeps its node values (its new origins chained on by their
    /// measured transforms), a new one takes the values it was sent. Then each component is
    /// anchored and its parts moved into its frame ([`Global::align`]).
    fn rebuild(&mut self) {
        self.version += 1;
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
        // The frame each part's values are in.
        let mut frames = Vec::new();
        for part in &parts {
            let known = current.contains_key(&(part.robot.clone(), 0));
            let mut previous: Option<Isometry3<f64>> = None;
            for (k, pose) in part.poses.iter().enumerate() {
                let key = (part.robot.clone(), k);
                let at = match (known, current.get(&key), previous) {
                    (true, Some(x), _) => *x,
                    (true, None, Some(p)) => p * part.chain[k - 1].0,
                    _ => *pose,
                };
                previous = Some(at);
                index.insert(key.clone(), graph.add_node(at));
                keys.push(key);
            }
            frames.push(match self.frames.get(&part.robot) {
                Some(f) if known => f.clone(),
                _ => part.frame.clone(),
            });
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
                let Some(other) = parts.iter().find(|p| p.robot == l.other) else {
                    unresolved += 1;
                    continue;
                };
                // The other robot's origin at the link's stamp, or the anchor of its frame
                // then (the link then reaches the anchor's origin through the anchor).
                if let Some(j) = other.stamps.iter().position(|t| *t == l.other_stamp_ns) {
                    graph.edges.push(Edge {
                        from: node(l.node),
                        to: index[&(l.other.clone(), j)],
                        z: l.z,
                        info: l.info,
                    });
                } else if let Some(a) = other
                    .anchors
                    .iter()
                    .find(|a| a.stamp_ns == l.other_stamp_ns && a.node < other.stamps.len())
                {
                    let cov_z = l.info.try_inverse().unwrap_or_else(Matrix6::identity);
                    let (z, cov) = crate::graph::through(&l.z, &cov_z, &a.pose, &a.cov);
                    graph.edges.push(Edge {
                        from: node(l.node),
                        to: index[&(l.other.clone(), a.node)],
                        z,
                        info: cov.try_inverse().unwrap_or_else(Matrix6::identity),
                    });
                } else {
                    unresolved += 1;
                }
            }
        }
        let robots: Vec<String> = parts.iter().map(|p| p.robot.clone()).collect();
        let part_of: Vec<usize> = keys
            .iter()
            .map(|(r, _)| robots.iter().position(|x| x == r).expect("a part's key"))
            .collect();
        let firsts: Vec<usize> = robots.iter().map(|r| index[&(r.clone(), 0)]).collect();
        let frames = align(
            &mut graph,
            &part_of,
            &firsts,
            &robots,
            frames,
            &self.reference,
        );
        self.frames = robots.into_iter().zip(frames).collect();
        self.graph = graph;
        self.keys = keys;
        self.unresolved = unresolved;
        self.own.frame = self.frames[&self.own.robot].clone();
        for k in 0..self.own.poses.len() {
            self.own.poses[k] = self.graph.nodes[k];
        }
    }
}

/// Anchors each connected component of `graph` and moves its parts into its frame; returns
/// the frame of each part's values afterwards.
///
/// `part_of[n]` is node `n`'s part, `firsts[p]` part `p`'s first node, `frames[p]` the frame
/// its values are in now. A component's gauge is the reference's part if it holds it, else
/// its first part. Going out from the gauge over event edges (breadth first, in edge order),
/// a part reached whose values are in another frame is moved rigidly so that the edge it was
/// reached by holds exactly: `x_to = x_from z`.
fn align(
    graph: &mut Graph,
    part_of: &[usize],
    firsts: &[usize],
    robots: &[String],
    mut frames: Vec<String>,
    reference: &str,
) -> Vec<String> {
    let n = robots.len();
    // Components of parts, by union-find over the edges between parts.
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for e in &graph.edges {
        let (a, b) = (
            root(&mut parent, part_of[e.from]),
            root(&mut parent, part_of[e.to]),
        );
        if a != b {
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut placed = vec![false; n];
    graph.anchors.clear();
    for p in 0..n {
        if root(&mut parent, p) != p {
            continue;
        }
        let members: Vec<usize> = (0..n).filter(|&q| root(&mut parent, q) == p).collect();
        let gauge = members
            .iter()
            .copied()
            .find(|&q| robots[q] == reference)
            .unwrap_or(p);
        graph.anchors.push(firsts[gauge]);
        let frame = frames[gauge].clone();
        placed[gauge] = true;
        let mut progress = true;
        while progress {
            progress = false;
            for e in graph.edges.clone() {
                let (pf, pt) = (part_of[e.from], part_of[e.to]);
                if placed[pf] == placed[pt] || root(&mut parent, pf) != p {
                    continue;
                }
                // The part reached, and where the edge puts the node it was reached at.
                let (part, node, predicted) = if placed[pf] {
                    (pt, e.to, graph.nodes[e.from] * e.z)
                } else {
                    (pf, e.from, graph.nodes[e.to] * e.z.inverse())
                };
                if frames[part] != frame {
                    let moved = predicted * graph.nodes[node].inverse();
                    for (x, _) in graph
                        .nodes
                        .iter_mut()
                        .zip(part_of)
                        .filter(|(_, q)| **q == part)
                    {
                        *x = moved * *x;
                    }
                    frames[part] = frame.clone();
                }
                placed[part] = true;
                progress = true;
            }
        }
    }
    frames
}

#[cfg(test)]
mod tests;
