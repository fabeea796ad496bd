//! Inverse-depth points (Civera, Davison and Montiel, 2008), in a local map frame.
//!
//! A point is the 6-vector `y = (p0, θ, φ, ρ)`: the anchor `p0` (the optical centre where it
//! was first seen), the azimuth `θ` and elevation `φ` of its ray in the map frame (x, y
//! horizontal, z up), `m(θ, φ) = (cos φ cos θ, cos φ sin θ, sin φ)`, and the inverse depth
//! `ρ` along that ray: the Euclidean point is `p0 + m / ρ`.
//!
//! The robot pose is `(p, q)`, position and unit quaternion `[w, x, y, z]` of the body in the
//! map frame; the camera's optical frame is at `body_from_camera = (t_bc, R_bc)`. A point is
//! seen in the optical frame along `h_c = R_bcᵀ (R(q)ᵀ (ρ (p0 - p) + m) - ρ t_bc)`, which is
//! the camera-frame point scaled by `ρ` (well defined even at infinity, `ρ = 0`), and projects
//! to `u = αu h_x / h_z + u0`, `v = αv h_y / h_z + v0`.

use crate::quat::{d_rot_dq, d_rot_t_dq, rot};
use hetsim_msgs::Pinhole;
use nalgebra::{Isometry3, Matrix2x3, Matrix3, Matrix3x4, SMatrix, Vector2, Vector3, Vector4};

/// An inverse-depth point.
pub type Idp = SMatrix<f64, 6, 1>;

/// The camera of a local map's observations: intrinsics and where it sits on the body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensor {
    /// Pinhole intrinsics.
    pub camera: Pinhole,
    /// Translation of the optical frame in the body frame.
    pub t_bc: Vector3<f64>,
    /// Rotation of the optical frame in the body frame.
    pub r_bc: Matrix3<f64>,
}

impl Sensor {
    /// A sensor at `body_from_camera` (optical frame: x right, y down, z forward).
    pub fn new(camera: Pinhole, body_from_camera: &Isometry3<f64>) -> Self {
        Self {
            camera,
            t_bc: body_from_camera.translation.vector,
            r_bc: body_from_camera.rotation.to_rotation_matrix().into_inner(),
        }
    }
}

/// The unit ray of azimuth `θ` and elevation `φ`, and its derivatives.
fn ray(theta: f64, phi: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    (
        Vector3::new(cp * ct, cp * st, sp),
        Vector3::new(-cp * st, cp * ct, 0.0),
        Vector3::new(-sp * ct, -sp * st, cp),
    )
}

/// The Euclidean point of an inverse-depth point (`None` at infinity or behind).
pub fn euclidean(y: &Idp) -> Option<Vector3<f64>> {
    let (m, _, _) = ray(y[3], y[4]);
    (y[5] > 1e-9).then(|| Vector3::new(y[0], y[1], y[2]) + m / y[5])
}

/// An observation's prediction: the pixel, and its Jacobians with respect to the robot
/// position (2 x 3), quaternion (2 x 4) and the point (2 x 6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// Predicted pixel.
    pub pixel: Vector2<f64>,
    /// `∂u/∂p`.
    pub d_p: Matrix2x3<f64>,
    /// `∂u/∂q`.
    pub d_q: SMatrix<f64, 2, 4>,
    /// `∂u/∂y`.
    pub d_y: SMatrix<f64, 2, 6>,
    /// Depth of the point along the optical axis times ρ (positive in front).
    pub h_z: f64,
}

/// Projects a point seen from the robot at `(p, q)`; `None` when it is behind the camera.
pub fn project(sensor: &Sensor, p: &Vector3<f64>, q: &Vector4<f64>, y: &Idp) -> Option<Projection> {
    let p0 = Vector3::new(y[0], y[1], y[2]);
    let rho = y[5];
    let (m, dm_dt, dm_dp) = ray(y[3], y[4]);
    let w = rho * (p0 - p) + m;
    let rt = rot(q).transpose();
    let rbt = sensor.r_bc.transpose();
    let h = rbt * (rt * w - rho * sensor.t_bc);
    if h.z <= 1e-9 {
        return None;
    }
    let c = &sensor.camera;
    let iz = 1.0 / h.z;
    let pixel = Vector2::new(c.alpha_u * h.x * iz + c.u0, c.alpha_v * h.y * iz + c.v0);
    let j_proj = Matrix2x3::new(
        c.alpha_u * iz,
        0.0,
        -c.alpha_u * h.x * iz * iz,
        0.0,
        c.alpha_v * iz,
        -c.alpha_v * h.y * iz * iz,
    );
    let a = rbt * rt; // ∂h/∂w
    let dh_dp = -rho * a;
    let dh_dq: Matrix3x4<f64> = rbt * d_rot_t_dq(q, &w);
    let mut dh_dy = SMatrix::<f64, 3, 6>::zeros();
    dh_dy.fixed_view_mut::<3, 3>(0, 0).copy_from(&(rho * a));
    dh_dy.set_column(3, &(a * dm_dt));
    dh_dy.set_column(4, &(a * dm_dp));
    dh_dy.set_column(5, &(rbt * (rt * (p0 - p) - sensor.t_bc)));
    Some(Projection {
        pixel,
        d_p: j_proj * dh_dp,
        d_q: j_proj * dh_dq,
        d_y: j_proj * dh_dy,
        h_z: h.z,
    })
}

/// A new point from a pixel: the point and its Jacobians with respect to the robot
/// position (6 x 3), quaternion (6 x 4), the pixel (6 x 2) and the inverse-depth prior
/// (6 x 1, the unit vector of ρ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Init {
    /// The point, with `ρ = ρ_init`.
    pub y: Idp,
    /// `∂y/∂p`.
    pub d_p: SMatrix<f64, 6, 3>,
    /// `∂y/∂q`.
    pub d_q: SMatrix<f64, 6, 4>,
    /// `∂y/∂pixel`.
    pub d_pixel: SMatrix<f64, 6, 2>,
}

/// Back-projects `pixel` from the robot at `(p, q)` with inverse depth `rho_init`.
pub fn init(
    sensor: &Sensor,
    p: &Vector3<f64>,
    q: &Vector4<f64>,
    pixel: &Vector2<f64>,
    rho_init: f64,
) -> Init {
    let c = &sensor.camera;
    let r_c = Vector3::new(
        (pixel.x - c.u0) / c.alpha_u,
        (pixel.y - c.v0) / c.alpha_v,
        1.0,
    );
    let r = rot(q);
    let v = sensor.r_bc * r_c;
    let d = r * v;
    let anchor = p + r * sensor.t_bc;
    let horiz2 = d.x * d.x + d.y * d.y;
    let horiz = horiz2.sqrt();
    let n2 = horiz2 + d.z * d.z;
    let theta = d.y.atan2(d.x);
    let phi = d.z.atan2(horiz);
    // ∂(θ, φ)/∂d.
    let mut dang = SMatrix::<f64, 2, 3>::zeros();
    dang[(0, 0)] = -d.y / horiz2;
    dang[(0, 1)] = d.x / horiz2;
    dang[(1, 0)] = -d.x * d.z / (n2 * horiz);
    dang[(1, 1)] = -d.y * d.z / (n2 * horiz);
    dang[(1, 2)] = horiz / n2;
    let mut y = Idp::zeros();
    y.fixed_view_mut::<3, 1>(0, 0).copy_from(&anchor);
    y[3] = theta;
    y[4] = phi;
    y[5] = rho_init;
    let mut d_p = SMatrix::<f64, 6, 3>::zeros();
    d_p.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    let mut d_q = SMatrix::<f64, 6, 4>::zeros();
    d_q.fixed_view_mut::<3, 4>(0, 0)
        .copy_from(&d_rot_dq(q, &sensor.t_bc));
    d_q.fixed_view_mut::<2, 4>(3, 0)
        .copy_from(&(dang * d_rot_dq(q, &v)));
    let d_rc = SMatrix::<f64, 3, 2>::new(1.0 / c.alpha_u, 0.0, 0.0, 1.0 / c.alpha_v, 0.0, 0.0);
    let mut d_pixel = SMatrix::<f64, 6, 2>::zeros();
    d_pixel
        .fixed_view_mut::<2, 2>(3, 0)
        .copy_from(&(dang * r * sensor.r_bc * d_rc));
    Init {
        y,
        d_p,
        d_q,
        d_pixel,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quat::tests::{assert_close, numeric, random_quat};
    use nalgebra::{DMatrix, DVector, UnitQuaternion};
    use rand::{RngExt, SeedableRng};

    fn sensor() -> Sensor {
        // A forward camera 0.5 m ahead and 1 m up, pitched down 10 degrees.
        let mount = Isometry3::from_parts(
            nalgebra::Translation3::new(0.5, 0.1, 1.0),
            UnitQuaternion::from_euler_angles(0.0, 10f64.to_radians(), 0.0)
                * UnitQuaternion::from_matrix(&Matrix3::new(
                    0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
                )),
        );
        Sensor::new(
            Pinhole {
                alpha_u: 500.0,
                alpha_v: 505.0,
                u0: 320.0,
                v0: 240.0,
            },
            &mount,
        )
    }

    fn dm<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
        DMatrix::from_column_slice(R, C, m.as_slice())
    }

    #[test]
    fn a_point_initialized_from_a_pixel_projects_back_to_it_at_any_depth() {
        let s = sensor();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for _ in 0..100 {
            let p = Vector3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                rng.random_range(-1.0..1.0),
            );
            let q = random_quat(&mut rng);
            let px = Vector2::new(rng.random_range(10.0..630.0), rng.random_range(10.0..470.0));
            for rho in [0.0, 0.02, 0.5] {
                let i = init(&s, &p, &q, &px, rho);
                let pr = project(&s, &p, &q, &i.y).expect("in front");
                assert!((pr.pixel - px).norm() < 1e-8, "{} vs {px}", pr.pixel);
            }
            // The Euclidean point: a depth-10 point is 10 / |r_c| along the ray.
            let i = init(&s, &p, &q, &px, 0.1);
            let e = euclidean(&i.y).unwrap();
            assert!(((e - (p + rot(&q) * s.t_bc)).norm() - 10.0).abs() < 1e-9);
        }
    }

    #[test]
    fn projection_and_initialization_jacobians_match_finite_differences() {
        let s = sensor();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut checked = 0;
        while checked < 100 {
            let p = Vector3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                rng.random_range(-1.0..1.0),
            );
            let q = random_quat(&mut rng);
            let px = Vector2::new(rng.random_range(10.0..630.0), rng.random_range(10.0..470.0));
            let mut y = init(&s, &p, &q, &px, rng.random_range(0.05..1.0)).y;
            // A different robot pose, close enough to still see it.
            let p2 = p + Vector3::new(
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            );
            let q2 = (q + Vector4::new(
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.05..0.05),
                rng.random_range(-0.05..0.05),
            ))
            .normalize();
            y[5] *= rng.random_range(0.5..2.0);
            let Some(pr) = project(&s, &p2, &q2, &y) else {
                continue;
            };
            checked += 1;
            let f_p = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    project(&s, &Vector3::from_column_slice(x.as_slice()), &q2, &y)
                        .unwrap()
                        .pixel
                        .as_slice(),
                )
            };
            let f_q = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    project(&s, &p2, &Vector4::from_column_slice(x.as_slice()), &y)
                        .unwrap()
                        .pixel
                        .as_slice(),
                )
            };
            let f_y = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    project(&s, &p2, &q2, &Idp::from_column_slice(x.as_slice()))
                        .unwrap()
                        .pixel
                        .as_slice(),
                )
            };
            assert_close(
                &dm(&pr.d_p),
                &numeric(&f_p, &DVector::from_column_slice(p2.as_slice())),
                "du/dp",
            );
            assert_close(
                &dm(&pr.d_q),
                &numeric(&f_q, &DVector::from_column_slice(q2.as_slice())),
                "du/dq",
            );
            assert_close(
                &dm(&pr.d_y),
                &numeric(&f_y, &DVector::from_column_slice(y.as_slice())),
                "du/dy",
            );
            let i = init(&s, &p, &q, &px, 0.2);
            let g_p = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    init(&s, &Vector3::from_column_slice(x.as_slice()), &q, &px, 0.2)
                        .y
                        .as_slice(),
                )
            };
            let g_q = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    init(&s, &p, &Vector4::from_column_slice(x.as_slice()), &px, 0.2)
                        .y
                        .as_slice(),
                )
            };
            let g_u = |x: &DVector<f64>| {
                DVector::from_column_slice(
                    init(&s, &p, &q, &Vector2::from_column_slice(x.as_slice()), 0.2)
                        .y
                        .as_slice(),
                )
            };
            assert_close(
                &dm(&i.d_p),
                &numeric(&g_p, &DVector::from_column_slice(p.as_slice())),
                "dy/dp",
            );
            assert_close(
                &dm(&i.d_q),
                &numeric(&g_q, &DVector::from_column_slice(q.as_slice())),
                "dy/dq",
            );
            assert_close(
                &dm(&i.d_pixel),
                &numeric(&g_u, &DVector::from_column_slice(px.as_slice())),
                "dy/dpixel",
            );
        }
    }
}
