#!/bin/bash
# Device check 3: the GL fix (indirect-call validation off, de5bf37): the render bench on
# Vulkan, GL and Vulkan with anisotropy 1, then the reference once, then the lab on GL.
set -u
for f in .gl/*.deb; do dpkg -x $f / ; done; ldconfig
I=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; [ -f $I ] && export VK_DRIVER_FILES=$I
E=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json; [ -f $E ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$E
export XDG_RUNTIME_DIR=/tmp
H=.dev/hetsim; R=.dev/wgpu-reference
el() { python3 -c "print(round($(date +%s.%N) - $1, 1))"; }
ref() { for b in vulkan gl; do for a in "w=1024 h=768 views=1" "w=1024 h=768 views=2" "w=120 h=88 views=1"; do echo "ref $b $a: $(timeout 30 $R backend=$b $a mode=readback secs=3 2>&1 | grep -E 'RESULT|rror' | head -2 | sed 's/ med_ms.*//')"; done; done; }
: > $OUT/bench.txt
for b in vulkan gl vulkan-aniso1; do
  t0=$(date +%s.%N); HETSIM_BACKEND=${b%-aniso1} HETSIM_ANISOTROPY=$([ $b = vulkan-aniso1 ] && echo 1 || echo 16) timeout 90 $H bench --render --json > $OUT/render-$b.json 2>&1; echo "bench --render $b rc=$? $(el $t0) s" | tee -a $OUT/bench.txt
  cat $OUT/render-$b.json
done
ref 2>&1 | tee -a $OUT/bench.txt
mkdir -p /tmp/runs
run() { n=$1; shift; t0=$(date +%s.%N); timeout $1 "${@:2}" --out /tmp/runs/$n > /tmp/runs/$n.log 2>&1; rc=$?
  echo "run $n rc=$rc wall $(el $t0) s; $(tail -2 /tmp/runs/$n.log | tr '\n' ' ')" | tee -a $OUT/bench.txt; }
run lab-gl 120 $H run scenarios/lab.toml --backend gl
(cd /tmp/runs && tar czf $OUT/runs.tgz --exclude='*.png' --exclude='images' . ) ; ls -la $OUT
