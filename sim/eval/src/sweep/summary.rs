//! A sweep's summary: runs.csv, summary.csv, summary.md and the box plots, rebuilt from the
//! row files in run order.

use super::runs::{csv_text, read_row};
use super::*;

/// One metric over the seeds of a cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Stat {
    /// Mean of the runs that have a value.
    pub mean: f64,
    /// Sample standard deviation (0 for one sample).
    pub std: f64,
    /// The values, in run order (runs without a value left out).
    pub samples: Vec<f64>,
    /// Runs of the cell without a value (NaN in their row).
    pub missing: usize,
}

impl Stat {
    /// The smallest value (infinity when there is none).
    pub fn least(&self) -> f64 {
        self.samples.iter().copied().fold(f64::INFINITY, f64::min)
    }
}

/// The runs of one combination of axis values.
#[derive(Clone, Debug, PartialEq)]
pub struct SummaryCell {
    /// Axis values, in axis order.
    pub values: Vec<String>,
    /// The metric names, in column order.
    pub metrics: Vec<String>,
    /// One [`Stat`] per metric.
    pub stats: Vec<Stat>,
    /// Runs in the cell.
    pub runs: usize,
}

impl SummaryCell {
    /// The statistics of a metric by name.
    ///
    /// # Panics
    /// When the sweep has no such metric: a caller's defect (the names are the sweep's).
    pub fn stat(&self, metric: &str) -> &Stat {
        let i = self
            .metrics
            .iter()
            .position(|m| m == metric)
            .unwrap_or_else(|| panic!("metric {metric} is not one of {:?}", self.metrics));
        &self.stats[i]
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

/// Rebuilds `runs.csv`, `summary.csv`, `summary.md` and the box plots from the row files.
pub fn summarize(sweep: &Sweep, out: &Path) -> Result<SweepSummary, SweepError> {
    let rows_dir = out.join("rows");
    let header = sweep.header();
    let names = sweep.metrics();
    let skip = sweep.id_columns();
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
            metrics: names.clone(),
            runs: cols.first().map_or(0, Vec::len),
            stats: cols
                .into_iter()
                .map(|all| {
                    let samples: Vec<f64> = all.iter().copied().filter(|v| v.is_finite()).collect();
                    let s = crate::stats::MeanStd::sample(&samples);
                    Stat {
                        mean: if samples.is_empty() { f64::NAN } else { s.mean },
                        std: if samples.is_empty() { f64::NAN } else { s.std },
                        missing: all.len() - samples.len(),
                        samples,
                    }
                })
                .collect(),
        })
        .collect();
    let axes = sweep.axes();
    let mut summary_header = axes.clone();
    summary_header.push("runs".into());
    for m in &names {
        summary_header.push(format!("{m}_mean"));
        summary_header.push(format!("{m}_std"));
    }
    let mut summary = vec![summary_header];
    for cell in &stats {
        let mut record = cell.values.clone();
        record.push(cell.runs.to_string());
        for st in &cell.stats {
            record.push(st.mean.to_string());
            record.push(st.std.to_string());
        }
        summary.push(record);
    }
    let md = match sweep.file.kind {
        SweepKind::Plan => plan_markdown(sweep, &stats, finished),
        SweepKind::Run => run_markdown(sweep, &stats, finished),
    };
    let png = match sweep.file.kind {
        SweepKind::Plan => children_boxplot(sweep, &stats),
        SweepKind::Run => Some(metric_boxplots(sweep, &stats)),
    };
    if let Some(png) = png {
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

fn intro(sweep: &Sweep, finished: usize) -> String {
    let base = match &sweep.file.recording {
        Some(rec) => format!(
            "replays of the recording `{rec}` (scenario `{}`)",
            sweep.base.display()
        ),
        None => format!("base scenario `{}`", sweep.file.base),
    };
    format!(
        "# Sweep `{}`\n\nRuns: {base}, {} seeds per cell from seed {}, {} of {} runs finished. Mean ± sample standard deviation.\n\n",
        sweep.file.name,
        sweep.file.seeds,
        sweep.file.first_seed,
        finished,
        sweep.runs.len()
    )
}

/// A planning sweep's table: the planner's main figures per cell.
fn plan_markdown(sweep: &Sweep, stats: &[SummaryCell], finished: usize) -> String {
    let axes = sweep.axes();
    let mut md = intro(sweep, finished);
    let shown = [
        "parent_vertices",
        "following",
        "mapping_timesteps",
        "coordination_timesteps",
        "total_timesteps",
        "coverage",
    ];
    md.push_str(&format!(
        "| {} | runs | {} | least coverage | least coverable coverage | skipped stages |\n",
        axes.join(" | "),
        shown.join(" | ")
    ));
    md.push_str(&format!(
        "|{}\n",
        "---|".repeat(axes.len() + 4 + shown.len())
    ));
    for cell in stats {
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
        let least = |m: &str| cell.stat(m).least();
        let skipped: f64 = cell.stat("skipped_stages").samples.iter().sum();
        md.push_str(&format!(
            "| {} | {} | {} | {:.4} | {:.4} | {} |\n",
            cell.values.join(" | "),
            cell.runs,
            shown_cells.join(" | "),
            least("coverage"),
            least("coverable_coverage"),
            skipped
        ));
    }
    md.push_str(
        "\nLeast coverage: the run of the cell with the smallest imaged fraction of V \\ V_p; \
         least coverable coverage: the same over the vertices some vertex sees freely (Eq. 4's \
         promise, 1 wherever the team got everywhere it could image).\n",
    );
    md
}

/// A whole-run sweep's tables: one per metric, each cell's mean ± std, least and greatest
/// run, and how many runs had no value.
fn run_markdown(sweep: &Sweep, stats: &[SummaryCell], finished: usize) -> String {
    let axes = sweep.axes();
    let mut md = intro(sweep, finished);
    md.push_str("Each table is one metric of the runs' `metrics.json`; min and max are the least and greatest run of the cell, so a spread hidden by the mean shows. `runs.csv` has every run with its digest; `runs/<run>/` its results folder. Box plots: `boxplot.png`.\n");
    for (m, name) in sweep.metrics().iter().enumerate() {
        md.push_str(&format!(
            "\n## `{name}`\n\n| {} | runs | mean ± std | min | max | no value |\n|{}\n",
            axes.join(" | "),
            "---|".repeat(axes.len() + 5)
        ));
        for cell in stats {
            let st = &cell.stats[m];
            let (lo, hi) = st
                .samples
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(*v), b.max(*v))
                });
            let num = |v: f64| {
                if v.is_finite() {
                    format!("{v:.4}")
                } else {
                    "-".into()
                }
            };
            md.push_str(&format!(
                "| {} | {} | {} ± {} | {} | {} | {} |\n",
                cell.values.join(" | "),
                cell.runs,
                num(st.mean),
                num(st.std),
                num(lo),
                num(hi),
                st.missing
            ));
        }
    }
    md
}

/// One box plot per metric of a whole-run sweep, one box per cell.
fn metric_boxplots(sweep: &Sweep, cells: &[SummaryCell]) -> Vec<u8> {
    let panels: Vec<crate::charts::BoxPanel> = sweep
        .metrics()
        .iter()
        .enumerate()
        .map(|(m, name)| crate::charts::BoxPanel {
            title: name.clone(),
            boxes: cells
                .iter()
                .map(|c| (c.values.join(", "), c.stats[m].samples.clone()))
                .collect(),
        })
        .collect();
    crate::charts::boxes_png(
        &format!(
            "{}: each metric over the {} seeds of each cell",
            sweep.file.name, sweep.file.seeds
        ),
        &sweep.axes().join(", "),
        &panels,
    )
}

/// Box plots in the style of Figs. 3 and 4 when a planning sweep varies `coverage.children`:
/// one panel per combination of the other axes, one stacked box per number of children.
fn children_boxplot(sweep: &Sweep, cells: &[SummaryCell]) -> Option<Vec<u8>> {
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
