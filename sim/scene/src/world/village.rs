//! The village: rolling terrain and two groups of buildings.
//!
//! Terrain is value noise (four octaves, wavelengths 160/80/40/20 m) scaled to `relief_m`,
//! flattened smoothly inside each building group (villages sit on level ground). Buildings
//! are boxes 8-20 x 6-14 m, 4-12 m tall, scattered in a disc around each group centre with
//! orientations near a per-group street direction (semi-structured, not a grid city), at
//! least 3 m apart, and never within the clearance of a robot's start or route.

use super::{KeepClear, Solid, SolidKind, Terrain, World};
use crate::scenario::VillageSpec;
use hetsim_core::Streams;
use rand::{Rng, RngExt};

/// Builds the village for a seed.
pub fn generate_village(spec: &VillageSpec, streams: &Streams, keep: &KeepClear) -> World {
    let mut terrain = terrain(spec, streams);
    for centre in [spec.north_west_centre, spec.south_east_centre] {
        flatten(&mut terrain, centre, spec.group_radius_m);
    }
    let mut rng = streams.stream("world/village/buildings");
    let mut solids = Vec::new();
    for b in &spec.buildings {
        let half = [b.size_m[0] / 2.0, b.size_m[1] / 2.0];
        solids.push(building(
            &terrain,
            b.centre,
            half,
            b.height_m,
            b.yaw_deg.to_radians(),
            rng.next_u64(),
        ));
    }
    for centre in [spec.north_west_centre, spec.south_east_centre] {
        let street_yaw = rng.random_range(0.0..std::f64::consts::FRAC_PI_2);
        let mut placed = 0;
        let mut attempts = 0;
        while placed < spec.buildings_per_group && attempts < 200 * spec.buildings_per_group.max(1)
        {
            attempts += 1;
            let r = spec.group_radius_m * rng.random::<f64>().sqrt();
            let theta = rng.random_range(0.0..std::f64::consts::TAU);
            let c = [centre[0] + r * theta.cos(), centre[1] + r * theta.sin()];
            let half: [f64; 2] = [rng.random_range(4.0..10.0), rng.random_range(3.0..7.0)];
            let height = rng.random_range(4.0..12.0);
            let yaw = street_yaw + rng.random_range(-0.2..0.2);
            let material = rng.next_u64();
            let radius = half[0].hypot(half[1]);
            if keep.margin(c[0], c[1]) < radius {
                continue;
            }
            let crowded = solids.iter().any(|s: &Solid| {
                let other = s.half_extents[0].hypot(s.half_extents[1]);
                (s.centre[0] - c[0]).hypot(s.centre[1] - c[1]) < radius + other + 3.0
            });
            if crowded {
                continue;
            }
            solids.push(building(&terrain, c, half, height, yaw, material));
            placed += 1;
        }
    }
    World {
        half_extent: [spec.size_m / 2.0, spec.size_m / 2.0],
        terrain: Some(terrain),
        solids,
        grid: None,
    }
}

/// A building box whose base is sunk 0.5 m below the lowest terrain under its footprint and
/// whose roof is `height` above the highest.
fn building(
    terrain: &Terrain,
    c: [f64; 2],
    half: [f64; 2],
    height: f64,
    yaw: f64,
    material: u64,
) -> Solid {
    let (s, co) = yaw.sin_cos();
    let corners = [
        (-1.0, -1.0),
        (1.0, -1.0),
        (1.0, 1.0),
        (-1.0, 1.0),
        (0.0, 0.0),
    ];
    let zs: Vec<f64> = corners
        .iter()
        .map(|(a, b)| {
            let (lx, ly) = (a * half[0], b * half[1]);
            terrain.height_at(c[0] + co * lx - s * ly, c[1] + s * lx + co * ly)
        })
        .collect();
    let low = zs.iter().cloned().fold(f64::INFINITY, f64::min) - 0.5;
    let high = zs.iter().cloned().fold(f64::NEG_INFINITY, f64::max) + height;
    Solid {
        kind: SolidKind::Building,
        centre: [c[0], c[1], (low + high) / 2.0],
        half_extents: [half[0], half[1], (high - low) / 2.0],
        yaw_rad: yaw,
        material_seed: material,
    }
}

fn terrain(spec: &VillageSpec, streams: &Streams) -> Terrain {
    let n = (spec.size_m / spec.terrain_cell_m).round() as usize + 1;
    let cell = spec.size_m / (n - 1) as f64;
    let origin = [-spec.size_m / 2.0, -spec.size_m / 2.0];
    let mut rng = streams.stream("world/village/terrain");
    let octaves: Vec<(f64, f64, usize, Vec<f64>)> =
        [(160.0, 1.0), (80.0, 0.5), (40.0, 0.25), (20.0, 0.125)]
            .iter()
            .map(|&(wavelength, amp)| {
                let lattice = (spec.size_m / wavelength).ceil() as usize + 2;
                let values = (0..lattice * lattice)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                (wavelength, amp, lattice, values)
            })
            .collect();
    let norm: f64 = octaves.iter().map(|o| o.1).sum();
    let mut heights = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f64 * cell, j as f64 * cell);
            let mut h = 0.0;
            for (wavelength, amp, lattice, values) in &octaves {
                h += amp * value_noise(values, *lattice, x / wavelength, y / wavelength);
            }
            heights.push(spec.relief_m * h / norm);
        }
    }
    Terrain {
        origin,
        cell_m: cell,
        nx: n,
        ny: n,
        heights,
    }
}

fn value_noise(values: &[f64], lattice: usize, x: f64, y: f64) -> f64 {
    let (i, j) = (x.floor() as usize, y.floor() as usize);
    let smooth = |t: f64| t * t * (3.0 - 2.0 * t);
    let (tx, ty) = (smooth(x - i as f64), smooth(y - j as f64));
    let v = |i: usize, j: usize| values[(j.min(lattice - 1)) * lattice + i.min(lattice - 1)];
    let south = v(i, j) * (1.0 - tx) + v(i + 1, j) * tx;
    let north = v(i, j + 1) * (1.0 - tx) + v(i + 1, j + 1) * tx;
    south * (1.0 - ty) + north * ty
}

/// Blends the terrain towards its height at `centre` within `radius`, fading out over 40 m.
fn flatten(terrain: &mut Terrain, centre: [f64; 2], radius: f64) {
    let level = terrain.height_at(centre[0], centre[1]);
    for j in 0..terrain.ny {
        for i in 0..terrain.nx {
            let x = terrain.origin[0] + i as f64 * terrain.cell_m;
            let y = terrain.origin[1] + j as f64 * terrain.cell_m;
            let d = (x - centre[0]).hypot(y - centre[1]);
            let w = (1.0 - (d - radius) / 40.0).clamp(0.0, 1.0);
            let h = &mut terrain.heights[j * terrain.nx + i];
            *h += w * (level - *h);
        }
    }
}
