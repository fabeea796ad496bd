use super::*;
use crate::stereo::StereoPoint;
use rand::SeedableRng;

/// A smooth random texture (sum of a few hundred Gaussian blobs), deterministic.
fn texture(w: usize, h: usize, seed: u64) -> Gray {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    use rand::RngExt;
    let blobs: Vec<(f64, f64, f64, f64)> = (0..600)
        .map(|_| {
            (
                rng.random_range(0.0..w as f64),
                rng.random_range(0.0..h as f64),
                rng.random_range(1.5..5.0),
                rng.random_range(-60.0..60.0),
            )
        })
        .collect();
    let mut data = vec![128f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let v: f64 = blobs
                .iter()
                .filter(|b| (b.0 - x as f64).abs() < 15.0 && (b.1 - y as f64).abs() < 15.0)
                .map(|b| {
                    let d2 = (b.0 - x as f64).powi(2) + (b.1 - y as f64).powi(2);
                    b.3 * (-d2 / (2.0 * b.2 * b.2)).exp()
                })
                .sum();
            data[y * w + x] = (128.0 + v).clamp(0.0, 255.0) as f32;
        }
    }
    Gray {
        width: w,
        height: h,
        data,
    }
}

/// The image turned 180 degrees: pixel (x, y) goes to (w-1-x, h-1-y).
fn turned(img: &Gray) -> Gray {
    let mut data = img.data.clone();
    data.reverse();
    Gray {
        data,
        ..img.clone()
    }
}

#[test]
fn the_descriptor_survives_a_half_turn_and_tells_points_apart() {
    let img = texture(240, 180, 1);
    let (s, t) = (smooth(&img), smooth(&turned(&img)));
    let mut same = Vec::new();
    let mut other = Vec::new();
    // Patches 30 pixels apart do not overlap (diameter 27).
    let points: Vec<(usize, usize)> = (0..7)
        .flat_map(|i| (0..5).map(move |j| (25 + 30 * i, 25 + 30 * j)))
        .collect();
    for &(x, y) in &points {
        let a = describe(&s, x as f64, y as f64).unwrap();
        let b = describe(&t, (239 - x) as f64, (179 - y) as f64).unwrap();
        same.push(hamming(&a, &b));
        for &(x2, y2) in &points {
            if (x2, y2) != (x, y) {
                let c = describe(&t, (239 - x2) as f64, (179 - y2) as f64).unwrap();
                other.push(hamming(&a, &c));
            }
        }
    }
    same.sort_unstable();
    other.sort_unstable();
    // A half turn is exact on the pixel grid and the pattern's rotation rounds to the same
    // pixels up to the orientation's own rounding: the bits barely change. Unrelated patches
    // differ in about 40 % of the bits for steered BRIEF (Rublee et al. 2011, Fig. 3: its
    // steering correlates the comparisons; 50 % for independent ones), with a long lower
    // tail: the same point must beat nearly all of them.
    let worst_same = *same.last().unwrap();
    let fifth = other[other.len() / 20];
    let median_other = other[other.len() / 2];
    assert!(worst_same <= 16, "same point after a half turn: {same:?}");
    assert!(
        worst_same < fifth,
        "5th percentile of distinct points {fifth}"
    );
    assert!(
        (80..=156).contains(&median_other),
        "median distance of unrelated patches {median_other}"
    );
}

#[test]
fn key_frames_cross_the_radio_bit_for_bit_and_truncation_is_refused() {
    let img = texture(120, 90, 2);
    let cam = Pinhole {
        alpha_u: 100.0,
        alpha_v: 100.0,
        u0: 59.5,
        v0: 44.5,
    };
    let stereo: Vec<StereoPoint> = (0..5)
        .map(|k| StereoPoint {
            left: [30.0 + 10.0 * k as f64, 40.0],
            disparity: 5.0,
            point: Vector3::new(0.1 * k as f64, -0.2, 8.0),
            score: 0.9,
        })
        .collect();
    let kf = KeyFrame::new(&img, cam, 0.4, &stereo);
    assert_eq!(kf.points.len(), 5);
    let bytes = kf.to_bytes();
    assert_eq!(bytes.len(), 44 + 52 * 5);
    assert_eq!(KeyFrame::from_bytes(&bytes), Some(kf.clone()));
    assert_eq!(KeyFrame::from_bytes(&bytes[..bytes.len() - 1]), None);
    assert_eq!(KeyFrame::from_bytes(&[]), None);
    let mut nan = bytes.clone();
    nan[44 + 8..44 + 12].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(KeyFrame::from_bytes(&nan), None);
    // A camera of zero focal length, a zero baseline, a point behind the camera.
    for (at, value) in [(0usize, 0.0f64), (32, 0.0)] {
        let mut bad = bytes.clone();
        bad[at..at + 8].copy_from_slice(&value.to_le_bytes());
        assert_eq!(KeyFrame::from_bytes(&bad), None, "byte {at}");
    }
    let mut behind = bytes.clone();
    behind[44 + 16..44 + 20].copy_from_slice(&(-8.0f32).to_le_bytes());
    assert_eq!(KeyFrame::from_bytes(&behind), None);
    // Points whose patch leaves the image have no descriptor and are left out.
    let edge = [StereoPoint {
        left: [3.0, 3.0],
        ..stereo[0]
    }];
    assert!(KeyFrame::new(&img, cam, 0.4, &edge).points.is_empty());
}

/// A synthetic stereo key frame: points on a plane 20 m below a downward camera, seen from
/// the key frame's pose and from the current one, with the descriptors of the same texture
/// at the projected pixels (the image rendered by placing the texture on the plane).
#[test]
fn a_half_turned_view_of_the_same_ground_gives_its_relative_pose_within_its_covariance() {
    let (w, h) = (240usize, 180usize);
    let cam = Pinhole {
        alpha_u: 200.0,
        alpha_v: 200.0,
        u0: (w as f64 - 1.0) / 2.0,
        v0: (h as f64 - 1.0) / 2.0,
    };
    // The ground texture, 1 pixel per 0.1 m, seen from 20 m: 1 texel is 1 image pixel.
    let ground = texture(400, 400, 3);
    let view = |pose: &Pose| -> Gray {
        // Each pixel's ray meets the plane z = 20 (optical frame of the key frame).
        let mut data = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let ray = pose.inverse().rotation
                    * Vector3::new(
                        (x as f64 - cam.u0) / 200.0,
                        (y as f64 - cam.v0) / 200.0,
                        1.0,
                    );
                let o = pose.inverse().translation.vector;
                let s = (20.0 - o.z) / ray.z;
                let p = o + ray * s;
                let (gx, gy) = (p.x * 10.0 + 200.0, p.y * 10.0 + 200.0);
                data[y * w + x] = ground.sample(gx, gy).unwrap_or(0.0);
            }
        }
        Gray {
            width: w,
            height: h,
            data,
        }
    };
    let stereo_of = |pose: &Pose, img: &Gray| -> Vec<StereoPoint> {
        crate::harris::detect(img, 0.01, 8)
            .iter()
            .take(200)
            .map(|c| {
                let (x, y) = (c.x as f64, c.y as f64);
                let ray = Vector3::new((x - cam.u0) / 200.0, (y - cam.v0) / 200.0, 1.0);
                // Depth to the plane along this camera's ray.
                let d = 20.0 - pose.inverse().translation.vector.z;
                let z = d / (pose.inverse().rotation * ray).z;
                StereoPoint {
                    left: [x, y],
                    disparity: 200.0 * 0.5 / z,
                    point: ray * z,
                    score: 1.0,
                }
            })
            .collect()
    };
    let kf_pose = Pose::identity();
    // Current: 2 m over and 1 m closer to the ground, turned 180 degrees about the axis.
    let truth = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(1.5, -2.0, -1.0),
        nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI),
    );
    let (a, b) = (view(&kf_pose), view(&truth));
    let kf = KeyFrame::new(&a, cam, 0.5, &stereo_of(&kf_pose, &a));
    let cur = KeyFrame::new(&b, cam, 0.5, &stereo_of(&truth, &b));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let m = match_keyframes(&kf, &cur, &MatchParams::default(), &mut rng).unwrap();
    assert!(m.inliers >= 20, "{m:?}");
    // The error as a left perturbation, against its covariance: chi-square(6) at 99.9 %
    // is 22.46 (the synthetic points are exact but for pixel rounding, well inside).
    let e = truth * m.current_from_keyframe.inverse();
    let r = e.rotation.scaled_axis();
    let v = nalgebra::Vector6::new(
        e.translation.x,
        e.translation.y,
        e.translation.z,
        r.x,
        r.y,
        r.z,
    );
    let nees = (v.transpose() * m.covariance.try_inverse().unwrap() * v)[0];
    assert!(nees < 22.46, "NEES {nees}, error {v:?}");
    assert!(
        e.translation.vector.norm() < 0.2 && r.norm().to_degrees() < 1.0,
        "{v:?}"
    );
    // Another place (the texture of another seed) does not match.
    let elsewhere = texture(w, h, 9);
    let other = KeyFrame::new(&elsewhere, cam, 0.5, &stereo_of(&kf_pose, &elsewhere));
    assert!(match_keyframes(&other, &cur, &MatchParams::default(), &mut rng).is_err());
}
