//! Indoor grids and the lab: a walled floor, fixed furniture and random obstacles.
//!
//! The floor `W x H` is divided into `d x d` cells; each cell's centre is a grid vertex. A cell
//! is occupied when its centre lies inside an obstacle's footprint. Random obstacles are
//! axis-aligned rectangles of whole cells, sides drawn from `obstacle_cells`, heights from
//! `obstacle_height_m`, placed at random free positions until the occupied fraction of the
//! floor reaches `obstruction_ratio`. A placement is refused when it would cover a kept cell
//! (robot starts) or split the free cells into more than one 4-connected component, so every
//! free vertex stays reachable by up/down/left/right moves, and, unless
//! `obstacles_overlap`, when it would cover a cell another obstacle occupies (then obstacles
//! never overlap, though they may touch; with it, they merge into larger ones, and only a
//! placement's new cells count). Fixed obstacles can still
//! disconnect the floor: the vertices outside the component of the first kept cell (or the
//! largest component) are then reported in [`IndoorGrid::unreachable`]. Because every obstacle
//! is taller than the robots' sensors, line of sight on the grid and in 3D agree.

use super::{KeepClear, Solid, SolidKind, World};
use crate::scenario::IndoorSpec;
use hetsim_core::Streams;
use hetsim_msgs::OccupancyGrid;
use rand::{Rng, RngExt};
use serde::Serialize;
use std::collections::VecDeque;

/// The vertex grid of an indoor world and how generation went.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IndoorGrid {
    /// One cell per vertex; occupied where an obstacle stands.
    pub grid: OccupancyGrid,
    /// The obstruction ratio the scenario asked for.
    pub requested_ratio: f64,
    /// The obstruction ratio realised (occupied cells / all cells), fixed obstacles included.
    pub realised_ratio: f64,
    /// Free vertices that cannot be reached from the main free component, `(col, row)`.
    pub unreachable: Vec<(usize, usize)>,
}

/// Builds an indoor world for a seed.
pub fn generate_indoor(spec: &IndoorSpec, streams: &Streams, keep: &KeepClear) -> World {
    let d = spec.spacing_m;
    let cols = (spec.width_m / d).round() as usize;
    let rows = (spec.height_m / d).round() as usize;
    let mut grid = OccupancyGrid {
        origin_x: -spec.width_m / 2.0,
        origin_y: -spec.height_m / 2.0,
        cell_m: d,
        cols,
        rows,
        occupied: vec![false; cols * rows],
    };
    let mut rng = streams.stream("world/indoor/obstacles");
    let mut solids = vec![floor(spec)];
    solids.extend(walls(spec));
    for b in &spec.obstacles {
        let solid = Solid {
            kind: SolidKind::Obstacle,
            centre: [b.centre[0], b.centre[1], b.height_m / 2.0],
            half_extents: [b.size_m[0] / 2.0, b.size_m[1] / 2.0, b.height_m / 2.0],
            yaw_rad: b.yaw_deg.to_radians(),
            material_seed: rng.next_u64(),
        };
        for row in 0..rows {
            for col in 0..cols {
                let [x, y] = grid.centre_of(col, row);
                if solid.footprint_overlaps(x, y, 1e-9) {
                    grid.occupied[row * cols + col] = true;
                }
            }
        }
        solids.push(solid);
    }
    // Cells a robot starts in (or whose centre is within a robot's clearance) stay free.
    let kept: Vec<bool> = (0..rows * cols)
        .map(|i| {
            let [x, y] = grid.centre_of(i % cols, i / cols);
            keep.margin(x, y) < d / 2.0
        })
        .collect();
    let target = (spec.obstruction_ratio * (cols * rows) as f64).round() as usize;
    let mut occupied = grid.occupied.iter().filter(|o| **o).count();
    let [lo, hi] = spec.obstacle_cells;
    let mut attempts = 0;
    while occupied < target && attempts < 50 * target.max(1) {
        attempts += 1;
        let w = rng.random_range(lo..=hi) as usize;
        let h = rng.random_range(lo..=hi) as usize;
        if w > cols || h > rows {
            continue;
        }
        let c0 = rng.random_range(0..=cols - w);
        let r0 = rng.random_range(0..=rows - h);
        let height = rng.random_range(spec.obstacle_height_m[0]..=spec.obstacle_height_m[1]);
        let material = rng.next_u64();
        let cells: Vec<usize> = (r0..r0 + h)
            .flat_map(|r| (c0..c0 + w).map(move |c| r * cols + c))
            .collect();
        if cells
            .iter()
            .any(|&i| kept[i] || (grid.occupied[i] && !spec.obstacles_overlap))
        {
            continue;
        }
        // Over other obstacles (`obstacles_overlap`) only the new cells count.
        let cells: Vec<usize> = cells.into_iter().filter(|&i| !grid.occupied[i]).collect();
        if cells.is_empty() {
            continue;
        }
        for &i in &cells {
            grid.occupied[i] = true;
        }
        if component_count(&grid) > 1 {
            for &i in &cells {
                grid.occupied[i] = false;
            }
            continue;
        }
        occupied += cells.len();
        let [x0, y0] = [grid.origin_x + c0 as f64 * d, grid.origin_y + r0 as f64 * d];
        solids.push(Solid {
            kind: SolidKind::Obstacle,
            centre: [
                x0 + w as f64 * d / 2.0,
                y0 + h as f64 * d / 2.0,
                height / 2.0,
            ],
            half_extents: [w as f64 * d / 2.0, h as f64 * d / 2.0, height / 2.0],
            yaw_rad: 0.0,
            material_seed: material,
        });
    }
    let anchor = kept.iter().position(|k| *k);
    let unreachable = unreachable_cells(&grid, anchor);
    let realised_ratio = occupied as f64 / (cols * rows) as f64;
    World {
        half_extent: [spec.width_m / 2.0, spec.height_m / 2.0],
        terrain: None,
        solids,
        grid: Some(IndoorGrid {
            grid,
            requested_ratio: spec.obstruction_ratio,
            realised_ratio,
            unreachable,
        }),
    }
}

fn floor(spec: &IndoorSpec) -> Solid {
    Solid {
        kind: SolidKind::Floor,
        centre: [0.0, 0.0, -0.05],
        half_extents: [spec.width_m / 2.0 + 0.1, spec.height_m / 2.0 + 0.1, 0.05],
        yaw_rad: 0.0,
        material_seed: 0,
    }
}

/// Four 0.1 m thick walls just outside the floor.
fn walls(spec: &IndoorSpec) -> Vec<Solid> {
    let (hw, hh, t) = (spec.width_m / 2.0, spec.height_m / 2.0, 0.05);
    let z = spec.wall_height_m / 2.0;
    let wall = |cx: f64, cy: f64, hx: f64, hy: f64, k: u64| Solid {
        kind: SolidKind::Wall,
        centre: [cx, cy, z],
        half_extents: [hx, hy, z],
        yaw_rad: 0.0,
        material_seed: k,
    };
    vec![
        wall(0.0, -hh - t, hw + 2.0 * t, t, 1),
        wall(hw + t, 0.0, t, hh, 2),
        wall(0.0, hh + t, hw + 2.0 * t, t, 3),
        wall(-hw - t, 0.0, t, hh, 4),
    ]
}

/// Labels of the 4-connected free components, `usize::MAX` on occupied cells.
fn components(grid: &OccupancyGrid) -> (Vec<usize>, usize) {
    let (cols, rows) = (grid.cols, grid.rows);
    let mut label = vec![usize::MAX; cols * rows];
    let mut count = 0;
    for start in 0..cols * rows {
        if grid.occupied[start] || label[start] != usize::MAX {
            continue;
        }
        label[start] = count;
        let mut queue = VecDeque::from([start]);
        while let Some(i) = queue.pop_front() {
            let (c, r) = ((i % cols) as i64, (i / cols) as i64);
            for (dc, dr) in [(1, 0), (0, 1), (-1, 0), (0, -1)] {
                let (nc, nr) = (c + dc, r + dr);
                if grid.is_free(nc, nr) {
                    let j = nr as usize * cols + nc as usize;
                    if label[j] == usize::MAX {
                        label[j] = count;
                        queue.push_back(j);
                    }
                }
            }
        }
        count += 1;
    }
    (label, count)
}

fn component_count(grid: &OccupancyGrid) -> usize {
    components(grid).1
}

/// Free cells outside the component of `anchor` (or the largest component).
fn unreachable_cells(grid: &OccupancyGrid, anchor: Option<usize>) -> Vec<(usize, usize)> {
    let (label, count) = components(grid);
    if count <= 1 {
        return Vec::new();
    }
    let main = match anchor.filter(|&a| label[a] != usize::MAX) {
        Some(a) => label[a],
        None => {
            let mut sizes = vec![0usize; count];
            for &l in label.iter().filter(|l| **l != usize::MAX) {
                sizes[l] += 1;
            }
            // Largest first; ties to the lowest label, which is the south-westmost component.
            (0..count)
                .max_by_key(|&k| (sizes[k], std::cmp::Reverse(k)))
                .unwrap_or(0)
        }
    };
    (0..label.len())
        .filter(|&i| label[i] != usize::MAX && label[i] != main)
        .map(|i| (i % grid.cols, i / grid.cols))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The random obstacles of a 30 x 30 m floor at 40 %, with or without overlaps.
    fn grid_40(overlap: bool, seed: u64) -> World {
        let spec = IndoorSpec {
            obstruction_ratio: 0.4,
            obstacles_overlap: overlap,
            ..IndoorSpec::default()
        };
        generate_indoor(&spec, &Streams::new(seed), &KeepClear::default())
    }

    /// Whether the footprints of two axis-aligned obstacles share some area.
    fn overlap(a: &Solid, b: &Solid) -> bool {
        (0..2).all(|k| {
            (a.centre[k] - b.centre[k]).abs() < a.half_extents[k] + b.half_extents[k] - 1e-9
        })
    }

    #[test]
    fn obstacles_overlap_only_when_asked_and_the_grid_is_their_union() {
        for seed in 0..3 {
            for asked in [false, true] {
                let world = grid_40(asked, seed);
                let g = world.grid.as_ref().unwrap();
                let obstacles: Vec<&Solid> = world
                    .solids
                    .iter()
                    .filter(|s| s.kind == SolidKind::Obstacle)
                    .collect();
                let pairs = obstacles
                    .iter()
                    .enumerate()
                    .flat_map(|(i, a)| obstacles[i + 1..].iter().map(move |b| (*a, *b)))
                    .filter(|(a, b)| overlap(a, b))
                    .count();
                assert_eq!(pairs > 0, asked, "seed {seed}: {pairs} overlapping pairs");
                // A cell is occupied exactly where some obstacle covers its centre.
                for row in 0..g.grid.rows {
                    for col in 0..g.grid.cols {
                        let [x, y] = g.grid.centre_of(col, row);
                        let covered = obstacles.iter().any(|o| o.footprint_overlaps(x, y, 1e-9));
                        assert_eq!(g.grid.occupied[row * g.grid.cols + col], covered);
                    }
                }
                let occupied = g.grid.occupied.iter().filter(|o| **o).count();
                let realised = occupied as f64 / g.grid.occupied.len() as f64;
                assert_eq!(realised, g.realised_ratio);
                // The request is met to within one obstacle's largest area (36 of 3600 cells).
                assert!((realised - 0.4).abs() <= 0.01, "seed {seed}: {realised}");
                assert_eq!(component_count(&g.grid), 1, "seed {seed}");
            }
        }
    }
}
