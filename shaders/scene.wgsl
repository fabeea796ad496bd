// The one scene pass: lit, procedurally textured geometry, writing colour and linear depth.
//
// Textures are computed from world position (or face coordinates) and a per-object seed, so
// nothing repeats at the helicopter's altitude and no texture files are needed:
//   kind 0 terrain   - multi-octave value noise (grass, soil, paths), aperiodic
//   kind 1 building  - facades: irregular window grid, doors at ground level, roof noise
//   kind 2 wall      - indoor walls: seed-dependent stripes, posters and colour
//   kind 3 obstacle  - indoor obstacles: seed-dependent blocks, stripes and labels
//   kind 4 floor     - floor tiles with noise
//   kind 5 robot     - robot bodies (seed picks the colour)
//   kind 6 hat       - the c't-Bots' orange hats
// Lighting: sun + sky ambient outdoors; ceiling light (from above) + ambient indoors.

struct Camera {
    view_proj: mat4x4<f32>,
    // xyz: optical centre in world; w: 1 outdoors, 0 indoors
    eye: vec4<f32>,
    // xyz: optical axis (camera z) in world
    forward: vec4<f32>,
};

@group(0) @binding(0) var<uniform> camera: Camera;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) material: vec2<u32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) material: vec2<u32>,
};

struct FragmentOut {
    @location(0) color: vec4<f32>,
    // Depth along the optical axis in units of 0.1 mm (integer targets are colour-renderable
    // on every backend, 32-bit float ones are not on GLES); 0 means "nothing here".
    @location(1) depth: u32,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = camera.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.uv = v.uv;
    out.material = v.material;
    return out;
}

fn hash2(p: vec2<f32>, seed: u32) -> f32 {
    // Integer hash of a lattice point and a seed (PCG-style), in [0, 1).
    var h: u32 = u32(i32(floor(p.x)) + 32768) * 1664525u ^ u32(i32(floor(p.y)) + 32768) * 22695477u ^ seed * 2654435761u;
    h = h ^ (h >> 16u);
    h = h * 2246822519u;
    h = h ^ (h >> 13u);
    h = h * 3266489917u;
    h = h ^ (h >> 16u);
    return f32(h & 16777215u) / 16777216.0;
}

fn value_noise(p: vec2<f32>, seed: u32) -> f32 {
    let i = floor(p);
    let f = fract(p);
    let u = f * f * (3.0 - 2.0 * f);
    let a = hash2(i, seed);
    let b = hash2(i + vec2<f32>(1.0, 0.0), seed);
    let c = hash2(i + vec2<f32>(0.0, 1.0), seed);
    let d = hash2(i + vec2<f32>(1.0, 1.0), seed);
    return mix(mix(a, b, u.x), mix(c, d, u.x), u.y);
}

fn fbm(p: vec2<f32>, seed: u32) -> f32 {
    var sum = 0.0;
    var amp = 0.5;
    var q = p;
    for (var k = 0u; k < 5u; k = k + 1u) {
        sum = sum + amp * value_noise(q, seed + k * 101u);
        q = q * 2.03;
        amp = amp * 0.5;
    }
    return sum;
}

fn terrain_color(w: vec3<f32>) -> vec3<f32> {
    let broad = fbm(w.xy / 40.0, 11u);
    let grass = mix(vec3<f32>(0.26, 0.40, 0.16), vec3<f32>(0.47, 0.54, 0.26), broad);
    let soil = vec3<f32>(0.52, 0.41, 0.28);
    let patchy = smoothstep(0.45, 0.62, fbm(w.xy / 12.0, 37u));
    var color = mix(grass, soil, patchy);
    // Texture that survives 40 m of altitude: tufts and stones at 0.3-3 m scales, and dark
    // bushes; value noise is aperiodic, so nothing repeats.
    let fine = fbm(w.xy / 0.6, 23u);
    color = color * (0.55 + 0.9 * fine);
    let bush = smoothstep(0.68, 0.74, value_noise(w.xy / 2.5, 53u));
    color = mix(color, vec3<f32>(0.10, 0.18, 0.07), bush * 0.85);
    let stone = smoothstep(0.80, 0.84, value_noise(w.xy / 0.9, 61u));
    color = mix(color, vec3<f32>(0.78, 0.76, 0.72), stone);
    return color;
}

fn facade_color(uv: vec2<f32>, n: vec3<f32>, seed: u32) -> vec3<f32> {
    let base = vec3<f32>(0.70, 0.66, 0.60) * (0.85 + 0.3 * hash2(vec2<f32>(f32(seed & 255u), 7.0), seed));
    if (abs(n.z) > 0.5) {
        // Roof: weathered tiles.
        let roof = vec3<f32>(0.45, 0.25, 0.20) * (0.7 + 0.5 * fbm(uv * 0.8, seed));
        return roof;
    }
    let stain = 0.85 + 0.25 * fbm(uv * vec2<f32>(0.7, 0.3), seed + 5u);
    // Floors of 3 m, bays of 2.5-4 m depending on the building.
    let bay = 2.5 + 1.5 * hash2(vec2<f32>(3.0, 1.0), seed);
    let cell = vec2<f32>(floor(uv.x / bay), floor(uv.y / 3.0));
    let local = vec2<f32>(fract(uv.x / bay), fract(uv.y / 3.0));
    let r = hash2(cell, seed);
    var color = base * stain;
    if (cell.y < 0.5 && r > 0.8) {
        // A door: dark wood, full height of the ground floor bay centre.
        if (local.x > 0.3 && local.x < 0.7 && local.y < 0.75) {
            color = vec3<f32>(0.30, 0.18, 0.10);
        }
    } else if (r > 0.25) {
        // A window, slightly jittered per bay: frame, then glass.
        let jx = 0.08 * (hash2(cell + vec2<f32>(9.0, 0.0), seed) - 0.5);
        let inside = local.x > 0.25 + jx && local.x < 0.75 + jx && local.y > 0.3 && local.y < 0.8;
        let frame = local.x > 0.22 + jx && local.x < 0.78 + jx && local.y > 0.27 && local.y < 0.83;
        if (inside) {
            color = vec3<f32>(0.15, 0.20, 0.28) + 0.15 * hash2(cell * 3.0, seed + 1u);
        } else if (frame) {
            color = vec3<f32>(0.92, 0.92, 0.90);
        }
    }
    // A darker plinth and a cornice line: horizontal segments for the line detector.
    if (uv.y < 0.4) {
        color = color * 0.6;
    }
    return color;
}

fn indoor_color(uv: vec2<f32>, n: vec3<f32>, seed: u32, kind: u32) -> vec3<f32> {
    let hue = vec3<f32>(hash2(vec2<f32>(1.0, 2.0), seed), hash2(vec2<f32>(3.0, 4.0), seed), hash2(vec2<f32>(5.0, 6.0), seed));
    let base = 0.35 + 0.55 * hue;
    let freq = 1.0 + 4.0 * hash2(vec2<f32>(7.0, 8.0), seed);
    let angle = 3.14159 * hash2(vec2<f32>(9.0, 10.0), seed);
    let dir = vec2<f32>(cos(angle), sin(angle));
    let stripes = step(0.5, fract(dot(uv, dir) * freq));
    var color = mix(base, base * 0.45, stripes * 0.8);
    // Posters / labels: a few seeded rectangles per metre of wall.
    let cell = floor(uv / 0.8);
    let local = fract(uv / 0.8);
    let r = hash2(cell, seed + 17u);
    if (r > 0.6 && local.x > 0.2 && local.x < 0.8 && local.y > 0.25 && local.y < 0.75) {
        color = vec3<f32>(hash2(cell, seed + 1u), hash2(cell, seed + 2u), hash2(cell, seed + 3u));
    }
    if (kind == 2u && abs(n.z) < 0.5 && uv.y < 0.1) {
        color = vec3<f32>(0.15, 0.15, 0.15); // skirting board
    }
    return color * (0.85 + 0.3 * value_noise(uv * 6.0, seed));
}

fn floor_color(w: vec3<f32>) -> vec3<f32> {
    let tile = floor(w.xy / 0.5);
    let checker = (i32(tile.x) + i32(tile.y)) & 1;
    let base = select(vec3<f32>(0.62, 0.60, 0.56), vec3<f32>(0.52, 0.50, 0.47), checker == 1);
    return base * (0.85 + 0.3 * fbm(w.xy * 2.0, 71u));
}

@fragment
fn fs_main(in: VertexOut) -> FragmentOut {
    let kind = in.material.x;
    let seed = in.material.y;
    let n = normalize(in.normal);
    var albedo: vec3<f32>;
    switch kind {
        case 0u: { albedo = terrain_color(in.world); }
        case 1u: { albedo = facade_color(in.uv, n, seed); }
        case 2u, 3u: { albedo = indoor_color(in.uv, n, seed, kind); }
        case 4u: { albedo = floor_color(in.world); }
        case 5u: { albedo = select(vec3<f32>(0.25, 0.30, 0.40), vec3<f32>(0.55, 0.55, 0.58), (seed & 1u) == 1u); }
        default: { albedo = vec3<f32>(1.0, 0.45, 0.05); }
    }
    var light: f32;
    if (camera.eye.w > 0.5) {
        let sun = normalize(vec3<f32>(0.45, 0.30, 0.84));
        light = 0.38 + 0.72 * max(dot(n, sun), 0.0);
    } else {
        let up = max(n.z, 0.0);
        let side = 0.5 + 0.5 * abs(dot(n, normalize(vec3<f32>(0.6, 0.8, 0.0))));
        light = 0.45 + 0.35 * up + 0.25 * side;
    }
    var out: FragmentOut;
    let linear = albedo * light;
    out.color = vec4<f32>(pow(clamp(linear, vec3<f32>(0.0), vec3<f32>(1.0)), vec3<f32>(1.0 / 2.2)), 1.0);
    out.depth = u32(clamp(dot(in.world - camera.eye.xyz, camera.forward.xyz) * 10000.0 + 0.5, 1.0, 4294967040.0));
    return out;
}
