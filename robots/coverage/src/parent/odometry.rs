//! The children's encoders, calibrated against the parent's tracks while it maps.
//!
//! A child's encoders count more or less than it travels: its wheels slip, and their
//! diameters are not what the software assumes. Teleoperated, that does not matter (the
//! parent re-aims a child it sees); on the localization run after mapping (`team/tour.rs`)
//! the child drives twenty moves by its encoders alone, and a few per cent short on each
//! adds up to decimetres: a lab child ran 0.15-0.19 m short of its path after twelve moves
//! and scraped a desk.
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
//! * **Its use.** The scale goes to the child with the database ([`TeamMsg::Localize`]), and
//!   the child scales its encoder distances by it on its run. While mapping nothing changes.

/// Samples needed before the median is trusted over no calibration.
pub(super) const MIN_SAMPLES: usize = 5;

/// One child's calibration: the last position it was seen still at, and the samples.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Calibration {
    /// Where the child last stood seen, metres, and its odometer there.
    rest: Option<([f64; 2], f64)>,
    /// Metres travelled per metre counted, one per hop between two seen images.
    samples: Vec<f64>,
}

impl Calibration {
    /// An image taken at odometer reading `odometer_m`, at `seen` if the parent tracked the
    /// child while it was taken. `cell_m` is the grid's spacing.
    pub(super) fn rest(&mut self, seen: Option<[f64; 2]>, odometer_m: f64, cell_m: f64) {
        if let (Some(p), Some((p0, o0))) = (seen, self.rest) {
            let counted = odometer_m - o0;
            if (0.6 * cell_m..=1.6 * cell_m).contains(&counted) {
                self.samples
                    .push((p[0] - p0[0]).hypot(p[1] - p0[1]) / counted);
            }
        }
        // Not seen: the chain breaks, the next sample starts at the next seen image.
        self.rest = seen.map(|p| (p, odometer_m));
    }

    /// Metres travelled per metre counted: the samples' median, or 1 with too few.
    pub(super) fn scale(&self) -> f64 {
        if self.samples.len() < MIN_SAMPLES {
            return 1.0;
        }
        let mut s = self.samples.clone();
        s.sort_by(f64::total_cmp);
        let n = s.len();
        if n % 2 == 1 {
            s[n / 2]
        } else {
            (s[n / 2 - 1] + s[n / 2]) / 2.0
        }
    }

    /// How many samples the scale rests on.
    pub(super) fn samples(&self) -> usize {
        self.samples.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A child whose encoders count 1 / 0.95 of what it travels, hopping east one 0.5 m
    /// cell per image, each hop bent where it was re-aimed (up to 3 cm sideways 0.3 m in,
    /// at most 0.7 % longer than straight), seen to the tracker's ±2 cm: the median comes
    /// back within 1 % (a hop's sample is off by 0.04 m / 0.5 m = 8 % at worst, and the
    /// median of 30 is far tighter).
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
            c.rest(Some(seen), odometer, 0.5);
        }
        assert_eq!(c.samples(), 30);
        assert!((c.scale() - 0.95).abs() < 0.01, "{}", c.scale());
    }

    /// Too few samples: uncalibrated. An image the parent did not see breaks the chain, and
    /// a stretch through several vertices (a route, not a hop) gives no sample.
    #[test]
    fn unseen_images_and_long_routes_give_no_sample() {
        let mut c = Calibration::default();
        c.rest(Some([0.0, 0.0]), 0.0, 0.5);
        c.rest(Some([0.5, 0.0]), 0.52, 0.5);
        assert_eq!(c.samples(), 1);
        // Not seen at 1.0: the hop to it and the hop from it are both lost.
        c.rest(None, 1.04, 0.5);
        c.rest(Some([1.5, 0.0]), 1.56, 0.5);
        assert_eq!(c.samples(), 1);
        // A route of three cells, east then back north-west: 1.5 m counted, 0.71 m apart.
        c.rest(Some([1.0, 0.5]), 3.1, 0.5);
        assert_eq!(c.samples(), 1);
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
            let x = c.rest.map_or(0.0, |(p, _)| p[0]) + if k == 0 { 0.0 } else { travelled };
            c.rest(Some([x, 0.0]), odometer, 0.5);
        }
        assert_eq!(c.samples(), 6);
        assert!((c.scale() - 0.97).abs() < 1e-9, "{}", c.scale());
    }
}
