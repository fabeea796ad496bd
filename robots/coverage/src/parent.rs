//! The parent robot's software: plans the mission, drives its tour, tracks the children and
//! teleoperates them over the radio so that an image is taken at every child vertex (seed
//! 002, Sections III, IV.D and V.B).
//!
//! Decisions:
//! * **Map.** The parent is given the occupancy map at resolution d ([`CoverageMission`]),
//!   as the seed assumes ("a range map of the environment was created before, e.g., by the
//!   parent robot"); building it is not part of this mission.
//! * **Localization.** The seed's parent "has an accurate localization"; this one earns it:
//!   Monte Carlo localization from its laser scans and wheel encoders against the map it is
//!   given, starting around the pose the operator gives ([`crate::mcl`]). It steers, plans
//!   and places the children's tracks (measured in its body frame) with that estimate, and
//!   publishes it as the `mcl` trajectory. It reads no truth: an oracle pose in its inbox
//!   (a scenario may switch the parent model's on for waypoint following) is ignored. It
//!   drives between vertices by rotating in place, then straight.
//! * **Tracking.** It finds the children's orange hats in its omnidirectional panoramas
//!   ([`hetsim_vision::hats`], from its plan to the mission's end) and gives each hat within
//!   r_los to the child expected nearest (see `parent/sense.rs`); without a camera it takes
//!   an emulated tracker's fixes (`ChildTracks`).
//! * **Execution.** The grid-level plan ([`crate::plan`]) is executed timestep by timestep:
//!   the robots that move in a timestep are driven to their next vertex together; when all
//!   have arrived, the timestep's grabs are ordered; when all images are in, the next
//!   timestep starts. A robot moving onto a vertex that another robot leaves in the same
//!   timestep starts when that robot has arrived. The plan keeps robots on distinct
//!   vertices and out of each other's views at grab time, so this execution inherits its
//!   collision and view guarantees up to the children's position errors. Before the grabs
//!   it checks the views with the robots where it tracks them, and drives a child off its
//!   vertex in one back onto it first (`parent/views.rs`).
//! * **Teleoperation** (Section V.B). To send a child to a vertex, the parent takes the
//!   child's tracked position, orders a drive towards the goal (the child rotates by
//!   compass, then drives straight for the distance by its encoders), re-aims it once when it
//!   is within 0.2 m of the goal, and, when the drive is done, accepts the position if it is
//!   within `arrive_m` of the goal or orders a correction (at most three).
//! * **Out of view.** A child the parent should not see (farther than r_los, or its hat not
//!   wholly in sight on the map: `teleop.rs`, `expected_in_view`; this happens in the
//!   following behaviour) is driven open loop: its
//!   position is dead-reckoned from the drive it reported, until the tracker sees it again;
//!   an idle child found more than `2 arrive_m` from its planned vertex is driven back there.
//! * **Stuck.** A tracked child whose drive should long be over is driven again from where
//!   it is; a child whose encoders stall while driving ends the drive itself (see
//!   [`crate::team`]).
//! * **Found again.** A driving child tracked again after more than a second without fixes
//!   is re-aimed from where it is seen: its dead-reckoned course can be decimetres off.
//! * **Lost track.** A child that should be in view but has not been tracked for
//!   `lost_after_ns` while driving is stopped at once (a tracking loss); it is driven on when
//!   the tracker finds it again, or open loop from its last track after `reacquire_ns` (the
//!   map's line of sight and the tracker's can disagree near obstacle corners).
//! * **Radio.** Orders are repeated every `resend_ns` until acknowledged, and a drive or grab
//!   whose reply does not come is ordered again; see [`crate::team`].

use crate::map::{Map, Vertex};
use crate::mcl::{Mcl, MclParams};
use crate::report::{DatabaseImage, TeamReport, TEAM_ARTIFACT};
use crate::team::{Order, TeamMsg};
use crate::visibility::{segment_open, FINE};
use crate::{plan, CoverageParams, Direction, Plan, Reading, ViewRule};
use hetsim_msgs::{
    Artifact, Command, CoverageMission, InboxGuard, InputError, Mission, Outgoing, Pose,
    PoseStamped, RobotStack, SensorMsg, StackStatus,
};
use hetsim_pilot::{GroundPilot, GroundPilotParams};

mod handover;
mod odometry;
mod sense;
mod steps;
mod teleop;
mod views;

pub use sense::HatTracker;

/// Tuning of the parent's teleoperation.
#[derive(Clone, Debug, PartialEq)]
pub struct ParentParams {
    /// The parent's own pilot.
    pub pilot: GroundPilotParams,
    /// A child within this of its goal has arrived, metres.
    pub arrive_m: f64,
    /// Re-aim distance, metres (0.2 in the seed).
    pub reaim_m: f64,
    /// A track older than this is no track, nanoseconds.
    pub track_timeout_ns: u64,
    /// A child in view untracked for this long while driving is stopped, nanoseconds.
    pub lost_after_ns: u64,
    /// A lost child not found again within this long is driven on open loop, nanoseconds.
    pub reacquire_ns: u64,
    /// Unacknowledged orders are repeated this often, nanoseconds.
    pub resend_ns: u64,
    /// The laser the parent localizes with, `[x, y, yaw]` in its body frame (metres,
    /// radians); without one it cannot localize and stands still.
    pub laser_mount: Option<[f64; 3]>,
    /// Its laser localization.
    pub mcl: MclParams,
    /// Its hat tracker on the omnidirectional camera; without one it takes the fixes of an
    /// emulated tracker (`ChildTracks`).
    pub hat_tracker: Option<HatTracker>,
    /// Seed of the localization's random numbers.
    pub seed: u64,
    /// Seed of the path a child localizes along after mapping.
    pub tour_seed: u64,
}

impl ParentParams {
    /// The defaults used by the simulator, for a parent driven by `pilot`. The parent drives
    /// between vertices by rotating in place and then straight (its footprint leaves a few
    /// centimetres on each side of a cell, too little for curved approaches).
    pub fn with_pilot(pilot: GroundPilotParams) -> Self {
        Self {
            pilot: GroundPilotParams {
                steering: hetsim_pilot::Steering::RotateThenDrive {
                    reaim_m: 0.1,
                    aim_tolerance_rad: 1f64.to_radians(),
                },
                ..pilot
            },
            arrive_m: 0.07,
            reaim_m: 0.2,
            // Two and a half of the hat tracker's 5 Hz periods: one panorama without a
            // child's hat does not make it untracked.
            track_timeout_ns: 500_000_000,
            lost_after_ns: 500_000_000,
            reacquire_ns: 3_000_000_000,
            resend_ns: 500_000_000,
            laser_mount: None,
            mcl: MclParams::default(),
            hat_tracker: None,
            seed: 0,
            tour_seed: 0,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Task {
    Idle,
    Move {
        goal: [f64; 2],
        reaimed: bool,
        corrections: u32,
        /// The drive order in flight: when its reply is due, nanoseconds.
        due_ns: u64,
        /// Where the child was believed to be when the drive was ordered.
        from: [f64; 2],
        /// Driven open loop after a tracking loss: no loss detection for this move.
        blind: bool,
    },
    Lost {
        goal: [f64; 2],
        since_ns: u64,
        corrections: u32,
    },
    Grab {
        vertex: (usize, usize),
        sent_ns: u64,
        /// The tracker's fixes while the child grabs: their sum and count (a child that
        /// waits long for its image must not grow the parent's memory).
        fixes: ([f64; 2], u32),
    },
}

struct Child {
    name: String,
    /// Where the plan has the child: its current or next vertex's centre.
    planned: [f64; 2],
    estimate: [f64; 2],
    last_fix_ns: Option<u64>,
    /// Tracked again, while driving, after more than a second without fixes.
    reacquired: bool,
    seq: u32,
    order: Option<Order>,
    acked: bool,
    sent_ns: u64,
    task: Task,
    path: Vec<(u64, [f64; 2])>,
    /// The encoders' calibration against the tracks (`parent/odometry.rs`).
    odometry: odometry::Calibration,
}

/// The parent's software.
pub struct ParentStack {
    /// The boundary checks of what the stack is fed (stamp order per sensor).
    guard: InboxGuard,
    params: ParentParams,
    mission: CoverageMission,
    coverage: CoverageParams,
    map: Map,
    plan: Option<Plan>,
    plan_failed: bool,
    /// The pose it steers by: the laser localization's.
    pose: Option<Pose>,
    localizer: Option<Mcl>,
    /// The localization's estimates, one per filter update.
    estimates: Vec<(u64, Pose)>,
    step_index: usize,
    moves_started: bool,
    grabbing: bool,
    /// Rounds of driving children back onto their vertices for the current timestep's
    /// grabs (see `parent/views.rs`).
    recentres: u32,
    pilot: Option<GroundPilot>,
    /// Moves of the current timestep not started yet: (robot, target, the robot leaving the
    /// target); robot 0 is the parent, robot k the k-th child.
    waiting: Vec<(usize, Vertex, Option<usize>)>,
    children: Vec<Child>,
    /// The hat tracker's last panorama, and since when it has looked without a break (a
    /// child is lost only if untracked while the parent looks), nanoseconds.
    looked: Option<(u64, u64)>,
    report: TeamReport,
    /// After mapping: the database's delivery and a child's localization run.
    handover: handover::Delivery,
    outbox: Vec<Outgoing>,
    now_ns: u64,
}

fn direction(name: &str) -> Direction {
    match name {
        "north" => Direction::North,
        "west" => Direction::West,
        "south" => Direction::South,
        _ => Direction::East,
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

impl ParentStack {
    /// A parent for `mission` (a [`Mission::CoverageParent`]; any other leaves it idle).
    pub fn new(params: ParentParams, mission: &Mission) -> Self {
        let mission = match mission {
            Mission::CoverageParent(m) => m.clone(),
            _ => CoverageMission {
                grid: hetsim_msgs::OccupancyGrid {
                    origin_x: 0.0,
                    origin_y: 0.0,
                    cell_m: 1.0,
                    cols: 0,
                    rows: 0,
                    occupied: Vec::new(),
                },
                children: Vec::new(),
                r_los_m: 2.0,
                direction: "east".into(),
                child_fov_deg: 80.0,
                view_margin_deg: 0.0,
                view_margin_m: 0.0,
                parent_radius_m: 0.225,
                child_radius_m: 0.06,
                f_factor: 2.0,
                child_speed_mps: 0.15,
                parent_start: [0.0; 3],
                localize_steps: 0,
            },
        };
        let localizer = params
            .laser_mount
            .filter(|_| mission.grid.cols > 0)
            .map(|mount| {
                Mcl::new(
                    params.mcl,
                    &mission.grid,
                    mission.parent_start,
                    params.pilot.track_m,
                    mount,
                    params.seed,
                )
            });
        let coverage = CoverageParams {
            r_los_m: mission.r_los_m,
            direction: direction(&mission.direction),
            child_fov_deg: mission.child_fov_deg,
            view_margin_deg: mission.view_margin_deg,
            view_margin_m: mission.view_margin_m,
            parent_radius_m: mission.parent_radius_m,
            child_radius_m: mission.child_radius_m,
            children: mission.children.len().max(1),
            f_factor: mission.f_factor,
            // Its children's images are the database: no robot in any of them.
            views: ViewRule::EveryGrab,
            // The shipped reading (others are for grid planning only).
            reading: Reading::Ours,
        };
        let children = mission
            .children
            .iter()
            .map(|(name, (c, r))| Child {
                name: name.clone(),
                planned: mission.grid.centre_of(*c, *r),
                estimate: mission.grid.centre_of(*c, *r),
                last_fix_ns: None,
                reacquired: false,
                seq: 0,
                order: None,
                acked: true,
                sent_ns: 0,
                task: Task::Idle,
                path: Vec::new(),
                odometry: odometry::Calibration::default(),
            })
            .collect();
        Self {
            guard: InboxGuard::new(),
            params,
            map: Map::from_grid(&mission.grid),
            mission,
            coverage,
            plan: None,
            plan_failed: false,
            pose: None,
            localizer,
            estimates: Vec::new(),
            step_index: 0,
            moves_started: false,
            grabbing: false,
            recentres: 0,
            pilot: None,
            waiting: Vec::new(),
            children,
            looked: None,
            report: TeamReport::default(),
            handover: handover::Delivery::NotYet,
            outbox: Vec::new(),
            now_ns: 0,
        }
    }

    fn centre(&self, v: Vertex) -> [f64; 2] {
        let (c, r) = self.map.cell(v);
        self.mission.grid.centre_of(c, r)
    }

    fn vertex_at(&self, p: [f64; 2]) -> Option<Vertex> {
        self.mission
            .grid
            .cell_of(p[0], p[1])
            .and_then(|(c, r)| self.map.at(c as i64, r as i64))
    }
}

impl ParentStack {
    /// The command for one step's messages, once the boundary has checked them
    /// ([`RobotStack::step`] checks, then calls this).
    pub fn command(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Command {
        self.now_ns = now_ns;
        // In stamp order, and at one stamp the encoders before the laser before the rest:
        // the filter moves its particles up to the scan's time before it weighs them, and
        // tracks are placed by the pose at their own time (sensors reach the inbox in the
        // robot file's order, the laser first).
        let rank = |m: &SensorMsg| match m {
            SensorMsg::WheelOdometry(_) => 0,
            SensorMsg::LaserScan(_) => 1,
            _ => 2,
        };
        let mut order: Vec<&SensorMsg> = inbox.iter().collect();
        order.sort_by_key(|m| (m.stamp_ns(), rank(m)));
        for msg in order {
            match msg {
                SensorMsg::WheelOdometry(o) => {
                    if let Some(m) = self.localizer.as_mut() {
                        m.wheel_odometry(o.left_m, o.right_m);
                    }
                    self.localized(o.stamp_ns, false);
                }
                SensorMsg::LaserScan(scan) => {
                    let updated = self.localizer.as_mut().is_some_and(|m| m.laser(scan));
                    self.localized(scan.stamp_ns, updated);
                }
                SensorMsg::ChildTracks(t) => self.tracks(t),
                SensorMsg::Image(image) => self.look(image),
                SensorMsg::Comms(d) => {
                    if let (Some(i), Some(m)) = (
                        self.children.iter().position(|c| c.name == d.from),
                        TeamMsg::decode(d),
                    ) {
                        if !self.handover_reply(i, &m) {
                            self.handle_reply(i, m);
                        }
                    }
                }
                _ => {}
            }
        }
        let Some(pose) = self.pose else {
            return Command::Stop;
        };
        if self.plan.is_none() && !self.plan_failed {
            self.make_plan(&pose);
        }
        // After the mapping the children are on their own.
        if self.report.finished_ns.is_none() {
            for i in 0..self.children.len() {
                self.supervise(i);
            }
        }
        if !self.waiting.is_empty() {
            self.release_waiting();
        }
        self.advance();
        self.hand_over();
        let Some(pilot) = self.pilot.as_mut() else {
            return Command::Stop;
        };
        let cmd = pilot.command(
            now_ns,
            &[SensorMsg::TruthPose(PoseStamped {
                stamp_ns: now_ns,
                pose,
            })],
        );
        if pilot.status().done() {
            self.pilot = None;
            return Command::Stop;
        }
        cmd
    }
}

impl RobotStack for ParentStack {
    fn step(&mut self, now_ns: u64, inbox: &[SensorMsg]) -> Result<Command, InputError> {
        self.guard.check(now_ns, inbox)?;
        Ok(self.command(now_ns, inbox))
    }

    fn status(&self) -> StackStatus {
        StackStatus {
            goals_reached: self.report.steps_done,
            goals_total: self.report.steps_total,
            goals_skipped: 0,
            // The hat tracker's panoramas, while the mission runs.
            wants_images: self.params.hat_tracker.is_some()
                && self.plan.is_some()
                && self.report.finished_ns.is_none(),
            mission_over: self.report.finished_ns.is_some() && self.handover_over(),
        }
    }

    fn outbox(&mut self) -> Vec<Outgoing> {
        std::mem::take(&mut self.outbox)
    }

    fn artifacts(&self) -> Vec<Artifact> {
        let mut out = vec![Artifact::report(TEAM_ARTIFACT, &self.team_report())];
        if !self.estimates.is_empty() {
            out.push(Artifact::trajectory("mcl", self.estimates.clone()));
        }
        out
    }
}

impl ParentStack {
    /// The mission's report: the plan's figures, the image database and the children's paths
    /// as the tracker measured them.
    pub fn team_report(&self) -> TeamReport {
        let mut r = self.report.clone();
        r.tracked_paths = self
            .children
            .iter()
            .map(|c| (c.name.clone(), c.path.clone()))
            .collect();
        r.tour = self.handover.sent().map(|h| crate::report::TourReport {
            child: self.children[h.child].name.clone(),
            path: h.path.clone(),
            over_ns: h.over_ns,
            timed_out: h.timed_out,
            odometry_scale: h.odometry_scale,
            odometry_hops: self.children[h.child].odometry.hops().to_vec(),
        });
        r
    }
}

/// A coverage mission on a room of `cols` x `rows` cells of 0.5 m from the origin, free but
/// for the cells `occupied` ((col, row)), with `children` at their vertices and the parent
/// starting at `parent_start` (x, y, yaw): r_los 2 m, 80 deg cameras looking east, the lab's
/// view margins (10 deg, 0.04 m), the lab's robot sizes, no localization steps (the
/// parent-side unit tests' common mission; tests change fields as they need).
#[cfg(test)]
fn test_mission(
    [cols, rows]: [usize; 2],
    occupied: &[(usize, usize)],
    children: &[(&str, (usize, usize))],
    parent_start: [f64; 3],
) -> CoverageMission {
    let mut cells = vec![false; cols * rows];
    for &(c, r) in occupied {
        cells[r * cols + c] = true;
    }
    CoverageMission {
        grid: hetsim_msgs::OccupancyGrid {
            origin_x: 0.0,
            origin_y: 0.0,
            cell_m: 0.5,
            cols,
            rows,
            occupied: cells,
        },
        children: children.iter().map(|&(n, v)| (n.into(), v)).collect(),
        r_los_m: 2.0,
        direction: "east".into(),
        child_fov_deg: 80.0,
        view_margin_deg: 10.0,
        view_margin_m: 0.04,
        parent_radius_m: 0.2,
        child_radius_m: 0.06,
        f_factor: 2.0,
        child_speed_mps: 0.15,
        parent_start,
        localize_steps: 0,
    }
}

/// A parent for `mission` with a test pilot, standing at the mission's start, planned (the
/// parent-side unit tests' common setup).
#[cfg(test)]
fn planned_test_parent(mission: CoverageMission) -> ParentStack {
    let pilot = hetsim_pilot::GroundPilotParams {
        track_m: 0.35,
        max_wheel_mps: 0.5,
        cruise_mps: 0.3,
        max_yaw_rate_radps: 1.0,
        arrive_m: 0.05,
        steering: hetsim_pilot::Steering::Smooth {
            turn_in_place_rad: 1.0,
        },
    };
    let [x, y, yaw] = mission.parent_start;
    let mut p = ParentStack::new(
        ParentParams::with_pilot(pilot),
        &Mission::CoverageParent(mission),
    );
    let pose = hetsim_msgs::pose_from_xyz_rpy([x, y, 0.0], [0.0, 0.0, yaw]);
    p.pose = Some(pose);
    p.make_plan(&pose);
    assert!(p.plan.is_some(), "the test room has a plan");
    p
}
