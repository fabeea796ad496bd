//! The parts of a tick that a live run ([`crate::run`]) and a replay ([`crate::replay`])
//! share, so that both feed and read the stacks the same way and digest the same bytes in
//! the same order: the stacks stepped, what each sent published (the digests and the radio),
//! messages posted to the robots, when the run ends, and the run's output.

use crate::comms::Comms;
use crate::output::{RobotOutcome, RunOutput};
use crate::sinks::RunRecorder;
use hetsim_core::{PayloadHasher, RunDigest, SimClock};
use hetsim_msgs::{Command, InputError, Pose, RobotStack, SensorMsg, StackStatus};
use hetsim_render::AdapterSummary;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// One robot stack per robot, in scenario order. A live run has every one; a replay may leave
/// a robot out (`None`): its recorded messages then speak for it.
pub(crate) type Stacks = Vec<Option<Box<dyn RobotStack>>>;

/// Per-robot topic names of what the stacks send, made once.
pub(crate) struct StackTopics {
    /// `<robot>/cmd`.
    pub cmd: Vec<String>,
    /// `<robot>/radio`.
    pub radio: Vec<String>,
}

impl StackTopics {
    pub fn of(names: &[String]) -> Self {
        let each = |suffix: &str| names.iter().map(|r| format!("{r}/{suffix}")).collect();
        Self {
            cmd: each("cmd"),
            radio: each("radio"),
        }
    }
}

/// Stage "step the stacks": every stack turns the messages delivered since its last step
/// into a command, in parallel, and its inbox is emptied; the results come back in robot
/// order (`None` where no stack runs).
pub(crate) fn step_stacks(
    stacks: &mut Stacks,
    inboxes: &mut [Vec<SensorMsg>],
    now_ns: u64,
) -> Vec<Option<Result<Command, InputError>>> {
    stacks
        .par_iter_mut()
        .zip(inboxes.par_iter_mut())
        .map(|(stack, inbox)| {
            let cmd = stack.as_mut().map(|s| s.step(now_ns, inbox));
            inbox.clear();
            cmd
        })
        .collect()
}

/// What robot `robot`'s stack computed this tick, published: its command, then each of its
/// radio messages, into the run's digest and the stack's own, and the radio messages into
/// the radio (range judged on `positions`, the robots' positions at the start of the tick).
#[allow(clippy::too_many_arguments)]
pub(crate) fn publish(
    stack: &mut dyn RobotStack,
    robot: usize,
    tick: u64,
    cmd: &Command,
    topics: &StackTopics,
    digests: (&mut RunDigest, &mut RunDigest),
    comms: &mut Comms,
    positions: &[[f64; 3]],
) {
    let (run, own) = digests;
    let bytes = encode(cmd);
    run.record(&topics.cmd[robot], &bytes);
    own.record(&topics.cmd[robot], &bytes);
    for msg in stack.outbox() {
        let bytes = encode(&msg);
        run.record(&topics.radio[robot], &bytes);
        own.record(&topics.radio[robot], &bytes);
        comms.send(tick, robot, msg, positions);
    }
}

/// Where delivered messages go: the robot's inbox, the run digest, the recording (live runs
/// only) and the per-topic counts.
pub(crate) struct Post<'a> {
    pub names: Vec<String>,
    pub inboxes: Vec<Vec<SensorMsg>>,
    pub digest: RunDigest,
    pub recorder: Option<&'a mut dyn RunRecorder>,
    pub counts: BTreeMap<String, u64>,
    /// When the messages being posted reach their robot (the next tick's time).
    pub received_ns: u64,
}

impl<'a> Post<'a> {
    pub fn new(names: Vec<String>, recorder: Option<&'a mut dyn RunRecorder>) -> Self {
        Self {
            inboxes: vec![Vec::new(); names.len()],
            names,
            digest: RunDigest::new(),
            recorder,
            counts: BTreeMap::new(),
            received_ns: 0,
        }
    }

    /// Delivers `msg` to `robot` on `topic`. An image is digested by the hash of its
    /// encoding (megabytes, never copied), anything else by its encoding.
    pub fn deliver(&mut self, robot: usize, topic: &str, msg: SensorMsg, mount: Option<&Pose>) {
        if let SensorMsg::Image(_) = &msg {
            self.digest.record_hashed(topic, hash_encoded(&msg));
        } else {
            self.digest.record(topic, &encode(&msg));
        }
        self.file(robot, topic, msg, mount);
    }

    /// [`Post::deliver`] for an image whose encoding was hashed beforehand (in parallel).
    pub fn deliver_hashed(
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

/// When a run ends: after its last tick, or two seconds of sim time after a stack first says
/// its mission is over, whichever comes first.
pub(crate) struct Ending {
    total: u64,
    end: u64,
    linger: u64,
}

impl Ending {
    pub fn new(clock: SimClock, total: u64) -> Self {
        Self {
            total,
            end: total,
            linger: clock.ticks_in(2.0),
        }
    }

    /// Whether tick `tick` is past the end.
    pub fn reached(&self, tick: u64) -> bool {
        tick >= self.end
    }

    /// Tick `tick` is done; `over`: a stack said its mission is over.
    pub fn after(&mut self, tick: u64, over: bool) {
        if self.end == self.total && over {
            self.end = (tick + 1 + self.linger).min(self.total);
        }
    }
}

/// Ticks between progress reports: every sim second or every 1 % of the run, whichever comes
/// more often.
pub(crate) fn report_every(clock: SimClock, total: u64) -> u64 {
    clock.ticks_in(1.0).min(total / 100).max(1)
}

/// The run's output from what the loop kept.
pub(crate) struct Kept<'a> {
    pub ticks: u64,
    pub post: Post<'a>,
    pub robots: Vec<RobotOutcome>,
    pub truth: Vec<Vec<(u64, Pose)>>,
    pub adapter: Option<AdapterSummary>,
    pub cameras: Vec<(
        String,
        hetsim_sensors::camera::calibration::CameraCalibration,
    )>,
}

/// The run's raw output: what the stacks published at the end, beside what the loop kept.
pub(crate) fn output(clock: SimClock, stacks: &Stacks, comms: &Comms, kept: Kept<'_>) -> RunOutput {
    let Kept {
        ticks,
        post,
        robots,
        truth,
        adapter,
        cameras,
    } = kept;
    RunOutput {
        ticks,
        sim_secs: clock.time_secs(ticks),
        records: post.digest.records(),
        robots,
        truth: post.names.iter().cloned().zip(truth).collect(),
        artifacts: post
            .names
            .iter()
            .cloned()
            .zip(
                stacks
                    .iter()
                    .map(|s| s.as_ref().map(|s| s.artifacts()).unwrap_or_default()),
            )
            .collect(),
        messages: post.counts,
        comms: comms.stats.clone(),
        digest: post.digest,
        adapter,
        cameras,
    }
}

/// A stack's last status, or the default where no stack runs.
pub(crate) fn status_of(stack: &Option<Box<dyn RobotStack>>) -> StackStatus {
    stack.as_ref().map(|s| s.status()).unwrap_or_default()
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

    #[test]
    fn a_mission_over_ends_the_run_two_seconds_later_and_never_after_its_duration() {
        let clock = SimClock::from_dt_secs(0.01).unwrap();
        let mut ending = Ending::new(clock, 1000);
        ending.after(99, false);
        assert!(!ending.reached(999));
        ending.after(100, true);
        // Two seconds of 10 ms ticks after tick 100 is done.
        assert!(!ending.reached(300) && ending.reached(301));
        // A later "over" does not move the end.
        ending.after(200, true);
        assert!(ending.reached(301));
        let mut late = Ending::new(clock, 1000);
        late.after(950, true);
        assert!(!late.reached(999) && late.reached(1000));
    }
}
