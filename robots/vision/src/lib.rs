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
