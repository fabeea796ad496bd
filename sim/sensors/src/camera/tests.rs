//! Tests of the cameras: projection, distortion, panoramas, noise.

use super::*;
use hetsim_render::Frame;

/// A synthetic render whose red channel is the column and green the row (both < 256).
fn ramp(k: &CameraGeometry) -> Frame {
    let mut rgba = Vec::new();
    for v in 0..k.height {
        for u in 0..k.width {
            rgba.extend([u as u8, v as u8, 255, 255]);
        }
    }
    Frame {
        width: k.width,
        height: k.height,
        rgba,
        depth_m: Some(vec![1.0; (k.width * k.height) as usize]),
    }
}

#[test]
fn radial_distortion_samples_where_the_model_says() {
    let k = CameraGeometry {
        width: 120,
        height: 100,
        k: hetsim_msgs::Pinhole {
            alpha_u: 90.0,
            alpha_v: 90.0,
            u0: 59.5,
            v0: 49.5,
        },
    };
    let (k1, k2) = (-0.2, 0.05);
    let Model::Pinhole { render, .. } = pinhole(k, Some([k1, k2])) else {
        unreachable!()
    };
    assert!(
        render.width > k.width && render.height > k.height,
        "barrel distortion needs a wider render"
    );
    assert!(
        render.width < 256 && render.height < 256,
        "the ramp encodes coordinates in a byte"
    );
    let (rgb, _) = distort(&ramp(&render), &k, &render, [k1, k2]);
    assert_eq!(rgb.len(), (k.width * k.height * 3) as usize);
    assert!(
        rgb.chunks_exact(3).all(|p| p[2] == 255),
        "every pixel has data: no black corners"
    );
    for &(u, v) in &[(0u32, 0u32), (119, 5), (60, 50), (10, 99), (100, 80)] {
        // Forward model from the sampled (undistorted) point must give back the pixel.
        let i = ((v * k.width + u) * 3) as usize;
        let (su, sv) = (rgb[i] as f64, rgb[i + 1] as f64);
        let (xu, yu) = (
            (su - render.k.u0) / render.k.alpha_u,
            (sv - render.k.v0) / render.k.alpha_v,
        );
        let r2 = xu * xu + yu * yu;
        let s = 1.0 + k1 * r2 + k2 * r2 * r2;
        let (ud, vd) = (k.k.alpha_u * xu * s + k.k.u0, k.k.alpha_v * yu * s + k.k.v0);
        assert!(
            (ud - u as f64).abs() < 1.0 && (vd - v as f64).abs() < 1.0,
            "pixel ({u}, {v}) sampled ({su}, {sv}) -> ({ud:.2}, {vd:.2})"
        );
    }
    // Barrel distortion (k1 < 0): the corner samples from beyond the image's own corner.
    assert!(
        rgb[0] as f64 + 0.5 < render.k.u0 - k.k.u0 && rgb[1] as f64 + 0.5 < render.k.v0 - k.k.v0
    );
}

#[test]
fn panorama_centre_column_looks_forward_and_the_top_row_up() {
    let face = CameraGeometry::from_hfov(64, 64, 90.0);
    let lookup = panorama_lookup(&face, 360, 180, [-1.5, 1.5]);
    // Centre column, middle row: straight ahead, face 0 at its centre.
    let (f, u, v, scale) = lookup[90 * 360 + 180];
    assert_eq!(f, 0);
    assert!(
        (u as f64 - 31.5).abs() < 1.0
            && (v as f64 - 31.5).abs() < 1.0
            && (scale - 1.0).abs() < 0.01
    );
    // Quarter of the way across: 90 deg to the left, face 1.
    assert_eq!(lookup[90 * 360 + 90].0, 1);
    // Top row: looking up, face 4.
    assert_eq!(lookup[180].0, 4);
}

#[test]
fn the_panorama_in_fixed_point_is_the_exact_bilinear_within_a_level_and_a_half_and_skips_the_top_face(
) {
    let face = CameraGeometry::from_hfov(64, 64, 90.0);
    let lookup = panorama_lookup(&face, 256, 128, [-75f64.to_radians(), 15f64.to_radians()]);
    let (taps, faces) = panorama_taps(&face, &lookup);
    // Elevations up to 15 degrees never reach the upward face (4): five faces are rendered.
    assert_eq!(faces, vec![0, 1, 2, 3, 5]);
    // Faces of pseudo-random colours (a different pattern per face).
    let frames: Vec<Frame> = faces
        .iter()
        .map(|&f| {
            let rgba = (0..64 * 64 * 4)
                .map(|k: usize| ((k * 2654435761 + f * 97) >> 7) as u8)
                .collect();
            Frame {
                width: 64,
                height: 64,
                rgba,
                depth_m: Some(vec![2.0; 64 * 64]),
            }
        })
        .collect();
    let (rgb, depth) = panorama(&frames, &taps);
    let mut all = [None; 6];
    for (k, &f) in faces.iter().enumerate() {
        all[f] = Some(&frames[k]);
    }
    for (i, &(f, u, v, scale)) in lookup.iter().enumerate() {
        let (exact, _) = optics::bilinear(all[f as usize].unwrap(), u as f64, v as f64).unwrap();
        // Weights in 1/256ths (each off by at most 1/512, on two axes, of a step of at most
        // 255 levels) and the final rounding (half a level): 1.5 levels at most.
        for ch in 0..3 {
            let got = rgb[i * 3 + ch] as f64;
            assert!(
                (got - exact[ch]).abs() <= 1.5,
                "pixel {i} channel {ch}: {got} against {:.2}",
                exact[ch]
            );
        }
        assert!((depth.as_ref().unwrap()[i] - 2.0 * scale).abs() < 1e-6);
    }
}

#[test]
fn panorama_range_is_the_nearest_source_pixels_and_face_edges_read_the_edge_pixel() {
    let face = CameraGeometry::from_hfov(64, 64, 90.0);
    // The panorama's own rays, and taps on the faces' last row and column.
    let mut lookup = panorama_lookup(&face, 256, 128, [-75f64.to_radians(), 15f64.to_radians()]);
    lookup.extend([
        (0, 63.0, 63.0, 1.0),
        (0, 62.999, 10.2, 1.0),
        (1, 0.0, 63.0, 1.5),
        (3, 31.5, 62.6, 1.0),
    ]);
    let (taps, faces) = panorama_taps(&face, &lookup);
    // Depth 1, 2, 3, ... along the faces laid end to end, and pseudo-random colours.
    let frames: Vec<Frame> = (0..faces.len())
        .map(|k| Frame {
            width: 64,
            height: 64,
            rgba: (0..64 * 64 * 4)
                .map(|i: usize| ((i * 2654435761 + k * 97) >> 7) as u8)
                .collect(),
            depth_m: Some((0..64 * 64).map(|i| (k * 4096 + i + 1) as f32).collect()),
        })
        .collect();
    let (rgb, depth) = panorama(&frames, &taps);
    let depth = depth.expect("faces with depth");
    for (i, &(f, u, v, scale)) in lookup.iter().enumerate() {
        let k = faces.iter().position(|&g| g == f as usize).unwrap();
        let index = (depth[i] / scale).round() as usize - 1;
        assert_eq!(index / 4096, k, "pixel {i}: range from another face");
        let (x, y) = ((index % 4096) % 64, (index % 4096) / 64);
        // The nearest source pixel, up to the weights' 1/512 rounding.
        let near = 0.5 + 1.0 / 512.0 + 1e-4;
        assert!(
            (x as f32 - u).abs() <= near && (y as f32 - v).abs() <= near,
            "pixel {i}: range of ({x}, {y}) for ({u}, {v})"
        );
        let (exact, _) = optics::bilinear(&frames[k], u as f64, v as f64).unwrap();
        for ch in 0..3 {
            assert!(
                (rgb[i * 3 + ch] as f64 - exact[ch]).abs() <= 1.5,
                "pixel {i}"
            );
        }
    }
}
