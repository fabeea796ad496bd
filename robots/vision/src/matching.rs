//! Patch descriptors and zero-mean normalized cross-correlation (ZNCC) matching inside a
//! predicted search ellipse.

use crate::Gray;

/// Half size of a patch: patches are 11 x 11 pixels.
pub const HALF: usize = 5;

/// A patch normalized to zero mean and unit norm, so that ZNCC is a dot product.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch(Vec<f32>);

impl Patch {
    /// The patch centred on integer pixel `(x, y)`, if it fits and is not flat.
    pub fn at(img: &Gray, x: usize, y: usize) -> Option<Self> {
        if x < HALF || y < HALF || x + HALF >= img.width || y + HALF >= img.height {
            return None;
        }
        let mut v = Vec::with_capacity((2 * HALF + 1) * (2 * HALF + 1));
        for yy in y - HALF..=y + HALF {
            v.extend_from_slice(&img.data[yy * img.width + x - HALF..=yy * img.width + x + HALF]);
        }
        Self::normalized(v)
    }

    fn normalized(mut v: Vec<f32>) -> Option<Self> {
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        let mut norm = 0.0;
        for x in v.iter_mut() {
            *x -= mean;
            norm += *x * *x;
        }
        if norm < 1e-3 * v.len() as f32 {
            return None;
        }
        let inv = 1.0 / norm.sqrt();
        v.iter_mut().for_each(|x| *x *= inv);
        Some(Self(v))
    }

    /// ZNCC with the image's patch centred on `(x, y)`, without building that patch: as the
    /// template has zero mean, the image patch's mean drops out of the dot product. `None`
    /// where [`Patch::at`] would give `None`.
    #[inline]
    pub fn score(&self, img: &Gray, x: usize, y: usize) -> Option<f32> {
        if x < HALF || y < HALF || x + HALF >= img.width || y + HALF >= img.height {
            return None;
        }
        let (mut dot, mut sum, mut sum2) = (0f32, 0f32, 0f32);
        let side = 2 * HALF + 1;
        for (r, yy) in (y - HALF..=y + HALF).enumerate() {
            let row = &img.data[yy * img.width + x - HALF..=yy * img.width + x + HALF];
            let t = &self.0[r * side..(r + 1) * side];
            for (a, b) in t.iter().zip(row) {
                dot += a * b;
                sum += b;
                sum2 += b * b;
            }
        }
        let n = (side * side) as f32;
        let norm = sum2 - sum * sum / n;
        if norm < 1e-3 * n {
            return None;
        }
        Some(dot / norm.sqrt())
    }

    /// ZNCC with another patch, in [-1, 1].
    pub fn zncc(&self, other: &Patch) -> f32 {
        self.0.iter().zip(&other.0).map(|(a, b)| a * b).sum()
    }
}

/// A match found by a search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    /// Sub-pixel column.
    pub x: f64,
    /// Sub-pixel row.
    pub y: f64,
    /// ZNCC score of the best integer position.
    pub score: f32,
}

fn parabola(left: f32, centre: f32, right: f32) -> f64 {
    let denom = left - 2.0 * centre + right;
    if denom.abs() < 1e-9 {
        0.0
    } else {
        (0.5 * (left - right) / denom).clamp(-0.5, 0.5) as f64
    }
}

/// Searches `img` for `template` inside the ellipse `(p - predicted)^T S^-1 (p - predicted)
/// <= chi2` (S the caller's 2 x 2 predicted covariance in pixels², e.g. from the EKF's
/// innovation covariance; chi2 = 9.21 is the 99 % gate), returning the best position
/// refined to sub-pixel by a parabola through the neighbouring scores, if its score reaches
/// `min_score`.
pub fn search_ellipse(
    img: &Gray,
    template: &Patch,
    predicted: [f64; 2],
    s: [[f64; 2]; 2],
    chi2: f64,
    min_score: f32,
) -> Option<Match> {
    let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
    if det <= 0.0 {
        return None;
    }
    let inv = [
        [s[1][1] / det, -s[0][1] / det],
        [-s[1][0] / det, s[0][0] / det],
    ];
    let (hw, hh) = ((chi2 * s[0][0]).sqrt(), (chi2 * s[1][1]).sqrt());
    let x0 = (predicted[0] - hw).floor().max(HALF as f64) as usize;
    let x1 = (predicted[0] + hw)
        .ceil()
        .min((img.width - HALF - 1) as f64) as usize;
    let y0 = (predicted[1] - hh).floor().max(HALF as f64) as usize;
    let y1 = (predicted[1] + hh)
        .ceil()
        .min((img.height - HALF - 1) as f64) as usize;
    let score_at = |x: usize, y: usize| template.score(img, x, y).unwrap_or(-1.0);
    let mut best: Option<(f32, usize, usize)> = None;
    for y in y0..=y1.max(y0) {
        for x in x0..=x1.max(x0) {
            let (dx, dy) = (x as f64 - predicted[0], y as f64 - predicted[1]);
            if dx * (inv[0][0] * dx + inv[0][1] * dy) + dy * (inv[1][0] * dx + inv[1][1] * dy)
                > chi2
            {
                continue;
            }
            let sc = score_at(x, y);
            if best.is_none_or(|b| sc > b.0) {
                best = Some((sc, x, y));
            }
        }
    }
    let (score, x, y) = best?;
    if score < min_score {
        return None;
    }
    let fx = if x > HALF && x + HALF + 1 < img.width {
        parabola(score_at(x - 1, y), score, score_at(x + 1, y))
    } else {
        0.0
    };
    let fy = if y > HALF && y + HALF + 1 < img.height {
        parabola(score_at(x, y - 1), score, score_at(x, y + 1))
    } else {
        0.0
    };
    Some(Match {
        x: x as f64 + fx,
        y: y as f64 + fy,
        score,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(w: usize, h: usize, shift: f64) -> Gray {
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64 - shift, (i / w) as f64);
                (128.0
                    + 60.0 * (x * 0.31).sin() * (y * 0.23).cos()
                    + 40.0 * (x * 0.11 + y * 0.17).sin()) as f32
            })
            .collect();
        Gray {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn finds_a_shifted_patch_to_sub_pixel_inside_the_ellipse_only() {
        let a = textured(100, 80, 0.0);
        let b = textured(100, 80, 3.4);
        let t = Patch::at(&a, 40, 40).unwrap();
        let m = search_ellipse(&b, &t, [41.0, 40.0], [[16.0, 0.0], [0.0, 4.0]], 9.21, 0.8).unwrap();
        assert!(
            (m.x - 43.4).abs() < 0.15 && (m.y - 40.0).abs() < 0.15,
            "{m:?}"
        );
        assert!(m.score > 0.95);
        // The true position (43.4) lies outside a tight ellipse around 35: no match inside.
        let none = search_ellipse(&b, &t, [35.0, 40.0], [[1.0, 0.0], [0.0, 1.0]], 9.21, 0.95);
        assert!(none.is_none(), "{none:?}");
    }
}
