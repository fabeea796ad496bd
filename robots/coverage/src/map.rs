//! The vertex grid: free cells, 4-neighbourhoods, geodesic distances and paths.

use hetsim_msgs::OccupancyGrid;
use std::collections::VecDeque;

/// A vertex index, `row * cols + col`.
pub type Vertex = usize;

/// Neighbour order used everywhere: east, north, west, south (fixed for reproducible ties).
const STEPS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

/// The grid of vertices V: the centres of the free `d x d` cells of an occupancy grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Map {
    /// Columns (x, east).
    pub cols: usize,
    /// Rows (y, north).
    pub rows: usize,
    /// Vertex spacing d, metres.
    pub cell_m: f64,
    free: Vec<bool>,
}

impl Map {
    /// The vertex grid of an occupancy grid.
    pub fn from_grid(grid: &OccupancyGrid) -> Self {
        Self {
            cols: grid.cols,
            rows: grid.rows,
            cell_m: grid.cell_m,
            free: grid.occupied.iter().map(|o| !o).collect(),
        }
    }

    /// A map from rows of text, north first: `#` occupied, anything else free.
    pub fn from_text(rows: &[&str], cell_m: f64) -> Self {
        let cols = rows[0].len();
        let mut free = Vec::new();
        for line in rows.iter().rev() {
            assert_eq!(line.len(), cols, "ragged map");
            free.extend(line.chars().map(|c| c != '#'));
        }
        Self {
            cols,
            rows: rows.len(),
            cell_m,
            free,
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.free.len()
    }

    /// Whether the map has no cells.
    pub fn is_empty(&self) -> bool {
        self.free.is_empty()
    }

    /// Whether vertex `v` is free (is in V).
    pub fn is_free(&self, v: Vertex) -> bool {
        self.free[v]
    }

    /// All free vertices, ascending.
    pub fn vertices(&self) -> Vec<Vertex> {
        (0..self.free.len()).filter(|&v| self.free[v]).collect()
    }

    /// `(col, row)` of a vertex.
    pub fn cell(&self, v: Vertex) -> (usize, usize) {
        (v % self.cols, v / self.cols)
    }

    /// The vertex at `(col, row)`, if inside the map.
    pub fn at(&self, col: i64, row: i64) -> Option<Vertex> {
        (col >= 0 && row >= 0 && (col as usize) < self.cols && (row as usize) < self.rows)
            .then(|| row as usize * self.cols + col as usize)
    }

    /// Free 4-neighbours in the order east, north, west, south.
    pub fn neighbours(&self, v: Vertex) -> impl Iterator<Item = Vertex> + '_ {
        let (c, r) = self.cell(v);
        STEPS
            .iter()
            .filter_map(move |(dc, dr)| self.at(c as i64 + dc, r as i64 + dr))
            .filter(|&n| self.free[n])
    }

    /// Number of free vertices among the 8 cells around `v`.
    pub fn free_8_neighbours(&self, v: Vertex) -> usize {
        self.free_8_around(v).count()
    }

    /// The free vertices among the 8 cells around `v`.
    pub fn free_8_around(&self, v: Vertex) -> impl Iterator<Item = Vertex> + '_ {
        let (c, r) = self.cell(v);
        (-1..=1i64)
            .flat_map(|dr| (-1..=1i64).map(move |dc| (dc, dr)))
            .filter(|&d| d != (0, 0))
            .filter_map(move |(dc, dr)| self.at(c as i64 + dc, r as i64 + dr))
            .filter(|&u| self.free[u])
    }

    /// Whether two vertices are one up/down/left/right step apart.
    pub fn adjacent(&self, a: Vertex, b: Vertex) -> bool {
        let ((ac, ar), (bc, br)) = (self.cell(a), self.cell(b));
        ac.abs_diff(bc) + ar.abs_diff(br) == 1
    }

    /// Euclidean distance between vertex centres, metres.
    pub fn distance_m(&self, a: Vertex, b: Vertex) -> f64 {
        let ((ac, ar), (bc, br)) = (self.cell(a), self.cell(b));
        (ac as f64 - bc as f64).hypot(ar as f64 - br as f64) * self.cell_m
    }

    /// Geodesic (4-connected step) distances from `from` over free vertices for which
    /// `passable` holds; `usize::MAX` where unreachable. This is the distance transform.
    pub fn distances(&self, from: Vertex, passable: impl Fn(Vertex) -> bool) -> Vec<usize> {
        let mut dist = vec![usize::MAX; self.len()];
        dist[from] = 0;
        let mut queue = VecDeque::from([from]);
        while let Some(v) = queue.pop_front() {
            for n in self.neighbours(v) {
                if dist[n] == usize::MAX && passable(n) {
                    dist[n] = dist[v] + 1;
                    queue.push_back(n);
                }
            }
        }
        dist
    }

    /// Geodesic distances from `from` over free vertices stepping to any of the 8 cells
    /// around a vertex, each step costing 1; a diagonal step only where both cells it passes
    /// between are free (it cuts no occupied corner). `usize::MAX` where unreachable. The
    /// distance transform as [`crate::Reading::Tour8Connected`] reads it.
    pub fn distances_8(&self, from: Vertex) -> Vec<usize> {
        let mut dist = vec![usize::MAX; self.len()];
        dist[from] = 0;
        let mut queue = VecDeque::from([from]);
        let free = |c: i64, r: i64| self.at(c, r).filter(|&u| self.free[u]);
        while let Some(v) = queue.pop_front() {
            let (c, r) = self.cell(v);
            let (c, r) = (c as i64, r as i64);
            for (dc, dr) in [
                (1, 0),
                (1, 1),
                (0, 1),
                (-1, 1),
                (-1, 0),
                (-1, -1),
                (0, -1),
                (1, -1),
            ] {
                let Some(n) = free(c + dc, r + dr) else {
                    continue;
                };
                let corner_free = free(c + dc, r).is_some() && free(c, r + dr).is_some();
                if dist[n] == usize::MAX && (dc == 0 || dr == 0 || corner_free) {
                    dist[n] = dist[v] + 1;
                    queue.push_back(n);
                }
            }
        }
        dist
    }

    /// [`Self::distances`], stopped once every vertex of `until` is reached: exact for every
    /// vertex nearer `from` than the farthest of them (and for them), `usize::MAX` for the
    /// rest. Enough to walk from any of them to `from` by always stepping to a nearer
    /// neighbour, or to compare their distances.
    pub fn distances_until(
        &self,
        from: Vertex,
        passable: impl Fn(Vertex) -> bool,
        until: &[Vertex],
    ) -> Vec<usize> {
        let mut dist = vec![usize::MAX; self.len()];
        dist[from] = 0;
        let mut left: Vec<Vertex> = until.to_vec();
        left.sort_unstable();
        left.dedup();
        let mut queue = VecDeque::from([from]);
        while let Some(v) = queue.pop_front() {
            if let Ok(i) = left.binary_search(&v) {
                left.remove(i);
                if left.is_empty() {
                    break;
                }
            }
            for n in self.neighbours(v) {
                if dist[n] == usize::MAX && passable(n) {
                    dist[n] = dist[v] + 1;
                    queue.push_back(n);
                }
            }
        }
        dist
    }

    /// A shortest path from `from` to the first vertex (in BFS order) satisfying `goal`,
    /// through vertices where `passable` holds; both ends included.
    pub fn path_to(
        &self,
        from: Vertex,
        goal: impl Fn(Vertex) -> bool,
        passable: impl Fn(Vertex) -> bool,
    ) -> Option<Vec<Vertex>> {
        if goal(from) {
            return Some(vec![from]);
        }
        let mut parent = vec![usize::MAX; self.len()];
        parent[from] = from;
        let mut queue = VecDeque::from([from]);
        while let Some(v) = queue.pop_front() {
            for n in self.neighbours(v) {
                if parent[n] != usize::MAX || !passable(n) {
                    continue;
                }
                parent[n] = v;
                if goal(n) {
                    let mut path = vec![n];
                    let mut at = n;
                    while at != from {
                        at = parent[at];
                        path.push(at);
                    }
                    path.reverse();
                    return Some(path);
                }
                queue.push_back(n);
            }
        }
        None
    }
}

/// A random `size` x `size` map of 0.5 m cells, each occupied with probability `occupied`
/// (the unit tests' random maps).
#[cfg(test)]
pub(crate) fn random_map(rng: &mut rand_chacha::ChaCha8Rng, size: usize, occupied: f64) -> Map {
    use rand::RngExt;
    let rows: Vec<String> = (0..size)
        .map(|_| {
            (0..size)
                .map(|_| {
                    if rng.random::<f64>() < occupied {
                        '#'
                    } else {
                        '.'
                    }
                })
                .collect()
        })
        .collect();
    let refs: Vec<&str> = rows.iter().map(String::as_str).collect();
    Map::from_text(&refs, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_search_stopped_at_its_targets_agrees_with_the_whole_one_up_to_them() {
        let m = Map::from_text(
            &[
                "......#...",
                ".####.#.#.",
                "......#.#.",
                "..........",
                "...#......",
            ],
            0.5,
        );
        let from = m.at(0, 0).unwrap();
        let full = m.distances(from, |_| true);
        // At 6 and 8 steps: a search that stopped at the first target would leave the
        // second unlabelled.
        let targets = [m.at(4, 0).unwrap(), m.at(5, 3).unwrap()];
        let part = m.distances_until(from, |_| true, &targets);
        let reach = targets.iter().map(|&t| full[t]).max().unwrap();
        assert_ne!(full[targets[0]], full[targets[1]]);
        for v in m.vertices() {
            if full[v] < reach || targets.contains(&v) {
                assert_eq!(part[v], full[v], "{:?}", m.cell(v));
            } else {
                assert!(
                    part[v] == full[v] || part[v] == usize::MAX,
                    "{:?}",
                    m.cell(v)
                );
            }
        }
        // Somewhere beyond the targets was left unsearched.
        let unsearched = |d: &[usize]| d.iter().filter(|&&x| x == usize::MAX).count();
        assert!(unsearched(&part) > unsearched(&full));
    }

    #[test]
    fn neighbours_and_distances() {
        let m = Map::from_text(&["....", ".##.", "...."], 0.5);
        let v = m.at(0, 1).unwrap();
        assert_eq!(
            m.neighbours(v).collect::<Vec<_>>(),
            vec![m.at(0, 2).unwrap(), m.at(0, 0).unwrap()]
        );
        assert_eq!(m.free_8_neighbours(m.at(0, 0).unwrap()), 2);
        let d = m.distances(m.at(0, 1).unwrap(), |_| true);
        assert_eq!(d[m.at(3, 1).unwrap()], 5);
        assert_eq!(d[m.at(1, 1).unwrap()], usize::MAX);
        // Over 8 neighbours, open ground: (3, 2) is 3 steps from (0, 0) (2 diagonal, 1
        // east; 5 over 4 neighbours). Around the obstacle the diagonals past its corners
        // ((0, 1) -> (1, 0), (2, 0) -> (3, 1)) would cut them, so the way round is 5 steps,
        // as over 4.
        let open = Map::from_text(&["....", "....", "...."], 0.5);
        assert_eq!(
            open.distances_8(open.at(0, 0).unwrap())[open.at(3, 2).unwrap()],
            3
        );
        let d8 = m.distances_8(m.at(0, 1).unwrap());
        assert_eq!(d8[m.at(3, 1).unwrap()], 5);
        assert_eq!(d8[m.at(1, 1).unwrap()], usize::MAX);
        let p = m
            .path_to(m.at(0, 1).unwrap(), |v| v == m.at(3, 1).unwrap(), |_| true)
            .unwrap();
        assert_eq!(p.len(), 6);
    }
}
