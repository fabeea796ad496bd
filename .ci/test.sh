#!/usr/bin/env bash
# The test suite: every test on Mesa's Vulkan rasterizer (lavapipe), then the tests that read
# rendered images again on its GL rasterizer (llvmpipe through EGL), so that both stay green.
# tests/tests/golden.rs runs its rendered scenarios on both backends by itself.
set -euo pipefail
cd "$(dirname "$0")/.."
# The Vulkan loader warns without it; nothing of ours reads it.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"

echo "== cargo test --workspace (HETSIM_BACKEND=vulkan)"
HETSIM_BACKEND=vulkan cargo test --workspace
echo "== rendered-image tests again (HETSIM_BACKEND=gl)"
# `--workspace` as above: with `-p` Cargo resolves other features and builds everything again.
HETSIM_BACKEND=gl cargo test --workspace \
    --test render --test vision --test vo_scale --test slam --test team \
    --test cameras --test oracle
echo "== ROS 2 recordings decoded by Foxglove's and rosbags' decoders"
bash tests/ros2/check.sh
