//! Materials baked once per world, on the CPU, into textures with full mip chains.
//!
//! Every texel is a pure function of its coordinates and a seed, and the mip levels are box
//! filtered in linear light on the CPU, so the bytes uploaded are the same on every run and
//! every adapter. The shader only samples (trilinear, anisotropic where offered) and lights.
//!
//! What is baked, and at what scale:
//! * **terrain**: one aperiodic texture over the whole heightfield, [`TERRAIN_TEXELS`] on a
//!   side (20 cm a texel in the village): grass and soil patches, bushes, stones and tufts
//!   from 0.3 m to 100 m, what the helicopter sees from 40 m without anything repeating;
//! * **detail**: a tileable grey multiplier of value-noise octaves from 15 cm down to 1 cm,
//!   [`DETAIL_TILE_M`] per tile: texture at centimetre scale for the rover's near field;
//! * **material layers**: one texture array of [`LAYER_TEXELS`]-square layers: a plain white
//!   layer (robots, tinted per vertex), façade and roof variants, indoor wall and obstacle
//!   variants, the floor. An object picks its variant, offset and tint from its seed.

use rayon::prelude::*;

/// Side of the terrain texture, texels.
pub(crate) const TERRAIN_TEXELS: u32 = 4096;
/// Side of one material layer and of the detail tile, texels.
pub(crate) const LAYER_TEXELS: u32 = 512;
/// Size of the terrain detail tile, metres.
pub(crate) const DETAIL_TILE_M: f32 = 4.8;
/// Size of a façade (and roof) layer, metres, both ways.
pub(crate) const FACADE_TILE_M: f64 = 16.0;
/// Size of an indoor wall, obstacle or floor layer, metres, both ways.
pub(crate) const INDOOR_TILE_M: f64 = 4.0;

/// Layer indices in the material array.
pub(crate) mod layer {
    pub const PLAIN: u32 = 0;
    pub const FACADE: u32 = 1;
    pub const FACADES: u32 = 8;
    pub const ROOF: u32 = FACADE + FACADES;
    pub const ROOFS: u32 = 2;
    pub const WALL: u32 = ROOF + ROOFS;
    pub const WALLS: u32 = 8;
    pub const OBSTACLE: u32 = WALL + WALLS;
    pub const OBSTACLES: u32 = 8;
    pub const FLOOR: u32 = OBSTACLE + OBSTACLES;
    pub const COUNT: u32 = FLOOR + 1;
}

/// One square texture level 0, RGBA8: gamma-encoded colour (`encoded`) or linear values.
pub(crate) struct Texels {
    pub side: u32,
    pub rgba: Vec<u8>,
    pub encoded: bool,
}

/// 32-bit integer hash of a lattice point and a seed, in [0, 1).
#[inline]
pub(crate) fn hash(ix: i64, iy: i64, seed: u32) -> f32 {
    let mut h = (ix as u32).wrapping_mul(0x9E37_79B1)
        ^ (iy as u32).wrapping_mul(0x85EB_CA77)
        ^ seed.wrapping_mul(0xC2B2_AE3D);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^= h >> 16;
    (h >> 8) as f32 / 16_777_216.0
}

/// `x.floor()`, the same value (the sign of a zero included), without the libm call that
/// x86-64's baseline instruction set (no SSE4.1 `roundss`) makes of it: value noise floors
/// two coordinates per octave, hundreds of millions a bake. Beyond 2^23 every float is whole,
/// and what is not finite goes to libm.
fn floor_of(x: f32) -> f32 {
    if x.is_nan() || x.abs() >= 8_388_608.0 {
        return x.floor();
    }
    let t = x as i32 as f32;
    let r = if t > x { t - 1.0 } else { t };
    r.copysign(x)
}

/// One value-noise lattice that keeps the hashes of the last cell it was read in: a row of
/// texels reads each cell of a coarse lattice many times (the terrain's 40 m octave some 200
/// times at 20 cm a texel), and the four hashes are most of a read's cost. The same
/// arithmetic as a fresh read, so the same bits (a test compares the two).
pub(crate) struct Lattice {
    seed: u32,
    period: i64,
    /// The cell `(ix, iy)` the hashes are of, and the hashes of its corners
    /// `(0,0), (1,0), (0,1), (1,1)`.
    cell: Option<((i64, i64), [f32; 4])>,
}

impl Lattice {
    pub(crate) fn new(seed: u32, period: i64) -> Self {
        Self {
            seed,
            period,
            cell: None,
        }
    }

    /// The noise at `(x, y)`.
    #[inline]
    pub(crate) fn at(&mut self, x: f32, y: f32) -> f32 {
        let (fx, fy) = (floor_of(x), floor_of(y));
        let (tx, ty) = (x - fx, y - fy);
        let (ux, uy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
        let (ix, iy) = (fx as i64, fy as i64);
        let [h00, h10, h01, h11] = match self.cell {
            Some((cell, h)) if cell == (ix, iy) => h,
            _ => {
                let h = self.corners(ix, iy);
                self.cell = Some(((ix, iy), h));
                h
            }
        };
        let top = h00 + (h10 - h00) * ux;
        let bottom = h01 + (h11 - h01) * ux;
        top + (bottom - top) * uy
    }

    /// The hashes of cell `(ix, iy)`'s corners, each lattice coordinate wrapped once.
    #[cold]
    fn corners(&self, ix: i64, iy: i64) -> [f32; 4] {
        let period = self.period;
        let wrap = |i: i64| if period > 0 { i.rem_euclid(period) } else { i };
        let (x0, x1, y0, y1) = (wrap(ix), wrap(ix + 1), wrap(iy), wrap(iy + 1));
        let seed = self.seed;
        [
            hash(x0, y0, seed),
            hash(x1, y0, seed),
            hash(x0, y1, seed),
            hash(x1, y1, seed),
        ]
    }
}

/// Fractal sum of `octaves` value-noise octaves, amplitudes 1/2, 1/4, ...; frequencies double
/// (and so does the period), so a tileable base stays tileable: a [`Lattice`] per octave.
pub(crate) struct Fbm(Vec<Lattice>);

impl Fbm {
    pub(crate) fn new(seed: u32, octaves: u32, period: i64) -> Self {
        Self(
            (0..octaves)
                .map(|k| Lattice::new(seed.wrapping_add(k * 101), period << k))
                .collect(),
        )
    }

    /// The sum at `(x, y)`.
    #[inline]
    pub(crate) fn at(&mut self, x: f32, y: f32) -> f32 {
        let (mut sum, mut amp, mut f) = (0.0, 0.5, 1.0);
        for octave in &mut self.0 {
            sum += amp * octave.at(x * f, y * f);
            amp *= 0.5;
            f *= 2.0;
        }
        sum
    }
}

fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * t)
}

fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    a.map(|c| c * s)
}

/// The display gamma: texels and images are `linear^(1/GAMMA)`, as the old per-pixel `pow`
/// wrote them. A pure power law commutes with the shader's lighting (a product), so the
/// shader applies it per vertex to the light and never per pixel.
pub(crate) const GAMMA: f64 = 2.2;

/// The linear light of every 8-bit encoded value.
fn gamma_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|b| (b as f64 / 255.0).powf(GAMMA) as f32))
}

/// The midpoints between successive encoded values' linear light, `(t[k] + t[k + 1]) / 2` in
/// `f32`, and per bucket of [`BUCKETS`] over [0, 1] how many of them lie below the bucket's
/// lower end: where [`encode`]'s walk starts.
struct Encoder {
    midpoints: [f32; 255],
    start: Vec<u8>,
}

/// Buckets of [`Encoder::start`] over [0, 1]: at most a few midpoints share one, but near 0
/// (the first 6 encoded values lie under 1/4096 in linear light).
const BUCKETS: usize = 4096;

fn encoder() -> &'static Encoder {
    static ENCODER: std::sync::OnceLock<Encoder> = std::sync::OnceLock::new();
    ENCODER.get_or_init(|| {
        let t = gamma_table();
        let midpoints: [f32; 255] = std::array::from_fn(|k| (t[k] + t[k + 1]) / 2.0);
        let start = (0..=BUCKETS)
            .map(|b| {
                let low = b as f32 / BUCKETS as f32;
                midpoints.iter().filter(|&&m| m < low).count() as u8
            })
            .collect();
        Encoder { midpoints, start }
    })
}

/// Linear light to the nearest 8-bit encoded value (nearest in linear light, so that it
/// inverts [`decode`] exactly): the number of midpoints between encoded values below it.
/// Every texel of every bake goes through here, so it starts from the bucket below the
/// value's and walks up, instead of searching all 255 midpoints; the bytes are those of the
/// plain count (a test compares the two).
pub(crate) fn encode(linear: f32) -> u8 {
    let e = encoder();
    let l = linear.clamp(0.0, 1.0);
    // Scaling by a power of two is exact, so the bucket's lower end is at or below `l`.
    let bucket = (l * BUCKETS as f32) as usize;
    let mut k = e.start[bucket] as usize;
    while k < 255 && e.midpoints[k] < l {
        k += 1;
    }
    k as u8
}

/// An 8-bit encoded value to linear light.
pub(crate) fn decode(b: u8) -> f32 {
    gamma_table()[b as usize]
}

/// Fills a `side`² colour texture from `f(u, v)` at texel centres (`u`, `v` in [0, 1)), rows
/// in parallel.
fn paint(side: u32, f: impl Fn(f32, f32) -> [f32; 3] + Sync) -> Texels {
    paint_rows(side, || &f)
}

/// [`paint`] with state along a row: `row()` makes each row's `f` (its noise lattices, which
/// keep the last cell's hashes), called at the row's texels left to right.
fn paint_rows<F: FnMut(f32, f32) -> [f32; 3]>(side: u32, row: impl Fn() -> F + Sync) -> Texels {
    let mut rgba = vec![0u8; (side * side * 4) as usize];
    let fill = |(j, out): (usize, &mut [u8])| {
        let mut f = row();
        let v = (j as f32 + 0.5) / side as f32;
        for (i, px) in out.chunks_exact_mut(4).enumerate() {
            let c = f((i as f32 + 0.5) / side as f32, v);
            px[..3].copy_from_slice(&c.map(encode));
            px[3] = 255;
        }
    };
    rgba.par_chunks_mut(side as usize * 4)
        .enumerate()
        .for_each(fill);
    Texels {
        side,
        rgba,
        encoded: true,
    }
}

/// The terrain texture over `extent_m` metres from `origin` (u along x, v along y).
pub(crate) fn terrain(origin: [f64; 2], extent_m: f64) -> Texels {
    let (x0, y0, e) = (origin[0] as f32, origin[1] as f32, extent_m as f32);
    paint_rows(TERRAIN_TEXELS, || {
        let mut broad = Fbm::new(11, 4, 0);
        let mut patchy = Fbm::new(37, 4, 0);
        let mut bush = Lattice::new(53, 0);
        let mut stone = Lattice::new(61, 0);
        let mut tufts = Fbm::new(23, 2, 0);
        move |u, v| {
            let (x, y) = (x0 + u * e, y0 + v * e);
            let broad = broad.at(x / 40.0, y / 40.0);
            let grass = mix([0.26, 0.40, 0.16], [0.47, 0.54, 0.26], broad);
            let patchy = smoothstep(0.45, 0.62, patchy.at(x / 12.0, y / 12.0));
            let mut c = mix(grass, [0.52, 0.41, 0.28], patchy);
            let bush = smoothstep(0.68, 0.74, bush.at(x / 2.5, y / 2.5));
            c = mix(c, [0.10, 0.18, 0.07], bush * 0.85);
            let stone = smoothstep(0.80, 0.84, stone.at(x / 0.6, y / 0.6));
            c = mix(c, [0.55, 0.53, 0.50], stone);
            // Tufts at 0.6 and 0.3 m, aperiodic: what the helicopter resolves from 40 m.
            let tufts = tufts.at(x / 0.6, y / 0.6) / 0.75;
            scale(c, 0.6 + 0.8 * tufts)
        }
    })
}

/// The tileable detail multiplier, gamma-encoded and halved (the shader doubles it): grain
/// from 15 cm down to 1 cm, light pebbles of 2-5 cm and dark crevices, around 1.
pub(crate) fn detail() -> Texels {
    let side = LAYER_TEXELS;
    let tile = DETAIL_TILE_M;
    // Lattices that divide the tile: 15 cm (32 cells), 5 cm (96), 7.5 cm (64).
    let cells = |m: f32| (tile / m).round() as i64;
    let mut t = paint_rows(side, || {
        let mut grain = Fbm::new(29, 4, cells(0.15));
        let mut pebbles = Lattice::new(31, cells(0.05));
        let mut crevices = Lattice::new(37, cells(0.075));
        move |u, v| {
            let n = grain.at(u * cells(0.15) as f32, v * cells(0.15) as f32) / 0.94;
            let mut m = 0.55 + 0.9 * (0.5 + 2.2 * (n - 0.5)).clamp(0.0, 1.0);
            let (pu, pv) = (u * cells(0.05) as f32, v * cells(0.05) as f32);
            let pebble = smoothstep(0.72, 0.80, pebbles.at(pu, pv));
            m += (1.5 - m) * 0.8 * pebble;
            let (cu, cv) = (u * cells(0.075) as f32, v * cells(0.075) as f32);
            let crevice = smoothstep(0.27, 0.2, crevices.at(cu, cv));
            m *= 1.0 - 0.5 * crevice;
            [0.5 * m.powf(1.0 / GAMMA as f32); 3]
        }
    });
    // Values, not colours: store them as they are, not encoded.
    for px in t.rgba.chunks_exact_mut(4) {
        let l = (decode(px[0]) * 255.0 + 0.5) as u8;
        px[..3].fill(l);
    }
    t.encoded = false;
    t
}

/// The material array's layers, in [`layer`] order.
pub(crate) fn layers() -> Vec<Texels> {
    let mut out = vec![paint(LAYER_TEXELS, |_, _| [1.0; 3])];
    out.extend((0..layer::FACADES).map(facade));
    out.extend((0..layer::ROOFS).map(roof));
    out.extend((0..layer::WALLS).map(|v| indoor(v, true)));
    out.extend((0..layer::OBSTACLES).map(|v| indoor(100 + v, false)));
    out.push(floor());
    out
}

/// A façade: 5 floors of 3.2 m, 4-6 bays, windows with frames, ground-floor doors, a plinth;
/// `u`, `v` span [`FACADE_TILE_M`] with v up from the building's base.
fn facade(variant: u32) -> Texels {
    let seed = 1000 + variant * 7919;
    let tile = FACADE_TILE_M as f32;
    let bays = 4 + (variant % 3) as i64;
    let (bay, storey) = (tile / bays as f32, tile / 5.0);
    let base = scale(
        [0.70, 0.66, 0.60],
        0.85 + 0.3 * hash(variant as i64, 7, seed),
    );
    paint_rows(LAYER_TEXELS, || {
        let mut stain = Fbm::new(seed + 5, 4, 10);
        move |u, v| {
            let (x, y) = (u * tile, (1.0 - v) * tile);
            let stain = 0.85 + 0.25 * stain.at(x / 1.6, y / 4.0);
            let (cx, cy) = ((x / bay).floor() as i64, (y / storey).floor() as i64);
            let (lx, ly) = ((x / bay).fract(), (y / storey).fract());
            let r = hash(cx, cy, seed);
            let mut c = scale(base, stain);
            if cy == 0 && r > 0.8 {
                if lx > 0.3 && lx < 0.7 && ly < 0.75 {
                    c = [0.30, 0.18, 0.10];
                }
            } else if r > 0.25 {
                let j = 0.08 * (hash(cx + 9, cy, seed) - 0.5);
                let inside = lx > 0.25 + j && lx < 0.75 + j && ly > 0.3 && ly < 0.8;
                let frame = lx > 0.22 + j && lx < 0.78 + j && ly > 0.27 && ly < 0.83;
                if inside {
                    let g = 0.15 * hash(cx * 3, cy * 3, seed + 1);
                    c = [0.15 + g, 0.20 + g, 0.28 + g];
                } else if frame {
                    c = [0.92, 0.92, 0.90];
                }
            }
            // A darker plinth: a horizontal edge for the line detector.
            if y < 0.4 {
                c = scale(c, 0.6);
            }
            c
        }
    })
}

/// Roof tiles: rows of 0.32 m, tiles of 0.4 m, each with its own shade, dark joints.
fn roof(variant: u32) -> Texels {
    let seed = 2000 + variant * 104_729;
    let tile = FACADE_TILE_M as f32;
    let base = if variant % 2 == 0 {
        [0.45, 0.25, 0.20]
    } else {
        [0.33, 0.30, 0.28]
    };
    paint_rows(LAYER_TEXELS, || {
        let mut shade = Fbm::new(seed, 3, 12);
        move |u, v| {
            let (x, y) = (u * tile, v * tile);
            let row = (y / 0.32).floor() as i64;
            let shift = if row % 2 == 0 { 0.0 } else { 0.2 };
            let col = ((x + shift) / 0.4).floor() as i64;
            let (lx, ly) = (((x + shift) / 0.4).fract(), (y / 0.32).fract());
            let shade = 0.7 + 0.5 * shade.at(x * 0.75, y * 0.75);
            let own = 0.8 + 0.4 * hash(col.rem_euclid(40), row.rem_euclid(50), seed);
            let joint = if lx < 0.06 || ly < 0.08 { 0.45 } else { 1.0 };
            scale(base, shade * own * joint)
        }
    })
}

/// Indoor surfaces (grey, tinted per object): stripes at a seeded angle, posters on 0.8 m
/// cells, fine noise; walls add a dark skirting board along their base.
fn indoor(variant: u32, skirting: bool) -> Texels {
    let seed = 3000 + variant * 15_485_863;
    let tile = INDOOR_TILE_M as f32;
    // An integer wave vector (cycles per tile) keeps the stripes tileable: 1-5 per metre.
    let a = 1 + (hash(1, 1, seed) * 16.0) as i64;
    let b = (hash(2, 2, seed) * 12.0) as i64 - 6;
    paint_rows(LAYER_TEXELS, || {
        let mut grain = Fbm::new(seed, 3, 24);
        move |u, v| {
            let (x, y) = (u * tile, (1.0 - v) * tile);
            let stripes = if (a as f32 * u + b as f32 * v).fract() < 0.5 {
                1.0
            } else {
                0.56
            };
            let mut c = [stripes; 3];
            let (cx, cy) = ((x / 0.8).floor() as i64, (y / 0.8).floor() as i64);
            let (lx, ly) = ((x / 0.8).fract(), (y / 0.8).fract());
            if hash(cx, cy, seed + 17) > 0.6 && lx > 0.2 && lx < 0.8 && ly > 0.25 && ly < 0.75 {
                c = [1, 2, 3].map(|k| 0.3 + 1.2 * hash(cx, cy, seed + k));
            }
            if skirting && y < 0.1 {
                c = [0.25; 3];
            }
            scale(c, 0.85 + 0.3 * grain.at(x * 6.0, y * 6.0))
        }
    })
}

/// Floor tiles of 0.5 m in two shades, with noise.
fn floor() -> Texels {
    let tile = INDOOR_TILE_M as f32;
    paint_rows(LAYER_TEXELS, || {
        let mut grain = Fbm::new(71, 5, 8);
        move |u, v| {
            let (x, y) = (u * tile, v * tile);
            let checker = ((x / 0.5).floor() as i64 + (y / 0.5).floor() as i64) & 1;
            let base = if checker == 1 {
                [0.52, 0.50, 0.47]
            } else {
                [0.62, 0.60, 0.56]
            };
            scale(base, 0.85 + 0.3 * grain.at(x * 2.0, y * 2.0))
        }
    })
}

/// The mip chain of a level-0 texture, level 0 first: 2x2 box filter, in linear light for
/// gamma-encoded textures (value textures are averaged as stored). Rows in parallel.
pub(crate) fn mips(t: Texels) -> Vec<Vec<u8>> {
    let encoded = t.encoded;
    let to_linear = move |b: u8| {
        if encoded {
            decode(b)
        } else {
            b as f32 / 255.0
        }
    };
    let from_linear = move |l: f32| {
        if encoded {
            encode(l)
        } else {
            (l.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
        }
    };
    let mut side = t.side as usize;
    let mut levels = vec![t.rgba];
    while side > 1 {
        let prev = levels.last().expect("level 0");
        let half = side / 2;
        let mut next = vec![0u8; half * half * 4];
        next.par_chunks_mut(half * 4)
            .enumerate()
            .for_each(|(j, row)| {
                for (i, px) in row.chunks_exact_mut(4).enumerate() {
                    for (c, o) in px.iter_mut().enumerate() {
                        let at = |x: usize, y: usize| prev[(y * side + x) * 4 + c];
                        let quad = [
                            at(2 * i, 2 * j),
                            at(2 * i + 1, 2 * j),
                            at(2 * i, 2 * j + 1),
                            at(2 * i + 1, 2 * j + 1),
                        ];
                        *o = if c == 3 {
                            255
                        } else {
                            from_linear(quad.iter().map(|&b| to_linear(b)).sum::<f32>() / 4.0)
                        };
                    }
                }
            });
        levels.push(next);
        side = half;
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shader_tiles_the_detail_texture_as_it_was_baked() {
        let line = crate::SCENE_WGSL
            .lines()
            .find(|l| l.starts_with("const DETAIL_TILE_M: f32 = "))
            .expect("the shader declares the detail tile");
        let value: f32 = line
            .trim_start_matches("const DETAIL_TILE_M: f32 = ")
            .trim_end_matches(';')
            .parse()
            .unwrap();
        assert_eq!(value, DETAIL_TILE_M);
    }

    #[test]
    fn every_layer_is_baked_at_the_same_size() {
        let l = layers();
        assert_eq!(l.len() as u32, layer::COUNT);
        assert!(l.iter().all(|t| t.side == LAYER_TEXELS && t.encoded));
    }

    /// The plain definition [`encode`] computes fast: the first value whose midpoint with
    /// its successor is not below `l` (a binary search over the 255 midpoints).
    fn encode_by_search(linear: f32) -> u8 {
        let t = gamma_table();
        let l = linear.clamp(0.0, 1.0);
        let (mut lo, mut hi) = (0usize, 255usize);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if (t[mid] + t[mid + 1]) / 2.0 < l {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        lo as u8
    }

    #[test]
    fn encoding_is_the_binary_search_s_at_every_midpoint_bucket_edge_and_between() {
        let e = encoder();
        // The walk counts midpoints below the value only because they ascend.
        assert!(e.midpoints.windows(2).all(|w| w[0] < w[1]));
        // Each midpoint and bucket edge and the 8 floats either side, where a walk that
        // starts too late or stops too early would show; then a dense sweep of [0, 1] and
        // what lies outside it.
        let edges = e
            .midpoints
            .iter()
            .copied()
            .chain((0..=BUCKETS).map(|b| b as f32 / BUCKETS as f32));
        let mut values: Vec<f32> = edges
            .flat_map(|m| {
                (-8i32..=8).map(move |d| f32::from_bits((m.to_bits() as i32 + d).max(0) as u32))
            })
            .collect();
        values.extend((0..=2_000_000).map(|i| i as f32 / 2_000_000.0));
        values.extend([-1.0, -0.0, 1.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN]);
        for l in values {
            assert_eq!(encode(l), encode_by_search(l), "{l:e} ({:#x})", l.to_bits());
        }
    }

    #[test]
    fn floor_is_the_standard_library_s_bit_for_bit() {
        let mut values: Vec<f32> = (-3_000_000..=3_000_000)
            .map(|i| i as f32 / 1024.0)
            .collect();
        for w in [
            0.0f32,
            1.0,
            -1.0,
            8_388_607.0,
            8_388_608.0,
            -8_388_608.0,
            3e9,
            -3e9,
        ] {
            values.extend((-4i32..=4).map(|d| f32::from_bits((w.to_bits() as i32 + d) as u32)));
        }
        values.extend([
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            0.999_999_94,
            -0.999_999_94,
        ]);
        values.extend([f32::MAX, f32::MIN, f32::INFINITY, f32::NEG_INFINITY]);
        for x in values {
            assert_eq!(floor_of(x).to_bits(), x.floor().to_bits(), "{x:e}");
        }
        assert!(floor_of(f32::NAN).is_nan());
    }

    #[test]
    fn gamma_encoding_round_trips_every_byte() {
        for b in 0..=255u8 {
            assert_eq!(encode(decode(b)), b);
        }
    }

    /// Value noise read afresh at every point: the four corners hashed each time.
    fn value_noise(x: f32, y: f32, seed: u32, period: i64) -> f32 {
        let (fx, fy) = (floor_of(x), floor_of(y));
        let (tx, ty) = (x - fx, y - fy);
        let (ux, uy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
        let (ix, iy) = (fx as i64, fy as i64);
        let wrap = |i: i64| if period > 0 { i.rem_euclid(period) } else { i };
        let (x0, x1, y0, y1) = (wrap(ix), wrap(ix + 1), wrap(iy), wrap(iy + 1));
        let (h00, h10) = (hash(x0, y0, seed), hash(x1, y0, seed));
        let (h01, h11) = (hash(x0, y1, seed), hash(x1, y1, seed));
        let top = h00 + (h10 - h00) * ux;
        let bottom = h01 + (h11 - h01) * ux;
        top + (bottom - top) * uy
    }

    /// The fractal sum of fresh reads.
    fn fbm(x: f32, y: f32, seed: u32, octaves: u32, period: i64) -> f32 {
        let (mut sum, mut amp, mut f, mut p) = (0.0, 0.5, 1.0, period);
        for k in 0..octaves {
            sum += amp * value_noise(x * f, y * f, seed.wrapping_add(k * 101), p);
            amp *= 0.5;
            f *= 2.0;
            p *= 2;
        }
        sum
    }

    #[test]
    fn a_row_s_lattices_read_what_fresh_reads_do_bit_for_bit() {
        // Rows of texels at several spacings (coarser and finer than a cell), across negative
        // and positive coordinates, with and without a period: the cached hashes of the last
        // cell give the bits of reading every point afresh.
        for (seed, period) in [(11u32, 0i64), (37, 0), (31, 64), (29, 10)] {
            for step in [0.013f32, 0.2, 0.77, 3.1] {
                // Rows (a texture's use), a diagonal that changes the cell's row too, and walks
                // that start in cell (0, 0).
                for (x0, y, slope) in [
                    (-40.0f32, -7.3f32, 0.0f32),
                    (-40.0, -0.5, 0.0),
                    (0.0, 0.0, 0.0),
                    (0.0, 2.25, 0.0),
                    (-40.0, 101.9, 0.0),
                    (-40.0, -30.0, 0.37),
                ] {
                    let mut lattice = Lattice::new(seed, period);
                    let mut octaves = Fbm::new(seed, 4, period);
                    for i in 0..2000 {
                        let x = x0 + i as f32 * step;
                        let y = y + slope * i as f32 * step;
                        assert_eq!(
                            lattice.at(x, y).to_bits(),
                            value_noise(x, y, seed, period).to_bits(),
                            "value noise at ({x}, {y}), seed {seed}, period {period}"
                        );
                        assert_eq!(
                            octaves.at(x, y).to_bits(),
                            fbm(x, y, seed, 4, period).to_bits(),
                            "fbm at ({x}, {y}), seed {seed}, period {period}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn tileable_noise_matches_across_the_period() {
        for k in 0..50 {
            let (x, y) = (0.37 * k as f32, 0.11 * k as f32);
            let a = Fbm::new(5, 4, 8).at(x, y);
            let b = Fbm::new(5, 4, 8).at(x + 8.0, y - 16.0);
            assert!((a - b).abs() < 1e-4, "{a} vs {b}");
        }
    }

    #[test]
    fn mip_levels_halve_down_to_one_texel_and_keep_the_mean() {
        let levels = mips(floor());
        assert_eq!(levels.len(), LAYER_TEXELS.trailing_zeros() as usize + 1);
        assert_eq!(levels.last().unwrap().len(), 4);
        let mean = |bytes: &[u8]| {
            bytes
                .chunks_exact(4)
                .map(|p| decode(p[0]) as f64)
                .sum::<f64>()
                / (bytes.len() / 4) as f64
        };
        // Averaging in linear light keeps the mean up to rounding at each of the 9 levels.
        let (m0, m9) = (mean(&levels[0]), mean(levels.last().unwrap()));
        assert!((m0 - m9).abs() < 0.01, "{m0} vs {m9}");
    }
}
