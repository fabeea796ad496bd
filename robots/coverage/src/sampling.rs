//! The random draws both particle filters share ([`crate::localize`], [`crate::mcl`]).

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// A standard normal draw (Box-Muller, two uniforms).
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = rng.random_range(1e-12..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Systematic (low-variance) resampling (Thrun, Burgard and Fox, Table 4.4): the index of
/// the particle each of the `weights.len()` new particles copies, from one uniform draw.
/// `weights` sum to 1.
pub(crate) fn systematic(weights: &[f64], rng: &mut ChaCha8Rng) -> Vec<usize> {
    let n = weights.len();
    let step = 1.0 / n as f64;
    let mut u = rng.random_range(0.0..step);
    let mut cumulative = weights[0];
    let mut i = 0;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        while u > cumulative && i + 1 < n {
            i += 1;
            cumulative += weights[i];
        }
        out.push(i);
        u += step;
    }
    out
}
