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

/// Anchored Plücker lines in this map (its state holds them after the points).
pub mod lines;

/// A frame's updates applied to the covariance in one blocked product.
pub mod deferred;

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
    /// The state covariance before the pending updates ([`deferred`]); read it with
    /// [`LocalMap::covariance`] or [`LocalMap::cov_block`].
    p: DMatrix<f64>,
    pending: deferred::Pending,
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
    /// Size of the state vector: the robot's 7, then 6 per point and 9 per line.
    pub fn state_len(&self) -> usize {
        self.x.len()
    }

    /// A new map: the robot at its origin, certain.
    pub fn new() -> Self {
        let mut x = DVector::zeros(7);
        x[3] = 1.0;
        Self {
            x,
            p: DMatrix::zeros(7, 7),
            pending: Default::default(),
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
        let block = self.cov_block(&[0, 1, 2, 3, 4, 5, 6]);
        let prr = SMatrix::<f64, 7, 7>::from_fn(|a, b| block[(a, b)]);
        let c = j * prr * j.transpose();
        (c + c.transpose()) * 0.5
    }

    /// Moves the robot by `motion` (`previous_from_current` of the body), whose covariance
    /// on `(Δp, δθ)` is `cov`.
    pub fn predict(&mut self, motion: &Isometry3<f64>, cov: &Matrix6<f64>) {
        self.flush();
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
        let pss = self.cov_block(&self.indices(k));
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
        let predicted = self.predict_point(sensor, k, sigma_px)?;
        self.update_predicted(k, z, &predicted, gate)
    }

    /// [`LocalMap::update`] with the prediction [`LocalMap::predict_point`] just gave for
    /// point `k` (the map unchanged since), as a caller that searched the image with it has.
    pub fn update_predicted(
        &mut self,
        k: usize,
        z: &Vector2<f64>,
        (pr, s): &(Projection, Matrix2<f64>),
        gate: f64,
    ) -> Option<Update> {
        let nu = z - pr.pixel;
        let s_inv = s.try_inverse()?;
        let d2 = (nu.transpose() * s_inv * nu)[0];
        if d2 > gate {
            return Some(Update::Gated(d2));
        }
        let h = Self::h_small(pr);
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
        let pss = self.cov_block(idx);
        h * pss * h.transpose() + DMatrix::identity(h.nrows(), h.nrows()) * (sigma * sigma)
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
        self.flush();
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
        self.flush();
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

    /// Applies the pending updates and makes the covariance exactly symmetric (the frame's
    /// updates leave its lower triangle mirrored; otherwise the two halves are averaged).
    pub fn symmetrize(&mut self) {
        if self.pending.cols > 0 {
            self.flush();
            return;
        }
        deferred::for_each_below_diagonal(&mut self.p, |p, r, c| {
            let v = 0.5 * (p[(r, c)] + p[(c, r)]);
            p[(r, c)] = v;
            p[(c, r)] = v;
        });
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
pub(crate) mod tests;
