//! The children's encoders, calibrated against the parent's tracks while it maps.
//!
//! A child's encoders count more or less than it travels: its wheels slip, and their
//! diameters are not what the software assumes. Teleoperated, that does not matter (the
//! parent re-aims a child it sees); on the localization run after mapping (`team/tour.rs`)
//! the child drives twenty moves by its encoders alone, and a few per cent short on each
//! adds up to decimetres: a lab child ran 0.15-0.19 m east of its path (short on its
//! westward moves) after twelve moves and scraped the work desk.
//!
//! Decisions:
//! * **The sample.** Between two consecutive images of a child that the parent saw it take
//!   (its hat tracked while it turned and settled, so the child stood still and the fixes'
//!   mean is its position), the straight distance between the two positions over the
//!   odometer's distance between them (the child sends its odometer with every image).
//! * **One hop only.** An odometer distance between 0.6 and 1.6 grid cells: one move to a
//!   neighbouring vertex, straight or diagonal, with its corrections. Longer stretches are
//!   routes through several vertices, whose straight distance is shorter than the path.
//! * **The estimate.** The median of the samples, once there are [`MIN_SAMPLES`]; 1 before
//!   (uncalibrated). The median, not the mean: a drive that stalled against furniture, or a
//!   child driven back onto its vertex, gives a sample far from the rest.
//! * **Its use.** The scale goes to the child with the database
//!   ([`crate::team::TeamMsg::Localize`]), and the child scales its encoder distances by it
//!   from then on (its run after mapping). While mapping nothing changes.
//! * **Its check.** The hops go into the report with their images' stamps, and the
//!   evaluation measures the same hops on the truth (`localization_odometry_scale_true` in
//!   `metrics.json`): the difference is the tracker's share of the error; the rest is the
//!   hops' bends (a hop's path is about 0.6 % longer than straight in the lab), so the
//!   scale comes out about that much low. Before the hat tracker undid the pull of the hats'
//!   sides (`hetsim_vision::hats`) it placed children about 0.9 % too close to the
//!   parent's camera (measured on the lab's seed 5), and the scale came out 1-1.5 % low.

use crate::report::{median, OdometryHop};

/// Samples needed before the median is trusted over no calibration.
pub(super) const MIN_SAMPLES: usize = 5;

/// One child's calibration: the last position it was seen still at, and the samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Calibration {
    /// Where the child last stood seen, metres, the image's stamp and the odometer there.
    rest: Option<([f64; 2], u64, f64)>,
    /// One per hop between two seen images.
    hops: Vec<OdometryHop>,
}

impl Calibration {
    /// An image stamped `stamp_ns`, taken at odometer reading `odometer_m`, at `seen` if the
    /// parent tracked the child while it was taken. `cell_m` is the grid's spacing.
    pub(super) fn rest(
        &mut self,
        seen: Option<[f64; 2]>,
        stamp_ns: u64,
        odometer_m: f64,
        cell_m: f64,
    ) {
        if let (Some(p), Some((p0, t0, o0))) = (seen, self.rest) {
            let counted_m = odometer_m - o0;
            if (0.6 * cell_m..=1.6 * cell_m).contains(&counted_m) {
                self.hops.push(OdometryHop {
                    from_ns: t0,
                    to_ns: stamp_ns,
                    seen_m: (p[0] - p0[0]).hypot(p[1] - p0[1]),
                    counted_m,
                });
            }
        }
        // Not seen: the chain breaks, the next sample starts at the next seen image.
        self.rest = seen.map(|p| (p, stamp_ns, odometer_m));
    }

    /// Metres travelled per metre counted: the hops' median, or 1 with too few.
    pub(super) fn scale(&self) -> f64 {
        median(self.hops.iter().map(|h| h.seen_m / h.counted_m).collect())
            .filter(|_| self.hops.len() >= MIN_SAMPLES)
            .unwrap_or(1.0)
    }

    /// The hops the scale rests on.
    pub(super) fn hops(&self) -> &[OdometryHop] {
        &self.hops
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A child whose encoders count 1 / 0.95 of what it travels, hopping east one 0.5 m
    /// cell per image, each hop bent where it was re-aimed (up to 3 cm sideways 0.3 m in,
    /// at most 0.74 % longer than straight), seen to the tracker's ±2 cm: the median comes
    /// back within 1 % (a hop's sample is off by up to 0.04 m / 0.5 m = 8 %, uniformly
    /// spread; the median of 30 such spreads about 0.4 %, and the bends bias it by about
    /// 0.25 %).
    #[test]
    fn hops_between_seen_images_give_the_encoders_scale() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut c = Calibration::default();
        let mut odometer = 0.0;
        for k in 0..31 {
            let noise = [rng.random_range(-0.02..0.02), rng.random_range(-0.02..0.02)];
            let seen = [0.5 * k as f64 + noise[0], noise[1]];
            if k > 0 {
                let side: f64 = rng.random_range(-0.03..0.03);
                odometer += (0.3f64.hypot(side) + 0.2f64.hypot(side)) / 0.95;
            }
            c.rest(Some(seen), k, odometer, 0.5);
        }
        assert_eq!(c.hops().len(), 30);
        assert!((c.scale() - 0.95).abs() < 0.01, "{}", c.scale());
    }

    /// Too few samples: uncalibrated. An image the parent did not see breaks the chain, and
    /// a stretch through several vertices (a route, not a hop) gives no sample.
    #[test]
    fn unseen_images_and_long_routes_give_no_sample() {
        let mut c = Calibration::default();
        c.rest(Some([0.0, 0.0]), 0, 0.0, 0.5);
        c.rest(Some([0.5, 0.0]), 1, 0.52, 0.5);
        assert_eq!(c.hops().len(), 1);
        assert_eq!((c.hops()[0].from_ns, c.hops()[0].to_ns), (0, 1));
        // An image not seen between two seen ones, a hop's worth counted across it: the
        // chain breaks there, no sample.
        c.rest(None, 2, 0.78, 0.5);
        c.rest(Some([1.0, 0.0]), 3, 1.04, 0.5);
        assert_eq!(c.hops().len(), 1);
        // A route of three cells, east then back north-west: 1.5 m counted, 0.71 m apart.
        c.rest(Some([1.5, 0.5]), 4, 2.6, 0.5);
        assert_eq!(c.hops().len(), 1);
        assert_eq!(c.scale(), 1.0, "one sample is not a calibration");
    }

    /// A stalled drive (the wheels counted 0.5 m, the child moved 0.3 m) among good hops
    /// does not move the median.
    #[test]
    fn a_stalled_hop_does_not_move_the_scale() {
        let mut c = Calibration::default();
        let mut odometer = 0.0;
        for k in 0..7 {
            let travelled = if k == 3 { 0.3 } else { 0.5 };
            odometer += 0.5 / 0.97;
            let x = c.rest.map_or(0.0, |(p, _, _)| p[0]) + if k == 0 { 0.0 } else { travelled };
            c.rest(Some([x, 0.0]), k, odometer, 0.5);
        }
        assert_eq!(c.hops().len(), 6);
        assert!((c.scale() - 0.97).abs() < 1e-9, "{}", c.scale());
    }
}
