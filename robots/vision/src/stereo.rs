//! Matching points between the rectified left and right images of a stereo bench.
//!
//! The right camera sits `baseline` metres along the left camera's x axis (to its right), with
//! the same intrinsics and orientation, so a point at depth Z appears `d = αu b / Z` pixels
//! further left in the right image, on the same row.

use crate::harris::Corner;
use crate::matching::{row_scores, Patch, HALF};
use crate::Gray;
use hetsim_msgs::Pinhole;
use nalgebra::Vector3;

/// A rectified stereo bench: the left camera's intrinsics (shared by the right camera) and
/// the baseline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bench {
    /// Intrinsics of both cameras.
    pub camera: Pinhole,
    /// Distance between the optical centres, metres.
    pub baseline_m: f64,
}

/// A point matched in both images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoPoint {
    /// Pixel in the left image.
    pub left: [f64; 2],
    /// Disparity, pixels.
    pub disparity: f64,
    /// The point in the left camera's optical frame, metres.
    pub point: Vector3<f64>,
    /// ZNCC score of the match.
    pub score: f32,
}

/// Matches `corners` of the left image along their rows in the right image, for depths in
/// `[z_min, z_max]`, keeping matches scoring at least `min_score` whose best score is
/// clearly better (by `0.05`) than any other more than 2 px away (repetitive texture is
/// ambiguous) and that survive a left-right consistency check, refined to sub-pixel
/// disparity.
pub fn match_stereo(
    left: &Gray,
    right: &Gray,
    bench: &Bench,
    corners: &[Corner],
    [z_min, z_max]: [f64; 2],
    min_score: f32,
) -> Vec<StereoPoint> {
    let (cam, baseline) = (&bench.camera, bench.baseline_m);
    let (d_min, d_max) = (
        cam.alpha_u * baseline / z_max,
        cam.alpha_u * baseline / z_min,
    );
    let mut out = Vec::new();
    let mut row = Vec::new();
    for c in corners {
        let Some(t) = Patch::at(left, c.x, c.y) else {
            continue;
        };
        let lo = (c.x as f64 - d_max).floor().max(HALF as f64) as usize;
        let hi = (c.x as f64 - d_min)
            .ceil()
            .min((c.x as f64).min((right.width - HALF - 1) as f64)) as usize;
        if hi <= lo {
            continue;
        }
        let scores: Vec<(usize, f32)> = scored(right, &t, c.y, lo, hi, &mut row).collect();
        let Some(&(bx, best)) = scores.iter().max_by(|a, b| a.1.total_cmp(&b.1)) else {
            continue;
        };
        let rival = scores
            .iter()
            .filter(|(x, _)| x.abs_diff(bx) > 2)
            .map(|s| s.1)
            .fold(-1.0f32, f32::max);
        if best < min_score || best - rival < 0.05 {
            continue;
        }
        let at = |x: usize| scores.iter().find(|s| s.0 == x).map(|s| s.1);
        let frac = match (bx.checked_sub(1).and_then(at), at(bx + 1)) {
            (Some(l), Some(r)) => {
                let denom = l - 2.0 * best + r;
                if denom.abs() > 1e-9 {
                    (0.5 * (l - r) / denom).clamp(-0.5, 0.5) as f64
                } else {
                    0.0
                }
            }
            _ => 0.0,
        };
        // Left-right consistency: matching the right patch back along the left row must land
        // on the corner again (fails at occlusion boundaries, where a window straddles depths).
        let Some(back) = Patch::at(right, bx, c.y) else {
            continue;
        };
        let lo_l = (bx as f64 + d_min).floor() as usize;
        let hi_l = ((bx as f64 + d_max).ceil() as usize).min(left.width - HALF - 1);
        let back_best = scored(left, &back, c.y, lo_l, hi_l.max(lo_l), &mut row)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if back_best.is_none_or(|(x, _)| x.abs_diff(c.x) > 1) {
            continue;
        }
        let disparity = c.x as f64 - (bx as f64 + frac);
        if disparity <= 0.0 {
            continue;
        }
        let z = cam.alpha_u * baseline / disparity;
        out.push(StereoPoint {
            left: [c.x as f64, c.y as f64],
            disparity,
            point: cam.back_project(c.x as f64, c.y as f64, z),
            score: best,
        });
    }
    out
}

/// The positions of `xa..=xb` on row `y` where the template scores, with their scores
/// (`row` is the scratch buffer).
fn scored<'a>(
    img: &Gray,
    template: &Patch,
    y: usize,
    xa: usize,
    xb: usize,
    row: &'a mut Vec<f32>,
) -> impl Iterator<Item = (usize, f32)> + 'a {
    row_scores(img, template, y, xa, xb, row);
    (xa..=xb)
        .zip(row.iter())
        .filter(|(_, v)| !v.is_nan())
        .map(|(x, &v)| (x, v))
}
