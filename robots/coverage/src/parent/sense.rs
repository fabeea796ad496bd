//! What the parent makes of its sensors: its own pose from the laser localization, and the
//! children's floor positions from the hats in its panoramas (or an emulated tracker's
//! fixes), measured in its body frame.
//!
//! **Which hat is which child.** The hats look alike, so each panorama's hats go to the
//! children the parent expects there: every (child, hat) pair within [`HatTracker::gate_m`]
//! of the child's estimate (of an untracked driving child's drive, from where it began to
//! its goal), nearest pairs first, one hat per child and one child per hat. A hat nobody is
//! expected at (a child off its estimate by more than the gate, or one
//! beyond the tracker's range) is left alone; a child not given a hat is untracked in that
//! panorama.

use super::*;
use hetsim_msgs::{pose_from_xyz_rpy, yaw_of, ChildTracks, Image};
use hetsim_vision::hats::HatFinder;

/// The parent's hat tracker: which camera, where it sits, how it finds hats, and how far it
/// trusts them.
#[derive(Clone, Debug, PartialEq)]
pub struct HatTracker {
    /// The omnidirectional camera's name on the parent.
    pub camera: String,
    /// The camera's mount in the body frame, planar: `[x, y, yaw]` (metres, radians).
    pub mount: [f64; 3],
    /// The hat finder (the panorama's calibration, the camera's and the hats' heights).
    pub finder: HatFinder,
    /// Hats farther than this from the camera are not used, metres (the seed's tracker works
    /// within r_los).
    pub range_m: f64,
    /// A hat goes to a child only within this of the child's estimate, metres.
    pub gate_m: f64,
}

impl ParentStack {
    /// Takes the laser localization's pose as the one to steer by, and keeps the estimate
    /// of each filter update.
    pub(super) fn localized(&mut self, stamp_ns: u64, updated: bool) {
        let Some(m) = self.localizer.as_ref() else {
            return;
        };
        let [x, y, h] = m.pose();
        let pose = pose_from_xyz_rpy([x, y, 0.0], [0.0, 0.0, h]);
        self.pose = Some(pose);
        if updated {
            self.estimates.push((stamp_ns, pose));
        }
    }

    /// A body-frame point on the map, by the parent's pose.
    fn on_map(pose: &Pose, p: [f64; 2]) -> [f64; 2] {
        let origin = pose.translation.vector;
        planar([origin.x, origin.y, yaw_of(pose)], p)
    }

    /// An emulated tracker's fixes, placed on the map by the parent's pose.
    pub(super) fn tracks(&mut self, t: &ChildTracks) {
        let Some(pose) = self.pose else {
            return;
        };
        for track in &t.tracks {
            if let Some(i) = self.children.iter().position(|c| c.name == track.child) {
                // A light low-pass against the emulated tracker's noise (0.04 ± 0.02 m).
                self.fix(i, t.stamp_ns, Self::on_map(&pose, track.position_m), 0.4);
            }
        }
    }

    /// A panorama: the hats in it, placed on the map and given to the children expected
    /// there (see the module's decisions).
    pub(super) fn look(&mut self, image: &Image) {
        let (Some(tracker), Some(pose)) = (self.params.hat_tracker.as_ref(), self.pose) else {
            return;
        };
        if image.sensor != tracker.camera {
            return;
        }
        // Looking without a break: the previous panorama came within LOOK_GAP_NS.
        let since = match self.looked {
            Some((last, since)) if image.stamp_ns <= last + LOOK_GAP_NS => since,
            _ => image.stamp_ns,
        };
        self.looked = Some((image.stamp_ns, since));
        let hats: Vec<[f64; 2]> = tracker
            .finder
            .find(image)
            .iter()
            .filter(|h| h.position_m[0].hypot(h.position_m[1]) <= tracker.range_m)
            .map(|h| Self::on_map(&pose, planar(tracker.mount, h.position_m)))
            .collect();
        let tracked: Vec<bool> = (0..self.children.len()).map(|i| self.tracked(i)).collect();
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (i, c) in self.children.iter().enumerate() {
            for (k, h) in hats.iter().enumerate() {
                // An untracked driving child is somewhere on its drive: out of view, its
                // estimate stays where the drive began until the child reports.
                let d = match c.task {
                    Task::Move { from, goal, .. } if !tracked[i] => to_segment(*h, from, goal),
                    _ => dist(c.estimate, *h),
                };
                if d <= tracker.gate_m {
                    pairs.push((d, i, k));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let (mut child_done, mut hat_done) =
            (vec![false; self.children.len()], vec![false; hats.len()]);
        for (_, i, k) in pairs {
            if !child_done[i] && !hat_done[k] {
                child_done[i] = true;
                hat_done[k] = true;
                // Taken as they are: the hats are placed to about a centimetre, less than a
                // filter would remove, and one at 5 Hz would lag a driving child by ~5 cm.
                self.fix(i, image.stamp_ns, hats[k], 1.0);
            }
        }
    }

    /// One fix of child `i` at `stamp_ns`, on the map, blended into its estimate with
    /// weight `alpha` (1: taken as it is).
    fn fix(&mut self, i: usize, stamp_ns: u64, position_m: [f64; 2], alpha: f64) {
        let c = &mut self.children[i];
        let gap_ns = c
            .last_fix_ns
            .map_or(u64::MAX, |t0| stamp_ns.saturating_sub(t0));
        // A fresh track after a gap is taken as it is.
        let alpha = if gap_ns > 300_000_000 { 1.0 } else { alpha };
        // Out of view for more than a second (five panoramas), not a hat missed once.
        c.reacquired = gap_ns > 1_000_000_000 && matches!(c.task, Task::Move { .. });
        c.estimate = [
            c.estimate[0] + alpha * (position_m[0] - c.estimate[0]),
            c.estimate[1] + alpha * (position_m[1] - c.estimate[1]),
        ];
        c.last_fix_ns = Some(stamp_ns);
        if c.path
            .last()
            .is_none_or(|(t0, _)| stamp_ns >= t0 + 200_000_000)
        {
            c.path.push((stamp_ns, position_m));
        }
        if let Task::Grab { fixes, .. } = &mut c.task {
            fixes.0[0] += position_m[0];
            fixes.0[1] += position_m[1];
            fixes.1 += 1;
        }
    }
}

/// Panoramas further apart than this are not one look without a break (two periods of a
/// camera at 2.5 Hz), nanoseconds.
pub(super) const LOOK_GAP_NS: u64 = 800_000_000;

/// Point `p` of a frame placed at `[x, y, yaw]`, in the outer frame.
fn planar([x, y, yaw]: [f64; 3], [px, py]: [f64; 2]) -> [f64; 2] {
    let (sin, cos) = yaw.sin_cos();
    [x + cos * px - sin * py, y + sin * px + cos * py]
}

/// Distance from `p` to the segment from `a` to `b`.
fn to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    dist(p, [a[0] + t * dx, a[1] + t * dy])
}
