//! `hetsim replay` end to end: a recorded run fed back to the robot software computes the
//! live run's bytes; a closed-loop mission replays with every command matching and stops at
//! the first divergence; a EuRoC dump feeds the VO; and each kind of damaged input is refused
//! with its file and where in it.

use hetsim_eval::Metrics;
use hetsim_tests::{hetsim, hetsim_release, printed_digest};
use std::path::Path;

/// Every file of a results folder by relative path, with its bytes.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    hetsim_tests::sweep_folder_files(dir)
}

fn file(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{}/{name}: {e}", dir.display()))
}

/// A results folder's metrics.json, typed.
fn metrics(dir: &Path) -> Metrics {
    Metrics::read(dir).unwrap_or_else(|e| panic!("{e}"))
}

fn ok(args: &[&str]) -> String {
    printed_digest(&hetsim(args, &[]))
}

/// The refusal's message, checking the exit status and that nothing was written.
fn refused(args: &[&str], out: &Path) -> String {
    let o = hetsim(args, &[]);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "{args:?} succeeded");
    assert!(!out.exists(), "{args:?} left {}", out.display());
    stderr
}

#[test]
fn a_replayed_village_computes_the_live_runs_bytes_and_a_changed_parameter_changes_them() {
    let tmp = tempfile::tempdir().unwrap();
    let (rec, live, replay) = (
        tmp.path().join("v.mcap"),
        tmp.path().join("live"),
        tmp.path().join("replay"),
    );
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let live_digest = ok(&[
        "run",
        "scenarios/village-short.toml",
        "--duration",
        "4",
        "--record",
        &s(&rec),
        "--out",
        &s(&live),
    ]);
    // Same messages, commands, radio traffic and outputs: the same run digest.
    let replay_digest = ok(&["replay", &s(&rec), "--out", &s(&replay)]);
    assert_eq!(replay_digest, live_digest);
    let (a, b) = (files(&live), files(&replay));
    assert_eq!(
        a.iter().map(|f| &f.0).collect::<Vec<_>>(),
        b.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        // The manifest names the renderer, which replay does not use.
        if name != "manifest.json" {
            assert!(x == y, "{name} differs between the live run and its replay");
        }
    }
    for robot in ["dala", "ressac"] {
        for kind in ["slam", "vo"] {
            let name = format!("{kind}/{robot}.tum");
            assert!(file(&live, &name).len() > 1000, "{name} has poses");
        }
    }
    // One robot alone: the other's recorded radio messages still reach it, so its SLAM
    // computes the same bytes.
    let alone = tmp.path().join("alone");
    ok(&["replay", &s(&rec), "--robot", "dala", "--out", &s(&alone)]);
    for name in ["slam/dala.tum", "vo/dala.tum"] {
        assert!(file(&live, name) == file(&alone, name), "{name}");
    }
    // Ressac alone: its estimates are in Dala's frame, which the evaluation places in the
    // world by Dala's first origin though Dala publishes no report here (Ressac's report
    // names its stamp); every one of them lands where the live run put it.
    let ressac = tmp.path().join("ressac");
    ok(&[
        "replay",
        &s(&rec),
        "--robot",
        "ressac",
        "--out",
        &s(&ressac),
    ]);
    for name in ["slam/ressac.tum", "slam-open/ressac.tum", "vo/ressac.tum"] {
        assert!(file(&live, name) == file(&ressac, name), "{name}");
    }
    // Robot software reads no truth: with every oracle message withheld from both robots
    // (their pilots, which steer by the oracle, then stand still, so commands are not
    // compared), the SLAM and VO of both compute the same bytes, through the rendezvous and
    // the radio exchange of graphs and key frames, and send the same radio traffic.
    let blind = tmp.path().join("blind");
    ok(&["replay", &s(&rec), "--withhold-truth", "--out", &s(&blind)]);
    for robot in ["dala", "ressac"] {
        for kind in ["slam", "slam-open", "vo"] {
            let name = format!("{kind}/{robot}.tum");
            assert!(
                file(&live, &name) == file(&blind, &name),
                "{name} changed with the truth withheld"
            );
        }
    }
    assert!(file(&live, "map.ply") == file(&blind, "map.ply"));
    let blind_m = metrics(&blind);
    let live_m = metrics(&live);
    assert!(live_m.comms.sent > 0, "{:?}", live_m.comms);
    assert_eq!(blind_m.comms, live_m.comms, "the radio traffic changed");
    assert_eq!(blind_m.slam, live_m.slam);
    // ... while the oracle did reach them in the live run, and not in this replay.
    for robot in ["dala", "ressac"] {
        let topic = format!("{robot}/truth");
        let live_truth = live_m
            .messages
            .get(&topic)
            .copied()
            .unwrap_or_else(|| panic!("no {topic} messages in the live run"));
        assert!(live_truth > 0, "{topic}");
        assert!(
            !blind_m.messages.contains_key(&topic),
            "{topic} was withheld"
        );
    }
    // A SLAM parameter changed: the pilots' commands still match (they fly on the oracle),
    // the SLAM's estimate changes.
    let tuned = tmp.path().join("tuned");
    ok(&[
        "replay",
        &s(&rec),
        "--set",
        "robots.dala.slam.sigma_px=4.0",
        "--out",
        &s(&tuned),
    ]);
    assert!(file(&live, "slam/dala.tum") != file(&tuned, "slam/dala.tum"));
    assert!(
        file(&live, "vo/dala.tum") == file(&tuned, "vo/dala.tum"),
        "VO has no sigma_px"
    );
    // The radio is modelled again, not replayed: with every message lost, Ressac never
    // receives Dala's graph, so its SLAM estimate changes and its VO does not. (Never
    // linked to Dala, its VO is placed in the world by its own first pose instead of the
    // rendezvous, so the VO is compared by what does not depend on where its frame lies:
    // the aligned ATE and the RPE.)
    let lossy = tmp.path().join("lossy");
    ok(&[
        "replay",
        &s(&rec),
        "--set",
        "comms.loss=1.0",
        "--out",
        &s(&lossy),
    ]);
    assert!(file(&live, "slam/ressac.tum") != file(&lossy, "slam/ressac.tum"));
    let lossy_m = metrics(&lossy);
    let live_vo = live_m
        .estimates
        .get("vo/ressac")
        .expect("a vo/ressac estimate in the live run");
    let lossy_vo = lossy_m
        .estimates
        .get("vo/ressac")
        .expect("a vo/ressac estimate in the lossy run");
    for (field, a, b) in [
        ("ate_m", live_vo.ate_m, lossy_vo.ate_m),
        ("rpe_1s_m", live_vo.rpe_1s_m, lossy_vo.rpe_1s_m),
        ("length_m", live_vo.length_m, lossy_vo.length_m),
    ] {
        assert!(
            (a - b).abs() < 1e-9,
            "vo/ressac {field}: {a} live, {b} lossy"
        );
    }
    assert!(lossy_m.comms.dropped_loss > 0, "{:?}", lossy_m.comms);
    // A setting that is not a field is refused by the robot file's loader.
    let bad = tmp.path().join("bad");
    let e = refused(
        &[
            "replay",
            &s(&rec),
            "--set",
            "robots.dala.slam.sigma_pix=4",
            "--out",
            &s(&bad),
        ],
        &bad,
    );
    assert!(e.contains("sigma_pix"), "{e}");
    // The calibration's settings reach the SLAM (VO's covariance in the local map changes
    // the open loop), and a drift out of range is refused naming its field and value. (The
    // VO's own estimate does not change, but where the first link places it does.)
    let scaled = tmp.path().join("scaled");
    ok(&[
        "replay",
        &s(&rec),
        "--set",
        "robots.ressac.slam.vo_covariance_scale=10",
        "--set",
        "robots.ressac.slam.edge_drift.translation=[0.02,0.02,0.02]",
        "--out",
        &s(&scaled),
    ]);
    assert!(file(&live, "slam-open/ressac.tum") != file(&scaled, "slam-open/ressac.tum"));
    let e = refused(
        &[
            "replay",
            &s(&rec),
            "--set",
            "robots.ressac.slam.edge_drift.translation=[0.02,-1,0.02]",
            "--out",
            &s(&bad),
        ],
        &bad,
    );
    assert!(
        e.contains("edge_drift.translation") && e.contains("-1"),
        "{e}"
    );
    // Another tick would feed the recorded messages at other ticks: refused.
    let e = refused(
        &[
            "replay",
            &s(&rec),
            "--set",
            "dt_secs=0.005",
            "--out",
            &s(&bad),
        ],
        &bad,
    );
    assert!(e.contains("recorded with a 10000000 ns tick"), "{e}");

    // Damaged recordings, each refused with the file and the byte.
    let bytes = std::fs::read(&rec).unwrap();
    let cut = tmp.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = refused(&["replay", &s(&cut), "--out", &s(&bad)], &bad);
    assert!(
        e.contains("cut.mcap: at byte") && e.contains("truncated"),
        "{e}"
    );
    let mut flipped = bytes.clone();
    let middle = bytes.len() / 2;
    for b in &mut flipped[middle..middle + 8] {
        *b ^= 0x5a;
    }
    let flip = tmp.path().join("flip.mcap");
    std::fs::write(&flip, &flipped).unwrap();
    let e = refused(&["replay", &s(&flip), "--out", &s(&bad)], &bad);
    // In the middle of the file is a chunk of images: its CRC, or its zstd frame, fails.
    assert!(
        e.contains("flip.mcap: at byte") && e.contains("the chunk"),
        "{e}"
    );
    // A byte outside the chunks: the robot file the recording carries, Dala's 60 degree
    // field of view made 40. Caught by the data section's CRC before anything is written.
    let at = bytes
        .windows(15)
        .position(|w| w == b"hfov_deg = 60.0")
        .expect("the recording carries dala's robot file");
    let mut edited = bytes.clone();
    edited[at + 11] = b'4';
    let meta = tmp.path().join("meta.mcap");
    std::fs::write(&meta, &edited).unwrap();
    let e = refused(&["replay", &s(&meta), "--out", &s(&bad)], &bad);
    assert!(
        e.contains("meta.mcap: at byte 0: the data section's CRC"),
        "{e}"
    );
    let not_mcap = tmp.path().join("notes.mcap");
    std::fs::write(&not_mcap, b"hello").unwrap();
    let e = refused(&["replay", &s(&not_mcap), "--out", &s(&bad)], &bad);
    assert!(e.contains("notes.mcap: at byte 0: not an MCAP file"), "{e}");
    // A channel of a schema hetsim does not know, in an otherwise valid recording.
    let odd = tmp.path().join("odd.mcap");
    with_unknown_schema(&bytes, &odd);
    let e = refused(&["replay", &s(&odd), "--out", &s(&bad)], &bad);
    assert!(
        e.contains("odd.mcap: at byte")
            && e.contains("\"foo_msgs/msg/Bar\" is not one hetsim replays"),
        "{e}"
    );
}

/// A copy of a recording with one more channel, `/dala/thing` of schema `foo_msgs/msg/Bar`,
/// and a message on it.
fn with_unknown_schema(recording: &[u8], to: &Path) {
    let summary = mcap::read::Summary::read(recording).unwrap().unwrap();
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(std::io::BufWriter::new(std::fs::File::create(to).unwrap()))
        .unwrap();
    for index in &summary.metadata_indexes {
        w.write_metadata(&mcap::read::metadata(recording, index).unwrap())
            .unwrap();
    }
    let channel = mcap::Channel {
        id: 999,
        topic: "/dala/thing".into(),
        schema: Some(std::sync::Arc::new(mcap::Schema {
            id: 999,
            name: "foo_msgs/msg/Bar".into(),
            encoding: "ros2msg".into(),
            data: std::borrow::Cow::Borrowed(b"int32 x\n"),
        })),
        message_encoding: "cdr".into(),
        metadata: Default::default(),
    };
    w.write(&mcap::Message {
        channel: std::sync::Arc::new(channel),
        sequence: 1,
        log_time: 0,
        publish_time: 0,
        data: std::borrow::Cow::Borrowed(&[0, 1, 0, 0, 7, 0, 0, 0]),
    })
    .unwrap();
    for m in mcap::MessageStream::new(recording).unwrap() {
        w.write(&m.unwrap()).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn a_replayed_coverage_mission_sends_every_recorded_command_or_stops_at_the_first_other() {
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    // The whole mission, rendered: the children grab their images, the parent teleoperates
    // them to every vertex, and the run ends two seconds after the parent says it is over.
    // The release build, as the golden runs: a whole mission and its replay. The recording
    // is golden's Vulkan lab run (crate::shared); on a machine without Vulkan, one of its own
    // on the default backend.
    let release = |args: &[&str]| printed_digest(&hetsim_release(args, &[]));
    let shared = crate::shared::recorded_lab_on_vulkan();
    let (rec, live, live_digest) = if shared.had_no_adapter() {
        let (rec, live) = (tmp.path().join("lab.mcap"), tmp.path().join("live"));
        let digest = release(&[
            "run",
            "scenarios/lab.toml",
            "--record",
            &s(&rec),
            "--out",
            &s(&live),
        ]);
        (rec, live, digest)
    } else {
        (
            shared.recording.clone(),
            shared.out.clone(),
            printed_digest(&shared.output),
        )
    };
    let m = metrics(&live);
    assert_eq!(
        m.team.as_ref().map(|t| t.imaged_fraction),
        Some(1.0),
        "the mission images every vertex"
    );
    // The parent's plan, its orders over the radio and the children's driving and grabs:
    // every command the replayed stacks send is the recorded one (replay checks each), the
    // replay ends where the mission ended, and the digest is the live run's.
    let replay = tmp.path().join("replay");
    assert_eq!(
        release(&["replay", &s(&rec), "--out", &s(&replay)]),
        live_digest
    );
    // A child that drives faster sends other wheel speeds: the replay stops there.
    let bad = tmp.path().join("bad");
    let e = refused(
        &[
            "replay",
            &s(&rec),
            "--set",
            "robots.child1.pilot.cruise_mps=0.12",
            "--out",
            &s(&bad),
        ],
        &bad,
    );
    assert!(
        e.contains("replay diverged at t = ")
            && e.contains("robot child1 sent")
            && e.contains("on /child1/cmd"),
        "{e}"
    );
    // A JSON recording is not one replay reads, and says which one is.
    let json = tmp.path().join("lab.json.mcap");
    ok(&[
        "run",
        "scenarios/lab.toml",
        "--duration",
        "1",
        "--no-render",
        "--record",
        &s(&json),
        "--record-encoding",
        "json",
        "--out",
        &s(&tmp.path().join("json")),
    ]);
    let e = refused(&["replay", &s(&json), "--out", &s(&bad)], &bad);
    assert!(e.contains("hetsim replays ROS 2 recordings"), "{e}");
    // Nothing else reads the recording (golden reads the results folder): 2.2 GB freed.
    std::fs::remove_file(&rec).unwrap_or_else(|e| panic!("{}: {e}", rec.display()));
}

#[test]
fn a_euroc_dump_replays_into_the_vo_and_a_missing_image_is_refused_with_its_row() {
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let live = tmp.path().join("live");
    ok(&[
        "run",
        "scenarios/village-short.toml",
        "--duration",
        "3",
        "--dump-frames",
        "--out",
        &s(&live),
    ]);
    let mav0 = live.join("frames/dala/mav0");
    let replay = tmp.path().join("replay");
    ok(&[
        "replay",
        &s(&mav0),
        "--scenario",
        "scenarios/village-short.toml",
        "--robot",
        "dala",
        "--out",
        &s(&replay),
    ]);
    // The VO sees the same images at the same ticks: the same estimate, byte for byte. The
    // live run ended before its robots read the frames of its last tick; the replay reads
    // them, one pose more.
    let (a, b) = (file(&live, "vo/dala.tum"), file(&replay, "vo/dala.tum"));
    assert!(
        a.len() > 1000 && b.starts_with(&a),
        "the live estimate is the replay's start"
    );
    let more = String::from_utf8_lossy(&b[a.len()..]).into_owned();
    assert!(
        more.lines().count() == 1 && more.starts_with("3.000000000 "),
        "{more}"
    );
    // Without --scenario, or into the wrong bench, the dataset is refused.
    let bad = tmp.path().join("bad");
    let e = refused(
        &["replay", &s(&mav0), "--robot", "dala", "--out", &s(&bad)],
        &bad,
    );
    assert!(e.contains("--scenario"), "{e}");
    let e = refused(
        &[
            "replay",
            &s(&mav0),
            "--scenario",
            "scenarios/village.toml",
            "--robot",
            "dala",
            "--out",
            &s(&bad),
        ],
        &bad,
    );
    assert!(
        e.contains("cam0/sensor.yaml: resolution [512.0, 384.0]"),
        "{e}"
    );
    // A damaged row, then a missing image: each named with its file and row.
    let csv = mav0.join("cam0/data.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut rows: Vec<String> = text.lines().map(str::to_string).collect();
    let name = rows[3].split(',').nth(1).unwrap().to_string();
    let good = rows[3].clone();
    rows[3] = format!("12x4,{name}");
    std::fs::write(&csv, rows.join("\n")).unwrap();
    let args = [
        "replay",
        &s(&mav0),
        "--scenario",
        "scenarios/village-short.toml",
        "--robot",
        "dala",
        "--out",
        &s(&bad),
    ];
    let e = refused(&args, &bad);
    assert!(
        e.contains("cam0/data.csv: row 4: timestamp \"12x4\""),
        "{e}"
    );
    rows[3] = good;
    std::fs::write(&csv, rows.join("\n")).unwrap();
    // An image that is not a PNG: found when replay reaches it, named with its row.
    let png = mav0.join("cam0/data").join(&name);
    let original = std::fs::read(&png).unwrap();
    std::fs::write(&png, b"not a png").unwrap();
    let e = refused(&args, &bad);
    assert!(e.contains("cam0/data.csv: row 4: left image"), "{e}");
    std::fs::write(&png, original).unwrap();
    std::fs::remove_file(&png).unwrap();
    let e = refused(&args, &bad);
    assert!(
        e.contains(&format!("cam0/data.csv: row 4: image {name} is missing")),
        "{e}"
    );
}

#[test]
fn a_sweep_over_a_recording_replays_each_setting() {
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let (rec, live) = (tmp.path().join("rec.mcap"), tmp.path().join("live"));
    ok(&[
        "run",
        "scenarios/village-short.toml",
        "--duration",
        "3",
        "--record",
        &s(&rec),
        "--out",
        &s(&live),
    ]);
    let sweep = tmp.path().join("sweep.toml");
    let text = r#"schema_version = 1
name = "replayed"
kind = "run"
recording = "rec.mcap"
seeds = 1
metrics = ["estimates.slam/dala.ate_m", "estimates.vo/dala.ate_m"]
[axes]
"models.dala.slam.sigma_px" = [1.0, 4.0]
"#;
    std::fs::write(&sweep, text).unwrap();
    let out = tmp.path().join("out");
    let o = hetsim(
        &["sweep", &s(&sweep), "--out", &s(&out), "--jobs", "2"],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 2, "{csv}");
    // Columns: run, the axis, seed, digest, then the metrics.
    let (slam, vo) = ((rows[0][4], rows[1][4]), (rows[0][5], rows[1][5]));
    assert_eq!(vo.0, vo.1, "the VO does not use sigma_px: {csv}");
    assert_ne!(slam.0, slam.1, "the SLAM does: {csv}");
    // sigma_px 1.0 is the robot file's: that replay is the live run.
    assert!(file(&live, "slam/dala.tum") == file(&out.join("runs/000000"), "slam/dala.tum"));
    // A recording carries its scenario: a base beside it is refused, by name.
    std::fs::write(
        &sweep,
        text.replace("seeds = 1", "seeds = 1\nbase = \"x.toml\""),
    )
    .unwrap();
    let o = hetsim(
        &["sweep", &s(&sweep), "--out", &s(&tmp.path().join("no"))],
        &[],
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("field `base`") && e.contains("carries its scenario"),
        "{e}"
    );
}
