//! Box plots of a whole-run sweep: one panel per metric, one box per cell of the sweep
//! (whiskers min-max, box quartiles, thick line the median, every run as a dot), so a
//! spread that a mean hides shows.

use super::coverage::quartiles;
use super::{legend, render, Result, Swatch, COLOURS, FONT};
use plotters::coord::Shift;
use plotters::prelude::*;

/// One panel: a metric's name and, per cell, its label and the runs' values.
pub struct BoxPanel {
    /// The metric (the panel's caption and y axis).
    pub title: String,
    /// `(cell label, values of its runs)`, in cell order.
    pub boxes: Vec<(String, Vec<f64>)>,
}

/// The panels on a grid of up to three columns, as PNG bytes; `x_desc` names what the boxes'
/// labels are. Values that are not finite are left out; a box with no values is left empty.
pub fn boxes_png(title: &str, x_desc: &str, panels: &[BoxPanel]) -> Vec<u8> {
    let columns = panels.len().clamp(1, 3);
    let rows = panels.len().div_ceil(columns).max(1);
    let width = (columns as u32 * 480).max(900);
    let height = 120 + rows as u32 * 420;
    render((width, height), |root| {
        draw(root, (title, x_desc), panels, (rows, columns))
    })
}

fn draw(
    root: &DrawingArea<BitMapBackend<'_>, Shift>,
    (title, x_desc): (&str, &str),
    panels: &[BoxPanel],
    (rows, columns): (usize, usize),
) -> Result<()> {
    let root = root.titled(title, (FONT, 20))?;
    let root = legend(
        &root,
        &[
            (
                "median, quartiles, min-max over the seeds",
                Swatch::Line(BLACK.stroke_width(2)),
            ),
            ("one run", Swatch::Dot(COLOURS[0].filled())),
        ],
    )?;
    let areas = root.split_evenly((rows, columns));
    for (panel, area) in panels.iter().zip(&areas) {
        let values: Vec<f64> = panel
            .boxes
            .iter()
            .flat_map(|(_, v)| v.iter().copied())
            .filter(|v| v.is_finite())
            .collect();
        let (lo, hi) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(*v), b.max(*v))
            });
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
        // A constant metric (every run the same) gets a span around its value, not a
        // nanoscopic one whose ticks read -0.000000.
        let pad = if hi - lo > 1e-9 * hi.abs().max(1.0) {
            (hi - lo) * 0.08
        } else {
            (hi.abs() * 0.05).max(0.5)
        };
        let n = panel.boxes.len().max(1);
        // Enough decimals to tell the ticks apart, and no more.
        let decimals = (2.0 - (hi - lo + 2.0 * pad).log10().floor()).clamp(0.0, 6.0) as usize;
        let labels: Vec<String> = panel.boxes.iter().map(|(l, _)| l.clone()).collect();
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 16))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(80)
            .build_cartesian_2d(0.5..n as f64 + 0.5, (lo - pad)..(hi + pad))?;
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
            .y_label_formatter(&|v| format!("{v:.decimals$}"))
            .x_desc(x_desc)
            .y_desc(y_label(&panel.title))
            .label_style((FONT, 13))
            .axis_desc_style((FONT, 14))
            .draw()?;
        for (i, (_, runs)) in panel.boxes.iter().enumerate() {
            let finite: Vec<f64> = runs.iter().copied().filter(|v| v.is_finite()).collect();
            if finite.is_empty() {
                continue;
            }
            let x = (i + 1) as f64;
            let [min, q1, med, q3, max] = quartiles(&finite);
            let half = 0.2;
            chart.draw_series([Rectangle::new(
                [(x - half, q1), (x + half, q3)],
                BLACK.stroke_width(2),
            )])?;
            for segment in [
                [(x, q3), (x, max)],
                [(x, min), (x, q1)],
                [(x - half / 2.0, max), (x + half / 2.0, max)],
                [(x - half / 2.0, min), (x + half / 2.0, min)],
            ] {
                chart.draw_series(LineSeries::new(segment, BLACK.stroke_width(2)))?;
            }
            chart.draw_series(LineSeries::new(
                [(x - half, med), (x + half, med)],
                BLACK.stroke_width(4),
            ))?;
            // Each run, spread sideways by its order so equal values stay visible.
            let k = finite.len().max(2) as f64;
            chart.draw_series(finite.iter().enumerate().map(|(j, v)| {
                let dx = (j as f64 / (k - 1.0) - 0.5) * 0.25;
                Circle::new((x + 0.3 + dx * 0.4, *v), 3, COLOURS[0].filled())
            }))?;
        }
    }
    Ok(())
}

/// The y axis of a metric's panel: its last key, which carries the unit by hetsim's naming
/// (`ate_m`, `mission_min`, `heading_error_deg`); a statistic's key (`mean`, `std`) goes
/// with the key it summarizes (`position_error_m.mean`).
fn y_label(metric: &str) -> String {
    let keys: Vec<&str> = metric.split('.').collect();
    match keys.as_slice() {
        [.., parent, stat] if ["mean", "std", "min", "max", "median"].contains(stat) => {
            format!("{parent} ({stat})")
        }
        [.., last] => last.to_string(),
        [] => String::new(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_statistic_is_labelled_with_the_key_it_summarizes() {
        assert_eq!(super::y_label("estimates.vo/ressac.ate_m"), "ate_m");
        assert_eq!(
            super::y_label("team.position_error_m.mean"),
            "position_error_m (mean)"
        );
        assert_eq!(super::y_label("comms.sent"), "sent");
    }
}
