#!/usr/bin/env bash
# The GPU figures in docs/scaling.md (issue 16), on a machine where SAPIEN finds a CUDA device:
#   scripts/gpu_figures.sh OUT render   # CUDA-rendered expert traces (Setting I and II) for
#                                       # `check-render --against` on a lavapipe machine, and
#                                       # `bench --only env` (env steps/s at 224x224)
#   scripts/gpu_figures.sh OUT eval     # a learned team's (hangrcom, Setting I) episodes/h,
#                                       # 8 test episodes on 1 process, 16 on 8 processes
# PY (default python3) must import maniskill_tidy and its dependencies; data/tidy120 and
# agents/hangrcom{.yaml,/setting_I} and agents/perception/knowledge must be here. Each step has a
# time limit and its output is packed into OUT as it finishes, so a cut-off run still returns.
set -u
OUT=${1:?usage: scripts/gpu_figures.sh OUT render|eval}
PART=${2:?usage: scripts/gpu_figures.sh OUT render|eval}
PY=${PY:-python3}
BACKEND=${BACKEND:-gpu}  # cpu: try the script on a machine without a GPU
WORK=$(mktemp -d)
mkdir -p "$OUT"
LOG="$OUT/gpu_$PART.log"
exec > >(tee -a "$LOG") 2>&1

step() {  # step NAME LIMIT_S COMMAND...: runs it, says how long it took and how it ended
  local name=$1 limit=$2 start
  shift 2
  echo "== $name: $* (limit ${limit}s) at $(date -u +%T)"
  start=$(date +%s.%N)
  timeout "$limit" "$@" 2>&1 | tr '\r' '\n' | grep -v '^\s*$' | grep -v '%|' | tail -40
  echo "== $name: exit ${PIPESTATUS[0]}, $(python3 -c "print(round($(date +%s.%N) - $start, 1))") s"
}

echo "== machine: $(nproc) cores, $(uname -r)"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
ldconfig -p | grep -E 'libvulkan|libX11.so|libEGL.so|libGL.so' || echo "no system vulkan/X11/GL"
ls /usr/share/vulkan/icd.d /etc/vulkan/icd.d /usr/local/nvidia/share/vulkan/icd.d 2>/dev/null
step imports 120 "$PY" -c "
import time; t = time.perf_counter()
import sapien, torch, numpy, mani_skill
from maniskill_tidy.envs.hetero_tidy import default_render_backend
print('sapien', sapien.__version__, 'torch', torch.__version__, 'numpy', numpy.__version__,
      'mani_skill', mani_skill.__version__, 'cuda', torch.cuda.is_available())
print('render backend:', default_render_backend(), round(time.perf_counter() - t, 1), 's')"

if [ "$PART" = render ]; then
  step trace_I 150 "$PY" -m maniskill_tidy.cli check-render --save "$WORK/trace_I" \
    --backend "$BACKEND" --episodes 8 --dataset data/tidy120
  step trace_II 150 "$PY" -m maniskill_tidy.cli check-render --save "$WORK/trace_II" \
    --backend "$BACKEND" --setting II --episodes 5 --dataset data/tidy120
  tar cf "$OUT/traces.tar" -C "$WORK" . && ls -la "$OUT/traces.tar"
  step bench_env 240 "$PY" -m maniskill_tidy.bench --only env
elif [ "$PART" = eval ]; then
  for spec in "8 1 200" "16 8 180"; do
    set -- $spec
    step "eval_w$2" "$3" "$PY" -m maniskill_tidy.cli eval --policy agents/hangrcom.yaml \
      --setting I --split test --dataset data/tidy120 --episodes "$1" --workers "$2" \
      --out "$WORK/w$2"
    tar cf "$OUT/evals.tar" -C "$WORK" . 2>/dev/null
  done
else
  echo "unknown part $PART: expected render or eval" >&2
  exit 2
fi
