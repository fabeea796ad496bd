//! The camera models after rendering: radial distortion and the omnidirectional panorama,
//! resampled bilinearly from what the renderer drew.

use super::Model;
use hetsim_render::{mount_to_optical, Frame, Intrinsics};
use nalgebra::{UnitQuaternion, Vector3};
use rayon::prelude::*;

/// The six cube faces as (yaw, pitch) of the face's mount frame: forward, left, back, right,
/// up (pitch -90°: x axis up), down.
pub(super) const CUBE: [(f64, f64); 6] = [
    (0.0, 0.0),
    (std::f64::consts::FRAC_PI_2, 0.0),
    (std::f64::consts::PI, 0.0),
    (-std::f64::consts::FRAC_PI_2, 0.0),
    (0.0, -std::f64::consts::FRAC_PI_2),
    (0.0, std::f64::consts::FRAC_PI_2),
];

pub(super) fn bilinear(f: &Frame, u: f64, v: f64) -> Option<([f64; 3], Option<f32>)> {
    let (w, h) = (f.width as i64, f.height as i64);
    if u < 0.0 || v < 0.0 || u > (w - 1) as f64 || v > (h - 1) as f64 {
        return None;
    }
    let (x0, y0) = (u.floor() as i64, v.floor() as i64);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (tx, ty) = (u - x0 as f64, v - y0 as f64);
    let px = |x: i64, y: i64, c: usize| f.rgba[((y * w + x) * 4) as usize + c] as f64;
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let top = px(x0, y0, c) * (1.0 - tx) + px(x1, y0, c) * tx;
        let bottom = px(x0, y1, c) * (1.0 - tx) + px(x1, y1, c) * tx;
        *o = top * (1.0 - ty) + bottom * ty;
    }
    let depth = f
        .depth_m
        .as_ref()
        .map(|d| d[(v.round() as i64 * w + u.round() as i64) as usize]);
    Some((out, depth))
}

/// The undistorted normalized coordinates of distorted normalized `(xd, yd)`.
pub(super) fn undistort(xd: f64, yd: f64, [k1, k2]: [f64; 2]) -> (f64, f64) {
    let (mut xu, mut yu) = (xd, yd);
    for _ in 0..20 {
        let r2 = xu * xu + yu * yu;
        let s = 1.0 + k1 * r2 + k2 * r2 * r2;
        xu = xd / s;
        yu = yd / s;
    }
    (xu, yu)
}

/// A pinhole model; with distortion, the render is padded so that every image pixel's
/// undistorted ray falls inside it.
pub(super) fn pinhole(k: Intrinsics, distortion: Option<[f64; 2]>) -> Model {
    let Some(d) = distortion else {
        return Model::Pinhole {
            distortion,
            render: k,
        };
    };
    let (mut left, mut right, mut top, mut bottom) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (w, h) = (k.width as f64 - 1.0, k.height as f64 - 1.0);
    let border = (0..=64).flat_map(|i| {
        let t = i as f64 / 64.0;
        [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)]
    });
    for (u, v) in border {
        let (xu, yu) = undistort((u - k.u0) / k.alpha_u, (v - k.v0) / k.alpha_v, d);
        let (ru, rv) = (k.alpha_u * xu + k.u0, k.alpha_v * yu + k.v0);
        left = left.max(-ru);
        right = right.max(ru - w);
        top = top.max(-rv);
        bottom = bottom.max(rv - h);
    }
    let (pl, pr, pt, pb) = [left, right, top, bottom]
        .map(|m| m.ceil() as u32 + 1)
        .into();
    let render = Intrinsics {
        width: k.width + pl + pr,
        height: k.height + pt + pb,
        u0: k.u0 + pl as f64,
        v0: k.v0 + pt as f64,
        ..k
    };
    Model::Pinhole { distortion, render }
}

/// Applies radial distortion: each output pixel samples the (padded) undistorted render at the
/// undistorted position of its ray (fixed-point inversion of the distortion).
pub(super) fn distort(
    f: &Frame,
    k: &Intrinsics,
    render: &Intrinsics,
    d: [f64; 2],
) -> (Vec<u8>, Option<Vec<f32>>) {
    let n = (k.width * k.height) as usize;
    let mut rgb = vec![0u8; n * 3];
    let mut depth = f.depth_m.as_ref().map(|_| vec![0f32; n]);
    for v in 0..k.height {
        for u in 0..k.width {
            let (xu, yu) = undistort(
                (u as f64 - k.u0) / k.alpha_u,
                (v as f64 - k.v0) / k.alpha_v,
                d,
            );
            let i = (v * k.width + u) as usize;
            if let Some((c, d)) = bilinear(
                f,
                render.alpha_u * xu + render.u0,
                render.alpha_v * yu + render.v0,
            ) {
                for ch in 0..3 {
                    rgb[i * 3 + ch] = c[ch].round() as u8;
                }
                if let (Some(out), Some(d)) = (depth.as_mut(), d) {
                    out[i] = d;
                }
            }
        }
    }
    (rgb, depth)
}

/// For each panorama pixel: which cube face sees its ray, where, and the ratio of range to
/// that face's depth.
pub(super) fn panorama_lookup(
    face: &Intrinsics,
    w: u32,
    h: u32,
    [lo, hi]: [f64; 2],
) -> Vec<(u8, f32, f32, f32)> {
    let to_optical = mount_to_optical().inverse();
    let face_from_mount: Vec<UnitQuaternion<f64>> = CUBE
        .iter()
        .map(|(yaw, pitch)| UnitQuaternion::from_euler_angles(0.0, *pitch, *yaw).inverse())
        .collect();
    let mut out = Vec::with_capacity((w * h) as usize);
    for v in 0..h {
        let el = hi - (hi - lo) * (v as f64 + 0.5) / h as f64;
        for u in 0..w {
            let az = std::f64::consts::PI - std::f64::consts::TAU * (u as f64 + 0.5) / w as f64;
            let dir = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
            // The face whose optical axis is closest to the ray.
            let (best, p) = face_from_mount
                .iter()
                .enumerate()
                .map(|(i, r)| (i, to_optical * (r * dir)))
                .max_by(|a, b| a.1.z.total_cmp(&b.1.z))
                .expect("six faces");
            let (fu, fv) = face.project(&p).unwrap_or((0.0, 0.0));
            let (fu, fv) = (
                fu.clamp(0.0, (face.width - 1) as f64),
                fv.clamp(0.0, (face.height - 1) as f64),
            );
            out.push((
                best as u8,
                fu as f32,
                fv as f32,
                (p.norm() / p.z.max(1e-9)) as f32,
            ));
        }
    }
    out
}

/// Resamples the six rendered cube faces into the panorama (depth becomes range).
/// One panorama pixel's bilinear tap: the rendered face it reads (its index among the faces
/// rendered), the byte offset of the top-left source pixel in the face's RGBA and the steps
/// to its right and lower neighbours (0 on the face's last column or row), the weights of
/// those neighbours in 1/256ths, and the ratio of range to the face's depth there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Tap {
    face: u8,
    offset: u32,
    right: u32,
    down: u32,
    wx: u16,
    wy: u16,
    scale: f32,
}

/// The panorama's taps in fixed point and the cube faces they read (indices into [`CUBE`],
/// ascending): a face no pixel reads (above 45° for the robot file's elevations) is not
/// rendered at all.
pub(super) fn panorama_taps(
    face: &Intrinsics,
    lookup: &[(u8, f32, f32, f32)],
) -> (Vec<Tap>, Vec<usize>) {
    let mut used = [false; 6];
    for &(f, ..) in lookup {
        used[f as usize] = true;
    }
    let faces: Vec<usize> = (0..6).filter(|&f| used[f]).collect();
    let (w, h) = (face.width, face.height);
    let taps = lookup
        .iter()
        .map(|&(f, u, v, scale)| {
            let (u, v) = (u.clamp(0.0, (w - 1) as f32), v.clamp(0.0, (h - 1) as f32));
            let (x, y) = (u.floor() as u32, v.floor() as u32);
            Tap {
                face: faces.iter().position(|&k| k == f as usize).expect("used") as u8,
                offset: (y * w + x) * 4,
                right: if x + 1 < w { 4 } else { 0 },
                down: if y + 1 < h { w * 4 } else { 0 },
                wx: ((u - x as f32) * 256.0).round() as u16,
                wy: ((v - y as f32) * 256.0).round() as u16,
                scale,
            }
        })
        .collect();
    (taps, faces)
}

/// The panorama (RGB) resampled from the rendered faces (in the order of
/// [`panorama_taps`]'s faces), and its range where the faces have depth. Bilinear in fixed
/// point (weights in 1/256ths): each channel is within 1.5 levels of the exact
/// interpolation, and within one where neighbours differ by under 128 levels.
pub(super) fn panorama(faces: &[Frame], taps: &[Tap]) -> (Vec<u8>, Option<Vec<f32>>) {
    // In blocks of 4096 pixels on the worker threads (each pixel is its own; the bytes do
    // not depend on the split).
    const BLOCK: usize = 4096;
    let mut rgb = vec![0u8; taps.len() * 3];
    rgb.par_chunks_mut(BLOCK * 3)
        .zip(taps.par_chunks(BLOCK))
        .for_each(|(block, taps)| {
            for (px, t) in block.chunks_exact_mut(3).zip(taps) {
                let src = &faces[t.face as usize].rgba;
                let (wx, wy) = (t.wx as u32, t.wy as u32);
                let (a, b) = (t.offset as usize, (t.offset + t.right) as usize);
                let (c, d) = (a + t.down as usize, b + t.down as usize);
                for (ch, out) in px.iter_mut().enumerate() {
                    let top = src[a + ch] as u32 * (256 - wx) + src[b + ch] as u32 * wx;
                    let bottom = src[c + ch] as u32 * (256 - wx) + src[d + ch] as u32 * wx;
                    *out = ((top * (256 - wy) + bottom * wy + 32768) >> 16) as u8;
                }
            }
        });
    let depth = faces[0].depth_m.as_ref().map(|_| {
        taps.iter()
            .map(|t| {
                let f = &faces[t.face as usize];
                let mut k = t.offset as usize / 4;
                if t.wx >= 128 {
                    k += t.right as usize / 4;
                }
                if t.wy >= 128 {
                    k += t.down as usize / 4;
                }
                f.depth_m.as_ref().map_or(0.0, |d| d[k]) * t.scale
            })
            .collect()
    });
    (rgb, depth)
}
