//! Noise of the relative-pose sensors (rendezvous, image match), drawn in the convention the
//! SLAM's graph weighs them in.
//!
//! The graph (`hetsim_slam::graph`) models a relative measurement `z` of a true `T` as
//! `T = z Exp(ε)`, `ε = (εt, εθ) ~ N(0, diag(σ_m² I, σ_rad² I))`, with `Exp(ε)` the
//! translation `εt` followed by the rotation `Exp(εθ)`, and tells the filter exactly that
//! covariance. So the sensor draws `ε` on all six axes and reports `z = T Exp(ε)⁻¹`: the
//! residual the graph computes at the true poses is then `ε` itself.

use hetsim_core::SimRng;
use hetsim_msgs::Pose;
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand_distr::{Distribution, StandardNormal};

/// `truth` measured with `σ_m` (metres, each axis) and `σ_rad` (radians, each rotation
/// axis) in the graph's convention.
pub fn noisy_relative(truth: &Pose, sigma_m: f64, sigma_rad: f64, rng: &mut SimRng) -> Pose {
    let mut n = || -> f64 { StandardNormal.sample(rng) };
    let t = Vector3::new(n(), n(), n()) * sigma_m;
    let r = Vector3::new(n(), n(), n()) * sigma_rad;
    let e = Pose::from_parts(Translation3::from(t), UnitQuaternion::from_scaled_axis(r));
    truth * e.inverse()
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_msgs::pose_from_xyz_rpy;
    use nalgebra::{Matrix6, Vector6};

    /// The residual at the truth, `Log(z⁻¹ T)`, over many draws: its covariance is the one
    /// the SLAM is told, on all six axes.
    #[test]
    fn the_error_has_exactly_the_covariance_the_slam_is_told() {
        let (sm, sr) = (0.5, 2f64.to_radians());
        let truth = pose_from_xyz_rpy([3.0, -1.0, 38.0], [0.1, -0.2, 2.5]);
        let mut rng = hetsim_core::Streams::new(3).stream("relative-test");
        let n = 20_000;
        let mut cov = Matrix6::<f64>::zeros();
        let mut nees = 0.0;
        for _ in 0..n {
            let z = noisy_relative(&truth, sm, sr, &mut rng);
            let e = z.inverse() * truth;
            let r = e.rotation.scaled_axis();
            let v = Vector6::new(
                e.translation.x,
                e.translation.y,
                e.translation.z,
                r.x,
                r.y,
                r.z,
            );
            let s = Vector6::new(sm, sm, sm, sr, sr, sr);
            nees += v.component_div(&s).norm_squared();
            cov += v * v.transpose();
        }
        cov /= n as f64;
        // The mean of n chi-square(6) draws: 6 with standard deviation sqrt(12 / n) = 0.024;
        // five of those.
        let nees = nees / n as f64;
        assert!((nees - 6.0).abs() < 0.12, "mean NEES {nees}");
        // Each axis's variance within 5 standard errors (sqrt(2 / n) = 1 %) of its own, the
        // rotation axes included; correlations near zero.
        for i in 0..6 {
            let s2 = if i < 3 { sm * sm } else { sr * sr };
            assert!(
                (cov[(i, i)] / s2 - 1.0).abs() < 0.05,
                "axis {i}: {}",
                cov[(i, i)] / s2
            );
            for j in 0..i {
                let rho = cov[(i, j)] / (cov[(i, i)] * cov[(j, j)]).sqrt();
                assert!(rho.abs() < 0.04, "axes {i},{j}: correlation {rho}");
            }
        }
    }
}
