//! Model-driven tracking of a segment: the prediction from its 3D estimate, edge points searched along its normal, a robust line fit, the ends extended while the edge goes on.

use super::*;

/// The image of the 3D segment `p`-`q` (in the frame `world`, seen from a camera whose optical
/// frame is at `world_from_camera`), clipped to `near` metres in front of the camera. `None`
/// when the whole segment is behind that plane.
pub fn project_segment(
    camera: &Pinhole,
    world_from_camera: &Isometry3<f64>,
    p: &Point3<f64>,
    q: &Point3<f64>,
    near: f64,
) -> Option<Segment> {
    let (mut a, mut b) = (
        world_from_camera.inverse_transform_point(p).coords,
        world_from_camera.inverse_transform_point(q).coords,
    );
    if a.z < near && b.z < near {
        return None;
    }
    let clip = |inside: Vector3<f64>, outside: Vector3<f64>| {
        let t = (near - inside.z) / (outside.z - inside.z);
        inside + (outside - inside) * t
    };
    if a.z < near {
        a = clip(b, a);
    } else if b.z < near {
        b = clip(a, b);
    }
    Some(Segment::new(camera.project(&a)?, camera.project(&b)?))
}

/// Parameters of [`track`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackParams {
    /// Half length of the search along the predicted segment's normal, pixels.
    pub search_px: f64,
    /// Spacing of the edge samples along the predicted segment, pixels.
    pub spacing_px: f64,
    /// Largest angle between an edge point's gradient and the predicted normal, radians.
    pub angle_tolerance: f64,
    /// Smallest gradient magnitude of an edge point, grey levels per pixel.
    pub min_gradient: f64,
    /// Residual beyond which an edge point is rejected from the line fit, pixels.
    pub inlier_px: f64,
    /// Smallest fraction of the samples that must support the fitted line.
    pub min_support: f64,
}

impl Default for TrackParams {
    fn default() -> Self {
        Self {
            search_px: 12.0,
            spacing_px: 4.0,
            angle_tolerance: 30f64.to_radians(),
            min_gradient: 6.0,
            inlier_px: 1.5,
            min_support: 0.5,
        }
    }
}

/// Central-difference gradient of the image at a sub-pixel position.
fn gradient(img: &Gray, x: f64, y: f64) -> Option<Vector2<f64>> {
    let gx = img.sample(x + 1.0, y)? as f64 - img.sample(x - 1.0, y)? as f64;
    let gy = img.sample(x, y + 1.0)? as f64 - img.sample(x, y - 1.0)? as f64;
    Some(Vector2::new(gx, gy) / 2.0)
}

/// The edge point nearest `p` along `normal` (within `reach` pixels each side) whose
/// gradient agrees with the normal: the sub-pixel maximum of the gradient's component along
/// the normal.
fn edge_along(
    img: &Gray,
    p: [f64; 2],
    normal: Vector2<f64>,
    reach: f64,
    params: &TrackParams,
) -> Option<[f64; 2]> {
    let steps = (reach * 2.0).round() as i64;
    let at = |k: i64| {
        let t = k as f64 * 0.5;
        let (x, y) = (p[0] + t * normal.x, p[1] + t * normal.y);
        gradient(img, x, y).map(|g| (g.dot(&normal), g.norm()))
    };
    let values: Vec<Option<(f64, f64)>> = (-steps - 1..=steps + 1).map(at).collect();
    let mut best: Option<(i64, f64)> = None;
    for k in -steps..=steps {
        let i = (k + steps + 1) as usize;
        let Some((along, norm)) = values[i] else {
            continue;
        };
        if norm < params.min_gradient || along < norm * params.angle_tolerance.cos() {
            continue;
        }
        let (prev, next) = (values[i - 1].map(|v| v.0), values[i + 1].map(|v| v.0));
        if prev.is_some_and(|v| v > along) || next.is_some_and(|v| v > along) {
            continue;
        }
        // Nearest to the prediction among the local maxima, ties to the stronger.
        let better = match best {
            None => true,
            Some((bk, bv)) => k.abs() < bk.abs() || (k.abs() == bk.abs() && along > bv),
        };
        if better {
            best = Some((k, along));
        }
    }
    let (k, v0) = best?;
    let i = (k + steps + 1) as usize;
    let (vm, vp) = (values[i - 1]?.0, values[i + 1]?.0);
    let denom = vm - 2.0 * v0 + vp;
    let offset = if denom < 0.0 {
        (0.5 * (vm - vp) / denom).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    let t = (k as f64 + offset) * 0.5;
    Some([p[0] + t * normal.x, p[1] + t * normal.y])
}

/// Total least-squares line through points: a point on it and its unit direction.
fn fit_line(points: &[[f64; 2]]) -> Option<(Vector2<f64>, Vector2<f64>)> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let c = points
        .iter()
        .fold(Vector2::zeros(), |acc, p| acc + Vector2::new(p[0], p[1]))
        / n;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - c.x, p[1] - c.y);
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some((c, Vector2::new(theta.cos(), theta.sin())))
}

/// Tracks a segment in `img` from its predicted image `predicted` (whose direction carries
/// the expected polarity). Returns the observed segment, with endpoints extended along the
/// edge where it goes on beyond the prediction, or `None` when too few edge points support a
/// line.
pub fn track(img: &Gray, predicted: &Segment, params: &TrackParams) -> Option<Segment> {
    let len = predicted.length();
    if len < 2.0 * params.spacing_px {
        return None;
    }
    let d = predicted.direction();
    // The gradient points to the left of the direction: the normal (d.y, -d.x) in image
    // coordinates (y down) is that side.
    let normal = Vector2::new(d.y, -d.x);
    let samples = (len / params.spacing_px).floor() as usize;
    let mut points = Vec::with_capacity(samples + 1);
    for k in 0..=samples {
        let s = len * k as f64 / samples as f64;
        if let Some(p) = edge_along(img, predicted.at(s), normal, params.search_px, params) {
            points.push(p);
        }
    }
    // Fit, reject the outliers, refit.
    let mut line = fit_line(&points)?;
    for _ in 0..3 {
        let (c, u) = line;
        let keep: Vec<[f64; 2]> = points
            .iter()
            .copied()
            .filter(|p| ((p[1] - c.y) * u.x - (p[0] - c.x) * u.y).abs() <= params.inlier_px)
            .collect();
        if keep.len() < 2 {
            return None;
        }
        points = keep;
        line = fit_line(&points)?;
    }
    if (points.len() as f64) < params.min_support * (samples + 1) as f64 {
        return None;
    }
    let (c, mut u) = line;
    if u.dot(&d) < 0.0 {
        u = -u;
    }
    let s: Vec<f64> = points
        .iter()
        .map(|p| (p[0] - c.x) * u.x + (p[1] - c.y) * u.y)
        .collect();
    let (mut s0, mut s1) = (
        s.iter().copied().fold(f64::MAX, f64::min),
        s.iter().copied().fold(f64::MIN, f64::max),
    );
    // Extend each end while the edge goes on (two misses in a row stop it).
    let n = Vector2::new(u.y, -u.x);
    let on_edge = |t: f64| {
        let p = c + u * t;
        edge_along(img, [p.x, p.y], n, 1.0, params).is_some()
    };
    for (end, sign) in [(&mut s1, 1.0), (&mut s0, -1.0)] {
        let mut misses = 0;
        let mut t = *end;
        while misses < 2 {
            t += sign * params.spacing_px / 2.0;
            if on_edge(t) {
                *end = t;
                misses = 0;
            } else {
                misses += 1;
            }
        }
    }
    let a = c + u * s0;
    let b = c + u * s1;
    Some(Segment::new([a.x, a.y], [b.x, b.y]))
}
