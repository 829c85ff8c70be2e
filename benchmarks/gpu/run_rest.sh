#!/bin/bash
# Third device run (2026-12-04, second session): what the first two left out.  gpu_check's
# rows it did not reach (inferred on mixed_lights and street_lamps, deferred_calver on all
# three scenes: run here on every scene, inferred's many_lights row again beside them), then
# `pipegen check --precision f64` for the techniques the second run did not reach, mixed_lights
# first (completing that scene), then many_lights, until the time is spent.
# Carried: .gl (glvnd debs), .whl (wheels for python 3.12, pocl as a tar.xz); see README.md.
# Local dry run (no install: the pipegen of this checkout):
#   DRY=1 OUT=/tmp/o SIZE=160x90 F64_SIZE=64x36 FRAMES=1 bash benchmarks/gpu/run_rest.sh
set -u
OUT=${OUT:-/tmp/gpu_out3}; mkdir -p "$OUT"
PY=${PY:-python3}; SIZE=${SIZE:-640x360}; FRAMES=${FRAMES:-5}; F64_SIZE=${F64_SIZE:-320x180}
SITE=${SITE:-/tmp/site}
REPO=$(pwd)
exec > >(tee "$OUT/log3.txt") 2>&1
t0=$(date +%s); stamp() { echo "== $(( $(date +%s) - t0 )) s: $*"; }

stamp setup
. benchmarks/gpu/install.sh
unset LP_NUM_THREADS POCL_MAX_PTHREAD_COUNT
(cd /tmp && $PY -c "
import pipegen, sys
from pipegen.runtime.gl import context
print('pipegen from', pipegen.__file__, sys.version.split()[0])
print('GL:', context.describe())")

stamp "gpu_check $SIZE: inferred, deferred_calver"
timeout ${CHECK_LIMIT:-150} $PY benchmarks/gpu_check.py --size "$SIZE" --frames "$FRAMES" \
    --json "$OUT/gpu_check_rest.json" inferred deferred_calver
echo "gpu_check exit $?"

end=$(( $(date +%s) + ${F64_LIMIT:-300} ))
cd /tmp || exit 1
for pair in mixed_lights:lidr_shadow_volumes mixed_lights:lidr_shadow_prepass \
            mixed_lights:lidr_shadow_indexed mixed_lights:light_prepass mixed_lights:inferred \
            mixed_lights:deferred_calver \
            many_lights:forward many_lights:deferred many_lights:light_prepass \
            many_lights:inferred many_lights:deferred_calver many_lights:lidr_cpu_sort \
            many_lights:lidr_bitplanes many_lights:lidr_max_stencil \
            many_lights:lidr_shadow_indexed many_lights:forward_multipass \
            many_lights:lidr_transparent many_lights:lidr_msaa_texture \
            many_lights:lidr_nearest_edge many_lights:lidr_shadow_volumes \
            many_lights:lidr_shadow_prepass; do
    scene=${pair%%:*}; t=${pair#*:}
    left=$(( end - $(date +%s) )); [ $left -gt 5 ] || { echo "out of time"; break; }
    stamp "check --precision f64 $t $scene"
    timeout $left $PY -m pipegen check "$REPO/pipelines/$t.pipe" \
        --scene "$REPO/examples/scenes/$scene.toml" --size "$F64_SIZE" --precision f64 \
        -o "/tmp/f64_${t}_$scene" 2>&1 | grep -v "^  …"
    echo "exit ${PIPESTATUS[0]}"
done
stamp done
