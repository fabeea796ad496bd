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
# Mesa's CPU rasterizers (lavapipe, llvmpipe) rasterize each draw on threads of their own,
# one per core, woken and joined at a barrier per draw. The suite keeps both cores busy with
# its own test threads, so those threads only add waking, waiting and switching: with none
# (rasterizing on the rendering thread), 400 s of indoor-team cost 31.3 CPU-s instead of
# 36.4 and 30 s of the village 60.7 instead of 70.3, with the same digests
# (results/README.md, "CI's own time").
# A run alone is faster with them (the README's main command keeps Mesa's default).
export LP_NUM_THREADS="${LP_NUM_THREADS:-0}"

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
