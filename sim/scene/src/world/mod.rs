//! Static worlds built from a scenario and a seed.
//!
//! A [`World`] is plain geometry: an optional terrain heightfield and a list of boxes
//! ([`Solid`]s), plus, for indoor worlds, the vertex grid. The physics crate turns it into
//! colliders; the renderer draws the same list.

mod indoor;
mod village;

pub use indoor::{generate_indoor, IndoorGrid};
pub use village::generate_village;

use serde::Serialize;

/// What a solid is, for materials and statistics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolidKind {
    /// A village building.
    Building,
    /// An indoor border wall.
    Wall,
    /// An indoor obstacle or piece of furniture.
    Obstacle,
    /// The indoor floor slab (its top is z = 0).
    Floor,
}

/// A box in the world, rotated about z by `yaw_rad`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Solid {
    /// What it is.
    pub kind: SolidKind,
    /// Centre, metres.
    pub centre: [f64; 3],
    /// Half sizes along its own x, y, z, metres.
    pub half_extents: [f64; 3],
    /// Rotation about z, radians.
    pub yaw_rad: f64,
    /// Per-object seed for procedural textures.
    pub material_seed: u64,
}

impl Solid {
    /// Whether a disc of `radius` around world `(x, y)` overlaps the footprint.
    pub fn footprint_overlaps(&self, x: f64, y: f64, radius: f64) -> bool {
        let (dx, dy) = (x - self.centre[0], y - self.centre[1]);
        let (s, c) = self.yaw_rad.sin_cos();
        let (lx, ly) = (c * dx + s * dy, -s * dx + c * dy);
        let qx = (lx.abs() - self.half_extents[0]).max(0.0);
        let qy = (ly.abs() - self.half_extents[1]).max(0.0);
        qx.hypot(qy) < radius
    }

    /// Height of the top face, metres.
    pub fn top_z(&self) -> f64 {
        self.centre[2] + self.half_extents[2]
    }
}

/// A terrain heightfield over a square area, z up.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Terrain {
    /// World xy of sample `(0, 0)` (the south-west corner), metres.
    pub origin: [f64; 2],
    /// Sample spacing, metres.
    pub cell_m: f64,
    /// Samples along x.
    pub nx: usize,
    /// Samples along y.
    pub ny: usize,
    /// Heights, `heights[j * nx + i]` at `origin + (i, j) * cell_m`, metres.
    pub heights: Vec<f64>,
}

impl Terrain {
    /// Height at a world point by bilinear interpolation (clamped to the area).
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let fx = ((x - self.origin[0]) / self.cell_m).clamp(0.0, (self.nx - 1) as f64);
        let fy = ((y - self.origin[1]) / self.cell_m).clamp(0.0, (self.ny - 1) as f64);
        let (i, j) = (
            (fx.floor() as usize).min(self.nx - 2),
            (fy.floor() as usize).min(self.ny - 2),
        );
        let (tx, ty) = (fx - i as f64, fy - j as f64);
        let h = |i: usize, j: usize| self.heights[j * self.nx + i];
        let south = h(i, j) * (1.0 - tx) + h(i + 1, j) * tx;
        let north = h(i, j + 1) * (1.0 - tx) + h(i + 1, j + 1) * tx;
        south * (1.0 - ty) + north * ty
    }
}

/// A generated world.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct World {
    /// Half sizes of the world's xy extent around the origin, metres.
    pub half_extent: [f64; 2],
    /// Terrain (village), or `None` for a flat floor at z = 0.
    pub terrain: Option<Terrain>,
    /// Buildings, walls, obstacles, floor, in creation order.
    pub solids: Vec<Solid>,
    /// The vertex grid (indoor worlds).
    pub grid: Option<IndoorGrid>,
}

impl World {
    /// Ground height at a point: terrain, or 0 indoors.
    pub fn ground_z(&self, x: f64, y: f64) -> f64 {
        self.terrain.as_ref().map_or(0.0, |t| t.height_at(x, y))
    }

    /// The first solid (not the floor) whose footprint overlaps a disc, with its top below
    /// `z_max`: what a robot at that place would stand inside.
    pub fn solid_at(&self, x: f64, y: f64, radius: f64, z: f64) -> Option<&Solid> {
        self.solids.iter().find(|s| {
            s.kind != SolidKind::Floor && s.footprint_overlaps(x, y, radius) && z < s.top_z()
        })
    }
}

/// Places the generator must keep free: robot starts and the routes of ground robots.
#[derive(Clone, Debug, Default)]
pub struct KeepClear {
    /// Polylines (a single point is a polyline of one) with the clearance around each.
    pub paths: Vec<(Vec<[f64; 2]>, f64)>,
}

impl KeepClear {
    /// Distance from a point to the nearest kept path minus that path's clearance (negative
    /// inside a kept area).
    pub fn margin(&self, x: f64, y: f64) -> f64 {
        self.paths
            .iter()
            .map(|(path, clearance)| distance_to_polyline(path, x, y) - clearance)
            .fold(f64::INFINITY, f64::min)
    }
}

fn distance_to_polyline(path: &[[f64; 2]], x: f64, y: f64) -> f64 {
    match path {
        [] => f64::INFINITY,
        [p] => (x - p[0]).hypot(y - p[1]),
        _ => path
            .windows(2)
            .map(|w| {
                let (ax, ay, bx, by) = (w[0][0], w[0][1], w[1][0], w[1][1]);
                let (dx, dy) = (bx - ax, by - ay);
                let len2 = dx * dx + dy * dy;
                let t = if len2 > 0.0 {
                    (((x - ax) * dx + (y - ay) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (x - ax - t * dx).hypot(y - ay - t * dy)
            })
            .fold(f64::INFINITY, f64::min),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_overlap_respects_rotation() {
        let s = Solid {
            kind: SolidKind::Building,
            centre: [0.0, 0.0, 5.0],
            half_extents: [10.0, 1.0, 5.0],
            yaw_rad: std::f64::consts::FRAC_PI_2,
            material_seed: 0,
        };
        assert!(s.footprint_overlaps(0.0, 9.0, 0.1));
        assert!(!s.footprint_overlaps(9.0, 0.0, 0.1));
        assert!(s.footprint_overlaps(1.5, 0.0, 0.6));
    }

    #[test]
    fn keep_clear_measures_distance_to_segments() {
        let k = KeepClear {
            paths: vec![(vec![[0.0, 0.0], [10.0, 0.0]], 2.0)],
        };
        assert!((k.margin(5.0, 3.0) - 1.0).abs() < 1e-12);
        assert!((k.margin(13.0, 4.0) - 3.0).abs() < 1e-12);
        assert!(k.margin(5.0, 1.0) < 0.0);
    }
}
