//! The camera models after rendering: radial distortion and the omnidirectional panorama,
//! resampled bilinearly from what the renderer drew.

use super::Model;
use hetsim_msgs::{mount_to_optical, CameraGeometry};
use hetsim_render::Frame;
use nalgebra::{UnitQuaternion, Vector3};
use rayon::prelude::*;

/// The six cube faces as (yaw, pitch) of the face's mount frame: forward, left, back, right,
/// up (pitch -90°: x axis up), down.
pub const CUBE: [(f64, f64); 6] = [
    (0.0, 0.0),
    (std::f64::consts::FRAC_PI_2, 0.0),
    (std::f64::consts::PI, 0.0),
    (-std::f64::consts::FRAC_PI_2, 0.0),
    (0.0, -std::f64::consts::FRAC_PI_2),
    (0.0, std::f64::consts::FRAC_PI_2),
];

/// The colour (and depth, where rendered) at `(u, v)` of a rendered frame, bilinear, if
/// inside it.
pub fn bilinear(f: &Frame, u: f64, v: f64) -> Option<([f64; 3], Option<f32>)> {
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
pub fn undistort(xd: f64, yd: f64, [k1, k2]: [f64; 2]) -> (f64, f64) {
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
pub fn pinhole(k: CameraGeometry, distortion: Option<[f64; 2]>) -> Model {
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
        let (xu, yu) = undistort((u - k.k.u0) / k.k.alpha_u, (v - k.k.v0) / k.k.alpha_v, d);
        let (ru, rv) = (k.k.alpha_u * xu + k.k.u0, k.k.alpha_v * yu + k.k.v0);
        left = left.max(-ru);
        right = right.max(ru - w);
        top = top.max(-rv);
        bottom = bottom.max(rv - h);
    }
    let (pl, pr, pt, pb) = [left, right, top, bottom]
        .map(|m| m.ceil() as u32 + 1)
        .into();
    let render = CameraGeometry {
        width: k.width + pl + pr,
        height: k.height + pt + pb,
        k: hetsim_msgs::Pinhole {
            u0: k.k.u0 + pl as f64,
            v0: k.k.v0 + pt as f64,
            ..k.k
        },
    };
    Model::Pinhole { distortion, render }
}

/// Applies radial distortion: each output pixel samples the (padded) undistorted render at the
/// undistorted position of its ray (fixed-point inversion of the distortion).
pub fn distort(
    f: &Frame,
    k: &CameraGeometry,
    render: &CameraGeometry,
    d: [f64; 2],
) -> (Vec<u8>, Option<Vec<f32>>) {
    let n = (k.width * k.height) as usize;
    let mut rgb = vec![0u8; n * 3];
    let mut depth = f.depth_m.as_ref().map(|_| vec![0f32; n]);
    for v in 0..k.height {
        for u in 0..k.width {
            let (xu, yu) = undistort(
                (u as f64 - k.k.u0) / k.k.alpha_u,
                (v as f64 - k.k.v0) / k.k.alpha_v,
                d,
            );
            let i = (v * k.width + u) as usize;
            if let Some((c, d)) = bilinear(
                f,
                render.k.alpha_u * xu + render.k.u0,
                render.k.alpha_v * yu + render.k.v0,
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
pub fn panorama_lookup(
    face: &CameraGeometry,
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
            let [fu, fv] = face.k.project(&p).unwrap_or([0.0, 0.0]);
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

/// One panorama pixel's bilinear tap: the index of its top-left source pixel in the rendered
/// faces laid end to end (each `width x height`, in the order of [`panorama_taps`]'s faces),
/// and the weights of its right and lower neighbours in 1/256ths. On a face's last column
/// (row) the tap starts one pixel left (up) with the full weight 256 on the edge pixel, so
/// that the neighbours always exist and the value is the edge pixel's, as clamping gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tap {
    index: u32,
    wx: u16,
    wy: u16,
}

/// Every panorama pixel's [`Tap`], the faces' width, and per pixel the ratio of range to the
/// face's depth there (for panoramas with depth).
#[derive(Clone, Debug, PartialEq)]
pub struct Taps {
    taps: Vec<Tap>,
    face_width: u32,
    range_scale: Vec<f32>,
}

/// The panorama's taps in fixed point and the cube faces they read (indices into [`CUBE`],
/// ascending): a face no pixel reads (above 45° for the robot file's elevations) is not
/// rendered at all.
pub fn panorama_taps(face: &CameraGeometry, lookup: &[(u8, f32, f32, f32)]) -> (Taps, Vec<usize>) {
    let mut used = [false; 6];
    for &(f, ..) in lookup {
        used[f as usize] = true;
    }
    let faces: Vec<usize> = (0..6).filter(|&f| used[f]).collect();
    let (w, h) = (face.width, face.height);
    assert!(w >= 2 && h >= 2, "a cube face of {w} x {h} pixels");
    // The top-left pixel and the weight of the next one along an axis of `n` pixels.
    let axis = |t: f32, n: u32| {
        let t = t.clamp(0.0, (n - 1) as f32);
        let x = t.floor() as u32;
        let weight = ((t - x as f32) * 256.0).round() as u16;
        if x + 1 < n {
            (x, weight)
        } else {
            (n - 2, 256)
        }
    };
    let taps = lookup
        .iter()
        .map(|&(f, u, v, _)| {
            let (x, wx) = axis(u, w);
            let (y, wy) = axis(v, h);
            let k = faces.iter().position(|&k| k == f as usize).expect("used") as u32;
            Tap {
                index: k * w * h + y * w + x,
                wx,
                wy,
            }
        })
        .collect();
    let range_scale = lookup.iter().map(|&(.., scale)| scale).collect();
    (
        Taps {
            taps,
            face_width: w,
            range_scale,
        },
        faces,
    )
}

/// The panorama (RGB) resampled from the rendered faces (in the order of
/// [`panorama_taps`]'s faces), and its range where the faces have depth. Bilinear in fixed
/// point (weights in 1/256ths): each channel is within 1.5 levels of the exact
/// interpolation, and within one where neighbours differ by under 128 levels.
pub fn panorama(faces: &[Frame], taps: &Taps) -> (Vec<u8>, Option<Vec<f32>>) {
    // The faces end to end, a pixel (RGBA, little-endian) per u32.
    let mut pixels: Vec<u32> = Vec::with_capacity(faces.iter().map(|f| f.rgba.len() / 4).sum());
    for f in faces {
        pixels.extend(
            f.rgba
                .chunks_exact(4)
                .map(|p| u32::from_le_bytes([p[0], p[1], p[2], p[3]])),
        );
    }
    let w = taps.face_width as usize;
    // In blocks of 4096 pixels on the worker threads (each pixel is its own; the bytes do
    // not depend on the split).
    const BLOCK: usize = 4096;
    let mut rgb = vec![0u8; taps.taps.len() * 3];
    rgb.par_chunks_mut(BLOCK * 3)
        .zip(taps.taps.par_chunks(BLOCK))
        .for_each(|(block, taps)| {
            for (px, t) in block.chunks_exact_mut(3).zip(taps) {
                let (wx, wy) = (t.wx as u32, t.wy as u32);
                let i = t.index as usize;
                let (top, bottom) = (&pixels[i..i + 2], &pixels[i + w..i + w + 2]);
                // Along the row, two channels per product: red and blue (green and alpha)
                // in 16-bit lanes, each weighted sum at most 255 * 256.
                let row = |p: &[u32], shift: u32| {
                    let (a, b) = ((p[0] >> shift) & 0x00ff_00ff, (p[1] >> shift) & 0x00ff_00ff);
                    a * (256 - wx) + b * wx
                };
                // Down the column, in 32-bit lanes (each sum under 2^24), rounded to nearest.
                let column = |t: u32, b: u32| {
                    let spread = |x: u32| (x & 0xffff) as u64 | ((x >> 16) as u64) << 32;
                    (spread(t) * (256 - wy) as u64 + spread(b) * wy as u64 + 0x8000_0000_8000) >> 16
                };
                let rb = column(row(top, 0), row(bottom, 0));
                let ga = column(row(top, 8), row(bottom, 8));
                px[0] = rb as u8;
                px[1] = ga as u8;
                px[2] = (rb >> 32) as u8;
            }
        });
    let depth = faces[0].depth_m.as_ref().map(|_| {
        let depths: Vec<f32> = faces
            .iter()
            .flat_map(|f| f.depth_m.as_deref().expect("every face has depth"))
            .copied()
            .collect();
        taps.taps
            .iter()
            .zip(&taps.range_scale)
            .map(|(t, scale)| {
                let mut k = t.index as usize;
                if t.wx >= 128 {
                    k += 1;
                }
                if t.wy >= 128 {
                    k += w;
                }
                depths[k] * scale
            })
            .collect()
    });
    (rgb, depth)
}
