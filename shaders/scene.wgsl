// The scene pass: geometry with baked, mip-mapped materials (see sim/render/src/bake.rs),
// lit per vertex, optionally with linear depth in a second target.
//
// Gamma: texels hold linear^(1/2.2) and so do the output pixels. The power law commutes with
// the lighting (a product), so the vertex shader encodes the light once per vertex and the
// fragment shader only multiplies: no per-pixel pow and no sRGB conversion.
//
// Materials:
//   terrain - one texture over the whole heightfield (u, v in [0, 1]) times a tileable grey
//             detail multiplier (centimetre grain)
//   objects - a layer of the material array (facades, roofs, walls, obstacles, floor, plain)
//             times the vertex tint
// Lighting (Lambertian, exact per vertex on flat faces): sun + sky ambient outdoors;
// ceiling light (from above) + ambient indoors.

struct Camera {
    view_proj: mat4x4<f32>,
    // xyz: optical centre in world; w: 1 outdoors, 0 indoors
    eye: vec4<f32>,
    // xyz: optical axis (camera z) in world
    forward: vec4<f32>,
};

@group(0) @binding(0) var<uniform> camera: Camera;
@group(0) @binding(1) var materials_sampler: sampler;
@group(0) @binding(2) var terrain_texture: texture_2d<f32>;
@group(0) @binding(3) var detail_texture: texture_2d<f32>;
@group(0) @binding(4) var material_layers: texture_2d_array<f32>;

// Metres per detail tile (bake::DETAIL_TILE_M).
const DETAIL_TILE_M: f32 = 4.8;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) layer: u32,
    @location(4) tint: vec4<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) shade: vec3<f32>,
    @location(1) uv: vec2<f32>,
    // Terrain: the detail texture's coordinates; objects: unused.
    @location(2) detail: vec2<f32>,
    @location(3) @interpolate(flat) layer: u32,
    // Distance along the optical axis, metres.
    @location(4) depth: f32,
};

// Branch-free on purpose: lavapipe specializes shaders on uniforms used in control flow and
// recompiled them on every frame when this was an `if`.
fn light(n: vec3<f32>) -> f32 {
    let sun = normalize(vec3<f32>(0.45, 0.30, 0.84));
    let outdoor = 0.38 + 0.72 * max(dot(n, sun), 0.0);
    let up = max(n.z, 0.0);
    let side = 0.5 + 0.5 * abs(dot(n, normalize(vec3<f32>(0.6, 0.8, 0.0))));
    let indoor = 0.45 + 0.35 * up + 0.25 * side;
    return mix(indoor, outdoor, camera.eye.w);
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = camera.view_proj * vec4<f32>(v.position, 1.0);
    out.shade = pow(v.tint.rgb * light(normalize(v.normal)), vec3<f32>(1.0 / 2.2));
    out.uv = v.uv;
    out.detail = v.position.xy / DETAIL_TILE_M;
    out.layer = v.layer;
    out.depth = dot(v.position - camera.eye.xyz, camera.forward.xyz);
    return out;
}

fn terrain_color(in: VertexOut) -> vec4<f32> {
    let albedo = textureSample(terrain_texture, materials_sampler, in.uv).rgb;
    // The detail texture holds half the (encoded) multiplier.
    let detail = 2.0 * textureSample(detail_texture, materials_sampler, in.detail).r;
    return vec4<f32>(albedo * detail * in.shade, 1.0);
}

fn object_color(in: VertexOut) -> vec4<f32> {
    let albedo = textureSample(material_layers, materials_sampler, in.uv, in.layer).rgb;
    return vec4<f32>(albedo * in.shade, 1.0);
}

// Depth in units of 0.1 mm (integer targets are colour-renderable on every backend, 32-bit
// float ones are not on GLES); 0 means "nothing here".
fn depth_units(depth_m: f32) -> u32 {
    return u32(clamp(depth_m * 10000.0 + 0.5, 1.0, 4294967040.0));
}

struct WithDepth {
    @location(0) color: vec4<f32>,
    @location(1) depth: u32,
};

@fragment
fn fs_terrain(in: VertexOut) -> @location(0) vec4<f32> {
    return terrain_color(in);
}

@fragment
fn fs_object(in: VertexOut) -> @location(0) vec4<f32> {
    return object_color(in);
}

@fragment
fn fs_terrain_depth(in: VertexOut) -> WithDepth {
    return WithDepth(terrain_color(in), depth_units(in.depth));
}

@fragment
fn fs_object_depth(in: VertexOut) -> WithDepth {
    return WithDepth(object_color(in), depth_units(in.depth));
}
