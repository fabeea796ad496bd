//! A GPS receiver: the antenna's position with white noise, silent during outages, at its rate
//! or at the instants of a schedule.

use super::{normal, At, Model};
use crate::ros2::{from_cdr, geo, with_deps, DecodeError, Encoded, Frames, Header, Ros2Message};
use crate::ros2::{Vector3, HEADER, POINT, TIME};
use hetsim_core::SimRng;
use hetsim_msgs::{GpsFix, SensorMsg};
use serde::{Deserialize, Serialize};

pub(crate) struct Gps {
    pub sigma_m: f64,
    pub outages_s: Vec<[f64; 2]>,
    /// Fix instants, seconds (empty: every period).
    pub schedule_s: Vec<f64>,
    /// The next instant of the schedule.
    pub next: usize,
}

impl Model for Gps {
    fn due(&mut self, after: u64, period: u64, now_ns: u64) -> bool {
        if self.schedule_s.is_empty() {
            return after % period == 0;
        }
        let t = now_ns as f64 / 1e9;
        let mut fire = false;
        while self.next < self.schedule_s.len() && self.schedule_s[self.next] <= t + 1e-12 {
            self.next += 1;
            fire = true;
        }
        fire
    }

    fn measure(&mut self, at: &At, rng: &mut SimRng) -> Vec<SensorMsg> {
        let t = at.stamp_ns as f64 / 1e9;
        if self.outages_s.iter().any(|[a, b]| t >= *a && t <= *b) {
            return Vec::new();
        }
        let origin = at.world_from_sensor.translation.vector;
        let position_m = [0, 1, 2].map(|a| origin[a] + normal(rng, self.sigma_m));
        vec![SensorMsg::Gps(GpsFix {
            stamp_ns: at.stamp_ns,
            sensor: at.sensor.clone(),
            position_m,
            sigma_m: self.sigma_m,
        })]
    }
}

const NAV_SAT_FIX: &str = "sensor_msgs/msg/NavSatFix";

const NAV_SAT_STATUS: (&str, &str) = (
    "sensor_msgs/NavSatStatus",
    "int8 STATUS_NO_FIX=-1\nint8 STATUS_FIX=0\nint8 STATUS_SBAS_FIX=1\nint8 STATUS_GBAS_FIX=2\nint8 status\nuint16 SERVICE_GPS=1\nuint16 SERVICE_GLONASS=2\nuint16 SERVICE_COMPASS=4\nuint16 SERVICE_GALILEO=8\nuint16 service\n",
);

/// `sensor_msgs/msg/NavSatStatus`.
#[derive(Serialize)]
struct NavSatStatus {
    status: i8,
    service: u16,
}

/// `sensor_msgs/msg/NavSatFix`.
#[derive(Serialize)]
struct NavSatFix {
    header: Header,
    status: NavSatStatus,
    latitude: f64,
    longitude: f64,
    altitude: f64,
    position_covariance: [f64; 9],
    position_covariance_type: u8,
}

/// `hetsim_msgs/msg/GpsLocal`.
#[derive(Serialize, Deserialize)]
struct GpsLocal {
    header: Header,
    position: Vector3,
    sigma_m: f64,
}

/// A fix is recorded twice: as a `NavSatFix` in WGS-84 for ROS tools, and on `<gps>/local`
/// in the local frame exactly as the robot received it (WGS-84 does not round-trip to the
/// same bits, and replay must feed the same bytes), which replay reads.
impl Ros2Message for GpsFix {
    const SCHEMA: &'static str = "hetsim_msgs/msg/GpsLocal";

    fn definitions() -> Vec<(&'static str, String)> {
        vec![
            (
                NAV_SAT_FIX,
                with_deps(
                    "uint8 COVARIANCE_TYPE_UNKNOWN=0\nuint8 COVARIANCE_TYPE_APPROXIMATED=1\nuint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2\nuint8 COVARIANCE_TYPE_KNOWN=3\nstd_msgs/Header header\nsensor_msgs/NavSatStatus status\nfloat64 latitude\nfloat64 longitude\nfloat64 altitude\nfloat64[9] position_covariance\nuint8 position_covariance_type\n",
                    &[HEADER, TIME, NAV_SAT_STATUS],
                ),
            ),
            (
                Self::SCHEMA,
                with_deps(
                    "# A GPS fix in the local world frame (east, north, up), metres, exactly as the robot received it; the NavSatFix beside it carries the same fix in WGS-84.\nstd_msgs/Header header\ngeometry_msgs/Point position\nfloat64 sigma_m\n",
                    &[HEADER, TIME, POINT],
                ),
            ),
        ]
    }

    fn encode(&self, frames: &mut Frames) -> Vec<Encoded> {
        let (latitude, longitude, altitude) = geo(self.position_m);
        let var = self.sigma_m * self.sigma_m;
        let fix = NavSatFix {
            header: frames.in_sensor(),
            status: NavSatStatus {
                status: 0,
                service: 1,
            },
            latitude,
            longitude,
            altitude,
            position_covariance: [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var],
            position_covariance_type: 2,
        };
        let [x, y, z] = self.position_m;
        let local = GpsLocal {
            header: frames.header("world".into()),
            position: Vector3 { x, y, z },
            sigma_m: self.sigma_m,
        };
        vec![
            Encoded::on_topic(NAV_SAT_FIX, &fix),
            Encoded {
                suffix: "/local",
                ..Encoded::on_topic(Self::SCHEMA, &local)
            },
        ]
    }

    fn decode(data: &[u8], sensor: String) -> Result<SensorMsg, DecodeError> {
        let m: GpsLocal = from_cdr(data)?;
        Ok(SensorMsg::Gps(GpsFix {
            stamp_ns: m.header.stamp.ns()?,
            sensor,
            position_m: [m.position.x, m.position.y, m.position.z],
            sigma_m: m.sigma_m,
        }))
    }
}
