//! One frame: robots, per-view targets, culling and draw order, one submission, readback.

use crate::camera::CameraView;
use crate::gpu::{
    CameraUniform, Frame, Geometry, Renderer, Target, COLOR_FORMAT, DEPTH_FORMAT,
    LINEAR_DEPTH_FORMAT,
};
use crate::mesh::{robots_mesh, Chunk, RobotDraw};
use nalgebra::{Matrix4, Vector4};

const DEPTH_UNIT_M: f32 = 1e-4;

fn padded_row(width: u32, bytes_per_pixel: u32) -> u32 {
    let row = width * bytes_per_pixel;
    row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// The sky, or the indoor background (gamma-encoded values, as the target holds).
fn background(outdoor: bool) -> wgpu::Color {
    let [r, g, b] = if outdoor {
        [0.55, 0.70, 0.90]
    } else {
        [0.2, 0.2, 0.2]
    };
    wgpu::Color { r, g, b, a: 1.0 }
}

/// Whether a box is entirely outside one of the clip volume's six planes.
fn outside(m: &Matrix4<f64>, lo: [f32; 3], hi: [f32; 3]) -> bool {
    let corners: [Vector4<f64>; 8] = std::array::from_fn(|k| {
        let pick = |axis: usize| f64::from(if k >> axis & 1 == 0 { lo } else { hi }[axis]);
        m * Vector4::new(pick(0), pick(1), pick(2), 1.0)
    });
    let planes: [fn(&Vector4<f64>) -> f64; 6] = [
        |c| c.w + c.x,
        |c| c.w - c.x,
        |c| c.w + c.y,
        |c| c.w - c.y,
        |c| c.z,
        |c| c.w - c.z,
    ];
    planes
        .iter()
        .any(|plane| corners.iter().all(|c| plane(c) < 0.0))
}

/// Distance from the eye beyond which a terrain chunk is drawn at each coarser level of
/// detail, for a focal length of [`LOD_FOCAL_PX`]: a 16 m grid 400 m away is as fine on
/// screen as the 4 m grid 100 m away. Scaled with the view's focal length, so that the
/// decimation error stays the same in pixels.
const LOD_FROM_M: [f64; 3] = [100.0, 200.0, 400.0];
/// The focal length the distances are for: 1024 px over 60°.
const LOD_FOCAL_PX: f64 = 887.0;

/// The terrain chunks a view can see, nearest first to its LOD point (ties by index, so the
/// order is fixed), with the level of detail for each.
fn visible_chunks(chunks: &[Chunk], view: &CameraView, m: &Matrix4<f64>) -> Vec<(usize, usize)> {
    let eye = view
        .lod_from
        .map_or(view.world_from_optical.translation.vector, |p| p.coords);
    let mut seen: Vec<(f64, usize)> = chunks
        .iter()
        .enumerate()
        .filter(|(_, c)| !outside(m, c.min, c.max))
        .map(|(i, c)| {
            // Distance from the eye to the nearest point of the chunk's box.
            let gap = |k: usize, e: f64| {
                (f64::from(c.min[k]) - e)
                    .max(e - f64::from(c.max[k]))
                    .max(0.0)
            };
            let d = gap(0, eye.x).hypot(gap(1, eye.y)).hypot(gap(2, eye.z));
            (d, i)
        })
        .collect();
    seen.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let scale = view.intrinsics.k.alpha_u.max(view.intrinsics.k.alpha_v) / LOD_FOCAL_PX;
    seen.into_iter()
        .map(|(d, i)| {
            let lod = LOD_FROM_M.iter().filter(|&&from| d >= from * scale).count();
            (i, lod)
        })
        .collect()
}

impl Renderer {
    /// Robots to draw in the next frames (a view can hide one of them: its own robot).
    pub fn set_robots(&mut self, robots: &[RobotDraw]) {
        let (mesh, ranges) = robots_mesh(robots);
        if mesh.indices.is_empty() {
            self.robots = None;
            return;
        }
        let vertices: &[u8] = bytemuck::cast_slice(&mesh.vertices);
        let indices: &[u8] = bytemuck::cast_slice(&mesh.indices);
        let fits = self.robots.as_ref().is_some_and(|(g, _)| {
            g.vertices.size() >= vertices.len() as u64 && g.indices.size() >= indices.len() as u64
        });
        if !fits {
            let buffer = |size: usize, usage: wgpu::BufferUsages| {
                self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("robots"),
                    size: size as u64,
                    usage: usage | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            self.robots = Some((
                Geometry {
                    vertices: buffer(vertices.len(), wgpu::BufferUsages::VERTEX),
                    indices: buffer(indices.len(), wgpu::BufferUsages::INDEX),
                    count: 0,
                },
                Vec::new(),
            ));
        }
        let (g, r) = self.robots.as_mut().expect("made above");
        self.queue.write_buffer(&g.vertices, 0, vertices);
        self.queue.write_buffer(&g.indices, 0, indices);
        g.count = mesh.indices.len() as u32;
        *r = ranges;
    }

    fn target(&mut self, slot: usize, size: (u32, u32), depth: bool) {
        if self.targets.get(slot).is_none_or(|t| t.size != size) {
            let t = self.new_target(size);
            if slot < self.targets.len() {
                self.targets[slot] = t;
            } else {
                self.targets.push(t);
            }
        }
        if depth && self.targets[slot].linear_depth.is_none() {
            let texture = self.texture(size, LINEAR_DEPTH_FORMAT, true);
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let buffer = self.readback(size);
            self.targets[slot].linear_depth = Some((texture, view, buffer));
        }
    }

    fn texture(&self, size: (u32, u32), format: wgpu::TextureFormat, read: bool) -> wgpu::Texture {
        let usage = if read {
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC
        } else {
            wgpu::TextureUsages::RENDER_ATTACHMENT
        };
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("target"),
            size: wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    fn readback(&self, size: (u32, u32)) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: (padded_row(size.0, 4) * size.1) as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        })
    }

    fn new_target(&self, size: (u32, u32)) -> Target {
        let color = self.texture(size, COLOR_FORMAT, true);
        let color_view = color.create_view(&wgpu::TextureViewDescriptor::default());
        let depth_view = self
            .texture(size, DEPTH_FORMAT, false)
            .create_view(&wgpu::TextureViewDescriptor::default());
        let uniform = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("camera"),
            size: std::mem::size_of::<CameraUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let [terrain, detail, layers] = &self.textures;
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("camera and materials"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(terrain),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: wgpu::BindingResource::TextureView(detail),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(layers),
                },
            ],
        });
        Target {
            size,
            color_buf: self.readback(size),
            color,
            color_view,
            depth_view,
            linear_depth: None,
            uniform,
            bind_group,
        }
    }

    /// Records one view: objects first (they hide terrain), then the visible terrain chunks
    /// nearest first, so that early depth testing skips hidden terrain.
    fn encode(&self, encoder: &mut wgpu::CommandEncoder, slot: usize, v: &CameraView) {
        let t = &self.targets[slot];
        let m = v.view_proj();
        let mut view_proj = [[0f32; 4]; 4];
        for (c, column) in view_proj.iter_mut().enumerate() {
            for (r, value) in column.iter_mut().enumerate() {
                *value = m[(r, c)] as f32;
            }
        }
        let eye = v.world_from_optical.translation.vector;
        let fwd = v.world_from_optical.rotation * nalgebra::Vector3::z();
        let uniform = CameraUniform {
            view_proj,
            eye: [
                eye.x as f32,
                eye.y as f32,
                eye.z as f32,
                if self.outdoor { 1.0 } else { 0.0 },
            ],
            forward: [fwd.x as f32, fwd.y as f32, fwd.z as f32, 0.0],
        };
        self.queue
            .write_buffer(&t.uniform, 0, bytemuck::bytes_of(&uniform));
        let linear = t.linear_depth.as_ref().filter(|_| v.depth);
        let mut attachments = vec![Some(wgpu::RenderPassColorAttachment {
            view: &t.color_view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(background(self.outdoor)),
                store: wgpu::StoreOp::Store,
            },
        })];
        if let Some((_, view, _)) = linear {
            attachments.push(Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            }));
        }
        let (object, terrain) = if linear.is_some() {
            (&self.pipelines.object_depth, &self.pipelines.terrain_depth)
        } else {
            (&self.pipelines.object, &self.pipelines.terrain)
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &t.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &t.bind_group, &[]);
        pass.set_pipeline(object);
        if let Some(g) = &self.robots.as_ref().filter(|(g, _)| g.count > 0) {
            let (g, ranges) = g;
            pass.set_vertex_buffer(0, g.vertices.slice(..));
            pass.set_index_buffer(g.indices.slice(..), wgpu::IndexFormat::Uint32);
            for (robot, range) in ranges.iter().enumerate() {
                if v.hide_robot != Some(robot) {
                    pass.draw_indexed(range.clone(), 0, 0..1);
                }
            }
        }
        if let Some(g) = &self.objects {
            pass.set_vertex_buffer(0, g.vertices.slice(..));
            pass.set_index_buffer(g.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..g.count, 0, 0..1);
        }
        if let Some((g, chunks)) = &self.terrain {
            pass.set_pipeline(terrain);
            pass.set_vertex_buffer(0, g.vertices.slice(..));
            pass.set_index_buffer(g.indices.slice(..), wgpu::IndexFormat::Uint32);
            for (i, lod) in visible_chunks(chunks, v, &m) {
                pass.draw_indexed(chunks[i].lods[lod].clone(), 0, 0..1);
            }
        }
    }

    /// Renders every view in one submission and reads the images back (depth only for the
    /// views that ask for it).
    pub fn render(&mut self, views: &[CameraView]) -> Vec<Frame> {
        for (slot, v) in views.iter().enumerate() {
            self.target(slot, (v.intrinsics.width, v.intrinsics.height), v.depth);
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("cameras"),
            });
        for (slot, v) in views.iter().enumerate() {
            self.encode(&mut encoder, slot, v);
            let t = &self.targets[slot];
            let (w, h) = t.size;
            let mut copies = vec![(&t.color, &t.color_buf)];
            if let Some((texture, _, buffer)) = t.linear_depth.as_ref().filter(|_| v.depth) {
                copies.push((texture, buffer));
            }
            for (texture, buffer) in copies {
                encoder.copy_texture_to_buffer(
                    wgpu::TexelCopyTextureInfo {
                        texture,
                        mip_level: 0,
                        origin: wgpu::Origin3d::ZERO,
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::TexelCopyBufferInfo {
                        buffer,
                        layout: wgpu::TexelCopyBufferLayout {
                            offset: 0,
                            bytes_per_row: Some(padded_row(w, 4)),
                            rows_per_image: Some(h),
                        },
                    },
                    wgpu::Extent3d {
                        width: w,
                        height: h,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
        self.queue.submit([encoder.finish()]);
        for (t, v) in self.targets.iter().zip(views) {
            let depth = t.linear_depth.as_ref().filter(|_| v.depth);
            for b in std::iter::once(&t.color_buf).chain(depth.map(|(_, _, d)| d)) {
                b.map_async(wgpu::MapMode::Read, .., |r| {
                    r.expect("mapping a readback buffer")
                });
            }
        }
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .expect("the device finishes its work");
        let mut frames = Vec::with_capacity(views.len());
        for (t, v) in self.targets.iter().zip(views) {
            let (w, h) = t.size;
            let (row, tight) = (padded_row(w, 4) as usize, 4 * w as usize);
            let copy_rows = |buffer: &wgpu::Buffer| {
                let mapped = buffer.get_mapped_range(..).expect("mapped");
                let bytes = if row == tight {
                    mapped[..tight * h as usize].to_vec()
                } else {
                    let mut out = Vec::with_capacity(tight * h as usize);
                    for r in mapped.chunks_exact(row).take(h as usize) {
                        out.extend_from_slice(&r[..tight]);
                    }
                    out
                };
                drop(mapped);
                buffer.unmap();
                bytes
            };
            let rgba = copy_rows(&t.color_buf);
            let depth_m = t
                .linear_depth
                .as_ref()
                .filter(|_| v.depth)
                .map(|(_, _, buffer)| {
                    let units: Vec<u32> = bytemuck::pod_collect_to_vec(&copy_rows(buffer));
                    units.iter().map(|&u| u as f32 * DEPTH_UNIT_M).collect()
                });
            frames.push(Frame {
                width: w,
                height: h,
                rgba,
                depth_m,
            });
        }
        frames
    }
}
