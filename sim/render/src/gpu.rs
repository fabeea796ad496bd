//! The wgpu device, the baked materials, the scene pipelines and the static geometry.

use crate::bake;
use crate::mesh::{world_mesh, Chunk, Vertex};
use hetsim_scene::world::World;
use wgpu::util::DeviceExt;

/// How to pick the adapter.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderOptions {
    /// `vulkan`, `gl` or `any` (default: the `HETSIM_BACKEND` variable, else `any`).
    pub backend: Option<String>,
    /// A substring of the adapter name (default: the `HETSIM_ADAPTER` variable, else any).
    pub adapter: Option<String>,
    /// Anisotropic filtering, 1-16 samples (default: the `HETSIM_ANISOTROPY` variable, else
    /// 16 on GPUs and 1 on CPU rasterizers).
    pub anisotropy: Option<u16>,
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
    /// A mesh is larger than one buffer of the device may be.
    #[error("the world's {what} mesh needs a {bytes}-byte buffer and a device on {adapter} allows {max} (wgpu's portable limit): make it about {:.1} times coarser (a village's terrain_cell_m), or run with --no-render", (*.bytes as f64 / *.max as f64).sqrt())]
    TooLarge {
        /// `terrain` or `objects`.
        what: String,
        /// Bytes the buffer would need.
        bytes: u64,
        /// The device's largest buffer.
        max: u64,
        /// Adapter name.
        adapter: String,
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
    /// RGBA, 8 bits per channel (colour encoded as `linear^(1/2.2)`, alpha 255), row-major from the
    /// top-left, tightly packed: the bytes the GPU wrote.
    pub rgba: Vec<u8>,
    /// Depth along the optical axis, metres, per pixel, 0 where nothing was hit; only for
    /// views that asked for it ([`crate::CameraView::depth`]).
    pub depth_m: Option<Vec<f32>>,
}

impl Frame {
    /// The image as RGB, 8 bits per channel.
    pub fn rgb(&self) -> Vec<u8> {
        let mut rgb = vec![0u8; self.rgba.len() / 4 * 3];
        for (out, px) in rgb.chunks_exact_mut(3).zip(self.rgba.chunks_exact(4)) {
            out.copy_from_slice(&px[..3]);
        }
        rgb
    }

    /// The depth image; panics if the view did not ask for depth.
    pub fn depth(&self) -> &[f32] {
        self.depth_m
            .as_deref()
            .expect("this view was rendered without depth: set CameraView::depth")
    }
}

/// What the scene shader reads per view.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct CameraUniform {
    pub view_proj: [[f32; 4]; 4],
    pub eye: [f32; 4],
    pub forward: [f32; 4],
}

/// A vertex and an index buffer, and how many indices they hold.
pub(crate) struct Geometry {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub count: u32,
}

/// The scene pipelines: terrain or objects, colour only or colour and linear depth.
pub(crate) struct Pipelines {
    pub terrain: wgpu::RenderPipeline,
    pub object: wgpu::RenderPipeline,
    pub terrain_depth: wgpu::RenderPipeline,
    pub object_depth: wgpu::RenderPipeline,
}

/// A view's render targets, readback buffers, uniform and bind group, kept between frames.
pub(crate) struct Target {
    pub size: (u32, u32),
    pub color: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
    pub color_buf: wgpu::Buffer,
    /// Linear depth and its readback, made the first time a view of this slot asks for depth.
    pub linear_depth: Option<(wgpu::Texture, wgpu::TextureView, wgpu::Buffer)>,
    pub uniform: wgpu::Buffer,
    pub bind_group: wgpu::BindGroup,
}

/// A headless renderer of one world.
pub struct Renderer {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    pub(crate) pipelines: Pipelines,
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) sampler: wgpu::Sampler,
    pub(crate) textures: [wgpu::TextureView; 3],
    pub(crate) objects: Option<Geometry>,
    pub(crate) terrain: Option<(Geometry, Vec<Chunk>)>,
    /// Robot geometry (grown as needed) and each robot's index range.
    pub(crate) robots: Option<(Geometry, Vec<std::ops::Range<u32>>)>,
    pub(crate) targets: Vec<Target>,
    pub(crate) outdoor: bool,
    adapter: AdapterSummary,
}

/// Gamma-encoded colour (see `scene.wgsl`).
pub(crate) const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Linear depth in 0.1 mm units (see `scene.wgsl`).
pub(crate) const LINEAR_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// The sampler's anisotropy clamp: the option (or `HETSIM_ANISOTROPY`) if given, else 16 on
/// hardware and 1 on CPU rasterizers, where Mesa 22's llvmpipe filters anisotropically so
/// slowly that the render bench's first scenario did not finish in 14 minutes (10 s without).
/// wgpu clamps it to 1 where the adapter has no anisotropic filtering.
fn anisotropy(info: &wgpu::AdapterInfo, options: &RenderOptions) -> u16 {
    options
        .anisotropy
        .or_else(|| std::env::var("HETSIM_ANISOTROPY").ok()?.parse().ok())
        .unwrap_or(if info.device_type == wgpu::DeviceType::Cpu {
            1
        } else {
            16
        })
        .clamp(1, 16)
}

/// wgpu's defaults without the validation of indirect draws and dispatches: the renderer
/// issues none, and that validation builds compute pipelines when the device is made, which
/// NVIDIA's OpenGL driver refuses ("Parent device is lost": on an H200, driver 580, every
/// GL device failed with it and the bare-wgpu reference, which clears all flags, did not).
/// `WGPU_VALIDATION_INDIRECT_CALL=1` and wgpu's other variables still apply.
fn instance_flags() -> wgpu::InstanceFlags {
    (wgpu::InstanceFlags::from_build_config() - wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL)
        .with_env()
}

fn pick_adapter(options: &RenderOptions) -> Result<wgpu::Adapter, RenderError> {
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
        flags: instance_flags(),
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
    candidates
        .into_iter()
        .next()
        .ok_or_else(|| RenderError::NoAdapter {
            backend: backend.clone(),
            wanted: wanted
                .as_ref()
                .map_or(String::new(), |w| format!(" with a name containing {w:?}")),
            found,
        })
}

impl Renderer {
    /// A renderer for `world` on the adapter the options (or environment) choose. Bakes the
    /// world's materials (`hetsim bench --render` reports how long this takes).
    pub fn new(world: &World, options: &RenderOptions) -> Result<Self, RenderError> {
        let adapter = pick_adapter(options)?;
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
        let layout = bind_group_layout(&device);
        let pipelines = pipelines(&device, &layout);
        let mesh = world_mesh(world);
        // A buffer over the device's limit is a validation error (a panic) in wgpu: say
        // which mesh and what to change instead.
        let max = device.limits().max_buffer_size;
        for (what, m) in [("terrain", &mesh.terrain), ("objects", &mesh.objects)] {
            let bytes = std::mem::size_of_val(m.vertices.as_slice())
                .max(std::mem::size_of_val(m.indices.as_slice())) as u64;
            if bytes > max {
                return Err(RenderError::TooLarge {
                    what: what.to_string(),
                    bytes,
                    max,
                    adapter: info.name.clone(),
                });
            }
        }
        let textures = upload_materials(&device, &queue, mesh.terrain_area);
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("materials"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            anisotropy_clamp: anisotropy(&info, options),
            ..wgpu::SamplerDescriptor::default()
        });

        let geometry = |label: &str, m: &crate::mesh::Mesh| {
            (!m.indices.is_empty()).then(|| Geometry {
                vertices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(&m.vertices),
                    usage: wgpu::BufferUsages::VERTEX,
                }),
                indices: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(&m.indices),
                    usage: wgpu::BufferUsages::INDEX,
                }),
                count: m.indices.len() as u32,
            })
        };
        let objects = geometry("objects", &mesh.objects);
        let terrain = geometry("terrain", &mesh.terrain).map(|g| (g, mesh.chunks));
        Ok(Self {
            device,
            queue,
            pipelines,
            layout,
            sampler,
            textures,
            objects,
            terrain,
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
}

fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let texture =
        |binding: u32, view_dimension: wgpu::TextureViewDimension| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: true },
                view_dimension,
                multisampled: false,
            },
            count: None,
        };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("camera and materials"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
            texture(2, wgpu::TextureViewDimension::D2),
            texture(3, wgpu::TextureViewDimension::D2),
            texture(4, wgpu::TextureViewDimension::D2Array),
        ],
    })
}

fn pipelines(device: &wgpu::Device, layout: &wgpu::BindGroupLayout) -> Pipelines {
    let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("scene.wgsl"),
        source: wgpu::ShaderSource::Wgsl(crate::SCENE_WGSL.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("scene"),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    let attributes = wgpu::vertex_attr_array![
        0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Uint32, 4 => Unorm8x4
    ];
    let make = |entry: &str, depth: bool| {
        let color = Some(COLOR_FORMAT.into());
        let with_depth = [color.clone(), Some(LINEAR_DEPTH_FORMAT.into())];
        let color_only = [color];
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(entry),
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
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: Some(wgpu::Face::Back),
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
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: if depth { &with_depth } else { &color_only },
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    Pipelines {
        terrain: make("fs_terrain", false),
        object: make("fs_object", false),
        terrain_depth: make("fs_terrain_depth", true),
        object_depth: make("fs_object_depth", true),
    }
}

/// Bakes and uploads the terrain (a 1-texel stand-in indoors), detail and material textures
/// with their mip chains; returns their views in binding order.
fn upload_materials(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    terrain_area: Option<([f64; 2], f64)>,
) -> [wgpu::TextureView; 3] {
    let upload = |label: &str, layers: Vec<bake::Texels>, dimension: wgpu::TextureViewDimension| {
        let side = layers[0].side;
        let count = layers.len() as u32;
        // Plain 8-bit unorm, whatever the encoding: llvmpipe filters these with its fast
        // 8-bit path, sRGB formats with a float path.
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let levels: Vec<Vec<Vec<u8>>> = layers.into_iter().map(bake::mips).collect();
        let mip_level_count = levels[0].len() as u32;
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: count,
            },
            mip_level_count,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        for (z, chain) in levels.iter().enumerate() {
            for (level, bytes) in chain.iter().enumerate() {
                let s = (side >> level).max(1);
                queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &texture,
                        mip_level: level as u32,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: z as u32,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    bytes,
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(4 * s),
                        rows_per_image: Some(s),
                    },
                    wgpu::Extent3d {
                        width: s,
                        height: s,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
        texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(dimension),
            ..wgpu::TextureViewDescriptor::default()
        })
    };
    let d2 = wgpu::TextureViewDimension::D2;
    let terrain = match terrain_area {
        Some((origin, extent)) => bake::terrain(origin, extent),
        None => bake::Texels {
            side: 1,
            rgba: vec![255; 4],
            encoded: true,
        },
    };
    let layers = bake::layers();
    debug_assert_eq!(layers.len() as u32, bake::layer::COUNT);
    [
        upload("terrain", vec![terrain], d2),
        upload("detail", vec![bake::detail()], d2),
        upload("materials", layers, wgpu::TextureViewDimension::D2Array),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CI has no NVIDIA GL driver to catch it, so this guards the flag directly: with wgpu's
    /// default flags every GL device on an NVIDIA H200 failed ("Parent device is lost").
    #[test]
    fn indirect_call_validation_stays_off_unless_asked_for() {
        if std::env::var_os("WGPU_VALIDATION_INDIRECT_CALL").is_none() {
            assert!(!instance_flags().contains(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL));
        }
    }
}
