//! Headless offscreen rendering with wgpu: colour and ground-truth depth for pinhole cameras.
//!
//! * Backends: Vulkan (real GPUs, Mesa's lavapipe) and GL/GLES through EGL (Mesa's
//!   llvmpipe); `HETSIM_BACKEND` (`vulkan`, `gl`, `any`) and `HETSIM_ADAPTER` (a substring of
//!   the adapter's name) choose. No window or display server is needed.
//! * Materials are baked once per world on the CPU into mip-mapped textures (`bake`), sampled
//!   with trilinear (and, where the adapter offers it, anisotropic) filtering by one shader,
//!   `shaders/scene.wgsl`, into an 8-bit target holding `linear^(1/2.2)` (the gamma is
//!   applied per vertex to the light, see the shader); linear depth (distance along the
//!   optical axis, metres) goes to a second target only for views that ask for it.
//! * Back faces are culled, terrain chunks outside a view are not drawn, and what is drawn
//!   goes nearest first, so that hidden surfaces are rejected before they are shaded.
//! * Cameras are exact pinholes: pixel `(u, v)` (OpenCV convention, centre of the top-left
//!   pixel at (0, 0)) of a point `(x, y, z)` in the optical frame (x right, y down, z
//!   forward) is `(αu x/z + u0, αv y/z + v0)`; the projection matrix reproduces this to
//!   floating-point precision.
//! * Several cameras are rendered as one batch: one command buffer, one submission, one wait.

mod bake;
mod camera;
mod draw;
mod gpu;
mod mesh;

pub use camera::CameraView;
pub use gpu::{AdapterSummary, Frame, RenderError, RenderOptions, Renderer};
pub use mesh::{RobotDraw, RobotPart};

/// The scene shader's source, compiled into the binary from `shaders/scene.wgsl`.
pub const SCENE_WGSL: &str = include_str!("../../../shaders/scene.wgsl");
