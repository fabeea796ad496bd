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

/// Side of a patch, pixels.
const SIDE: usize = 2 * HALF + 1;

/// The ZNCC scores of `template` at `(x, y)` for `x` in `xa..=xb` into `out` (NaN where
/// [`Patch::score`] gives `None`): what [`Patch::score`] computes at each position, organised
/// for a row of candidates. The dot products are 121 multiply-adds over contiguous spans of
/// the row (which the compiler vectorizes), in the same order as [`Patch::score`]'s, so they
/// are the same numbers; the windows' sums and sums of squares come from column sums over the
/// 11 rows, in f64 (their difference cancels).
pub fn row_scores(
    img: &Gray,
    template: &Patch,
    y: usize,
    xa: usize,
    xb: usize,
    out: &mut Vec<f32>,
) {
    out.clear();
    if xb < xa {
        return;
    }
    out.resize(xb - xa + 1, f32::NAN);
    let w = img.width;
    if y < HALF || y + HALF >= img.height {
        return;
    }
    // The part of the span where the window fits.
    let (lo, hi) = (xa.max(HALF), xb.min(w.saturating_sub(HALF + 1)));
    if hi < lo {
        return;
    }
    let len = hi - lo + 1;
    let dots = &mut out[lo - xa..=hi - xa];
    dots.fill(0.0);
    // Column sums over the window's rows, for the columns the span's windows cover.
    let span = len + 2 * HALF;
    let (mut cs, mut cq) = (vec![0f64; span], vec![0f64; span]);
    for r in 0..SIDE {
        let base = (y - HALF + r) * w + lo - HALF;
        let row = &img.data[base..base + span];
        for ((s, q), &v) in cs.iter_mut().zip(cq.iter_mut()).zip(row) {
            let v = v as f64;
            *s += v;
            *q += v * v;
        }
        for c in 0..SIDE {
            let t = template.0[r * SIDE + c];
            for (o, v) in dots.iter_mut().zip(&row[c..c + len]) {
                *o += t * v;
            }
        }
    }
    let n = (SIDE * SIDE) as f64;
    for (i, o) in dots.iter_mut().enumerate() {
        let (s, q): (f64, f64) = (cs[i..i + SIDE].iter().sum(), cq[i..i + SIDE].iter().sum());
        let norm = q - s * s / n;
        *o = if norm < 1e-3 * n {
            f32::NAN
        } else {
            *o / (norm as f32).sqrt()
        };
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
    let (width, height) = (img.width, img.height);
    let inv = [
        [s[1][1] / det, -s[0][1] / det],
        [-s[1][0] / det, s[0][0] / det],
    ];
    let (hw, hh) = ((chi2 * s[0][0]).sqrt(), (chi2 * s[1][1]).sqrt());
    let x0 = (predicted[0] - hw).floor().max(HALF as f64) as usize;
    let x1 = (predicted[0] + hw).ceil().min((width - HALF - 1) as f64) as usize;
    let y0 = (predicted[1] - hh).floor().max(HALF as f64) as usize;
    let y1 = (predicted[1] + hh).ceil().min((height - HALF - 1) as f64) as usize;
    let inside = |x: usize, y: usize| {
        let (dx, dy) = (x as f64 - predicted[0], y as f64 - predicted[1]);
        dx * (inv[0][0] * dx + inv[0][1] * dy) + dy * (inv[1][0] * dx + inv[1][1] * dy) <= chi2
    };
    // Neighbours' scores for the sub-pixel fit, computed as the searched ones were.
    let score_at = |x: usize, y: usize| {
        let mut one = Vec::with_capacity(1);
        row_scores(img, template, y, x, x, &mut one);
        one.first().copied().filter(|s| !s.is_nan()).unwrap_or(-1.0)
    };
    let mut best: Option<(f32, usize, usize)> = None;
    let mut scores = Vec::new();
    let xs = x0..=x1.max(x0);
    for y in y0..=y1.max(y0) {
        // The row's positions inside the ellipse: an interval (scored as one vectorized
        // span), each position still tested as it is taken.
        let Some(xa) = xs.clone().find(|&x| inside(x, y)) else {
            continue;
        };
        let xb = xs.clone().rev().find(|&x| inside(x, y)).unwrap_or(xa);
        row_scores(img, template, y, xa, xb, &mut scores);
        for (x, &sc) in (xa..=xb).zip(&scores) {
            if !inside(x, y) {
                continue;
            }
            let sc = if sc.is_nan() { -1.0 } else { sc };
            if best.is_none_or(|b| sc > b.0) {
                best = Some((sc, x, y));
            }
        }
    }
    let (score, x, y) = best?;
    if score < min_score {
        return None;
    }
    let fx = if x > HALF && x + HALF + 1 < width {
        parabola(score_at(x - 1, y), score, score_at(x + 1, y))
    } else {
        0.0
    };
    let fy = if y > HALF && y + HALF + 1 < height {
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

/// A template at full resolution and, where it has texture there, at half resolution
/// ([`crate::Gray::half`]): the half-resolution patch is centred on the half-resolution pixel
/// nearest the full one's centre, `offset` full-resolution pixels away from it.
#[derive(Clone, Debug, PartialEq)]
pub struct Template {
    /// The 11 x 11 patch at full resolution.
    pub full: Patch,
    /// The 11 x 11 patch at half resolution and the offset of the full centre from its centre.
    pub half: Option<(Patch, [f64; 2])>,
}

impl Template {
    /// The template centred on integer pixel `(x, y)` of `img`, whose half-resolution image
    /// is `half`; `None` where [`Patch::at`] gives none at full resolution.
    pub fn at(img: &Gray, half: &Gray, x: usize, y: usize) -> Option<Self> {
        let full = Patch::at(img, x, y)?;
        let to_half = |v: usize| ((v as f64 - 0.5) / 2.0).round().max(0.0) as usize;
        let (hx, hy) = (to_half(x), to_half(y));
        let offset = [
            x as f64 - (2.0 * hx as f64 + 0.5),
            y as f64 - (2.0 * hy as f64 + 0.5),
        ];
        let half = Patch::at(half, hx, hy).map(|p| (p, offset));
        Some(Self { full, half })
    }
}

/// [`search_ellipse`] coarse to fine: where the ellipse's larger 1σ radius reaches
/// `coarse_from_px` and the template has a half-resolution patch, the ellipse (halved) is
/// searched at half resolution (score `min_score - 0.1`), then a 2 px (1σ) ellipse at full
/// resolution around the coarse match (`min_score`). A point the coarse search misses is not
/// searched again at full resolution: that search is the cost saved (a 30 px ellipse is
/// 2800 positions, its coarse search 700 and the fine one 80).
#[allow(clippy::too_many_arguments)]
pub fn search_pyramid(
    img: &Gray,
    half: &Gray,
    template: &Template,
    predicted: [f64; 2],
    s: [[f64; 2]; 2],
    chi2: f64,
    min_score: f32,
    coarse_from_px: f64,
) -> Option<Match> {
    let spread = s[0][0].max(s[1][1]).sqrt();
    let Some((coarse, offset)) = template.half.as_ref().filter(|_| spread >= coarse_from_px) else {
        return search_ellipse(img, &template.full, predicted, s, chi2, min_score);
    };
    let quarter = |m: [[f64; 2]; 2]| m.map(|r| r.map(|v| v / 4.0));
    let found = search_ellipse(
        half,
        coarse,
        [
            (predicted[0] - offset[0] - 0.5) / 2.0,
            (predicted[1] - offset[1] - 0.5) / 2.0,
        ],
        quarter(s),
        chi2,
        min_score - 0.1,
    )?;
    let fine = [
        2.0 * found.x + 0.5 + offset[0],
        2.0 * found.y + 0.5 + offset[1],
    ];
    search_ellipse(
        img,
        &template.full,
        fine,
        [[4.0, 0.0], [0.0, 4.0]],
        chi2,
        min_score,
    )
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

    fn zncc_f64(a: &Gray, ax: usize, ay: usize, b: &Gray, bx: usize, by: usize) -> f64 {
        let window = |g: &Gray, x: usize, y: usize| -> Vec<f64> {
            (0..SIDE * SIDE)
                .map(|i| g.at(x + i % SIDE - HALF, y + i / SIDE - HALF) as f64)
                .collect()
        };
        let centred = |v: Vec<f64>| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            v.into_iter().map(|x| x - m).collect::<Vec<f64>>()
        };
        let (p, q) = (centred(window(a, ax, ay)), centred(window(b, bx, by)));
        let dot: f64 = p.iter().zip(&q).map(|(x, y)| x * y).sum();
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        dot / (norm(&p) * norm(&q))
    }

    #[test]
    fn row_scores_are_the_patch_scores_and_reject_flat_windows() {
        let mut a = textured(90, 70, 0.0);
        // A flat block: its windows have no texture to correlate.
        for y in 40..70 {
            for x in 0..40 {
                a.data[y * 90 + x] = 77.0;
            }
        }
        let b = textured(90, 70, 1.7);
        let t = Patch::at(&a, 60, 20).unwrap();
        let mut row = Vec::new();
        for (img, name) in [(&a, "a"), (&b, "b")] {
            for y in 0..70 {
                row_scores(img, &t, y, 0, 89, &mut row);
                for (x, &got) in row.iter().enumerate() {
                    let direct = t.score(img, x, y);
                    assert_eq!(direct.is_some(), !got.is_nan(), "{name} ({x}, {y})");
                    if let Some(d) = direct {
                        // Against ZNCC in f64, two-pass: f32 sums of 121 terms keep ~1e-5.
                        let exact = zncc_f64(&a, 60, 20, img, x, y);
                        assert!((got as f64 - exact).abs() < 1e-5, "{got} vs {exact}");
                        assert!((d as f64 - exact).abs() < 1e-4, "{d} vs {exact}");
                    }
                }
            }
        }
        row_scores(&a, &t, 20, 55, 65, &mut row);
        assert!(
            (row[5] - 1.0).abs() < 1e-5,
            "the template's own window: {}",
            row[5]
        );
    }
}
