//! Tests of the local EKF map: Jacobians, gating, consistency.

use super::*;
use crate::quat::tests::{assert_close, numeric};
use hetsim_msgs::Pinhole;
use nalgebra::{Matrix3, Translation3, UnitQuaternion};
use rand::{RngExt, SeedableRng};

pub(crate) fn forward_sensor() -> Sensor {
    // Looking along the body x axis, 1 m up.
    let r = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    Sensor::new(
        Pinhole {
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
        let sigma = DMatrix::from_diagonal(&DVector::from_fn(
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
    let after = m.covariance()[(12, 12)];
    assert!(after < before, "{after} vs {before}");
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
                truth *= Isometry3::from_parts(dp.into(), UnitQuaternion::from_scaled_axis(dth));
                let mp = dp + Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * sp;
                let mt = dth + Vector3::new(gauss(&mut rng), gauss(&mut rng), gauss(&mut rng)) * sr;
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

/// Two frames of point and line updates, some gated, on a 40-landmark map: the deferred
/// covariance (one blocked product per frame) against the same updates with the covariance
/// brought up to date after each one (the textbook sequential filter).
#[test]
fn deferred_updates_reproduce_the_sequential_filter() {
    use crate::lines::LinePrior;
    let s = forward_sensor();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let mut map = LocalMap::new();
    map.p = DMatrix::from_diagonal(&DVector::from_element(7, 1e-4));
    for k in 0..32 {
        let px = Vector2::new(rng.random_range(20.0..620.0), rng.random_range(20.0..460.0));
        map.add_point(&s, &px, 1.0, 0.1, 0.3, k);
    }
    let segment = |k: usize| {
        let a = Vector2::new(60.0 + (k * 131 % 400) as f64, 60.0 + (k * 89 % 300) as f64);
        (a, a + Vector2::new(120.0, 40.0 + (k * 37 % 80) as f64))
    };
    for k in 0..8 {
        let (a, b) = segment(k);
        map.add_line(&s, &a, &b, 1.0, &LinePrior::seed(), 100 + k as u64);
    }
    let (mut deferred, mut sequential) = (map.clone(), map);
    let mut outcomes = (Vec::new(), Vec::new());
    for frame in 0..2 {
        let motion = Isometry3::translation(0.05, 0.01 * frame as f64, 0.0);
        let noise = Matrix6::from_diagonal_element(1e-5);
        deferred.predict(&motion, &noise);
        sequential.predict(&motion, &noise);
        for k in 0..deferred.points.len() {
            let Some((pr, _)) = deferred.predict_point(&s, k, 1.0) else {
                continue;
            };
            // Every fifth measurement is 40 px off: the gate must reject it in both.
            let off = if k % 5 == 0 { 40.0 } else { 0.0 };
            let z = pr.pixel
                + Vector2::new(
                    rng.random_range(-1.5..1.5) + off,
                    rng.random_range(-1.5..1.5),
                );
            outcomes.0.push(deferred.update(&s, k, &z, 1.0, 9.21));
            outcomes.1.push(sequential.update(&s, k, &z, 1.0, 9.21));
            sequential.flush();
        }
        for j in 0..deferred.lines.len() {
            let (a, b) = segment(j);
            let shift = Vector2::new(0.0, 0.3 * (frame + 1) as f64);
            outcomes
                .0
                .push(deferred.update_line(&s, j, &(a + shift), &b, 1.0, 9.21));
            outcomes
                .1
                .push(sequential.update_line(&s, j, &(a + shift), &b, 1.0, 9.21));
            sequential.flush();
        }
        deferred.symmetrize();
        sequential.symmetrize();
    }
    let accepted = outcomes
        .0
        .iter()
        .filter(|o| **o == Some(Update::Accepted))
        .count();
    assert!(
        accepted >= 40,
        "{accepted} updates accepted: the test must exercise updates"
    );
    assert!(outcomes
        .0
        .iter()
        .any(|o| matches!(o, Some(Update::Gated(_)))));
    // Same decisions; gated distances equal to rounding.
    for (a, b) in outcomes.0.iter().zip(&outcomes.1) {
        match (a, b) {
            (Some(Update::Gated(x)), Some(Update::Gated(y))) => assert!((x - y).abs() < 1e-9 * x),
            _ => assert_eq!(a, b),
        }
    }
    let dx = (&deferred.x - &sequential.x).amax();
    assert!(dx < 1e-9 * sequential.x.amax(), "state differs by {dx}");
    let scale = sequential.covariance().amax();
    let dp = (deferred.covariance() - sequential.covariance()).amax();
    assert!(dp < 1e-9 * scale, "covariance differs by {dp} of {scale}");
    let p = deferred.covariance();
    assert_eq!(p, &p.transpose(), "exactly symmetric");
}
