//! Quaternions as plain 4-vectors `[w, x, y, z]` (Hamilton, unit, `R(q)` rotates body to
//! world), with the Jacobians the filter needs (after Solà, "Quaternion kinematics for the
//! error-state Kalman filter", 2017).

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Matrix4x3, Vector3, Vector4};

/// Rotation matrix of a unit quaternion.
pub fn rot(q: &Vector4<f64>) -> Matrix3<f64> {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    Matrix3::new(
        w * w + x * x - y * y - z * z,
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        w * w - x * x + y * y - z * z,
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        w * w - x * x - y * y + z * z,
    )
}

/// `[w, x, y, z]` of a nalgebra unit quaternion.
pub fn from_unit(q: &nalgebra::UnitQuaternion<f64>) -> Vector4<f64> {
    let c = q.quaternion();
    Vector4::new(c.w, c.i, c.j, c.k)
}

/// The nalgebra unit quaternion of `[w, x, y, z]` (normalized).
pub fn to_unit(q: &Vector4<f64>) -> nalgebra::UnitQuaternion<f64> {
    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// The cross-product matrix: `skew(a) b = a × b`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `∂(R(q) v)/∂q`, 3 x 4.
pub fn d_rot_dq(q: &Vector4<f64>, v: &Vector3<f64>) -> Matrix3x4<f64> {
    let w = q[0];
    let u = Vector3::new(q[1], q[2], q[3]);
    let first = 2.0 * (w * v + u.cross(v));
    let rest = 2.0
        * (Matrix3::identity() * u.dot(v) + u * v.transpose() - v * u.transpose() - w * skew(v));
    let mut j = Matrix3x4::zeros();
    j.set_column(0, &first);
    j.fixed_view_mut::<3, 3>(0, 1).copy_from(&rest);
    j
}

/// `∂(R(q)ᵀ v)/∂q`, 3 x 4.
pub fn d_rot_t_dq(q: &Vector4<f64>, v: &Vector3<f64>) -> Matrix3x4<f64> {
    let conj = Vector4::new(q[0], -q[1], -q[2], -q[3]);
    let mut j = d_rot_dq(&conj, v);
    for c in 1..4 {
        let col = -j.column(c);
        j.set_column(c, &col);
    }
    j
}

/// `q ⊗ p`.
pub fn mul(q: &Vector4<f64>, p: &Vector4<f64>) -> Vector4<f64> {
    left(q) * p
}

/// `[q]_L`: `q ⊗ p = [q]_L p`.
pub fn left(q: &Vector4<f64>) -> Matrix4<f64> {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    Matrix4::new(w, -x, -y, -z, x, w, -z, y, y, z, w, -x, z, -y, x, w)
}

/// `[p]_R`: `q ⊗ p = [p]_R q`.
pub fn right(p: &Vector4<f64>) -> Matrix4<f64> {
    let (w, x, y, z) = (p[0], p[1], p[2], p[3]);
    Matrix4::new(w, -x, -y, -z, x, w, z, -y, y, -z, w, x, z, y, -x, w)
}

/// The quaternion of a rotation vector, and its Jacobian, 4 x 3.
pub fn from_rotation_vector(theta: &Vector3<f64>) -> (Vector4<f64>, Matrix4x3<f64>) {
    let a = theta.norm();
    let mut j = Matrix4x3::zeros();
    if a < 1e-8 {
        // Series: q ≈ [1 - a²/8, θ/2], ∂q_w/∂θ = -θᵀ/4, ∂q_v/∂θ = I/2.
        let q = Vector4::new(
            1.0 - a * a / 8.0,
            theta.x / 2.0,
            theta.y / 2.0,
            theta.z / 2.0,
        );
        j.fixed_view_mut::<1, 3>(0, 0)
            .copy_from(&(-theta.transpose() / 4.0));
        j.fixed_view_mut::<3, 3>(1, 0)
            .copy_from(&(Matrix3::identity() * 0.5));
        return (q, j);
    }
    let (s, c) = (a / 2.0).sin_cos();
    let u = theta / a;
    let q = Vector4::new(c, s * u.x, s * u.y, s * u.z);
    j.fixed_view_mut::<1, 3>(0, 0)
        .copy_from(&(-0.5 * s * u.transpose()));
    let uu = u * u.transpose();
    let block = (s / a) * (Matrix3::identity() - uu) + 0.5 * c * uu;
    j.fixed_view_mut::<3, 3>(1, 0).copy_from(&block);
    (q, j)
}

/// The Jacobian of `q / |q|` at `q`, 4 x 4.
pub fn d_normalize(q: &Vector4<f64>) -> Matrix4<f64> {
    let n = q.norm();
    (Matrix4::identity() - q * q.transpose() / (n * n)) / n
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use rand::{RngExt, SeedableRng};

    /// Central finite differences of `f` at `x`.
    pub fn numeric(f: &dyn Fn(&DVector<f64>) -> DVector<f64>, x: &DVector<f64>) -> DMatrix<f64> {
        let y = f(x);
        let mut j = DMatrix::zeros(y.len(), x.len());
        for k in 0..x.len() {
            let h = 1e-6 * (1.0 + x[k].abs());
            let (mut a, mut b) = (x.clone(), x.clone());
            a[k] += h;
            b[k] -= h;
            j.set_column(k, &((f(&a) - f(&b)) / (2.0 * h)));
        }
        j
    }

    pub fn assert_close(analytic: &DMatrix<f64>, numeric: &DMatrix<f64>, what: &str) {
        let err = (analytic - numeric).abs().max();
        let scale = 1.0 + numeric.abs().max();
        assert!(
            err < 1e-5 * scale,
            "{what}: max error {err:e}\nanalytic {analytic}\nnumeric {numeric}"
        );
    }

    pub fn random_quat(rng: &mut impl rand::Rng) -> Vector4<f64> {
        let q = Vector4::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        q.normalize()
    }

    #[test]
    fn rotation_matches_nalgebra_and_jacobians_match_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for _ in 0..50 {
            let q = random_quat(&mut rng);
            let v = Vector3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
            );
            assert!(
                (rot(&q) - to_unit(&q).to_rotation_matrix().into_inner())
                    .abs()
                    .max()
                    < 1e-12
            );
            let x = DVector::from_column_slice(q.as_slice());
            // The formulas hold for any q (not only unit ones): differentiate freely.
            let f = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    (rot(&Vector4::from_column_slice(x.as_slice())) * v).as_slice(),
                )
            };
            let g = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    (rot(&Vector4::from_column_slice(x.as_slice())).transpose() * v).as_slice(),
                )
            };
            let dm = |m: Matrix3x4<f64>| DMatrix::from_column_slice(3, 4, m.as_slice());
            assert_close(&dm(d_rot_dq(&q, &v)), &numeric(&f, &x), "dR v/dq");
            assert_close(&dm(d_rot_t_dq(&q, &v)), &numeric(&g, &x), "dRᵀ v/dq");
            let p = random_quat(&mut rng);
            assert!((mul(&q, &p) - right(&p) * q).abs().max() < 1e-12);
            assert!((rot(&mul(&q, &p)) - rot(&q) * rot(&p)).abs().max() < 1e-12);
            let theta = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            ) * rng.random_range(0.0..1.0);
            let (qt, jt) = from_rotation_vector(&theta);
            let r = nalgebra::Rotation3::new(theta);
            assert!((rot(&qt) - r.into_inner()).abs().max() < 1e-12);
            let h = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    from_rotation_vector(&Vector3::from_column_slice(x.as_slice()))
                        .0
                        .as_slice(),
                )
            };
            assert_close(
                &DMatrix::from_column_slice(4, 3, jt.as_slice()),
                &numeric(&h, &DVector::from_column_slice(theta.as_slice())),
                "dq/dθ",
            );
            let n = |x: &DVector<f64>| x.normalize();
            let q2 = q * 1.3;
            assert_close(
                &DMatrix::from_column_slice(4, 4, d_normalize(&q2).as_slice()),
                &numeric(&n, &DVector::from_column_slice(q2.as_slice())),
                "d normalize",
            );
        }
        // Near zero, the series branch.
        let (_, j0) = from_rotation_vector(&Vector3::new(1e-10, 0.0, 0.0));
        assert!(
            (j0.fixed_view::<3, 3>(1, 0) - Matrix3::identity() * 0.5)
                .abs()
                .max()
                < 1e-9
        );
    }
}
