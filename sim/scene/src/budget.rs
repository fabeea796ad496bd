//! What a world will cost before it is built: a village's terrain is a grid of height
//! samples, `(size_m / terrain_cell_m)^2` of them, and every one costs memory in the scene,
//! the physics and (rendered) the renderer. A 20 km village at 0.25 m cells is 6.4e9 samples,
//! about 110 GB: the loader refuses it within milliseconds, with the estimate and the fields
//! that drive it, instead of building until the machine runs out.
//!
//! The bound is the machine's available memory (`MemAvailable` in `/proc/meminfo`, or the
//! cgroup's `memory.max` where that is less), or the one the command line declares
//! ([`set_max_memory`], `--max-memory`). It is read when a scenario loads, so a sweep
//! whose runs load while others hold memory may see less than its first run did.

use std::sync::OnceLock;

/// Bytes a run holds per terrain height sample without rendering, measured: `hetsim run
/// --no-render --duration 0.1` of a village of 4000 m at 1 m cells (1.6e7 samples) peaked at
/// 276 MB resident, 17.2 bytes each, and the issue measured 5000 m at 0.5 m (1e8) at 1.7 GB
/// (the scene's heights and the physics' heightfield). Rendering adds about 160 more (the
/// terrain's mesh: 2.8 GB for the 4000 m village rendered), so this
/// is the least a run of the world needs.
pub const TERRAIN_BYTES_PER_SAMPLE: f64 = 17.0;

static MAX_MEMORY: OnceLock<u64> = OnceLock::new();

/// Declares the memory bound worlds are checked against, bytes (instead of the machine's
/// available memory). Only the first call counts.
pub fn set_max_memory(bytes: u64) {
    let _ = MAX_MEMORY.set(bytes);
}

/// The memory bound and where it comes from; `None` where neither is known.
pub fn memory_bound() -> Option<(u64, &'static str)> {
    if let Some(b) = MAX_MEMORY.get() {
        return Some((*b, "--max-memory"));
    }
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kb: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    let available = kb * 1024;
    // A container's or a Slurm job's cgroup may allow less than the machine has free.
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok());
    Some(match cgroup {
        Some(limit) if limit < available => (limit, "this process's cgroup memory limit"),
        _ => (available, "this machine's available memory"),
    })
}

/// Terrain height samples of a village of side `size_m` sampled every `cell_m`.
pub fn terrain_samples(size_m: f64, cell_m: f64) -> f64 {
    let per_side = (size_m / cell_m).ceil() + 1.0;
    per_side * per_side
}

/// The least memory a run of a village of side `size_m` at `cell_m` needs, bytes.
pub fn village_bytes(size_m: f64, cell_m: f64) -> f64 {
    terrain_samples(size_m, cell_m) * TERRAIN_BYTES_PER_SAMPLE
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_issues_worlds_cost_what_their_samples_do() {
        // 20 km at 0.25 m: 6.4e9 samples, about 109 GB: more than any of this project's
        // machines (24 GiB here; 128 GiB on the GPU machine).
        assert!(village_bytes(20_000.0, 0.25) > 100e9);
        // 5 km at 0.5 m: 1e8 samples, the 1.7 GB the issue measured, which fits here.
        let b = village_bytes(5_000.0, 0.5);
        assert!((1.6e9..1.8e9).contains(&b), "{b}");
        // The shipped village: 800 m at 4 m, 201^2 samples, under a megabyte.
        assert!(village_bytes(800.0, 4.0) < 1e6);
        let (bound, _) = memory_bound().expect("/proc/meminfo on Linux");
        assert!(bound > 0);
    }
}
