//! "What moves each entry" of `results/coverage-tables.md`: for each of Tables I-II's twelve
//! entries (Q and following behaviours in the six distinct columns), how far the planner's
//! open points (the readings) move it, and how far the choices of map the paper does not give
//! (the obstacles' sizes and overlap, where the walls stand), against the paper's spread.
//! Every variant changes one thing from the shipped runs; no combination is run.

use super::readings::{columns, following_of, q_of, PaperColumn, Runs, COLUMN_LABELS};
use super::{mean_std, samples, within};

/// One variant of the shipped runs.
pub(super) struct Variant<'a> {
    pub label: String,
    /// Table I's and Table II's runs; `None` where the variant has no sweep for that table.
    pub runs: [Option<Runs<'a>>; 2],
    /// What picks its cells where its sweep has an axis for it (a reading, the obstacles'
    /// sides); unused otherwise.
    pub pick: String,
    /// Whether its following behaviours compare with the paper's: false for sweeps with one
    /// child per map (the paper pools following behaviours over teams of 1 to 8).
    pub following: bool,
}

impl Variant<'_> {
    /// The mean of `metric` over the runs of the column at `x` of `table`; `None` where the
    /// variant has no runs there.
    fn mean(&self, table: usize, x: f64, metric: &str) -> Option<f64> {
        let runs = self.runs[table]?;
        let all = samples(&runs.cells(x, &self.pick), metric);
        (!all.is_empty()).then(|| mean_std(&all).0)
    }
}

/// The readings: the shipped runs (`ours`, labelled so) and each of `names` in the readings
/// sweeps (`others`, whose reading axis picks it).
pub(super) fn readings<'a>(
    ours: [Runs<'a>; 2],
    others: [Runs<'a>; 2],
    names: &[&str],
) -> Vec<Variant<'a>> {
    std::iter::once(("ours", ours))
        .chain(names.iter().map(|n| (*n, others)))
        .map(|(name, runs)| Variant {
            label: format!("`{name}`"),
            runs: runs.map(Some),
            pick: name.to_string(),
            following: true,
        })
        .collect()
}

/// The obstacles' sides of the shipped maps as a sweep's axis writes them ("[1, 6]"): the
/// `[world.indoor] obstacle_cells` of the shipped sweeps' base scenario (`base_text`), or
/// the generator's default where it gives none.
pub(super) fn shipped_sides(base_text: &str) -> String {
    let given = base_text.parse::<toml::Table>().ok().and_then(|t| {
        t.get("world")?
            .get("indoor")?
            .get("obstacle_cells")
            .map(toml::Value::to_string)
    });
    given.unwrap_or_else(|| format!("{:?}", hetsim_scene::IndoorSpec::default().obstacle_cells))
}

/// The maps: the shipped runs, the obstacles over each other (`over`, 1 to 8 children), the
/// walls inside the 30 m (`inside`, one child per map) and each range of the obstacles' sides
/// of `sizes` but the shipped maps' (`shipped_sides`: those are the shipped maps again), for
/// Table I only, one child per map; its size axis picks them, by value.
pub(super) fn maps<'a>(
    ours: [Runs<'a>; 2],
    over: [Runs<'a>; 2],
    inside: [Runs<'a>; 2],
    sizes: (Runs<'a>, usize),
    shipped_sides: &str,
) -> Vec<Variant<'a>> {
    // The sides in the sweep's order, each once, but the shipped maps'.
    let mut sides: Vec<&str> = Vec::new();
    for c in &sizes.0.summary.cells {
        let side = c.values[sizes.1].as_str();
        if side != shipped_sides && !sides.contains(&side) {
            sides.push(side);
        }
    }
    let whole = |label: &str, runs: [Runs<'a>; 2], following| Variant {
        label: label.to_string(),
        runs: runs.map(Some),
        pick: String::new(),
        following,
    };
    let mut all = vec![
        whole("not overlapping (ours)", ours, true),
        whole("over each other", over, true),
        whole("walls inside the 30 m", inside, false),
    ];
    all.extend(sides.into_iter().map(|side| Variant {
        label: format!("sides {side} cells"),
        runs: [
            Some(Runs {
                reading_axis: Some(sizes.1),
                ..sizes.0
            }),
            None,
        ],
        pick: side.to_string(),
        following: false,
    }));
    all
}

/// An entry's means under a family of variants: the least and most, how many variants have
/// one, and how many of those lie within the paper's spread.
struct Moved {
    low: f64,
    high: f64,
    count: usize,
    within: usize,
}

impl Moved {
    /// The means of `metric` under `family` in one paper column (`pick`: Q's or the following
    /// behaviours' paper mean and std); `None` where no variant has runs there.
    fn of(
        family: &[Variant],
        (table, p): (usize, PaperColumn),
        metric: &str,
        pick: fn(&PaperColumn) -> (f64, f64),
    ) -> Option<Self> {
        let (pm, ps) = pick(&p);
        let means: Vec<f64> = family
            .iter()
            .filter(|v| metric != "following" || v.following)
            .filter_map(|v| v.mean(table, p.0, metric))
            .collect();
        let first = *means.first()?;
        Some(Self {
            low: means.iter().copied().fold(first, f64::min),
            high: means.iter().copied().fold(first, f64::max),
            count: means.len(),
            within: means.iter().filter(|&&m| within(m, pm, ps)).count(),
        })
    }

    /// Table cells: the range, its width in units of `band`, and how many are within.
    fn cells(&self, band: f64) -> String {
        format!(
            "{:.1} to {:.1} | {:.1} | {} of {}",
            self.low,
            self.high,
            (self.high - self.low) / band,
            self.within,
            self.count
        )
    }
}

/// The section: a row per entry with the paper's mean ± std, the shipped mean (`readings`'
/// first variant), the range of means under `readings` and under `maps`, each range's width
/// in the paper's standard deviations (3 % of its mean for Q at 0 %, where it gives none),
/// and how many variants bring the entry within the paper's spread; then sentences, computed
/// from the rows, naming the entries no variant brings within and the family that moves each
/// entry further (where both have two variants or more; neither where they tie).
pub(super) fn section(readings: &[Variant], maps: &[Variant]) -> String {
    let mut md = String::from("## What moves each entry\n\nTables I-II's twelve entries under each reading of the planner's open points (\"Readings of the open points\" above, the shipped one included) and under each choice of map the paper does not give (the obstacles' sides and overlap, the walls inside the 30 m: the sections above; the shipped maps included; the one-child sweeps count for Q only, as the paper pools following behaviours over teams). Each variant changes one thing from the shipped runs; no combination was run. 'Width' is the range of the means in the paper's standard deviations (for Q at 0 %, where the paper gives none, in 3 % of its mean); 'within' counts the variants whose mean lies within the paper's spread:\n\n| entry | paper | ours | readings: means | width | within | maps: means | width | within |\n|---|---|---|---|---|---|---|---|---|\n");
    let mut nowhere = Vec::new();
    let (mut maps_further, mut readings_further) = (Vec::new(), Vec::new());
    for (name, metric, pick) in [
        (
            "Q",
            "parent_vertices",
            q_of as fn(&PaperColumn) -> (f64, f64),
        ),
        ("following", "following", following_of),
    ] {
        for (column, label) in columns().into_iter().zip(COLUMN_LABELS) {
            let entry = format!("{name} {label}");
            let (pm, ps) = pick(&column.1);
            let band = if ps > 0.0 { ps } else { 0.03 * pm };
            let (r, m) = (
                Moved::of(readings, column, metric, pick),
                Moved::of(maps, column, metric, pick),
            );
            let ours = readings[0].mean(column.0, column.1 .0, metric);
            let cells =
                |f: &Option<Moved>| f.as_ref().map_or("- | - | -".into(), |f| f.cells(band));
            md.push_str(&format!(
                "| {entry} | {pm:.1} ± {ps:.1} | {} | {} | {} |\n",
                ours.map_or("-".into(), |o| format!("{o:.1}")),
                cells(&r),
                cells(&m)
            ));
            let none_within = |f: &Option<Moved>| f.as_ref().is_none_or(|f| f.within == 0);
            if none_within(&r) && none_within(&m) {
                nowhere.push(entry.clone());
            }
            // Which family moves the entry further, where both have two variants or more.
            if let (Some(r), Some(m)) = (r.filter(|r| r.count > 1), m.filter(|m| m.count > 1)) {
                let (rw, mw) = (r.high - r.low, m.high - m.low);
                if mw > rw {
                    maps_further.push(entry);
                } else if rw > mw {
                    readings_further.push(entry);
                }
            }
        }
    }
    let list = |v: &[String]| {
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(", ")
        }
    };
    let labels = |family: &[Variant]| {
        family
            .iter()
            .map(|v| v.label.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    md.push_str(&format!(
        "\nThe readings: {}. The maps: {}.\n\nNo variant brings within the paper's spread: {}. \
         The maps move further than the readings: {}; the readings further than the maps: \
         {}.\n\n",
        labels(readings),
        labels(maps),
        list(&nowhere),
        list(&maps_further),
        list(&readings_further)
    ));
    md
}

#[cfg(test)]
mod tests {
    use super::{maps, readings};
    use super::{section, Variant};
    use crate::report::readings::Runs;
    use crate::report::testing::q_following_cell as cell;
    use crate::sweep::{SummaryCell, SweepSummary};

    fn summary(cells: Vec<SummaryCell>) -> SweepSummary {
        SweepSummary {
            finished: 0,
            total: 0,
            cells,
        }
    }

    /// A one-axis summary: per column (x, Q, following), one run.
    fn table(columns: &[(f64, f64, f64)]) -> SweepSummary {
        summary(
            columns
                .iter()
                .map(|&(x, q, f)| cell(&[&x.to_string()], q, f))
                .collect(),
        )
    }

    fn variant<'a>(
        label: &str,
        t1: &'a SweepSummary,
        t2: Option<&'a SweepSummary>,
        following: bool,
    ) -> Variant<'a> {
        let runs = |s| Runs {
            summary: s,
            column_axis: 0,
            reading_axis: None,
        };
        Variant {
            label: label.to_string(),
            runs: [Some(runs(t1)), t2.map(runs)],
            pick: String::new(),
            following,
        }
    }

    #[test]
    fn each_entry_gets_each_familys_range_in_paper_deviations() {
        // The paper's (column, Q, following) of Table I and of Table II but 2 m.
        let paper1 = [(0.0, 167.0, 32.5), (0.2, 180.5, 54.8), (0.4, 174.9, 82.9)];
        let paper2 = [(1.0, 538.5, 403.1), (4.0, 71.2, 18.4), (8.0, 42.0, 9.5)];
        // Ours: every entry at the paper's mean but following at 0 % (0, below 32.5 - 12.3).
        let mut ours1 = paper1;
        ours1[0].2 = 0.0;
        let (o1, o2) = (table(&ours1), table(&paper2));
        // A reading: Q at 40 % two paper deviations up (174.9 + 10.8), following at 0 % 0.
        let mut read1 = ours1;
        read1[2].1 += 10.8;
        let r1 = table(&read1);
        // A map with one child per map (Q only; its following, 1000, must not count), Table I
        // only: Q at 40 % four deviations down, at 0 % 6 % up (two 3 % bands).
        let map1 = table(&[
            (0.0, 177.02, 1000.0),
            (0.2, 180.5, 1000.0),
            (0.4, 153.3, 1000.0),
        ]);
        let md = section(
            &[
                variant("ours", &o1, Some(&o2), true),
                variant("reading", &r1, Some(&o2), true),
            ],
            &[
                variant("ours", &o1, Some(&o2), true),
                variant("one child", &map1, None, false),
            ],
        );
        assert!(
            md.contains("| Q 40 % | 174.9 ± 5.4 | 174.9 | 174.9 to 185.7 | 2.0 | 1 of 2 | 153.3 to 174.9 | 4.0 | 1 of 2 |"),
            "{md}"
        );
        // Q at 0 %: the width is in 3 % of 167.0 (5.01); 177.02 is 2.0 of them up.
        assert!(md.contains("| Q 0 % | 167.0 ± 0.0 | 167.0 | 167.0 to 167.0 | 0.0 | 2 of 2 | 167.0 to 177.0 | 2.0 | 1 of 2 |"), "{md}");
        // Following: the one-child map does not count, and Table II has only ours as a map.
        assert!(md.contains("| following 0 % | 32.5 ± 12.3 | 0.0 | 0.0 to 0.0 | 0.0 | 0 of 2 | 0.0 to 0.0 | 0.0 | 0 of 1 |"), "{md}");
        assert!(md.contains("| Q 4 m | 71.2 ± 4.1 | 71.2 | 71.2 to 71.2 | 0.0 | 2 of 2 | 71.2 to 71.2 | 0.0 | 1 of 1 |"), "{md}");
        assert!(
            md.contains("No variant brings within the paper's spread: following 0 %."),
            "{md}"
        );
        // Only Table I's Q has two maps; Q at 20 % moves under neither family (in neither list).
        assert!(
            md.contains(
                "The maps move further than the readings: Q 0 %, Q 40 %; the readings further \
                 than the maps: none."
            ),
            "{md}"
        );
    }

    #[test]
    fn the_builders_pick_each_variants_cells_and_leave_the_shipped_sides_out() {
        let paper1 = [(0.0, 167.0, 32.5), (0.2, 180.5, 54.8), (0.4, 174.9, 82.9)];
        let paper2 = [(1.0, 538.5, 403.1), (4.0, 71.2, 18.4), (8.0, 42.0, 9.5)];
        let (o1, o2) = (table(&paper1), table(&paper2));
        // Obstacles over each other: Q at 20 % 190.
        let mut over = paper1;
        over[1].1 = 190.0;
        let v1 = table(&over);
        // The readings sweeps (column, reading): Q at 40 % 190 under `a`, 210 under `b`.
        let r1 = summary(vec![
            cell(&["0.4", "a"], 190.0, 82.9),
            cell(&["0.4", "b"], 210.0, 82.9),
        ]);
        let r2 = summary(vec![cell(&["4", "a"], 71.2, 18.4)]);
        // The sides sweep (column, sides): the shipped sides, whose 999 must be left out, and
        // [2, 6].
        let sides = summary(vec![
            cell(&["0.4", "[1, 6]"], 999.0, 0.0),
            cell(&["0.4", "[2, 6]"], 150.0, 0.0),
        ]);
        let runs = |s, axis| Runs {
            summary: s,
            column_axis: 0,
            reading_axis: axis,
        };
        let ours = [runs(&o1, None), runs(&o2, None)];
        let readings = readings(ours, [runs(&r1, Some(1)), runs(&r2, Some(1))], &["a", "b"]);
        let maps = maps(
            ours,
            [runs(&v1, None), runs(&o2, None)],
            ours,
            (runs(&sides, None), 1),
            "[1, 6]",
        );
        let md = section(&readings, &maps);
        assert!(
            md.contains(
                "The readings: `ours`, `a`, `b`. The maps: not overlapping (ours), over each \
                 other, walls inside the 30 m, sides [2, 6] cells."
            ),
            "{md}"
        );
        // Q at 40 %: readings 174.9, 190 and 210 (35.1 / 5.4 = 6.5 deviations); maps 174.9
        // three times and 150 (24.9 / 5.4 = 4.6).
        assert!(
            md.contains("| Q 40 % | 174.9 ± 5.4 | 174.9 | 174.9 to 210.0 | 6.5 | 1 of 3 | 150.0 to 174.9 | 4.6 | 3 of 4 |"),
            "{md}"
        );
        // Q at 20 %: the maps move it (9.5 / 4.1 = 2.3), the readings have only ours there, so
        // neither family is said to move it further.
        assert!(
            md.contains("| Q 20 % | 180.5 ± 4.1 | 180.5 | 180.5 to 180.5 | 0.0 | 1 of 1 | 180.5 to 190.0 | 2.3 | 2 of 3 |"),
            "{md}"
        );
        assert!(
            md.contains(
                "No variant brings within the paper's spread: none. The maps move further than \
                 the readings: none; the readings further than the maps: Q 40 %."
            ),
            "{md}"
        );
    }
}
