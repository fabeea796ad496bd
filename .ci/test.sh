#!/usr/bin/env bash
# The test suite: every test on Mesa's Vulkan rasterizer (lavapipe), then the tests that read
# rendered images again on its GL rasterizer (llvmpipe through EGL), so that both stay green.
# tests/tests/it/golden.rs runs its rendered missions on both backends by itself.
#
# The tests build in the release profile: they share every artifact of the release build of
# `hetsim` that the whole missions run (and that .ci/run builds first for the benchmarks), and
# the in-process runs are as fast as the binary's.
set -euo pipefail
cd "$(dirname "$0")/.."
source .ci/steps.sh
# The Vulkan loader warns without it; nothing of ours reads it.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"

step "tests build" cargo test --release --workspace --no-run
step "cargo test --workspace (HETSIM_BACKEND=vulkan)" \
    env HETSIM_BACKEND=vulkan cargo test --release --workspace
# `--workspace` as above: with `-p` Cargo resolves other features and builds everything again.
# oracle:: (truth withheld, same stack bytes) is not here: what it checks is how truth is
# routed, not how images are rasterized, and golden runs the lab mission on GL in full.
step "rendered-image tests again (HETSIM_BACKEND=gl)" \
    env HETSIM_BACKEND=gl cargo test --release --workspace --test it -- \
    render:: vision:: vo_scale:: slam:: team:: cameras::
step "ROS 2 recordings decoded by Foxglove's and rosbags' decoders" bash tests/ros2/check.sh
