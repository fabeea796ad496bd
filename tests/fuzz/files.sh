#!/usr/bin/env bash
# The file fuzzer on demand: 100,000 mutated scenario and robot files (CI runs 2,000) through
# tests/tests/it/fuzz_files.rs, with a release build, under a 12 GB address-space limit so a
# file that would allocate more aborts the run instead of the machine. Prints the counts and
# the slowest refusal; a failing case is kept in the temporary folder and named.
#   bash tests/fuzz/files.sh [CASES] [SEED]      (default 100000 cases, seed 1)
set -euo pipefail
cd "$(dirname "$0")/../.."
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
ulimit -v 12000000
HETSIM_FUZZ_CASES="${1:-100000}" HETSIM_FUZZ_SEED="${2:-1}" \
    cargo test --release --workspace --test it -- fuzz_files:: --nocapture
