//! A local EKF map (seed Section II, "Metric level"): the robot pose and inverse-depth points
//! in the map's own frame, whose origin is the robot pose when the map was started.
//!
//! State: `x = (p, q, y_1, …, y_n, A_1, …, A_m)`, position (3) and quaternion `[w, x, y, z]`
//! (4) of the body in the map frame, then 6 per point ([`crate::idp`]), then 9 per anchored
//! Plücker line ([`crate::apl`]; their updates and initialization are in [`crate::lines`]). A
//! new map starts with the robot at the origin and zero covariance.
//!
//! * **Prediction** by a body motion `(Δp, δθ)` measured by stereo VO with its 6 x 6
//!   covariance: `p ← p + R(q) Δp`, `q ← q ⊗ q(δθ)`, normalized.
//! * **Update** by one point's pixel: `ν = z - h(x)`, `S = H P Hᵀ + σ² I`, gated by the
//!   Mahalanobis distance `νᵀ S⁻¹ ν ≤ gate` (9.21, the 99 % χ² bound for 2 degrees of
//!   freedom); only the robot's and the point's 13 columns of `H` are non-zero, and the update
//!   uses just them.
//! * **Initialization** (undelayed): the point from a pixel with `ρ = ρ_init`, its covariance
//!   from the robot's, the pixel's (`σ_pixel`) and the prior's (`σ_ρ`).
//! * **Deletion policy**: a point is removed when it has been searched at least `min_searches`
//!   times and found in fewer than half of them (bad appearance, occluded, or a wrong match
//!   early on), or when its inverse depth is estimated negative (behind its anchor). Lines
//!   follow the same search/found rule, and are removed when their direction vanishes.

use crate::idp::{self, Idp, Projection, Sensor};
use crate::quat::{d_normalize, d_rot_dq, from_rotation_vector, left, right, rot};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix2, Matrix6, SMatrix, Vector2, Vector3, Vector4};

/// The deletion rule for points and lines: searched at least `min_searches` times and found
/// in fewer than half of them.
pub(crate) fn unreliable(searched: u32, found: u32, min_searches: u32) -> bool {
    searched >= min_searches && 2 * found < searched
}

/// Book-keeping of a mapped point beside its state.
#[derive(Clone, Debug, PartialEq)]
pub struct PointInfo {
    /// Identifier, unique in the robot's run.
    pub id: u64,
    /// Times it was searched for in an image.
    pub searched: u32,
    /// Times it was found and used.
    pub found: u32,
}

/// A local map.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalMap {
    /// The state mean.
    pub x: DVector<f64>,
    /// The state covariance.
    pub p: DMatrix<f64>,
    /// The points, in state order.
    pub points: Vec<PointInfo>,
    /// The lines, in state order (after the points).
    pub lines: Vec<crate::lines::LineInfo>,
}

/// The outcome of an update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Update {
    /// Used.
    Accepted,
    /// Rejected by the Mahalanobis gate (the squared distance).
    Gated(f64),
}

impl Default for LocalMap {
    fn default() -> Self {
        Self::new()
    }
}

impl LocalMap {
    /// A new map: the robot at its origin, certain.
    pub fn new() -> Self {
        let mut x = DVector::zeros(7);
        x[3] = 1.0;
        Self {
            x,
            p: DMatrix::zeros(7, 7),
            points: Vec::new(),
            lines: Vec::new(),
        }
    }

    /// Landmarks mapped: points and lines together (the seed's sub-map size counts both).
    pub fn landmarks(&self) -> usize {
        self.points.len() + self.lines.len()
    }

    /// Index in the state of the first line (the lines follow the points).
    pub fn line_start(&self) -> usize {
        7 + 6 * self.points.len()
    }

    /// The robot position.
    pub fn position(&self) -> Vector3<f64> {
        Vector3::new(self.x[0], self.x[1], self.x[2])
    }

    /// The robot quaternion.
    pub fn quaternion(&self) -> Vector4<f64> {
        Vector4::new(self.x[3], self.x[4], self.x[5], self.x[6])
    }

    /// The robot pose `map_from_body`.
    pub fn pose(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            self.position().into(),
            crate::quat::to_unit(&self.quaternion()),
        )
    }

    /// Point `k`.
    pub fn point(&self, k: usize) -> Idp {
        Idp::from_column_slice(&self.x.as_slice()[7 + 6 * k..13 + 6 * k])
    }

    /// The robot pose covariance on right perturbations `(δt, δθ)` in the body frame
    /// (`T = T̂ Exp(δ)`), 6 x 6: what a sub-map hands to the global level.
    pub fn pose_covariance(&self) -> Matrix6<f64> {
        let q = self.quaternion();
        let r = rot(&q);
        // δθ ≈ 2 vec(q̂* ⊗ q): rows 1..3 of 2 [q̂*]_L.
        let conj = Vector4::new(q[0], -q[1], -q[2], -q[3]);
        let lq = left(&conj);
        let mut j = SMatrix::<f64, 6, 7>::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(&r.transpose());
        j.fixed_view_mut::<3, 4>(3, 3)
            .copy_from(&(2.0 * lq.fixed_view::<3, 4>(1, 0)));
        let prr = SMatrix::<f64, 7, 7>::from_fn(|a, b| self.p[(a, b)]);
        let c = j * prr * j.transpose();
        (c + c.transpose()) * 0.5
    }

    /// Moves the robot by `motion` (`previous_from_current` of the body), whose covariance
    /// on `(Δp, δθ)` is `cov`.
    pub fn predict(&mut self, motion: &Isometry3<f64>, cov: &Matrix6<f64>) {
        let p = self.position();
        let q = self.quaternion();
        let dp = motion.translation.vector;
        let dtheta = motion.rotation.scaled_axis();
        let (dq, j_dq) = from_rotation_vector(&dtheta);
        let r = rot(&q);
        let p_new = p + r * dp;
        let q_raw = crate::quat::mul(&q, &dq);
        let j_norm = d_normalize(&q_raw);
        let q_new = q_raw.normalize();
        // F (7 x 7) on the robot, G (7 x 6) on the motion.
        let mut f = SMatrix::<f64, 7, 7>::identity();
        f.fixed_view_mut::<3, 4>(0, 3).copy_from(&d_rot_dq(&q, &dp));
        f.fixed_view_mut::<4, 4>(3, 3)
            .copy_from(&(j_norm * right(&dq)));
        let mut g = SMatrix::<f64, 7, 6>::zeros();
        g.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        g.fixed_view_mut::<4, 3>(3, 3)
            .copy_from(&(j_norm * left(&q) * j_dq));
        self.x.fixed_rows_mut::<3>(0).copy_from(&p_new);
        self.x.fixed_rows_mut::<4>(3).copy_from(&q_new);
        let n = self.x.len();
        let fd = DMatrix::from_column_slice(7, 7, f.as_slice());
        let prr = self.p.view((0, 0), (7, 7)).clone_owned();
        let new_rr = &fd * prr * fd.transpose()
            + DMatrix::from_column_slice(7, 7, (g * cov * g.transpose()).as_slice());
        if n > 7 {
            let prm = self.p.view((0, 7), (7, n - 7)).clone_owned();
            let new_rm = &fd * prm;
            self.p.view_mut((0, 7), (7, n - 7)).copy_from(&new_rm);
            self.p
                .view_mut((7, 0), (n - 7, 7))
                .copy_from(&new_rm.transpose());
        }
        self.p.view_mut((0, 0), (7, 7)).copy_from(&new_rr);
    }

    /// Predicts point `k`'s pixel and its innovation covariance with pixel noise `sigma_px`.
    pub fn predict_point(
        &self,
        sensor: &Sensor,
        k: usize,
        sigma_px: f64,
    ) -> Option<(Projection, Matrix2<f64>)> {
        let pr = idp::project(sensor, &self.position(), &self.quaternion(), &self.point(k))?;
        let h = Self::h_small(&pr);
        let idx = self.indices(k);
        let pss = DMatrix::from_fn(13, 13, |a, b| self.p[(idx[a], idx[b])]);
        let hs = DMatrix::from_column_slice(2, 13, h.as_slice());
        let s = &hs * pss * hs.transpose();
        let s = Matrix2::new(s[(0, 0)], s[(0, 1)], s[(1, 0)], s[(1, 1)])
            + Matrix2::identity() * sigma_px * sigma_px;
        Some((pr, s))
    }

    fn indices(&self, k: usize) -> [usize; 13] {
        let mut idx = [0usize; 13];
        for (i, v) in idx.iter_mut().enumerate() {
            *v = if i < 7 { i } else { 7 + 6 * k + (i - 7) };
        }
        idx
    }

    fn h_small(pr: &Projection) -> SMatrix<f64, 2, 13> {
        let mut h = SMatrix::<f64, 2, 13>::zeros();
        h.fixed_view_mut::<2, 3>(0, 0).copy_from(&pr.d_p);
        h.fixed_view_mut::<2, 4>(0, 3).copy_from(&pr.d_q);
        h.fixed_view_mut::<2, 6>(0, 7).copy_from(&pr.d_y);
        h
    }

    /// Updates with point `k` observed at pixel `z`, unless the innovation fails the gate.
    pub fn update(
        &mut self,
        sensor: &Sensor,
        k: usize,
        z: &Vector2<f64>,
        sigma_px: f64,
        gate: f64,
    ) -> Option<Update> {
        let (pr, s) = self.predict_point(sensor, k, sigma_px)?;
        let nu = z - pr.pixel;
        let s_inv = s.try_inverse()?;
        let d2 = (nu.transpose() * s_inv * nu)[0];
        if d2 > gate {
            return Some(Update::Gated(d2));
        }
        let h = Self::h_small(&pr);
        self.correct(
            &self.indices(k),
            &DMatrix::from_column_slice(2, 13, h.as_slice()),
            &DVector::from_column_slice(nu.as_slice()),
            &DMatrix::from_column_slice(2, 2, s_inv.as_slice()),
        );
        Some(Update::Accepted)
    }

    /// The innovation covariance `H P Hᵀ + σ² I` of a measurement whose Jacobian `h`
    /// (m x k) has non-zero columns only at the state indices `idx`.
    pub(crate) fn innovation_covariance(
        &self,
        idx: &[usize],
        h: &DMatrix<f64>,
        sigma: f64,
    ) -> DMatrix<f64> {
        let k = idx.len();
        let pss = DMatrix::from_fn(k, k, |a, b| self.p[(idx[a], idx[b])]);
        h * pss * h.transpose() + DMatrix::identity(h.nrows(), h.nrows()) * (sigma * sigma)
    }

    /// The EKF correction by innovation `nu` with inverse innovation covariance `s_inv`, for
    /// a measurement whose Jacobian `h` (m x k) has non-zero columns only at `idx`.
    pub(crate) fn correct(
        &mut self,
        idx: &[usize],
        h: &DMatrix<f64>,
        nu: &DVector<f64>,
        s_inv: &DMatrix<f64>,
    ) {
        let n = self.x.len();
        let m = h.nrows();
        // P Hᵀ (n x m) from the k columns.
        let mut pht = DMatrix::zeros(n, m);
        for r in 0..n {
            for c in 0..m {
                pht[(r, c)] = idx
                    .iter()
                    .enumerate()
                    .map(|(i, &col)| self.p[(r, col)] * h[(c, i)])
                    .sum();
            }
        }
        let gain = &pht * s_inv;
        self.x += &gain * nu;
        // P ← P - K (P Hᵀ)ᵀ, in place (the caller symmetrizes once per frame).
        self.p.gemm(-1.0, &gain, &pht.transpose(), 1.0);
        let q = self.quaternion().normalize();
        self.x.fixed_rows_mut::<4>(3).copy_from(&q);
    }

    /// Inserts a new landmark `y` at state index `at`, initialized from the robot pose by a
    /// function whose Jacobian on the robot is `jr` (m x 7) and whose other inputs (pixels,
    /// priors) add the covariance `noise` (m x m).
    pub(crate) fn insert(
        &mut self,
        at: usize,
        y: &DVector<f64>,
        jr: &DMatrix<f64>,
        noise: &DMatrix<f64>,
    ) {
        let n = self.x.len();
        let m = y.len();
        let cross = jr * self.p.view((0, 0), (7, n)); // m x n
        let pyy = jr * self.p.view((0, 0), (7, 7)) * jr.transpose() + noise;
        self.x = self.x.clone().insert_rows(at, m, 0.0);
        self.x.rows_mut(at, m).copy_from(y);
        let mut p = self
            .p
            .clone()
            .insert_rows(at, m, 0.0)
            .insert_columns(at, m, 0.0);
        // The cross-covariance's columns are the old state's: before `at`, and after the block.
        let (before, after) = (cross.columns(0, at), cross.columns(at, n - at));
        p.view_mut((at, 0), (m, at)).copy_from(&before);
        p.view_mut((0, at), (at, m)).copy_from(&before.transpose());
        p.view_mut((at, at + m), (m, n - at)).copy_from(&after);
        p.view_mut((at + m, at), (n - at, m))
            .copy_from(&after.transpose());
        p.view_mut((at, at), (m, m)).copy_from(&pyy);
        self.p = p;
    }

    /// Removes the state block of `len` entries at `start`.
    pub(crate) fn remove_block(&mut self, start: usize, len: usize) {
        self.x = self.x.clone().remove_rows(start, len);
        self.p = self
            .p
            .clone()
            .remove_rows(start, len)
            .remove_columns(start, len);
    }

    /// Adds a point seen at `pixel`, with pixel noise `sigma_px` and the inverse-depth prior
    /// `rho_init ± sigma_rho`. Returns its index.
    pub fn add_point(
        &mut self,
        sensor: &Sensor,
        pixel: &Vector2<f64>,
        sigma_px: f64,
        rho_init: f64,
        sigma_rho: f64,
        id: u64,
    ) -> usize {
        let i = idp::init(
            sensor,
            &self.position(),
            &self.quaternion(),
            pixel,
            rho_init,
        );
        let mut jr = SMatrix::<f64, 6, 7>::zeros();
        jr.fixed_view_mut::<6, 3>(0, 0).copy_from(&i.d_p);
        jr.fixed_view_mut::<6, 4>(0, 3).copy_from(&i.d_q);
        let mut noise = i.d_pixel * i.d_pixel.transpose() * (sigma_px * sigma_px);
        noise[(5, 5)] += sigma_rho * sigma_rho;
        // The point goes after the points, before the lines.
        self.insert(
            self.line_start(),
            &DVector::from_column_slice(i.y.as_slice()),
            &DMatrix::from_column_slice(6, 7, jr.as_slice()),
            &DMatrix::from_column_slice(6, 6, noise.as_slice()),
        );
        self.points.push(PointInfo {
            id,
            searched: 0,
            found: 0,
        });
        self.points.len() - 1
    }

    /// Makes the covariance exactly symmetric again (rounding in the updates drifts it).
    pub fn symmetrize(&mut self) {
        let n = self.p.nrows();
        for r in 0..n {
            for c in r + 1..n {
                let v = 0.5 * (self.p[(r, c)] + self.p[(c, r)]);
                self.p[(r, c)] = v;
                self.p[(c, r)] = v;
            }
        }
    }

    /// Removes point `k` from the state.
    pub fn remove(&mut self, k: usize) {
        self.remove_block(7 + 6 * k, 6);
        self.points.remove(k);
    }

    /// Applies the deletion policy to the points and the lines; returns the ids removed.
    pub fn prune(&mut self, min_searches: u32) -> Vec<u64> {
        let mut removed = Vec::new();
        let mut k = 0;
        while k < self.points.len() {
            let info = &self.points[k];
            let behind = self.x[7 + 6 * k + 5] < 0.0;
            if unreliable(info.searched, info.found, min_searches) || behind {
                removed.push(info.id);
                self.remove(k);
            } else {
                k += 1;
            }
        }
        removed.extend(self.prune_lines(min_searches));
        removed
    }

    /// The Euclidean points (finite inverse depth) in the map frame, with ids.
    pub fn euclidean_points(&self) -> Vec<(u64, Vector3<f64>)> {
        (0..self.points.len())
            .filter_map(|k| idp::euclidean(&self.point(k)).map(|e| (self.points[k].id, e)))
            .collect()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::quat::tests::{assert_close, numeric};
    use hetsim_vision::Camera;
    use nalgebra::{Matrix3, Translation3, UnitQuaternion};
    use rand::{RngExt, SeedableRng};

    pub(crate) fn forward_sensor() -> Sensor {
        // Looking along the body x axis, 1 m up.
        let r = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        Sensor::new(
            Camera {
                alpha_u: 400.0,
                alpha_v: 400.0,
                u0: 320.0,
                v0: 240.0,
            },
            &Isometry3::from_parts(
                Translation3::new(0.2, 0.0, 1.0),
                UnitQuaternion::from_matrix(&r),
            ),
        )
    }

    /// The depth and the pixel of world point `w` seen by the robot at `pose`.
    pub(crate) fn seen(s: &Sensor, pose: &Isometry3<f64>, w: &Vector3<f64>) -> (f64, Vector2<f64>) {
        let cam = pose * Isometry3::from_parts(s.t_bc.into(), UnitQuaternion::from_matrix(&s.r_bc));
        let c = cam.inverse_transform_point(&(*w).into());
        let pixel = Vector2::new(
            s.camera.alpha_u * c.x / c.z + s.camera.u0,
            s.camera.alpha_v * c.y / c.z + s.camera.v0,
        );
        (c.z, pixel)
    }

    #[test]
    fn prediction_jacobians_match_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for _ in 0..20 {
            let q0 = crate::quat::tests::random_quat(&mut rng);
            let p0 = Vector3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                0.0,
            );
            let dp = Vector3::new(
                rng.random_range(-0.5..0.5),
                rng.random_range(-0.1..0.1),
                0.02,
            );
            let dth = Vector3::new(0.01, -0.02, rng.random_range(-0.1..0.1));
            // The state after prediction as a function of (robot, motion): compare the
            // covariance propagation with J Σ Jᵀ from finite differences.
            let f = |v: &DVector<f64>| {
                let mut m = LocalMap::new();
                m.x.copy_from(&v.rows(0, 7));
                let motion = Isometry3::from_parts(
                    Vector3::new(v[7], v[8], v[9]).into(),
                    UnitQuaternion::from_scaled_axis(Vector3::new(v[10], v[11], v[12])),
                );
                m.predict(&motion, &Matrix6::zeros());
                m.x.clone()
            };
            let mut v = DVector::zeros(13);
            v.rows_mut(0, 3).copy_from(&p0);
            v.rows_mut(3, 4).copy_from(&q0);
            v.rows_mut(7, 3).copy_from(&dp);
            v.rows_mut(10, 3).copy_from(&dth);
            let j = numeric(&f, &v);
            let sigma =
                DMatrix::from_diagonal(&DVector::from_fn(
                    13,
                    |i, _| if i < 7 { 0.01 } else { 0.002 },
                ));
            let expected = &j * &sigma * j.transpose();
            let mut m = LocalMap::new();
            m.x.copy_from(&v.rows(0, 7));
            m.p = sigma.view((0, 0), (7, 7)).clone_owned();
            let motion = Isometry3::from_parts(dp.into(), UnitQuaternion::from_scaled_axis(dth));
            m.predict(&motion, &Matrix6::from_diagonal_element(0.002));
            // Compare on the tangent of the unit quaternion (the normalization's Jacobian
            // removes the radial direction in both).
            assert_close(&m.p, &expected, "predicted covariance");
        }
    }

    #[test]
    fn a_new_point_is_correlated_with_the_robot_and_updates_shrink_uncertainty() {
        let s = forward_sensor();
        let mut m = LocalMap::new();
        m.p.view_mut((0, 0), (3, 3)).fill_with_identity();
        m.p.view_mut((0, 0), (3, 3)).scale_mut(0.01);
        let k = m.add_point(&s, &Vector2::new(300.0, 200.0), 1.0, 0.1, 0.2, 7);
        assert_eq!(m.points[k].id, 7);
        assert!(m.p[(7, 0)].abs() > 1e-6, "anchor correlated with the robot");
        let before = m.p[(7 + 5, 7 + 5)];
        // Move sideways and observe the point where it truly is (10 m away).
        let target = {
            let mut y = m.point(k);
            y[5] = 0.1;
            idp::euclidean(&y).unwrap()
        };
        m.predict(
            &Isometry3::translation(0.0, 1.0, 0.0),
            &Matrix6::from_diagonal_element(1e-6),
        );
        let (_, z) = seen(&s, &m.pose(), &target);
        assert_eq!(m.update(&s, k, &z, 1.0, 9.21), Some(Update::Accepted));
        assert!(m.p[(12, 12)] < before, "{} vs {before}", m.p[(12, 12)]);
        // A wild measurement is gated.
        assert!(matches!(
            m.update(&s, k, &(z + Vector2::new(80.0, 0.0)), 1.0, 9.21),
            Some(Update::Gated(_))
        ));
        // Removal keeps the state consistent.
        m.add_point(&s, &Vector2::new(100.0, 100.0), 1.0, 0.1, 0.2, 8);
        m.remove(0);
        assert_eq!((m.x.len(), m.p.nrows(), m.points[0].id), (13, 13, 8));
    }

    /// The robot pose error in the convention of [`LocalMap::pose_covariance`]:
    /// `T_true = T̂ Exp(δ)`.
    fn pose_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> nalgebra::Vector6<f64> {
        let d = estimate.inverse() * truth;
        let mut e = nalgebra::Vector6::zeros();
        e.fixed_rows_mut::<3>(0).copy_from(&d.translation.vector);
        e.fixed_rows_mut::<3>(3)
            .copy_from(&d.rotation.scaled_axis());
        e
    }

    /// Normal samples by Box-Muller.
    pub(crate) fn gauss(rng: &mut impl rand::Rng) -> f64 {
        let u1: f64 = rng.random_range(1e-12..1.0);
        let u2: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Spread of the synthetic test's inverse-depth priors, m⁻¹.
    const SIGMA_RHO: f64 = 0.02;

    /// The average NEES of the final robot pose over 25 seeded runs in a small synthetic
    /// world of `n_points` points and `n_lines` segments.
    ///
    /// The world: points 4-14 m ahead, segments of 1.5-4 m from such points; the robot
    /// drives 1.5 m forward with a gentle turn in 15 steps; odometry noise 1 cm and 0.2 deg
    /// per step, pixels 1 px; true data association; inverse-depth priors drawn around the
    /// truth with σ_ρ = 0.02 m⁻¹, line priors `β` around the truth with σβ = 0.02 m⁻¹ each.
    fn average_nees(n_points: usize, n_lines: usize) -> f64 {
        let s = forward_sensor();
        let runs = 25;
        let mut total = 0.0;
        for seed in 0..runs {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed);
            let random_point = |rng: &mut rand_chacha::ChaCha8Rng| {
                Vector3::new(
                    rng.random_range(4.0..14.0),
                    rng.random_range(-4.0..4.0),
                    rng.random_range(0.0..3.0),
                )
            };
            let world: Vec<Vector3<f64>> = (0..n_points).map(|_| random_point(&mut rng)).collect();
            let segments: Vec<[Vector3<f64>; 2]> = (0..n_lines)
                .map(|_| {
                    let a = random_point(&mut rng);
                    let d = Vector3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    )
                    .normalize();
                    [a, a + d * rng.random_range(1.5..4.0)]
                })
                .collect();
            let (sp, sr) = (0.01, 0.2f64.to_radians());
            let q_cov = Matrix6::from_diagonal(&nalgebra::Vector6::new(
                sp * sp,
                sp * sp,
                sp * sp,
                sr * sr,
                sr * sr,
                sr * sr,
            ));
            let mut truth = Isometry3::identity();
            let mut m = LocalMap::new();
            let cam = Isometry3::from_parts(s.t_bc.into(), UnitQuaternion::from_matrix(&s.r_bc));
            let observe =
                |pose: &Isometry3<f64>, w: &Vector3<f64>, rng: &mut rand_chacha::ChaCha8Rng| {
                    let (depth, pixel) = seen(&s, pose, w);
                    (depth > 0.5)
                        .then(|| pixel + Vector2::new(gauss(rng), gauss(rng)))
                        .filter(|z| z.x > 0.0 && z.y > 0.0 && z.x < 640.0 && z.y < 480.0)
                };
            let mut ids: Vec<Option<usize>> = vec![None; world.len()];
            let mut line_ids: Vec<Option<usize>> = vec![None; segments.len()];
            for step in 0..=15 {
                if step > 0 {
                    let dp = Vector3::new(0.1, 0.0, 0.0);
                    let dth = Vector3::new(0.0, 0.0, 0.01);
                    truth *=
                        Isometry3::from_parts(dp.into(), UnitQuaternion::from_scaled_axis(dth));
                    let mp =
                        dp + Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * sp;
                    let mt =
                        dth + Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * sr;
                    m.predict(
                        &Isometry3::from_parts(mp.into(), UnitQuaternion::from_scaled_axis(mt)),
                        &q_cov,
                    );
                }
                for (w, slot) in world.iter().zip(ids.iter_mut()) {
                    let Some(z) = observe(&truth, w, &mut rng) else {
                        continue;
                    };
                    match slot {
                        Some(k) => {
                            m.update(&s, *k, &z, 1.0, f64::INFINITY);
                        }
                        None => {
                            // A prior drawn around the truth with its stated spread (the broad
                            // priors of undelayed monocular initialization are outside the
                            // EKF's linear regime; see the test's comment).
                            let anchor = (truth * cam).translation.vector;
                            let rho = 1.0 / (w - anchor).norm() + SIGMA_RHO * gauss(&mut rng);
                            *slot = Some(m.add_point(&s, &z, 1.0, rho, SIGMA_RHO, 0));
                        }
                    }
                }
                for (ends, slot) in segments.iter().zip(line_ids.iter_mut()) {
                    let (Some(e1), Some(e2)) = (
                        observe(&truth, &ends[0], &mut rng),
                        observe(&truth, &ends[1], &mut rng),
                    ) else {
                        continue;
                    };
                    match slot {
                        Some(j) => {
                            m.update_line(&s, *j, &e1, &e2, 1.0, f64::INFINITY);
                        }
                        None => {
                            let beta = true_beta(&(truth * cam), ends)
                                + Vector2::new(gauss(&mut rng), gauss(&mut rng)) * SIGMA_RHO;
                            let prior = crate::lines::LinePrior {
                                beta,
                                sigma_beta: Vector2::new(SIGMA_RHO, SIGMA_RHO),
                            };
                            *slot = m.add_line(&s, &e1, &e2, 1.0, &prior, 0);
                        }
                    }
                }
            }
            let e = pose_error(&m.pose(), &truth);
            let c = m.pose_covariance();
            total += (e.transpose() * c.try_inverse().unwrap() * e)[0];
        }
        total / runs as f64
    }

    /// The `β` of Eqs. 15-17 that back-projects a segment seen from `camera` (world from
    /// camera) onto the true line through `ends`, for a moment scaled to unit norm.
    fn true_beta(camera: &Isometry3<f64>, ends: &[Vector3<f64>; 2]) -> Vector2<f64> {
        let [a, b] = ends.map(|e| camera.inverse_transform_point(&e.into()).coords);
        // Pixels a/a.z and b/b.z give the image line a × b, the moment of the line.
        let n = a.cross(&(b - a));
        let (v, n) = ((b - a) / n.norm(), n / n.norm());
        let e1 = Vector3::new(n.y, -n.x, 0.0) / n.x.hypot(n.y);
        let e2 = n.cross(&e1);
        Vector2::new(e1.dot(&v), e2.dot(&v))
    }

    /// χ²(150) 2.5 % and 97.5 % quantiles over 25 runs: the two-sided 95 % interval of the
    /// average NEES of a 6-dof pose.
    const NEES_BOUNDS: (f64, f64) = (117.98 / 25.0, 185.80 / 25.0);

    #[test]
    fn robot_pose_nees_is_within_its_95_percent_bound_over_seeded_runs() {
        // 40 points (measured when set: 6.18).
        //
        // With the seed's broad undelayed priors instead (ρ_init = 0.1 ± 0.2 m⁻¹ for every
        // point) the same runs give an average NEES of 9.1 after 30 steps (17 after 3, while
        // the depths are still unknown), and 34 with ± 0.5: the first updates of a point
        // linearize the product ρ (p0 - p) far from the true ρ, a known overconfidence of
        // EKF-SLAM that the seed's method inherits.
        let average = average_nees(40, 0);
        let (lo, hi) = NEES_BOUNDS;
        assert!(
            (lo..=hi).contains(&average),
            "average NEES {average:.2} outside [{lo:.2}, {hi:.2}]"
        );
    }

    #[test]
    fn robot_pose_nees_with_points_and_lines_is_within_its_95_percent_bound() {
        // 25 points and 10 segments: the line updates keep the filter consistent (measured
        // when set: 6.75; the same 25 points alone give 7.58,
        // just outside the bound).
        let average = average_nees(25, 10);
        let (lo, hi) = NEES_BOUNDS;
        assert!(
            (lo..=hi).contains(&average),
            "average NEES {average:.2} outside [{lo:.2}, {hi:.2}]"
        );
    }
}
