//! The image LSD works on: a Gaussian blur against aliasing, then bilinear scaling.

use crate::Gray;

/// Separable Gaussian blur (edges clamped).
fn blur(img: &Gray, sigma: f64) -> Gray {
    if sigma <= 0.0 {
        return img.clone();
    }
    let r = (3.0 * sigma).ceil() as usize;
    let kernel: Vec<f32> = (-(r as isize)..=r as isize)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let norm: f32 = kernel.iter().sum();
    let (w, h) = (img.width, img.height);
    // Rows: the row padded by clamping, then each output a dot with the kernel.
    let mut tmp = vec![0f32; w * h];
    let mut padded = vec![0f32; w + 2 * r];
    for (src, dst) in img.data.chunks_exact(w).zip(tmp.chunks_exact_mut(w)) {
        for (i, p) in padded.iter_mut().enumerate() {
            *p = src[i.saturating_sub(r).min(w - 1)];
        }
        for (x, d) in dst.iter_mut().enumerate() {
            let acc: f32 = kernel.iter().zip(&padded[x..]).map(|(k, v)| k * v).sum();
            *d = acc / norm;
        }
    }
    // Columns: each output row the kernel-weighted sum of the clamped input rows.
    let mut data = vec![0f32; w * h];
    let mut acc = vec![0f32; w];
    for (y, dst) in data.chunks_exact_mut(w).enumerate() {
        acc.fill(0.0);
        for (j, k) in kernel.iter().enumerate() {
            let yy = (y + j).saturating_sub(r).min(h - 1);
            for (a, v) in acc.iter_mut().zip(&tmp[yy * w..(yy + 1) * w]) {
                *a += k * v;
            }
        }
        for (d, a) in dst.iter_mut().zip(&acc) {
            *d = a / norm;
        }
    }
    Gray {
        width: w,
        height: h,
        data,
    }
}

/// The image scaled by `scale` (pixel `i` of the result samples the original at `i / scale`),
/// blurred first with σ = 0.6 / scale (LSD's Gaussian sub-sampling).
pub(super) fn rescale(img: &Gray, scale: f64) -> Gray {
    let sigma = if scale < 1.0 { 0.6 / scale } else { 0.6 };
    let smooth = blur(img, sigma);
    if scale == 1.0 {
        return smooth;
    }
    let (w, h) = (
        ((img.width as f64) * scale).floor() as usize,
        ((img.height as f64) * scale).floor() as usize,
    );
    // Bilinear sampling at `i / scale`, its columns' and rows' weights computed once (what
    // `Gray::sample` does per pixel).
    let taps = |n: usize, size: usize| -> Vec<(usize, usize, f32)> {
        (0..n)
            .map(|i| {
                let t = i as f64 / scale;
                let i0 = t.floor() as usize;
                (i0, (i0 + 1).min(size - 1), (t - i0 as f64) as f32)
            })
            .collect()
    };
    let (xs, ys) = (taps(w, img.width), taps(h, img.height));
    let mut data = Vec::with_capacity(w * h);
    for &(y0, y1, ty) in &ys {
        let (top, bottom) = (
            &smooth.data[y0 * img.width..(y0 + 1) * img.width],
            &smooth.data[y1 * img.width..(y1 + 1) * img.width],
        );
        data.extend(xs.iter().map(|&(x0, x1, tx)| {
            let t = top[x0] * (1.0 - tx) + top[x1] * tx;
            let b = bottom[x0] * (1.0 - tx) + bottom[x1] * tx;
            t * (1.0 - ty) + b * ty
        }));
    }
    Gray {
        width: w,
        height: h,
        data,
    }
}
