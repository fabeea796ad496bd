//! Every figure hetsim draws, with `plotters`: axes with ticks and units, a title, a legend
//! naming every series, text in DejaVu Sans (embedded, so a figure is the same bytes on any
//! machine, with no system font or font library).
//!
//! [`trajectories_png`] is Fig. 7 of seed 000 as the seed draws it: the top view (x east,
//! y north, equal scales) on the left, the altitude against time on the right, each estimate
//! beside the truth, and the SLAM events as labelled vertical lines on the time axis.

use image::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::sync::Once;

mod boxes;
mod coverage;
mod lines;
mod localization;
pub use boxes::{boxes_png, BoxPanel};
pub use coverage::{coverage_map_png, stacked_boxes_png, CoverageMap, StackedBox};
pub use lines::lines_png;
pub use localization::localization_png;

/// A figure's font family, registered once from the embedded DejaVu Sans.
const FONT: &str = "sans-serif";

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font (the dejavu crate's); a failure here is a
        // build defect, not an input.
        plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
            .unwrap_or_else(|_| panic!("the embedded DejaVu Sans is a valid font"));
    });
}

/// Series colours, in order: a colour-blind-safe set (Okabe-Ito), the truth in black.
const COLOURS: [RGBColor; 6] = [
    RGBColor(0, 114, 178),
    RGBColor(230, 159, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(213, 94, 0),
    RGBColor(86, 180, 233),
];

/// One estimate: its legend label and its positions `(ns since the figure's start, [x, y, z]
/// metres)`.
pub struct Series<'a> {
    /// The legend's name for it.
    pub label: &'a str,
    /// Stamped positions.
    pub points: &'a [(u64, [f64; 3])],
}

/// A vertical line on the time axis: `(seconds since the figure's start, label)`.
pub type Mark = (f64, String);

/// The figure's size, pixels.
const SIZE: (u32, u32) = (1400, 620);

/// Fig. 7 of seed 000 (see the module docs) as PNG bytes: `truth` in black and each of
/// `series` in its colour, `marks` on the altitude panel. Points that are not finite are
/// left out (they would have no place on the axes).
pub fn trajectories_png(
    title: &str,
    truth: &[(u64, [f64; 3])],
    series: &[Series<'_>],
    marks: &[Mark],
) -> Vec<u8> {
    render(SIZE, |root| draw(root, title, truth, series, marks))
}

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

/// Draws a figure of `(width, height)` pixels on white with `draw`, as PNG bytes. Drawing
/// into a memory buffer fails only on a defect of the figure's code.
fn render(
    (w, h): (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Vec<u8> {
    register_font();
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE)
            .and_then(|()| draw(&root))
            .and_then(|()| root.present())
            .unwrap_or_else(|e| panic!("drawing into a memory buffer: {e}"));
    }
    let img = RgbImage::from_raw(w, h, buf).expect("the buffer is w x h x 3");
    png(&img)
}

/// How a legend entry shows its mark: as the figure draws it.
#[derive(Clone, Copy)]
enum Swatch {
    /// A line (a series).
    Line(ShapeStyle),
    /// A filled area (a bar, an obstacle).
    Area(ShapeStyle),
    /// A dot.
    Dot(ShapeStyle),
    /// A small square.
    Square(ShapeStyle),
    /// A cross.
    Cross(ShapeStyle),
    /// A triangle.
    Triangle(ShapeStyle),
}

/// Where each legend entry goes in an area `width` pixels wide: `(x, row)` of its swatch,
/// left to right, wrapping to a new row where the next would not fit.
fn legend_layout(entries: &[(&str, Swatch)], width: u32) -> Vec<(i32, i32)> {
    let (mut x, mut row) = (90, 0);
    let mut places = Vec::new();
    for (label, _) in entries {
        let w = 70 + 9 * label.chars().count() as i32;
        if x > 90 && x + w - 20 > width as i32 {
            (x, row) = (90, row + 1);
        }
        places.push((x, row));
        x += w;
    }
    places
}

/// The height of the legend strip for `entries` in an area `width` pixels wide.
fn legend_height(entries: &[(&str, Swatch)], width: u32) -> u32 {
    let rows = legend_layout(entries, width)
        .last()
        .map_or(1, |(_, row)| row + 1);
    34 + 26 * (rows as u32 - 1)
}

/// Draws a legend in a strip of its own at the top of `area` (under a title: it never hides
/// data), a swatch and a name per entry, and returns the rest of the area.
fn legend<'a>(
    area: &DrawingArea<BitMapBackend<'a>, Shift>,
    entries: &[(&str, Swatch)],
) -> Result<DrawingArea<BitMapBackend<'a>, Shift>> {
    let width = area.dim_in_pixel().0;
    let (strip, rest) = area.split_vertically(legend_height(entries, width));
    for ((label, style), (x, row)) in entries.iter().zip(legend_layout(entries, width)) {
        let y = 26 * row;
        match *style {
            Swatch::Line(style) => strip.draw(&PathElement::new(
                vec![(x, y + 17), (x + 30, y + 17)],
                style,
            ))?,
            Swatch::Area(style) => {
                strip.draw(&Rectangle::new([(x, y + 9), (x + 30, y + 25)], style))?
            }
            Swatch::Dot(style) => strip.draw(&Circle::new((x + 15, y + 17), 3, style))?,
            Swatch::Square(style) => {
                strip.draw(&Rectangle::new([(x + 9, y + 11), (x + 21, y + 23)], style))?
            }
            Swatch::Cross(style) => strip.draw(&Cross::new((x + 15, y + 17), 5, style))?,
            Swatch::Triangle(style) => {
                strip.draw(&TriangleMarker::new((x + 15, y + 17), 8, style))?
            }
        }
        strip.draw(&Text::new(label.to_string(), (x + 38, y + 8), (FONT, 16)))?;
    }
    Ok(rest)
}

type Result<T> = std::result::Result<
    T,
    DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>,
>;

fn finite(p: &(u64, [f64; 3])) -> bool {
    p.1.iter().all(|v| v.is_finite())
}

/// `[lo, hi]` of `values`, widened to at least `min_span` about its centre.
fn range(values: impl Iterator<Item = f64>, min_span: f64) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        return (0.0, min_span);
    }
    let mid = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo).max(min_span);
    (mid - half, mid + half)
}

fn draw(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    title: &str,
    truth: &[(u64, [f64; 3])],
    series: &[Series<'_>],
    marks: &[Mark],
) -> Result<()> {
    let root = root.titled(title, (FONT, 24))?;
    // The legend in a strip of its own under the title: it never hides data or marks.
    let entries: Vec<(&str, Swatch)> = series
        .iter()
        .enumerate()
        .map(|(k, s)| {
            (
                s.label,
                Swatch::Line(COLOURS[k % COLOURS.len()].stroke_width(3)),
            )
        })
        .chain(std::iter::once((
            "truth",
            Swatch::Line(BLACK.stroke_width(3)),
        )))
        .collect();
    let root = legend(&root, &entries)?;
    let (left, right) = root.split_horizontally(SIZE.1 as i32 - 20 - 34);
    let all = || {
        truth
            .iter()
            .chain(series.iter().flat_map(|s| s.points.iter()))
            .filter(|p| finite(p))
    };
    let style = |k: usize| COLOURS[k % COLOURS.len()].stroke_width(2);
    let truth_style = BLACK.stroke_width(2);

    // Top view with equal scales: the ranges take the plotting area's aspect ratio.
    let (label_x, label_y, margin) = (50u32, 70u32, 15u32);
    let left = left.titled("top view (equal scales)", (FONT, 18))?;
    let (pw, ph) = left.dim_in_pixel();
    let (aw, ah) = (
        (pw - label_y - 2 * margin) as f64,
        (ph - label_x - 2 * margin) as f64,
    );
    let (x0, x1) = range(all().map(|p| p.1[0]), 1.0);
    let (y0, y1) = range(all().map(|p| p.1[1]), 1.0);
    let per_px = ((x1 - x0) / aw).max((y1 - y0) / ah) * 1.05;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (hx, hy) = (0.5 * per_px * aw, 0.5 * per_px * ah);
    let mut top = ChartBuilder::on(&left)
        .margin(margin)
        .x_label_area_size(label_x)
        .y_label_area_size(label_y)
        .build_cartesian_2d(cx - hx..cx + hx, cy - hy..cy + hy)?;
    top.configure_mesh()
        .x_desc("x east [m]")
        .y_desc("y north [m]")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    let xy = |pts: &[(u64, [f64; 3])]| -> Vec<(f64, f64)> {
        pts.iter()
            .filter(|p| finite(p))
            .map(|p| (p.1[0], p.1[1]))
            .collect()
    };
    for (k, s) in series.iter().enumerate() {
        top.draw_series(LineSeries::new(xy(s.points), style(k)))?;
    }
    top.draw_series(LineSeries::new(xy(truth), truth_style))?;
    if let Some(start) = truth.iter().find(|p| finite(p)) {
        top.draw_series(std::iter::once(Circle::new(
            (start.1[0], start.1[1]),
            5,
            BLACK.filled(),
        )))?;
    }

    // Altitude against time, with the events.
    let secs = |t: u64| t as f64 * 1e-9;
    let (t0, t1) = range(all().map(|p| secs(p.0)), 1.0);
    let (z0, z1) = range(all().map(|p| p.1[2]), 2.0);
    let pad = 0.05 * (z1 - z0);
    let right = right.titled("altitude", (FONT, 18))?;
    let mut alt = ChartBuilder::on(&right)
        .margin(margin)
        .x_label_area_size(label_x)
        .y_label_area_size(label_y)
        .build_cartesian_2d(t0.min(0.0)..t1, z0 - pad..z1 + pad)?;
    alt.configure_mesh()
        .x_desc("time [s]")
        .y_desc("z up [m]")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    let tz = |pts: &[(u64, [f64; 3])]| -> Vec<(f64, f64)> {
        pts.iter()
            .filter(|p| finite(p))
            .map(|p| (secs(p.0), p.1[2]))
            .collect()
    };
    for (k, s) in series.iter().enumerate() {
        alt.draw_series(LineSeries::new(tz(s.points), style(k)))?;
    }
    alt.draw_series(LineSeries::new(tz(truth), truth_style))?;
    let grey = RGBColor(110, 110, 110);
    for (k, (t, label)) in marks.iter().filter(|m| m.0.is_finite()).enumerate() {
        alt.draw_series(LineSeries::new(
            [(*t, z0 - pad), (*t, z1 + pad)],
            grey.stroke_width(1),
        ))?;
        // Labels in three rows from the top, so that events seconds apart stay legible.
        let row = (k % 3) as f64;
        alt.draw_series(std::iter::once(Text::new(
            format!(" {label}"),
            (*t, z1 + pad - (0.01 + 0.045 * row) * (z1 - z0 + 2.0 * pad)),
            (FONT, 13).into_font().color(&grey),
        )))?;
    }
    Ok(())
}

/// The robot pose's NEES averaged over `runs` Monte Carlo runs against time (log scale),
/// with the two-sided 95 % interval `(lo, hi)` of a consistent estimate shaded, as PNG bytes.
pub fn nees_png(robot: &str, avg: &[(f64, f64)], (lo, hi): (f64, f64), runs: usize) -> Vec<u8> {
    render((1000, 480), |root| {
        draw_nees(root, robot, avg, (lo, hi), runs)
    })
}

fn draw_nees(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    robot: &str,
    avg: &[(f64, f64)],
    (lo, hi): (f64, f64),
    runs: usize,
) -> Result<()> {
    let pts: Vec<(f64, f64)> = avg
        .iter()
        .copied()
        .filter(|p| p.0.is_finite() && p.1.is_finite() && p.1 > 0.0)
        .collect();
    let (t0, t1) = range(pts.iter().map(|p| p.0), 1.0);
    let y0 = pts.iter().map(|p| p.1).fold(lo, f64::min) * 0.8;
    let y1 = pts.iter().map(|p| p.1).fold(hi, f64::max) * 1.25;
    let title = format!("{robot}: robot pose NEES averaged over {runs} runs");
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT, 22))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(t0.min(0.0)..t1, (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time [s]")
        .y_desc("NEES (6 expected), log scale")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    let band = RGBColor(200, 230, 200);
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(t0.min(0.0), lo), (t1, hi)],
            band.filled(),
        )))?
        .label(format!(
            "95 % interval of a consistent estimate [{lo:.2}, {hi:.2}]"
        ))
        .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 24, y + 6)], band.filled()));
    chart
        .draw_series(LineSeries::new(pts, COLOURS[0].stroke_width(2)))?
        .label("NEES averaged over the runs")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], COLOURS[0].stroke_width(3)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font((FONT, 14))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(png: &[u8]) -> RgbImage {
        image::load_from_memory(png).unwrap().to_rgb8()
    }

    fn count(img: &RgbImage, c: RGBColor) -> usize {
        img.pixels().filter(|p| p.0 == [c.0, c.1, c.2]).count()
    }

    #[test]
    fn every_series_the_truth_and_the_labels_are_drawn() {
        let truth: Vec<(u64, [f64; 3])> = (0..50)
            .map(|k| (k * 1_000_000_000, [k as f64, 0.0, 10.0]))
            .collect();
        let a: Vec<_> = truth.iter().map(|(t, p)| (*t, [p[0], 2.0, 11.0])).collect();
        let b: Vec<_> = truth.iter().map(|(t, p)| (*t, [p[0], -2.0, 9.0])).collect();
        let series = [
            Series {
                label: "VO",
                points: &a,
            },
            Series {
                label: "SLAM",
                points: &b,
            },
        ];
        let with = decode(&trajectories_png(
            "test",
            &truth,
            &series,
            &[(20.0, "event".into())],
        ));
        assert_eq!(with.dimensions(), SIZE);
        // Two panels of 2-pixel lines about 50 m long: hundreds of pixels of each colour.
        assert!(count(&with, COLOURS[0]) > 400, "the first series");
        assert!(count(&with, COLOURS[1]) > 400, "the second series");
        assert!(count(&with, BLACK) > 400, "the truth, axes and text");
        // Text is drawn: a figure without the title, labels and legend has fewer dark pixels.
        let without = decode(&trajectories_png("", &truth, &[], &[]));
        let dark = |img: &RgbImage| {
            img.pixels()
                .filter(|p| p.0.iter().all(|v| *v < 100))
                .count()
        };
        assert!(dark(&with) > dark(&without));
    }

    #[test]
    fn the_top_view_keeps_equal_scales() {
        // A 50 m square as a series: in a panel that is not square, unequal scales would
        // draw it as a rectangle.
        let square: Vec<(u64, [f64; 3])> = [
            [0.0, 0.0],
            [50.0, 0.0],
            [50.0, 50.0],
            [0.0, 50.0],
            [0.0, 0.0],
        ]
        .iter()
        .enumerate()
        .map(|(k, p)| (k as u64 * 1_000_000_000, [p[0], p[1], 0.0]))
        .collect();
        let series = [Series {
            label: "square",
            points: &square,
        }];
        let img = decode(&trajectories_png("", &[], &series, &[]));
        let left_panel = SIZE.1 - 20;
        let (mut x0, mut x1, mut y0, mut y1) = (u32::MAX, 0, u32::MAX, 0);
        for (x, y, p) in img.enumerate_pixels() {
            // Below the title and the legend strip (whose sample line has the colour too).
            if x < left_panel && y > 70 && p.0 == [COLOURS[0].0, COLOURS[0].1, COLOURS[0].2] {
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
        }
        let (wide, tall) = (x1 - x0, y1 - y0);
        assert!(wide > 200, "the square fills the panel: {wide} px");
        assert!(wide.abs_diff(tall) <= 3, "{wide} x {tall} px");
    }

    #[test]
    fn non_finite_points_are_left_out_and_the_rest_is_drawn() {
        // A series whose middle is not finite: the finite parts are still drawn, on axes that
        // the non-finite values do not stretch (a NaN or infinity in the range would leave
        // nothing on the canvas).
        let points: Vec<(u64, [f64; 3])> = (0..40)
            .map(|k| {
                let p = [k as f64, (k as f64).sin(), 10.0 + 0.1 * k as f64];
                let p = match k {
                    10 => [f64::NAN, p[1], p[2]],
                    20 => [p[0], p[1], f64::INFINITY],
                    _ => p,
                };
                (k * 1_000_000_000, p)
            })
            .collect();
        let series = [Series {
            label: "gappy",
            points: &points,
        }];
        let img = decode(&trajectories_png(
            "nan",
            &[],
            &series,
            &[(f64::NAN, "x".into())],
        ));
        assert_eq!(img.dimensions(), SIZE);
        assert!(count(&img, COLOURS[0]) > 400, "the finite points are drawn");
    }
}
