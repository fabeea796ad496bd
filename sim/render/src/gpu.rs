//! The wgpu device, the scene pipeline, and batched render-and-read-back.

use crate::camera::CameraView;
use crate::mesh::{robots_mesh, world_mesh, RobotDraw, Vertex};
use hetsim_scene::world::World;
use wgpu::util::DeviceExt;

/// How to pick the adapter.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderOptions {
    /// `vulkan`, `gl` or `any` (default: the `HETSIM_BACKEND` variable, else `any`).
    pub backend: Option<String>,
    /// A substring of the adapter name (default: the `HETSIM_ADAPTER` variable, else any).
    pub adapter: Option<String>,
}

/// Why rendering cannot start.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter matched.
    #[error("no usable graphics adapter for backend {backend:?}{wanted}; found: {found}. Install a GPU driver, or Mesa's software rasterizers: on Debian `apt-get install mesa-vulkan-drivers libvulkan1` (lavapipe, Vulkan) or `libegl1 libegl-mesa0 libgles2` (llvmpipe, GL); choose one with HETSIM_BACKEND=vulkan|gl and HETSIM_ADAPTER=<name part>")]
    NoAdapter {
        /// The backend asked for.
        backend: String,
        /// The adapter filter, described.
        wanted: String,
        /// Adapters seen.
        found: String,
    },
    /// The value of `HETSIM_BACKEND` (or the option) is not a backend.
    #[error("HETSIM_BACKEND = {0:?} is not allowed: use vulkan, gl or any")]
    BadBackend(String),
    /// Device creation failed.
    #[error("the adapter {adapter} refused a device: {reason}")]
    Device {
        /// Adapter name.
        adapter: String,
        /// Why.
        reason: String,
    },
}

/// Which adapter renders (recorded in the manifest).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    /// Adapter name, e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`.
    pub name: String,
    /// `Vulkan` or `Gl`.
    pub backend: String,
    /// Driver and its version.
    pub driver: String,
}

/// One rendered camera image.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGB, 8 bits per channel, row-major from the top-left.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis, metres, per pixel; 0 where nothing was hit.
    pub depth_m: Vec<f32>,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct CameraUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    forward: [f32; 4],
}

struct Target {
    size: (u32, u32),
    color: wgpu::Texture,
    linear_depth: wgpu::Texture,
    depth: wgpu::TextureView,
    color_buf: wgpu::Buffer,
    depth_buf: wgpu::Buffer,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

/// A headless renderer of one world.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    world: (wgpu::Buffer, wgpu::Buffer, u32),
    robots: Option<(wgpu::Buffer, wgpu::Buffer, Vec<std::ops::Range<u32>>)>,
    targets: Vec<Target>,
    outdoor: bool,
    adapter: AdapterSummary,
}

const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Linear depth in 0.1 mm units (see `scene.wgsl`).
const LINEAR_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
const DEPTH_UNIT_M: f32 = 1e-4;

fn padded_row(width: u32, bytes_per_pixel: u32) -> u32 {
    let row = width * bytes_per_pixel;
    row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

impl Renderer {
    /// A renderer for `world` on the adapter the options (or environment) choose.
    pub fn new(world: &World, options: &RenderOptions) -> Result<Self, RenderError> {
        let backend = options
            .backend
            .clone()
            .or_else(|| std::env::var("HETSIM_BACKEND").ok())
            .unwrap_or_else(|| "any".into());
        let wanted = options
            .adapter
            .clone()
            .or_else(|| std::env::var("HETSIM_ADAPTER").ok());
        let backends = match backend.to_lowercase().as_str() {
            "vulkan" => wgpu::Backends::VULKAN,
            "gl" | "gles" => wgpu::Backends::GL,
            "any" | "" => wgpu::Backends::VULKAN | wgpu::Backends::GL,
            other => return Err(RenderError::BadBackend(other.to_string())),
        };
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let describe = |a: &wgpu::Adapter| {
            let i = a.get_info();
            format!("{} ({:?})", i.name, i.backend)
        };
        let found = if adapters.is_empty() {
            "none".to_string()
        } else {
            adapters.iter().map(describe).collect::<Vec<_>>().join(", ")
        };
        // Prefer Vulkan over GL, then the order the system lists them in.
        let mut candidates: Vec<wgpu::Adapter> = adapters
            .into_iter()
            .filter(|a| {
                wanted
                    .as_ref()
                    .is_none_or(|w| a.get_info().name.to_lowercase().contains(&w.to_lowercase()))
            })
            .collect();
        candidates.sort_by_key(|a| u8::from(a.get_info().backend != wgpu::Backend::Vulkan));
        let adapter = candidates
            .into_iter()
            .next()
            .ok_or_else(|| RenderError::NoAdapter {
                backend: backend.clone(),
                wanted: wanted
                    .as_ref()
                    .map_or(String::new(), |w| format!(" with a name containing {w:?}")),
                found,
            })?;
        let info = adapter.get_info();
        let summary = AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("hetsim"),
            required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
            ..wgpu::DeviceDescriptor::default()
        }))
        .map_err(|e| RenderError::Device {
            adapter: info.name.clone(),
            reason: e.to_string(),
        })?;

        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("scene.wgsl"),
            source: wgpu::ShaderSource::Wgsl(crate::SCENE_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("camera"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Uint32x2];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("scene"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<Vertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: None,
                ..wgpu::PrimitiveState::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(COLOR_FORMAT.into()), Some(LINEAR_DEPTH_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let mesh = world_mesh(world);
        let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("world vertices"),
            contents: bytemuck::cast_slice(&mesh.vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("world indices"),
            contents: bytemuck::cast_slice(&mesh.indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        Ok(Self {
            device,
            queue,
            pipeline,
            layout,
            world: (vb, ib, mesh.indices.len() as u32),
            robots: None,
            targets: Vec::new(),
            outdoor: world.terrain.is_some(),
            adapter: summary,
        })
    }

    /// The adapter in use.
    pub fn adapter(&self) -> &AdapterSummary {
        &self.adapter
    }

    /// Robots to draw in the next frames (a view can hide one of them: its own robot).
    pub fn set_robots(&mut self, robots: &[RobotDraw]) {
        let (mesh, ranges) = robots_mesh(robots);
        if mesh.indices.is_empty() {
            self.robots = None;
            return;
        }
        let vb = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("robot vertices"),
                contents: bytemuck::cast_slice(&mesh.vertices),
                usage: wgpu::BufferUsages::VERTEX,
            });
        let ib = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("robot indices"),
                contents: bytemuck::cast_slice(&mesh.indices),
                usage: wgpu::BufferUsages::INDEX,
            });
        self.robots = Some((vb, ib, ranges));
    }

    fn target(&mut self, slot: usize, size: (u32, u32)) {
        if self.targets.get(slot).is_some_and(|t| t.size == size) {
            return;
        }
        let texture = |label: &str, format: wgpu::TextureFormat, usage: wgpu::TextureUsages| {
            self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
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
        };
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let color = texture("color", COLOR_FORMAT, attach);
        let linear_depth = texture("linear depth", LINEAR_DEPTH_FORMAT, attach);
        let depth = texture(
            "depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )
        .create_view(&wgpu::TextureViewDescriptor::default());
        let buffer = |label: &str| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: (padded_row(size.0, 4) * size.1) as u64,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let uniform = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("camera"),
            size: std::mem::size_of::<CameraUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("camera"),
            layout: &self.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            }],
        });
        let t = Target {
            size,
            color,
            linear_depth,
            depth,
            color_buf: buffer("color readback"),
            depth_buf: buffer("depth readback"),
            uniform,
            bind_group,
        };
        if slot < self.targets.len() {
            self.targets[slot] = t;
        } else {
            self.targets.push(t);
        }
    }

    /// Renders every view in one submission and reads the images back.
    pub fn render(&mut self, views: &[CameraView]) -> Vec<Frame> {
        for (slot, v) in views.iter().enumerate() {
            self.target(slot, (v.intrinsics.width, v.intrinsics.height));
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("cameras"),
            });
        for (slot, v) in views.iter().enumerate() {
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
            let t = &self.targets[slot];
            self.queue
                .write_buffer(&t.uniform, 0, bytemuck::bytes_of(&uniform));
            let color_view = t.color.create_view(&wgpu::TextureViewDescriptor::default());
            let depth_view = t
                .linear_depth
                .create_view(&wgpu::TextureViewDescriptor::default());
            let sky = if self.outdoor {
                wgpu::Color {
                    r: 0.55,
                    g: 0.70,
                    b: 0.90,
                    a: 1.0,
                }
            } else {
                wgpu::Color {
                    r: 0.2,
                    g: 0.2,
                    b: 0.2,
                    a: 1.0,
                }
            };
            {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("scene"),
                    color_attachments: &[
                        Some(wgpu::RenderPassColorAttachment {
                            view: &color_view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Clear(sky),
                                store: wgpu::StoreOp::Store,
                            },
                        }),
                        Some(wgpu::RenderPassColorAttachment {
                            view: &depth_view,
                            depth_slice: None,
                            resolve_target: None,
                            ops: wgpu::Operations {
                                load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                                store: wgpu::StoreOp::Store,
                            },
                        }),
                    ],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &t.depth,
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
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &t.bind_group, &[]);
                let (vb, ib, count) = &self.world;
                pass.set_vertex_buffer(0, vb.slice(..));
                pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*count, 0, 0..1);
                if let Some((vb, ib, ranges)) = &self.robots {
                    pass.set_vertex_buffer(0, vb.slice(..));
                    pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
                    for (robot, range) in ranges.iter().enumerate() {
                        if v.hide_robot != Some(robot) {
                            pass.draw_indexed(range.clone(), 0, 0..1);
                        }
                    }
                }
            }
            let (w, h) = t.size;
            for (texture, buffer) in [(&t.color, &t.color_buf), (&t.linear_depth, &t.depth_buf)] {
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
        #[allow(clippy::disallowed_methods)]
        let t0 = std::time::Instant::now();
        self.queue.submit([encoder.finish()]);
        for t in &self.targets[..views.len()] {
            t.color_buf.map_async(wgpu::MapMode::Read, .., |r| {
                r.expect("mapping a readback buffer")
            });
            t.depth_buf.map_async(wgpu::MapMode::Read, .., |r| {
                r.expect("mapping a readback buffer")
            });
        }
        let t1 = t0.elapsed();
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: None,
                timeout: None,
            })
            .expect("the device finishes its work");
        let t2 = t0.elapsed();
        let mut frames = Vec::with_capacity(views.len());
        for t in &self.targets[..views.len()] {
            let (w, h) = t.size;
            let row = padded_row(w, 4) as usize;
            let mut rgb = Vec::with_capacity((w * h * 3) as usize);
            let mut depth_m = Vec::with_capacity((w * h) as usize);
            {
                let color = t.color_buf.get_mapped_range(..).expect("mapped");
                let depth = t.depth_buf.get_mapped_range(..).expect("mapped");
                for y in 0..h as usize {
                    let c = &color[y * row..y * row + 4 * w as usize];
                    for px in c.chunks_exact(4) {
                        rgb.extend_from_slice(&px[..3]);
                    }
                    let d = &depth[y * row..y * row + 4 * w as usize];
                    depth_m.extend(d.chunks_exact(4).map(|b| {
                        u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32 * DEPTH_UNIT_M
                    }));
                }
            }
            t.color_buf.unmap();
            t.depth_buf.unmap();
            frames.push(Frame {
                width: w,
                height: h,
                rgb,
                depth_m,
            });
        }
        if std::env::var("HETSIM_RENDER_PROFILE").is_ok() {
            eprintln!(
                "PROFILE submit {:?} wait {:?} readback {:?}",
                t1,
                t2 - t1,
                t0.elapsed() - t2
            );
        }
        frames
    }
}
