//! A robot stack running stereo VO beside another stack (the waypoint pilot).
//!
//! The true pose at the first stereo pair fixes where the estimate starts (in the seed the
//! first sub-map of Dala is the world origin); after that only the stereo images are used:
//! each pair `<stereo>/left`, `<stereo>/right` with the same stamp gives the motion of the
//! left camera, which is chained into `world_from_body`. Frames where VO fails keep the
//! previous motion (constant velocity) and are counted.

use crate::stereo::Bench;
use crate::vo::StereoVo;
use crate::Gray;
use hetsim_msgs::{Command, Image, Outgoing, Pose, RobotStack, SensorMsg, StackStatus};

/// Pilot + stereo visual odometry.
pub struct VoStack {
    inner: Box<dyn RobotStack>,
    vo: StereoVo,
    stereo: String,
    body_from_camera: Pose,
    world_from_camera: Option<Pose>,
    pending_left: Option<Image>,
    last_motion: Pose,
    trajectory: Vec<(u64, Pose)>,
    rng: ransac_rng::Lcg,
    /// Frames whose motion could not be estimated.
    pub failures: usize,
}

/// A small deterministic generator for RANSAC, seeded by the caller (robots do not depend
/// on the simulator's stream machinery).
mod ransac_rng {
    /// 64-bit linear congruential generator (Knuth's MMIX constants), output mixed by
    /// xorshift; ample for drawing RANSAC samples.
    pub struct Lcg(pub u64);

    impl rand::TryRng for Lcg {
        type Error = core::convert::Infallible;
        fn try_next_u32(&mut self) -> Result<u32, Self::Error> {
            Ok((self.try_next_u64()? >> 32) as u32)
        }
        fn try_next_u64(&mut self) -> Result<u64, Self::Error> {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let mut x = self.0;
            x ^= x >> 33;
            Ok(x)
        }
        fn try_fill_bytes(&mut self, dst: &mut [u8]) -> Result<(), Self::Error> {
            for chunk in dst.chunks_mut(8) {
                let v = self.try_next_u64()?.to_le_bytes();
                chunk.copy_from_slice(&v[..chunk.len()]);
            }
            Ok(())
        }
    }
}

impl VoStack {
    /// VO on the stereo camera named `stereo` (its images are `<stereo>/left` and
    /// `<stereo>/right`), whose left optical frame is at `body_from_camera`, around `inner`.
    pub fn new(
        inner: Box<dyn RobotStack>,
        stereo: &str,
        bench: Bench,
        body_from_camera: Pose,
        seed: u64,
    ) -> Self {
        Self {
            inner,
            vo: StereoVo::new(bench),
            stereo: stereo.to_string(),
            body_from_camera,
            world_from_camera: None,
            pending_left: None,
            last_motion: Pose::identity(),
            trajectory: Vec::new(),
            rng: ransac_rng::Lcg(seed),
            failures: 0,
        }
    }

    fn on_pair(&mut self, left: &Image, right: &Image) {
        let (l, r) = (
            Gray::from_rgb(left.width as usize, left.height as usize, &left.rgb),
            Gray::from_rgb(right.width as usize, right.height as usize, &right.rgb),
        );
        let motion = self.vo.process(&l, &r, &mut self.rng);
        let Some(world_from_camera) = self.world_from_camera.as_mut() else {
            return;
        };
        if self.trajectory.is_empty() {
            // First pair: the estimate starts at the first known pose.
            self.trajectory.push((
                left.stamp_ns,
                *world_from_camera * self.body_from_camera.inverse(),
            ));
            return;
        }
        let current_from_previous = match motion {
            Some(m) => {
                self.last_motion = m.current_from_previous;
                m.current_from_previous
            }
            None => {
                self.failures += 1;
                self.last_motion
            }
        };
        *world_from_camera *= current_from_previous.inverse();
        self.trajectory.push((
            left.stamp_ns,
            *world_from_camera * self.body_from_camera.inverse(),
        ));
    }
}

impl RobotStack for VoStack {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Command {
        for msg in inbox {
            match msg {
                // The latest true pose until the first stereo pair anchors the estimate.
                SensorMsg::TruthPose(p) if self.trajectory.is_empty() => {
                    self.world_from_camera = Some(p.pose * self.body_from_camera);
                }
                SensorMsg::Image(img) if img.sensor == format!("{}/left", self.stereo) => {
                    self.pending_left = Some(img.clone())
                }
                SensorMsg::Image(img) if img.sensor == format!("{}/right", self.stereo) => {
                    if let Some(left) = self
                        .pending_left
                        .take()
                        .filter(|l| l.stamp_ns == img.stamp_ns)
                    {
                        self.on_pair(&left, img);
                    }
                }
                _ => {}
            }
        }
        self.inner.step(now_ns, inbox)
    }

    fn status(&self) -> StackStatus {
        self.inner.status()
    }

    fn outbox(&mut self) -> Vec<Outgoing> {
        self.inner.outbox()
    }

    fn trajectories(&self) -> Vec<(String, Vec<(u64, Pose)>)> {
        let mut t = self.inner.trajectories();
        t.push(("vo".to_string(), self.trajectory.clone()));
        t
    }
}
