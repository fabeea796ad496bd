//! Seed 002's figures drawn with `plotters`: the stacked box plots of Figs. 3 and 4 (total
//! timesteps per number of children, split into mapping and coordination) and the coverage
//! maps of Fig. 5 (the grid's vertices, the obstacles, the parent vertices and the parent's
//! tour; the children's tracked paths and the places they grabbed their images). Every figure
//! has axes with ticks and units, a title and a legend naming each mark.

use super::{legend, legend_height, render, Result, Swatch, COLOURS, FONT};
use hetsim_msgs::OccupancyGrid;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Mapping's fill in the box plots (Okabe-Ito blue), coordination's (orange).
pub(crate) const MAPPING: RGBColor = RGBColor(0, 114, 178);
pub(crate) const COORDINATION: RGBColor = RGBColor(230, 159, 0);
/// Obstacle cells on the coverage maps.
pub(crate) const OBSTACLE: RGBColor = RGBColor(170, 170, 170);
/// The grid's vertices (free cells' centres).
const VERTEX: RGBColor = RGBColor(90, 90, 90);

/// One box of a panel: the mapping and coordination timesteps of each run.
pub struct StackedBox {
    /// Label under the box (the number of children).
    pub label: String,
    /// Mapping timesteps per run.
    pub mapping: Vec<f64>,
    /// Coordination timesteps per run.
    pub coordination: Vec<f64>,
}

/// Min, quartiles and max by linear interpolation between order statistics (NumPy's
/// default), of a non-empty slice.
pub(crate) fn quartiles(values: &[f64]) -> [f64; 5] {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let pos = p * (v.len() - 1) as f64;
        let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
        v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
    };
    [v[0], q(0.25), q(0.5), q(0.75), v[v.len() - 1]]
}

/// Figs. 3 and 4 of seed 002 as PNG bytes: panels side by side on a shared timestep axis,
/// one box per number of children. A box is the distribution of the total timesteps (whiskers
/// min-max, box quartiles, black line the median); behind it a bar filled with the median
/// mapping timesteps and, above that, coordination up to the median total.
pub fn stacked_boxes_png(title: &str, panels: &[(String, Vec<StackedBox>)]) -> Vec<u8> {
    let width = (120 + 330 * panels.len() as u32).max(900);
    render((width, 560), |root| draw_boxes(root, title, panels))
}

fn draw_boxes(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    panels: &[(String, Vec<StackedBox>)],
) -> Result<()> {
    let root = root.titled(title, (FONT, 22))?;
    let root = legend(
        &root,
        &[
            ("mapping, median", Swatch::Area(MAPPING.filled())),
            ("coordination, median", Swatch::Area(COORDINATION.filled())),
            (
                "total: median, quartiles, min-max",
                Swatch::Line(BLACK.stroke_width(2)),
            ),
        ],
    )?;
    let totals = |b: &StackedBox| -> Vec<f64> {
        b.mapping
            .iter()
            .zip(&b.coordination)
            .map(|(m, c)| m + c)
            .collect()
    };
    let max = panels
        .iter()
        .flat_map(|(_, boxes)| boxes.iter().flat_map(totals))
        .fold(1.0f64, f64::max);
    let y_max = max * 1.05;
    let cells = root.split_evenly((1, panels.len().max(1)));
    for (k, ((name, boxes), area)) in panels.iter().zip(&cells).enumerate() {
        let n = boxes.len().max(1);
        let mut chart = ChartBuilder::on(area)
            .caption(name, (FONT, 18))
            .margin(10)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(0.5..n as f64 + 0.5, 0.0..y_max)?;
        let labels: Vec<String> = boxes.iter().map(|b| b.label.clone()).collect();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&|x| {
                let i = x.round() as usize;
                if (x - x.round()).abs() < 1e-6 && (1..=labels.len()).contains(&i) {
                    labels[i - 1].clone()
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|v| format!("{v:.0}"))
            .x_desc("children")
            .y_desc(if k == 0 { "timesteps" } else { "" })
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .draw()?;
        for (i, b) in boxes.iter().enumerate() {
            if b.mapping.is_empty() {
                continue;
            }
            let x = (i + 1) as f64;
            let [lo, q1, med, q3, hi] = quartiles(&totals(b));
            let mapping = quartiles(&b.mapping)[2];
            let (bar, half) = (0.3, 0.2);
            chart.draw_series([
                Rectangle::new([(x - bar, 0.0), (x + bar, mapping)], MAPPING.filled()),
                Rectangle::new(
                    [(x - bar, mapping), (x + bar, med.max(mapping))],
                    COORDINATION.filled(),
                ),
                Rectangle::new([(x - half, q1), (x + half, q3)], BLACK.stroke_width(2)),
            ])?;
            for segment in [
                [(x, q3), (x, hi)],
                [(x, lo), (x, q1)],
                [(x - half / 2.0, hi), (x + half / 2.0, hi)],
                [(x - half / 2.0, lo), (x + half / 2.0, lo)],
            ] {
                chart.draw_series(LineSeries::new(segment, BLACK.stroke_width(2)))?;
            }
            chart.draw_series(LineSeries::new(
                [(x - half, med), (x + half, med)],
                BLACK.stroke_width(4),
            ))?;
        }
    }
    Ok(())
}

/// What a coverage map shows besides the grid.
pub struct CoverageMap<'a> {
    /// The figure's title.
    pub title: &'a str,
    /// The parent's start, metres.
    pub start: [f64; 2],
    /// The parent vertices in visiting order, metres.
    pub parent_vertices: &'a [[f64; 2]],
    /// Draw the parent's tour between them (start, then each in order).
    pub tour: bool,
    /// The children's paths (name, positions in metres), one colour each.
    pub paths: &'a [(String, Vec<[f64; 2]>)],
    /// Where images were grabbed, metres.
    pub grabs: &'a [[f64; 2]],
}

/// A coverage map as PNG bytes (Fig. 5 of seed 002): the grid at equal scales in metres,
/// obstacle cells grey, every free cell's vertex a dot, parent vertices as squares, and what
/// `map` adds (tour arrows, child paths, grabs), each named in the legend.
pub fn coverage_map_png(grid: &OccupancyGrid, map: &CoverageMap<'_>) -> Vec<u8> {
    let (wm, hm) = (
        grid.cols as f64 * grid.cell_m,
        grid.rows as f64 * grid.cell_m,
    );
    // Pixels per metre: the larger side about 900 pixels, at most 80 per metre.
    let scale = (900.0 / wm.max(hm)).min(80.0);
    let mut entries: Vec<(&str, Swatch)> = vec![
        ("obstacle", Swatch::Area(OBSTACLE.filled())),
        ("vertex", Swatch::Dot(VERTEX.filled())),
        ("parent vertex", Swatch::Square(MAPPING.filled())),
    ];
    if map.tour {
        entries.push(("parent's tour", Swatch::Line(COORDINATION.stroke_width(3))));
    }
    for (k, (name, _)) in map.paths.iter().enumerate() {
        entries.push((name.as_str(), Swatch::Line(child_colour(k).stroke_width(3))));
    }
    if !map.grabs.is_empty() {
        entries.push(("image grabbed", Swatch::Cross(BLACK.stroke_width(2))));
    }
    entries.push(("start", Swatch::Triangle(BLACK.filled())));
    let (label_x, label_y, margin) = (50u32, 70u32, 15u32);
    let width = (wm * scale) as u32 + label_y + 2 * margin;
    // Room for the title (about 26 pixels, and a margin) and the legend's strip above the
    // map; the scales are made equal from the area that is left (`draw_map`).
    let head = 40 + legend_height(&entries, width);
    let size = (width, (hm * scale) as u32 + label_x + 2 * margin + head);
    render(size, |root| {
        draw_map(root, grid, map, &entries, (label_x, label_y, margin))
    })
}

fn draw_map(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    grid: &OccupancyGrid,
    map: &CoverageMap<'_>,
    entries: &[(&str, Swatch)],
    (label_x, label_y, margin): (u32, u32, u32),
) -> Result<()> {
    let root = root.titled(map.title, (FONT, 20))?;
    let root = legend(&root, entries)?;
    // Equal scales: the grid's extent, padded on one axis to the plotting area's aspect.
    let (pw, ph) = root.dim_in_pixel();
    let (aw, ah) = (
        pw.saturating_sub(label_y + 2 * margin).max(1) as f64,
        ph.saturating_sub(label_x + 2 * margin).max(1) as f64,
    );
    let (wm, hm) = (
        grid.cols as f64 * grid.cell_m,
        grid.rows as f64 * grid.cell_m,
    );
    let per_px = (wm / aw).max(hm / ah);
    let (cx, cy) = (grid.origin_x + wm / 2.0, grid.origin_y + hm / 2.0);
    let (x0, x1) = (cx - per_px * aw / 2.0, cx + per_px * aw / 2.0);
    let (y0, y1) = (cy - per_px * ah / 2.0, cy + per_px * ah / 2.0);
    let mut chart = ChartBuilder::on(&root)
        .margin(margin)
        .x_label_area_size(label_x)
        .y_label_area_size(label_y)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    let half = grid.cell_m / 2.0;
    let cells = (0..grid.rows).flat_map(|r| (0..grid.cols).map(move |c| (c, r)));
    let (occupied, free): (Vec<_>, Vec<_>) =
        cells.partition(|(c, r)| grid.occupied[r * grid.cols + c]);
    chart.draw_series(occupied.iter().map(|(c, r)| {
        let p = grid.centre_of(*c, *r);
        Rectangle::new(
            [(p[0] - half, p[1] - half), (p[0] + half, p[1] + half)],
            OBSTACLE.filled(),
        )
    }))?;
    chart.draw_series(free.iter().map(|(c, r)| {
        let p = grid.centre_of(*c, *r);
        Circle::new((p[0], p[1]), 2, VERTEX.filled())
    }))?;
    // Marks of a fixed size on screen, in metres.
    let px = per_px;
    if map.tour {
        let stops: Vec<[f64; 2]> = std::iter::once(map.start)
            .chain(map.parent_vertices.iter().copied())
            .collect();
        for pair in stops.windows(2) {
            chart.draw_series(arrow(pair[0], pair[1], 10.0 * px, COORDINATION))?;
        }
    }
    // A path is broken where it leaves the axes (plotters does not clip lines to the
    // plotting area) and drawn segment by segment: plotters mitres a wide polyline's joints,
    // and the tracker's jitter (a path turning back on itself within a pixel or two) would
    // throw mitre spikes across the figure. Points closer than a pixel are dropped first.
    let inside = |p: &[f64; 2]| (x0..=x1).contains(&p[0]) && (y0..=y1).contains(&p[1]);
    for (k, (_, path)) in map.paths.iter().enumerate() {
        let style = child_colour(k).stroke_width(2);
        for run in path.split(|p| !inside(p)) {
            let points = thinned(run, per_px);
            chart.draw_series(
                points
                    .windows(2)
                    .map(|w| PathElement::new(vec![w[0], w[1]], style)),
            )?;
        }
    }
    let s = 6.0 * px;
    chart.draw_series(map.parent_vertices.iter().map(|p| {
        Rectangle::new(
            [(p[0] - s, p[1] - s), (p[0] + s, p[1] + s)],
            MAPPING.filled(),
        )
    }))?;
    chart.draw_series(
        map.grabs
            .iter()
            .map(|p| Cross::new((p[0], p[1]), 4, BLACK.stroke_width(2))),
    )?;
    chart.draw_series(std::iter::once(TriangleMarker::new(
        (map.start[0], map.start[1]),
        8,
        BLACK.filled(),
    )))?;
    Ok(())
}

/// The points of `path` at least `step` from the last one kept (the first always).
fn thinned(path: &[[f64; 2]], step: f64) -> Vec<(f64, f64)> {
    let mut kept: Vec<(f64, f64)> = Vec::new();
    for p in path {
        if kept
            .last()
            .is_none_or(|q| (p[0] - q.0).hypot(p[1] - q.1) >= step)
        {
            kept.push((p[0], p[1]));
        }
    }
    kept
}

/// A child's colour on the maps (the series colours after the two the map uses itself).
pub(crate) fn child_colour(k: usize) -> RGBColor {
    COLOURS[(k + 2) % COLOURS.len()]
}

/// A line from `a` to `b` with a two-stroke head `head` long, in data units.
fn arrow(a: [f64; 2], b: [f64; 2], head: f64, colour: RGBColor) -> Vec<PathElement<(f64, f64)>> {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dy).max(1e-12);
    let (ux, uy) = (dx / len, dy / len);
    let style = colour.stroke_width(2);
    let mut parts = vec![PathElement::new(vec![(a[0], a[1]), (b[0], b[1])], style)];
    for side in [-1.0, 1.0] {
        let tip = (
            b[0] - head * ux + side * 0.5 * head * -uy,
            b[1] - head * uy + side * 0.5 * head * ux,
        );
        parts.push(PathElement::new(vec![(b[0], b[1]), tip], style));
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::RgbImage;

    fn decode(png: &[u8]) -> RgbImage {
        image::load_from_memory(png).unwrap().to_rgb8()
    }

    /// Pixels of colour `c` within columns `x` and rows `y`.
    fn count(
        img: &RgbImage,
        c: RGBColor,
        x: std::ops::Range<u32>,
        y: std::ops::RangeFrom<u32>,
    ) -> usize {
        img.enumerate_pixels()
            .filter(|(px, py, p)| x.contains(px) && y.contains(py) && p.0 == [c.0, c.1, c.2])
            .count()
    }

    /// Below the title and the legend strip (their swatches carry the colours too).
    const BODY: std::ops::RangeFrom<u32> = 80..;

    #[test]
    fn thinning_keeps_points_a_step_apart() {
        let path = [[0.0, 0.0], [0.1, 0.0], [0.5, 0.0], [0.55, 0.0], [1.6, 0.0]];
        assert_eq!(
            thinned(&path, 0.5),
            vec![(0.0, 0.0), (0.5, 0.0), (1.6, 0.0)]
        );
    }

    #[test]
    fn quartiles_of_known_values() {
        assert_eq!(
            quartiles(&[1.0, 2.0, 3.0, 4.0, 5.0]),
            [1.0, 2.0, 3.0, 4.0, 5.0]
        );
        assert_eq!(quartiles(&[4.0, 0.0]), [0.0, 1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn box_fills_scale_with_the_medians() {
        let b = |m: f64, c: f64| StackedBox {
            label: "1".into(),
            mapping: vec![m; 3],
            coordination: vec![c; 3],
        };
        let img = decode(&stacked_boxes_png(
            "test",
            &[
                ("a".into(), vec![b(600.0, 400.0)]),
                ("b".into(), vec![b(300.0, 100.0)]),
            ],
        ));
        // Panel a's mapping bar is twice panel b's (same width, twice the height), and its
        // coordination bar four times.
        let (mid, w) = (img.width() / 2, img.width());
        let ratio = |c: RGBColor| {
            count(&img, c, 0..mid, BODY) as f64 / count(&img, c, mid..w, BODY).max(1) as f64
        };
        assert!((ratio(MAPPING) - 2.0).abs() < 0.1, "{}", ratio(MAPPING));
        assert!(
            (ratio(COORDINATION) - 4.0).abs() < 0.3,
            "{}",
            ratio(COORDINATION)
        );
    }

    #[test]
    fn a_coverage_map_draws_obstacles_parent_vertices_and_paths_where_they_are() {
        // 8 x 4 cells of 0.5 m: 80 px/m, a cell is 40 x 40 px.
        let grid = OccupancyGrid {
            origin_x: -2.0,
            origin_y: -1.0,
            cell_m: 0.5,
            cols: 8,
            rows: 4,
            occupied: (0..32).map(|i| i == 9).collect(),
        };
        let paths = vec![("child1".to_string(), vec![[-1.75, -0.25], [1.75, -0.25]])];
        let img = decode(&coverage_map_png(
            &grid,
            &CoverageMap {
                title: "test",
                start: [-1.75, -0.75],
                parent_vertices: &[[0.25, 0.25], [1.25, 0.75]],
                tour: true,
                paths: &paths,
                grabs: &[[0.25, 0.25]],
            },
        ));
        // The chart is the bottom of the figure: the 2 m of grid at 80 px/m, the x labels'
        // 50 px and the margins' 30; the title and the wrapped legend lie above it.
        let chart = img.height() - (160 + 50 + 30)..;
        let body = |c: RGBColor| count(&img, c, 0..img.width(), chart.clone());
        // One occupied cell of 40 x 40 px (the tour or a path may cross it).
        let grey = body(OBSTACLE);
        assert!(
            (1400..=1681).contains(&grey),
            "one obstacle cell: {grey} px"
        );
        // Two parent squares of 12 x 12 px (288), less what the tour's arrow heads and the
        // grab's cross draw over them.
        let squares = body(MAPPING);
        assert!((150..=300).contains(&squares), "two squares: {squares} px");
        // The path, 3.5 m at 80 px/m and 2 px wide, less what the squares cover.
        let path = body(child_colour(0));
        assert!(path >= 2 * 250, "a 3.5 m path: {path} px");
        assert!(body(COORDINATION) > 100, "the tour");
    }
}
