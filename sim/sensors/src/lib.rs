//! Sensor models: compass, GPS, wheel odometry, IMU, laser scanner, child tracker, rendezvous
//! and image-match sensors, one module each (`kinds`), sampled from the physics world in
//! lockstep; and the camera model after rendering ([`camera`]).
//!
//! Every sensor of every robot gets its own random stream, `<robot>/<sensor>/noise`, so that
//! adding a sensor or a robot never changes another sensor's noise. Each sensor fires on the
//! ticks that are whole multiples of its period (GPS may instead follow a schedule), and its
//! message is stamped with the sim time at the end of that tick. Cameras are rendered by the
//! engine; what a camera does to the rendered image (distortion, panorama, gain, pixel noise)
//! is [`camera`]'s.
//!
//! Noise models (σ values come from the robot files):
//! * compass: `yaw + bias + distortion * sin(yaw) + N(0, σ)`, wrapped to (-π, π];
//! * GPS: antenna position plus `N(0, σ)` per axis; no fix during outages;
//! * wheel odometry: each wheel's true surface distance times `(1 + s)` with a per-run scale
//!   error `s ~ N(0, scale_sigma)`, plus `N(0, noise_per_m * |d|)`;
//! * IMU: angular rate and specific force from the body's motion (finite differences over
//!   the sample interval), plus a per-run bias `N(0, bias_sigma)` and white `N(0, σ)`;
//! * laser: exact ray casts against every collider but the robot's own, plus `N(0, σ)`;
//!   no return beyond `max_range_m` reads infinity;
//! * child tracker: a child within `range_m` of the tracker with a clear line to its hat is
//!   reported at its true position displaced by `|N(mean, std)|` in a uniform direction
//!   (mean 0.04, std 0.02 m in the seed); occluded or distant children are not reported;
//! * rendezvous: another robot within `range_m`, inside the `fov_deg` cone and with a clear
//!   line of sight yields its relative pose with `N(0, σ_m)` on each axis and `N(0, σ)` on
//!   each rotation axis, drawn in the SLAM graph's convention ([`relative`]) so that the
//!   error has exactly the covariance the message tells;
//! * image match (emulates the seed's image-to-image matching): once per key frame of
//!   another robot (a sub-map origin its stack reported) at least `min_age_s` old whose
//!   position is within `range_m` horizontally of this robot, the relative pose
//!   `self_from_keyframe` with `N(0, σ_m)` per axis and a rotation of `N(0, σ)` per axis.

pub mod camera;
mod kinds;
pub mod relative;
pub mod ros2;
mod suite;

pub use suite::{ImuTruth, Sample, SensorSuite};
