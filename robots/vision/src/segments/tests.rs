//! Tests of segment detection and tracking on synthetic images.

use super::*;

/// A synthetic image: dark background, a bright quadrilateral, plus a little
/// deterministic texture.
fn square(width: usize, height: usize, corners: [[f64; 2]; 4]) -> Gray {
    let mut data = vec![0f32; width * height];
    let inside = |x: f64, y: f64| {
        (0..4).all(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0.0
        })
    };
    for y in 0..height {
        for x in 0..width {
            // 4 x 4 supersampling for anti-aliased edges.
            let mut cover = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let (px, py) = (
                        x as f64 + (sx as f64 + 0.5) / 4.0 - 0.5,
                        y as f64 + (sy as f64 + 0.5) / 4.0 - 0.5,
                    );
                    if inside(px, py) {
                        cover += 1.0 / 16.0;
                    }
                }
            }
            let texture = ((x * 7 + y * 13) % 5) as f64;
            data[y * width + x] = (40.0 + 150.0 * cover + texture) as f32;
        }
    }
    Gray {
        width,
        height,
        data,
    }
}

fn dist_to_edge(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    Segment::new(a, b).line_distance(p).abs()
}

#[test]
fn detects_the_sides_of_a_rotated_square_within_half_a_pixel() {
    let c = [[60.0, 40.0], [180.0, 70.0], [150.0, 190.0], [30.0, 160.0]];
    let img = square(240, 220, c);
    let segs = detect(&img, &DetectParams::default());
    assert_eq!(segs.len(), 4, "{segs:?}");
    for s in &segs {
        let best = (0..4)
            .map(|i| {
                dist_to_edge(s.a, c[i], c[(i + 1) % 4]).max(dist_to_edge(s.b, c[i], c[(i + 1) % 4]))
            })
            .fold(f64::MAX, f64::min);
        assert!(best < 0.5, "{s:?} is {best:.2} px from every side");
        assert!(s.length() > 100.0 && s.significance > 10.0, "{s:?}");
    }
}

#[test]
fn pure_noise_yields_no_segment() {
    let mut state = 12345u64;
    let data = (0..200 * 200)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 56) as f32
        })
        .collect();
    let img = Gray {
        width: 200,
        height: 200,
        data,
    };
    let params = DetectParams {
        min_length: 0.0,
        ..DetectParams::default()
    };
    assert!(detect(&img, &params).is_empty());
}

#[test]
fn tracks_a_moved_edge_from_an_offset_prediction_and_extends_it() {
    let c = [[60.0, 40.0], [180.0, 70.0], [150.0, 190.0], [30.0, 160.0]];
    let img = square(240, 220, c);
    let found = detect(&img, &DetectParams::default());
    // The same image, the square moved by (3, -2) px; predict from the old segments,
    // shortened to their middle half.
    let moved = square(240, 220, c.map(|p| [p[0] + 3.0, p[1] - 2.0]));
    for s in &found {
        let l = s.length();
        let predicted = Segment::new(s.at(0.25 * l), s.at(0.75 * l));
        let t = track(&moved, &predicted, &TrackParams::default()).expect("tracked");
        let side = (0..4)
            .map(|i| [c[i], c[(i + 1) % 4]].map(|p| [p[0] + 3.0, p[1] - 2.0]))
            .min_by(|x, y| dist_to_edge(t.a, x[0], x[1]).total_cmp(&dist_to_edge(t.a, y[0], y[1])))
            .unwrap();
        for p in [t.a, t.b] {
            assert!(dist_to_edge(p, side[0], side[1]) < 0.5, "{t:?} vs {side:?}");
        }
        // Extended to (nearly) the whole side, not just the predicted half.
        assert!(t.length() > 0.85 * l, "{} of {l}", t.length());
    }
}

#[test]
fn clipping_keeps_the_inside_part_and_the_direction() {
    let s = Segment::new([-10.0, 5.0], [30.0, 25.0]);
    let c = s.clipped([0.0, 0.0], [20.0, 40.0]).unwrap();
    assert_eq!((c.a, c.b), ([0.0, 10.0], [20.0, 20.0]));
    let r = Segment::new(s.b, s.a)
        .clipped([0.0, 0.0], [20.0, 40.0])
        .unwrap();
    assert_eq!((r.a, r.b), ([20.0, 20.0], [0.0, 10.0]));
    assert_eq!(s.clipped([-20.0, 0.0], [40.0, 40.0]), Some(s));
    assert_eq!(s.clipped([40.0, 0.0], [50.0, 40.0]), None);
    assert_eq!(s.clipped([0.0, 30.0], [50.0, 40.0]), None);
}

#[test]
fn binomial_tail_matches_direct_sums() {
    for (n, k, p) in [(10u64, 3u64, 0.125f64), (50, 20, 0.125), (200, 5, 0.3)] {
        let direct: f64 = (k..=n)
            .map(|i| {
                let c = (ln_gamma(n as f64 + 1.0)
                    - ln_gamma(i as f64 + 1.0)
                    - ln_gamma((n - i) as f64 + 1.0))
                .exp();
                c * p.powi(i as i32) * (1.0 - p).powi((n - i) as i32)
            })
            .sum();
        let got = 10f64.powf(log10_binomial_tail(n, k, p));
        assert!(
            (got - direct).abs() < 1e-9 * direct.max(1e-300),
            "{got} vs {direct}"
        );
    }
    assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
}
