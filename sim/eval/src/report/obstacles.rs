//! The obstacles' sections of `results/coverage-tables.md`: Q by the obstacles' sizes, and
//! Tables I-II and Figs. 3-4 with obstacles that may lie over each other. Section V.A says
//! only that obstacles "of different sizes" were added to the random maps.

use super::readings::{self, Runs};
use super::{
    best_team_label, cells_with, falling_steps, pooled, teams, Figure, PAPER_FIG4_BEST,
    PAPER_TABLE1,
};
use crate::sweep::{SummaryCell, SweepSummary};

/// "Q and the obstacles' sizes": Q at 20 and 40 % for each range of sides of
/// `obstacle-sizes.toml` (one child per map).
pub(super) fn sizes(s: &SweepSummary, ratio_axis: usize, sizes_axis: usize) -> String {
    let mut md = String::from("## Q and the obstacles' sizes\n\n`scenarios/sweeps/obstacle-sizes.toml`: the paper does not give its obstacles' sizes. Q (r_los = 2 m, one child per map, so the ± is the spread over the 10 maps, a little wider than the pooled ± of the tables above) for rectangles with sides drawn from these ranges of 0.5 m cells; 1-6 is the generator's default, used everywhere else:\n\n| sides (cells) | 20 % (paper 180.5 ± 4.1) | 40 % (paper 174.9 ± 5.4) |\n|---|---|---|\n");
    let mut sizes: Vec<String> = s
        .cells
        .iter()
        .map(|c| c.values[sizes_axis].clone())
        .collect();
    sizes.dedup();
    for size in &sizes {
        let q = |ratio: f64| {
            let cells: Vec<&SummaryCell> = cells_with(s, ratio_axis, ratio)
                .into_iter()
                .filter(|c| &c.values[sizes_axis] == size)
                .collect();
            let (m, sd) = pooled(&cells, "parent_vertices");
            format!("{m:.1} ± {sd:.1}")
        };
        md.push_str(&format!("| {size} | {} | {} |\n", q(0.2), q(0.4)));
    }
    md.push('\n');
    md
}

/// Tables I-II's and Figs. 3-4's runs of one kind of map: Table I's sweep with its
/// obstruction and children axes, Table II's with its r_los and children axes.
pub(super) struct Maps<'a> {
    pub t1: &'a SweepSummary,
    pub ratio_axis: usize,
    pub kids1: usize,
    pub t2: &'a SweepSummary,
    pub r_los_axis: usize,
    pub kids2: usize,
}

impl<'a> Maps<'a> {
    pub(super) fn runs(&self) -> [Runs<'a>; 2] {
        [
            Runs {
                summary: self.t1,
                column_axis: self.ratio_axis,
                reading_axis: None,
            },
            Runs {
                summary: self.t2,
                column_axis: self.r_los_axis,
                reading_axis: None,
            },
        ]
    }

    /// `f` per panel of Fig. 3, then of Fig. 4.
    fn per_panel<T>(&self, f: fn(&[&SummaryCell], usize) -> T) -> Vec<T> {
        let fig3 = Figure::obstruction(self.t1, self.ratio_axis, self.kids1);
        let fig4 = Figure::r_los(self.t2, self.r_los_axis, self.kids2);
        let mut all = fig3.per_panel(f);
        all.extend(fig4.per_panel(f));
        all
    }

    /// Q's mean and std at an obstruction ratio (Table I's runs).
    fn q_at(&self, ratio: f64) -> (f64, f64) {
        pooled(
            &cells_with(self.t1, self.ratio_axis, ratio),
            "parent_vertices",
        )
    }
}

/// The least coverable coverage of any run of a panel.
fn least_coverable(cells: &[&SummaryCell], _children_axis: usize) -> String {
    let least = cells
        .iter()
        .map(|c| c.stat("coverable_coverage").least())
        .fold(f64::INFINITY, f64::min);
    format!("{least:.4}")
}

/// "Obstacles over each other": Tables I-II's Q and following behaviours, Figs. 3-4's best
/// teams and mapping trend, and the least coverable coverage, for the generator's obstacles
/// not overlapping (`apart`, Tables I-II's runs) and allowed over each other (`over`).
pub(super) fn overlap(apart: &Maps, over: &Maps) -> String {
    let mut md = String::from("## Obstacles over each other\n\n`scenarios/sweeps/obstacle-overlap-table1.toml` and `obstacle-overlap-table2.toml`: Tables I-II's and Figs. 3-4's maps and teams (1 to 8 children, 10 maps per cell) with the random obstacles allowed to lie over each other (`[world.indoor] obstacles_overlap = true`: a placement may cover cells other obstacles occupy, and only its new cells count towards the obstruction), so that they merge into larger ones of irregular shape. The generator's default, used everywhere else, refuses a placement that covers an occupied cell, so obstacles never overlap (they may touch). The paper says only that obstacles \"of different sizes\" were added; the sides are drawn from the same 1-6 cells either way, and the same rule keeps every free vertex reachable:\n\n");
    md.push_str(&readings::variant_tables(
        "obstacles",
        &[
            ("not overlapping (ours)", apart.runs()),
            ("over each other", over.runs()),
        ],
    ));
    let paper = |i: usize| PAPER_FIG4_BEST[i].to_string();
    let row = |label: &str, cells: Vec<String>| format!("| {label} | {} |\n", cells.join(" | "));
    md.push_str("Figs. 3 and 4 (as in the best-team table above) and the least coverable coverage of any run of a panel:\n\n| | Fig. 3: 0 % | 20 % | 40 % | Fig. 4: 1 m | 2 m | 4 m | 8 m |\n|---|---|---|---|---|---|---|---|\n");
    md.push_str(&row(
        "paper, best team",
        vec![
            String::new(),
            paper(1),
            String::new(),
            paper(0),
            paper(1),
            paper(2),
            paper(3),
        ],
    ));
    for (label, maps) in [("not overlapping (ours)", apart), ("over each other", over)] {
        md.push_str(&row(
            &format!("{label}, best team"),
            maps.per_panel(best_team_label),
        ));
        md.push_str(&row(
            &format!("{label}, best team per map"),
            maps.per_panel(teams::best_team_per_map),
        ));
        md.push_str(&row(
            &format!("{label}, steps that lower mapping"),
            maps.per_panel(falling_steps),
        ));
        md.push_str(&row(
            &format!("{label}, least coverable coverage"),
            maps.per_panel(least_coverable),
        ));
    }
    let trend = |m: &Maps| {
        let ((q20, s20), (q40, s40)) = (m.q_at(0.2), m.q_at(0.4));
        let way = if q40 < q20 { "falls" } else { "rises" };
        format!("{way} from {q20:.1} ± {s20:.1} to {q40:.1} ± {s40:.1}")
    };
    let ((p20, s20), (p40, s40)) = (
        (PAPER_TABLE1[1].1, PAPER_TABLE1[1].2),
        (PAPER_TABLE1[2].1, PAPER_TABLE1[2].2),
    );
    md.push_str(&format!(
        "\nFrom 20 to 40 % obstruction the paper's Q falls from {p20:.1} ± {s20:.1} to \
         {p40:.1} ± {s40:.1}; ours {} with the obstacles not overlapping and {} with them \
         over each other.\n\n",
        trend(apart),
        trend(over)
    ));
    md
}
