//! The drift of a SLAM stack's sub-map edges against the truth, fitted per axis: how the
//! SLAM's `EdgeDrift` (`robots/slam/src/stack/params.rs`) is calibrated.
//!
//! An edge is the relative transform between two consecutive sub-map origins of the
//! open-loop chain (`slam-open`, untouched by events), `z = O_k⁻¹ O_{k+1}`; the truth's is
//! `T = W_k⁻¹ W_{k+1}` at the same stamps. Its error `ε = Log(z⁻¹ T)`, in the graph's
//! convention (translation, then rotation vector, in the body frame at the edge's end), is
//! modelled per axis as `N(0, (f d)²)` with `d` the edge's length, and `f` is estimated by
//! moments, `sqrt(Σ ε² / Σ d²)` (unbiased for `f²`; it weights long edges more than the
//! maximum-likelihood `mean((ε / d)²)` would, which suits a model used on sub-maps tens of
//! metres long). The whole error is put on the drift, though the SLAM adds the local map's
//! own covariance and 1 mm to it (`EdgeDrift::covariance`): the fit errs on the
//! conservative side. The sums are kept, so that runs pool exactly ([`EdgeDriftFit::pool`]).
//! Edges shorter than [`MIN_EDGE_M`] are left out: there the local map's own noise, not
//! drift, is the error.

use hetsim_msgs::Pose;
use nalgebra::Vector6;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The error `Log(T̂⁻¹ T)` in the graph's convention (translation, rotation vector), as the
/// drift fit and the SLAM evaluation's NEES take it.
pub(crate) fn error(estimate: &Pose, truth: &Pose) -> Vector6<f64> {
    let e = estimate.inverse() * truth;
    let r = e.rotation.scaled_axis();
    Vector6::new(
        e.translation.x,
        e.translation.y,
        e.translation.z,
        r.x,
        r.y,
        r.z,
    )
}

/// Edges shorter than this are not fitted, metres.
pub const MIN_EDGE_M: f64 = 1.0;

/// The fit's sums and the per-axis drift they give.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EdgeDriftFit {
    /// Edges fitted.
    pub edges: usize,
    /// `Σ d²`, m².
    pub sum_d2: f64,
    /// `Σ ε²` per axis (x, y, z in m², then roll, pitch, yaw in rad²).
    pub sum_e2: [f64; 6],
    /// The fitted translation drift, a fraction of the distance, x, y, z.
    pub translation: [f64; 3],
    /// The fitted rotation drift, degrees per metre, roll, pitch, yaw.
    pub rotation_deg_per_m: [f64; 3],
}

impl EdgeDriftFit {
    /// Fits the edges between the origins at `stamps` of the open-loop trajectory `open`
    /// against `truth` (both by stamp; origins missing from either are skipped).
    pub fn fit(stamps: &[u64], open: &BTreeMap<u64, Pose>, truth: &BTreeMap<u64, Pose>) -> Self {
        let mut fit = Self::default();
        for w in stamps.windows(2) {
            let (Some(o0), Some(o1), Some(t0), Some(t1)) = (
                open.get(&w[0]),
                open.get(&w[1]),
                truth.get(&w[0]),
                truth.get(&w[1]),
            ) else {
                continue;
            };
            let z = o0.inverse() * o1;
            let d = z.translation.vector.norm();
            if d < MIN_EDGE_M {
                continue;
            }
            let v = error(&z, &(t0.inverse() * t1));
            for (s, x) in fit.sum_e2.iter_mut().zip(v.iter()) {
                *s += x * x;
            }
            fit.sum_d2 += d * d;
            fit.edges += 1;
        }
        fit.finish()
    }

    /// The fit of all the edges of several runs together.
    pub fn pool<'a>(fits: impl IntoIterator<Item = &'a EdgeDriftFit>) -> Self {
        let mut all = Self::default();
        for f in fits {
            all.edges += f.edges;
            all.sum_d2 += f.sum_d2;
            for (a, b) in all.sum_e2.iter_mut().zip(f.sum_e2) {
                *a += b;
            }
        }
        all.finish()
    }

    fn finish(mut self) -> Self {
        let f = |k: usize| (self.sum_e2[k] / self.sum_d2).sqrt();
        if self.edges > 0 {
            self.translation = [f(0), f(1), f(2)];
            self.rotation_deg_per_m = [f(3), f(4), f(5)].map(f64::to_degrees);
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_core::Streams;
    use hetsim_msgs::pose_from_xyz_rpy;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};
    use rand_distr::{Distribution, StandardNormal};

    /// A chain whose every edge is the true one perturbed by `Exp(ε)⁻¹`, `ε` drawn from
    /// `N(0, (f d)²)` per axis with known `f`: the fit recovers each `f`. Over 4000 edges of
    /// 5 to 65 m the moment estimate of `f` has a relative standard error of about 1.5 %
    /// (`sqrt(Σ d⁴ / 2) / Σ d²`); the bound is 3.7 of those.
    #[test]
    fn the_fit_recovers_the_drift_a_chain_was_made_with() {
        let f = [0.01, 0.004, 0.02, 0.0002, 0.0005, 0.001];
        let mut rng = Streams::new(5).stream("drift-fit");
        let (mut truth, mut open) = (BTreeMap::new(), BTreeMap::new());
        let (mut w, mut o) = (Pose::identity(), Pose::identity());
        let mut stamps = Vec::new();
        for k in 0..4001u64 {
            stamps.push(k);
            truth.insert(k, w);
            open.insert(k, o);
            let d = 5.0 + (k % 7) as f64 * 10.0;
            let step = pose_from_xyz_rpy([d, 0.0, 0.0], [0.0, 0.0, 0.1 * (k % 3) as f64]);
            let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
            let eps: Vec<f64> = f.iter().map(|fi| fi * d * n()).collect();
            let e = Pose::from_parts(
                Translation3::new(eps[0], eps[1], eps[2]),
                UnitQuaternion::from_scaled_axis(Vector3::new(eps[3], eps[4], eps[5])),
            );
            w *= step;
            // z = T Exp(ε)⁻¹, so that Log(z⁻¹ T) = ε.
            o *= step * e.inverse();
        }
        let fit = EdgeDriftFit::fit(&stamps, &open, &truth);
        assert_eq!(fit.edges, 4000);
        let got = [
            fit.translation[0],
            fit.translation[1],
            fit.translation[2],
            fit.rotation_deg_per_m[0].to_radians(),
            fit.rotation_deg_per_m[1].to_radians(),
            fit.rotation_deg_per_m[2].to_radians(),
        ];
        for (k, (g, want)) in got.iter().zip(f).enumerate() {
            assert!((g / want - 1.0).abs() < 0.056, "axis {k}: {g} vs {want}");
        }
        // Pooling two halves gives the whole.
        let (a, b) = stamps.split_at(2001);
        let halves = [
            EdgeDriftFit::fit(a, &open, &truth),
            EdgeDriftFit::fit(
                &stamps[2000..2001]
                    .iter()
                    .chain(b)
                    .copied()
                    .collect::<Vec<_>>(),
                &open,
                &truth,
            ),
        ];
        let pooled = EdgeDriftFit::pool(&halves);
        assert_eq!(pooled.edges, 4000);
        for k in 0..3 {
            assert!((pooled.translation[k] / fit.translation[k] - 1.0).abs() < 1e-9);
        }
    }
}
