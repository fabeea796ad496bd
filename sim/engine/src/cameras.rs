//! The robots' cameras: what to render when, and applying the camera model after rendering
//! (`hetsim_sensors::camera`) to what was rendered.
//!
//! * Pinhole cameras and each camera of a stereo bench render as one view; the right camera
//!   of a bench sits `baseline_m` along the left camera's -y (its right), same orientation.
//! * The parent's omnidirectional camera is an **equirectangular panorama**: column u is the
//!   azimuth `φ = π - 2π (u + 0.5) / W` (the centre column looks along the mount's x axis,
//!   the left half to its left) and row v the elevation `θ = θmax - (θmax - θmin)(v + 0.5)/H`
//!   over the robot file's `elevation_deg`. It is rendered as six 90° pinhole faces and
//!   resampled (bilinear).
//! * After rendering: radial distortion `x_d = x_u (1 + k1 r² + k2 r⁴)` (resampled, bilinear),
//!   exposure gain, then Gaussian pixel noise from the camera's stream
//!   `<robot>/<camera>/pixel_noise` (stereo: `.../left/pixel_noise`, `.../right/...`).
//! * Every camera due on a tick is rendered in one batch; a camera never sees its own robot.

use hetsim_core::{SimClock, SimRng, Streams};
use hetsim_msgs::{mount_to_optical, CameraGeometry};
use hetsim_msgs::{pose_from_xyz_rpy, Image, PixelEncoding, Pose};
use hetsim_physics::Physics;
use hetsim_render::Frame;
use hetsim_render::{
    AdapterSummary, CameraView, RenderError, RenderOptions, Renderer, RobotDraw, RobotPart,
};
use hetsim_scene::{DriveKind, Scenario, Sensor, HAT_SCALE, HAT_THICKNESS_M};
use nalgebra::Isometry3;
use rayon::prelude::*;

struct Rig {
    robot: usize,
    /// `<robot>/<camera>` or `<robot>/<camera>/<left|right>`.
    topic: String,
    /// The camera's name on the robot (as in `Image::sensor`).
    sensor: String,
    period: u64,
    intrinsics: CameraGeometry,
    body_from_mount: Pose,
    /// Pixel noise, `None` for a noiseless camera.
    noise: Option<PixelNoise>,
    gain: f32,
    model: Model,
    rng: SimRng,
    /// What the camera delivers (grey is the luminance of the noisy RGB, rounded).
    encoding: PixelEncoding,
}

/// One captured image with its ground truth.
pub struct Shot {
    /// Robot index.
    pub robot: usize,
    /// `<robot>/<camera>[/<left|right>]`.
    pub topic: String,
    /// The image as the robot receives it.
    pub image: Image,
    /// Ground-truth depth along the optical axis (pinhole) or range (panorama), metres,
    /// 0 = none; rendered only when the cameras were made with depth (frame dumps).
    pub depth_m: Option<Vec<f32>>,
    /// `world_from_optical` at exposure.
    pub world_from_optical: Pose,
    /// The image and its pinhole (for a panorama: its size, with focal lengths 0).
    pub intrinsics: CameraGeometry,
    /// `body_from_optical`.
    pub body_from_optical: Pose,
    /// Radial distortion `[k1, k2]` applied.
    pub distortion: [f64; 2],
    /// The camera's rate after rounding to whole ticks, Hz.
    pub rate_hz: f64,
}

/// All cameras of a run and the renderer they share.
pub struct Cameras {
    rigs: Vec<Rig>,
    renderer: Renderer,
    parts: Vec<(Vec<RobotPart>, u32)>,
    far_m: f64,
    dt_ns: u64,
}

fn robot_parts(model: &hetsim_scene::RobotModel) -> Vec<RobotPart> {
    let b = &model.body;
    let (l, w, h) = (b.length_m / 2.0, b.width_m / 2.0, b.height_m / 2.0);
    match b.drive {
        DriveKind::Helicopter => vec![
            RobotPart {
                centre: [0.0, 0.0, 0.0],
                half_extents: [l * 0.6, w, h],
                hat: false,
            },
            RobotPart {
                centre: [0.0, 0.0, h + 0.15],
                half_extents: [l, l, 0.02],
                hat: false,
            },
        ],
        _ if model.body.hat => vec![
            RobotPart {
                centre: [0.0, 0.0, h],
                half_extents: [l, w, h],
                hat: false,
            },
            RobotPart {
                centre: [0.0, 0.0, 2.0 * h + HAT_THICKNESS_M / 2.0],
                half_extents: [l * HAT_SCALE, w * HAT_SCALE, HAT_THICKNESS_M / 2.0],
                hat: true,
            },
        ],
        _ => vec![RobotPart {
            centre: [0.0, 0.0, h],
            half_extents: [l, w, h],
            hat: false,
        }],
    }
}

impl Cameras {
    /// The scenario's cameras, or `None` when no robot has one.
    pub fn new(
        scenario: &Scenario,
        streams: &Streams,
        options: &RenderOptions,
    ) -> Result<Option<Self>, RenderError> {
        let clock: SimClock = scenario.clock;
        let rigs = rigs(scenario, streams);
        if rigs.is_empty() {
            return Ok(None);
        }
        let renderer = Renderer::new(&scenario.world, options)?;
        let parts = scenario
            .robots
            .iter()
            .enumerate()
            .map(|(i, r)| (robot_parts(&r.model), i as u32))
            .collect();
        let far_m = if scenario.world.terrain.is_some() {
            3000.0
        } else {
            200.0
        };
        Ok(Some(Self {
            rigs,
            renderer,
            parts,
            far_m,
            dt_ns: clock.dt_ns(),
        }))
    }

    /// The adapter rendering the images.
    pub fn adapter(&self) -> &AdapterSummary {
        self.renderer.adapter()
    }

    /// Topics of all cameras, in order.
    pub fn topics(&self) -> Vec<String> {
        self.rigs.iter().map(|r| r.topic.clone()).collect()
    }

    /// Renders every camera due at the end of tick `tick` (robots where physics has them),
    /// keeping only the cameras `keep` accepts, with ground-truth depth for those `depth`
    /// accepts (frame dumps; robot software never gets depth); returns the shots in camera
    /// order.
    pub fn capture(
        &mut self,
        physics: &Physics,
        tick: u64,
        stamp_ns: u64,
        keep: &dyn Fn(&str) -> bool,
        depth: &dyn Fn(&str) -> bool,
    ) -> Vec<Shot> {
        let after = tick + 1;
        let due: Vec<usize> = (0..self.rigs.len())
            .filter(|&k| after % self.rigs[k].period == 0 && keep(&self.rigs[k].topic))
            .collect();
        if due.is_empty() {
            return Vec::new();
        }
        let draws: Vec<RobotDraw> = self
            .parts
            .iter()
            .enumerate()
            .map(|(i, (parts, seed))| RobotDraw {
                pose: physics.pose(i),
                parts: parts.clone(),
                seed: *seed,
            })
            .collect();
        self.renderer.set_robots(&draws);
        let mut views = Vec::new();
        let mut spans = Vec::new();
        for &k in &due {
            let rig = &self.rigs[k];
            let body = physics.pose(rig.robot);
            let world_from_mount = body * rig.body_from_mount;
            let with_depth = depth(&rig.topic);
            // Every camera of a robot picks the terrain's levels of detail from the robot's
            // position, so a stereo pair sees the same geometry.
            let lod_from = Some(nalgebra::Point3::from(body.translation.vector));
            let start = views.len();
            match &rig.model {
                Model::Pinhole { render, .. } => views.push(CameraView {
                    intrinsics: *render,
                    world_from_optical: Isometry3::from_parts(
                        world_from_mount.translation,
                        world_from_mount.rotation * mount_to_optical(),
                    ),
                    near_far_m: [0.01, self.far_m],
                    hide_robot: Some(rig.robot),
                    depth: with_depth,
                    lod_from,
                }),
                Model::Omni { face, faces, .. } => {
                    for (yaw, pitch) in faces.iter().map(|&f| CUBE[f]) {
                        let face_mount =
                            world_from_mount * pose_from_xyz_rpy([0.0; 3], [0.0, pitch, yaw]);
                        views.push(CameraView {
                            intrinsics: *face,
                            world_from_optical: Isometry3::from_parts(
                                face_mount.translation,
                                face_mount.rotation * mount_to_optical(),
                            ),
                            near_far_m: [0.01, self.far_m],
                            hide_robot: Some(rig.robot),
                            depth: with_depth,
                            lod_from,
                        });
                    }
                }
            }
            spans.push((k, start, views.len(), world_from_mount));
        }
        let frames = self.renderer.render(&views);
        // Post-processing is per camera (its own noise stream), so the cameras run in
        // parallel; the shots come back in camera order.
        let dt_ns = self.dt_ns;
        let mut spans = spans.into_iter().peekable();
        let jobs: Vec<_> = self
            .rigs
            .iter_mut()
            .enumerate()
            .filter_map(|(k, rig)| {
                let (_, start, end, world_from_mount) = spans.next_if(|s| s.0 == k)?;
                Some((rig, &frames[start..end], world_from_mount))
            })
            .collect();
        jobs.into_par_iter()
            .map(|(rig, frames, world_from_mount)| {
                rig.shot(frames, world_from_mount, stamp_ns, dt_ns)
            })
            .collect()
    }
}

/// Every camera of the scenario as a rig, in robot then sensor order (a stereo bench: its
/// left camera, then its right).
fn rigs(scenario: &Scenario, streams: &Streams) -> Vec<Rig> {
    let clock: SimClock = scenario.clock;
    let mut rigs = Vec::new();
    for (i, r) in scenario.robots.iter().enumerate() {
        for s in &r.model.sensors {
            let m = s.mount();
            let mount = pose_from_xyz_rpy(m.xyz_m, m.rpy_deg.map(f64::to_radians));
            let base = format!("{}/{}", r.spec.name, s.name());
            let period = clock.period_ticks(s.rate_hz()).expect("validated rate");
            match s {
                Sensor::Camera { .. } => rigs.push(camera_rig(i, base, s, period, mount, streams)),
                Sensor::StereoCamera { .. } => {
                    rigs.extend(stereo_rigs(i, &base, s, period, mount, streams));
                }
                Sensor::OmniCamera { .. } => {
                    rigs.push(omni_rig(i, base, s, period, mount, streams))
                }
                _ => {}
            }
        }
    }
    rigs
}

/// The rig of pinhole camera `s` of robot `robot` (`base`: its topic, `mount`:
/// `body_from_mount`).
fn camera_rig(
    robot: usize,
    base: String,
    s: &Sensor,
    period: u64,
    mount: Pose,
    streams: &Streams,
) -> Rig {
    let Sensor::Camera {
        width_px,
        height_px,
        hfov_deg,
        intrinsics,
        pixel_noise_sigma,
        distortion,
        gain,
        encoding,
        ..
    } = s
    else {
        unreachable!("a camera rig is made of a camera");
    };
    Rig {
        encoding: *encoding,
        robot,
        rng: streams.stream(&format!("{base}/pixel_noise")),
        topic: base,
        sensor: s.name().to_string(),
        period,
        intrinsics: hetsim_scene::camera_geometry(
            *width_px,
            *height_px,
            *hfov_deg,
            intrinsics.as_ref(),
        ),
        body_from_mount: mount,
        noise: pixel_noise(*pixel_noise_sigma),
        gain: *gain as f32,
        model: pinhole(
            hetsim_scene::camera_geometry(*width_px, *height_px, *hfov_deg, intrinsics.as_ref()),
            *distortion,
        ),
    }
}

/// The rigs of stereo bench `s` of robot `robot`, left then right (`base`: the bench's
/// topic, `mount`: the left camera's `body_from_mount`).
fn stereo_rigs(
    robot: usize,
    base: &str,
    s: &Sensor,
    period: u64,
    mount: Pose,
    streams: &Streams,
) -> Vec<Rig> {
    let Sensor::StereoCamera {
        width_px,
        height_px,
        hfov_deg,
        intrinsics,
        baseline_m,
        pixel_noise_sigma,
        distortion,
        gain,
        encoding,
        ..
    } = s
    else {
        unreachable!("stereo rigs are made of a stereo camera");
    };
    let mut rigs = Vec::new();
    for (eye, offset) in [("left", 0.0), ("right", -baseline_m)] {
        rigs.push(Rig {
            encoding: *encoding,
            robot,
            rng: streams.stream(&format!("{base}/{eye}/pixel_noise")),
            topic: format!("{base}/{eye}"),
            sensor: format!("{}/{eye}", s.name()),
            period,
            intrinsics: hetsim_scene::camera_geometry(
                *width_px,
                *height_px,
                *hfov_deg,
                intrinsics.as_ref(),
            ),
            body_from_mount: mount * pose_from_xyz_rpy([0.0, offset, 0.0], [0.0; 3]),
            noise: pixel_noise(*pixel_noise_sigma),
            gain: *gain as f32,
            model: pinhole(
                hetsim_scene::camera_geometry(
                    *width_px,
                    *height_px,
                    *hfov_deg,
                    intrinsics.as_ref(),
                ),
                *distortion,
            ),
        });
    }
    rigs
}

/// The rig of omnidirectional camera `s` of robot `robot`: a panorama resampled from six
/// pinhole faces, noiseless at unit gain (`base`: its topic, `mount`: `body_from_mount`).
fn omni_rig(
    robot: usize,
    base: String,
    s: &Sensor,
    period: u64,
    mount: Pose,
    streams: &Streams,
) -> Rig {
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
    Rig {
        encoding: PixelEncoding::Rgb8,
        robot,
        rng: streams.stream(&format!("{base}/pixel_noise")),
        topic: base,
        sensor: s.name().to_string(),
        period,
        intrinsics: CameraGeometry {
            width: *width_px,
            height: *height_px,
            k: hetsim_msgs::Pinhole {
                alpha_u: 0.0,
                alpha_v: 0.0,
                u0: 0.0,
                v0: 0.0,
            },
        },
        body_from_mount: mount,
        noise: None,
        gain: 1.0,
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

impl Rig {
    /// The camera model after rendering: distortion or panorama resampling, gain and noise.
    fn shot(
        &mut self,
        frames: &[Frame],
        world_from_mount: Pose,
        stamp_ns: u64,
        dt_ns: u64,
    ) -> Shot {
        // The colour to post-process (RGBA straight from the renderer, or RGB after
        // resampling) and its depth.
        let resampled;
        let (src, stride, depth) = match &self.model {
            Model::Pinhole {
                distortion: None, ..
            } => (&frames[0].rgba, 4, frames[0].depth_m.clone()),
            Model::Pinhole {
                distortion: Some(d),
                render,
            } => {
                let (rgb, depth) = distort(&frames[0], &self.intrinsics, render, *d);
                resampled = rgb;
                (&resampled, 3, depth)
            }
            Model::Omni { taps, .. } => {
                let (rgb, depth) = panorama(frames, taps);
                resampled = rgb;
                (&resampled, 3, depth)
            }
        };
        let data = match (&self.noise, self.encoding) {
            // Grey straight from the noise pass, with no RGB image in between.
            (Some(noise), PixelEncoding::Mono8) => noise.apply_grey(
                src,
                stride,
                self.gain,
                &mut self.rng,
                PixelEncoding::luminance,
            ),
            (Some(noise), PixelEncoding::Rgb8) => {
                noise.apply(src, stride, self.gain, &mut self.rng)
            }
            (None, encoding) => {
                let rgb = if stride == 3 && self.gain == 1.0 {
                    // Unit gain, no noise: the RGB as it is.
                    src.clone()
                } else {
                    src.chunks_exact(stride)
                        .flat_map(|px| px[..3].iter().map(|&c| quantize(c as f32 * self.gain)))
                        .collect()
                };
                match encoding {
                    PixelEncoding::Rgb8 => rgb,
                    PixelEncoding::Mono8 => rgb
                        .chunks_exact(3)
                        .map(|p| PixelEncoding::luminance([p[0], p[1], p[2]]))
                        .collect(),
                }
            }
        };
        let body_from_optical = Isometry3::from_parts(
            self.body_from_mount.translation,
            self.body_from_mount.rotation * mount_to_optical(),
        );
        let distortion = match &self.model {
            Model::Pinhole {
                distortion: Some(d),
                ..
            } => *d,
            _ => [0.0, 0.0],
        };
        let rate_hz = 1e9 / (self.period as f64 * dt_ns as f64);
        Shot {
            robot: self.robot,
            topic: self.topic.clone(),
            image: Image {
                stamp_ns,
                sensor: self.sensor.clone(),
                width: self.intrinsics.width,
                height: self.intrinsics.height,
                encoding: self.encoding,
                data,
            },
            depth_m: depth,
            world_from_optical: Isometry3::from_parts(
                world_from_mount.translation,
                world_from_mount.rotation * mount_to_optical(),
            ),
            intrinsics: self.intrinsics,
            body_from_optical,
            distortion,
            rate_hz,
        }
    }
}

/// A camera's noise model from its robot file's `pixel_noise_sigma`.
fn pixel_noise(sigma: f64) -> Option<PixelNoise> {
    (sigma > 0.0).then(|| PixelNoise::new(sigma))
}

use hetsim_sensors::camera::{
    distort, panorama, panorama_lookup, panorama_taps, pinhole, quantize, Model, PixelNoise, CUBE,
};
