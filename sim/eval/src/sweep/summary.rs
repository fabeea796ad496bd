//! A sweep's summary: runs.csv, summary.csv, summary.md and the box plot, rebuilt from the row files in run order.

use super::*;

/// One metric over the seeds of a cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for one sample).
    pub std: f64,
    /// The values, in run order.
    pub samples: Vec<f64>,
}

/// The runs of one combination of axis values.
#[derive(Clone, Debug, PartialEq)]
pub struct SummaryCell {
    /// Axis values, in axis order.
    pub values: Vec<String>,
    /// One [`Stat`] per entry of [`METRICS`].
    pub stats: Vec<Stat>,
}

impl SummaryCell {
    /// The statistics of a metric by name.
    pub fn stat(&self, metric: &str) -> &Stat {
        &self.stats[METRICS
            .iter()
            .position(|m| *m == metric)
            .expect("a metric of METRICS")]
    }
}

/// Mean and sample standard deviation of each metric per combination of axis values.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepSummary {
    /// Rows present.
    pub finished: usize,
    /// Runs in the sweep.
    pub total: usize,
    /// Cells in combination order.
    pub cells: Vec<SummaryCell>,
}

/// Rebuilds `runs.csv`, `summary.csv` and `summary.md` from the row files.
pub fn summarize(sweep: &Sweep, out: &Path) -> Result<SweepSummary, SweepError> {
    let rows_dir = out.join("rows");
    let header = sweep.header();
    let mut run_rows = vec![header.clone()];
    let mut cells: Vec<(Vec<String>, Vec<Vec<f64>>)> = Vec::new();
    let mut finished = 0;
    for run in &sweep.runs {
        let path = rows_dir.join(format!("{:06}.csv", run.index));
        if !path.is_file() {
            continue;
        }
        let fields = read_row(&path, &header)?;
        finished += 1;
        let skip = 2 + sweep.axes().len();
        let values: Vec<f64> = fields[skip..]
            .iter()
            .zip(&header[skip..])
            .map(|(f, column)| {
                f.parse::<f64>().map_err(|e| SweepError::Row {
                    path: path.clone(),
                    row: 1,
                    message: format!("column {column} = {f:?}: {e}; expected a number"),
                })
            })
            .collect::<Result<_, _>>()?;
        run_rows.push(fields);
        let key: Vec<String> = run.values.iter().map(value_text).collect();
        match cells.iter_mut().find(|(k, _)| *k == key) {
            Some((_, cols)) => cols.iter_mut().zip(values).for_each(|(c, v)| c.push(v)),
            None => cells.push((key, values.into_iter().map(|v| vec![v]).collect())),
        }
    }
    let stats: Vec<SummaryCell> = cells
        .into_iter()
        .map(|(values, cols)| SummaryCell {
            values,
            stats: cols
                .into_iter()
                .map(|samples| {
                    let s = crate::stats::MeanStd::sample(&samples);
                    Stat {
                        mean: s.mean,
                        std: s.std,
                        samples,
                    }
                })
                .collect(),
        })
        .collect();
    let axes = sweep.axes();
    let mut summary_header = axes.clone();
    summary_header.push("runs".into());
    for m in METRICS {
        summary_header.push(format!("{m}_mean"));
        summary_header.push(format!("{m}_std"));
    }
    let mut summary = vec![summary_header];
    let mut md = format!("# Sweep `{}`\n\nBase scenario `{}`, {} seeds per cell, {} of {} runs finished. Mean ± sample standard deviation.\n\n", sweep.file.name, sweep.file.base, sweep.file.seeds, finished, sweep.runs.len());
    let shown = [
        "parent_vertices",
        "following",
        "mapping_timesteps",
        "coordination_timesteps",
        "total_timesteps",
        "coverage",
    ];
    md.push_str(&format!(
        "| {} | runs | {} |\n",
        axes.join(" | "),
        shown.join(" | ")
    ));
    md.push_str(&format!(
        "|{}\n",
        "---|".repeat(axes.len() + 1 + shown.len())
    ));
    for cell in &stats {
        let runs = cell.stats[0].samples.len();
        let mut record = cell.values.clone();
        record.push(runs.to_string());
        for st in &cell.stats {
            record.push(st.mean.to_string());
            record.push(st.std.to_string());
        }
        summary.push(record);
        let shown_cells: Vec<String> = shown
            .iter()
            .map(|m| {
                let st = cell.stat(m);
                if *m == "coverage" {
                    format!("{:.4} ± {:.4}", st.mean, st.std)
                } else {
                    format!("{:.1} ± {:.1}", st.mean, st.std)
                }
            })
            .collect();
        md.push_str(&format!(
            "| {} | {runs} | {} |\n",
            cell.values.join(" | "),
            shown_cells.join(" | ")
        ));
    }
    if let Some(png) = boxplot(sweep, &stats) {
        write_atomic(&out.join("boxplot.png"), &png)?;
    }
    write_atomic(&out.join("runs.csv"), &csv_text(run_rows))?;
    write_atomic(&out.join("summary.csv"), &csv_text(summary))?;
    write_atomic(&out.join("summary.md"), md.as_bytes())?;
    Ok(SweepSummary {
        finished,
        total: sweep.runs.len(),
        cells: stats,
    })
}

/// Box plots in the style of Figs. 3 and 4 when the sweep varies `coverage.children`: one
/// panel per combination of the other axes, one stacked box per number of children.
fn boxplot(sweep: &Sweep, cells: &[SummaryCell]) -> Option<Vec<u8>> {
    let axes = sweep.axes();
    let kids = axes.iter().position(|a| a == "coverage.children")?;
    let mut panels: Vec<(String, Vec<crate::charts::StackedBox>)> = Vec::new();
    for cell in cells {
        let title: Vec<&str> = cell
            .values
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != kids)
            .map(|(_, v)| v.as_str())
            .collect();
        let title = title.join(" ");
        let b = crate::charts::StackedBox {
            label: cell.values[kids].clone(),
            mapping: cell.stat("mapping_timesteps").samples.clone(),
            coordination: cell.stat("coordination_timesteps").samples.clone(),
        };
        match panels.iter_mut().find(|(t, _)| *t == title) {
            Some((_, boxes)) => boxes.push(b),
            None => panels.push((title, vec![b])),
        }
    }
    Some(crate::charts::stacked_boxes_png(
        &format!("{}: timesteps by number of children", sweep.file.name),
        &panels,
    ))
}
