//! A camera after rendering: the renderer draws exact pinholes, and this is what a real
//! camera does to them.
//!
//! * radial distortion `x_d = x_u (1 + k1 r² + k2 r⁴)`, resampled (bilinear) from a render
//!   padded beyond the image where the distortion needs rays outside its field of view;
//! * the omnidirectional camera's equirectangular panorama, resampled from six 90° faces;
//! * the exposure: motion blur and the rolling shutter ([`motion`]), rendered with the true
//!   calibration, not the one the robot software is given ([`calibration`]);
//! * exposure gain, vignetting and Gaussian pixel noise ([`PixelNoise`]), rounded to bytes.
//!
//! The engine (`hetsim_engine::cameras`) decides what to render when and applies these.

pub mod calibration;
pub mod motion;
mod noise;
mod optics;
#[cfg(test)]
mod tests;

pub use noise::{inverse_normal_cdf, quantize, PixelNoise};
pub use optics::{
    bilinear, distort, panorama, panorama_lookup, panorama_taps, pinhole, undistort, Tap, Taps,
    CUBE,
};

use crate::ros2::{from_cdr, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{HEADER, TIME};
use hetsim_msgs::{CameraGeometry, Image, PixelEncoding, SensorMsg};
use serde::{Deserialize, Serialize};

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

/// `sensor_msgs/msg/Image`, as the recorder writes it.
#[derive(Serialize)]
struct Ros2Image<'a> {
    header: Header,
    height: u32,
    width: u32,
    encoding: &'a str,
    is_bigendian: u8,
    step: u32,
    #[serde(with = "serde_bytes")]
    data: &'a [u8],
}

/// `sensor_msgs/msg/Image`, as replay reads it.
#[derive(Deserialize)]
struct Ros2ImageIn {
    header: Header,
    height: u32,
    width: u32,
    encoding: String,
    _is_bigendian: u8,
    step: u32,
    data: serde_bytes::ByteBuf,
}

/// Raw and unpadded, `rgb8` or `mono8`, in the camera's optical frame (z forward).
impl Ros2Message for Image {
    const SCHEMA: &'static str = "sensor_msgs/msg/Image";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![(
            Self::SCHEMA,
            with_deps(
                "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
                &[HEADER, TIME],
            ),
        )]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let m = Ros2Image {
            header: frames.in_sensor(),
            height: self.height,
            width: self.width,
            encoding: self.encoding.ros_name(),
            is_bigendian: 0,
            step: self.width * self.encoding.channels(),
            data: &self.data,
        };
        vec![Encoded::on_topic(Self::SCHEMA, &m)]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: Ros2ImageIn = from_cdr(data)?;
        let encoding = PixelEncoding::from_ros_name(&m.encoding)
            .ok_or_else(|| DecodeError::ImageEncoding(m.encoding.clone()))?;
        if m.step != m.width.saturating_mul(encoding.channels()) {
            return Err(DecodeError::ImageStep {
                step: m.step,
                width: m.width,
                encoding: m.encoding.clone(),
            });
        }
        Ok(SensorMsg::Image(Image {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            width: m.width,
            height: m.height,
            encoding,
            data: m.data.into_vec(),
        }))
    }
}
