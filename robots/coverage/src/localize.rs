//! Appearance-based localization of a child from the mission's image database (seed 002,
//! Sections I and V.B, after its reference \[2\]).
//!
//! The child knows only its compass and its encoders. Every image it takes facing the
//! direction of mapping is compared with the database (WGOH or pixelwise, see
//! [`hetsim_vision::appearance`]); a particle filter over the child's position combines the
//! matches with its motion:
//! * **particles**: positions, drawn uniformly over the free cells of the map at the start;
//! * **motion**: a drive of `d` metres at compass heading `h` moves each particle by
//!   `d (1 + ε_d)` along `h + ε_h`, ε_d ~ N(0, `distance_sigma`), ε_h ~ N(0, `heading_sigma`);
//!   a particle that ends in an occupied cell or outside the map gets no weight;
//! * **measurement**: the `top` database images nearest the query in feature space, each
//!   with a similarity `exp(-(D - D_min) / τ)` (τ the spread of those `top` distances), give
//!   a likelihood `floor + Σ similarity · exp(-|p - x|² / 2σ²)` at a particle at `p` (x the
//!   image's database position, σ = `place_sigma_m`); the floor keeps a wrong match from
//!   killing the right particles;
//! * **resampling**: systematic, when the effective number of particles drops below half,
//!   followed by a small jitter (`jitter_m`).

use hetsim_msgs::OccupancyGrid;
use hetsim_vision::appearance::{Feature, Features};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::sampling::{normal, systematic};

/// A database image: where it was taken and its features.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    /// Position in the database, metres.
    pub xy: [f64; 2],
    /// Its features.
    pub features: Features,
}

/// Parameters of the particle filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PfParams {
    /// Number of particles.
    pub particles: usize,
    /// Relative error of a drive's distance (1σ).
    pub distance_sigma: f64,
    /// Error of a drive's heading, radians (1σ).
    pub heading_sigma: f64,
    /// Spread of a place's likelihood around its database position, metres.
    pub place_sigma_m: f64,
    /// Database images used per measurement.
    pub top: usize,
    /// Likelihood floor.
    pub floor: f64,
    /// Jitter after resampling, metres.
    pub jitter_m: f64,
    /// The feature compared.
    pub feature: Feature,
}

impl Default for PfParams {
    fn default() -> Self {
        Self {
            particles: 1000,
            distance_sigma: 0.1,
            heading_sigma: 0.1,
            place_sigma_m: 0.3,
            top: 5,
            floor: 0.02,
            jitter_m: 0.03,
            feature: Feature::Wgoh,
        }
    }
}

/// A particle filter over a child's position.
pub struct ParticleFilter {
    params: PfParams,
    grid: OccupancyGrid,
    particles: Vec<[f64; 2]>,
    weights: Vec<f64>,
    rng: ChaCha8Rng,
}

impl ParticleFilter {
    /// Particles spread uniformly over the free cells of `grid`.
    pub fn new(params: PfParams, grid: OccupancyGrid, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let free: Vec<(usize, usize)> = (0..grid.rows)
            .flat_map(|r| (0..grid.cols).map(move |c| (c, r)))
            .filter(|&(c, r)| grid.is_free(c as i64, r as i64))
            .collect();
        let particles = (0..params.particles)
            .map(|_| {
                let (c, r) = free[rng.random_range(0..free.len().max(1))];
                [
                    grid.origin_x + (c as f64 + rng.random_range(0.0..1.0)) * grid.cell_m,
                    grid.origin_y + (r as f64 + rng.random_range(0.0..1.0)) * grid.cell_m,
                ]
            })
            .collect();
        Self {
            weights: vec![1.0 / params.particles as f64; params.particles],
            params,
            grid,
            particles,
            rng,
        }
    }

    fn free(&self, p: [f64; 2]) -> bool {
        self.grid
            .cell_of(p[0], p[1])
            .is_some_and(|(c, r)| self.grid.is_free(c as i64, r as i64))
    }

    /// A drive of `distance_m` at compass heading `heading_rad`.
    pub fn predict(&mut self, distance_m: f64, heading_rad: f64) {
        for k in 0..self.particles.len() {
            let d = distance_m * (1.0 + self.params.distance_sigma * normal(&mut self.rng));
            let h = heading_rad + self.params.heading_sigma * normal(&mut self.rng);
            let p = &mut self.particles[k];
            *p = [p[0] + d * h.cos(), p[1] + d * h.sin()];
            if !self.free(self.particles[k]) {
                self.weights[k] = 0.0;
            }
        }
        self.normalize();
    }

    /// An image taken facing the direction of mapping, compared with `places`.
    pub fn update(&mut self, query: &Features, places: &[Place]) {
        if places.is_empty() {
            return;
        }
        let mut d: Vec<(f32, usize)> = places
            .iter()
            .enumerate()
            .map(|(i, p)| (self.params.feature.distance(query, &p.features), i))
            .collect();
        d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let top = &d[..self.params.top.min(d.len())];
        let d_min = top[0].0 as f64;
        let tau = ((top[top.len() - 1].0 as f64 - d_min) / 2.0).max(1e-9);
        let votes: Vec<([f64; 2], f64)> = top
            .iter()
            .map(|(dist, i)| (places[*i].xy, (-(*dist as f64 - d_min) / tau).exp()))
            .collect();
        let s2 = 2.0 * self.params.place_sigma_m.powi(2);
        for (p, w) in self.particles.iter().zip(self.weights.iter_mut()) {
            let like: f64 = votes
                .iter()
                .map(|(x, s)| s * (-((p[0] - x[0]).powi(2) + (p[1] - x[1]).powi(2)) / s2).exp())
                .sum();
            *w *= self.params.floor + like;
        }
        self.normalize();
        let n_eff = 1.0 / self.weights.iter().map(|w| w * w).sum::<f64>();
        if n_eff < self.particles.len() as f64 / 2.0 {
            self.resample();
        }
    }

    fn normalize(&mut self) {
        let sum: f64 = self.weights.iter().sum();
        let n = self.weights.len() as f64;
        if sum > 0.0 && sum.is_finite() {
            self.weights.iter_mut().for_each(|w| *w /= sum);
        } else {
            // Every particle was ruled out: start again, spread over the map.
            let fresh = Self::new(self.params, self.grid.clone(), self.rng.random());
            self.particles = fresh.particles;
            self.weights = vec![1.0 / n; self.weights.len()];
        }
    }

    fn resample(&mut self) {
        let n = self.particles.len();
        let j = self.params.jitter_m;
        let mut out = Vec::with_capacity(n);
        for i in systematic(&self.weights, &mut self.rng) {
            let p = self.particles[i];
            out.push([
                p[0] + j * normal(&mut self.rng),
                p[1] + j * normal(&mut self.rng),
            ]);
        }
        self.particles = out;
        self.weights = vec![1.0 / n as f64; n];
    }

    /// The weighted mean position.
    pub fn estimate(&self) -> [f64; 2] {
        let mut m = [0.0, 0.0];
        for (p, w) in self.particles.iter().zip(&self.weights) {
            m[0] += w * p[0];
            m[1] += w * p[1];
        }
        m
    }

    /// The weighted standard deviation of the particles' distance to the estimate, metres.
    pub fn spread(&self) -> f64 {
        let m = self.estimate();
        self.particles
            .iter()
            .zip(&self.weights)
            .map(|(p, w)| w * ((p[0] - m[0]).powi(2) + (p[1] - m[1]).powi(2)))
            .sum::<f64>()
            .sqrt()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use hetsim_vision::Gray;

    /// A synthetic room whose 120 x 88 grey "image" at a position is a pattern unique to its
    /// column and row, so that features identify places (also the child's tests' room).
    pub(crate) fn room(x: f64, y: f64) -> Gray {
        let (w, h) = (120, 88);
        let data = (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f64, (i / w) as f64);
                (128.0
                    + 60.0 * (u * (0.05 + 0.04 * x)).sin()
                    + 60.0 * (v * (0.05 + 0.05 * y)).cos()) as f32
            })
            .collect();
        Gray {
            width: w,
            height: h,
            data,
        }
    }

    /// The room's view at a position as a camera's RGB image.
    pub(crate) fn room_view(stamp_ns: u64, x: f64, y: f64) -> hetsim_msgs::Image {
        let gray = room(x, y);
        hetsim_msgs::Image {
            stamp_ns,
            sensor: "camera".into(),
            width: gray.width as u32,
            height: gray.height as u32,
            encoding: hetsim_msgs::PixelEncoding::Rgb8,
            data: gray.data.iter().flat_map(|g| [*g as u8; 3]).collect(),
        }
    }

    fn view(x: f64, y: f64) -> Features {
        Features::of(&room(x, y))
    }

    /// A 4 x 3 m room of 0.5 m cells (8 x 6) with two occupied cells, (3, 2) and (4, 2).
    pub(crate) fn grid() -> OccupancyGrid {
        OccupancyGrid {
            origin_x: 0.0,
            origin_y: 0.0,
            cell_m: 0.5,
            cols: 8,
            rows: 6,
            occupied: (0..48).map(|i| i == 19 || i == 20).collect(),
        }
    }

    #[test]
    fn converges_on_a_short_path_with_a_noisy_compass() {
        let g = grid();
        let places: Vec<Place> = (0..48)
            .filter(|i| !g.occupied[*i])
            .map(|i| {
                let xy = g.centre_of(i % 8, i / 8);
                Place {
                    xy,
                    features: view(xy[0], xy[1]),
                }
            })
            .collect();
        for feature in Feature::ALL {
            let mut pf = ParticleFilter::new(
                PfParams {
                    feature,
                    ..PfParams::default()
                },
                g.clone(),
                7,
            );
            let mut truth = [0.25, 0.25];
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            // East along the bottom row, then north: 0.5 m steps, compass 3.5 deg noise, images
            // taken 5 cm off the vertex.
            let north = std::f64::consts::FRAC_PI_2;
            for (k, heading) in [0.0, 0.0, 0.0, 0.0, 0.0, north, north, north]
                .into_iter()
                .enumerate()
            {
                if k > 0 {
                    truth = [
                        truth[0] + 0.5 * heading.cos(),
                        truth[1] + 0.5 * heading.sin(),
                    ];
                    pf.predict(0.5, heading + 0.06 * normal(&mut rng));
                }
                pf.update(&view(truth[0] + 0.05, truth[1] - 0.03), &places);
            }
            let e = pf.estimate();
            let error = (e[0] - truth[0]).hypot(e[1] - truth[1]);
            // Within one grid spacing (0.5 m), from particles spread over the whole room.
            assert!(
                error < 0.5,
                "{feature:?}: error {error:.2} m at {e:?}, truth {truth:?}"
            );
            assert!(pf.spread() < 0.4, "{feature:?}: spread {}", pf.spread());
        }
    }

    #[test]
    fn particles_start_on_free_cells_and_die_in_obstacles() {
        let g = grid();
        let mut pf = ParticleFilter::new(PfParams::default(), g.clone(), 1);
        assert!(pf.particles.iter().all(|p| pf.free(*p)));
        // Drive 10 m east: everyone leaves the map; the filter starts again, spread out.
        pf.predict(10.0, 0.0);
        assert!(pf.particles.iter().all(|p| pf.free(*p)));
        assert!(pf.spread() > 0.5);
    }
}
