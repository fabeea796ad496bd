//! hetsim's integration tests, one module per subject, in one test binary: each binary links
//! wgpu and rapier again, which costs minutes per CI run on two cores. The memory test
//! (`tests/tests/memory.rs`) is a binary of its own: it counts the heap with a global
//! allocator, which would count every other test's allocations too.
//!
//! Run one subject with a filter on its module: `cargo test --release --workspace --test it
//! -- village::`.

mod architecture;
mod bad_input;
mod cameras;
mod coverage;
mod determinism;
mod euroc;
mod files;
mod fuzz_files;
mod golden;
mod oracle;
mod place;
mod record;
mod render;
mod replay;
mod replay_fuzz;
mod sensors;
mod shared;
mod slam;
mod slurm;
mod stack_inputs;
mod sweep;
mod sweep_runs;
mod team;
mod village;
mod vision;
mod vo_scale;
