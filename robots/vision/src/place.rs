//! Image-to-image matching of stereo key frames: the relative pose between the robot's current
//! frame and a past one (its own or another robot's), from interest points alone (seed 000,
//! Section V: "the image matching event recovers the relative transformation between the
//! current robot's pose and a past pose ... using also matches of interest points between
//! their respective frames"; the rendezvous is "emulated" the same way).
//!
//! A [`KeyFrame`] is the left image's stereo points (pixel, 3D position in the left optical
//! frame) with a rotation-invariant binary descriptor each, the bench's intrinsics and baseline.
//! It is what a robot keeps at each sub-map origin and sends over the radio
//! ([`KeyFrame::to_bytes`]: 52 bytes a point).
//!
//! **Descriptor** (ORB's steered BRIEF, Rublee et al. 2011): on the image smoothed by a 5 x 5
//! box, the patch's orientation is its intensity centroid's direction within a disk of radius
//! [`RADIUS`]; 256 intensity comparisons between point pairs drawn once from an isotropic
//! Gaussian (BRIEF's G II, σ = patch size / 5), rotated by that orientation, give 256 bits.
//! Rotating the image rotates the orientation with it, so the same bits come out: a
//! helicopter crossing its earlier leg the other way sees the ground turned 180 degrees, and
//! still matches.
//!
//! **Matching** ([`match_keyframes`]): each current point's nearest key-frame descriptor in
//! Hamming distance, kept if under [`MatchParams::max_distance`], clearly better than the
//! second nearest (Lowe's ratio) and mutual. Then RANSAC on three 3D-3D correspondences
//! (Kabsch) scored by reprojection into the current image, refined by Gauss-Newton
//! ([`crate::vo::estimate`]). Its covariance is that of the weighted least squares
//! (Gauss-Markov): each inlier's residual weighed by its pixel noise plus the key frame
//! point's stereo uncertainty (pixel and disparity noise through the triangulation),
//! projected into the current image.

use crate::stereo::StereoPoint;
use crate::vo::{estimate, Correspondence};
use crate::Gray;
use hetsim_msgs::Pinhole;
use hetsim_msgs::Pose;
use nalgebra::{Matrix2, Matrix2x3, Matrix3, Matrix3x6, Matrix6, Point3, Vector3};
use std::sync::OnceLock;

/// Radius of the descriptor's patch, pixels (ORB: a 31 x 31 patch).
pub const RADIUS: i64 = 13;

/// Bits of a descriptor.
const BITS: usize = 256;

/// A point of a key frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyPoint {
    /// Pixel in the left image.
    pub pixel: [f32; 2],
    /// 3D position in the left camera's optical frame, metres.
    pub point: [f32; 3],
    /// Steered BRIEF descriptor.
    pub descriptor: [u64; 4],
}

/// A stereo key frame: what image matching compares.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyFrame {
    /// The left camera's intrinsics.
    pub camera: Pinhole,
    /// The bench's baseline, metres.
    pub baseline_m: f64,
    /// Its points.
    pub points: Vec<KeyPoint>,
}

/// The 256 point pairs, drawn once (deterministically) from BRIEF's isotropic Gaussian.
fn pattern() -> &'static [[i8; 4]; BITS] {
    static PATTERN: OnceLock<[[i8; 4]; BITS]> = OnceLock::new();
    PATTERN.get_or_init(|| {
        // SplitMix64 and Box-Muller: no dependency on a generator's version.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let sigma = (2 * RADIUS + 1) as f64 / 5.0;
        let mut gauss = || loop {
            let (u, v) = (next().max(1e-300), next());
            let g = (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos() * sigma;
            if g.abs() <= (RADIUS - 1) as f64 / std::f64::consts::SQRT_2 {
                return g.round() as i8;
            }
        };
        let mut out = [[0i8; 4]; BITS];
        for p in out.iter_mut() {
            *p = [gauss(), gauss(), gauss(), gauss()];
        }
        out
    })
}

/// The image smoothed by a 5 x 5 box (borders: the mean of the pixels inside).
pub fn smooth(img: &Gray) -> Gray {
    let (w, h) = (img.width, img.height);
    let box_1d = |src: &[f32], n: usize, stride: usize, dst: &mut [f32]| {
        for i in 0..n {
            let (lo, hi) = (i.saturating_sub(2), (i + 2).min(n - 1));
            let s: f32 = (lo..=hi).map(|j| src[j * stride]).sum();
            dst[i * stride] = s / (hi - lo + 1) as f32;
        }
    };
    let mut rows = vec![0f32; w * h];
    for y in 0..h {
        box_1d(&img.data[y * w..], w, 1, &mut rows[y * w..]);
    }
    let mut out = vec![0f32; w * h];
    for x in 0..w {
        box_1d(&rows[x..], h, w, &mut out[x..]);
    }
    Gray {
        width: w,
        height: h,
        data: out,
    }
}

/// The steered BRIEF descriptor of the smoothed image `s` at `(x, y)`; `None` within
/// `RADIUS + 1` pixels of the border.
pub fn describe(s: &Gray, x: f64, y: f64) -> Option<[u64; 4]> {
    let (cx, cy) = (x.round() as i64, y.round() as i64);
    let margin = RADIUS + 1;
    if cx < margin || cy < margin || cx + margin >= s.width as i64 || cy + margin >= s.height as i64
    {
        return None;
    }
    let at = |dx: i64, dy: i64| s.data[((cy + dy) * s.width as i64 + cx + dx) as usize];
    // Intensity centroid over the disk.
    let (mut m10, mut m01) = (0f64, 0f64);
    for dy in -RADIUS..=RADIUS {
        let half = ((RADIUS * RADIUS - dy * dy) as f64).sqrt() as i64;
        for dx in -half..=half {
            let v = at(dx, dy) as f64;
            m10 += dx as f64 * v;
            m01 += dy as f64 * v;
        }
    }
    let theta = m01.atan2(m10);
    let (c, s) = (theta.cos(), theta.sin());
    let rot = |px: i8, py: i8| {
        let (px, py) = (px as f64, py as f64);
        (
            (c * px - s * py).round() as i64,
            (s * px + c * py).round() as i64,
        )
    };
    let mut d = [0u64; 4];
    for (i, p) in pattern().iter().enumerate() {
        let (ax, ay) = rot(p[0], p[1]);
        let (bx, by) = rot(p[2], p[3]);
        if at(ax, ay) < at(bx, by) {
            d[i / 64] |= 1 << (i % 64);
        }
    }
    Some(d)
}

/// Hamming distance of two descriptors.
pub fn hamming(a: &[u64; 4], b: &[u64; 4]) -> u32 {
    a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
}

impl KeyFrame {
    /// The key frame of a left image and its stereo points (those near the border, without a
    /// descriptor, are left out).
    pub fn new(left: &Gray, camera: Pinhole, baseline_m: f64, stereo: &[StereoPoint]) -> Self {
        let s = smooth(left);
        let points = stereo
            .iter()
            .filter_map(|q| {
                describe(&s, q.left[0], q.left[1]).map(|descriptor| KeyPoint {
                    pixel: [q.left[0] as f32, q.left[1] as f32],
                    point: [q.point.x as f32, q.point.y as f32, q.point.z as f32],
                    descriptor,
                })
            })
            .collect();
        Self {
            camera,
            baseline_m,
            points,
        }
    }

    /// The median depth of its points, metres (0 without points).
    pub fn median_depth(&self) -> f64 {
        let mut z: Vec<f32> = self.points.iter().map(|p| p.point[2]).collect();
        z.sort_by(f32::total_cmp);
        z.get(z.len() / 2).map_or(0.0, |v| *v as f64)
    }

    /// Little-endian bytes: the camera (4 f64), the baseline (f64), the number of points
    /// (u32), then per point the pixel (2 f32), the 3D point (3 f32) and the descriptor
    /// (4 u64).
    pub fn to_bytes(&self) -> Vec<u8> {
        let c = &self.camera;
        let mut out = Vec::with_capacity(44 + 52 * self.points.len());
        for v in [c.alpha_u, c.alpha_v, c.u0, c.v0, self.baseline_m] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(self.points.len() as u32).to_le_bytes());
        for p in &self.points {
            for v in p.pixel.iter().chain(&p.point) {
                out.extend_from_slice(&v.to_le_bytes());
            }
            for v in &p.descriptor {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out
    }

    /// Reads [`KeyFrame::to_bytes`]'s layout; `None` if the bytes do not hold exactly one, or
    /// hold numbers that are not finite, a camera or baseline that is not positive, or a point
    /// that is not in front of the camera.
    pub fn from_bytes(b: &[u8]) -> Option<Self> {
        let f64_at = |i: usize| Some(f64::from_le_bytes(b.get(i..i + 8)?.try_into().ok()?));
        let f32_at = |i: usize| Some(f32::from_le_bytes(b.get(i..i + 4)?.try_into().ok()?));
        let u64_at = |i: usize| Some(u64::from_le_bytes(b.get(i..i + 8)?.try_into().ok()?));
        let n = u32::from_le_bytes(b.get(40..44)?.try_into().ok()?) as usize;
        if b.len() != 44 + 52 * n {
            return None;
        }
        let camera = Pinhole {
            alpha_u: f64_at(0)?,
            alpha_v: f64_at(8)?,
            u0: f64_at(16)?,
            v0: f64_at(24)?,
        };
        let baseline_m = f64_at(32)?;
        let points = (0..n)
            .map(|k| {
                let o = 44 + 52 * k;
                Some(KeyPoint {
                    pixel: [f32_at(o)?, f32_at(o + 4)?],
                    point: [f32_at(o + 8)?, f32_at(o + 12)?, f32_at(o + 16)?],
                    descriptor: [
                        u64_at(o + 20)?,
                        u64_at(o + 28)?,
                        u64_at(o + 36)?,
                        u64_at(o + 44)?,
                    ],
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let finite = [
            camera.alpha_u,
            camera.alpha_v,
            camera.u0,
            camera.v0,
            baseline_m,
        ]
        .iter()
        .all(|v| v.is_finite())
            && points
                .iter()
                .all(|p| p.pixel.iter().chain(&p.point).all(|v| v.is_finite()));
        // A real camera and baseline, points in front of it: anything else would make the
        // matcher's geometry meaningless (an infinite footprint, a link that is not a number).
        let real = camera.alpha_u > 0.0
            && camera.alpha_v > 0.0
            && baseline_m > 0.0
            && points.iter().all(|p| p.point[2] > 0.0);
        (finite && real).then_some(Self {
            camera,
            baseline_m,
            points,
        })
    }
}

/// Tuning of [`match_keyframes`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MatchParams {
    /// Largest Hamming distance of a descriptor match (of 256 bits).
    pub max_distance: u32,
    /// Lowe's ratio: the nearest at most this fraction of the second nearest.
    pub ratio: f64,
    /// RANSAC hypotheses.
    pub iterations: usize,
    /// Reprojection error of an inlier, pixels.
    pub inlier_px: f64,
    /// Inliers needed to accept the relative pose.
    pub min_inliers: usize,
    /// Noise of a matched interest point's position, pixels (1σ).
    pub sigma_px: f64,
    /// Noise of a stereo disparity, pixels (1σ).
    pub sigma_disparity_px: f64,
}

impl Default for MatchParams {
    fn default() -> Self {
        Self {
            max_distance: 64,
            ratio: 0.8,
            iterations: 400,
            inlier_px: 3.0,
            min_inliers: 20,
            sigma_px: 1.0,
            sigma_disparity_px: 0.5,
        }
    }
}

/// A relative pose found by image matching.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaceMatch {
    /// The current left optical frame from the key frame's: maps the key frame's points into
    /// the current frame.
    pub current_from_keyframe: Pose,
    /// Covariance of `ξ` (translation, rotation) of a left perturbation `exp(ξ) T`.
    pub covariance: Matrix6<f64>,
    /// Descriptor matches.
    pub matches: usize,
    /// RANSAC inliers after refinement.
    pub inliers: usize,
}

/// Why a key frame did not match.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoMatch {
    /// Fewer descriptor matches than the inliers needed.
    TooFewMatches(usize),
    /// RANSAC found no pose with enough inliers (the matches found).
    TooFewInliers(usize),
}

/// Mutual nearest descriptors passing the distance and ratio tests: `(key-frame point,
/// current point)` indices.
fn descriptor_matches(kf: &KeyFrame, current: &KeyFrame, p: &MatchParams) -> Vec<(usize, usize)> {
    let nearest = |d: &[u64; 4], set: &[KeyPoint]| {
        let (mut best, mut second) = ((u32::MAX, usize::MAX), u32::MAX);
        for (i, q) in set.iter().enumerate() {
            let h = hamming(d, &q.descriptor);
            if h < best.0 {
                second = best.0;
                best = (h, i);
            } else if h < second {
                second = h;
            }
        }
        (best, second)
    };
    current
        .points
        .iter()
        .enumerate()
        .filter_map(|(c, cp)| {
            let ((h, k), second) = nearest(&cp.descriptor, &kf.points);
            let good = h <= p.max_distance && (h as f64) < p.ratio * second as f64;
            let mutual = good && nearest(&kf.points[k].descriptor, &current.points).0 .1 == c;
            mutual.then_some((k, c))
        })
        .collect()
}

/// The covariance of a key-frame point from its stereo triangulation: pixel noise on `u`,
/// `v` and disparity noise on `d`, through `P = b (u - u0, (αu/αv)(v - v0), αu) / d`.
fn stereo_covariance(kf: &KeyFrame, p: &KeyPoint, params: &MatchParams) -> Matrix3<f64> {
    let (c, b) = (&kf.camera, kf.baseline_m);
    let z = p.point[2] as f64;
    let d = c.alpha_u * b / z;
    let (u, v) = (p.pixel[0] as f64 - c.u0, p.pixel[1] as f64 - c.v0);
    let r = c.alpha_u / c.alpha_v;
    let g = Matrix3::new(
        b / d,
        0.0,
        -b * u / (d * d),
        0.0,
        b * r / d,
        -b * r * v / (d * d),
        0.0,
        0.0,
        -c.alpha_u * b / (d * d),
    );
    let s = Matrix3::from_diagonal(&Vector3::new(
        params.sigma_px.powi(2),
        params.sigma_px.powi(2),
        params.sigma_disparity_px.powi(2),
    ));
    g * s * g.transpose()
}

/// Matches the key frame `kf` against the `current` one (both from [`KeyFrame::new`]; the
/// current one's camera is the one projected into) and estimates `current_from_keyframe`.
pub fn match_keyframes(
    kf: &KeyFrame,
    current: &KeyFrame,
    params: &MatchParams,
    rng: &mut impl rand::Rng,
) -> Result<PlaceMatch, NoMatch> {
    let pairs = descriptor_matches(kf, current, params);
    if pairs.len() < params.min_inliers.max(3) {
        return Err(NoMatch::TooFewMatches(pairs.len()));
    }
    let v3 = |p: [f32; 3]| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    let data: Vec<Correspondence> = pairs
        .iter()
        .map(|&(k, c)| Correspondence {
            previous: v3(kf.points[k].point),
            current: v3(current.points[c].point),
            pixel: [
                current.points[c].pixel[0] as f64,
                current.points[c].pixel[1] as f64,
            ],
        })
        .collect();
    let cam = &current.camera;
    let found = estimate(
        cam,
        &data,
        params.iterations,
        params.inlier_px,
        params.min_inliers,
        rng,
    )
    .ok_or(NoMatch::TooFewInliers(pairs.len()))?;
    let t = found.current_from_previous;
    // Gauss-Markov covariance of the refined pose over its inliers.
    let mut info = Matrix6::zeros();
    let mut inliers = 0;
    for (&(k, _), c) in pairs.iter().zip(&data) {
        let p = t * Point3::from(c.previous);
        let Some(uv) = cam.project(&p.coords) else {
            continue;
        };
        if (uv[0] - c.pixel[0]).hypot(uv[1] - c.pixel[1]) >= params.inlier_px {
            continue;
        }
        inliers += 1;
        let jp = cam.project_jacobian(&p.coords);
        let jp = Matrix2x3::new(jp[0][0], jp[0][1], jp[0][2], jp[1][0], jp[1][1], jp[1][2]);
        let mut dp = Matrix3x6::zeros();
        dp.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::identity());
        dp.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&-crate::vo::skew(&p.coords));
        let j = jp * dp;
        let jpoint = jp * t.rotation.to_rotation_matrix().into_inner();
        let r = Matrix2::identity() * params.sigma_px.powi(2)
            + jpoint * stereo_covariance(kf, &kf.points[k], params) * jpoint.transpose();
        let Some(w) = r.try_inverse() else { continue };
        info += j.transpose() * w * j;
    }
    if inliers < params.min_inliers {
        return Err(NoMatch::TooFewInliers(pairs.len()));
    }
    let covariance = info
        .try_inverse()
        .ok_or(NoMatch::TooFewInliers(pairs.len()))?;
    Ok(PlaceMatch {
        current_from_keyframe: t,
        covariance: (covariance + covariance.transpose()) * 0.5,
        matches: pairs.len(),
        inliers,
    })
}

#[cfg(test)]
mod tests;
