//! Line segments: detection in the manner of LSD, and model-driven tracking.
//!
//! **Detection** follows the Line Segment Detector of Grompone von Gioi, Jakubowicz, Morel and
//! Randall (IPOL 2012), without its 0.8 down-scaling (a Gaussian of σ = 0.8 px stands in for
//! it): level-line angles from a 2 x 2 gradient mask, pixels pseudo-ordered by gradient
//! magnitude (1024 bins), regions grown from seeds within an angle tolerance τ = 22.5°,
//! approximated by the rectangle of their inertia, refined (a tighter tolerance, then a
//! shrinking radius) while too few of the rectangle's pixels are in the region, and kept when
//! the number of false alarms, `NFA = (NM)^(5/2) B(n, k, τ/π)`, is below 1 (an a-contrario
//! test: the segment would not appear by chance in noise).
//!
//! **Tracking** is the model-driven step the seed relies on (its reference \[14\]): the
//! caller predicts the segment's image from its 3D estimate ([`project_segment`]); edge points
//! are searched along the predicted segment's normal, a line is fitted to them with residual
//! rejection, and the ends are extended along the line while the edge goes on.
//!
//! A segment's direction carries its polarity, as in LSD: going from `a` to `b`, the darker
//! side is on the right in image coordinates (x right, y down); equivalently the gradient
//! points to the left of `b - a`.

use crate::Gray;
use hetsim_msgs::Pinhole;
use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use std::f64::consts::PI;

mod scale;
use scale::rescale;
mod track;
pub use track::{project_segment, track, TrackParams};

/// An image line segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// First endpoint, pixels.
    pub a: [f64; 2],
    /// Second endpoint, pixels.
    pub b: [f64; 2],
    /// Width of the supporting rectangle, pixels (detection only; 1 when tracked).
    pub width: f64,
    /// −log10(NFA) of the detection (larger is more meaningful); 0 when tracked.
    pub significance: f64,
}

impl Segment {
    /// A segment from its endpoints.
    pub fn new(a: [f64; 2], b: [f64; 2]) -> Self {
        Self {
            a,
            b,
            width: 1.0,
            significance: 0.0,
        }
    }

    /// Length, pixels.
    pub fn length(&self) -> f64 {
        (self.b[0] - self.a[0]).hypot(self.b[1] - self.a[1])
    }

    /// Unit direction from `a` to `b`.
    pub fn direction(&self) -> Vector2<f64> {
        Vector2::new(self.b[0] - self.a[0], self.b[1] - self.a[1]).normalize()
    }

    /// Signed distance of `p` from the segment's supporting line (positive on the left of
    /// `b - a`, i.e. the gradient's side).
    pub fn line_distance(&self, p: [f64; 2]) -> f64 {
        let d = self.direction();
        (p[1] - self.a[1]) * d.x - (p[0] - self.a[0]) * d.y
    }

    /// Abscissa of `p`'s projection on the line, pixels from `a` towards `b`.
    pub fn abscissa(&self, p: [f64; 2]) -> f64 {
        let d = self.direction();
        (p[0] - self.a[0]) * d.x + (p[1] - self.a[1]) * d.y
    }

    /// The point at abscissa `s`.
    pub fn at(&self, s: f64) -> [f64; 2] {
        let d = self.direction();
        [self.a[0] + s * d.x, self.a[1] + s * d.y]
    }

    /// The part of the segment inside the rectangle `[min, max]` (pixels), keeping its
    /// direction (Liang-Barsky); `None` when no part is inside.
    pub fn clipped(&self, min: [f64; 2], max: [f64; 2]) -> Option<Segment> {
        let d = [self.b[0] - self.a[0], self.b[1] - self.a[1]];
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for i in 0..2 {
            for (p, q) in [(-d[i], self.a[i] - min[i]), (d[i], max[i] - self.a[i])] {
                if p == 0.0 {
                    if q < 0.0 {
                        return None;
                    }
                } else if p < 0.0 {
                    t0 = t0.max(q / p);
                } else {
                    t1 = t1.min(q / p);
                }
            }
        }
        (t0 < t1).then(|| {
            let at = |t: f64| [self.a[0] + t * d[0], self.a[1] + t * d[1]];
            Segment {
                a: at(t0),
                b: at(t1),
                ..*self
            }
        })
    }
}

/// Parameters of [`detect`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectParams {
    /// The image is first scaled by this factor (LSD: 0.8), after a Gaussian of
    /// σ = 0.6 / scale pixels against aliasing; 1 works on the image as it is.
    pub scale: f64,
    /// Angle tolerance τ, radians.
    pub angle_tolerance: f64,
    /// Gradient quantization error bound q (grey levels); pixels with a gradient under
    /// `q / sin τ` have no reliable angle.
    pub quantization: f64,
    /// Minimal density of region pixels in the rectangle before refinement stops.
    pub density: f64,
    /// Segments shorter than this are dropped, pixels.
    pub min_length: f64,
}

impl Default for DetectParams {
    fn default() -> Self {
        Self {
            scale: 0.8,
            angle_tolerance: 22.5f64.to_radians(),
            quantization: 2.0,
            density: 0.7,
            min_length: 60.0,
        }
    }
}

/// Level-line field of an image: gradient magnitude and level-line angle at the centre of
/// each 2 x 2 block (`(x + 0.5, y + 0.5)`); `None` where the gradient is too small.
struct Field {
    width: usize,
    height: usize,
    magnitude: Vec<f64>,
    angle: Vec<Option<f64>>,
    /// `(cos, sin)` of the angle where there is one.
    unit: Vec<[f64; 2]>,
}

impl Field {
    fn new(img: &Gray, threshold: f64) -> Self {
        let (w, h) = (img.width - 1, img.height - 1);
        let mut magnitude = vec![0.0; w * h];
        let mut angle = vec![None; w * h];
        let mut unit = vec![[0.0; 2]; w * h];
        let iw = img.width;
        for y in 0..h {
            let (top, bottom) = (
                &img.data[y * iw..(y + 1) * iw],
                &img.data[(y + 1) * iw..(y + 2) * iw],
            );
            for x in 0..w {
                let (c1, c2) = (
                    bottom[x + 1] as f64 - top[x] as f64,
                    top[x + 1] as f64 - bottom[x] as f64,
                );
                let (gx, gy) = ((c1 + c2) / 2.0, (c1 - c2) / 2.0);
                let m = (gx * gx + gy * gy).sqrt();
                let i = y * w + x;
                magnitude[i] = m;
                if m > threshold {
                    // The level-line angle atan2(gx, -gy) and its cosine and sine.
                    angle[i] = Some(gx.atan2(-gy));
                    unit[i] = [-gy / m, gx / m];
                }
            }
        }
        Self {
            width: w,
            height: h,
            magnitude,
            angle,
            unit,
        }
    }
}

/// Absolute difference of two angles, in [0, π].
fn angle_diff(a: f64, b: f64) -> f64 {
    let mut d = (a - b).rem_euclid(2.0 * PI);
    if d > PI {
        d = 2.0 * PI - d;
    }
    d
}

/// A grown region: its pixels and their mean level-line angle.
struct Region {
    pixels: Vec<(usize, usize)>,
    angle: f64,
}

/// Grows a region from `seed` over the 8-neighbours whose angle is within `tolerance` of the
/// region's mean angle (kept as the sum of unit vectors: `|a - θ| <= τ` is
/// `u_a · s >= cos τ |s|`).
fn grow(field: &Field, used: &mut [bool], seed: (usize, usize), tolerance: f64) -> Region {
    let w = field.width;
    let [mut sx, mut sy] = field.unit[seed.1 * w + seed.0];
    let (cos_tol, mut norm) = (tolerance.cos(), 1.0f64);
    let mut pixels = vec![seed];
    used[seed.1 * w + seed.0] = true;
    let mut i = 0;
    while i < pixels.len() {
        let (px, py) = pixels[i];
        for yy in py.saturating_sub(1)..=(py + 1).min(field.height - 1) {
            for xx in px.saturating_sub(1)..=(px + 1).min(w - 1) {
                let j = yy * w + xx;
                if used[j] {
                    continue;
                }
                if field.angle[j].is_some() {
                    let [c, s] = field.unit[j];
                    if c * sx + s * sy >= cos_tol * norm {
                        used[j] = true;
                        pixels.push((xx, yy));
                        sx += c;
                        sy += s;
                        norm = (sx * sx + sy * sy).sqrt();
                    }
                }
            }
        }
        i += 1;
    }
    Region {
        pixels,
        angle: sy.atan2(sx),
    }
}

/// The rectangle approximating a region.
#[derive(Clone, Copy, Debug)]
struct Rect {
    centre: [f64; 2],
    theta: f64,
    l: [f64; 2],
    w: [f64; 2],
}

impl Rect {
    fn of(field: &Field, region: &Region, tolerance: f64) -> Self {
        let wsum: f64 = region
            .pixels
            .iter()
            .map(|&(x, y)| field.magnitude[y * field.width + x])
            .sum();
        let (mut cx, mut cy) = (0.0, 0.0);
        for &(x, y) in &region.pixels {
            let m = field.magnitude[y * field.width + x];
            cx += m * x as f64;
            cy += m * y as f64;
        }
        cx /= wsum;
        cy /= wsum;
        let (mut ixx, mut iyy, mut ixy) = (0.0, 0.0, 0.0);
        for &(x, y) in &region.pixels {
            let m = field.magnitude[y * field.width + x];
            let (dx, dy) = (x as f64 - cx, y as f64 - cy);
            ixx += m * dy * dy;
            iyy += m * dx * dx;
            ixy -= m * dx * dy;
        }
        let lambda = 0.5 * (ixx + iyy - ((ixx - iyy).powi(2) + 4.0 * ixy * ixy).sqrt());
        let mut theta = if ixx.abs() > iyy.abs() {
            (lambda - ixx).atan2(ixy)
        } else {
            ixy.atan2(lambda - iyy)
        };
        if angle_diff(theta, region.angle) > tolerance {
            theta += PI;
        }
        let (dx, dy) = (theta.cos(), theta.sin());
        let (mut l, mut w) = ([0f64, 0f64], [0f64, 0f64]);
        for &(x, y) in &region.pixels {
            let (ox, oy) = (x as f64 - cx, y as f64 - cy);
            let lv = ox * dx + oy * dy;
            let wv = -ox * dy + oy * dx;
            l = [l[0].min(lv), l[1].max(lv)];
            w = [w[0].min(wv), w[1].max(wv)];
        }
        Self {
            centre: [cx, cy],
            theta,
            l,
            w,
        }
    }

    fn length(&self) -> f64 {
        self.l[1] - self.l[0]
    }

    fn width(&self) -> f64 {
        (self.w[1] - self.w[0]).max(1.0)
    }

    /// log10 of the number of false alarms, counting the field's pixels inside the rectangle
    /// and those aligned with it.
    fn log_nfa(&self, field: &Field, tolerance: f64, log_nt: f64) -> f64 {
        let (dx, dy) = (self.theta.cos(), self.theta.sin());
        let half_w = self.width() / 2.0;
        let wmid = (self.w[0] + self.w[1]) / 2.0;
        let corners = [
            (self.l[0], wmid - half_w),
            (self.l[0], wmid + half_w),
            (self.l[1], wmid - half_w),
            (self.l[1], wmid + half_w),
        ]
        .map(|(l, w)| {
            (
                self.centre[0] + l * dx - w * dy,
                self.centre[1] + l * dy + w * dx,
            )
        });
        let x0 = corners.iter().map(|c| c.0).fold(f64::MAX, f64::min).floor() as isize;
        let x1 = corners.iter().map(|c| c.0).fold(f64::MIN, f64::max).ceil() as isize;
        let y0 = corners.iter().map(|c| c.1).fold(f64::MAX, f64::min).floor() as isize;
        let y1 = corners.iter().map(|c| c.1).fold(f64::MIN, f64::max).ceil() as isize;
        let (mut n, mut k) = (0u64, 0u64);
        for y in y0.max(0)..=y1.min(field.height as isize - 1) {
            for x in x0.max(0)..=x1.min(field.width as isize - 1) {
                let (ox, oy) = (x as f64 - self.centre[0], y as f64 - self.centre[1]);
                let lv = ox * dx + oy * dy;
                let wv = -ox * dy + oy * dx - wmid;
                if lv < self.l[0] - 0.5 || lv > self.l[1] + 0.5 || wv.abs() > half_w + 1e-9 {
                    continue;
                }
                n += 1;
                if let Some(a) = field.angle[y as usize * field.width + x as usize] {
                    if angle_diff(a, self.theta) <= tolerance {
                        k += 1;
                    }
                }
            }
        }
        log_nt + log10_binomial_tail(n, k, tolerance / PI)
    }
}

/// log10 of the binomial tail `P[X >= k]`, X ~ B(n, p) (the series of LSD's `nfa()`,
/// summed until its terms stop mattering).
fn log10_binomial_tail(n: u64, k: u64, p: f64) -> f64 {
    if k == 0 {
        return 0.0;
    }
    if k > n {
        return f64::NEG_INFINITY;
    }
    let (nf, kf) = (n as f64, k as f64);
    let log_term = |i: f64| {
        ln_gamma(nf + 1.0) - ln_gamma(i + 1.0) - ln_gamma(nf - i + 1.0)
            + i * p.ln()
            + (nf - i) * (1.0 - p).ln()
    };
    let first = log_term(kf);
    let mut sum = 1.0;
    let mut term = 1.0;
    let mut i = kf;
    while i < nf {
        // term(i+1) / term(i) = (n - i) / (i + 1) * p / (1 - p).
        term *= (nf - i) / (i + 1.0) * p / (1.0 - p);
        sum += term;
        i += 1.0;
        if term < 1e-12 * sum {
            break;
        }
    }
    (first + sum.ln()) / std::f64::consts::LN_10
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let s = G[0]
        + G[1..]
            .iter()
            .enumerate()
            .map(|(i, g)| g / (x + i as f64 + 1.0))
            .sum::<f64>();
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

/// Line segments of an image, longest first.
pub fn detect(img: &Gray, params: &DetectParams) -> Vec<Segment> {
    if img.width < 4 || img.height < 4 {
        return Vec::new();
    }
    let smooth = rescale(img, params.scale);
    let tau = params.angle_tolerance;
    let field = Field::new(&smooth, params.quantization / tau.sin());
    let (w, h) = (field.width, field.height);
    let log_nt = 2.5 * ((w as f64).log10() + (h as f64).log10()) + 11f64.log10();
    let p = tau / PI;
    let min_region = (-log_nt / p.log10()).ceil() as usize;

    // Pseudo-order: 1024 magnitude bins, strongest first, scan order inside a bin.
    let max_mag = field.magnitude.iter().copied().fold(0.0, f64::max);
    let mut bins: Vec<Vec<u32>> = vec![Vec::new(); 1024];
    for (i, m) in field.magnitude.iter().enumerate() {
        if field.angle[i].is_some() {
            let b = ((m / max_mag) * 1023.0) as usize;
            bins[1023 - b.min(1023)].push(i as u32);
        }
    }

    let mut used = vec![false; w * h];
    let mut out = Vec::new();
    for i in bins.into_iter().flatten() {
        let i = i as usize;
        if used[i] {
            continue;
        }
        let seed = (i % w, i / w);
        let mut region = grow(&field, &mut used, seed, tau);
        if region.pixels.len() < min_region {
            continue;
        }
        let mut rect = Rect::of(&field, &region, tau);
        if !refine(&field, &mut used, &mut region, &mut rect, seed, tau, params) {
            continue;
        }
        let log_nfa = rect.log_nfa(&field, tau, log_nt);
        if log_nfa >= 0.0 {
            continue;
        }
        let (dx, dy) = (rect.theta.cos(), rect.theta.sin());
        let wmid = (rect.w[0] + rect.w[1]) / 2.0;
        // The 2 x 2 mask's values sit at (x + 0.5, y + 0.5) of the scaled image.
        let end = |l: f64| {
            [
                (rect.centre[0] + l * dx - wmid * dy + 0.5) / params.scale,
                (rect.centre[1] + l * dy + wmid * dx + 0.5) / params.scale,
            ]
        };
        let seg = Segment {
            a: end(rect.l[0]),
            b: end(rect.l[1]),
            width: rect.width() / params.scale,
            significance: -log_nfa,
        };
        if seg.length() >= params.min_length {
            out.push(seg);
        }
    }
    out.sort_by(|a, b| b.length().total_cmp(&a.length()));
    out
}

/// LSD's refinement: while the rectangle holds too few region pixels, regrow from the seed
/// with a tolerance fitted to the angles near it, then shrink the region's radius. Returns
/// whether a dense enough region of at least two pixels remains.
fn refine(
    field: &Field,
    used: &mut [bool],
    region: &mut Region,
    rect: &mut Rect,
    seed: (usize, usize),
    tau: f64,
    params: &DetectParams,
) -> bool {
    let density =
        |r: &Region, rect: &Rect| r.pixels.len() as f64 / (rect.length().max(1.0) * rect.width());
    if density(region, rect) >= params.density {
        return true;
    }
    // A new tolerance: twice the spread of the angles of the pixels near the seed.
    let seed_angle = field.angle[seed.1 * field.width + seed.0].expect("seed");
    let near: Vec<f64> = region
        .pixels
        .iter()
        .filter(|&&(x, y)| {
            let (dx, dy) = (x as f64 - seed.0 as f64, y as f64 - seed.1 as f64);
            dx * dx + dy * dy < rect.width() * rect.width()
        })
        .filter_map(|&(x, y)| field.angle[y * field.width + x])
        .map(|a| (a - seed_angle + PI).rem_euclid(2.0 * PI) - PI)
        .collect();
    if near.len() >= 2 {
        let mean = near.iter().sum::<f64>() / near.len() as f64;
        let var = near.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / near.len() as f64;
        let new_tau = (2.0 * var.sqrt()).min(tau);
        for &(x, y) in &region.pixels {
            used[y * field.width + x] = false;
        }
        *region = grow(field, used, seed, new_tau.max(1e-3));
        if region.pixels.len() < 2 {
            return false;
        }
        *rect = Rect::of(field, region, tau);
        if density(region, rect) >= params.density {
            return true;
        }
    }
    // Shrink the region's radius around the seed.
    let mut radius = region
        .pixels
        .iter()
        .map(|&(x, y)| {
            let (dx, dy) = (x as f64 - seed.0 as f64, y as f64 - seed.1 as f64);
            dx * dx + dy * dy
        })
        .fold(0.0, f64::max)
        .sqrt();
    while density(region, rect) < params.density {
        radius *= 0.75;
        let (keep, drop): (Vec<_>, Vec<_>) = region.pixels.iter().partition(|&&(x, y)| {
            let (dx, dy) = (x as f64 - seed.0 as f64, y as f64 - seed.1 as f64);
            dx * dx + dy * dy <= radius * radius
        });
        for (x, y) in drop {
            used[y * field.width + x] = false;
        }
        region.pixels = keep;
        if region.pixels.len() < 2 {
            return false;
        }
        *rect = Rect::of(field, region, tau);
    }
    true
}

#[cfg(test)]
mod tests;
