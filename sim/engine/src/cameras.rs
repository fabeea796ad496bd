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
//! * A pinhole camera renders with its **true** calibration (`rigs`, drawn per run from the
//!   robot file's `calibration_error`) at its true mid-exposure: the image's stamp plus the
//!   drawn time offset, the robot's pose extrapolated there along its motion over the last
//!   tick. The robot software is told the **given** calibration (the robot file's), and so is
//!   whoever reads a shot (`Shot::intrinsics`, `Shot::body_from_optical`).
//! * After rendering: motion blur and the rolling shutter (`hetsim_sensors::camera::motion`,
//!   from the rendered depth and the camera's twist), radial distortion
//!   `x_d = x_u (1 + k1 r² + k2 r⁴)` (resampled, bilinear), exposure gain and vignetting, then
//!   Gaussian pixel noise from the camera's stream `<robot>/<camera>/pixel_noise` (stereo:
//!   `.../left/pixel_noise`, `.../right/...`).
//! * Every camera due on a tick is rendered in one batch; a camera never sees its own robot.

mod rigs;

pub use hetsim_sensors::camera::calibration::{
    reprojection_rms_px, Calibration, CameraCalibration, REPROJECTION_DEPTH_M,
};

use hetsim_core::{SimClock, SimRng, Streams};
use hetsim_msgs::{mount_to_optical, CameraGeometry};
use hetsim_msgs::{pose_from_xyz_rpy, Image, PixelEncoding, Pose};
use hetsim_physics::Physics;
use hetsim_render::Frame;
use hetsim_render::{
    AdapterSummary, CameraView, RenderError, RenderOptions, Renderer, RobotDraw, RobotPart,
};
use hetsim_scene::{DriveKind, Scenario, HAT_SCALE, HAT_THICKNESS_M};
use hetsim_sensors::camera::motion::{self, Timing, Twist};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

struct Rig {
    robot: usize,
    /// `<robot>/<camera>` or `<robot>/<camera>/<left|right>`.
    topic: String,
    /// The camera's name on the robot (as in `Image::sensor`).
    sensor: String,
    period: u64,
    /// The calibration the robot is given and the one the camera renders with.
    calibration: CameraCalibration,
    /// Pixel noise, `None` for a noiseless camera.
    noise: Option<PixelNoise>,
    gain: f32,
    /// Each pixel's gain with vignetting (`gain` falling off towards the corners); `None`:
    /// `gain` everywhere.
    gain_map: Option<Vec<f32>>,
    /// The exposure time and the rolling shutter's line delay.
    timing: Timing,
    /// The true camera's model (its pinhole, or its padded render where it distorts).
    model: Model,
    rng: SimRng,
    /// What the camera delivers (grey is the luminance of the noisy RGB, rounded).
    encoding: PixelEncoding,
}

/// A robot's motion over the last tick: the world-frame velocity of its body's origin and
/// its angular velocity in the body frame (`R(t + dt) = R(t) exp([ω] dt)`).
#[derive(Clone, Copy, Default)]
struct BodyTwist {
    v_world: Vector3<f64>,
    w_body: Vector3<f64>,
}

impl BodyTwist {
    /// The twist that took `before` to `now` in `dt_s` seconds.
    fn between(before: &Pose, now: &Pose, dt_s: f64) -> Self {
        Self {
            v_world: (now.translation.vector - before.translation.vector) / dt_s,
            w_body: (before.rotation.inverse() * now.rotation).scaled_axis() / dt_s,
        }
    }

    /// `world_from_body` `dt_s` seconds after `now`, along this twist.
    fn advance(&self, now: &Pose, dt_s: f64) -> Pose {
        if dt_s == 0.0 {
            return *now;
        }
        Isometry3::from_parts(
            Translation3::from(now.translation.vector + self.v_world * dt_s),
            now.rotation * UnitQuaternion::from_scaled_axis(self.w_body * dt_s),
        )
    }

    /// The twist of a camera at `body_from_optical` on a body at `world_from_body`, in the
    /// camera's optical frame.
    fn of_camera(&self, world_from_body: &Pose, body_from_optical: &Pose) -> Twist {
        let lever =
            world_from_body.rotation * self.w_body.cross(&body_from_optical.translation.vector);
        let world_from_optical = world_from_body.rotation * body_from_optical.rotation;
        Twist {
            v: world_from_optical.inverse() * (self.v_world + lever),
            w: body_from_optical.rotation.inverse() * self.w_body,
        }
    }

    fn is_still(&self) -> bool {
        self.v_world == Vector3::zeros() && self.w_body == Vector3::zeros()
    }
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
    /// The true `world_from_optical` at mid-exposure (the rendered view).
    pub world_from_optical: Pose,
    /// The image and its given pinhole (for a panorama: its size, with focal lengths 0).
    pub intrinsics: CameraGeometry,
    /// The given `body_from_optical`.
    pub body_from_optical: Pose,
    /// The given radial distortion `[k1, k2]`.
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
    /// Every robot's pose at the end of the previous tick (`None` before the first), from
    /// which each robot's motion is taken.
    previous: Option<Vec<Pose>>,
}

/// Every camera's topic with its given and true calibration, in camera order, as a run of
/// `scenario` with `streams` draws them (a replay reports them without rendering).
pub fn calibrations(scenario: &Scenario, streams: &Streams) -> Vec<(String, CameraCalibration)> {
    rigs::rigs(scenario, streams)
        .into_iter()
        .map(|r| (r.topic, r.calibration))
        .collect()
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
        let rigs = rigs::rigs(scenario, streams);
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
            previous: None,
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

    /// Every camera's topic with its given and true calibration, in order.
    pub fn calibrations(&self) -> Vec<(String, CameraCalibration)> {
        self.rigs
            .iter()
            .map(|r| (r.topic.clone(), r.calibration))
            .collect()
    }

    /// Each robot's motion over the tick that just ended, and the poses kept for the next.
    fn motions(&mut self, physics: &Physics) -> Vec<BodyTwist> {
        let now: Vec<Pose> = (0..self.parts.len()).map(|i| physics.pose(i)).collect();
        let dt_s = self.dt_ns as f64 * 1e-9;
        let twists = match &self.previous {
            Some(before) => before
                .iter()
                .zip(&now)
                .map(|(b, n)| BodyTwist::between(b, n, dt_s))
                .collect(),
            None => vec![BodyTwist::default(); now.len()],
        };
        self.previous = Some(now);
        twists
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
        let twists = self.motions(physics);
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
            let twist = twists[rig.robot];
            let body = twist.advance(&physics.pose(rig.robot), rig.calibration.time_offset_s);
            let world_from_mount = body * rig.calibration.truth.body_from_mount;
            let camera_twist = twist.of_camera(&body, &rig.calibration.truth.body_from_optical());
            let keep_depth = depth(&rig.topic);
            // The exposure needs the depth of what the camera sees when it moves.
            let with_depth = keep_depth || !(rig.timing.is_instant() || twist.is_still());
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
            let exposed = Exposed {
                world_from_mount,
                twist: camera_twist,
                keep_depth,
            };
            spans.push((k, start, views.len(), exposed));
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
                let (_, start, end, exposed) = spans.next_if(|s| s.0 == k)?;
                Some((rig, &frames[start..end], exposed))
            })
            .collect();
        jobs.into_par_iter()
            .map(|(rig, frames, exposure)| rig.shot(frames, &exposure, stamp_ns, dt_ns))
            .collect()
    }
}

/// Where and how a camera was when its view was rendered.
struct Exposed {
    /// The true `world_from_mount` at mid-exposure.
    world_from_mount: Pose,
    /// The camera's motion, optical frame.
    twist: Twist,
    /// Whether the shot keeps the rendered depth (frame dumps).
    keep_depth: bool,
}

impl Rig {
    /// The camera model after rendering: the exposure (blur, rolling shutter), distortion or
    /// panorama resampling, gain, vignetting and noise.
    fn shot(&mut self, frames: &[Frame], at: &Exposed, stamp_ns: u64, dt_ns: u64) -> Shot {
        let truth = self.calibration.truth;
        // The exposure over the rendered instant, in the (undistorted) render's geometry.
        let exposed = match &self.model {
            Model::Pinhole { render, .. } => motion::expose(
                &frames[0].rgba,
                frames[0].depth_m.as_deref(),
                render.width as usize,
                render.height as usize,
                &render.k,
                &at.twist,
                &self.timing,
            )
            .map(|rgba| Frame {
                width: render.width,
                height: render.height,
                rgba,
                depth_m: frames[0].depth_m.clone().filter(|_| at.keep_depth),
            }),
            Model::Omni { .. } => None,
        };
        let frame = exposed.as_ref().unwrap_or(&frames[0]);
        // The colour to post-process (RGBA straight from the renderer, or RGB after
        // resampling) and its depth.
        let resampled;
        let (src, stride, depth) = match &self.model {
            Model::Pinhole {
                distortion: None, ..
            } => (&frame.rgba, 4, frame.depth_m.clone()),
            Model::Pinhole {
                distortion: Some(d),
                render,
            } => {
                let (rgb, depth) = distort(frame, &truth.geometry, render, *d);
                resampled = rgb;
                (&resampled, 3, depth)
            }
            Model::Omni { taps, .. } => {
                let (rgb, depth) = panorama(frames, taps);
                resampled = rgb;
                (&resampled, 3, depth)
            }
        };
        // Depth rendered only for the exposure is not the shot's.
        let depth = depth.filter(|_| at.keep_depth);
        let data = self.develop(src, stride);
        let given = &self.calibration.given;
        let rate_hz = 1e9 / (self.period as f64 * dt_ns as f64);
        Shot {
            robot: self.robot,
            topic: self.topic.clone(),
            image: Image {
                stamp_ns,
                sensor: self.sensor.clone(),
                width: given.geometry.width,
                height: given.geometry.height,
                encoding: self.encoding,
                data,
            },
            depth_m: depth,
            world_from_optical: Isometry3::from_parts(
                at.world_from_mount.translation,
                at.world_from_mount.rotation * mount_to_optical(),
            ),
            intrinsics: given.geometry,
            body_from_optical: given.body_from_optical(),
            distortion: given.distortion,
            rate_hz,
        }
    }

    /// Gain (with vignetting) and noise over the exposed colour `src` (pixels of `stride`
    /// bytes, RGB first), in the camera's encoding.
    fn develop(&mut self, src: &[u8], stride: usize) -> Vec<u8> {
        let rgb_to = |rgb: Vec<u8>, encoding| match encoding {
            PixelEncoding::Rgb8 => rgb,
            PixelEncoding::Mono8 => rgb
                .chunks_exact(3)
                .map(|p| PixelEncoding::luminance([p[0], p[1], p[2]]))
                .collect(),
        };
        match (&self.noise, &self.gain_map, self.encoding) {
            (Some(noise), Some(gains), encoding) => rgb_to(
                noise.apply_mapped(src, stride, gains, &mut self.rng),
                encoding,
            ),
            // Grey straight from the noise pass, with no RGB image in between.
            (Some(noise), None, PixelEncoding::Mono8) => noise.apply_grey(
                src,
                stride,
                self.gain,
                &mut self.rng,
                PixelEncoding::luminance,
            ),
            (Some(noise), None, PixelEncoding::Rgb8) => {
                noise.apply(src, stride, self.gain, &mut self.rng)
            }
            (None, gains, encoding) => {
                let rgb = if stride == 3 && self.gain == 1.0 && gains.is_none() {
                    // Unit gain, no noise: the RGB as it is.
                    src.to_vec()
                } else {
                    let gain = |i: usize| gains.as_ref().map_or(self.gain, |g| g[i]);
                    src.chunks_exact(stride)
                        .enumerate()
                        .flat_map(|(i, px)| {
                            let g = gain(i);
                            px[..3].iter().map(move |&c| quantize(c as f32 * g))
                        })
                        .collect()
                };
                rgb_to(rgb, encoding)
            }
        }
    }
}

use hetsim_sensors::camera::{distort, panorama, quantize, Model, PixelNoise, CUBE};
