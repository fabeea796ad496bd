//! Hierarchical visual EKF-SLAM of seed `000_955784a9d1cf66bf` (Sections II-IV): local
//! EKF sub-maps with inverse-depth points and anchored Plücker lines, the team's graph of
//! sub-map origins, and the geometry they rest on.
//!
//! * [`apl`]: anchored Plücker lines (Eqs. 7-19): frame transformations, un-anchoring,
//!   projection, endpoint measurements, back-projection with the β prior, with Jacobians;
//! * [`quat`]: quaternions `[w, x, y, z]` with the Jacobians the filter needs;
//! * [`idp`]: inverse-depth points: undelayed initialization from a pixel, projection, and
//!   their analytic Jacobians;
//! * [`ekf`]: the local EKF map: VO prediction, gated point updates, undelayed
//!   initialization, deletion policy;
//! * [`lines`]: anchored Plücker lines in the local map: undelayed initialization from an
//!   image segment with the β prior, endpoint-distance updates, segment endpoints as
//!   abscissas outside the filter;
//! * [`graph`]: the global level: sub-map origins, relative and GPS constraints, Gauss-Newton
//!   loop closure, compounding with covariance;
//! * [`global`]: the team's graph on each robot: its own part, the parts received over the
//!   radio, event links (rendezvous, image matching) resolved by origin stamps;
//! * [`report`]: what the stack publishes for evaluation (origins, covariances, events);
//! * [`stack`]: the robot stack: stereo VO, points and segments tracked in the local maps in
//!   lockstep, sub-maps every 100 landmarks, events and the radio;
//!
//! Every Jacobian is checked against finite differences in the module's tests.

pub mod apl;
pub mod ekf;
pub use ekf::lines;
pub mod global;
pub mod graph;
pub mod idp;
pub mod quat;
pub mod report;
pub mod stack;
