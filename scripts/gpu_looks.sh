#!/usr/bin/env bash
# v2's cost on a machine where SAPIEN finds a CUDA device (issue 46): the same-run looks
# benchmark (v1 and v2 env steps/s, v2 against its raw render loop) rendered by the GPU.
#   scripts/gpu_looks.sh OUT
# PY (default python3) must import maniskill_tidy and its dependencies (sapien, mani_skill).
set -u
OUT=${1:?usage: scripts/gpu_looks.sh OUT}
PY=${PY:-python3}
mkdir -p "$OUT"
exec > >(tee -a "$OUT/gpu_looks.log") 2>&1
echo "== machine: $(nproc) cores"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
timeout 420 "$PY" - <<'PY' 2>&1 | grep -v -i "warn\|deprecat"
import json, time
from maniskill_tidy.envs.hetero_tidy import default_render_backend
from maniskill_tidy.envs.looks_benchmark import bench_looks, report
print("render backend:", default_render_backend())
runs = []
for setting in ("I", "II"):
    for quality in ("fast", "high"):
        t = time.perf_counter()
        runs.append(bench_looks(setting, quality))
        print(f"{setting} {quality}: {time.perf_counter() - t:.0f} s", flush=True)
print(report(runs, []))
print(json.dumps(runs))
PY
echo "== exit ${PIPESTATUS[0]}"
