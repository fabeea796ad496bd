#!/bin/bash
# Device check 2: the GL fix (instance kept alive), both backends' render bench back to back
# with the reference, and digests: lab on Vulkan with 2 threads (vs 93e14f52 with 16), lab on
# GL, indoor-team on Vulkan.
set -u
for f in .gl/*.deb; do dpkg -x $f / ; done; ldconfig
I=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; [ -f $I ] && export VK_DRIVER_FILES=$I
E=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json; [ -f $E ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$E
export XDG_RUNTIME_DIR=/tmp
H=.dev/hetsim; R=.dev/wgpu-reference
el() { python3 -c "print(round($(date +%s.%N) - $1, 1))"; }
ref() { for b in vulkan gl; do for a in "w=1024 h=768 views=1" "w=1024 h=768 views=2" "w=120 h=88 views=1"; do echo "ref $b $a: $(timeout 30 $R backend=$b $a mode=readback secs=3 2>&1 | grep -E 'RESULT|rror' | head -2 | sed 's/ med_ms.*//')"; done; done; }
: > $OUT/bench.txt
for b in vulkan gl; do
  t0=$(date +%s.%N); HETSIM_BACKEND=$b timeout 90 $H bench --render --json > $OUT/render-$b.json 2>&1; echo "bench --render $b rc=$? $(el $t0) s" | tee -a $OUT/bench.txt
  cat $OUT/render-$b.json
done
ref 2>&1 | tee -a $OUT/bench.txt
mkdir -p /tmp/runs
run() { n=$1; shift; t0=$(date +%s.%N); timeout $1 "${@:2}" --out /tmp/runs/$n > /tmp/runs/$n.log 2>&1; rc=$?
  echo "run $n rc=$rc wall $(el $t0) s; $(tail -2 /tmp/runs/$n.log | tr '\n' ' ')" | tee -a $OUT/bench.txt; }
export RAYON_NUM_THREADS=2; run lab-vk-2threads 150 $H run scenarios/lab.toml --backend vulkan; unset RAYON_NUM_THREADS
run lab-gl 120 $H run scenarios/lab.toml --backend gl
run indoor-team-vk 150 $H run scenarios/indoor-team.toml --backend vulkan
(cd /tmp/runs && tar czf $OUT/runs.tgz --exclude='*.png' --exclude='images' . ) ; ls -la $OUT
