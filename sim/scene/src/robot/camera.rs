//! What makes a robot file's camera imperfect: the error of its calibration and its exposure.
//!
//! The robot file's intrinsics, distortion, baseline and mount are the calibration the robot
//! software is **given**. The simulator renders with a **true** calibration drawn per run from
//! `calibration_error` (`hetsim_sensors::camera::calibration`), and integrates each image over
//! its `exposure` (`hetsim_sensors::camera::motion`). A scenario's `camera_profile = "perfect"`
//! switches both off.

use crate::check::Checker;
use crate::SceneError;
use serde::{Deserialize, Serialize};

/// How far the error distributions reach: every error is a normal draw truncated at this many
/// standard deviations (drawn again beyond it), so a file is checked at its extremes.
pub const TRUNCATION_SIGMAS: f64 = 3.0;

/// The standard deviations of a camera's calibration error, each a normal truncated at
/// [`TRUNCATION_SIGMAS`]. All zero (the default): the given calibration is the true one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationError {
    /// Each focal length (`alpha_u`, `alpha_v`, drawn apart), pixels.
    pub focal_px: f64,
    /// Each coordinate of the principal point, pixels.
    pub principal_point_px: f64,
    /// The radial distortion coefficients `[k1, k2]`.
    pub distortion: [f64; 2],
    /// Each axis of the camera-to-body mount's position, metres.
    pub mount_translation_m: f64,
    /// Each axis of the camera-to-body mount's rotation, degrees.
    pub mount_rotation_deg: f64,
    /// Each axis of the right camera's rotation against the left (stereo benches), degrees.
    pub stereo_rotation_deg: f64,
    /// Each axis of the right camera's position against the left (stereo benches), metres.
    pub baseline_m: f64,
    /// The offset of the image's time stamp against the true mid-exposure (the camera's
    /// clock against the IMU's), milliseconds.
    pub time_offset_ms: f64,
}

impl CalibrationError {
    /// Whether every error is zero.
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }
}

/// When a row of the image is exposed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shutter {
    /// Every row over the same interval.
    #[default]
    Global,
    /// Row `r` `r * line_delay_us` after row 0; the stamp is the middle row's mid-exposure.
    Rolling,
}

/// How an image is exposed. The default is an instant (no blur), global shutter, no
/// vignetting: the ideal camera.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Exposure {
    /// Exposure time, milliseconds: the image integrates the scene over it (motion blur).
    pub time_ms: f64,
    /// Global or rolling shutter.
    pub shutter: Shutter,
    /// A rolling shutter's delay between consecutive rows, microseconds.
    pub line_delay_us: f64,
    /// Light lost in the image's corners: the gain falls as `1 - vignetting * (r / r_corner)²`
    /// with the distance `r` from the principal point.
    pub vignetting: f64,
}

impl Exposure {
    /// Whether the image is an instant with no vignetting (nothing to do after rendering).
    pub fn is_ideal(&self) -> bool {
        self.time_ms == 0.0 && !self.rolls() && self.vignetting == 0.0
    }

    /// Whether rows are exposed at different times.
    pub fn rolls(&self) -> bool {
        self.shutter == Shutter::Rolling && self.line_delay_us > 0.0
    }
}

/// Which imperfections a run's cameras have.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraProfile {
    /// As the robot files declare them.
    #[default]
    Realistic,
    /// None: the true calibration is the given one, every image an instant with no
    /// vignetting (ablations, and tests that need the ideal camera).
    Perfect,
}

/// A camera's given geometry and what its imperfections may do to it, for the checks.
pub(super) struct Nominal<'a> {
    /// `["sensors", "<i>"]`.
    pub at: [&'a str; 2],
    pub width_px: u32,
    pub height_px: u32,
    pub k: hetsim_msgs::Pinhole,
    pub distortion: [f64; 2],
    /// The stereo baseline, metres; `None` for a single camera.
    pub baseline_m: Option<f64>,
    pub rate_hz: f64,
}

/// Refuses an error distribution that can reach a non-physical camera, and an exposure that
/// does not fit the frame period, naming the field and what is allowed.
pub(super) fn check(
    c: &Checker,
    n: &Nominal,
    e: &CalibrationError,
    x: &Exposure,
) -> Result<(), SceneError> {
    let s = TRUNCATION_SIGMAS;
    let path = |table: &'static str, field: &'static str| [n.at[0], n.at[1], table, field];
    let ce = |field| path("calibration_error", field);
    let sigmas = [
        ("focal_px", e.focal_px),
        ("principal_point_px", e.principal_point_px),
        ("mount_translation_m", e.mount_translation_m),
        ("mount_rotation_deg", e.mount_rotation_deg),
        ("stereo_rotation_deg", e.stereo_rotation_deg),
        ("baseline_m", e.baseline_m),
        ("time_offset_ms", e.time_offset_ms),
    ];
    for (field, sigma) in sigmas.into_iter().chain([
        ("distortion", e.distortion[0]),
        ("distortion", e.distortion[1]),
    ]) {
        c.range(&ce(field), sigma, 0.0, 1e6)
            .map_err(|err| c.reword(err, "a standard deviation: a finite number >= 0"))?;
    }
    let focal = n.k.alpha_u.min(n.k.alpha_v);
    if focal - s * e.focal_px <= 0.0 {
        return Err(c.error_at(
            &ce("focal_px"),
            e.focal_px,
            format!("below {} (the focal length {focal} px over {s}): a draw at {s} sigma would make a focal length <= 0", focal / s),
        ));
    }
    let inside = |p: f64, size: u32| {
        p - s * e.principal_point_px >= 0.0 && p + s * e.principal_point_px <= size as f64
    };
    if !(inside(n.k.u0, n.width_px) && inside(n.k.v0, n.height_px)) {
        return Err(c.error_at(
            &ce("principal_point_px"),
            e.principal_point_px,
            format!("a value that keeps the principal point ({}, {}) inside the {}x{} image at {s} sigma", n.k.u0, n.k.v0, n.width_px, n.height_px),
        ));
    }
    if !monotonic_at_extremes(n, e.distortion) {
        return Err(c.error_at(
            &ce("distortion"),
            format!("{:?}", e.distortion),
            format!("errors that keep the distortion monotonic out to the image's corners at {s} sigma (1 + 3 k1 r² + 5 k2 r⁴ > 0)"),
        ));
    }
    if e.mount_rotation_deg * s > 10.0 || e.stereo_rotation_deg * s > 10.0 {
        let field = if e.mount_rotation_deg * s > 10.0 {
            "mount_rotation_deg"
        } else {
            "stereo_rotation_deg"
        };
        let v = if field == "mount_rotation_deg" {
            e.mount_rotation_deg
        } else {
            e.stereo_rotation_deg
        };
        return Err(c.error_at(&ce(field), v, format!("at most {:.3} degrees ({s} sigma within 10 degrees: a calibration, not a different mount)", 10.0 / s)));
    }
    if let Some(b) = n.baseline_m {
        if b - s * e.baseline_m <= 0.0 {
            return Err(c.error_at(
                &ce("baseline_m"),
                e.baseline_m,
                format!("below {} (the baseline {b} m over {s}): a draw at {s} sigma would put the right camera at or left of the left one", b / s),
            ));
        }
    } else if e.baseline_m != 0.0 || e.stereo_rotation_deg != 0.0 {
        let field = if e.baseline_m != 0.0 {
            "baseline_m"
        } else {
            "stereo_rotation_deg"
        };
        return Err(c.error_at(
            &ce(field),
            if e.baseline_m != 0.0 {
                e.baseline_m
            } else {
                e.stereo_rotation_deg
            },
            "0: only a stereo bench has a second camera",
        ));
    }
    check_exposure(c, n, e, x)
}

/// The exposure's fields, and that the exposure, the rolling shutter's readout and the time
/// offset's reach fit in one frame period.
fn check_exposure(
    c: &Checker,
    n: &Nominal,
    e: &CalibrationError,
    x: &Exposure,
) -> Result<(), SceneError> {
    let ex = |field| [n.at[0], n.at[1], "exposure", field];
    let period_ms = 1e3 / n.rate_hz;
    c.range(&ex("vignetting"), x.vignetting, 0.0, 0.9)?;
    c.range(&ex("line_delay_us"), x.line_delay_us, 0.0, 1e6)?;
    if x.shutter == Shutter::Global && x.line_delay_us != 0.0 {
        return Err(c.error_at(
            &ex("line_delay_us"),
            x.line_delay_us,
            "0 for a global shutter (set shutter = \"rolling\")",
        ));
    }
    if x.shutter == Shutter::Rolling && x.line_delay_us <= 0.0 {
        return Err(c.error_at(
            &ex("line_delay_us"),
            x.line_delay_us,
            "a delay > 0 for a rolling shutter",
        ));
    }
    let readout_ms = x.line_delay_us * 1e-3 * n.height_px as f64;
    let reach_ms = x.time_ms + readout_ms + 2.0 * TRUNCATION_SIGMAS * e.time_offset_ms;
    if !(x.time_ms >= 0.0 && reach_ms < period_ms) {
        return Err(c.error_at(
            &ex("time_ms"),
            x.time_ms,
            format!(
                "an exposure >= 0 ms that, with the readout ({readout_ms:.3} ms) and the time offset's reach ({:.3} ms), stays shorter than the frame period {period_ms:.3} ms",
                2.0 * TRUNCATION_SIGMAS * e.time_offset_ms
            ),
        ));
    }
    Ok(())
}

/// Whether `x_d = x (1 + k1 r² + k2 r⁴)` stays monotonic out to the image's farthest corner
/// for every coefficient at its nominal value plus or minus [`TRUNCATION_SIGMAS`] errors.
fn monotonic_at_extremes(n: &Nominal, sigma: [f64; 2]) -> bool {
    let s = TRUNCATION_SIGMAS;
    let corner = |p: f64, size: u32, f: f64| (p.max(size as f64 - p) / f).powi(2);
    // r² at the corner, with a margin for the undistorted radius being larger.
    let r2max =
        (corner(n.k.u0, n.width_px, n.k.alpha_u) + corner(n.k.v0, n.height_px, n.k.alpha_v)) * 1.5;
    let [k1, k2] = n.distortion;
    [-1.0, 1.0].iter().all(|&a| {
        [-1.0, 1.0].iter().all(|&b| {
            let (k1, k2) = (k1 + a * s * sigma[0], k2 + b * s * sigma[1]);
            (0..=32).all(|i| {
                let r2 = r2max * i as f64 / 32.0;
                1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2 > 0.0
            })
        })
    })
}
