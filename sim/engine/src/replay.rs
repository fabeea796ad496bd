//! Replaying a recording into the robot software (`hetsim replay`): no physics, no rendering.
//!
//! The recording's messages are fed tick by tick in the order the live run delivered them: a
//! message the live run delivered at the end of tick `t - 1` (its MCAP log time is `t`'s
//! time) is in the inbox of tick `t`, in file order. The robot's oracle, where its robot file
//! declares one, is derived from the recorded ground truth at the oracle's rate, as the live
//! run derived it from the physics. Radio messages between replayed robots are not taken from
//! the recording: each stack's outgoing messages go through the same radio model (same seeded
//! streams, range judged on the recorded true positions), so a changed parameter changes what
//! the other robot receives. A robot that is not replayed (`--robot`) still speaks: its
//! recorded deliveries reach the replayed robots as recorded.
//!
//! Every command a replayed stack sends is compared with the recorded one; the first
//! difference stops the replay with its stamp, robot and topic (a regression check for robot
//! software, and a proof that a closed-loop mission saw what it saw live). Everything the
//! stacks receive and send goes into the run digest in the live run's order, so the replay of
//! an unchanged run has the live run's message digest and stack digests.

use crate::comms::Comms;
use crate::output::{RobotOutcome, RunOutput};
use crate::run::oracles;
use crate::sinks::RecordedOutcome;
use crate::stages::{
    self, publish, report_every, step_stacks, truth_buffers, Ending, Kept, Post, StackTopics,
    Stacks,
};
use hetsim_core::{RunDigest, Streams};
use hetsim_msgs::{Command, InputError, Pose, PoseStamped, RobotStack, SensorMsg};
use hetsim_scene::{Scenario, Sensor};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The run a recording holds, as its `hetsim.run` metadata describes it.
#[derive(Clone, Debug, PartialEq)]
pub struct RunDescription {
    /// The scenario file's path when it was recorded.
    pub scenario_path: PathBuf,
    /// The scenario file's text.
    pub scenario_text: String,
    /// The seed in force.
    pub seed: u64,
    /// The duration in force, seconds.
    pub duration_secs: f64,
    /// Every robot file's text, by model.
    pub robot_files: BTreeMap<String, String>,
    /// The tick, nanoseconds.
    pub dt_ns: u64,
    /// Whether the SLAM stacks ran open loop (`--open-loop`).
    pub open_loop: bool,
    /// Whether the live run rendered its cameras (then the evaluation, which may render
    /// what it needs, such as the coverage mission's localization paths, renders again).
    pub rendered: bool,
    /// The camera profile the live run had (`None` in a recording from before profiles:
    /// the scenario's).
    pub camera_profile: Option<hetsim_scene::CameraProfile>,
}

/// Something recorded.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A robot's true pose.
    Truth {
        /// The robot.
        robot: String,
        /// When, nanoseconds.
        stamp_ns: u64,
        /// `world_from_body`.
        pose: Pose,
    },
    /// A robot's command.
    Command {
        /// The robot.
        robot: String,
        /// When, nanoseconds.
        stamp_ns: u64,
        /// What it sent.
        cmd: Command,
    },
    /// A message a robot received.
    Sensor {
        /// The robot.
        robot: String,
        /// `<robot>/<sensor>`.
        topic: String,
        /// The message.
        msg: SensorMsg,
    },
}

impl Event {
    /// When it was measured or sent, nanoseconds.
    pub fn stamp_ns(&self) -> u64 {
        match self {
            Event::Truth { stamp_ns, .. } | Event::Command { stamp_ns, .. } => *stamp_ns,
            Event::Sensor { msg, .. } => msg.stamp_ns(),
        }
    }
}

/// A recorded event and when it reached the robot (MCAP log time).
#[derive(Clone, Debug, PartialEq)]
pub struct Logged {
    /// Delivery time, nanoseconds.
    pub log_ns: u64,
    /// What.
    pub event: Event,
}

/// A source of recorded events in delivery order.
pub trait Recording {
    /// The next event, `None` at the end.
    fn next_logged(&mut self) -> Result<Option<Logged>, ReplayError>;
    /// What the physics measured per robot, if the recording says.
    fn outcome(&self) -> Option<&[RecordedOutcome]>;
    /// The ticks the recorded run ran, if the recording says: the replay runs no more.
    fn ticks(&self) -> Option<u64> {
        None
    }
    /// Whether the recording holds every command the robots sent (a hetsim recording does,
    /// a dataset does not): then a replayed stack's command with no recorded one diverges.
    fn has_commands(&self) -> bool {
        false
    }
    /// Whether the recorded run rendered its cameras: then the replay reports the same
    /// calibrations (drawn again from the same streams) as the live run did.
    fn rendered(&self) -> bool {
        false
    }
}

/// Why a replay stopped.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// A file could not be read.
    #[error("{}: {reason}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What failed.
        reason: String,
    },
    /// A recording is damaged or is not one hetsim reads.
    #[error("{}: at byte {offset}: {what}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// Byte offset of the record at fault (of its chunk, for a message in a chunk).
        offset: u64,
        /// What is wrong.
        what: String,
    },
    /// A dataset file has a bad row, or a file it lists is missing or unreadable.
    #[error("{}: row {row}: {what}", path.display())]
    Row {
        /// The file.
        path: PathBuf,
        /// 1-based row (the header is row 1).
        row: usize,
        /// What is wrong.
        what: String,
    },
    /// The recording and the scenario replayed into do not fit each other.
    #[error("{0}")]
    Mismatch(String),
    /// A replayed stack sent a command other than the recorded one.
    #[error(
        "replay diverged at t = {:.3} s: robot {robot} sent {replayed} on /{robot}/cmd, the recording has {recorded}",
        *stamp_ns as f64 * 1e-9
    )]
    Diverged {
        /// The robot.
        robot: String,
        /// When, nanoseconds.
        stamp_ns: u64,
        /// The recorded command.
        recorded: String,
        /// The replayed one.
        replayed: String,
    },
    /// A robot's software refused a recorded message.
    #[error("robot {robot} refused a message: {error}")]
    Input {
        /// The robot.
        robot: String,
        /// What it refused.
        error: Box<InputError>,
    },
}

impl ReplayError {
    /// A file that could not be opened or read.
    pub fn file(path: &Path, e: impl std::fmt::Display) -> Self {
        ReplayError::File {
            path: path.to_path_buf(),
            reason: e.to_string(),
        }
    }
}

/// Replays `recording` into `stacks` (scenario order; `None`: that robot is not replayed)
/// until the scenario's duration or the tick the recorded run ended at (or two seconds
/// after a replayed stack's mission is over, as a live run ends). `progress(tick, total)` as
/// in [`crate::run`].
pub fn replay(
    scenario: &Scenario,
    stacks: Vec<Option<Box<dyn RobotStack>>>,
    recording: &mut dyn Recording,
    progress: impl FnMut(u64, u64) + Send,
) -> Result<RunOutput, ReplayError> {
    replay_withholding_truth(scenario, stacks, recording, false, progress)
}

/// [`replay`], with every oracle message withheld from the stacks when `withhold_truth`:
/// commands are then not compared (a pilot that steers by the oracle stands still), and what
/// the estimators compute must not change, for they read no truth.
pub fn replay_withholding_truth(
    scenario: &Scenario,
    stacks: Stacks,
    recording: &mut dyn Recording,
    withhold_truth: bool,
    mut progress: impl FnMut(u64, u64) + Send,
) -> Result<RunOutput, ReplayError> {
    let n = scenario.robots.len();
    if stacks.len() != n {
        return Err(ReplayError::Mismatch(format!(
            "{} robot stacks for {n} robots",
            stacks.len()
        )));
    }
    let clock = scenario.clock;
    let mut replayed = Replayed::new(scenario, stacks);
    let mut feed = Feed::start(
        scenario,
        recording,
        withhold_truth,
        &replayed.active,
        &replayed.names,
    )?;
    // No further than the recorded run went (a mission that ended early ended it).
    let total = clock
        .ticks_in(scenario.duration_secs)
        .min(feed.recording.ticks().unwrap_or(u64::MAX));
    let checked = feed.recording.has_commands() && !withhold_truth;
    let report_every = report_every(clock, total);
    let mut ending = Ending::new(clock, total);
    let mut ticks = 0;
    for tick in 0..total {
        if ending.reached(tick) {
            break;
        }
        let now = clock.time_ns(tick);
        // 1. Everything delivered for this tick, in the live order.
        feed.drain(tick)?;
        ticks = tick + 1;
        // 2. The stacks, in parallel; the first refusal in robot order stops the replay.
        let over = replayed.step_stacks(&mut feed, tick, now, checked)?;
        // 3. Radio deliveries at the end of this tick, fed at the next.
        replayed.deliver_radio(&mut feed.radio, tick);
        ending.after(tick, over);
        if tick % report_every == 0 {
            progress(tick, total);
        }
    }
    progress(total, total);
    // What the live run delivered at the end of its last tick: digested and counted, as there.
    feed.drain(ticks)?;
    let Feed {
        recording,
        post,
        truth,
        last_pose,
        ..
    } = feed;
    let outcome = recording.outcome();
    let robots = replayed.outcomes(scenario, outcome, &last_pose);
    let cameras = if recording.rendered() {
        crate::cameras::calibrations(scenario, &Streams::new(scenario.seed))
    } else {
        Vec::new()
    };
    Ok(stages::output(
        clock,
        &replayed.stacks,
        &replayed.comms,
        Kept {
            ticks,
            post,
            robots,
            truth,
            adapter: None,
            cameras,
        },
    ))
}

/// The replayed robots' side of a replay: their stacks (`None`: not replayed), what the
/// stacks send (topics, per-stack digests) and the radio that carries it.
struct Replayed {
    names: Vec<String>,
    /// Which robots have a stack.
    active: Vec<bool>,
    stacks: Stacks,
    comms: Comms,
    topics: StackTopics,
    /// What each stack computed (its commands and radio messages), digested per robot.
    stack_digests: Vec<RunDigest>,
}

impl Replayed {
    /// The robots of `scenario` with their `stacks`, each stack's digest empty, and the radio
    /// (the scenario's comms settings, on its seeded streams).
    fn new(scenario: &Scenario, stacks: Stacks) -> Self {
        let n = scenario.robots.len();
        let clock = scenario.clock;
        let names: Vec<String> = scenario
            .robots
            .iter()
            .map(|r| r.spec.name.clone())
            .collect();
        let active: Vec<bool> = stacks.iter().map(Option::is_some).collect();
        let comms = Comms::new(
            scenario.file.comms.clone(),
            clock,
            names.clone(),
            Streams::new(scenario.seed),
        );
        let topics = StackTopics::of(&names);
        let stack_digests: Vec<RunDigest> = (0..n).map(|_| RunDigest::new()).collect();
        Self {
            names,
            active,
            stacks,
            comms,
            topics,
            stack_digests,
        }
    }

    /// Stage "step the stacks": every stack steps on its inbox (in parallel); each command,
    /// compared with the recorded one when `checked`, is published as the live run publishes
    /// it. Returns whether a stack said its mission is over; the first refusal in robot
    /// order, or the first command unlike the recorded one, stops the replay.
    fn step_stacks(
        &mut self,
        feed: &mut Feed<'_>,
        tick: u64,
        now: u64,
        checked: bool,
    ) -> Result<bool, ReplayError> {
        let results = step_stacks(&mut self.stacks, &mut feed.post.inboxes, now);
        let mut over = false;
        for (i, result) in results.into_iter().enumerate() {
            let Some(result) = result else {
                continue;
            };
            let cmd = result.map_err(|error| ReplayError::Input {
                robot: self.names[i].clone(),
                error: Box::new(error),
            })?;
            let recorded = feed.recorded_cmd[i].take();
            if checked && recorded.as_ref() != Some(&cmd) {
                return Err(ReplayError::Diverged {
                    robot: self.names[i].clone(),
                    stamp_ns: now,
                    recorded: recorded.map_or("no command".into(), |r| format!("{r:?}")),
                    replayed: format!("{cmd:?}"),
                });
            }
            let stack = self.stacks[i]
                .as_deref_mut()
                .expect("an active robot has a stack");
            // The status right after the step, before the outbox is read, as the live run.
            over |= stack.status().mission_over;
            publish(
                stack,
                i,
                tick,
                &cmd,
                &self.topics,
                (&mut feed.post.digest, &mut self.stack_digests[i]),
                &mut self.comms,
                &feed.position,
            );
        }
        Ok(over)
    }

    /// Stage "deliver": the radio messages that arrive at the end of tick `tick` for a
    /// replayed robot, into `radio` (fed at the next tick).
    fn deliver_radio(&mut self, radio: &mut Vec<(usize, SensorMsg)>, tick: u64) {
        for (to, delivered) in self.comms.deliver(tick + 1) {
            if self.active[to] {
                radio.push((to, SensorMsg::Comms(delivered)));
            }
        }
    }

    /// Each robot's outcome: what the recording says the physics measured (`outcome`), its
    /// stack's last status, its last recorded position (`last_pose`) and its stack's digest
    /// (empty for a robot not replayed).
    fn outcomes(
        &self,
        scenario: &Scenario,
        outcome: Option<&[RecordedOutcome]>,
        last_pose: &[Option<Pose>],
    ) -> Vec<RobotOutcome> {
        scenario
            .robots
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let measured = outcome.and_then(|o| o.iter().find(|m| m.name == r.spec.name));
                RobotOutcome {
                    name: r.spec.name.clone(),
                    model: r.spec.model.clone(),
                    distance_m: measured.map_or(0.0, |m| m.distance_m),
                    collisions: measured.map_or(0, |m| m.collisions),
                    status: stages::status_of(&self.stacks[i]),
                    final_position_m: last_pose[i]
                        .map_or([0.0; 3], |p| p.translation.vector.into()),
                    stack_digest: if self.active[i] {
                        self.stack_digests[i].hex()
                    } else {
                        String::new()
                    },
                }
            })
            .collect()
    }
}

/// The recording's events turned into the robots' inboxes, tick by tick.
struct Feed<'a> {
    scenario: &'a Scenario,
    recording: &'a mut dyn Recording,
    /// The next event, read ahead.
    next: Option<Logged>,
    oracles: Vec<Option<(String, u64)>>,
    lasers: BTreeMap<String, (f64, f64, f64)>,
    truth_period: u64,
    active: Vec<bool>,
    /// The stacks' inboxes, the digest and the counts (no recorder).
    post: Post<'static>,
    /// Truth at the truth rate, for evaluation.
    truth: Vec<Vec<(u64, Pose)>>,
    /// Where each robot is now (the radio's range).
    position: Vec<[f64; 3]>,
    last_pose: Vec<Option<Pose>>,
    /// Radio deliveries for the next tick, in arrival order: (robot, message).
    radio: Vec<(usize, SensorMsg)>,
    /// The recorded command of this tick, per robot.
    recorded_cmd: Vec<Option<Command>>,
}

impl<'a> Feed<'a> {
    /// The feed before the first tick: the recording's first event read ahead, the oracles
    /// (none when `withhold_truth`), the lasers' exact angles, empty inboxes and buffers.
    fn start(
        scenario: &'a Scenario,
        recording: &'a mut dyn Recording,
        withhold_truth: bool,
        active: &[bool],
        names: &[String],
    ) -> Result<Self, ReplayError> {
        let n = scenario.robots.len();
        let clock = scenario.clock;
        let truth_period = clock
            .period_ticks(scenario.file.truth_rate_hz)
            .expect("validated truth rate");
        let next = recording.next_logged()?;
        Ok(Feed {
            scenario,
            recording,
            next,
            oracles: if withhold_truth {
                vec![None; n]
            } else {
                oracles(scenario)
            },
            lasers: laser_angles(scenario),
            truth_period,
            active: active.to_vec(),
            post: Post::new(names.to_vec(), None),
            truth: truth_buffers(n, clock.ticks_in(scenario.duration_secs) / truth_period + 2),
            position: vec![[0.0; 3]; n],
            last_pose: vec![None; n],
            radio: Vec::new(),
            recorded_cmd: vec![None; n],
        })
    }

    fn robot_of(&self, name: &str) -> Result<usize, ReplayError> {
        self.scenario
            .robots
            .iter()
            .position(|r| r.spec.name == name)
            .ok_or_else(|| {
                let names: Vec<&str> =
                    self.scenario.robots.iter().map(|r| r.spec.name.as_str()).collect();
                ReplayError::Mismatch(format!(
                    "the recording has messages of robot \"{name}\", which the scenario does not have (robots: {})",
                    names.join(", ")
                ))
            })
    }

    /// Posts everything delivered for `tick` (logged at or before its time), in the live
    /// order: the recording's messages in file order, then the radio model's deliveries.
    fn drain(&mut self, tick: u64) -> Result<(), ReplayError> {
        let clock = self.scenario.clock;
        let now = clock.time_ns(tick);
        while let Some(logged) = self.next.take_if(|l| l.log_ns <= now) {
            self.next = self.recording.next_logged()?;
            match logged.event {
                Event::Truth {
                    robot,
                    stamp_ns,
                    pose,
                } => {
                    let i = self.robot_of(&robot)?;
                    self.position[i] = pose.translation.vector.into();
                    self.last_pose[i] = Some(pose);
                    if stamp_ns % (self.truth_period * clock.dt_ns()) == 0 {
                        self.truth[i].push((stamp_ns, pose));
                    }
                    let due = self.oracles[i]
                        .as_ref()
                        .filter(|(_, p)| now == stamp_ns && tick % p == 0);
                    if let (true, Some((topic, _))) = (self.active[i], due) {
                        let msg = SensorMsg::TruthPose(PoseStamped { stamp_ns, pose });
                        let topic = topic.clone();
                        self.post(i, &topic, msg);
                    }
                }
                Event::Command { robot, cmd, .. } => {
                    let i = self.robot_of(&robot)?;
                    self.recorded_cmd[i] = Some(cmd);
                }
                Event::Sensor { robot, topic, msg } => {
                    let i = self.robot_of(&robot)?;
                    if !self.active[i] {
                        continue;
                    }
                    let msg = match msg {
                        SensorMsg::Comms(d) => {
                            // Deliveries from replayed robots come from the radio model.
                            if self.robot_of(&d.from).is_ok_and(|f| self.active[f]) {
                                continue;
                            }
                            SensorMsg::Comms(d)
                        }
                        SensorMsg::LaserScan(s) => exact_laser(&self.lasers, &topic, s)?,
                        other => other,
                    };
                    self.post(i, &topic, msg);
                }
            }
        }
        for (i, msg) in std::mem::take(&mut self.radio) {
            let topic = format!("{}/radio", self.scenario.robots[i].spec.name);
            self.post(i, &topic, msg);
        }
        Ok(())
    }

    /// A message into an inbox, the digest and the counts, as the live run posts it.
    fn post(&mut self, robot: usize, topic: &str, msg: SensorMsg) {
        self.post.deliver(robot, topic, msg, None);
    }
}

/// Each laser's exact angles and range (`<robot>/<laser>` -> (first angle, increment,
/// range)), as the sensor computes them from the robot file.
fn laser_angles(scenario: &Scenario) -> BTreeMap<String, (f64, f64, f64)> {
    let mut out = BTreeMap::new();
    for r in &scenario.robots {
        for s in &r.model.sensors {
            if let Sensor::Laser {
                name,
                fov_deg,
                resolution_deg,
                max_range_m,
                ..
            } = s
            {
                out.insert(
                    format!("{}/{name}", r.spec.name),
                    (
                        -fov_deg.to_radians() / 2.0,
                        resolution_deg.to_radians(),
                        *max_range_m,
                    ),
                );
            }
        }
    }
    out
}

/// A recorded scan with the robot file's exact angles (`sensor_msgs/LaserScan` keeps them as
/// `float32`), refused if they are not the same angles.
fn exact_laser(
    lasers: &BTreeMap<String, (f64, f64, f64)>,
    topic: &str,
    mut scan: hetsim_msgs::LaserScan,
) -> Result<SensorMsg, ReplayError> {
    let Some(&(min, step, range)) = lasers.get(topic) else {
        return Err(ReplayError::Mismatch(format!(
            "the recording has laser scans on /{topic}, a laser the scenario's robot file does not declare"
        )));
    };
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 * b.abs().max(1.0);
    if !(close(scan.angle_min_rad, min)
        && close(scan.angle_increment_rad, step)
        && close(scan.range_max_m, range))
    {
        return Err(ReplayError::Mismatch(format!(
            "/{topic}: the recorded scan's angles and range ({}, {}, {}) are not the robot file's ({min}, {step}, {range})",
            scan.angle_min_rad, scan.angle_increment_rad, scan.range_max_m
        )));
    }
    (
        scan.angle_min_rad,
        scan.angle_increment_rad,
        scan.range_max_m,
    ) = (min, step, range);
    Ok(SensorMsg::LaserScan(scan))
}
