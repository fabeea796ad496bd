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
/// smoothed with a separable binomial 5 x 5 window), k = 0.04; zero within two pixels of
/// the border.
///
/// The image is streamed row by row: each row's gradient products are smoothed along the
/// row into a ring of the last five rows, and an output row is smoothed down its columns
/// from the ring as soon as its five rows are there. The arithmetic is that of the
/// whole-image passes (same operations in the same order, so the same bits: a test holds it
/// to them), but the working set is a few rows instead of seven image-sized buffers, and
/// each pass is a zip of row slices the compiler vectorizes. `hetsim bench --vision`, back
/// to back: Harris with the selection 5.1 -> 4.1 ms per 1024 x 768 frame, the VO step
/// 14.2 -> 13.0 ms.
pub fn response(img: &Gray) -> Vec<f32> {
    let (w, h) = (img.width, img.height);
    let mut out = vec![0f32; w * h];
    if w < 5 || h < 5 {
        return out;
    }
    // [product][ring slot][x], products xx, yy, xy.
    let mut ring = vec![0f32; 3 * 5 * w];
    let mut raw = vec![0f32; 3 * w];
    let (mut sxx, mut syy, mut sxy) = (vec![0f32; w], vec![0f32; w], vec![0f32; w]);
    let at = |k: usize, slot: usize| (k * 5 + slot) * w;
    for r in 0..h {
        // Gradient products of row r (zero on the image's first and last rows and columns).
        raw.fill(0.0);
        if r >= 1 && r + 1 < h {
            let (a, b, c) = (
                &img.data[(r - 1) * w..r * w],
                &img.data[r * w..(r + 1) * w],
                &img.data[(r + 1) * w..(r + 2) * w],
            );
            let (xx, rest) = raw.split_at_mut(w);
            let (yy, xy) = rest.split_at_mut(w);
            let windows = a.windows(3).zip(b.windows(3)).zip(c.windows(3));
            let products = xx[1..].iter_mut().zip(&mut yy[1..]).zip(&mut xy[1..]);
            // Pixel x = i + 1; its neighbours at i, i + 1, i + 2.
            for (((a, b), c), ((xx, yy), xy)) in windows.zip(products) {
                let gx = (a[2] + 2.0 * b[2] + c[2]) - (a[0] + 2.0 * b[0] + c[0]);
                let gy = (c[0] + 2.0 * c[1] + c[2]) - (a[0] + 2.0 * a[1] + a[2]);
                *xx = gx * gx;
                *yy = gy * gy;
                *xy = gx * gy;
            }
        }
        // Binomial [1 4 6 4 1] / 16 along the row, into the ring.
        let slot = r % 5;
        for k in 0..3 {
            let src = &raw[k * w..(k + 1) * w];
            let dst = &mut ring[at(k, slot)..at(k, slot) + w];
            dst[..2].fill(0.0);
            dst[w - 2..].fill(0.0);
            for (d, s) in dst[2..w - 2].iter_mut().zip(src.windows(5)) {
                *d = (s[0] + 4.0 * s[1] + 6.0 * s[2] + 4.0 * s[3] + s[4]) / 16.0;
            }
        }
        // Output row y = r - 2, down the columns over rows y - 2 ..= y + 2.
        if r < 4 {
            continue;
        }
        let y = r - 2;
        let column = |k: usize, o: &mut [f32]| {
            let row = |j: usize| &ring[at(k, (y - 2 + j) % 5)..at(k, (y - 2 + j) % 5) + w];
            let rows = row(0)
                .iter()
                .zip(row(1))
                .zip(row(2))
                .zip(row(3))
                .zip(row(4));
            for (d, ((((r0, r1), r2), r3), r4)) in o.iter_mut().zip(rows) {
                *d = (r0 + 4.0 * r1 + 6.0 * r2 + 4.0 * r3 + r4) / 16.0;
            }
        };
        column(0, &mut sxx);
        column(1, &mut syy);
        column(2, &mut sxy);
        for (((o, a), b), c) in out[y * w..(y + 1) * w]
            .iter_mut()
            .zip(&sxx)
            .zip(&syy)
            .zip(&sxy)
        {
            *o = a * b - c * c - 0.04 * ((a + b) * (a + b));
        }
    }
    out
}

/// Local maxima of the Harris response in 5 x 5 neighbourhoods, above `relative` times the
/// image's largest response and at least `border` pixels from the edges, strongest first
/// (ties broken by position, so the order is deterministic).
pub fn detect(img: &Gray, relative: f32, border: usize) -> Vec<Corner> {
    detect_with_max(img, relative, border).0
}

/// [`detect`], and the image's largest response: the corners of a higher `relative` are
/// those of these whose response reaches that fraction of it.
pub fn detect_with_max(img: &Gray, relative: f32, border: usize) -> (Vec<Corner>, f32) {
    let r = response(img);
    let (w, h) = (img.width, img.height);
    let max = r.iter().cloned().fold(0.0f32, f32::max);
    if max <= 0.0 {
        return (Vec::new(), max);
    }
    let threshold = relative * max;
    let b = border.max(3);
    // The 5 x 5 maximum of the response (rows, then columns): only a pixel equal to it can
    // be a peak; the exact test (with its tie rule) runs on those alone.
    let mut rows = vec![f32::MIN; w * h];
    for (src, dst) in r.chunks_exact(w).zip(rows.chunks_exact_mut(w)) {
        for (x, d) in dst[2..w.saturating_sub(2)].iter_mut().enumerate() {
            let s = &src[x..x + 5];
            *d = s[0].max(s[1]).max(s[2]).max(s[3]).max(s[4]);
        }
    }
    let mut corners = Vec::new();
    for y in b..h.saturating_sub(b) {
        let col = |k: usize| &rows[(y + k - 2) * w..(y + k - 1) * w];
        let (r0, r1, r2, r3, r4) = (col(0), col(1), col(2), col(3), col(4));
        let line = &r[y * w..(y + 1) * w];
        for x in b..w.saturating_sub(b) {
            let v = line[x];
            if v < threshold || v < r0[x].max(r1[x]).max(r2[x]).max(r3[x]).max(r4[x]) {
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
    (corners, max)
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
    // Taken points bucketed in cells of `min_distance`: a new one is checked against the
    // 3 x 3 cells around it, not against every point taken.
    let cell = min_distance.max(1.0);
    let (cols, rows) = (
        (width as f64 / cell) as usize + 3,
        (height as f64 / cell) as usize + 3,
    );
    let bucket = |p: [f64; 2]| {
        let c = ((p[0] / cell).floor().max(-1.0) + 1.0) as usize;
        let r = ((p[1] / cell).floor().max(-1.0) + 1.0) as usize;
        (c.min(cols - 2), r.min(rows - 2))
    };
    let mut grid: Vec<Vec<[f64; 2]>> = vec![Vec::new(); cols * rows];
    for &p in tracked {
        let (c, r) = bucket(p);
        grid[r * cols + c].push(p);
    }
    let mut out = Vec::new();
    for c in corners {
        let reg = region(width, height, c.x as f64, c.y as f64);
        if count[reg] >= per_region {
            continue;
        }
        let p = [c.x as f64, c.y as f64];
        let (bc, br) = bucket(p);
        let near = (br - 1..=br + 1).any(|r| {
            (bc - 1..=bc + 1).any(|cc| {
                grid[r * cols + cc].iter().any(|q| {
                    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
                    dx * dx + dy * dy < min_distance * min_distance
                })
            })
        });
        if near {
            continue;
        }
        count[reg] += 1;
        grid[br * cols + bc].push(p);
        out.push(*c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole-image passes [`response`] streams (its implementation before), as the
    /// reference it must reproduce bit for bit.
    fn response_by_whole_image_passes(img: &Gray) -> Vec<f32> {
        let (w, h) = (img.width, img.height);
        let mut ixx = vec![0f32; w * h];
        let mut iyy = vec![0f32; w * h];
        let mut ixy = vec![0f32; w * h];
        if w < 3 || h < 3 {
            return vec![0.0; w * h];
        }
        for y in 1..h - 1 {
            let (a, b, c) = (
                &img.data[(y - 1) * w..y * w],
                &img.data[y * w..(y + 1) * w],
                &img.data[(y + 1) * w..(y + 2) * w],
            );
            let row = y * w + 1..(y + 1) * w - 1;
            let (oxx, oyy, oxy) = (&mut ixx[row.clone()], &mut iyy[row.clone()], &mut ixy[row]);
            for (i, ((xx, yy), xy)) in oxx
                .iter_mut()
                .zip(oyy.iter_mut())
                .zip(oxy.iter_mut())
                .enumerate()
            {
                // Pixel x = i + 1; its neighbours at i, i + 1, i + 2.
                let gx = (a[i + 2] + 2.0 * b[i + 2] + c[i + 2]) - (a[i] + 2.0 * b[i] + c[i]);
                let gy = (c[i] + 2.0 * c[i + 1] + c[i + 2]) - (a[i] + 2.0 * a[i + 1] + a[i + 2]);
                *xx = gx * gx;
                *yy = gy * gy;
                *xy = gx * gy;
            }
        }
        // Separable binomial [1 4 6 4 1] / 16: rows into `tmp`, then columns row by row
        // straight into the response.
        let smooth_rows = |a: &mut [f32]| {
            let mut row = vec![0f32; w];
            for line in a.chunks_exact_mut(w) {
                row.copy_from_slice(line);
                line.fill(0.0);
                if w >= 5 {
                    for (d, s) in line[2..w - 2].iter_mut().zip(row.windows(5)) {
                        *d = (s[0] + 4.0 * s[1] + 6.0 * s[2] + 4.0 * s[3] + s[4]) / 16.0;
                    }
                }
            }
        };
        smooth_rows(&mut ixx);
        smooth_rows(&mut iyy);
        smooth_rows(&mut ixy);
        let mut out = vec![0f32; w * h];
        let (mut sxx, mut syy, mut sxy) = (vec![0f32; w], vec![0f32; w], vec![0f32; w]);
        let column = |a: &[f32], y: usize, o: &mut [f32]| {
            let r = |k: usize| &a[(y + k - 2) * w..(y + k - 1) * w];
            let rows = r(0).iter().zip(r(1)).zip(r(2)).zip(r(3)).zip(r(4));
            for (d, ((((r0, r1), r2), r3), r4)) in o.iter_mut().zip(rows) {
                *d = (r0 + 4.0 * r1 + 6.0 * r2 + 4.0 * r3 + r4) / 16.0;
            }
        };
        for y in 2..h.saturating_sub(2) {
            column(&ixx, y, &mut sxx);
            column(&iyy, y, &mut syy);
            column(&ixy, y, &mut sxy);
            for (((o, a), b), c) in out[y * w..(y + 1) * w]
                .iter_mut()
                .zip(&sxx)
                .zip(&syy)
                .zip(&sxy)
            {
                *o = a * b - c * c - 0.04 * ((a + b) * (a + b));
            }
        }
        out
    }

    #[test]
    fn streamed_response_is_the_whole_image_passes_bit_for_bit() {
        // A textured image with a constant border band, and sizes at the edge cases.
        for (w, h) in [(97, 61), (5, 5), (6, 9), (4, 12), (12, 4), (3, 3)] {
            let data = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    (128.0 + 90.0 * (0.37 * x).sin() * (0.23 * y + 0.1 * x).cos()).floor()
                })
                .collect();
            let img = Gray {
                width: w,
                height: h,
                data,
            };
            let (a, b) = (response(&img), response_by_whole_image_passes(&img));
            assert_eq!(a.len(), b.len());
            for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                assert_eq!(x.to_bits(), y.to_bits(), "{w} x {h}, pixel {i}: {x} vs {y}");
            }
        }
    }

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
