//! Triangle meshes for the world and the robots, with face coordinates for texturing.

use crate::bake::{self, layer};
use hetsim_msgs::Pose;
use hetsim_scene::world::{Solid, SolidKind, Terrain, World};
use nalgebra::{Point3, Vector3};

/// One vertex: world position, normal, texture coordinates (in texture tiles; for the terrain,
/// in [0, 1] over its extent), material layer, and a linear tint (RGBA8) that multiplies the
/// texture.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub layer: u32,
    pub tint: [u8; 4],
}

/// Vertices and triangle indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Mesh {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
}

/// How a box is textured: the layer and tint of its side faces and of its top and bottom,
/// metres per texture tile, and an offset in tiles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Skin {
    pub side: u32,
    pub top: u32,
    pub tint: [u8; 4],
    pub tile_m: f64,
    pub offset: [f64; 2],
}

/// A box of a robot, in the robot's body frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobotPart {
    /// Centre in the body frame, metres.
    pub centre: [f64; 3],
    /// Half sizes, metres.
    pub half_extents: [f64; 3],
    /// Draw it as an orange hat (the tracker's target) instead of the body colour.
    pub hat: bool,
}

/// A robot to draw this frame.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotDraw {
    /// `world_from_body`.
    pub pose: Pose,
    /// Its boxes.
    pub parts: Vec<RobotPart>,
    /// Colour choice.
    pub seed: u32,
}

impl Mesh {
    /// Appends a box given by its pose (box frame to world), half sizes and material. Face
    /// coordinates: on side faces u runs along the face's horizontal edge and v up from the
    /// box's bottom; on top and bottom faces they are the box-frame x and y.
    pub fn push_box(&mut self, world_from_box: &Pose, half: [f64; 3], skin: &Skin) {
        let [hx, hy, hz] = half;
        // (normal, u axis, v axis) in the box frame; the face is at normal * half.
        let faces: [([f64; 3], [f64; 3], [f64; 3]); 6] = [
            ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
            ([-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]),
            ([0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            ([0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            ([0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ];
        let extent = |a: [f64; 3]| (a[0] * hx).abs() + (a[1] * hy).abs() + (a[2] * hz).abs();
        for (n, u, v) in faces {
            let (eu, ev) = (extent(u), extent(v));
            let centre = Vector3::new(n[0] * hx, n[1] * hy, n[2] * hz);
            let base = self.vertices.len() as u32;
            let normal = world_from_box.rotation * Vector3::from(n);
            for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let local = centre + Vector3::from(u) * (su * eu) + Vector3::from(v) * (sv * ev);
                let world = world_from_box * Point3::from(local);
                // Side faces: v from the bottom; top/bottom: box-frame coordinates.
                let uv = if n[2] == 0.0 {
                    [(su + 1.0) * eu, (sv + 1.0) * ev]
                } else {
                    [local.x, local.y]
                };
                // Texture rows run downwards: v = -height / tile puts row 0 at the top.
                self.vertices.push(Vertex {
                    position: [world.x as f32, world.y as f32, world.z as f32],
                    normal: [normal.x as f32, normal.y as f32, normal.z as f32],
                    uv: [
                        (uv[0] / skin.tile_m + skin.offset[0]) as f32,
                        (-uv[1] / skin.tile_m + skin.offset[1]) as f32,
                    ],
                    layer: if n[2] == 0.0 { skin.side } else { skin.top },
                    tint: skin.tint,
                });
            }
            self.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }

    /// Appends the terrain heightfield as two triangles per cell (split along the same
    /// diagonal as parry's heightfield, so render and physics agree), in square chunks of
    /// [`CHUNK_CELLS`] cells for culling. Texture coordinates span [0, 1] over `extent_m`.
    pub fn push_terrain(&mut self, t: &Terrain, extent_m: f64) -> Vec<Chunk> {
        // The grid's vertices; each chunk and level copies those it uses, so that a draw
        // touches a compact range of vertices (a software rasterizer shades the whole range).
        let mut grid = Vec::with_capacity(t.nx * t.ny);
        let h = |i: usize, j: usize| t.heights[j.min(t.ny - 1) * t.nx + i.min(t.nx - 1)];
        for j in 0..t.ny {
            for i in 0..t.nx {
                let x = t.origin[0] + i as f64 * t.cell_m;
                let y = t.origin[1] + j as f64 * t.cell_m;
                let dzdx = (h(i + 1, j) - h(i.saturating_sub(1), j)) / (2.0 * t.cell_m);
                let dzdy = (h(i, j + 1) - h(i, j.saturating_sub(1))) / (2.0 * t.cell_m);
                let n = Vector3::new(-dzdx, -dzdy, 1.0).normalize();
                grid.push(Vertex {
                    position: [x as f32, y as f32, h(i, j) as f32],
                    normal: [n.x as f32, n.y as f32, n.z as f32],
                    uv: [
                        ((x - t.origin[0]) / extent_m) as f32,
                        ((y - t.origin[1]) / extent_m) as f32,
                    ],
                    layer: 0,
                    tint: [255; 4],
                });
            }
        }
        let mut chunks = Vec::new();
        for cj in (0..t.ny - 1).step_by(CHUNK_CELLS) {
            for ci in (0..t.nx - 1).step_by(CHUNK_CELLS) {
                let (i1, j1) = (
                    (ci + CHUNK_CELLS).min(t.nx - 1),
                    (cj + CHUNK_CELLS).min(t.ny - 1),
                );
                let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
                for j in cj..=j1 {
                    for i in ci..=i1 {
                        let p = grid[j * t.nx + i].position;
                        for k in 0..3 {
                            lo[k] = lo[k].min(p[k]);
                            hi[k] = hi[k].max(p[k]);
                        }
                    }
                }
                let lods = std::array::from_fn(|level| {
                    let start = self.indices.len() as u32;
                    self.push_terrain_lod(t, &grid, [ci, cj], [i1, j1], 1 << level);
                    start..self.indices.len() as u32
                });
                lo[2] -= SKIRT_M as f32;
                chunks.push(Chunk {
                    lods,
                    min: lo,
                    max: hi,
                });
            }
        }
        chunks
    }

    /// One chunk of the terrain at a level of detail: every `step`-th grid vertex, and at
    /// coarser levels a skirt hanging [`SKIRT_M`] below the chunk's edges so that no gap
    /// opens where a finer neighbour has vertices between ours.
    fn push_terrain_lod(
        &mut self,
        t: &Terrain,
        grid: &[Vertex],
        [i0, j0]: [usize; 2],
        [i1, j1]: [usize; 2],
        step: usize,
    ) {
        // Grid lines at multiples of `step`, always including the chunk's far edges.
        let lines = |a: usize, b: usize| {
            let mut v: Vec<usize> = (a..b).step_by(step).collect();
            v.push(b);
            v
        };
        let (xs, ys) = (lines(i0, i1), lines(j0, j1));
        let first = self.vertices.len() as u32;
        for &j in &ys {
            for &i in &xs {
                self.vertices.push(grid[j * t.nx + i]);
            }
        }
        // The copy of grid vertex (i, j), which lies on this level's lines.
        let column = |i: usize| xs.iter().position(|&x| x == i).expect("on a line") as u32;
        let row = |j: usize| ys.iter().position(|&y| y == j).expect("on a line") as u32;
        let at = |i: usize, j: usize| first + row(j) * xs.len() as u32 + column(i);
        for w in ys.windows(2) {
            for u in xs.windows(2) {
                let (a, b, c, d) = (
                    at(u[0], w[0]),
                    at(u[1], w[0]),
                    at(u[0], w[1]),
                    at(u[1], w[1]),
                );
                self.indices.extend([a, b, d, a, d, c]);
            }
        }
        if step == 1 {
            return;
        }
        // The edges counter-clockwise seen from above (interior on the left): south, east,
        // north, west; each skirt quad faces outwards.
        let mut ring: Vec<(usize, usize)> = xs.iter().map(|&i| (i, j0)).collect();
        ring.extend(ys[1..].iter().map(|&j| (i1, j)));
        ring.extend(xs.iter().rev().skip(1).map(|&i| (i, j1)));
        ring.extend(ys.iter().rev().skip(1).map(|&j| (i0, j)));
        for e in ring.windows(2) {
            let (p, q) = (at(e[0].0, e[0].1), at(e[1].0, e[1].1));
            let low = |v: u32| {
                let mut lowered = self.vertices[v as usize];
                lowered.position[2] -= SKIRT_M as f32;
                lowered
            };
            let (pl, ql) = (low(p), low(q));
            let k = self.vertices.len() as u32;
            self.vertices.extend([pl, ql]);
            self.indices.extend([k, k + 1, q, k, q, p]);
        }
    }
}

/// Terrain cells per chunk side.
pub(crate) const CHUNK_CELLS: usize = 16;
/// Levels of detail of a terrain chunk: every 1st, 2nd, 4th, 8th grid vertex.
pub(crate) const LODS: usize = 4;
/// How far terrain skirts hang below the surface, metres.
const SKIRT_M: f64 = 3.0;

/// A culling unit of the terrain: its index range at each level of detail and its bounding
/// box (skirts included).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Chunk {
    pub lods: [std::ops::Range<u32>; LODS],
    pub min: [f32; 3],
    pub max: [f32; 3],
}

/// The static world: boxes (buildings, walls, obstacles, floors) and the terrain.
pub(crate) struct WorldMesh {
    pub objects: Mesh,
    pub terrain: Mesh,
    pub chunks: Vec<Chunk>,
    /// The terrain texture's origin and extent, metres (for baking it).
    pub terrain_area: Option<([f64; 2], f64)>,
}

/// The static world's mesh.
pub(crate) fn world_mesh(world: &World) -> WorldMesh {
    let mut terrain = Mesh::default();
    let mut chunks = Vec::new();
    let mut terrain_area = None;
    if let Some(t) = &world.terrain {
        let extent = (t.nx.max(t.ny) - 1) as f64 * t.cell_m;
        chunks = terrain.push_terrain(t, extent);
        terrain_area = Some((t.origin, extent));
    }
    let mut objects = Mesh::default();
    for s in &world.solids {
        objects.push_box(&solid_pose(s), s.half_extents, &skin(s));
    }
    WorldMesh {
        objects,
        terrain,
        chunks,
        terrain_area,
    }
}

/// A solid's texture: its kind picks the layers, its seed the variant, offset and tint.
fn skin(s: &Solid) -> Skin {
    let seed = s.material_seed;
    let pick = |first: u32, count: u32| first + (seed % count as u64) as u32;
    let h = |k: u32| bake::hash(k as i64, (seed >> 32) as i64, seed as u32);
    let offset = [h(1) as f64, h(2) as f64];
    match s.kind {
        SolidKind::Building => Skin {
            side: pick(layer::FACADE, layer::FACADES),
            top: pick(layer::ROOF, layer::ROOFS),
            tint: [255; 4],
            tile_m: bake::FACADE_TILE_M,
            // Shift along u alone, so that doors and the plinth stay at the base.
            offset: [offset[0], 0.0],
        },
        SolidKind::Wall | SolidKind::Obstacle => {
            let (first, count) = if s.kind == SolidKind::Wall {
                (layer::WALL, layer::WALLS)
            } else {
                (layer::OBSTACLE, layer::OBSTACLES)
            };
            // A hue per object, as light as the old per-seed base colour (0.35 + 0.55 hue).
            let tint = [h(3), h(4), h(5)].map(|c| ((0.35 + 0.55 * c) * 255.0).round() as u8);
            Skin {
                side: pick(first, count),
                top: pick(layer::OBSTACLE, layer::OBSTACLES),
                tint: [tint[0], tint[1], tint[2], 255],
                tile_m: bake::INDOOR_TILE_M,
                offset: if s.kind == SolidKind::Wall {
                    [offset[0], 0.0]
                } else {
                    offset
                },
            }
        }
        SolidKind::Floor => Skin {
            side: layer::FLOOR,
            top: layer::FLOOR,
            tint: [255; 4],
            tile_m: bake::INDOOR_TILE_M,
            offset: [0.0, 0.0],
        },
    }
}

fn solid_pose(s: &Solid) -> Pose {
    hetsim_msgs::pose_from_xyz_rpy(s.centre, [0.0, 0.0, s.yaw_rad])
}

/// The robots' mesh for one frame, and each robot's range of indices.
pub(crate) fn robots_mesh(robots: &[RobotDraw]) -> (Mesh, Vec<std::ops::Range<u32>>) {
    let mut mesh = Mesh::default();
    let mut ranges = Vec::with_capacity(robots.len());
    for r in robots {
        let start = mesh.indices.len() as u32;
        for p in &r.parts {
            let pose = r.pose * hetsim_msgs::pose_from_xyz_rpy(p.centre, [0.0; 3]);
            let tint = if p.hat {
                [255, 115, 13, 255]
            } else if r.seed & 1 == 1 {
                [140, 140, 148, 255]
            } else {
                [64, 77, 102, 255]
            };
            let skin = Skin {
                side: layer::PLAIN,
                top: layer::PLAIN,
                tint,
                tile_m: 1.0,
                offset: [0.0, 0.0],
            };
            mesh.push_box(&pose, p.half_extents, &skin);
        }
        ranges.push(start..mesh.indices.len() as u32);
    }
    (mesh, ranges)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_faces_point_outwards_and_cover_the_box() {
        let mut m = Mesh::default();
        let pose = hetsim_msgs::pose_from_xyz_rpy([1.0, 2.0, 3.0], [0.0, 0.0, 0.5]);
        m.push_box(
            &pose,
            [1.0, 2.0, 3.0],
            &Skin {
                side: 1,
                top: 2,
                tint: [255; 4],
                tile_m: 1.0,
                offset: [0.0; 2],
            },
        );
        assert_eq!((m.vertices.len(), m.indices.len()), (24, 36));
        for tri in m.indices.chunks(3) {
            let p: Vec<Vector3<f64>> = tri
                .iter()
                .map(|&i| Vector3::from(m.vertices[i as usize].position.map(f64::from)))
                .collect();
            let face_n = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
            let n = Vector3::from(m.vertices[tri[0] as usize].normal.map(f64::from));
            assert!((face_n - n).norm() < 1e-5, "winding agrees with the normal");
            let centroid = (p[0] + p[1] + p[2]) / 3.0;
            assert!(
                (centroid - Vector3::new(1.0, 2.0, 3.0)).dot(&n) > 0.0,
                "normal points outwards"
            );
        }
    }
}
