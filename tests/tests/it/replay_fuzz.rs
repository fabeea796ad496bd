//! Replay never panics on a damaged recording: a lab recording rewritten without CRCs or
//! compression (so that flipped bytes reach the record parser and the CDR decoders
//! instead of being caught by a CRC), then bytes flipped at random, 1,000 times: each replay
//! ends with its results or with an error, never a panic.

use hetsim_io::McapRecording;
use hetsim_scene::{load_scenario_text, LoadOptions};
use rand::{RngExt, SeedableRng};

/// A copy of `bytes` with no chunk or data-section CRCs and no compression.
fn unprotected(bytes: &[u8]) -> Vec<u8> {
    let summary = mcap::read::Summary::read(bytes).unwrap().unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::WriteOptions::new()
            .profile("ros2")
            .compression(None)
            .calculate_chunk_crcs(false)
            .calculate_data_section_crc(false)
            .chunk_size(Some(4096))
            .create(&mut out)
            .unwrap();
        for index in &summary.metadata_indexes {
            w.write_metadata(&mcap::read::metadata(bytes, index).unwrap())
                .unwrap();
        }
        for m in mcap::MessageStream::new(bytes).unwrap() {
            w.write(&m.unwrap()).unwrap();
        }
        w.finish().unwrap();
    }
    out.into_inner()
}

/// Opens and replays a recording in-process; what it ends with, as text.
fn replay(path: &std::path::Path) -> Result<u64, String> {
    let mut rec = McapRecording::open(path).map_err(|e| e.to_string())?;
    let run = rec.run.clone();
    let s = load_scenario_text(
        &run.scenario_path,
        run.scenario_text.clone(),
        &LoadOptions {
            seed: Some(run.seed),
            duration_secs: Some(run.duration_secs.min(2.0)),
            robot_files: Some(run.robot_files.clone()),
        },
    )
    .map_err(|e| e.to_string())?;
    let stacks = hetsim_stacks::build_stacks(&s, false)
        .into_iter()
        .map(Some)
        .collect();
    hetsim_engine::replay(&s, stacks, &mut rec, |_, _| {})
        .map(|o| o.ticks)
        .map_err(|e| e.to_string())
}

#[test]
fn flipped_bytes_in_a_recording_give_an_error_or_a_replay_never_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("lab.mcap");
    let o = hetsim_tests::hetsim(
        &[
            "run",
            "scenarios/lab.toml",
            "--duration",
            "2",
            "--no-render",
            "--record",
            rec.to_str().unwrap(),
            "--out",
            tmp.path().join("live").to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let clean = unprotected(&std::fs::read(&rec).unwrap());
    let path = tmp.path().join("clean.mcap");
    std::fs::write(&path, &clean).unwrap();
    if let Err(e) = replay(&path) {
        panic!("the rewritten recording replays: {e}");
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    let (mut refused, mut replayed) = (0, 0);
    for case in 0..1000 {
        let mut bytes = clean.clone();
        for _ in 0..rng.random_range(1..=8) {
            let at = rng.random_range(8..bytes.len() - 8);
            bytes[at] ^= 1 << rng.random_range(0..8);
        }
        let path = tmp.path().join(format!("case-{case}.mcap"));
        std::fs::write(&path, &bytes).unwrap();
        match replay(&path) {
            Ok(_) => replayed += 1,
            Err(e) => {
                assert!(!e.is_empty());
                refused += 1;
            }
        }
        std::fs::remove_file(&path).unwrap();
    }
    println!("1000 damaged recordings: {refused} refused, {replayed} replayed");
    assert!(refused > 0, "flipped bytes were never noticed");
}
