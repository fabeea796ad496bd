//! A camera after rendering: the renderer draws exact pinholes, and this is what a real
//! camera does to them.
//!
//! * radial distortion `x_d = x_u (1 + k1 r² + k2 r⁴)`, resampled (bilinear) from a render
//!   padded beyond the image where the distortion needs rays outside its field of view;
//! * the omnidirectional camera's equirectangular panorama, resampled from six 90° faces;
//! * exposure gain and Gaussian pixel noise ([`PixelNoise`]), rounded to bytes.
//!
//! The engine (`hetsim_engine::cameras`) decides what to render when and applies these.

mod noise;
mod optics;
#[cfg(test)]
mod tests;

pub use noise::{inverse_normal_cdf, quantize, PixelNoise};
pub use optics::{
    bilinear, distort, panorama, panorama_lookup, panorama_taps, pinhole, undistort, Tap, Taps,
    CUBE,
};

use hetsim_msgs::CameraGeometry;

/// A camera's model after rendering.
pub enum Model {
    /// A pinhole, with radial distortion where the robot file gives it.
    Pinhole {
        /// `[k1, k2]`.
        distortion: Option<[f64; 2]>,
        /// The geometry actually rendered (padded beyond the image when distortion needs rays
        /// outside its undistorted field of view).
        render: CameraGeometry,
    },
    /// The omnidirectional camera's panorama.
    Omni {
        /// Each cube face's geometry.
        face: CameraGeometry,
        /// The panorama's pixels, computed once: where each reads the rendered faces.
        taps: Taps,
        /// The faces the taps read (indices into [`CUBE`]).
        faces: Vec<usize>,
    },
}
