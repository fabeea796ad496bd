//! Gaussian pixel noise, cheap enough for 40 megapixel-channels per sim second.
//!
//! A camera adds `σ n` to each channel, `n ~ N(0, 1)`. Drawing an f64 normal (ziggurat on
//! ChaCha's output) for every channel of every pixel cost 13 % of the village's time. Here each
//! 16 bits of an image's noise stream (seeded from the camera's ChaCha stream) pick one of
//! 4096 equiprobable cells of the normal ([`PixelNoise`]): the cell's midpoint quantile, or in
//! the two tail cells the exact quantile. Its spacing near the mode (σ / 1600) is far below the
//! byte the value is rounded to, and the tails reach ±4.3σ.

use rand::Rng;

/// Cells of the quantile table: 16 KB of f32, so that 2.4 million lookups an image stay in
/// the L1 cache (a 65 536-entry table spilled to L3 and cost 10 ms an image).
const LEVELS: usize = 1 << 12;

/// The quantile function of the standard normal, Φ⁻¹(p) for 0 < p < 1 (Acklam's rational
/// approximation, relative error below 1.2e-9).
///
/// Kept rather than `statrs`' `Normal::inverse_cdf` on purpose: the noise table is built from
/// it once per camera, a byte-rounded pixel cannot show the difference, and another
/// implementation's last bits could move table cells and with them every rendered digest.
pub fn inverse_normal_cdf(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const LOW: f64 = 0.024_25;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

/// A camera's pixel noise: the midpoints of 4096 equiprobable cells of the normal, scaled
/// by σ. A 16-bit draw picks a cell with its top 12 bits; in the two tail cells (beyond
/// ±3.35σ, where a midpoint would truncate the tail) its low 4 bits place the value within
/// the cell by the exact quantile function, down to p = 2⁻¹⁷ (±4.33σ).
pub struct PixelNoise {
    table: Vec<f32>,
    /// The table rounded half up, for unit gain: `round(c + n) = c + round(n)` for integer
    /// `c`, so the image needs only integer additions.
    rounded: Vec<i16>,
    sigma: f64,
}

impl PixelNoise {
    /// Noise of standard deviation `sigma` (grey levels).
    pub fn new(sigma: f64) -> Self {
        let table = (0..LEVELS)
            .map(|i| (sigma * inverse_normal_cdf((i as f64 + 0.5) / LEVELS as f64)) as f32)
            .collect::<Vec<f32>>();
        let rounded = table.iter().map(|v| (v + 0.5).floor() as i16).collect();
        Self {
            table,
            rounded,
            sigma,
        }
    }

    /// The noise value of a 16-bit draw.
    #[inline]
    fn value(&self, draw: u16) -> f32 {
        let cell = (draw >> 4) as usize;
        if cell == 0 || cell == LEVELS - 1 {
            return self.tail(draw);
        }
        self.table[cell]
    }

    /// A draw in a tail cell (one in 2048).
    #[cold]
    #[inline(never)]
    fn tail(&self, draw: u16) -> f32 {
        let cell = (draw >> 4) as f64;
        let p = (cell + ((draw & 0xf) as f64 + 0.5) / 16.0) / LEVELS as f64;
        (self.sigma * inverse_normal_cdf(p)) as f32
    }

    /// `c + round(n)` clamped to a byte, for a 16-bit draw.
    #[inline]
    fn add_rounded(&self, c: u8, draw: u16) -> u8 {
        let cell = (draw >> 4) as usize;
        let n = if cell == 0 || cell == LEVELS - 1 {
            (self.tail(draw) + 0.5).floor() as i16
        } else {
            self.rounded[cell & (LEVELS - 1)]
        };
        (c as i16 + n).clamp(0, 255) as u8
    }

    /// The unit-gain path for RGBA pixels, the renderer's readback: four pixels (twelve
    /// channels, three words of noise) at a time, with one test for a tail cell among the
    /// twelve draws instead of one per channel. The same bits reach the same channels as in
    /// [`PixelNoise::apply`]'s general path (a test compares the two).
    fn add_rounded_rgba(&self, src: &[u8], bits: &mut SplitMix64) -> Vec<u8> {
        let mut rgb = vec![0u8; src.len() / 4 * 3];
        self.add_rounded_rgba_into(src, bits, &mut rgb);
        rgb
    }

    /// [`PixelNoise::add_rounded_rgba`] into grey bytes: the noisy RGB of 1024 pixels at a
    /// time, in a buffer that stays in the L1 cache, reduced by `luminance` (the stereo
    /// benches' mono8: no 2.4 MB RGB image written and read back). Every run but the last
    /// is a whole number of four-pixel blocks, so the draws are those of one pass.
    fn add_rounded_rgba_grey(
        &self,
        src: &[u8],
        bits: &mut SplitMix64,
        luminance: impl Fn([u8; 3]) -> u8,
    ) -> Vec<u8> {
        const RUN: usize = 1024;
        const _: () = assert!(RUN % 4 == 0, "runs of whole four-pixel blocks");
        let mut grey = vec![0u8; src.len() / 4];
        let mut rgb = vec![0u8; RUN * 3];
        for (run, out) in src.chunks(RUN * 4).zip(grey.chunks_mut(RUN)) {
            let rgb = &mut rgb[..out.len() * 3];
            self.add_rounded_rgba_into(run, bits, rgb);
            for (g, p) in out.iter_mut().zip(rgb.chunks_exact(3)) {
                *g = luminance([p[0], p[1], p[2]]);
            }
        }
        grey
    }

    /// The RGBA unit-gain loop, into `rgb` (three bytes for each of `src`'s pixels).
    fn add_rounded_rgba_into(&self, src: &[u8], bits: &mut SplitMix64, rgb: &mut [u8]) {
        let mut out = rgb.chunks_exact_mut(12);
        let mut inp = src.chunks_exact(16);
        let table: &[i16; LEVELS] = self.rounded[..].try_into().expect("LEVELS cells");
        for (o, i) in (&mut out).zip(&mut inp) {
            let words = [bits.next(), bits.next(), bits.next()];
            let tails = words.iter().any(|&w| has_tail_draw(w));
            let i: &[u8; 16] = i.try_into().expect("chunks of sixteen");
            let o: &mut [u8; 12] = o.try_into().expect("chunks of twelve");
            // Channel j of the block: byte SRC[j] of the four RGBA pixels.
            const SRC: [usize; 12] = [0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14];
            if tails {
                for j in 0..12 {
                    let draw = (words[j / 4] >> (16 * (j % 4))) as u16;
                    o[j] = self.add_rounded(i[SRC[j]], draw);
                }
            } else {
                for j in 0..12 {
                    let cell = (words[j / 4] >> (16 * (j % 4) + 4)) as usize & (LEVELS - 1);
                    o[j] = (i[SRC[j]] as i16 + table[cell]).clamp(0, 255) as u8;
                }
            }
        }
        // The last pixels (fewer than four), channel by channel as in the general path.
        let rest: Vec<u8> = inp
            .remainder()
            .chunks_exact(4)
            .flat_map(|px| px[..3].to_vec())
            .collect();
        let last = out.into_remainder();
        for (q, chunk) in rest.chunks(4).enumerate() {
            let word = bits.next();
            for (k, &c) in chunk.iter().enumerate() {
                last[q * 4 + k] = self.add_rounded(c, (word >> (16 * k)) as u16);
            }
        }
    }

    /// `round(clamp(gain c + σ n))` for every colour channel of `src` (pixels of `stride`
    /// bytes, the first three of which are RGB), into `rgb`. The image's noise bits come from
    /// [`SplitMix64`] seeded by one word of the camera's stream; channel `i` takes bits
    /// `16 (i mod 4)..` of word `i / 4`.
    pub fn apply(&self, src: &[u8], stride: usize, gain: f32, rng: &mut impl Rng) -> Vec<u8> {
        let mut bits = SplitMix64(rng.next_u64());
        if gain == 1.0 && stride == 4 {
            self.add_rounded_rgba(src, &mut bits)
        } else {
            self.add_general(src, stride, gain, &mut bits)
        }
    }

    /// [`PixelNoise::apply`] with each pixel's own gain `gains[i]` (vignetting): the general
    /// path, with the same bits reaching the same channels.
    pub fn apply_mapped(
        &self,
        src: &[u8],
        stride: usize,
        gains: &[f32],
        rng: &mut impl Rng,
    ) -> Vec<u8> {
        let mut bits = SplitMix64(rng.next_u64());
        let mut rgb: Vec<u8> = Vec::with_capacity(src.len() / stride * 3);
        for px in src.chunks_exact(stride) {
            rgb.extend_from_slice(&px[..3]);
        }
        for (q, o) in rgb.chunks_mut(4).enumerate() {
            let word = bits.next();
            for (k, c) in o.iter_mut().enumerate() {
                let n = self.value((word >> (16 * k)) as u16);
                *c = quantize(*c as f32 * gains[(q * 4 + k) / 3] + n);
            }
        }
        rgb
    }

    /// [`PixelNoise::apply`] reduced to one grey byte a pixel by `luminance`: the same noise
    /// draws and the same bytes as `apply` followed by `luminance` on each pixel, without the
    /// RGB image in between where the renderer's RGBA is taken at unit gain.
    pub fn apply_grey(
        &self,
        src: &[u8],
        stride: usize,
        gain: f32,
        rng: &mut impl Rng,
        luminance: impl Fn([u8; 3]) -> u8,
    ) -> Vec<u8> {
        if gain == 1.0 && stride == 4 {
            let mut bits = SplitMix64(rng.next_u64());
            self.add_rounded_rgba_grey(src, &mut bits, luminance)
        } else {
            self.apply(src, stride, gain, rng)
                .chunks_exact(3)
                .map(|p| luminance([p[0], p[1], p[2]]))
                .collect()
        }
    }

    /// [`PixelNoise::apply`] for any stride and gain, channel by channel.
    fn add_general(&self, src: &[u8], stride: usize, gain: f32, bits: &mut SplitMix64) -> Vec<u8> {
        // The colour channels, then the noise added in place, four channels to a word.
        let mut rgb: Vec<u8> = Vec::with_capacity(src.len() / stride * 3);
        for px in src.chunks_exact(stride) {
            rgb.extend_from_slice(&px[..3]);
        }
        if gain == 1.0 {
            let mut quads = rgb.chunks_exact_mut(4);
            for o in &mut quads {
                let word = bits.next();
                for (k, c) in o.iter_mut().enumerate() {
                    *c = self.add_rounded(*c, (word >> (16 * k)) as u16);
                }
            }
            let word = bits.next();
            for (k, c) in quads.into_remainder().iter_mut().enumerate() {
                *c = self.add_rounded(*c, (word >> (16 * k)) as u16);
            }
        } else {
            for o in rgb.chunks_mut(4) {
                let word = bits.next();
                for (k, c) in o.iter_mut().enumerate() {
                    let n = self.value((word >> (16 * k)) as u16);
                    *c = quantize(*c as f32 * gain + n);
                }
            }
        }
        rgb
    }
}

/// Whether any of a word's four 16-bit draws falls in a tail cell (top 12 bits all zeros or
/// all ones), lane-parallel: adding 1 to each cell maps the tail cells to 0 and 1, and
/// `0x1000 - t` keeps bit 12 only where `t = 0` (no borrow crosses a lane, since `t < 0x1000`).
#[inline]
fn has_tail_draw(word: u64) -> bool {
    const LANES: u64 = 0x0001_0001_0001_0001;
    let cells = (word >> 4) & (0x0fff * LANES);
    let t = (cells + LANES) & (0x0ffe * LANES);
    ((0x1000 * LANES - t) & (0x1000 * LANES)) != 0
}

/// SplitMix64 (Steele, Lea and Flood, OOPSLA 2014; the generator that seeds xoshiro and
/// backs Java's `SplittableRandom`, passing BigCrush): 64 bits for a few cycles, where the
/// camera's ChaCha8 stream would cost a third of the noise's time.
struct SplitMix64(u64);

impl SplitMix64 {
    #[inline]
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// The channel's byte: rounded half up, clamped to 0-255 (a float-to-integer conversion, not
/// a libm call).
#[inline]
pub fn quantize(v: f32) -> u8 {
    (v.clamp(0.0, 255.0) + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quantile_function_matches_the_normal_tables() {
        // Φ⁻¹ at the usual table points (Abramowitz and Stegun, Table 26.5).
        for (p, z) in [
            (0.5, 0.0),
            (0.841_344_746_068_542_9, 1.0),
            (0.975, 1.959_963_985),
            (0.995, 2.575_829_304),
            (0.999_968_328_758_166_9, 4.0),
            (0.001, -3.090_232_306),
        ] {
            let got = inverse_normal_cdf(p);
            assert!((got - z).abs() < 1e-6, "Φ⁻¹({p}) = {got}, tables: {z}");
        }
    }

    #[test]
    fn the_table_is_a_unit_normal_and_noisy_images_have_the_robot_files_sigma() {
        // Every 16-bit draw once: the distribution the noise draws from, exactly.
        let unit = PixelNoise::new(1.0);
        let values: Vec<f64> = (0..=u16::MAX).map(|d| unit.value(d) as f64).collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| v * v).sum::<f64>() / n;
        assert!(mean.abs() < 1e-6, "mean {mean}");
        // Truncation at ±4.3σ drops E[n²; |n| > 4.3] ≈ 3e-4 of the variance; the cells'
        // midpoints a little more.
        assert!((0.998..=1.0).contains(&var), "variance {var}");
        let max = values.iter().cloned().fold(0.0, f64::max);
        assert!((4.2..4.4).contains(&max), "the tail reaches {max}");
        // A flat grey image with σ = 2: the sample variance of 300 000 channels lies within
        // 0.5 % of 4 (its standard error is σ² √(2/N) = 0.26 %), plus 1/12 for rounding.
        let noise = PixelNoise::new(2.0);
        let src = vec![100u8; 100_000 * 4];
        let mut rng = hetsim_core::Streams::new(5).stream("noise-test");
        let out = noise.apply(&src, 4, 1.0, &mut rng);
        assert_eq!(out.len(), 300_000);
        let m = out.iter().map(|&v| v as f64).sum::<f64>() / out.len() as f64;
        let v = out.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / out.len() as f64;
        assert!((m - 100.0).abs() < 0.02, "mean {m}");
        let expected = 4.0 + 1.0 / 12.0;
        assert!(
            (v / expected - 1.0).abs() < 0.01,
            "variance {v}, expected {expected}"
        );
        // Clamping and rounding.
        assert_eq!(
            (quantize(-3.0), quantize(254.6), quantize(300.0)),
            (0, 255, 255)
        );
        assert_eq!((quantize(1.49), quantize(1.5)), (1, 2));
    }
}
#[cfg(test)]
mod fast_path {
    use super::*;

    /// Vignetting's per-pixel gains, all equal, are the scalar gain's general path bit for
    /// bit; and a pixel's own gain scales only that pixel.
    #[test]
    fn per_pixel_gains_are_the_general_path_pixel_by_pixel() {
        let noise = PixelNoise::new(2.0);
        let src: Vec<u8> = (0..10_001 * 4).map(|i| (i * 53 % 256) as u8).collect();
        let uniform = vec![0.8f32; 10_001];
        let mut a = hetsim_core::Streams::new(5).stream("v");
        let mut b = hetsim_core::Streams::new(5).stream("v");
        assert!(noise.apply_mapped(&src, 4, &uniform, &mut a) == noise.apply(&src, 4, 0.8, &mut b));
        let quiet = PixelNoise::new(0.0);
        let mut gains = vec![1.0f32; 10_001];
        gains[17] = 0.5;
        let mut c = hetsim_core::Streams::new(5).stream("v");
        let out = quiet.apply_mapped(&src, 4, &gains, &mut c);
        for (i, px) in out.chunks_exact(3).enumerate() {
            for ch in 0..3 {
                let want = quantize(src[i * 4 + ch] as f32 * gains[i]);
                assert_eq!(px[ch], want, "pixel {i} channel {ch}");
            }
        }
    }

    #[test]
    fn the_rgba_path_adds_the_same_noise_as_the_general_one() {
        // 100 003 pixels: about 150 draws in tail cells, and three pixels past the last block
        // of four.
        let noise = PixelNoise::new(2.5);
        let src: Vec<u8> = (0..100_003 * 4).map(|i| (i * 37 % 256) as u8).collect();
        let fast = noise.add_rounded_rgba(&src, &mut SplitMix64(7));
        let general = noise.add_general(&src, 4, 1.0, &mut SplitMix64(7));
        assert_eq!(fast.len(), 100_003 * 3);
        assert!(fast == general, "the two paths differ");
        // The grey path: the same bytes as the RGB ones reduced pixel by pixel, for the fast
        // path and for the general one (a gain), the three pixels past the last block included.
        let luminance = hetsim_msgs::PixelEncoding::luminance;
        for gain in [1.0, 1.3] {
            let mut a = hetsim_core::Streams::new(3).stream("grey");
            let mut b = hetsim_core::Streams::new(3).stream("grey");
            let rgb = noise.apply(&src, 4, gain, &mut a);
            let grey = noise.apply_grey(&src, 4, gain, &mut b, luminance);
            let reduced: Vec<u8> = rgb
                .chunks_exact(3)
                .map(|p| luminance([p[0], p[1], p[2]]))
                .collect();
            assert_eq!(grey.len(), 100_003, "gain {gain}");
            assert!(grey == reduced, "gain {gain}: the grey path differs");
        }
        // The comparison reaches the tail cells (one draw in 2048: about 146 expected).
        let mut bits = SplitMix64(7);
        let tails = (0..(100_003 * 3 + 3) / 4)
            .flat_map(|_| {
                let w = bits.next();
                (0..4).map(move |k| (w >> (16 * k + 4)) & 0xfff)
            })
            .filter(|&cell| cell == 0 || cell == 0xfff)
            .count();
        assert!(tails > 50, "only {tails} tail draws");
        // The lane-parallel tail test against the cell-by-cell one, at every cell in every lane.
        for cell in 0..0x1000u64 {
            for lane in 0..4 {
                for low in [0u64, 0xf] {
                    let w = ((cell << 4) | low) << (16 * lane)
                        | 0x0800_0800_0800_0800 & !(0xffff << (16 * lane));
                    assert_eq!(
                        has_tail_draw(w),
                        cell == 0 || cell == 0xfff,
                        "cell {cell:#x} lane {lane}"
                    );
                }
            }
        }
    }
}
