//! Pinhole intrinsics, camera poses and the projection matrix.

use hetsim_msgs::Pose;
use nalgebra::{Matrix3, Matrix4, Rotation3, UnitQuaternion, Vector3};

/// Pinhole intrinsics in pixels (OpenCV convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along u, pixels.
    pub alpha_u: f64,
    /// Focal length along v, pixels.
    pub alpha_v: f64,
    /// Principal point u0, pixels.
    pub u0: f64,
    /// Principal point v0, pixels.
    pub v0: f64,
}

impl Intrinsics {
    /// Square pixels, principal point at the image centre, horizontal opening angle `hfov`.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Self {
        let alpha = (width as f64 / 2.0) / (hfov_deg.to_radians() / 2.0).tan();
        Self {
            width,
            height,
            alpha_u: alpha,
            alpha_v: alpha,
            u0: (width as f64 - 1.0) / 2.0,
            v0: (height as f64 - 1.0) / 2.0,
        }
    }

    /// Pixel coordinates of a point in the optical frame, if in front of the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        (p.z > 1e-9).then(|| {
            (
                self.alpha_u * p.x / p.z + self.u0,
                self.alpha_v * p.y / p.z + self.v0,
            )
        })
    }

    /// The ray through pixel `(u, v)` in the optical frame, with z = 1.
    pub fn back_project(&self, u: f64, v: f64) -> Vector3<f64> {
        Vector3::new(
            (u - self.u0) / self.alpha_u,
            (v - self.v0) / self.alpha_v,
            1.0,
        )
    }

    /// `K`.
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

/// Pinhole intrinsics of a camera sensor: given, or from resolution and field of view.
pub fn intrinsics_of(
    width: u32,
    height: u32,
    hfov_deg: Option<f64>,
    k: Option<&hetsim_scene::Intrinsics>,
) -> Intrinsics {
    match k {
        Some(k) => Intrinsics {
            width,
            height,
            alpha_u: k.alpha_u,
            alpha_v: k.alpha_v,
            u0: k.u0,
            v0: k.v0,
        },
        None => Intrinsics::from_hfov(width, height, hfov_deg.unwrap_or(60.0)),
    }
}

/// `mount_from_optical`: sensor mounts follow the body convention (x along the optical axis,
/// y left, z up); the optical frame is x right, y down, z forward.
pub fn mount_to_optical() -> UnitQuaternion<f64> {
    let m = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// A camera to render.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraView {
    /// Intrinsics.
    pub intrinsics: Intrinsics,
    /// `world_from_optical`.
    pub world_from_optical: Pose,
    /// Near and far clipping distances, metres.
    pub near_far_m: [f64; 2],
    /// A robot (index into the last `set_robots`) not to draw: the camera's own.
    pub hide_robot: Option<usize>,
    /// Render and read back linear depth too (frame dumps, tests, depth cameras); without
    /// it only colour is written and read.
    pub depth: bool,
    /// Where the terrain's levels of detail are measured from (default: the optical
    /// centre). Views that must see the same geometry (a stereo pair, a robot's cameras)
    /// share one point.
    pub lod_from: Option<nalgebra::Point3<f64>>,
}

impl CameraView {
    /// A camera whose sensor mount (x along the optical axis, y left, z up) is at
    /// `world_from_mount`, clipping at `near_far_m`, hiding no robot.
    pub fn from_mount(
        intrinsics: Intrinsics,
        world_from_mount: &Pose,
        near_far_m: [f64; 2],
    ) -> Self {
        Self {
            intrinsics,
            world_from_optical: nalgebra::Isometry3::from_parts(
                world_from_mount.translation,
                world_from_mount.rotation * mount_to_optical(),
            ),
            near_far_m,
            hide_robot: None,
            depth: false,
            lod_from: None,
        }
    }

    /// The same view, with depth rendered and read back.
    pub fn with_depth(mut self) -> Self {
        self.depth = true;
        self
    }

    /// The matrix taking world points to clip space.
    pub fn view_proj(&self) -> Matrix4<f64> {
        let k = &self.intrinsics;
        let (w, h) = (k.width as f64, k.height as f64);
        let [n, f] = self.near_far_m;
        #[rustfmt::skip]
        let proj = Matrix4::new(
            2.0 * k.alpha_u / w, 0.0, 2.0 * (k.u0 + 0.5) / w - 1.0, 0.0,
            0.0, -2.0 * k.alpha_v / h, 1.0 - 2.0 * (k.v0 + 0.5) / h, 0.0,
            0.0, 0.0, f / (f - n), -f * n / (f - n),
            0.0, 0.0, 1.0, 0.0,
        );
        proj * self.world_from_optical.inverse().to_homogeneous()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3, Translation3};

    #[test]
    fn projection_matrix_lands_points_on_their_pixels() {
        let k = Intrinsics {
            width: 120,
            height: 88,
            alpha_u: 71.5,
            alpha_v: 70.0,
            u0: 60.3,
            v0: 42.8,
        };
        let view = CameraView {
            intrinsics: k,
            world_from_optical: Isometry3::from_parts(
                Translation3::new(1.0, 2.0, 3.0),
                UnitQuaternion::from_euler_angles(0.3, -0.2, 1.1),
            ),
            near_far_m: [0.05, 100.0],
            hide_robot: None,
            depth: false,
            lod_from: None,
        };
        let m = view.view_proj();
        for p in [
            Vector3::new(0.3, -0.2, 4.0),
            Vector3::new(-1.0, 0.5, 2.0),
            Vector3::new(0.0, 0.0, 9.0),
        ] {
            let world = view.world_from_optical * Point3::from(p);
            let clip = m * world.to_homogeneous();
            let (ndc_x, ndc_y) = (clip.x / clip.w, clip.y / clip.w);
            let u = (ndc_x + 1.0) / 2.0 * 120.0 - 0.5;
            let v = (1.0 - ndc_y) / 2.0 * 88.0 - 0.5;
            let (eu, ev) = k.project(&p).unwrap();
            assert!(
                (u - eu).abs() < 1e-9 && (v - ev).abs() < 1e-9,
                "{u},{v} vs {eu},{ev}"
            );
            let z = clip.z / clip.w;
            assert!((0.0..=1.0).contains(&z));
        }
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
