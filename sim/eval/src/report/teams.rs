//! The best team map by map: the ten maps of a cell are too few to tell teams whose mean
//! totals lie close apart, so the report also says on how many maps each team is the best.

use crate::sweep::SummaryCell;
use std::collections::BTreeMap;

/// For each number of children (the value on `children_axis`), on how many maps it has the
/// least total timesteps (ties to the smaller team). `cells` hold one number of children
/// each, their samples the same maps in the same order (the sweep's seeds, in run order);
/// empty when a cell misses a value or holds another number of maps, so that no map is
/// paired with another. (A run without a row is in neither count, but the report's sweeps
/// are complete: `run_sweep` fails on a run that fails.)
pub(super) fn wins_per_map(cells: &[&SummaryCell], children_axis: usize) -> BTreeMap<usize, usize> {
    let mut teams: Vec<(usize, &[f64])> = cells
        .iter()
        .filter_map(|c| {
            let n = c.values[children_axis].parse().ok()?;
            Some((n, c.stat("total_timesteps").samples.as_slice()))
        })
        .collect();
    teams.sort_by_key(|t| t.0);
    let maps = teams.first().map_or(0, |t| t.1.len());
    let paired = cells.iter().all(|c| c.stat("total_timesteps").missing == 0)
        && teams.iter().all(|t| t.1.len() == maps);
    let mut wins = BTreeMap::new();
    if !paired {
        return wins;
    }
    for k in 0..maps {
        // The first of the least: teams are sorted, so a tie goes to the smaller one.
        let best = teams.iter().min_by(|a, b| a.1[k].total_cmp(&b.1[k]));
        if let Some(&(n, _)) = best {
            *wins.entry(n).or_insert(0) += 1;
        }
    }
    wins
}

/// [`wins_per_map`] as "3 on 4, 4 on 6" (children on how many maps).
pub(super) fn best_team_per_map(cells: &[&SummaryCell], children_axis: usize) -> String {
    let wins = wins_per_map(cells, children_axis);
    let parts: Vec<String> = wins.iter().map(|(n, w)| format!("{n} on {w}")).collect();
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::best_team_per_map;
    use crate::sweep::SummaryCell;

    fn cell(children: usize, totals: &[f64], missing: usize) -> SummaryCell {
        super::super::testing::test_cell(&children.to_string(), "total_timesteps", totals, missing)
    }

    #[test]
    fn each_map_counts_for_the_team_with_its_least_total() {
        // Map 0: 2 children best; map 1: 3; map 2: 1 and 3 tie, so 1; map 3: 2. The cells
        // come in any order.
        let (one, two, three) = (
            cell(1, &[50.0, 40.0, 30.0, 60.0], 0),
            cell(2, &[20.0, 35.0, 31.0, 10.0], 0),
            cell(3, &[30.0, 25.0, 30.0, 70.0], 0),
        );
        assert_eq!(
            best_team_per_map(&[&three, &one, &two], 0),
            "1 on 1, 2 on 2, 3 on 1"
        );
        // A run without a value in one cell (its 4 values then come from 5 runs), or a cell
        // of fewer maps: the maps cannot be paired, so nothing is said.
        let missing = cell(2, &[20.0, 35.0, 31.0, 10.0], 1);
        assert_eq!(best_team_per_map(&[&one, &missing, &three], 0), "");
        let short = cell(2, &[20.0, 35.0, 31.0], 0);
        assert_eq!(best_team_per_map(&[&one, &short, &three], 0), "");
    }
}
