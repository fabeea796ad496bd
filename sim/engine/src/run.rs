//! Running a scenario tick by tick.

use crate::cameras::Cameras;
use crate::comms::Comms;
use crate::frames::{FrameDump, ImuSpec};
use crate::output::{RobotOutcome, RunOutput};
use crate::record::Recorder;
use hetsim_core::{PayloadHasher, RunDigest, Streams};
use hetsim_msgs::{
    pose_from_xyz_rpy, Command, InputError, Pose, PoseStamped, RobotStack, SensorMsg,
};
use hetsim_physics::Physics;
use hetsim_render::{RenderError, RenderOptions};
use hetsim_scene::Scenario;
use hetsim_sensors::SensorSuite;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// Runs a scenario to its duration with one robot stack per robot (scenario order).
/// `progress(tick, total)` is called every sim second or every 1 % of the run, whichever
/// comes more often. With a recorder, every command, message
/// and ground-truth pose also goes to its MCAP file.
///
/// The loop itself runs on a rayon worker thread, so the per-tick fan-out to the stacks is a
/// cheap fork-join rather than a hand-off from an outside thread every tick.
pub fn run(
    scenario: &Scenario,
    stacks: Vec<Box<dyn RobotStack>>,
    progress: impl FnMut(u64, u64) + Send,
    options: RunOptions<'_>,
) -> Result<RunOutput, RunError> {
    if stacks.len() != scenario.robots.len() {
        return Err(RunError::Stacks {
            stacks: stacks.len(),
            robots: scenario.robots.len(),
        });
    }
    rayon::scope(|_| run_on_worker(scenario, stacks, progress, options))
}

/// What a run does besides simulating.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// Record every message, command and ground-truth pose.
    pub recorder: Option<&'a mut Recorder>,
    /// Render the robots' cameras on this adapter choice; `None`: no cameras.
    pub render: Option<RenderOptions>,
    /// Write camera frames.
    pub dump: Option<&'a mut FrameDump>,
    /// Render only the frames the dump wants (for `hetsim frames`).
    pub frames_only: bool,
}

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// No renderer.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Frames could not be written.
    #[error("writing frames: {0}")]
    Frames(#[from] crate::frames::FrameError),
    /// The recording could not be written.
    #[error("recording: {0}")]
    Record(#[from] crate::record::RecordError),
    /// A robot's software refused a message it was fed.
    #[error("robot {robot} refused a message: {error}")]
    Input {
        /// The robot.
        robot: String,
        /// What it refused.
        error: Box<InputError>,
    },
    /// The caller gave a stack count that is not the robot count.
    #[error("{stacks} robot stacks for {robots} robots")]
    Stacks {
        /// Stacks given.
        stacks: usize,
        /// Robots in the scenario.
        robots: usize,
    },
}

/// Where messages go: the robot's inbox, the digest, the recording and the counts.
struct Post<'a> {
    names: Vec<String>,
    inboxes: Vec<Vec<SensorMsg>>,
    digest: RunDigest,
    recorder: Option<&'a mut Recorder>,
    counts: BTreeMap<String, u64>,
    /// When the messages being posted reach their robot (the next tick's time).
    received_ns: u64,
}

impl Post<'_> {
    fn deliver(&mut self, robot: usize, topic: &str, msg: SensorMsg, mount: Option<&Pose>) {
        self.digest.record(topic, &encode(&msg));
        self.file(robot, topic, msg, mount);
    }

    /// [`Post::deliver`] for a message whose encoding was hashed beforehand (an image).
    fn deliver_hashed(
        &mut self,
        robot: usize,
        topic: &str,
        msg: SensorMsg,
        mount: &Pose,
        hash: (u64, [u8; 32]),
    ) {
        self.digest.record_hashed(topic, hash);
        self.file(robot, topic, msg, Some(mount));
    }

    /// The recording, the counts and the inbox.
    fn file(&mut self, robot: usize, topic: &str, msg: SensorMsg, mount: Option<&Pose>) {
        if let Some(r) = self.recorder.as_deref_mut() {
            r.sensor(&self.names[robot], topic, mount, &msg, self.received_ns);
        }
        *self.counts.entry(topic.to_string()).or_default() += 1;
        self.inboxes[robot].push(msg);
    }
}

/// Per-robot topic names, made once.
struct Topics {
    cmd: Vec<String>,
    radio: Vec<String>,
    /// `robot/sensor` -> `body_from_sensor`.
    mounts: BTreeMap<String, Pose>,
}

impl Topics {
    fn of(scenario: &Scenario, names: &[String]) -> Self {
        let each = |suffix: &str| names.iter().map(|r| format!("{r}/{suffix}")).collect();
        Self {
            cmd: each("cmd"),
            radio: each("radio"),
            mounts: scenario
                .robots
                .iter()
                .flat_map(|r| {
                    r.model.sensors.iter().map(move |s| {
                        let m = s.mount();
                        (
                            format!("{}/{}", r.spec.name, s.name()),
                            pose_from_xyz_rpy(m.xyz_m, m.rpy_deg.map(f64::to_radians)),
                        )
                    })
                })
                .collect(),
        }
    }
}

/// Each robot's enabled oracle, if its robot file declares one: (topic, period in ticks).
pub(crate) fn oracles(scenario: &Scenario) -> Vec<Option<(String, u64)>> {
    scenario
        .robots
        .iter()
        .map(|r| {
            r.model
                .sensors
                .iter()
                .find(|s| s.is_enabled_oracle())
                .map(|s| {
                    (
                        format!("{}/{}", r.spec.name, s.name()),
                        scenario
                            .clock
                            .period_ticks(s.rate_hz())
                            .expect("validated rate"),
                    )
                })
        })
        .collect()
}

fn run_on_worker(
    scenario: &Scenario,
    mut stacks: Vec<Box<dyn RobotStack>>,
    mut progress: impl FnMut(u64, u64),
    options: RunOptions<'_>,
) -> Result<RunOutput, RunError> {
    let RunOptions {
        recorder,
        render,
        mut dump,
        frames_only,
    } = options;
    let clock = scenario.clock;
    let streams = Streams::new(scenario.seed);
    let mut physics = Physics::for_scenario(scenario, &streams);
    let names: Vec<String> = scenario
        .robots
        .iter()
        .map(|r| r.spec.name.clone())
        .collect();
    let mut sensors = SensorSuite::new(scenario, &streams);
    let mut cameras = match &render {
        Some(o) => Cameras::new(scenario, &streams, o)?,
        None => None,
    };
    if let Some(d) = dump.as_deref_mut() {
        let imus: Vec<ImuSpec> = sensors
            .imus()
            .into_iter()
            .map(|m| ImuSpec {
                topic: m.topic,
                rate_hz: m.rate_hz,
                gyro_sigma_radps: m.gyro_sigma_radps,
                accel_sigma_mps2: m.accel_sigma_mps2,
                body_from_sensor: m.body_from_sensor,
                bias: (m.gyro_bias, m.accel_bias),
            })
            .collect();
        let topics = cameras.as_ref().map(|c| c.topics()).unwrap_or_default();
        d.begin(&topics, &imus);
    }
    let mut comms = Comms::new(scenario.file.comms.clone(), clock, names.clone(), streams);
    let n = stacks.len();
    let total = clock.ticks_in(scenario.duration_secs);
    let truth_period = clock
        .period_ticks(scenario.file.truth_rate_hz)
        .expect("validated truth rate");
    let mut post = Post {
        names: names.clone(),
        inboxes: vec![Vec::new(); n],
        digest: RunDigest::new(),
        recorder,
        counts: BTreeMap::new(),
        received_ns: 0,
    };
    if let Some(r) = post.recorder.as_deref_mut() {
        r.describe(scenario, render.is_some())?;
    }
    // What each stack computed (its commands and radio messages), digested per robot.
    let mut stack_digests: Vec<RunDigest> = (0..n).map(|_| RunDigest::new()).collect();
    let mut truth = truth_buffers(n, total / truth_period + 2);
    let mut keyframes_seen = vec![0usize; n];
    let topics = Topics::of(scenario, &names);
    let oracles = oracles(scenario);
    // Ground truth is kept for every robot at the truth rate, for evaluation, and recorded at
    // every tick (replay's radio needs the positions the live radio saw); a robot receives it
    // only through its oracle.
    let sample_truth =
        |post: &mut Post, truth: &mut Vec<Vec<(u64, Pose)>>, physics: &Physics, tick: u64| {
            let stamp_ns = clock.time_ns(tick);
            post.received_ns = stamp_ns;
            for i in 0..n {
                let oracle = oracles[i].as_ref().filter(|(_, period)| tick % period == 0);
                let kept = tick % truth_period == 0;
                let recorded = post.recorder.is_some();
                if oracle.is_none() && !kept && !recorded {
                    continue;
                }
                let pose = physics.pose(i);
                if let Some(r) = post.recorder.as_deref_mut() {
                    r.truth(&names[i], stamp_ns, &pose);
                }
                if let Some((topic, _)) = oracle {
                    let msg = SensorMsg::TruthPose(PoseStamped { stamp_ns, pose });
                    post.deliver(i, topic, msg, None);
                }
                if kept {
                    truth[i].push((stamp_ns, pose));
                }
            }
        };
    // The initial pose, before the first tick.
    sample_truth(&mut post, &mut truth, &physics, 0);
    // Progress every sim second or every 1 % of the run, whichever comes more often.
    let report_every = clock.ticks_in(1.0).min(total / 100).max(1);
    // A mission that ends before the scenario's duration ends the run two seconds later.
    let mut end = total;
    let linger = clock.ticks_in(2.0);
    let mut ticks = 0;
    for tick in 0..total {
        if tick >= end {
            break;
        }
        ticks = tick + 1;
        let now = clock.time_ns(tick);
        // 1. stacks -> commands (in parallel; collected in robot order)
        let results: Vec<Result<Command, InputError>> = stacks
            .par_iter_mut()
            .zip(post.inboxes.par_iter_mut())
            .map(|(stack, inbox)| {
                let cmd = stack.step(now, inbox);
                inbox.clear();
                cmd
            })
            .collect();
        // A message a stack refused stops the run: the first refusal in robot order.
        let mut commands = Vec::with_capacity(n);
        for (i, r) in results.into_iter().enumerate() {
            commands.push(r.map_err(|error| RunError::Input {
                robot: names[i].clone(),
                error: Box::new(error),
            })?);
        }
        let statuses: Vec<_> = stacks.iter().map(|s| s.status()).collect();
        // Oracle: key frames the stacks made, with the true pose then, for the emulated
        // image matcher (the manifest lists it).
        for (i, stack) in stacks.iter().enumerate() {
            for &stamp in &stack.oracle_keyframes()[keyframes_seen[i]..] {
                let k = truth[i].partition_point(|(t, _)| *t <= stamp);
                if let Some((_, pose)) = k.checked_sub(1).map(|k| truth[i][k]) {
                    sensors.add_keyframe(i, stamp, pose);
                }
            }
            keyframes_seen[i] = stack.oracle_keyframes().len();
        }
        // 2. commands -> actuators; outgoing radio messages -> the radio
        let positions: Vec<[f64; 3]> = (0..n)
            .map(|i| physics.pose(i).translation.vector.into())
            .collect();
        for (i, cmd) in commands.iter().enumerate() {
            let bytes = encode(cmd);
            post.digest.record(&topics.cmd[i], &bytes);
            stack_digests[i].record(&topics.cmd[i], &bytes);
            if let Some(r) = post.recorder.as_deref_mut() {
                r.command(&names[i], now, cmd);
            }
            physics.command(i, cmd);
            for msg in stacks[i].outbox() {
                let bytes = encode(&msg);
                post.digest.record(&topics.radio[i], &bytes);
                stack_digests[i].record(&topics.radio[i], &bytes);
                comms.send(tick, i, msg, &positions);
            }
        }
        // 3. physics
        physics.step();
        // 4. sensors due at the end of this tick
        let after = tick + 1;
        sample_truth(&mut post, &mut truth, &physics, after);
        for sample in sensors.sample(&physics, tick) {
            if let (Some(d), SensorMsg::Imu(m)) = (dump.as_deref_mut(), &sample.msg) {
                d.imu(&sample.topic, m);
            }
            let mount = topics.mounts.get(&sample.topic);
            post.deliver(sample.robot, &sample.topic, sample.msg, mount);
        }
        // Cameras (all due ones in one batch).
        if let Some(cams) = cameras.as_mut() {
            let stamp = clock.time_ns(after);
            // A robot that wants no images now (a child between grabs) gets none rendered;
            // the dump's frames are rendered whatever the stack wants.
            let wanted = |topic: &str| {
                let dumped = dump
                    .as_ref()
                    .is_some_and(|d| d.wants(topic) && d.in_window(stamp));
                if frames_only {
                    return dumped;
                }
                let robot = topic.split('/').next().unwrap_or_default();
                dumped
                    || names
                        .iter()
                        .position(|n| n == robot)
                        .is_none_or(|i| statuses[i].wants_images)
            };
            // Ground-truth depth only for the frames the dump writes.
            let depth = |topic: &str| {
                dump.as_ref()
                    .is_some_and(|d| d.wants(topic) && d.in_window(stamp))
            };
            let mut images = Vec::new();
            for shot in cams.capture(&physics, tick, stamp, &wanted, &depth) {
                if let Some(d) = dump.as_deref_mut() {
                    if d.wants(&shot.topic) && d.in_window(stamp) {
                        d.write(&shot)?;
                    }
                }
                let mount = shot.body_from_optical;
                images.push((shot.robot, shot.topic, SensorMsg::Image(shot.image), mount));
            }
            // Megabytes each: hashed in parallel, then recorded in camera order.
            let hashes: Vec<_> = images
                .par_iter()
                .map(|(_, _, m, _)| hash_encoded(m))
                .collect();
            for ((robot, topic, msg, mount), hash) in images.into_iter().zip(hashes) {
                post.deliver_hashed(robot, &topic, msg, &mount, hash);
            }
        }
        // 5. radio deliveries
        for (to, delivered) in comms.deliver(after) {
            post.deliver(to, &topics.radio[to], SensorMsg::Comms(delivered), None);
        }
        if end == total && statuses.iter().any(|s| s.mission_over) {
            end = (tick + 1 + linger).min(total);
        }
        if tick % report_every == 0 {
            progress(tick, total);
        }
    }
    progress(total, total);
    if let Some(r) = post.recorder.as_deref_mut() {
        let outcomes: Vec<_> = (0..n)
            .map(|i| crate::record::RecordedOutcome {
                name: names[i].clone(),
                distance_m: physics.state(i).distance_m,
                collisions: physics.state(i).collisions,
            })
            .collect();
        r.outcome(ticks, &outcomes)?;
    }
    if let Some(d) = dump.as_deref() {
        let samples: Vec<(&str, &[(u64, Pose)])> = names
            .iter()
            .map(String::as_str)
            .zip(truth.iter().map(Vec::as_slice))
            .collect();
        d.finish(&samples)?;
    }
    let robots = scenario
        .robots
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let state = physics.state(i);
            let t = physics.pose(i).translation.vector;
            RobotOutcome {
                name: r.spec.name.clone(),
                model: r.spec.model.clone(),
                distance_m: state.distance_m,
                collisions: state.collisions,
                status: stacks[i].status(),
                final_position_m: [t.x, t.y, t.z],
                stack_digest: stack_digests[i].hex(),
            }
        })
        .collect();
    Ok(RunOutput {
        ticks,
        sim_secs: clock.time_secs(ticks),
        records: post.digest.records(),
        robots,
        truth: names.iter().cloned().zip(truth).collect(),
        artifacts: names
            .iter()
            .cloned()
            .zip(stacks.iter().map(|s| s.artifacts()))
            .collect(),
        messages: post.counts,
        comms: comms.stats.clone(),
        digest: post.digest,
        adapter: cameras.as_ref().map(|c| c.adapter().clone()),
    })
}

/// One ground-truth buffer per robot, reserved for the whole run (at most a million samples
/// each up front), so that the run's heap grows only by what the robots keep.
pub(crate) fn truth_buffers(robots: usize, samples: u64) -> Vec<Vec<(u64, Pose)>> {
    let reserve = samples.min(1 << 20) as usize;
    (0..robots).map(|_| Vec::with_capacity(reserve)).collect()
}

/// The postcard encoding's length and SHA-256, written straight into the hasher.
pub(crate) fn hash_encoded<T: Serialize>(value: &T) -> (u64, [u8; 32]) {
    struct Hashing(PayloadHasher);
    impl postcard::ser_flavors::Flavor for Hashing {
        type Output = PayloadHasher;
        fn try_push(&mut self, data: u8) -> postcard::Result<()> {
            self.0.write(&[data]);
            Ok(())
        }
        fn try_extend(&mut self, data: &[u8]) -> postcard::Result<()> {
            self.0.write(data);
            Ok(())
        }
        fn finalize(self) -> postcard::Result<PayloadHasher> {
            Ok(self.0)
        }
    }
    postcard::serialize_with_flavor(value, Hashing(PayloadHasher::default()))
        .expect("plain-data messages always encode")
        .finish()
}

pub(crate) fn encode<T: Serialize>(value: &T) -> Vec<u8> {
    postcard::to_stdvec(value).expect("plain-data messages always encode")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hashing_while_encoding_is_hashing_the_encoding() {
        let msg = SensorMsg::Image(hetsim_msgs::Image {
            stamp_ns: 7,
            sensor: "stereo/left".into(),
            width: 3,
            height: 2,
            encoding: hetsim_msgs::PixelEncoding::Rgb8,
            data: (0..18).collect(),
        });
        let mut direct = PayloadHasher::default();
        direct.write(&encode(&msg));
        assert_eq!(hash_encoded(&msg), direct.finish());
    }
}
