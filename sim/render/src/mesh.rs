//! Triangle meshes for the world and the robots, with face coordinates for texturing.

use hetsim_msgs::Pose;
use hetsim_scene::world::{Solid, SolidKind, Terrain, World};
use nalgebra::{Point3, Vector3};

/// Material kinds understood by `shaders/scene.wgsl`.
pub(crate) mod kind {
    pub const TERRAIN: u32 = 0;
    pub const BUILDING: u32 = 1;
    pub const WALL: u32 = 2;
    pub const OBSTACLE: u32 = 3;
    pub const FLOOR: u32 = 4;
    pub const ROBOT: u32 = 5;
    pub const HAT: u32 = 6;
}

/// One vertex: world position, normal, face coordinates (metres), material (kind, seed).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
    pub material: [u32; 2],
}

/// Vertices and triangle indices.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Mesh {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
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
    pub fn push_box(&mut self, world_from_box: &Pose, half: [f64; 3], material: [u32; 2]) {
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
                self.vertices.push(Vertex {
                    position: [world.x as f32, world.y as f32, world.z as f32],
                    normal: [normal.x as f32, normal.y as f32, normal.z as f32],
                    uv: [uv[0] as f32, uv[1] as f32],
                    material,
                });
            }
            self.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }

    /// Appends the terrain heightfield as two triangles per cell (split along the same
    /// diagonal as parry's heightfield, so render and physics agree).
    pub fn push_terrain(&mut self, t: &Terrain) {
        let base = self.vertices.len() as u32;
        let h = |i: usize, j: usize| t.heights[j.min(t.ny - 1) * t.nx + i.min(t.nx - 1)];
        for j in 0..t.ny {
            for i in 0..t.nx {
                let x = t.origin[0] + i as f64 * t.cell_m;
                let y = t.origin[1] + j as f64 * t.cell_m;
                let dzdx = (h(i + 1, j) - h(i.saturating_sub(1), j)) / (2.0 * t.cell_m);
                let dzdy = (h(i, j + 1) - h(i, j.saturating_sub(1))) / (2.0 * t.cell_m);
                let n = Vector3::new(-dzdx, -dzdy, 1.0).normalize();
                self.vertices.push(Vertex {
                    position: [x as f32, y as f32, h(i, j) as f32],
                    normal: [n.x as f32, n.y as f32, n.z as f32],
                    uv: [x as f32, y as f32],
                    material: [kind::TERRAIN, 0],
                });
            }
        }
        for j in 0..t.ny - 1 {
            for i in 0..t.nx - 1 {
                let a = base + (j * t.nx + i) as u32;
                let b = a + 1;
                let c = a + t.nx as u32;
                let d = c + 1;
                self.indices.extend([a, b, d, a, d, c]);
            }
        }
    }
}

/// The static world's mesh.
pub(crate) fn world_mesh(world: &World) -> Mesh {
    let mut mesh = Mesh::default();
    if let Some(t) = &world.terrain {
        mesh.push_terrain(t);
    }
    for s in &world.solids {
        mesh.push_box(
            &solid_pose(s),
            s.half_extents,
            [solid_kind(s.kind), (s.material_seed & 0xffff_ffff) as u32],
        );
    }
    mesh
}

fn solid_kind(k: SolidKind) -> u32 {
    match k {
        SolidKind::Building => kind::BUILDING,
        SolidKind::Wall => kind::WALL,
        SolidKind::Obstacle => kind::OBSTACLE,
        SolidKind::Floor => kind::FLOOR,
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
            let material = if p.hat {
                [kind::HAT, r.seed]
            } else {
                [kind::ROBOT, r.seed]
            };
            mesh.push_box(&pose, p.half_extents, material);
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
        m.push_box(&pose, [1.0, 2.0, 3.0], [1, 7]);
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
