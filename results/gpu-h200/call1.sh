#!/bin/bash
# Device check: renderer speed on a real GPU against the bare-wgpu reference, and the lab
# mission with the hat tracker's panoramas at 5 Hz and at the seed's rate (25 Hz).
set -u
for f in .gl/*.deb; do dpkg -x $f / ; done; ldconfig
nvidia-smi --query-gpu=name,driver_version,clocks.sm --format=csv
nproc; cat /proc/cpuinfo | grep "model name" | head -1
I=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; [ -f $I ] && export VK_DRIVER_FILES=$I
E=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json; [ -f $E ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$E
export XDG_RUNTIME_DIR=/tmp
H=.dev/hetsim; R=.dev/wgpu-reference
ref() { for b in vulkan gl; do for a in "w=1024 h=768 views=1" "w=1024 h=768 views=2" "w=120 h=88 views=1"; do echo "ref $b $a: $(timeout 30 $R backend=$b $a mode=readback secs=3 2>&1 | grep -E 'RESULT|rror' | head -2)"; done; done; }
ref 2>&1 | tee $OUT/bench.txt
for b in vulkan gl; do
  t0=$(date +%s.%N); HETSIM_BACKEND=$b timeout 90 $H bench --render --json > $OUT/render-$b.json 2>&1; echo "bench --render $b rc=$? $(python3 -c "print(round($(date +%s.%N) - $t0, 1))") s" | tee -a $OUT/bench.txt
  cat $OUT/render-$b.json
done
ref 2>&1 | tee -a $OUT/bench.txt
mkdir -p /tmp/runs
for s in scenarios/lab.toml .dev/lab-omni25.toml; do
  n=$(basename $s .toml); t0=$(date +%s.%N)
  timeout $([ $n = lab ] && echo 150 || echo 200) $H run $s --backend vulkan --out /tmp/runs/$n > /tmp/runs/$n.log 2>&1; rc=$?
  echo "run $n rc=$rc wall $(python3 -c "print(round($(date +%s.%N) - $t0, 1))") s; $(tail -2 /tmp/runs/$n.log | tr '\n' ' ')" | tee -a $OUT/bench.txt
done
(cd /tmp/runs && tar czf $OUT/runs.tgz --exclude='*.png' --exclude='images' . ) ; ls -la $OUT
