//! The renderer against geometry: depth, projection, stereo, determinism, golden images.
//!
//! These need a graphics adapter; on CI that is Mesa's llvmpipe (GL) or lavapipe (Vulkan).

use hetsim_msgs::CameraGeometry;
use hetsim_msgs::{pose_from_xyz_rpy, Pose};
use hetsim_render::{CameraView, Frame, RenderOptions, Renderer};
use hetsim_scene::world::SolidKind;
use hetsim_scene::{load_scenario, LoadOptions, Scenario};
use hetsim_tests::repo;
use nalgebra::{Point3, Vector3};

fn scenario(name: &str) -> Scenario {
    load_scenario(
        &repo().join(format!("scenarios/{name}.toml")),
        &LoadOptions::default(),
    )
    .unwrap()
}

/// A camera whose mount frame (x forward, y left, z up) is `world_from_mount`.
fn view(k: CameraGeometry, world_from_mount: Pose) -> CameraView {
    CameraView::from_mount(k, &world_from_mount, [0.02, 2000.0]).with_depth()
}

fn luminance(f: &Frame) -> Vec<f64> {
    f.rgb()
        .chunks_exact(3)
        .map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64)
        .collect()
}

/// The three reference views: the village from the rover's left camera, from the
/// helicopter's left camera at 40 m, and the lab from a c't-Bot.
fn reference_views() -> Vec<(&'static str, Scenario, CameraView)> {
    let village = scenario("village");
    let dala = &village.robots[0].spec.start;
    let ground = village.world.ground_z(dala.x, dala.y);
    let rover = view(
        CameraGeometry::from_hfov(320, 240, 60.0),
        pose_from_xyz_rpy(
            [dala.x, dala.y, ground + 1.4],
            [0.0, 8f64.to_radians(), dala.yaw_deg.to_radians()],
        ),
    );
    let heli = view(
        CameraGeometry::from_hfov(320, 240, 60.0),
        pose_from_xyz_rpy(
            [dala.x, dala.y, 40.0],
            [0.0, 90f64.to_radians(), -45f64.to_radians()],
        ),
    );
    let lab = scenario("lab");
    let c = &lab.robots[1].spec.start;
    let bot = view(
        CameraGeometry::from_hfov(120, 88, 80.0),
        pose_from_xyz_rpy([c.x, c.y, 0.08], [0.0, 0.0, 0.0]),
    );
    vec![
        ("village-rover", village.clone(), rover),
        ("village-helicopter", village, heli),
        ("lab-ctbot", lab, bot),
    ]
}

#[test]
fn no_reference_frame_is_blank_or_saturated() {
    for (name, s, v) in reference_views() {
        let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
        let f = r.render(&[v]).remove(0);
        let l = luminance(&f);
        let mean = l.iter().sum::<f64>() / l.len() as f64;
        let std = (l.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / l.len() as f64).sqrt();
        let clipped = f
            .rgb()
            .chunks_exact(3)
            .filter(|p| p.iter().all(|c| *c == 255) || p.iter().all(|c| *c == 0))
            .count();
        assert!(std > 12.0, "{name}: luminance std {std}: a blank image");
        assert!(mean > 30.0 && mean < 225.0, "{name}: mean {mean}");
        assert!(
            (clipped as f64) < 0.02 * l.len() as f64,
            "{name}: {clipped} saturated pixels"
        );
    }
}

#[test]
fn depth_is_read_back_only_when_asked_and_leaves_the_colour_unchanged() {
    for (name, s, v) in reference_views() {
        let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
        let plain = CameraView {
            depth: false,
            ..v.clone()
        };
        let frames = r.render(&[plain, v]);
        assert!(
            frames[0].depth_m.is_none(),
            "{name}: depth nobody asked for"
        );
        let depth = frames[1].depth();
        assert_eq!(depth.len(), frames[1].rgba.len() / 4);
        assert!(depth.iter().any(|&d| d > 0.0), "{name}: no depth");
        // The robots' images must not depend on whether frames are being dumped.
        assert!(frames[0].rgba == frames[1].rgba, "{name}: colour changed");
    }
}

#[test]
fn same_view_twice_gives_identical_bytes() {
    let (_, s, v) = reference_views().remove(0);
    let a = Renderer::new(&s.world, &RenderOptions::default())
        .unwrap()
        .render(std::slice::from_ref(&v))
        .remove(0);
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let b = r.render(std::slice::from_ref(&v)).remove(0);
    let c = r.render(&[v]).remove(0);
    assert!(a == b && b == c);
}

#[test]
fn building_corners_project_onto_their_rendered_depth() {
    let (_, s, cam) = reference_views().remove(0);
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let f = r.render(std::slice::from_ref(&cam)).remove(0);
    let k = cam.intrinsics;
    let optical_from_world = cam.world_from_optical.inverse();
    let mut checked = 0;
    for b in s
        .world
        .solids
        .iter()
        .filter(|b| b.kind == SolidKind::Building)
    {
        let pose = pose_from_xyz_rpy(b.centre, [0.0, 0.0, b.yaw_rad]);
        let [hx, hy, hz] = b.half_extents;
        // Points just inside each vertical face near its top corners (0.5 m in from the edges).
        for (sx, sy, face_n) in [
            (1.0, 0.0, Vector3::x()),
            (-1.0, 0.0, -Vector3::x()),
            (0.0, 1.0, Vector3::y()),
            (0.0, -1.0, -Vector3::y()),
        ] {
            for along in [-1.0, 1.0] {
                let (ex, ey) = if sx != 0.0 {
                    (sx * hx, along * (hy - 0.5))
                } else {
                    (along * (hx - 0.5), sy * hy)
                };
                let p_world = pose * Point3::new(ex, ey, hz - 0.5);
                let n_world = pose.rotation * face_n;
                let p = optical_from_world * p_world;
                let Some([u, v]) = k.k.project(&p.coords) else {
                    continue;
                };
                let (iu, iv) = (u.round(), v.round());
                if iu < 1.0 || iv < 1.0 || iu >= (k.width - 1) as f64 || iv >= (k.height - 1) as f64
                {
                    continue;
                }
                let eye = v_eye(&cam);
                if (p_world - eye).dot(&n_world) >= 0.0 {
                    continue; // back face
                }
                // Depth where the pixel centre's ray meets the face's plane.
                let ray = cam.world_from_optical.rotation * k.k.back_project(iu, iv, 1.0);
                let t = (p_world - eye).dot(&n_world) / ray.dot(&n_world);
                let at = |du: i64, dv: i64| {
                    f.depth()
                        [((iv as i64 + dv) as usize) * k.width as usize + (iu as i64 + du) as usize]
                        as f64
                };
                let rendered = at(0, 0);
                // Skip pixels on a silhouette (the 3 x 3 neighbourhood is not one plane) or
                // where something nearer hides the face.
                let smooth = (-1..=1)
                    .all(|dv| (-1..=1).all(|du| (at(du, dv) - rendered).abs() < 0.02 * rendered));
                if !smooth || (rendered - t).abs() > 0.05 * t {
                    continue;
                }
                assert!(
                    (rendered - t).abs() < 2e-3 * t + 2e-3,
                    "depth {rendered} vs {t} at ({iu}, {iv})"
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 6, "only {checked} corners visible");
}

fn v_eye(v: &CameraView) -> Point3<f64> {
    Point3::from(v.world_from_optical.translation.vector)
}

#[test]
fn stereo_disparity_of_matched_points_is_f_b_over_z() {
    // Dala's bench: 0.35 m baseline, looking into the north-west village.
    let s = scenario("village");
    let d = &s.robots[0].spec.start;
    let ground = s.world.ground_z(d.x, d.y);
    let k = CameraGeometry::from_hfov(512, 384, 60.0);
    let left = pose_from_xyz_rpy(
        [d.x, d.y, ground + 1.4],
        [0.0, 5f64.to_radians(), d.yaw_deg.to_radians()],
    );
    let right = left * pose_from_xyz_rpy([0.0, -0.35, 0.0], [0.0; 3]);
    let mut r = Renderer::new(&s.world, &RenderOptions::default()).unwrap();
    let frames = r.render(&[view(k, left), view(k, right)]);
    let (l, rt) = (luminance(&frames[0]), luminance(&frames[1]));
    let w = k.width as usize;
    let mut checked = 0;
    for v in (40..k.height as usize - 40).step_by(7) {
        for u in (60..w - 20).step_by(9) {
            let z = frames[0].depth()[v * w + u] as f64;
            if z <= 0.0 || z > 60.0 {
                continue;
            }
            // Only surfaces close to fronto-parallel (facades facing the bench): on slanted
            // ground the disparity changes across the matching window and biases it.
            let dz = |du: i64, dv: i64| {
                (frames[0].depth()[(v as i64 + dv) as usize * w + (u as i64 + du) as usize] as f64
                    - z)
                    .abs()
            };
            if [(-5, 0), (5, 0), (0, -5), (0, 5)]
                .iter()
                .any(|&(du, dv)| dz(du, dv) > 0.03 * z)
            {
                continue;
            }
            // Textured enough to match?
            let patch = |img: &[f64], cu: usize| -> Vec<f64> {
                (-5i64..=5)
                    .flat_map(|dv| {
                        (-5i64..=5).map(move |du| {
                            img[(v as i64 + dv) as usize * w + (cu as i64 + du) as usize]
                        })
                    })
                    .collect()
            };
            let a = patch(&l, u);
            let mean = a.iter().sum::<f64>() / a.len() as f64;
            if a.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (a.len() as f64) < 100.0 {
                continue;
            }
            let expected = k.k.alpha_u * 0.35 / z;
            let scores: Vec<(f64, usize)> = (0..=(expected as usize + 12).min(u - 6))
                .map(|disp| {
                    let b = patch(&rt, u - disp);
                    let ssd: f64 = a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum();
                    (ssd, disp)
                })
                .collect();
            let best = *scores.iter().min_by(|x, y| x.0.total_cmp(&y.0)).unwrap();
            // Ambiguous (repetitive windows, or an edge along the epipolar line): another
            // disparity more than 1 px away scores nearly as well. Such points prove nothing
            // about geometry; skip them.
            let rival = scores
                .iter()
                .filter(|s| s.1.abs_diff(best.1) > 1)
                .map(|s| s.0)
                .fold(f64::INFINITY, f64::min);
            if best.0 > 0.5 * rival {
                continue;
            }
            // Sub-pixel: a parabola through the best score and its neighbours.
            let score = |d: usize| scores.iter().find(|s| s.1 == d).map(|s| s.0);
            let refined = match (best.1.checked_sub(1).and_then(score), score(best.1 + 1)) {
                (Some(a), Some(c)) if a - 2.0 * best.0 + c > 0.0 => {
                    best.1 as f64 + (a - c) / (2.0 * (a - 2.0 * best.0 + c))
                }
                _ => best.1 as f64,
            };
            assert!((refined - expected).abs() <= 1.0, "pixel ({u}, {v}): matched disparity {refined:.2} vs f b / Z = {expected:.2} (Z = {z:.2})");
            checked += 1;
        }
    }
    assert!(checked >= 15, "only {checked} textured points matched");
}

/// The folder of an adapter's golden images: backend and the adapter's first word, e.g.
/// `gl-llvmpipe` (Mesa's llvmpipe over GL) or `vulkan-llvmpipe` (lavapipe); the folder's
/// `ADAPTER` file holds the exact adapter and driver its images were made with.
fn adapter_key(r: &Renderer) -> (String, String) {
    let a = r.adapter();
    let name = a.name.split_whitespace().next().unwrap_or("unknown");
    (
        format!("{}-{}", a.backend, name).to_lowercase(),
        format!("{} | {} | {}\n", a.name, a.backend, a.driver),
    )
}

/// Golden images, one set per adapter under `tests/golden/<adapter>/`: compared tightly with
/// the set made on this very adapter and driver (`ADAPTER`; the same rasterizer on another
/// CPU may still round differently, hence the margin), and loosely with llvmpipe's GL set
/// otherwise (another Mesa, a real GPU). Anisotropic filtering is off for these views, as on
/// the CPU rasterizers the sets come from. On failure `<name>-actual.png` and
/// `<name>-difference.png` go to `target/golden-failures/`. HETSIM_BLESS=1 writes this
/// adapter's set (only after a deliberate change to the scene, the shader, the bake or the
/// generators).
#[test]
fn reference_views_match_their_golden_images() {
    let root = repo().join("tests/golden");
    let out = repo().join("target/golden-failures");
    let bless = std::env::var("HETSIM_BLESS").is_ok();
    let options = RenderOptions {
        anisotropy: Some(1),
        ..RenderOptions::default()
    };
    let mut failures = Vec::new();
    for (name, s, v) in reference_views() {
        let mut r = Renderer::new(&s.world, &options).unwrap();
        let (key, adapter) = adapter_key(&r);
        let own = root.join(&key);
        let same = std::fs::read_to_string(own.join("ADAPTER")).is_ok_and(|a| a == adapter);
        // (mean difference, fraction of pixels allowed over `large`, large)
        let (dir, bound) = if bless || same {
            (own, (1.0, 0.005, 24))
        } else {
            println!("no golden images for {adapter}: comparing loosely with gl-llvmpipe");
            (root.join("gl-llvmpipe"), (3.0, 0.01, 48))
        };
        if bless {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(dir.join("ADAPTER"), &adapter).unwrap();
        }
        let f = r.render(&[v]).remove(0);
        let actual = image::RgbImage::from_raw(f.width, f.height, f.rgb()).unwrap();
        let path = dir.join(format!("{name}.png"));
        if bless {
            std::fs::create_dir_all(&dir).unwrap();
            actual.save(&path).unwrap();
            continue;
        }
        let golden = image::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e} (HETSIM_BLESS=1 creates it)", path.display()))
            .to_rgb8();
        assert_eq!(golden.dimensions(), actual.dimensions());
        let mut diff = image::RgbImage::new(f.width, f.height);
        let mut total = 0.0;
        let mut large = 0usize;
        for (x, y, g) in golden.enumerate_pixels() {
            let a = actual.get_pixel(x, y);
            let d: [u8; 3] = [0, 1, 2].map(|c| (g[c] as i16 - a[c] as i16).unsigned_abs() as u8);
            let m = *d.iter().max().unwrap();
            total += m as f64;
            large += usize::from(m > bound.2);
            diff.put_pixel(
                x,
                y,
                image::Rgb([
                    m.saturating_mul(4),
                    m.saturating_mul(4),
                    m.saturating_mul(4),
                ]),
            );
        }
        let n = (f.width * f.height) as f64;
        let (mean, frac) = (total / n, large as f64 / n);
        if mean > bound.0 || frac > bound.1 {
            std::fs::create_dir_all(&out).unwrap();
            actual
                .save(out.join(format!("{key}-{name}-actual.png")))
                .unwrap();
            diff.save(out.join(format!("{key}-{name}-difference.png")))
                .unwrap();
            failures.push(format!(
                "{key}/{name}: mean difference {mean:.2}, {:.2} % of pixels off by more than {}",
                100.0 * frac,
                bound.2
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:?}; see {}", out.display());
}

#[test]
fn a_terrain_larger_than_a_device_buffer_is_refused_naming_the_mesh_and_the_fix() {
    // 2000 m at 1 m cells: 4e6 height samples, a vertex buffer over the 256 MiB a wgpu
    // device allows by default (which was a validation panic).
    let text = std::fs::read_to_string(repo().join("scenarios/village.toml"))
        .unwrap()
        .replace("size_m = 800.0", "size_m = 2000.0")
        .replace("terrain_cell_m = 4.0", "terrain_cell_m = 1.0");
    let s = hetsim_scene::load_scenario_text(
        &repo().join("scenarios/village.toml"),
        text,
        &LoadOptions::default(),
    )
    .unwrap();
    let Err(e) = Renderer::new(&s.world, &RenderOptions::default()) else {
        panic!("a {}-sample terrain was accepted", 2001 * 2001)
    };
    let said = e.to_string();
    let hetsim_render::RenderError::TooLarge {
        what, bytes, max, ..
    } = e
    else {
        panic!("expected TooLarge, got {said}")
    };
    assert_eq!(what, "terrain");
    assert!(bytes > max, "{said}");
    assert!(
        said.contains("terrain_cell_m") && said.contains("--no-render"),
        "{said}"
    );
}
