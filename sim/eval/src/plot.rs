//! Small PNG charts drawn directly into pixels: stacked box plots in the style of Figs. 3
//! and 4 of seed 002, with a built-in 3x5 pixel font for tick labels and titles.

use image::{Rgb, RgbImage};

const BG: Rgb<u8> = Rgb([255, 255, 255]);
const INK: Rgb<u8> = Rgb([30, 30, 30]);
const GRID: Rgb<u8> = Rgb([225, 225, 225]);
const MAPPING: Rgb<u8> = Rgb([52, 101, 164]);
const COORDINATION: Rgb<u8> = Rgb([252, 175, 62]);

/// The PNG bytes of an image.
pub fn png(img: &RgbImage) -> Vec<u8> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .expect("PNG encodes in memory");
    bytes
}

/// Glyphs of the font, 3 columns x 5 rows, one row per 3 bits (MSB left).
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        '%' => [5, 1, 2, 4, 5],
        '=' => [0, 7, 0, 7, 0],
        '-' => [0, 0, 7, 0, 0],
        'k' => [4, 5, 6, 5, 5],
        'N' => [5, 7, 7, 7, 5],
        'r' => [0, 6, 5, 4, 4],
        _ => [0, 0, 0, 0, 0],
    }
}

/// Draws text with its top-left corner at (x, y), each font pixel `scale` pixels wide.
pub fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, scale: i64, color: Rgb<u8>) {
    for (i, c) in s.chars().enumerate() {
        let g = glyph(c);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    rect(
                        img,
                        x + (i as i64 * 4 + col) * scale,
                        y + row as i64 * scale,
                        scale,
                        scale,
                        color,
                    );
                }
            }
        }
    }
}

fn text_width(s: &str, scale: i64) -> i64 {
    (s.chars().count() as i64 * 4 - 1) * scale
}

/// Fills a rectangle, clipped to the image.
pub fn rect(img: &mut RgbImage, x: i64, y: i64, w: i64, h: i64, color: Rgb<u8>) {
    for py in y.max(0)..(y + h).min(img.height() as i64) {
        for px in x.max(0)..(x + w).min(img.width() as i64) {
            img.put_pixel(px as u32, py as u32, color);
        }
    }
}

fn quartiles(values: &[f64]) -> [f64; 5] {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let pos = p * (v.len() - 1) as f64;
        let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
        v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
    };
    [v[0], q(0.25), q(0.5), q(0.75), v[v.len() - 1]]
}

/// One box of a panel: mapping and coordination timesteps of each seed.
pub struct StackedBox {
    /// Label under the box (the number of children).
    pub label: String,
    /// Mapping timesteps per seed.
    pub mapping: Vec<f64>,
    /// Coordination timesteps per seed.
    pub coordination: Vec<f64>,
}

/// Panels of stacked box plots side by side: each box is the distribution of total
/// timesteps (whiskers min-max, box quartiles, median line), filled blue up to the median
/// mapping timesteps and orange above (coordination), as in Figs. 3 and 4.
pub fn stacked_boxes(panels: &[(String, Vec<StackedBox>)]) -> RgbImage {
    let (panel_w, h, left, bottom, top) = (300i64, 420i64, 70i64, 40i64, 40i64);
    let width = left + panel_w * panels.len() as i64 + 20;
    let mut img = RgbImage::from_pixel(width as u32, h as u32, BG);
    let max = panels
        .iter()
        .flat_map(|(_, boxes)| {
            boxes
                .iter()
                .flat_map(|b| b.mapping.iter().zip(&b.coordination).map(|(m, c)| m + c))
        })
        .fold(1.0f64, f64::max);
    let step = nice_step(max / 6.0);
    let y_max = (max / step).ceil() * step;
    let plot_h = h - top - bottom;
    let y_of = |v: f64| top + plot_h - (v / y_max * plot_h as f64).round() as i64;
    let mut tick = 0.0;
    while tick <= y_max + 1e-9 {
        let y = y_of(tick);
        rect(&mut img, left, y, panel_w * panels.len() as i64, 1, GRID);
        let label = if step >= 1000.0 {
            format!("{}k", tick / 1000.0)
        } else {
            format!("{tick}")
        };
        text(
            &mut img,
            left - 8 - text_width(&label, 2),
            y - 5,
            &label,
            2,
            INK,
        );
        tick += step;
    }
    for (p, (title, boxes)) in panels.iter().enumerate() {
        let x0 = left + p as i64 * panel_w;
        rect(&mut img, x0, top, 1, plot_h, INK);
        text(
            &mut img,
            x0 + panel_w / 2 - text_width(title, 3) / 2,
            8,
            title,
            3,
            INK,
        );
        let slot = (panel_w - 20) / boxes.len().max(1) as i64;
        for (i, b) in boxes.iter().enumerate() {
            if b.mapping.is_empty() {
                continue;
            }
            let totals: Vec<f64> = b
                .mapping
                .iter()
                .zip(&b.coordination)
                .map(|(m, c)| m + c)
                .collect();
            let [lo, q1, med, q3, hi] = quartiles(&totals);
            let mapping_median = quartiles(&b.mapping)[2];
            let cx = x0 + 10 + slot * i as i64 + slot / 2;
            let bw = (slot * 3 / 5).max(4);
            // Stacked fill: mapping from 0 to its median, coordination on top to the total median.
            rect(
                &mut img,
                cx - bw / 2,
                y_of(mapping_median),
                bw,
                y_of(0.0) - y_of(mapping_median),
                MAPPING,
            );
            rect(
                &mut img,
                cx - bw / 2,
                y_of(med),
                bw,
                y_of(mapping_median) - y_of(med),
                COORDINATION,
            );
            // Box and whiskers of the total.
            rect(&mut img, cx, y_of(hi), 1, y_of(q3) - y_of(hi), INK);
            rect(&mut img, cx, y_of(q1), 1, y_of(lo) - y_of(q1), INK);
            rect(&mut img, cx - bw / 4, y_of(hi), bw / 2, 1, INK);
            rect(&mut img, cx - bw / 4, y_of(lo), bw / 2, 1, INK);
            rect(&mut img, cx - bw / 2 - 2, y_of(q3), bw + 4, 1, INK);
            rect(&mut img, cx - bw / 2 - 2, y_of(q1), bw + 4, 1, INK);
            rect(
                &mut img,
                cx - bw / 2 - 2,
                y_of(q3),
                1,
                y_of(q1) - y_of(q3) + 1,
                INK,
            );
            rect(
                &mut img,
                cx + bw / 2 + 2,
                y_of(q3),
                1,
                y_of(q1) - y_of(q3) + 1,
                INK,
            );
            rect(&mut img, cx - bw / 2 - 2, y_of(med), bw + 5, 2, INK);
            text(
                &mut img,
                cx - text_width(&b.label, 2) / 2,
                h - bottom + 8,
                &b.label,
                2,
                INK,
            );
        }
    }
    rect(
        &mut img,
        left,
        y_of(0.0),
        panel_w * panels.len() as i64,
        1,
        INK,
    );
    img
}

fn nice_step(raw: f64) -> f64 {
    let mag = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag)
}

/// Draws a 2-pixel line.
fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), color: Rgb<u8>) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as i64).max(1);
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let (x, y) = (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
        rect(img, x.round() as i64, y.round() as i64, 2, 2, color);
    }
}

/// Colours of the children in path plots.
const CHILDREN: [Rgb<u8>; 6] = [
    Rgb([204, 0, 0]),
    Rgb([52, 101, 164]),
    Rgb([78, 154, 6]),
    Rgb([117, 80, 123]),
    Rgb([206, 92, 0]),
    Rgb([193, 125, 17]),
];

/// A top view of an occupancy grid: occupied cells grey, vertices as dots; `to_px` maps
/// world metres to pixels.
fn grid_canvas(grid: &hetsim_msgs::OccupancyGrid) -> (RgbImage, impl Fn([f64; 2]) -> (f64, f64)) {
    let (wm, hm) = (
        grid.cols as f64 * grid.cell_m,
        grid.rows as f64 * grid.cell_m,
    );
    let scale = (900.0 / wm.max(hm)).min(80.0);
    let pad = 30.0;
    let (w, h) = (
        (wm * scale + 2.0 * pad) as u32,
        (hm * scale + 2.0 * pad) as u32,
    );
    let mut img = RgbImage::from_pixel(w, h, BG);
    let (ox, oy) = (grid.origin_x, grid.origin_y);
    let to_px = move |p: [f64; 2]| {
        (
            pad + (p[0] - ox) * scale,
            h as f64 - pad - (p[1] - oy) * scale,
        )
    };
    let cell = (scale * grid.cell_m).ceil() as i64;
    for row in 0..grid.rows {
        for col in 0..grid.cols {
            let c = grid.centre_of(col, row);
            let (x, y) = to_px([c[0] - grid.cell_m / 2.0, c[1] + grid.cell_m / 2.0]);
            if grid.occupied[row * grid.cols + col] {
                rect(
                    &mut img,
                    x as i64,
                    y as i64,
                    cell,
                    cell,
                    Rgb([170, 170, 170]),
                );
            } else {
                let (cx, cy) = to_px(c);
                rect(&mut img, cx as i64 - 1, cy as i64 - 1, 3, 3, INK);
            }
        }
    }
    // The outline.
    let (x0, y1) = to_px([ox, oy]);
    let (x1, y0) = to_px([ox + wm, oy + hm]);
    for (a, b) in [
        ((x0, y0), (x1, y0)),
        ((x1, y0), (x1, y1)),
        ((x1, y1), (x0, y1)),
        ((x0, y1), (x0, y0)),
    ] {
        line(&mut img, a, b, INK);
    }
    (img, to_px)
}

/// An arrow from `a` to `b` (pixels): a line and a two-stroke head.
fn arrow(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), color: Rgb<u8>) {
    line(img, a, b, color);
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len = dx.hypot(dy).max(1e-9);
    let (ux, uy) = (dx / len, dy / len);
    for side in [-1.0, 1.0] {
        let (hx, hy) = (
            b.0 - 10.0 * ux + side * 5.0 * -uy,
            b.1 - 10.0 * uy + side * 5.0 * ux,
        );
        line(img, b, (hx, hy), color);
    }
}

/// Fig. 5(a) of seed 002: the grid of vertices, the parent vertices (squares) and the
/// parent's tour between them (arrows, in visiting order from the start).
pub fn coverage_plan_plot(
    grid: &hetsim_msgs::OccupancyGrid,
    start: [f64; 2],
    parent_vertices: &[[f64; 2]],
) -> RgbImage {
    let (mut img, to_px) = grid_canvas(grid);
    let mut previous = to_px(start);
    for p in parent_vertices {
        let q = to_px(*p);
        arrow(&mut img, previous, q, COORDINATION);
        previous = q;
    }
    for p in parent_vertices {
        let (x, y) = to_px(*p);
        let s = 12;
        rect(&mut img, x as i64 - s / 2, y as i64 - s / 2, s, s, MAPPING);
    }
    let (sx, sy) = to_px(start);
    rect(&mut img, sx as i64 - 4, sy as i64 - 4, 8, 8, INK);
    img
}

/// Fig. 5(b) of seed 002: the children's paths as the parent's tracker measured them (one
/// colour per child) and the parent vertices (squares).
pub fn child_paths_plot(
    grid: &hetsim_msgs::OccupancyGrid,
    parent_vertices: &[[f64; 2]],
    paths: &[Vec<[f64; 2]>],
) -> RgbImage {
    let (mut img, to_px) = grid_canvas(grid);
    for (k, path) in paths.iter().enumerate() {
        let color = CHILDREN[k % CHILDREN.len()];
        for pair in path.windows(2) {
            line(&mut img, to_px(pair[0]), to_px(pair[1]), color);
        }
    }
    for p in parent_vertices {
        let (x, y) = to_px(*p);
        let s = 14;
        rect(&mut img, x as i64 - s / 2, y as i64 - s / 2, s, 2, INK);
        rect(&mut img, x as i64 - s / 2, y as i64 + s / 2 - 2, s, 2, INK);
        rect(&mut img, x as i64 - s / 2, y as i64 - s / 2, 2, s, INK);
        rect(&mut img, x as i64 + s / 2 - 2, y as i64 - s / 2, 2, s, INK);
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_are_drawn_where_the_values_say() {
        let b = |m: f64, c: f64| StackedBox {
            label: "1".into(),
            mapping: vec![m; 3],
            coordination: vec![c; 3],
        };
        let img = stacked_boxes(&[("0%".into(), vec![b(600.0, 400.0), b(300.0, 100.0)])]);
        // Some pixels carry each fill colour, and the taller box has more mapping fill.
        let count = |color: Rgb<u8>, x0: u32, x1: u32| {
            (x0..x1)
                .flat_map(|x| (0..img.height()).map(move |y| (x, y)))
                .filter(|&(x, y)| *img.get_pixel(x, y) == color)
                .count()
        };
        let half = 70 + 10 + 140;
        let (m1, m2) = (count(MAPPING, 70, half), count(MAPPING, half, img.width()));
        assert!(m1 > 0 && m2 > 0);
        assert!((m1 as f64 / m2 as f64 - 2.0).abs() < 0.2, "{m1} vs {m2}");
        assert!(count(COORDINATION, 70, img.width()) > 0);
    }

    #[test]
    fn quartiles_of_known_values() {
        assert_eq!(
            quartiles(&[1.0, 2.0, 3.0, 4.0, 5.0]),
            [1.0, 2.0, 3.0, 4.0, 5.0]
        );
    }

    #[test]
    fn coverage_plots_mark_parent_vertices_and_paths() {
        let grid = hetsim_msgs::OccupancyGrid {
            origin_x: -2.0,
            origin_y: -1.0,
            cell_m: 0.5,
            cols: 8,
            rows: 4,
            occupied: (0..32).map(|i| i == 9).collect(),
        };
        let count = |img: &RgbImage, c: Rgb<u8>| img.pixels().filter(|p| **p == c).count();
        let plan = coverage_plan_plot(&grid, [-1.75, -0.75], &[[0.25, 0.25], [1.25, 0.75]]);
        assert!(count(&plan, MAPPING) >= 2 * 144, "two parent squares");
        assert!(count(&plan, COORDINATION) > 100, "the tour");
        // One occupied 0.5 m cell at 80 px/m (the tour's line may cross it).
        let grey = count(&plan, Rgb([170, 170, 170]));
        assert!(
            (1400..=1600).contains(&grey),
            "one occupied cell: {grey} px"
        );
        let paths = child_paths_plot(
            &grid,
            &[[0.25, 0.25]],
            &[vec![[-1.75, -0.25], [1.75, -0.25]], vec![]],
        );
        assert!(
            count(&paths, CHILDREN[0]) > 2 * 280,
            "a 3.5 m path at 80 px/m"
        );
        assert_eq!(count(&paths, CHILDREN[1]), 0);
    }
}
