//! The hat finder on panoramas drawn by exact ray casting: a grey floor and flat orange
//! squares (the hats' tops) at a known height.

use super::*;

const CAMERA_M: f64 = 1.45;
const HAT_M: f64 = 0.124;
/// The lab children's hat: 0.9 of a 0.12 m body.
const HAT_SIDE_M: f64 = 0.108;

fn finder() -> HatFinder {
    HatFinder {
        panorama: Panorama {
            width: 780,
            height: 580,
            elevation_rad: [(-75f64).to_radians(), 15f64.to_radians()],
        },
        camera_height_m: CAMERA_M,
        hat_height_m: HAT_M,
        min_pixels: 4,
        hat_size_m: [HAT_SIDE_M; 2],
        // Flat hats (`draw`); `draw_slabs` draws them with sides.
        hat_thickness_m: 0.0,
    }
}

/// A panorama of flat hats (their tops) centred at `centres` (mount frame, metres),
/// axis-aligned squares.
fn draw(f: &HatFinder, centres: &[[f64; 2]]) -> Image {
    let hats: Vec<[f64; 3]> = centres.iter().map(|&[x, y]| [x, y, 0.0]).collect();
    cast(f, &hats, 0.0)
}

/// One row's step in floor range at `range`: the resolution the centroid improves on.
fn row_footprint_m(f: &HatFinder, range: f64) -> f64 {
    let p = f.panorama;
    let step = (p.elevation_rad[1] - p.elevation_rad[0]) / p.height as f64;
    let el = ((CAMERA_M - HAT_M) / range).atan();
    (CAMERA_M - HAT_M) / (el - step).tan() - range
}

#[test]
fn a_hat_is_placed_within_one_rows_footprint_of_its_centre() {
    let f = finder();
    for c in [
        [0.6, 0.0],
        [1.2, 0.9],
        [-1.5, 0.7],
        [0.3, -1.9],
        [-0.4, -0.5],
    ] {
        let hats = f.find(&draw(&f, &[c]));
        assert_eq!(hats.len(), 1, "{c:?}: {hats:?}");
        let e = (hats[0].position_m[0] - c[0]).hypot(hats[0].position_m[1] - c[1]);
        let bound = row_footprint_m(&f, c[0].hypot(c[1]));
        assert!(
            e < bound,
            "{c:?}: {:?} is {e:.4} m off (bound {bound:.4})",
            hats[0]
        );
    }
}

#[test]
fn a_hat_across_the_seam_is_one_blob_behind_the_camera() {
    let f = finder();
    let hats = f.find(&draw(&f, &[[-1.0, 0.0]]));
    assert_eq!(hats.len(), 1, "{hats:?}");
    assert!((hats[0].azimuth_rad.abs() - std::f64::consts::PI).abs() < 0.01);
    assert!((hats[0].position_m[0] + 1.0).abs() < 0.02 && hats[0].position_m[1].abs() < 0.01);
}

#[test]
fn hats_apart_are_apart_and_specks_are_not_hats() {
    let f = finder();
    let hats = f.find(&draw(&f, &[[0.5, 0.5], [1.0, -0.5], [1.5, 0.0]]));
    assert_eq!(hats.len(), 3, "{hats:?}");
    // Largest (nearest) first.
    assert!(hats.windows(2).all(|w| w[0].pixels >= w[1].pixels));
    // A speck of three orange pixels is below the 4-pixel blob.
    let mut img = draw(&f, &[]);
    for k in [300 * 780 + 10, 300 * 780 + 11, 301 * 780 + 10] {
        img.data[k * 3..k * 3 + 3].copy_from_slice(&[246, 171, 64]);
    }
    assert!(f.find(&img).is_empty());
}

#[test]
fn orange_is_the_hat_lit_or_shaded_and_nothing_grey_or_blue() {
    // The rendered hat's top, its sides in shade (from the lab's panoramas).
    for c in [
        [246, 171, 64],
        [234, 173, 86],
        [200, 140, 50],
        [190, 140, 70],
    ] {
        assert!(is_orange(c), "{c:?}");
    }
    // Grey and blue bodies, white walls, black, a dark brown and a yellow.
    for c in [
        [140, 140, 148],
        [64, 77, 102],
        [230, 230, 225],
        [0, 0, 0],
        [90, 60, 30],
        [240, 230, 40],
    ] {
        assert!(!is_orange(c), "{c:?}");
    }
}

#[test]
fn an_image_of_another_size_or_encoding_has_no_hats() {
    let f = finder();
    let mut img = draw(&f, &[[0.6, 0.0]]);
    img.encoding = PixelEncoding::Mono8;
    assert!(f.find(&img).is_empty());
    let mut small = finder();
    small.panorama.width = 390;
    assert!(small.find(&draw(&f, &[[0.6, 0.0]])).is_empty());
}

#[test]
fn pixel_inverts_azimuth_and_elevation() {
    let p = finder().panorama;
    for (u, v) in [(0.0, 0.0), (389.5, 290.0), (779.0, 579.0)] {
        let (uu, vv) = p.pixel(p.azimuth(u), p.elevation(v));
        assert!((uu - u).abs() < 1e-9 && (vv - v).abs() < 1e-9, "({u}, {v})");
    }
}

#[test]
fn a_whole_hat_measures_its_area_and_a_cut_or_doubled_one_is_dropped() {
    let f = finder();
    let top = HAT_SIDE_M * HAT_SIDE_M;
    let hats = f.find(&draw(&f, &[[1.0, 0.5]]));
    assert_eq!(hats.len(), 1);
    // The drawn top alone: its area to within the pixels' edge (a few per cent at 1.1 m).
    assert!(
        (hats[0].area_m2 / top - 1.0).abs() < 0.1,
        "{}",
        hats[0].area_m2 / top
    );
    // Half the hat hidden (the columns left of its centre painted over): no hat.
    let mut cut = draw(&f, &[[1.0, 0.5]]);
    let (u_centre, _) = f.panorama.pixel(0.5f64.atan2(1.0), 0.0);
    for v in 0..f.panorama.height as usize {
        for u in u_centre as usize..u_centre as usize + 40 {
            let k = (v * f.panorama.width as usize + u) * 3;
            cut.data[k..k + 3].copy_from_slice(&[120, 118, 112]);
        }
    }
    assert!(f.find(&cut).is_empty(), "{:?}", f.find(&cut));
    // Two hats touching, one blob of twice the area: no hat.
    let pair = f.find(&draw(&f, &[[1.0, 0.5], [1.0, 0.5 + HAT_SIDE_M]]));
    assert!(pair.is_empty(), "{pair:?}");
}

/// The lab's hats: 2.4 cm thick.
const HAT_THICK_M: f64 = 0.024;

/// A panorama of hats as slabs `HAT_THICK_M` thick, centred at `hats`' first two values and
/// turned by the third (radians).
fn draw_slabs(f: &HatFinder, hats: &[[f64; 3]]) -> Image {
    cast(f, hats, HAT_THICK_M)
}

/// A panorama drawn by exact ray casting: a grey floor, and orange where a pixel's ray passes
/// through a hat, a square slab `thickness` thick (0: its top alone) whose top is at `HAT_M`,
/// centred at `hats`' first two values and turned by the third (radians).
fn cast(f: &HatFinder, hats: &[[f64; 3]], thickness: f64) -> Image {
    let p = f.panorama;
    let half = HAT_SIDE_M / 2.0;
    let mut data = Vec::with_capacity((p.width * p.height * 3) as usize);
    for v in 0..p.height {
        let el = p.elevation(v as f64);
        for u in 0..p.width {
            let az = p.azimuth(u as f64);
            let hit = el < 0.0 && {
                // The ray's floor ranges at the slab's top and bottom planes.
                let r0 = (CAMERA_M - HAT_M) / (-el).tan();
                let r1 = (CAMERA_M - HAT_M + thickness) / (-el).tan();
                hats.iter().any(|&[cx, cy, turn]| {
                    // The segment from r0 to r1 in the slab's frame, clipped to its square.
                    let to_slab = |r: f64| {
                        let (dx, dy) = (r * az.cos() - cx, r * az.sin() - cy);
                        [
                            turn.cos() * dx + turn.sin() * dy,
                            -turn.sin() * dx + turn.cos() * dy,
                        ]
                    };
                    let (a, b) = (to_slab(r0), to_slab(r1));
                    let (mut lo, mut hi) = (0.0f64, 1.0f64);
                    for k in 0..2 {
                        let d = b[k] - a[k];
                        if d.abs() < 1e-12 {
                            if a[k].abs() > half {
                                return false;
                            }
                            continue;
                        }
                        let (t0, t1) = ((-half - a[k]) / d, (half - a[k]) / d);
                        lo = lo.max(t0.min(t1));
                        hi = hi.min(t0.max(t1));
                    }
                    lo <= hi
                })
            };
            data.extend_from_slice(if hit {
                &[246, 171, 64]
            } else {
                &[120, 118, 112]
            });
        }
    }
    Image {
        stamp_ns: 0,
        sensor: "omni".into(),
        width: p.width,
        height: p.height,
        encoding: PixelEncoding::Rgb8,
        data,
    }
}

#[test]
fn a_slab_hats_sides_are_undone_to_within_one_rows_footprint() {
    let flat = finder();
    let slab = HatFinder {
        hat_thickness_m: HAT_THICK_M,
        ..finder()
    };
    for h in [
        [0.6, 0.0, 0.0],
        [1.2, 0.9, 0.3],
        [-1.5, 0.7, 0.785],
        [0.3, -1.9, -0.5],
        [2.2, 0.4, 1.2],
    ] {
        let img = draw_slabs(&slab, &[h]);
        let range = h[0].hypot(h[1]);
        let bound = row_footprint_m(&slab, range);
        let off = |f: &HatFinder| {
            let hats = f.find(&img);
            assert_eq!(hats.len(), 1, "{h:?}: {hats:?}");
            let [x, y] = hats[0].position_m;
            // Along the sight line (negative: towards the camera) and across it.
            let along = (x * h[0] + y * h[1]) / range - range;
            let across = (-x * h[1] + y * h[0]) / range;
            (along, across)
        };
        let (along, across) = off(&slab);
        assert!(
            along.hypot(across) < bound,
            "{h:?}: {along:.4} m along, {across:.4} across (bound {bound:.4})"
        );
        // Without the sides' correction the centroid lies towards the camera by about half
        // the sides' shadow on the top's plane, range t / (d + t) / 2: more than a row's
        // footprint here, so the bound above holds only with the correction.
        let (flat_along, _) = off(&flat);
        let half_shadow = range * HAT_THICK_M / (CAMERA_M - HAT_M + HAT_THICK_M) / 2.0;
        assert!(
            (flat_along + half_shadow).abs() < bound / 2.0 && -flat_along > bound,
            "{h:?}: uncorrected {flat_along:.4} m along (half shadow {half_shadow:.4}, bound \
             {bound:.4})"
        );
    }
}

#[test]
fn a_whole_slab_hat_is_found_as_far_as_it_spans_enough_pixels() {
    // Its sides' shadow and the pixels along its outline grow with range: a bound of a fixed
    // 1.6 times the top dropped these hats from 3 m on.
    let slab = HatFinder {
        hat_thickness_m: HAT_THICK_M,
        ..finder()
    };
    for r in [1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0] {
        for turn in [0.0, 0.6, 1.2] {
            let h = [0.8 * r, 0.6 * r, turn];
            let hats = slab.find(&draw_slabs(&slab, &[h]));
            assert_eq!(hats.len(), 1, "{h:?}: {hats:?}");
            // Placed on its own top: within half its side of the centre.
            let [x, y] = hats[0].position_m;
            let off = (x - h[0]).hypot(y - h[1]);
            assert!(off < HAT_SIDE_M / 2.0, "{h:?}: {off:.4} m off");
        }
    }
    // Two touching hats are still no hat where the bound is below twice the top.
    assert!(slab.largest_whole_m2(1.75) < 2.0 * slab.top_area_m2());
    let pair = slab.find(&draw_slabs(
        &slab,
        &[[1.4, 0.3, 0.0], [1.4, 0.3 + HAT_SIDE_M, 0.0]],
    ));
    assert!(pair.is_empty(), "{pair:?}");
}

#[test]
fn a_whole_hat_top_is_found_at_any_offset_as_far_as_its_pixels_blur_its_area() {
    // A hat whose sides are in shade shows its top alone. From about 3 m it spans 10-25
    // pixels, and where its outline cuts the pixels decides its measured area. (Here, a
    // pixel orange where its centre's ray meets the top, whole tops measure 0.83 of their
    // area or more, so this loop passes under the fixed 0.8 too; in the rendered
    // panoramas, whose edge pixels are blended, down to 0.67 at 3 m: the module's
    // decisions. The hat 0.7 of the top below is what the fixed 0.8 failed.)
    let f = finder();
    for k in 0..40 {
        let r = 2.5 + 0.04 * k as f64;
        let az = 0.3 + 0.0011 * k as f64;
        let turn = 0.07 * k as f64;
        let h = [r * az.cos(), r * az.sin(), turn];
        let hats = f.find(&cast(&f, &[h], 0.0));
        assert_eq!(hats.len(), 1, "{h:?} at {r:.2} m: {hats:?}");
        let [x, y] = hats[0].position_m;
        assert!((x - h[0]).hypot(y - h[1]) < HAT_SIDE_M / 2.0, "{h:?}");
    }
    // Near the camera the bound stays 0.8 of the top, and a hat cut by an obstacle's edge
    // is still dropped there.
    assert_eq!(f.smallest_whole_m2(1.0), 0.8 * f.top_area_m2());
    // A hat 0.7 of the top the finder knows (drawn 0.108 m wide where it expects 0.154 m):
    // dropped at 1 m, found at 3.5 m, where a whole top may measure that little (the
    // fixed 0.8 of the top dropped it there too).
    let expects_larger = HatFinder {
        hat_size_m: [HAT_SIDE_M / 0.7, HAT_SIDE_M],
        ..f
    };
    assert!(expects_larger.find(&draw(&f, &[[1.0, 0.0]])).is_empty());
    assert_eq!(expects_larger.find(&draw(&f, &[[3.5, 0.0]])).len(), 1);
}
