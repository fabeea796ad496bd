//! The radio protocol between a coverage parent and its children, and the child's software
//! (seed 002, Section V.B).
//!
//! The children have no localization of their own while mapping: a camera, a compass and
//! wheel encoders. The parent tracks them and sends **orders**; a child
//! * **drives**: rotates by compass towards a heading, then drives straight at the mission's
//!   speed (0.15 m/s in the seed), holding the heading by compass, for a distance measured by
//!   its encoders, and stops (also when its encoders stall: less than 1 cm in two seconds),
//!   reporting the distance once it stands, the roll to a stop included;
//! * **grabs**: rotates by compass to the direction of mapping, lets the robot settle, takes
//!   the next camera image and sends it with the vertex id;
//! * **stops**.
//!
//! The radio may lose messages, so every order carries a sequence number; the child
//! acknowledges each order (again when it receives it again), reports a finished drive with
//! `Done` and a grab with `Grabbed` (again whenever the order is repeated), and ignores orders
//! older than the one it is executing. The parent repeats an order until it hears back.
//!
//! After the mapping the parent may send a child the database and a path
//! ([`TeamMsg::Localize`]): the child then drives and localizes on its own (`team/tour.rs`),
//! and reports the run done with [`TeamMsg::Localized`]; the parent polls for that report
//! ([`TeamMsg::Poll`]).

use hetsim_msgs::{
    wrap_angle, Artifact, Command, Image, InboxGuard, InputError, Mission, OccupancyGrid, Outgoing,
    RobotStack, SensorMsg, StackStatus,
};
use hetsim_vision::appearance::Features;
use serde::{Deserialize, Serialize};

/// The radio topic of the team's messages.
pub const TOPIC: &str = "team";

/// What a parent orders a child to do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Order {
    /// Stop now and hold.
    Stop,
    /// Rotate to `heading_rad` by compass, then drive straight for `distance_m` and stop.
    Drive {
        /// Compass heading, radians counter-clockwise from east.
        heading_rad: f64,
        /// Distance by the encoders, metres.
        distance_m: f64,
    },
    /// Rotate to `heading_rad` by compass, settle, grab an image and send it.
    Grab {
        /// The direction of mapping, radians counter-clockwise from east.
        heading_rad: f64,
        /// The vertex being imaged, `(col, row)`.
        vertex: (usize, usize),
    },
}

/// A message of the team protocol.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum TeamMsg {
    /// Parent to child: an order.
    Order {
        /// Sequence number, increasing per child.
        seq: u32,
        /// The order.
        order: Order,
    },
    /// Child to parent: order `seq` received.
    Ack {
        /// The order's sequence number.
        seq: u32,
    },
    /// Child to parent: the drive of order `seq` is finished.
    Done {
        /// The order's sequence number.
        seq: u32,
        /// Distance driven by the encoders, metres: the roll to a stop included, scaled by
        /// the encoders' calibration once the child has one (its run after mapping).
        driven_m: f64,
        /// The compass heading while driving (mean of the readings), radians.
        heading_rad: f64,
    },
    /// Child to parent: the image of grab order `seq`.
    Grabbed {
        /// The order's sequence number.
        seq: u32,
        /// The vertex, `(col, row)`.
        vertex: (usize, usize),
        /// Mean compass heading while the image was taken, radians.
        heading_rad: f64,
        /// The image.
        image: Image,
        /// The encoders' odometer when the image was taken: all the distance they have
        /// counted since the start, metres (turns on the spot add about nothing). The parent
        /// calibrates the encoders against its tracks with it (`parent/odometry.rs`).
        odometer_m: f64,
    },
    /// Parent to child, after mapping: the database by radio, and a new path to localize
    /// along on its own (see `team/tour.rs`).
    Localize {
        /// Sequence number, increasing per child (shared with the orders).
        seq: u32,
        /// The map the particles live on (the parent's occupancy grid).
        grid: OccupancyGrid,
        /// The database: the parent's grab position estimate and the image's features.
        places: Vec<([f64; 2], Features)>,
        /// The path: the positions (metres) of the vertices to image at, the child's own
        /// (as the parent tracked it) first.
        path: Vec<[f64; 2]>,
        /// The direction of mapping, radians: every image faces it.
        heading_rad: f64,
        /// Metres travelled per metre the encoders count, as the parent measured it while it
        /// tracked this child (1 where it could not): the child's encoder distances on the
        /// run are scaled by it.
        odometry_scale: f64,
    },
    /// Parent to child: is the run of [`TeamMsg::Localize`] `seq` over? (Answered, like a
    /// repeated message, with the acknowledgement and the report if there is one.)
    Poll {
        /// The [`TeamMsg::Localize`]'s sequence number.
        seq: u32,
    },
    /// Child to parent: the localization run of message `seq` is over.
    Localized {
        /// The [`TeamMsg::Localize`]'s sequence number.
        seq: u32,
    },
}

impl TeamMsg {
    /// The radio message carrying this to `to`.
    pub fn to(&self, to: &str) -> Outgoing {
        Outgoing {
            to: to.to_string(),
            topic: TOPIC.to_string(),
            payload: postcard::to_stdvec(self).expect("plain data always encodes"),
        }
    }

    /// Decodes a delivered team message, if it is one.
    pub fn decode(msg: &hetsim_msgs::Delivered) -> Option<Self> {
        (msg.topic == TOPIC)
            .then(|| postcard::from_bytes(&msg.payload).ok())
            .flatten()
    }
}

/// Parameters of a child.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChildParams {
    /// Wheel track, metres.
    pub track_m: f64,
    /// Driving speed, metres per second.
    pub speed_mps: f64,
    /// Largest turn rate, radians per second.
    pub max_turn_radps: f64,
    /// A heading within this of the target ends a rotation, radians.
    pub aim_tolerance_rad: f64,
    /// Time to stand still after rotating before an image is taken, nanoseconds.
    pub settle_ns: u64,
    /// Seed of the localization's particle filters.
    pub seed: u64,
}

#[derive(Clone, Debug, PartialEq)]
enum Phase {
    Idle,
    Turning {
        target: f64,
        then_drive: Option<f64>,
        grab: Option<(usize, usize)>,
    },
    Driving {
        /// The compass heading held while driving.
        target: f64,
        remaining_m: f64,
        driven_m: f64,
        headings: (f64, f64),
        /// Encoder distance and time at the last check for a stall.
        progress: (f64, u64),
    },
    /// The drive's distance is counted, the wheels are told to stop: the robot rolls on a
    /// little, and the encoders count on until it stands.
    Stopping {
        driven_m: f64,
        headings: (f64, f64),
        since_ns: u64,
    },
    Settling {
        since_ns: u64,
        vertex: (usize, usize),
        headings: (f64, f64),
    },
}

/// A child robot's software: obeys the parent's orders.
pub struct ChildStack {
    /// The boundary checks of what the stack is fed (stamp order per sensor).
    guard: InboxGuard,
    params: ChildParams,
    parent: String,
    seq: Option<u32>,
    phase: Phase,
    heading: Option<f64>,
    /// A reading arrived since the turn command was last computed.
    fresh_heading: bool,
    /// The reply to the current order once it is finished (repeated on request).
    reply: Option<TeamMsg>,
    /// The localization run after mapping, once the database has come.
    tour: Option<tour::Tour>,
    /// All the distance the encoders have counted, metres.
    odometer_m: f64,
    /// The last encoder reading's stamp.
    odometry_ns: Option<u64>,
    /// Metres travelled per metre the encoders count: 1 until the database's message brings
    /// the parent's calibration.
    odometry_scale: f64,
    outbox: Vec<Outgoing>,
    status: StackStatus,
}

impl ChildStack {
    /// A child obeying `mission` (it must be [`Mission::Teleoperated`]; any other mission
    /// leaves the child idle, with no parent to answer).
    pub fn new(params: ChildParams, mission: &Mission) -> Self {
        let parent = match mission {
            Mission::Teleoperated { parent } => parent.clone(),
            _ => String::new(),
        };
        Self {
            guard: InboxGuard::new(),
            params,
            parent,
            seq: None,
            phase: Phase::Idle,
            heading: None,
            fresh_heading: false,
            reply: None,
            tour: None,
            odometer_m: 0.0,
            odometry_ns: None,
            odometry_scale: 1.0,
            outbox: Vec::new(),
            status: StackStatus::default(),
        }
    }

    fn send(&mut self, msg: TeamMsg) {
        if !self.parent.is_empty() {
            self.outbox.push(msg.to(&self.parent));
        }
    }

    /// Whether message `seq` is new: then it is acknowledged and becomes the current one. An
    /// old one is ignored; the current one again is acknowledged again, with its reply.
    fn accept(&mut self, seq: u32) -> bool {
        match self.seq {
            Some(current) if seq < current => return false,
            Some(current) if seq == current => {
                // The parent did not hear us: say it again.
                self.send(TeamMsg::Ack { seq });
                if let Some(reply) = self.reply.clone() {
                    self.send(reply);
                }
                return false;
            }
            _ => {}
        }
        self.seq = Some(seq);
        self.reply = None;
        self.send(TeamMsg::Ack { seq });
        true
    }

    fn obey(&mut self, seq: u32, order: Order) {
        if !self.accept(seq) {
            return;
        }
        // An order from the parent ends a localization run (its estimates stay).
        if let Some(t) = self.tour.as_mut() {
            t.running = false;
        }
        self.phase = match order {
            Order::Stop => Phase::Idle,
            Order::Drive {
                heading_rad,
                distance_m,
            } => Phase::Turning {
                target: heading_rad,
                then_drive: Some(distance_m),
                grab: None,
            },
            Order::Grab {
                heading_rad,
                vertex,
            } => Phase::Turning {
                target: heading_rad,
                then_drive: None,
                grab: Some(vertex),
            },
        };
    }

    fn wheels(&self, forward: f64, turn: f64) -> Command {
        let half = self.params.track_m / 2.0;
        Command::Wheels {
            left_mps: forward - turn * half,
            right_mps: forward + turn * half,
        }
    }

    fn finish(&mut self, reply: TeamMsg) {
        if let Some(tour) = self.tour.as_mut().filter(|t| t.running) {
            // On its own: the drive or image goes to the particle filters, not the radio.
            self.phase = tour.next(&reply);
            if self.phase == Phase::Idle {
                let done = TeamMsg::Localized { seq: tour.seq };
                self.reply = Some(done.clone());
                self.send(done);
            }
            return;
        }
        self.status.goals_reached += 1;
        self.reply = Some(reply.clone());
        self.send(reply);
        self.phase = Phase::Idle;
    }
}

/// Adds a heading to a running (sum of cos, sum of sin).
fn accumulate(sum: (f64, f64), heading: f64) -> (f64, f64) {
    (sum.0 + heading.cos(), sum.1 + heading.sin())
}

/// What one step's messages brought that the phase acts on (the rest they set on the stack).
struct Readings<'a> {
    /// The step's camera image, the last if several.
    image: Option<&'a Image>,
    /// Distance the step's encoder readings counted, metres (uncalibrated).
    driven: f64,
    /// The time the step's encoder readings span (none: it has counted nothing, which is
    /// not standing).
    counted_ns: u64,
}

/// The step a phase is advanced by.
#[derive(Clone, Copy)]
struct Tick {
    /// Sim time of the step, nanoseconds.
    now_ns: u64,
    /// The current order's sequence number (0 before any).
    seq: u32,
    /// Distance the step's encoder readings counted, calibrated, metres.
    driven: f64,
    /// The time the step's encoder readings span.
    counted_ns: u64,
}

impl ChildStack {
    /// The command for one step's messages, once the boundary has checked them
    /// ([`RobotStack::step`] checks, then calls this).
    pub fn command(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Command {
        let Readings {
            image,
            driven,
            counted_ns,
        } = self.read_inbox(inbox);
        self.odometer_m += driven;
        // Calibrated (from the database's message on), the encoders' distance is scaled.
        let driven = driven * self.odometry_scale;
        let seq = self.seq.unwrap_or(0);
        let tick = Tick {
            now_ns,
            seq,
            driven,
            counted_ns,
        };
        match self.phase.clone() {
            Phase::Idle => Command::Stop,
            Phase::Turning {
                target,
                then_drive,
                grab,
            } => self.turn(now_ns, target, then_drive, grab),
            Phase::Driving {
                target,
                remaining_m,
                driven_m,
                headings,
                progress,
            } => self.drive(tick, target, remaining_m, driven_m, headings, progress),
            Phase::Stopping {
                driven_m,
                headings,
                since_ns,
            } => self.stop(tick, driven_m, headings, since_ns),
            Phase::Settling {
                since_ns,
                vertex,
                headings,
            } => self.settle(tick, image, since_ns, vertex, headings),
        }
    }

    /// Reads one step's messages as they came: compass readings, encoder counts, the
    /// parent's radio and the camera.
    fn read_inbox<'a>(&mut self, inbox: &'a [SensorMsg]) -> Readings<'a> {
        let mut image: Option<&Image> = None;
        let mut driven = 0.0;
        // The time the step's encoder readings span (none: it has counted nothing, which is
        // not standing).
        let mut counted_ns = 0u64;
        for msg in inbox {
            match msg {
                SensorMsg::Compass(c) => self.read_compass(c.heading_rad),
                SensorMsg::WheelOdometry(o) => {
                    driven += (o.left_m + o.right_m) / 2.0;
                    if let Some(t0) = self.odometry_ns {
                        counted_ns += o.stamp_ns.saturating_sub(t0);
                    }
                    self.odometry_ns =
                        Some(self.odometry_ns.map_or(o.stamp_ns, |t| t.max(o.stamp_ns)));
                }
                SensorMsg::Comms(d) if d.from == self.parent => self.hear(d),
                SensorMsg::Image(i) => image = Some(i),
                _ => {}
            }
        }
        Readings {
            image,
            driven,
            counted_ns,
        }
    }

    /// Keeps a compass reading, and adds it to the headings the phase averages.
    fn read_compass(&mut self, heading_rad: f64) {
        self.heading = Some(heading_rad);
        self.fresh_heading = true;
        match &mut self.phase {
            Phase::Driving { headings, .. }
            | Phase::Stopping { headings, .. }
            | Phase::Settling { headings, .. } => {
                *headings = accumulate(*headings, heading_rad);
            }
            _ => {}
        }
    }

    /// Handles a radio message from the parent: an order, the database or a poll.
    fn hear(&mut self, d: &hetsim_msgs::Delivered) {
        match TeamMsg::decode(d) {
            Some(TeamMsg::Order { seq, order }) => self.obey(seq, order),
            Some(TeamMsg::Localize {
                seq,
                grid,
                places,
                path,
                heading_rad,
                odometry_scale,
            }) if self.accept(seq) => {
                // A scale under 0.8 or over 1.25 is no wheel's slip or encoders'
                // error (a c't-Bot's: 2 % and a 2 % sigma): a bad measurement, not
                // used.
                self.odometry_scale = if (0.8..=1.25).contains(&odometry_scale) {
                    odometry_scale
                } else {
                    1.0
                };
                let tour = tour::Tour::new(seq, grid, places, path, heading_rad, self.params.seed);
                self.phase = tour.first();
                self.tour = Some(tour);
            }
            Some(TeamMsg::Poll { seq }) if self.seq == Some(seq) => {
                self.accept(seq);
            }
            _ => {}
        }
    }

    /// Turns towards `target` by compass; once aimed, starts the drive or the settling.
    fn turn(
        &mut self,
        now_ns: u64,
        target: f64,
        then_drive: Option<f64>,
        grab: Option<(usize, usize)>,
    ) -> Command {
        let Some(heading) = self.heading else {
            return Command::Stop;
        };
        let error = wrap_angle(target - heading);
        if error.abs() <= self.params.aim_tolerance_rad && self.fresh_heading {
            self.phase = match (then_drive, grab) {
                (Some(d), _) => Phase::Driving {
                    target,
                    remaining_m: d,
                    driven_m: 0.0,
                    headings: (0.0, 0.0),
                    progress: (0.0, now_ns),
                },
                (None, Some(vertex)) => Phase::Settling {
                    since_ns: now_ns,
                    vertex,
                    headings: (0.0, 0.0),
                },
                (None, None) => Phase::Idle,
            };
            return Command::Stop;
        }
        // Turn only as far as a compass period allows, so a noisy reading is not
        // overshot: proportional, with a floor so that small errors still close.
        self.fresh_heading = false;
        // (A robot file may allow less than the floor: then its maximum is the rate.)
        let max = self.params.max_turn_radps;
        let rate = (1.5 * error).abs().clamp(0.25f64.min(max), max);
        self.wheels(0.0, rate * error.signum())
    }

    /// Drives straight by compass, counting the distance; at its end or stalled, stops.
    fn drive(
        &mut self,
        tick: Tick,
        target: f64,
        remaining_m: f64,
        driven_m: f64,
        headings: (f64, f64),
        mut progress: (f64, u64),
    ) -> Command {
        let Tick { now_ns, driven, .. } = tick;
        let remaining = remaining_m - driven;
        let driven_m = driven_m + driven;
        // Stalled (against an obstacle, the wheels held): less than 1 cm in the last
        // two seconds ends the drive, so that the parent hears how far it got.
        let stalled = if now_ns >= progress.1 + 2_000_000_000 {
            let stuck = driven_m - progress.0 < 0.01;
            progress = (driven_m, now_ns);
            stuck
        } else {
            false
        };
        if remaining <= 0.0 || stalled {
            self.phase = Phase::Stopping {
                driven_m,
                headings,
                since_ns: now_ns,
            };
            return Command::Stop;
        }
        self.phase = Phase::Driving {
            target,
            remaining_m: remaining,
            driven_m,
            headings,
            progress,
        };
        // Straight by compass: the wheels' speed errors would curve the path by
        // several degrees a second.
        let hold = self
            .heading
            .map_or(0.0, |h| (1.0 * wrap_angle(target - h)).clamp(-0.3, 0.3));
        self.wheels(self.params.speed_mps, hold)
    }

    /// Counts the roll to a stop; once standing (or a second on), reports the drive.
    fn stop(&mut self, tick: Tick, driven_m: f64, headings: (f64, f64), since_ns: u64) -> Command {
        let Tick {
            now_ns,
            seq,
            driven,
            counted_ns,
        } = tick;
        // The drive is reported with what the encoders counted while it rolled to a
        // stop (about 7 mm at 0.15 m/s): dead reckoning from the report, the parent's
        // out of view and the child's own on its run, is not short by that on every
        // drive. Standing: encoder readings of under 1 cm/s (at the c't-Bot's 10 Hz,
        // the second or third reading after the stop), or a second on.
        let driven_m = driven_m + driven;
        let heading = self.mean_heading(headings);
        let standing = counted_ns > 0 && driven.abs() < 0.01 * counted_ns as f64 / 1e9;
        if standing || now_ns >= since_ns + 1_000_000_000 {
            self.finish(TeamMsg::Done {
                seq,
                driven_m,
                heading_rad: heading,
            });
        } else {
            self.phase = Phase::Stopping {
                driven_m,
                headings,
                since_ns,
            };
        }
        Command::Stop
    }

    /// Waits for an image taken after settling, and sends it.
    fn settle(
        &mut self,
        tick: Tick,
        image: Option<&Image>,
        since_ns: u64,
        vertex: (usize, usize),
        headings: (f64, f64),
    ) -> Command {
        if let Some(img) = image.filter(|i| i.stamp_ns >= since_ns + self.params.settle_ns) {
            let heading = self.mean_heading(headings);
            self.finish(TeamMsg::Grabbed {
                seq: tick.seq,
                vertex,
                heading_rad: heading,
                image: img.clone(),
                odometer_m: self.odometer_m,
            });
        }
        Command::Stop
    }

    /// The mean of the compass readings summed in `headings`, or the last reading if none
    /// was summed.
    fn mean_heading(&self, headings: (f64, f64)) -> f64 {
        if headings == (0.0, 0.0) {
            self.heading.unwrap_or(0.0)
        } else {
            headings.1.atan2(headings.0)
        }
    }
}

impl RobotStack for ChildStack {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<Command, InputError> {
        self.guard.check(now_ns, inbox)?;
        Ok(self.command(now_ns, inbox))
    }

    fn status(&self) -> StackStatus {
        StackStatus {
            wants_images: matches!(self.phase, Phase::Settling { .. }),
            ..self.status
        }
    }

    fn outbox(&mut self) -> Vec<Outgoing> {
        std::mem::take(&mut self.outbox)
    }

    fn artifacts(&self) -> Vec<Artifact> {
        self.tour
            .as_ref()
            .map_or_else(Vec::new, tour::Tour::artifacts)
    }
}

#[cfg(test)]
mod tests;
mod tour;
