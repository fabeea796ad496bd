//! The global level (seed Sections II-III): a graph whose nodes are the world poses of the
//! sub-maps' origins and whose edges are relative transforms with covariances (consecutive
//! sub-maps, and events: rendezvous, image matching), plus absolute position priors (GPS
//! fixes). Loop closure is a batch Gauss-Newton over all node poses, the first node held
//! fixed (the gauge).
//!
//! Conventions: a node's pose `T` is perturbed on the right, `T Exp(δ)`, `δ = (δt, δθ)`; an
//! edge `(i, j, z, Σ)` measures `T_i⁻¹ T_j` with `z Exp(ε)`, `ε ~ N(0, Σ)`, and its residual is
//! `r = Log(z⁻¹ T_i⁻¹ T_j)` (translation of the error transform, then its rotation vector); a
//! prior `(i, g, Σ_g)` measures the position of node `i`'s frame point `offset` as `g`.
//! Residual Jacobians are taken by central differences on the perturbations (the graph is
//! small; the local level's Jacobians are the analytic ones).

use nalgebra::{
    DMatrix, DVector, Isometry3, Matrix3, Matrix6, SMatrix, SVector, Translation3, UnitQuaternion,
    Vector3, Vector6,
};

/// A relative measurement between two nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Edge {
    /// From node.
    pub from: usize,
    /// To node.
    pub to: usize,
    /// Measured `T_from⁻¹ T_to`.
    pub z: Isometry3<f64>,
    /// Information (inverse covariance) of the right perturbation of `z`.
    pub info: Matrix6<f64>,
}

/// An absolute position measurement of a point fixed in a node's frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Prior {
    /// The node.
    pub node: usize,
    /// The point in the node's frame (e.g. the GPS antenna).
    pub offset: Vector3<f64>,
    /// Its measured world position.
    pub position: Vector3<f64>,
    /// Information of the position.
    pub info: Matrix3<f64>,
}

/// The global graph.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Graph {
    /// World poses of the sub-map origins.
    pub nodes: Vec<Isometry3<f64>>,
    /// Relative measurements.
    pub edges: Vec<Edge>,
    /// Absolute position measurements.
    pub priors: Vec<Prior>,
    /// Nodes held fixed (the gauge); the first node when empty.
    pub anchors: Vec<usize>,
}

/// `Exp` of `(δt, δθ)` as used here: translation `δt`, rotation `Exp(δθ)`.
pub fn exp(d: &Vector6<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(d[0], d[1], d[2]),
        UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5])),
    )
}

/// The inverse of [`exp`].
pub fn log(t: &Isometry3<f64>) -> Vector6<f64> {
    let r = t.rotation.scaled_axis();
    Vector6::new(
        t.translation.x,
        t.translation.y,
        t.translation.z,
        r.x,
        r.y,
        r.z,
    )
}

impl Edge {
    /// The residual at node poses `a` (from) and `b` (to).
    pub fn residual(&self, a: &Isometry3<f64>, b: &Isometry3<f64>) -> Vector6<f64> {
        log(&(self.z.inverse() * a.inverse() * b))
    }
}

impl Prior {
    /// The residual at the node pose `t`.
    pub fn residual(&self, t: &Isometry3<f64>) -> Vector3<f64> {
        (t * nalgebra::Point3::from(self.offset)).coords - self.position
    }
}

impl Graph {
    /// Adds a node; returns its index.
    pub fn add_node(&mut self, pose: Isometry3<f64>) -> usize {
        self.nodes.push(pose);
        self.nodes.len() - 1
    }

    /// The total weighted squared error.
    pub fn cost(&self) -> f64 {
        let e: f64 = self
            .edges
            .iter()
            .map(|e| {
                let r = e.residual(&self.nodes[e.from], &self.nodes[e.to]);
                (r.transpose() * e.info * r)[0]
            })
            .sum();
        let p: f64 = self
            .priors
            .iter()
            .map(|p| {
                let r = p.residual(&self.nodes[p.node]);
                (r.transpose() * p.info * r)[0]
            })
            .sum();
        e + p
    }

    /// The column block of each node in the normal equations (`None`: an anchor).
    fn blocks(&self) -> (Vec<Option<usize>>, usize) {
        let mut next = 0;
        let blocks = (0..self.nodes.len())
            .map(|i| {
                let fixed = if self.anchors.is_empty() {
                    i == 0
                } else {
                    self.anchors.contains(&i)
                };
                (!fixed).then(|| {
                    next += 6;
                    next - 6
                })
            })
            .collect();
        (blocks, next)
    }

    /// The Gauss-Newton normal equations `(H, g)` at the current nodes over the free nodes.
    fn normal_equations(
        &self,
        blocks: &[Option<usize>],
        dim: usize,
    ) -> (DMatrix<f64>, DVector<f64>) {
        let mut h = DMatrix::<f64>::zeros(dim, dim);
        let mut g = DVector::<f64>::zeros(dim);
        let mut add = |bi: usize, bj: usize, hij: &Matrix6<f64>| {
            let mut view = h.view_mut((bi, bj), (6, 6));
            view += DMatrix::from_column_slice(6, 6, hij.as_slice());
        };
        for e in &self.edges {
            let (a, b) = (self.nodes[e.from], self.nodes[e.to]);
            let r = e.residual(&a, &b);
            let ja = numeric(|d| e.residual(&(a * exp(d)), &b));
            let jb = numeric(|d| e.residual(&a, &(b * exp(d))));
            let parts = [(blocks[e.from], &ja), (blocks[e.to], &jb)];
            for (bi, ji) in parts {
                let Some(bi) = bi else { continue };
                let gi = ji.transpose() * e.info * r;
                for k in 0..6 {
                    g[bi + k] += gi[k];
                }
                for (bj, jj) in parts {
                    let Some(bj) = bj else { continue };
                    add(bi, bj, &(ji.transpose() * e.info * jj));
                }
            }
        }
        for p in &self.priors {
            let Some(bi) = blocks[p.node] else { continue };
            let t = self.nodes[p.node];
            let r = p.residual(&t);
            let j = numeric(|d| p.residual(&(t * exp(d))));
            let gi = j.transpose() * p.info * r;
            for k in 0..6 {
                g[bi + k] += gi[k];
            }
            add(bi, bi, &(j.transpose() * p.info * j));
        }
        // A whisper of damping keeps nodes without constraints solvable.
        for k in 0..dim {
            h[(k, k)] += 1e-9;
        }
        (h, g)
    }

    /// Gauss-Newton over every node but the anchors, at most `iterations` steps; returns the
    /// final cost.
    pub fn optimize(&mut self, iterations: usize) -> f64 {
        let (blocks, dim) = self.blocks();
        let mut cost = self.cost();
        if dim == 0 {
            return cost;
        }
        for _ in 0..iterations {
            let (h, g) = self.normal_equations(&blocks, dim);
            let Some(chol) = h.cholesky() else { break };
            let step = chol.solve(&(-g));
            let old = self.nodes.clone();
            for (i, b) in blocks.iter().enumerate() {
                if let Some(b) = b {
                    let d = Vector6::from_column_slice(&step.as_slice()[*b..b + 6]);
                    self.nodes[i] *= exp(&d);
                }
            }
            let new_cost = self.cost();
            if new_cost > cost {
                self.nodes = old;
                break;
            }
            let converged = cost - new_cost < 1e-9 * (1.0 + cost);
            cost = new_cost;
            if converged {
                break;
            }
        }
        cost
    }

    /// The joint covariance of the nodes' right perturbations at the current estimate,
    /// `H⁻¹` (anchors have none); `None` if `H` is not positive definite.
    pub fn covariance(&self) -> Option<Covariance> {
        let (blocks, dim) = self.blocks();
        let cov = if dim == 0 {
            DMatrix::zeros(0, 0)
        } else {
            let (h, _) = self.normal_equations(&blocks, dim);
            h.cholesky()?.inverse()
        };
        Some(Covariance { blocks, cov })
    }

    /// The marginal covariance of every node's right perturbation at the current estimate
    /// (the diagonal blocks of `H⁻¹`; zero for anchors).
    pub fn marginals(&self) -> Vec<Matrix6<f64>> {
        match self.covariance() {
            Some(c) => (0..self.nodes.len()).map(|i| c.block(i, i)).collect(),
            None => vec![Matrix6::zeros(); self.nodes.len()],
        }
    }
}

/// The joint covariance of a graph's nodes ([`Graph::covariance`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Covariance {
    blocks: Vec<Option<usize>>,
    cov: DMatrix<f64>,
}

impl Covariance {
    /// The cross-covariance of nodes `i` (rows) and `j` (columns); zero if either is an anchor.
    pub fn block(&self, i: usize, j: usize) -> Matrix6<f64> {
        match (self.blocks[i], self.blocks[j]) {
            (Some(a), Some(b)) => Matrix6::from_fn(|r, c| self.cov[(a + r, b + c)]),
            _ => Matrix6::zeros(),
        }
    }
}

/// The relative pose `a⁻¹ b` of two nodes and the covariance of its right perturbation, to
/// first order, from their joint covariance (`cov_ab`: rows `a`, columns `b`).
pub fn relative(
    (a, cov_a): (&Isometry3<f64>, &Matrix6<f64>),
    (b, cov_b): (&Isometry3<f64>, &Matrix6<f64>),
    cov_ab: &Matrix6<f64>,
) -> (Isometry3<f64>, Matrix6<f64>) {
    let u = a.inverse() * b;
    let ja = numeric(|d| log(&(u.inverse() * (a * exp(d)).inverse() * b)));
    let jb = numeric(|d| log(&(u.inverse() * a.inverse() * b * exp(d))));
    let c = ja * cov_a * ja.transpose()
        + jb * cov_b * jb.transpose()
        + ja * cov_ab * jb.transpose()
        + jb * cov_ab.transpose() * ja.transpose();
    (u, (c + c.transpose()) * 0.5)
}

/// The covariance of the right perturbation of `t⁻¹`, given that of `t`.
pub fn inverse_covariance(t: &Isometry3<f64>, cov: &Matrix6<f64>) -> Matrix6<f64> {
    // t⁻¹ Exp(ε) = (t Exp(d))⁻¹: ε = Log(t (t Exp(d))⁻¹).
    let j = numeric(|d| log(&(t * (t * exp(d)).inverse())));
    j * cov * j.transpose()
}

/// Central differences of a function of a 6-vector perturbation, at zero.
pub(crate) fn numeric<const R: usize>(
    f: impl Fn(&Vector6<f64>) -> SVector<f64, R>,
) -> SMatrix<f64, R, 6> {
    let mut j = SMatrix::<f64, R, 6>::zeros();
    for k in 0..6 {
        let mut d = Vector6::zeros();
        d[k] = 1e-6;
        let plus = f(&d);
        d[k] = -1e-6;
        let minus = f(&d);
        j.set_column(k, &((plus - minus) / 2e-6));
    }
    j
}

/// Compounds `a ⊕ b` with first-order covariances of right perturbations: returns `a b` and
/// the covariance of its perturbation, `Ad(b⁻¹) Σ_a Ad(b⁻¹)ᵀ + Σ_b`.
pub fn compound(
    a: &Isometry3<f64>,
    cov_a: &Matrix6<f64>,
    b: &Isometry3<f64>,
    cov_b: &Matrix6<f64>,
) -> (Isometry3<f64>, Matrix6<f64>) {
    let j = numeric(|d| log(&((a * b).inverse() * (a * exp(d) * b))));
    (a * b, j * cov_a * j.transpose() + cov_b)
}

/// A measured `z = T_i⁻¹ T_o` where `T_o = T_k a` is known only through `a`, node `k`'s pose of
/// the point `o` (a robot's frame between two of its origins): returns the measurement of
/// `T_i⁻¹ T_k`, `z a⁻¹`, with the covariance of its perturbation from `z`'s and `a`'s
/// (independent, right perturbations), first order.
pub fn through(
    z: &Isometry3<f64>,
    cov_z: &Matrix6<f64>,
    a: &Isometry3<f64>,
    cov_a: &Matrix6<f64>,
) -> (Isometry3<f64>, Matrix6<f64>) {
    let out = z * a.inverse();
    let j_z = numeric(|d| log(&(out.inverse() * (z * exp(d) * a.inverse()))));
    let j_a = numeric(|d| log(&(out.inverse() * (z * (a * exp(d)).inverse()))));
    (
        out,
        j_z * cov_z * j_z.transpose() + j_a * cov_a * j_a.transpose(),
    )
}

/// The information of a relative pose measured with deviation `sigma_m` on each position
/// axis and `sigma_rad` on each rotation axis.
pub fn relative_info(sigma_m: f64, sigma_rad: f64) -> Matrix6<f64> {
    let (it, ir) = (
        1.0 / (sigma_m * sigma_m).max(1e-12),
        1.0 / (sigma_rad * sigma_rad).max(1e-12),
    );
    Matrix6::from_diagonal(&nalgebra::Vector6::new(it, it, it, ir, ir, ir))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    fn gauss(rng: &mut impl rand::Rng) -> f64 {
        let u1: f64 = rng.random_range(1e-12..1.0);
        let u2: f64 = rng.random_range(0.0..1.0);
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    #[test]
    fn a_loop_of_drifting_odometry_is_closed_by_a_relative_measurement_and_gps() {
        // A square loop of 20 nodes, 5 m sides; odometry edges with noise; the last node
        // measured relative to the first (a rendezvous with itself), and two GPS priors.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut truth = vec![Isometry3::identity()];
        for k in 1..20 {
            let turn = if k % 5 == 0 {
                std::f64::consts::FRAC_PI_2
            } else {
                0.0
            };
            let step = Isometry3::from_parts(
                Translation3::new(1.25, 0.0, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, turn),
            );
            truth.push(truth[k - 1] * step);
        }
        let (st, sr) = (0.02, 0.01);
        let info = relative_info(st, sr);
        let mut g = Graph::default();
        g.add_node(truth[0]);
        for k in 1..20 {
            let z = truth[k - 1].inverse() * truth[k];
            let noise = Vector6::new(
                gauss(&mut rng) * st,
                gauss(&mut rng) * st,
                gauss(&mut rng) * st,
                gauss(&mut rng) * sr,
                gauss(&mut rng) * sr,
                gauss(&mut rng) * sr,
            );
            let zn = z * exp(&noise);
            let prev = g.nodes[k - 1];
            g.add_node(prev * zn);
            g.edges.push(Edge {
                from: k - 1,
                to: k,
                z: zn,
                info,
            });
        }
        let drift = (g.nodes[19].translation.vector - truth[19].translation.vector).norm();
        g.edges.push(Edge {
            from: 19,
            to: 0,
            z: truth[19].inverse() * truth[0],
            info,
        });
        g.priors.push(Prior {
            node: 10,
            offset: Vector3::zeros(),
            position: truth[10].translation.vector,
            info: Matrix3::identity() * 100.0,
        });
        let before = g.cost();
        let after = g.optimize(10);
        let error = (g.nodes[19].translation.vector - truth[19].translation.vector).norm();
        assert!(after < 0.1 * before, "cost {before} -> {after}");
        assert!(
            error < drift / 2.0 && error < 0.1,
            "end error {error:.3} m (open loop {drift:.3} m)"
        );
    }

    /// On a chain from the anchor, the marginals are the compounded edge covariances.
    #[test]
    fn chain_marginals_equal_compounded_covariances() {
        let z1 = Isometry3::from_parts(
            Translation3::new(2.0, 0.5, 0.1),
            UnitQuaternion::from_euler_angles(0.05, -0.1, 0.6),
        );
        let z2 = Isometry3::from_parts(
            Translation3::new(1.0, -1.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.2, -0.3),
        );
        let c1 = Matrix6::from_diagonal(&Vector6::new(1e-2, 2e-2, 1e-2, 1e-3, 2e-3, 3e-3));
        let c2 = Matrix6::from_diagonal(&Vector6::new(3e-2, 1e-2, 2e-2, 2e-3, 1e-3, 1e-3));
        let mut g = Graph::default();
        g.add_node(Isometry3::identity());
        g.add_node(z1);
        g.add_node(z1 * z2);
        for (from, z, c) in [(0, z1, c1), (1, z2, c2)] {
            g.edges.push(Edge {
                from,
                to: from + 1,
                z,
                info: c.try_inverse().unwrap(),
            });
        }
        let m = g.marginals();
        assert_eq!(m[0], Matrix6::zeros());
        assert!((m[1] - c1).abs().max() < 1e-6, "{}", m[1]);
        let (_, c) = compound(&z1, &c1, &z2, &c2);
        assert!(
            (m[2] - c).abs().max() < 1e-6 * c.abs().max().max(1.0),
            "{}\n{c}",
            m[2]
        );
    }

    #[test]
    fn compounding_matches_sampled_covariance() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let a = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
        );
        let b = Isometry3::from_parts(
            Translation3::new(3.0, -1.0, 0.2),
            UnitQuaternion::from_euler_angles(0.0, 0.1, -0.4),
        );
        let ca = Matrix6::from_diagonal(&Vector6::new(1e-4, 2e-4, 1e-4, 1e-5, 2e-5, 3e-5));
        let cb = Matrix6::from_diagonal(&Vector6::new(3e-4, 1e-4, 1e-4, 2e-5, 1e-5, 1e-5));
        let (ab, c) = compound(&a, &ca, &b, &cb);
        let n = 20000;
        let mut sample = Matrix6::zeros();
        for _ in 0..n {
            let da = Vector6::from_fn(|i, _| gauss(&mut rng) * ca[(i, i)].sqrt());
            let db = Vector6::from_fn(|i, _| gauss(&mut rng) * cb[(i, i)].sqrt());
            let e = log(&(ab.inverse() * (a * exp(&da) * b * exp(&db))));
            sample += e * e.transpose() / n as f64;
        }
        let rel = (sample - c).abs().max() / c.abs().max();
        assert!(
            rel < 0.05,
            "sampled vs first-order covariance differ by {rel:.3}\n{sample}\n{c}"
        );
    }

    /// The relative pose of two correlated nodes and its inverse: first-order covariances
    /// against sampled ones (joint Gaussian perturbations, 20000 draws: a 5 % bound is well
    /// beyond the sampling error of about 1 % per entry).
    #[test]
    fn relative_and_inverse_covariances_match_sampled_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let a = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
        );
        let b = Isometry3::from_parts(
            Translation3::new(6.0, -3.0, 1.2),
            UnitQuaternion::from_euler_angles(0.0, 0.3, 2.4),
        );
        // A joint covariance with strong correlation between the nodes (b = a then a step).
        let l = nalgebra::SMatrix::<f64, 12, 12>::from_fn(|i, j| {
            if j > i {
                0.0
            } else if i == j {
                if i % 6 < 3 {
                    0.02
                } else {
                    0.004
                }
            } else if i == j + 6 {
                if i % 6 < 3 {
                    0.015
                } else {
                    0.003
                }
            } else {
                0.0
            }
        });
        let joint = l * l.transpose();
        let block = |r: usize, c: usize| Matrix6::from_fn(|i, j| joint[(r + i, c + j)]);
        let (u, cu) = relative((&a, &block(0, 0)), (&b, &block(6, 6)), &block(0, 6));
        let ci = inverse_covariance(&u, &cu);
        let n = 20000;
        let (mut su, mut si) = (Matrix6::zeros(), Matrix6::zeros());
        for _ in 0..n {
            let w = nalgebra::SVector::<f64, 12>::from_fn(|_, _| gauss(&mut rng));
            let d = l * w;
            let (da, db) = (
                Vector6::from_column_slice(&d.as_slice()[..6]),
                Vector6::from_column_slice(&d.as_slice()[6..]),
            );
            let v = (a * exp(&da)).inverse() * (b * exp(&db));
            let e = log(&(u.inverse() * v));
            su += e * e.transpose() / n as f64;
            let f = log(&(u * v.inverse()));
            si += f * f.transpose() / n as f64;
        }
        for (sample, c) in [(su, cu), (si, ci)] {
            let rel = (sample - c).abs().max() / c.abs().max();
            assert!(
                rel < 0.05,
                "sampled vs first order: {rel:.3}\n{sample}\n{c}"
            );
        }
    }
}
