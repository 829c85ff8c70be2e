#!/bin/bash
# Second device run: GL on the GPU against the float64 evaluation (check --precision f64),
# every shipped technique on mixed_lights and many_lights at 320x180; GL renders saved.
set -u
OUT=${OUT:-/tmp/gpu_out2}; mkdir -p "$OUT"; PY=${PY:-python3}; SITE=${SITE:-/tmp/site}
REPO=$(pwd)
exec > >(tee "$OUT/log2.txt") 2>&1
t0=$(date +%s); stamp() { echo "== $(( $(date +%s) - t0 )) s: $*"; }
KEEP_SITE=1 . benchmarks/gpu/install.sh
stamp dump
timeout ${DUMP_LIMIT:-90} $PY benchmarks/gpu/dump.py
end=$(( $(date +%s) + ${F64_LIMIT:-170} ))
cd /tmp
for scene in mixed_lights many_lights; do
  for t in forward forward_multipass deferred lidr_cpu_sort lidr_max_stencil lidr_bitplanes \
           lidr_transparent lidr_msaa_texture lidr_nearest_edge lidr_shadow_volumes \
           lidr_shadow_prepass lidr_shadow_indexed light_prepass inferred deferred_calver; do
    left=$(( end - $(date +%s) )); [ $left -gt 5 ] || { echo "out of time"; break 2; }
    stamp "$t $scene"
    timeout $left $PY -m pipegen check "$REPO/pipelines/$t.pipe" \
        --scene "$REPO/examples/scenes/$scene.toml" --size 320x180 --precision f64 \
        -o "/tmp/f64_${t}_$scene" 2>&1 | grep -v "^  …"
  done
done
stamp done
