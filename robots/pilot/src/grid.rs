//! Shortest 4-connected paths on an occupancy grid.

use hetsim_msgs::OccupancyGrid;
use std::collections::VecDeque;

/// Neighbour order used everywhere a grid is searched: east, north, west, south. Fixed so that
/// ties between equally short paths always break the same way.
const STEPS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

/// The shortest path from `from` to `to` moving up/down/left/right through free cells,
/// both ends included; `None` when `to` cannot be reached or either end is not free.
pub fn grid_path(
    grid: &OccupancyGrid,
    from: (usize, usize),
    to: (usize, usize),
) -> Option<Vec<(usize, usize)>> {
    if !grid.is_free(from.0 as i64, from.1 as i64) || !grid.is_free(to.0 as i64, to.1 as i64) {
        return None;
    }
    let index = |c: (usize, usize)| c.1 * grid.cols + c.0;
    let mut parent = vec![usize::MAX; grid.cols * grid.rows];
    parent[index(from)] = index(from);
    let mut queue = VecDeque::from([from]);
    while let Some(cell) = queue.pop_front() {
        if cell == to {
            let mut path = vec![to];
            let mut i = index(to);
            while i != index(from) {
                i = parent[i];
                path.push((i % grid.cols, i / grid.cols));
            }
            path.reverse();
            return Some(path);
        }
        for (dc, dr) in STEPS {
            let (c, r) = (cell.0 as i64 + dc, cell.1 as i64 + dr);
            if grid.is_free(c, r) {
                let next = (c as usize, r as usize);
                if parent[index(next)] == usize::MAX {
                    parent[index(next)] = index(cell);
                    queue.push_back(next);
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> OccupancyGrid {
        // rows given north first, as drawn
        let cols = rows[0].len();
        let mut occupied = Vec::new();
        for line in rows.iter().rev() {
            occupied.extend(line.chars().map(|c| c == '#'));
        }
        OccupancyGrid {
            origin_x: 0.0,
            origin_y: 0.0,
            cell_m: 0.5,
            cols,
            rows: rows.len(),
            occupied,
        }
    }

    #[test]
    fn goes_around_walls_with_unit_steps() {
        let g = grid(&[".....", ".###.", "..#..", "....."]);
        let path = grid_path(&g, (2, 0), (2, 3)).unwrap();
        assert_eq!(path.first(), Some(&(2, 0)));
        assert_eq!(path.last(), Some(&(2, 3)));
        for w in path.windows(2) {
            let d = (w[0].0 as i64 - w[1].0 as i64).abs() + (w[0].1 as i64 - w[1].1 as i64).abs();
            assert_eq!(d, 1);
            assert!(g.is_free(w[1].0 as i64, w[1].1 as i64));
        }
        // Manhattan distance is 3 but the wall forces a detour round its west end:
        // (2,0) (1,0) (1,1) (0,1) (0,2) (0,3) (1,3) (2,3)
        assert_eq!(path.len(), 8);
    }

    #[test]
    fn unreachable_is_none() {
        let g = grid(&["..#.", "..#.", "###."]);
        assert_eq!(grid_path(&g, (0, 2), (3, 0)), None);
        assert_eq!(
            grid_path(&g, (0, 2), (2, 2)),
            None,
            "goal inside an obstacle"
        );
    }
}
