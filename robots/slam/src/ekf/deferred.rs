//! A frame's sequential EKF updates with the covariance brought up to date once.
//!
//! Update `j` of a frame (Jacobian `Hⱼ` non-zero on the state indices `idxⱼ`) needs
//! `Cⱼ = P_{j-1} Hⱼᵀ` (n x m) and changes the covariance by `P_j = P_{j-1} - Kⱼ Cⱼᵀ`, with the
//! gain `Kⱼ = Cⱼ Sⱼ⁻¹`. Applied one by one, that is a rank-m update of the whole n x n
//! covariance per measurement: memory-bound, 252 µs per point on a 667-state map.
//!
//! Here `P₀` (the covariance when the batch began) is kept, with the columns of every `Kᵢ`
//! and `Cᵢ` since, so that `P_{j-1} = P₀ - K Cᵀ`. Update `j` then needs only
//!
//! * `Cⱼ = P₀[:, idxⱼ] Hⱼᵀ - K (C[idxⱼ, :]ᵀ Hⱼᵀ)`: O(n k m) plus O(n M m) for the M
//!   columns so far, not O(n²);
//! * the innovation covariance from the block `P_{j-1}[idx, idx] = P₀[idx, idx] -
//!   K[idx, :] C[idx, :]ᵀ`, so the gate sees exactly the covariance the sequential filter
//!   would.
//!
//! The mean is updated at once (`x += Kⱼ νⱼ`, O(n)). When something needs the whole
//! covariance (the next prediction, a new landmark, a removal, the end of the frame) or the
//! batch holds 64 columns,
//! [`LocalMap::flush`] applies `P₀ - K Cᵀ` as one blocked matrix product over the lower
//! triangle (the sum `Σ Kᵢ Cᵢᵀ = Σ Cᵢ Sᵢ⁻¹ Cᵢᵀ` is symmetric) and mirrors it. This is the
//! sequential filter, re-linearized at every update, in another order of floating-point
//! operations; `tests::deferred_updates_reproduce_the_sequential_filter` holds them to
//! 1e-9.

use super::LocalMap;
use nalgebra::{DMatrix, DMatrixView, DVector};

/// The gains and cross-covariances of the updates not yet applied to the covariance: the
/// gains column-major (`K[:, j]` contiguous, for the axpys of `C -= K g`), the
/// cross-covariances row-major with `CAP` columns a row (`C[r, :]` contiguous, for the rows a
/// measurement touches). At `CAP` columns the batch is applied: the blocked product costs
/// the same per column whatever the batch, and the per-update work stays bounded.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Pending {
    /// `K`, n x `CAP`, column-major.
    k: Vec<f64>,
    /// `C`, n x `CAP`, row-major.
    c: Vec<f64>,
    /// Each update's first column, size and `S⁻¹` (row-major, at `d[offset..]`): `K = C D`
    /// with `D` their block diagonal.
    blocks: Vec<(usize, usize, usize)>,
    d: Vec<f64>,
    /// Columns held.
    pub(super) cols: usize,
}

/// Columns a batch holds before it is applied.
const CAP: usize = 64;

/// Column block of the lower-triangular product.
const BLOCK: usize = 64;

/// A dot product in four interleaved partial sums (a fixed order, so deterministic; a
/// single running sum would wait on each addition).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

impl LocalMap {
    /// The covariance block `P[idx, idx]` with the pending updates.
    pub(crate) fn cov_block(&self, idx: &[usize]) -> DMatrix<f64> {
        let pend = &self.pending;
        let m = pend.cols;
        // K's rows at idx as (C D)[idx, :], from C's contiguous rows.
        let mut k_rows = vec![0f64; idx.len() * m];
        for (a, &r) in idx.iter().enumerate() {
            if m == 0 {
                break;
            }
            let c_row = &pend.c[r * CAP..][..m];
            let out = &mut k_rows[a * m..(a + 1) * m];
            for &(start, size, offset) in &pend.blocks {
                let d = &pend.d[offset..offset + size * size];
                for j in 0..size {
                    out[start + j] = (0..size).map(|i| c_row[start + i] * d[i * size + j]).sum();
                }
            }
        }
        DMatrix::from_fn(idx.len(), idx.len(), |a, b| {
            let (ra, rb) = (idx[a], idx[b]);
            if m == 0 {
                return self.p[(ra, rb)];
            }
            self.p[(ra, rb)] - dot(&k_rows[a * m..(a + 1) * m], &pend.c[rb * CAP..][..m])
        })
    }

    /// The full covariance, with every update applied.
    pub fn covariance(&mut self) -> &DMatrix<f64> {
        self.flush();
        &self.p
    }

    /// The EKF correction by innovation `nu` with inverse innovation covariance `s_inv`, for
    /// a measurement whose Jacobian `h` (m x k) has non-zero columns only at `idx`. The mean
    /// changes now; the covariance's change is pending until [`LocalMap::flush`].
    pub(crate) fn correct(
        &mut self,
        idx: &[usize],
        h: &DMatrix<f64>,
        nu: &DVector<f64>,
        s_inv: &DMatrix<f64>,
    ) {
        let m = h.nrows();
        if self.pending.cols + m > CAP {
            self.flush();
        }
        let n = self.x.len();
        let pend = &self.pending;
        let held = pend.cols;
        // C = P₀[:, idx] Hᵀ: axpys over P₀'s contiguous columns.
        let mut cross = DMatrix::<f64>::zeros(n, m);
        for (i, &col) in idx.iter().enumerate() {
            let p_col = self.p.column(col);
            for r in 0..m {
                let f = h[(r, i)];
                if f != 0.0 {
                    cross.column_mut(r).axpy(f, &p_col, 1.0);
                }
            }
        }
        if held > 0 {
            // C -= K g with g = C_pending[idx, :]ᵀ Hᵀ (held x m).
            let mut g = vec![0f64; held * m];
            for (i, &s) in idx.iter().enumerate() {
                let c_row = &pend.c[s * CAP..][..held];
                for r in 0..m {
                    let f = h[(r, i)];
                    if f != 0.0 {
                        for (o, v) in g[r * held..(r + 1) * held].iter_mut().zip(c_row) {
                            *o += f * v;
                        }
                    }
                }
            }
            if m == 2 {
                // Both output columns in one pass over each gain column.
                let (c0, c1) = cross.as_mut_slice().split_at_mut(n);
                for col in 0..held {
                    let (f0, f1) = (g[col], g[held + col]);
                    let k_col = &pend.k[col * n..(col + 1) * n];
                    for ((o0, o1), kv) in c0.iter_mut().zip(c1.iter_mut()).zip(k_col) {
                        *o0 -= kv * f0;
                        *o1 -= kv * f1;
                    }
                }
            } else {
                for r in 0..m {
                    let out = &mut cross.as_mut_slice()[r * n..(r + 1) * n];
                    for (col, &f) in g[r * held..(r + 1) * held].iter().enumerate() {
                        for (o, kv) in out.iter_mut().zip(&pend.k[col * n..(col + 1) * n]) {
                            *o -= kv * f;
                        }
                    }
                }
            }
        }
        let gain = &cross * s_inv;
        self.x += &gain * nu;
        let q = self.quaternion().normalize();
        self.x.fixed_rows_mut::<4>(3).copy_from(&q);
        let pend = &mut self.pending;
        if pend.k.len() != n * CAP {
            pend.k = vec![0.0; n * CAP];
            pend.c = vec![0.0; n * CAP];
        }
        for r in 0..m {
            pend.k[(held + r) * n..(held + r + 1) * n]
                .copy_from_slice(&gain.as_slice()[r * n..(r + 1) * n]);
            for row in 0..n {
                pend.c[row * CAP + held + r] = cross[(row, r)];
            }
        }
        pend.blocks.push((held, m, pend.d.len()));
        pend.d.extend((0..m * m).map(|i| s_inv[(i / m, i % m)]));
        pend.cols += m;
    }

    /// Applies the pending updates to the covariance (`P₀ - K Cᵀ`, lower triangle by
    /// blocked products, then mirrored), leaving it exactly symmetric.
    pub fn flush(&mut self) {
        let cols = self.pending.cols;
        if cols == 0 {
            return;
        }
        let n = self.x.len();
        let pend = &self.pending;
        // K (n x cols) and Cᵀ (cols x n) as views of the row-major buffers.
        let k = DMatrixView::from_slice(&pend.k[..n * cols], n, cols);
        let c_t = DMatrixView::from_slice_with_strides(&pend.c, cols, n, 1, CAP);
        let mut j0 = 0;
        while j0 < n {
            let b = BLOCK.min(n - j0);
            self.p.view_mut((j0, j0), (n - j0, b)).gemm(
                -1.0,
                &k.rows(j0, n - j0),
                &c_t.columns(j0, b),
                1.0,
            );
            j0 += b;
        }
        self.pending.cols = 0;
        self.pending.blocks.clear();
        self.pending.d.clear();
        mirror_lower(&mut self.p);
    }
}

/// Copies the lower triangle onto the upper.
pub(super) fn mirror_lower(p: &mut DMatrix<f64>) {
    for_each_below_diagonal(p, |p, r, c| p[(c, r)] = p[(r, c)]);
}

/// Calls `f(p, r, c)` for every `r > c`, by 32 x 32 tiles (touching `(c, r)` one element at a
/// time row by row strides through the whole matrix).
pub(super) fn for_each_below_diagonal(
    p: &mut DMatrix<f64>,
    mut f: impl FnMut(&mut DMatrix<f64>, usize, usize),
) {
    let n = p.nrows();
    const TILE: usize = 32;
    for c0 in (0..n).step_by(TILE) {
        for r0 in (c0..n).step_by(TILE) {
            for c in c0..(c0 + TILE).min(n) {
                for r in r0.max(c + 1)..(r0 + TILE).min(n) {
                    f(p, r, c);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    #[test]
    fn mirroring_copies_every_lower_element_and_only_those() {
        for n in [1, 5, 32, 33, 64, 97] {
            let mut p = DMatrix::from_fn(n, n, |r, c| (r * 1000 + c) as f64);
            mirror_lower(&mut p);
            for r in 0..n {
                for c in 0..n {
                    let want = (r.max(c) * 1000 + r.min(c)) as f64;
                    assert_eq!(p[(r, c)], want, "n {n}: ({r}, {c})");
                }
            }
        }
    }

    /// 120 updates with random Jacobians on the robot and a random point's block of a
    /// 151-state map (240 columns: batches applied at 64, 128 and 192 columns on the way),
    /// against the textbook dense update `P ← P - K (P Hᵀ)ᵀ` computed here on the full matrix.
    #[test]
    fn pending_updates_and_blocked_flushes_match_the_dense_update() {
        let n = 7 + 6 * 24;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let p0 = (&a * a.transpose()) * 0.01 + DMatrix::identity(n, n);
        let mut map = LocalMap::new();
        map.x = DVector::zeros(n);
        map.x[3] = 1.0;
        map.p = p0.clone();
        let (mut dense, mut x) = (p0, map.x.clone());
        for _ in 0..120 {
            let j = rng.random_range(0..24);
            let idx: Vec<usize> = (0..7).chain(7 + 6 * j..13 + 6 * j).collect();
            let h = DMatrix::from_fn(2, 13, |_, _| rng.random_range(-1.0..1.0));
            let nu = DVector::from_fn(2, |_, _| rng.random_range(-0.1..0.1));
            let block = DMatrix::from_fn(13, 13, |r, c| dense[(idx[r], idx[c])]);
            // What the gate sees: the pending covariance's block is the dense one.
            let pending = map.cov_block(&idx);
            assert!((&pending - &block).amax() < 1e-10, "block differs");
            let s_inv = (&h * &block * h.transpose() + DMatrix::identity(2, 2))
                .try_inverse()
                .unwrap();
            map.correct(&idx, &h, &nu, &s_inv);
            let ph = DMatrix::from_fn(n, 2, |r, c| {
                (0..13).map(|i| dense[(r, idx[i])] * h[(c, i)]).sum()
            });
            let gain = &ph * &s_inv;
            x += &gain * &nu;
            let q = x.fixed_rows::<4>(3).normalize();
            x.fixed_rows_mut::<4>(3).copy_from(&q);
            dense -= &gain * ph.transpose();
        }
        assert!((&map.x - &x).amax() < 1e-10, "means differ");
        let p = map.covariance().clone();
        assert_eq!(p, p.transpose(), "exactly symmetric");
        let scale = dense.amax();
        assert!((&p - &dense).amax() < 1e-10 * scale, "covariances differ");
    }
}
