//! hetsim's integration tests, one module per subject, in one test binary: each binary links
//! wgpu and rapier again, which costs minutes per CI run on two cores. The memory test
//! (`tests/tests/memory.rs`) is a binary of its own: it counts the heap with a global
//! allocator, which would count every other test's allocations too.
//!
//! Run one subject with a filter on its module: `cargo test --release --workspace --test it
//! -- full_village::`.
//!
//! libtest starts the tests in the order of their names, on as many threads as there are
//! cores. The full village is by far the longest (about 13 minutes of the suite's 35 on two
//! cores), so its module's name sorts it among the first few seconds' tests: the others then
//! run beside it on the second core instead of leaving it to run alone at the end, where it
//! ran from about 1,300 s to 2,060 s with the cores 93 % busy (`results/ci/`).

mod architecture;
mod bad_input;
mod cameras;
mod coverage;
mod determinism;
mod euroc;
mod files;
mod full_village;
mod fuzz_files;
mod golden;
mod oracle;
mod place;
mod record;
mod render;
mod replay;
mod replay_fuzz;
mod results_folder;
mod sensors;
mod shared;
mod slam;
mod slurm;
mod stack_inputs;
mod sweep;
mod sweep_runs;
mod team;
mod vision;
mod vo_scale;
