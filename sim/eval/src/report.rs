//! `results/coverage-tables.md`: the reproduced Tables I and II and Figs. 3 and 4 of seed 002
//! beside the paper's values.

use crate::charts::{stacked_boxes_png, StackedBox};
use crate::sweep::{load_sweep, run_sweep, SummaryCell, Sweep, SweepError, SweepSummary};
use crate::EvalError;
use hetsim_core::files::{write_atomic, FileError};
use std::path::Path;

mod obstacles;
mod readings;
mod spread;
mod teams;
#[cfg(test)]
mod testing;

/// The paper's Table I: (obstruction, Q mean, Q std, following mean, following std).
const PAPER_TABLE1: [(f64, f64, f64, f64, f64); 3] = [
    (0.0, 167.0, 0.0, 32.5, 12.3),
    (0.2, 180.5, 4.1, 54.8, 18.1),
    (0.4, 174.9, 5.4, 82.9, 24.9),
];
/// The paper's best teams in Fig. 4 at r_los = 1, 2, 4 and 8 m (Section V.A).
const PAPER_FIG4_BEST: [usize; 4] = [2, 3, 5, 7];
/// The paper's Table II: (r_los, Q mean, Q std, following mean, following std).
const PAPER_TABLE2: [(f64, f64, f64, f64, f64); 4] = [
    (1.0, 538.5, 5.4, 403.1, 154.7),
    (2.0, 180.5, 4.1, 54.8, 18.1),
    (4.0, 71.2, 4.1, 18.4, 5.6),
    (8.0, 42.0, 2.6, 9.5, 3.6),
];

/// The values of `metric` over `cells`, in the cells' order and each cell's run order; runs
/// without a value (NaN in `runs.csv`) are left out.
fn samples(cells: &[&SummaryCell], metric: &str) -> Vec<f64> {
    cells
        .iter()
        .flat_map(|c| c.stat(metric).samples.iter().copied())
        .collect()
}

fn mean_std(all: &[f64]) -> (f64, f64) {
    let s = crate::stats::MeanStd::sample(all);
    (s.mean, s.std)
}

fn pooled(cells: &[&SummaryCell], metric: &str) -> (f64, f64) {
    mean_std(&samples(cells, metric))
}

/// Cells whose value on `axis` (by index) equals `value`.
fn cells_with(s: &SweepSummary, axis: usize, value: f64) -> Vec<&SummaryCell> {
    s.cells
        .iter()
        .filter(|c| {
            c.values[axis]
                .parse::<f64>()
                .is_ok_and(|v| (v - value).abs() < 1e-9)
        })
        .collect()
}

fn boxes(cells: &[&SummaryCell], children_axis: usize) -> Vec<StackedBox> {
    let mut v: Vec<StackedBox> = cells
        .iter()
        .map(|c| StackedBox {
            label: c.values[children_axis].clone(),
            mapping: c.stat("mapping_timesteps").samples.clone(),
            coordination: c.stat("coordination_timesteps").samples.clone(),
        })
        .collect();
    v.sort_by_key(|b| b.label.parse::<u32>().unwrap_or(0));
    v
}

/// The cell with the least mean of `stat`.
fn least<'a>(cells: &[&'a SummaryCell], stat: &str) -> Option<&'a SummaryCell> {
    cells
        .iter()
        .copied()
        .min_by(|a, b| a.stat(stat).mean.total_cmp(&b.stat(stat).mean))
}

/// The number of children (the value on `children_axis`) with the least mean total
/// timesteps.
fn best_team(cells: &[&SummaryCell], children_axis: usize) -> usize {
    least(cells, "total_timesteps")
        .and_then(|c| c.values[children_axis].parse().ok())
        .unwrap_or(0)
}

/// The number of children (the value on `children_axis`) with the fewest mean mapping
/// timesteps: where adding children stops making the mapping faster.
fn fastest_mapping(cells: &[&SummaryCell], children_axis: usize) -> String {
    least(cells, "mapping_timesteps").map_or_else(String::new, |c| c.values[children_axis].clone())
}

/// Of the steps from one number of children to the next, how many lower the mean mapping
/// timesteps, as "k of n".
fn falling_steps(cells: &[&SummaryCell], children_axis: usize) -> String {
    let mut by_n: Vec<(i64, f64)> = cells
        .iter()
        .filter_map(|c| {
            let n = c.values[children_axis].parse::<i64>().ok()?;
            Some((n, c.stat("mapping_timesteps").mean))
        })
        .collect();
    by_n.sort_by_key(|&(n, _)| n);
    let falls = by_n.windows(2).filter(|w| w[1].1 < w[0].1).count();
    format!("{falls} of {}", by_n.len().saturating_sub(1))
}

/// The best team, with the others whose mean total is within 1 % of its own in brackets
/// (10 maps per cell cannot tell those apart).
fn best_team_label(cells: &[&SummaryCell], children_axis: usize) -> String {
    let best = best_team(cells, children_axis);
    let total = |c: &SummaryCell| c.stat("total_timesteps").mean;
    let least = cells.iter().map(|c| total(c)).fold(f64::INFINITY, f64::min);
    let mut near: Vec<usize> = cells
        .iter()
        .filter(|c| total(c) <= 1.01 * least)
        .filter_map(|c| c.values[children_axis].parse().ok())
        .filter(|&n| n != best)
        .collect();
    near.sort_unstable();
    if near.is_empty() {
        best.to_string()
    } else {
        let list: Vec<String> = near.iter().map(usize::to_string).collect();
        format!("{best} ({})", list.join(", "))
    }
}

/// Whether ours lies within the paper's mean ± standard deviation, or within 3 % of its mean
/// where it gives no spread.
fn within(ours: f64, mean: f64, std: f64) -> bool {
    if std > 0.0 {
        (ours - mean).abs() <= std
    } else {
        (ours - mean).abs() <= 0.03 * mean
    }
}

/// The Q and following rows of a table beside the paper's, the following behaviours split by
/// cause (ours only: the paper counts one kind), and whether Q and following are within the
/// paper's spread; with (axis value, Q, following, paper Q, paper following) per column, and
/// (axis value, ours within, the |H| < N part alone within) for the following behaviours.
#[allow(clippy::type_complexity)]
fn paper_rows(
    s: &SweepSummary,
    ax: usize,
    paper: &[(f64, f64, f64, f64, f64)],
) -> Result<
    (
        String,
        Vec<(f64, f64, f64, f64, f64)>,
        Vec<(f64, bool, bool)>,
    ),
    EvalError,
> {
    let mut q_row = String::from("| Q = abs(V_p) |");
    let mut f_row = String::from("| following |");
    let mut small_row = String::from("| of which \\|H\\| < N (Eq. 8) |");
    let mut reach_row = String::from("| of which H out of reach (ours) |");
    let mut w_row = String::from("| within (Q, following) |");
    let mut ours = Vec::new();
    let mut fits = Vec::new();
    for &(x, pq, pqs, pf, pfs) in paper {
        let cells = cells_with(s, ax, x);
        let (q, qs) = pooled(&cells, "parent_vertices");
        // The split is taken run by run, so both counts must come from the same runs (one
        // plan gives both, so a run has both or neither).
        for c in &cells {
            let (a, b) = (c.stat("following"), c.stat("following_out_of_reach"));
            if a.samples.len() != b.samples.len() || a.missing != b.missing {
                return Err(EvalError::Plan(format!(
                    "cell {}: following and following_out_of_reach come from different runs \
                     ({} and {} values)",
                    c.values.join(", "),
                    a.samples.len(),
                    b.samples.len()
                )));
            }
        }
        let following = samples(&cells, "following");
        let out_of_reach = samples(&cells, "following_out_of_reach");
        let few_in_h: Vec<f64> = following
            .iter()
            .zip(&out_of_reach)
            .map(|(f, r)| f - r)
            .collect();
        let (f, fs) = mean_std(&following);
        let (h, hs) = mean_std(&few_in_h);
        let (r, rs) = mean_std(&out_of_reach);
        q_row.push_str(&format!(" {pq:.1} ± {pqs:.1} | {q:.1} ± {qs:.1} |"));
        f_row.push_str(&format!(" {pf:.1} ± {pfs:.1} | {f:.1} ± {fs:.1} |"));
        small_row.push_str(&format!(" | {h:.1} ± {hs:.1} |"));
        reach_row.push_str(&format!(" | {r:.1} ± {rs:.1} |"));
        let yes = |b: bool| if b { "yes" } else { "no" };
        w_row.push_str(&format!(
            " | {}, {} |",
            yes(within(q, pq, pqs)),
            yes(within(f, pf, pfs))
        ));
        ours.push((x, q, f, pq, pf));
        fits.push((x, within(f, pf, pfs), within(h, pf, pfs)));
    }
    Ok((
        format!("{q_row}\n{f_row}\n{small_row}\n{reach_row}\n{w_row}\n\n"),
        ours,
        fits,
    ))
}

/// Runs or resumes `sweep` in `dir`, the report's own folder under `results/runs/`. A folder
/// that another sweep file or another build of hetsim made (its `identity.json` differs) is
/// removed and the sweep run afresh: resuming it would mix rows of another planner into the
/// tables.
pub fn run_cached(
    sweep: &Sweep,
    dir: &Path,
    jobs: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<SweepSummary, EvalError> {
    match run_sweep(sweep, dir, jobs, (1, 1), progress) {
        Err(SweepError::Mismatch { what, .. }) => {
            eprintln!(
                "{}: made by another sweep or build ({what} differ); running it afresh",
                dir.display()
            );
            std::fs::remove_dir_all(dir).map_err(FileError::at(dir))?;
            Ok(run_sweep(sweep, dir, jobs, (1, 1), progress)?)
        }
        other => Ok(other?),
    }
}

/// One figure of the report: a sweep's cells split into panels by one axis, with the
/// number of children on another.
struct Figure<'a> {
    summary: &'a SweepSummary,
    axis: usize,
    children_axis: usize,
    values: &'static [f64],
    label: fn(f64) -> String,
}

impl<'a> Figure<'a> {
    /// Fig. 3's panels: obstruction 0, 20 and 40 %.
    fn obstruction(summary: &'a SweepSummary, axis: usize, children_axis: usize) -> Self {
        Self {
            summary,
            axis,
            children_axis,
            values: &[0.0, 0.2, 0.4],
            label: |r| format!("obstruction {} %", (r * 100.0) as u32),
        }
    }

    /// Fig. 4's panels: r_los 1, 2, 4 and 8 m.
    fn r_los(summary: &'a SweepSummary, axis: usize, children_axis: usize) -> Self {
        Self {
            summary,
            axis,
            children_axis,
            values: &[1.0, 2.0, 4.0, 8.0],
            label: |r| format!("r_los {r} m"),
        }
    }

    /// `f` of each panel's cells and the children axis, panel by panel.
    fn per_panel<T>(&self, f: fn(&[&SummaryCell], usize) -> T) -> Vec<T> {
        self.values
            .iter()
            .map(|&v| f(&cells_with(self.summary, self.axis, v), self.children_axis))
            .collect()
    }

    /// Each panel's title and boxes.
    fn panels(&self) -> Vec<(String, Vec<StackedBox>)> {
        self.values
            .iter()
            .map(|&v| {
                (
                    ((self.label)(v)),
                    boxes(&cells_with(self.summary, self.axis, v), self.children_axis),
                )
            })
            .collect()
    }
}

/// One shipped sweep, run or resumed, and its summary.
struct Ran {
    sweep: Sweep,
    summary: SweepSummary,
}

/// The shipped sweeps the report reads (`scenarios/sweeps/<name>.toml`).
struct Shipped {
    table1: Ran,
    table2: Ran,
    start_points: Ran,
    start_points_fig3: Ran,
    obstacle_sizes: Ran,
    readings1: Ran,
    readings2: Ran,
    border1: Ran,
    border2: Ran,
    overlap1: Ran,
    overlap2: Ran,
}

impl Shipped {
    /// Runs or resumes each shipped sweep in `results/runs/sweep-<name>`.
    fn run(
        root: &Path,
        jobs: usize,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, EvalError> {
        let sweep = |name: &str| -> Result<Ran, EvalError> {
            let file = load_sweep(&root.join(format!("scenarios/sweeps/{name}.toml")))?;
            let dir = root.join(format!("results/runs/sweep-{name}"));
            let summary = run_cached(&file, &dir, jobs, progress)?;
            Ok(Ran {
                sweep: file,
                summary,
            })
        };
        Ok(Self {
            table1: sweep("table1")?,
            table2: sweep("table2")?,
            start_points: sweep("start-points")?,
            start_points_fig3: sweep("start-points-fig3")?,
            obstacle_sizes: sweep("obstacle-sizes")?,
            readings1: sweep("readings-table1")?,
            readings2: sweep("readings-table2")?,
            border1: sweep("map-border-table1")?,
            border2: sweep("map-border-table2")?,
            overlap1: sweep("obstacle-overlap-table1")?,
            overlap2: sweep("obstacle-overlap-table2")?,
        })
    }
}

/// The index of `sweep`'s axis `name`.
fn axis(sweep: &Sweep, name: &str) -> Result<usize, EvalError> {
    sweep
        .axes()
        .iter()
        .position(|a| a == name)
        .ok_or_else(|| EvalError::Scenario(format!("sweep {} has no axis {name}", sweep.file.name)))
}

/// The axes the tables and figures split the sweeps by.
struct Axes {
    /// Table I: obstruction, children.
    ratio1: usize,
    kids1: usize,
    /// Table II: r_los, children.
    rlos2: usize,
    kids2: usize,
    /// `start-points`: r_los, children.
    rlos_sp: usize,
    kids_sp: usize,
    /// `start-points-fig3`: obstruction, children.
    ratio_sp3: usize,
    kids_sp3: usize,
    /// `obstacle-sizes`: obstruction, obstacle sides.
    ratio_sizes: usize,
    sizes: usize,
}

impl Axes {
    fn of(s: &Shipped) -> Result<Self, EvalError> {
        const RATIO: &str = "world.indoor.obstruction_ratio";
        const R_LOS: &str = "coverage.r_los_m";
        const CHILDREN: &str = "coverage.children";
        Ok(Self {
            ratio1: axis(&s.table1.sweep, RATIO)?,
            kids1: axis(&s.table1.sweep, CHILDREN)?,
            rlos2: axis(&s.table2.sweep, R_LOS)?,
            kids2: axis(&s.table2.sweep, CHILDREN)?,
            rlos_sp: axis(&s.start_points.sweep, R_LOS)?,
            kids_sp: axis(&s.start_points.sweep, CHILDREN)?,
            ratio_sp3: axis(&s.start_points_fig3.sweep, RATIO)?,
            kids_sp3: axis(&s.start_points_fig3.sweep, CHILDREN)?,
            ratio_sizes: axis(&s.obstacle_sizes.sweep, RATIO)?,
            sizes: axis(&s.obstacle_sizes.sweep, "world.indoor.obstacle_cells")?,
        })
    }
}

/// Figs. 3 and 4, with every grab checked and with only the starting points checked.
struct Figures<'a> {
    fig3: Figure<'a>,
    fig4: Figure<'a>,
    fig3_sp: Figure<'a>,
    fig4_sp: Figure<'a>,
}

impl<'a> Figures<'a> {
    fn of(s: &'a Shipped, ax: &Axes) -> Self {
        Self {
            fig3: Figure::obstruction(&s.table1.summary, ax.ratio1, ax.kids1),
            fig4: Figure::r_los(&s.table2.summary, ax.rlos2, ax.kids2),
            fig3_sp: Figure::obstruction(&s.start_points_fig3.summary, ax.ratio_sp3, ax.kids_sp3),
            fig4_sp: Figure::r_los(&s.start_points.summary, ax.rlos_sp, ax.kids_sp),
        }
    }

    /// Writes the four figures' PNGs under `root/results/`.
    fn write(&self, root: &Path) -> Result<(), EvalError> {
        for (name, title, panels) in [
            (
                "coverage-fig3.png",
                "Fig. 3: timesteps by number of children, r_los 2 m",
                self.fig3.panels(),
            ),
            (
                "coverage-fig4.png",
                "Fig. 4: timesteps by number of children, obstruction 20 %",
                self.fig4.panels(),
            ),
            (
                "coverage-fig3-start-points.png",
                "Fig. 3 with only the starting points checked, r_los 2 m",
                self.fig3_sp.panels(),
            ),
            (
                "coverage-fig4-start-points.png",
                "Fig. 4 with only the starting points checked, obstruction 20 %",
                self.fig4_sp.panels(),
            ),
        ] {
            let path = root.join("results").join(name);
            write_atomic(&path, &stacked_boxes_png(title, &panels))?;
        }
        Ok(())
    }
}

/// What the best-team table found, for the discussion.
struct Teams {
    best4: Vec<String>,
    best3_sp: Vec<String>,
    best4_sp: Vec<String>,
    paper_team_maps: Vec<(usize, usize)>,
    fastest: Vec<String>,
    falls_sp: Vec<String>,
}

/// The best team, per map, by mapping, and the steps that lower mapping, per panel.
fn best_teams(md: &mut String, figs: &Figures) -> Teams {
    let Figures {
        fig3,
        fig4,
        fig3_sp,
        fig4_sp,
    } = figs;
    let best3 = fig3.per_panel(best_team_label);
    let best4 = fig4.per_panel(best_team_label);
    let best3_sp = fig3_sp.per_panel(best_team_label);
    let best4_sp = fig4_sp.per_panel(best_team_label);
    // Fig. 3's panels, then Fig. 4's.
    let both = |a: &Figure, b: &Figure, f: fn(&[&SummaryCell], usize) -> String| {
        [a.per_panel(f), b.per_panel(f)].concat()
    };
    let fastest = both(fig3, fig4, fastest_mapping);
    let per_map = both(fig3, fig4, teams::best_team_per_map);
    // On how many maps the paper's team is the best, and of how many, per Fig. 4 panel.
    let paper_team_maps: Vec<(usize, usize)> = PAPER_FIG4_BEST
        .iter()
        .zip(fig4.per_panel(teams::wins_per_map))
        .map(|(n, wins)| (wins.get(n).copied().unwrap_or(0), wins.values().sum()))
        .collect();
    let fastest_sp = both(fig3_sp, fig4_sp, fastest_mapping);
    // Mapping falling at every child added (the paper's "generally decrease").
    let falls_grab = both(fig3, fig4, falling_steps);
    let falls_sp = both(fig3_sp, fig4_sp, falling_steps);
    md.push_str("The number of children with the least mean total timesteps, and in brackets those within 1 % of it (the paper states the best team for Fig. 4 only; its 2 m panel is Fig. 3's 20 %), the number with the least total on each of the 10 maps (children on how many maps; at 0 % the map and the start are the same every time), the number with the fewest mean mapping timesteps, and of the 7 steps from 1 to 8 children how many lower the mean mapping timesteps (the paper: mapping \"generally\" decreases with more children):\n\n| | Fig. 3: 0 % | 20 % | 40 % | Fig. 4: 1 m | 2 m | 4 m | 8 m |\n|---|---|---|---|---|---|---|---|\n");
    md.push_str(&format!(
        "| paper, best team | | {} | | {} | {} | {} | {} |\n| hetsim, best team | {} | {} | {} | {} | {} | {} | {} |\n| hetsim, best team per map | {} |\n| hetsim, fewest mapping timesteps | {} |\n| hetsim, steps that lower mapping | {} |\n| hetsim, grabs not checked (start points only), best team | {} | {} | {} | {} | {} | {} | {} |\n| grabs not checked, fewest mapping timesteps | {} |\n| grabs not checked, steps that lower mapping | {} |\n\nWith one child nothing else stands in its view, so the two view rules give the same 1-child runs. Fig. 3's 20 % and Fig. 4's 2 m panels are the same maps and settings (the same runs under each rule).\n\n",
        // Fig. 3's 20 % panel is Fig. 4's 2 m one, so its paper team is the second.
        PAPER_FIG4_BEST[1], PAPER_FIG4_BEST[0], PAPER_FIG4_BEST[1], PAPER_FIG4_BEST[2], PAPER_FIG4_BEST[3],
        best3[0], best3[1], best3[2], best4[0], best4[1], best4[2], best4[3],
        per_map.join(" | "),
        fastest.join(" | "),
        falls_grab.join(" | "),
        best3_sp[0], best3_sp[1], best3_sp[2],
        best4_sp[0], best4_sp[1], best4_sp[2], best4_sp[3],
        fastest_sp.join(" | "),
        falls_sp.join(" | "),
    ));
    Teams {
        best4,
        best3_sp,
        best4_sp,
        paper_team_maps,
        fastest,
        falls_sp,
    }
}

/// The sections on the points the paper leaves open: obstacles' sizes and overlap, the
/// map's border, the other readings, and what moves each entry.
fn open_points(md: &mut String, s: &Shipped, ax: &Axes) -> Result<(), EvalError> {
    md.push_str(&obstacles::sizes(
        &s.obstacle_sizes.summary,
        ax.ratio_sizes,
        ax.sizes,
    ));
    let reading_names: Vec<&str> = hetsim_coverage::Reading::ALL[1..]
        .iter()
        .map(|r| r.name())
        .collect();
    /// `ran`'s runs by its axis `column`, and by its readings where `reading`.
    fn runs<'a>(
        ran: &'a Ran,
        column: &str,
        reading: bool,
    ) -> Result<readings::Runs<'a>, EvalError> {
        Ok(readings::Runs {
            summary: &ran.summary,
            column_axis: axis(&ran.sweep, column)?,
            reading_axis: if reading {
                Some(axis(&ran.sweep, "coverage.reading")?)
            } else {
                None
            },
        })
    }
    let over = obstacles::Maps {
        t1: &s.overlap1.summary,
        ratio_axis: axis(&s.overlap1.sweep, "world.indoor.obstruction_ratio")?,
        kids1: axis(&s.overlap1.sweep, "coverage.children")?,
        t2: &s.overlap2.summary,
        r_los_axis: axis(&s.overlap2.sweep, "coverage.r_los_m")?,
        kids2: axis(&s.overlap2.sweep, "coverage.children")?,
    };
    let apart = obstacles::Maps {
        t1: &s.table1.summary,
        ratio_axis: ax.ratio1,
        kids1: ax.kids1,
        t2: &s.table2.summary,
        r_los_axis: ax.rlos2,
        kids2: ax.kids2,
    };
    md.push_str(&obstacles::overlap(&apart, &over));
    let (ratio, r_los) = ("world.indoor.obstruction_ratio", "coverage.r_los_m");
    let ours = [
        runs(&s.table1, ratio, false)?,
        runs(&s.table2, r_los, false)?,
    ];
    let others = [
        runs(&s.readings1, ratio, true)?,
        runs(&s.readings2, r_los, true)?,
    ];
    let inside = [
        runs(&s.border1, ratio, false)?,
        runs(&s.border2, r_los, false)?,
    ];
    md.push_str(&readings::border(ours, inside));
    md.push_str("## Readings of the open points\n\n`scenarios/sweeps/readings-table1.toml` and `readings-table2.toml`: Tables I-II's maps and teams (1 to 8 children) under each other reading of a point Section IV leaves open (`[coverage] reading`), one decision changed at a time: `parent_a_point` (LOS_free drops only the vertices whose view holds the parent's centre, not its disc), `los_strict` (LOS radius < r_los, not <=), `los_open` (a vertex is in LOS when the sight line crosses the inside of no occupied cell, as a camera's does, so it may graze an obstacle cell's corner or pass between two that meet at one; ours may touch no occupied cell), `eq6_last_choice` (Eq. 6's candidates within f of the last parent vertex chosen, not of any), `eq6_every_choice` (Eq. 6 as written, within f of every one chosen; the whole map where none is), `ties_nearest_last` and `ties_nearest_any` (ties in the score to the vertex nearest the last / any choice, then the lowest index), `h_from_los_free` (H = LOS_free ∩ LOS_free, not LOS ∩ LOS as Eq. 8 has it), `tour_8_connected` (the tour's distance transform over the 8 cells around a vertex, each step costing 1 and none cutting an occupied corner, not over the 4 the robots step to: Section IV states 4, so this one only measures what the tour's metric does), `n_uncovered` (n(v) counts the uncovered free vertices around v, not all free ones, so a vertex's weight w_s grows as its neighbours are covered). `ours` is the shipped reading (the runs of Tables I-II above). Mean ± sample standard deviation over the 80 runs of a column; 'within' counts the six distinct columns within the paper's spread (3 % at 0 %, where it gives none). The sentence under the tables, computed from them, names the readings that bring the most entries within it; docs/coverage-planning.md (\"Coverage planning decisions\") says why the shipped readings stay.\n\n");
    md.push_str(&readings::tables(ours, others, &reading_names));
    let sizes = readings::Runs {
        summary: &s.obstacle_sizes.summary,
        column_axis: ax.ratio_sizes,
        reading_axis: None,
    };
    md.push_str(&spread::section(
        &spread::readings(ours, others, &reading_names),
        &spread::maps(
            ours,
            over.runs(),
            inside,
            (sizes, ax.sizes),
            &spread::shipped_sides(&s.table1.sweep.base_text),
        ),
    ));
    Ok(())
}

/// Every cell's timesteps, coverage, skipped stages and revisits.
fn cells_section(md: &mut String, s: &Shipped) {
    md.push_str("## Timesteps and coverage per cell\n\nMean timesteps per cell (mapping + coordination, each mean rounded on its own, so the total may differ from their sum by one), the mean coverage of V \\ V_p, and the least coverage of any run of the cell, of V \\ V_p and of the vertices some vertex sees freely (Eq. 4's promise: 1 wherever its assumption holds; `uncoverable` vertices are the rest), with the stages skipped (a transition the moves could not complete; their vertices are revisited) and the vertices imaged after the tour, summed over the cell. `table1` and `start-points-fig3` are at r_los = 2 m, `table2` and `start-points` at 20 % obstruction; `start-points*` check only the starting points:\n\n| sweep | cell | mapping | coordination | total | coverage | least coverage | least coverable coverage | skipped stages | revisited |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for (name, ran) in [
        ("table1", &s.table1),
        ("table2", &s.table2),
        ("start-points-fig3", &s.start_points_fig3),
        ("start-points", &s.start_points),
    ] {
        let axes = ran.sweep.axes();
        for c in &ran.summary.cells {
            let label: Vec<String> = axes
                .iter()
                .zip(&c.values)
                .map(|(a, v)| format!("{}={v}", a.rsplit('.').next().unwrap_or(a)))
                .collect();
            let least = |m: &str| c.stat(m).least();
            let sum = |m: &str| c.stat(m).samples.iter().sum::<f64>();
            md.push_str(&format!(
                "| {name} | {} | {:.0} | {:.0} | {:.0} | {:.4} | {:.4} | {:.4} | {} | {} |\n",
                label.join(", "),
                c.stat("mapping_timesteps").mean,
                c.stat("coordination_timesteps").mean,
                c.stat("total_timesteps").mean,
                c.stat("coverage").mean,
                least("coverage"),
                least("coverable_coverage"),
                sum("skipped_stages"),
                sum("revisited")
            ));
        }
    }
}

/// Runs (or resumes) the shipped sweeps and writes the report and its figures under
/// `root/results/`. Returns the report's path.
pub fn coverage_report(
    root: &Path,
    jobs: usize,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<std::path::PathBuf, EvalError> {
    let shipped = Shipped::run(root, jobs, progress)?;
    let ax = Axes::of(&shipped)?;
    let mut md = String::from(
        "# Coverage planning: seed 002's Tables I and II and Figs. 3 and 4, reproduced\n\n",
    );
    md.push_str("Generated by `hetsim report coverage` (runs or resumes `scenarios/sweeps/table1.toml` and `table2.toml`: 30 x 30 m maps, d = 0.5 m, 80 deg cameras, mapping east, 10 random maps per cell, 1 to 8 children; and `start-points-fig3.toml`, `start-points.toml`, `obstacle-sizes.toml`, `obstacle-overlap-table1.toml` / `obstacle-overlap-table2.toml`, `map-border-table1.toml` / `map-border-table2.toml` and `readings-table1.toml` / `readings-table2.toml`, below). Our figures are mean ± sample standard deviation over the runs of all numbers of children (each map once per number of children, as the paper pools following behaviours; Q does not depend on N, so its ± is the spread over maps, slightly shrunk by the repetition). 'Within' compares with the paper's mean ± its standard deviation; where the paper gives none (Q at 0 %, one fixed map), within 3 %. Table II's 2 m column is Table I's 20 % column (the same runs).\n\n");
    md.push_str("The paper's view rule holds at every grab (\"no robot must stand in the field of view of another robot at the instance an image is grabbed\", Section II): a child grabs only when no other robot its camera could see, at any distance, is in its 80 deg view (`views = \"every_grab\"`, the default). A robot is in view when the cone, widened by the angle its half-side subtends, holds it and its centre or a point of the diameter across the sight line of the disc that holds its footprint (the half-diagonal, plus `view_margin_m`: 0 here, 0.04 m in the lab and 0.12 m in indoor-team) is in sight, the diameter sampled at its ends and every 1/16 cell or less between; testing the edges too (2026-11-27) moved, of Tables I-II, only following at 20 % (40.6 to 40.7), and no best team; per-cell timesteps moved by up to 3.7 % (53 of 88 cells changed); it removed indoor-team's last two images with a robot in view. Sampling the whole diameter (every 1/16 cell or less, not only its ends; later the same day) moved one cell's mean coordination by one timestep (4 m, 7 children: 1540 to 1539) and no lab or indoor-team digest. `start-points-fig3.toml` and `start-points.toml` relax it to the stages' starting points only, for comparison (further down).\n\n");
    md.push_str("## Table I: parent vertices Q and following behaviours by obstruction (r_los = 2 m)\n\n| | 0 % (paper) | 0 % (hetsim) | 20 % (paper) | 20 % (hetsim) | 40 % (paper) | 40 % (hetsim) |\n|---|---|---|---|---|---|---|\n");
    let (rows1, ours1, fits1) = paper_rows(&shipped.table1.summary, ax.ratio1, &PAPER_TABLE1)?;
    md.push_str(&rows1);
    md.push_str("## Table II: Q and following behaviours by line-of-sight radius (20 % obstruction)\n\n| | 1 m (paper) | 1 m (hetsim) | 2 m (paper) | 2 m (hetsim) | 4 m (paper) | 4 m (hetsim) | 8 m (paper) | 8 m (hetsim) |\n|---|---|---|---|---|---|---|---|---|\n");
    let (rows2, ours2, fits2) = paper_rows(&shipped.table2.summary, ax.rlos2, &PAPER_TABLE2)?;
    md.push_str(&rows2);
    let figs = Figures::of(&shipped, &ax);
    figs.write(root)?;
    md.push_str("## Figs. 3 and 4: timesteps by number of children\n\nEach box is the distribution of total timesteps over the 10 maps of a cell (whiskers min-max, box quartiles, black line median); the fill is blue up to the median mapping timesteps and orange above (coordination). x: number of children 1-8.\n\n![Fig. 3: obstruction 0, 20, 40 %](coverage-fig3.png)\n\n![Fig. 4: r_los = 1, 2, 4, 8 m at 20 % (panel titles in metres)](coverage-fig4.png)\n\n");
    let teams = best_teams(&mut md, &figs);
    md.push_str("## Figs. 3 and 4 with only the starting points checked\n\n`scenarios/sweeps/start-points-fig3.toml` and `start-points.toml`: Figs. 3 and 4's maps and teams again with the view rule relaxed to what Section IV.C says of the starting points (no starting point in the view of another); grabs are not checked, so images may show robots. Without waits for clear views the children's parallel walks pay off longer: mapping falls with every child added, and the best team grows further with r_los.\n\n![Fig. 3 with only the starting points checked](coverage-fig3-start-points.png)\n\n![Fig. 4 with only the starting points checked](coverage-fig4-start-points.png)\n\n");
    open_points(&mut md, &shipped, &ax)?;
    cells_section(&mut md, &shipped);
    // The distinct columns: Table II's 2 m is Table I's 20 % (the same runs).
    let fits: Vec<(String, bool, bool)> = fits1
        .iter()
        .map(|&(x, a, b)| (format!("{:.0} %", x * 100.0), a, b))
        .chain(
            fits2
                .iter()
                .filter(|f| f.0 != 2.0)
                .map(|&(x, a, b)| (format!("{x} m"), a, b)),
        )
        .collect();
    md.push_str(&discussion(
        &ours1,
        &ours2,
        &fits,
        &teams.best4,
        &teams.paper_team_maps,
        &teams.fastest,
        Relaxed {
            best3: &teams.best3_sp,
            best4: &teams.best4_sp,
            falls: &teams.falls_sp,
        },
    ));
    let path = root.join("results/coverage-tables.md");
    write_atomic(&path, md.as_bytes())?;
    Ok(path)
}

/// Figs. 3 and 4 with only the starting points checked: best teams per panel, and the steps
/// from 1 to 8 children that lower mapping (Fig. 3's panels, then Fig. 4's).
struct Relaxed<'a> {
    best3: &'a [String],
    best4: &'a [String],
    falls: &'a [String],
}

/// Where and why our figures differ from the paper's; the numbers are read from the runs.
fn discussion(
    t1: &[(f64, f64, f64, f64, f64)],
    t2: &[(f64, f64, f64, f64, f64)],
    fits: &[(String, bool, bool)],
    best4: &[String],
    paper_team_maps: &[(usize, usize)],
    fastest: &[String],
    relaxed: Relaxed,
) -> String {
    let pct = |ours: f64, paper: f64| 100.0 * (ours - paper) / paper;
    let mut s = String::from("\n## Differences and why\n\n");
    s.push_str("- **Maps.** The paper's random maps are not published; ours come from hetsim's generator (rectangles of 1-6 cells that do not overlap, connectivity kept), so individual maps differ and only the trends and magnitudes can be compared. At 0 % the map is fixed in both, which is why Q has no spread there.\n");
    let (r0, q0, _, p0, _) = t1[0];
    s.push_str(&format!("- **Q at {:.0} %** is {q0:.1} against {p0:.1} ({:+.0} %). Q depends on the open points of the greedy choice (weights updated over what is still uncovered, Eq. 6 read as 'within f of some parent vertex', ties to the lowest index) and on the exact LOS and view-cone geometry (robots as discs), all of which the paper leaves open, and on whether the map's walls lie inside its 30 m (\"Q and the map's border\" above); the readings table above and the coverage decisions in docs/coverage-planning.md give Q under the other readings we measured. None is tuned to the paper's value.\n", r0 * 100.0, pct(q0, p0)));
    let (_, q40, _, p40, _) = t1[2];
    let (_, q20, _, p20, _) = t1[1];
    s.push_str(&format!("- **Q against obstruction.** Ours goes from {q0:.1} (0 %) over {q20:.1} (20 %) to {q40:.1} (40 %), {:+.0} % / {:+.0} % from the paper at 20 / 40 %; the paper's rises to 180.5 at 20 % then falls to 174.9 at 40 %. The obstacles decide it (\"Q and the obstacles' sizes\" and \"Obstacles over each other\" above): with the generator's sides of 1-6 cells, not overlapping, many small rectangles fragment lines of sight and Q rises with clutter; with larger obstacles, or the same ones allowed over each other so that they merge into fewer, larger ones, the same share of the floor cuts fewer lines of sight and Q no longer rises at 40 %, as the paper's does not. The paper gives neither their sizes nor whether they may overlap, so the default stays: choosing among rules it does not give by how well they fit its tables would be tuning.\n", pct(q20, p20), pct(q40, p40)));
    let list = |pick: fn(&(String, bool, bool)) -> bool| {
        let v: Vec<&str> = fits
            .iter()
            .filter(|f| pick(f))
            .map(|f| f.0.as_str())
            .collect();
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(", ")
        }
    };
    s.push_str(&format!("- **Following behaviours** are counted when fewer than N vertices lie in H = LOS(v_p^t) ∩ LOS(v_p^(t+1)) (Eq. 8), as the paper defines them, and also when the children cannot get to N of them through LOS(v_p^t), where the parent can track them (ours: the paper does not say what happens then). Children go to vertices of H off the parent's path where there are N of those. A child that a stage left outside the parent's line of sight may cross anything to get to H (it is out of sight already). They grow with obstruction and fall with r_los in both. The two rows under each table's following row split ours by cause (counted per run: `following_out_of_reach` in the sweeps' `runs.csv`; the first row is the rest). Within the paper's spread, of the {} distinct columns (Table II's 2 m is Table I's 20 %): ours in {}; the |H| < N part alone in {}.\n", fits.len(), list(|f| f.1), list(|f| f.2)));
    let rl: Vec<String> = t2
        .iter()
        .map(|(r, q, _, p, _)| format!("{r} m: {q:.1} vs {p:.1}"))
        .collect();
    s.push_str(&format!("- **Table II** ({}): Q falls steeply with r_los in both. Differences at small radii come from the LOS radius test (centre distance <= r_los, so r_los = 1 m sees only 12 neighbours) and at large radii from the view cone, which with r_los = 8 m excludes a long wedge west of each parent vertex.\n", rl.join("; ")));
    s.push_str(&format!("- **Timesteps** (`robots/coverage/src/execute.rs`). Mapping: the children walk their roadmaps in parallel, one step per timestep each; a child done with its walk steps out of the view of a child waiting to grab; a round ends as soon as a child is idle while another still walks, and what is still to image gets a new round of roadmaps from where the children stand, so that the idle child takes a share of it; only what no round images is mopped up one vertex at a time. The roadmaps grow in parallel in time (the child whose walk, its way to its start point included, is shortest grows first), and goals are paired with start points in the same order across the direction of mapping, so that paths do not swap sides (`robots/coverage/src/roadmap.rs`). Coordination: the team moves together, as the paper's [17] behaviour-based formations (children into H all at once; in a following behaviour the children walk in file behind the parent and spread into its line of sight together); where that gets stuck (corridors, a robot ahead of the parent) the rest moves one robot at a time, which is why coordination still grows steeply with N at r_los = 1 m and at 40 %. Mapping timesteps are fewest with {} / {} / {} children at 0 / 20 / 40 % and {} / {} / {} / {} at r_los = 1 / 2 / 4 / 8 m (the best-team table above; the per-cell table above has every mean), and where that is under 8 they rise again with more children: children wait for clear views and for each other in the crowded stages (docs/coverage-planning.md, \"Mapping with many children\", has the measurements and the other ways of sharing a stage we tried); coordination grows with N, as the paper says. The least total is at {} / {} / {} / {} children for r_los = 1 / 2 / 4 / 8 m (brackets: within 1 %) against the paper's 2 / 3 / 5 / 7; map by map, the paper's team is the best on {} (the per-map row above).\n", fastest[0], fastest[1], fastest[2], fastest[3], fastest[4], fastest[5], fastest[6], best4[0], best4[1], best4[2], best4[3], paper_team_maps.iter().map(|&(w, m)| if m == 0 { "-".to_string() } else { format!("{w} of {m}") }).collect::<Vec<_>>().join(" / ")));
    let sp = relaxed;
    s.push_str(&format!("- **Grabs not checked.** With the view rule relaxed to the starting points (`start-points-fig3.toml`, `start-points.toml`), the steps from 1 to 8 children that lower mean mapping are {} at 0 / 20 / 40 % and {} at r_los = 1 / 2 / 4 / 8 m, the best team is {} / {} / {} at 0 / 20 / 40 % and {} / {} / {} / {} at 1 / 2 / 4 / 8 m: without the waits for clear views at every grab (which the paper's planner promises too, but whose cost its Figs. 3-4 may not show) larger teams pay off for longer, mapping falls as the paper says it generally does, and the best team grows with r_los (where it is 8, the largest team swept, a larger one might be better still).\n", sp.falls[..3].join(" / "), sp.falls[3..].join(" / "), sp.best3[0], sp.best3[1], sp.best3[2], sp.best4[0], sp.best4[1], sp.best4[2], sp.best4[3]));
    s.push_str("- **Coverage** is not reported by the paper (Eq. 4 promises every vertex wherever every vertex is in some LOS_free). Ours images every vertex some vertex sees freely in every run (the least coverable coverage column): robots make way for each other, the parent backs off to let a pocket of children out of a dead end and steps aside to let a child behind it, and what a stage could not reach is imaged after the tour from another vertex that sees it freely (`robots/coverage/src/execute/moves.rs`). Coverage of all of V \\ V_p is below 1 only by the uncoverable vertices, which no vertex sees freely.\n");
    s
}
