//! The calibration a camera is given and the one it truly has.
//!
//! The robot file's intrinsics, distortion, baseline and mount are what the robot software is
//! given, as a real bench's calibration file is. The simulator renders with a true calibration
//! drawn once per run from the file's `calibration_error`: every error a normal draw truncated
//! at [`TRUNCATION_SIGMAS`] (drawn again beyond it), from the camera's own stream
//! `<robot>/<camera>/calibration`, in a fixed order (the left camera's intrinsics and
//! distortion, the mount, the time offset, then a bench's right camera's intrinsics and
//! distortion, its rotation and its offset against the left camera). A bench's two cameras
//! share the mount error and the time offset (one rigid, hardware-triggered bench).
//!
//! [`reprojection_rms_px`] turns the drawn errors into what a calibration report gives: the
//! RMS distance between where the true camera sees a point and where the given calibration
//! predicts it.

use hetsim_core::SimRng;
use hetsim_msgs::{mount_to_optical, pose_from_xyz_rpy, CameraGeometry, Pinhole, Pose};
use hetsim_scene::{CalibrationError, TRUNCATION_SIGMAS};
use nalgebra::{Isometry3, Point3, Vector3};
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// One camera's calibration: intrinsics, radial distortion and mount.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Image size and pinhole.
    pub geometry: CameraGeometry,
    /// Radial distortion `[k1, k2]`.
    pub distortion: [f64; 2],
    /// `body_from_mount` (body axis convention: x along the view).
    pub body_from_mount: Pose,
}

impl Calibration {
    /// `body_from_optical` (x right, y down, z forward).
    pub fn body_from_optical(&self) -> Pose {
        Isometry3::from_parts(
            self.body_from_mount.translation,
            self.body_from_mount.rotation * mount_to_optical(),
        )
    }

    /// Pixel of a point in the optical frame (distorted), `None` behind the camera.
    pub fn project(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        if p.z <= 1e-9 {
            return None;
        }
        let (x, y) = (p.x / p.z, p.y / p.z);
        let [k1, k2] = self.distortion;
        let r2 = x * x + y * y;
        let s = 1.0 + k1 * r2 + k2 * r2 * r2;
        let k = &self.geometry.k;
        Some((k.alpha_u * x * s + k.u0, k.alpha_v * y * s + k.v0))
    }

    /// The unit-depth point (z = 1, optical frame) seen at pixel `(u, v)`.
    pub fn ray(&self, u: f64, v: f64) -> Vector3<f64> {
        let k = &self.geometry.k;
        let (x, y) = super::undistort(
            (u - k.u0) / k.alpha_u,
            (v - k.v0) / k.alpha_v,
            self.distortion,
        );
        Vector3::new(x, y, 1.0)
    }
}

/// A camera's two calibrations and its stamp's offset.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraCalibration {
    /// What the robot software is given (the robot file).
    pub given: Calibration,
    /// What the simulator renders with.
    pub truth: Calibration,
    /// True mid-exposure minus the image's stamp, seconds.
    pub time_offset_s: f64,
}

impl CameraCalibration {
    /// A camera whose true calibration is the given one.
    pub fn exact(given: Calibration) -> Self {
        Self {
            given,
            truth: given,
            time_offset_s: 0.0,
        }
    }
}

/// A normal draw of standard deviation `sigma` truncated at [`TRUNCATION_SIGMAS`].
fn truncated(rng: &mut SimRng, sigma: f64) -> f64 {
    loop {
        let n: f64 = StandardNormal.sample(rng);
        if n.abs() <= TRUNCATION_SIGMAS {
            return sigma * n;
        }
    }
}

/// The true intrinsics and distortion of a camera whose given ones are `given`.
fn draw_lens(rng: &mut SimRng, given: &Calibration, e: &CalibrationError) -> Calibration {
    let k = &given.geometry.k;
    let k = Pinhole {
        alpha_u: k.alpha_u + truncated(rng, e.focal_px),
        alpha_v: k.alpha_v + truncated(rng, e.focal_px),
        u0: k.u0 + truncated(rng, e.principal_point_px),
        v0: k.v0 + truncated(rng, e.principal_point_px),
    };
    let d = given.distortion;
    let distortion = [
        d[0] + truncated(rng, e.distortion[0]),
        d[1] + truncated(rng, e.distortion[1]),
    ];
    Calibration {
        geometry: CameraGeometry {
            k,
            ..given.geometry
        },
        distortion,
        ..*given
    }
}

/// A small rigid motion: `sigma_m` per axis of translation, `sigma_deg` per axis of rotation.
fn draw_motion(rng: &mut SimRng, sigma_m: f64, sigma_deg: f64) -> Pose {
    let t = [(); 3].map(|_| truncated(rng, sigma_m));
    let r = [(); 3].map(|_| truncated(rng, sigma_deg).to_radians());
    pose_from_xyz_rpy(t, r)
}

/// The calibrations of a camera (`right = None`) or a stereo bench (`right`: the right
/// camera's given calibration), drawn from `rng` (the camera's `calibration` stream); one
/// entry per camera, left first.
pub fn draw(
    rng: &mut SimRng,
    left: Calibration,
    right: Option<Calibration>,
    e: &CalibrationError,
) -> Vec<CameraCalibration> {
    if e.is_zero() {
        return std::iter::once(left)
            .chain(right)
            .map(CameraCalibration::exact)
            .collect();
    }
    let mut truth = draw_lens(rng, &left, e);
    let mount_error = draw_motion(rng, e.mount_translation_m, e.mount_rotation_deg);
    truth.body_from_mount = left.body_from_mount * mount_error;
    let time_offset_s = truncated(rng, e.time_offset_ms) * 1e-3;
    let mut out = vec![CameraCalibration {
        given: left,
        truth,
        time_offset_s,
    }];
    if let Some(right) = right {
        let mut truth_right = draw_lens(rng, &right, e);
        let rotation = draw_motion(rng, 0.0, e.stereo_rotation_deg);
        let offset = draw_motion(rng, e.baseline_m, 0.0);
        // The right camera as it sits on the true left one: the given offset, then the error.
        let left_from_right = left.body_from_mount.inverse() * right.body_from_mount;
        truth_right.body_from_mount = truth.body_from_mount * offset * left_from_right * rotation;
        out.push(CameraCalibration {
            given: right,
            truth: truth_right,
            time_offset_s,
        });
    }
    out
}

/// The depth at which [`reprojection_rms_px`] places its points, metres: mount and baseline
/// errors reproject in proportion to `1 / depth`.
pub const REPROJECTION_DEPTH_M: f64 = 10.0;

/// The drawn errors as pixels: for a 16 x 12 grid over the image, the point the true camera
/// sees at `depth_m` along each pixel's ray is projected with the given calibration; the RMS
/// of the distances to the pixels. `depth_m = f64::INFINITY` leaves the mount's translation
/// out (rays only: intrinsics, distortion and rotations).
pub fn reprojection_rms_px(c: &CameraCalibration, depth_m: f64) -> f64 {
    let g = &c.given.geometry;
    let given_from_true = c.given.body_from_optical().inverse() * c.truth.body_from_optical();
    let (mut sum, mut n) = (0.0, 0usize);
    for j in 0..12 {
        for i in 0..16 {
            let u = (i as f64 + 0.5) / 16.0 * g.width as f64 - 0.5;
            let v = (j as f64 + 0.5) / 12.0 * g.height as f64 - 0.5;
            let ray = c.truth.ray(u, v);
            let p = if depth_m.is_finite() {
                given_from_true * Point3::from(ray * depth_m)
            } else {
                Point3::from(given_from_true.rotation * ray)
            };
            if let Some((pu, pv)) = c.given.project(&p) {
                sum += (pu - u).powi(2) + (pv - v).powi(2);
                n += 1;
            }
        }
    }
    (sum / n.max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use hetsim_core::Streams;

    fn bench() -> (Calibration, Calibration) {
        let left = Calibration {
            geometry: CameraGeometry::from_hfov(1024, 768, 60.0),
            distortion: [0.0; 2],
            body_from_mount: pose_from_xyz_rpy([0.6, 0.45, -0.5], [0.0, 90f64.to_radians(), 0.0]),
        };
        let right = Calibration {
            body_from_mount: left.body_from_mount * pose_from_xyz_rpy([0.0, -0.9, 0.0], [0.0; 3]),
            ..left
        };
        (left, right)
    }

    #[test]
    fn no_error_is_the_given_calibration_and_zero_pixels() {
        let (l, r) = bench();
        let mut rng = Streams::new(1).stream("ressac/stereo/calibration");
        for c in draw(&mut rng, l, Some(r), &CalibrationError::default()) {
            assert_eq!(c.given, c.truth);
            assert!(reprojection_rms_px(&c, REPROJECTION_DEPTH_M) < 1e-9);
        }
    }

    /// A focal-length error alone reprojects, over a grid uniform over the image, to
    /// `|Δf| * sqrt(E[x²])`: for a centred principal point and a uniform grid, `E[x²]` is
    /// `(tan(hfov/2))² / 3`. Checked on the drawn errors themselves.
    #[test]
    fn a_focal_error_reprojects_as_the_pinhole_predicts() {
        let (l, _) = bench();
        let e = CalibrationError {
            focal_px: 2.0,
            ..CalibrationError::default()
        };
        let mut rng = Streams::new(7).stream("dala/camera/calibration");
        let c = draw(&mut rng, l, None, &e)[0];
        let (du, dv) = (
            c.truth.geometry.k.alpha_u - l.geometry.k.alpha_u,
            c.truth.geometry.k.alpha_v - l.geometry.k.alpha_v,
        );
        // The truth's pixel u sees x = (u - u0) / f_true; the given camera puts it at
        // u0 + f x, off by (u - u0)(f - f_true) / f_true. Over a grid uniform across the
        // image, E[(u - u0)²] = (width / 2)² / 3.
        let f_true = [c.truth.geometry.k.alpha_u, c.truth.geometry.k.alpha_v];
        let ex2 = 512f64.powi(2) / 3.0;
        let ey2 = 384f64.powi(2) / 3.0;
        let expected = ((du / f_true[0]).powi(2) * ex2 + (dv / f_true[1]).powi(2) * ey2).sqrt();
        let got = reprojection_rms_px(&c, REPROJECTION_DEPTH_M);
        assert!(
            (got - expected).abs() < 0.05 * expected + 1e-6,
            "{got} px against {expected} px"
        );
    }

    #[test]
    fn draws_are_truncated_and_seeded() {
        let (l, r) = bench();
        let e = CalibrationError {
            focal_px: 1.0,
            principal_point_px: 1.0,
            baseline_m: 0.01,
            stereo_rotation_deg: 0.1,
            mount_rotation_deg: 0.1,
            mount_translation_m: 0.01,
            time_offset_ms: 1.0,
            distortion: [0.01, 0.001],
        };
        let run = |seed| {
            let mut rng = Streams::new(seed).stream("ressac/stereo/calibration");
            draw(&mut rng, l, Some(r), &e)
        };
        assert_eq!(run(3), run(3));
        assert_ne!(run(3), run(4));
        for seed in 0..200 {
            for c in run(seed) {
                let k = c.truth.geometry.k;
                assert!((k.alpha_u - l.geometry.k.alpha_u).abs() <= 3.0 + 1e-9);
                assert!((k.u0 - l.geometry.k.u0).abs() <= 3.0 + 1e-9);
                assert!(c.time_offset_s.abs() <= 3e-3 + 1e-12);
            }
        }
    }
}
