//! Harris interest points and the 3 x 3 partition heuristic of the seed.

use crate::Gray;

/// An interest point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Column, pixels.
    pub x: usize,
    /// Row, pixels.
    pub y: usize,
    /// Harris response.
    pub response: f32,
}

/// Harris responses `det(M) - k trace(M)^2` of the structure tensor M (Sobel gradients,
/// smoothed with a separable binomial 5 x 5 window), k = 0.04.
pub fn response(img: &Gray) -> Vec<f32> {
    let (w, h) = (img.width, img.height);
    let mut ixx = vec![0f32; w * h];
    let mut iyy = vec![0f32; w * h];
    let mut ixy = vec![0f32; w * h];
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let p = |dx: isize, dy: isize| {
                img.at((x as isize + dx) as usize, (y as isize + dy) as usize)
            };
            let gx = (p(1, -1) + 2.0 * p(1, 0) + p(1, 1)) - (p(-1, -1) + 2.0 * p(-1, 0) + p(-1, 1));
            let gy = (p(-1, 1) + 2.0 * p(0, 1) + p(1, 1)) - (p(-1, -1) + 2.0 * p(0, -1) + p(1, -1));
            let i = y * w + x;
            ixx[i] = gx * gx;
            iyy[i] = gy * gy;
            ixy[i] = gx * gy;
        }
    }
    let smooth = |a: &[f32]| {
        const K: [f32; 5] = [1.0, 4.0, 6.0, 4.0, 1.0];
        let mut tmp = vec![0f32; w * h];
        let mut out = vec![0f32; w * h];
        for y in 0..h {
            for x in 2..w.saturating_sub(2) {
                tmp[y * w + x] = (0..5).map(|k| K[k] * a[y * w + x + k - 2]).sum::<f32>() / 16.0;
            }
        }
        for y in 2..h.saturating_sub(2) {
            for x in 0..w {
                out[y * w + x] =
                    (0..5).map(|k| K[k] * tmp[(y + k - 2) * w + x]).sum::<f32>() / 16.0;
            }
        }
        out
    };
    let (sxx, syy, sxy) = (smooth(&ixx), smooth(&iyy), smooth(&ixy));
    (0..w * h)
        .map(|i| sxx[i] * syy[i] - sxy[i] * sxy[i] - 0.04 * (sxx[i] + syy[i]).powi(2))
        .collect()
}

/// Local maxima of the Harris response in 5 x 5 neighbourhoods, above `relative` times the
/// image's largest response and at least `border` pixels from the edges, strongest first
/// (ties broken by position, so the order is deterministic).
pub fn detect(img: &Gray, relative: f32, border: usize) -> Vec<Corner> {
    let r = response(img);
    let (w, h) = (img.width, img.height);
    let max = r.iter().cloned().fold(0.0f32, f32::max);
    if max <= 0.0 {
        return Vec::new();
    }
    let threshold = relative * max;
    let b = border.max(3);
    let mut corners = Vec::new();
    for y in b..h.saturating_sub(b) {
        for x in b..w.saturating_sub(b) {
            let v = r[y * w + x];
            if v < threshold {
                continue;
            }
            let mut peak = true;
            'n: for dy in -2i32..=2 {
                for dx in -2i32..=2 {
                    if (dx, dy) == (0, 0) {
                        continue;
                    }
                    let o = r[(y as i32 + dy) as usize * w + (x as i32 + dx) as usize];
                    // Strictly greater than earlier neighbours, >= later ones: one peak per plateau.
                    if o > v || (o == v && (dy < 0 || (dy == 0 && dx < 0))) {
                        peak = false;
                        break 'n;
                    }
                }
            }
            if peak {
                corners.push(Corner { x, y, response: v });
            }
        }
    }
    corners.sort_by(|a, b| {
        b.response
            .total_cmp(&a.response)
            .then((a.y, a.x).cmp(&(b.y, b.x)))
    });
    corners
}

/// Which of the 3 x 3 regions a pixel lies in (row-major).
pub fn region(width: usize, height: usize, x: f64, y: f64) -> usize {
    let c = ((x * 3.0 / width as f64) as usize).min(2);
    let r = ((y * 3.0 / height as f64) as usize).min(2);
    r * 3 + c
}

/// The seed's landmark-selection heuristic: the image is partitioned into 3 x 3 regions, and
/// in each region new points are taken (strongest first) until it holds at least
/// `per_region` tracked points. `tracked` are the pixels of points already tracked; returns
/// the corners to initialise, at least `min_distance` pixels from each other and from
/// tracked points.
pub fn select_new(
    corners: &[Corner],
    width: usize,
    height: usize,
    tracked: &[[f64; 2]],
    per_region: usize,
    min_distance: f64,
) -> Vec<Corner> {
    let mut count = [0usize; 9];
    for p in tracked {
        count[region(width, height, p[0], p[1])] += 1;
    }
    let mut taken: Vec<[f64; 2]> = tracked.to_vec();
    let mut out = Vec::new();
    for c in corners {
        let reg = region(width, height, c.x as f64, c.y as f64);
        if count[reg] >= per_region {
            continue;
        }
        let p = [c.x as f64, c.y as f64];
        if taken
            .iter()
            .any(|q| (q[0] - p[0]).hypot(q[1] - p[1]) < min_distance)
        {
            continue;
        }
        count[reg] += 1;
        taken.push(p);
        out.push(*c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn squares() -> Gray {
        // Two bright squares on black: eight corners.
        let (w, h) = (80, 60);
        let mut data = vec![0f32; w * h];
        for (x0, y0) in [(10, 10), (45, 25)] {
            for y in y0..y0 + 20 {
                for x in x0..x0 + 20 {
                    data[y * w + x] = 200.0;
                }
            }
        }
        Gray {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn finds_the_corners_of_squares() {
        let corners = detect(&squares(), 0.1, 3);
        assert_eq!(corners.len(), 8, "{corners:?}");
        let truth = [
            (10, 10),
            (29, 10),
            (10, 29),
            (29, 29),
            (45, 25),
            (64, 25),
            (45, 44),
            (64, 44),
        ];
        for (tx, ty) in truth {
            assert!(
                corners
                    .iter()
                    .any(|c| (c.x as i32 - tx).abs() <= 1 && (c.y as i32 - ty).abs() <= 1),
                "corner near ({tx}, {ty})"
            );
        }
    }

    #[test]
    fn selection_fills_each_region_to_the_quota() {
        let corners: Vec<Corner> = (0..30)
            .flat_map(|i| {
                (0..30).map(move |j| Corner {
                    x: 5 + i * 10,
                    y: 5 + j * 10,
                    response: (i * 31 + j) as f32,
                })
            })
            .collect();
        let tracked = [[10.0, 10.0], [20.0, 20.0], [150.0, 150.0]];
        let new = select_new(&corners, 300, 300, &tracked, 4, 15.0);
        let mut per = [0usize; 9];
        for p in tracked
            .iter()
            .map(|p| (p[0], p[1]))
            .chain(new.iter().map(|c| (c.x as f64, c.y as f64)))
        {
            per[region(300, 300, p.0, p.1)] += 1;
        }
        assert!(per.iter().all(|n| *n == 4), "{per:?}");
    }
}
