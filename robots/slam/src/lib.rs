//! Hierarchical visual EKF-SLAM of seed `000_955784a9d1cf66bf` (Sections II-IV): local
//! EKF sub-maps with inverse-depth points, and the geometry they rest on.
//!
//! * [`quat`]: quaternions `[w, x, y, z]` with the Jacobians the filter needs;
//! * [`idp`]: inverse-depth points: undelayed initialization from a pixel, projection, and
//!   their analytic Jacobians;
//!
//! Every Jacobian is checked against finite differences in the module's tests.

pub mod ekf;
pub mod idp;
pub mod quat;
