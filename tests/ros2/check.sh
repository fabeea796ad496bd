#!/usr/bin/env bash
# ROS 2 recordings read by outside tools: records the lab (laser, compass, encoders,
# commands, radio) and two rendered seconds of the short village (raw images, IMU,
# rendezvous) with `hetsim run --record`, then decodes every message with Foxglove's
# decoder (mcap-ros2-support) and with rosbags' built-in ROS 2 Humble types
# (tests/ros2/check_mcap.py). Installs both, pinned, into target/ros2-venv the first time.
# Run by .ci/test.sh; by hand: bash tests/ros2/check.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}"
venv=target/ros2-venv
if ! "$venv/bin/python" -c "import mcap_ros2, rosbags" 2>/dev/null; then
    command -v python3 >/dev/null || { echo "check.sh: python3 not found" >&2; exit 1; }
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check \
        mcap==1.6.0 mcap-ros2-support==0.6.0 rosbags==0.11.9
fi
cargo build --release -q -p hetsim-cli
hetsim="${CARGO_TARGET_DIR:-target}/release/hetsim"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$hetsim" run scenarios/lab.toml --duration 10 --no-render \
    --record "$tmp/lab.mcap" --out "$tmp/lab" >/dev/null
"$venv/bin/python" tests/ros2/check_mcap.py "$tmp/lab.mcap" "$tmp/lab"
"$hetsim" run scenarios/village-short.toml --duration 2 \
    --record "$tmp/village.mcap" --out "$tmp/village" >/dev/null
"$venv/bin/python" tests/ros2/check_mcap.py "$tmp/village.mcap" "$tmp/village"
