#!/usr/bin/env bash
# Installs what hetsim needs beyond a Rust toolchain, and only what is missing: Mesa's CPU
# rasterizers, lavapipe (Vulkan) and llvmpipe (GL through EGL), which render the cameras on a
# machine without a GPU; and Slurm with munge (slurm-wlm), which the sweep's end-to-end test
# starts as a one-node cluster (tests/slurm/cluster.sh). Safe to run again: it does nothing
# when they are there.
#
# Used by the README's two commands and by .ci/run. On a machine where it cannot install
# (not root, or no apt-get), it says what to install and exits non-zero.
set -euo pipefail

if ! command -v cargo >/dev/null 2>&1; then
    echo "setup: cargo not found: install a Rust toolchain first (https://rustup.rs)" >&2
    exit 1
fi

# (grep without -q: with pipefail, -q's early exit would fail the pipeline on SIGPIPE)
libs() { ldconfig -p 2>/dev/null || true; }
icds() { ls /usr/share/vulkan/icd.d /etc/vulkan/icd.d 2>/dev/null || true; }
have_vulkan() { libs | grep 'libvulkan\.so\.1' >/dev/null && icds | grep '\.json$' >/dev/null; }
have_lavapipe() { icds | grep '^lvp_icd' >/dev/null; }
have_egl() { libs | grep 'libEGL_mesa\.so' >/dev/null; }
have_slurm() { command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null && command -v ss >/dev/null; }

if have_vulkan && have_lavapipe && have_egl && have_slurm; then
    exit 0
fi

PACKAGES="mesa-vulkan-drivers libvulkan1 libegl1 libegl-mesa0 libgles2 slurm-wlm munge iproute2"
if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    echo "setup: installing Mesa's software rasterizers ($PACKAGES)" >&2
    apt-get update -qq || true
    if ! DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $PACKAGES >/dev/null; then
        echo "setup: apt-get install $PACKAGES failed (see apt's message above)" >&2
        exit 1
    fi
    if have_vulkan && have_egl && have_slurm; then
        exit 0
    fi
    echo "setup: installed $PACKAGES but still found no Vulkan ICD, libEGL_mesa or Slurm" >&2
    exit 1
fi

echo "setup: the cameras need a graphics adapter, and none of Mesa's CPU rasterizers is installed." >&2
echo "setup: as root on Debian or Ubuntu: apt-get install $PACKAGES" >&2
echo "setup: (a machine with a GPU driver for Vulkan or EGL needs nothing; runs with --no-render need no adapter)" >&2
if have_vulkan || have_egl; then
    # Some adapter is there (a GPU driver, or one of the two rasterizers): go on.
    echo "setup: an adapter is present; going on without Mesa's rasterizers" >&2
    exit 0
fi
exit 1
