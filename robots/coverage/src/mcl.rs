//! Monte Carlo localization of the parent from its laser scans and wheel encoders against the
//! occupancy map it is given (seed 002 assumes the parent "has an accurate localization"; this
//! is how it earns it). The textbook filter (Thrun, Burgard and Fox, *Probabilistic
//! Robotics*, 2005, Tables 5.6 and 6.3, and Section 8.3):
//!
//! * **Prior.** Particles drawn around the pose the operator gives at the start (the mission's
//!   `parent_start`, as one sets a ROS `amcl` initial pose), `init_sigma_m` and
//!   `init_sigma_rad` on each axis.
//! * **Motion.** The encoders are integrated into an odometry pose (nominal track). Between
//!   filter updates the odometry's motion is split into a rotation, a translation and a
//!   rotation, and each particle moves by those with noise whose standard deviations grow
//!   with them (`alpha`, Table 5.6 with standard deviations in place of variances).
//! * **Measurement.** The likelihood field model: each used beam's end point is looked up in
//!   a field of distances to the nearest obstacle (an occupied cell as the square it is, or
//!   outside the map, where the walls stand), `p = z_hit exp(-d² / 2σ²) + z_rand`; a particle's
//!   log weight is the sum over the beams. Beams with no return are not used.
//! * **Updates** only once the robot has moved `update_min_m` or turned `update_min_rad`
//!   since the last one (a standing robot would otherwise collapse its particles onto
//!   one scan's noise), then systematic resampling when the effective number of particles
//!   falls below half.
//! * **Estimate.** The weighted mean (circular for the heading). Between updates the pose
//!   is the last estimate moved on by the odometry since (the `map -> odom` correction of a
//!   ROS navigation stack), so the pilot gets a pose at the encoders' rate.

use hetsim_msgs::{LaserScan, OccupancyGrid};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::sampling::{normal, systematic};

/// A planar pose `[x, y, heading]`, metres and radians.
pub type Pose2 = [f64; 3];

/// Parameters of the filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MclParams {
    /// Number of particles.
    pub particles: usize,
    /// Beams used per scan: every beam whose index is a multiple of this.
    pub beam_stride: usize,
    /// Spread of an end point around the nearest obstacle, metres.
    pub hit_sigma_m: f64,
    /// Weight of the hit model.
    pub z_hit: f64,
    /// Weight of random returns (people, unmapped things).
    pub z_rand: f64,
    /// Motion noise: rotation from rotation, rotation from translation (rad/m), translation
    /// from translation, translation from rotation (m/rad).
    pub alpha: [f64; 4],
    /// Standard deviation of the prior on x and y, metres.
    pub init_sigma_m: f64,
    /// Standard deviation of the prior on the heading, radians.
    pub init_sigma_rad: f64,
    /// Distance driven before an update, metres.
    pub update_min_m: f64,
    /// Turn before an update, radians.
    pub update_min_rad: f64,
    /// Resolution of the likelihood field, metres.
    pub field_resolution_m: f64,
}

impl Default for MclParams {
    /// Defaults for the seed's parent: a 0.5° laser with 1 cm noise on a map whose obstacles
    /// and walls stand exactly on its cell boundaries. `hit_sigma_m` is five times the range
    /// noise (the map does not know the robots, and a beam grazing a corner ends far from
    /// where its angle says); 31 of the 481 beams over 240°, about ROS `amcl`'s `max_beams`
    /// of 30. The motion
    /// noise is a few times the parent's wheel slip (1 %) and encoder errors (0.5 %), so that
    /// the particles cover what the odometry gets wrong.
    fn default() -> Self {
        Self {
            particles: 300,
            beam_stride: 16,
            hit_sigma_m: 0.05,
            z_hit: 0.95,
            z_rand: 0.05,
            alpha: [0.1, 0.1, 0.1, 0.05],
            init_sigma_m: 0.1,
            init_sigma_rad: 5f64.to_radians(),
            update_min_m: 0.02,
            update_min_rad: 2f64.to_radians(),
            field_resolution_m: 0.025,
        }
    }
}

/// Distances from points of the map to the nearest obstacle, on a regular field.
struct LikelihoodField {
    origin: [f64; 2],
    /// The map's width and height, metres.
    extent: [f64; 2],
    resolution: f64,
    cols: usize,
    rows: usize,
    distance: Vec<f32>,
    /// Distances are exact up to this, and this beyond.
    cap: f64,
}

impl LikelihoodField {
    fn new(grid: &OccupancyGrid, resolution: f64, cap: f64) -> Self {
        let width = grid.cols as f64 * grid.cell_m;
        let height = grid.rows as f64 * grid.cell_m;
        let cols = (width / resolution).ceil() as usize;
        let rows = (height / resolution).ceil() as usize;
        let reach = (cap / grid.cell_m).ceil() as i64 + 1;
        let mut distance = vec![0f32; cols * rows];
        for r in 0..rows {
            for c in 0..cols {
                let x = grid.origin_x + (c as f64 + 0.5) * resolution;
                let y = grid.origin_y + (r as f64 + 0.5) * resolution;
                // The walls: outside the map.
                let mut d = (x - grid.origin_x)
                    .min(grid.origin_x + width - x)
                    .min(y - grid.origin_y)
                    .min(grid.origin_y + height - y)
                    .max(0.0)
                    .min(cap);
                let gc = ((x - grid.origin_x) / grid.cell_m).floor() as i64;
                let gr = ((y - grid.origin_y) / grid.cell_m).floor() as i64;
                for dr in -reach..=reach {
                    for dc in -reach..=reach {
                        let (oc, or) = (gc + dc, gr + dr);
                        let inside = oc >= 0
                            && or >= 0
                            && (oc as usize) < grid.cols
                            && (or as usize) < grid.rows;
                        if !inside || grid.is_free(oc, or) {
                            continue;
                        }
                        let x0 = grid.origin_x + oc as f64 * grid.cell_m;
                        let y0 = grid.origin_y + or as f64 * grid.cell_m;
                        let dx = (x0 - x).max(x - x0 - grid.cell_m).max(0.0);
                        let dy = (y0 - y).max(y - y0 - grid.cell_m).max(0.0);
                        d = d.min(dx.hypot(dy));
                    }
                }
                distance[r * cols + c] = d as f32;
            }
        }
        Self {
            origin: [grid.origin_x, grid.origin_y],
            extent: [width, height],
            resolution,
            cols,
            rows,
            distance,
            cap,
        }
    }

    /// Distance from `(x, y)` to the nearest obstacle; outside the map, to the map's edge
    /// (the walls' inner faces: a beam ending beyond them went through a wall).
    fn at(&self, x: f64, y: f64) -> f64 {
        let (lx, ly) = (x - self.origin[0], y - self.origin[1]);
        let out_x = (-lx).max(lx - self.extent[0]).max(0.0);
        let out_y = (-ly).max(ly - self.extent[1]).max(0.0);
        if out_x > 0.0 || out_y > 0.0 {
            return out_x.hypot(out_y).min(self.cap);
        }
        let c = (lx / self.resolution).floor();
        let r = (ly / self.resolution).floor();
        if c >= self.cols as f64 || r >= self.rows as f64 {
            return 0.0;
        }
        (self.distance[r as usize * self.cols + c as usize] as f64).min(self.cap)
    }
}

fn wrap(a: f64) -> f64 {
    let t = a.rem_euclid(std::f64::consts::TAU);
    if t > std::f64::consts::PI {
        t - std::f64::consts::TAU
    } else {
        t
    }
}

fn compose(a: Pose2, b: Pose2) -> Pose2 {
    let (s, c) = a[2].sin_cos();
    [
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        wrap(a[2] + b[2]),
    ]
}

fn inverse(a: Pose2) -> Pose2 {
    let (s, c) = a[2].sin_cos();
    [-c * a[0] - s * a[1], s * a[0] - c * a[1], wrap(-a[2])]
}

/// The parent's laser localizer.
pub struct Mcl {
    params: MclParams,
    field: LikelihoodField,
    /// The map, for particles that stand where the robot cannot.
    grid: OccupancyGrid,
    particles: Vec<Pose2>,
    weights: Vec<f64>,
    rng: ChaCha8Rng,
    track_m: f64,
    /// The laser in the body frame.
    mount: Pose2,
    /// The encoders' dead-reckoned pose, in their own frame.
    odom: Pose2,
    /// `odom` at the last update.
    odom_at_update: Pose2,
    /// The estimate at the last update.
    estimate: Pose2,
    /// Filter updates and resamplings done.
    pub updates: u64,
    /// Resamplings done.
    pub resamples: u64,
}

impl Mcl {
    /// A filter on `grid` around `start`, for a robot whose wheels are `track_m` apart and
    /// whose laser sits at `mount` in its body frame; `seed` seeds its random numbers.
    pub fn new(
        params: MclParams,
        grid: &OccupancyGrid,
        start: Pose2,
        track_m: f64,
        mount: Pose2,
        seed: u64,
    ) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let particles = (0..params.particles)
            .map(|_| {
                [
                    start[0] + params.init_sigma_m * normal(&mut rng),
                    start[1] + params.init_sigma_m * normal(&mut rng),
                    wrap(start[2] + params.init_sigma_rad * normal(&mut rng)),
                ]
            })
            .collect();
        let cap = 4.0 * params.hit_sigma_m;
        Self {
            field: LikelihoodField::new(grid, params.field_resolution_m, cap.max(0.2)),
            grid: grid.clone(),
            weights: vec![1.0 / params.particles.max(1) as f64; params.particles],
            particles,
            rng,
            track_m,
            mount,
            odom: [0.0; 3],
            odom_at_update: [0.0; 3],
            estimate: start,
            updates: 0,
            resamples: 0,
            params,
        }
    }

    /// Integrates one encoder reading: wheel surface distances since the previous one.
    pub fn wheel_odometry(&mut self, left_m: f64, right_m: f64) {
        let ds = 0.5 * (left_m + right_m);
        let dtheta = (right_m - left_m) / self.track_m;
        let mid = self.odom[2] + 0.5 * dtheta;
        self.odom = [
            self.odom[0] + ds * mid.cos(),
            self.odom[1] + ds * mid.sin(),
            wrap(self.odom[2] + dtheta),
        ];
    }

    /// The current pose: the last estimate moved on by the odometry since.
    pub fn pose(&self) -> Pose2 {
        compose(
            self.estimate,
            compose(inverse(self.odom_at_update), self.odom),
        )
    }

    /// Standard deviations of the particles' positions (the larger axis, metres) and
    /// headings (radians), unweighted.
    pub fn spread(&self) -> (f64, f64) {
        let n = self.particles.len().max(1) as f64;
        let mean = |k: usize| self.particles.iter().map(|p| p[k]).sum::<f64>() / n;
        let (mx, my) = (mean(0), mean(1));
        let var = |k: usize, m: f64| {
            self.particles
                .iter()
                .map(|p| (p[k] - m).powi(2))
                .sum::<f64>()
                / n
        };
        let h = self.estimate[2];
        let vh = self
            .particles
            .iter()
            .map(|p| wrap(p[2] - h).powi(2))
            .sum::<f64>()
            / n;
        (var(0, mx).max(var(1, my)).sqrt(), vh.sqrt())
    }

    /// Moves the particles by the odometry since the last update, weighs them by `scan` and
    /// resamples; does nothing until the robot has moved enough. Returns whether it updated.
    pub fn laser(&mut self, scan: &LaserScan) -> bool {
        let delta = compose(inverse(self.odom_at_update), self.odom);
        let trans = delta[0].hypot(delta[1]);
        if trans < self.params.update_min_m && delta[2].abs() < self.params.update_min_rad {
            return false;
        }
        self.predict(delta);
        self.odom_at_update = self.odom;
        self.weigh(scan);
        self.estimate = self.mean();
        self.updates += 1;
        let n_eff = 1.0 / self.weights.iter().map(|w| w * w).sum::<f64>();
        if n_eff < 0.5 * self.particles.len() as f64 {
            self.resample();
        }
        true
    }

    /// Table 5.6: the odometry's motion `delta` (in the odometry frame at the last update)
    /// as rotate, translate, rotate, with noise, applied to every particle.
    fn predict(&mut self, delta: Pose2) {
        let trans = delta[0].hypot(delta[1]);
        // A motion mostly backwards is a reverse drive, not a half turn and a drive.
        let (rot1, signed) = if trans < 1e-4 {
            (0.0, 0.0)
        } else {
            let a = delta[1].atan2(delta[0]);
            if a.abs() > std::f64::consts::FRAC_PI_2 {
                (wrap(a + std::f64::consts::PI), -trans)
            } else {
                (a, trans)
            }
        };
        let rot2 = wrap(delta[2] - rot1);
        let [a1, a2, a3, a4] = self.params.alpha;
        let s_rot1 = a1 * rot1.abs() + a2 * trans;
        let s_trans = a3 * trans + a4 * (rot1.abs() + rot2.abs());
        let s_rot2 = a1 * rot2.abs() + a2 * trans;
        for k in 0..self.particles.len() {
            let r1 = rot1 + s_rot1 * normal(&mut self.rng);
            let t = signed + s_trans * normal(&mut self.rng);
            let r2 = rot2 + s_rot2 * normal(&mut self.rng);
            let p = &mut self.particles[k];
            let h = p[2] + r1;
            p[0] += t * h.cos();
            p[1] += t * h.sin();
            p[2] = wrap(h + r2);
        }
    }

    fn weigh(&mut self, scan: &LaserScan) {
        let stride = self.params.beam_stride.max(1);
        let beams: Vec<(f64, f64)> = scan
            .ranges_m
            .iter()
            .enumerate()
            .filter(|(i, r)| i % stride == 0 && r.is_finite() && (**r as f64) < scan.range_max_m)
            .map(|(i, r)| {
                (
                    scan.angle_min_rad + i as f64 * scan.angle_increment_rad,
                    *r as f64,
                )
            })
            .collect();
        let two_var = 2.0 * self.params.hit_sigma_m.powi(2);
        let mut logs = Vec::with_capacity(self.particles.len());
        for p in &self.particles {
            // A robot does not stand in an obstacle or beyond the walls.
            let free = self
                .grid
                .cell_of(p[0], p[1])
                .is_some_and(|(c, r)| self.grid.is_free(c as i64, r as i64));
            if !free {
                logs.push(f64::NEG_INFINITY);
                continue;
            }
            let laser = compose(*p, self.mount);
            let mut log = 0.0;
            for &(a, r) in &beams {
                let h = laser[2] + a;
                let d = self
                    .field
                    .at(laser[0] + r * h.cos(), laser[1] + r * h.sin());
                log += (self.params.z_hit * (-d * d / two_var).exp() + self.params.z_rand).ln();
            }
            logs.push(log);
        }
        // Log domain: the best particle's weight factor is 1, so no underflow to all zeros
        // unless every particle stands where the robot cannot.
        let best = logs.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        for (w, l) in self.weights.iter_mut().zip(&logs) {
            *w *= if best.is_finite() {
                (l - best).exp()
            } else {
                1.0
            };
        }
        let total: f64 = self.weights.iter().sum();
        if total > 0.0 && total.is_finite() {
            self.weights.iter_mut().for_each(|w| *w /= total);
        } else {
            let n = self.weights.len() as f64;
            self.weights.iter_mut().for_each(|w| *w = 1.0 / n);
        }
    }

    fn mean(&self) -> Pose2 {
        let (mut x, mut y, mut s, mut c) = (0.0, 0.0, 0.0, 0.0);
        for (p, w) in self.particles.iter().zip(&self.weights) {
            x += w * p[0];
            y += w * p[1];
            s += w * p[2].sin();
            c += w * p[2].cos();
        }
        [x, y, s.atan2(c)]
    }

    /// Systematic (low-variance) resampling.
    fn resample(&mut self) {
        let n = self.particles.len();
        self.particles = systematic(&self.weights, &mut self.rng)
            .into_iter()
            .map(|i| self.particles[i])
            .collect();
        self.weights = vec![1.0 / n as f64; n];
        self.resamples += 1;
    }
}

#[cfg(test)]
mod tests;
