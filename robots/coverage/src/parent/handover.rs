//! After mapping: the database goes to a child by radio, with a new path to localize along
//! (seed 002, Section I; the child's side is `team/tour.rs`).
//!
//! Decisions:
//! * **Who.** The first child that can move (one boxed in by the robots around it cannot);
//!   the seed re-sends the database "to the child robots", and one child's run is the
//!   experiment (`[coverage] localize_steps` moves; 0 sends nothing).
//! * **What.** For every database image, the parent's grab position estimate (its tracker's)
//!   and the image's features (WGOH and the 15 x 11 thumbnail, computed by the parent from the
//!   images it received); the occupancy map; the direction of mapping.
//! * **The path.** A seeded random walk over the free vertices (stream `<parent>/tour`), from
//!   the vertex where the plan left the child, never straight back unless at a dead end, and
//!   never onto a vertex where another robot stands (they all stand still now), sent as the
//!   vertices' centres (the first: where the parent last tracked the child). The parent plans
//!   it on its map; the child drives it on its own, with no tracking.
//! * **Radio.** The message is repeated every ten `resend_ns` until the child acknowledges
//!   it, then a small [`TeamMsg::Poll`] as often until the child reports the run done
//!   ([`TeamMsg::Localized`]; a poll is answered with that report, which the radio may
//!   lose). The mission is over when the report comes, or at a deadline of a minute per move
//!   (a 0.5 m move takes about ten seconds): a child stuck, or out of radio range, does not
//!   hold the run open until the scenario's end; the report says `timed_out`.

use super::ParentStack;
use crate::map::Vertex;
use crate::team::TeamMsg;
use hetsim_vision::appearance::Features;
use hetsim_vision::Gray;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// What became of the database after the mapping.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Delivery {
    /// Not tried yet: the mapping is not done.
    NotYet,
    /// Tried, and nothing sent: no run asked for, or none possible (no database, no child
    /// that can move).
    Nothing,
    /// Sent to a child: the run is over when it reports, or at the deadline (boxed: the
    /// database message is large).
    Sent(Box<Handover>),
}

impl Delivery {
    /// The run, if the database was sent.
    pub(super) fn sent(&self) -> Option<&Handover> {
        match self {
            Self::Sent(h) => Some(h.as_ref()),
            _ => None,
        }
    }
}

/// The database's delivery and the child's localization run.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Handover {
    /// The child, by index.
    pub(super) child: usize,
    /// The message, repeated until acknowledged.
    msg: TeamMsg,
    seq: u32,
    acked: bool,
    sent_ns: u64,
    /// When the parent heard the child's report that the run is done, or gave up on it.
    pub(super) over_ns: Option<u64>,
    /// No report came before the deadline.
    pub(super) timed_out: bool,
    /// The deadline: a minute per move of the path, from the first sending.
    deadline_ns: u64,
    /// The path's vertices, `(col, row)`, the child's own first.
    pub(super) path: Vec<(usize, usize)>,
    /// The encoders' scale sent with the database.
    pub(super) odometry_scale: f64,
}

impl ParentStack {
    /// Once the mapping is done: sends the database (once), repeats it until heard.
    pub(super) fn hand_over(&mut self) {
        if self.report.finished_ns.is_none() || self.plan.is_none() {
            return;
        }
        let resend_ns = 10 * self.params.resend_ns;
        match &mut self.handover {
            Delivery::NotYet => {
                self.handover = match self.start_handover() {
                    Some(h) => {
                        let name = &self.children[h.child].name;
                        self.outbox.push(h.msg.to(name));
                        Delivery::Sent(Box::new(h))
                    }
                    None => Delivery::Nothing,
                };
            }
            // Not heard: the database again every ten `resend_ns` (it is large: about 90 kB
            // for the lab, 0.7 s on a 1 Mbit/s radio). Heard: a small poll as often, which
            // the child answers with its report once there is one (the radio may lose it).
            // Past the deadline the run is given up (`timed_out`).
            Delivery::Sent(h) if h.over_ns.is_none() && self.now_ns >= h.deadline_ns => {
                h.over_ns = Some(self.now_ns);
                h.timed_out = true;
            }
            Delivery::Sent(h) if h.over_ns.is_none() && self.now_ns >= h.sent_ns + resend_ns => {
                h.sent_ns = self.now_ns;
                let name = &self.children[h.child].name;
                if h.acked {
                    self.outbox.push(TeamMsg::Poll { seq: h.seq }.to(name));
                } else {
                    self.report.resent_orders += 1;
                    self.outbox.push(h.msg.to(name));
                }
            }
            _ => {}
        }
    }

    /// Whether nothing is left to do after the mapping: no localization run asked for, none
    /// possible, or the child's is over.
    pub(super) fn handover_over(&self) -> bool {
        !self.handover_wanted()
            || match &self.handover {
                Delivery::NotYet => false,
                Delivery::Nothing => true,
                Delivery::Sent(h) => h.over_ns.is_some(),
            }
    }

    fn handover_wanted(&self) -> bool {
        self.mission.localize_steps > 0
            && self.plan.is_some()
            && !self.children.is_empty()
            && !self.report.database.is_empty()
    }

    /// A reply to the database's message; `false` if `msg` is not one.
    pub(super) fn handover_reply(&mut self, child: usize, msg: &TeamMsg) -> bool {
        let now = self.now_ns;
        let Delivery::Sent(h) = &mut self.handover else {
            return false;
        };
        if h.child != child {
            return false;
        }
        match *msg {
            TeamMsg::Ack { seq } if seq == h.seq => h.acked = true,
            TeamMsg::Localized { seq } if seq == h.seq => {
                h.acked = true;
                h.over_ns.get_or_insert(now);
            }
            _ => return false,
        }
        true
    }

    fn start_handover(&mut self) -> Option<Handover> {
        if !self.handover_wanted() {
            return None;
        }
        let places: Vec<([f64; 2], Features)> = self
            .report
            .database
            .iter()
            .filter_map(|d| Some((d.estimated_xy, Features::of(&Gray::from_image(&d.image)?))))
            .collect();
        // The first child that can move: one boxed in by the others stays.
        let (i, path) = (0..self.children.len()).find_map(|i| Some((i, self.tour_path(i)?)))?;
        let mut waypoints: Vec<[f64; 2]> = path.iter().map(|v| self.centre(*v)).collect();
        waypoints[0] = self.children[i].estimate;
        let child = &mut self.children[i];
        let odometry_scale = child.odometry.scale();
        child.seq += 1;
        let heading_rad = {
            let (x, y) = self.coverage.direction.unit();
            y.atan2(x)
        };
        let msg = TeamMsg::Localize {
            seq: child.seq,
            grid: self.mission.grid.clone(),
            places,
            path: waypoints,
            heading_rad,
            odometry_scale,
        };
        Some(Handover {
            child: i,
            msg,
            seq: child.seq,
            acked: false,
            sent_ns: self.now_ns,
            over_ns: None,
            timed_out: false,
            deadline_ns: self.now_ns + 60_000_000_000 * (path.len() - 1) as u64,
            path: path.iter().map(|v| self.map.cell(*v)).collect(),
            odometry_scale,
        })
    }

    /// A random walk of `localize_steps` moves for child `i`, off the other robots' vertices.
    fn tour_path(&self, i: usize) -> Option<Vec<Vertex>> {
        let start = self.vertex_at(self.children[i].planned)?;
        let mut taken: Vec<Vertex> = self
            .children
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != i)
            .filter_map(|(_, c)| self.vertex_at(c.planned))
            .collect();
        if let Some(p) = self.pose {
            taken.extend(self.vertex_at([p.translation.vector.x, p.translation.vector.y]));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(self.params.tour_seed);
        let mut path = vec![start];
        let mut previous = None;
        for _ in 0..self.mission.localize_steps {
            let here = *path.last().expect("starts with one vertex");
            let free: Vec<Vertex> = self
                .map
                .neighbours(here)
                .filter(|v| !taken.contains(v))
                .collect();
            // Back only out of a dead end.
            let onward: Vec<Vertex> = free
                .iter()
                .copied()
                .filter(|v| Some(*v) != previous)
                .collect();
            let options = if onward.is_empty() { free } else { onward };
            if options.is_empty() {
                break;
            }
            previous = Some(here);
            path.push(options[rng.random_range(0..options.len())]);
        }
        (path.len() > 1).then_some(path)
    }
}

#[cfg(test)]
mod tests;
