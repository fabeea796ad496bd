//! The village over several seeds (Fig. 7 of seed 000 as mean ± sample standard deviation, the
//! image matches judged, and the Monte Carlo consistency test of the robot pose's NEES).
//!
//! Consistency as Bar-Shalom tests it for `N` independent runs: at each time, the NEES
//! averaged over the runs, times `N`, is chi-square with `6N` degrees of freedom for a
//! consistent 6-degree-of-freedom estimate; the fraction of times inside its two-sided 95 %
//! interval should be at least 95 %.

use super::{copy, Files};
use crate::manifest::Manifest;
use crate::slam::RobotSlam;
use crate::stats::MeanStd;
use crate::{EvalError, Metrics};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// The chi-square quantile with `k` degrees of freedom (statrs' inverse CDF).
pub fn chi2_quantile(p: f64, k: f64) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    ChiSquared::new(k)
        .expect("positive degrees of freedom")
        .inverse_cdf(p)
}

/// One run's figures that the seeds section reads.
struct Run {
    seed: u64,
    metrics: Metrics,
    path: PathBuf,
}

impl Run {
    fn read(dir: &Path) -> Result<Self, EvalError> {
        Ok(Self {
            seed: Manifest::read(dir)?.seed,
            metrics: Metrics::read(dir)?,
            path: dir.join("metrics.json"),
        })
    }

    /// The SLAM section of `robot`, or an error naming the file and the field.
    fn robot(&self, robot: &str) -> Result<&RobotSlam, EvalError> {
        self.metrics
            .slam
            .as_ref()
            .and_then(|s| s.robots.get(robot))
            .ok_or_else(|| self.missing(&format!("slam.robots.{robot}")))
    }

    /// The ATE of the estimate `kind/robot`, aligned and unaligned.
    fn ate(&self, kind: &str, robot: &str) -> Result<(f64, f64), EvalError> {
        let key = format!("{kind}/{robot}");
        let a = self
            .metrics
            .estimates
            .get(&key)
            .ok_or_else(|| self.missing(&format!("estimates.{key}")))?;
        Ok((a.ate_m, a.ate_unaligned_m))
    }

    fn missing(&self, dotted: &str) -> EvalError {
        EvalError::Content {
            path: self.path.clone(),
            message: format!("no field `{dotted}` (is this a village run's results folder?)"),
        }
    }
}

/// Every run's `metrics.json`, `manifest.json` and `timing.json` (where it has one), as
/// `seeds/seed-<seed>/<file>`: the page's per-seed figures can be checked against them.
pub fn run_files(dirs: &[PathBuf]) -> Result<Files, EvalError> {
    let mut files = Vec::new();
    for dir in dirs {
        let seed = Manifest::read(dir)?.seed;
        for name in ["metrics.json", "manifest.json", "timing.json"] {
            if name == "timing.json" && !dir.join(name).exists() {
                continue;
            }
            files.push((format!("seeds/seed-{seed}/{name}"), copy(dir, name)?));
        }
    }
    Ok(files)
}

/// The seeds section of the page and its figures, from the runs' folders (the same scenario
/// with different seeds).
pub fn section(dirs: &[PathBuf]) -> Result<(String, Files), EvalError> {
    let runs = dirs
        .iter()
        .map(|d| Run::read(d))
        .collect::<Result<Vec<_>, _>>()?;
    let robots: Vec<String> = runs[0]
        .metrics
        .slam
        .as_ref()
        .map(|s| s.robots.keys().cloned().collect())
        .unwrap_or_default();
    let mut md = String::new();
    let means = accuracy(&mut md, &runs, &robots)?;
    fig7_order(&mut md, &means);
    matching(&mut md, &runs, &robots)?;
    let files = consistency(&mut md, &runs, &robots)?;
    edge_drift(&mut md, &runs, &robots)?;
    for robot in &robots {
        let _ = writeln!(md, "\n![NEES over time, {robot}](nees-{robot}.png)");
    }
    Ok((md, files))
}

/// The mean ATE, aligned and unaligned, of each robot's slam, slam-open and vo.
type Means = BTreeMap<String, Vec<(f64, f64)>>;

/// Every estimate's ATE over the seeds: mean ± sample deviation, and every seed's value.
fn accuracy(md: &mut String, runs: &[Run], robots: &[String]) -> Result<Means, EvalError> {
    let seeds: Vec<String> = runs.iter().map(|r| r.seed.to_string()).collect();
    let _ = writeln!(
        md,
        "\n## Over {} seeds\n\nSeeds {} of the same scenario, each run whole. Mean ± sample \
         standard deviation over the seeds; every value per seed in the last columns. ATE \
         aligned: after SE(3) alignment of the whole trajectory; unaligned: in Dala's frame, \
         which the evaluation places in the world by Dala's true first pose. A robot's \
         open loop and VO have no events: they lie in Dala's frame where the robot's first \
         link (the rendezvous) put its first origin, as its cooperative estimate starts.\n",
        runs.len(),
        seeds.join(", ")
    );
    let _ = writeln!(
        md,
        "| robot | estimate | ATE aligned m | ATE unaligned m | per seed, aligned / unaligned |\n|---|---|---|---|---|"
    );
    let mut ordered = BTreeMap::new();
    for robot in robots {
        let mut means = Vec::new();
        for kind in ["slam", "slam-open", "vo"] {
            let (a, u): (Vec<f64>, Vec<f64>) = runs
                .iter()
                .map(|r| r.ate(kind, robot))
                .collect::<Result<Vec<_>, _>>()?
                .into_iter()
                .unzip();
            let (MeanStd { mean: am, std: asd }, MeanStd { mean: um, std: usd }) =
                (MeanStd::sample(&a), MeanStd::sample(&u));
            means.push((am, um));
            let per: Vec<String> = a
                .iter()
                .zip(&u)
                .map(|(x, y)| format!("{x:.2} / {y:.2}"))
                .collect();
            let _ = writeln!(
                md,
                "| {robot} | {kind} | {am:.2} ± {asd:.2} | {um:.2} ± {usd:.2} | {} |",
                per.join(", ")
            );
        }
        ordered.insert(robot.clone(), means);
    }
    Ok(ordered)
}

/// Whether the seed's Fig. 7 order (cooperative < open loop < VO) holds on the means.
fn fig7_order(md: &mut String, means: &Means) {
    let _ = writeln!(
        md,
        "\nThe seed's Fig. 7 result, cooperative below open loop below VO, on the means:\n"
    );
    for (robot, m) in means {
        let holds = |f: fn(&(f64, f64)) -> f64| f(&m[0]) < f(&m[1]) && f(&m[1]) < f(&m[2]);
        let verdict = |h: bool| if h { "holds" } else { "**does not hold**" };
        let _ = writeln!(
            md,
            "- {robot}: aligned {}, unaligned {}",
            verdict(holds(|x| x.0)),
            verdict(holds(|x| x.1)),
        );
    }
}

/// Image matching per robot and seed, judged against the truth.
fn matching(md: &mut String, runs: &[Run], robots: &[String]) -> Result<(), EvalError> {
    let _ = writeln!(
        md,
        "\n## Image matching over the seeds\n\nAccepted matches, how many were false (more \
         than 2 m or 5 degrees from the true relative pose), the passes over a key frame the \
         truth says could match and how many of them got a match, were missed, or came \
         within 30 s of the robot's last match (it waits by design); and the first match's \
         altitude correction.\n"
    );
    let _ = writeln!(
        md,
        "| robot | seed | attempts | accepted | false | gated | passes found / missed / waiting | first match: time s, error before -> after m, altitude m |\n|---|---|---|---|---|---|---|---|"
    );
    for robot in robots {
        for r in runs {
            let s = r.robot(robot)?;
            let c = |k: &str| s.counters.get(k).copied().unwrap_or(0);
            let m = s.matching.clone().unwrap_or_default();
            let first =
                s.events
                    .iter()
                    .find(|e| e.kind == "image_match")
                    .map_or("-".to_string(), |e| {
                        format!(
                            "{:.1}, {:.2} -> {:.2}, {:.2} -> {:.2}",
                            e.time_s,
                            e.error_before_m,
                            e.error_after_m,
                            e.altitude_error_before_m,
                            e.altitude_error_after_m
                        )
                    });
            let _ = writeln!(
                md,
                "| {robot} | {} | {} | {} | {} | {} | {} / {} / {} | {first} |",
                r.seed,
                c("match_attempts"),
                c("matches_accepted"),
                m.false_matches,
                c("matches_gated"),
                m.found,
                m.missed,
                m.waiting,
            );
        }
    }
    Ok(())
}

/// The Monte Carlo consistency test of the robot pose's NEES, per robot, with its figures
/// and the per-axis table.
fn consistency(md: &mut String, runs: &[Run], robots: &[String]) -> Result<Files, EvalError> {
    let n = runs.len();
    let (lo, hi) = (
        chi2_quantile(0.025, 6.0 * n as f64) / n as f64,
        chi2_quantile(0.975, 6.0 * n as f64) / n as f64,
    );
    let _ = writeln!(
        md,
        "\n## Consistency over the seeds\n\nThe robot pose's NEES at every whole second, \
         averaged over the {n} runs: consistent where it lies within [{lo:.2}, {hi:.2}] \
         (chi-square with {} degrees of freedom over {n}, two-sided 95 %) at 95 % of the \
         times or more. The mean over the whole run is judged against the same interval: one \
         run's poses are correlated in time, and treating them as one sample per run is the \
         cautious reading (as independent samples, the interval would narrow to about a \
         tenth around 6).\n",
        6 * n
    );
    let _ = writeln!(
        md,
        "| robot | times | inside | below | above | mean of the averaged NEES | mean within the interval | median |\n|---|---|---|---|---|---|---|---|"
    );
    let mut files = Vec::new();
    let mut axis_rows = Vec::new();
    for robot in robots {
        let avg = averaged_nees(runs, robot)?;
        let inside = avg.iter().filter(|(_, v)| *v >= lo && *v <= hi).count();
        let below = avg.iter().filter(|(_, v)| *v < lo).count();
        let mut sorted: Vec<f64> = avg.iter().map(|p| p.1).collect();
        sorted.sort_by(f64::total_cmp);
        let median = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
        let mean = sorted.iter().sum::<f64>() / sorted.len().max(1) as f64;
        let pct = |k: usize| 100.0 * k as f64 / avg.len().max(1) as f64;
        let _ = writeln!(
            md,
            "| {robot} | {} | {:.1} % | {:.1} % | {:.1} % | {mean:.2} | {} | {median:.2} |",
            avg.len(),
            pct(inside),
            pct(below),
            pct(avg.len() - inside - below),
            if (lo..=hi).contains(&mean) {
                "yes"
            } else if mean < lo {
                "no (below)"
            } else {
                "no (above)"
            }
        );
        let mut axes = [0.0; 6];
        for r in runs {
            let robot_axes = r.robot(robot)?.nees_axes;
            for (a, v) in axes.iter_mut().zip(robot_axes) {
                *a += v / n as f64;
            }
        }
        axis_rows.push(format!(
            "| {robot} | {} |",
            axes.map(|a| format!("{a:.2}")).join(" | ")
        ));
        let name = format!("nees-{robot}.png");
        files.push((name, crate::charts::nees_png(robot, &avg, (lo, hi), n)));
    }
    let _ = writeln!(
        md,
        "\nWhich term is overconfident: each axis's squared error over its own variance \
         (1 expected), averaged over the poses and the seeds; position in the body frame \
         (x forward, y left, z up), then rotation.\n\n| robot | x | y | z | roll | pitch | yaw |\n|---|---|---|---|---|---|---|\n{}",
        axis_rows.join("\n")
    );
    Ok(files)
}

/// `robot`'s NEES at each whole second that every run has, averaged over the runs.
fn averaged_nees(runs: &[Run], robot: &str) -> Result<Vec<(f64, f64)>, EvalError> {
    let n = runs.len();
    let mut by_time: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
    for r in runs {
        for (t, v) in &r.robot(robot)?.nees_series {
            by_time.entry(t.round() as i64).or_default().push(*v);
        }
    }
    Ok(by_time
        .iter()
        .filter(|(_, v)| v.len() == n)
        .map(|(t, v)| (*t as f64, v.iter().sum::<f64>() / n as f64))
        .collect())
}

/// The open-loop sub-map edges' drift, fitted per axis over every run's edges.
fn edge_drift(md: &mut String, runs: &[Run], robots: &[String]) -> Result<(), EvalError> {
    let _ = writeln!(
        md,
        "\nThe drift of the open-loop sub-map edges against the truth, fitted per axis over \
         every edge of the {} runs (`hetsim_eval::drift`, a moment fit; edges of {} m or more): the \
         random-walk part of what the SLAM's `EdgeDrift` models, set from the calibration \
         seeds (`robots/slam/src/stack/params.rs`).\n\n| robot | edges | x % | y % | z % | \
         roll °/m | pitch °/m | yaw °/m |\n|---|---|---|---|---|---|---|---|",
        runs.len(),
        crate::drift::MIN_EDGE_M
    );
    for robot in robots {
        let fits = runs
            .iter()
            .map(|r| Ok(r.robot(robot)?.edge_drift.clone()))
            .collect::<Result<Vec<_>, EvalError>>()?;
        let f = crate::drift::EdgeDriftFit::pool(&fits);
        if f.edges == 0 {
            let _ = writeln!(md, "| {robot} | 0 | - | - | - | - | - | - |");
            continue;
        }
        let _ = writeln!(
            md,
            "| {robot} | {} | {} | {} |",
            f.edges,
            f.translation
                .map(|x| format!("{:.3}", 100.0 * x))
                .join(" | "),
            f.rotation_deg_per_m.map(|x| format!("{x:.4}")).join(" | ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the chi-square tables (Abramowitz and Stegun, Table 26.8).
    #[test]
    fn chi_square_quantiles_match_the_tables() {
        for (p, k, table) in [
            (0.025, 30.0, 16.791),
            (0.975, 30.0, 46.979),
            (0.025, 12.0, 4.4038),
            (0.975, 12.0, 23.337),
        ] {
            let q = chi2_quantile(p, k);
            // The tables give five significant digits.
            assert!(
                (q / table - 1.0).abs() < 1e-4,
                "chi2({p}, {k}) = {q}, table {table}"
            );
        }
    }

    fn run(dir: &Path, seed: u64, ate: [f64; 2], nees: &[f64]) {
        use super::super::tests::{accuracy, manifest, metrics, robot, run_folder};
        let mut dala = robot(Vec::new());
        (dala.nees_mean, dala.nees_poses, dala.submaps) = (6.0, 100, 3);
        dala.nees_series = nees
            .iter()
            .enumerate()
            .map(|(k, v)| (k as f64, *v))
            .collect();
        dala.counters = [
            ("match_attempts".to_string(), 4),
            ("matches_accepted".to_string(), 1),
        ]
        .into();
        dala.matching = Some(crate::matching::MatchingMetrics {
            passes: 2,
            found: 1,
            missed: 1,
            ..Default::default()
        });
        let m = metrics(
            vec![("dala", dala)],
            vec![
                ("slam/dala", accuracy(100.0, ate[0])),
                ("slam-open/dala", accuracy(100.0, ate[1])),
                ("vo/dala", accuracy(100.0, ate[1] + 1.0)),
            ],
        );
        run_folder(dir, &m, &manifest(seed, Vec::new()));
    }

    /// Two seeds: the means and sample deviations, the order of Fig. 7, and the Monte Carlo
    /// test against chi-square(12)/2's 95 % interval [2.20, 11.67] (tables).
    #[test]
    fn the_seeds_section_gives_spreads_and_the_consistency_test() {
        let tmp = tempfile::tempdir().unwrap();
        let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
        // Ten whole seconds; the averages: eight at 6, one at 20 (above), one at 1 (below).
        let mut na = vec![6.0; 10];
        let mut nb = vec![6.0; 10];
        (na[3], nb[3]) = (30.0, 10.0);
        (na[7], nb[7]) = (1.0, 1.0);
        run(&a, 1, [1.0, 3.0], &na);
        run(&b, 2, [3.0, 5.0], &nb);
        let out = tmp.path().join("page");
        super::super::village_report(&[a, b], &out).unwrap();
        let md = std::fs::read_to_string(out.join("README.md")).unwrap();
        // ATE 1 and 3: mean 2, sample deviation sqrt(2) = 1.41; unaligned twice that.
        assert!(
            md.contains("| dala | slam | 2.00 ± 1.41 | 4.00 ± 2.83 | 1.00 / 2.00, 3.00 / 6.00 |"),
            "{md}"
        );
        assert!(
            md.contains("- dala: aligned holds, unaligned holds"),
            "{md}"
        );
        // The tables' 4.4038 / 2 and 23.337 / 2.
        assert!(md.contains("within [2.20, 11.67]"), "{md}");
        assert!(
            md.contains("| dala | 10 | 80.0 % | 10.0 % | 10.0 % |"),
            "{md}"
        );
        assert!(
            md.contains("| dala | 2 | 4 | 1 | 0 | 0 | 1 / 1 / 0 |"),
            "{md}"
        );
        let png = std::fs::read(out.join("nees-dala.png")).unwrap();
        assert!(image::load_from_memory(&png).is_ok());
    }
}
