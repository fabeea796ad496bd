//! A frame dump is a EuRoC MAV dataset: read back the way a EuRoC loader (evo's, a VIO
//! system's) reads one, against the robot file and the run's own truth.

use hetsim_tests::{hetsim, printed_digest};
use std::collections::BTreeMap;
use std::path::Path;

/// Rows of a EuRoC CSV (header line starting with `#` skipped), as numbers.
fn rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    assert!(
        lines.next().unwrap().starts_with("#timestamp"),
        "{}",
        path.display()
    );
    lines
        .map(|l| {
            l.split(',')
                .map(|f| {
                    f.trim()
                        .parse::<f64>()
                        .unwrap_or_else(|e| panic!("{l}: {e}"))
                })
                .collect()
        })
        .collect()
}

/// `key: [a, b, ...]` of a sensor.yaml, as numbers (the list may span lines, as T_BS's).
fn yaml_list(text: &str, key: &str) -> Vec<f64> {
    let start = text
        .find(&format!("{key}: ["))
        .unwrap_or_else(|| panic!("no {key} in {text}"));
    let rest = &text[start + key.len() + 3..];
    rest[..rest.find(']').unwrap()]
        .split(',')
        .map(|f| f.trim().parse().unwrap())
        .collect()
}

fn yaml_number(text: &str, key: &str) -> f64 {
    let line = text
        .lines()
        .find(|l| l.starts_with(&format!("{key}:")))
        .unwrap_or_else(|| panic!("no {key} in {text}"));
    line[key.len() + 1..]
        .split('#')
        .next()
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

#[test]
fn a_dump_is_a_euroc_dataset_per_robot() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d");
    let o = hetsim(
        &[
            "frames",
            "scenarios/village-short.toml",
            "--from",
            "1",
            "--to",
            "2",
            "--cameras",
            "ressac",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    printed_digest(&o);
    let mav0 = out.join("frames/ressac/mav0");
    let mut entries: Vec<String> = std::fs::read_dir(&mav0)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    entries.sort();
    assert_eq!(
        entries,
        [
            "body.yaml",
            "cam0",
            "cam1",
            "imu0",
            "state_groundtruth_estimate0"
        ],
        "EuRoC's mav0 layout for a stereo bench and an IMU"
    );
    assert!(std::fs::read_to_string(mav0.join("body.yaml"))
        .unwrap()
        .contains("base_link"));

    // Cameras: cam0 left, cam1 right, the same stamps, 10 Hz within [1, 2] s, the images
    // of the size sensor.yaml states, as a stereo EuRoC loader pairs them.
    // The robot as the run resolved it (the scenario's overrides applied), from its manifest.
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let model = manifest["resolved"]["robots"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "ressac")
        .unwrap()["model"]
        .clone();
    let sensor = |kind: &str| {
        model["sensors"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["kind"] == kind)
            .unwrap()
            .clone()
    };
    let stereo = sensor("stereo_camera");
    let (width, height) = (
        stereo["width_px"].as_i64().unwrap(),
        stereo["height_px"].as_i64().unwrap(),
    );
    let hfov = stereo["hfov_deg"].as_f64().unwrap().to_radians();
    let mut stamps = Vec::new();
    let mut t_bs = Vec::new();
    for cam in ["cam0", "cam1"] {
        let csv = std::fs::read_to_string(mav0.join(cam).join("data.csv")).unwrap();
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some("#timestamp [ns],filename"));
        let list: Vec<(u64, String)> = lines
            .map(|l| {
                let (t, f) = l.split_once(',').unwrap();
                (t.parse().unwrap(), f.to_string())
            })
            .collect();
        assert_eq!(list.len(), 11, "{cam}: 10 Hz over [1, 2] s");
        let yaml = std::fs::read_to_string(mav0.join(cam).join("sensor.yaml")).unwrap();
        assert!(yaml.contains("sensor_type: camera") && yaml.contains("camera_model: pinhole"));
        assert_eq!(
            yaml_list(&yaml, "resolution"),
            vec![width as f64, height as f64]
        );
        assert_eq!(yaml_number(&yaml, "rate_hz"), 10.0);
        let k = yaml_list(&yaml, "intrinsics");
        let fu = width as f64 / 2.0 / (hfov / 2.0).tan();
        assert!(
            (k[0] - fu).abs() < 1e-6 * fu && (k[1] - fu).abs() < 1e-6 * fu,
            "{k:?} vs fu {fu}"
        );
        for (t, file) in &list {
            assert_eq!(file, &format!("{t}.png"));
            let img = image::open(mav0.join(cam).join("data").join(file)).unwrap();
            assert_eq!((img.width() as i64, img.height() as i64), (width, height));
        }
        stamps.push(list.iter().map(|(t, _)| *t).collect::<Vec<_>>());
        t_bs.push(yaml_list(&yaml, "data"));
    }
    assert_eq!(stamps[0], stamps[1], "stereo pairs share their stamps");
    // T_BS (body_from_optical, row major): the optical centres are the bench's baseline apart,
    // along the left camera's x axis (towards the right camera), and the rotations agree.
    let (l, r) = (&t_bs[0], &t_bs[1]);
    assert_eq!(l.len(), 16);
    let d = [r[3] - l[3], r[7] - l[7], r[11] - l[11]];
    let baseline = stereo["baseline_m"].as_f64().unwrap();
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    assert!(
        (len - baseline).abs() < 1e-6,
        "{d:?} vs baseline {baseline}"
    );
    let along_x = (d[0] * l[0] + d[1] * l[4] + d[2] * l[8]) / len;
    assert!(
        (along_x - 1.0).abs() < 1e-6,
        "right camera along the left's +x: {along_x}"
    );
    for i in [0, 1, 2, 4, 5, 6, 8, 9, 10] {
        assert!((l[i] - r[i]).abs() < 1e-9);
    }

    // IMU: 100 Hz within the window, 7 columns; the noise density is the robot file's
    // per-sample sigma times sqrt(dt).
    let imu = rows(&mav0.join("imu0/data.csv"));
    assert_eq!(imu.len(), 101, "100 Hz over [1, 2] s");
    assert!(imu
        .iter()
        .all(|r| r.len() == 7 && (1e9..=2e9).contains(&r[0])));
    let imu_spec = sensor("imu");
    let yaml = std::fs::read_to_string(mav0.join("imu0/sensor.yaml")).unwrap();
    assert_eq!(yaml_number(&yaml, "rate_hz"), 100.0);
    let density = yaml_number(&yaml, "gyroscope_noise_density");
    let sigma = imu_spec["gyro_sigma_radps"].as_f64().unwrap();
    assert!(
        (density - sigma * 0.1).abs() < 1e-12,
        "{density} vs {sigma} / sqrt(100 Hz)"
    );
    // The helicopter hovers and flies level: the accelerometer reads about +g up.
    let mean_az = imu.iter().map(|r| r[6]).sum::<f64>() / imu.len() as f64;
    assert!((mean_az - 9.81).abs() < 1.0, "specific force z {mean_az}");

    // Ground truth, read as evo's EuRoC reader does (ns -> s, quaternion w first), against
    // the run's own truth/ressac.tum (x y z qx qy qz qw, seconds) at the same stamps.
    let gt = rows(&mav0.join("state_groundtruth_estimate0/data.csv"));
    assert_eq!(gt.len(), 51, "50 Hz truth over [1, 2] s");
    let tum: BTreeMap<u64, Vec<f64>> = std::fs::read_to_string(out.join("truth/ressac.tum"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|f| f.parse().unwrap()).collect();
            ((v[0] * 1e9).round() as u64, v)
        })
        .collect();
    let max_speed = model["body"]["max_speed_mps"].as_f64().unwrap();
    let (bias_w, bias_sigma) = (
        gt[0][11..14].to_vec(),
        imu_spec["gyro_bias_sigma_radps"].as_f64().unwrap(),
    );
    for r in &gt {
        assert_eq!(r.len(), 17);
        let t = tum
            .get(&(r[0] as u64))
            .unwrap_or_else(|| panic!("no truth at {}", r[0]));
        for a in 0..3 {
            assert!(
                (r[1 + a] - t[1 + a]).abs() < 2e-6,
                "position {r:?} vs {t:?}"
            );
        }
        // Same rotation: q and -q alike.
        let dot = r[4] * t[7] + r[5] * t[4] + r[6] * t[5] + r[7] * t[6];
        assert!((dot.abs() - 1.0).abs() < 1e-6, "orientation {r:?} vs {t:?}");
        let speed = (r[8] * r[8] + r[9] * r[9] + r[10] * r[10]).sqrt();
        assert!(
            speed <= max_speed * 1.01,
            "{speed} m/s beyond the airframe's {max_speed}"
        );
        assert_eq!(r[11..14], bias_w[..], "a constant bias per run");
    }
    assert!(
        bias_w.iter().all(|b| b.abs() < 5.0 * bias_sigma),
        "{bias_w:?}"
    );
    // The velocities integrate to the displacement (trapezoids; 1 cm over a second).
    let mut moved = [0.0; 3];
    for w in gt.windows(2) {
        let dt = (w[1][0] - w[0][0]) * 1e-9;
        for a in 0..3 {
            moved[a] += 0.5 * (w[0][8 + a] + w[1][8 + a]) * dt;
        }
    }
    let (first, last) = (&gt[0], &gt[gt.len() - 1]);
    for a in 0..3 {
        assert!(
            (moved[a] - (last[1 + a] - first[1 + a])).abs() < 0.01,
            "axis {a}: {moved:?}"
        );
    }
}
