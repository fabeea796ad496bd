//! Cameras in the lockstep loop, and frame dumps in the EuRoC layout.

use hetsim_tests::{hetsim, hetsim_without, printed_digest};

/// Lines a healthy run must not print: `error:` is how hetsim, and the graphics stack's
/// libraries, report a failure.
fn error_lines(out: &std::process::Output) -> Vec<String> {
    [&out.stdout, &out.stderr]
        .iter()
        .flat_map(|b| {
            String::from_utf8_lossy(b)
                .lines()
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .filter(|l| l.to_lowercase().contains("error:"))
        .collect()
}

#[test]
fn rendered_runs_deliver_images_at_their_rates_and_repeat_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let mut digests = Vec::new();
    for k in 0..2 {
        let out = dir.path().join(format!("r{k}"));
        // The second run as on a machine without a desktop session, where `XDG_RUNTIME_DIR`
        // is not set (a fresh server, CI): it must start as quietly as the first.
        let removed: &[&str] = if k == 1 { &["XDG_RUNTIME_DIR"] } else { &[] };
        let o = hetsim_without(
            &[
                "run",
                "scenarios/indoor-grid-20.toml",
                "--duration",
                "2",
                "--out",
                out.to_str().unwrap(),
            ],
            removed,
        );
        assert_eq!(
            error_lines(&o),
            Vec::<String>::new(),
            "run {k} printed errors"
        );
        digests.push(printed_digest(&o));
        let metrics = hetsim_eval::Metrics::read(&out).unwrap();
        let m = &metrics.messages;
        // 2 s: c't-Bot cameras at 2 Hz, the parent's panorama at 5 Hz.
        assert_eq!(m.get("child1/camera"), Some(&4), "{m:?}");
        assert_eq!(m.get("parent/omni"), Some(&10), "{m:?}");
        let manifest = hetsim_eval::manifest::Manifest::read(&out).unwrap();
        assert!(
            manifest.adapter.is_some_and(|a| !a.name.is_empty()),
            "the manifest names the adapter"
        );
    }
    assert_eq!(
        digests[0], digests[1],
        "same seed, same adapter: same images, same digest"
    );
}

#[test]
fn cameras_render_only_for_robots_that_want_images() {
    // In the lab's coverage mission the children want an image only while waiting for a
    // grab (nothing in the first 2 s), and the parent its panoramas from when it has a plan
    // (its first laser localization) until the mapping is done: 5 Hz.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("lab");
    printed_digest(&hetsim(
        &[
            "run",
            "scenarios/lab.toml",
            "--duration",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    ));
    let metrics = hetsim_eval::Metrics::read(&out).unwrap();
    let m = &metrics.messages;
    assert!(!m.contains_key("child1/camera"), "{m:?}");
    let panoramas = m.get("parent/omni").copied().unwrap_or(0);
    assert!(
        (8..=10).contains(&panoramas),
        "{panoramas} panoramas in 2 s at 5 Hz: {m:?}"
    );
    assert!(
        !m.contains_key("parent/tracker"),
        "no emulated tracker: {m:?}"
    );
}

#[test]
fn frames_are_dumped_in_the_euroc_layout() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f");
    let o = hetsim(
        &[
            "frames",
            "scenarios/lab.toml",
            "--from",
            "1",
            "--to",
            "2",
            "--cameras",
            "child2,parent/omni",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    printed_digest(&o);
    let frames = out.join("frames");
    let mut robots: Vec<String> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    robots.sort();
    assert_eq!(
        robots,
        vec!["child2", "parent"],
        "only the cameras asked for"
    );
    // One EuRoC dataset per robot: child2's only camera is its cam0.
    let cam = frames.join("child2/mav0/cam0");
    let csv = std::fs::read_to_string(cam.join("data.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "#timestamp [ns],filename");
    // 2 Hz within [1 s, 2 s]: frames at 1.0, 1.5 and 2.0 s.
    assert_eq!(
        &lines[1..],
        &[
            "1000000000,1000000000.png",
            "1500000000,1500000000.png",
            "2000000000,2000000000.png"
        ]
    );
    for line in &lines[1..] {
        let name = line.split(',').nth(1).unwrap();
        let img = image::open(cam.join("data").join(name)).unwrap();
        assert_eq!((img.width(), img.height()), (120, 88));
        let depth = image::open(cam.join("depth").join(name)).unwrap();
        assert!(
            matches!(depth, image::DynamicImage::ImageLuma16(_)),
            "depth is 16-bit"
        );
        let d = depth.to_luma16();
        let seen = d.pixels().filter(|p| p.0[0] > 0).count();
        assert!(seen > 100, "depth has surfaces");
        assert!(
            d.pixels().all(|p| p.0[0] < 20_000),
            "millimetres inside an 8 x 4 m lab"
        );
    }
    let yaml = std::fs::read_to_string(cam.join("sensor.yaml")).unwrap();
    for key in [
        "sensor_type: camera",
        "T_BS:",
        "rate_hz: 2",
        "comment: hetsim camera child2/camera",
        "resolution: [120, 88]",
        "camera_model: pinhole",
        "intrinsics: [",
        "distortion_coefficients:",
    ] {
        assert!(yaml.contains(key), "{key} in {yaml}");
    }
    let tum = std::fs::read_to_string(cam.join("world_from_optical.tum")).unwrap();
    assert_eq!(tum.lines().count(), 3);
    for line in tum.lines() {
        assert_eq!(
            line.split(' ')
                .filter_map(|f| f.parse::<f64>().ok())
                .count(),
            8
        );
    }
    // The parent's laser is not a camera: its omnidirectional camera, the only one asked
    // for, is its cam0.
    let omni = std::fs::read_to_string(frames.join("parent/mav0/cam0/data.csv")).unwrap();
    assert_eq!(omni.lines().count(), 1 + 6, "5 Hz over [1, 2] s");
    let pano = image::open(frames.join("parent/mav0/cam0/data/1000000000.png")).unwrap();
    assert_eq!((pano.width(), pano.height()), (780, 580));
    assert!(
        !dir.path().read_dir().unwrap().any(|e| e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .starts_with(".frames")),
        "no staging left"
    );
}
