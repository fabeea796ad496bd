//! Validation of robot files: every value against its allowed range, with the field's place.

use super::*;
use crate::check::Checker;
use crate::SceneError;
use std::collections::BTreeSet;

impl RobotModel {
    /// Checks every value against its allowed range. `dt_secs` is the scenario's tick, which
    /// bounds sensor rates (a sensor cannot sample faster than once per tick).
    pub fn validate(&self, c: &Checker, dt_secs: f64) -> Result<(), SceneError> {
        check_body(c, &self.body)?;
        // The SLAM's and the pilot's tables, by their own crates' rules.
        let slam = self.slam_params().map_err(|e| {
            let path: Vec<&str> = std::iter::once("slam")
                .chain(e.path.iter().map(String::as_str))
                .collect();
            c.error_at(&path, e.given.as_deref().unwrap_or("(missing)"), e.message)
        })?;
        crate::params::check(c, &["slam"], slam.rules())?;
        crate::params::check(c, &["pilot"], self.pilot.rules(self.body.max_speed_mps))?;
        let mut names = BTreeSet::new();
        for (i, sensor) in self.sensors.iter().enumerate() {
            check_sensor(c, i, sensor, &mut names, dt_secs)?;
        }
        Ok(())
    }
}

/// Checks the `[body]` table: its size, mass and limits, then its drive's own table.
fn check_body(c: &Checker, b: &Body) -> Result<(), SceneError> {
    // Bounded, not only positive: the physics' shapes and sweeps are built from them
    // (a 1e300 m airframe overflowed parry's heightfield cast).
    c.range(&["body", "length_m"], b.length_m, 0.01, 50.0)?;
    c.range(&["body", "width_m"], b.width_m, 0.01, 50.0)?;
    c.range(&["body", "height_m"], b.height_m, 0.01, 50.0)?;
    c.range(&["body", "mass_kg"], b.mass_kg, 0.01, 100_000.0)?;
    c.range(&["body", "max_speed_mps"], b.max_speed_mps, 1e-3, 100.0)?;
    c.range(
        &["body", "max_yaw_rate_deg_s"],
        b.max_yaw_rate_deg_s,
        1e-3,
        720.0,
    )?;
    match b.drive {
        DriveKind::SkidSteer | DriveKind::Differential => check_wheels(c, b),
        DriveKind::Helicopter => check_helicopter(c, b),
    }
}

/// Checks a wheeled body: a `[body.wheels]` table in range and no `[body.helicopter]` table.
fn check_wheels(c: &Checker, b: &Body) -> Result<(), SceneError> {
    let Some(w) = &b.wheels else {
        return Err(c.error(
            &["body"],
            "body.wheels",
            "(missing)",
            "a [body.wheels] table for a skid_steer or differential drive",
        ));
    };
    c.positive(&["body", "wheels", "track_m"], w.track_m)?;
    c.range(
        &["body", "wheels", "motor_time_constant_s"],
        w.motor_time_constant_s,
        0.0,
        5.0,
    )?;
    c.range(
        &["body", "wheels", "longitudinal_slip"],
        w.longitudinal_slip,
        0.0,
        0.5,
    )?;
    c.range(
        &["body", "wheels", "icr_expansion"],
        w.icr_expansion,
        1.0,
        3.0,
    )?;
    c.range(&["body", "wheels", "speed_noise"], w.speed_noise, 0.0, 0.5)?;
    if b.helicopter.is_some() {
        return Err(c.error(
            &["body", "helicopter"],
            "body.helicopter",
            "(table)",
            "no [body.helicopter] table on a wheeled robot",
        ));
    }
    Ok(())
}

/// Checks a helicopter body: a `[body.helicopter]` table in range and no `[body.wheels]` table.
fn check_helicopter(c: &Checker, b: &Body) -> Result<(), SceneError> {
    let Some(h) = &b.helicopter else {
        return Err(c.error(
            &["body"],
            "body.helicopter",
            "(missing)",
            "a [body.helicopter] table for a helicopter drive",
        ));
    };
    c.range(
        &["body", "helicopter", "max_tilt_deg"],
        h.max_tilt_deg,
        1e-3,
        45.0,
    )?;
    c.range(
        &["body", "helicopter", "max_climb_mps"],
        h.max_climb_mps,
        1e-3,
        20.0,
    )?;
    c.range(
        &["body", "helicopter", "attitude_time_constant_s"],
        h.attitude_time_constant_s,
        0.0,
        5.0,
    )?;
    c.range(
        &["body", "helicopter", "climb_time_constant_s"],
        h.climb_time_constant_s,
        0.0,
        5.0,
    )?;
    if b.wheels.is_some() {
        return Err(c.error(
            &["body", "wheels"],
            "body.wheels",
            "(table)",
            "no [body.wheels] table on a helicopter",
        ));
    }
    Ok(())
}

/// Checks `sensors[i]`: its name is not taken by an earlier sensor (`names`), its rate fits the
/// tick, its mount is finite, then the fields of its kind.
fn check_sensor<'s>(
    c: &Checker,
    i: usize,
    sensor: &'s Sensor,
    names: &mut BTreeSet<&'s str>,
    dt_secs: f64,
) -> Result<(), SceneError> {
    let idx = i.to_string();
    let at = |field: &'static str| ["sensors", idx.as_str(), field];
    if !names.insert(sensor.name()) {
        return Err(c.error(
            &at("name"),
            &format!("sensors[{i}].name"),
            format!("\"{}\"", sensor.name()),
            "a name not used by another sensor of this robot",
        ));
    }
    check_rate(c, &at, sensor.rate_hz(), dt_secs)?;
    check_mount(c, &at, i, sensor.mount())?;
    check_sensor_kind(c, &at, i, sensor)
}

/// Checks a sensor's `rate_hz`: above 0 and at most the tick rate `1 / dt_secs`.
fn check_rate<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    rate_hz: f64,
    dt_secs: f64,
) -> Result<(), SceneError> {
    let tick_hz = 1.0 / dt_secs;
    c.range(&at("rate_hz"), rate_hz, f64::MIN_POSITIVE, tick_hz)
        .map_err(|e| {
            c.reword(
                e,
                &format!("a rate > 0 and <= the tick rate {tick_hz} Hz (dt_secs = {dt_secs})"),
            )
        })
}

/// Checks that `sensors[i]`'s mount pose (`xyz_m`, then `rpy_deg`) is finite numbers.
fn check_mount<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    i: usize,
    mount: &Mount,
) -> Result<(), SceneError> {
    for (k, v) in mount.xyz_m.iter().chain(&mount.rpy_deg).enumerate() {
        if !v.is_finite() {
            return Err(c.error(
                &at("mount"),
                &format!("sensors[{i}].mount"),
                v,
                "finite numbers",
            ));
        }
        let _ = k;
    }
    Ok(())
}

/// Checks the fields that only `sensors[i]`'s kind has, handing each kind to its family's check.
fn check_sensor_kind<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    i: usize,
    sensor: &Sensor,
) -> Result<(), SceneError> {
    match sensor {
        Sensor::Camera { .. } | Sensor::StereoCamera { .. } | Sensor::OmniCamera { .. } => {
            check_camera(c, at, i, sensor)
        }
        Sensor::Compass { .. }
        | Sensor::Gps { .. }
        | Sensor::WheelOdometry { .. }
        | Sensor::Imu { .. } => check_navigation_sensor(c, at, sensor),
        Sensor::Rendezvous { .. }
        | Sensor::ImageMatch { .. }
        | Sensor::Laser { .. }
        | Sensor::ChildTracker { .. } => check_ranging_sensor(c, at, sensor),
        Sensor::OraclePose { .. } => Ok(()),
    }
}

/// Checks a camera's fields (pinhole, stereo or omnidirectional): image, optics, noise, lens.
fn check_camera<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    i: usize,
    sensor: &Sensor,
) -> Result<(), SceneError> {
    match sensor {
        Sensor::Camera {
            width_px,
            height_px,
            hfov_deg,
            intrinsics,
            pixel_noise_sigma,
            distortion,
            gain,
            ..
        } => {
            check_image(c, at, *width_px, *height_px)?;
            check_optics(c, at, *hfov_deg, intrinsics.as_ref())?;
            c.range(&at("pixel_noise_sigma"), *pixel_noise_sigma, 0.0, 64.0)?;
            check_lens(c, at, *distortion, *gain)?;
            check_imperfections(c, at, sensor, None)
        }
        Sensor::StereoCamera {
            width_px,
            height_px,
            hfov_deg,
            intrinsics,
            baseline_m,
            pixel_noise_sigma,
            distortion,
            gain,
            ..
        } => {
            check_image(c, at, *width_px, *height_px)?;
            // The stereo VO's windows and search margins need room: the SLAM refuses
            // smaller images at its boundary, so the file is refused here first.
            c.range(&at("width_px"), *width_px as f64, 64.0, 8192.0)?;
            c.range(&at("height_px"), *height_px as f64, 64.0, 8192.0)?;
            check_optics(c, at, *hfov_deg, intrinsics.as_ref())?;
            c.range(&at("baseline_m"), *baseline_m, 1e-3, 10.0)?;
            c.range(&at("pixel_noise_sigma"), *pixel_noise_sigma, 0.0, 64.0)?;
            check_lens(c, at, *distortion, *gain)?;
            check_imperfections(c, at, sensor, Some(*baseline_m))
        }
        Sensor::OmniCamera {
            width_px,
            height_px,
            elevation_deg,
            ..
        } => {
            check_image(c, at, *width_px, *height_px)?;
            if !(elevation_deg[0] >= -90.0
                && elevation_deg[0] < elevation_deg[1]
                && elevation_deg[1] <= 90.0)
            {
                return Err(c.error(
                    &at("elevation_deg"),
                    &format!("sensors[{i}].elevation_deg"),
                    format!("{elevation_deg:?}"),
                    "[min, max] with -90 <= min < max <= 90",
                ));
            }
            Ok(())
        }
        // The other kinds are not cameras: `check_sensor_kind` hands them elsewhere.
        _ => Ok(()),
    }
}

/// Checks the noise and schedule fields of a compass, GPS, wheel odometry or IMU.
fn check_navigation_sensor<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    sensor: &Sensor,
) -> Result<(), SceneError> {
    match sensor {
        Sensor::Compass {
            sigma_deg,
            bias_deg,
            distortion_deg,
            ..
        } => {
            c.range(&at("sigma_deg"), *sigma_deg, 0.0, 90.0)?;
            c.range(&at("bias_deg"), *bias_deg, -180.0, 180.0)?;
            c.range(&at("distortion_deg"), *distortion_deg, -90.0, 90.0)
        }
        Sensor::Gps {
            sigma_m,
            schedule_s,
            outages_s,
            ..
        } => {
            c.range(&at("sigma_m"), *sigma_m, 0.0, 100.0)?;
            if schedule_s.iter().any(|t| !(t.is_finite() && *t >= 0.0))
                || schedule_s.windows(2).any(|w| w[1] < w[0])
            {
                return Err(c.error_at(
                    &at("schedule_s"),
                    format!("{schedule_s:?}"),
                    "ascending sim times in seconds >= 0",
                ));
            }
            if outages_s
                .iter()
                .any(|[a, b]| !(a.is_finite() && b.is_finite() && *a >= 0.0 && a <= b))
            {
                return Err(c.error_at(
                    &at("outages_s"),
                    format!("{outages_s:?}"),
                    "intervals [start, end] in seconds with 0 <= start <= end",
                ));
            }
            Ok(())
        }
        Sensor::WheelOdometry {
            scale_sigma,
            noise_per_m,
            ..
        } => {
            c.range(&at("scale_sigma"), *scale_sigma, 0.0, 0.5)?;
            c.range(&at("noise_per_m"), *noise_per_m, 0.0, 1.0)
        }
        Sensor::Imu {
            gyro_sigma_radps,
            gyro_bias_sigma_radps,
            accel_sigma_mps2,
            accel_bias_sigma_mps2,
            ..
        } => {
            c.range(&at("gyro_sigma_radps"), *gyro_sigma_radps, 0.0, 1.0)?;
            c.range(
                &at("gyro_bias_sigma_radps"),
                *gyro_bias_sigma_radps,
                0.0,
                1.0,
            )?;
            c.range(&at("accel_sigma_mps2"), *accel_sigma_mps2, 0.0, 10.0)?;
            c.range(
                &at("accel_bias_sigma_mps2"),
                *accel_bias_sigma_mps2,
                0.0,
                10.0,
            )
        }
        // The other kinds are not navigation sensors: `check_sensor_kind` hands them elsewhere.
        _ => Ok(()),
    }
}

/// Checks the range, opening angle and noise fields of a rendezvous, image-match, laser or
/// child-tracker sensor.
fn check_ranging_sensor<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    sensor: &Sensor,
) -> Result<(), SceneError> {
    match sensor {
        Sensor::Rendezvous {
            range_m,
            fov_deg,
            sigma_m,
            sigma_deg,
            ..
        } => {
            c.positive(&at("range_m"), *range_m)?;
            c.range(&at("fov_deg"), *fov_deg, 1e-3, 360.0)?;
            c.range(&at("sigma_m"), *sigma_m, 0.0, 100.0)?;
            c.range(&at("sigma_deg"), *sigma_deg, 0.0, 180.0)
        }
        Sensor::ImageMatch {
            range_m,
            min_age_s,
            sigma_m,
            sigma_deg,
            ..
        } => {
            c.positive(&at("range_m"), *range_m)?;
            c.range(&at("min_age_s"), *min_age_s, 0.0, 1e6)?;
            c.range(&at("sigma_m"), *sigma_m, 0.0, 100.0)?;
            c.range(&at("sigma_deg"), *sigma_deg, 0.0, 180.0)
        }
        Sensor::Laser {
            fov_deg,
            resolution_deg,
            max_range_m,
            range_sigma_m,
            ..
        } => {
            c.range(&at("fov_deg"), *fov_deg, 1e-3, 360.0)?;
            c.range(&at("resolution_deg"), *resolution_deg, 1e-3, *fov_deg)?;
            c.positive(&at("max_range_m"), *max_range_m)?;
            c.range(&at("range_sigma_m"), *range_sigma_m, 0.0, 1.0)
        }
        Sensor::ChildTracker {
            range_m,
            error_mean_m,
            error_std_m,
            ..
        } => {
            c.positive(&at("range_m"), *range_m)?;
            c.range(&at("error_mean_m"), *error_mean_m, 0.0, 1.0)?;
            c.range(&at("error_std_m"), *error_std_m, 0.0, 1.0)
        }
        // The other kinds have no range: `check_sensor_kind` hands them elsewhere.
        _ => Ok(()),
    }
}

/// Checks a pinhole camera's or a bench's `calibration_error` and `exposure` against its
/// given geometry and rate.
fn check_imperfections<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    sensor: &Sensor,
    baseline_m: Option<f64>,
) -> Result<(), SceneError> {
    let (Some((error, exposure)), Some((width_px, height_px, k, distortion))) =
        (sensor.imperfections(), sensor.given_geometry())
    else {
        return Ok(());
    };
    let [sensors, i, _] = at("");
    let nominal = super::camera::Nominal {
        at: [sensors, i],
        width_px,
        height_px,
        k,
        distortion,
        baseline_m,
        rate_hz: sensor.rate_hz(),
    };
    super::camera::check(c, &nominal, error, exposure)
}

/// Checks a camera's lens: `distortion` coefficients within 1 in size, `gain` in range.
fn check_lens<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    distortion: Option<[f64; 2]>,
    gain: f64,
) -> Result<(), SceneError> {
    if let Some([k1, k2]) = distortion {
        if !(k1.is_finite() && k2.is_finite() && k1.abs() <= 1.0 && k2.abs() <= 1.0) {
            return Err(c.error_at(
                &at("distortion"),
                format!("{:?}", [k1, k2]),
                "[k1, k2] with |k1|, |k2| <= 1",
            ));
        }
    }
    c.range(&at("gain"), gain, 0.1, 10.0)
}

/// Checks an image's `width_px` and `height_px`.
fn check_image<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    width: u32,
    height: u32,
) -> Result<(), SceneError> {
    c.range(&at("width_px"), width as f64, 8.0, 8192.0)?;
    c.range(&at("height_px"), height as f64, 8.0, 8192.0)
}

/// Checks a camera's `intrinsics` table where given, else its `hfov_deg`.
fn check_optics<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    hfov_deg: Option<f64>,
    intrinsics: Option<&hetsim_msgs::Pinhole>,
) -> Result<(), SceneError> {
    match (hfov_deg, intrinsics) {
        (_, Some(k)) => {
            c.positive(
                &[
                    at("intrinsics")[0],
                    at("intrinsics")[1],
                    "intrinsics",
                    "alpha_u",
                ],
                k.alpha_u,
            )?;
            c.positive(
                &[
                    at("intrinsics")[0],
                    at("intrinsics")[1],
                    "intrinsics",
                    "alpha_v",
                ],
                k.alpha_v,
            )
        }
        (Some(fov), None) => c.range(&at("hfov_deg"), fov, 1.0, 179.0),
        (None, None) => Err(c.error(
            &at("hfov_deg"),
            &at("hfov_deg").join("."),
            "(missing)",
            "hfov_deg in [1, 179] degrees, or an [intrinsics] table",
        )),
    }
}
