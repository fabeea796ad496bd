//! The camera geometry that the renderer, the robot software and the evaluation share: one
//! pinhole model (also a robot file's `intrinsics` table), its projection and Jacobian, the
//! image it fills, and the mount-to-optical rotation.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// A pinhole camera (OpenCV convention: `u = αu x/z + u0`, `v = αv y/z + v0` in the optical
/// frame, x right, y down, z forward; pixel centres at integer coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pinhole {
    /// Focal length along u, pixels.
    pub alpha_u: f64,
    /// Focal length along v, pixels.
    pub alpha_v: f64,
    /// Principal point u0, pixels.
    pub u0: f64,
    /// Principal point v0, pixels.
    pub v0: f64,
}

impl Pinhole {
    /// Pixel of a point in the optical frame, if in front of the camera (z > 0).
    #[inline]
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        (p.z > 1e-9).then(|| {
            [
                self.alpha_u * p.x / p.z + self.u0,
                self.alpha_v * p.y / p.z + self.v0,
            ]
        })
    }

    /// Jacobian of [`Pinhole::project`] with respect to the point, 2 x 3, row-major.
    #[inline]
    pub fn project_jacobian(&self, p: &Vector3<f64>) -> [[f64; 3]; 2] {
        let iz = 1.0 / p.z;
        [
            [self.alpha_u * iz, 0.0, -self.alpha_u * p.x * iz * iz],
            [0.0, self.alpha_v * iz, -self.alpha_v * p.y * iz * iz],
        ]
    }

    /// The point at depth `z` (along the optical axis) seen at pixel `(u, v)`; with `z = 1`,
    /// the pixel's ray.
    #[inline]
    pub fn back_project(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        Vector3::new(
            (u - self.u0) / self.alpha_u * z,
            (v - self.v0) / self.alpha_v * z,
            z,
        )
    }

    /// `K`.
    #[inline]
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.alpha_u,
            0.0,
            self.u0,
            0.0,
            self.alpha_v,
            self.v0,
            0.0,
            0.0,
            1.0,
        )
    }
}

/// A camera's image and its pinhole: what a renderer needs to make the image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraGeometry {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The pinhole (`K`).
    pub k: Pinhole,
}

impl CameraGeometry {
    /// Square pixels, principal point at the image centre, horizontal opening angle `hfov`.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Self {
        let alpha = (width as f64 / 2.0) / (hfov_deg.to_radians() / 2.0).tan();
        Self {
            width,
            height,
            k: Pinhole {
                alpha_u: alpha,
                alpha_v: alpha,
                u0: (width as f64 - 1.0) / 2.0,
                v0: (height as f64 - 1.0) / 2.0,
            },
        }
    }
}

/// `mount_from_optical`: sensor mounts follow the body convention (x along the optical axis,
/// y left, z up); the optical frame is x right, y down, z forward.
pub fn mount_to_optical() -> UnitQuaternion<f64> {
    let m = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn back_projection_inverts_projection_and_the_jacobian_is_the_derivative() {
        let k = Pinhole {
            alpha_u: 71.5,
            alpha_v: 70.0,
            u0: 60.3,
            v0: 42.8,
        };
        let p = Vector3::new(0.3, -0.2, 4.0);
        let [u, v] = k.project(&p).unwrap();
        assert!((k.back_project(u, v, p.z) - p).norm() < 1e-12);
        assert!(k.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
        let j = k.project_jacobian(&p);
        let h = 1e-6;
        for (c, col) in [Vector3::x(), Vector3::y(), Vector3::z()]
            .iter()
            .enumerate()
        {
            let [up, vp] = k.project(&(p + col * h)).unwrap();
            let [um, vm] = k.project(&(p - col * h)).unwrap();
            assert!((j[0][c] - (up - um) / (2.0 * h)).abs() < 1e-5);
            assert!((j[1][c] - (vp - vm) / (2.0 * h)).abs() < 1e-5);
        }
        let m = k.matrix() * p;
        assert!((m.x / m.z - u).abs() < 1e-12 && (m.y / m.z - v).abs() < 1e-12);
    }

    #[test]
    fn optical_axis_is_the_mount_x_axis() {
        let r = mount_to_optical();
        assert!((r * Vector3::z() - Vector3::x()).norm() < 1e-12);
        assert!(
            (r * Vector3::x() + Vector3::y()).norm() < 1e-12,
            "optical x (right) is mount -y"
        );
        assert!(
            (r * Vector3::y() + Vector3::z()).norm() < 1e-12,
            "optical y (down) is mount -z"
        );
    }
}
