//! The full 600 s village of `scenarios/village.toml` (seed 1), as the README's main command
//! runs it, with the release build (about 8 minutes on two cores, alone): the seed's Fig. 7
//! result earned by the robot software (issue 17). The five-seed figures are in
//! `results/village/`.

use hetsim_eval::Metrics;
use hetsim_tests::{hetsim_release_bin, printed_digest, repo};
use std::process::Command;

/// The two-sided 95 % interval of one chi-square draw with 6 degrees of freedom (a pose's
/// NEES): its 2.5 % and 97.5 % quantiles, from any chi-square table.
const CHI2_6_95: (f64, f64) = (1.2373, 14.4494);

/// The run's digest on Mesa 22.3.6's lavapipe (the adapter and driver as the manifest records
/// them), the one `results/village/` holds for seed 1 and the README's main command gave on a
/// fresh machine: code that is only moved must keep it. Another adapter renders other pixels,
/// so its digest is reported and not compared. Regenerating it is legitimate only in a commit
/// of its own that says which change moved it and why (DESIGN.md, determinism contract).
const LAVAPIPE_DIGEST: (&str, &str, &str) = (
    "Vulkan",
    "llvmpipe Mesa 22.3.6 (LLVM 15.0.6)",
    "bd0ea7b8503b37a61176301e384a37b90e076f814c27bae7a483625671fb2a3a",
);
// It moved when the SLAM's RANSAC generators became rand_chacha's ChaCha8 instead of a
// hand-written LCG (issue 57; before: 12929424).

#[test]
fn the_full_village_earns_fig_7_with_consistent_covariances() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("village");
    let o = Command::new(hetsim_release_bin())
        .args([
            "run",
            "scenarios/village.toml",
            "--out",
            out.to_str().unwrap(),
        ])
        .current_dir(repo())
        .output()
        .expect("hetsim starts");
    let digest = printed_digest(&o);
    let manifest = hetsim_eval::manifest::Manifest::read(&out).unwrap();
    let (backend, driver) = manifest.adapter.as_ref().map_or(("none", "none"), |a| {
        (a.backend.as_str(), a.driver.as_str())
    });
    if (backend, driver) == (LAVAPIPE_DIGEST.0, LAVAPIPE_DIGEST.1) {
        assert_eq!(digest, LAVAPIPE_DIGEST.2, "the full village's digest moved");
    } else {
        eprintln!("village: no recorded digest for {backend} / {driver}; {digest} not compared");
    }
    let m = Metrics::read(&out).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(m.sim_secs.round(), 600.0);
    let ate = |kind: &str, robot: &str| {
        m.estimates
            .get(&format!("{kind}/{robot}"))
            .unwrap_or_else(|| panic!("{kind}/{robot}: {:?}", m.estimates))
            .ate_m
    };
    let slam = m.slam.as_ref().expect("metrics.json has a slam section");
    for robot in ["dala", "ressac"] {
        // Fig. 7: the cooperative estimate (rendezvous, image matching, the radio) below the
        // robot's own sub-map chain and its VO, after SE(3) alignment.
        let (coop, open, vo) = (
            ate("slam", robot),
            ate("slam-open", robot),
            ate("vo", robot),
        );
        assert!(coop < open && coop < vo, "{robot}: {coop} / {open} / {vo}");
        // Consistency: the run's time-averaged NEES of the pose. For a consistent filter
        // each second's NEES is a chi-square draw with 6 degrees of freedom; their average
        // over the run (correlated draws, mean 6) is less spread than one draw, so one
        // draw's 95 % interval is the loosest bound a consistent filter meets. (Before
        // issue 17 the first 60 s alone averaged 93 for Dala.)
        let nees = slam
            .robots
            .get(robot)
            .unwrap_or_else(|| panic!("no SLAM figures of {robot}"))
            .nees_mean;
        assert!(
            (CHI2_6_95.0..CHI2_6_95.1).contains(&nees),
            "{robot}: NEES {nees} outside {CHI2_6_95:?}"
        );
    }
    // Ressac's loop closes from images: accepted matches, none false (judged against the
    // truth by the evaluation: more than 2 m or 5 degrees off).
    let matching = slam
        .robots
        .get("ressac")
        .expect("SLAM figures of ressac")
        .matching
        .as_ref()
        .expect("ressac's image matching judged against the truth (matching)");
    assert!(!matching.links.is_empty(), "{matching:?}");
    assert_eq!(matching.false_matches, 0, "{matching:?}");
}
