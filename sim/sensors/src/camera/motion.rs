//! An image as an exposure, not an instant: motion blur and the rolling shutter.
//!
//! The renderer draws the scene at one instant, the image's mid-exposure (for a rolling
//! shutter: the middle row's). A real pixel integrates light over its exposure, and a rolling
//! shutter's row `r` is exposed `(r - (H - 1) / 2) * line_delay` later than the middle row.
//! Over that short a time the camera's motion is one twist (`v`, `ω` in the optical frame), and
//! a static point at pixel `x = (u - u0) / α_u`, `y = (v - v0) / α_v` and depth `Z` moves on the
//! image as Longuet-Higgins and Prazdny's instantaneous flow gives it:
//!
//! ```text
//! ẋ = (-v_x + x v_z) / Z + x y ω_x - (1 + x²) ω_y + y ω_z
//! ẏ = (-v_y + y v_z) / Z + (1 + y²) ω_x - x y ω_y - x ω_z
//! ```
//!
//! So the pixel `q` of row `r` sees at time `t` what the rendered image shows at
//! `q - flow(q) t`, and its value is the mean over its exposure window
//! `t ∈ τ_r + [-T/2, T/2]` (midpoint rule, one bilinear sample per pixel of motion).
//! Depth comes from the renderer (0, the sky, is infinitely far: only the rotation moves it).
//! Where a pixel's motion over its exposure is under half a pixel it is not blurred
//! ([`BLUR_MIN_PX`]), and where no pixel of the image moves that much, and no row is shifted
//! by a rolling shutter, the rendered image is delivered as it is.
//!
//! What this leaves out, and why it is small: the flow is linear in time over the few
//! milliseconds of an exposure (second-order terms are the twist's change within it); the
//! depth is the rendered instant's at the output pixel (it is wrong only at occlusion edges,
//! where the blur's few pixels mix foreground and background slightly differently than
//! sub-frame accumulation); and other robots moving in view are blurred by the camera's
//! motion only. [`tests`] compares the whole against sub-frame accumulation of exact views.

use hetsim_msgs::Pinhole;
use nalgebra::Vector3;

/// Image motion during an exposure below which a pixel is not blurred, pixels.
pub const BLUR_MIN_PX: f64 = 0.5;

/// A rolling shutter's row shift below which an image is not resampled, pixels.
pub const SHIFT_MIN_PX: f64 = 0.05;

/// The spacing of the samples along a pixel's motion, pixels: each sample is bilinear, which
/// already averages over a pixel, so one a pixel integrates the motion (the test against
/// sub-frame accumulation holds it to account).
pub const SAMPLE_SPACING_PX: f32 = 1.0;

/// The width of the row segments tested as a whole for motion below the thresholds, pixels.
const SEGMENT_PX: usize = 32;

/// The most samples along one pixel's motion (motion over 15 pixels is sampled coarser).
pub const MAX_SAMPLES: usize = 16;

/// The camera's motion at the rendered instant, in its optical frame (x right, y down,
/// z forward): linear velocity, metres per second, and angular velocity, radians per second
/// (`R(t + dt) = R(t) exp([ω] dt)`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub v: Vector3<f64>,
    /// Angular velocity, rad/s.
    pub w: Vector3<f64>,
}

/// When a camera's pixels gather light, relative to the rendered instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Timing {
    /// Exposure time, seconds.
    pub exposure_s: f64,
    /// Delay between consecutive rows, seconds (0: global shutter).
    pub line_delay_s: f64,
}

impl Timing {
    /// Row `r`'s mid-exposure against the rendered instant, seconds.
    fn row_offset_s(&self, r: usize, height: usize) -> f64 {
        (r as f64 - (height as f64 - 1.0) / 2.0) * self.line_delay_s
    }

    /// Whether the camera needs depth and a pass after rendering when it moves.
    pub fn is_instant(&self) -> bool {
        self.exposure_s == 0.0 && self.line_delay_s == 0.0
    }
}

/// A camera's image motion in f32 (a byte image needs no more): its focal lengths and twist.
struct Flow {
    f: [f32; 2],
    v: Vector3<f32>,
    w: Vector3<f32>,
}

impl Flow {
    fn new(k: &Pinhole, t: &Twist) -> Self {
        Self {
            f: [k.alpha_u as f32, k.alpha_v as f32],
            v: t.v.map(|x| x as f32),
            w: t.w.map(|x| x as f32),
        }
    }

    /// The motion, pixels per second, at normalized image coordinates `(x, y)` of a static
    /// point at inverse depth `inv_z` (0: at infinity): the module's equations.
    #[inline]
    fn at(&self, x: f32, y: f32, inv_z: f32) -> [f32; 2] {
        let (v, w) = (&self.v, &self.w);
        let xd = (-v.x + x * v.z) * inv_z + x * y * w.x - (1.0 + x * x) * w.y + y * w.z;
        let yd = (-v.y + y * v.z) * inv_z + (1.0 + y * y) * w.x - x * y * w.y - x * w.z;
        [self.f[0] * xd, self.f[1] * yd]
    }

    /// An upper bound of the squared motion over points with `|x| <= xm`, `|y| <= ym` and
    /// inverse depth at most `inv_z`: each term of [`Flow::at`] at its largest.
    fn bound2(&self, xm: f32, ym: f32, inv_z: f32) -> f32 {
        let (v, w) = (self.v.abs(), self.w.abs());
        let bu = (v.x + xm * v.z) * inv_z + xm * ym * w.x + (1.0 + xm * xm) * w.y + ym * w.z;
        let bv = (v.y + ym * v.z) * inv_z + (1.0 + ym * ym) * w.x + xm * ym * w.y + xm * w.z;
        (self.f[0] * bu).powi(2) + (self.f[1] * bv).powi(2)
    }
}

/// The inverse of the nearest positive depth of `depth` (0 where all of it is sky).
fn nearest_inverse_depth(depth: Option<&[f32]>) -> f32 {
    let near = depth.map_or(f32::INFINITY, |d| {
        d.iter()
            .fold(f32::INFINITY, |a, &z| if z > 0.0 { a.min(z) } else { a })
    });
    if near.is_finite() {
        1.0 / near
    } else {
        0.0
    }
}

/// The rendered RGBA image `rgba` (`width x height`, pinhole `k`, depth along the optical axis
/// `depth_m`, 0 = sky; `None`: everything at infinity) as the camera exposes it while moving
/// with `twist`; `None` where no pixel would change (the rendered image is the exposure).
pub fn expose(
    rgba: &[u8],
    depth_m: Option<&[f32]>,
    width: usize,
    height: usize,
    k: &Pinhole,
    twist: &Twist,
    timing: &Timing,
) -> Option<Vec<u8>> {
    if timing.is_instant() || (twist.v.norm() == 0.0 && twist.w.norm() == 0.0) {
        return None;
    }
    const BLUR_MIN_PX2: f32 = (BLUR_MIN_PX * BLUR_MIN_PX) as f32;
    const SHIFT_MIN_PX2: f32 = (SHIFT_MIN_PX * SHIFT_MIN_PX) as f32;
    let flow = Flow::new(k, twist);
    let exposure = timing.exposure_s as f32;
    // Whether motion bounded by `speed2` (squared) neither blurs nor shifts rows offset `tau`.
    let still = |speed2: f32, tau: f32| {
        speed2 * exposure * exposure < BLUR_MIN_PX2 && speed2 * tau * tau < SHIFT_MIN_PX2
    };
    // Normalized image coordinates of each column and row.
    let xs: Vec<f32> = (0..width)
        .map(|c| ((c as f64 - k.u0) / k.alpha_u) as f32)
        .collect();
    let ys: Vec<f32> = (0..height)
        .map(|r| ((r as f64 - k.v0) / k.alpha_v) as f32)
        .collect();
    let widest = |c: &[f32]| c.iter().fold(0f32, |a, x| a.max(x.abs()));
    let image_bound = flow.bound2(widest(&xs), widest(&ys), nearest_inverse_depth(depth_m));
    if still(image_bound, timing.row_offset_s(0, height) as f32) {
        return None;
    }
    let mut out = vec![0u8; rgba.len()];
    for (r, row) in out.chunks_exact_mut(width * 4).enumerate() {
        let tau = timing.row_offset_s(r, height) as f32;
        let y = ys[r];
        let depth_row = depth_m.map(|d| &d[r * width..(r + 1) * width]);
        // Segments of a row whose every pixel moves less than the thresholds (a bound from
        // the segment's nearest depth and its widest x) are copied as they are.
        let segment_still = |c0: usize, c1: usize| {
            let xm = xs[c0].abs().max(xs[c1 - 1].abs());
            let inv_z = nearest_inverse_depth(depth_row.map(|d| &d[c0..c1]));
            still(flow.bound2(xm, y.abs(), inv_z), tau)
        };
        let mut still_until = 0;
        for (c, px) in row.chunks_exact_mut(4).enumerate() {
            if c % SEGMENT_PX == 0 {
                let end = (c + SEGMENT_PX).min(width);
                if segment_still(c, end) {
                    still_until = end;
                }
            }
            if c < still_until {
                let i = r * width + c;
                px.copy_from_slice(&rgba[i * 4..i * 4 + 4]);
                continue;
            }
            let z = depth_row.map_or(0.0, |d| d[c]);
            let inv_z = if z > 0.0 { 1.0 / z } else { 0.0 };
            let [du, dv] = flow.at(xs[c], y, inv_z);
            // Squared lengths first: most pixels of a slow camera stop here.
            let speed2 = du * du + dv * dv;
            let i = r * width + c;
            if still(speed2, tau) {
                px.copy_from_slice(&rgba[i * 4..i * 4 + 4]);
                continue;
            }
            let blurs = speed2 * exposure * exposure >= BLUR_MIN_PX2;
            let n = if blurs {
                ((speed2.sqrt() * exposure / SAMPLE_SPACING_PX).ceil() as usize)
                    .clamp(2, MAX_SAMPLES)
            } else {
                1
            };
            let mut sum = [0u32; 3];
            for j in 0..n {
                let t = if n == 1 {
                    tau
                } else {
                    tau + ((j as f32 + 0.5) / n as f32 - 0.5) * exposure
                };
                sample_into(
                    &mut sum,
                    rgba,
                    width,
                    height,
                    c as f32 - du * t,
                    r as f32 - dv * t,
                );
            }
            let (scale, half) = (n as u32 * 65_536, n as u32 * 32_768);
            for (o, s) in px.iter_mut().zip(sum) {
                *o = ((s + half) / scale) as u8;
            }
            px[3] = 255;
        }
    }
    Some(out)
}

/// Adds the bilinear RGB of `rgba` at `(u, v)` (pixel centres at integers, clamped to the
/// border) to `sum`, in units of 1/65536 of a grey level (8-bit weights per axis).
#[inline]
fn sample_into(sum: &mut [u32; 3], rgba: &[u8], width: usize, height: usize, u: f32, v: f32) {
    let u = u.clamp(0.0, (width - 1) as f32);
    let v = v.clamp(0.0, (height - 1) as f32);
    let (u0, v0) = (u as usize, v as usize);
    let (du, dv) = (
        usize::from(u0 + 1 < width) * 4,
        usize::from(v0 + 1 < height) * width * 4,
    );
    let a = ((u - u0 as f32) * 256.0) as u32;
    let b = ((v - v0 as f32) * 256.0) as u32;
    let weights = [(256 - a) * (256 - b), a * (256 - b), (256 - a) * b, a * b];
    let at = (v0 * width + u0) * 4;
    // The four neighbours' bytes in one slice, so that one bounds check covers them.
    let block = &rgba[at..at + dv + du + 3];
    for (offset, wgt) in [0, du, dv, dv + du].into_iter().zip(weights) {
        let px = &block[offset..offset + 3];
        sum[0] += px[0] as u32 * wgt;
        sum[1] += px[1] as u32 * wgt;
        sum[2] += px[2] as u32 * wgt;
    }
}

#[cfg(test)]
mod tests {
    //! The per-pixel blur against sub-frame accumulation of exact views of a textured,
    //! tilted plane (ray-cast here, so the reference is exact and needs no GPU).

    use super::*;
    use hetsim_msgs::CameraGeometry;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

    const W: usize = 160;
    const H: usize = 120;

    /// The plane `n · p = d` (world frame) with a smooth texture of wavelength ~1 m, seen by
    /// a pinhole at `world_from_optical`: RGBA and depth along the optical axis.
    fn view(k: &Pinhole, world_from_optical: &Isometry3<f64>) -> (Vec<u8>, Vec<f32>) {
        let n = Vector3::new(0.0, 0.3, -1.0).normalize();
        let d = -8.0 * n.z; // the plane passes through (0, 0, 8)
        let mut rgba = vec![0u8; W * H * 4];
        let mut depth = vec![0f32; W * H];
        for r in 0..H {
            for c in 0..W {
                let ray_c = Vector3::new(
                    (c as f64 - k.u0) / k.alpha_u,
                    (r as f64 - k.v0) / k.alpha_v,
                    1.0,
                );
                let o = world_from_optical.translation.vector;
                let dir = world_from_optical.rotation * ray_c;
                let s = (d - n.dot(&o)) / n.dot(&dir);
                let p = o + dir * s;
                let tex = |a: f64, b: f64| {
                    (127.5
                        + 60.0 * (a * 3.0).sin() * (b * 2.5).cos()
                        + 50.0 * ((a + b) * 5.0).sin())
                    .clamp(0.0, 255.0)
                };
                let i = r * W + c;
                rgba[i * 4] = tex(p.x, p.y) as u8;
                rgba[i * 4 + 1] = tex(p.y, p.x) as u8;
                rgba[i * 4 + 2] = tex(p.x * 0.7, p.y * 1.3) as u8;
                rgba[i * 4 + 3] = 255;
                depth[i] = s as f32; // ray_c has z = 1: s is the depth along the axis
            }
        }
        (rgba, depth)
    }

    /// The pose at `t` of a camera moving with `twist` (optical frame) from `start`.
    fn at(start: &Isometry3<f64>, twist: &Twist, t: f64) -> Isometry3<f64> {
        let step = Isometry3::from_parts(
            Translation3::from(twist.v * t),
            UnitQuaternion::from_scaled_axis(twist.w * t),
        );
        start * step
    }

    /// Mean absolute difference of the colour channels, away from the border (where the
    /// blur clamps and the reference sees beyond the rendered image).
    fn mean_abs(a: &[u8], b: &[u8]) -> f64 {
        const MARGIN: usize = 12;
        let (mut s, mut n) = (0.0, 0);
        for r in MARGIN..H - MARGIN {
            for c in MARGIN..W - MARGIN {
                for ch in 0..3 {
                    let i = (r * W + c) * 4 + ch;
                    s += (a[i] as f64 - b[i] as f64).abs();
                    n += 1;
                }
            }
        }
        s / n as f64
    }

    /// Sub-frame accumulation: the mean of `m` exact views over each row's exposure window.
    fn accumulate(
        k: &Pinhole,
        start: &Isometry3<f64>,
        twist: &Twist,
        timing: &Timing,
        m: usize,
    ) -> Vec<u8> {
        let mut sum = vec![0f64; W * H * 4];
        let rows_at = |t: f64| view(k, &at(start, twist, t)).0;
        if timing.line_delay_s == 0.0 {
            for j in 0..m {
                let t = ((j as f64 + 0.5) / m as f64 - 0.5) * timing.exposure_s;
                for (s, v) in sum.iter_mut().zip(rows_at(t)) {
                    *s += v as f64;
                }
            }
        } else {
            for r in 0..H {
                let tau = timing.row_offset_s(r, H);
                for j in 0..m {
                    let t = tau + ((j as f64 + 0.5) / m as f64 - 0.5) * timing.exposure_s;
                    let img = rows_at(t);
                    for i in r * W * 4..(r + 1) * W * 4 {
                        sum[i] += img[i] as f64;
                    }
                }
            }
        }
        sum.iter().map(|s| (s / m as f64).round() as u8).collect()
    }

    /// The mean error of [`expose`] and of the rendered instant against `m` exact views over
    /// each row's exposure window, for a camera at the origin moving with `twist`.
    fn against_reference(twist: &Twist, timing: &Timing, m: usize) -> (f64, f64) {
        let k = CameraGeometry::from_hfov(W as u32, H as u32, 60.0).k;
        let start = Isometry3::identity();
        let (rgba, depth) = view(&k, &start);
        let exposed = expose(&rgba, Some(&depth), W, H, &k, twist, timing).expect("moving");
        let reference = accumulate(&k, &start, twist, timing, m);
        (mean_abs(&exposed, &reference), mean_abs(&rgba, &reference))
    }

    /// The blur explains the exposure: against sub-frame accumulation its error is under a
    /// fifth of the error of the instant it replaces, and under one grey level on average.
    #[test]
    fn blur_matches_sub_frame_accumulation() {
        let twist = Twist {
            v: Vector3::new(2.0, -1.0, 3.0),
            w: Vector3::new(0.4, -1.5, 0.8),
        };
        let timing = Timing {
            exposure_s: 0.02,
            line_delay_s: 0.0,
        };
        let (model, instant) = against_reference(&twist, &timing, 64);
        assert!(instant > 3.0, "the test's motion must blur: {instant}");
        assert!(
            model < 0.2 * instant && model < 1.0,
            "blur {model} against instant {instant}"
        );
    }

    /// A rolling shutter's rows, each at its own time, as exact views at those times.
    #[test]
    fn rolling_shutter_matches_row_by_row_views() {
        let twist = Twist {
            v: Vector3::new(1.0, 0.0, 0.5),
            w: Vector3::new(0.0, 2.0, 0.3),
        };
        let timing = Timing {
            exposure_s: 0.0,
            line_delay_s: 100e-6,
        };
        let (model, instant) = against_reference(&twist, &timing, 1);
        assert!(instant > 3.0, "the shutter must move rows: {instant}");
        assert!(
            model < 0.2 * instant && model < 1.5,
            "rolling {model} against global {instant}"
        );
    }

    /// A still camera, or motion under half a pixel, delivers the rendered image as it is.
    #[test]
    fn slow_motion_is_not_resampled() {
        let k = CameraGeometry::from_hfov(W as u32, H as u32, 60.0).k;
        let (rgba, depth) = view(&k, &Isometry3::identity());
        let timing = Timing {
            exposure_s: 0.005,
            line_delay_s: 0.0,
        };
        assert!(expose(&rgba, Some(&depth), W, H, &k, &Twist::default(), &timing).is_none());
        // 0.01 rad/s at 139 px focal length over 5 ms: 0.007 px.
        let slow = Twist {
            v: Vector3::zeros(),
            w: Vector3::new(0.0, 0.01, 0.0),
        };
        assert!(expose(&rgba, Some(&depth), W, H, &k, &slow, &timing).is_none());
    }
}
