//! The robots' cameras: what to render when, and the camera model after rendering.
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
use hetsim_msgs::{pose_from_xyz_rpy, Image, Pose};
use hetsim_physics::Physics;
use hetsim_render::{
    mount_to_optical, AdapterSummary, CameraView, Frame, Intrinsics, RenderError, RenderOptions,
    Renderer, RobotDraw, RobotPart,
};
use hetsim_scene::{DriveKind, Scenario, Sensor};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use rand_distr::{Distribution, StandardNormal};

enum Model {
    /// `render`: the intrinsics actually rendered (padded beyond the image when distortion
    /// needs rays outside its undistorted field of view).
    Pinhole {
        distortion: Option<[f64; 2]>,
        render: Intrinsics,
    },
    /// The panorama's pixels: (cube face, face u, face v, range / depth), computed once.
    Omni {
        face: Intrinsics,
        lookup: Vec<(u8, f32, f32, f32)>,
    },
}

struct Rig {
    robot: usize,
    /// `<robot>/<camera>` or `<robot>/<camera>/<left|right>`.
    topic: String,
    /// The camera's name on the robot (as in `Image::sensor`).
    sensor: String,
    period: u64,
    intrinsics: Intrinsics,
    body_from_mount: Pose,
    noise: f64,
    gain: f64,
    model: Model,
    rng: SimRng,
}

/// One captured image with its ground truth.
pub struct Shot {
    /// Robot index.
    pub robot: usize,
    /// `<robot>/<camera>[/<left|right>]`.
    pub topic: String,
    /// The image as the robot receives it.
    pub image: Image,
    /// Ground-truth depth along the optical axis (pinhole) or range (panorama), metres; 0 = none.
    pub depth_m: Vec<f32>,
    /// `world_from_optical` at exposure.
    pub world_from_optical: Pose,
    /// Intrinsics (for a panorama: its size, with focal lengths 0).
    pub intrinsics: Intrinsics,
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
                centre: [0.0, 0.0, 2.0 * h + 0.012],
                half_extents: [l * 0.9, w * 0.9, 0.012],
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
        let mut rigs = Vec::new();
        for (i, r) in scenario.robots.iter().enumerate() {
            for s in &r.model.sensors {
                let m = s.mount();
                let mount = pose_from_xyz_rpy(m.xyz_m, m.rpy_deg.map(f64::to_radians));
                let base = format!("{}/{}", r.spec.name, s.name());
                let period = clock.period_ticks(s.rate_hz()).expect("validated rate");
                match s {
                    Sensor::Camera {
                        width_px,
                        height_px,
                        hfov_deg,
                        intrinsics,
                        pixel_noise_sigma,
                        distortion,
                        gain,
                        ..
                    } => rigs.push(Rig {
                        robot: i,
                        rng: streams.stream(&format!("{base}/pixel_noise")),
                        topic: base,
                        sensor: s.name().to_string(),
                        period,
                        intrinsics: hetsim_render::intrinsics_of(
                            *width_px,
                            *height_px,
                            *hfov_deg,
                            intrinsics.as_ref(),
                        ),
                        body_from_mount: mount,
                        noise: *pixel_noise_sigma,
                        gain: *gain,
                        model: pinhole(
                            hetsim_render::intrinsics_of(
                                *width_px,
                                *height_px,
                                *hfov_deg,
                                intrinsics.as_ref(),
                            ),
                            *distortion,
                        ),
                    }),
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
                        for (eye, offset) in [("left", 0.0), ("right", -baseline_m)] {
                            rigs.push(Rig {
                                robot: i,
                                rng: streams.stream(&format!("{base}/{eye}/pixel_noise")),
                                topic: format!("{base}/{eye}"),
                                sensor: format!("{}/{eye}", s.name()),
                                period,
                                intrinsics: hetsim_render::intrinsics_of(
                                    *width_px,
                                    *height_px,
                                    *hfov_deg,
                                    intrinsics.as_ref(),
                                ),
                                body_from_mount: mount
                                    * pose_from_xyz_rpy([0.0, offset, 0.0], [0.0; 3]),
                                noise: *pixel_noise_sigma,
                                gain: *gain,
                                model: pinhole(
                                    hetsim_render::intrinsics_of(
                                        *width_px,
                                        *height_px,
                                        *hfov_deg,
                                        intrinsics.as_ref(),
                                    ),
                                    *distortion,
                                ),
                            });
                        }
                    }
                    Sensor::OmniCamera {
                        width_px,
                        height_px,
                        elevation_deg,
                        ..
                    } => {
                        let face_px = (width_px / 4).max(16);
                        rigs.push(Rig {
                            robot: i,
                            rng: streams.stream(&format!("{base}/pixel_noise")),
                            topic: base,
                            sensor: s.name().to_string(),
                            period,
                            intrinsics: Intrinsics {
                                width: *width_px,
                                height: *height_px,
                                alpha_u: 0.0,
                                alpha_v: 0.0,
                                u0: 0.0,
                                v0: 0.0,
                            },
                            body_from_mount: mount,
                            noise: 0.0,
                            gain: 1.0,
                            model: {
                                let face = Intrinsics::from_hfov(face_px, face_px, 90.0);
                                Model::Omni {
                                    lookup: panorama_lookup(
                                        &face,
                                        *width_px,
                                        *height_px,
                                        elevation_deg.map(f64::to_radians),
                                    ),
                                    face,
                                }
                            },
                        });
                    }
                    _ => {}
                }
            }
        }
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
    /// keeping only the cameras `keep` accepts; returns the shots in camera order.
    pub fn capture(
        &mut self,
        physics: &Physics,
        tick: u64,
        stamp_ns: u64,
        keep: &dyn Fn(&str) -> bool,
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
            let world_from_mount = physics.pose(rig.robot) * rig.body_from_mount;
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
                }),
                Model::Omni { face, .. } => {
                    for (yaw, pitch) in CUBE {
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
                        });
                    }
                }
            }
            spans.push((k, start, views.len(), world_from_mount));
        }
        let frames = self.renderer.render(&views);
        let mut shots = Vec::new();
        for (k, start, end, world_from_mount) in spans {
            let rig = &mut self.rigs[k];
            let (mut rgb, depth) = match &rig.model {
                Model::Pinhole {
                    distortion: None, ..
                } => (frames[start].rgb.clone(), frames[start].depth_m.clone()),
                Model::Pinhole {
                    distortion: Some(d),
                    render,
                } => distort(&frames[start], &rig.intrinsics, render, *d),
                Model::Omni { lookup, .. } => panorama(&frames[start..end], lookup),
            };
            for c in rgb.iter_mut() {
                let mut v = *c as f64 * rig.gain;
                if rig.noise > 0.0 {
                    let n: f64 = StandardNormal.sample(&mut rig.rng);
                    v += n * rig.noise;
                }
                *c = v.round().clamp(0.0, 255.0) as u8;
            }
            let body_from_optical = Isometry3::from_parts(
                rig.body_from_mount.translation,
                rig.body_from_mount.rotation * mount_to_optical(),
            );
            let distortion = match &rig.model {
                Model::Pinhole {
                    distortion: Some(d),
                    ..
                } => *d,
                _ => [0.0, 0.0],
            };
            let rate_hz = 1e9 / (rig.period as f64 * self.dt_ns as f64);
            shots.push(Shot {
                robot: rig.robot,
                topic: rig.topic.clone(),
                image: Image {
                    stamp_ns,
                    sensor: rig.sensor.clone(),
                    width: rig.intrinsics.width,
                    height: rig.intrinsics.height,
                    rgb,
                },
                depth_m: depth,
                world_from_optical: Isometry3::from_parts(
                    world_from_mount.translation,
                    world_from_mount.rotation * mount_to_optical(),
                ),
                intrinsics: rig.intrinsics,
                body_from_optical,
                distortion,
                rate_hz,
            });
        }
        shots
    }
}

/// The six cube faces as (yaw, pitch) of the face's mount frame: forward, left, back, right,
/// up (pitch -90°: x axis up), down.
const CUBE: [(f64, f64); 6] = [
    (0.0, 0.0),
    (std::f64::consts::FRAC_PI_2, 0.0),
    (std::f64::consts::PI, 0.0),
    (-std::f64::consts::FRAC_PI_2, 0.0),
    (0.0, -std::f64::consts::FRAC_PI_2),
    (0.0, std::f64::consts::FRAC_PI_2),
];

fn bilinear(f: &Frame, u: f64, v: f64) -> Option<([f64; 3], f32)> {
    let (w, h) = (f.width as i64, f.height as i64);
    if u < 0.0 || v < 0.0 || u > (w - 1) as f64 || v > (h - 1) as f64 {
        return None;
    }
    let (x0, y0) = (u.floor() as i64, v.floor() as i64);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (u - x0 as f64, v - y0 as f64);
    let px = |x: i64, y: i64, c: usize| f.rgb[((y * w + x) * 3) as usize + c] as f64;
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = px(x0, y0, c) * (1.0 - tx) + px(x1, y0, c) * tx;
        let bottom = px(x0, y1, c) * (1.0 - tx) + px(x1, y1, c) * tx;
        *o = top * (1.0 - ty) + bottom * ty;
    }
    let depth = f.depth_m[(v.round() as i64 * w + u.round() as i64) as usize];
    Some((out, depth))
}

/// The undistorted normalized coordinates of distorted normalized `(xd, yd)`.
fn undistort(xd: f64, yd: f64, [k1, k2]: [f64; 2]) -> (f64, f64) {
    let (mut xu, mut yu) = (xd, yd);
    for _ in 0..20 {
        let r2 = xu * xu + yu * yu;
        let s = 1.0 + k1 * r2 + k2 * r2 * r2;
        xu = xd / s;
        yu = yd / s;
    }
    (xu, yu)
}

/// A pinhole model; with distortion, the render is padded so that every image pixel's
/// undistorted ray falls inside it.
fn pinhole(k: Intrinsics, distortion: Option<[f64; 2]>) -> Model {
    let Some(d) = distortion else {
        return Model::Pinhole {
            distortion,
            render: k,
        };
    };
    let (mut left, mut right, mut top, mut bottom) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (w, h) = (k.width as f64 - 1.0, k.height as f64 - 1.0);
    let border = (0..=64).flat_map(|i| {
        let t = i as f64 / 64.0;
        [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)]
    });
    for (u, v) in border {
        let (xu, yu) = undistort((u - k.u0) / k.alpha_u, (v - k.v0) / k.alpha_v, d);
        let (ru, rv) = (k.alpha_u * xu + k.u0, k.alpha_v * yu + k.v0);
        left = left.max(-ru);
        right = right.max(ru - w);
        top = top.max(-rv);
        bottom = bottom.max(rv - h);
    }
    let (pl, pr, pt, pb) = [left, right, top, bottom]
        .map(|m| m.ceil() as u32 + 1)
        .into();
    let render = Intrinsics {
        width: k.width + pl + pr,
        height: k.height + pt + pb,
        u0: k.u0 + pl as f64,
        v0: k.v0 + pt as f64,
        ..k
    };
    Model::Pinhole { distortion, render }
}

/// Applies radial distortion: each output pixel samples the (padded) undistorted render at the
/// undistorted position of its ray (fixed-point inversion of the distortion).
fn distort(f: &Frame, k: &Intrinsics, render: &Intrinsics, d: [f64; 2]) -> (Vec<u8>, Vec<f32>) {
    let n = (k.width * k.height) as usize;
    let mut rgb = vec![0u8; n * 3];
    let mut depth = vec![0f32; n];
    for v in 0..k.height {
        for u in 0..k.width {
            let (xu, yu) = undistort(
                (u as f64 - k.u0) / k.alpha_u,
                (v as f64 - k.v0) / k.alpha_v,
                d,
            );
            let i = (v * k.width + u) as usize;
            if let Some((c, d)) = bilinear(
                f,
                render.alpha_u * xu + render.u0,
                render.alpha_v * yu + render.v0,
            ) {
                for ch in 0..3 {
                    rgb[i * 3 + ch] = c[ch].round() as u8;
                }
                depth[i] = d;
            }
        }
    }
    (rgb, depth)
}

/// For each panorama pixel: which cube face sees its ray, where, and the ratio of range to
/// that face's depth.
fn panorama_lookup(
    face: &Intrinsics,
    w: u32,
    h: u32,
    [lo, hi]: [f64; 2],
) -> Vec<(u8, f32, f32, f32)> {
    let to_optical = mount_to_optical().inverse();
    let face_from_mount: Vec<UnitQuaternion<f64>> = CUBE
        .iter()
        .map(|(yaw, pitch)| UnitQuaternion::from_euler_angles(0.0, *pitch, *yaw).inverse())
        .collect();
    let mut out = Vec::with_capacity((w * h) as usize);
    for v in 0..h {
        let el = hi - (hi - lo) * (v as f64 + 0.5) / h as f64;
        for u in 0..w {
            let az = std::f64::consts::PI - std::f64::consts::TAU * (u as f64 + 0.5) / w as f64;
            let dir = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            // The face whose optical axis is closest to the ray.
            let (best, p) = face_from_mount
                .iter()
                .enumerate()
                .map(|(i, r)| (i, to_optical * (r * dir)))
                .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
                .expect("six faces");
            let (fu, fv) = face.project(&p).unwrap_or((0.0, 0.0));
            let (fu, fv) = (
                fu.clamp(0.0, (face.width - 1) as f64),
                fv.clamp(0.0, (face.height - 1) as f64),
            );
            out.push((
                best as u8,
                fu as f32,
                fv as f32,
                (p.norm() / p.z.max(1e-9)) as f32,
            ));
        }
    }
    out
}

/// Resamples the six rendered cube faces into the panorama (depth becomes range).
fn panorama(faces: &[Frame], lookup: &[(u8, f32, f32, f32)]) -> (Vec<u8>, Vec<f32>) {
    let mut rgb = vec![0u8; lookup.len() * 3];
    let mut depth = vec![0f32; lookup.len()];
    for (i, &(f, u, v, scale)) in lookup.iter().enumerate() {
        if let Some((c, d)) = bilinear(&faces[f as usize], u as f64, v as f64) {
            for ch in 0..3 {
                rgb[i * 3 + ch] = c[ch].round() as u8;
            }
            depth[i] = d * scale;
        }
    }
    (rgb, depth)
}

#[cfg(test)]
mod tests;
