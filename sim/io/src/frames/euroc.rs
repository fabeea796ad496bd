//! The text files of a EuRoC dataset: `sensor.yaml` of cameras, IMUs and the ground truth,
//! `body.yaml`, and the ground truth's 17-column CSV.

use super::ImuSpec;
use hetsim_engine::cameras::Shot;
use hetsim_msgs::Pose;

/// `T_BS` as EuRoC writes it: a row-major 4 x 4 block.
fn t_bs(body_from_sensor: &Pose) -> String {
    let t = body_from_sensor.to_homogeneous();
    let rows: Vec<String> = (0..4)
        .map(|r| {
            (0..4)
                .map(|c| format!("{:.9}", t[(r, c)]))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    format!(
        "T_BS:\n  cols: 4\n  rows: 4\n  data: [{}]\n",
        rows.join(",\n         ")
    )
}

/// A camera's `sensor.yaml`: EuRoC's keys (pinhole, radial-tangential), `comment` naming
/// the hetsim camera.
pub(super) fn camera_yaml(shot: &Shot) -> String {
    let k = &shot.intrinsics;
    let (model, intrinsics) = if k.k.alpha_u > 0.0 {
        (
            "pinhole",
            format!("[{}, {}, {}, {}]", k.k.alpha_u, k.k.alpha_v, k.k.u0, k.k.v0),
        )
    } else {
        ("equirectangular", "[]".to_string())
    };
    format!(
        "# General sensor definitions.\nsensor_type: camera\ncomment: hetsim camera {topic}\n\n# Sensor extrinsics wrt. the body-frame.\n{}\n# Camera specific definitions.\nrate_hz: {}\nresolution: [{}, {}]\ncamera_model: {model}\nintrinsics: {intrinsics} #fu, fv, cu, cv\ndistortion_model: radial-tangential\ndistortion_coefficients: [{}, {}, 0.0, 0.0]\n",
        t_bs(&shot.body_from_optical),
        shot.rate_hz,
        k.width,
        k.height,
        shot.distortion[0],
        shot.distortion[1],
        topic = shot.topic
    )
}

/// An IMU's `sensor.yaml`. The noise densities are the per-sample white noise times
/// sqrt(dt) (a sample's sigma is density / sqrt(dt)); hetsim's biases are constant over a
/// run, so the random walks are 0.
pub(super) fn imu_yaml(spec: &ImuSpec) -> String {
    let root_dt = (1.0 / spec.rate_hz).sqrt();
    format!(
        "# General sensor definitions.\nsensor_type: imu\ncomment: hetsim IMU {}\n\n# Sensor extrinsics wrt. the body-frame.\n{}rate_hz: {}\n\n# inertial sensor noise model parameters (static)\ngyroscope_noise_density: {:e}     # [ rad / s / sqrt(Hz) ]   ( gyro \"white noise\" )\ngyroscope_random_walk: 0.0       # [ rad / s^2 / sqrt(Hz) ] ( constant bias per run )\naccelerometer_noise_density: {:e}  # [ m / s^2 / sqrt(Hz) ]   ( accel \"white noise\" )\naccelerometer_random_walk: 0.0   # [ m / s^3 / sqrt(Hz) ] ( constant bias per run )\n",
        spec.topic,
        t_bs(&spec.body_from_sensor),
        spec.rate_hz,
        spec.gyro_sigma_radps * root_dt,
        spec.accel_sigma_mps2 * root_dt,
    )
}

/// `body.yaml`: what the body frame is.
pub(super) fn body_yaml(robot: &str) -> String {
    format!(
        "# The body frame B of hetsim robot {robot}: its base_link (REP-103: x forward, y left,\n# z up). Every sensor.yaml's T_BS is body_from_sensor; the ground truth is world_from_body,\n# the world R being x east, y north, z up.\ncomment: hetsim robot {robot}, body frame = base_link\n"
    )
}

/// The ground truth's `sensor.yaml`.
pub(super) const GROUNDTRUTH_YAML: &str = "# Additional sensor information\nsensor_type: visual-inertial\ncomment: hetsim's simulated truth of the body (base_link) in the world; velocity by central differences of the truth samples, IMU biases the run's true constant biases of imu0 (0 without an IMU)\n\n# Sensor extrinsics wrt. the body-frame.\nT_BS:\n  cols: 4\n  rows: 4\n  data: [1.0, 0.0, 0.0, 0.0,\n         0.0, 1.0, 0.0, 0.0,\n         0.0, 0.0, 1.0, 0.0,\n         0.0, 0.0, 0.0, 1.0]\n";

/// EuRoC's ground-truth CSV of `world_from_body` samples (time order) within `window_ns`:
/// position, quaternion (w first), velocity in the world by central differences (one-sided
/// at the ends), and the constant biases.
pub(super) fn groundtruth_csv(
    samples: &[(u64, Pose)],
    window_ns: Option<(u64, u64)>,
    (gyro_bias, accel_bias): ([f64; 3], [f64; 3]),
) -> String {
    let mut text = String::from("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n");
    let position = |i: usize| samples[i].1.translation.vector;
    for (i, (stamp, pose)) in samples.iter().enumerate() {
        if window_ns.is_some_and(|(a, b)| *stamp < a || *stamp > b) {
            continue;
        }
        let (lo, hi) = (i.saturating_sub(1), (i + 1).min(samples.len() - 1));
        let dt = (samples[hi].0 as f64 - samples[lo].0 as f64) * 1e-9;
        let v = if dt > 0.0 {
            (position(hi) - position(lo)) / dt
        } else {
            nalgebra::Vector3::zeros()
        };
        let p = pose.translation.vector;
        let q = pose.rotation.quaternion();
        let [bw, ba] = [gyro_bias, accel_bias];
        text.push_str(&format!(
            "{stamp},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            p.x,
            p.y,
            p.z,
            q.w,
            q.i,
            q.j,
            q.k,
            v.x,
            v.y,
            v.z,
            bw[0],
            bw[1],
            bw[2],
            ba[0],
            ba[1],
            ba[2]
        ));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn ground_truth_velocity_is_the_central_difference_and_the_window_cuts_rows() {
        // 1 m/s east, sampled every 20 ms.
        let samples: Vec<(u64, Pose)> = (0..5)
            .map(|k| {
                (
                    k * 20_000_000,
                    Pose::from_parts(
                        Translation3::new(0.02 * k as f64, 0.0, 1.0),
                        UnitQuaternion::identity(),
                    ),
                )
            })
            .collect();
        let text = groundtruth_csv(
            &samples,
            Some((20_000_000, 60_000_000)),
            ([0.1, 0.0, 0.0], [0.0; 3]),
        );
        let rows: Vec<Vec<f64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 3);
        for r in &rows {
            assert_eq!(r.len(), 17);
            assert!((r[8] - 1.0).abs() < 1e-9 && r[9].abs() < 1e-12, "{r:?}");
            assert_eq!((r[4], r[11]), (1.0, 0.1));
        }
    }
}
