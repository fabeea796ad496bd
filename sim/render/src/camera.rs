//! Camera poses and the projection matrix of a [`CameraGeometry`].

use hetsim_msgs::{mount_to_optical, CameraGeometry, Pose};
use nalgebra::Matrix4;

/// A camera to render.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraView {
    /// Intrinsics.
    pub intrinsics: CameraGeometry,
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
        intrinsics: CameraGeometry,
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
        let (w, h) = (self.intrinsics.width as f64, self.intrinsics.height as f64);
        let k = &self.intrinsics.k;
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
    use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

    #[test]
    fn projection_matrix_lands_points_on_their_pixels() {
        let k = hetsim_msgs::Pinhole {
            alpha_u: 71.5,
            alpha_v: 70.0,
            u0: 60.3,
            v0: 42.8,
        };
        let view = CameraView {
            intrinsics: CameraGeometry {
                width: 120,
                height: 88,
                k,
            },
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
            let [eu, ev] = k.project(&p).unwrap();
            assert!(
                (u - eu).abs() < 1e-9 && (v - ev).abs() < 1e-9,
                "{u},{v} vs {eu},{ev}"
            );
            let z = clip.z / clip.w;
            assert!((0.0..=1.0).contains(&z));
        }
    }
}
