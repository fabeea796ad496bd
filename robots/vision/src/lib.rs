//! Image features and stereo visual odometry for the SLAM stack of seed
//! `000_955784a9d1cf66bf` (Section V, "Involved processes").
//!
//! * [`appearance`]: global image features (WGOH, 15 x 11 thumbnails) for the children's
//!   appearance-based localization (seed 002);
//! * [`hats`]: the parent's hat tracker on its omnidirectional panorama (seed 002): orange
//!   blobs, and the children's floor positions from their bearing and elevation;
//! * [`harris`]: Harris interest points, and the seed's heuristic of a regular 3 x 3
//!   partition of the image with at least two tracked landmarks per region;
//! * [`matching`]: zero-mean normalized cross-correlation (ZNCC) of patches, searched inside a
//!   predicted ellipse given by the caller's covariance;
//! * [`place`]: stereo key frames with rotation-invariant binary descriptors (steered BRIEF),
//!   and the relative pose between two of them (image matching, seed Section V);
//! * [`segments`]: LSD-class line segment detection, and tracking from a predicted segment;
//! * [`stereo`]: points matched along the rows of a rectified stereo pair, triangulated to
//!   3D points in the left camera's optical frame;
//! * [`vo`]: frame-to-frame motion from matched 3D points, RANSAC then Gauss-Newton on the
//!   reprojection error, with a covariance, as the EKF's motion prediction.
//!
//! Everything works on [`Gray`] images in the optical frame convention (x right, y down,
//! z forward; pixel centres at integer coordinates).
//!
//! Why hand-written: these are the seeds' own processes, and what the evaluation measures is
//! how the robot software built from them behaves, so each is written as the papers describe
//! it (Harris with the 3 x 3 partition, ZNCC inside the EKF's ellipse, the segment growing and
//! its 3D tracking, the key frames' steered BRIEF) and its definition is part of the result.
//! The candidates do not fit: OpenCV is C++ (a system library and bindings in a crate every
//! robot links), and `imageproc` has other definitions (FAST corners, whole-image template
//! matching without the predicted ellipse, Hough lines rather than LSD-class segments). The
//! generic maths is not hand-written: nalgebra's decompositions and rand's generators.

pub mod appearance;
pub mod harris;
pub mod hats;
pub mod image;
pub mod matching;
pub mod place;
pub mod segments;
pub mod stereo;
pub mod vo;

pub use image::Gray;
