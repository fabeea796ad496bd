//! The scenario's cameras as rigs: what each renders with (its true calibration), what its
//! robot is told (the given one), and how it exposes.

use super::{Model, PixelNoise, Rig};
use hetsim_core::{SimClock, Streams};
use hetsim_msgs::{pose_from_xyz_rpy, CameraGeometry, PixelEncoding, Pose};
use hetsim_scene::{CalibrationError, CameraProfile, Exposure, Scenario, Sensor};
use hetsim_sensors::camera::calibration::{self, Calibration, CameraCalibration};
use hetsim_sensors::camera::motion::Timing;
use hetsim_sensors::camera::{panorama_lookup, panorama_taps, pinhole};

/// Every camera of the scenario as a rig, in robot then sensor order (a stereo bench: its
/// left camera, then its right). The `perfect` profile renders every camera with its given
/// calibration, as an instant, with no vignetting.
pub(super) fn rigs(scenario: &Scenario, streams: &Streams) -> Vec<Rig> {
    let clock: SimClock = scenario.clock;
    let perfect = scenario.file.camera_profile == CameraProfile::Perfect;
    let mut rigs = Vec::new();
    for (i, r) in scenario.robots.iter().enumerate() {
        for s in &r.model.sensors {
            let m = s.mount();
            let mount = pose_from_xyz_rpy(m.xyz_m, m.rpy_deg.map(f64::to_radians));
            let base = format!("{}/{}", r.spec.name, s.name());
            let period = clock.period_ticks(s.rate_hz()).expect("validated rate");
            let (error, exposure) = match s.imperfections() {
                Some((e, x)) if !perfect => (*e, *x),
                _ => (CalibrationError::default(), Exposure::default()),
            };
            let at = RigAt {
                robot: i,
                period,
                mount,
                streams,
                error,
                exposure,
            };
            match s {
                Sensor::Camera { .. } | Sensor::StereoCamera { .. } => {
                    rigs.extend(pinhole_rigs(&at, &base, s));
                }
                Sensor::OmniCamera { .. } => rigs.push(omni_rig(&at, base, s)),
                _ => {}
            }
        }
    }
    rigs
}

/// What every rig of one sensor shares.
struct RigAt<'a> {
    robot: usize,
    period: u64,
    /// The given `body_from_mount` (a bench's left camera's).
    mount: Pose,
    streams: &'a Streams,
    /// The sensor's calibration error (none under the `perfect` profile).
    error: CalibrationError,
    /// The sensor's exposure (an instant under the `perfect` profile).
    exposure: Exposure,
}

/// The rigs of pinhole camera or stereo bench `s` (`base`: its topic): one camera, or a bench's
/// left then right camera, the right `baseline_m` along the left's -y, same orientation. The
/// true calibrations are drawn from `<base>/calibration`.
fn pinhole_rigs(at: &RigAt, base: &str, s: &Sensor) -> Vec<Rig> {
    let (Some((width, height, k, distortion)), Some((noise_sigma, gain, encoding))) =
        (s.given_geometry(), image_settings(s))
    else {
        unreachable!("pinhole rigs are made of a camera or a stereo bench");
    };
    let given = Calibration {
        geometry: CameraGeometry { width, height, k },
        distortion,
        body_from_mount: at.mount,
    };
    let right = match s {
        Sensor::StereoCamera { baseline_m, .. } => Some(Calibration {
            body_from_mount: at.mount * pose_from_xyz_rpy([0.0, -baseline_m, 0.0], [0.0; 3]),
            ..given
        }),
        _ => None,
    };
    let mut rng = at.streams.stream(&format!("{base}/calibration"));
    let calibrations = calibration::draw(&mut rng, given, right, &at.error);
    let eyes: &[&str] = if right.is_some() {
        &["left", "right"]
    } else {
        &[""]
    };
    let timing = Timing {
        exposure_s: at.exposure.time_ms * 1e-3,
        line_delay_s: if at.exposure.rolls() {
            at.exposure.line_delay_us * 1e-6
        } else {
            0.0
        },
    };
    eyes.iter()
        .zip(calibrations)
        .map(|(eye, calibration)| {
            let (topic, sensor) = if eye.is_empty() {
                (base.to_string(), s.name().to_string())
            } else {
                (format!("{base}/{eye}"), format!("{}/{eye}", s.name()))
            };
            let truth = &calibration.truth;
            let distorted = truth.distortion != [0.0, 0.0];
            Rig {
                encoding,
                robot: at.robot,
                rng: at.streams.stream(&format!("{topic}/pixel_noise")),
                topic,
                sensor,
                period: at.period,
                noise: pixel_noise(noise_sigma),
                gain: gain as f32,
                model: pinhole(truth.geometry, distorted.then_some(truth.distortion)),
                gain_map: vignette(&truth.geometry, gain as f32, at.exposure.vignetting),
                calibration,
                timing,
            }
        })
        .collect()
}

/// The rig of omnidirectional camera `s`: a panorama resampled from six pinhole faces,
/// noiseless at unit gain, calibrated exactly and exposed as an instant (`base`: its topic).
fn omni_rig(at: &RigAt, base: String, s: &Sensor) -> Rig {
    let Sensor::OmniCamera {
        width_px,
        height_px,
        elevation_deg,
        ..
    } = s
    else {
        unreachable!("an omni rig is made of an omnidirectional camera");
    };
    let face_px = (width_px / 4).max(16);
    let geometry = CameraGeometry {
        width: *width_px,
        height: *height_px,
        k: hetsim_msgs::Pinhole {
            alpha_u: 0.0,
            alpha_v: 0.0,
            u0: 0.0,
            v0: 0.0,
        },
    };
    Rig {
        encoding: PixelEncoding::Rgb8,
        robot: at.robot,
        rng: at.streams.stream(&format!("{base}/pixel_noise")),
        topic: base,
        sensor: s.name().to_string(),
        period: at.period,
        calibration: CameraCalibration::exact(Calibration {
            geometry,
            distortion: [0.0, 0.0],
            body_from_mount: at.mount,
        }),
        noise: None,
        gain: 1.0,
        gain_map: None,
        timing: Timing::default(),
        model: {
            let face = CameraGeometry::from_hfov(face_px, face_px, 90.0);
            let lookup = panorama_lookup(
                &face,
                *width_px,
                *height_px,
                elevation_deg.map(f64::to_radians),
            );
            let (taps, faces) = panorama_taps(&face, &lookup);
            Model::Omni { face, taps, faces }
        },
    }
}

/// A camera's noise model from its robot file's `pixel_noise_sigma`.
fn pixel_noise(sigma: f64) -> Option<PixelNoise> {
    (sigma > 0.0).then(|| PixelNoise::new(sigma))
}

/// Each pixel's gain `gain * (1 - vignetting * (r / r_corner)²)`, `r` from the principal
/// point, `r_corner` to the farthest corner; `None` without vignetting.
fn vignette(g: &CameraGeometry, gain: f32, vignetting: f64) -> Option<Vec<f32>> {
    if vignetting == 0.0 {
        return None;
    }
    let (w, h, k) = (g.width as usize, g.height as usize, &g.k);
    let (right, bottom) = (w as f64 - 1.0, h as f64 - 1.0);
    let corner2 = [(0.0, 0.0), (right, 0.0), (0.0, bottom), (right, bottom)]
        .map(|(u, v)| (u - k.u0).powi(2) + (v - k.v0).powi(2))
        .into_iter()
        .fold(0.0, f64::max);
    Some(
        (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f64, (i / w) as f64);
                let r2 = ((u - k.u0).powi(2) + (v - k.v0).powi(2)) / corner2;
                gain * (1.0 - vignetting * r2) as f32
            })
            .collect(),
    )
}

/// A pinhole camera's or a bench's pixel noise sigma, gain and encoding.
fn image_settings(s: &Sensor) -> Option<(f64, f64, PixelEncoding)> {
    match s {
        Sensor::Camera {
            pixel_noise_sigma,
            gain,
            encoding,
            ..
        }
        | Sensor::StereoCamera {
            pixel_noise_sigma,
            gain,
            encoding,
            ..
        } => Some((*pixel_noise_sigma, *gain, *encoding)),
        _ => None,
    }
}
