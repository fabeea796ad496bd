//! What the parent makes of its sensors: its own pose from the laser localization, and the
//! children's floor positions from the tracker's measurements in its body frame.

use super::*;
use hetsim_msgs::{pose_from_xyz_rpy, yaw_of, ChildTracks};

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

    /// The tracker's fixes, placed on the map by the parent's pose.
    pub(super) fn tracks(&mut self, t: &ChildTracks) {
        let Some(pose) = self.pose else {
            return;
        };
        let (sin, cos) = yaw_of(&pose).sin_cos();
        let origin = pose.translation.vector;
        for track in &t.tracks {
            let [lx, ly] = track.position_m;
            let position_m = [
                origin.x + cos * lx - sin * ly,
                origin.y + sin * lx + cos * ly,
            ];
            let Some(i) = self.children.iter().position(|c| c.name == track.child) else {
                continue;
            };
            let c = &mut self.children[i];
            let fresh = c
                .last_fix_ns
                .is_none_or(|t0| t.stamp_ns.saturating_sub(t0) > 300_000_000);
            // A light low-pass against the tracker's noise; a fresh track after a gap is
            // taken as it is.
            let alpha = if fresh { 1.0 } else { 0.4 };
            c.estimate = [
                c.estimate[0] + alpha * (position_m[0] - c.estimate[0]),
                c.estimate[1] + alpha * (position_m[1] - c.estimate[1]),
            ];
            c.last_fix_ns = Some(t.stamp_ns);
            if c.path
                .last()
                .is_none_or(|(t0, _)| t.stamp_ns >= t0 + 200_000_000)
            {
                c.path.push((t.stamp_ns, position_m));
            }
            if let Task::Grab { fixes, .. } = &mut c.task {
                fixes.0[0] += position_m[0];
                fixes.0[1] += position_m[1];
                fixes.1 += 1;
            }
        }
    }
}
