//! The readings tables of `results/coverage-tables.md`: Q and the following behaviours of
//! Tables I-II under each reading of the points Section IV leaves open
//! (`hetsim_coverage::Reading`), beside the shipped reading's and the paper's.

use super::{mean_std, samples, within, PAPER_TABLE1, PAPER_TABLE2};
use crate::sweep::{SummaryCell, SweepSummary};

/// A column of the paper's Tables I-II: (axis value, Q mean, Q std, following mean,
/// following std).
pub(super) type PaperColumn = (f64, f64, f64, f64, f64);

/// The runs of one table: a sweep, the axis its columns are on and, for the readings
/// sweeps, the axis that names the reading.
#[derive(Clone, Copy)]
pub(super) struct Runs<'a> {
    pub summary: &'a SweepSummary,
    pub column_axis: usize,
    pub reading_axis: Option<usize>,
}

impl Runs<'_> {
    /// The cells of column `x` under `reading` (any, for a sweep without a reading axis).
    pub(super) fn cells(&self, x: f64, reading: &str) -> Vec<&SummaryCell> {
        self.summary
            .cells
            .iter()
            .filter(|c| {
                c.values[self.column_axis]
                    .parse::<f64>()
                    .is_ok_and(|v| (v - x).abs() < 1e-9)
                    && self.reading_axis.is_none_or(|a| c.values[a] == reading)
            })
            .collect()
    }
}

/// The six distinct columns of Tables I-II (Table II's 2 m is Table I's 20 %): which table's
/// runs, and the paper's (column, Q mean, Q std, following mean, following std).
pub(super) fn columns() -> Vec<(usize, PaperColumn)> {
    PAPER_TABLE1
        .iter()
        .map(|&p| (0, p))
        .chain(PAPER_TABLE2.iter().filter(|p| p.0 != 2.0).map(|&p| (1, p)))
        .collect()
}

/// A table's header, its first column named `first`.
fn header(first: &str) -> String {
    format!(
        "| {first} | {} | within |\n|---|---|---|---|---|---|---|---|\n",
        COLUMN_LABELS.join(" | ")
    )
}

/// The paper's row, `pick` choosing a column's (mean, std): Q's or the following
/// behaviours'.
fn paper_row(pick: fn(&PaperColumn) -> (f64, f64)) -> String {
    let cells: Vec<String> = columns()
        .iter()
        .map(|(_, p)| {
            let (m, s) = pick(p);
            format!("{m:.1} ± {s:.1}")
        })
        .collect();
    format!("| paper | {} | |\n", cells.join(" | "))
}

/// One row's cells ("mean ± std" of `metric` over the runs of `reading`) and, per column,
/// whether the mean lies within the paper's spread (`pick` as in [`paper_row`]).
fn row(
    runs: &[Runs; 2],
    reading: &str,
    metric: &str,
    pick: fn(&PaperColumn) -> (f64, f64),
) -> (Vec<String>, Vec<bool>) {
    columns()
        .iter()
        .map(|&(table, p)| {
            let (m, s) = mean_std(&samples(&runs[table].cells(p.0, reading), metric));
            let (pm, ps) = pick(&p);
            (format!("{m:.1} ± {s:.1}"), within(m, pm, ps))
        })
        .unzip()
}

/// Q's mean and std in a paper column.
pub(super) fn q_of(p: &PaperColumn) -> (f64, f64) {
    (p.1, p.2)
}

/// The following behaviours' mean and std in a paper column.
pub(super) fn following_of(p: &PaperColumn) -> (f64, f64) {
    (p.3, p.4)
}

/// Two tables, Q and following behaviours, with a row for the paper, the shipped reading
/// (`ours`: Tables I-II's runs) and each reading of `others` (the readings sweeps' runs), and
/// how many of the six columns lie within the paper's spread; then a sentence, computed from
/// them, on which readings bring the most of the twelve entries within it.
pub(super) fn tables(ours: [Runs; 2], others: [Runs; 2], readings: &[&str]) -> String {
    let rows: Vec<(String, &[Runs; 2], &str)> = std::iter::once(("ours", &ours))
        .chain(readings.iter().map(|r| (*r, &others)))
        .map(|(name, runs)| (format!("`{name}`"), runs, name))
        .collect();
    let (md, fits) = q_and_following("reading", &rows);
    let fits: Vec<(&str, usize)> = rows.iter().map(|r| r.2).zip(fits).collect();
    format!("{md}{}\n", verdict(&fits, 2 * COLUMN_LABELS.len()))
}

/// Q and following behaviours beside the paper's, one row per `(label, runs)` (Tables I-II's
/// runs of one variant), and a sentence, computed from them, on how many of the twelve
/// entries each brings within the paper's spread.
pub(super) fn variant_tables(first: &str, rows: &[(&str, [Runs; 2])]) -> String {
    let rows: Vec<(String, &[Runs; 2], &str)> = rows
        .iter()
        .map(|(label, runs)| (label.to_string(), runs, ""))
        .collect();
    let (md, fits) = q_and_following(first, &rows);
    let said: Vec<String> = rows
        .iter()
        .zip(&fits)
        .map(|(r, n)| format!("{} {n}", r.0))
        .collect();
    format!(
        "{md}Entries within the paper's spread, of {}: {}.\n\n",
        2 * COLUMN_LABELS.len(),
        said.join("; ")
    )
}

/// The Q and following tables (first column named `first`), a row per `(label, runs,
/// reading)`, and how many of the twelve entries each row has within the paper's spread.
fn q_and_following(first: &str, rows: &[(String, &[Runs; 2], &str)]) -> (String, Vec<usize>) {
    let mut q_table = header(first) + &paper_row(q_of);
    let mut f_table = header(first) + &paper_row(following_of);
    let n = COLUMN_LABELS.len();
    let mut fits = Vec::new();
    for (label, runs, reading) in rows {
        let (q_row, q_in) = row(runs, reading, "parent_vertices", q_of);
        let (f_row, f_in) = row(runs, reading, "following", following_of);
        let q_fits = q_in.iter().filter(|&&b| b).count();
        let f_fits = f_in.iter().filter(|&&b| b).count();
        fits.push(q_fits + f_fits);
        q_table.push_str(&format!(
            "| {label} | {} | {q_fits} of {n} |\n",
            q_row.join(" | ")
        ));
        f_table.push_str(&format!(
            "| {label} | {} | {f_fits} of {n} |\n",
            f_row.join(" | ")
        ));
    }
    (
        format!("Q = abs(V_p):\n\n{q_table}\nFollowing behaviours:\n\n{f_table}\n"),
        fits,
    )
}

/// The six columns' labels, in [`columns`]' order.
pub(super) const COLUMN_LABELS: [&str; 6] = ["0 %", "20 %", "40 %", "1 m", "4 m", "8 m"];

/// "Q and the map's border": Q with the map's walls outside its 30 m (`ours`: Tables I-II's
/// runs) and inside them (`inside`: one child per map).
pub(super) fn border(ours: [Runs; 2], inside: [Runs; 2]) -> String {
    let mut md = String::from("## Q and the map's border\n\n`scenarios/sweeps/map-border-table1.toml` and `map-border-table2.toml`: the paper's maps are 30 x 30 m, and it does not say whether their walls lie inside them. Ours stand outside (60 x 60 vertices at 0 %); in these sweeps the walls take the outermost ring of cells (58 x 58 vertices at 0 %, the obstacles covering the given share of the floor inside them). Q; outside: Tables I-II's runs (all numbers of children); inside: one child per map, so its ± is the spread over the 10 maps:\n\n");
    md.push_str(&q_table(&[
        ("walls outside the 30 m (ours)", ours),
        ("walls inside the 30 m", inside),
    ]));
    md
}

/// A Q table with the paper's row and one row per `(label, runs)`, and how many of the six
/// columns lie within the paper's spread; then a sentence, computed from the table, naming
/// the columns each row brings within it.
pub(super) fn q_table(rows: &[(&str, [Runs; 2])]) -> String {
    let mut md = header("map") + &paper_row(q_of);
    let mut said = Vec::new();
    for (label, runs) in rows {
        let (cells, fits) = row(runs, "", "parent_vertices", q_of);
        let inside: Vec<&str> = COLUMN_LABELS
            .iter()
            .zip(&fits)
            .filter(|(_, &b)| b)
            .map(|(l, _)| *l)
            .collect();
        md.push_str(&format!(
            "| {label} | {} | {} of {} |\n",
            cells.join(" | "),
            inside.len(),
            COLUMN_LABELS.len()
        ));
        let list = if inside.is_empty() {
            "none".to_string()
        } else {
            inside.join(", ")
        };
        said.push(format!("{label}: {list}"));
    }
    format!(
        "{md}\nColumns within the paper's spread, {}.\n\n",
        said.join("; ")
    )
}

/// Which readings bring the most of the `entries` (Q and following, per column) within the
/// paper's spread, from each reading's count; says so when one brings them all.
fn verdict(fits: &[(&str, usize)], entries: usize) -> String {
    let most = fits.iter().map(|f| f.1).max().unwrap_or(0);
    let mut best: Vec<String> = fits
        .iter()
        .filter(|f| f.1 == most)
        .map(|f| format!("`{}`", f.0))
        .collect();
    let last = best.pop().unwrap_or_default();
    let best = if best.is_empty() {
        last
    } else {
        format!("{} and {last}", best.join(", "))
    };
    if most == entries {
        format!("Every entry of Tables I-II is within the paper's spread under {best}.\n")
    } else {
        format!(
            "No reading brings all {entries} entries (Q and following behaviours, {} columns \
             each) within the paper's spread; the most within is {most}, under {best}.\n",
            entries / 2
        )
    }
}

#[cfg(test)]
mod tests {
    use super::{q_table, variant_tables, verdict, Runs};
    use crate::sweep::SweepSummary;

    /// A summary of one-axis cells, each with its `parent_vertices` samples.
    fn summary(cells: &[(f64, &[f64])]) -> SweepSummary {
        let cells = cells
            .iter()
            .map(|&(x, q)| {
                super::super::testing::test_cell(&x.to_string(), "parent_vertices", q, 0)
            })
            .collect::<Vec<_>>();
        SweepSummary {
            finished: 0,
            total: 0,
            cells,
        }
    }

    #[test]
    fn the_q_table_counts_the_columns_within_the_papers_spread() {
        let runs = |s| Runs {
            summary: s,
            column_axis: 0,
            reading_axis: None,
        };
        // The paper's Table I (0 % without a spread: within 3 %, so 172.0 of 167.0 is in and
        // 172.1 out) and Table II's 1 / 4 / 8 m, whose 2 m column must not be read.
        let (t1_in, t2_in) = (
            summary(&[(0.0, &[172.0]), (0.2, &[176.5, 184.5]), (0.4, &[174.9])]),
            summary(&[
                (1.0, &[538.5]),
                (2.0, &[1.0]),
                (4.0, &[75.2]),
                (8.0, &[42.0]),
            ]),
        );
        let (t1_out, t2_out) = (
            summary(&[(0.0, &[172.1]), (0.2, &[185.0]), (0.4, &[169.4])]),
            summary(&[(1.0, &[545.0]), (4.0, &[75.4]), (8.0, &[45.0])]),
        );
        let md = q_table(&[
            ("in", [runs(&t1_in), runs(&t2_in)]),
            ("out", [runs(&t1_out), runs(&t2_out)]),
        ]);
        assert!(md.contains("| paper | 167.0 ± 0.0 | 180.5 ± 4.1 |"), "{md}");
        assert!(md.contains("| in | 172.0 ± 0.0 | 180.5 ± 5.7 |"), "{md}");
        assert!(
            md.contains("| 6 of 6 |") && md.contains("| 0 of 6 |"),
            "{md}"
        );
        assert!(
            md.contains("in: 0 %, 20 %, 40 %, 1 m, 4 m, 8 m; out: none."),
            "{md}"
        );
    }

    #[test]
    fn the_variant_tables_count_q_and_following_entries_within() {
        // One run per column with Q at the paper's mean, and following behaviours either at
        // the paper's mean (all 12 entries within) or 0 (below every column's spread: the
        // paper's least mean minus its std is 9.5 - 3.6 at 8 m).
        let table = |columns: &[(f64, f64, f64)]| SweepSummary {
            finished: 0,
            total: 0,
            cells: columns
                .iter()
                .map(|&(x, q, f)| super::super::testing::q_following_cell(&[&x.to_string()], q, f))
                .collect(),
        };
        let runs = |s| Runs {
            summary: s,
            column_axis: 0,
            reading_axis: None,
        };
        // The paper's (column, Q, following) of Tables I and II (but 2 m).
        let (t1, t2) = (
            [(0.0, 167.0, 32.5), (0.2, 180.5, 54.8), (0.4, 174.9, 82.9)],
            [(1.0, 538.5, 403.1), (4.0, 71.2, 18.4), (8.0, 42.0, 9.5)],
        );
        let zero_following = |columns: &[(f64, f64, f64)]| {
            table(
                &columns
                    .iter()
                    .map(|&(x, q, _)| (x, q, 0.0))
                    .collect::<Vec<_>>(),
            )
        };
        let (a1, a2, b1, b2) = (
            table(&t1),
            table(&t2),
            zero_following(&t1),
            zero_following(&t2),
        );
        let md = variant_tables(
            "maps",
            &[
                ("in", [runs(&a1), runs(&a2)]),
                ("out", [runs(&b1), runs(&b2)]),
            ],
        );
        assert!(md.starts_with("Q = abs(V_p):\n\n| maps |"), "{md}");
        assert!(md.contains("| out | 0.0 ± 0.0 |"), "{md}");
        assert!(md.contains("| 0 of 6 |"), "{md}");
        assert!(
            md.contains("Entries within the paper's spread, of 12: in 12; out 6."),
            "{md}"
        );
    }

    #[test]
    fn the_verdict_names_the_readings_with_the_most_entries_within() {
        let some = verdict(&[("ours", 8), ("ties", 8), ("los", 8), ("eq6", 4)], 12);
        assert!(
            some.starts_with("No reading brings all 12 entries"),
            "{some}"
        );
        assert!(
            some.contains("6 columns each")
                && some.contains("the most within is 8, under `ours`, `ties` and `los`."),
            "{some}"
        );
        let all = verdict(&[("ours", 11), ("ties", 12)], 12);
        assert!(
            all.starts_with("Every entry") && all.contains("under `ties`."),
            "{all}"
        );
    }
}
