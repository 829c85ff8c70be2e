#!/bin/bash
# Issue 26 item 8 on the lent GPU machine: GL on the GPU (EGL, headless) against CL (PoCL on
# the machine's CPUs) for every shipped technique on three scenes, then frame times.
# Carried: .gl (this script, glvnd debs), .whl (wheels for python 3.12, pocl as a tar.xz).
# Local dry run (no install: this checkout's pipegen):
#   DRY=1 OUT=/tmp/o SIZE=160x90 FRAMES=1 bash benchmarks/gpu/run.sh
set -u
OUT=${OUT:-/tmp/gpu_out}; mkdir -p "$OUT"
PY=${PY:-python3}; SIZE=${SIZE:-640x360}; FRAMES=${FRAMES:-5}; BIG=${BIG:-1280x720}
SITE=${SITE:-/tmp/site}
REPO=$(pwd)
exec > >(tee "$OUT/log.txt") 2>&1
t0=$(date +%s); stamp() { echo "== $(( $(date +%s) - t0 )) s: $*"; }

stamp setup
. benchmarks/gpu/install.sh
unset LP_NUM_THREADS POCL_MAX_PTHREAD_COUNT
stamp "machine"
nvidia-smi -L 2>&1; nproc; grep -m1 "model name" /proc/cpuinfo
ldconfig -p | grep -E "libEGL|libGL\.so|libOpenGL" | head
ls /usr/share/glvnd/egl_vendor.d /usr/local/nvidia/share/glvnd/egl_vendor.d /etc/OpenCL/vendors 2>&1
echo "__EGL_VENDOR_LIBRARY_FILENAMES=${__EGL_VENDOR_LIBRARY_FILENAMES:-}"
cd /tmp || exit 1         # pipegen from the wheel, not the repo's folder
$PY -c "import pipegen, sys; print('pipegen from', pipegen.__file__, sys.version.split()[0])"
$PY -c "
from pipegen.runtime.gl import context
print('GL:', context.describe())
print('limits:', context.gl_limits())
"
stamp "run (default scene, 640x360, both backends)"
for b in gl cl; do
    timeout 120 $PY -m pipegen run "$REPO/pipelines/deferred.pipe" --size 640x360 \
        --backend $b -o "/tmp/run_$b" 2>&1 | grep -v "^  /tmp"
done
for b in gl cl; do cp "/tmp/run_$b/contact_sheet.png" "$OUT/run_${b}_contact_sheet.png" 2>/dev/null; done
cd "$REPO" || exit 1
stamp "gpu_check $SIZE"
timeout ${CHECK_LIMIT:-300} $PY benchmarks/gpu_check.py --size "$SIZE" --frames "$FRAMES" \
    --json "$OUT/gpu_check.json"
echo "gpu_check exit $?"
stamp "backends $BIG"
timeout ${BIG_LIMIT:-100} $PY benchmarks/backends.py --size "$BIG" --frames 5 \
    --threads "$(nproc)" 2>&1
stamp done
