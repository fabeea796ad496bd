//! Validation of robot files: every value against its allowed range, with the field's place.

use super::*;
use crate::check::Checker;
use crate::SceneError;

impl RobotModel {
    /// Checks every value against its allowed range. `dt_secs` is the scenario's tick, which
    /// bounds sensor rates (a sensor cannot sample faster than once per tick).
    pub fn validate(&self, c: &Checker, dt_secs: f64) -> Result<(), SceneError> {
        let b = &self.body;
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
            DriveKind::SkidSteer | DriveKind::Differential => {
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
            }
            DriveKind::Helicopter => {
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
            }
        }
        // The SLAM's and the pilot's tables, by their own crates' rules.
        crate::params::check(c, &["slam"], self.slam.rules())?;
        crate::params::check(c, &["pilot"], self.pilot.rules(b.max_speed_mps))?;
        let mut names = std::collections::BTreeSet::new();
        for (i, sensor) in self.sensors.iter().enumerate() {
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
            let tick_hz = 1.0 / dt_secs;
            c.range(&at("rate_hz"), sensor.rate_hz(), f64::MIN_POSITIVE, tick_hz)
                .map_err(|e| {
                    c.reword(
                        e,
                        &format!(
                            "a rate > 0 and <= the tick rate {tick_hz} Hz (dt_secs = {dt_secs})"
                        ),
                    )
                })?;
            for (k, v) in sensor
                .mount()
                .xyz_m
                .iter()
                .chain(&sensor.mount().rpy_deg)
                .enumerate()
            {
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
                    check_image(c, &at, *width_px, *height_px)?;
                    check_optics(c, &at, *hfov_deg, intrinsics.as_ref())?;
                    c.range(&at("pixel_noise_sigma"), *pixel_noise_sigma, 0.0, 64.0)?;
                    check_lens(c, &at, *distortion, *gain)?;
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
                    check_image(c, &at, *width_px, *height_px)?;
                    // The stereo VO's windows and search margins need room: the SLAM refuses
                    // smaller images at its boundary, so the file is refused here first.
                    c.range(&at("width_px"), *width_px as f64, 64.0, 8192.0)?;
                    c.range(&at("height_px"), *height_px as f64, 64.0, 8192.0)?;
                    check_optics(c, &at, *hfov_deg, intrinsics.as_ref())?;
                    c.range(&at("baseline_m"), *baseline_m, 1e-3, 10.0)?;
                    c.range(&at("pixel_noise_sigma"), *pixel_noise_sigma, 0.0, 64.0)?;
                    check_lens(c, &at, *distortion, *gain)?;
                }
                Sensor::OmniCamera {
                    width_px,
                    height_px,
                    elevation_deg,
                    ..
                } => {
                    check_image(c, &at, *width_px, *height_px)?;
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
                }
                Sensor::Compass {
                    sigma_deg,
                    bias_deg,
                    distortion_deg,
                    ..
                } => {
                    c.range(&at("sigma_deg"), *sigma_deg, 0.0, 90.0)?;
                    c.range(&at("bias_deg"), *bias_deg, -180.0, 180.0)?;
                    c.range(&at("distortion_deg"), *distortion_deg, -90.0, 90.0)?;
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
                }
                Sensor::WheelOdometry {
                    scale_sigma,
                    noise_per_m,
                    ..
                } => {
                    c.range(&at("scale_sigma"), *scale_sigma, 0.0, 0.5)?;
                    c.range(&at("noise_per_m"), *noise_per_m, 0.0, 1.0)?;
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
                    )?;
                }
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
                    c.range(&at("sigma_deg"), *sigma_deg, 0.0, 180.0)?;
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
                    c.range(&at("sigma_deg"), *sigma_deg, 0.0, 180.0)?;
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
                    c.range(&at("range_sigma_m"), *range_sigma_m, 0.0, 1.0)?;
                }
                Sensor::OraclePose { .. } => {}
                Sensor::ChildTracker {
                    range_m,
                    error_mean_m,
                    error_std_m,
                    ..
                } => {
                    c.positive(&at("range_m"), *range_m)?;
                    c.range(&at("error_mean_m"), *error_mean_m, 0.0, 1.0)?;
                    c.range(&at("error_std_m"), *error_std_m, 0.0, 1.0)?;
                }
            }
        }
        Ok(())
    }
}

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

fn check_image<'a>(
    c: &Checker,
    at: &dyn Fn(&'static str) -> [&'a str; 3],
    width: u32,
    height: u32,
) -> Result<(), SceneError> {
    c.range(&at("width_px"), width as f64, 8.0, 8192.0)?;
    c.range(&at("height_px"), height as f64, 8.0, 8192.0)
}

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
