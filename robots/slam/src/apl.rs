//! Anchored Plücker lines (seed Section IV, Eqs. 7-19): the geometry and its Jacobians; the
//! filter's use of them is in [`crate::lines`].
//!
//! An APL is the 9-vector `A = (p0, n, v)`: the anchor `p0` (the optical centre when the line
//! was first seen), the moment `n = (p - p0) × v` of the line about the anchor (normal to the
//! plane through the anchor and the line) and the direction `v`. The robot pose `(p, q)` and
//! the camera's mount `(t_bc, R_bc)` are those of [`crate::idp::Sensor`]; the camera sits at
//! `T = p + R(q) t_bc` with rotation `R_c = R(q) R_bc`.

use crate::idp::Sensor;
use crate::quat::{d_rot_dq, d_rot_t_dq, rot};
use nalgebra::{Matrix3, SMatrix, Vector2, Vector3, Vector4};

/// An anchored Plücker line.
pub type Apl = SMatrix<f64, 9, 1>;

/// The anchor, moment and direction of an APL.
pub(crate) fn parts(a: &Apl) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    (
        Vector3::new(a[0], a[1], a[2]),
        Vector3::new(a[3], a[4], a[5]),
        Vector3::new(a[6], a[7], a[8]),
    )
}

/// The Plücker intrinsic matrix `K` of Eq. 11: `l = K n` for a line of moment `n` in the
/// camera frame.
pub fn plucker_intrinsic(sensor: &Sensor) -> Matrix3<f64> {
    let c = &sensor.camera;
    Matrix3::new(
        c.alpha_v,
        0.0,
        0.0,
        0.0,
        c.alpha_u,
        0.0,
        -c.alpha_v * c.u0,
        -c.alpha_u * c.v0,
        c.alpha_u * c.alpha_v,
    )
}

/// Eq. 8: the line `a_c` given in a frame at rotation `r`, translation `t`, in the outer frame.
pub fn from_frame(r: &Matrix3<f64>, t: &Vector3<f64>, a_c: &Apl) -> Apl {
    let (p0, n, v) = parts(a_c);
    let mut a = Apl::zeros();
    a.fixed_rows_mut::<3>(0).copy_from(&(r * p0 + t));
    a.fixed_rows_mut::<3>(3).copy_from(&(r * n));
    a.fixed_rows_mut::<3>(6).copy_from(&(r * v));
    a
}

/// Eq. 9: the inverse of [`from_frame`].
pub fn to_frame(r: &Matrix3<f64>, t: &Vector3<f64>, a: &Apl) -> Apl {
    let (p0, n, v) = parts(a);
    let rt = r.transpose();
    let mut c = Apl::zeros();
    c.fixed_rows_mut::<3>(0).copy_from(&(rt * (p0 - t)));
    c.fixed_rows_mut::<3>(3).copy_from(&(rt * n));
    c.fixed_rows_mut::<3>(6).copy_from(&(rt * v));
    c
}

/// Eq. 10: the (un-anchored) Plücker coordinates `(n + p0 × v : v)`, moment about the origin.
pub fn unanchor(a: &Apl) -> (Vector3<f64>, Vector3<f64>) {
    let (p0, n, v) = parts(a);
    (n + p0.cross(&v), v)
}

/// A line's image and its Jacobians with respect to the robot position (3 x 3), quaternion
/// (3 x 4) and the line (3 x 9).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineProjection {
    /// The homogeneous image line `l` (Eq. 12).
    pub line: Vector3<f64>,
    /// `∂l/∂p`.
    pub d_p: Matrix3<f64>,
    /// `∂l/∂q`.
    pub d_q: SMatrix<f64, 3, 4>,
    /// `∂l/∂A`.
    pub d_a: SMatrix<f64, 3, 9>,
}

/// Eq. 12, `l = K R_cᵀ (n - (T - p0) × v)`, with its Jacobians.
pub fn project(sensor: &Sensor, p: &Vector3<f64>, q: &Vector4<f64>, a: &Apl) -> LineProjection {
    let (p0, n, v) = parts(a);
    let r = rot(q);
    let t = p + r * sensor.t_bc;
    let w = n - (t - p0).cross(&v);
    let k = plucker_intrinsic(sensor);
    let m = k * sensor.r_bc.transpose(); // l = m Rᵀ w
    let line = m * r.transpose() * w;
    let mrt = m * r.transpose();
    // ∂w/∂T = [v]x, ∂w/∂p0 = -[v]x, ∂w/∂n = I, ∂w/∂v = [T - p0]x... with sign: w = n + v × (T - p0).
    let dw_dt = crate::quat::skew(&v);
    let d_p = mrt * dw_dt;
    let d_q = m * d_rot_t_dq(q, &w) + mrt * dw_dt * d_rot_dq(q, &sensor.t_bc);
    let mut d_a = SMatrix::<f64, 3, 9>::zeros();
    d_a.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-mrt * crate::quat::skew(&v)));
    d_a.fixed_view_mut::<3, 3>(0, 3).copy_from(&mrt);
    d_a.fixed_view_mut::<3, 3>(0, 6)
        .copy_from(&(-mrt * crate::quat::skew(&(t - p0))));
    LineProjection {
        line,
        d_p,
        d_q,
        d_a,
    }
}

/// The measurement of a segment observation: the signed distances of its two endpoints
/// `e1`, `e2` (pixels) to the image line `l`, in pixels (zero when the segment lies on the
/// line), and their Jacobian with respect to `l` (2 x 3).
pub fn endpoint_distances(
    l: &Vector3<f64>,
    e1: &Vector2<f64>,
    e2: &Vector2<f64>,
) -> (Vector2<f64>, SMatrix<f64, 2, 3>) {
    let norm = l.x.hypot(l.y);
    let mut h = Vector2::zeros();
    let mut j = SMatrix::<f64, 2, 3>::zeros();
    for (i, e) in [e1, e2].iter().enumerate() {
        let eh = Vector3::new(e.x, e.y, 1.0);
        let d = l.dot(&eh);
        h[i] = d / norm;
        let grad = eh / norm - Vector3::new(l.x, l.y, 0.0) * d / norm.powi(3);
        j.set_row(i, &grad.transpose());
    }
    (h, j)
}

/// Eqs. 14-19: the APL of an image line `l` seen from the robot at `(p, q)`, with the prior
/// `β` on its two unmeasured degrees of freedom: anchored at the optical centre,
/// `n = R_c K⁻¹ l`, `v = R_c E β`.
pub fn back_project(
    sensor: &Sensor,
    p: &Vector3<f64>,
    q: &Vector4<f64>,
    l: &Vector3<f64>,
    beta: &Vector2<f64>,
) -> Apl {
    let k_inv = plucker_intrinsic(sensor)
        .try_inverse()
        .expect("the Plücker intrinsic matrix of a camera is invertible");
    let n_c = k_inv * l;
    let e1 = Vector3::new(n_c.y, -n_c.x, 0.0) / n_c.x.hypot(n_c.y);
    let e2 = n_c.cross(&e1) / n_c.norm();
    let v_c = e1 * beta.x + e2 * beta.y;
    let r = rot(q);
    let rc = r * sensor.r_bc;
    let mut a = Apl::zeros();
    a.fixed_rows_mut::<3>(0).copy_from(&(p + r * sensor.t_bc));
    a.fixed_rows_mut::<3>(3).copy_from(&(rc * n_c));
    a.fixed_rows_mut::<3>(6).copy_from(&(rc * v_c));
    a
}

/// Jacobians of [`back_project`] with respect to the robot position (9 x 3), quaternion
/// (9 x 4), image line (9 x 3) and prior `β` (9 x 2): what the filter needs for a new line's
/// covariance.
pub struct BackProjection {
    /// The line.
    pub a: Apl,
    /// ∂A/∂p.
    pub d_p: SMatrix<f64, 9, 3>,
    /// ∂A/∂q.
    pub d_q: SMatrix<f64, 9, 4>,
    /// ∂A/∂l.
    pub d_l: SMatrix<f64, 9, 3>,
    /// ∂A/∂β.
    pub d_beta: SMatrix<f64, 9, 2>,
}

/// [`back_project`] with its analytic Jacobians.
pub fn back_project_with_jacobians(
    sensor: &Sensor,
    p: &Vector3<f64>,
    q: &Vector4<f64>,
    l: &Vector3<f64>,
    beta: &Vector2<f64>,
) -> BackProjection {
    let a = back_project(sensor, p, q, l, beta);
    let k_inv = plucker_intrinsic(sensor)
        .try_inverse()
        .expect("the Plücker intrinsic matrix of a camera is invertible");
    let n = k_inv * l;
    let h = n.x.hypot(n.y);
    let nn = n.norm();
    let e1 = Vector3::new(n.y, -n.x, 0.0) / h;
    let e2 = n.cross(&e1) / nn;
    // de1/dn and de2/dn.
    let de1 = Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0) / h
        - Vector3::new(n.y, -n.x, 0.0) * Vector3::new(n.x, n.y, 0.0).transpose() / h.powi(3);
    let de2 = (-crate::quat::skew(&e1) + crate::quat::skew(&n) * de1) / nn
        - n.cross(&e1) * n.transpose() / nn.powi(3);
    let v_c = e1 * beta.x + e2 * beta.y;
    let dv_dn = de1 * beta.x + de2 * beta.y;
    let rc = rot(q) * sensor.r_bc;
    let mut d_p = SMatrix::<f64, 9, 3>::zeros();
    d_p.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    let mut d_q = SMatrix::<f64, 9, 4>::zeros();
    d_q.fixed_view_mut::<3, 4>(0, 0)
        .copy_from(&d_rot_dq(q, &sensor.t_bc));
    d_q.fixed_view_mut::<3, 4>(3, 0)
        .copy_from(&d_rot_dq(q, &(sensor.r_bc * n)));
    d_q.fixed_view_mut::<3, 4>(6, 0)
        .copy_from(&d_rot_dq(q, &(sensor.r_bc * v_c)));
    let mut d_l = SMatrix::<f64, 9, 3>::zeros();
    d_l.fixed_view_mut::<3, 3>(3, 0).copy_from(&(rc * k_inv));
    d_l.fixed_view_mut::<3, 3>(6, 0)
        .copy_from(&(rc * dv_dn * k_inv));
    let mut d_beta = SMatrix::<f64, 9, 2>::zeros();
    d_beta.fixed_view_mut::<3, 1>(6, 0).copy_from(&(rc * e1));
    d_beta.fixed_view_mut::<3, 1>(6, 1).copy_from(&(rc * e2));
    BackProjection {
        a,
        d_p,
        d_q,
        d_l,
        d_beta,
    }
}

/// Eq. 13: the Euclidean points at abscissas `t` along the line, measured from the point of
/// the line closest to the anchor.
pub fn point_at(a: &Apl, t: f64) -> Vector3<f64> {
    let (p0, n, v) = parts(a);
    let q = p0 + v.cross(&n) / v.dot(&v);
    q + v * (t / v.norm())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quat::tests::{assert_close, numeric, random_quat};
    use hetsim_msgs::Pinhole;
    use nalgebra::{DMatrix, DVector, Isometry3, Translation3, UnitQuaternion};
    use rand::{RngExt, SeedableRng};

    fn sensor() -> Sensor {
        let r = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        Sensor::new(
            Pinhole {
                alpha_u: 500.0,
                alpha_v: 480.0,
                u0: 320.0,
                v0: 240.0,
            },
            &Isometry3::from_parts(
                Translation3::new(0.3, 0.1, 1.2),
                UnitQuaternion::from_matrix(&r),
            ),
        )
    }

    /// The APL of the line through two world points, anchored at `anchor`.
    fn line_through(a: &Vector3<f64>, b: &Vector3<f64>, anchor: &Vector3<f64>) -> Apl {
        let v = b - a;
        let n = (a - anchor).cross(&v);
        let mut l = Apl::zeros();
        l.fixed_rows_mut::<3>(0).copy_from(anchor);
        l.fixed_rows_mut::<3>(3).copy_from(&n);
        l.fixed_rows_mut::<3>(6).copy_from(&v);
        l
    }

    fn pixel(s: &Sensor, p: &Vector3<f64>, q: &Vector4<f64>, w: &Vector3<f64>) -> Vector2<f64> {
        let c = rot(q) * s.r_bc;
        let x = c.transpose() * (w - (p + rot(q) * s.t_bc));
        Vector2::new(
            s.camera.alpha_u * x.x / x.z + s.camera.u0,
            s.camera.alpha_v * x.y / x.z + s.camera.v0,
        )
    }

    #[test]
    fn projected_lines_pass_through_projected_points_and_jacobians_match() {
        let s = sensor();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        for _ in 0..100 {
            let p = Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                0.0,
            );
            let q = UnitQuaternion::from_euler_angles(0.0, 0.0, rng.random_range(-3.0..3.0));
            let q = crate::quat::from_unit(&q);
            // Two points 5-15 m in front of the camera.
            let cam = p + rot(&q) * s.t_bc;
            let fwd = rot(&q) * Vector3::x();
            let left = rot(&q) * Vector3::y();
            let a = cam
                + fwd * rng.random_range(5.0..15.0)
                + left * rng.random_range(-3.0..3.0)
                + Vector3::z() * rng.random_range(-1.0..2.0);
            let b = cam
                + fwd * rng.random_range(5.0..15.0)
                + left * rng.random_range(-3.0..3.0)
                + Vector3::z() * rng.random_range(-1.0..2.0);
            let anchor = Vector3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                1.0,
            );
            let apl = line_through(&a, &b, &anchor);
            let lp = project(&s, &p, &q, &apl);
            let (d, _) =
                endpoint_distances(&lp.line, &pixel(&s, &p, &q, &a), &pixel(&s, &p, &q, &b));
            assert!(d.abs().max() < 1e-6, "{d}");
            // Un-anchoring gives the same line as anchoring at the origin.
            let (n0, v0) = unanchor(&apl);
            let at_origin = line_through(&a, &b, &Vector3::zeros());
            assert!(
                (n0 - Vector3::new(at_origin[3], at_origin[4], at_origin[5])).norm() < 1e-9
                    && (v0 - (b - a)).norm() < 1e-12
            );
            // Frame transformations are inverse to each other.
            let r = rot(&random_quat(&mut rng));
            let t = Vector3::new(1.0, -2.0, 0.5);
            assert!((from_frame(&r, &t, &to_frame(&r, &t, &apl)) - apl).norm() < 1e-9);
            // Jacobians.
            let q2 = random_quat(&mut rng);
            let lp = project(&s, &p, &q2, &apl);
            let dm = |m: &[f64], r: usize, c: usize| DMatrix::from_column_slice(r, c, m);
            let f_p = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    project(&s, &Vector3::from_column_slice(x.as_slice()), &q2, &apl)
                        .line
                        .as_slice(),
                )
            };
            let f_q = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    project(&s, &p, &Vector4::from_column_slice(x.as_slice()), &apl)
                        .line
                        .as_slice(),
                )
            };
            let f_a = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    project(&s, &p, &q2, &Apl::from_column_slice(x.as_slice()))
                        .line
                        .as_slice(),
                )
            };
            assert_close(
                &dm(lp.d_p.as_slice(), 3, 3),
                &numeric(&f_p, &DVector::from_column_slice(p.as_slice())),
                "dl/dp",
            );
            assert_close(
                &dm(lp.d_q.as_slice(), 3, 4),
                &numeric(&f_q, &DVector::from_column_slice(q2.as_slice())),
                "dl/dq",
            );
            assert_close(
                &dm(lp.d_a.as_slice(), 3, 9),
                &numeric(&f_a, &DVector::from_column_slice(apl.as_slice())),
                "dl/dA",
            );
            let (e1, e2) = (Vector2::new(100.0, 50.0), Vector2::new(400.0, 300.0));
            let (_, jd) = endpoint_distances(&lp.line, &e1, &e2);
            let g = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    endpoint_distances(&Vector3::from_column_slice(x.as_slice()), &e1, &e2)
                        .0
                        .as_slice(),
                )
            };
            assert_close(
                &dm(jd.as_slice(), 2, 3),
                &numeric(&g, &DVector::from_column_slice(lp.line.as_slice())),
                "dd/dl",
            );
        }
    }

    #[test]
    fn back_projection_jacobians_match_finite_differences() {
        let s = sensor();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for _ in 0..20 {
            let p = Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                0.3,
            );
            let q = random_quat(&mut rng);
            let l = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-300.0..300.0),
            );
            let beta = Vector2::new(rng.random_range(0.01..0.05), rng.random_range(-0.03..0.03));
            let bp = back_project_with_jacobians(&s, &p, &q, &l, &beta);
            let x = DVector::from_iterator(
                12,
                p.iter()
                    .chain(q.iter())
                    .chain(l.iter())
                    .chain(beta.iter())
                    .copied(),
            );
            let f = |x: &DVector<f64>| {
                let a = back_project(
                    &s,
                    &Vector3::new(x[0], x[1], x[2]),
                    &Vector4::new(x[3], x[4], x[5], x[6]),
                    &Vector3::new(x[7], x[8], x[9]),
                    &Vector2::new(x[10], x[11]),
                );
                DVector::from_column_slice(a.as_slice())
            };
            let num = numeric(&f, &x);
            let mut analytic = DMatrix::zeros(9, 12);
            analytic.view_mut((0, 0), (9, 3)).copy_from(&bp.d_p);
            analytic.view_mut((0, 3), (9, 4)).copy_from(&bp.d_q);
            analytic.view_mut((0, 7), (9, 3)).copy_from(&bp.d_l);
            analytic.view_mut((0, 10), (9, 2)).copy_from(&bp.d_beta);
            assert_close(&analytic, &num, "back-projection");
            assert_eq!(bp.a, back_project(&s, &p, &q, &l, &beta));
        }
    }

    #[test]
    fn back_projection_reprojects_onto_its_image_line_and_beta_sets_the_distance() {
        let s = sensor();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        for _ in 0..50 {
            let p = Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                0.0,
            );
            let q = random_quat(&mut rng);
            let l = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                0.0,
            );
            let l = Vector3::new(l.x, l.y, -(l.x * 300.0 + l.y * 200.0));
            // The seed's prior β = (0.025, 0): a line parallel to the image plane.
            let a = back_project(&s, &p, &q, &l, &Vector2::new(0.025, 0.0));
            let lp = project(&s, &p, &q, &a);
            // Same image line (up to scale).
            let cross = lp.line.normalize().cross(&l.normalize());
            assert!(cross.norm() < 1e-9, "{} vs {l}", lp.line);
            // Anchor at the optical centre; n ⟂ v; distance |n| / |v|.
            let (p0, n, v) = parts(&a);
            assert!((p0 - (p + rot(&q) * s.t_bc)).norm() < 1e-12);
            assert!(n.dot(&v).abs() < 1e-9 * n.norm() * v.norm());
            // |v| = |β| (E is orthonormal), and the line passes |n| / |v| from the anchor.
            assert!((v.norm() - 0.025).abs() < 1e-12);
            assert!(
                ((point_at(&a, 0.0) - p0).norm() - n.norm() / v.norm()).abs()
                    < 1e-6 * n.norm() / v.norm()
            );
            // Points on the line project onto the image line.
            for t in [-2.0, 0.0, 3.0] {
                let w = point_at(&a, t);
                let cam = (rot(&q) * s.r_bc).transpose() * (w - p0);
                if cam.z > 0.1 {
                    let (d, _) =
                        endpoint_distances(&l, &pixel(&s, &p, &q, &w), &pixel(&s, &p, &q, &w));
                    assert!(d[0].abs() < 1e-6, "{d}");
                }
            }
        }
    }
}
