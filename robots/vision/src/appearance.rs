//! Global image features for appearance-based localization of the children (seed 002,
//! Section V.B, after its reference \[2\]).
//!
//! **WGOH, Weighted Gradient Orientation Histograms** (Bradley et al., 2005), as used here,
//! on the full 120 x 88 grey image:
//! 1. gradients by central differences at every interior pixel, magnitude `m` and
//!    orientation `θ` in `[0, 2π)`;
//! 2. each gradient weighted by `m` times a Gaussian of the distance to the image centre,
//!    `σ` = half the image width;
//! 3. the image split into 4 x 4 equal sub-windows, each with an 8-bin orientation histogram
//!    (45° bins); a gradient adds its weight to the two nearest bins, linearly;
//! 4. the 128 values concatenated, scaled to unit length, clipped at 0.2 and scaled to unit
//!    length again (as SIFT does, against a few dominant edges);
//! 5. two images are compared by the Euclidean distance of their vectors.
//!
//! **Pixelwise comparison**: the grey image reduced to 15 x 11 by averaging equal blocks
//! (8 x 8 pixels for 120 x 88), compared by the mean absolute difference of the grey levels.

use crate::Gray;
use serde::{Deserialize, Serialize};

/// Side of the sub-window grid.
const CELLS: usize = 4;
/// Orientation bins per sub-window.
const BINS: usize = 8;

/// A WGOH descriptor (128 values, unit length).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Wgoh(pub Vec<f32>);

impl Wgoh {
    /// The descriptor of a grey image.
    pub fn of(img: &Gray) -> Self {
        let (w, h) = (img.width, img.height);
        let mut hist = vec![0f32; CELLS * CELLS * BINS];
        let (cx, cy) = ((w as f32 - 1.0) / 2.0, (h as f32 - 1.0) / 2.0);
        let sigma = w as f32 / 2.0;
        let inv = 1.0 / (2.0 * sigma * sigma);
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let gx = img.at(x + 1, y) - img.at(x - 1, y);
                let gy = img.at(x, y + 1) - img.at(x, y - 1);
                let m = gx.hypot(gy);
                if m == 0.0 {
                    continue;
                }
                let d2 = (x as f32 - cx).powi(2) + (y as f32 - cy).powi(2);
                let weight = m * (-d2 * inv).exp();
                let theta = gy.atan2(gx).rem_euclid(std::f32::consts::TAU);
                let pos = theta / std::f32::consts::TAU * BINS as f32 - 0.5;
                let lo = pos.floor();
                let frac = pos - lo;
                let b0 = (lo as i64).rem_euclid(BINS as i64) as usize;
                let b1 = (b0 + 1) % BINS;
                let cell = (y * CELLS / h) * CELLS + x * CELLS / w;
                hist[cell * BINS + b0] += weight * (1.0 - frac);
                hist[cell * BINS + b1] += weight * frac;
            }
        }
        normalize(&mut hist);
        for v in hist.iter_mut() {
            *v = v.min(0.2);
        }
        normalize(&mut hist);
        Self(hist)
    }

    /// Euclidean distance to another descriptor.
    pub fn distance(&self, other: &Self) -> f32 {
        self.0
            .iter()
            .zip(&other.0)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f32>()
            .sqrt()
    }
}

fn normalize(v: &mut [f32]) {
    let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    if n > 0.0 {
        v.iter_mut().for_each(|x| *x /= n);
    }
}

/// A reduced grey image for pixelwise comparison.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Thumbnail {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Mean grey levels of the blocks, row-major.
    pub data: Vec<f32>,
}

impl Thumbnail {
    /// The image reduced to `width x height` by block averaging (each output pixel averages
    /// the input pixels whose centres fall in its block).
    pub fn of(img: &Gray, width: usize, height: usize) -> Self {
        let mut sum = vec![0f32; width * height];
        let mut count = vec![0u32; width * height];
        for y in 0..img.height {
            let ty = y * height / img.height;
            for x in 0..img.width {
                let tx = x * width / img.width;
                sum[ty * width + tx] += img.at(x, y);
                count[ty * width + tx] += 1;
            }
        }
        Self {
            width,
            height,
            data: sum
                .iter()
                .zip(&count)
                .map(|(s, c)| s / (*c).max(1) as f32)
                .collect(),
        }
    }

    /// Mean absolute difference of grey levels.
    pub fn distance(&self, other: &Self) -> f32 {
        self.data
            .iter()
            .zip(&other.data)
            .map(|(a, b)| (a - b).abs())
            .sum::<f32>()
            / self.data.len().max(1) as f32
    }
}

/// The two features of a database image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Features {
    /// WGOH at full resolution.
    pub wgoh: Wgoh,
    /// The 15 x 11 thumbnail.
    pub thumbnail: Thumbnail,
}

impl Features {
    /// Both features of a grey image.
    pub fn of(img: &Gray) -> Self {
        Self {
            wgoh: Wgoh::of(img),
            thumbnail: Thumbnail::of(img, 15, 11),
        }
    }
}

/// Which feature compares two images.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// WGOH, Euclidean distance.
    Wgoh,
    /// 15 x 11 thumbnails, mean absolute difference.
    Pixelwise,
}

impl Feature {
    /// Both, in reporting order.
    pub const ALL: [Feature; 2] = [Feature::Wgoh, Feature::Pixelwise];

    /// The name used in results.
    pub fn name(self) -> &'static str {
        match self {
            Feature::Wgoh => "wgoh",
            Feature::Pixelwise => "pixelwise",
        }
    }

    /// The distance between two images' features.
    pub fn distance(self, a: &Features, b: &Features) -> f32 {
        match self {
            Feature::Wgoh => a.wgoh.distance(&b.wgoh),
            Feature::Pixelwise => a.thumbnail.distance(&b.thumbnail),
        }
    }
}

/// The index of the database entry nearest the query (ties: the first).
pub fn best_match(query: &Features, database: &[Features], feature: Feature) -> Option<usize> {
    database
        .iter()
        .enumerate()
        .map(|(i, f)| (i, feature.distance(query, f)))
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(f: impl Fn(usize, usize) -> f32) -> Gray {
        let (w, h) = (120, 88);
        Gray {
            width: w,
            height: h,
            data: (0..w * h).map(|i| f(i % w, i / w)).collect(),
        }
    }

    #[test]
    fn wgoh_is_unit_length_and_sees_edge_orientation() {
        // Vertical stripes: horizontal gradients only (bins 0 and 4 of every cell).
        let img = image(|x, _| if (x / 10) % 2 == 0 { 50.0 } else { 200.0 });
        let d = Wgoh::of(&img);
        assert_eq!(d.0.len(), 128);
        let norm: f32 = d.0.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!((norm - 1.0).abs() < 1e-4);
        let horizontal: f32 = (0..16)
            .flat_map(|c| [c * 8, c * 8 + 3, c * 8 + 4, c * 8 + 7])
            .map(|i| d.0[i])
            .sum();
        let total: f32 = d.0.iter().sum();
        assert!(horizontal > 0.99 * total, "{horizontal} of {total}");
        // Horizontal stripes differ; the same stripes brighter and with more contrast do not
        // (gradients only, normalized).
        let other = Wgoh::of(&image(|_, y| if (y / 10) % 2 == 0 { 50.0 } else { 200.0 }));
        let brighter = Wgoh::of(&image(|x, _| if (x / 10) % 2 == 0 { 80.0 } else { 245.0 }));
        assert!(d.distance(&other) > 1.0);
        assert!(d.distance(&brighter) < 1e-5);
    }

    #[test]
    fn thumbnails_average_blocks() {
        let img = image(|x, y| (x / 8 + 100 * (y / 8)) as f32);
        let t = Thumbnail::of(&img, 15, 11);
        assert_eq!((t.width, t.height, t.data.len()), (15, 11, 165));
        assert_eq!(t.data[0], 0.0);
        assert_eq!(t.data[15 + 3], 103.0);
        let brighter = Thumbnail::of(&image(|x, y| (x / 8 + 100 * (y / 8)) as f32 + 4.0), 15, 11);
        assert!((t.distance(&brighter) - 4.0).abs() < 1e-4);
    }

    #[test]
    fn best_match_picks_the_nearest() {
        let a = Features::of(&image(|x, _| x as f32));
        let b = Features::of(&image(|_, y| y as f32 * 2.0));
        let q = Features::of(&image(|x, _| x as f32 + 3.0));
        for f in Feature::ALL {
            assert_eq!(best_match(&q, &[b.clone(), a.clone()], f), Some(1));
        }
    }
}
