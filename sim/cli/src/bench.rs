//! `hetsim bench`: the speed figures recorded in `results/README.md`, as a Markdown table on
//! a terminal or, with `--json`, as one JSON object for scripts and CI.

use anyhow::{Context, Result};
use hetsim_engine::RunOptions;
use hetsim_msgs::CameraGeometry;
use hetsim_render::{CameraView, RenderOptions, Renderer};
use hetsim_scene::{load_scenario, LoadOptions, Scenario};
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One bench's figures: named columns, one row per measured case.
pub struct Figures {
    /// Which bench.
    bench: &'static str,
    /// Facts about the measurement (adapter, frame size).
    pub(crate) about: Map<String, Value>,
    /// `(key, header)` of each column, in order.
    columns: Vec<(&'static str, &'static str)>,
    /// Rows, each keyed by column key.
    rows: Vec<Map<String, Value>>,
}

impl Figures {
    pub(crate) fn new(bench: &'static str, columns: &[(&'static str, &'static str)]) -> Self {
        Self {
            bench,
            about: Map::new(),
            columns: columns.to_vec(),
            rows: Vec::new(),
        }
    }

    pub(crate) fn row(&mut self, values: Vec<Value>) {
        debug_assert_eq!(values.len(), self.columns.len());
        self.rows.push(
            self.columns
                .iter()
                .map(|(k, _)| k.to_string())
                .zip(values)
                .collect(),
        );
    }

    /// Prints the figures: JSON, or a Markdown table with the facts above it.
    pub fn print(&self, as_json: bool) {
        if as_json {
            let doc = json!({"bench": self.bench, "about": self.about, "rows": self.rows});
            println!(
                "{}",
                serde_json::to_string_pretty(&doc).expect("JSON encodes")
            );
            return;
        }
        for (k, v) in &self.about {
            println!(
                "{k}: {}",
                v.as_str().map_or_else(|| v.to_string(), str::to_string)
            );
        }
        if !self.about.is_empty() {
            println!();
        }
        let headers: Vec<&str> = self.columns.iter().map(|(_, h)| *h).collect();
        println!("| {} |", headers.join(" | "));
        println!("|{}", "---|".repeat(headers.len()));
        for row in &self.rows {
            let cells: Vec<String> = self
                .columns
                .iter()
                .map(|(k, _)| match &row[*k] {
                    Value::Number(n) => match n.as_f64() {
                        Some(x) if n.is_f64() => format!("{x:.2}"),
                        _ => n.to_string(),
                    },
                    Value::String(s) => s.clone(),
                    Value::Null => "-".to_string(),
                    other => other.to_string(),
                })
                .collect();
            println!("| {} |", cells.join(" | "));
        }
    }
}

/// Wall-clock start of a measurement. Wall time goes to `timing.json` and `hetsim bench`
/// only, never into anything the digest covers.
#[allow(clippy::disallowed_methods)]
pub fn wall_clock() -> Instant {
    Instant::now()
}

/// A scenario with its own seed, run for `secs` sim seconds.
pub(crate) fn load_for(path: &Path, secs: f64) -> Result<Scenario> {
    Ok(load_scenario(
        path,
        &LoadOptions {
            robot_files: None,
            seed: None,
            duration_secs: Some(secs),
        },
    )?)
}

/// The scenario with every robot's sensors (cameras included) removed: physics and ground
/// truth only.
fn without_sensors(mut scenario: Scenario) -> Scenario {
    for r in &mut scenario.robots {
        r.model.sensors.clear();
    }
    scenario
}

/// Runs a scenario with its stacks, no cameras; returns (ticks, wall seconds).
fn time_run(scenario: &Scenario) -> Result<(u64, f64)> {
    let stacks = hetsim_stacks::build_stacks(scenario, false);
    let start = wall_clock();
    let out = hetsim_engine::run(scenario, stacks, |_, _| {}, RunOptions::default())?;
    Ok((out.ticks, start.elapsed().as_secs_f64()))
}

/// Sim seconds per wall second with physics and ground truth only.
pub fn physics(scenarios: &[PathBuf], sim_secs: f64) -> Result<Figures> {
    let mut f = Figures::new(
        "physics",
        &[
            ("scenario", "scenario"),
            ("robots", "robots"),
            ("sim_s", "sim s"),
            ("wall_s", "wall s"),
            ("sim_per_wall", "sim s / wall s"),
        ],
    );
    for s in scenarios {
        let loaded = without_sensors(load_for(s, sim_secs)?);
        let (ticks, wall) = time_run(&loaded)?;
        let sim = loaded.clock.time_secs(ticks);
        f.row(vec![
            json!(loaded.file.name),
            json!(loaded.robots.len()),
            json!(sim),
            json!(wall),
            json!(sim / wall),
        ]);
    }
    Ok(f)
}

/// The cost of one laser scan, and of a tick with and without the non-visual sensors.
pub fn sensors(scenarios: &[PathBuf], sim_secs: f64) -> Result<Figures> {
    let mut f = Figures::new(
        "sensors",
        &[
            ("scenario", "scenario"),
            ("laser_scan_us", "laser scan (481 rays) us"),
            ("tick_all_sensors_us", "tick, all sensors us"),
            ("tick_bare_us", "tick, physics + truth only us"),
        ],
    );
    for s in scenarios {
        let loaded = load_for(s, sim_secs)?;
        let mut physics =
            hetsim_physics::Physics::for_scenario(&loaded, &hetsim_core::Streams::new(loaded.seed));
        physics.step();
        let origin = physics.pose(0).translation.vector;
        let o = [origin.x, origin.y, origin.z + 0.3];
        let scans = 200;
        let start = wall_clock();
        let mut hits = 0usize;
        for _ in 0..scans {
            for b in 0..481 {
                let a = (-120.0 + 0.5 * b as f64).to_radians();
                hits += usize::from(
                    physics
                        .cast_ray(o, [a.cos(), a.sin(), 0.0], 20.0, Some(0))
                        .is_some(),
                );
            }
        }
        std::hint::black_box(hits);
        let scan_us = start.elapsed().as_secs_f64() * 1e6 / scans as f64;
        let (ticks, wall) = time_run(&loaded)?;
        let with = wall * 1e6 / ticks as f64;
        let (ticks, wall) = time_run(&without_sensors(loaded.clone()))?;
        let without = wall * 1e6 / ticks as f64;
        f.row(vec![
            json!(loaded.file.name),
            json!(scan_us),
            json!(with),
            json!(without),
        ]);
    }
    Ok(f)
}

/// Coverage planning time per scenario (median of 5).
pub fn coverage(scenarios: &[PathBuf]) -> Result<Figures> {
    let mut f = Figures::new(
        "coverage",
        &[
            ("scenario", "scenario"),
            ("vertices", "vertices"),
            ("parent_vertices", "parent vertices"),
            ("timesteps", "timesteps"),
            ("planning_ms", "planning ms (median of 5)"),
        ],
    );
    for s in scenarios {
        let loaded = load_scenario(s, &LoadOptions::default())?;
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..5 {
            let start = wall_clock();
            last = Some(hetsim_eval::coverage::plan_scenario(&loaded)?);
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let (_, _, plan) = last.expect("five plans");
        f.row(vec![
            json!(loaded.file.name),
            json!(plan.vertices),
            json!(plan.parent_vertices.len()),
            json!(plan.mapping_timesteps + plan.coordination_timesteps),
            json!(times[2]),
        ]);
    }
    Ok(f)
}

/// Frames per second with readback on the chosen adapter: 1024x768 mono, 1024x768 stereo
/// pairs, 120x88, from the first robot's start pose of each scenario.
pub fn render(scenarios: &[PathBuf], options: &RenderOptions) -> Result<Figures> {
    let mut f = Figures::new(
        "render",
        &[
            ("scenario", "scenario"),
            ("fps_1024x768", "1024x768 frames/s"),
            ("stereo_pairs_per_s_1024x768", "1024x768 stereo pairs/s"),
            ("fps_120x88", "120x88 frames/s"),
            ("start_ms", "renderer start ms (bake + upload)"),
            ("depth_ms", "+ depth, ms/frame"),
            ("blur_ms", "motion blur ms/frame"),
            ("rolling_ms", "rolling shutter ms/frame"),
            ("vignetting_ms", "+ vignetting, ms/frame"),
        ],
    );
    f.about.insert(
        "effects".into(),
        json!(
            "what each camera effect costs a 1024x768 frame on one core: rendering depth as \
             well (the exposure needs it), blur over a 5 ms exposure at 6 m/s and 0.3 rad/s \
             (Ressac's cruise and a turn), a rolling shutter of 30 us a row at the same \
             motion, and vignetting's per-pixel gain against the noise pass's unit-gain path"
        ),
    );
    for s in scenarios {
        let loaded = load_scenario(s, &LoadOptions::default())?;
        let start = wall_clock();
        let mut renderer = Renderer::new(&loaded.world, options)?;
        let start_ms = start.elapsed().as_secs_f64() * 1e3;
        if f.about.is_empty() {
            let a = renderer.adapter();
            f.about.insert(
                "adapter".into(),
                json!(format!("{} ({}, {})", a.name, a.backend, a.driver)),
            );
        }
        let r = &loaded.robots[0].spec.start;
        let ground = loaded.world.ground_z(r.x, r.y);
        let mut rates = Vec::new();
        for (k, pair) in [
            (CameraGeometry::from_hfov(1024, 768, 60.0), false),
            (CameraGeometry::from_hfov(1024, 768, 60.0), true),
            (CameraGeometry::from_hfov(120, 88, 80.0), false),
        ] {
            let frames = if k.width > 200 { 20 } else { 200 };
            let views = |i: usize| {
                let yaw = r.yaw_deg.to_radians() + 0.01 * i as f64;
                let mount =
                    hetsim_msgs::pose_from_xyz_rpy([r.x, r.y, ground + 1.2], [0.0, 0.1, yaw]);
                let mut v = vec![CameraView::from_mount(k, &mount, [0.02, 3000.0])];
                if pair {
                    let right = mount * hetsim_msgs::pose_from_xyz_rpy([0.0, -0.35, 0.0], [0.0; 3]);
                    v.push(CameraView::from_mount(k, &right, [0.02, 3000.0]));
                }
                v
            };
            // Warm up (targets, shader compilation), then render for at least three seconds
            // and `frames` frames, as the wgpu reference does.
            for i in 0..5 {
                renderer.render(&views(i));
            }
            let start = wall_clock();
            let mut done = 0;
            while done < frames || start.elapsed().as_secs_f64() < 3.0 {
                std::hint::black_box(renderer.render(&views(done)));
                done += 1;
            }
            rates.push(done as f64 / start.elapsed().as_secs_f64());
        }
        let mount = hetsim_msgs::pose_from_xyz_rpy([r.x, r.y, ground + 1.2], [0.0, 0.1, 0.0]);
        let costs = effect_costs(&mut renderer, &mount, 1e3 / rates[0]);
        f.row(vec![
            json!(loaded.file.name),
            json!(rates[0]),
            json!(rates[1]),
            json!(rates[2]),
            json!(start_ms),
            json!(costs[0]),
            json!(costs[1]),
            json!(costs[2]),
            json!(costs[3]),
        ]);
    }
    Ok(f)
}

/// Milliseconds per 1024x768 frame of each camera effect: depth (against `plain_ms`, a
/// frame without), motion blur, rolling shutter, vignetting (against unit gain).
fn effect_costs(renderer: &mut Renderer, mount: &hetsim_msgs::Pose, plain_ms: f64) -> [f64; 4] {
    use hetsim_sensors::camera::motion::{expose, Timing, Twist};
    use hetsim_sensors::camera::PixelNoise;
    let k = CameraGeometry::from_hfov(1024, 768, 60.0);
    let mut view = CameraView::from_mount(k, mount, [0.02, 3000.0]);
    view.depth = true;
    let time_ms = |n: usize, f: &mut dyn FnMut()| {
        f();
        let start = wall_clock();
        for _ in 0..n {
            f();
        }
        start.elapsed().as_secs_f64() * 1e3 / n as f64
    };
    let depth_ms = time_ms(10, &mut || {
        std::hint::black_box(renderer.render(std::slice::from_ref(&view)));
    }) - plain_ms;
    let frame = renderer.render(std::slice::from_ref(&view)).remove(0);
    let twist = Twist {
        v: nalgebra::Vector3::new(6.0, 0.0, 0.0),
        w: nalgebra::Vector3::new(0.0, 0.3, 0.0),
    };
    let (w, h) = (k.width as usize, k.height as usize);
    let effect = |timing: Timing| {
        time_ms(5, &mut || {
            std::hint::black_box(expose(
                &frame.rgba,
                frame.depth_m.as_deref(),
                w,
                h,
                &k.k,
                &twist,
                &timing,
            ));
        })
    };
    let blur_ms = effect(Timing {
        exposure_s: 5e-3,
        line_delay_s: 0.0,
    });
    let rolling_ms = effect(Timing {
        exposure_s: 0.0,
        line_delay_s: 30e-6,
    });
    let noise = PixelNoise::new(2.0);
    let gains = vec![0.9f32; w * h];
    let mut rng = hetsim_core::Streams::new(1).stream("bench/noise");
    let unit_ms = time_ms(5, &mut || {
        std::hint::black_box(noise.apply(&frame.rgba, 4, 1.0, &mut rng));
    });
    let mapped_ms = time_ms(5, &mut || {
        std::hint::black_box(noise.apply_mapped(&frame.rgba, 4, &gains, &mut rng));
    });
    [depth_ms, blur_ms, rolling_ms, mapped_ms - unit_ms]
}

/// Rounds of the vision bench's frame sequence.
const VISION_ROUNDS: usize = 7;

/// Milliseconds per stereo frame for Harris, stereo matching, a VO step and line segments,
/// on rendered frames of the scenario's first stereo robot driving 6 cm per frame from its
/// start: the median over [`VISION_ROUNDS`] rounds of the sequence, with the least and
/// greatest round.
pub fn vision(scenario: &Path) -> Result<Figures> {
    use hetsim_vision::{segments, stereo};
    let loaded = load_scenario(scenario, &LoadOptions::default())?;
    let (robot, stereo) = first_stereo_robot(&loaded, scenario)?;
    let (k, baseline, mount) = (stereo.intrinsics, stereo.baseline_m, stereo.body_from_mount);
    let mut renderer = Renderer::new(&loaded.world, &RenderOptions::default())?;
    let bench = stereo::Bench {
        camera: k.k,
        baseline_m: baseline,
    };
    let frames = vision_frames(&mut renderer, &loaded, robot, k, baseline, mount);
    // Segment detection as the SLAM stack runs it: at its scale, every `line_detect_period`
    // frames.
    let slam = hetsim_slam::stack::SlamParams::ground();
    let at_slam_scale = segments::DetectParams {
        scale: slam.line_detect_scale,
        ..Default::default()
    };
    // One round is the whole sequence from a fresh VO; the figure of a stage is its median
    // over the rounds (this machine is shared, and one round of 11 frames moved by 30 %
    // between back-to-back runs), with the rounds' least and greatest beside it.
    let mut rounds: Vec<[f64; 8]> = Vec::new();
    let mut n_segments = 0usize;
    for _ in 0..VISION_ROUNDS {
        let (round, found) = vision_round(&frames, bench, &slam, &at_slam_scale);
        rounds.push(round);
        n_segments = found;
    }
    Ok(vision_figures(
        k,
        &loaded.robots[robot].spec.name,
        frames.len(),
        &rounds,
        n_segments,
    ))
}

/// The first robot of `loaded` with a stereo bench (its index), and the bench.
fn first_stereo_robot(
    loaded: &Scenario,
    scenario: &Path,
) -> Result<(usize, hetsim_scene::StereoBench)> {
    loaded
        .robots
        .iter()
        .enumerate()
        .find_map(|(i, r)| Some((i, hetsim_scene::stereo_bench(r)?)))
        .with_context(|| {
            format!(
                "{}: no robot with a stereo_camera to measure",
                scenario.display()
            )
        })
}

/// The vision bench's sequence: 11 stereo pairs, grey, of robot `robot` driving 6 cm per
/// frame straight ahead from its start.
fn vision_frames(
    renderer: &mut Renderer,
    loaded: &Scenario,
    robot: usize,
    k: CameraGeometry,
    baseline: f64,
    mount: hetsim_msgs::Pose,
) -> Vec<(hetsim_vision::Gray, hetsim_vision::Gray)> {
    use hetsim_vision::Gray;
    let (w, h) = (k.width as usize, k.height as usize);
    let d = &loaded.robots[robot].spec.start;
    let pair = |renderer: &mut Renderer, forward: f64| {
        let yaw = d.yaw_deg.to_radians();
        let (x, y) = (d.x + forward * yaw.cos(), d.y + forward * yaw.sin());
        let body =
            hetsim_msgs::pose_from_xyz_rpy([x, y, loaded.world.ground_z(x, y)], [0.0, 0.0, yaw]);
        let left = body * mount;
        let right = left * hetsim_msgs::pose_from_xyz_rpy([0.0, -baseline, 0.0], [0.0; 3]);
        let views: Vec<CameraView> = [left, right]
            .iter()
            .map(|m| CameraView::from_mount(k, m, [0.05, 3000.0]))
            .collect();
        let f = renderer.render(&views);
        (
            Gray::from_rgb(w, h, &f[0].rgb()).expect("a rendered frame is w x h x 3"),
            Gray::from_rgb(w, h, &f[1].rgb()).expect("a rendered frame is w x h x 3"),
        )
    };
    (0..11)
        .map(|i| pair(&mut *renderer, 0.06 * i as f64))
        .collect()
}

/// One round of the vision bench: the whole sequence from a fresh VO, each stage's
/// milliseconds per stereo frame (in the order of [`vision_figures`]' stages), and the
/// segments detected.
fn vision_round(
    frames: &[(hetsim_vision::Gray, hetsim_vision::Gray)],
    bench: hetsim_vision::stereo::Bench,
    slam: &hetsim_slam::stack::SlamParams,
    at_slam_scale: &hetsim_vision::segments::DetectParams,
) -> ([f64; 8], usize) {
    use hetsim_vision::{harris, segments, stereo, vo::StereoVo};
    let n = frames.len() as f64;
    let (mut t_detect, mut t_stereo, mut t_vo, mut t_vo_lost) = (0.0, 0.0, 0.0, 0.0);
    let (mut t_lsd, mut t_lsd_slam, mut t_track) = (0.0, 0.0, 0.0);
    let mut previous: Vec<segments::Segment> = Vec::new();
    let mut vo = StereoVo::new(bench);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(0);
    let mut n_segments = 0usize;
    for (i, (l, r)) in frames.iter().enumerate() {
        let start = wall_clock();
        let corners = harris::detect(l, 0.005, 8);
        let chosen = harris::select_new(&corners, l.width, l.height, &[], 25, 8.0);
        t_detect += start.elapsed().as_secs_f64();
        let start = wall_clock();
        std::hint::black_box(stereo::match_stereo(
            l,
            r,
            &bench,
            &chosen,
            [0.5, 120.0],
            0.85,
        ));
        t_stereo += start.elapsed().as_secs_f64();
        let start = wall_clock();
        std::hint::black_box(vo.process(l, r, &mut rng));
        // The first pair only initializes; the second searches five times wider (no
        // velocity yet, as after a loss); the rest are steady-state tracking.
        match i {
            0 => {}
            1 => t_vo_lost = start.elapsed().as_secs_f64(),
            _ => t_vo += start.elapsed().as_secs_f64(),
        }
        let start = wall_clock();
        let found = segments::detect(l, &segments::DetectParams::default());
        t_lsd += start.elapsed().as_secs_f64();
        n_segments += found.len();
        let start = wall_clock();
        std::hint::black_box(segments::detect(l, at_slam_scale));
        t_lsd_slam += start.elapsed().as_secs_f64();
        let start = wall_clock();
        for s in &previous {
            std::hint::black_box(segments::track(l, s, &segments::TrackParams::default()));
        }
        t_track += start.elapsed().as_secs_f64();
        previous = found;
    }
    (
        [
            1e3 * t_detect / n,
            1e3 * t_stereo / n,
            1e3 * t_vo / (n - 2.0),
            1e3 * t_vo_lost,
            1e3 * t_lsd / n,
            1e3 * t_lsd_slam / n,
            1e3 * t_lsd_slam / n / slam.line_detect_period as f64,
            1e3 * t_track / (n - 1.0),
        ],
        n_segments,
    )
}

/// The vision bench's figures: each stage's median over the `rounds`, with the least and
/// greatest round and its target, and what was measured (frame size, robot `robot`,
/// `frames` frames a round, segments found per frame in the last round).
fn vision_figures(
    k: CameraGeometry,
    robot: &str,
    frames: usize,
    rounds: &[[f64; 8]],
    n_segments: usize,
) -> Figures {
    let mut f = Figures::new(
        "vision",
        &[
            ("stage", "stage, per stereo frame"),
            ("ms", "ms (median of rounds)"),
            ("ms_min", "least"),
            ("ms_max", "greatest"),
            ("target_ms", "target (issue 16)"),
        ],
    );
    f.about.insert(
        "frame".into(),
        json!(format!("{} x {} stereo", k.width, k.height)),
    );
    f.about.insert("robot".into(), json!(robot));
    f.about.insert("frames".into(), json!(frames));
    f.about.insert("rounds".into(), json!(VISION_ROUNDS));
    let stages: [(&str, Option<f64>); 8] = [
        ("harris_selection", None),
        ("stereo_matching", None),
        ("vo_step_tracking", Some(15.0)),
        ("vo_step_without_velocity", Some(60.0)),
        ("segment_detection", None),
        ("segment_detection_at_slam_scale", None),
        ("segment_detection_amortised", Some(10.0)),
        ("segment_tracking", None),
    ];
    for (j, (stage, target)) in stages.into_iter().enumerate() {
        let mut ms: Vec<f64> = rounds.iter().map(|r| r[j]).collect();
        ms.sort_by(f64::total_cmp);
        f.row(vec![
            json!(stage),
            json!(ms[ms.len() / 2]),
            json!(ms[0]),
            json!(ms[ms.len() - 1]),
            json!(target),
        ]);
    }
    f.about.insert(
        "segments_per_frame".into(),
        json!(n_segments as f64 / frames as f64),
    );
    f
}

/// The local EKF's time per frame against the number of landmarks (synthetic, a fifth of
/// them lines, every landmark observed once per frame).
pub fn slam() -> Figures {
    use hetsim_slam::idp::Sensor;
    use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion};
    let r = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    let sensor = Sensor::new(
        hetsim_msgs::Pinhole {
            alpha_u: 887.0,
            alpha_v: 887.0,
            u0: 511.5,
            v0: 383.5,
        },
        &Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 1.4),
            UnitQuaternion::from_matrix(&r),
        ),
    );
    let mut f = Figures::new(
        "slam",
        &[
            ("landmarks", "landmarks in the local map"),
            ("points", "points"),
            ("lines", "lines"),
            ("state_size", "state size"),
            (
                "ms_per_frame",
                "ms per frame (prediction + an update per landmark; median of rounds)",
            ),
            ("ms_min", "least"),
            ("ms_max", "greatest"),
            ("us_per_point_update", "us per point update"),
            ("us_per_line_update", "us per line update"),
            ("target_ms", "target (issue 16)"),
        ],
    );
    for n in [10usize, 25, 50, 100] {
        // Each round from a freshly built map, so that every round does the same work; the
        // figures are the medians over the rounds, with the least and greatest frame time.
        let mut rounds: Vec<[f64; 3]> = Vec::new();
        let mut shape = (0, 0, 0);
        for _ in 0..SLAM_ROUNDS {
            let (map, [ms, point_us, line_us]) = slam_round(&sensor, n);
            shape = (map.points.len(), map.lines.len(), map.state_len());
            rounds.push([ms, point_us, line_us]);
        }
        let median = |j: usize| {
            let mut v: Vec<f64> = rounds.iter().map(|r| r[j]).collect();
            v.sort_by(f64::total_cmp);
            (v[v.len() / 2], v[0], v[v.len() - 1])
        };
        let (ms, least, greatest) = median(0);
        f.row(vec![
            json!(n),
            json!(shape.0),
            json!(shape.1),
            json!(shape.2),
            json!(ms),
            json!(least),
            json!(greatest),
            json!(median(1).0),
            json!(median(2).0),
            json!((n == 100).then_some(6.0)),
        ]);
    }
    f
}

/// Rounds of each size in the SLAM bench.
const SLAM_ROUNDS: usize = 7;

/// One round of the SLAM bench: a map of `n` landmarks (a fifth of them lines, about what the
/// village's sub-maps hold) built, then 20 frames of a prediction and an update of every
/// landmark; returns the map and (ms per frame, us per point update, us per line update).
fn slam_round(
    sensor: &hetsim_slam::idp::Sensor,
    n: usize,
) -> (hetsim_slam::ekf::LocalMap, [f64; 3]) {
    use hetsim_slam::ekf::LocalMap;
    use hetsim_slam::lines::LinePrior;
    use nalgebra::{Isometry3, Matrix6, Vector2};
    let lines = n / 5;
    let mut map = LocalMap::new();
    for k in 0..n - lines {
        let px = Vector2::new(40.0 + (k * 97 % 940) as f64, 40.0 + (k * 61 % 680) as f64);
        map.add_point(sensor, &px, 1.0, 0.1, 0.2, k as u64);
    }
    let segment = |k: usize| {
        let a = Vector2::new(60.0 + (k * 131 % 800) as f64, 60.0 + (k * 89 % 560) as f64);
        (a, a + Vector2::new(120.0, 40.0 + (k * 37 % 80) as f64))
    };
    for k in 0..lines {
        let (a, b) = segment(k);
        map.add_line(sensor, &a, &b, 1.0, &LinePrior::seed(), (n + k) as u64);
    }
    let frames = 20;
    let (mut points_s, mut lines_s) = (0.0, 0.0);
    let start = wall_clock();
    for fr in 0..frames {
        map.predict(
            &Isometry3::translation(0.05, 0.0, 0.0),
            &Matrix6::from_diagonal_element(1e-6),
        );
        let t = wall_clock();
        for k in 0..map.points.len() {
            if let Some(predicted) = map.predict_point(sensor, k, 1.0) {
                let z = predicted.0.pixel + Vector2::new(0.1 * (fr % 3) as f64, -0.1);
                std::hint::black_box(map.update_predicted(k, &z, &predicted, 9.21));
            }
        }
        points_s += t.elapsed().as_secs_f64();
        let t = wall_clock();
        for j in 0..map.lines.len() {
            let (a, b) = segment(j);
            let shift = Vector2::new(0.0, 0.2 * (fr % 3) as f64);
            std::hint::black_box(map.update_line(sensor, j, &(a + shift), &b, 1.0, 9.21));
        }
        lines_s += t.elapsed().as_secs_f64();
        map.symmetrize();
    }
    let ms = start.elapsed().as_secs_f64() * 1e3 / frames as f64;
    let per = |total: f64, count: usize| total * 1e6 / (frames * count.max(1)) as f64;
    let figures = [
        ms,
        per(points_s, map.points.len()),
        per(lines_s, map.lines.len()),
    ];
    (map, figures)
}
