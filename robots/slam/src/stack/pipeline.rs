//! The SLAM stack as the engine steps it: the pilot every tick, the SLAM core a frame behind.
//!
//! A stereo pair costs tens of milliseconds of vision and filtering; the ticks between two
//! pairs cost almost nothing. So the core runs on a worker thread of its own: at each pair,
//! the events since the last pair (the new pair last) go to the worker as a batch, and the
//! simulator goes on stepping physics and rendering the next images on the other core. The
//! worker may fall up to `DEPTH` batches behind before the simulator waits for it, so a
//! costly frame overlaps the next one's rendering.
//!
//! The core sees the same events in the same order as if it ran inside each step (the
//! messages it uses, the pairs, and a tick at the end of each step, when the graph may be
//! shared), so its estimates do not depend on when the thread ran. What it produces waits:
//! the radio messages and key frames (which the emulated image matcher reads) of batch `k`
//! come out when batch `k + DEPTH` is handed over, i.e. up to `DEPTH + 1` frame periods late;
//! those of the last batches are not sent. Every hand-off happens at a tick fixed by the
//! inputs alone (a pair, or `MAX_QUEUED` events without one, so a robot whose images stop
//! still processes its messages), so the run's digest is the same whatever the machine's speed
//! or thread count.
//!
//! The accessors ([`SlamStack::report`], [`SlamStack::map_points`], ...) stop the worker and
//! give the core the queued events first: they are for the end of a run (or a test).

use super::{Event, SlamCore, SlamParams};
use crate::report::SlamReport;
use hetsim_msgs::{
    Artifact, Command, Image, InboxGuard, InputError, Outgoing, Pose, RobotStack, SensorMsg,
    StackStatus,
};
use hetsim_vision::stereo::Bench;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Mutex;
use std::thread::JoinHandle;

/// Events queued without a pair before the core is handed them anyway (two seconds of ticks
/// at 100 Hz).
const MAX_QUEUED: usize = 200;

/// Batches the core may be behind by: the results of batch `k` are collected when batch
/// `k + DEPTH` is handed over. One: the pair's work overlaps the next frame's ticks and
/// rendering. Two (a costly frame may also overlap the one after) measured no faster on the
/// village (30 s runs, 47.1 and 47.6 s wall against 48.2 and 44.8 s) and delays the radio by
/// a frame more.
const DEPTH: usize = 1;

/// What a batch produced: radio messages, and the key frames so far.
type Produced = (Vec<Outgoing>, Vec<u64>);

/// Where the core is.
enum Slot {
    /// Here.
    Idle(Box<SlamCore>),
    /// On its worker thread, which takes batches of events in order and answers each with
    /// what it produced; the thread gives the core back when the batches stop.
    Busy {
        batches: Sender<Vec<Event>>,
        produced: Receiver<Produced>,
        worker: JoinHandle<Box<SlamCore>>,
        in_flight: usize,
    },
}

/// The core back from its worker: no more batches, every one so far finished.
fn stop(slot: Slot) -> Box<SlamCore> {
    match slot {
        Slot::Idle(core) => core,
        Slot::Busy {
            batches, worker, ..
        } => {
            drop(batches);
            worker
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        }
    }
}

/// The core and the events it has not been handed yet.
struct Held {
    slot: Option<Slot>,
    queue: Vec<Event>,
}

impl Held {
    /// The core back, with every event so far processed.
    fn settle(&mut self) -> &mut SlamCore {
        let mut core = stop(
            self.slot
                .take()
                .expect("the slot is refilled before unlocking"),
        );
        for event in self.queue.drain(..) {
            core.handle(event);
        }
        self.slot = Some(Slot::Idle(core));
        match self.slot.as_mut() {
            Some(Slot::Idle(core)) => core,
            _ => unreachable!("just put back"),
        }
    }
}

/// SLAM for one robot beside its pilot (see the module docs of [`crate::stack`]).
pub struct SlamStack {
    /// The boundary checks of what the stack is fed (stamp order per sensor).
    guard: InboxGuard,
    /// The size of the bench's images, from its first pair: every later image must match.
    image_size: Option<(u32, u32)>,
    inner: Box<dyn RobotStack>,
    robot: String,
    left: String,
    right: String,
    pending_left: Option<Image>,
    held: Mutex<Held>,
    keyframes: Vec<u64>,
    outgoing: Vec<Outgoing>,
}

impl SlamStack {
    /// SLAM for robot `robot` on the stereo camera named `stereo`, whose left optical frame
    /// is at `body_from_camera`, around `inner`.
    pub fn new(
        inner: Box<dyn RobotStack>,
        robot: &str,
        stereo: &str,
        bench: Bench,
        body_from_camera: Pose,
        params: SlamParams,
        seed: u64,
    ) -> Self {
        let core = SlamCore::new(robot, bench, body_from_camera, params, seed);
        Self {
            guard: InboxGuard::new(),
            image_size: None,
            inner,
            robot: robot.to_string(),
            left: format!("{stereo}/left"),
            right: format!("{stereo}/right"),
            pending_left: None,
            held: Mutex::new(Held {
                slot: Some(Slot::Idle(Box::new(core))),
                queue: Vec::new(),
            }),
            keyframes: Vec::new(),
            outgoing: Vec::new(),
        }
    }

    /// Runs `f` on the core once it has processed every event so far (waiting for its
    /// thread).
    fn with_core<T>(&self, f: impl FnOnce(&mut SlamCore) -> T) -> T {
        let mut held = self
            .held
            .lock()
            .expect("the SLAM core's lock is never poisoned");
        f(held.settle())
    }

    /// Number of sub-maps so far (the current one included).
    pub fn submaps(&self) -> usize {
        self.with_core(|c| c.submaps())
    }

    /// Events of a kind so far.
    pub fn events_of(&self, kind: &str) -> usize {
        self.with_core(|c| c.events_of(kind))
    }

    /// The global level's report for evaluation.
    pub fn report(&self) -> Option<SlamReport> {
        self.with_core(|c| c.report())
    }

    /// Mapped points in the world frame, with their sub-map.
    pub fn map_points(&self) -> Vec<(usize, [f64; 3])> {
        self.with_core(|c| c.map_points())
    }

    /// Mapped segments in the world frame, with their sub-map.
    pub fn map_segments(&self) -> Vec<(usize, [[f64; 3]; 2])> {
        self.with_core(|c| c.map_segments())
    }

    /// Takes the core back (waiting for the previous pair), collects what it produced, and
    /// hands it the events queued since, the new pair last, on a thread of its own.
    fn hand_off(&mut self) {
        let held = self
            .held
            .get_mut()
            .expect("the SLAM core's lock is never poisoned");
        let events = std::mem::take(&mut held.queue);
        let slot = match held
            .slot
            .take()
            .expect("the slot is refilled before unlocking")
        {
            Slot::Idle(mut core) => {
                let (batches, inbox) = channel::<Vec<Event>>();
                let (reply, produced) = channel();
                let worker = std::thread::Builder::new()
                    .name(format!("slam-{}", self.robot))
                    .spawn(move || {
                        for batch in inbox {
                            for event in batch {
                                core.handle(event);
                            }
                            let made = (core.take_outgoing(), core.keyframes().to_vec());
                            if reply.send(made).is_err() {
                                break;
                            }
                        }
                        core
                    })
                    .expect("a thread for the SLAM core");
                Slot::Busy {
                    batches,
                    produced,
                    worker,
                    in_flight: 0,
                }
            }
            busy => busy,
        };
        let Slot::Busy {
            batches,
            produced,
            worker,
            mut in_flight,
        } = slot
        else {
            unreachable!("started above")
        };
        batches
            .send(events)
            .expect("the SLAM worker runs until its batches stop");
        in_flight += 1;
        // Collect what the batch `DEPTH` back produced (waiting for it if need be).
        while in_flight > DEPTH {
            let Ok((out, keyframes)) = produced.recv() else {
                std::panic::resume_unwind(stop_panicked(worker));
            };
            self.outgoing.extend(out);
            self.keyframes = keyframes;
            in_flight -= 1;
        }
        held.slot = Some(Slot::Busy {
            batches,
            produced,
            worker,
            in_flight,
        });
    }
}

/// The panic of a worker whose reply channel closed.
fn stop_panicked(worker: JoinHandle<Box<SlamCore>>) -> Box<dyn std::any::Any + Send> {
    match worker.join() {
        Err(panic) => panic,
        Ok(_) => Box::new("the SLAM worker stopped early"),
    }
}

impl SlamStack {
    /// The bench's images: all of one size (the first image's), at least
    /// [`MIN_IMAGE_SIDE`] pixels each way, so the VO's windows fit.
    fn check_images(&mut self, inbox: &[SensorMsg]) -> Result<(), InputError> {
        for msg in inbox {
            let SensorMsg::Image(img) = msg else {
                continue;
            };
            if img.sensor != self.left && img.sensor != self.right {
                continue;
            }
            let size = (img.width, img.height);
            if size.0 < MIN_IMAGE_SIDE || size.1 < MIN_IMAGE_SIDE {
                return Err(InputError::of(
                    msg,
                    "width x height",
                    format!("{} x {}", size.0, size.1),
                    &format!(
                        "at least {MIN_IMAGE_SIDE} x {MIN_IMAGE_SIDE} pixels for the stereo VO"
                    ),
                ));
            }
            match self.image_size {
                None => self.image_size = Some(size),
                Some(first) if first != size => {
                    return Err(InputError::of(
                        msg,
                        "width x height",
                        format!("{} x {}", size.0, size.1),
                        &format!(
                            "the bench's size, {} x {} (its first image)",
                            first.0, first.1
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
        Ok(())
    }
}

/// The smallest image side the stereo VO takes, pixels: its Harris and correlation windows
/// and search margins need room.
pub const MIN_IMAGE_SIDE: u32 = 64;

impl RobotStack for SlamStack {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<Command, InputError> {
        self.guard.check(now_ns, inbox)?;
        self.check_images(inbox)?;
        let mut paired = false;
        let queue = &mut self.held.get_mut().expect("never poisoned").queue;
        for msg in inbox {
            match msg {
                SensorMsg::Image(img) if img.sensor == self.left => {
                    self.pending_left = Some(img.clone())
                }
                SensorMsg::Image(img) if img.sensor == self.right => {
                    if let Some(left) = self
                        .pending_left
                        .take()
                        .filter(|l| l.stamp_ns == img.stamp_ns)
                    {
                        queue.push(Event::Pair(Box::new((left, img.clone()))));
                        paired = true;
                    }
                }
                // The messages the core uses (SlamCore::on_message); not the IMU's 100 Hz,
                // and never the truth, which only the pilot inside may read.
                SensorMsg::Rendezvous(_) | SensorMsg::ImageMatch(_) | SensorMsg::Comms(_) => {
                    queue.push(Event::Msg(msg.clone()))
                }
                _ => {}
            }
        }
        queue.push(Event::Tick(now_ns));
        if paired || queue.len() >= MAX_QUEUED {
            self.hand_off();
        }
        self.inner.step(now_ns, inbox)
    }

    fn status(&self) -> StackStatus {
        self.inner.status()
    }

    fn outbox(&mut self) -> Vec<Outgoing> {
        let mut out = std::mem::take(&mut self.outgoing);
        out.extend(self.inner.outbox());
        out
    }

    fn artifacts(&self) -> Vec<Artifact> {
        let mut out = self.inner.artifacts();
        // The events after the last pair reach the core too (a share received, a fix).
        out.extend(self.with_core(|c| c.artifacts()));
        out
    }

    fn oracle_keyframes(&self) -> &[u64] {
        &self.keyframes
    }
}
