//! Frame-to-frame motion of a stereo bench from matched 3D points.
//!
//! Points triangulated at the previous frame are matched in the current left image (and
//! triangulated again there). RANSAC draws three correspondences, fits the rigid motion
//! (Kabsch), and counts the points whose reprojection into the current image falls within
//! `inlier_px`; the best hypothesis is refined by Gauss-Newton on the reprojection errors of
//! its inliers. The covariance of the motion is `σ² (JᵀJ)⁻¹`, σ² the residual variance,
//! expressed on a left perturbation `exp(ξ) T` with `ξ = (ρ, φ)` (translation, rotation).

use hetsim_msgs::Pinhole;
use hetsim_msgs::Pose;
use nalgebra::{
    Isometry3, Matrix3, Matrix6, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6,
};
use rand::RngExt;

/// One correspondence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correspondence {
    /// The point in the previous left camera frame.
    pub previous: Vector3<f64>,
    /// The point in the current left camera frame (from stereo), if triangulated.
    pub current: Vector3<f64>,
    /// Where it was matched in the current left image.
    pub pixel: [f64; 2],
}

/// An estimated motion.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// `current_from_previous`: maps previous-frame coordinates into the current frame.
    pub current_from_previous: Pose,
    /// Covariance of `ξ` (translation, rotation) of a left perturbation of the motion.
    pub covariance: Matrix6<f64>,
    /// Inliers used in the refinement.
    pub inliers: usize,
    /// Root-mean-square reprojection error of the inliers, pixels.
    pub rms_px: f64,
}

/// The rigid motion best mapping `a` onto `b` (least squares, Kabsch/Umeyama without scale).
pub fn kabsch(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Option<Pose> {
    if a.len() < 3 || a.len() != b.len() {
        return None;
    }
    let n = a.len() as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p - ca) * (q - cb).transpose())
        .sum();
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let t = cb - rot * ca;
    Some(Isometry3::from_parts(Translation3::from(t), rot))
}

/// The cross-product matrix `[v]x`.
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

fn residual(cam: &Pinhole, t: &Pose, c: &Correspondence) -> Option<[f64; 2]> {
    let p = t * nalgebra::Point3::from(c.previous);
    cam.project(&p.coords)
        .map(|[u, v]| [u - c.pixel[0], v - c.pixel[1]])
}

/// Estimates the motion; `None` with fewer than `min_inliers` inliers.
pub fn estimate(
    cam: &Pinhole,
    data: &[Correspondence],
    iterations: usize,
    inlier_px: f64,
    min_inliers: usize,
    rng: &mut impl rand::Rng,
) -> Option<Motion> {
    if data.len() < 3 {
        return None;
    }
    let count = |t: &Pose| {
        data.iter()
            .filter(|c| residual(cam, t, c).is_some_and(|r| r[0].hypot(r[1]) < inlier_px))
            .count()
    };
    let mut best: Option<(usize, Pose)> = None;
    for _ in 0..iterations {
        let i = rng.random_range(0..data.len());
        let j = rng.random_range(0..data.len());
        let k = rng.random_range(0..data.len());
        if i == j || j == k || i == k {
            continue;
        }
        let a = [data[i].previous, data[j].previous, data[k].previous];
        let b = [data[i].current, data[j].current, data[k].current];
        let Some(t) = kabsch(&a, &b) else { continue };
        let n = count(&t);
        if best.as_ref().is_none_or(|(m, _)| n > *m) {
            best = Some((n, t));
        }
    }
    let (_, mut t) = best?;
    let mut inliers: Vec<&Correspondence> = Vec::new();
    let mut jtj = Matrix6::zeros();
    let mut sum_sq = 0.0;
    for _ in 0..8 {
        inliers = data
            .iter()
            .filter(|c| residual(cam, &t, c).is_some_and(|r| r[0].hypot(r[1]) < inlier_px))
            .collect();
        if inliers.len() < min_inliers.max(3) {
            return None;
        }
        jtj = Matrix6::zeros();
        let mut jtr = Vector6::zeros();
        sum_sq = 0.0;
        for c in &inliers {
            let p = t * nalgebra::Point3::from(c.previous);
            let Some(r) = residual(cam, &t, c) else {
                continue;
            };
            let jp = cam.project_jacobian(&p.coords);
            // d p / d xi for p' = exp(xi) p: [I, -[p]x].
            let dp = {
                let mut m = nalgebra::Matrix3x6::zeros();
                m.fixed_view_mut::<3, 3>(0, 0)
                    .copy_from(&Matrix3::identity());
                m.fixed_view_mut::<3, 3>(0, 3)
                    .copy_from(&(-skew(&p.coords)));
                m
            };
            let jpm = nalgebra::Matrix2x3::new(
                jp[0][0], jp[0][1], jp[0][2], jp[1][0], jp[1][1], jp[1][2],
            );
            let j = jpm * dp;
            let rv = nalgebra::Vector2::new(r[0], r[1]);
            jtj += j.transpose() * j;
            jtr += j.transpose() * rv;
            sum_sq += r[0] * r[0] + r[1] * r[1];
        }
        let step = jtj.cholesky().map(|ch| ch.solve(&(-jtr)))?;
        let delta = Isometry3::from_parts(
            Translation3::new(step[0], step[1], step[2]),
            UnitQuaternion::from_scaled_axis(Vector3::new(step[3], step[4], step[5])),
        );
        t = delta * t;
        if step.norm() < 1e-10 {
            break;
        }
    }
    let dof = (2 * inliers.len()).saturating_sub(6).max(1) as f64;
    let sigma2 = sum_sq / dof;
    let covariance = jtj.try_inverse()? * sigma2.max(1e-6);
    Some(Motion {
        current_from_previous: t,
        covariance,
        inliers: inliers.len(),
        rms_px: (sum_sq / inliers.len().max(1) as f64).sqrt(),
    })
}

/// Stereo visual odometry, frame to frame.
///
/// Each stereo pair: Harris corners of the left image (3 x 3 partition, `per_region` each)
/// are triangulated with the right image; the previous frame's points are predicted into the
/// new left image with the previous motion (constant velocity) and matched by ZNCC inside an
/// ellipse of `search_px` pixels (1σ) around each prediction; the motion is estimated from
/// those correspondences. Until a motion is known (first frames, or after a failure) the
/// search is five times wider; a pair the narrow search fails on is searched again five
/// times wider before it is given up.
///
/// Two savings keep a 1024 x 768 pair within its time: the ellipse is searched coarse to
/// fine (at half resolution, then within 2 px at full resolution), and stereo matching
/// searches the disparities the last frame's points spanned (halved and one and a half
/// times, plus margins) rather than the whole depth range, which it searches every
/// `full_stereo_every` frames and after a loss, so nearer or farther structure coming into
/// view is found again. The narrower window also narrows stereo's ambiguity and left-right
/// checks: repetitive texture whose rival peak lies outside it no longer rejects a match
/// (RANSAC then has to).
pub struct StereoVo {
    bench: crate::stereo::Bench,
    previous: Option<Vec<(crate::matching::Template, Vector3<f64>)>>,
    velocity: Pose,
    /// No motion estimate yet, or the last one failed: search wider.
    lost: bool,
    /// Corners kept per 3 x 3 region.
    pub per_region: usize,
    /// Search ellipse radius, pixels (1σ).
    pub search_px: f64,
    /// Depth range triangulated, metres.
    pub depth_range_m: [f64; 2],
    /// Frames between stereo searches over the whole depth range.
    pub full_stereo_every: u64,
    corners: Vec<crate::harris::Corner>,
    max_response: f32,
    /// The last left image at half resolution.
    half: Option<crate::Gray>,
    /// Disparities the last frame's points spanned, pixels.
    disparities: Option<[f64; 2]>,
    /// The last frame's stereo points.
    points: Vec<crate::stereo::StereoPoint>,
    frames: u64,
}

impl StereoVo {
    /// VO for a rectified bench.
    pub fn new(bench: crate::stereo::Bench) -> Self {
        Self {
            bench,
            previous: None,
            velocity: Pose::identity(),
            lost: true,
            per_region: 25,
            search_px: 6.0,
            depth_range_m: [0.5, 120.0],
            full_stereo_every: 10,
            corners: Vec::new(),
            max_response: 0.0,
            half: None,
            disparities: None,
            points: Vec::new(),
            frames: 0,
        }
    }

    /// The last left image at half resolution (for a caller's [`crate::matching::Template`]s
    /// and [`crate::matching::search_pyramid`]).
    pub fn half(&self) -> Option<&crate::Gray> {
        self.half.as_ref()
    }

    /// The Harris corners of the last left image (response at least 0.005 of its largest),
    /// strongest first, and that largest response: a caller wanting a higher threshold
    /// filters them rather than detecting again.
    pub fn corners(&self) -> (&[crate::harris::Corner], f32) {
        (&self.corners, self.max_response)
    }

    /// The stereo points of the last pair (pixel in the left image, 3D point in its optical
    /// frame): what a key frame is made of ([`crate::place::KeyFrame::new`]).
    pub fn points(&self) -> &[crate::stereo::StereoPoint] {
        &self.points
    }

    /// Processes a stereo pair; returns the motion since the previous pair (`None` for the
    /// first pair or when tracking fails).
    pub fn process(
        &mut self,
        left: &crate::Gray,
        right: &crate::Gray,
        rng: &mut impl rand::Rng,
    ) -> Option<Motion> {
        use crate::harris::{detect_with_max, select_new};
        use crate::matching::Template;
        (self.corners, self.max_response) = detect_with_max(left, 0.005, 8);
        let corners = &self.corners;
        let chosen = select_new(corners, left.width, left.height, &[], self.per_region, 8.0);
        let points = crate::stereo::match_stereo(
            left,
            right,
            &self.bench,
            &chosen,
            self.stereo_depths(),
            0.85,
        );
        self.frames += 1;
        let half = left.half();
        let mut motion = None;
        if let Some(prev) = &self.previous {
            // Without a trusted velocity the prediction is poor: search five times wider.
            // With one, a sudden change of motion (a helicopter starting a 30 deg/s turn:
            // image edges 25 px off the prediction) can leave the narrow search with too few
            // matches; the same pair is then searched again five times wider rather than
            // lost, since a lost pair's motion is never recovered (measured: the village's
            // Ressac lost the pair at the start of its first turn, and with it 3.6 deg of
            // tilt that its estimate kept for the rest of the flight).
            let wide = 5.0 * self.search_px;
            let first = if self.lost { wide } else { self.search_px };
            motion = self.track(prev, left, &half, &points, first, rng);
            if motion.is_none() && !self.lost {
                motion = self.track(prev, left, &half, &points, wide, rng);
            }
            self.lost = motion.is_none();
            if let Some(m) = &motion {
                self.velocity = m.current_from_previous;
            }
        }
        self.disparities = points.iter().map(|q| q.disparity).fold(None, |r, d| {
            Some(r.map_or([d, d], |[lo, hi]: [f64; 2]| [lo.min(d), hi.max(d)]))
        });
        self.previous = Some(
            points
                .iter()
                .filter_map(|q| {
                    let (x, y) = (q.left[0] as usize, q.left[1] as usize);
                    Template::at(left, &half, x, y).map(|t| (t, q.point))
                })
                .collect(),
        );
        self.half = Some(half);
        self.points = points;
        motion
    }

    /// Matches the previous pair's points in `left` inside ellipses of `sigma` pixels (1σ)
    /// around their constant-velocity predictions, pairs each with the stereo point found at
    /// the match, and estimates the motion from them.
    fn track(
        &self,
        prev: &[(crate::matching::Template, Vector3<f64>)],
        left: &crate::Gray,
        half: &crate::Gray,
        points: &[crate::stereo::StereoPoint],
        sigma: f64,
        rng: &mut impl rand::Rng,
    ) -> Option<Motion> {
        let cam = self.bench.camera;
        let s = sigma * sigma;
        let ellipse = [[s, 0.0], [0.0, s]];
        let mut data = Vec::new();
        for (template, p) in prev {
            let predicted = self.velocity * nalgebra::Point3::from(*p);
            let Some(uv) = cam.project(&predicted.coords) else {
                continue;
            };
            let Some(m) =
                crate::matching::search_pyramid(left, half, template, uv, ellipse, 9.21, 0.8, 3.0)
            else {
                continue;
            };
            // The point's 3D position now: a stereo point triangulated at the match.
            let Some(near) = points.iter().find(|q| {
                let (dx, dy) = (q.left[0] - m.x, q.left[1] - m.y);
                dx * dx + dy * dy < 1.5 * 1.5
            }) else {
                continue;
            };
            data.push(Correspondence {
                previous: *p,
                current: near.point,
                pixel: [m.x, m.y],
            });
        }
        estimate(&cam, &data, 150, 2.0, 12, rng)
    }

    /// The depths stereo matching searches this frame: the whole range on the first frame,
    /// after a loss and every `full_stereo_every` frames; otherwise the disparities of the
    /// last frame's points from half their least - 2 px to one and a half their largest
    /// + 4 px.
    fn stereo_depths(&self) -> [f64; 2] {
        let [z_min, z_max] = self.depth_range_m;
        let f = self.bench.camera.alpha_u * self.bench.baseline_m;
        match self.disparities {
            Some([lo, hi]) if !self.lost && self.frames % self.full_stereo_every != 0 => {
                let d_lo = (0.5 * lo - 2.0).max(f / z_max);
                let d_hi = (1.5 * hi + 4.0).min(f / z_min);
                [f / d_hi, f / d_lo]
            }
            _ => [z_min, z_max],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr_free::normal;

    /// Box-Muller, to keep this crate's dependencies small.
    mod rand_distr_free {
        use rand::RngExt;
        pub fn normal(rng: &mut impl rand::Rng) -> f64 {
            let u1: f64 = rng.random_range(1e-12..1.0);
            let u2: f64 = rng.random_range(0.0..1.0);
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    #[test]
    fn recovers_a_known_motion_despite_outliers_with_a_sensible_covariance() {
        let cam = Pinhole {
            alpha_u: 600.0,
            alpha_v: 600.0,
            u0: 320.0,
            v0: 240.0,
        };
        let truth: Pose = Isometry3::from_parts(
            Translation3::new(0.05, -0.02, -0.4),
            UnitQuaternion::from_euler_angles(0.01, -0.03, 0.02),
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut data = Vec::new();
        for k in 0..200 {
            let prev = Vector3::new(
                rng.random_range(-8.0..8.0),
                rng.random_range(-4.0..4.0),
                rng.random_range(4.0..30.0),
            );
            let cur = truth * nalgebra::Point3::from(prev);
            let Some([u, v]) = cam.project(&cur.coords) else {
                continue;
            };
            let noise = [0.3 * normal(&mut rng), 0.3 * normal(&mut rng)];
            let mut c = Correspondence {
                previous: prev,
                current: cur.coords + Vector3::new(0.0, 0.0, 0.02 * cur.z * normal(&mut rng)),
                pixel: [u + noise[0], v + noise[1]],
            };
            if k % 5 == 0 {
                c.pixel = [rng.random_range(0.0..640.0), rng.random_range(0.0..480.0)];
                // 20 % outliers
            }
            data.push(c);
        }
        let m = estimate(&cam, &data, 200, 2.0, 20, &mut rng).unwrap();
        let err = m.current_from_previous.inverse() * truth;
        assert!(
            err.translation.vector.norm() < 0.02,
            "translation error {}",
            err.translation.vector.norm()
        );
        assert!(
            err.rotation.angle() < 0.002,
            "rotation error {}",
            err.rotation.angle()
        );
        assert!(
            m.inliers >= 150 && m.inliers <= 165,
            "{} inliers of ~160 good",
            m.inliers
        );
        assert!(
            (m.rms_px - 0.3 * std::f64::consts::SQRT_2).abs() < 0.1,
            "rms {}",
            m.rms_px
        );
        assert!(m.covariance.cholesky().is_some(), "positive definite");
        // The true error lies within a plausible multiple of the estimated spread.
        assert!(m.covariance[(2, 2)].sqrt() < 0.05 && m.covariance[(2, 2)].sqrt() > 1e-4);
    }

    #[test]
    fn kabsch_is_exact_without_noise() {
        let t: Pose = Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 3.0),
            UnitQuaternion::from_euler_angles(0.3, -0.4, 1.0),
        );
        let a: Vec<Vector3<f64>> = (0..10)
            .map(|i| Vector3::new(i as f64, (i * i) as f64 * 0.1, (i % 3) as f64))
            .collect();
        let b: Vec<Vector3<f64>> = a
            .iter()
            .map(|p| (t * nalgebra::Point3::from(*p)).coords)
            .collect();
        let k = kabsch(&a, &b).unwrap();
        assert!((k.translation.vector - t.translation.vector).norm() < 1e-9);
        assert!(k.rotation.angle_to(&t.rotation) < 1e-9);
    }
}
