//! What a coverage parent publishes for evaluation (as the `coverage/team` artifact): the
//! plan's figures, the image database and the children's tracked paths.

use hetsim_msgs::Image;
use serde::{Deserialize, Serialize};

/// The name of the report artifact a [`crate::ParentStack`] publishes.
pub const TEAM_ARTIFACT: &str = "coverage/team";

/// One image of a coverage mission's database, as the parent stored it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatabaseImage {
    /// The grid vertex `(col, row)` it was taken at.
    pub vertex: (usize, usize),
    /// The child that took it.
    pub child: String,
    /// The parent's estimate of the grab position (tracker), metres.
    pub estimated_xy: [f64; 2],
    /// The child's compass heading at the grab, radians.
    pub estimated_heading_rad: f64,
    /// The image (its stamp is the grab time).
    pub image: Image,
}

/// Positions of a robot over time: `(stamp_ns, [x, y])`, metres.
pub type TrackedPath = Vec<(u64, [f64; 2])>;

/// What a coverage parent reports at the end of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TeamReport {
    /// Free vertices of the map |V|.
    pub vertices: usize,
    /// Parent vertices V_p in tour order, `(col, row)`.
    pub parent_vertices: Vec<(usize, usize)>,
    /// Vertices the plan could not image (uncoverable or unreached), `(col, row)`.
    pub unplanned: Vec<(usize, usize)>,
    /// Goals a tracked child could not be brought within twice the arrival distance of after
    /// three corrections (blocked), `(col, row)`; the mission goes on from where it is.
    pub abandoned: Vec<(usize, usize)>,
    /// The image database.
    pub database: Vec<DatabaseImage>,
    /// Times a child expected in view was not tracked and had to be stopped.
    pub tracking_losses: u32,
    /// Orders sent again because no acknowledgement came.
    pub resent_orders: u32,
    /// Drives of a child back onto its vertex because the parent saw it, where it believes
    /// it is, in the view of a child about to grab (see the parent's `views.rs`).
    pub view_recentres: u32,
    /// Grabs ordered while the parent still saw a robot, where it tracks it, in the
    /// grabbing child's view (after its rounds of driving children back onto their
    /// vertices).
    pub grabs_with_tracked_robot_in_view: u32,
    /// When the last step of the plan was done, nanoseconds; `None` while unfinished.
    pub finished_ns: Option<u64>,
    /// Steps of the plan (timesteps) executed, and in the plan.
    pub steps_done: usize,
    /// Steps of the plan.
    pub steps_total: usize,
    /// Every child's positions as the parent's tracker measured them.
    pub tracked_paths: Vec<(String, TrackedPath)>,
    /// The localization run after mapping, if the database was sent.
    pub tour: Option<TourReport>,
}

/// A child's localization run after mapping (its estimates are its own `pf-<feature>`
/// trajectories).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TourReport {
    /// The child.
    pub child: String,
    /// The path the parent gave it, `(col, row)`, from where it stood.
    pub path: Vec<(usize, usize)>,
    /// When the parent heard the child report the run done (or gave up), nanoseconds.
    pub over_ns: Option<u64>,
    /// The parent gave up: no report within a minute per move.
    pub timed_out: bool,
    /// The encoders' scale the child was sent (metres travelled per metre counted; 1:
    /// uncalibrated; `parent/odometry.rs`).
    pub odometry_scale: f64,
    /// The hops it rests on.
    pub odometry_hops: Vec<OdometryHop>,
}

/// One hop of a child between two images the parent saw it take: the encoders' calibration
/// sample (`parent/odometry.rs`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OdometryHop {
    /// The first image's stamp, nanoseconds.
    pub from_ns: u64,
    /// The second image's stamp, nanoseconds.
    pub to_ns: u64,
    /// The straight distance between where the parent saw the child take them, metres.
    pub seen_m: f64,
    /// What the child's encoders counted between them, metres.
    pub counted_m: f64,
}

/// The median of `v`, the middle two's mean for an even count (`None` when empty): the
/// encoders' scale from its hops, by the parent and, on the truth, by the evaluation.
pub fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    })
}
