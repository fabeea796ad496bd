//! The children's localization along new paths (seed 002, Section V.B): each path's particle
//! filter error against the distance driven, one colour per image feature, on a logarithmic
//! error axis with the 0.5 m convergence threshold marked.

use super::{legend, render, Result, Swatch, COLOURS, FONT};
use crate::localize::PathRun;
use plotters::coord::Shift;
use plotters::prelude::*;

/// The convergence threshold of [`PathRun::converged_at`], metres.
const CONVERGED_M: f64 = 0.5;

/// The figure as PNG bytes: every run of `runs`, coloured by its feature (in order of first
/// appearance), errors clamped to the axis' [1 cm, 10 m].
pub fn localization_png(title: &str, runs: &[PathRun]) -> Vec<u8> {
    render((1000, 520), |root| draw(root, title, runs))
}

fn draw(root: &DrawingArea<BitMapBackend<'_>, Shift>, title: &str, runs: &[PathRun]) -> Result<()> {
    let root = root.titled(title, (FONT, 22))?;
    let mut features: Vec<&str> = Vec::new();
    for r in runs {
        if !features.contains(&r.feature.as_str()) {
            features.push(&r.feature);
        }
    }
    let colour = |f: &str| COLOURS[features.iter().position(|g| *g == f).unwrap_or(0) % 6];
    let grey = RGBColor(110, 110, 110);
    let mut entries: Vec<(&str, Swatch)> = features
        .iter()
        .map(|f| (*f, Swatch::Line(colour(f).stroke_width(2))))
        .collect();
    entries.push(("converged (0.5 m)", Swatch::Line(grey.stroke_width(1))));
    let root = legend(&root, &entries)?;
    let d_max = runs
        .iter()
        .flat_map(|r| r.distance_m.iter().copied())
        .fold(1.0f64, f64::max);
    let (lo, hi) = (0.01, 10.0);
    let mut chart = ChartBuilder::on(&root)
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..d_max, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("distance driven [m]")
        .y_desc("position error [m]")
        .y_label_formatter(&|v| format!("{v}"))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .draw()?;
    chart.draw_series(LineSeries::new(
        [(0.0, CONVERGED_M), (d_max, CONVERGED_M)],
        grey.stroke_width(1),
    ))?;
    for r in runs {
        let style = colour(&r.feature).stroke_width(2);
        let points: Vec<(f64, f64)> = r
            .distance_m
            .iter()
            .zip(&r.errors_m)
            .filter(|(d, e)| d.is_finite() && e.is_finite())
            .map(|(d, e)| (*d, e.clamp(lo, hi)))
            .collect();
        // Segment by segment: a wide polyline's mitred joints spike at sharp turns.
        chart.draw_series(
            points
                .windows(2)
                .map(|w| PathElement::new(vec![w[0], w[1]], style)),
        )?;
        chart.draw_series(points.iter().map(|p| Circle::new(*p, 3, style.filled())))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(feature: &str, errors: &[f64]) -> PathRun {
        PathRun {
            feature: feature.into(),
            steps: errors.len(),
            errors_m: errors.to_vec(),
            distance_m: (0..errors.len()).map(|i| 0.5 * i as f64).collect(),
            converged_at: None,
            final_error_m: *errors.last().unwrap(),
        }
    }

    #[test]
    fn each_feature_has_its_colour_and_a_path_falls_left_to_right() {
        let img = image::load_from_memory(&localization_png(
            "test",
            &[
                run("wgoh", &[3.0, 1.0, 0.3, 0.05]),
                run("pixelwise", &[2.0, 2.0, 2.0, 2.0]),
            ],
        ))
        .unwrap()
        .to_rgb8();
        let rows_of = |c: RGBColor| -> Vec<(u32, u32)> {
            img.enumerate_pixels()
                .filter(|(_, y, p)| *y > 80 && p.0 == [c.0, c.1, c.2])
                .map(|(x, y, _)| (x, y))
                .collect()
        };
        let (wgoh, pixelwise) = (rows_of(COLOURS[0]), rows_of(COLOURS[1]));
        assert!(wgoh.len() > 200 && pixelwise.len() > 200);
        // The falling path: its leftmost pixels are higher in the image than its rightmost.
        let mean_y = |pts: &[(u32, u32)], left: bool| {
            let xs: Vec<u32> = pts.iter().map(|p| p.0).collect();
            let (min, max) = (*xs.iter().min().unwrap(), *xs.iter().max().unwrap());
            let cut = if left { min + 20 } else { max - 20 };
            let sel: Vec<f64> = pts
                .iter()
                .filter(|p| if left { p.0 <= cut } else { p.0 >= cut })
                .map(|p| p.1 as f64)
                .collect();
            sel.iter().sum::<f64>() / sel.len() as f64
        };
        assert!(mean_y(&wgoh, true) + 100.0 < mean_y(&wgoh, false));
        // The flat one stays level within its line width and markers.
        assert!((mean_y(&pixelwise, true) - mean_y(&pixelwise, false)).abs() < 4.0);
    }
}
