//! Running a scenario tick by tick: a [`LiveRun`] stepped through its named stages.

use crate::cameras::Cameras;
use crate::comms::Comms;
use crate::output::{RobotOutcome, RunOutput};
use crate::sinks::{FrameSink, ImuSpec, RecordedOutcome, RunRecorder, SinkError};
use crate::stages::{
    self, hash_encoded, publish, report_every, step_stacks, truth_buffers, Ending, Kept, Post,
    StackTopics, Stacks,
};
use hetsim_core::{RunDigest, SimClock, Streams};
use hetsim_msgs::{
    pose_from_xyz_rpy, Command, InputError, Pose, PoseStamped, RobotStack, SensorMsg, StackStatus,
};
use hetsim_physics::Physics;
use hetsim_render::{RenderError, RenderOptions};
use hetsim_scene::Scenario;
use hetsim_sensors::SensorSuite;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Runs a scenario to its duration with one robot stack per robot (scenario order).
/// `progress(tick, total)` is called every sim second or every 1 % of the run, whichever
/// comes more often. With a recorder, every command, message and ground-truth pose also goes
/// to it; with a frame dump, the frames it wants.
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
    let stacks = stacks.into_iter().map(Some).collect();
    rayon::scope(|_| run_on_worker(scenario, stacks, progress, options))
}

/// What a run does besides simulating.
#[derive(Default)]
pub struct RunOptions<'a> {
    /// Record every message, command and ground-truth pose.
    pub recorder: Option<&'a mut dyn RunRecorder>,
    /// Render the robots' cameras on this adapter choice; `None`: no cameras.
    pub render: Option<RenderOptions>,
    /// Write camera frames.
    pub dump: Option<&'a mut dyn FrameSink>,
    /// Render only the frames the dump wants (for `hetsim frames`).
    pub frames_only: bool,
}

/// Why a run stopped.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// No renderer.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// Frames could not be written (the cause is the error's source, which `{:#}` prints).
    #[error("writing frames")]
    Frames(#[source] SinkError),
    /// The recording could not be written (the cause is the error's source).
    #[error("recording")]
    Record(#[source] SinkError),
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

fn run_on_worker(
    scenario: &Scenario,
    stacks: Stacks,
    mut progress: impl FnMut(u64, u64),
    options: RunOptions<'_>,
) -> Result<RunOutput, RunError> {
    let mut run = LiveRun::start(scenario, stacks, options)?;
    let total = run.total;
    let report_every = report_every(run.clock, total);
    let mut ending = Ending::new(run.clock, total);
    let mut ticks = 0;
    for tick in 0..total {
        if ending.reached(tick) {
            break;
        }
        ticks = tick + 1;
        let (commands, statuses) = run.step_stacks(tick)?;
        run.actuate(tick, &commands);
        run.physics.step();
        run.sense(tick);
        run.capture(tick, &statuses)?;
        run.deliver_radio(tick);
        ending.after(tick, statuses.iter().any(|s| s.mission_over));
        if tick % report_every == 0 {
            progress(tick, total);
        }
    }
    progress(total, total);
    run.finish(ticks)
}

/// Everything a live run holds between ticks. One tick is its stages in order:
/// [`LiveRun::step_stacks`], [`LiveRun::actuate`], the physics' step, [`LiveRun::sense`],
/// [`LiveRun::capture`], [`LiveRun::deliver_radio`].
struct LiveRun<'s, 'o> {
    scenario: &'s Scenario,
    clock: SimClock,
    /// Ticks in the scenario's duration.
    total: u64,
    names: Vec<String>,
    stacks: Stacks,
    physics: Physics,
    sensors: SensorSuite,
    cameras: Option<Cameras>,
    dump: Option<&'o mut dyn FrameSink>,
    frames_only: bool,
    comms: Comms,
    post: Post<'o>,
    topics: StackTopics,
    /// `robot/sensor` -> `body_from_sensor`.
    mounts: BTreeMap<String, Pose>,
    /// What each stack computed (its commands and radio messages), digested per robot.
    stack_digests: Vec<RunDigest>,
    /// Each robot's enabled oracle, if its robot file declares one: (topic, period in ticks).
    oracles: Vec<Option<(String, u64)>>,
    truth_period: u64,
    /// Ground truth at the truth rate, for evaluation.
    truth: Vec<Vec<(u64, Pose)>>,
    /// How many of each stack's oracle key frames the emulated image matcher has.
    keyframes_seen: Vec<usize>,
}

impl<'s, 'o> LiveRun<'s, 'o> {
    /// The world, the sensors, the cameras and the radio of `scenario` at tick 0, the sinks
    /// told what the run is, and the initial poses sampled.
    fn start(
        scenario: &'s Scenario,
        stacks: Stacks,
        options: RunOptions<'o>,
    ) -> Result<Self, RunError> {
        let RunOptions {
            recorder,
            render,
            mut dump,
            frames_only,
        } = options;
        let clock = scenario.clock;
        let streams = Streams::new(scenario.seed);
        let physics = Physics::for_scenario(scenario, &streams);
        let names: Vec<String> = scenario
            .robots
            .iter()
            .map(|r| r.spec.name.clone())
            .collect();
        let sensors = SensorSuite::new(scenario, &streams);
        let cameras = match &render {
            Some(o) => Cameras::new(scenario, &streams, o)?,
            None => None,
        };
        if let Some(d) = dump.as_deref_mut() {
            let topics = cameras.as_ref().map(|c| c.topics()).unwrap_or_default();
            d.begin(&topics, &imu_specs(&sensors));
        }
        let comms = Comms::new(scenario.file.comms.clone(), clock, names.clone(), streams);
        let n = stacks.len();
        let total = clock.ticks_in(scenario.duration_secs);
        let truth_period = clock
            .period_ticks(scenario.file.truth_rate_hz)
            .expect("validated truth rate");
        let mut post = Post::new(names.clone(), recorder);
        if let Some(r) = post.recorder.as_deref_mut() {
            r.describe(scenario, render.is_some())
                .map_err(RunError::Record)?;
        }
        let mut run = LiveRun {
            scenario,
            clock,
            total,
            topics: StackTopics::of(&names),
            mounts: mounts(scenario),
            names,
            stacks,
            physics,
            sensors,
            cameras,
            dump,
            frames_only,
            comms,
            post,
            stack_digests: (0..n).map(|_| RunDigest::new()).collect(),
            oracles: oracles(scenario),
            truth_period,
            truth: truth_buffers(n, total / truth_period + 2),
            keyframes_seen: vec![0; n],
        };
        // The initial pose, before the first tick.
        run.sample_truth(0);
        Ok(run)
    }

    /// Stage "step the stacks": every stack turns the messages received since its last
    /// step into a command (in parallel; collected in robot order); a message a stack refused
    /// stops the run (the first refusal in robot order). Returns the commands and the
    /// stacks' statuses right after the step; hands the emulated image matcher (an oracle)
    /// the key frames the stacks made, with the true pose then.
    fn step_stacks(&mut self, tick: u64) -> Result<(Vec<Command>, Vec<StackStatus>), RunError> {
        let now = self.clock.time_ns(tick);
        let results = step_stacks(&mut self.stacks, &mut self.post.inboxes, now);
        let mut commands = Vec::with_capacity(results.len());
        for (i, r) in results.into_iter().enumerate() {
            let r = r.expect("a live run has every robot's stack");
            commands.push(r.map_err(|error| RunError::Input {
                robot: self.names[i].clone(),
                error: Box::new(error),
            })?);
        }
        let statuses: Vec<StackStatus> = self.stacks.iter().map(stages::status_of).collect();
        for (i, stack) in self.stacks.iter().enumerate() {
            let stack = stack.as_ref().expect("a live run has every robot's stack");
            let truth = &self.truth[i];
            for &stamp in &stack.oracle_keyframes()[self.keyframes_seen[i]..] {
                let k = truth.partition_point(|(t, _)| *t <= stamp);
                if let Some((_, pose)) = k.checked_sub(1).map(|k| truth[k]) {
                    self.sensors.add_keyframe(i, stamp, pose);
                }
            }
            self.keyframes_seen[i] = stack.oracle_keyframes().len();
        }
        Ok((commands, statuses))
    }

    /// Stage "actuate": each command and the stack's radio messages into the digests, the
    /// radio messages into the radio (range judged where the robots stand now), the command
    /// into the recording and to the robot's drive.
    fn actuate(&mut self, tick: u64, commands: &[Command]) {
        let now = self.clock.time_ns(tick);
        let n = self.names.len();
        let positions: Vec<[f64; 3]> = (0..n)
            .map(|i| self.physics.pose(i).translation.vector.into())
            .collect();
        for (i, cmd) in commands.iter().enumerate() {
            let stack = self.stacks[i]
                .as_deref_mut()
                .expect("a live run has every robot's stack");
            publish(
                stack,
                i,
                tick,
                cmd,
                &self.topics,
                (&mut self.post.digest, &mut self.stack_digests[i]),
                &mut self.comms,
                &positions,
            );
            if let Some(r) = self.post.recorder.as_deref_mut() {
                r.command(&self.names[i], now, cmd);
            }
            self.physics.command(i, cmd);
        }
    }

    /// Stage "sense": the true poses at the end of tick `tick` (kept, recorded, and to the
    /// oracles due), then every non-visual sensor due, each message queued for its robot's
    /// next step.
    fn sense(&mut self, tick: u64) {
        self.sample_truth(tick + 1);
        for sample in self.sensors.sample(&self.physics, tick) {
            if let (Some(d), SensorMsg::Imu(m)) = (self.dump.as_deref_mut(), &sample.msg) {
                d.imu(&sample.topic, m);
            }
            let mount = self.mounts.get(&sample.topic);
            self.post
                .deliver(sample.robot, &sample.topic, sample.msg, mount);
        }
    }

    /// Ground truth at tick `tick`: kept for every robot at the truth rate, for evaluation,
    /// and recorded at every tick (replay's radio needs the positions the live radio saw); a
    /// robot receives it only through its oracle.
    fn sample_truth(&mut self, tick: u64) {
        let stamp_ns = self.clock.time_ns(tick);
        self.post.received_ns = stamp_ns;
        for i in 0..self.names.len() {
            let oracle = self.oracles[i]
                .as_ref()
                .filter(|(_, period)| tick % period == 0);
            let kept = tick % self.truth_period == 0;
            let recorded = self.post.recorder.is_some();
            if oracle.is_none() && !kept && !recorded {
                continue;
            }
            let pose = self.physics.pose(i);
            if let Some(r) = self.post.recorder.as_deref_mut() {
                r.truth(&self.names[i], stamp_ns, &pose);
            }
            if let Some((topic, _)) = oracle {
                let msg = SensorMsg::TruthPose(PoseStamped { stamp_ns, pose });
                self.post.deliver(i, topic, msg, None);
            }
            if kept {
                self.truth[i].push((stamp_ns, pose));
            }
        }
    }

    /// Stage "capture": every camera due at the end of tick `tick`, in one render batch,
    /// for the robots that want images now (a child between grabs gets none) and the frames
    /// the dump wants; the dump's frames written; the images hashed in parallel and queued
    /// in camera order.
    fn capture(&mut self, tick: u64, statuses: &[StackStatus]) -> Result<(), RunError> {
        let Some(cams) = self.cameras.as_mut() else {
            return Ok(());
        };
        let stamp = self.clock.time_ns(tick + 1);
        let (dump, names, frames_only) = (&self.dump, &self.names, self.frames_only);
        let dumped = |topic: &str| dump.as_ref().is_some_and(|d| d.wants_frame(topic, stamp));
        let wanted = |topic: &str| {
            if frames_only {
                return dumped(topic);
            }
            let robot = topic.split('/').next().unwrap_or_default();
            dumped(topic)
                || names
                    .iter()
                    .position(|n| n == robot)
                    .is_none_or(|i| statuses[i].wants_images)
        };
        // Ground-truth depth only for the frames the dump writes.
        let shots = cams.capture(&self.physics, tick, stamp, &wanted, &dumped);
        let mut images = Vec::with_capacity(shots.len());
        for shot in shots {
            if let Some(d) = self.dump.as_deref_mut() {
                if d.wants_frame(&shot.topic, stamp) {
                    d.write(&shot).map_err(RunError::Frames)?;
                }
            }
            let mount = shot.body_from_optical;
            images.push((shot.robot, shot.topic, SensorMsg::Image(shot.image), mount));
        }
        // Megabytes each: hashed in parallel, then queued in camera order.
        let hashes: Vec<_> = images
            .par_iter()
            .map(|(_, _, m, _)| hash_encoded(m))
            .collect();
        for ((robot, topic, msg, mount), hash) in images.into_iter().zip(hashes) {
            self.post.deliver_hashed(robot, &topic, msg, &mount, hash);
        }
        Ok(())
    }

    /// Stage "deliver": the radio messages that arrive at the end of tick `tick`.
    fn deliver_radio(&mut self, tick: u64) {
        for (to, delivered) in self.comms.deliver(tick + 1) {
            let topic = &self.topics.radio[to];
            self.post
                .deliver(to, topic, SensorMsg::Comms(delivered), None);
        }
    }

    /// After the last tick: the sinks finished, what the physics measured of each robot, and
    /// the run's raw output.
    fn finish(mut self, ticks: u64) -> Result<RunOutput, RunError> {
        let n = self.names.len();
        if let Some(r) = self.post.recorder.as_deref_mut() {
            let outcomes: Vec<_> = (0..n)
                .map(|i| RecordedOutcome {
                    name: self.names[i].clone(),
                    distance_m: self.physics.state(i).distance_m,
                    collisions: self.physics.state(i).collisions,
                })
                .collect();
            r.outcome(ticks, &outcomes).map_err(RunError::Record)?;
        }
        if let Some(d) = self.dump.as_deref() {
            let samples: Vec<(&str, &[(u64, Pose)])> = self
                .names
                .iter()
                .map(String::as_str)
                .zip(self.truth.iter().map(Vec::as_slice))
                .collect();
            d.finish(&samples).map_err(RunError::Frames)?;
        }
        let robots = self
            .scenario
            .robots
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let state = self.physics.state(i);
                let t = self.physics.pose(i).translation.vector;
                RobotOutcome {
                    name: r.spec.name.clone(),
                    model: r.spec.model.clone(),
                    distance_m: state.distance_m,
                    collisions: state.collisions,
                    status: stages::status_of(&self.stacks[i]),
                    final_position_m: [t.x, t.y, t.z],
                    stack_digest: self.stack_digests[i].hex(),
                }
            })
            .collect();
        let adapter = self.cameras.as_ref().map(|c| c.adapter().clone());
        let cameras = self
            .cameras
            .as_ref()
            .map(|c| c.calibrations())
            .unwrap_or_default();
        Ok(stages::output(
            self.clock,
            &self.stacks,
            &self.comms,
            Kept {
                ticks,
                post: self.post,
                robots,
                truth: self.truth,
                adapter,
                cameras,
            },
        ))
    }
}

/// The IMUs of the run, as a frame dump describes them.
fn imu_specs(sensors: &SensorSuite) -> Vec<ImuSpec> {
    sensors
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
        .collect()
}

/// `robot/sensor` -> `body_from_sensor`, for every sensor of every robot.
fn mounts(scenario: &Scenario) -> BTreeMap<String, Pose> {
    scenario
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
        .collect()
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
